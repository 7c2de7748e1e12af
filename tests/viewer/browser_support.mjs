// SPDX-License-Identifier: Apache-2.0
// What the browser tests share (viewer_browser.test.mjs, story_browser.test.mjs): the command
// line, Debian's Chromium launched headless through playwright-core, a toonforce started with a
// viewer (resolving with the URL it serves), and a page that records every error it meets.
import { spawn } from 'node:child_process';
import { createRequire } from 'node:module';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import { fileURLToPath } from 'node:url';

export const source = path.resolve(path.dirname(fileURLToPath(import.meta.url)), '../..');
const require = createRequire(path.join(source, 'tools/viewer/package.json'));
const { chromium } = require('playwright-core');

export function arg(name, fallback) {
  const i = process.argv.indexOf(name);
  return i > 0 && i + 1 < process.argv.length ? process.argv[i + 1] : fallback;
}
export const binary = path.resolve(arg('--binary', path.join(source, 'build/debug/bin/toonforce')));
export const outDir = path.resolve(arg('--out', path.join(os.tmpdir(), 'toonforce-viewer-screenshots')));
const executablePath = process.env.CHROMIUM ?? '/usr/bin/chromium';
fs.mkdirSync(outDir, { recursive: true });

// The flags the machine's notes ask for: no sandbox as root, no GPU, nothing reaching out.
const CHROMIUM_ARGS = [
  '--headless',
  '--no-sandbox',
  '--disable-gpu',
  '--no-first-run',
  '--disable-background-networking',
  '--disable-component-update',
  '--disable-sync',
  '--disable-quic',
];

/** A headless Chromium with a fresh profile; close() removes the profile too. */
export async function launchBrowser() {
  const userDataDir = fs.mkdtempSync(path.join(os.tmpdir(), 'toonforce-chromium-'));
  const context = await chromium.launchPersistentContext(userDataDir, {
    executablePath,
    headless: true,
    args: CHROMIUM_ARGS,
    viewport: { width: 1280, height: 800 },
  });
  return {
    context,
    close: async () => {
      await context.close();
      fs.rmSync(userDataDir, { recursive: true, force: true });
    },
  };
}

/** Starts `toonforce ARGS` and resolves with its viewer URL and the process. */
export function startToonforce(args) {
  const child = spawn(binary, args, { cwd: source, stdio: ['ignore', 'pipe', 'pipe'] });
  let stderr = '';
  let stdout = '';
  child.stdout.on('data', (d) => (stdout += d));
  const url = new Promise((resolve, reject) => {
    const timer = setTimeout(() => reject(new Error(`no viewer URL from toonforce ${args.join(' ')}:\n${stderr}`)), 30000);
    child.stderr.on('data', (d) => {
      stderr += d;
      const m = /viewer: (http:\/\/[^ ]+\/)/.exec(stderr);
      if (m) {
        clearTimeout(timer);
        resolve(m[1]);
      }
    });
    child.on('exit', (code) => reject(new Error(`toonforce exited (${code}) before serving:\n${stderr}`)));
  });
  const exited = new Promise((resolve) => child.on('exit', (code, signal) => resolve({ code, signal })));
  return { child, url, exited, output: () => ({ stdout, stderr }) };
}

/** Opens the page and records every console error, page error and failed request. */
export async function openPage(context, url) {
  const page = await context.newPage();
  const errors = [];
  page.on('console', (m) => {
    if (m.type() === 'error') errors.push(`console: ${m.text()}`);
  });
  page.on('pageerror', (e) => errors.push(`page error: ${e.message}`));
  page.on('requestfailed', (r) => errors.push(`request failed: ${r.url()} ${r.failure()?.errorText}`));
  page.on('response', (r) => {
    if (r.status() >= 400) errors.push(`HTTP ${r.status()}: ${r.url()}`);
  });
  await page.goto(url);
  return { page, errors };
}
