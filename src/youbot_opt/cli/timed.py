"""The timed trajectory through waypoints on the command line (#30 item 3).

``youbot-opt solve --waypoints FILE [--closed]`` times the problem's motion
through a user's waypoints; ``youbot-opt ikpath ... --timed`` times the IK
path's configurations as a closed cycle from the first one, at rest
(:func:`youbot_opt.trajopt.timed.solve_through`). The text prints each
waypoint's time, T, W and the certificate; ``summary.json`` holds them under
``"timed"``. Refinement through waypoints is not built: the plan is certified
once on its grid (docs/timed.md).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from youbot_opt._files import json_ready
from youbot_opt._typing import JSONDict
from youbot_opt.cli.flags import ipopt_options
from youbot_opt.cli.output import open_folder, report_outputs, write_solve_outputs
from youbot_opt.cli.trajopt_text import certificate_of, format_result
from youbot_opt.exceptions import ParameterError
from youbot_opt.robot.model import RobotModel
from youbot_opt.trajopt.certify import Certificate
from youbot_opt.trajopt.problem import BoundaryState, TrajOptProblem
from youbot_opt.trajopt.timed import DEFAULT_KNOTS_PER_SEGMENT, TimedResult, TimedSolver
from youbot_opt.trajopt.waypoints import Waypoints, load_waypoints

__all__ = ["NOT_REFINED", "run_solve", "time_ik_path", "timed_lines", "timed_summary"]

NOT_REFINED = "not refined: refinement through waypoints is not built; certified once on its grid"


def timed_summary(timed: TimedResult, certificate: Certificate | None) -> JSONDict:
    """Return the ``"timed"`` entry of ``summary.json``: times [s], T [s], W, certificate."""
    doc: JSONDict = {**timed.summary(), "refined": False, "note": NOT_REFINED}
    doc["certificate"] = None if certificate is None else certificate.summary()
    doc["certified"] = certificate is not None and certificate.ok
    return doc


def timed_lines(timed: TimedResult, certificate: Certificate | None) -> list[str]:
    """Text lines: each waypoint's time, T, W, the waypoint error and the certificate verdict."""
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
    lines.append(f"  {NOT_REFINED}")
    return lines


def _certificate(timed: TimedResult) -> Certificate | None:
    return certificate_of(timed.result) if timed.success else None


def run_solve(args: argparse.Namespace, problem: TrajOptProblem, method: str) -> int:
    """``solve --waypoints FILE``: exit 0 if solved, every waypoint hit and certified, else 1."""
    for flag, bad in (
        ("--starts", args.starts != 1),
        ("--guess spline", args.guess != "straight"),
        ("--knots (use --segment-knots)", args.knots != 50),
    ):
        if bad:
            raise ParameterError(f"{flag} does not apply with --waypoints", name="waypoints")
    refine_flags = (
        ("--error-tol", args.error_tol != 1e-3),
        ("--max-rounds", args.max_rounds != 8),
        ("--max-knots", args.max_knots != 1000),
        ("--refine-time", args.refine_time is not None),
    )
    for flag, given in refine_flags:
        if given:
            raise ParameterError(
                f"{flag}: refinement through waypoints is not built; the plan is certified "
                "once on its grid (--segment-knots sets it)",
                name="waypoints",
            )
    waypoints = load_waypoints(args.waypoints, closed=True if args.closed else None)
    knots = DEFAULT_KNOTS_PER_SEGMENT if args.segment_knots is None else args.segment_knots
    solver = TimedSolver(
        problem, waypoints, method, knots_per_segment=knots, options=ipopt_options(args),
        backend=args.backend,
    )  # fmt: skip
    timed = solver.solve(beta=args.beta, bound_scale=args.bound_scale)
    certificate = _certificate(timed)
    summary: JSONDict = {**timed.result.summary(), "timed": timed_summary(timed, certificate)}
    if certificate is not None:
        summary["certificate"] = certificate.summary()
    if not args.json:
        print(format_result(timed.result, certificate))
        print()
        print("\n".join(timed_lines(timed, certificate)), flush=True)
    folder = open_folder("solve", args.out)
    files = write_solve_outputs(folder, timed.result, summary)
    if args.json:
        print(json.dumps(json_ready(summary)))
    report_outputs(folder, files, args.json)
    return 0 if timed.success and certificate is not None and certificate.ok else 1


def time_ik_path(
    robot: RobotModel, configurations: object, folder: Path, *, knots_per_segment: int | None = None
) -> tuple[JSONDict, list[str], list[Path], bool]:
    """``ikpath --timed``: time the path's configurations as a closed cycle from the first.

    Returns
    -------
    (dict, list of str, list of Path, bool)
        The ``"timed"`` summary entry, its text lines, the files written
        (``timed_result.npz``) and whether it succeeded and is certified.
        ``knots_per_segment``: ``--segment-knots`` (None: the default).
    """
    from youbot_opt.trajopt.io import save_result

    waypoints = Waypoints.from_configurations(configurations, closed=True)
    start = BoundaryState(q=waypoints.q[0])
    problem = TrajOptProblem(robot=robot, start=start, goal=start)
    knots = DEFAULT_KNOTS_PER_SEGMENT if knots_per_segment is None else knots_per_segment
    timed = TimedSolver(problem, waypoints, knots_per_segment=knots).solve()
    certificate = _certificate(timed)
    files: list[Path] = []
    if timed.result.trajectory is not None:
        files.append(save_result(timed.result, folder / "timed_result.npz"))
    ok = timed.success and certificate is not None and certificate.ok
    return timed_summary(timed, certificate), timed_lines(timed, certificate), files, ok
