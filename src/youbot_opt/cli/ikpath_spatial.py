"""The spatial mode of ``youbot-opt ikpath`` (any robot, 3-D targets, poses).

Called by :mod:`youbot_opt.cli.ikpath` when the command line asks for it:
builds a :class:`~youbot_opt.ikpath.problem.CyclicIKProblem` from
``--robot``/``--frame``/``--target``/``--targets``, decides every target's
reachability (exit 2 with the certificate of an unreachable one), runs the
resumable multistart (``--starts``, ``--start-kind``, ``--method``,
``--max-wall-time``, ``--workers``, ``--scheduler``/``--shard``; progress on
stderr) into the run folder's sweep store, and writes ``result.json``
(:func:`~youbot_opt.ikpath.io.load_result`), ``summary.json``,
``ikpath_legs.png``, ``ikpath_path3d.png`` and ``replay.html``. Exit 0 when
the best start succeeded, 1 otherwise.
"""

from __future__ import annotations

import argparse
import math
import sys
from dataclasses import replace
from typing import TYPE_CHECKING, Any, cast

import numpy as np

from youbot_opt.cli.ikpath_starts import StartProgress, print_starts, start_fields, start_sweep
from youbot_opt.cli.robot_args import loading_options
from youbot_opt.exceptions import ParameterError

if TYPE_CHECKING:
    from youbot_opt.ikpath.methods.al import ALOptions
    from youbot_opt.ikpath.problem import CyclicIKProblem
    from youbot_opt.nlp.ipopt import IpoptOptions
    from youbot_opt.robot.model import RobotModel
    from youbot_opt.viz.meshcat.scene import RobotLike

__all__ = ["SPATIAL_DEFAULT_START_KIND", "StartProgress", "run_spatial", "spatial_targets"]

SPATIAL_DEFAULT_START_KIND = "mixed"
"""``--start-kind`` of spatial runs when none is given."""


def spatial_targets(args: argparse.Namespace) -> tuple[Any, ...]:
    """Targets from ``--target`` (3, 6 or 7 numbers) and ``--targets FILE``.

    Raises
    ------
    ParameterError
        For a ``--target`` of another length, or both sources at once.
    """
    from youbot_opt.ikpath.targets import Target, load_targets, quaternion_to_matrix

    tol = {"position_tol": args.tol, "orientation_tol": args.orientation_tol}
    if args.targets_file and args.target:
        raise ParameterError(
            "give targets either with --target or with --targets FILE, not both",
            name="target",
            value=args.targets_file,
        )
    if args.targets_file:
        return load_targets(args.targets_file, **tol)
    out = []
    for k, t in enumerate(args.target or ()):
        if len(t) == 3:
            out.append(Target(position=t, **tol))
        elif len(t) == 6:
            out.append(Target(position=t[:3], approach=t[3:], **tol))
        elif len(t) == 7:
            out.append(Target(position=t[:3], rotation=quaternion_to_matrix(t[3:]), **tol))
        else:
            raise ParameterError(
                f"--target {k + 1} has {len(t)} numbers; spatial targets take X Y Z, "
                "X Y Z AX AY AZ or X Y Z QX QY QZ QW",
                name="target",
                value=t,
            )
    return tuple(out)


def _check_spatial_flags(args: argparse.Namespace) -> str | None:
    """Refuse the planar-only flags; return the start kind (None: the robot kind's)."""
    if args.example or args.lengths:
        raise ParameterError(
            "--example/--lengths describe planar chains; spatial targets need --robot",
            name="robot",
            value=args.robot,
        )
    if args.reach_evaluations is not None and args.reach_evaluations < 1:
        raise ParameterError(
            f"--reach-evaluations must be >= 1, got {args.reach_evaluations}",
            name="reach_evaluations",
            value=args.reach_evaluations,
        )
    kind = args.start_kind
    if kind not in (None, "mixed", "coherent", "random", "feasible"):
        raise ParameterError(
            f"--start-kind {kind} is a planar start kind; spatial targets take mixed "
            "(default), coherent or random",
            name="start_kind",
            value=kind,
        )
    if args.max_wall_time is not None and not (
        math.isfinite(args.max_wall_time) and args.max_wall_time > 0
    ):
        raise ParameterError(
            f"--max-wall-time must be a positive time in [s], got {args.max_wall_time}",
            name="max_wall_time",
            value=args.max_wall_time,
        )
    return kind


def _problem(args: argparse.Namespace, robot: RobotModel) -> CyclicIKProblem:
    """Build the spatial problem of the command line on the loaded ``robot``."""
    from youbot_opt.ikpath.problem import CyclicIKProblem

    frame = args.frame or robot.tip_frame
    targets = spatial_targets(args)
    if len(targets) < 2:
        raise ParameterError(
            f"a cyclic path needs at least 2 targets, got {len(targets)}",
            name="target",
            value=len(targets),
        )
    lower = upper = None
    if args.limit is not None:
        if not args.limit > 0:
            raise ParameterError(f"--limit must be > 0, got {args.limit}", name="limit")
        lower, upper = -args.limit, args.limit
    lower = args.lower if args.lower is not None else lower
    upper = args.upper if args.upper is not None else upper
    n = CyclicIKProblem(robot=robot, frame=frame, targets=targets).n_joints
    return CyclicIKProblem(
        robot=robot,
        frame=frame,
        targets=targets,
        use_limits=not args.no_limits,
        q_lower=None if lower is None else np.broadcast_to(lower, (n,)),
        q_upper=None if upper is None else np.broadcast_to(upper, (n,)),
    )


def _options(args: argparse.Namespace) -> ALOptions | IpoptOptions | None:
    """Solver options of ``--method`` with ``--max-wall-time`` (None: the defaults)."""
    if args.max_wall_time is None:
        return None
    if args.method == "al":
        from youbot_opt.ikpath.methods.al import SPATIAL_AL_OPTIONS

        return replace(SPATIAL_AL_OPTIONS, max_wall_time=args.max_wall_time)
    from youbot_opt.nlp.ipopt import IpoptOptions

    return IpoptOptions.for_ikpath(max_wall_time=args.max_wall_time)


def _start_kind(kind: str | None, problem: CyclicIKProblem) -> str:
    """Return the start kind: ``feasible`` (planar starts) for a planar robot, else ``mixed``."""
    if kind is None:
        return "feasible" if problem.chain is not None else SPATIAL_DEFAULT_START_KIND
    if kind == "feasible" and problem.chain is None:
        raise ParameterError(
            f"--start-kind feasible is a planar start kind; robot {problem.robot_model.name!r} "
            f"is not planar for frame {problem.frame!r}: spatial targets take mixed (default), "
            "coherent or random",
            name="start_kind",
            value=kind,
        )
    return kind


def run_spatial(args: argparse.Namespace) -> int:
    """Run the spatial IK path from the parsed command line; return the exit status."""
    from youbot_opt.cli.cluster_args import report_shard, scheduler_address
    from youbot_opt.cli.output import print_json, print_outputs, run_folder, save_figure
    from youbot_opt.cli.warning_lines import flush_warnings
    from youbot_opt.ikpath.io import RobotSource, save_result
    from youbot_opt.ikpath.multistart import run_multistart
    from youbot_opt.ikpath.reachability.spatial import Reachability3D, check_reachability_3d
    from youbot_opt.robot.load import load_model
    from youbot_opt.sweeps.resume import ShardReport

    kind = _check_spatial_flags(args)
    robot = load_model(args.robot or "youbot", tip_frame=args.frame, **loading_options(args))  # type: ignore[arg-type]
    flush_warnings()  # the loader's warnings, grouped, before the run
    problem = _problem(args, robot)
    kind = _start_kind(kind, problem)
    frame = problem.frame
    targets = problem.targets
    options = _options(args)
    executor = scheduler_address(args) or ("process" if args.starts > 1 else "serial")
    budget = {} if args.reach_evaluations is None else {"interval_boxes": args.reach_evaluations}
    verdicts = check_reachability_3d(problem, **budget)
    folder = run_folder("ikpath", args.out)
    doc: dict[str, Any] = {
        "robot": robot.name,
        "frame": frame,
        "joints": list(problem.joint_names),
        "q_lower": problem.q_lower,
        "q_upper": problem.q_upper,
        "use_limits": problem.use_limits,
        "method": args.method,
        "targets": [t.to_dict() for t in targets],
        "reachability": [
            {
                "index": v.index,
                "verdict": v.status.value,
                "witness": None if v.witness is None else v.witness,
                "distance": v.distance,
                "reach": v.reach,
                "message": v.message,
                "decided_by": v.method,
                "interval_boxes": v.boxes,
                "interval_depth": v.depth,
            }
            for v in verdicts
        ],
    }
    unreachable = [v for v in verdicts if v.status is Reachability3D.UNREACHABLE]
    files = []
    code = 2
    if not unreachable:
        for v in verdicts:
            if v.status is Reachability3D.UNDECIDED:
                print(
                    f"youbot-opt: warning: reachability of target {v.index} is undecided "
                    f"({v.message}); solving anyway (a failed solve may mean it is unreachable; "
                    "a larger --reach-evaluations may decide it)",
                    file=sys.stderr,
                )
        ms = run_multistart(
            problem,
            planar=False,
            method=args.method,
            n_starts=args.starts,
            seed=args.seed,
            starts=kind,
            options=options,
            sweep=start_sweep(args, folder, executor),
        )
        if isinstance(ms, ShardReport):  # --shard I/K solved its share
            return report_shard(ms)
        best = ms.best
        doc.update(
            status=best.status.value,
            E=best.objective,
            result=best.to_dict(),
            start_index=ms.best_index,
            starts=len(ms.results),
            seed=args.seed,
            start_kind=kind,
            max_wall_time=args.max_wall_time,
            workers=ms.n_workers,
            n_success=ms.n_converged,
            status_counts=ms.status_counts(),
            minima=[{"E": m.objective, "count": m.count} for m in ms.minima],
            starts_per_second=ms.starts_per_second(),
            wall_time=ms.wall_time,
            resumed=ms.resumed,
            **start_fields(ms.results, ms.attempts),
        )
        source = RobotSource.of(robot, strict=not args.lenient)
        files.append(save_result(best, folder / "result.json", source))
        from youbot_opt.viz.plots.ikpath import plot_leg_motion, plot_spatial_path

        files.append(save_figure(plot_leg_motion(best), folder, "ikpath_legs.png"))
        files.append(save_figure(plot_spatial_path(best), folder, "ikpath_path3d.png"))
        if not args.no_replay:
            from youbot_opt.viz.meshcat.ikpath import export_spatial_ikpath_html

            files.append(
                export_spatial_ikpath_html(
                    best,
                    cast("RobotLike", robot),
                    folder / "replay.html",
                    segment_time=args.segment_time,
                )
            )
        files += [folder / "manifest.json", folder / "items"]  # the starts, by the sweep store
        code = 0 if best.success else 1
    else:
        doc.update(status="unreachable", E=None, result=None)
    doc["output_folder"] = str(folder.resolve())
    doc["files"] = [f.name for f in files] + ["summary.json"]
    from youbot_opt.cli.output import write_summary

    files.append(write_summary(folder, doc))
    if args.json:
        print_json(doc)
    else:
        _print_text(doc, robot.name, frame, len(targets), args.method)
    print_outputs(folder, files)
    for v in unreachable:
        print(f"youbot-opt: error: unreachable: {v.message}", file=sys.stderr)
    return code


def _print_text(doc: dict[str, Any], robot: str, frame: str, n_targets: int, method: str) -> None:
    print(f"IK path (spatial): {robot}, frame {frame}, {n_targets} targets, method {method}")
    for v in doc["reachability"]:
        print(f"  target {v['index']}: {v['verdict']} ({v['message']})")
    if doc["E"] is None:
        return
    print_starts(doc)
    print(
        f"best: E = {doc['E']:.10g} rad^2 ({doc['status']}, start {doc['start_index']}), "
        f"{doc['n_success']} of {doc['starts']} starts succeeded, {len(doc['minima'])} "
        "distinct minima"
    )
    for j, q in enumerate(doc["result"]["configurations_rad"]):
        print(f"  q{j + 1} = [{', '.join(f'{x:+.6f}' for x in q)}] rad")
    if not doc["result"]["success"]:
        print(f"failed: {doc['result']['message']}")
