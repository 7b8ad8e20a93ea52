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
import json
import logging
import math
import sys
from pathlib import Path
from typing import Any

import numpy as np

from youbot_opt._files import json_ready
from youbot_opt.cli.cluster_args import (
    MAX_ITER_LIMIT,
    SEED_LIMIT,
    add_scheduler_args,
    int_in_range,
    out_arg,
)
from youbot_opt.cli.robot_args import add_robot_arguments, is_study_youbot, load_robot
from youbot_opt.cli.run_size import check_trajopt_size
from youbot_opt.exceptions import ParameterError
from youbot_opt.nlp.ipopt import LINEAR_SOLVERS, IpoptOptions

__all__ = [
    "add_refine_arguments",
    "refine_many",
    "refinement_figures",
    "refine_result",
    "refinement_budget",
    "refinement_table",
    "register",
    "run_solve",
    "transcription",
    "format_result",
    "certificate_of",
    "open_folder",
    "write_solve_outputs",
    "optima_replay",
    "draw_figure",
    "replay_html",
    "report_outputs",
]

_log = logging.getLogger(__name__)

DEFAULT_TRANSCRIPTION = "radau"
"""``solve``'s transcription on any robot but the study's youBot (docs/refinement.md)."""


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Add the ``solve`` sub-command."""
    p = sub.add_parser(
        "solve",
        help="optimise a point-to-point trajectory (default: the study-1 youBot problem)",
        description="Solve the time/work trajectory problem f = beta T + (1 - beta) W by "
        "direct collocation with IPOPT.",
    )
    add_robot_arguments(p)
    p.add_argument(
        "--start",
        type=float,
        nargs="+",
        metavar="Q",
        help="start joint positions [rad] (default for the youBot: the study's; required "
        "for any other robot)",
    )
    p.add_argument(
        "--goal",
        type=float,
        nargs="+",
        metavar="Q",
        help="goal joint positions [rad] (default for the youBot: the study's; required "
        "for any other robot)",
    )
    p.add_argument("--beta", type=float, default=0.5, help="time weight in [0, 1] (default 0.5)")
    p.add_argument("--knots", type=int, default=50, help="number of knots (default 50)")
    p.add_argument(
        "--transcription",
        choices=("trapezoidal", "hermite-simpson", "radau", "auto"),
        default=None,
        help="collocation scheme (default: trapezoidal for the study's youBot, as the study "
        f"did; {DEFAULT_TRANSCRIPTION} for any other robot: L-stable, so stiff joint damping "
        "and light links do not keep the refinement from certifying; auto picks radau when "
        "the damping is stiff on the grid, else hermite-simpson)",
    )
    p.add_argument(
        "--guess",
        choices=("straight", "spline"),
        default="straight",
        help="initial guess: straight line or the study's random feasible spline",
    )
    p.add_argument(
        "--seed",
        type=int_in_range("--seed", 0, SEED_LIMIT),
        default=0,
        help="seed of the spline guess(es) (default 0)",
    )
    p.add_argument(
        "--starts",
        type=int,
        default=1,
        help="number of random starts; > 1 runs a multistart (default 1)",
    )
    p.add_argument(
        "--workers",
        type=int,
        default=None,
        help="parallel starts with --starts > 1 (default: the CPUs available; 0: serial)",
    )
    p.add_argument("--quiet", action="store_true", help="no progress on stderr (implied by --json)")
    add_scheduler_args(p, shard=False)  # the --starts > 1 multistart runs on Dask with them
    p.add_argument(
        "--bound-scale",
        type=float,
        default=1.0,
        help="scale of all bounds, 1.0 = data sheet (default 1.0)",
    )
    p.add_argument(
        "--damping",
        type=float,
        default=None,
        help="youBot joint damping [N m s/rad] (the study's code: 0.1; default 0)",
    )
    p.add_argument(
        "--backend",
        choices=("symbolic", "pinocchio"),
        default="symbolic",
        help="dynamics backend (default symbolic: exact Hessian)",
    )
    add_ipopt_arguments(p)
    p.add_argument(
        "--out",
        type=lambda text: Path(out_arg(text)),
        default=None,
        metavar="DIR",
        help="output folder (default: a new youbot_opt_runs/solve-<date>-<time>)",
    )
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    add_refine_arguments(p)
    p.set_defaults(func=run_solve)  # fmt: skip


def add_ipopt_arguments(p: argparse.ArgumentParser) -> None:
    """IPOPT's iteration cap and linear solver (read back by :func:`ipopt_options`)."""
    p.add_argument(
        "--max-iter",
        type=int_in_range("--max-iter", 0, MAX_ITER_LIMIT),
        default=3000,
        help="IPOPT iteration cap (default 3000)",
    )
    p.add_argument(
        "--linear-solver",
        choices=LINEAR_SOLVERS,
        default="mumps",
        help="IPOPT's sparse linear solver (default mumps; HSL's ma27/ma57/... need "
        "--linear-solver-library)",
    )
    p.add_argument(
        "--linear-solver-library",
        default=None,
        metavar="PATH",
        help="the library IPOPT loads HSL's solvers (libhsl.so) or Pardiso from",
    )


def ipopt_options(args: argparse.Namespace) -> IpoptOptions:
    """Return the :class:`IpoptOptions` of :func:`add_ipopt_arguments`' flags."""
    return IpoptOptions(
        max_iter=args.max_iter,
        linear_solver=args.linear_solver,
        linear_solver_library=args.linear_solver_library,
    )


MULTISTART_HINT = (
    "note: one start finds a local optimum; a multistart may find a better one: --starts 8"
)


def add_refine_arguments(
    p: argparse.ArgumentParser,
    grid: str = "the grid of --knots",
    unrefined: str = "the plan is certified once on it, not refined",
) -> None:
    """Add the mesh-refinement options (on by default; ``--no-refine`` keeps the grid).

    ``grid`` names the starting grid in the help (``main`` has no ``--knots``),
    ``unrefined`` says what ``--no-refine`` does with the plan.
    """
    g = p.add_argument_group(
        "mesh refinement",
        f"by default {grid} is refined until every interval's collocation error "
        "is within --error-tol and the plan passes its certificate (or the budget runs out)",
    )
    g.add_argument(
        "--no-refine",
        dest="refine",
        action="store_false",
        help=f"keep {grid}: {unrefined}",
    )
    g.add_argument(
        "--error-tol",
        type=float,
        default=1e-3,
        help="largest relative collocation error of an interval (default 1e-3)",
    )
    g.add_argument("--max-rounds", type=int, default=8, help="refinement rounds (default 8)")
    g.add_argument("--max-knots", type=int, default=1000, help="largest grid (default 1000)")
    g.add_argument(
        "--refine-time",
        type=float,
        default=None,
        metavar="SECONDS",
        help="no new refinement round after this wall time [s] (default: no limit)",
    )


def refinement_budget(args: argparse.Namespace) -> Any:
    """Return the :class:`~youbot_opt.trajopt.refine.RefinementBudget` of the options."""
    from youbot_opt.trajopt.refine import RefinementBudget

    return RefinementBudget(
        tolerance=args.error_tol,
        max_rounds=args.max_rounds,
        max_knots=args.max_knots,
        time_limit=args.refine_time,
    )


def refine_result(solver: Any, result: Any, args: argparse.Namespace, quiet: bool = False) -> Any:
    """Refine ``result`` (solved on ``solver``'s grid) unless ``--no-refine``; progress: stderr.

    Returns
    -------
    Refined or None
        :func:`~youbot_opt.trajopt.refine.refine`'s result and record; None with
        ``--no-refine`` or when there is no trajectory to refine.
    """
    if not getattr(args, "refine", False) or result is None or result.trajectory is None:
        return None
    from youbot_opt.trajopt.refine import refine

    def progress(r: Any) -> None:
        if not quiet:
            verdict = {True: "passes", False: "fails", None: "not run"}[r.certificate_passed]
            print(
                f"refine: round {r.index}: {r.n_knots} knots, f = {r.objective:.6g}, "
                f"T = {r.duration:.4g} s, max error {r.max_error:.3g}, certificate {verdict}",
                file=sys.stderr,
                flush=True,
            )

    return refine(solver, first=result, budget=refinement_budget(args), progress=progress)


def refine_many(
    solver: Any, items: list[tuple[str, Any]], args: argparse.Namespace, quiet: bool = False
) -> tuple[list[Any], list[str], list[dict[str, Any]]]:
    """Refine the labelled results of a study (``--no-refine``: nothing, empty outputs).

    Returns
    -------
    refined : list of (TrajOptResult, Refinement or None)
        The refined results and their records, in order (the record is None
        for a result without a trajectory, left as it was).
    lines : list of str
        One table line per result: label, knots, ``f``, ``T``, certified or why not.
    summaries : list of dict
        Per result: its label and :meth:`Refinement.summary`.
    """
    if not getattr(args, "refine", False) or not items:
        return [], [], []
    refined, summaries = [], []
    lines = [
        f"refined ({refinement_budget(args).describe()}):",
        f"  {'':<14} {'knots':>6} {'f':>12} {'T [s]':>9}  certified",
    ]
    for label, result in items:
        if not quiet:
            print(f"refine: {label}", file=sys.stderr, flush=True)
        done = refine_result(solver, result, args, quiet=True)
        r, record = (result, None) if done is None else done
        refined.append((r, record))
        verdict = (
            "no trajectory"
            if record is None
            else "yes"
            if record.certified
            else "no: " + record.reason
        )
        lines.append(
            f"  {label:<14} {r.problem.n_knots:>6} {r.objective:>12.6f} {r.duration:>9.4f}  "
            f"{verdict}"
        )
        summaries.append({"label": label, **(record.summary() if record else {})})
    return refined, lines, summaries


def refinement_figures(folder: Path, refined: list[Any], labels: list[str]) -> list[Path | None]:
    """Draw each refined plan's rounds: ``refinement.png``, or ``refinement_<k>.png`` for several.

    Plans without a refinement record (no trajectory to refine) are skipped;
    ``k`` counts from 1 in the order of ``refined``, and the title names the label.
    Nothing is drawn when nothing was refined (``--no-refine``).
    """
    from youbot_opt.viz.plots.trajopt import plot_refinement

    if not refined:
        return []
    done = [(record, label) for (_, record), label in zip(refined, labels, strict=True) if record]
    return [
        draw_figure(
            folder,
            "refinement.png" if len(done) == 1 else f"refinement_{k}.png",
            plot_refinement,
            record,
            title=f"{label}: {record.reason}",
        )
        for k, (record, label) in enumerate(done, start=1)
    ]


def refinement_table(result: Any, record: Any = None) -> list[str]:
    """Lines describing a result's grid and certification (its refinement ``record``)."""
    from youbot_opt.cli.advice import next_step

    if record is None:
        return [
            f"grid          fixed uniform, {result.problem.n_knots} knots "
            "(--no-refine: not refined, certified once on this grid)"
        ]
    lines = [
        f"certified     {'yes' if record.certified else 'NO'}: {record.reason}",
        f"  {'round':>5} {'knots':>6} {'f':>12} {'T [s]':>9} {'max error':>10} "
        f"{'fb RMS':>7} {'fb peak':>7} {'cert.':>6} {'time [s]':>8}",
    ]
    for r in record.rounds:
        verdict = {True: "pass", False: "fail", None: "-"}[r.certificate_passed]
        lines.append(
            f"  {r.index:>5} {r.n_knots:>6} {r.objective:>12.6f} {r.duration:>9.4f} "
            f"{r.max_error:>10.3g} {r.feedback_rms:>7.3f} {r.feedback_peak:>7.3f} "
            f"{verdict:>6} {r.solve_time + r.check_time:>8.3f}"
        )
    if not record.certified:
        lines.append(f"next          {next_step(result, record)}")
    return lines


def _problem(args: argparse.Namespace) -> Any:
    from youbot_opt.reproduction.study1 import study1_problem
    from youbot_opt.trajopt.problem import BoundaryState, TrajOptProblem

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


def certificate_of(result: Any, record: Any = None) -> Any:
    """Return the :func:`youbot_opt.trajopt.certify.certify` certificate of ``result``, or None.

    The last round's certificate of its refinement ``record``, when it has one.
    """
    if result.trajectory is None:
        return None
    if record is not None and record.certificate is not None:
        return record.certificate  # the last round's, already computed
    try:
        from youbot_opt.trajopt.certify import certify
    except ImportError:  # pragma: no cover - verify is part of the package
        return None
    return certify(result)


def _status_line(result: Any, record: Any) -> str:
    """Return the status line: for a refined plan, whether it is certified (and why not)."""
    if record is None or record.certified or not result.success:
        return f"{result.status.value} ({result.message})"
    return f"{result.status.value}, NOT certified: {record.reason.removeprefix('not certified: ')}"


def _bound_unit(bound: str, unit: Any) -> str:
    """Return the unit of an active bound's value (``position_lower``: the joint's position's)."""
    family = bound.split("_")[0]
    return {"position": unit.position, "velocity": unit.velocity}.get(family, unit.effort)


def format_result(
    result: Any, certificate: Any = None, *, refinement: Any = None, max_active: int = 12
) -> str:
    """Readable multi-line summary of a result (its certificate, its refinement record)."""
    s = result.summary()
    lines = [
        f"{s['robot']}: {s['n_knots']} knots, {s['method']}, backend {s['backend']}, "
        f"beta = {s['beta']:g}, bound scale = {s['bound_scale']:g}",
        f"status        {_status_line(result, refinement)}",
        f"objective f   {result.objective:.6f}   (beta T + (1 - beta) W)",
        f"duration T    {result.duration:.5f} s   (dt = {result.dt:.6f} s)",
        f"work W        {result.work:.5f} N^2 m^2 s",
        f"iterations    {result.iterations}",
        f"solve time    {result.wall_time:.4f} s wall, {result.cpu_time:.4f} s CPU",
        f"max violation {result.max_violation:.2e}",
    ]
    lines += refinement_table(result, refinement)
    from youbot_opt.cli.advice import gripper_note

    note = gripper_note(result)
    if note:
        lines.append(note)
    if certificate is not None:
        lines += ["", str(certificate)]
    active = result.active_bounds(1e-6) if result.trajectory is not None else []
    lines += ["", f"active bounds (within 1e-6): {len(active)}"]
    if active:
        width = max(16, *(len(row.name) + 1 for row in active[:max_active]))
        units = result.problem.robot.joint_units()
        header = f"{'knot':>5}{'joint':>6}{'value':>13} {'unit':<6}{'multiplier':>13}"
        lines.append(f"  {'bound':<{width}}{header}")
        for row in active[:max_active]:
            unit = _bound_unit(row.name, units[row.joint])
            lines.append(
                f"  {row.name:<{width}}{row.knot:>5}{row.joint:>6}{row.value:>13.6f} {unit:<6}"
                f"{row.multiplier:>13.4e}"
            )
        if len(active) > max_active:
            lines.append(f"  ... {len(active) - max_active} more")
    return "\n".join(lines)


def open_folder(command: str, out: str | Path | None) -> Path:
    """Create the run's output folder (:func:`youbot_opt.cli.output.run_folder`).

    Raises
    ------
    ParameterError
        If ``out`` exists and is not a folder, or cannot be created.
    """
    from youbot_opt.cli.output import run_folder

    try:
        return run_folder(command, out)
    except OSError as exc:
        raise ParameterError(
            f"cannot use the output folder (--out): {exc}", name="out", value=out
        ) from exc


def draw_figure(folder: Path, name: str, make: Any, *args: Any, **kwargs: Any) -> Path | None:
    """Draw and save one figure; a figure that cannot be drawn is logged and skipped."""
    from youbot_opt.cli.output import save_figure

    try:
        fig = make(*args, **kwargs)
    except ParameterError as exc:  # e.g. no converged run to draw
        _log.warning("figure %s not drawn: %s", name, exc)
        return None
    return save_figure(fig, folder, name)


def write_solve_outputs(
    folder: Path,
    result: Any,
    summary: dict[str, Any],
    multistart: Any = None,
    *,
    refinement: Any = None,
) -> list[Path]:
    """Write a solve's result, figures, replay and summary into ``folder``.

    Parameters
    ----------
    folder : Path
        The run's output folder.
    result : TrajOptResult
        The solution (the best start's after a multistart).
    summary : dict
        The JSON summary; ``"output_folder"`` and ``"files"`` are added.
    multistart : MultistartResult, optional
        The multistart the result comes from: adds its histogram, and the
        replay shows its distinct optima side by side.
    refinement : Refinement, optional
        The record of the refinement that made ``result``: saved with it, drawn
        (``refinement.png``) and summarised (``"refinement"``).

    Returns
    -------
    list of Path
        The files written, ``summary.json`` last.
    """
    from youbot_opt.cli.output import write_summary
    from youbot_opt.trajopt.io import save_result
    from youbot_opt.viz.plots import plot_arm_2d, plot_convergence, plot_multistart, plot_trajectory
    from youbot_opt.viz.plots.trajopt import plot_refinement

    files: list[Path | None] = [save_result(result, folder / "result.npz", refinement=refinement)]
    if result.trajectory is not None:
        files.append(draw_figure(folder, "trajectory.png", plot_trajectory, result))
        files.append(draw_figure(folder, "arm.png", plot_arm_2d, None, result))
    if refinement is not None:
        files.append(draw_figure(folder, "refinement.png", plot_refinement, refinement))
        summary["refinement"] = refinement.summary()
    runs = multistart if multistart is not None else refinement  # its every round's solve
    runs = [result] if runs is None else runs
    files.append(draw_figure(folder, "convergence.png", plot_convergence, runs))
    if multistart is not None:
        files.append(draw_figure(folder, "multistart.png", plot_multistart, multistart))
        files.append(optima_replay(folder, multistart))
    elif result.trajectory is not None:
        files.append(replay_html(folder, [result], [f"f = {result.objective:.5g}"]))
    written = [f for f in files if f is not None]
    summary["output_folder"] = str(folder.resolve())
    summary["files"] = [f.name for f in written] + ["summary.json"]
    written.append(write_summary(folder, summary))
    return written


def optima_replay(
    folder: Path,
    multistart: Any,
    objective_tol: float = 1e-5,
    traj_tol: float = 1e-2,
    limit: int = 6,
) -> Path | None:
    """Write ``replay.html`` with up to ``limit`` distinct optima of a multistart, side by side."""
    optima = multistart.distinct_optima(objective_tol, traj_tol)[:limit]
    labels = [
        f"optimum {i + 1}: f = {o.objective:.5g}, {o.count} of {o.n_starts} starts"
        for i, o in enumerate(optima)
    ]
    return replay_html(folder, [o.best.result for o in optima], labels)


def replay_html(folder: Path, results: list[Any], labels: list[str]) -> Path | None:
    """Write ``replay.html``: the results side by side (one: the plain replay)."""
    kept = [(r, lab) for r, lab in zip(results, labels, strict=True) if r is not None]
    if not kept or any(r.trajectory is None for r, _ in kept):
        return None
    if len(kept) == 1:
        from youbot_opt.viz.meshcat.replay import export_html

        traj = kept[0][0].trajectory
        return export_html(kept[0][0].problem.robot, traj.t, traj.q, folder / "replay.html")
    from youbot_opt.viz.meshcat.results import export_results_html

    return export_results_html(
        [r for r, _ in kept], folder / "replay.html", labels=[lab for _, lab in kept]
    )


def report_outputs(folder: Path, files: list[Path], as_json: bool) -> None:
    """Print the output folder and its files: to stdout, or to stderr under ``--json``."""
    from youbot_opt.cli.output import print_outputs

    print_outputs(folder, files, stream=sys.stderr if as_json else sys.stdout)


def _representative(ms: Any) -> Any:
    """Return the start to report: the best converged one, else the least violated failure."""
    best = ms.best
    if best is not None and best.result is not None:
        return best.result
    failed = [s.result for s in ms.starts if s.result is not None]
    if not failed:
        return None
    return min(failed, key=lambda r: (not math.isfinite(r.max_violation), r.max_violation))


def _multistart(args: argparse.Namespace, solver: Any) -> Any:
    """Run the starts in a process pool (serial with ``--workers 0``), progress on stderr."""
    from youbot_opt.cli.cluster_args import scheduler_address
    from youbot_opt.cli.output import ProgressLine
    from youbot_opt.sweeps.options import SweepOptions
    from youbot_opt.trajopt.multistart import run_multistart

    if args.workers is not None and args.workers < 0:
        raise ParameterError(f"--workers must be >= 0, got {args.workers}", name="workers")
    executor: str = "serial" if args.workers == 0 else "process"
    executor = scheduler_address(args) or executor  # --scheduler / --scheduler-file: Dask
    prog = ProgressLine("solve", args.quiet or args.json)
    sweep = SweepOptions(
        executor=executor, workers=None if args.workers == 0 else args.workers, progress=prog
    )
    ms = run_multistart(
        solver, args.starts, beta=args.beta, bound_scale=args.bound_scale, seed=args.seed,
        include_straight=args.guess == "straight", sweep=sweep,
    )  # fmt: skip
    prog.close()
    return ms


def transcription(args: argparse.Namespace) -> str:
    """Return the transcription of the options: ``--transcription``, else the default.

    The study's youBot keeps the study's trapezoid (its reproduction depends on
    it); any other robot gets :data:`DEFAULT_TRANSCRIPTION`.
    """
    if args.transcription is not None:
        return str(args.transcription).replace("-", "_")
    return "trapezoidal" if is_study_youbot(args) else DEFAULT_TRANSCRIPTION


def run_solve(args: argparse.Namespace) -> int:
    """Run ``youbot-opt solve``; returns the exit code (0 ok, 1 failed solve, 2 bad input)."""
    from youbot_opt._checks import check_beta
    from youbot_opt.trajopt.solver import TrajOptSolver

    if args.starts < 1:
        raise ParameterError(f"--starts must be >= 1, got {args.starts}", name="starts")
    if args.knots < 2:
        raise ParameterError(f"--knots must be >= 2, got {args.knots}", name="knots")
    check_beta(args.beta)  # before the NLP is built (the solve checks it with the same rule)
    problem = _problem(args)
    check_trajopt_size(
        n_knots=args.knots,
        nq=problem.robot.nq,
        n_starts=args.starts,
        max_knots=args.max_knots if args.refine else 0,
    )  # noqa: E501
    solver = TrajOptSolver(problem, transcription(args), ipopt_options(args), args.backend)
    extra: dict[str, Any] = {"build_time_s": solver.build_time}
    ms = None
    if args.starts > 1:
        ms = _multistart(args, solver)
        result = _representative(ms)
        extra["multistart"] = {
            "n_starts": ms.n_starts,
            "success_rate": ms.success_rate,
            "starts": [s.summary() for s in ms.starts],
        }
    else:
        guess = None
        if args.guess == "spline":
            from youbot_opt.trajopt.spline_guess import random_spline_guess
            from youbot_opt.trajopt.sweep import default_dt0

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
        summary: dict[str, Any] = {
            "status": "error",
            "success": False,
            "message": "every start failed without a result",
            **extra,
        }
        from youbot_opt.cli.output import write_summary

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
    files = write_solve_outputs(
        folder, result, summary, ms if has_optimum else None, refinement=record
    )
    if args.json:
        print(json.dumps(json_ready(summary)))
    else:
        if ms is not None and not has_optimum:
            print("youbot-opt: no start converged; the least violated failed start follows")
        print(format_result(result, certificate, refinement=record))
        if ms is None and result.success and not problem.robot.name.startswith("youbot"):
            print(MULTISTART_HINT)
        print()
    report_outputs(folder, files, args.json)
    return 0 if result.success and (record is None or record.certified) else 1
