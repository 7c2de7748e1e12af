// SPDX-License-Identifier: Apache-2.0
// A study session with a person, the person played through the participant's page in a real
// browser (Debian's Chromium, headless, through playwright-core): `python3 -m toonforce.study run
// --device sim` with a scripted hand (docs/STUDIES.md, "A person at a device"). The test reads the
// page as a participant does and answers with keys and clicks, never with the page's requests:
// - nothing plays before Start: the page asks for it, no trial begins before the click (each
//   trial's started_utc in trials.jsonl), and the run's trace shows no force before the first
//   interval, though the scripted hand pressed through the floor's plane all along;
// - the experiment file's words: the Start page's instructions, each block's question, answer
//   buttons and interval instructions; rating items with their names and both anchors;
// - two-interval answers by the keys 1 and 2 (recorded as pressed), ratings by clicks (Done
//   refuses a partial rating), the Pause button (the session pauses after the trial under way
//   and goes on after Continue), the break between blocks, and Escape, which stops the session
//   with zero force and keeps every answered trial.
//
//   node tests/viewer/study_browser.test.mjs --binary build/release/bin/toonforce [--python python3]
//
// The toonforce module is the build tree's (BUILD/python beside BUILD/bin/toonforce) unless
// PYTHONPATH is set. Run through tests/viewer/run-browser-tests --suite study (CTest: study_browser).
import { test, after, before } from 'node:test';
import assert from 'node:assert/strict';
import { spawn } from 'node:child_process';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import { arg, binary, launchBrowser, openPage, source } from './browser_support.mjs';

const python = arg('--python', '/usr/bin/python3');
const SCENES = path.join(source, 'scenes');

const EXPERIMENT = `
name = "ice or not"
order = "fixed"
seed = 5
script = "${SCENES}/hands/stroke.toml"
instructions = "Hold the handle lightly. Two strokes follow, then a question."

[[condition]]
name = "floor"
scene = "${SCENES}/studies/floor.toml"

[[condition]]
name = "ice"
scene = "${SCENES}/slippery.toml"
vary = "surface1.slippery.mu"

[[condition]]
name = "friction"
scene = "${SCENES}/realistic_friction.toml"

[[block]]
name = "levels"
procedure = "constant-stimuli"
reference = "floor"
test = "ice"
levels = [1.0, 2.0, 4.0]
repetitions = 1
instructions = "Let the surface carry your hand."
question = "Which stroke slid by itself?"
answers = ["the left one", "the right one"]

[[block]]
name = "how they feel"
procedure = "rating"
conditions = ["friction", "ice"]
repetitions = 1
question = "Rate the surface you just felt."
items = [
  { name = "slippery", scale = "likert", points = 5, anchors = ["not at all", "very"] },
  { name = "playful", scale = "semantic-differential", points = 7, anchors = ["serious", "playful"] },
]
`;

// The simulated device's hand (`--hand`): a script plays once from the run's start, before Start
// and through the whole session, so this one presses 1 N downwards and strokes for two minutes
// (longer than the session): with nothing in reach it sinks below the floor's plane (z = 0), and
// whatever scene is loaded pushes back. (scenes/hands/stroke.toml lifts off after 1.4 s.)
const PRESSING_HAND = ['name = "pressing strokes"\n[hand]\nstart = [-0.03, 0.0, 0.003]\nstiffness = 100.0\n',
  '[[segment]]\ntype = "hold"\nduration = 0.2\nforce = 1.0\n',
  ...Array.from({ length: 200 }, (_, k) =>
    `[[segment]]\ntype = "stroke"\nto = [${k % 2 === 0 ? 0.03 : -0.03}, 0.0, 0.0]\nspeed = 0.1\nforce = 1.0\n`),
].join('\n');

let browser;

before(async () => {
  browser = await launchBrowser();
});

after(async () => {
  if (browser) await browser.close();
});

/** Starts the session; resolves with the page's URL once the command prints it. */
function startStudy(args) {
  const env = { ...process.env, PYTHONDONTWRITEBYTECODE: '1' };
  env.TOONFORCE_BINARY ??= binary;
  env.PYTHONPATH ??= path.join(path.dirname(binary), '..', 'python');
  const child = spawn(python, ['-m', 'toonforce.study', ...args], { cwd: source, env, stdio: ['ignore', 'pipe', 'pipe'] });
  let stderr = '';
  child.stdout.on('data', () => {});
  const exited = new Promise((resolve) => child.on('exit', (code, signal) => resolve({ code, signal })));
  const url = new Promise((resolve, reject) => {
    child.stderr.on('data', (d) => {
      stderr += d;
      const m = /participant's page: (http:\/\/\S+\/)/.exec(stderr);
      if (m) resolve(m[1]);
    });
    exited.then(({ code }) => reject(new Error(`the study exited (${code}) before serving its page:\n${stderr}`)));
  });
  return { child, url, exited, stderr: () => stderr };
}

function trials(folder) {
  const file = path.join(folder, 'trials.jsonl');
  if (!fs.existsSync(file)) return [];
  return fs.readFileSync(file, 'utf8').split('\n').filter((l) => l.trim()).map((l) => JSON.parse(l));
}

/** The trace's rows (the CSV's header names the columns). */
function readTrace(file) {
  const lines = fs.readFileSync(file, 'utf8').trim().split('\n');
  const header = lines[0].split(',');
  const rows = lines.slice(1).map((l) => l.split(','));
  const col = (name) => {
    const i = header.indexOf(name);
    assert.ok(i >= 0, `the trace has a ${name} column`);
    return rows.map((r) => Number(r[i]));
  };
  return { rows, col };
}

/** Waits until the page shows `phase` (the page marks what it shows: #main's data-phase), and
 * resolves with what it showed then (#main's text), read at that moment. */
async function phase(page, wanted, what, run) {
  try {
    const shown = await page.waitForFunction((p) => {
      const main = document.getElementById('main');
      return main.dataset.phase === p && main.innerText;
    }, wanted, { timeout: 60000 });
    return await shown.jsonValue();
  } catch (e) {
    const shown = await page.evaluate(() => `${document.getElementById('main').dataset.phase}: ${document.body.innerText}`);
    assert.fail(`${what}: the page never showed '${wanted}' (it shows ${shown})\n${run.stderr()}`);
  }
}

const text = (page, selector) => page.locator(selector).innerText();
const shownAt = (t) => Date.parse(t.started_utc);

test('a person plays a session through the page: start, keys, clicks, pause, break, abort', async () => {
  const dir = fs.mkdtempSync(path.join(os.tmpdir(), 'toonforce-study-page-'));
  const experiment = path.join(dir, 'study.toml');
  fs.writeFileSync(experiment, EXPERIMENT);
  const hand = path.join(dir, 'pressing.toml');
  fs.writeFileSync(hand, PRESSING_HAND);
  const folder = path.join(dir, 'session');
  const run = startStudy(['run', experiment, '--participant', '1', '--out', folder, '--device', 'sim',
    '--hand', hand, '--allow-non-rt', '--interval', '1']);
  try {
    const { page, errors } = await openPage(browser.context, await run.url);

    // Nothing plays before Start: the page asks for it, with the file's instructions.
    await page.waitForFunction(() => document.getElementById('main').dataset.phase !== 'message');
    assert.equal(await page.evaluate(() => document.getElementById('main').dataset.phase), 'start',
      `the page's first prompt is Start:\n${await page.innerText('body')}`);
    assert.equal(await text(page, 'h1'), 'ice or not');
    assert.equal(await text(page, '#instructions'), 'Hold the handle lightly. Two strokes follow, then a question.');
    assert.ok(await page.locator('#pause').isHidden(), 'no pause before the session started');
    assert.deepEqual(trials(folder), [], 'no trial before Start');
    const clicked = Date.now();
    await page.click('#start');

    // Two-interval trials, answered with the keys; the file's instructions, question and answers.
    const pressed = [];
    const paused = {};
    for (let k = 0; k < 3; ++k) {
      const interval = await phase(page, 'interval', `trial ${k + 1}'s first interval`, run);
      assert.match(interval, /^Interval 1 of 2\s+Let the surface carry your hand\.$/);
      await phase(page, 'choice', `trial ${k + 1}'s question`, run);
      assert.equal(await text(page, '.question'), 'Which stroke slid by itself?');
      assert.equal(await text(page, '#answer1'), 'the left one [1]');
      assert.equal(await text(page, '#answer2'), 'the right one [2]');
      if (k === 1) {
        // The Pause button during a trial: the session pauses after it.
        await page.click('#pause');
        await page.waitForFunction(() => document.getElementById('pause').innerText.startsWith('Pausing'));
      }
      const key = String(1 + (k % 2));
      pressed.push(Number(key));
      await page.keyboard.press(key);
      if (k === 1) {
        await phase(page, 'paused', 'the pause asked for', run);
        paused.trialsBefore = trials(folder).length;
        paused.continued = Date.now();
        await page.keyboard.press(' ');
      }
    }

    // The break before the next block, continued with a click.
    assert.match(await phase(page, 'break', 'the break between the blocks', run), /Next: how they feel\./);
    const breakEnded = Date.now();
    await page.click('#continue');

    // A rating: the items by name, each with its anchors; Done wants every item rated.
    await phase(page, 'rating', 'the first rating', run);
    assert.equal(await text(page, '.question'), 'Rate the surface you just felt.');
    const items = await page.$$eval('fieldset.item', (sets) => sets.map((f) => ({
      name: f.querySelector('legend').innerText,
      anchors: [...f.querySelectorAll('.anchor')].map((a) => a.innerText),
      points: f.querySelectorAll('input[type=radio]').length,
    })));
    assert.deepEqual(items, [
      { name: 'slippery', anchors: ['not at all', 'very'], points: 5 },
      { name: 'playful', anchors: ['serious', 'playful'], points: 7 },
    ]);
    await page.click('input[name="slippery"][value="2"]');
    await page.click('#done');
    assert.match(await text(page, '#note'), /Please rate "playful"/);
    assert.equal(await page.evaluate(() => document.getElementById('main').dataset.phase), 'rating', 'not sent');
    await page.click('input[name="playful"][value="6"]');
    await page.click('#done');

    // Escape in the next trial's interval stops the session.
    await phase(page, 'interval', 'the second rating\'s interval', run);
    const seen = [...errors];
    await page.keyboard.press('Escape');
    await phase(page, 'stopped', 'the page after Escape', run);
    const ended = await Promise.race([run.exited, new Promise((r) => setTimeout(() => r(null), 60000))]);
    assert.ok(ended, `the session ended after Escape:\n${run.stderr()}`);
    assert.equal(ended.code, 1, run.stderr());
    assert.match(run.stderr(), /aborted by the participant \(zero force\)/);
    assert.deepEqual(seen, [], 'no console error, page error or failed request while the session ran');

    // What the session's folder says.
    const kept = trials(folder);
    assert.equal(kept.length, 4, 'three two-interval trials and one rating; the aborted one not recorded');
    const twoInterval = kept.filter((t) => t.block === 0);
    assert.deepEqual(twoInterval.map((t) => t.answer), pressed, 'each answer is the key pressed');
    for (const t of twoInterval) assert.equal(t.correct, t.answer === (t.test_first ? 1 : 2));
    assert.deepEqual(kept[3].ratings, { slippery: 2, playful: 6 }, 'the ratings clicked');
    for (const t of kept) assert.ok(shownAt(t) >= clicked, `trial ${t.block}/${t.trial} began after Start (${t.started_utc})`);
    assert.equal(paused.trialsBefore, 2, 'the pause came after the trial under way, answered and recorded');
    assert.ok(shownAt(kept[2]) >= paused.continued, 'the trial after the pause began after Continue');
    assert.ok(shownAt(kept[3]) >= breakEnded, 'the next block began after the break');

    // The device silent until the first interval, and at the end (the abort's last tick).
    const trace = readTrace(path.join(folder, 'run-1.csv'));
    const [fx, fy, fz, z] = ['fx', 'fy', 'fz', 'z'].map((c) => trace.col(c));
    const force = fx.map((x, i) => Math.hypot(x, fy[i], fz[i]));
    const largest = (xs) => xs.reduce((a, b) => Math.max(a, b), 0);
    const firstOn = kept[0].trace.intervals[0][0];
    assert.ok(firstOn > 0 && firstOn < force.length, `the first interval's frame (${firstOn}) is in the trace`);
    assert.equal(largest(force.slice(0, firstOn)), 0, 'no force before the first interval');
    // Not for want of a hand: it pressed through where the floor is, the device silent.
    assert.ok(Math.min(...z.slice(0, firstOn)) < -0.002, 'before it the hand pressed through the floor\'s plane');
    assert.ok(largest(force.slice(firstOn)) > 0.5, 'the intervals pushed back on the pressing hand');
    assert.equal(force[force.length - 1], 0, 'the abort ends the run on a zero-force tick');
  } finally {
    if (run.child.exitCode === null && run.child.signalCode === null) {
      run.child.kill('SIGTERM');
      await run.exited;
    }
    if (process.env.KEEP_SESSION === undefined) fs.rmSync(dir, { recursive: true, force: true });
  }
});
