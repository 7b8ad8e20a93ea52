"""youbot-opt ikpath: minimum-motion cyclic joint path through targets (study 2).

    youbot-opt ikpath --example A --starts 200
    youbot-opt ikpath --example B --method ipopt --starts 200 --json
    youbot-opt ikpath --lengths 3 2 2 --limit 1.5708 --target 0 7 --target 5 0 --method ipopt
    youbot-opt ikpath --robot youbot --target 0.3 0.3 --target 0.1 0.5 --target 0.35 0.1
    youbot-opt ikpath --robot ur5 --target 0.4 0.2 0.3 --target 0.3 -0.3 0.4 --target 0.5 0 0.2

Targets X Y [m] are planar (--example, --lengths, --robot youbot); X Y Z, X Y Z AX AY AZ
(approach of the frame's z axis), X Y Z QX QY QZ QW (pose) or --targets FILE are spatial
(any --robot NAME|PATH, --frame). Exit 0: best start succeeded; 1: failed; 2: unreachable target.
Starts are saved in --out DIR as they finish; a rerun resumes. Details: docs/ikpath.md.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

from youbot_opt.cli.cluster_args import (
    add_keep_results_arg,
    add_scheduler_args,
    report_shard,
    scheduler_address,
)
from youbot_opt.cli.ikpath_starts import print_starts, start_fields, start_sweep
from youbot_opt.cli.robot_args import add_loading_options
from youbot_opt.cli.run_size import check_ikpath_size
from youbot_opt.exceptions import ParameterError

if TYPE_CHECKING:  # the library is imported in _run, so --help and argument errors stay fast
    from youbot_opt.ikpath.multistart import MultistartResult
    from youbot_opt.ikpath.problem import CyclicIKProblem
    from youbot_opt.ikpath.reachability.planar import ReachVerdict

# The choices of the parser, spelled out here so that building it imports no solver;
# tests/cli/test_cli_help.py checks them against the library's EXAMPLES, METHODS, START_KINDS.
EXAMPLE_NAMES: tuple[str, ...] = ("A", "B")
METHOD_NAMES: tuple[str, ...] = ("al", "ipopt")
START_KIND_NAMES: tuple[str, ...] = ("feasible", "uniform")
PLANAR_REACH_EVALUATIONS = 20_000
SPATIAL_REACH_BOXES = 200_000  # ikpath.spatial_reachability.DEFAULT_INTERVAL_BOXES
SPATIAL_REACH_SECONDS = 1.0  # ikpath.spatial_reachability.DEFAULT_INTERVAL_SECONDS
SPATIAL_START_KIND_NAMES: tuple[str, ...] = ("mixed", "coherent", "random")


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Add the ``ikpath`` sub-command."""
    p = sub.add_parser(
        "ikpath",
        help="minimum-motion cyclic IK path through tip targets (study 2)",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    src = p.add_argument_group("arm and targets")
    src.add_argument("--example", choices=EXAMPLE_NAMES, help="the study's example A or B")
    src.add_argument(
        "--robot",
        metavar="NAME|PATH",
        help="youbot (planar, targets: platform x z), or a robot name (ur5, panda, ...) or "
        "URDF path for spatial targets",
    )
    src.add_argument("--frame", metavar="F", help="spatial: the frame that visits the targets")
    add_loading_options(src)
    src.add_argument(
        "--targets",
        metavar="FILE",
        dest="targets_file",
        help="spatial: targets from a CSV or JSON file (see above)",
    )
    src.add_argument(
        "--tol", type=float, default=1e-6, help="spatial: position tolerance [m] (default 1e-6)"
    )
    src.add_argument(
        "--orientation-tol",
        type=float,
        default=1e-6,
        help="spatial: orientation tolerance [rad] (default 1e-6)",
    )
    src.add_argument("--lengths", type=float, nargs="+", metavar="L", help="link lengths [m]")
    src.add_argument(
        "--target",
        type=float,
        nargs="+",
        action="append",
        metavar="X",
        help="a target (repeat, in visiting order): X Y [m] (planar), X Y Z, X Y Z AX AY AZ "
        "or X Y Z QX QY QZ QW (spatial)",
    )
    lim = p.add_argument_group("joint limits [rad]")
    lim.add_argument("--limit", type=float, metavar="C", help="symmetric limits |q_i| <= C")
    lim.add_argument("--lower", type=float, nargs="+", metavar="L", help="lower limit(s)")
    lim.add_argument("--upper", type=float, nargs="+", metavar="U", help="upper limit(s)")
    lim.add_argument("--no-limits", action="store_true", help="ignore the arm's joint limits")
    lim.add_argument(
        "--reach-evaluations",
        type=int,
        default=None,
        metavar="N",
        help="budget of the reachability test: planar, evaluations of the branch and bound "
        f"(3+ links; default {PLANAR_REACH_EVALUATIONS}); spatial, boxes of the interval "
        f"search per target (default {SPATIAL_REACH_BOXES}, within its "
        f"{SPATIAL_REACH_SECONDS:g} s per target)",
    )
    run = p.add_argument_group("solver")
    run.add_argument("--method", choices=METHOD_NAMES, default="al", help="al (default) or ipopt")
    run.add_argument(
        "--starts", type=int, default=1, help="number of starts (default 1: the zero vector only)"
    )
    run.add_argument("--seed", type=int, default=0, help="seed of the random starts")
    run.add_argument(
        "--start-kind",
        choices=START_KIND_NAMES + SPATIAL_START_KIND_NAMES,
        default=None,
        help="random starts: feasible (default for a planar robot) or uniform (planar); mixed "
        "(default for other robots), coherent, random or, for a planar robot, feasible (spatial)",
    )
    run.add_argument(
        "--workers",
        type=int,
        default=None,
        help="worker processes (default: the CPUs, 1 below 8 starts)",
    )
    add_scheduler_args(run)  # --starts > 1 on a Dask cluster
    run.add_argument(
        "--max-wall-time",
        type=float,
        default=None,
        metavar="S",
        help="wall-time limit of each start's solve [s] (status max_time when reached)",
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
    add_keep_results_arg(out)
    out.add_argument("--json", action="store_true", help="print one JSON object")
    out.add_argument("--no-progress", action="store_true", help="no progress on stderr")
    p.set_defaults(func=_run)


def _spatial_mode(args: argparse.Namespace) -> bool:
    """Whether the command line asks for the spatial problem (see the usage text)."""
    if args.frame or args.targets_file:
        return True
    if args.robot is not None and args.robot != "youbot":
        return True
    return any(len(t) != 2 for t in args.target or ())


def _problem(args: argparse.Namespace) -> CyclicIKProblem:
    """Build the problem from the command line."""
    import numpy as np

    from youbot_opt.ikpath.examples import example_problem
    from youbot_opt.ikpath.problem import CyclicIKProblem
    from youbot_opt.ikpath.targets import position_targets
    from youbot_opt.robot.planar import PlanarChain

    if args.example:
        if args.lengths or args.target or args.robot:
            raise ParameterError(
                "--example fixes the arm and targets; drop --lengths/--target/--robot",
                name="example",
                value=args.example,
            )
        base = example_problem(args.example)
        chain, targets = base.planar_chain, base.target_points
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
            from youbot_opt.robot.planar import youbot_chain

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
    return CyclicIKProblem(
        robot=chain, targets=position_targets(targets), use_limits=not args.no_limits
    )


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
    import numpy as np

    from youbot_opt.ikpath.examples import STUDY_E_A
    from youbot_opt.ikpath.reachability.planar import Reachability

    chain = problem.planar_chain
    doc: dict[str, Any] = {
        "chain": chain.name,
        "lengths": chain.lengths.tolist(),
        "q_lower": [_num(v) for v in chain.q_lower] if problem.bounded else None,
        "q_upper": [_num(v) for v in chain.q_upper] if problem.bounded else None,
        "targets": problem.target_points.tolist(),
        "method": args.method,
        "reachability": [_verdict_json(v) for v in verdicts],
        "reachability_undecided": [v.index for v in verdicts if v.status is Reachability.UNDECIDED],
    }
    if args.example == "A":
        doc["study_E"] = STUDY_E_A
    if ms is None:
        doc.update(status="unreachable", E=None, configurations=None, max_residual=None)
        return doc
    best = ms.best
    doc.update(
        status=best.status.value,
        message=best.message,
        E=best.objective,
        configurations=best.configurations.tolist(),
        residuals=best.position_errors.tolist(),
        max_residual=best.max_position_error(),
        limit_violation=best.limit_violation,
        multipliers=best.multipliers.tolist(),
        iterations=best.iterations,
        solve_time=best.wall_time,
        start_index=ms.best_index,
        starts=ms.n_starts,
        seed=ms.seed,
        start_kind=args.start_kind,
        n_success=ms.n_converged,
        best_count=ms.best_count,
        status_counts=ms.status_counts(),
        minima=[
            {
                "E": m.objective,
                "count": m.count,
                "first_start": m.start_indices[0],
                "max_residual": m.result.max_position_error(),
                "multiplier_norm": float(np.linalg.norm(m.result.multipliers)),
            }
            for m in ms.minima
        ],
        zero_start={"status": ms.results[0].status.value, "E": ms.results[0].objective},
        wall_time=ms.wall_time,
        workers=ms.n_workers,
        starts_per_second=ms.starts_per_second(),
        resumed=ms.resumed,
        **start_fields(ms.results, ms.attempts, _residual_field),
    )
    return doc


def _residual_field(r: Any) -> dict[str, Any]:  # noqa: ANN401 - IKPathResult or StartSummary
    """Return the planar per-start field of ``summary.json``: the largest residual in [m]."""
    if hasattr(r, "max_position_error"):  # a result, not its stored summary
        return {"max_residual": r.max_position_error()}
    return {"max_residual": r.max_residual}


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
    if doc["starts"] == 1:
        _print_single_start(doc)
    else:
        _print_multistart(doc)
    for j, q in enumerate(doc["configurations"]):
        print(f"  q{j + 1} = [{', '.join(f'{v:+.6f}' for v in q)}] rad")
    if "study_E" in doc:
        print(
            f"study reported E = {doc['study_E']} from the zero guess "
            f"(difference {doc['study_E'] - doc['E']:+.4f} rad^2; see docs/ikpath.md)"
        )


def _print_single_start(doc: dict[str, Any]) -> None:
    """Print the one run of ``--starts 1`` (the zero start) as one run, not as a multistart."""
    resumed = " (loaded from the output folder: resumed)" if doc["resumed"] else ""
    print(f"one start (the zero vector), {doc['wall_time']:.2f} s{resumed}")
    if doc["retried"]:
        print("  retried once after a failed attempt")
    for o in doc["start_outcomes"]:
        if o["status"] == "crashed":
            print(f"  failed after {o['attempts']} attempts: {o['message']}")
    print(
        f"result: E = {doc['E']:.10f} rad^2 ({doc['status']}); max residual "
        f"{doc['max_residual']:.2e} m, limit violation {doc['limit_violation']:.2e} rad"
    )
    _print_failure(doc)


def _print_failure(doc: dict[str, Any]) -> None:
    """Print why the best start failed (nothing for a success)."""
    if doc["status"] not in ("solved", "solved_acceptable"):
        print(f"failed: {doc['message']}")


def _print_multistart(doc: dict[str, Any]) -> None:
    """Print the multistart's outcomes, its local minima, the zero start and the best."""
    print_starts(doc)
    for m in doc["minima"][:8]:
        print(
            f"  local minimum E = {m['E']:.10f} rad^2 found by {m['count']} starts "
            f"(first: start {m['first_start']})"
        )
    z = doc["zero_start"]
    print(f"start 0 (the zero vector): {z['status']}, E = {z['E']:.10f} rad^2")
    print(
        f"best: E = {doc['E']:.10f} rad^2 ({doc['status']}), found by {doc['best_count']} of "
        f"{doc['starts']} starts; max residual {doc['max_residual']:.2e} m, "
        f"limit violation {doc['limit_violation']:.2e} rad"
    )
    _print_failure(doc)


def _warn_undecided(verdicts: tuple[ReachVerdict, ...]) -> None:
    """Warn on stderr about every target whose reachability was not decided."""
    from youbot_opt.ikpath.reachability.planar import Reachability

    for v in verdicts:
        if v.status is Reachability.UNDECIDED:
            print(
                f"youbot-opt: warning: reachability of target p{v.index + 1} = "
                f"({v.target[0]:.6g}, {v.target[1]:.6g}) is undecided (branch and bound "
                f"budget exhausted after {v.evaluations} evaluations): its distance to the "
                f"workspace is certified only to lie in [{v.distance_lower:.6g}, "
                f"{v.distance_upper:.6g}] m; solving anyway (a failed solve may mean the "
                "target is unreachable; a larger --reach-evaluations may decide it)",
                file=sys.stderr,
            )


def _write_outputs(
    args: argparse.Namespace,
    folder: Path,
    problem: CyclicIKProblem,
    verdicts: tuple[ReachVerdict, ...],
    ms: MultistartResult | None,
    doc: dict[str, Any],
) -> list[Path]:
    """Write the run folder: figures, replay, saved result, then ``summary.json``."""
    from youbot_opt.cli.output import save_figure, write_summary
    from youbot_opt.ikpath.io import save_result
    from youbot_opt.viz.plots.ikpath import (
        plot_arm_path,
        plot_convergence,
        plot_minima,
        plot_workspace,
    )

    files = [save_figure(plot_workspace(problem, verdicts), folder, "ikpath_workspace.png")]
    if ms is not None:
        best = ms.best
        files.append(save_figure(plot_arm_path(best), folder, "ikpath_arm.png"))
        if best.history:
            files.append(save_figure(plot_convergence(best), folder, "ikpath_convergence.png"))
        files.append(save_figure(plot_minima(ms), folder, "ikpath_minima.png"))
        files.append(save_result(best, folder / "result.json"))
        if not args.no_replay:
            from youbot_opt.viz.meshcat.ikpath import export_ikpath_html

            files.append(
                export_ikpath_html(best, folder / "replay.html", segment_time=args.segment_time)
            )
        files += [folder / "manifest.json", folder / "items"]  # the starts, by the sweep store
    doc["output_folder"] = str(folder.resolve())
    doc["files"] = [f.name for f in files] + ["summary.json"]
    files.append(write_summary(folder, doc))
    return files


def _run(args: argparse.Namespace) -> int:
    from youbot_opt.cli.output import print_json, print_outputs, run_folder
    from youbot_opt.ikpath.methods.al import ALOptions
    from youbot_opt.ikpath.methods.ipopt import IpoptOptions
    from youbot_opt.ikpath.multistart import run_multistart
    from youbot_opt.ikpath.reachability.planar import Reachability, check_reachability
    from youbot_opt.sweeps.resume import ShardReport

    if not (math.isfinite(args.segment_time) and args.segment_time > 0):
        raise ParameterError(
            f"--segment-time must be a positive duration in [s], got {args.segment_time}",
            name="segment_time",
            value=args.segment_time,
        )
    check_ikpath_size(
        n_starts=args.starts, n_links=len(args.lengths or ()), n_targets=len(args.target or ())
    )  # noqa: E501
    if _spatial_mode(args):
        from youbot_opt.cli.ikpath_spatial import run_spatial

        return run_spatial(args)
    if args.start_kind is None:
        args.start_kind = "feasible"
    elif args.start_kind not in START_KIND_NAMES:
        raise ParameterError(
            f"--start-kind {args.start_kind} is a spatial start kind; planar targets take "
            f"{' or '.join(START_KIND_NAMES)}",
            name="start_kind",
            value=args.start_kind,
        )
    if args.reach_evaluations is None:
        args.reach_evaluations = PLANAR_REACH_EVALUATIONS
    problem = _problem(args)
    if args.reach_evaluations < 1:
        raise ParameterError(
            f"--reach-evaluations must be >= 1, got {args.reach_evaluations}",
            name="reach_evaluations",
            value=args.reach_evaluations,
        )
    verdicts = check_reachability(problem, max_evaluations=args.reach_evaluations)
    unreachable = [v for v in verdicts if v.status is Reachability.UNREACHABLE]
    folder = run_folder("ikpath", args.out)
    ms = None
    if not unreachable:
        _warn_undecided(verdicts)
        options: ALOptions | IpoptOptions | None = None
        if args.max_wall_time is not None:
            kind = ALOptions if args.method == "al" else IpoptOptions.for_ikpath
            options = kind(max_wall_time=args.max_wall_time)
        # With --scheduler / --scheduler-file the starts run on that Dask cluster.
        executor = scheduler_address(args) or ("process" if args.starts > 1 else "serial")
        got = run_multistart(
            problem,
            method=args.method,
            options=options,
            n_starts=args.starts,
            seed=args.seed,
            starts=args.start_kind,
            verdicts=verdicts,
            sweep=start_sweep(args, folder, executor),
        )
        if isinstance(got, ShardReport):  # --shard I/K solved its share
            return report_shard(got)
        ms = got
    doc = _report(args, problem, verdicts, ms)
    files = _write_outputs(args, folder, problem, verdicts, ms, doc)
    if args.json:
        print_json(doc)
    else:
        _print_text(doc)
    print_outputs(folder, files)
    for v in unreachable:
        print(f"youbot-opt: error: {v.describe()}", file=sys.stderr)
    if ms is None:
        return 2
    return 0 if ms.best.success else 1
