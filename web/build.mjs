// Bundles the page into OUTDIR (argument, default dist): index.html and one ES module.
// esbuild's JS API runs on Node 18 (Debian 12's) as well as newer Nodes.
import {build} from 'esbuild';
import {copyFile, mkdir} from 'node:fs/promises';
import {dirname, join, resolve} from 'node:path';
import {fileURLToPath} from 'node:url';

const here = dirname(fileURLToPath(import.meta.url));
const outDir = resolve(process.argv[2] ?? join(here, 'dist'));

await mkdir(outDir, {recursive: true});
await build({
  entryPoints: [join(here, 'src', 'main.js')],
  bundle: true,
  format: 'esm',
  target: 'es2020',
  minify: true,
  sourcemap: false,
  legalComments: 'linked',  // three.js's licence beside the bundle
  outfile: join(outDir, 'main.js'),
  logLevel: 'warning',
});
await copyFile(join(here, 'index.html'), join(outDir, 'index.html'));
