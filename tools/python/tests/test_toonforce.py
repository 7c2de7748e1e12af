# SPDX-License-Identifier: Apache-2.0
"""The module against the `toonforce` program: the same numbers, errors and verdicts.

Each comparison runs the program on the same inputs and reads what it writes. The CSVs print
every double in shortest round-trip form, so float() of a field is the double the program held:
the arrays must equal them bit for bit (NaN where the CSV says nan or leaves a field empty)."""
import csv
import pathlib
import subprocess
import tomllib
import warnings

import numpy as np
import pytest

import toonforce

# (scene, hand script or motion, simulated seconds): paper scenarios of `toonforce figures`.
SIM_CASES = [
    ("scenes/cartoon_wall.toml", "scenes/hands/strike.toml", 1.0),
    ("scenes/cliff.toml", "scenes/hands/cross_fast.toml", 1.3),
]
REPLAY_CASES = [
    ("scenes/cartoon_wall.toml", "scenes/motions/strike.csv"),
    ("scenes/cliff.toml", "scenes/motions/crossing_fast.csv"),
]
SCALARS = ["double", "q16.16"]


def read_csv(path: pathlib.Path):
    """Header and columns of a CSV the program wrote, each field as the double it reads back as."""
    with open(path, newline="") as f:
        rows = [r for r in csv.reader(f) if r and not r[0].startswith("#")]
    header, body = rows[0], rows[1:]
    columns = {name: np.array([float(r[i]) if r[i] != "" else np.nan for r in body]) for i, name in enumerate(header)}
    return header, columns


def assert_same_doubles(name: str, ours: np.ndarray, theirs: np.ndarray) -> None:
    assert ours.dtype == np.float64 and ours.shape == theirs.shape, name
    both_nan = np.isnan(ours) & np.isnan(theirs)
    same_bits = ours.view(np.uint64) == theirs.view(np.uint64)
    bad = np.flatnonzero(~(same_bits | both_nan))
    assert bad.size == 0, f"{name}: row {bad[0]}: module {ours[bad[0]]!r}, program {theirs[bad[0]]!r}"


@pytest.mark.parametrize("scalar", SCALARS)
@pytest.mark.parametrize("scene,script,duration_s", SIM_CASES)
def test_sim_arrays_are_the_programs_trace(cli, root, tmp_path, scene, script, duration_s, scalar):
    csv_path = tmp_path / "trace.csv"
    subprocess.run([cli, "sim", "--scene", str(root / scene), "--script", str(root / script), "--duration",
                    str(duration_s), "--scalar", scalar, "--trace", str(csv_path), "--quiet"], check=True)
    header, theirs = read_csv(csv_path)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", toonforce.PlausibilityWarning)
        trace = toonforce.sim(root / scene, root / script, duration_s=duration_s, scalar=scalar)
    assert list(trace) == header
    assert set(trace.units) == set(header)
    assert trace.units["fx"] == "N" and trace.units["t"] == "s" and trace.units["true_vz"] == "m/s"
    assert trace.rows == len(theirs["t"]) == round(duration_s * 1000)
    for name in header:
        assert_same_doubles(name, trace[name], theirs[name])


WORLD = ("scenes/two_players.toml", {"left": "scenes/hands/left_push.toml", "right": "scenes/hands/right_push.toml"})


def test_sim_world_arrays_are_the_programs_trace(cli, root, tmp_path):
    scene, scripts = WORLD
    csv_path = tmp_path / "world.csv"
    command = [cli, "sim", "--scene", str(root / scene), "--fail", "right@1.2", "--trace", str(csv_path), "--quiet"]
    for name, path in scripts.items():
        command += ["--script", f"{name}={root / path}"]
    subprocess.run(command, check=True)
    header, theirs = read_csv(csv_path)
    trace = toonforce.sim_world(root / scene, {n: root / p for n, p in scripts.items()}, fail=("right", 1.2))
    assert list(trace) == header
    assert trace.units["left.fx"] == "N" and trace.units["ball.z"] == "m" and trace.units["held"] == ""
    for name in header:
        assert_same_doubles(name, trace[name], theirs[name])
    # What the README says of it: the couplings' two ends are negations, and the pulled cable
    # holds both devices.
    assert np.array_equal(trace["left.coupling_fx"], -trace["right.coupling_fx"])
    assert trace.summary["held_by"] == "right" and trace.summary["forced_while_held"] == 0
    assert [d["name"] for d in trace.summary["devices"]] == ["left", "right"]


def test_sim_world_names_a_device_without_a_hand_script(root):
    scene, scripts = WORLD
    with pytest.raises(ValueError, match="device 'right' has no hand script"):
        toonforce.sim_world(root / scene, {"left": root / scripts["left"]})
    with pytest.raises(TypeError, match="one-device scene"):
        toonforce.sim_world(toonforce.Scene.__new__(toonforce.Scene), {})


def test_run_world_arrays_are_the_runs_trace_and_name_every_device(root, tmp_path):
    # In real time: the row count is the ticks run (a loaded host skips and counts deadlines), so
    # the arrays are compared with the run's own CSV, not with a simulation.
    scene, scripts = WORLD
    csv_path = tmp_path / "run.csv"
    trace = toonforce.run_world(root / scene, 1.5, {n: root / p for n, p in scripts.items()}, fail=("right", 1.2),
                                trace_path=csv_path)
    header, theirs = read_csv(csv_path)
    assert list(trace) == header
    for name in header:
        assert_same_doubles(name, trace[name], theirs[name])
    assert trace.rows == trace.summary["ticks"] + 1  # and the shut-down row
    assert np.array_equal(trace["left.coupling_fx"], -trace["right.coupling_fx"])
    assert np.abs(trace["left.coupling_fx"]).max() > 0.3
    held = np.flatnonzero(trace["held"] == 1)
    assert len(held) > 0 and trace.summary["held_by"] == "right"
    after = slice(held[0] + 1, None)
    for name in ("left.fx", "left.fy", "left.fz", "right.fx", "right.fy", "right.fz"):
        assert not trace[name][after].any(), name
    assert [(d["name"], d["backend"]) for d in trace.summary["devices"]] == [("left", "sim"), ("right", "sim")]
    assert "device silent" in trace.summary["devices"][1]["faults"]


def test_run_world_refuses_what_it_cannot_run(root):
    scene, scripts = WORLD
    with pytest.raises(ValueError, match="the scene has no device 'middle'"):
        toonforce.run_world(root / scene, 0.1, {"middle": root / scripts["left"]})
    with pytest.raises(ValueError, match="duration_s must be > 0"):
        toonforce.run_world(root / scene, 0)


@pytest.mark.parametrize("scalar", SCALARS)
@pytest.mark.parametrize("scene,motion", REPLAY_CASES)
def test_replay_arrays_are_the_programs_output(cli, root, tmp_path, scene, motion, scalar):
    out = tmp_path / "forces.csv"
    subprocess.run([cli, "replay", "--scene", str(root / scene), "--input", str(root / motion), "--output", str(out),
                    "--scalar", scalar, "--quiet"], check=True)
    header, theirs = read_csv(out)
    trace = toonforce.replay(root / scene, root / motion, scalar=scalar)
    assert list(trace) == header
    for name in header:
        assert_same_doubles(name, trace[name], theirs[name])


def test_scene_from_dict_runs_as_its_file(root):
    """A dict goes through the same loader: the file's own dict gives the file's numbers."""
    scene, script, duration_s = SIM_CASES[0]
    with open(root / scene, "rb") as f:
        as_dict = tomllib.load(f)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", toonforce.PlausibilityWarning)
        from_file = toonforce.sim(root / scene, root / script, duration_s=0.3)
        from_dict = toonforce.sim(as_dict, root / script, duration_s=0.3)
    for name in from_file:
        assert_same_doubles(name, from_dict[name], from_file[name])


BROKEN_SCENE = """name = "broken"

[[surface]]
point = [0.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]
stiffness = -1500.0
damping = 0.0
"""


def test_scene_error_names_file_line_and_key_as_the_program(cli, root, tmp_path):
    path = tmp_path / "broken.toml"
    path.write_text(BROKEN_SCENE)
    program = subprocess.run([cli, "sim", "--scene", str(path), "--script", str(root / "scenes/hands/strike.toml"),
                              "--trace", str(tmp_path / "t.csv")], capture_output=True, text=True)
    assert program.returncode == 1
    with pytest.raises(toonforce.SceneError) as caught:
        toonforce.sim(path, root / "scenes/hands/strike.toml")
    error = caught.value
    assert isinstance(error, ValueError)
    assert str(error) == program.stderr.rstrip("\n")
    assert (error.file, error.line, error.key) == (str(path), 6, "surface[1].stiffness")
    # The same from Scene, as soon as it is made.
    with pytest.raises(toonforce.SceneError) as again:
        toonforce.Scene.from_file(path)
    assert (again.value.file, again.value.line, again.value.key) == (str(path), 6, "surface[1].stiffness")


def test_scene_error_of_a_dict_names_its_key_and_line_in_its_toml():
    surface = {"point": [0.0, 0.0, 0.0], "normal": [0.0, 0.0, 1.0], "stiffness": -1500.0}
    scene = {"name": "bad", "surface": [surface]}
    text = toonforce._toonforce.toml_from_dict(scene)
    with pytest.raises(toonforce.SceneError) as caught:
        toonforce.Scene.from_dict(scene)
    error = caught.value
    assert (error.file, error.key) == ("<dict>", "surface[1].stiffness")
    assert str(error) == f"<dict>:{error.line}: surface[1].stiffness: must be > 0 (got -1500)"
    assert text.splitlines()[error.line - 1].strip().startswith("stiffness = -1500")
    # A misspelt key: the loader's own did-you-mean, and the missing key first (by line); the
    # key named is the misspelt one, the missing key's cause.
    del surface["stiffness"]
    surface["stiffnes"] = 1500.0
    with pytest.raises(toonforce.SceneError) as misspelt:
        toonforce.sim(scene, "no-such-hand-script.toml")  # the scene's errors come first
    assert misspelt.value.key == "surface[1].stiffnes"
    assert str(misspelt.value).splitlines()[1].endswith("surface[1]: unknown key 'stiffnes' (did you mean 'stiffness'?)")
    # check() reports it as `toonforce check` does, as data, without raising.
    report = toonforce.check(scene)
    assert not report["ok"] and report["errors"] == [str(misspelt.value) + "\n"]


def test_scene_error_of_a_bad_hand_script_is_the_programs(cli, tmp_path, root):
    path = tmp_path / "hand.toml"
    path.write_text('name = "h"\n[hand]\nstart = [0.0, 0.0, 0.02]\nflavour = 1\n\n[[segment]]\nhold = 0.5\n')
    program = subprocess.run([cli, "sim", "--scene", str(root / "scenes/wall.toml"), "--script", str(path), "--trace",
                              str(tmp_path / "t.csv")], capture_output=True, text=True)
    assert program.returncode == 1
    with pytest.raises(toonforce.SceneError) as caught:
        toonforce.sim(root / "scenes/wall.toml", path)
    assert str(caught.value) == program.stderr.rstrip("\n")
    assert (caught.value.file, caught.value.line) == (str(path), 4)
    assert caught.value.key == "hand.flavour"


# (arguments to `toonforce check`, as keywords to toonforce.check)
CHECK_CASES = [
    (["scenes/cartoon_wall.toml", "scenes/hands/strike.toml"], {}),
    (["scenes/slippery.toml"], {"device": "omni", "rate_hz": 500}),
    (["scenes/cliff.toml"], {"scalar": "q16.16", "rate_hz": 20000}),
    (["scenes/cliff.toml"], {"scalar": "q16.16", "rate_hz": 90000}),  # a rate Q16.16 cannot hold: exit 2
]


@pytest.mark.parametrize("paths,options", CHECK_CASES)
def test_check_says_what_the_program_says(cli, root, paths, options):
    args = [cli, "check"] + [str(root / p) for p in paths]
    for key, flag in (("device", "--device"), ("rate_hz", "--rate"), ("scalar", "--scalar")):
        if key in options:
            args += [flag, str(options[key])]
    program = subprocess.run(args, capture_output=True, text=True)
    report = toonforce.check(*(root / p for p in paths), **options)
    assert report["exit_code"] == program.returncode
    assert report["ok"] == (program.returncode == 0)
    if report["rate_error"]:
        assert program.stdout == "" and report["text"] == program.stderr
    else:
        assert report["text"] == program.stdout
        lines = program.stdout.splitlines()
        assert [l[8:] for l in lines if l.startswith("warning ")] == report["warnings"]
        assert [l[8:] for l in lines if l.startswith("note    ")] == report["notes"]


def test_check_of_a_broken_scene_is_not_ok(cli, tmp_path):
    path = tmp_path / "broken.toml"
    path.write_text(BROKEN_SCENE)
    program = subprocess.run([cli, "check", str(path)], capture_output=True, text=True)
    report = toonforce.check(path)
    assert program.returncode == 1 and report["exit_code"] == 1 and not report["ok"]
    assert report["text"] == program.stdout
    assert report["errors"] and report["errors"][0].startswith(f"{path}:6: surface[1].stiffness: ")


def test_figures_writes_the_programs_traces(cli, root, tmp_path):
    ours, theirs = tmp_path / "module", tmp_path / "program"
    lines = toonforce.figures(ours, root=str(root), plot=False)
    subprocess.run([cli, "figures", "--out", str(theirs), "--root", str(root), "--no-plot", "--quiet"], check=True)
    names = sorted(p.name for p in theirs.iterdir())
    assert names and sorted(p.name for p in ours.iterdir()) == names
    assert len(lines) == 1 + len(names)
    for name in names:
        assert (ours / name).read_bytes() == (theirs / name).read_bytes(), name


def test_ctrl_c_stops_a_long_sim(root):
    """Ctrl-C during sim() (which holds no GIL) raises KeyboardInterrupt within moments: the run
    stops as the program's does on a signal, not after its hour of simulated time."""
    import os
    import signal
    import sys
    import time

    code = ("import sys, toonforce\n"
            "print('start', flush=True)\n"
            f"toonforce.sim({str(root / 'scenes/wall.toml')!r}, {str(root / 'scenes/hands/strike.toml')!r}, "
            "duration_s=3600)\n"
            "print('finished', flush=True)\n")
    child = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                             env=dict(os.environ))
    assert child.stdout.readline() == "start\n"
    time.sleep(0.5)
    sent = time.monotonic()
    child.send_signal(signal.SIGINT)
    out, err = child.communicate(timeout=30)
    assert time.monotonic() - sent < 15.0  # promptly, with room for a loaded host
    assert "finished" not in out
    assert "KeyboardInterrupt" in err


def _wait_for(condition, timeout_s=5.0):
    import time

    end = time.monotonic() + timeout_s
    while not condition():
        assert time.monotonic() < end, "timed out"
        time.sleep(0.01)


def _telemetry_until(run, rows):
    """The live run's telemetry as it comes, until more than `rows` rows (waiting, not sleeping:
    a loaded host's loop may miss deadlines, so a fixed time need not hold them). The last part
    has rows."""
    parts = []
    _wait_for(lambda: parts.append(run.telemetry()) or sum(p.rows for p in parts) > rows, 60.0)
    return parts


def test_live_run_takes_changes_and_streams_telemetry(root):
    """`toonforce run --device sim` from Python: telemetry while it runs, set/fire through the
    live-scene editor (refused whole when wrong), and the end of the block stopping the loop with
    zero force at its shut-down tick."""
    import signal
    import time

    with toonforce.run(root / "scenes/cartoon_wall.toml", root / "scenes/hands/strike.toml") as r:
        _wait_for(lambda: r.applied == 0 and r.running)
        first = _telemetry_until(r, 50)[-1]
        assert list(first)[:10] == ["t", "x", "y", "z", "vx", "vy", "vz", "fx", "fy", "fz"]
        assert r.units["fz"] == "N"
        stiffer = r.set("surface1", {"stiffness": 800.0})
        fired = r.fire("surface1", "impact", 0.3)
        assert fired > stiffer > 0
        _wait_for(lambda: r.applied >= fired)
        with pytest.raises(ValueError, match="stiffnes"):
            r.set("surface1", "stiffnes = 1.0")
        second = next(p for p in _telemetry_until(r, 50) if p.rows > 0)
        assert second["t"][0] > first["t"][-1]
    assert r.summary["updates_applied"] == 2
    assert r.summary["updates_refused"] == 0
    assert r.summary["stop_signal"] == signal.SIGINT
    last = r.telemetry()
    assert last.rows >= 1 and (last["fx"][-1], last["fy"][-1], last["fz"][-1]) == (0.0, 0.0, 0.0)


def test_an_exception_in_the_block_stops_the_run_with_zero_force(root):
    run = toonforce.run(root / "scenes/wall.toml", root / "scenes/hands/strike.toml")
    with pytest.raises(KeyboardInterrupt):
        with run:
            _wait_for(lambda: run.telemetry().rows > 0)
            raise KeyboardInterrupt
    assert not run.running and run.summary is not None
    last = run.telemetry()
    assert last.rows >= 1 and (last["fx"][-1], last["fy"][-1], last["fz"][-1]) == (0.0, 0.0, 0.0)
