"""`python3 -m toonforce.study`: run, resume and analyze study sessions (docs/STUDIES.md).

    python3 -m toonforce.study run EXPERIMENT --participant N --out FOLDER --simulated-threshold T
    python3 -m toonforce.study resume FOLDER
    python3 -m toonforce.study analyze FOLDER... --out REPORT_DIR

Today a session's participant is a simulated one (a model observer on the simulated device):
the participant's page and the device trials for a person are not built yet.
"""

from __future__ import annotations

import argparse
import sys

from .analysis import analyze
from .session import Session
from .simulated import SimulatedParticipant


def _participant(session: Session) -> SimulatedParticipant:
    spec = session.meta.get("observer")
    if not spec:
        sys.exit("toonforce study: this session has no simulated observer; sessions with a person are not "
                 "supported yet (docs/STUDIES.md)")
    block = session.experiment.blocks[spec.get("block", 0)]
    return SimulatedParticipant.with_threshold(session.experiment, block, spec["threshold"], spec.get("lapse", 0.0),
                                               spec.get("seed", session.meta["seed"]))


def _go(session: Session) -> int:
    participant = _participant(session)
    try:
        session.run(participant, progress=lambda line: print(line, file=sys.stderr, flush=True))
    except KeyboardInterrupt:
        print(f"toonforce study: stopped; {len(session.trials)} trials kept in {session.folder} "
              f"(`toonforce study resume {session.folder}` goes on)", file=sys.stderr)
        return 1
    print(f"toonforce study: session done, {len(session.trials)} trials in {session.folder}", file=sys.stderr)
    return 0


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="toonforce study")
    sub = parser.add_subparsers(dest="command", required=True)
    run = sub.add_parser("run", help="start a session")
    run.add_argument("experiment")
    run.add_argument("--participant", type=int, required=True)
    run.add_argument("--out", required=True, help="the session's folder (new)")
    run.add_argument("--seed", type=int)
    run.add_argument("--simulated-threshold", type=float, required=True,
                     help="a model observer with this threshold on the first level block's test condition")
    run.add_argument("--simulated-lapse", type=float, default=0.0)
    resume = sub.add_parser("resume", help="go on with a session from its next trial")
    resume.add_argument("folder")
    report = sub.add_parser("analyze", help="a Markdown report with plots of sessions")
    report.add_argument("folders", nargs="+")
    report.add_argument("--out", required=True)
    args = parser.parse_args(argv)
    try:
        if args.command == "run":
            import toonforce

            from . import experiment as experiments

            exp = experiments.load(args.experiment)
            first = next((i for i, b in enumerate(exp.blocks) if b.procedure in experiments.LEVEL_PROCEDURES), None)
            if first is None:
                raise ValueError("--simulated-threshold needs a block with a level (a staircase or constant stimuli)")
            observer = {"threshold": args.simulated_threshold, "lapse": args.simulated_lapse, "block": first}
            session = Session.start(args.experiment, args.out, args.participant, args.seed, "sim", observer,
                                    toonforce.__version__)
            return _go(session)
        if args.command == "resume":
            session = Session(args.folder)
            if session.done:
                print(f"toonforce study: {args.folder} is done already", file=sys.stderr)
                return 0
            return _go(session)
        print(analyze(args.folders, args.out))
        return 0
    except (ValueError, FileExistsError, FileNotFoundError) as e:
        print(f"toonforce study: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
