// Shared set-up of the browser tests: skips (exit 77, one line) when something they need is
// missing, starts `spacewarp view` on a free port, opens its page in headless Chromium, and
// reads back what the page and the command line produce.
import {spawn, spawnSync} from 'node:child_process';
import {existsSync, mkdtempSync, readFileSync, rmSync, writeFileSync} from 'node:fs';
import {tmpdir} from 'node:os';
import {join} from 'node:path';
import {pathToFileURL} from 'node:url';
import {inflateSync} from 'node:zlib';

export const env = {
  cli: process.env.SPACEWARP_CLI,
  webDir: process.env.SPACEWARP_WEB_DIR,
  modules: process.env.SPACEWARP_WEB_MODULES,
  chromium: process.env.SPACEWARP_CHROMIUM || '/usr/bin/chromium',
  data: process.env.SPACEWARP_SHARED_DATA,
};

export function skip(message) {
  console.log(`SKIPPED: ${message}`);
  process.exit(77);
}

/** Skips the test file unless the CLI, the built page, playwright-core and Chromium exist. */
export async function requirements() {
  if (!env.cli || !existsSync(env.cli)) skip(`no spacewarp executable (SPACEWARP_CLI=${env.cli})`);
  if (!env.webDir || !existsSync(join(env.webDir, 'index.html'))) {
    skip(`no built page in ${
        env.webDir} (install Node.js and npm, apt-get install nodejs npm, and rebuild)`);
  }
  if (!existsSync(env.chromium)) skip(`no Chromium at ${env.chromium} (apt-get install chromium)`);
  const entry = env.modules && join(env.modules, 'playwright-core', 'index.mjs');
  if (!entry || !existsSync(entry))
    skip(`no playwright-core in ${env.modules} (build the spacewarp_web target)`);
  return (await import(pathToFileURL(entry).href)).chromium;
}

export const tempDir = (prefix) => mkdtempSync(join(tmpdir(), `spacewarp-web-${prefix}-`));

/** Runs the CLI to completion; throws with its stderr on a non-zero exit. */
export function runCli(args) {
  const result = spawnSync(env.cli, ['-q', ...args], {encoding: 'utf8'});
  if (result.status !== 0)
    throw new Error(`spacewarp ${args.join(' ')}: exit ${result.status}: ${result.stderr}`);
  return result;
}

/**
 * Runs `spacewarp demo DIR` until it has written `files` (its first outputs; each appears whole,
 * through the atomic writer), then stops it: the rest of the demo takes tens of seconds.
 */
export async function demoInputs(dir, files) {
  const child = spawn(env.cli, ['-q', 'demo', dir], {stdio: 'ignore'});
  const exited = new Promise((resolve) => child.once('exit', resolve));
  for (;;) {
    if (files.every((f) => existsSync(join(dir, f)))) break;
    if (child.exitCode !== null)
      throw new Error(
          `spacewarp demo ${dir} exited with ${child.exitCode} before writing ${files}`);
    await new Promise((resolve) => setTimeout(resolve, 50));
  }
  child.kill('SIGTERM');
  await exited;
}

/**
 * Starts `spacewarp view ARGS --port 0` and resolves to { url, process } once it prints its
 * URL. A command that has no viewer yet, or no page, skips the test file.
 */
export function startView(args) {
  const child = spawn(env.cli, ['view', ...args, '--port', '0', '--web-dir', env.webDir], {
    stdio: ['ignore', 'pipe', 'pipe'],
  });
  let stdout = '';
  let stderr = '';
  return new Promise((resolve, reject) => {
    child.stdout.on('data', (chunk) => {
      stdout += chunk;
      const match =
          /^spacewarp view: (http:\/\/127\.0\.0\.1:\d+\/) \(Ctrl-C to stop\)$/m.exec(stdout);
      if (match) resolve({url: match[1], process: child});
    });
    child.stderr.on('data', (chunk) => (stderr += chunk));
    child.on('exit', (code) => {
      const line = stderr.trim().split('\n')[0] ?? '';
      if (code === 2 && /view|page|npm|node/i.test(line) &&
          !/(MODEL|CAGE|RIG).*(not|no)/.test(line)) {
        skip(`spacewarp view is not available: ${line}`);
      }
      reject(new Error(`spacewarp view exited with ${code} before printing its URL: ${stderr}`));
    });
  });
}

/** Stops the server with SIGTERM; resolves to its exit code, or to the signal's name. */
export function stopView(view) {
  return new Promise((resolve) => {
    if (view.process.exitCode !== null) return resolve(view.process.exitCode);
    view.process.once('exit', (code, signal) => resolve(code ?? signal));
    view.process.kill('SIGTERM');
  });
}

export async function openPage(chromium, url) {
  const userDataDir = tempDir('chromium');
  const context = await chromium.launchPersistentContext(userDataDir, {
    executablePath: env.chromium,
    headless: true,
    args: [
      '--headless',
      '--no-sandbox',
      '--disable-gpu',
      '--disable-quic',
      '--no-first-run',
      '--disable-background-networking',
      '--disable-component-update',
      '--disable-sync',
    ],
    viewport: {width: 960, height: 720},
  });
  const page = context.pages()[0] ?? (await context.newPage());
  const errors = [];
  page.on('pageerror', (error) => errors.push(error));
  // Console errors (three.js warnings every frame) and missing files (a favicon) count too.
  page.on('console', (message) => {
    if (message.type() === 'error') errors.push(`console: ${message.text()}`);
  });
  page.on('response', (response) => {
    if (response.status() === 404) errors.push(`404: ${response.url()}`);
  });
  await page.goto(url);
  await page.evaluate(() => window.spacewarp.ready);
  return {
    page,
    errors,
    async close() {
      await context.close();
      rmSync(userDataDir, {recursive: true, force: true});
    },
  };
}

/**
 * The page's typed arrays come back from page.evaluate as plain arrays. positions() are world
 * positions in double: the drawn float32 offsets plus the scene's origin.
 */
export const positions = async (page) =>
    Float64Array.from(await page.evaluate(() => Array.from(window.spacewarp.positions())));
export const pose = async (page) =>
    Float64Array.from(await page.evaluate(() => Array.from(window.spacewarp.pose())));

/** The "v x y z" lines of an OBJ file, flattened. */
export function objVertices(path) {
  const out = [];
  for (const line of readFileSync(path, 'utf8').split('\n')) {
    if (line.startsWith('v ')) out.push(...line.trim().split(/\s+/).slice(1, 4).map(Number));
  }
  return Float64Array.from(out);
}

/** Largest |a_i − b_i| over the arrays (Infinity when their lengths differ). */
export function maxDifference(a, b) {
  if (a.length !== b.length) return Infinity;
  let worst = 0;
  for (let i = 0; i < a.length; ++i) worst = Math.max(worst, Math.abs(a[i] - b[i]));
  return worst;
}

/** The model's size: the largest extent of its bounding box (flat x, y, z triples). */
export function extent(a) {
  let size = 0;
  for (let c = 0; c < 3; ++c) {
    let lo = Infinity;
    let hi = -Infinity;
    for (let i = c; i < a.length; i += 3) (lo = Math.min(lo, a[i])), (hi = Math.max(hi, a[i]));
    size = Math.max(size, hi - lo);
  }
  return size;
}

/** Writes a copy of an OBJ file with every vertex moved by `offset` ([x, y, z]), in double. */
export function shiftedObj(from, to, offset) {
  const lines = readFileSync(from, 'utf8').split('\n').map((line) => {
    if (!line.startsWith('v ')) return line;
    const xyz = line.trim().split(/\s+/).slice(1, 4).map(Number);
    return `v ${xyz.map((x, c) => x + offset[c]).join(' ')}`;
  });
  writeFileSync(to, lines.join('\n'));
}

/**
 * Decodes an 8-bit, non-interlaced RGB or RGBA PNG (what a canvas gives) into
 * { width, height, rgba: Uint8Array }.
 */
export function decodePng(bytes) {
  const signature = [137, 80, 78, 71, 13, 10, 26, 10];
  if (!signature.every((b, i) => bytes[i] === b)) throw new Error('not a PNG');
  let offset = 8;
  let width = 0;
  let height = 0;
  let colourType = 0;
  const data = [];
  while (offset < bytes.length) {
    const length = bytes.readUInt32BE(offset);
    const type = bytes.toString('latin1', offset + 4, offset + 8);
    const chunk = bytes.subarray(offset + 8, offset + 8 + length);
    if (type === 'IHDR') {
      width = chunk.readUInt32BE(0);
      height = chunk.readUInt32BE(4);
      colourType = chunk[9];
      if (chunk[8] !== 8 || (colourType !== 2 && colourType !== 6) || chunk[12] !== 0) {
        throw new Error(`unsupported PNG: depth ${chunk[8]}, colour type ${colourType}, interlace ${
            chunk[12]}`);
      }
    } else if (type === 'IDAT') {
      data.push(chunk);
    }
    offset += 12 + length;
  }
  const channels = colourType === 6 ? 4 : 3;
  const raw = inflateSync(Buffer.concat(data));
  const stride = width * channels;
  const pixels = new Uint8Array(stride * height);
  for (let y = 0; y < height; ++y) {
    const filter = raw[y * (stride + 1)];
    const row = raw.subarray(y * (stride + 1) + 1, (y + 1) * (stride + 1));
    for (let x = 0; x < stride; ++x) {
      const a = x >= channels ? pixels[y * stride + x - channels] : 0;
      const b = y > 0 ? pixels[(y - 1) * stride + x] : 0;
      const c = x >= channels && y > 0 ? pixels[(y - 1) * stride + x - channels] : 0;
      let predictor = 0;
      if (filter === 1)
        predictor = a;
      else if (filter === 2)
        predictor = b;
      else if (filter === 3)
        predictor = (a + b) >> 1;
      else if (filter === 4) {
        const p = a + b - c;
        const pa = Math.abs(p - a);
        const pb = Math.abs(p - b);
        const pc = Math.abs(p - c);
        predictor = pa <= pb && pa <= pc ? a : pb <= pc ? b : c;
      }
      pixels[y * stride + x] = (row[x] + predictor) & 255;
    }
  }
  const rgba = new Uint8Array(4 * width * height);
  for (let i = 0; i < width * height; ++i) {
    for (let k = 0; k < 3; ++k) rgba[4 * i + k] = pixels[channels * i + k];
    rgba[4 * i + 3] = channels === 4 ? pixels[channels * i + 3] : 255;
  }
  return {width, height, rgba};
}

export function distinctColours(image) {
  const seen = new Set();
  for (let i = 0; i < image.rgba.length; i += 4)
    seen.add((image.rgba[i] << 16) | (image.rgba[i + 1] << 8) | image.rgba[i + 2]);
  return seen.size;
}

/** Pixels that differ between two images of the same size by more than 8 in some channel. */
export function differingPixels(a, b) {
  let count = 0;
  for (let i = 0; i < a.rgba.length; i += 4) {
    if (Math.max(
            Math.abs(a.rgba[i] - b.rgba[i]), Math.abs(a.rgba[i + 1] - b.rgba[i + 1]),
            Math.abs(a.rgba[i + 2] - b.rgba[i + 2])) > 8)
      ++count;
  }
  return count;
}

/** Pixels of a saturated red (folds), which neither the plain model nor the controls have. */
export function redPixels(image) {
  let count = 0;
  for (let i = 0; i < image.rgba.length; i += 4) {
    if (image.rgba[i] > 120 && image.rgba[i + 1] < 50 && image.rgba[i + 2] < 50) ++count;
  }
  return count;
}
