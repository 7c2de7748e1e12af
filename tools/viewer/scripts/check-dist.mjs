// SPDX-License-Identifier: Apache-2.0
// Rebuilds the page into a temporary directory and compares it with the committed dist/: the
// committed build must be exactly what the committed sources and locked packages give, so it
// cannot go stale. Exit 1 with the differences; `npm run build` updates dist/.
import { build } from 'vite';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import { fileURLToPath } from 'node:url';

const root = path.resolve(path.dirname(fileURLToPath(import.meta.url)), '..');
const out = fs.mkdtempSync(path.join(os.tmpdir(), 'toonforce-dist-'));
await build({ configFile: path.join(root, 'vite.config.js'), root: path.join(root, 'web'), logLevel: 'error', build: { outDir: out, emptyOutDir: true } });

const list = (dir) =>
  fs.readdirSync(dir, { recursive: true })
    .filter((f) => fs.statSync(path.join(dir, f)).isFile())
    .sort();
const committed = list(path.join(root, 'dist'));
const built = list(out);
const problems = [];
for (const f of built) if (!committed.includes(f)) problems.push(`missing in dist/: ${f}`);
for (const f of committed) if (!built.includes(f)) problems.push(`stale in dist/: ${f}`);
for (const f of built) {
  if (!committed.includes(f)) continue;
  if (!fs.readFileSync(path.join(out, f)).equals(fs.readFileSync(path.join(root, 'dist', f)))) problems.push(`differs: dist/${f}`);
}
fs.rmSync(out, { recursive: true, force: true });
if (problems.length) {
  console.error(`tools/viewer/dist does not match its sources (run: cd tools/viewer && npm run build, then commit dist/):\n  ${problems.join('\n  ')}`);
  process.exit(1);
}
console.log(`tools/viewer/dist matches its sources (${built.length} files)`);
