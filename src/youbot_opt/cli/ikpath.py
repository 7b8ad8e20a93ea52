"""``youbot-opt ikpath``: minimum-motion cyclic joint path through tip targets (study 2).

Examples::

    youbot-opt ikpath --example A --starts 200
    youbot-opt ikpath --example B --method ipopt --starts 200 --json
    youbot-opt ikpath --lengths 3 2 2 --limit 1.5708 --target 0 7 --target 5 0
    youbot-opt ikpath --robot youbot --target 0.3 0.3 --target 0.1 0.5 --target 0.35 0.1

Reachability of every target is decided first (exactly, no sampling); an
unreachable target ends the command with exit status 2 and the verdict. The
exit status is 0 when the best start succeeded and 1 otherwise.

Every run writes one folder (``--out DIR``, or a new
``youbot_opt_runs/ikpath-<UTC time>``; see :mod:`youbot_opt.cli._output`):
``summary.json`` (the ``--json`` object), ``result.json`` (the best result,
:func:`youbot_opt.ikpath.io.load_ikpath_result` reads it), the figures
``ikpath_arm.png``, ``ikpath_convergence.png``, ``ikpath_workspace.png``,
``ikpath_minima.png`` and ``replay.html`` (standalone meshcat animation of the
best path, linear in joint space, ``--segment-time`` seconds per move). An
unreachable target still writes the summary and the workspace figure. The
folder and its files are listed on stderr, so ``--json`` keeps stdout one
JSON object.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import Any

import numpy as np

from youbot_opt.cli._output import json_ready, print_outputs, run_folder, save_figure, write_summary
from youbot_opt.exceptions import ParameterError
from youbot_opt.ikpath.augmented_lagrangian import ALOptions
from youbot_opt.ikpath.chain import PlanarChain
from youbot_opt.ikpath.examples import EXAMPLES, STUDY_E_A, example_problem
from youbot_opt.ikpath.io import save_ikpath_result
from youbot_opt.ikpath.ipopt import IpoptOptions
from youbot_opt.ikpath.multistart import START_KINDS, MultistartResult, run_multistart
from youbot_opt.ikpath.problem import CyclicIKProblem
from youbot_opt.ikpath.reachability import Reachability, ReachVerdict, check_reachability
from youbot_opt.ikpath.solve import METHODS


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Add the ``ikpath`` sub-command."""
    p = sub.add_parser(
        "ikpath",
        help="minimum-motion cyclic IK path through tip targets (study 2)",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    src = p.add_argument_group("arm and targets")
    src.add_argument("--example", choices=sorted(EXAMPLES), help="the study's example A or B")
    src.add_argument("--robot", choices=["youbot"], help="use a real arm (targets: platform x z)")
    src.add_argument("--lengths", type=float, nargs="+", metavar="L", help="link lengths [m]")
    src.add_argument(
        "--target",
        type=float,
        nargs=2,
        action="append",
        metavar=("X", "Y"),
        help="a target in [m] (repeat, in visiting order)",
    )
    lim = p.add_argument_group("joint limits [rad]")
    lim.add_argument("--limit", type=float, metavar="C", help="symmetric limits |q_i| <= C")
    lim.add_argument("--lower", type=float, nargs="+", metavar="L", help="lower limit(s)")
    lim.add_argument("--upper", type=float, nargs="+", metavar="U", help="upper limit(s)")
    lim.add_argument("--no-limits", action="store_true", help="ignore the arm's joint limits")
    run = p.add_argument_group("solver")
    run.add_argument("--method", choices=METHODS, default="al", help="al (default) or ipopt")
    run.add_argument("--starts", type=int, default=1, help="number of starts (1 = zero vector)")
    run.add_argument("--seed", type=int, default=0, help="seed of the random starts")
    run.add_argument("--start-kind", choices=START_KINDS, default="feasible")
    run.add_argument("--workers", type=int, default=None, help="processes (default: CPUs)")
    run.add_argument(
        "--max-wall-time",
        type=float,
        default=None,
        metavar="S",
        help="wall-time limit of each start's solve [s] (status time_limit when reached)",
    )
    out = p.add_argument_group("output")
    out.add_argument(
        "--out",
        metavar="DIR",
        help="run folder (default: a new youbot_opt_runs/ikpath-<UTC time> in the cwd)",
    )
    out.add_argument(
        "--segment-time",
        type=float,
        default=1.0,
        metavar="S",
        help="replay: duration of each move between targets [s] (default 1)",
    )
    out.add_argument("--no-replay", action="store_true", help="do not write replay.html")
    out.add_argument("--json", action="store_true", help="print one JSON object")
    out.add_argument("--no-progress", action="store_true", help="no progress bar on stderr")
    p.set_defaults(func=_run)


def _problem(args: argparse.Namespace) -> CyclicIKProblem:
    """Build the problem from the command line."""
    if args.example:
        if args.lengths or args.target or args.robot:
            raise ParameterError(
                "--example fixes the arm and targets; drop --lengths/--target/--robot",
                name="example",
                value=args.example,
            )
        base = example_problem(args.example)
        chain, targets = base.chain, base.targets
    else:
        if not args.target:
            raise ParameterError(
                "give --example A|B or at least two --target X Y", name="target", value=None
            )
        targets = np.array(args.target)
        if args.robot:
            if args.lengths:
                raise ParameterError(
                    "--robot fixes the lengths", name="lengths", value=args.lengths
                )
            from youbot_opt.ikpath.robot import youbot_chain

            chain = youbot_chain()
        elif args.lengths:
            chain = PlanarChain(lengths=args.lengths)
        else:
            raise ParameterError("give --lengths, --robot or --example", name="lengths", value=None)
    if args.limit is not None or args.lower is not None or args.upper is not None:
        if args.limit is not None and not args.limit > 0:
            raise ParameterError(
                f"--limit must be > 0, got {args.limit}", name="limit", value=args.limit
            )
        lower = (
            args.lower
            if args.lower is not None
            else (-args.limit if args.limit is not None else chain.q_lower)
        )
        upper = (
            args.upper
            if args.upper is not None
            else (args.limit if args.limit is not None else chain.q_upper)
        )
        chain = chain.with_limits(lower, upper)
    return CyclicIKProblem(chain=chain, targets=targets, use_limits=not args.no_limits)


def _num(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


def _verdict_json(v: ReachVerdict) -> dict[str, Any]:
    return {
        "index": v.index,
        "target": v.target.tolist(),
        "verdict": v.status.value,
        "method": v.method,
        "witness": None if v.witness is None else v.witness.tolist(),
        "witness_error": _num(v.witness_error),
        "distance_lower": v.distance_lower,
        "distance_upper": v.distance_upper,
        "nearest": v.nearest.tolist(),
        "message": v.describe(),
    }


def _report(
    args: argparse.Namespace,
    problem: CyclicIKProblem,
    verdicts: tuple[ReachVerdict, ...],
    ms: MultistartResult | None,
) -> dict[str, Any]:
    chain = problem.chain
    doc: dict[str, Any] = {
        "chain": chain.name,
        "lengths": chain.lengths.tolist(),
        "q_lower": [_num(v) for v in chain.q_lower] if problem.bounded else None,
        "q_upper": [_num(v) for v in chain.q_upper] if problem.bounded else None,
        "targets": problem.targets.tolist(),
        "method": args.method,
        "reachability": [_verdict_json(v) for v in verdicts],
    }
    if args.example == "A":
        doc["study_E"] = STUDY_E_A
    if ms is None:
        doc.update(status="unreachable", E=None, configurations=None, max_residual=None)
        return doc
    best = ms.best
    doc.update(
        status=best.status.value,
        E=best.objective,
        configurations=best.configurations.tolist(),
        residuals=best.residuals.tolist(),
        max_residual=best.max_residual(),
        limit_violation=best.limit_violation,
        multipliers=best.multipliers.tolist(),
        iterations=best.iterations,
        solve_time=best.wall_time,
        start_index=ms.results.index(best),
        starts=ms.n_starts,
        seed=ms.seed,
        start_kind=args.start_kind,
        n_success=ms.n_success,
        best_count=ms.best_count,
        status_counts=ms.status_counts(),
        minima=[
            {
                "E": m.objective,
                "count": m.count,
                "first_start": m.start_indices[0],
                "max_residual": m.result.max_residual(),
                "multiplier_norm": float(np.linalg.norm(m.result.multipliers)),
            }
            for m in ms.minima
        ],
        zero_start={"status": ms.results[0].status.value, "E": ms.results[0].objective},
        wall_time=ms.wall_time,
        workers=ms.n_workers,
        starts_per_second=ms.starts_per_second(),
    )
    return doc


def _print_text(doc: dict[str, Any]) -> None:
    if doc["q_lower"] is None:
        lims = "none"
    else:
        lo = ", ".join("-inf" if v is None else f"{v:.4g}" for v in doc["q_lower"])
        hi = ", ".join("inf" if v is None else f"{v:.4g}" for v in doc["q_upper"])
        lims = f"[{lo}] .. [{hi}] rad"
    print(
        f"IK path: {doc['chain']} l = {doc['lengths']} m, limits {lims}, "
        f"{len(doc['targets'])} targets, method {doc['method']}"
    )
    print("reachability (exact, no sampling):")
    for v in doc["reachability"]:
        print(f"  {v['message']}")
    if doc["E"] is None:
        return
    print(
        f"multistart: {doc['starts']} starts (seed {doc['seed']}, {doc['start_kind']}), "
        f"{doc['workers']} workers, {doc['wall_time']:.2f} s "
        f"({doc['starts_per_second']:.1f} starts/s); outcomes {doc['status_counts']}"
    )
    for m in doc["minima"][:8]:
        print(
            f"  local minimum E = {m['E']:.10f} rad^2 found by {m['count']} starts "
            f"(first: start {m['first_start']})"
        )
    z = doc["zero_start"]
    print(f"zero start: {z['status']}, E = {z['E']:.10f} rad^2")
    print(
        f"best: E = {doc['E']:.10f} rad^2 ({doc['status']}), found by {doc['best_count']} of "
        f"{doc['starts']} starts; max residual {doc['max_residual']:.2e} m, "
        f"limit violation {doc['limit_violation']:.2e} rad"
    )
    for j, q in enumerate(doc["configurations"]):
        print(f"  q{j + 1} = [{', '.join(f'{v:+.6f}' for v in q)}] rad")
    if "study_E" in doc:
        print(
            f"study reported E = {doc['study_E']} from the zero guess "
            f"(difference {doc['study_E'] - doc['E']:+.4f} rad^2; see docs/ikpath.md)"
        )


def _progress_bar(done: int, total: int, best: float) -> None:
    width = 30
    fill = int(width * done / total)
    best_txt = f"{best:.6g}" if math.isfinite(best) else "-"
    sys.stderr.write(f"\r[{'#' * fill}{'.' * (width - fill)}] {done}/{total} best E {best_txt}")
    if done == total:
        sys.stderr.write("\n")
    sys.stderr.flush()


def _write_outputs(
    args: argparse.Namespace,
    problem: CyclicIKProblem,
    verdicts: tuple[ReachVerdict, ...],
    ms: MultistartResult | None,
    doc: dict[str, Any],
) -> tuple[Path, list[Path]]:
    """Write the run folder: figures, replay, saved result, then ``summary.json``."""
    from youbot_opt.ikpath.plots import plot_arm_path, plot_convergence, plot_minima, plot_workspace

    folder = run_folder("ikpath", args.out)
    files = [save_figure(plot_workspace(problem, verdicts), folder, "ikpath_workspace.png")]
    if ms is not None:
        best = ms.best
        files.append(save_figure(plot_arm_path(best), folder, "ikpath_arm.png"))
        if best.history:
            files.append(save_figure(plot_convergence(best), folder, "ikpath_convergence.png"))
        files.append(save_figure(plot_minima(ms), folder, "ikpath_minima.png"))
        files.append(save_ikpath_result(best, folder / "result.json"))
        if not args.no_replay:
            from youbot_opt.ikpath.replay import export_ikpath_html

            files.append(
                export_ikpath_html(best, folder / "replay.html", segment_time=args.segment_time)
            )
    doc["output_folder"] = str(folder.resolve())
    doc["files"] = [f.name for f in files] + ["summary.json"]
    files.append(write_summary(folder, doc))
    return folder, files


def _run(args: argparse.Namespace) -> int:
    if not (math.isfinite(args.segment_time) and args.segment_time > 0):
        raise ParameterError(
            f"--segment-time must be a positive duration in [s], got {args.segment_time}",
            name="segment_time",
            value=args.segment_time,
        )
    problem = _problem(args)
    verdicts = check_reachability(problem)
    unreachable = [v for v in verdicts if v.status is Reachability.UNREACHABLE]
    ms = None
    if not unreachable:
        workers = args.workers if args.workers is not None else (1 if args.starts < 8 else None)
        show = not args.no_progress and sys.stderr.isatty()
        options: ALOptions | IpoptOptions | None = None
        if args.max_wall_time is not None:
            kind = ALOptions if args.method == "al" else IpoptOptions
            options = kind(max_wall_time=args.max_wall_time)
        ms = run_multistart(
            problem,
            method=args.method,
            options=options,
            n_starts=args.starts,
            seed=args.seed,
            starts=args.start_kind,
            max_workers=workers,
            progress=_progress_bar if show else None,
            check_reachability=False,
        )
    doc = _report(args, problem, verdicts, ms)
    folder, files = _write_outputs(args, problem, verdicts, ms, doc)
    if args.json:
        print(json.dumps(json_ready(doc), indent=2))
    else:
        _print_text(doc)
    print_outputs(folder, files)
    for v in unreachable:
        print(f"youbot-opt: error: {v.describe()}", file=sys.stderr)
    if ms is None:
        return 2
    return 0 if ms.best.success else 1
