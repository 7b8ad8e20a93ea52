"""The spatial mode of ``youbot-opt ikpath`` (any robot, 3-D targets, poses).

Called by :mod:`youbot_opt.cli.ikpath` when the command line asks for it
(see its usage text): builds a :class:`~youbot_opt.ikpath.spatial.SpatialIKProblem`
from ``--robot``/``--frame``/``--target``/``--targets``, decides every target's
reachability (exit 2 with the certificate of an unreachable one), runs the
multistart, and writes the run folder: ``result.json`` (the best path),
``summary.json`` (the ``--json`` object), ``ikpath_legs.png``,
``ikpath_path3d.png`` and ``replay.html``. Exit 0 when the best start
succeeded, 1 otherwise.
"""

from __future__ import annotations

import argparse
import json
import sys
from typing import TYPE_CHECKING, Any, cast

import numpy as np

from youbot_opt.cli.robot_args import loading_options
from youbot_opt.exceptions import ParameterError

if TYPE_CHECKING:
    from youbot_opt.viz.meshcat.scene import RobotLike

__all__ = ["run_spatial", "spatial_targets"]


def spatial_targets(args: argparse.Namespace) -> tuple[Any, ...]:
    """Targets from ``--target`` (3, 6 or 7 numbers) and ``--targets FILE``.

    Raises
    ------
    ParameterError
        For a ``--target`` of another length, or both sources at once.
    """
    from youbot_opt.ikpath.targets import SpatialTarget, load_targets, quaternion_to_matrix

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
            out.append(SpatialTarget(position=t, **tol))
        elif len(t) == 6:
            out.append(SpatialTarget(position=t[:3], approach=t[3:], **tol))
        elif len(t) == 7:
            out.append(SpatialTarget(position=t[:3], rotation=quaternion_to_matrix(t[3:]), **tol))
        else:
            raise ParameterError(
                f"--target {k + 1} has {len(t)} numbers; spatial targets take X Y Z, "
                "X Y Z AX AY AZ or X Y Z QX QY QZ QW",
                name="target",
                value=t,
            )
    return tuple(out)


def run_spatial(args: argparse.Namespace) -> int:
    """Run the spatial IK path from the parsed command line; return the exit status."""
    from youbot_opt.cli.output import json_ready, print_outputs, run_folder, save_figure
    from youbot_opt.ikpath.spatial import (
        SpatialIKProblem,
        SpatialReach,
        check_spatial_reachability,
    )
    from youbot_opt.ikpath.spatial_solve import run_spatial_multistart
    from youbot_opt.robot.model import load_model

    if args.example or args.lengths:
        raise ParameterError(
            "--example/--lengths describe planar chains; spatial targets need --robot",
            name="robot",
            value=args.robot,
        )
    robot = load_model(args.robot or "youbot", tip_frame=args.frame, **loading_options(args))  # type: ignore[arg-type]
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
    base = SpatialIKProblem(model=robot.model, frame=frame, targets=targets)
    n = base.n_joints
    problem = SpatialIKProblem(
        model=robot.model,
        frame=frame,
        targets=targets,
        use_limits=not args.no_limits,
        q_lower=None if lower is None else np.broadcast_to(lower, (n,)),
        q_upper=None if upper is None else np.broadcast_to(upper, (n,)),
    )
    verdicts = check_spatial_reachability(problem)
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
            }
            for v in verdicts
        ],
    }
    unreachable = [v for v in verdicts if v.status is SpatialReach.UNREACHABLE]
    files = []
    code = 2
    if not unreachable:
        workers = args.workers if args.workers is not None else (1 if args.starts < 8 else 2)
        ms = run_spatial_multistart(
            problem, method=args.method, n_starts=args.starts, seed=args.seed, workers=workers
        )
        best = ms.best
        doc.update(
            status=best.status.value,
            E=best.objective,
            result=best.to_dict(),
            starts=len(ms.results),
            seed=args.seed,
            workers=ms.workers,
            n_success=sum(r.success for r in ms.results),
            minima=[{"E": ms.results[g[0]].objective, "count": len(g)} for g in ms.minima],
            starts_per_second=ms.starts_per_second,
            wall_time=ms.wall_time,
        )
        result_path = folder / "result.json"
        result_path.write_text(json.dumps(json_ready(best.to_dict()), indent=2) + "\n")
        files.append(result_path)
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
        code = 0 if best.success else 1
    else:
        doc.update(status="unreachable", E=None, result=None)
    doc["output_folder"] = str(folder.resolve())
    doc["files"] = [f.name for f in files] + ["summary.json"]
    from youbot_opt.cli.output import write_summary

    files.append(write_summary(folder, doc))
    if args.json:
        print(json.dumps(json_ready(doc), indent=2))
    else:
        print(
            f"IK path (spatial): {robot.name}, frame {frame}, {len(targets)} targets, "
            f"method {args.method}"
        )
        for v in doc["reachability"]:
            print(f"  target {v['index']}: {v['verdict']} ({v['message']})")
        if doc["E"] is not None:
            print(
                f"best: E = {doc['E']:.10g} rad^2 ({doc['status']}), {doc['n_success']} of "
                f"{doc['starts']} starts succeeded, {len(doc['minima'])} distinct minima"
            )
            for j, q in enumerate(doc["result"]["configurations_rad"]):
                print(f"  q{j + 1} = [{', '.join(f'{x:+.6f}' for x in q)}] rad")
    print_outputs(folder, files)
    for v in unreachable:
        print(f"youbot-opt: error: unreachable: {v.message}", file=sys.stderr)
    return code
