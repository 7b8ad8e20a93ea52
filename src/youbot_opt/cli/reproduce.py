"""``youbot-opt reproduce-study1``: reproduce study 1 with its own and the correct transcription.

Usage::

    youbot-opt reproduce-study1 [--quick] [--out DIR] [--starts K] [--seed S]
                                [--workers W] [--serial] [--from-json FILE]

Runs :func:`youbot_opt.reproduction.reproduce_study1` (the full study takes
several minutes on 2 cores; ``--quick`` runs a subset in about 15 s), writes
``study1_reproduction.json`` and ``study1_reproduction.md`` to ``DIR``
(default ``reproduction_study1``) and prints the markdown tables.
``--from-json`` rebuilds the tables from a saved JSON file without solving.
Exit code 0 when every base-case solve converged, 1 otherwise.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

__all__ = ["register"]


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Add the ``reproduce-study1`` sub-command.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The dispatcher's sub-parsers.
    """
    p = sub.add_parser(
        "reproduce-study1",
        help="reproduce study 1 (its transcription and the correct ones), certified",
        description="Reproduce study 1 with the study's own transcription and the correct "
        "ones; write JSON and markdown tables.",
    )
    p.add_argument("--quick", action="store_true", help="a fast subset (about 15 s)")
    p.add_argument("--out", default="reproduction_study1", metavar="DIR",
                   help="output directory (default: reproduction_study1)")  # fmt: skip
    p.add_argument("--starts", type=int, default=None, metavar="K",
                   help="spline starts of the base case (default: 50, quick: 3)")  # fmt: skip
    p.add_argument("--seed", type=int, default=0, help="base seed of every multistart")
    p.add_argument("--workers", type=int, default=None, help="parallel starts (default: CPUs)")
    p.add_argument("--serial", action="store_true", help="run starts in this process")
    p.add_argument("--from-json", default=None, metavar="FILE",
                   help="rebuild the tables from a saved JSON file, without solving")  # fmt: skip
    p.set_defaults(func=_run)


def _run(args: argparse.Namespace) -> int:
    from youbot_opt.exceptions import ParameterError
    from youbot_opt.reproduction.report import write_report
    from youbot_opt.reproduction.runs import ReproductionConfig, reproduce_study1

    if args.from_json is not None:
        try:
            data = json.loads(Path(args.from_json).read_text())
        except (OSError, ValueError) as exc:
            raise ParameterError(
                f"cannot read {args.from_json!r}: {exc}", name="from_json"
            ) from exc
    else:
        changes: dict[str, Any] = {"seed": args.seed, "workers": args.workers}
        if args.starts is not None:
            changes["n_starts"] = args.starts
        if args.serial:
            changes["executor"] = "serial"
        config = (
            ReproductionConfig.quick(**changes) if args.quick else ReproductionConfig(**changes)
        )
        tic = time.perf_counter()

        def progress(message: str) -> None:
            print(f"[{time.perf_counter() - tic:7.1f} s] {message}", file=sys.stderr, flush=True)

        data = reproduce_study1(config, progress=progress).to_json()
    json_path, md_path = write_report(data, args.out)
    print(md_path.read_text())
    print(f"wrote {json_path} and {md_path}", file=sys.stderr)
    ok = all(b["best"] is not None and b["success_rate"] > 0 for b in data["base"].values())
    return 0 if ok else 1
