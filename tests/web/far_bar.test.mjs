// The viewer on the demo's bar and cage moved 1e6 away from the world origin, where float32
// world coordinates are 0.06 apart: the page must still show the model to float32 precision of
// its size (positions are sent relative to the model's centre).
import {rmSync} from 'node:fs';
import {join} from 'node:path';
import {after} from 'node:test';

import * as h from './harness.mjs';
import {viewSuite} from './view_suite.mjs';

await h.requirements();
const dir = h.tempDir('far');
after(() => rmSync(dir, {recursive: true, force: true}));
const offset = [1e6, -1e6, 1e6];
viewSuite({
  title: 'spacewarp view on the demo bar 1e6 from the origin',
  model: join(dir, 'far_bar.obj'),
  cage: join(dir, 'far_cage.obj'),
  secondMethod: 'green',
  prepare: async () => {
    await h.demoInputs(dir, ['bar.obj', 'cage.obj']);
    h.shiftedObj(join(dir, 'bar.obj'), join(dir, 'far_bar.obj'), offset);
    h.shiftedObj(join(dir, 'cage.obj'), join(dir, 'far_cage.obj'), offset);
  },
});
