# SPDX-License-Identifier: Apache-2.0
"""toonforce from Python: the C++ controller's scene loader, checks, closed-loop simulation,
replay and figures, through the same code as the ``toonforce`` program.

    import toonforce
    trace = toonforce.sim("scenes/cartoon_wall.toml", "scenes/hands/strike.toml")
    trace["fx"], trace.units["fx"]          # numpy float64 array, "N"

Scenes and hand scripts are a file path (str or os.PathLike), a ``Scene``/``HandScript`` (from a
file, a TOML string or a dict), or a dict. A dict is written as TOML text and read by the same
loader as a file, so it gets the same checks and messages. Errors in them raise ``SceneError``
(a ValueError) with ``file``, ``line`` (0: the whole file) and ``key`` (the offending key's path,
"" when none), and as its text the message ``toonforce`` prints. SI units throughout: metres,
seconds, newtons, hertz.
"""
from __future__ import annotations

import contextlib
import os
import re
import time
import warnings as _warnings
from typing import Any, Dict, List, Mapping, Optional, Tuple, Union

from . import _toonforce
from ._toonforce import SceneError
from ._trace import Trace

__all__ = ["SceneError", "RunError", "PlausibilityWarning", "Scene", "HandScript", "Trace", "Run", "check", "sim",
           "sim_world", "run_world", "replay", "figures", "run", "__version__"]
__version__: str = _toonforce.version


class PlausibilityWarning(UserWarning):
    """What ``toonforce sim`` prints as ``toonforce: warning: ...`` (the scene outside the device's
    limits, a trace larger than its limit): the run goes on."""


class RunError(Exception):
    """A run (``toonforce.Run``, ``toonforce.live.Run``) could not start or failed: its text
    holds the program's own message (a device that cannot be opened: which one, and what to
    check). ``output``: what the program printed (``toonforce.live``), ``returncode`` its exit
    status (None: in process, or still running)."""

    def __init__(self, message: str, output: str = "", returncode: Optional[int] = None):
        super().__init__(message)
        self.output = output
        self.returncode = returncode


# ---- SceneError.key: the offending key ------------------------------------------------------
# The extension sets `key` to the word before the first error's problem ("surface[1]" for
# "FILE:4: surface[1]: unknown key 'stiffnes' ..."): the table, not the key. The loader writes
# each error as "FILE:LINE: KEY: PROBLEM" (tools/config/src/toml_reader.cpp, ErrorList), LINE
# and KEY each left out when there is none, and names an unknown or missing key in its problem;
# so the key path is read from the message here, where every line of it is at hand.
_PLACE = re.compile(r"(?:(\d+):)? ?(?:([A-Za-z0-9_.\[\]-]+): )?(.*)")
_NAMED_KEY = re.compile(r"^(unknown|missing required) (?:key '([^']+)'|\w+ \[\[([^\]]+)\]\])"
                        r"(?: \(did you mean '([^']+)'\?\))?")


def _errors_of(message: str, file: str) -> List[Tuple[int, str, str, str]]:
    """Each error of a loader message: (line, key path, kind of problem, the key meant)."""
    errors = []
    for text in message.splitlines():
        if not text.startswith(file + ":"):
            continue
        line, table, problem = _PLACE.fullmatch(text[len(file) + 1:]).groups()
        key, kind, meant = table or "", "", ""
        named = _NAMED_KEY.match(problem)
        if named is not None:
            kind, name, meant = named.group(1), named.group(2) or named.group(3), named.group(4) or ""
            key = f"{table}.{name}" if table else name
        errors.append((int(line or 0), key, kind, meant))
    return errors


def _name_the_key(error: SceneError) -> None:
    """Sets error.key (and .line) to the first error's offending key, except that a missing
    key one of the same table's unknown keys was meant to be (the loader's "did you mean")
    gives way to that unknown key: the misspelling is the mistake, the missing key its effect."""
    errors = _errors_of(str(error), getattr(error, "file", ""))
    if not errors:
        return
    line, key, kind, _ = errors[0]
    if kind == "missing required":
        table, _, name = key.rpartition(".")
        for other_line, other_key, other_kind, meant in errors:
            if other_kind == "unknown" and meant == name and other_key.rpartition(".")[0] == table:
                line, key = other_line, other_key
                break
    error.key = key
    error.line = line


@contextlib.contextmanager
def _scene_errors():
    try:
        yield
    except SceneError as error:
        _name_the_key(error)
        raise


class _Source:
    def __init__(self, source: str, text: Optional[str]) -> None:
        self.source: str = source  #: the file, or the name standing for it in messages
        self.text: Optional[str] = text  #: the TOML text, or None for a file read when used

    @classmethod
    def from_file(cls, path: Union[str, "os.PathLike[str]"]):
        """From a TOML file."""
        return cls(os.fspath(path), None)

    @classmethod
    def from_toml(cls, text: str, name: str = "<string>"):
        """From TOML text; ``name`` stands for the file in messages."""
        return cls(name, text)

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], name: str = "<dict>"):
        """From a dict (nested dicts are tables, lists of dicts arrays of tables), written as TOML
        text and read by the same loader as a file. ``SceneError.line`` is a line of ``.text``."""
        return cls(name, _toonforce.toml_from_dict(dict(data)))

    def __repr__(self) -> str:
        return f"<toonforce.{type(self).__name__} {self.source}>"


class Scene(_Source):
    """A scene (docs/spec/interfaces.md "Scene files"). Loaded and checked (for the double scalar)
    when made, and again, for the run's scalar, by each use."""

    def __init__(self, source: str, text: Optional[str] = None) -> None:
        super().__init__(source, text)
        with _scene_errors():
            info = _toonforce.scene_info(source, text, "double", True)
        self.name: str = info["name"]  #: the scene's `name`, or the file's stem
        self.values: List[str] = info["values"]  #: its effect values' trace columns

class HandScript(_Source):
    """A hand script of the simulated hand (docs/HAND_SCRIPTS.md), loaded and checked when made."""

    def __init__(self, source: str, text: Optional[str] = None) -> None:
        super().__init__(source, text)
        with _scene_errors():
            info = _toonforce.script_info(source, text)
        self.name: str = info["name"]
        self.duration_s: float = info["duration_s"]  #: the script's length [s]


SceneLike = Union[Scene, str, "os.PathLike[str]", Mapping[str, Any]]
ScriptLike = Union[HandScript, str, "os.PathLike[str]", Mapping[str, Any]]


def _source(value: Any, kind: type) -> Tuple[str, Optional[str]]:
    """(name, text or None) of a scene or hand script given in any of the accepted ways."""
    if isinstance(value, _Source):
        return value.source, value.text
    if isinstance(value, Mapping):
        return "<dict>", _toonforce.toml_from_dict(dict(value))
    if isinstance(value, (str, os.PathLike)):
        return os.fspath(value), None
    raise TypeError(f"a {kind.__name__.lower()} is a path, a dict or a toonforce.{kind.__name__}, "
                    f"not {type(value).__name__}")


def check(scene: SceneLike, script: Optional[ScriptLike] = None, device: str = "falcon", rate_hz: float = 1000.0,
          scalar: str = "double", allow_empty: bool = False, strict: bool = False) -> Dict[str, Any]:
    """What ``toonforce check SCENE [SCRIPT]`` checks and reports, as data (nothing runs).

    Returns a dict: ``ok`` (bool), ``exit_code`` (what the command exits with: 0, 1, or 2 for a
    rate Q16.16 cannot hold), ``errors`` (each as printed; one file's errors are one entry),
    ``notes`` and ``warnings`` (the plausibility report's), ``rate_error`` ("" or the message)
    and ``text`` (exactly what the command prints). device: "falcon" or "omni"; rate_hz: the
    servo rate [Hz], 10 to 100000; scalar: "double", "float" or "q16.16".
    """
    scene_path, scene_text = _source(scene, Scene)
    script_path, script_text = ("", None) if script is None else _source(script, HandScript)
    return _toonforce.check(scene_path, scene_text, script_path, script_text, device, float(rate_hz), scalar,
                            allow_empty, strict)


def _warn(messages: List[str]) -> None:
    for message in messages:
        _warnings.warn(message, PlausibilityWarning, stacklevel=3)


def sim(scene: SceneLike, script: ScriptLike, rate_hz: float = 1000.0, scalar: str = "double",
        duration_s: Optional[float] = None, device: str = "falcon", integrator: str = "rk4", substeps: int = 4,
        seed: int = 1, sensor_noise_m: Optional[float] = None, sine: Optional[str] = None,
        allow_empty: bool = False, strict: bool = False, trace_path: Optional[str] = None) -> Trace:
    """``toonforce sim``: the scene, the hand script and the simulated device in closed loop, in
    simulated time. Returns the trace as a ``Trace`` of numpy arrays holding the same doubles as
    the CSV ``toonforce sim --trace`` writes for the same arguments.

    rate_hz: servo rate [Hz], 10 to 100000; scalar: "double", "float" or "q16.16";
    duration_s: simulated seconds (default: the hand script's length, at most 86400);
    device: "falcon" or "omni"; integrator: "semi-implicit-euler", "velocity-verlet", "rk4" or
    "exact"; substeps: integrator sub-steps per tick, 1 to 1000; seed: sensor noise seed;
    sensor_noise_m: position noise standard deviation [m] (default: the device's, 0);
    sine: "library", "polynomial" or "table" (overrides the scene's impact sine method);
    trace_path: also write the CSV there. Runs without the GIL; Ctrl-C stops it
    (KeyboardInterrupt). Plausibility warnings are PlausibilityWarning; strict makes them errors.
    """
    scene_path, scene_text = _source(scene, Scene)
    script_path, script_text = _source(script, HandScript)
    with _scene_errors():
        columns, units, summary, warned = _toonforce.sim(
            scene_path, scene_text, script_path, script_text, float(rate_hz), scalar,
            None if duration_s is None else float(duration_s), device, integrator, int(substeps), int(seed),
            None if sensor_noise_m is None else float(sensor_noise_m), sine, allow_empty, strict,
            "" if trace_path is None else os.fspath(trace_path))
    _warn(warned)
    return Trace(columns, units, summary, warned)


def sim_world(scene: Union[str, "os.PathLike[str]", Mapping[str, Any]], scripts: Mapping[str, ScriptLike],
              rate_hz: float = 1000.0, duration_s: Optional[float] = None, device: str = "falcon",
              integrator: str = "rk4", substeps: int = 4, seed: int = 1, fail: Optional[Tuple[str, float]] = None,
              trace_path: Optional[str] = None) -> Trace:
    """``toonforce sim`` of a world scene (``[[device]]`` tables, docs/spec/interfaces.md "World
    scenes"): every device simulated with its own hand script, in simulated time. ``scripts``
    maps each device's name to its hand script (a path, a dict or a ``HandScript``); ``fail`` is
    ``(name, seconds)``: that device's cable is pulled then. Returns the trace as a ``Trace``
    holding the same doubles as the CSV ``toonforce sim --trace`` writes: per device
    ``NAME.x``..., ``NAME.fx``..., ``NAME.coupling_fx``..., ``NAME.ball_fx``..., ``NAME.faults``,
    ``NAME.latched``, ``NAME.state``; ``couplingJ.fx``..., ``ball.x``..., ``held``. The world is a
    path or a dict (``toonforce.Scene`` is a one-device scene). Ctrl-C stops it.
    """
    if isinstance(scene, _Source):
        raise TypeError("a world is a path or a dict; toonforce.Scene holds a one-device scene")
    scene_path, scene_text = _source(scene, Scene)
    if not isinstance(scripts, Mapping):
        raise TypeError(f"scripts maps each device's name to its hand script, not {type(scripts).__name__}")
    named = []
    for name, script in scripts.items():
        path, text = _source(script, HandScript)
        named.append((str(name), path, text))
    failing = None if fail is None else (str(fail[0]), float(fail[1]))
    with _scene_errors():
        columns, units, summary, warned = _toonforce.sim_world(
            scene_path, scene_text, named, float(rate_hz), None if duration_s is None else float(duration_s), device,
            integrator, int(substeps), int(seed), failing, "" if trace_path is None else os.fspath(trace_path))
    return Trace(columns, units, summary, warned)


def run_world(scene: Union[str, "os.PathLike[str]", Mapping[str, Any]], duration_s: float,
              scripts: Optional[Mapping[str, ScriptLike]] = None, device: str = "sim", rate_hz: float = 1000.0,
              sim_device: str = "falcon", seed: int = 1, fail: Optional[Tuple[str, float]] = None,
              trace_path: Optional[str] = None, omni_library: Optional[str] = None, priority: int = 80,
              cpu: int = -1, lock_memory: bool = False, allow_empty: bool = False, strict: bool = False) -> Trace:
    """``toonforce run`` of a world scene, in real time, for ``duration_s`` seconds (docs/spec/
    interfaces.md "run of a world scene"): ``device="sim"`` simulates every device, ``"scene"``
    opens each as its ``[[device]]`` table says (Falcons by serial, Omnis by device name through
    ``omni_library`` or libHD). ``scripts`` maps simulated devices' names to hand scripts; a
    device without one holds still. ``fail=(name, seconds)`` pulls a simulated device's cable.
    SCHED_FIFO when permitted, else normal scheduling (said in ``summary["realtime"]``). Returns
    the ``Trace`` of the world's columns, one row a tick run; ``summary["devices"]`` names each
    device, with its faults and, for a device on its own clock, the ages of its readings and
    forces. Ctrl-C stops it with zero force on every device.
    """
    if isinstance(scene, _Source):
        raise TypeError("a world is a path or a dict; toonforce.Scene holds a one-device scene")
    if not duration_s > 0:
        raise ValueError(f"duration_s must be > 0 seconds (got {duration_s})")
    scene_path, scene_text = _source(scene, Scene)
    named = []
    for name, script in (scripts or {}).items():
        path, text = _source(script, HandScript)
        named.append((str(name), path, text))
    failing = None if fail is None else (str(fail[0]), float(fail[1]))
    with _scene_errors():
        columns, units, summary, warned = _toonforce.run_world(
            scene_path, scene_text, named, device, float(rate_hz), float(duration_s), sim_device, int(seed), failing,
            "" if trace_path is None else os.fspath(trace_path), "" if omni_library is None else os.fspath(omni_library),
            int(priority), int(cpu), bool(lock_memory), bool(allow_empty), bool(strict))
    return Trace(columns, units, summary, warned)


def _motion_text(motion: Mapping[str, Any]) -> str:
    """Arrays t, x, y, z [, vx, vy, vz] as the motion CSV replay reads (17 significant digits:
    every double reads back as itself), so they pass the same reader and checks as a file."""
    import io

    import numpy as np

    names = [n for n in ("t", "x", "y", "z", "vx", "vy", "vz") if n in motion]
    data = np.column_stack([np.asarray(motion[n], dtype=np.float64) for n in names])
    out = io.StringIO()
    out.write(",".join(names) + "\n")
    np.savetxt(out, data, delimiter=",", fmt="%.17g")
    return out.getvalue()


def replay(scene: SceneLike, motion: Union[str, "os.PathLike[str]", Mapping[str, Any]], scalar: str = "double",
           sine: Optional[str] = None, allow_empty: bool = False, output_path: Optional[str] = None) -> Trace:
    """``toonforce replay``: the forces for a given motion, open loop, one row per servo tick.

    motion: a motion CSV file (t,x,y,z[,vx,vy,vz] in s, m, m/s) or a dict of arrays with those
    keys (written as that CSV, read by the same reader). scalar: "double", "float" or "q16.16";
    sine: "library", "polynomial" or "table"; output_path: also write the CSV there. Returns a
    ``Trace`` with the output CSV's columns (t, fx, ..., contact, effect values), NaN where the
    CSV leaves a field empty (a tick whose input was not finite). Motion errors raise SceneError.
    """
    scene_path, scene_text = _source(scene, Scene)
    if isinstance(motion, Mapping):
        motion_path, motion_text = "<motion>", _motion_text(motion)
    else:
        motion_path, motion_text = os.fspath(motion), None
    with _scene_errors():
        columns, units, summary = _toonforce.replay(scene_path, scene_text, motion_path, motion_text, scalar, sine,
                                                    allow_empty, "" if output_path is None else os.fspath(output_path))
    warned = [summary["input_note"]] if summary["input_note"] else []
    _warn(warned)
    return Trace(columns, units, summary, warned)


def figures(out_dir: Union[str, "os.PathLike[str]"] = "docs/figures", root: Optional[str] = None,
            format: str = "png", plot: bool = True) -> List[str]:
    """``toonforce figures``: the paper's figures 1-4 (NAME.csv and NAME.png or .svg) in out_dir,
    through the real servo loop. root: the directory holding scenes/ (default as the command's).
    Returns the lines the command prints (where the scenes came from, one line per figure)."""
    return _toonforce.figures(os.fspath(out_dir), "" if root is None else os.fspath(root), format, plot)


def _keys_text(keys: Union[None, str, Mapping[str, Any]], named: Mapping[str, Any]) -> str:
    if isinstance(keys, str):
        if named:
            raise TypeError("keys as TOML text, or as a dict and/or keywords, not both")
        return keys
    merged = dict(keys or {})
    overlap = set(merged) & set(named)
    if overlap:
        raise ValueError(f"key(s) given twice: {', '.join(sorted(overlap))}")
    merged.update(named)
    if not merged:
        raise ValueError("no keys to set")
    return _toonforce.toml_from_dict(merged)


# The live-scene editor's refusal while the loop's mailbox is full (docs/spec/live-scenes.md
# section 2): nothing changed, and the same change passes once the loop has taken one.
_MAILBOX_FULL = re.compile(r"not applied: .*\btry again\s*$")


# How long a stopped loop may take to end (its shut-down tick, the trace's last rows); far more
# than it takes, so that only a loop that does not stop reaches it.
_STOP_TIMEOUT_S = 30.0


def _deprecated(old: str, new: str) -> None:
    _warnings.warn(f"{old} is deprecated: use {new}", DeprecationWarning, stacklevel=3)


class Run:
    """``toonforce run``: the servo loop in real time on its own thread (never holding the GIL),
    with live scene changes and telemetry read while it runs. Use as a context manager::

        with toonforce.run("scenes/wall.toml", "scenes/hands/strike.toml") as r:
            r.set("surface1", stiffness=800.0)         # or {"stiffness": 800.0}, or "stiffness = 800"
            r.fire("surface1", "impact", 0.3)          # v_i [m/s]
            fz = r.telemetry()["fz"]                   # the frames since the last call
        print(r.summary["text"])

    The same verbs as ``toonforce.live.Run`` (the run in a process of its own): set, add,
    remove, fire, load, applied, wait_applied, telemetry, running, stop, wait.

    Made, it waits for the loop's first frame: a run that cannot start (a device that cannot be
    opened) raises ``RunError`` with the program's message. Leaving the block, by its end, an
    exception or Ctrl-C (KeyboardInterrupt), stops the loop through the session's stop (as a
    signal stops the command): its shut-down tick commands zero force. Changes are checked by
    the same reader as scene files and refused whole (ValueError with its message); they reach
    the loop at the start of a tick, one a tick; a burst waits for room (at most
    ``change_timeout_s``, then TimeoutError). The run's scalar is double (the live scene's); the
    list of effects must stay that of the starting scene.
    """

    def __init__(self, scene: SceneLike, script: Optional[ScriptLike] = None, device: str = "sim",
                 rate_hz: float = 1000.0, duration_s: Optional[float] = None, sim_device: str = "falcon",
                 seed: int = 1, trace_path: Optional[str] = None, priority: int = 80, cpu: int = -1,
                 lock_memory: bool = False, allow_empty: bool = False, strict: bool = False,
                 start_timeout_s: float = 30.0, change_timeout_s: float = 5.0) -> None:
        """device: "sim", "falcon" or "omni"; rate_hz: 500 to 10000 Hz; duration_s: None (or 0)
        runs until stopped; script: the simulated hand's script (device "sim"; default: it holds
        still); sim_device: "falcon" or "omni" (the simulated device's model); trace_path: also
        the trace CSV; priority: SCHED_FIFO priority 1-99, normal priority if refused; cpu: pin
        the servo thread (-1: no); lock_memory: mlockall (off by default in a Python process);
        start_timeout_s: how long to wait for the first frame; change_timeout_s: how long a
        change waits for room in the loop's mailbox."""
        scene_path, scene_text = _source(scene, Scene)
        if script is None:
            script_path = ""
        elif isinstance(script, (str, os.PathLike)):
            script_path = os.fspath(script)
        elif isinstance(script, HandScript) and script.text is None:
            script_path = script.source
        else:
            raise TypeError("a run's hand script is a file (as toonforce run --script takes it)")
        self.change_timeout_s = change_timeout_s
        with _scene_errors():
            self._run = _toonforce.LiveRun(scene_path, scene_text, script_path, device, float(rate_hz),
                                           float(duration_s or 0.0), sim_device, int(seed),
                                           "" if trace_path is None else os.fspath(trace_path), int(priority),
                                           int(cpu), lock_memory, allow_empty, strict)
        self.units: Dict[str, str] = self._run.units()  #: the telemetry columns' SI units
        self.summary: Optional[Dict[str, Any]] = None  #: what the run did, once it ended
        self._pending: List[Dict[str, Any]] = []  # frames read before telemetry() was asked
        try:
            self._started(device, start_timeout_s)
        except BaseException:
            self._run.stop(2)
            try:
                self._wait(_STOP_TIMEOUT_S)
            except ValueError:
                pass  # the failure is being raised already
            raise

    def _started(self, device: str, timeout_s: float) -> None:
        # The loop opens the device on its own thread: a device that cannot be opened ends the
        # run with the program's message before any frame. So: the first frame, or the end.
        deadline = time.monotonic() + timeout_s
        while True:
            part = self._run.telemetry()
            if any(len(column) for column in part.values()):
                self._pending.append(part)
                return
            if not self._run.running():
                try:
                    self._wait(None)
                except ValueError as e:
                    raise RunError(f"toonforce run --device {device}: {e}") from None
                return  # it ended at once, as asked (a duration shorter than a frame)
            if time.monotonic() >= deadline:
                raise RunError(f"toonforce run --device {device}: no frame from the loop within {timeout_s:g} s")
            time.sleep(0.002)

    def _change(self, what: str, send) -> int:
        deadline = None
        pause_s = 0.001  # a tick at 1 kHz: the loop takes one change a tick
        while True:
            try:
                return send()
            except ValueError as e:
                if not _MAILBOX_FULL.search(str(e)):
                    raise
                if not self._run.running():
                    raise RunError(f"{what}: the run has ended") from None
                now = time.monotonic()
                if deadline is None:
                    deadline = now + self.change_timeout_s
                elif now >= deadline:
                    raise TimeoutError(f"{e}: still refused after {self.change_timeout_s:g} s") from None
                time.sleep(pause_s)
                pause_s = min(2.0 * pause_s, 0.02)

    def set(self, effect: str, keys: Union[None, str, Mapping[str, Any]] = None, **named: Any) -> int:
        """Replaces keys of `effect` ("surface1": the first [[surface]]), given as a dict, as
        keywords or as TOML text; returns the change's sequence."""
        text = _keys_text(keys, named)
        return self._change(f"set {effect}", lambda: self._run.set(effect, text))

    def add(self, kind: str, keys: Union[None, str, Mapping[str, Any]] = None, **named: Any) -> int:
        """Adds an effect of `kind` ("surface", "cliff") (refused while the run keeps its effect list)."""
        text = _keys_text(keys, named)
        return self._change(f"add {kind}", lambda: self._run.add(kind, text))

    def remove(self, effect: str) -> int:
        """Removes an effect (refused while the run keeps its effect list)."""
        return self._change(f"remove {effect}", lambda: self._run.remove(effect))

    def fire(self, effect: str, event: str, value: float = 0.0) -> int:
        """A one-shot event, e.g. fire("surface1", "impact", 0.3): a transient as at 0.3 m/s."""
        return self._change(f"fire {effect}", lambda: self._run.fire(effect, event, float(value)))

    def load(self, scene: SceneLike, name: Optional[str] = None) -> int:
        """Switches to another scene, whole (its effects' list must match the starting scene's):
        a path, a Scene, a dict, or a scene file's text (a str holding a newline; `name` stands
        for its file in messages)."""
        if isinstance(scene, str) and "\n" in scene:
            path, text = name or "<string>", scene
        else:
            path, text = _source(scene, Scene)
            if text is None:
                with open(path, encoding="utf-8") as f:
                    text = f.read()
        return self._change(f"load {path}", lambda: self._run.load(text, path))

    @property
    def applied(self) -> int:
        """The sequence of the last change the loop applied (0: none yet)."""
        return self._run.applied()

    def wait_applied(self, sequence: int, timeout_s: float = 5.0) -> int:
        """Waits until the loop has applied change `sequence`; `applied` then (TimeoutError after timeout_s)."""
        deadline = time.monotonic() + timeout_s
        while (applied := self._run.applied()) < sequence:
            if time.monotonic() >= deadline:
                raise TimeoutError(f"change {sequence} not applied within {timeout_s:g} s (applied: {applied})")
            time.sleep(0.002)
        return applied

    @property
    def running(self) -> bool:
        return self._run.running()

    def telemetry(self) -> Trace:
        """The frames since the last call, as a Trace (columns as `toonforce run --trace`'s)."""
        part = self._run.telemetry()
        if self._pending:
            import numpy as np

            parts, self._pending = self._pending + [part], []
            part = {name: np.concatenate([p[name] for p in parts]) for name in part}
        return Trace(part, self.units, {}, [])

    def stop(self, signal: int = 2, timeout_s: float = _STOP_TIMEOUT_S) -> Dict[str, Any]:
        """Stops the loop (zero force at its shut-down tick) and waits for it, at most
        `timeout_s` (then RunError: a loop that does not stop); the summary."""
        self._run.stop(signal)
        summary = self._wait(timeout_s)
        if summary is None:
            raise RunError(f"the run's loop did not stop within {timeout_s:g} s of its stop")
        return summary

    def wait(self, timeout_s: Optional[float] = None) -> Optional[Dict[str, Any]]:
        """Waits for the end (a duration_s run); the summary, or None after timeout_s [s]."""
        return self._wait(timeout_s)

    def join(self, timeout_s: Optional[float] = None) -> Optional[Dict[str, Any]]:
        """Deprecated: `wait` (the verb of toonforce.live.Run)."""
        _deprecated("toonforce.Run.join", "wait")
        return self._wait(timeout_s)

    def _wait(self, timeout_s: Optional[float]) -> Optional[Dict[str, Any]]:
        summary = self._run.join(-1.0 if timeout_s is None else float(timeout_s))
        if summary is not None:
            self.summary = summary
        return summary

    def __enter__(self) -> "Run":
        return self

    def __exit__(self, kind, value, traceback) -> bool:
        # The block's end, an exception and Ctrl-C alike: the session's stop, as SIGINT stops
        # `toonforce run` (a run of duration_s that ended already is only joined).
        self.stop()
        return False


def run(scene: SceneLike, script: Optional[ScriptLike] = None, **options: Any) -> Run:
    """Starts ``toonforce run`` (see ``Run``) and returns it; use it in a ``with`` block."""
    return Run(scene, script, **options)
