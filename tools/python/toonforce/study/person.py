# SPDX-License-Identifier: Apache-2.0
"""A person on a device: each interval is the condition's scene loaded into a running
`toonforce run --control` (toonforce.live) on the Falcon, the Omni or the simulated device, and
the participant answers on a page served here, http://127.0.0.1:PORT/: the experiment's
instructions and a Start button (no trial begins before it, the device silent), each trial's
prompt in the experiment file's words and its answer by key or click, rating items by name
between their anchors, a Pause key (after the trial under way), a break between blocks, and an
abort key.

The abort key (Escape, or the page's button) ends the trial at once: the run is stopped through
the command line's stop path (its last tick commands zero force), the trial in progress is not
recorded, and the session can be resumed.

The device is silent outside the intervals: before the first, between the two of a trial,
during the blank, the question, a break and until the next trial. `toonforce run` keeps its
scene's list of effects (its trace's columns), so there is no empty scene to load; the silent
scene is the first condition's with every effect moved out of reach (one metre behind its own
plane, a cliff's fall force 0): no contact, no force. Each scene change, the silent one
included, is faded by the loop over its update fade (docs/spec/live-scenes.md section 5, 0.25 s):
the force ramps to zero after an interval and in from zero at the next. The experiment file's
check makes every condition a session presents share the first one's list of effects.
"""

from __future__ import annotations

import json
import os
import threading
import time
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Any, Dict, Optional

from . import experiment as experiments
from .session import scene_with


def silent_scene(scene: Dict[str, Any], distance_m: float = 1.0) -> Dict[str, Any]:
    """The scene with every effect out of reach: each surface's and cliff's plane moved
    `distance_m` behind itself along its normal (far outside any device's workspace, so the
    handle never touches it), a cliff's fall force 0 (it pulls over its gap wherever the plane
    is). Its list of effects and [device] table are the scene's, as a running `toonforce run`
    requires of a scene it loads."""
    import copy

    out = copy.deepcopy(scene)
    for kind in ("surface", "cliff"):
        for effect in out.get(kind, []):
            point, normal = effect.get("point", [0.0, 0.0, 0.0]), effect.get("normal", [0.0, 0.0, 1.0])
            length = sum(n * n for n in normal) ** 0.5 or 1.0
            effect["point"] = [p - distance_m * n / length for p, n in zip(point, normal)]
            if kind == "cliff":
                effect["fall_force"] = 0.0
    return out


class Aborted(Exception):
    """The participant pressed the abort key: the run was stopped with zero force."""


PAGE = """<!doctype html><html><head><meta charset="utf-8"><title>toonforce study</title><link rel="icon" href="data:,">
<style>body{font:22px system-ui;margin:3em;max-width:40em}button{font:inherit;margin:.3em}
fieldset{border:0;margin:1em 0;padding:0}legend{font-weight:600;padding:0}.scale{display:flex;align-items:center;gap:.5em;flex-wrap:wrap}
.scale label{display:inline-flex;flex-direction:column;align-items:center}.anchor{font-style:italic}
#controls{position:fixed;right:1em;bottom:1em}#abort{background:#c33;color:#fff}.k{opacity:.6;font-size:70%}
.note{color:#a40}</style></head>
<body><div id="main">Please wait</div>
<div id="controls"><button id="pause" hidden>Pause <span class=k>[P]</span></button>
<button id="abort">Stop <span class=k>[Esc]</span></button></div>
<script>
// The page shows the state the session serves (/state, polled) and posts the participant's
// answers with the prompt's token, so that an answer never reaches another prompt. Every text
// the experiment file gives is set as text, never as markup.
let state = {phase: 'message', text: 'Please wait'};
let answered = null;   // the token of the prompt answered: the page waits for the next
let stopped = false;
const main = document.getElementById('main');
function el(tag, props, ...children) {
  const e = document.createElement(tag);
  Object.assign(e, props || {});
  e.append(...children);
  return e;
}
async function post(path, body) {
  try { await fetch(path, {method: 'POST', body: JSON.stringify(body)}); } catch (e) { /* the session ended */ }
}
function answer(value) {
  if (answered === state.token) return;
  answered = state.token;
  post('/answer', {token: state.token, value});
  render();
}
function abort() {
  if (stopped) return;
  stopped = true;
  post('/abort', {});
  render();
}
function pause() {
  if (!stopped && !state.pausing) post('/pause', {});
}
function keyButton(text, key, onclick, id) {
  return el('button', {id: id || '', onclick}, text + ' ', el('span', {className: 'k', textContent: `[${key}]`}));
}
function rating(s) {
  const out = [el('p', {className: 'question', textContent: s.question})];
  for (const it of s.items) {
    const scale = el('div', {className: 'scale'}, el('span', {className: 'anchor', textContent: it.anchors[0]}));
    for (let i = 1; i <= it.points; ++i)
      scale.append(el('label', {}, el('input', {type: 'radio', name: it.name, value: String(i)}), String(i)));
    scale.append(el('span', {className: 'anchor', textContent: it.anchors[1]}));
    out.push(el('fieldset', {className: 'item'}, el('legend', {textContent: it.name}), scale));
  }
  const note = el('p', {className: 'note', id: 'note'});
  out.push(el('button', {id: 'done', textContent: 'Done', onclick: () => {
    const v = {};
    for (const it of s.items) {
      const c = document.querySelector(`input[name="${CSS.escape(it.name)}"]:checked`);
      if (!c) { note.textContent = `Please rate "${it.name}".`; return; }
      v[it.name] = Number(c.value);
    }
    answer(v);
  }}), note);
  return out;
}
function render() {
  const s = state;
  document.getElementById('pause').hidden = stopped || !s.started || s.phase === 'paused' || s.phase === 'message';
  document.getElementById('pause').firstChild.textContent = s.pausing ? 'Pausing after this trial ' : 'Pause ';
  let view;
  if (stopped) view = [el('h1', {textContent: 'Stopped'}), el('p', {textContent: 'The session has been stopped.'})];
  else if (answered === s.token) view = [el('p', {textContent: 'Please wait'})];
  else if (s.phase === 'start') view = [el('h1', {textContent: s.title}), el('p', {id: 'instructions', textContent: s.text}),
                                        keyButton('Start', 'space', () => answer('start'), 'start')];
  else if (s.phase === 'interval') view = [el('h1', {textContent: `Interval ${s.number} of ${s.of}`}),
                                           el('p', {textContent: s.instructions})];
  else if (s.phase === 'blank') view = [el('h1', {textContent: '...'})];
  else if (s.phase === 'choice') view = [el('p', {className: 'question', textContent: s.question}),
      ...s.answers.map((a, i) => keyButton(a, i + 1, () => answer(i + 1), `answer${i + 1}`))];
  else if (s.phase === 'rating') view = rating(s);
  else if (s.phase === 'break' || s.phase === 'paused')
    view = [el('h1', {textContent: s.phase === 'break' ? 'A break' : 'Paused'}), el('p', {textContent: s.text}),
            keyButton('Continue', 'space', () => answer('continue'), 'continue')];
  else view = [el('h1', {textContent: s.text || ''})];
  main.replaceChildren(...view);
  main.dataset.phase = stopped ? 'stopped' : (answered === s.token ? 'wait' : s.phase);
}
document.getElementById('abort').onclick = abort;
document.getElementById('pause').onclick = pause;
document.addEventListener('keydown', (e) => {
  const s = state;
  let handled = true;
  if (e.key === 'Escape') abort();
  else if (stopped || answered === s.token) handled = false;
  else if (s.phase === 'choice' && /^[1-9]$/.test(e.key) && Number(e.key) <= s.answers.length) answer(Number(e.key));
  else if (e.key === ' ' && s.phase === 'start') answer('start');
  else if (e.key === ' ' && (s.phase === 'break' || s.phase === 'paused')) answer('continue');
  else if ((e.key === 'p' || e.key === 'P') && s.started && s.phase !== 'paused') pause();
  else handled = false;
  if (handled) {  // space on a focused button would click it too, when the key comes up
    e.preventDefault();
    document.activeElement?.blur?.();
  }
});
async function poll() {
  try {
    const s = await (await fetch('/state')).json();
    if (JSON.stringify(s) !== JSON.stringify(state)) { state = s; render(); }
  } catch (e) { /* the session ended */ }
  if (!stopped) setTimeout(poll, 100);
}
render();
poll();
</script></body></html>"""


class _Page:
    """The participant's page: a state the page polls, answers it posts, the pause and abort keys."""

    def __init__(self, port: int):
        self._lock = threading.Lock()
        self._state: Dict[str, Any] = {"phase": "message", "text": "Please wait"}
        self._answer: Optional[Any] = None
        self._token = 0
        self.started = False  # the participant pressed Start
        self.aborted = threading.Event()
        self.pause_requested = threading.Event()
        page = self

        class Handler(BaseHTTPRequestHandler):
            def log_message(self, *args):  # the experimenter's terminal shows progress, not requests
                pass

            def _send(self, code, body: bytes, kind: str):
                self.send_response(code)
                self.send_header("Content-Type", kind)
                self.send_header("Content-Length", str(len(body)))
                self.send_header("Cache-Control", "no-store")
                self.end_headers()
                self.wfile.write(body)

            def do_GET(self):
                if self.path == "/":
                    self._send(200, PAGE.encode(), "text/html; charset=utf-8")
                elif self.path == "/state":
                    with page._lock:
                        body = json.dumps({**page._state, "started": page.started,
                                           "pausing": page.pause_requested.is_set()}).encode()
                    self._send(200, body, "application/json")
                else:
                    self._send(404, b"not found", "text/plain")

            def do_POST(self):
                length = min(int(self.headers.get("Content-Length", 0) or 0), 65536)
                try:
                    body = json.loads(self.rfile.read(length) or b"{}")
                except ValueError:
                    return self._send(400, b"not JSON", "text/plain")
                if self.path == "/abort":
                    page.aborted.set()
                    return self._send(200, b"{}", "application/json")
                if self.path == "/pause":
                    if page.started:
                        page.pause_requested.set()
                    return self._send(200, b"{}", "application/json")
                if self.path == "/answer":
                    with page._lock:
                        if body.get("token") == page._token and page._answer is None:
                            page._answer = body.get("value")
                    return self._send(200, b"{}", "application/json")
                self._send(404, b"not found", "text/plain")

        self.server = ThreadingHTTPServer(("127.0.0.1", port), Handler)
        self.port = self.server.server_address[1]
        self._thread = threading.Thread(target=self.server.serve_forever, daemon=True)
        self._thread.start()

    def show(self, **state) -> None:
        with self._lock:
            self._token += 1
            self._answer = None
            self._state = {**state, "token": self._token}

    def wait_answer(self, valid) -> Any:
        """The answer to the prompt shown; the page then says to wait until the next."""
        while True:
            if self.aborted.is_set():
                raise Aborted()
            with self._lock:
                answer = self._answer
                if answer is not None and not valid(answer):
                    self._answer = None  # not an answer to this prompt: wait for one
                    answer = None
            if answer is not None:
                self.show(phase="message", text="Please wait")
                return answer
            time.sleep(0.01)

    def wait(self, seconds: float) -> None:
        if self.aborted.wait(seconds):
            raise Aborted()

    def close(self) -> None:
        self.server.shutdown()
        self.server.server_close()


class PersonAtDevice:
    """The participant: a person at `device`, answering on the page (see the module's text).
    `interval_s`: each interval's length; `run_options`: toonforce.live.Run's keyword
    arguments (realtime, script for the simulated device, trace_path, ...)."""

    def __init__(self, exp: experiments.Experiment, device: str = "sim", port: int = 0, interval_s: float = 3.0,
                 blank_s: float = 0.5, **run_options):
        from toonforce import _toonforce
        from toonforce.live import Run

        self.experiment = exp
        self.interval_s = interval_s
        self.blank_s = blank_s
        self._toml = lambda scene: _toonforce.toml_from_dict(scene)
        self.page = _Page(port)
        first = exp.conditions[exp.used_conditions()[0]]
        self._silent = self._toml(silent_scene(scene_with(first, None))) + "\n"
        self.run = Run(self._silent, device=device, **run_options)
        trace = run_options.get("trace_path") or run_options.get("trace")
        self._trace = os.path.basename(trace) if trace else None
        self._last_block: Optional[int] = None
        self._intervals: list = []  # the trial's intervals: [frame its scene was sent, frame the silence was]
        # The device is up and silent: the page asks the participant to start (prepare waits).
        self.page.show(phase="start", title=exp.name, text=exp.instructions)

    @property
    def url(self) -> str:
        return f"http://127.0.0.1:{self.page.port}/"

    def close(self) -> None:
        """Ends the run (zero force through its stop path) and the page."""
        self.run.stop()
        self.page.show(phase="message", text="The session was stopped" if self.page.aborted.is_set()
                       else "Thank you: the session has ended")
        time.sleep(0.2)
        self.page.close()

    # ---- presenting ---------------------------------------------------------------------

    def _load(self, text: str, name: str) -> int:
        """Loads a scene and waits until the loop has applied it; the frames received before it
        was sent (the loop applies it at a later tick)."""
        before = self.run.frames_received
        try:
            self.run.wait_applied(self.run.load(text, name))
        except Exception:
            if self.page.aborted.is_set():
                raise Aborted()
            raise
        return before

    def _present(self, condition: str, level: Optional[float], number: int, of: int, instructions: str) -> None:
        """One interval: the condition's scene while the page says so, then the silent scene
        (the force ramps out) through the blank and whatever follows until the next interval."""
        c = self.experiment.conditions[condition]
        on = self._load(self._toml(scene_with(c, level if c.vary else None)), condition)
        self.page.show(phase="interval", number=number, of=of, instructions=instructions)
        self.page.wait(self.interval_s)
        off = self._load(self._silent, "silent")
        self._intervals.append([on, off])
        self.page.show(phase="blank")
        self.page.wait(self.blank_s)

    def prepare(self, block: experiments.Block, index: int) -> None:
        """Before each trial, the device silent: the first waits for the participant's Start, any
        for the end of a pause the participant asked for (the Pause key during the trial before),
        the first of a block for the end of the break before it. A trial's record and its part of
        the trace begin after this."""
        if not self.page.started:
            self.page.wait_answer(lambda a: a == "start")  # the page has shown Start since the run is up
            self.page.started = True
        if self.page.pause_requested.is_set():
            self.page.show(phase="paused", text="Press Continue when you are ready.")
            self.page.wait_answer(lambda a: a == "continue")
            self.page.pause_requested.clear()
        if self._last_block is not None and self._last_block != index:
            self.page.show(phase="break", text=f"Next: {block.name}. Press Continue when you are ready.")
            self.page.wait_answer(lambda a: a == "continue")
        self._last_block = index

    def _guard(self, present):
        """Presents a trial; its result names the part of the run's trace it was (the frames'
        sequence numbers: one per tick the loop ran, so the trace's data rows), or stops the run
        with zero force if the participant aborts."""
        first = self.run.frames_received
        self._intervals = []
        try:
            result = present()
            if self._trace:
                result["trace"] = {"file": self._trace, "frames": [first, self.run.frames_received],
                                   "intervals": self._intervals}
            return result
        except Aborted:
            self.run.stop()  # zero force now; the session ends without this trial
            raise

    # ---- the procedures' trials ----------------------------------------------------------

    def _ask(self, block) -> Dict[str, Any]:
        """The block's two-interval question; the answer (1 or 2) and the time to it."""
        started = time.monotonic()
        self.page.show(phase="choice", question=experiments.page_text(block, "question"),
                       answers=experiments.page_text(block, "answers"))
        chose = self.page.wait_answer(lambda a: a in (1, 2))
        return {"answer": chose, "response_time_s": time.monotonic() - started}

    def two_interval(self, block, index, trial, level, test_first) -> Dict[str, Any]:
        def present():
            order = [block.test, block.reference] if test_first else [block.reference, block.test]
            for k, condition in enumerate(order):
                self._present(condition, level if condition == block.test else None, k + 1, 2,
                              experiments.page_text(block, "instructions"))
            asked = self._ask(block)
            return {"correct": asked["answer"] == (1 if test_first else 2), **asked}

        return self._guard(present)

    def compare(self, block, index, trial, first, second) -> Dict[str, Any]:
        def present():
            for k, condition in enumerate((first, second)):
                self._present(condition, None, k + 1, 2, experiments.page_text(block, "instructions"))
            asked = self._ask(block)
            return {"chose": asked["answer"], "response_time_s": asked["response_time_s"]}

        return self._guard(present)

    def rate(self, block, index, trial, condition) -> Dict[str, Any]:
        items = block.options["items"]

        def valid(a):
            return isinstance(a, dict) and all(isinstance(a.get(i["name"]), int) and 1 <= a[i["name"]] <= i["points"]
                                               for i in items)

        def present():
            self._present(condition, None, 1, 1, experiments.page_text(block, "instructions"))
            self.page.show(phase="rating", question=experiments.page_text(block, "question"), items=items)
            ratings = self.page.wait_answer(valid)
            return {"ratings": {i["name"]: int(ratings[i["name"]]) for i in items}}

        return self._guard(present)

    def perform(self, block, index, trial, condition) -> Dict[str, Any]:
        def present():
            self._present(condition, None, 1, 1, experiments.page_text(block, "instructions"))
            on, off = self._intervals[-1]  # the interval's frames: the task's window
            frames = self.run.telemetry()
            taken = {k: v[-(self.run.frames_received - on):][:off - on] for k, v in frames.items()}
            if "t" in taken and len(taken["t"]):
                taken["t"] = taken["t"] - taken["t"][0]
            return {"metrics": experiments.task_metrics(block.options["task"], taken, block.options)}

        return self._guard(present)
