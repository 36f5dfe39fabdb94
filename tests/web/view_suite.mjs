// The end-to-end checks of issue 18, run against one model and cage: one server and one browser
// for the whole file.
import assert from 'node:assert/strict';
import {readFileSync, rmSync} from 'node:fs';
import {basename, join} from 'node:path';
import {after, before, describe, it} from 'node:test';

import * as h from './harness.mjs';

/**
 * The page shows float32 offsets from the scene's origin (the model's centre), within half an
 * ulp of float: 2^-24 of the model's size; allow 4 ulps (the origin need not be a float).
 */
const floatTolerance = (size) => size * 2 ** -22;

/**
 * model, cage: paths; secondMethod: the method switched to; prepare(): optional set-up run
 * before the server starts (e.g. `spacewarp demo`).
 */
export function viewSuite({title, model, cage, secondMethod, prepare}) {
  describe(title, () => {
    let chromium;
    let view;
    let browser;
    let page;
    let saveDir;
    let rest;
    let restPose;
    let scale;
    let control;

    before(async () => {
      chromium = await h.requirements();
      await prepare?.();
      saveDir = h.tempDir('save');
      view = await h.startView([model, '--cage', cage, '--save-dir', saveDir]);
      browser = await h.openPage(chromium, view.url);
      page = browser.page;
      rest = await h.positions(page);
      restPose = await h.pose(page);
      scale = h.extent(rest);
      control = await page.evaluate(() => {
        // The control farthest on screen from every other one, so that the press picks it.
        const m = window.spacewarp.pose().length / 3;
        const at = Array.from({length: m}, (_, i) => window.spacewarp.controlScreenPosition(i));
        let best = 0;
        let bestGap = -1;
        at.forEach((p, i) => {
          const gap = Math.min(
              ...at.map((q, j) => (i === j ? Infinity : Math.hypot(p.x - q.x, p.y - q.y))));
          const inside = p.x > 20 && p.y > 20 && p.x < innerWidth - 60 && p.y < innerHeight - 60;
          if (inside && gap > bestGap) (best = i), (bestGap = gap);
        });
        return best;
      });
    });

    after(async () => {
      await browser?.close();
      if (view?.process.exitCode === null && view.process.signalCode === null)
        view.process.kill('SIGKILL');
      if (saveDir) rmSync(saveDir, {recursive: true, force: true});
    });

    /** Saves the rig through the page and returns `spacewarp deform --rig` of the model. */
    async function deformedBySavedRig(tag) {
      const paths = await page.evaluate(() => window.spacewarp.save('rig'));
      const rig = paths.find((p) => p.endsWith('.json'));
      assert.ok(rig, `save('rig') wrote ${paths.join(', ')}`);
      const out = join(saveDir, `${tag}.obj`);
      h.runCli(['deform', '--rig', rig, model, '-o', out]);
      return h.objVertices(out);
    }

    it('shows the model at rest with its controls', () => {
      assert.ok(rest.length > 0 && rest.length % 3 === 0);
      assert.ok(restPose.length > 0 && restPose.length % 3 === 0);
      const modelRest = h.objVertices(model);
      assert.ok(
          h.maxDifference(rest, modelRest) <= floatTolerance(scale),
          'the page shows the model as read');
      assert.deepEqual(browser.errors, []);
    });

    it('drags a control by the mouse offset and shows what deform makes of the saved rig',
       async () => {
         const offset = {x: 40, y: -30};
         const start =
             await page.evaluate((i) => window.spacewarp.controlScreenPosition(i), control);
         await page.mouse.move(start.x, start.y);
         await page.mouse.down();
         await page.mouse.move(start.x + offset.x / 2, start.y + offset.y / 2, {steps: 4});
         await page.mouse.move(start.x + offset.x, start.y + offset.y, {steps: 4});
         await page.mouse.up();
         await page.evaluate(() => window.spacewarp.settled());

         const end = await page.evaluate((i) => window.spacewarp.controlScreenPosition(i), control);
         assert.ok(
             Math.abs(end.x - start.x - offset.x) <= 1 && Math.abs(end.y - start.y - offset.y) <= 1,
             `control ${control} moved on screen from (${start.x}, ${start.y}) to (${end.x}, ${
                 end.y}), not by (${offset.x}, ${offset.y})`);
         const posed = await h.pose(page);
         for (let i = 0; i < posed.length; ++i) {
           if (Math.floor(i / 3) !== control)
             assert.equal(posed[i], restPose[i], `control ${Math.floor(i / 3)} moved too`);
         }

         const shown = await h.positions(page);
         assert.ok(
             h.maxDifference(shown, rest) > 1e-3 * scale,
             'the model did not move with the control');
         const expected = await deformedBySavedRig('dragged');
         const gap = h.maxDifference(shown, expected);
         assert.ok(gap <= floatTolerance(scale), `the page and deform --rig differ by ${gap}`);
         const latencies = await page.evaluate(() => window.spacewarp.latencies);
         assert.ok(
             latencies.length > 0 && latencies.every((t) => t >= 0),
             'every move that moved a control got a latency');
       });

    it(`switches to ${secondMethod} keeping the pose and shows that method's positions`,
       async () => {
         const before = await h.positions(page);
         const posed = await h.pose(page);
         const result = await page.evaluate((m) => window.spacewarp.setMethod(m), secondMethod);
         assert.equal(result.method, secondMethod);
         assert.deepEqual(await h.pose(page), posed, 'the pose is kept');
         const shown = await h.positions(page);
         assert.ok(
             h.maxDifference(shown, before) > 1e-4 * scale,
             `${secondMethod} shows the same positions as before`);
         const expected = await deformedBySavedRig(secondMethod);
         const gap = h.maxDifference(shown, expected);
         assert.ok(
             gap <= floatTolerance(scale),
             `the page and deform --rig (${secondMethod}) differ by ${gap}`);
         const rig = JSON.parse(readFileSync(
             join(saveDir, `${basename(model).replace(/\.[^.]+$/, '')}_rig.json`), 'utf8'));
         assert.equal(rig.method, secondMethod);
       });

    async function screenshot() {
      const paths = await page.evaluate(() => window.spacewarp.screenshot());
      assert.equal(paths.length, 1);
      assert.ok(paths[0].endsWith('.png'));
      return h.decodePng(readFileSync(paths[0]));
    }

    it('saves screenshots that are not blank, and the heat map differs from the plain view',
       async () => {
         const plain = await screenshot();
         const colours = h.distinctColours(plain);
         assert.ok(colours >= 64, `the plain screenshot has ${colours} colours`);
         await page.evaluate((i) => window.spacewarp.showWeights(i), control);
         const heat = await screenshot();
         assert.equal(heat.width, plain.width);
         const changed = h.differingPixels(plain, heat);
         assert.ok(
             changed > 0.01 * plain.width * plain.height,
             `the heat map changed only ${changed} pixels`);
         let zLo = Infinity;
         let zHi = -Infinity;
         for (let i = 2; i < restPose.length; i += 3)
           (zLo = Math.min(zLo, restPose[i])), (zHi = Math.max(zHi, restPose[i]));
         await page.evaluate((z) => window.spacewarp.showSlice('z', z), (zLo + zHi) / 2);
         const withSlice = await screenshot();
         assert.ok(
             h.differingPixels(heat, withSlice) > 0.01 * plain.width * plain.height,
             'the slice plane is not drawn');
         await page.evaluate(() => window.spacewarp.showSlice(null));
         await page.evaluate(() => window.spacewarp.showWeights(-1));
       });

    it('shows folds in red where a pose inverts part of the model, and none at rest', async () => {
      // A click on the background drops the selection and its gizmo (whose x axis is red).
      const box = await page.locator('canvas').boundingBox();
      await page.mouse.click(box.x + 5, box.y + box.height - 5);
      await page.evaluate(
          (p) => window.spacewarp.setPose(Float64Array.from(p)), Array.from(restPose));
      await page.evaluate(() => window.spacewarp.showFolds(true));
      const atRest = h.redPixels(await screenshot());
      assert.equal(atRest, 0, `${atRest} red pixels at rest`);

      // Mirror the controls of one half (along the longest axis) across a second axis: that
      // half of the model is reflected (det J < 0), the other half is not.
      const m = restPose.length / 3;
      const lo = [Infinity, Infinity, Infinity];
      const hi = [-Infinity, -Infinity, -Infinity];
      for (let i = 0; i < m; ++i) {
        for (let c = 0; c < 3; ++c)
          (lo[c] = Math.min(lo[c], restPose[3 * i + c])),
              (hi[c] = Math.max(hi[c], restPose[3 * i + c]));
      }
      const extent = [0, 1, 2].map((c) => hi[c] - lo[c]);
      const along = extent.indexOf(Math.max(...extent));
      const across = (along + 1) % 3;
      const inverted = Float64Array.from(restPose);
      for (let i = 0; i < m; ++i) {
        if (restPose[3 * i + along] > (lo[along] + hi[along]) / 2) {
          inverted[3 * i + across] = lo[across] + hi[across] - restPose[3 * i + across];
        }
      }
      await page.evaluate(
          (p) => window.spacewarp.setPose(Float64Array.from(p)), Array.from(inverted));
      const folded = h.redPixels(await screenshot());
      assert.ok(folded > 100, `${folded} red pixels for a pose that mirrors half the model`);
      await page.evaluate(() => window.spacewarp.showFolds(false));
      assert.equal(h.redPixels(await screenshot()), 0, 'red stays after folds are switched off');
      assert.deepEqual(browser.errors, []);
    });

    it('stops with exit code 0 on SIGTERM, as on Ctrl-C, and the page says the server stopped',
       async () => {
         assert.equal(await h.stopView(view), 0);
         const message = await browser.page.evaluate(
             () => window.spacewarp.setMethod('mvc').then(() => 'no error', (e) => e.message));
         assert.match(message, /the server stopped: restart spacewarp view/);
         await browser.close();
         browser = null;
       });
  });
}
