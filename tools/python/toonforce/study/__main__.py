# SPDX-License-Identifier: Apache-2.0
"""`python3 -m toonforce.study`: run, resume and analyze study sessions (docs/STUDIES.md).

    python3 -m toonforce.study check EXPERIMENT [--device sim|falcon|omni]
    python3 -m toonforce.study run EXPERIMENT --participant N --out FOLDER --simulated-threshold T
    python3 -m toonforce.study resume FOLDER
    python3 -m toonforce.study analyze FOLDER... --out REPORT_DIR [--include-flagged]

A session is a person's at a device (--device falcon|omni|sim: the participant answers on the
page the command prints) or a simulated participant's (--simulated-threshold: a model observer
on the simulated device). The experimenter's terminal shows the progress; `p` and Enter pauses
after the trial under way (Enter again goes on); Ctrl-C stops the session (resume goes on).
"""

from __future__ import annotations

import argparse
import os
import sys
import threading
import time

from .analysis import analyze
from .session import Session
from .simulated import SimulatedParticipant


def _participant(session: Session, args):
    spec = session.meta.get("observer")
    if spec:
        block = session.experiment.blocks[spec.get("block", 0)]
        return SimulatedParticipant.with_threshold(session.experiment, block, spec["threshold"],
                                                   spec.get("lapse", 0.0), spec.get("seed", session.meta["seed"]))
    from .person import PersonAtDevice

    # The run's trace beside the trials: run-1.csv, and run-2.csv after a resume, ...
    number = 1
    while os.path.exists(os.path.join(session.folder, f"run-{number}.csv")):
        number += 1
    options = {"realtime": not getattr(args, "allow_non_rt", False),
               "trace_path": os.path.join(session.folder, f"run-{number}.csv")}
    if getattr(args, "hand", None):
        options["script"] = args.hand
    person = PersonAtDevice(session.experiment, session.meta["device"], port=getattr(args, "page_port", 0),
                            interval_s=getattr(args, "interval", 3.0), **options)
    print(f"toonforce study: the participant's page: {person.url}", file=sys.stderr, flush=True)
    return person


class _Progress:
    """trial N of at most M, the time left at the pace so far; `p` + Enter pauses."""

    def __init__(self, session: Session):
        from .session import planned_trials

        self.total = planned_trials(session)
        self.done = len(session.trials)
        self.started = time.monotonic()
        self.new = 0
        self.paused = threading.Event()
        if sys.stdin is not None and sys.stdin.isatty():
            threading.Thread(target=self._keys, daemon=True).start()

    def _keys(self) -> None:
        for line in sys.stdin:
            if line.strip() == "p" and not self.paused.is_set():
                self.paused.set()
                print("toonforce study: pausing after this trial (Enter goes on)", file=sys.stderr, flush=True)
            elif self.paused.is_set():
                self.paused.clear()

    def before_trial(self) -> None:
        while self.paused.is_set():
            time.sleep(0.05)

    def __call__(self, line: str) -> None:
        self.done += 1
        self.new += 1
        pace = (time.monotonic() - self.started) / self.new
        left = max(0, self.total - self.done) * pace
        width = 30
        filled = min(width, int(width * self.done / max(1, self.total)))
        print(f"[{'#' * filled}{'.' * (width - filled)}] trial {self.done} of at most {self.total}, "
              f"at most {left / 60:.1f} min left | {line}", file=sys.stderr, flush=True)


def _go(session: Session, args) -> int:
    participant = _participant(session, args)
    progress = _Progress(session)

    def before_trial() -> None:  # the experimenter's pause, said on the participant's page too
        if progress.paused.is_set() and hasattr(participant, "page"):
            participant.page.show(phase="message", text="A pause: the experimenter will go on")
        progress.before_trial()

    try:
        session.run(participant, progress=progress, before_trial=before_trial)
    except KeyboardInterrupt:
        print(f"toonforce study: stopped; {len(session.trials)} trials kept in {session.folder} "
              f"(`toonforce study resume {session.folder}` goes on)", file=sys.stderr)
        return 1
    except Exception as e:  # noqa: BLE001 - said, and the session kept
        from .person import Aborted

        if isinstance(e, Aborted):
            print(f"toonforce study: aborted by the participant (zero force); {len(session.trials)} trials kept in "
                  f"{session.folder} (`toonforce study resume {session.folder}` goes on)", file=sys.stderr)
            return 1
        raise
    finally:
        if hasattr(participant, "close"):
            participant.close()
    print(f"toonforce study: session done, {len(session.trials)} trials in {session.folder}", file=sys.stderr)
    return 0


def _check_hand(args) -> None:
    if getattr(args, "hand", None):
        from toonforce import _toonforce

        try:
            _toonforce.script_info(os.path.abspath(args.hand), None)
        except _toonforce.SceneError as e:
            raise ValueError(f"--hand: {e.message.strip()}") from None


def _check_numbers(args) -> None:
    import math

    if not (math.isfinite(args.interval) and args.interval > 0):
        raise ValueError(f"--interval: a length in seconds > 0 (got {args.interval})")
    threshold = getattr(args, "simulated_threshold", None)
    if threshold is not None and not (math.isfinite(threshold) and threshold > 0):
        raise ValueError(f"--simulated-threshold: a level > 0 (got {threshold})")
    lapse = getattr(args, "simulated_lapse", 0.0)
    if not 0.0 <= lapse < 1.0:
        raise ValueError(f"--simulated-lapse: a rate in [0, 1) (got {lapse})")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="toonforce study")
    sub = parser.add_subparsers(dest="command", required=True)
    check = sub.add_parser("check", help="check an experiment file, its scenes and hand scripts (writes nothing)")
    check.add_argument("experiment")
    check.add_argument("--device", choices=("sim", "falcon", "omni"), default="sim",
                       help="the device the sessions will use (its limits)")
    check.add_argument("--hand", help="a hand script the simulated device will be given (--hand of run)")
    run = sub.add_parser("run", help="start a session")
    run.add_argument("experiment")
    run.add_argument("--participant", type=int, required=True)
    run.add_argument("--out", required=True, help="the session's folder (new)")
    run.add_argument("--seed", type=int)
    run.add_argument("--simulated-threshold", type=float,
                     help="a simulated participant: a model observer with this threshold on the first level "
                          "block's test condition (without it: a person at --device)")
    run.add_argument("--simulated-lapse", type=float, default=0.0)
    run.add_argument("--device", choices=("sim", "falcon", "omni"), default="sim")
    resume = sub.add_parser("resume", help="go on with a session from its next trial")
    resume.add_argument("folder")
    for p in (run, resume):
        p.add_argument("--page-port", type=int, default=0, help="the participant's page's port (0: any free one)")
        p.add_argument("--interval", type=float, default=3.0, help="each interval's length [s] (a person)")
        p.add_argument("--hand", help="a hand script for the simulated device (try a session without a device)")
        p.add_argument("--allow-non-rt", action="store_true", help="run the loop without real-time priority")
    report = sub.add_parser("analyze", help="a Markdown report with plots of sessions")
    report.add_argument("folders", nargs="+")
    report.add_argument("--out", required=True)
    report.add_argument("--include-flagged", action="store_true",
                        help="count flagged thresholds (not determined by their data) in the means across participants")
    args = parser.parse_args(argv)
    try:
        if args.command == "check":
            from . import experiment as experiments

            exp = experiments.load(args.experiment, device=args.device)
            _check_hand(args)
            print(f"{exp.path}: ok on the {args.device} device: {len(exp.conditions)} conditions, {len(exp.blocks)} "
                  f"blocks, {len(exp.files)} scenes and hand scripts loaded")
            for path, sha in exp.files.items():
                print(f"  {sha}  {path}")
            return 0
        if args.command == "run":
            import toonforce

            from . import experiment as experiments

            # Everything is checked before the session's folder is written: the file, its scenes
            # and hand scripts on the session's device, the hand given.
            device = "sim" if args.simulated_threshold is not None else args.device
            exp = experiments.load(args.experiment, device=device)
            _check_hand(args)
            _check_numbers(args)
            first = next((i for i, b in enumerate(exp.blocks) if b.procedure in experiments.LEVEL_PROCEDURES), None)
            if first is None and args.simulated_threshold is not None:
                raise ValueError("--simulated-threshold needs a block with a level (a staircase or constant stimuli)")
            if args.simulated_threshold is not None and args.hand:
                raise ValueError("--hand: a simulated participant (--simulated-threshold) answers from its model, "
                                 "with no hand on the device; --hand tries a person's session without a device")
            observer = None
            if args.simulated_threshold is not None:
                observer = {"threshold": args.simulated_threshold, "lapse": args.simulated_lapse, "block": first}
            session = Session.start(args.experiment, args.out, args.participant, args.seed,
                                    "sim" if observer else args.device, observer, toonforce.__version__,
                                    hand=args.hand)
            return _go(session, args)
        if args.command == "resume":
            _check_hand(args)
            _check_numbers(args)
            session = Session(args.folder, resume=True, hand=args.hand)
            if session.done:
                print(f"toonforce study: {args.folder} is done already", file=sys.stderr)
                return 0
            return _go(session, args)
        print(analyze(args.folders, args.out, include_flagged=args.include_flagged))
        return 0
    except (ValueError, FileExistsError, FileNotFoundError) as e:
        print(f"toonforce study: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
