// The viewer on the demo's bar (a 10k-vertex soup) and its concave cage.
import {rmSync} from 'node:fs';
import {join} from 'node:path';
import {after} from 'node:test';

import * as h from './harness.mjs';
import {viewSuite} from './view_suite.mjs';

await h.requirements();
const dir = h.tempDir('demo');
after(() => rmSync(dir, {recursive: true, force: true}));
viewSuite({
  title: 'spacewarp view on the demo bar',
  model: join(dir, 'bar.obj'),
  cage: join(dir, 'cage.obj'),
  secondMethod: 'green',
  prepare: () => h.demoInputs(dir, ['bar.obj', 'cage.obj']),
});
