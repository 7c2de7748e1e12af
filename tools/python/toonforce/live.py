# SPDX-License-Identifier: Apache-2.0
"""A real-time run from Python: `toonforce run` on the simulated device, a Falcon or an Omni, in
a process of its own (its loop never waits for Python: the GIL cannot touch the tick), changed
through the live-scene API and read as numpy arrays while it runs.

    import toonforce.live
    with toonforce.live.Run("scenes/wall.toml", device="falcon") as run:
        run.set("surface1", stiffness=800.0)          # the control protocol (toonforce.control)
        time.sleep(2.0)
        frames = run.telemetry()                      # {"t": array [s], "fz": array [N], ...}

The run is `toonforce run --view 0 --control --control-wait`: its loop starts once this object
is connected, so nothing the script sets up comes late, and every frame from the first tick is
read (the viewer's telemetry: each tick's handle position, velocity, forces, the effects'
values). Leaving the `with` block in any way, an exception or Ctrl-C (KeyboardInterrupt)
included, stops the run with SIGTERM: the same stop path as the command line's, which ends on a
zero-force tick. If the Python process itself dies, the run gets SIGTERM from the kernel
(PR_SET_PDEATHSIG) and stops the same way.

Made, it waits for the loop's first frame: a run whose program could not start (a device that
cannot be opened) raises `RunError` with the program's own message. Its verbs are those of
`toonforce.Run` (the run in process): set, add, remove, fire, load, applied, wait_applied,
telemetry, running, stop, wait.
"""

from __future__ import annotations

import asyncio
import ctypes
import json
import os
import re
import secrets
import shutil
import signal
import subprocess
import tempfile
import threading
import time
import tomllib
import warnings
from typing import Any, Dict, List, Mapping, Optional, Sequence, Union

import numpy as np
import websockets

from . import RunError
from .control import Client, parse_announcement

__all__ = ["Run", "RunError", "find_binary"]

_VIEWER = re.compile(r"viewer: (http://[^/\s]+)/")
_OURS = re.compile(r"^(viewer|control): ")  # the announcements; the rest is the program's own
_PR_SET_PDEATHSIG = 1
_BATCH_HEADER = 4  # kind (1 live, 2 history), stride, first sequence number, count


def find_binary() -> str:
    """The toonforce program: $TOONFORCE_BINARY, else `toonforce` on PATH."""
    binary = os.environ.get("TOONFORCE_BINARY") or shutil.which("toonforce")
    if not binary:
        raise RunError("no toonforce program: install it, or set TOONFORCE_BINARY to its path")
    return binary


def _die_with_parent() -> None:
    # In the child, before exec: SIGTERM when the Python process ends, however it ends. (The
    # kernel sends it when the thread that started the run ends: start runs from a thread that
    # lives as long as they do, as a script's or a notebook's main thread does.)
    ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_PDEATHSIG, signal.SIGTERM, 0, 0, 0)


class _Telemetry:
    """The viewer's /ws telemetry on a thread of its own, into a ring of `history_s` seconds of
    frames (at the rate the hello gives) indexed by sequence number. Frames lost on the way (a
    slow reader) show as `lost`."""

    def __init__(self, url: str, origin: str, history_s: float):
        self.history_s = history_s
        self.capacity = 1
        self.columns: List[str] = []
        self.rate_hz = 0.0
        self.lost = 0
        self._lock = threading.Lock()
        self._ring: Optional[np.ndarray] = None
        self._next = 0  # one past the highest sequence number stored
        self._first = 0  # the lowest sequence number still in the ring
        self._hello = threading.Event()
        self._error: Optional[BaseException] = None
        self._loop = asyncio.new_event_loop()
        self._thread = threading.Thread(target=self._loop.run_forever, name="toonforce.live telemetry", daemon=True)
        self._thread.start()
        self._task = asyncio.run_coroutine_threadsafe(self._read(url, origin), self._loop)

    async def _read(self, url: str, origin: str) -> None:
        try:
            async with websockets.connect(url, origin=origin, compression=None, max_size=None) as ws:
                async for message in ws:
                    if isinstance(message, str):
                        self._on_json(json.loads(message))
                    else:
                        self._on_batch(np.frombuffer(message, dtype="<f8"))
        except websockets.ConnectionClosed:
            pass  # the run ended
        except BaseException as e:  # noqa: BLE001 - reported to the reader
            self._error = e
        finally:
            self._hello.set()

    def _on_json(self, message: dict) -> None:
        if message.get("type") == "hello":
            self.columns = list(message["columns"])
            self.rate_hz = float(message.get("rate_hz", 0.0))
            with self._lock:
                self.capacity = max(1, int(self.history_s * (self.rate_hz or 1000.0)))
                self._ring = np.full((self.capacity, len(self.columns)), np.nan)
            self._hello.set()

    def _on_batch(self, batch: np.ndarray) -> None:
        if batch.size < _BATCH_HEADER or self._ring is None:
            return
        stride, first, count = int(batch[1]), int(batch[2]), int(batch[3])
        frames = batch[_BATCH_HEADER:_BATCH_HEADER + stride * count].reshape(count, stride)
        width = min(stride, self._ring.shape[1])
        with self._lock:
            if first > self._next:
                self.lost += first - self._next
            rows = (np.arange(first, first + count) % self.capacity)
            self._ring[rows, :width] = frames[:, :width]
            self._next = max(self._next, first + count)
            self._first = max(self._first, self._next - self.capacity)

    def wait_hello(self, timeout_s: float) -> None:
        if not self._hello.wait(timeout_s):
            raise RunError(f"the viewer's telemetry did not start within {timeout_s:g} s")
        if self._error is not None:
            raise RunError(f"the viewer's telemetry: {self._error}")

    @property
    def error(self) -> Optional[BaseException]:
        """Why the telemetry connection failed (None: it has not)."""
        return self._error

    @property
    def frames_received(self) -> int:
        with self._lock:
            return self._next

    def snapshot(self, last: Optional[int]) -> Dict[str, np.ndarray]:
        with self._lock:
            if self._ring is None:
                return {}
            end = self._next
            start = self._first if last is None else max(self._first, end - last)
            rows = np.arange(start, end) % self.capacity
            data = self._ring[rows].copy()
        return {name: data[:, i] for i, name in enumerate(self.columns) if name}

    def close(self) -> None:
        self._task.cancel()
        self._loop.call_soon_threadsafe(self._loop.stop)
        self._thread.join(5)


class Run:
    """`toonforce run` in its own process, with its control connection and telemetry.

    scene: a scene file's path, or a scene file's text (TOML) when it contains a newline.
    device: "sim", "falcon", "omni" (as `toonforce run --device`).
    script: a hand script for the simulated device (`--script`).
    duration_s: the run ends by itself after this (None: when stopped).
    realtime: False adds --allow-non-rt --no-mlock (a laptop, a test); True wants SCHED_FIFO.
    trace_path: a path for the run's trace CSV (`--trace`); `trace`, its old name, is deprecated.
    history_s: seconds of telemetry kept for telemetry() (at the run's rate).
    args: further `toonforce run` options, as a list of strings.
    start_timeout_s: how long to wait for the run's first frame; change_timeout_s: how long a
    change waits for room in the loop's mailbox (toonforce.control).
    """

    def __init__(self, scene: Union[str, os.PathLike], device: str = "sim", *, script: Optional[str] = None,
                 duration_s: Optional[float] = None, realtime: bool = True, trace_path: Optional[str] = None,
                 history_s: float = 60.0, args: Sequence[str] = (), binary: Optional[str] = None,
                 start_timeout_s: float = 30.0, change_timeout_s: float = 5.0, trace: Optional[str] = None):
        if trace is not None:
            if trace_path is not None:
                raise TypeError("trace_path and its deprecated name trace both given")
            warnings.warn("toonforce.live.Run(trace=...) is deprecated: use trace_path= (as toonforce.Run)",
                          DeprecationWarning, stacklevel=2)
            trace_path = trace
        self.binary = binary or find_binary()
        self.device = device
        self._tmp = tempfile.TemporaryDirectory(prefix="toonforce-live-")
        scene_text = str(scene)
        if "\n" in scene_text:
            path = os.path.join(self._tmp.name, "scene.toml")
            with open(path, "w", encoding="utf-8") as f:
                f.write(scene_text)
            scene_text = path
        self.token = secrets.token_hex(16)
        command = [self.binary, "run", "--device", device, "--scene", scene_text, "--view", "0", "--control",
                   "--control-wait", "--control-token", self.token]
        if script is not None:
            command += ["--script", str(script)]
        if duration_s is not None:
            command += ["--duration", repr(float(duration_s))]
        if not realtime:
            command += ["--allow-non-rt", "--no-mlock"]
        if trace_path is not None:
            command += ["--trace", str(trace_path)]
        command += [str(a) for a in args]
        self.command = command
        self._output: List[str] = []
        # A session of its own: a terminal's Ctrl-C reaches the script, whose stop() then sends
        # the run one SIGTERM. Were the run in the terminal's group too, it would get the SIGINT
        # and then that SIGTERM: a second stop signal, which zeroes the force and exits at once,
        # without the trace's shut-down row.
        self._process = subprocess.Popen(command, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                                         stderr=subprocess.PIPE, text=True, preexec_fn=_die_with_parent,
                                         start_new_session=True)
        self._telemetry: Optional[_Telemetry] = None
        self.control: Optional[Client] = None
        self.returncode: Optional[int] = None
        # Its standard error read from the start on a thread of its own: every wait below ends
        # at its deadline or as soon as the program has ended (its standard error closed),
        # never in a read that waits for a line the program will not write.
        self._said = threading.Condition()
        self._closed = False  # its standard error has ended: the program has, or is ending
        self._reader = threading.Thread(target=self._drain, name="toonforce.live output", daemon=True)
        self._reader.start()
        try:
            deadline = time.monotonic() + start_timeout_s
            viewer, control_url = self._announcements(deadline)
            host = viewer[len("http://"):]
            self._telemetry = _Telemetry(f"ws://{host}/ws", viewer, history_s)
            try:
                self._telemetry.wait_hello(max(0.0, deadline - time.monotonic()))
                # Its hello starts the loop (--control-wait), which then opens the device.
                self.control = Client(control_url, self.token, change_timeout_s=change_timeout_s,
                                      open_timeout_s=max(0.1, deadline - time.monotonic()))
            except Exception:
                if self._ended():
                    raise self._failure() from None  # the program's reason, not the connection's
                raise
            self._started(deadline, start_timeout_s)
        except BaseException:
            self.stop()
            raise

    # ---- start-up -----------------------------------------------------------------------

    def _announcements(self, deadline: float):
        """The viewer's and the control channel's addresses, as the program announces them."""
        viewer = control = None
        seen = 0
        with self._said:
            while viewer is None or control is None:
                for line in self._output[seen:]:
                    if (m := _VIEWER.search(line)) is not None:
                        viewer = m.group(1)
                    try:
                        control, _ = parse_announcement(line)  # the token is ours (--control-token)
                    except ValueError:
                        pass
                seen = len(self._output)
                if viewer is not None and control is not None:
                    break
                left = deadline - time.monotonic()
                if self._closed or left <= 0:
                    break
                self._said.wait(left)
        if viewer is None or control is None:
            if self._ended():
                raise self._failure()
            output = self.output
            raise RunError(f"`{' '.join(self.command)}` did not announce its viewer and control channel"
                           + (f"\n{output}" if output else ""), output, self._process.poll())
        return viewer, control

    def _ended(self, grace_s: float = 5.0) -> bool:
        """Whether the program has ended: at once if it has; if its standard error has closed,
        it is ending, and its exit status follows within `grace_s`."""
        if self._process.poll() is not None:
            return True
        if not self._closed:
            return False
        try:
            self._process.wait(grace_s)
        except subprocess.TimeoutExpired:
            return False
        return True

    def _failure(self) -> RunError:
        """The program has ended before its first frame: its own words (a device that cannot be
        opened: which one, and what to check) and its exit status."""
        self._reader.join(5)  # all it printed: the pipe is closed once it has ended
        said = "".join(line for line in self._output if not _OURS.match(line)).strip()
        return RunError(f"toonforce run --device {self.device} failed (exit status {self._process.returncode})"
                        + (f": {said}" if said else ""), self.output, self._process.returncode)

    def _started(self, deadline: float, timeout_s: float) -> None:
        # The first frame, or the program's end: one that cannot open its device says why on
        # standard error and exits. Its end is seen at the next poll, as is a telemetry
        # connection that failed.
        while self._telemetry.frames_received == 0:
            if self._ended():
                if self._process.returncode == 0:
                    return  # it ended at once, as asked
                raise self._failure()
            if self._telemetry.error is not None:
                raise RunError(f"the viewer's telemetry: {self._telemetry.error}", self.output)
            left = deadline - time.monotonic()
            if left <= 0:
                raise RunError(f"toonforce run --device {self.device}: no frame from the loop within {timeout_s:g} s",
                               self.output)
            time.sleep(min(left, 0.005))

    def _drain(self) -> None:
        for line in self._process.stderr:
            with self._said:
                self._output.append(line)
                self._said.notify_all()
        with self._said:
            self._closed = True
            self._said.notify_all()

    # ---- while it runs ------------------------------------------------------------------

    def set(self, effect: str, keys: Union[None, str, Mapping[str, Any]] = None, **named: Any) -> int:
        """Changes an effect's keys (toonforce.control.Client.set), given as a dict, as keywords
        or as TOML text; the change's sequence. A burst waits for room in the loop's mailbox."""
        if isinstance(keys, str):
            if named:
                raise TypeError("keys as TOML text, or as a dict and/or keywords, not both")
            keys = tomllib.loads(keys)
        return self.control.set(effect, keys, **named)

    def add(self, kind: str, keys: Union[None, str, Mapping[str, Any]] = None, **named: Any) -> int:
        """Adds an effect of `kind` (`toonforce run` refuses it: its trace's columns)."""
        if isinstance(keys, str):
            if named:
                raise TypeError("keys as TOML text, or as a dict and/or keywords, not both")
            keys = tomllib.loads(keys)
        return self.control.add(kind, keys, **named)

    def remove(self, effect: str) -> int:
        """Removes an effect (`toonforce run` refuses it too)."""
        return self.control.remove(effect)

    def fire(self, effect: str, event: str, value: float = 0.0) -> int:
        """A one-shot event ("impact" with its speed in m/s, "look_down"); its sequence."""
        return self.control.fire(effect, event, value)

    def load(self, scene: Any, name: Optional[str] = None) -> int:
        """Another scene with the same list of effects: a scene file's text (a str holding a
        newline), a path, a toonforce.Scene or a dict; its sequence."""
        if isinstance(scene, str) and "\n" in scene:
            return self.control.load(scene, name)
        from . import Scene, _source
        path, text = _source(scene, Scene)
        if text is None:
            with open(path, encoding="utf-8") as f:
                text = f.read()
        return self.control.load(text, name or path)

    @property
    def applied(self) -> int:
        """The sequence of the last change the loop applied (0: none yet)."""
        return self.control.applied()

    def wait_applied(self, sequence: int, timeout_s: float = 5.0) -> int:
        """Waits until the loop has applied change `sequence`."""
        return self.control.wait_applied(sequence, timeout_s)

    def telemetry(self, last: Optional[int] = None) -> Dict[str, np.ndarray]:
        """The frames read so far (at most `history_s` of them; the `last` N if given), one
        numpy array per column, oldest first: t [s], tick, x y z [m], vx vy vz [m/s], fx fy fz
        [N] (commanded), scene_fx.. [N] (the effects' sum before the safety stage), faults,
        limits, state, contact, the effects' values by name, ..."""
        return self._telemetry.snapshot(last) if self._telemetry else {}

    @property
    def frames_received(self) -> int:
        """How many ticks' frames have arrived (sequence numbers from 0)."""
        return self._telemetry.frames_received if self._telemetry else 0

    @property
    def frames_lost(self) -> int:
        """Frames the telemetry did not deliver (a reader too slow for the run's rate)."""
        return self._telemetry.lost if self._telemetry else 0

    @property
    def running(self) -> bool:
        return self._process.poll() is None

    @property
    def output(self) -> str:
        """What the run printed (its summary once it has ended)."""
        return "".join(self._output)

    # ---- the end ------------------------------------------------------------------------

    def wait(self, timeout_s: Optional[float] = None) -> int:
        """Waits for the run to end by itself (--duration); its exit status."""
        self.returncode = self._process.wait(timeout_s)
        return self.returncode

    def stop(self, timeout_s: float = 30.0) -> int:
        """Stops the run as the command line's stop signal does (the loop ends on a zero-force
        tick) and waits for it; its exit status (0 for a run stopped so)."""
        if self.control is not None:
            try:
                self.control.close()
            except Exception:  # noqa: BLE001 - the run may be gone already
                pass
            self.control = None
        if self._process.poll() is None:
            self._process.send_signal(signal.SIGTERM)
            try:
                self._process.wait(timeout_s)
            except subprocess.TimeoutExpired:
                self._process.kill()  # the guardian zeroes the force when the loop's process dies
                self._process.wait()
        self.returncode = self._process.returncode
        if self._telemetry is not None:
            self._telemetry.close()
        if hasattr(self, "_reader"):
            self._reader.join(5)
        self._tmp.cleanup()
        return self.returncode

    def __enter__(self) -> "Run":
        return self

    def __exit__(self, *exc) -> None:
        self.stop()
