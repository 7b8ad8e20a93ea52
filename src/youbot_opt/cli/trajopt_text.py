"""The readable text of a solved trajectory: status, figures, refinement, certificate, bounds.

:func:`format_result` is what ``youbot-opt solve`` and ``main`` print;
:func:`certificate_of` finds (or computes) the certificate it shows.

>>> print(format_result(result, certificate_of(result)))  # doctest: +SKIP
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import cast

from youbot_opt.cli.advice import gripper_note
from youbot_opt.cli.refinement import certificate_processes, refinement_table
from youbot_opt.robot.model import JointUnits
from youbot_opt.trajopt.certify import Certificate, certify
from youbot_opt.trajopt.refine import Refinement
from youbot_opt.trajopt.result import TrajOptResult

__all__ = ["MULTISTART_HINT", "certificate_of", "format_result"]

MULTISTART_HINT = (
    "note: one start finds a local optimum; a multistart may find a better one: --starts 8"
)


def certificate_of(result: TrajOptResult, record: Refinement | None = None) -> Certificate | None:
    """Return the :func:`youbot_opt.trajopt.certify.certify` certificate of ``result``, or None.

    The last round's certificate of its refinement ``record``, when it has one.
    A failed solve gets none: its plan is no motion to certify, and simulating it
    can take unbounded time (a 2-knot infeasible solve reports T = 5.7e5 s).
    """
    if result.trajectory is None or not result.success:
        return None
    if record is not None and record.certificate is not None:
        return record.certificate  # the last round's, already computed
    return certify(result, processes=certificate_processes())


def _status_line(result: TrajOptResult, record: Refinement | None) -> str:
    """Return the status line: for a refined plan, whether it is certified (and why not)."""
    if record is None or record.certified or not result.success:
        return f"{result.status.value} ({result.message})"
    return f"{result.status.value}, NOT certified: {record.reason.removeprefix('not certified: ')}"


def _bound_unit(bound: str, unit: JointUnits) -> str:
    """Return the unit of an active bound's value (``position_lower``: the joint's position's)."""
    family = bound.split("_")[0]
    return {"position": unit.position, "velocity": unit.velocity}.get(family, unit.effort)


def format_result(
    result: TrajOptResult,
    certificate: Certificate | None = None,
    *,
    refinement: Refinement | None = None,
    max_active: int = 12,
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
    note = gripper_note(result)
    if note:
        lines.append(note)
    # summary()["tool"] is a list of one document per tool constraint (TrajOptResult.summary)
    for tool in cast("Sequence[Mapping[str, object]]", s.get("tool", ())):
        lines.append(
            f"tool          {tool['label']}: largest at the knots {tool['largest_at_knots']:.4g} "
            f"{tool['unit']} (knot {tool['knot']}), limit {tool['limit']:.4g} {tool['unit']}"
        )
    if certificate is not None:
        lines += ["", str(certificate)]
    elif not result.success:
        lines += ["", "certificate   none: the solve failed, there is no plan to certify"]
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
