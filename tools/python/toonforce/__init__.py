"""toonforce from Python: the C++ controller's scene loader, checks, closed-loop simulation,
replay and figures, through the same code as the ``toonforce`` program (issue 30).

    import toonforce
    trace = toonforce.sim("scenes/cartoon_wall.toml", "scenes/hands/strike.toml")
    trace["fx"], trace.units["fx"]          # numpy float64 array, "N"

Scenes and hand scripts are a file path (str or os.PathLike), a ``Scene``/``HandScript`` (from a
file, a TOML string or a dict), or a dict. A dict is written as TOML text and read by the same
loader as a file, so it gets the same checks and messages. Errors in them raise ``SceneError``
(a ValueError) with ``file``, ``line`` (0: the whole file) and ``key`` ("" when none), and as its
text the message ``toonforce`` prints. SI units throughout: metres, seconds, newtons, hertz.
"""
from __future__ import annotations

import os
import warnings as _warnings
from typing import Any, Dict, List, Mapping, Optional, Tuple, Union

from . import _toonforce
from ._toonforce import SceneError
from ._trace import Trace

__all__ = ["SceneError", "PlausibilityWarning", "Scene", "HandScript", "Trace", "check", "sim", "replay",
           "figures", "__version__"]
__version__: str = _toonforce.version

SceneError.__module__ = __name__


class PlausibilityWarning(UserWarning):
    """What ``toonforce sim`` prints as ``toonforce: warning: ...`` (the scene outside the device's
    limits, a trace larger than its limit): the run goes on."""


class _Source:
    _what = "file"

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
        info = _toonforce.scene_info(source, text, "double", True)
        self.name: str = info["name"]  #: the scene's `name`, or the file's stem
        self.values: List[str] = info["values"]  #: its effect values' trace columns

class HandScript(_Source):
    """A hand script of the simulated hand (docs/HAND_SCRIPTS.md), loaded and checked when made."""

    def __init__(self, source: str, text: Optional[str] = None) -> None:
        super().__init__(source, text)
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
    columns, units, summary, warned = _toonforce.sim(
        scene_path, scene_text, script_path, script_text, float(rate_hz), scalar,
        None if duration_s is None else float(duration_s), device, integrator, int(substeps), int(seed),
        None if sensor_noise_m is None else float(sensor_noise_m), sine, allow_empty, strict,
        "" if trace_path is None else os.fspath(trace_path))
    _warn(warned)
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
