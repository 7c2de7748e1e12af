// SPDX-License-Identifier: Apache-2.0
// The viewer page in a real browser: Debian's Chromium, headless, driven by playwright-core,
// against `toonforce sim --view` of each of the paper's scenes (the six figure scenarios of
// tools/sim/src/figures.cpp). For each: the page loads without a console error or a failed
// request, follows the run live and shows what the physics says (the cliff "fallen" after the
// slow crossing and "bridged" after the fast one; the force arrow out of the wall in contact;
// friction against the stroke, the super-slippery surface along it; the impact transient), and
// a screenshot is kept. Then the safety rules as a browser meets them: another origin cannot
// open the socket, a message sent on it closes it, and paths outside the page's files are 404.
//
//   node tests/viewer/viewer_browser.test.mjs --binary build/debug/bin/toonforce [--out DIR]
//
// Run through tests/viewer/run-browser-tests, which CTest calls (it skips, exit 77, only when
// Chromium, node or the npm packages are missing outside CI).
import { test, after, before } from 'node:test';
import assert from 'node:assert/strict';
import fs from 'node:fs';
import http from 'node:http';
import os from 'node:os';
import path from 'node:path';
import { launchBrowser, openPage as openIn, outDir, startToonforce } from './browser_support.mjs';

// How long a wait for the page may take: generous, since it only bounds a failure. A run of the
// ASan build beside other tests on two cores once took past 60 s to reach a state it reaches in
// seconds alone; the CTest timeout (600 s) still bounds the whole suite.
const kWaitMs = 180000;

let browser;
let context;

before(async () => {
  browser = await launchBrowser();
  context = browser.context;
});

after(async () => {
  if (browser) await browser.close();
});

const openPage = (url) => openIn(context, url);

const snapshot = (page) => page.evaluate(() => window.toonforceViewer.snapshot());

/** Moves the time slider to frame i, as a person dragging it would. */
async function scrubTo(page, i) {
  await page.evaluate((index) => {
    const scrub = document.getElementById('scrub');
    scrub.value = String(index);
    scrub.dispatchEvent(new Event('input', { bubbles: true }));
  }, i);
  // Two animation frames: the page has drawn the new moment.
  await page.evaluate(() => new Promise((r) => requestAnimationFrame(() => requestAnimationFrame(r))));
}

const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];

const SCENARIOS = [
  { name: 'fig1_realistic', scene: 'scenes/realistic_friction.toml', script: 'scenes/hands/stroke.toml', duration: 1.6 },
  { name: 'fig1_slippery', scene: 'scenes/slippery.toml', script: 'scenes/hands/stroke.toml', duration: 1.6 },
  { name: 'fig3_wall', scene: 'scenes/wall.toml', script: 'scenes/hands/strike.toml', duration: 1.0 },
  { name: 'fig3_cartoon_wall', scene: 'scenes/cartoon_wall.toml', script: 'scenes/hands/strike.toml', duration: 1.0 },
  { name: 'fig4_fast', scene: 'scenes/cliff.toml', script: 'scenes/hands/cross_fast.toml', duration: 1.3 },
  { name: 'fig4_slow', scene: 'scenes/cliff.toml', script: 'scenes/hands/cross_slow.toml', duration: 1.4 },
];

/** Runs one scenario live in the page; `check` asserts on the page once the run is over. */
async function scenario(s, check) {
  const trace = path.join(os.tmpdir(), `toonforce-viewer-${process.pid}-${s.name}.csv`);
  const run = startToonforce([
    'sim', '--scene', s.scene, '--script', s.script, '--duration', String(s.duration), '--trace', trace,
    '--view', '0', '--quiet',
  ]);
  try {
    const url = await run.url;
    assert.match(url, /^http:\/\/127\.0\.0\.1:\d+\/$/, 'served on the loopback address by default');
    const { page, errors } = await openPage(url);
    // Live: the simulation waits for the page, then runs paced to the wall clock. The hello
    // says so; 'live' itself lasts only as long as the run (1-2 s), which a page polled on a
    // loaded machine can miss entirely, so the wait is on the hello, which stays.
    await page.waitForFunction(() => window.toonforceViewer.snapshot().live !== null, null, { timeout: kWaitMs });
    const hello = await snapshot(page);
    assert.equal(hello.live, true, 'the server says the run is live');
    assert.notEqual(hello.connection, 'closed', 'the socket was not closed under the page');
    await page.waitForFunction(() => window.toonforceViewer.snapshot().frames > 0, null, { timeout: kWaitMs });
    await page.waitForFunction(() => window.toonforceViewer.snapshot().ended, null, { timeout: kWaitMs });
    await page.evaluate(() => new Promise((r) => requestAnimationFrame(() => requestAnimationFrame(r))));
    const end = await snapshot(page);
    assert.equal(end.frames, Math.round(s.duration * 1000), 'every tick of the run reached the page');
    assert.equal(end.missing, 0, 'no frame dropped on loopback');
    await check(page, end);
    assert.deepEqual(errors, [], 'no console errors or failed requests');
    await page.close();
    return url;
  } finally {
    run.child.kill('SIGTERM');
    const { code } = await run.exited;
    assert.equal(code, 0, `toonforce sim exits cleanly on SIGTERM after serving:\n${run.output().stderr}`);
    fs.rmSync(trace, { force: true });
  }
}

const screenshot = (page, name) => page.screenshot({ path: path.join(outDir, `viewer_${name}.png`) });

test('fig4_slow: slowing over the gap, the character falls and the page says "fallen"', async () => {
  await scenario(SCENARIOS[5], async (page, end) => {
    assert.equal(end.cliff, 'fallen');
    assert.ok(end.hip[2] < -0.002, `the HIP is down in the gap (z = ${end.hip[2]})`);
    await screenshot(page, 'fig4_slow');
    // Scrubbing back to the start shows the ground holding again.
    await scrubTo(page, 0);
    assert.equal((await snapshot(page)).cliff, 'supported');
  });
});

test('fig4_fast: crossing decisively, the ground holds and the page says "bridged"', async () => {
  await scenario(SCENARIOS[4], async (page, end) => {
    assert.equal(end.cliff, 'bridged');
    const fell = await page.evaluate(() => window.toonforceViewer.findFrame('cliff1.state', '==', 1));
    assert.equal(fell, -1, 'the cliff never dropped the HIP');
    // Over the gap, mid-crossing, the arrow holds the HIP up (out of the ground, +z).
    const over = await page.evaluate(() => window.toonforceViewer.findFrame('x', '>', 0.01));
    await scrubTo(page, over);
    const mid = await snapshot(page);
    assert.equal(mid.cliff, 'bridged');
    if (mid.contact === 'yes') assert.ok(mid.arrow.direction[2] > 0.9, 'the ground pushes up over the gap');
    await screenshot(page, 'fig4_fast');
  });
});

test('fig3_wall: in contact the force arrow points out of the wall', async () => {
  await scenario(SCENARIOS[2], async (page) => {
    const peak = await page.evaluate(() => window.toonforceViewer.argmax('fz'));
    await scrubTo(page, peak);
    const s = await snapshot(page);
    assert.equal(s.contact, 'yes');
    assert.ok(s.arrow.visible, 'the arrow is drawn');
    assert.ok(dot(s.arrow.direction, [0, 0, 1]) > 0.95, `arrow ${s.arrow.direction} along the wall normal +z`);
    assert.ok(s.hip[2] < 0, 'the HIP is inside the wall');
    await screenshot(page, 'fig3_wall');
  });
});

test('fig3_cartoon_wall: the impact transient shows, recoil and oscillation', async () => {
  await scenario(SCENARIOS[3], async (page) => {
    const hit = await page.evaluate(() => window.toonforceViewer.findFrame('surface1.impact_t', '>', 0.015));
    assert.ok(hit >= 0, 'an impact transient ran');
    await scrubTo(page, hit);
    const s = await snapshot(page);
    assert.equal(s.impact, 'running');
    assert.ok(s.arrow.visible && s.arrow.direction[2] > 0.9, 'the recoil throws the stylus back out of the wall');
    await screenshot(page, 'fig3_cartoon_wall');
  });
});

for (const [index, expectAlong] of [[0, false], [1, true]]) {
  const s = SCENARIOS[index];
  test(`${s.name}: the tangential force ${expectAlong ? 'pushes along' : 'opposes'} the stroke`, async () => {
    await scenario(s, async (page) => {
      const fastest = await page.evaluate(() => window.toonforceViewer.argmax('vx', 'contact'));
      await scrubTo(page, fastest);
      const snap = await snapshot(page);
      assert.equal(snap.contact, 'yes', 'stroking on the surface');
      const along = snap.arrow.direction[0];
      if (expectAlong) assert.ok(along > 0.05, `super-slippery: force along +x (arrow ${snap.arrow.direction})`);
      else assert.ok(along < -0.05, `friction: force against +x (arrow ${snap.arrow.direction})`);
      assert.ok(snap.arrow.direction[2] > 0, 'and out of the surface');
      await screenshot(page, s.name);
    });
  });
}

test('safety: another origin cannot open the socket; a message closes it; only the page is served', async () => {
  const trace = path.join(os.tmpdir(), `toonforce-viewer-${process.pid}-safety.csv`);
  const run = startToonforce(['sim', '--scene', 'scenes/wall.toml', '--script', 'scenes/hands/strike.toml',
    '--duration', '0.5', '--trace', trace, '--view', '0', '--view-pace', '0', '--quiet']);
  // A page from another origin (another local server), trying the viewer's socket.
  const evil = http.createServer((req, res) => {
    res.writeHead(200, { 'content-type': 'text/html' });
    res.end('<!doctype html><link rel="icon" href="data:,"><title>other</title>');
  });
  await new Promise((r) => evil.listen(0, '127.0.0.1', r));
  try {
    const url = await run.url;
    const port = new URL(url).port;
    const { page, errors } = await openPage(url);
    await page.waitForFunction(() => window.toonforceViewer.snapshot().ended, null, { timeout: kWaitMs });
    const before = await snapshot(page);

    const other = await context.newPage();
    await other.goto(`http://127.0.0.1:${evil.address().port}/`);
    const outcome = await other.evaluate(
      (p) =>
        new Promise((resolve) => {
          const ws = new WebSocket(`ws://127.0.0.1:${p}/ws`);
          ws.onopen = () => resolve('opened');
          ws.onclose = (e) => resolve(`closed ${e.code}`);
        }),
      port,
    );
    assert.equal(outcome, 'closed 1006', 'the upgrade from another origin is refused');
    await other.close();

    // The viewer's own page may connect, but the socket is read-only: a message closes it.
    const closed = await page.evaluate(
      () =>
        new Promise((resolve) => {
          const ws = new WebSocket(`ws://${location.host}/ws`);
          ws.onmessage = () => ws.send(JSON.stringify({ type: 'force', force: [0, 0, 8] }));
          ws.onclose = (e) => resolve(e.code);
        }),
    );
    assert.equal(closed, 1008, 'closed with policy violation');
    const afterSnap = await snapshot(page);
    assert.equal(afterSnap.frames, before.frames, 'the run is what it was');

    // Nothing but the page's own files: the usual traversal spellings are all 404.
    const get = (p) =>
      new Promise((resolve, reject) => {
        const req = http.request({ host: '127.0.0.1', port, path: p, method: 'GET' }, (res) => {
          res.resume();
          resolve(res.statusCode);
        });
        req.on('error', reject);
        req.end();
      });
    for (const p of ['/../../../../etc/passwd', '/%2e%2e/%2e%2e/etc/passwd', '//etc/passwd', '/assets/../../CMakeLists.txt',
      '/..%2f..%2fCMakeLists.txt', '/index.html/../../README.md', '/assets/']) {
      assert.equal(await get(p), 404, `GET ${p}`);
    }
    assert.equal(await get('/'), 200);
    await page.close();
    assert.deepEqual(errors.filter((e) => !e.includes('1008')), [], 'no console errors on the viewer page');
  } finally {
    evil.close();
    run.child.kill('SIGTERM');
    await run.exited;
    fs.rmSync(trace, { force: true });
  }
});

test('toonforce view: a recorded trace plays, pauses and scrubs', async () => {
  const run = startToonforce(['view', 'docs/figures/fig4_slow.csv', '--scene', 'scenes/cliff.toml', '--port', '0']);
  try {
    const { page, errors } = await openPage(await run.url);
    await page.waitForFunction(() => window.toonforceViewer.snapshot().frames === 1400, null, { timeout: kWaitMs });
    const first = await snapshot(page);
    assert.equal(first.connection, 'recording');
    assert.equal(first.following, false, 'a recording is not live');
    // It plays on its own from the start. Back to the start (scrubbing pauses), slowed to 0.1x
    // so a loaded machine cannot reach the end before the pause below, then play and pause.
    await scrubTo(page, 0);
    assert.equal((await snapshot(page)).playing, false, 'scrubbing pauses');
    await page.selectOption('#speed', '0.1');
    await page.click('#play');
    await page.waitForFunction(() => window.toonforceViewer.snapshot().t > 0.01, null, { timeout: kWaitMs });
    assert.equal((await snapshot(page)).playing, true);
    await page.click('#play');
    const paused = await snapshot(page);
    assert.equal(paused.playing, false);
    await page.waitForTimeout(300);
    assert.equal((await snapshot(page)).t, paused.t, 'paused: time stands still');
    // Scrub to the end: the slow crossing has fallen; back to the start: supported.
    await scrubTo(page, 1399);
    assert.equal((await snapshot(page)).cliff, 'fallen');
    await scrubTo(page, 0);
    const start = await snapshot(page);
    assert.equal(start.cliff, 'supported');
    assert.equal(start.t, 0);
    // Play again from there.
    await page.click('#play');
    await page.waitForFunction(() => window.toonforceViewer.snapshot().t > 0.01, null, { timeout: kWaitMs });
    assert.deepEqual(errors, []);
    await page.close();
  } finally {
    run.child.kill('SIGTERM');
    const { code } = await run.exited;
    assert.equal(code, 0);
  }
});

test("toonforce view: a program's own effect shows its values by name (no library edit)", async () => {
  // A trace as examples/scene_with_own_effect.cpp writes it: the library's surface and the
  // program's [[magnet]], whose values the viewer has never heard of.
  const trace = path.join(os.tmpdir(), `toonforce-viewer-${process.pid}-magnet.csv`);
  const rows = ['t,x,y,z,vx,vy,vz,fx,fy,fz,contact,surface1.contact,surface1.impact_t,magnet1.captured,magnet1.distance'];
  for (let k = 0; k < 200; ++k) {
    const captured = k >= 100 ? 1 : 0;
    const distance = captured ? 0.004 : 0.02;
    rows.push(`${k / 1000},${distance},0,0,0,0,0,0,0,0,${captured},0,nan,${captured},${distance}`);
  }
  fs.writeFileSync(trace, rows.join('\n') + '\n');
  const run = startToonforce(['view', trace, '--port', '0']);
  try {
    const { page, errors } = await openPage(await run.url);
    await page.waitForFunction(() => window.toonforceViewer.snapshot().frames === 200, null, { timeout: kWaitMs });
    await scrubTo(page, 50);
    const before = await snapshot(page);
    assert.equal(before.effects.magnet1, 'captured 0 · distance 0.02', 'free: the values as the trace has them');
    assert.match(before.effects.surface1, /^contact 0 · impact_t –$/);
    await scrubTo(page, 150);
    const after = await snapshot(page);
    assert.equal(after.effects.magnet1, 'captured 1 · distance 0.004');
    assert.equal(after.contact, 'yes', 'the effect says the HIP touches it: the page shows contact');
    assert.deepEqual(errors, []);
    await page.close();
  } finally {
    run.child.kill('SIGTERM');
    await run.exited;
    fs.rmSync(trace, { force: true });
  }
});
