// SPDX-License-Identifier: Apache-2.0
// A world scene (several devices in one world: scenes/two_players.toml) in the viewer page, in
// Debian's Chromium, headless, driven by playwright-core: `toonforce sim --view` of the world live,
// then `toonforce view` of its trace, then `toonforce run --device sim --view` of the world. The
// page draws every device's HIP (named, in its own colour) where the trace has it, the ball
// with the scene's radius, the coupling between the two HIPs, and each device's commanded force
// turned into the world frame: pressing the ball from both sides, each is pushed back away from
// the middle. No console error or failed request.
//
//   node tests/viewer/world_browser.test.mjs --binary build/release/bin/toonforce [--out DIR]
//
// Run through tests/viewer/run-browser-tests --suite world (CTest: world_browser).
import { test, after, before } from 'node:test';
import assert from 'node:assert/strict';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import { launchBrowser, openPage as openIn, outDir, startToonforce } from './browser_support.mjs';

const kWaitMs = 180000; // bounds a failure only (as viewer_browser.test.mjs)
const kDuration = 1.3; // s: the hands wait 0.3 s, reach for 0.6 s, then press the ball
const kTrace = path.join(os.tmpdir(), `toonforce-world-${process.pid}.csv`);

let browser;
let context;

before(async () => {
  browser = await launchBrowser();
  context = browser.context;
});

after(async () => {
  if (browser) await browser.close();
  fs.rmSync(kTrace, { force: true });
});

const snapshot = (page) => page.evaluate(() => window.toonforceViewer.snapshot());
const twoFrames = (page) => page.evaluate(() => new Promise((r) => requestAnimationFrame(() => requestAnimationFrame(r))));

async function scrubTo(page, i) {
  await page.evaluate((index) => {
    const scrub = document.getElementById('scrub');
    scrub.value = String(index);
    scrub.dispatchEvent(new Event('input', { bubbles: true }));
  }, i);
  await twoFrames(page);
}

/** The trace's last row, by column name. */
function lastRow(file) {
  const lines = fs.readFileSync(file, 'utf8').trim().split('\n');
  const names = lines[0].split(',');
  const values = lines[lines.length - 1].split(',').map(Number);
  return Object.fromEntries(names.map((n, i) => [n, values[i]]));
}

/** What every world page shows, whatever its source: both devices drawn where the frames put
 *  them, named and apart in colour; the ball; the coupling; the plots by device. */
async function checkWorld(page) {
  await page.waitForFunction(
    () => {
      const w = window.toonforceViewer.snapshot().world;
      return w !== null && w.devices.length > 0 && w.devices.every((d) => d.drawn);
    },
    null,
    { timeout: kWaitMs },
  );
  const s = await snapshot(page);
  assert.deepEqual(s.world.devices.map((d) => d.name), ['left', 'right'], 'every device of the scene, by name');
  assert.notEqual(s.world.devices[0].colour, s.world.devices[1].colour, 'each device in its own colour');
  for (const d of s.world.devices) assert.ok(d.panel.startsWith('HIP ['), `${d.name}'s row lists its HIP: ${d.panel}`);
  assert.equal(s.world.ballRadius, 0.015, "the ball has the scene's radius");
  assert.ok(s.world.ball !== null, 'the ball is drawn');
  assert.deepEqual(s.world.couplings, [true], 'the coupling is drawn between the two HIPs');
  assert.equal(s.world.held, 'none', 'nothing holds the devices');
  assert.deepEqual(s.world.plotLabels, ['left x', 'left |F|', 'right x', 'right |F|'], 'plots named by device');
  return s;
}

/** Pressing the ball from both sides (the last frame): each HIP is pushed back away from the
 *  middle, in the world frame; right's own frame is turned half a turn, so its force must be
 *  turned too for its arrow to point +x. */
function checkPress(s) {
  const [left, right] = s.world.devices;
  assert.ok(left.hip[0] < s.world.ball[0] && s.world.ball[0] < right.hip[0], 'left, ball, right along x');
  assert.ok(left.arrow.visible && right.arrow.visible, 'both forces drawn');
  assert.ok(left.arrow.direction[0] < -0.5, `left is pushed back to -x: ${left.arrow.direction}`);
  assert.ok(right.arrow.direction[0] > 0.5, `right is pushed back to +x: ${right.arrow.direction}`);
}

test('sim --view of a world: live, every device drawn by name, the ball and the coupling', async () => {
  const run = startToonforce([
    'sim', '--scene', 'scenes/two_players.toml', '--script', 'left=scenes/hands/left_push.toml',
    '--script', 'right=scenes/hands/right_push.toml', '--duration', String(kDuration), '--trace', kTrace,
    '--view', '0', '--quiet',
  ]);
  try {
    const url = await run.url;
    const { page, errors } = await openIn(context, url);
    await page.waitForFunction(() => window.toonforceViewer.snapshot().live !== null, null, { timeout: kWaitMs });
    assert.equal((await snapshot(page)).live, true, 'the server says the run is live');
    await checkWorld(page);
    await page.waitForFunction(() => window.toonforceViewer.snapshot().ended, null, { timeout: kWaitMs });
    await twoFrames(page);
    const end = await snapshot(page);
    assert.equal(end.frames, Math.round(kDuration * 1000), 'every tick of the world reached the page');
    assert.equal(end.missing, 0);
    const row = lastRow(kTrace);
    for (const [k, d] of end.world.devices.entries()) {
      for (const [a, axis] of ['x', 'y', 'z'].entries()) {
        assert.ok(Math.abs(d.hip[a] - row[`${d.name}.${axis}`]) < 1e-9, `${d.name}.${axis} as the trace has it (device ${k})`);
      }
    }
    checkPress(end);
    await page.screenshot({ path: path.join(outDir, 'viewer_world.png') });
    assert.deepEqual(errors, [], 'no console errors or failed requests');
    await page.close();
  } finally {
    run.child.kill('SIGTERM');
    const { code } = await run.exited;
    assert.equal(code, 0, `toonforce sim exits cleanly on SIGTERM after serving:\n${run.output().stderr}`);
  }
});

test("view of a world's trace: a recording of every device, scrubbed back to the start", async () => {
  assert.ok(fs.existsSync(kTrace), 'the trace of the test before');
  const run = startToonforce(['view', kTrace, '--scene', 'scenes/two_players.toml', '--port', '0']);
  try {
    const { page, errors } = await openIn(context, await run.url);
    await page.waitForFunction(() => window.toonforceViewer.snapshot().frames === 1300, null, { timeout: kWaitMs });
    assert.equal((await snapshot(page)).live, false, 'a recording');
    await checkWorld(page);
    await scrubTo(page, 1299);
    checkPress(await snapshot(page));
    await scrubTo(page, 0);
    const start = await snapshot(page);
    // At the start each hand is at its device's centre: the devices sit at x = -4 and +4 cm.
    assert.ok(Math.abs(start.world.devices[0].hip[0] + 0.04) < 0.002, `left at -4 cm: ${start.world.devices[0].hip}`);
    assert.ok(Math.abs(start.world.devices[1].hip[0] - 0.04) < 0.002, `right at +4 cm: ${start.world.devices[1].hip}`);
    assert.deepEqual(errors, [], 'no console errors or failed requests');
    await page.close();
  } finally {
    run.child.kill('SIGTERM');
    await run.exited;
  }
});

test('run --view of a world: the run process hands every frame to the page, by device', async () => {
  const trace = path.join(os.tmpdir(), `toonforce-world-run-${process.pid}.csv`);
  const run = startToonforce([
    'run', '--device', 'sim', '--scene', 'scenes/two_players.toml', '--script', 'left=scenes/hands/left_push.toml',
    '--script', 'right=scenes/hands/right_push.toml', '--duration', String(kDuration), '--trace', trace,
    '--allow-non-rt', '--no-mlock', '--view', '0', '--quiet',
  ]);
  try {
    const { page, errors } = await openIn(context, await run.url);
    await checkWorld(page);
    await page.waitForFunction(() => window.toonforceViewer.snapshot().ended, null, { timeout: kWaitMs });
    await twoFrames(page);
    const rows = fs.readFileSync(trace, 'utf8').trim().split('\n').length - 1;
    const end = await snapshot(page);
    // A page that came late gets the history first: every row of the trace, none lost.
    assert.equal(end.frames, rows, 'every row of the trace reached the page');
    assert.equal(end.missing, 0);
    const row = lastRow(trace);
    for (const d of end.world.devices) {
      for (const [a, axis] of ['x', 'y', 'z'].entries()) {
        assert.ok(Math.abs(d.hip[a] - row[`${d.name}.${axis}`]) < 1e-9, `${d.name}.${axis} as the trace has it`);
      }
    }
    // The last row is the shut-down tick (zero force): the press shows on the one before.
    await scrubTo(page, end.frames - 2);
    checkPress(await snapshot(page));
    assert.deepEqual(errors, [], 'no console errors or failed requests');
    await page.close();
  } finally {
    run.child.kill('SIGTERM');
    await run.exited;
    fs.rmSync(trace, { force: true });
  }
});
