# SPDX-License-Identifier: Apache-2.0
"""A person on a device: each interval is the condition's scene loaded into a running
`toonforce run --control` (toonforce.live) on the Falcon, the Omni or the simulated device, and
the participant answers on a page served here, http://127.0.0.1:PORT/ (the instructions, each
trial's prompt and answer by key or click, a break between blocks, and an abort key).

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


PAGE = """<!doctype html><html><head><meta charset="utf-8"><title>toonforce study</title>
<style>body{font:22px system-ui;margin:3em;max-width:40em}button{font:inherit;margin:.3em}
#abort{position:fixed;right:1em;bottom:1em;background:#c33;color:#fff}.k{opacity:.6;font-size:70%}</style></head>
<body><div id="main">connecting...</div><button id="abort" onclick="post('/abort',{})">Stop (Esc)</button>
<script>
let state = {};
async function post(path, body) { await fetch(path, {method: 'POST', body: JSON.stringify(body)}); }
function answer(v) { post('/answer', {token: state.token, value: v}); }
function render() {
  const m = document.getElementById('main'); const s = state;
  if (s.phase === 'interval') m.innerHTML = `<h1>Interval ${s.number} of ${s.of}</h1><p>${s.instructions || ''}</p>`;
  else if (s.phase === 'blank') m.innerHTML = '<h1>...</h1>';
  else if (s.phase === 'choice') m.innerHTML = `<p>${s.question}</p>` + s.options.map((o, i) =>
      `<button onclick="answer(${i + 1})">${o} <span class=k>[${i + 1}]</span></button>`).join('');
  else if (s.phase === 'rating') m.innerHTML = `<p>${s.question}</p>` + s.items.map(it =>
      `<p>${it.anchors[0]} ` + Array.from({length: it.points}, (_, i) =>
        `<label><input type=radio name="${it.name}" value=${i + 1}>${i + 1}</label>`).join(' ') +
      ` ${it.anchors[1]}</p>`).join('') + '<button onclick="rate()">Done</button>';
  else if (s.phase === 'break') m.innerHTML = `<h1>A break</h1><p>${s.text}</p><button onclick="answer('continue')">Continue [space]</button>`;
  else if (s.phase === 'message') m.innerHTML = `<h1>${s.text}</h1>`;
}
function rate() {
  const v = {}; for (const it of state.items) { const c = document.querySelector(`input[name="${it.name}"]:checked`);
    if (!c) return; v[it.name] = Number(c.value); }
  answer(v);
}
document.addEventListener('keydown', e => {
  if (e.key === 'Escape') post('/abort', {});
  else if (state.phase === 'choice' && /^[1-9]$/.test(e.key) && Number(e.key) <= state.options.length) answer(Number(e.key));
  else if (state.phase === 'break' && e.key === ' ') answer('continue');
});
async function poll() {
  try { const r = await fetch('/state'); const s = await r.json(); if (JSON.stringify(s) !== JSON.stringify(state)) { state = s; render(); } }
  catch (e) {}
  setTimeout(poll, 100);
}
poll();
</script></body></html>"""


class _Page:
    """The participant's page: a state the page polls, answers it posts."""

    def __init__(self, port: int):
        self._lock = threading.Lock()
        self._state: Dict[str, Any] = {"phase": "message", "text": "Please wait"}
        self._answer: Optional[Any] = None
        self._token = 0
        self.aborted = threading.Event()
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
                        body = json.dumps(page._state).encode()
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
        while True:
            if self.aborted.is_set():
                raise Aborted()
            with self._lock:
                answer = self._answer
                if answer is not None and not valid(answer):
                    self._answer = None  # not an answer to this prompt: wait for one
                    answer = None
            if answer is not None:
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
    arguments (realtime, script for the simulated device, trace, ...)."""

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
        self._trace = os.path.basename(run_options["trace"]) if run_options.get("trace") else None
        self._last_block: Optional[int] = None
        self._intervals: list = []  # the trial's intervals: [frame its scene was sent, frame the silence was]

    @property
    def url(self) -> str:
        return f"http://127.0.0.1:{self.page.port}/"

    def close(self) -> None:
        """Ends the run (zero force through its stop path) and the page."""
        self.run.stop()
        self.page.show(phase="message", text="Thank you: the session has ended")
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

    def _block_start(self, block: experiments.Block, index: int) -> None:
        if self._last_block is not None and self._last_block != index:
            self.page.show(phase="break", text=f"Next: {block.name}. Press continue when you are ready.")
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

    def two_interval(self, block, index, trial, level, test_first) -> Dict[str, Any]:
        def present():
            self._block_start(block, index)
            order = [block.test, block.reference] if test_first else [block.reference, block.test]
            for k, condition in enumerate(order):
                self._present(condition, level if condition == block.test else None, k + 1, 2,
                              "Stroke across the surface.")
            started = time.monotonic()
            self.page.show(phase="choice", question=block.options.get("question", "Which interval pushed your "
                                                                                   "hand along?"),
                           options=["the first", "the second"])
            chose = self.page.wait_answer(lambda a: a in (1, 2))
            correct = chose == (1 if test_first else 2)
            return {"correct": correct, "answer": chose, "response_time_s": time.monotonic() - started}

        return self._guard(present)

    def compare(self, block, index, trial, first, second) -> Dict[str, Any]:
        def present():
            self._block_start(block, index)
            for k, condition in enumerate((first, second)):
                self._present(condition, None, k + 1, 2, "Stroke across the surface.")
            started = time.monotonic()
            self.page.show(phase="choice", question=block.options["question"], options=["the first", "the second"])
            chose = self.page.wait_answer(lambda a: a in (1, 2))
            return {"chose": chose, "response_time_s": time.monotonic() - started}

        return self._guard(present)

    def rate(self, block, index, trial, condition) -> Dict[str, Any]:
        items = block.options["items"]

        def valid(a):
            return isinstance(a, dict) and all(isinstance(a.get(i["name"]), int) and 1 <= a[i["name"]] <= i["points"]
                                               for i in items)

        def present():
            self._block_start(block, index)
            self._present(condition, None, 1, 1, "Explore the surface.")
            self.page.show(phase="rating", question="How was it?", items=items)
            ratings = self.page.wait_answer(valid)
            return {"ratings": {i["name"]: int(ratings[i["name"]]) for i in items}}

        return self._guard(present)

    def perform(self, block, index, trial, condition) -> Dict[str, Any]:
        def present():
            self._block_start(block, index)
            self._present(condition, None, 1, 1, block.options.get("instructions", ""))
            on, off = self._intervals[-1]  # the interval's frames: the task's window
            frames = self.run.telemetry()
            taken = {k: v[-(self.run.frames_received - on):][:off - on] for k, v in frames.items()}
            if "t" in taken and len(taken["t"]):
                taken["t"] = taken["t"] - taken["t"][0]
            return {"metrics": experiments.task_metrics(block.options["task"], taken, block.options)}

        return self._guard(present)
