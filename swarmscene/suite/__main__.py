"""``python -m swarmscene.suite``: score a suite sweep, or write the leaderboard page.

``python -m swarmscene.suite score multirun/suite_v1`` writes multirun/suite_v1/suite/ (again);
``python -m swarmscene.suite page multirun/suite_v1 --reference`` writes docs/suite.md's tables,
docs/suite/*.png, and the package's reference scores; ``python -m swarmscene.suite check
multirun/suite_v1`` says whether the sweep reproduces those reference scores.
"""

from __future__ import annotations

import argparse
import sys


def main(argv: list[str] | None = None) -> int:
    """Run the subcommand; one line on stderr and status 1 on a problem."""
    parser = argparse.ArgumentParser(prog="python -m swarmscene.suite", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    score = sub.add_parser("score", help="score a sweep directory's runs (writes SWEEP_DIR/suite/)")
    score.add_argument("sweep_dir")
    score.add_argument("--version", default="v1")
    score.add_argument("--no-reference", action="store_true", help="leave out the shipped reference results")
    page = sub.add_parser("page", help="docs/suite.md and its pictures from SWEEP_DIR/suite/")
    page.add_argument("sweep_dir")
    page.add_argument("--docs", default="docs/suite.md")
    page.add_argument("--reference", action="store_true",
                      help="also make these the shipped reference results (swarmscene/suite/reference_<version>.csv)")
    check = sub.add_parser("check", help="whether SWEEP_DIR's runs reproduce the shipped reference scores "
                           "(exit 1 if not)")
    check.add_argument("sweep_dir")
    check.add_argument("--version", default="v1")
    check.add_argument("--rtol", type=float, default=1e-12,
                       help="relative difference allowed where a score is not the same float (default 1e-12)")
    check.add_argument("--partial", action="store_true",
                       help="compare only the runs the sweep holds (a sweep of some tasks or seeds)")
    args = parser.parse_args(argv)
    try:
        if args.command == "check":
            from .check import check_sweep

            reproduced, text = check_sweep(args.sweep_dir, args.version, args.rtol, args.partial)
            print(text)
            return 0 if reproduced else 1
        if args.command == "score":
            from .callback import score_and_write

            print(score_and_write(args.sweep_dir, args.version, not args.no_reference))
        else:
            from .page import write_page

            for path in write_page(args.sweep_dir, args.docs, args.reference):
                print(f"wrote {path}")
    except (OSError, ValueError, ImportError, KeyError) as exc:
        print(f"swarmscene: {exc}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
