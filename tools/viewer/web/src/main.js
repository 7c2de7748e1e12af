// SPDX-License-Identifier: Apache-2.0
// The toonforce viewer page. Read-only: it opens one WebSocket to the server that served it,
// receives the hello (scene, columns, names), batches of frames and status messages, and sends
// nothing. Live, it follows the newest frame; paused, or once the run is over (or for a
// recorded trace), it plays back and can be scrubbed.
import './style.css';
import { FrameStore, CLIFF_LABELS, effectGroups } from './store.js';
import { Scene3D, DEVICE_COLOURS } from './scene3d.js';
import { Plots, drawHistogram, worldSeries } from './plots.js';

const $ = (id) => document.getElementById(id);

const view = {
  hello: null,
  store: null,
  scene: null,
  plots: new Plots($('plots')),
  connection: 'connecting',
  ended: false,
  status: null,
  following: true, // live: show the newest frame
  playing: true, // recording: time advances
  cursor: 0, // frame shown
  playTime: 0, // recording: time shown [s]
  speed: 1,
  lastNow: null,
  fps: 0,
  fpsFrames: 0,
  fpsSince: performance.now(),
  rendered: 0,
  effectGroups: [], // the effects' values, as the page lists them
  worldRows: [], // a world's devices, as the page lists them
};

function setBadge(el, state, text) {
  el.dataset.state = state;
  el.textContent = text;
}

function setConnection(state, text) {
  view.connection = state;
  setBadge($('connection'), state, text ?? state);
}

function onHello(hello) {
  view.hello = hello;
  view.store = new FrameStore(hello);
  view.ended = !hello.live;
  view.following = hello.live;
  view.playing = !hello.live;
  $('title').textContent = hello.title || '';
  const rate = hello.rate_hz ? `${Math.round(hello.rate_hz)} Hz` : '';
  const pacing = hello.pacing ? `, ${hello.pacing}` : '';
  $('source').textContent = `${hello.source}${rate ? ', ' + rate : ''}${pacing}${hello.scene ? ', scene ' + hello.scene.name : ', no scene'}`;
  if (view.scene === null) view.scene = new Scene3D($('view3d'), hello);
  buildEffectValues(hello);
  if (hello.world) buildWorld(hello);
  setConnection(hello.live ? 'live' : 'recording', hello.live ? 'live' : 'recording');
}

function onStatus(status) {
  view.status = status;
  if (status.ended && !view.ended) {
    view.ended = true;
    setConnection('ended', 'run over: recording');
  }
  const s = view.store;
  const parts = [];
  if (s) {
    if (s.missing > 0) parts.push(`${s.missing} frame(s) dropped for this page (it fell behind)`);
    if (s.discarded > 0) parts.push(`${s.discarded} oldest frame(s) let go`);
  }
  if (status.dropped_ring > 0) parts.push(`${status.dropped_ring} frame(s) dropped by the server`);
  $('drops').textContent = parts.length ? parts.join('; ') : 'no frames dropped';
}

function connect() {
  const ws = new WebSocket(`ws://${location.host}/ws`);
  ws.binaryType = 'arraybuffer';
  ws.onmessage = (event) => {
    if (typeof event.data === 'string') {
      const message = JSON.parse(event.data);
      if (message.type === 'hello') onHello(message);
      else if (message.type === 'status') onStatus(message);
      return;
    }
    if (view.store) view.store.addBatch(event.data);
  };
  ws.onclose = (event) => {
    if (view.ended) setConnection('ended', view.hello && !view.hello.live ? 'recording' : 'run over: recording');
    else setConnection('closed', event.code === 1008 ? 'closed: read-only' : 'disconnected');
    view.ended = true;
  };
  ws.onerror = () => {};
}

const fmt = (v, digits = 3) => (Number.isFinite(v) ? v.toFixed(digits) : '–');
const mm = (v) => fmt(v * 1000, 1);

function names(bits, table) {
  return table.filter(([bit]) => (bits & bit) !== 0).map(([, name]) => name);
}

/** One row per effect that shows values (the library's and a program's own alike). */
function buildEffectValues(hello) {
  const list = $('effect-values');
  list.replaceChildren();
  // A world's devices have their own panel: here only the rest (the ball, the couplings).
  const devices = hello.world ? hello.world.devices : [];
  view.effectGroups = effectGroups(hello).filter((g) => !devices.includes(g.effect));
  for (const group of view.effectGroups) {
    const dt = document.createElement('dt');
    dt.textContent = group.effect;
    const dd = document.createElement('dd');
    dd.dataset.effect = group.effect;
    list.append(dt, dd);
    group.element = dd;
  }
  $('effect-values-panel').hidden = view.effectGroups.length === 0;
}

/** A world: one row a device (its name in its colour), the stop's state, plots by device. */
function buildWorld(hello) {
  const list = $('world-devices');
  list.replaceChildren();
  view.worldRows = hello.world.devices.map((name, k) => {
    const dt = document.createElement('dt');
    dt.textContent = name;
    dt.style.color = DEVICE_COLOURS[k % DEVICE_COLOURS.length];
    const dd = document.createElement('dd');
    dd.dataset.device = name;
    list.append(dt, dd);
    return { name, element: dd };
  });
  $('world-panel').hidden = false;
  view.plots.setSeries(worldSeries(hello.world, DEVICE_COLOURS));
}

function updateWorld(i) {
  const s = view.store;
  const g = (name) => s.get(i, name);
  for (const row of view.worldRows) {
    const d = row.name;
    const f = [g(`${d}.fx`), g(`${d}.fy`), g(`${d}.fz`)];
    const state = g(`${d}.state`);
    const stateName = Number.isFinite(state) ? (view.hello.states[state] ?? `state ${state}`) : 'n/a';
    const faults = names(g(`${d}.faults`), view.hello.faults);
    row.element.textContent =
      `HIP [${mm(g(`${d}.x`))}, ${mm(g(`${d}.y`))}, ${mm(g(`${d}.z`))}] mm · ` +
      `F ${fmt(Math.hypot(...f), 2)} N · ${stateName}${faults.length ? ' · faults: ' + faults.join(', ') : ''}`;
  }
  const held = g('held');
  setBadge($('held'), held > 0 ? 'fault' : 'none', held > 0 ? 'held: every device at zero force' : 'not held');
  const ball = [g('ball.x'), g('ball.y'), g('ball.z')];
  $('hip').textContent = Number.isFinite(ball[0]) ? `ball [${ball.map(mm).join(', ')}] mm` : '–';
}

/** A value with its unit, lengths in mm and times in ms as the rest of the page shows them. */
function showValue(v, unit) {
  if (!Number.isFinite(v)) return '–';
  if (unit === 'm') return `${(v * 1000).toFixed(2)} mm`;
  if (unit === 's') return `${(v * 1000).toFixed(1)} ms`;
  const text = String(Number(v.toPrecision(3))); // 3 significant digits, no trailing zeros
  return unit ? `${text} ${unit}` : text;
}

function updateEffectValues(i) {
  const s = view.store;
  for (const group of view.effectGroups) {
    group.element.textContent = group.values
      .map((v) => `${v.name} ${showValue(s.data[i * s.stride + v.column], v.unit)}`)
      .join(' · ');
  }
}

function updatePanels(i) {
  const s = view.store;
  const g = (name) => s.get(i, name);
  $('time').textContent = `${fmt(g('t'), 3)} s (tick ${g('tick')})`;
  const contact = g('contact');
  setBadge($('contact'), contact > 0 ? 'yes' : 'no', contact > 0 ? 'in contact' : 'free');
  const impact = s.runningImpact(i);
  if (impact) {
    const impactT = impact.t;
    const surface = impact.surface;
    const d = surface ? surface.impact.duration : NaN;
    const f = surface ? surface.impact.frequency : NaN;
    const cycle = Number.isFinite(f) ? ` cycle ${Math.floor(impactT * f) + 1}` : '';
    setBadge($('impact'), 'running', 'recoil + oscillation');
    $('impact-detail').textContent = `${(impactT * 1000).toFixed(0)} of ${Number.isFinite(d) ? (d * 1000).toFixed(0) : '?'} ms${cycle}`;
  } else {
    setBadge($('impact'), 'none', 'none');
    $('impact-detail').textContent = '';
  }
  const label = CLIFF_LABELS[s.cliffLabel[i]];
  const detail = {
    none: '',
    supported: 'on the ground',
    bridged: s.cliff && s.overGap(g('x'), g('y'), g('z')) ? 'over the gap, held up' : 'crossed the gap, held up',
    fallen: 'dropped into the gap',
  };
  setBadge($('cliff'), label, label === 'none' ? 'no cliff' : label);
  $('cliff-detail').textContent = detail[label];
  const fx = g('fx');
  const fy = g('fy');
  const fz = g('fz');
  $('force').textContent = `${fmt(Math.hypot(fx, fy, fz), 2)} N  [${fmt(fx, 2)}, ${fmt(fy, 2)}, ${fmt(fz, 2)}]`;
  $('hip').textContent = `[${mm(g('x'))}, ${mm(g('y'))}, ${mm(g('z'))}] mm`;
  const state = g('state');
  if (Number.isFinite(state)) {
    const name = view.hello.states[state] ?? `state ${state}`;
    setBadge($('loop-state'), name, name);
  } else {
    setBadge($('loop-state'), 'none', 'n/a');
  }
  const limits = names(g('limits'), view.hello.limits);
  $('limits').textContent = limits.join(', ');
  const faults = g('faults');
  const latched = g('latched');
  const now = names(faults, view.hello.faults);
  const latchedNames = Number.isFinite(latched) ? names(latched, view.hello.faults) : [];
  const faultsEl = $('faults');
  faultsEl.dataset.state = now.length ? 'fault' : 'none';
  faultsEl.textContent = now.length ? now.join(', ') + (latchedNames.length ? ` (latched: ${latchedNames.join(', ')})` : '') : 'none';
  $('faults-seen').textContent = s.faultTicks
    ? `${s.faultTicks} tick(s) with faults so far: ${names(s.faultUnion, view.hello.faults).join(', ')}`
    : 'no faults so far';

  updateEffectValues(i);
  if (view.hello.world) updateWorld(i);

  if (s.latencyCount > 0) {
    const missed = g('missed');
    $('timing').textContent =
      `wake-up latency median ${s.latencyPercentile(0.5)} us, p99.9 ${s.latencyPercentile(0.999)} us, ` +
      `max ${fmt(s.latencyMax, 1)} us; compute max ${fmt(s.computeMax, 1)} us; ` +
      `missed deadlines ${Number.isFinite(missed) ? missed : '–'}`;
  } else {
    $('timing').textContent = view.hello.source === 'sim' ? 'simulated time: no real-time loop to time' : 'no timing in this stream';
  }
}

function updateTransport() {
  const s = view.store;
  const scrub = $('scrub');
  scrub.max = String(Math.max(0, s.count - 1));
  if (document.activeElement !== scrub || view.following) scrub.value = String(view.cursor);
  const live = view.hello.live && !view.ended;
  $('live').disabled = !live;
  $('live').dataset.active = String(view.following && live);
  $('play').textContent = view.following || view.playing ? 'pause' : 'play';
  $('scrub-time').textContent = s.count ? `${fmt(s.time(view.cursor), 3)} / ${fmt(s.time(s.count - 1), 3)} s` : '';
}

function frame(now) {
  requestAnimationFrame(frame);
  view.fpsFrames += 1;
  if (now - view.fpsSince >= 1000) {
    view.fps = (view.fpsFrames * 1000) / (now - view.fpsSince);
    view.fpsFrames = 0;
    view.fpsSince = now;
    $('fps').textContent = `${view.fps.toFixed(0)} fps`;
  }
  const dt = view.lastNow === null ? 0 : (now - view.lastNow) / 1000;
  view.lastNow = now;
  const s = view.store;
  if (!s || !view.scene) return;
  if (s.count === 0) {
    view.scene.update(s, 0);
    return;
  }
  if (view.following && !view.ended) {
    view.cursor = s.count - 1;
    view.playTime = s.time(view.cursor);
  } else if (view.following && view.ended) {
    // The run just ended while following: stay on its last frame, as a recording.
    view.following = false;
    view.playing = false;
    view.cursor = s.count - 1;
    view.playTime = s.time(view.cursor);
  } else if (view.playing) {
    view.playTime += dt * view.speed;
    const end = s.time(s.count - 1);
    if (view.playTime >= end) {
      view.playTime = end;
      view.playing = false;
    }
    view.cursor = s.indexAt(view.playTime);
  }
  view.cursor = Math.min(view.cursor, s.count - 1);
  view.scene.update(s, view.cursor);
  updatePanels(view.cursor);
  view.plots.draw(s, view.cursor, !view.following);
  drawHistogram($('histogram'), s);
  updateTransport();
  view.rendered += 1;
}

function seekIndex(i) {
  const s = view.store;
  if (!s || s.count === 0) return;
  view.following = false;
  view.playing = false;
  view.cursor = Math.max(0, Math.min(s.count - 1, i));
  view.playTime = s.time(view.cursor);
}

$('scrub').addEventListener('input', (e) => seekIndex(Number(e.target.value)));
$('play').addEventListener('click', () => {
  const s = view.store;
  if (!s) return;
  if (view.following || view.playing) {
    view.following = false;
    view.playing = false;
  } else {
    if (view.cursor >= s.count - 1) view.playTime = s.time(0); // from the start again
    view.playing = true;
  }
});
$('live').addEventListener('click', () => {
  view.following = true;
});
$('speed').addEventListener('change', (e) => {
  view.speed = Number(e.target.value);
});
window.addEventListener('keydown', (e) => {
  if (e.key === ' ' && e.target === document.body) {
    e.preventDefault();
    $('play').click();
  }
});

// For tests and scripts: what the page shows, read from the objects it draws with. Read-only.
window.toonforceViewer = {
  snapshot() {
    const s = view.store;
    const i = view.cursor;
    const has = s && s.count > 0;
    return {
      connection: view.connection,
      // What the server's hello said (null before it came): unlike `connection`, which a live
      // run passes through on its way to 'ended', this does not change once known.
      live: view.hello ? view.hello.live : null,
      ended: view.ended,
      following: view.following,
      playing: view.playing,
      frames: s ? s.count : 0,
      missing: s ? s.missing : 0,
      cursor: i,
      t: has ? s.time(i) : null,
      endTime: has ? s.time(s.count - 1) : null,
      contact: $('contact').dataset.state,
      impact: $('impact').dataset.state,
      cliff: $('cliff').dataset.state,
      faults: $('faults').dataset.state,
      effects: Object.fromEntries((view.effectGroups ?? []).map((g) => [g.effect, g.element.textContent])),
      arrow: view.scene && view.scene.arrow
        ? { visible: view.scene.arrow.visible, direction: view.scene.arrow.userData.direction, length: view.scene.arrow.userData.length }
        : null,
      hip: view.scene && view.scene.hip ? view.scene.hip.position.toArray() : null,
      // A world: every device's HIP as drawn (null until a frame placed it), its label and colour;
      // the ball; the couplings' lines; the stop.
      world:
        view.scene && view.scene.world
          ? {
              devices: view.scene.devices.map((d) => ({
                name: d.name,
                colour: d.colour,
                drawn: d.hip.visible,
                hip: d.hip.visible ? d.hip.position.toArray() : null,
                arrow: { visible: d.arrow.visible, direction: d.arrow.userData.direction },
                panel: view.worldRows.find((r) => r.name === d.name)?.element.textContent ?? '',
              })),
              ball: view.scene.ball && view.scene.ball.visible ? view.scene.ball.position.toArray() : null,
              ballRadius: view.scene.ball ? view.scene.ball.geometry.parameters.radius : null,
              couplings: view.scene.couplings.map((l) => l.visible),
              held: $('held').dataset.state,
              plotLabels: view.plots.series.map((p) => p.label),
            }
          : null,
      force: has ? [s.get(i, 'fx'), s.get(i, 'fy'), s.get(i, 'fz')] : null,
      fps: view.fps,
      rendered: view.rendered,
    };
  },
  /** Frames (indices) matching a predicate over a row getter, for tests that look for a moment. */
  findFrame(column, op, value) {
    const s = view.store;
    if (!s) return -1;
    for (let i = 0; i < s.count; ++i) {
      const v = s.get(i, column);
      if ((op === '>' && v > value) || (op === '<' && v < value) || (op === '==' && v === value)) return i;
    }
    return -1;
  },
  /** The frame where |column| is largest (among frames where `where` > 0, if given). */
  argmax(column, where) {
    const s = view.store;
    let best = -1;
    let bestValue = -Infinity;
    for (let i = 0; s && i < s.count; ++i) {
      if (where && !(s.get(i, where) > 0)) continue;
      const v = Math.abs(s.get(i, column));
      if (v > bestValue) {
        bestValue = v;
        best = i;
      }
    }
    return best;
  },
};

connect();
requestAnimationFrame(frame);
