#!/usr/bin/env node
// Latency of `spacewarp view` (issue 18): drags a control in headless Chromium at 60 moves per
// second and reports, per model and method, the median and 90th percentile of the page's
// drag-to-frame latency (window.spacewarp.latencies: from a pointermove to the first frame drawn
// with the server's positions for it) and of the server's deform time (X-Spacewarp-Deform-Ms).
// Models: the armadillo from ../shared/data (else the demo's bar), and generated point clouds of
// 1M and 5M points in a box cage (--sizes to change, in millions).
//
//   node bench/view_latency.mjs --spacewarp build/apps/spacewarp --web-dir build/web/dist \
//        --modules web/node_modules [--sizes 1,5] [--moves 60] [--cloud-moves 20]
//        [--methods mvc,green] [--data DIR|none]
import {spawn, spawnSync} from 'node:child_process';
import {closeSync, existsSync, mkdtempSync, openSync, rmSync, writeFileSync, writeSync} from 'node:fs';
import {tmpdir} from 'node:os';
import {dirname, join, resolve} from 'node:path';
import {fileURLToPath, pathToFileURL} from 'node:url';

const here = dirname(fileURLToPath(import.meta.url));
const args = Object.fromEntries(
    process.argv.slice(2).reduce(
        (pairs, a, i, all) => (a.startsWith('--') ? [...pairs, [a.slice(2), all[i + 1]]] : pairs),
        []),
);
const cli = resolve(args.spacewarp ?? 'build/apps/spacewarp');
const webDir = resolve(args['web-dir'] ?? 'build/web/dist');
const modules = resolve(args.modules ?? join(here, '..', 'web', 'node_modules'));
const chromiumPath = args.chromium ?? '/usr/bin/chromium';
const sizes = (args.sizes ?? '1,5').split(',').filter(Boolean).map(Number);
const moves = Number(args.moves ?? 60);
// Fewer on the clouds: a frame of millions of points takes seconds in software WebGL.
const cloudMoves = Number(args['cloud-moves'] ?? 20);
const data = args.data ?? join(here, '..', '..', 'shared', 'data', 'ju2005-armadillo');

for (const [what, path] of [
         ['spacewarp', cli], ['page', join(webDir, 'index.html')], ['chromium', chromiumPath]]) {
  if (!existsSync(path)) {
    console.error(`view_latency: no ${what} at ${path}`);
    process.exit(2);
  }
}
const {chromium} = await import(pathToFileURL(join(modules, 'playwright-core', 'index.mjs')).href);
const work = mkdtempSync(join(tmpdir(), 'spacewarp-view-bench-'));

/** A box cage (8 vertices, 12 triangles, outward) around [lo, hi]. */
function writeBoxCage(path, lo, hi) {
  const v = [];
  for (let i = 0; i < 8; ++i)
    v.push(`v ${i & 1 ? hi[0] : lo[0]} ${i & 2 ? hi[1] : lo[1]} ${i & 4 ? hi[2] : lo[2]}`);
  const quads =
      [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]];
  const f = quads.flatMap(
      ([a, b, c, d]) => [`f ${a + 1} ${b + 1} ${c + 1}`, `f ${a + 1} ${c + 1} ${d + 1}`]);
  writeFileSync(path, [...v, ...f, ''].join('\n'));
}

/** A binary PLY cloud of n points of a wavy slab in [-1, 1]×[-0.5, 0.5]×[-2, 2] (deterministic). */
function writeCloud(path, n) {
  const fd = openSync(path, 'w');
  writeSync(
      fd,
      `ply\nformat binary_little_endian 1.0\nelement vertex ${
          n}\nproperty float x\nproperty float y\nproperty float z\nend_header\n`);
  const chunk = 1 << 16;
  const buffer = new Float32Array(3 * chunk);
  let seed = 12345;
  const random = () => ((seed = (Math.imul(seed, 1103515245) + 12345) >>> 0) / 2 ** 32);
  for (let done = 0; done < n; done += chunk) {
    const count = Math.min(chunk, n - done);
    for (let i = 0; i < count; ++i) {
      const x = 2 * random() - 1;
      const z = 4 * random() - 2;
      buffer[3 * i] = x;
      buffer[3 * i + 1] = 0.3 * Math.sin(3 * x) * Math.cos(2 * z) + 0.2 * (random() - 0.5);
      buffer[3 * i + 2] = z;
    }
    writeSync(fd, new Uint8Array(buffer.buffer, 0, 12 * count));
  }
  closeSync(fd);
}

function models() {
  const list = [];
  if (data === 'none') {
    // only the generated clouds
  } else if (existsSync(join(data, 'armadilloman.obj'))) {
    list.push({
      name: 'armadillo',
      model: join(data, 'armadilloman.obj'),
      cage: join(data, 'bounding_mesh.obj'),
      methods: null,
      moves
    });
  } else {
    const demo = join(work, 'demo');
    spawnSync(cli, ['-q', 'demo', demo], {stdio: 'inherit'});
    list.push({
      name: 'demo bar',
      model: join(demo, 'bar.obj'),
      cage: join(demo, 'cage.obj'),
      methods: null,
      moves
    });
  }
  for (const millions of sizes) {
    const n = Math.round(millions * 1e6);
    const model = join(work, `cloud_${millions}M.ply`);
    const cage = join(work, `cage_${millions}M.obj`);
    writeCloud(model, n);
    writeBoxCage(cage, [-1.2, -0.8, -2.3], [1.2, 0.8, 2.3]);
    list.push({
      name: `cloud ${millions}M`,
      model,
      cage,
      methods: (args.methods ?? 'mvc,green').split(','),
      moves: cloudMoves
    });
  }
  return list;
}

function startView(model, cage) {
  const child = spawn(
      cli, ['view', model, '--cage', cage, '--port', '0', '--web-dir', webDir, '--save-dir', work],
      {
        stdio: ['ignore', 'pipe', 'inherit'],
      });
  return new Promise((resolve, reject) => {
    let out = '';
    child.stdout.on('data', (c) => {
      out += c;
      const m = /(http:\/\/\S+\/) \(Ctrl-C to stop\)/.exec(out);
      if (m) resolve({url: m[1], child});
    });
    child.on('exit', (code) => reject(new Error(`spacewarp view exited with ${code}`)));
  });
}

const quantile = (values, q) => {
  if (values.length === 0) return NaN;
  const sorted = [...values].sort((a, b) => a - b);
  return sorted[Math.min(sorted.length - 1, Math.floor(q * sorted.length))];
};

const rows = [];
let current = null;  // the server being measured
// Ctrl-C: stop the server and the browser too, then delete the generated models.
for (const signal of ['SIGINT', 'SIGTERM']) {
  process.once(signal, async () => {
    current?.child.kill('SIGTERM');
    await context?.close().catch(() => {});
    rmSync(work, {recursive: true, force: true});
    process.exit(130);
  });
}
let context = null;
const userDataDir = join(work, 'chromium');
context = await chromium.launchPersistentContext(userDataDir, {
  executablePath: chromiumPath,
  headless: true,
  args: [
    '--headless', '--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run',
    '--disable-background-networking', '--disable-component-update', '--disable-sync'
  ],
  viewport: {width: 960, height: 720},
});
try {
  for (const entry of models()) {
    const view = await startView(entry.model, entry.cage);
    current = view;
    const page = await context.newPage();
    page.setDefaultTimeout(600_000);
    const loadStart = Date.now();
    await page.goto(view.url);
    await page.evaluate(() => window.spacewarp.ready);
    const loadMs = Date.now() - loadStart;
    const info = await page.evaluate(async () => (await fetch('/api/scene')).json());
    const control = await page.evaluate(() => {
      const m = window.spacewarp.pose().length / 3;
      const at = Array.from({length: m}, (_, i) => window.spacewarp.controlScreenPosition(i));
      let best = 0;
      let bestGap = -1;
      at.forEach((p, i) => {
        const gap =
            Math.min(...at.map((q, j) => (i === j ? Infinity : Math.hypot(p.x - q.x, p.y - q.y))));
        if (p.x > 220 && p.y > 20 && p.x < innerWidth - 60 && p.y < innerHeight - 60 &&
            gap > bestGap)
          (best = i), (bestGap = gap);
      });
      return best;
    });
    for (const method of entry.methods ?? info.methods) {
      const {bindMs} = await page.evaluate((m) => window.spacewarp.setMethod(m), method);
      await page.evaluate(() => {
        window.spacewarp.latencies.length = 0;
        window.spacewarp.deformMs.length = 0;
      });
      const start = await page.evaluate((i) => window.spacewarp.controlScreenPosition(i), control);
      await page.mouse.move(start.x, start.y);
      await page.mouse.down();
      for (let k = 1; k <= entry.moves; ++k) {
        const t = (2 * Math.PI * k) / entry.moves;  // a circle of 40 px: back where it started
        await page.mouse.move(start.x + 40 * Math.sin(t), start.y + 40 * (1 - Math.cos(t)) / 2);
        await page.waitForTimeout(16);
      }
      await page.mouse.up();
      await page.evaluate(() => window.spacewarp.settled());
      const {latencies, deformMs} =
          await page.evaluate(() => ({
                                latencies: window.spacewarp.latencies.slice(),
                                deformMs: window.spacewarp.deformMs.slice(),
                              }));
      rows.push({
        model: entry.name,
        vertices: info.model.vertexCount,
        method,
        bindMs: Number(bindMs ?? 0),
        loadMs,
        moves: latencies.length,
        poses: deformMs.length,
        latency50: quantile(latencies, 0.5),
        latency90: quantile(latencies, 0.9),
        deform50: quantile(deformMs, 0.5),
      });
      console.log(JSON.stringify(rows.at(-1)));
    }
    await page.close();
    view.child.kill('SIGTERM');
    await new Promise((r) => view.child.once('exit', r));
  }
} finally {
  await context.close();
  rmSync(work, {recursive: true, force: true});
}

const f = (x) => (Number.isFinite(x) ? x.toFixed(1) : 'n/a');
console.log(
    '\n| model | vertices | method | bind ms | page load ms | moves / poses sent | drag→frame median ms | p90 ms | server deform median ms |');
console.log('|---|---:|---|---:|---:|---:|---:|---:|---:|');
for (const r of rows) {
  console.log(`| ${r.model} | ${r.vertices.toLocaleString('en')} | ${r.method} | ${f(r.bindMs)} | ${
      r.loadMs} | ${r.moves} / ${r.poses} | ${f(r.latency50)} | ${f(r.latency90)} | ${
      f(r.deform50)} |`);
}
