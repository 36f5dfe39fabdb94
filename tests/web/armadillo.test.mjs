// The viewer on the armadillo (15k vertices) and its 110-vertex cage, from ../shared/data.
import {existsSync} from 'node:fs';
import {join} from 'node:path';

import * as h from './harness.mjs';
import {viewSuite} from './view_suite.mjs';

const dir = h.env.data && join(h.env.data, 'ju2005-armadillo');
if (!dir || !existsSync(join(dir, 'armadilloman.obj')))
  h.skip(`no armadillo in ${dir} (../shared/data is optional)`);
await h.requirements();
viewSuite({
  title: 'spacewarp view on the armadillo',
  model: join(dir, 'armadilloman.obj'),
  cage: join(dir, 'bounding_mesh.obj'),
  secondMethod: 'green',
});
