# SPDX-License-Identifier: Apache-2.0
"""The Python API says what is wrong: a run whose device cannot be opened raises with the
program's own message; a burst of changes waits for the loop's mailbox (docs/PYTHON.md) instead
of being refused; the two run classes (toonforce.Run in process, toonforce.live.Run out of it)
share one vocabulary, old names warning; SceneError.key names the offending key; the example
notebook shows its figures inline, in Jupyter as under nbconvert with no display.

TOONFORCE_BINARY and TOONFORCE_CLI are the program (CTest sets them)."""

import contextlib
import glob
import json
import os
import signal
import subprocess
import time

import pytest

import toonforce
import toonforce.control
import toonforce.live

SOURCE_DIR = os.environ.get("TOONFORCE_SOURCE_DIR", os.path.join(os.path.dirname(__file__), "..", "..", ".."))
WALL = os.path.join(SOURCE_DIR, "scenes", "wall.toml")  # one [[surface]], 1500 N/m


def falcon_attached():
    for device in glob.glob("/sys/bus/usb/devices/*"):
        try:
            with open(os.path.join(device, "idVendor")) as v, open(os.path.join(device, "idProduct")) as p:
                if (v.read().strip(), p.read().strip()) == ("0403", "cb48"):
                    return True
        except OSError:
            pass
    return False


# ---- a device that cannot be opened ---------------------------------------------------------


@pytest.fixture(scope="module")
def falcon_refusal():
    """What `toonforce run --device falcon` itself says on this machine (no Falcon attached)."""
    if falcon_attached():
        pytest.skip("a Falcon is attached: it opens")
    program = subprocess.run([os.environ["TOONFORCE_CLI"], "run", "--device", "falcon", "--scene", WALL,
                              "--allow-non-rt", "--no-mlock"], capture_output=True, text=True, timeout=60)
    assert program.returncode != 0 and program.stderr.strip(), "the program fails without a Falcon, saying why"
    return program.stderr.strip()


def test_a_live_run_whose_device_cannot_be_opened_raises_with_the_programs_message(falcon_refusal):
    with pytest.raises(toonforce.RunError) as caught:
        toonforce.live.Run(WALL, device="falcon", realtime=False)
    assert falcon_refusal in str(caught.value)
    assert caught.value.returncode not in (None, 0)
    assert toonforce.live.RunError is toonforce.RunError  # the old name still catches it


def test_an_in_process_run_whose_device_cannot_be_opened_raises_with_the_programs_message(falcon_refusal):
    with pytest.raises(toonforce.RunError) as caught:
        toonforce.Run(WALL, device="falcon")
    assert falcon_refusal in str(caught.value)


# ---- a start that has failed is not waited for ------------------------------------------------
# A program (or loop) that has ended before its first frame is known to have failed at the next
# poll: the start must raise then, with its message, not poll on until start_timeout_s. The
# polls are counted, each after the run has ended: at most the one under way when it ended.


class PollCounter:
    """Stands for a module's `time`: its sleep counts the polls made once `ended()` is true."""

    def __init__(self, ended):
        self.ended = ended
        self.after_end = 0
        self.monotonic = time.monotonic

    def sleep(self, seconds):
        if self.ended():
            self.after_end += 1
        time.sleep(seconds)


def test_a_live_run_that_fails_after_announcing_raises_at_once(tmp_path, monkeypatch):
    # A trace in a folder that does not exist: the program announces, the loop starts and the
    # program ends (exit status 2) saying so.
    started = []

    class Recorded(subprocess.Popen):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            started.append(self)

    clock = PollCounter(lambda: bool(started) and started[0].poll() is not None)
    monkeypatch.setattr(toonforce.live.subprocess, "Popen", Recorded)
    monkeypatch.setattr(toonforce.live, "time", clock)
    with pytest.raises(toonforce.RunError) as caught:
        toonforce.live.Run(WALL, realtime=False, trace_path=str(tmp_path / "no-such-folder" / "trace.csv"))
    assert "cannot open the trace for writing" in str(caught.value), str(caught.value)
    assert caught.value.returncode == 2
    assert clock.after_end <= 1, f"{clock.after_end} polls after the program had ended"


def test_an_in_process_run_that_fails_at_start_raises_at_once(tmp_path, monkeypatch):
    made = []
    real = toonforce._toonforce.LiveRun

    def recorded(*args):
        made.append(real(*args))
        return made[-1]

    clock = PollCounter(lambda: bool(made) and not made[0].running())
    monkeypatch.setattr(toonforce._toonforce, "LiveRun", recorded)
    monkeypatch.setattr(toonforce, "time", clock)
    with pytest.raises(toonforce.RunError, match="cannot open the trace for writing"):
        toonforce.Run(WALL, trace_path=str(tmp_path / "no-such-folder" / "trace.csv"))
    assert clock.after_end <= 1, f"{clock.after_end} polls after the loop had ended"


class StillWaiting(Exception):
    pass


@contextlib.contextmanager
def interrupted_after(seconds):
    """Interrupts a wait (SIGALRM) still under way after `seconds`, far more than it needs."""
    def interrupt(signum, frame):
        raise StillWaiting(f"still waiting after {seconds} s")

    previous = signal.signal(signal.SIGALRM, interrupt)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


def test_a_live_run_whose_program_rejects_its_scene_raises_its_message_at_once(tmp_path):
    # The program reads the scene before it announces anything, and ends. The start must see
    # that end, not wait for announcements until start_timeout_s (an hour here).
    bad = tmp_path / "bad.toml"
    bad.write_text(open(WALL).read().replace("stiffness = 1500.0", "stiffness = -1500.0"))
    assert "-1500" in bad.read_text()
    with pytest.raises(toonforce.RunError) as caught, interrupted_after(120):
        toonforce.live.Run(str(bad), realtime=False, start_timeout_s=3600.0)
    said = f"{bad}:22: surface[1].stiffness: must be > 0 (got -1500)"  # the loader's words, as check says
    assert said in caught.value.output and said in str(caught.value)
    assert caught.value.returncode not in (None, 0)


# ---- a burst of changes ----------------------------------------------------------------------
# The loop takes one change a tick from a mailbox of a few (docs/spec/live-scenes.md): twenty
# changes in a row outrun it; each must wait for room, not be refused with "try again".


def burst(run):
    sequences = [run.set("surface1", stiffness=1000.0 + i) for i in range(20)]
    assert sequences == list(range(sequences[0], sequences[0] + 20)), "each change accepted, in order"
    assert run.wait_applied(sequences[-1]) >= sequences[-1]


def test_a_burst_of_changes_waits_for_the_in_process_loop():
    with toonforce.Run(WALL) as run:
        burst(run)
    assert run.summary["updates_applied"] == 20 and run.summary["updates_refused"] == 0


def test_a_burst_of_changes_waits_for_the_live_runs_loop():
    with toonforce.live.Run(WALL, realtime=False) as run:
        burst(run)
        assert run.control.current_scene()["effects"][0]["params"]["stiffness"] == 1019.0


def test_a_change_refused_for_a_mailbox_that_never_empties_ends_in_a_timeout():
    # A stand-in server whose loop never takes a change: the client retries, then says so.
    from test_control import StandIn

    seen = []

    def full(message):
        seen.append(message)
        return {"type": "error", "id": message["id"],
                "message": "set surface1: not applied: the loop has not yet taken the 4 change(s) before it "
                           "(it takes one a tick); try again"}

    server = StandIn(full)
    try:
        with toonforce.control.Client(f"ws://127.0.0.1:{server.port}/control", "t", change_timeout_s=0.2) as c:
            with pytest.raises(TimeoutError, match="try again.*still refused after 0.2 s"):
                c.set("surface1", stiffness=1.0)
    finally:
        server.close()
    assert len(seen) > 1 and all(m == dict(seen[0], id=m["id"]) for m in seen), "the same change, sent again"


# ---- one vocabulary --------------------------------------------------------------------------

VERBS = ["set", "add", "remove", "fire", "load", "applied", "wait_applied", "telemetry", "running", "stop", "wait"]


def test_both_run_classes_speak_one_vocabulary(tmp_path):
    for cls in (toonforce.Run, toonforce.live.Run):
        missing = [v for v in VERBS if not hasattr(cls, v)]
        assert not missing, f"{cls.__module__}.{cls.__name__} lacks {missing}"
    with toonforce.Run(WALL, trace_path=str(tmp_path / "in.csv")) as inside:
        a = inside.set("surface1", "stiffness = 900.0")  # TOML text, a dict or keywords, in both
        b = inside.set("surface1", {"stiffness": 800.0})
        assert inside.wait_applied(b) >= b > a and inside.applied >= b
        with pytest.warns(DeprecationWarning, match="use wait"):
            assert inside.join(0.001) is None  # still running
    with pytest.warns(DeprecationWarning, match="use trace_path"):
        outside = toonforce.live.Run(WALL, realtime=False, trace=str(tmp_path / "out.csv"))
    with outside:
        a = outside.set("surface1", "stiffness = 900.0")
        b = outside.set("surface1", {"stiffness": 800.0})
        assert outside.wait_applied(b) >= b > a and outside.applied >= b
    assert os.path.getsize(tmp_path / "in.csv") > 0 and os.path.getsize(tmp_path / "out.csv") > 0


# ---- SceneError.key --------------------------------------------------------------------------


def scene_error(scene):
    with pytest.raises(toonforce.SceneError) as caught:
        toonforce.Scene.from_dict(scene)
    return caught.value


def test_scene_error_key_names_a_misspelt_key():
    surface = {"point": [0.0, 0.0, 0.0], "normal": [0.0, 0.0, 1.0], "stiffnes": 1500.0}
    error = scene_error({"name": "bad", "surface": [surface]})
    # The loader reports the missing key first (its table's line), then the misspelling; the
    # misspelling is the mistake.
    assert "surface[1]: missing required key 'stiffness'" in str(error)
    assert error.key == "surface[1].stiffnes"
    text = toonforce._toonforce.toml_from_dict({"name": "bad", "surface": [surface]})
    assert text.splitlines()[error.line - 1].strip().startswith("stiffnes =")
    # An unknown key at the top, and one beside a complete table: named with their tables.
    whole = {"point": [0.0, 0.0, 0.0], "normal": [0.0, 0.0, 1.0], "stiffness": 1.0}
    assert scene_error({"nme": "bad"}).key == "nme"
    assert scene_error({"surface": [dict(whole, bogus=1.0)]}).key == "surface[1].bogus"
    # A key the loader checks keeps its path, and a key missing alone is named.
    assert scene_error({"surface": [dict(whole, stiffness=-1.0)]}).key == "surface[1].stiffness"
    assert scene_error({"surface": [{"point": [0.0, 0.0, 0.0], "normal": [0.0, 0.0, 1.0]}]}).key == \
        "surface[1].stiffness"


# ---- the notebook ----------------------------------------------------------------------------


def test_the_notebook_shows_its_figures_inline_without_a_display():
    """Its first code cell (the set-up, the backend's choice) and a plot, run by a kernel as
    nbconvert and Jupyter run it: the figure must come back as an image output."""
    nbformat = pytest.importorskip("nbformat")
    nbclient = pytest.importorskip("nbclient")
    pytest.importorskip("ipykernel")
    path = os.path.join(SOURCE_DIR, "examples", "python", "paper_figures.ipynb")
    notebook = nbformat.read(path, as_version=4)
    setup = next(c for c in notebook.cells if c.cell_type == "code")
    plot = nbformat.v4.new_code_cell("plt.plot([0.0, 1.0], [0.0, 1.0]); plt.show()")
    small = nbformat.v4.new_notebook(cells=[setup, plot], metadata=notebook.metadata)
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY", "MPLBACKEND")}
    old = os.environ.copy()
    os.environ.clear()
    os.environ.update(env)  # the kernel inherits this process's environment
    try:
        nbclient.NotebookClient(small, timeout=120, kernel_name="python3").execute()
    finally:
        os.environ.clear()
        os.environ.update(old)
    outputs = small.cells[1].outputs
    assert any("image/png" in o.get("data", {}) for o in outputs), json.dumps(outputs)[:400]
