"""``youbot-opt solve``: one trajectory solve (or a multistart) from the command line.

Solves, optionally from ``--starts N`` starts in a process pool with progress
on stderr, refines the grid until the plan is certified (``--no-refine``
keeps it), prints a table (``--json``: one JSON object) and writes an output
folder (:mod:`youbot_opt.cli.output`) with ``summary.json``, ``result.npz``,
figures and ``replay.html``. Exit codes: 0 success, 1 failed solve or
refinement out of budget (still saved), 2 bad input.

Usage::

    youbot-opt solve --beta 0.5 --knots 50 --starts 4 --out DIR
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
from pathlib import Path

import numpy as np

from youbot_opt._checks import check_beta
from youbot_opt._files import json_ready
from youbot_opt._typing import JSONDict
from youbot_opt.cli.drawing import DrawingAhead, FigureJob
from youbot_opt.cli.flags import (
    clearance_of,
    ipopt_options,
    is_study_youbot,
    load_robot,
    scheduler_address,
)
from youbot_opt.cli.output import (
    ProgressLine,
    open_folder,
    report_outputs,
    solve_drawing_ahead,
    write_solve_outputs,
    write_summary,
)
from youbot_opt.cli.parser import DEFAULT_TRANSCRIPTION
from youbot_opt.cli.refinement import refine_result
from youbot_opt.cli.run_size import check_trajopt_size
from youbot_opt.cli.trajopt_text import MULTISTART_HINT, certificate_of, format_result
from youbot_opt.exceptions import ParameterError
from youbot_opt.reproduction.study1 import study1_problem
from youbot_opt.sweeps.options import SweepOptions
from youbot_opt.trajopt.multistart import MultistartResult, run_multistart
from youbot_opt.trajopt.problem import BoundaryState, TrajOptProblem
from youbot_opt.trajopt.result import TrajOptResult
from youbot_opt.trajopt.solver import TrajOptSolver
from youbot_opt.trajopt.spline_guess import random_spline_guess
from youbot_opt.trajopt.sweep import default_dt0
from youbot_opt.trajopt.tool import KeepAxis, NearLine, ToolConstraint, ToolSpeed

__all__ = ["run", "transcription"]


def transcription(args: argparse.Namespace) -> str:
    """Return the transcription of the options: ``--transcription``, else the default.

    The study's youBot keeps the study's trapezoid (its reproduction depends on
    it); any other robot gets :data:`DEFAULT_TRANSCRIPTION`.
    """
    if args.transcription is not None:
        return str(args.transcription).replace("-", "_")
    return "trapezoidal" if is_study_youbot(args) else DEFAULT_TRANSCRIPTION


def tool_of(args: argparse.Namespace) -> tuple[ToolConstraint, ...]:
    """Return the tool constraints of the ``solve`` flags (docs/tool.md).

    ``--keep-axis`` with ``--max-tilt`` (degrees), ``--line`` with
    ``--line-tol`` [m] (each pair given together), ``--tool-speed`` [m/s].
    """
    out: list[ToolConstraint] = []
    for flag, value, other, limit in (
        ("--keep-axis", args.keep_axis, "--max-tilt", args.max_tilt),
        ("--line", args.line, "--line-tol", args.line_tol),
    ):
        if (value is None) != (limit is None):
            given, missing = (flag, other) if limit is None else (other, flag)
            raise ParameterError(f"{given} needs {missing}", name=missing.lstrip("-"))
    if args.keep_axis is not None:
        axis, direction = args.keep_axis[:3], args.keep_axis[3:]
        out.append(KeepAxis(axis=axis, direction=direction, max_angle=math.radians(args.max_tilt)))
    if args.line is not None:
        out.append(NearLine(p0=args.line[:3], p1=args.line[3:], tolerance=args.line_tol))
    if args.tool_speed is not None:
        out.append(ToolSpeed(max_speed=args.tool_speed))
    return tuple(out)


def _problem(args: argparse.Namespace) -> TrajOptProblem:
    problem = _free_problem(args)
    clearance = clearance_of(args, problem.robot)
    if clearance is not None:
        problem = dataclasses.replace(problem, clearance=clearance)
    tool = tool_of(args)
    return dataclasses.replace(problem, tool=tool) if tool else problem


def _free_problem(args: argparse.Namespace) -> TrajOptProblem:
    is_youbot = is_study_youbot(args)
    if args.damping is not None and not is_youbot:
        raise ParameterError("--damping applies to the youBot only", name="damping")
    robot = load_robot(args, damping=args.damping)
    if is_youbot and args.start is None and args.goal is None:
        return study1_problem(args.knots, robot=robot)
    if args.start is None or args.goal is None:
        raise ParameterError(
            f"--start and --goal (each {robot.nq} joint positions in rad) are required for "
            f"robot {robot.name!r}: only the youbot has a default motion (the study's). "
            f"`youbot-opt report --robot {args.robot}` lists the joint limits the positions "
            f"must respect",
            name="start",
        )
    return TrajOptProblem(
        robot=robot,
        start=BoundaryState(q=np.array(args.start)),
        goal=BoundaryState(q=np.array(args.goal)),
        n_knots=args.knots,
    )


def _representative(ms: MultistartResult) -> TrajOptResult | None:
    """Return the start to report: the best converged one, else the least violated failure."""
    best = ms.best
    if best is not None and best.result is not None:
        return best.result
    failed = [s.result for s in ms.starts if s.result is not None]
    if not failed:
        return None
    return min(failed, key=lambda r: (not math.isfinite(r.max_violation), r.max_violation))


_PLOTS = "youbot_opt.viz.plots"


STARTS_FOLDER = "starts"
"""Sub-folder of ``solve --starts K --out D`` where the starts are saved (a rerun resumes)."""


def _multistart(args: argparse.Namespace, solver: TrajOptSolver) -> MultistartResult:
    """Run the starts in a process pool (serial with ``--workers 0``), progress on stderr."""
    if args.workers is not None and args.workers < 0:
        raise ParameterError(f"--workers must be >= 0, got {args.workers}", name="workers")
    executor: str = "serial" if args.workers == 0 else "process"
    executor = scheduler_address(args) or executor  # --scheduler / --scheduler-file: Dask
    prog = ProgressLine("solve", args.quiet or args.json)
    # --out D: the starts are saved in D/starts as they finish, so a rerun resumes (#29)
    store = None if args.out is None else Path(args.out) / STARTS_FOLDER
    sweep = SweepOptions(
        executor=executor,
        workers=None if args.workers == 0 else args.workers,
        progress=prog,
        out=store,
    )
    ms = run_multistart(
        solver, args.starts, beta=args.beta, bound_scale=args.bound_scale, seed=args.seed,
        include_straight=args.guess == "straight", sweep=sweep,
    )  # fmt: skip
    prog.close()
    assert isinstance(ms, MultistartResult)  # a ShardReport only with --shard, which solve lacks
    return ms


def run(args: argparse.Namespace) -> int:
    """Run ``youbot-opt solve``; returns the exit code (0 ok, 1 failed solve, 2 bad input)."""
    if args.starts < 1:
        raise ParameterError(f"--starts must be >= 1, got {args.starts}", name="starts")
    if args.knots < 2:
        raise ParameterError(f"--knots must be >= 2, got {args.knots}", name="knots")
    check_beta(args.beta)  # before the NLP is built (the solve checks it with the same rule)
    problem = _problem(args)
    if args.waypoints is not None:
        from youbot_opt.cli.timed import run_solve

        method = "hermite_simpson" if args.transcription is None else transcription(args)
        return run_solve(args, problem, method)
    for flag, given in (("--closed", args.closed), ("--segment-knots", args.segment_knots)):
        if given:
            raise ParameterError(f"{flag} applies with --waypoints only", name=flag[2:])
    check_trajopt_size(
        n_knots=args.knots,
        nq=problem.robot.nq,
        n_starts=args.starts,
        max_knots=args.max_knots if args.refine else 0,
    )  # noqa: E501
    ahead = solve_drawing_ahead(problem, figures=not args.no_figures)
    try:
        return _solve(args, problem, ahead)
    finally:
        ahead.stop()  # when no output was drawn (handed over, it is the drawing's)


def _solve(args: argparse.Namespace, problem: TrajOptProblem, ahead: DrawingAhead) -> int:
    """Solve, refine, print and write the run folder (``ahead`` draws its figures and replay)."""
    solver = TrajOptSolver(problem, transcription(args), ipopt_options(args), args.backend)
    extra: JSONDict = {"build_time_s": solver.build_time, "hessian": solver.hessian}
    ms = None
    if args.starts > 1:
        ms = _multistart(args, solver)
        result = _representative(ms)
        extra["multistart"] = {
            "n_starts": ms.n_starts,
            "success_rate": ms.success_rate,
            "resumed": ms.resumed,  # starts loaded from --out DIR/starts, not solved again
            "starts": [s.summary() for s in ms.starts],
        }
    else:
        guess = None
        if args.guess == "spline":
            guess = random_spline_guess(
                problem.robot, problem.start, problem.goal, problem.n_knots, seed=args.seed,
                dt=default_dt0(problem), bounds=problem.bounds(args.bound_scale),
                damping=problem.damping,
            )  # fmt: skip
        result = solver.solve(
            beta=args.beta, bound_scale=args.bound_scale, guess=guess,
            seed=args.seed if args.guess == "spline" else None,
        )  # fmt: skip
    refined = refine_result(solver, result, args, quiet=args.quiet or args.json)
    record = None
    if refined is not None:
        result, record = refined
    folder = open_folder("solve", args.out)
    if result is None:  # every start raised: no iterate to report
        summary: JSONDict = {
            "status": "error",
            "success": False,
            "message": "every start failed without a result",
            **extra,
        }
        summary["output_folder"] = str(folder.resolve())
        summary["files"] = ["summary.json"]
        files = [write_summary(folder, summary)]
        print(json.dumps(json_ready(summary)) if args.json else "youbot-opt: every start failed")
        report_outputs(folder, files, args.json)
        return 1
    certificate = certificate_of(result, record)
    summary = {**(result.summary() if refined is None else refined.summary()), **extra}
    if certificate is not None:
        summary["certificate"] = certificate.summary()
    has_optimum = ms is not None and ms.best is not None and ms.best.result is not None
    if not args.json:  # the plan and its certificate first, before the figures are drawn
        if ms is not None and not has_optimum:
            print("youbot-opt: no start converged; the least violated failed start follows")
        print(format_result(result, certificate, refinement=record))
        if ms is None and result.success and not problem.robot.name.startswith("youbot"):
            print(MULTISTART_HINT)
        print(flush=True)
    more: list[FigureJob] = []  # matplotlib loads where they are drawn
    if problem.clearance is not None and result.trajectory is not None:
        more.append(
            FigureJob(
                "clearance.png", f"{_PLOTS}.trajopt:plot_clearance", (result,), optional=False
            )
        )
    if problem.tool and result.trajectory is not None:
        more.append(FigureJob("tool.png", f"{_PLOTS}.tool:plot_tool", (result,), optional=False))
    files = write_solve_outputs(
        folder, result, summary, ms if has_optimum else None, refinement=record,
        extra_figures=more, figures=not args.no_figures, ahead=ahead,
    )  # fmt: skip
    if args.json:
        print(json.dumps(json_ready(summary)))
    report_outputs(folder, files, args.json)
    return 0 if result.success and (record is None or record.certified) else 1
