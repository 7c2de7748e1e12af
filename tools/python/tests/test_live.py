# SPDX-License-Identifier: Apache-2.0
"""toonforce.live: a real-time run on the simulated device from Python. What the loop does is
checked against the physics (a penalty wall's force is its stiffness times the depth, before
and after a live change) and the stop path against the trace (every way a script ends, the
run's last row is the zero-force shut-down tick).

The binary is TOONFORCE_BINARY (CTest sets it)."""

import csv
import os
import signal
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest

from toonforce.live import Run

SOURCE_DIR = os.environ.get("TOONFORCE_SOURCE_DIR", os.path.join(os.path.dirname(__file__), "..", "..", ".."))
WALL = os.path.join(SOURCE_DIR, "scenes", "wall.toml")  # a penalty wall at z = 0, 1500 N/m, no damping
STRIKE = os.path.join(SOURCE_DIR, "scenes", "hands", "strike.toml")  # strikes 3 mm through it, holds


def last_row(trace):
    with open(trace, newline="") as f:
        rows = list(csv.DictReader(f))
    assert rows, "an empty trace"
    return rows[-1]


def test_the_wall_pushes_back_with_its_stiffness_before_and_after_a_live_change(tmp_path):
    with Run(WALL, script=STRIKE, realtime=False, trace_path=str(tmp_path / "trace.csv")) as run:
        while run.frames_received < 800:  # the strike lands at about 0.3 s and holds
            time.sleep(0.01)
        run.wait_applied(run.set("surface1", stiffness=750.0))
        seen = run.frames_received
        while run.frames_received < seen + 600:  # past the change's 250-tick fade
            time.sleep(0.01)
        frames = run.telemetry()
    assert run.returncode == 0, run.output
    assert run.frames_lost == 0
    ticks = frames["tick"]
    assert np.all(np.diff(ticks) > 0), "every tick's frame, in order (a missed deadline skips a tick number)"
    depth = -frames["z"]  # m, below the wall at z = 0
    force = frames["scene_fz"]  # N, the scene's force before the safety stage
    inside = np.flatnonzero(depth > 1e-5)
    old = np.isclose(force[inside], 1500.0 * depth[inside], rtol=1e-9, atol=0)
    # live-scenes.md section 5: the update's tick u still gives the old law's force; then the
    # difference D = (1500 - 750) N/m * depth(u) fades linearly to zero over 250 ticks (0.25 s),
    # one step per tick the loop runs (one frame each).
    u = inside[np.argmin(old)] - 1  # the last tick of the old law
    assert old[inside < u + 1].all() and not old[inside > u].any(), "the old law until the update, not after"
    fade = 250
    d = (1500.0 - 750.0) * depth[u]
    k = np.arange(0, fade + 100)
    expected = 750.0 * depth[u + k] + d * np.clip(1.0 - k / fade, 0.0, None)
    assert np.allclose(force[u + k], expected, rtol=0, atol=1e-9), "the fade, then the new law"
    assert d > 0.1  # a change the test can see (0.375 N at the 0.5 mm the hand holds)


def test_an_exception_in_the_script_ends_the_run_on_a_zero_force_tick(tmp_path):
    trace = tmp_path / "trace.csv"
    with pytest.raises(RuntimeError, match="the script failed"):
        with Run(WALL, script=STRIKE, realtime=False, trace_path=str(trace)) as run:
            while run.frames_received < 500:  # in contact, pushing
                time.sleep(0.01)
            assert abs(run.telemetry(last=1)["fz"][0]) > 0.1
            raise RuntimeError("the script failed")
    assert not run.running and run.returncode == 0, run.output
    assert "stopped by SIGTERM" in run.output
    row = last_row(trace)
    assert (float(row["fx"]), float(row["fy"]), float(row["fz"])) == (0.0, 0.0, 0.0)


SCRIPT = textwrap.dedent("""
    import sys, time
    from toonforce.live import Run
    run = Run(sys.argv[1], script=sys.argv[2], realtime=False, trace_path=sys.argv[3])
    with run:
        while run.frames_received < 500:
            time.sleep(0.01)
        print("running", flush=True)
        time.sleep(120)
""")


def script_with_a_run(tmp_path):
    """A Python script that runs the wall and waits, in a session of its own (as a terminal's
    foreground job: Ctrl-C reaches the script and its run alike)."""
    trace = tmp_path / "trace.csv"
    process = subprocess.Popen([sys.executable, "-c", SCRIPT, WALL, STRIKE, str(trace)], stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True, start_new_session=True, env=os.environ.copy())
    line = process.stdout.readline()
    assert line == "running\n", process.stderr.read() if process.poll() is not None else line
    return process, trace


def no_run_left(trace):
    """No toonforce process still has this trace open (the run, its guardian and server ended)."""
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline:
        found = subprocess.run(["pgrep", "-f", str(trace)], capture_output=True, text=True).stdout.split()
        if not found:
            return True
        time.sleep(0.05)
    return False


def test_ctrl_c_in_the_script_ends_the_run_on_a_zero_force_tick(tmp_path):
    process, trace = script_with_a_run(tmp_path)
    os.killpg(process.pid, signal.SIGINT)  # Ctrl-C in its terminal
    _, errors = process.communicate(timeout=60)
    assert "KeyboardInterrupt" in errors
    assert no_run_left(trace)
    row = last_row(trace)
    assert (float(row["fx"]), float(row["fy"]), float(row["fz"])) == (0.0, 0.0, 0.0)


def test_a_script_killed_outright_still_ends_its_run_on_a_zero_force_tick(tmp_path):
    process, trace = script_with_a_run(tmp_path)
    process.kill()  # SIGKILL: no Python code runs; the kernel sends the run SIGTERM (PR_SET_PDEATHSIG)
    process.wait(timeout=30)
    assert no_run_left(trace)
    row = last_row(trace)
    assert (float(row["fx"]), float(row["fy"]), float(row["fz"])) == (0.0, 0.0, 0.0)
