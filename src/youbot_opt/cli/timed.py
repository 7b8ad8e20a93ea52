"""The timed trajectory through waypoints on the command line (#30 item 3).

``youbot-opt solve --waypoints FILE [--closed]`` times the problem's motion
through a user's waypoints; ``youbot-opt ikpath ... --timed`` times the IK
path's configurations as a closed cycle from the first one, at rest
(:func:`youbot_opt.trajopt.timed.solve_through`). The text prints each
waypoint's time, T, W and the certificate; ``summary.json`` holds them under
``"timed"``. Both refine the plan within its segments by default
(:meth:`~youbot_opt.trajopt.timed.TimedSolver.refine`, the usual refinement
flags; ``--no-refine`` certifies it once on its grid), printing the rounds
(docs/timed.md).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from numpy.typing import ArrayLike

from youbot_opt._files import json_ready
from youbot_opt._typing import JSONDict
from youbot_opt.cli.flags import ipopt_options
from youbot_opt.cli.output import open_folder, report_outputs, write_solve_outputs
from youbot_opt.cli.refinement import (
    certificate_processes,
    refinement_budget,
    refinement_table,
    round_printer,
    scheme_change,
)
from youbot_opt.cli.trajopt_text import certificate_of, format_result
from youbot_opt.exceptions import ParameterError
from youbot_opt.robot.model import RobotModel
from youbot_opt.trajopt.certify import Certificate
from youbot_opt.trajopt.problem import BoundaryState, TrajOptProblem
from youbot_opt.trajopt.timed import DEFAULT_KNOTS_PER_SEGMENT, TimedResult, TimedSolver
from youbot_opt.trajopt.waypoints import Waypoints, load_waypoints

__all__ = ["NOT_REFINED", "run_solve", "time_ik_path", "timed_lines", "timed_summary"]

NOT_REFINED = "not refined (--no-refine): certified once on its grid"


def timed_summary(timed: TimedResult, certificate: Certificate | None) -> JSONDict:
    """Return the ``"timed"`` entry of ``summary.json``: times [s], T [s], W, certificate.

    A refined plan's entry also holds ``"refinement"`` (its rounds); ``"certified"``
    is then the refinement's verdict.
    """
    refined = timed.refinement is not None
    doc: JSONDict = {**timed.summary(), "refined": refined}
    if not refined:
        doc["note"] = NOT_REFINED
    doc["certificate"] = None if certificate is None else certificate.summary()
    doc["certified"] = timed.certified if refined else certificate is not None and certificate.ok
    return doc


def timed_lines(
    timed: TimedResult, certificate: Certificate | None, *, table: bool = True
) -> list[str]:
    """Text lines: each waypoint's time, T, W, the waypoint error, certificate and rounds.

    ``table``: the refinement's rounds as a table (False: one line, the table
    being printed with the result).
    """
    r = timed.result
    closed = " (closed: back to waypoint 1)" if timed.waypoints.closed else ""
    lines = [f"timed through {timed.waypoints.count} waypoints{closed}, {r.method}"]
    for i, t in enumerate(timed.waypoint_times):
        lines.append(f"  waypoint {i + 1:<4} t = {t:.5f} s")
    lines += [
        f"  duration T   {timed.duration:.5f} s",
        f"  work W       {timed.work:.5f} N^2 m^2 s",
        f"  waypoints hit within {timed.waypoint_error:.2e} rad "
        f"(feasibility tol {r.feasibility_tol:.1e})",
        f"  status       {r.status.value}",
    ]
    if certificate is None:
        lines.append("  certificate  none: the solve failed, there is no plan to certify")
    else:
        verdict = "passed" if certificate.ok else "FAILED: " + "; ".join(certificate.failures())
        lines.append(f"  certificate  {verdict}")
    record = timed.refinement
    if record is None:
        lines.append(f"  {NOT_REFINED}")
    elif table:
        lines += [f"  {line}" for line in refinement_table(r, record)]
    else:
        why = record.reason.removeprefix("not certified: ")
        verdict = "certified" if record.certified else f"NOT certified: {why}"
        change = f"; {scheme_change(record)}" if scheme_change(record) else ""
        lines.append(f"  refined      {len(record.rounds)} rounds, {verdict}{change}")
    return lines


def _refined(
    solver: TimedSolver, timed: TimedResult, args: argparse.Namespace, quiet: bool
) -> TimedResult:
    """Refine ``timed`` unless ``--no-refine`` (or nothing to refine); rounds on stderr."""
    if not getattr(args, "refine", True) or timed.result.trajectory is None:
        return timed
    budget = refinement_budget(args)
    return solver.refine(
        first=timed, budget=budget, progress=round_printer(quiet),
        processes=certificate_processes(),
    )  # fmt: skip


def _certificate(timed: TimedResult) -> Certificate | None:
    return certificate_of(timed.result, timed.refinement) if timed.success else None


def run_solve(args: argparse.Namespace, problem: TrajOptProblem, method: str) -> int:
    """``solve --waypoints FILE``: exit 0 if solved, every waypoint hit and certified, else 1."""
    for flag, bad in (
        ("--starts", args.starts != 1),
        ("--guess spline", args.guess != "straight"),
        ("--knots (use --segment-knots)", args.knots != 50),
    ):
        if bad:
            raise ParameterError(f"{flag} does not apply with --waypoints", name="waypoints")
    waypoints = load_waypoints(args.waypoints, closed=True if args.closed else None)
    knots = DEFAULT_KNOTS_PER_SEGMENT if args.segment_knots is None else args.segment_knots
    solver = TimedSolver(
        problem, waypoints, method, knots_per_segment=knots, options=ipopt_options(args),
        backend=args.backend,
    )  # fmt: skip
    timed = solver.solve(beta=args.beta, bound_scale=args.bound_scale)
    timed = _refined(solver, timed, args, quiet=args.quiet or args.json)
    certificate = _certificate(timed)
    summary: JSONDict = {**timed.result.summary(), "timed": timed_summary(timed, certificate)}
    if timed.refinement is not None:
        summary["certified"] = timed.certified
    if certificate is not None:
        summary["certificate"] = certificate.summary()
    if not args.json:
        print(format_result(timed.result, certificate, refinement=timed.refinement))
        print()
        print("\n".join(timed_lines(timed, certificate, table=False)), flush=True)
    folder = open_folder("solve", args.out)
    files = write_solve_outputs(
        folder, timed.result, summary, refinement=timed.refinement, figures=not args.no_figures
    )
    if args.json:
        print(json.dumps(json_ready(summary)))
    report_outputs(folder, files, args.json)
    return 0 if _passed(timed, certificate) else 1


def _passed(timed: TimedResult, certificate: Certificate | None) -> bool:
    """Solved, every waypoint hit and certified (by the refinement when refined)."""
    if timed.refinement is not None:
        return timed.certified
    return timed.success and certificate is not None and certificate.ok


def time_ik_path(
    robot: RobotModel,
    configurations: ArrayLike,
    folder: Path,
    *,
    knots_per_segment: int | None = None,
    args: argparse.Namespace | None = None,
) -> tuple[JSONDict, list[str], list[Path], bool]:
    """``ikpath --timed``: time the path's configurations as a closed cycle from the first.

    Returns
    -------
    (dict, list of str, list of Path, bool)
        The ``"timed"`` summary entry, its text lines, the files written
        (``timed_result.npz``) and whether it succeeded and is certified.
        ``knots_per_segment``: ``--segment-knots`` (None: the default);
        ``args``: the refinement flags (None: refined with the default budget, quietly).
    """
    from youbot_opt.trajopt.io import save_result

    waypoints = Waypoints.from_configurations(configurations, closed=True)
    start = BoundaryState(q=waypoints.q[0])
    problem = TrajOptProblem(robot=robot, start=start, goal=start)
    knots = DEFAULT_KNOTS_PER_SEGMENT if knots_per_segment is None else knots_per_segment
    solver = TimedSolver(problem, waypoints, knots_per_segment=knots)
    timed = solver.solve()
    if args is None:  # the default budget, quietly
        timed = solver.refine(first=timed) if timed.result.trajectory is not None else timed
    else:
        quiet = bool(getattr(args, "no_progress", False) or getattr(args, "json", False))
        timed = _refined(solver, timed, args, quiet)
    certificate = _certificate(timed)
    files: list[Path] = []
    if timed.result.trajectory is not None:
        files.append(
            save_result(timed.result, folder / "timed_result.npz", refinement=timed.refinement)
        )
    ok = _passed(timed, certificate)
    return timed_summary(timed, certificate), timed_lines(timed, certificate), files, ok
