# SPDX-License-Identifier: Apache-2.0
"""Type stubs of toonforce._toonforce, the C++ extension (tools/python/src/module.cpp). Use the
package ``toonforce``, which wraps it; units are SI (m, s, N, Hz)."""
from typing import Any, Dict, List, Optional, Tuple

import numpy as np

version: str
max_sim_duration_s: float  #: the longest simulation [s]: 86400 (one day)

class SceneError(ValueError):
    """A scene or hand script that does not load. str(e) is the message ``toonforce`` prints."""
    message: str  #: the whole message (every error, one per line, sorted by line)
    file: str  #: the file, or the name standing for the text ("<dict>", "<string>")
    line: int  #: line of the error `key` names (the first, or the misspelling behind it), from 1; 0: the whole file
    key: str  #: the offending key's path ("surface[1].stiffness"), "" when none (toonforce refines it)

def toml_from_dict(scene: Dict[str, Any]) -> str:
    """A dict as the TOML text the loaders read (floats in round-trip precision)."""
def scene_info(path: str, text: Optional[str], scalar: str, allow_empty: bool) -> Dict[str, Any]:
    """Loads a scene (file ``path``, or ``text`` named ``path``) for scalar "double", "float" or
    "q16.16": name, source, surfaces, cliffs, values (effect value columns). Raises SceneError."""
def script_info(path: str, text: Optional[str]) -> Dict[str, Any]:
    """Loads a hand script: name, source, duration_s [s]. Raises SceneError."""
def check(scene_path: str, scene_text: Optional[str], script_path: str, script_text: Optional[str], device: str,
          rate_hz: float, scalar: str, allow_empty: bool, strict: bool) -> Dict[str, Any]:
    """``toonforce check`` as data: ok, exit_code, rate_error, errors, notes, warnings, text.
    device "falcon" or "omni"; rate_hz [Hz] 10..100000."""
def sim(scene_path: str, scene_text: Optional[str], script_path: str, script_text: Optional[str], rate_hz: float,
        scalar: str, duration_s: Optional[float], device: str, integrator: str, substeps: int, seed: int,
        sensor_noise_m: Optional[float], sine: Optional[str], allow_empty: bool, strict: bool,
        trace_path: str) -> Tuple[Dict[str, np.ndarray], Dict[str, str], Dict[str, Any], List[str]]:
    """``toonforce sim``: (columns, units, summary, warnings); columns as the CSV's, float64.
    rate_hz [Hz] 10..100000; duration_s [s] (0, 86400] or None for the script's length;
    substeps 1..1000; sensor_noise_m [m] >= 0; trace_path "" for no CSV."""
def sim_world(scene_path: str, scene_text: Optional[str], scripts: List[Tuple[str, str, Optional[str]]],
              rate_hz: float, duration_s: Optional[float], device: str, integrator: str, substeps: int, seed: int,
              fail: Optional[Tuple[str, float]],
              trace_path: str) -> Tuple[Dict[str, np.ndarray], Dict[str, str], Dict[str, Any], List[str]]:
    """``toonforce sim`` of a world: (columns, units, summary, warnings); scripts are (device name,
    path or its stand-in name, text or None); fail is (device name, seconds) or None."""
def run_world(scene_path: str, scene_text: Optional[str], scripts: List[Tuple[str, str, Optional[str]]], device: str,
              rate_hz: float, duration_s: float, sim_device: str, seed: int, fail: Optional[Tuple[str, float]],
              trace_path: str, omni_library: str, priority: int, cpu: int, lock_memory: bool, allow_empty: bool,
              strict: bool) -> Tuple[Dict[str, np.ndarray], Dict[str, str], Dict[str, Any], List[str]]:
    """``toonforce run`` of a world, in real time: (columns, units, summary, warnings); device
    "sim" or "scene"; scripts and fail as sim_world's; duration_s > 0."""
def replay(scene_path: str, scene_text: Optional[str], motion_path: str, motion_text: Optional[str], scalar: str,
           sine: Optional[str], allow_empty: bool, output_path: str) -> Tuple[Dict[str, np.ndarray], Dict[str, str], Dict[str, Any]]:
    """``toonforce replay``: (columns, units, summary); columns as the output CSV's, float64,
    NaN where the CSV's field is empty (a tick whose input was not finite)."""
def figures(out_dir: str, root: str, format: str, plot: bool) -> List[str]:
    """``toonforce figures``: writes NAME.csv and NAME.png/.svg; returns the lines it prints."""

class LiveRun:
    """``toonforce run`` on a thread of its own, with live scene changes (use toonforce.Run)."""
    def __init__(self, scene_path: str, scene_text: Optional[str], script_path: str, device: str, rate_hz: float,
                 duration_s: float, sim_device: str, seed: int, trace_path: str, priority: int, cpu: int,
                 lock_memory: bool, allow_empty: bool, strict: bool) -> None:
        """device "sim", "falcon" or "omni"; rate_hz [Hz] 500..10000; duration_s [s], 0 until stopped;
        priority: SCHED_FIFO 1..99; cpu: -1 for no pinning."""
    def set(self, effect: str, keys_toml: str) -> int: ...
    def add(self, key: str, keys_toml: str) -> int: ...
    def remove(self, effect: str) -> int: ...
    def fire(self, effect: str, event: str, value: float) -> int: ...
    def load(self, text: str, source: str) -> int: ...
    def applied(self) -> int: ...
    def running(self) -> bool: ...
    def units(self) -> Dict[str, str]: ...
    def telemetry(self) -> Dict[str, np.ndarray]: ...
    def stop(self, signal: int) -> None: ...
    def join(self, timeout_s: float) -> Optional[Dict[str, Any]]: ...
