// SPDX-License-Identifier: Apache-2.0
// The story page: a short cartoon level in the paper's spirit, played on a
// running `toonforce run --view --control` with scenes/story/level.toml. The character is the
// handle (the HIP); the page's own logic changes the scene through the control protocol
// (docs/spec/control-protocol.md) as the character goes, and reads what the loop did from the
// viewer's telemetry (/ws), the frames every page gets:
//
//   1. the pond: the page freezes the ground into ice (surface1 gets the paper's super-slippery
//      law, §4.1): the character slides, the ice pushing it along;
//   2. the wall: once the character is on its way, the page puts a cartoon wall in its path
//      (surface2 moves in): it bumps into it and is thrown back, shaking (§4.2);
//   3. the gap: once the shaking is over, the page takes the wall and the ice away and swaps in
//      the ground with a gap (cliff1): the character falls once it hesitates over it (§4.3).
//
// What "slid", "bounced" and "fell" mean is measured here from the loop's frames, not assumed
// from what was sent: the ice did positive work on the character along its path; the wall's
// impact transient ran and threw the character backwards; the cliff's state became "fallen".
// The force the player feels is the loop's (the page never computes a force); the page only
// moves the world. Nothing here depends on the simulated hand: a person on a Falcon or an
// Omni plays the same level. window.toonforceStory.snapshot() is for tests.
import { FrameStore } from './store.js';
import './story.css';

// The level's geometry [m], as scenes/story/level.toml and the changes below put it.
const WALL_X = 0.0;           // the wall's plane (normal -x) once moved in
const GAP = [0.015, 0.035];   // the gap along x once the cliff is moved in
const PARK = 1.0;             // how far out of reach an effect waits [m]
// The page's cues, from the character's position and the loop's time.
const WALL_CUE_X = -0.035;    // put the wall up once the character has gone this far [m]
const CALM_S = 0.3;           // the shaking has been over this long: on to the gap [s]
const MIN_SLIDE_M = 0.01;     // a slide is at least this long on the ice [m]

const $ = (id) => document.getElementById(id);

const story = {
  chapter: 'waiting',
  frames: 0,
  t: null,
  hip: null,
  sent: [],        // {t, what, reply}
  errors: [],
  events: {},      // slid, bounced, fell: what the frames showed
  ice: { on: false, pathM: 0, workJ: 0, maxSpeed: 0, startX: null },
  wall: { up: false, impacts: 0, inTransient: false, transientS: 0, lastTransientT: null, maxRecoilN: 0, minVx: 0, contactT: null, signChanges: 0, lastSign: 0 },
  gap: { open: false },
};

let store = null;
const trail = [];  // the character's path (x, z), every 10th frame, drawn behind it
let done = 0;      // frames the story logic has read
let control = null;
let nextId = 1;
const pending = new Map();

function setBadge(id, state, text) {
  $(id).dataset.state = state;
  $(id).textContent = text;
}

function fail(message) {
  story.errors.push(message);
  $('error').hidden = false;
  $('error').textContent = story.errors.join('\n');
}

// --- the control protocol -----------------------------------------------------------------

/** Sends one message; resolves with its reply (every message gets exactly one, in order). */
function send(message, what) {
  const id = nextId++;
  const entry = { t: story.t, what, reply: null };
  story.sent.push(entry);
  const li = document.createElement('li');
  li.textContent = what;
  $('sent').append(li);
  return new Promise((resolve) => {
    pending.set(id, (reply) => {
      entry.reply = reply.type;
      li.textContent = `${what}: ${reply.type === 'ok' ? 'ok' : reply.message}`;
      if (reply.type === 'error') fail(`${what}: ${reply.message}`);
      resolve(reply);
    });
    control.send(JSON.stringify({ ...message, id }));
  });
}

const setKeys = (effect, keys, what) => send({ type: 'set', effect, keys }, what);

function openControl(token) {
  control = new WebSocket(`ws://${location.host}/control`);
  control.onopen = () => control.send(JSON.stringify({ type: 'hello', version: 1, token }));
  control.onmessage = (event) => {
    const reply = JSON.parse(event.data);
    if (reply.type === 'welcome') {
      setBadge('connection', 'live', 'playing');
      startChapter('pond');
      return;
    }
    const resolve = pending.get(reply.id);
    if (resolve) {
      pending.delete(reply.id);
      resolve(reply);
    } else if (reply.type === 'error') {
      fail(`control: ${reply.message}`);  // the hello refused: a wrong token
      $('token-form').hidden = false;
    }
  };
  control.onclose = () => {
    if (story.chapter !== 'end') setBadge('connection', 'closed', 'control closed');
  };
}

// --- the story ---------------------------------------------------------------------------

const CAPTIONS = {
  waiting: 'Waiting for the run…',
  pond: 'Chapter 1, the pond. The ground freezes over: walk on, and feel the ice push you along.',
  wall: 'Chapter 2, the wall. A wall springs up ahead. Run into it.',
  gap: 'Chapter 3, the gap. The wall is gone, and so is the ice; a gap opens. Cross it, and do not stop halfway.',
  end: 'The end. Slid, bounced and fell: a cartoon character\'s day.',
};

function startChapter(chapter) {
  story.chapter = chapter;
  setBadge('chapter', chapter, chapter);
  $('caption').textContent = CAPTIONS[chapter];
  if (chapter === 'pond') {
    // The paper's slippery surface (slippery.toml): mu = 4 N s/m, capped at 2 N.
    setKeys('surface1', { slippery: { mu: 4.0, max_tangential_force: 2.0 } }, 'freeze the ground into ice').then((r) => {
      story.ice.on = r.type === 'ok';
    });
  } else if (chapter === 'wall') {
    setKeys('surface2', { point: [WALL_X, 0, 0] }, 'put the wall up at x = 0').then((r) => {
      story.wall.up = r.type === 'ok';
    });
  } else if (chapter === 'gap') {
    // The gap ground comes in before the ice goes, so the character always stands on something
    // (the loop fades each change in over 0.25 s: live-scenes.md).
    setKeys('cliff1', { point: [GAP[0], 0, 0] }, 'open the gap (x 15-35 mm)').then((r) => {
      story.gap.open = r.type === 'ok';
    });
    setKeys('surface1', { point: [0, 0, -PARK] }, 'take the ice away');
    setKeys('surface2', { point: [PARK, 0, 0] }, 'take the wall away');
  }
}

function event(name, detail) {
  if (story.events[name]) return;
  story.events[name] = { t: story.t, at: story.hip, ...detail };
  const li = document.createElement('li');
  li.dataset.event = name;
  li.textContent = detail.text;
  $('events').append(li);
}

function retell(name, text) {
  story.events[name].text = text;
  document.querySelector(`#events li[data-event="${name}"]`).textContent = text;
}

/** The story logic, once per frame of the loop, in the loop's time. */
function step(i) {
  const g = (name) => store.get(i, name);
  const t = store.time(i);
  const x = g('x');
  const vx = g('vx');
  const vy = g('vy');
  const dt = i > 0 ? t - store.time(i - 1) : 0;
  story.t = t;
  story.hip = [x, g('y'), g('z')];
  if (i % 10 === 0) trail.push([x, g('z')]);

  if (story.chapter === 'pond' || story.chapter === 'wall') {
    // On the ice: the tangential force's power along the motion (positive: it pushes along, the
    // super-slippery law; negative on any real friction). The wall's force is along x too, so
    // only frames out of the wall's contact count.
    const onIce = story.ice.on && g('surface1.contact') > 0 && !(g('surface2.contact') > 0) && !Number.isFinite(g('surface2.impact_t'));
    if (onIce && dt > 0) {
      const speed = Math.hypot(vx, vy);
      story.ice.pathM += speed * dt;
      story.ice.workJ += (g('fx') * vx + g('fy') * vy) * dt;
      story.ice.maxSpeed = Math.max(story.ice.maxSpeed, speed);
      if (story.ice.startX === null) story.ice.startX = x;
      if (story.ice.pathM >= MIN_SLIDE_M && story.ice.workJ > 0) {
        // Told once, then kept up to date while the slide goes on.
        event('slid', { text: '' });
        Object.assign(story.events.slid, { pathM: story.ice.pathM, workJ: story.ice.workJ, maxSpeed: story.ice.maxSpeed });
        retell('slid', `slid ${(story.ice.pathM * 1000).toFixed(0)} mm over the ice, the ice pushing it along (${(story.ice.workJ * 1000).toFixed(1)} mJ of work)`);
      }
    }
  }
  if (story.chapter === 'pond' && story.ice.on && x > WALL_CUE_X) startChapter('wall');

  if (story.chapter === 'wall') {
    const w = story.wall;
    const transient = g('surface2.impact_t');
    if (Number.isFinite(transient)) {
      if (!w.inTransient) w.impacts += 1;
      w.inTransient = true;
      w.lastTransientT = t;
      if (w.contactT === null) {
        w.contactT = t;
        w.contactAt = story.hip;
      }
      w.transientS = Math.max(w.transientS, transient);
      w.maxRecoilN = Math.max(w.maxRecoilN, -g('fx'));
      const sign = Math.sign(g('fx'));
      if (sign !== 0 && w.lastSign !== 0 && sign !== w.lastSign) w.signChanges += 1;
      if (sign !== 0) w.lastSign = sign;
    } else {
      w.inTransient = false;
    }
    if (w.contactT !== null) w.minVx = Math.min(w.minVx, vx);
    // Told once the first transient is over, so its whole shake is in the numbers.
    if (w.impacts > 0 && !w.inTransient && w.minVx < -0.02) {
      event('bounced', {
        text: `bounced off the wall: thrown back at ${(-w.minVx * 1000).toFixed(0)} mm/s, shaking for ${(w.transientS * 1000).toFixed(0)} ms`,
        at: w.contactAt,
        impacts: w.impacts,
        backSpeed: -w.minVx,
        maxRecoilN: w.maxRecoilN,
        transientS: w.transientS,
        forceSignChanges: w.signChanges,
      });
    }
    if (story.events.bounced && !Number.isFinite(transient) && t - w.lastTransientT >= CALM_S) startChapter('gap');
  }

  if (story.chapter === 'gap' && story.gap.open && g('cliff1.state') === 1) {
    event('fell', {
      text: `slowed down over the gap (to ${(g('cliff1.speed') * 1000).toFixed(0)} mm/s, filtered) and fell`,
      x,
      speed: g('cliff1.speed'),
    });
    startChapter('end');
  }
}

// --- the telemetry (read-only, as the viewer's) --------------------------------------------

function openTelemetry() {
  const ws = new WebSocket(`ws://${location.host}/ws`);
  ws.binaryType = 'arraybuffer';
  ws.onmessage = (message) => {
    if (typeof message.data === 'string') {
      const m = JSON.parse(message.data);
      if (m.type === 'hello') {
        if (!m.live) fail('this stream is a recording: the story needs a live run (toonforce run --view --control)');
        store = new FrameStore(m);
        for (const column of ['surface1.contact', 'surface2.contact', 'surface2.impact_t', 'cliff1.state', 'cliff1.speed']) {
          if (!(column in store.col)) fail(`the run's scene is not the story's level (no ${column} column): run scenes/story/level.toml`);
        }
      }
      return;
    }
    if (!store) return;
    store.addBatch(message.data);
    for (; done < store.count; ++done) if (story.chapter !== 'waiting' && story.errors.length === 0) step(done);
    story.frames = store.count;
  };
  ws.onclose = () => {
    if (story.chapter !== 'end') setBadge('connection', 'ended', 'run over');
  };
}

// --- drawing: the level from the side (x to the right, z up) -------------------------------

const canvas = $('stage');
const ctx = canvas.getContext('2d');
const VIEW = { x0: -0.06, x1: 0.05, z0: -0.03, z1: 0.02 };
const px = (x) => ((x - VIEW.x0) / (VIEW.x1 - VIEW.x0)) * canvas.width;
const pz = (z) => ((VIEW.z1 - z) / (VIEW.z1 - VIEW.z0)) * canvas.height;

function draw() {
  const w = canvas.width;
  const h = canvas.height;
  ctx.clearRect(0, 0, w, h);
  const sky = ctx.createLinearGradient(0, 0, 0, h);
  sky.addColorStop(0, '#bfe3ff');
  sky.addColorStop(1, '#eef8ff');
  ctx.fillStyle = sky;
  ctx.fillRect(0, 0, w, h);

  const ground = pz(0);
  const inGap = story.gap.open;
  // The ground: earth, ice on it while the pond is frozen, the gap once it is open.
  ctx.fillStyle = '#8b6b4a';
  ctx.fillRect(0, ground, w, h - ground);
  if (story.ice.on && !inGap) {
    ctx.fillStyle = '#9fd8f5';
    ctx.fillRect(0, ground - 4, w, 10);
    ctx.strokeStyle = '#ffffff';
    ctx.lineWidth = 2;
    for (let x = 20; x < w; x += 90) {
      ctx.beginPath();
      ctx.moveTo(x, ground + 3);
      ctx.lineTo(x + 30, ground - 1);
      ctx.stroke();
    }
  } else {
    ctx.fillStyle = '#5c9e3b';
    ctx.fillRect(0, ground - 4, w, 8);
  }
  if (inGap) {
    ctx.fillStyle = '#1d1a17';
    ctx.fillRect(px(GAP[0]), ground - 4, px(GAP[1]) - px(GAP[0]), h - ground + 4);
  }
  if (story.wall.up && story.chapter !== 'wall') {
    // Taken away: its outline stays, so the picture tells the whole story.
    ctx.strokeStyle = 'rgba(181, 83, 47, 0.5)';
    ctx.setLineDash([6, 6]);
    ctx.strokeRect(px(WALL_X), pz(0.017), 46, ground - pz(0.017));
    ctx.setLineDash([]);
  }
  if (story.wall.up && story.chapter === 'wall') {
    const x = px(WALL_X);
    ctx.fillStyle = '#b5532f';
    ctx.fillRect(x, pz(0.017), 46, ground - pz(0.017));
    ctx.strokeStyle = '#f3d9c9';
    ctx.lineWidth = 2;
    for (let z = ground; z > pz(0.017); z -= 18) {
      ctx.beginPath();
      ctx.moveTo(x, z);
      ctx.lineTo(x + 46, z);
      ctx.stroke();
    }
  }
  // Where the character has been, and where each thing happened.
  ctx.strokeStyle = 'rgba(58, 42, 18, 0.35)';
  ctx.lineWidth = 2;
  ctx.setLineDash([4, 6]);
  ctx.beginPath();
  trail.forEach(([x, z], k) => (k === 0 ? ctx.moveTo(px(x), pz(z) - 26) : ctx.lineTo(px(x), pz(z) - 26)));
  ctx.stroke();
  ctx.setLineDash([]);
  ctx.font = 'bold 18px system-ui, sans-serif';
  ctx.fillStyle = '#3a2a12';
  const labels = { slid: 'whee!', bounced: 'boing!', fell: 'uh-oh' };
  for (const [name, e] of Object.entries(story.events)) {
    if (!e.at) continue;
    ctx.fillText(labels[name], px(e.at[0]) - 24, pz(e.at[2]) - 70);
  }
  // The character: the HIP, a round fellow with eyes that look where it goes; it shakes while
  // the impact transient runs and looks down once it has fallen.
  if (story.hip) {
    const shaking = story.chapter === 'wall' && story.wall.lastTransientT !== null && story.t - story.wall.lastTransientT < 0.02;
    const jitter = shaking ? Math.sin(performance.now() / 15) * 4 : 0;
    const cx = px(story.hip[0]) + jitter;
    const r = 26;
    const cy = pz(story.hip[2]) - r;
    ctx.fillStyle = '#ffcf3f';
    ctx.strokeStyle = '#3a2a12';
    ctx.lineWidth = 3;
    ctx.beginPath();
    ctx.arc(cx, cy, r, 0, 2 * Math.PI);
    ctx.fill();
    ctx.stroke();
    const look = story.events.fell ? [0, 6] : [story.chapter === 'wall' && shaking ? -5 : 5, -3];
    for (const dx of [-9, 9]) {
      ctx.fillStyle = '#fff';
      ctx.beginPath();
      ctx.arc(cx + dx, cy - 6, 7, 0, 2 * Math.PI);
      ctx.fill();
      ctx.stroke();
      ctx.fillStyle = '#000';
      ctx.beginPath();
      ctx.arc(cx + dx + look[0] * 0.6, cy - 6 + look[1] * 0.6, 3, 0, 2 * Math.PI);
      ctx.fill();
    }
    if (shaking) {
      ctx.strokeStyle = '#3a2a12';
      for (const dy of [-12, 0, 12]) {
        ctx.beginPath();
        ctx.moveTo(cx - r - 16, cy + dy);
        ctx.lineTo(cx - r - 6, cy + dy);
        ctx.stroke();
      }
    }
  }
  $('clock').textContent = story.t === null ? '' : `t = ${story.t.toFixed(2)} s`;
  requestAnimationFrame(draw);
}

// --- start ---------------------------------------------------------------------------------

window.toonforceStory = {
  snapshot() {
    return JSON.parse(JSON.stringify({
      chapter: story.chapter,
      frames: story.frames,
      t: story.t,
      hip: story.hip,
      events: story.events,
      sent: story.sent,
      errors: story.errors,
    }));
  },
};

const token = new URLSearchParams(location.hash.slice(1)).get('token');
$('token-form').addEventListener('submit', (e) => {
  e.preventDefault();
  $('token-form').hidden = true;
  story.errors.length = 0;
  $('error').hidden = true;
  openControl($('token').value);
});
openTelemetry();
if (token) openControl(token);
else {
  $('token-form').hidden = false;
  $('caption').textContent = 'Give the control token the run printed to start the story.';
}
requestAnimationFrame(draw);
