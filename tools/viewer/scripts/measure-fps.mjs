// SPDX-License-Identifier: Apache-2.0
// Measures the viewer page's frame rate while a 1 kHz `toonforce run` streams to it: headless
// Debian Chromium (software rendering: --disable-gpu), the page following the run live.
//   node tools/viewer/scripts/measure-fps.mjs --binary build/release/bin/toonforce [--seconds 10]
// Prints the page's frames per second each second, their median and minimum, and how many
// telemetry frames reached the page and how many it missed. A benchmark, not a test.
import { spawn } from 'node:child_process';
import { createRequire } from 'node:module';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import { fileURLToPath } from 'node:url';

const root = path.resolve(path.dirname(fileURLToPath(import.meta.url)), '../../..');
const require = createRequire(path.join(root, 'tools/viewer/package.json'));
const { chromium } = require('playwright-core');
const arg = (name, fallback) => {
  const i = process.argv.indexOf(name);
  return i > 0 ? process.argv[i + 1] : fallback;
};
const binary = path.resolve(arg('--binary', path.join(root, 'build/release/bin/toonforce')));
const seconds = Number(arg('--seconds', '10'));
const rate = Number(arg('--rate', '1000'));

const run = spawn(binary, ['run', '--device', 'sim', '--scene', 'scenes/cartoon_wall.toml', '--rate', String(rate),
  '--duration', String(seconds + 8), '--allow-non-rt', '--no-mlock', '--view', '0', '--quiet'], { cwd: root });
let stderr = '';
const url = await new Promise((resolve, reject) => {
  run.stderr.on('data', (d) => {
    stderr += d;
    const m = /viewer: (http:\/\/[^ ]+\/)/.exec(stderr);
    if (m) resolve(m[1]);
  });
  run.on('exit', (code) => reject(new Error(`toonforce run exited (${code}):\n${stderr}`)));
});
const userDataDir = fs.mkdtempSync(path.join(os.tmpdir(), 'toonforce-fps-'));
const context = await chromium.launchPersistentContext(userDataDir, {
  executablePath: process.env.CHROMIUM ?? '/usr/bin/chromium',
  headless: true,
  viewport: { width: 1280, height: 800 },
  args: ['--headless', '--no-sandbox', '--disable-gpu', '--no-first-run', '--disable-background-networking',
    '--disable-component-update', '--disable-sync', '--disable-quic'],
});
const page = await context.newPage();
await page.goto(url);
await page.waitForFunction(() => window.toonforceViewer.snapshot().frames > 0, null, { timeout: 20000 });
await page.waitForTimeout(3000); // warm up
const samples = [];
const start = await page.evaluate(() => window.toonforceViewer.snapshot());
for (let s = 0; s < seconds; ++s) {
  await page.waitForTimeout(1000);
  const snap = await page.evaluate(() => window.toonforceViewer.snapshot());
  samples.push(snap.fps);
  console.log(`t ${s + 1} s: ${snap.fps.toFixed(1)} fps, ${snap.frames} telemetry frames, following ${snap.following}`);
}
const end = await page.evaluate(() => window.toonforceViewer.snapshot());
const sorted = [...samples].sort((a, b) => a - b);
const frames = end.frames - start.frames;
console.log(`page frame rate at ${rate} Hz telemetry over ${seconds} s: median ${sorted[sorted.length >> 1].toFixed(1)} fps, ` +
  `min ${sorted[0].toFixed(1)} fps; telemetry ${(frames / seconds).toFixed(0)} frames/s reached the page, ` +
  `${end.missing} dropped for it`);
await context.close();
fs.rmSync(userDataDir, { recursive: true, force: true });
run.kill('SIGTERM');
await new Promise((r) => run.on('exit', r));
process.exit(0);
