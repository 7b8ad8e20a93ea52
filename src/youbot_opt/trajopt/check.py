"""Independent re-check of a trajectory result: :func:`check_result`.

A :class:`~youbot_opt.trajopt.result.TrajOptResult` may call itself a success only if
IPOPT converged *and* this module, which does not use the NLP, agrees: every
number is finite, every variable is within its bounds, the first and last knots
are the start and goal, the collocation defects recomputed with Pinocchio's
numeric ``pin.aba`` vanish, and the reported T, W and f follow from the
variables. :class:`~youbot_opt.trajopt.result.TrajOptResult` applies it in
``__post_init__`` and downgrades the status when a check fails.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from types import MappingProxyType
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from youbot_opt._typing import Array
from youbot_opt.trajopt.result import (
    BoundStructure,
    PathBlock,
    SolveStatus,
    status_from_ipopt,
)

if TYPE_CHECKING:
    from youbot_opt.trajopt.result import TrajOptResult

__all__ = ["ResultCheck", "check_result"]


class ResultCheck(NamedTuple):
    """Verdict of :func:`check_result`: the status a result deserves and why.

    Attributes
    ----------
    status : SolveStatus
        IPOPT's status (from ``solver_status``), downgraded when a check fails.
    message : str
        What failed (empty if nothing did).
    finite : bool
        Every variable and reported figure is finite.
    bound_violation : float
        Largest excess of a variable over its bound (``dt`` too), in its unit.
    boundary_violation : float
        Largest deviation of the first and last knot from start and goal, [rad] or [rad/s].
    defect : float
        Largest collocation defect by ``pin.aba`` (not CasADi), [rad] or [rad/s];
        NaN for a transcription other than trapezoidal and Hermite-Simpson.
    """

    status: SolveStatus
    message: str
    finite: bool
    bound_violation: float
    boundary_violation: float
    defect: float

    @property
    def passed(self) -> bool:
        """Whether :attr:`status` is a success."""
        return self.status.success


def _transcription_named(method: str) -> Any:
    """Return the transcription named ``method``, or None if it is not registered."""
    from youbot_opt.exceptions import ParameterError
    from youbot_opt.trajopt.transcription import get_transcription

    try:
        return get_transcription(method)
    except ParameterError:
        return None


def derive_structure(result: TrajOptResult) -> BoundStructure:
    """Return the :class:`BoundStructure` of a result, from its transcription's name.

    Parameters
    ----------
    result : TrajOptResult
        A result whose :attr:`~TrajOptResult.bound_structure` was not stored
        (for example one loaded from a file).

    Returns
    -------
    BoundStructure
        The unbounded variable blocks and the path-inequality rows of the NLP.
    """
    import casadi as ca

    from youbot_opt.trajopt.transcription.base import Transcription

    method = _transcription_named(result.method)
    if method is None:
        return BoundStructure(unbounded=(), path=MappingProxyType({}))
    unbounded = tuple(method.unbounded)
    if type(method).path_constraints is Transcription.path_constraints:  # none
        return BoundStructure(unbounded=unbounded, path=MappingProxyType({}))
    from youbot_opt.trajopt.simulate import _batched_aba, robot_view

    view = robot_view(result.problem.robot)
    if not result.problem.damping:
        view = view._replace(damping=np.zeros_like(view.damping))
    aba = _batched_aba(view)
    sym = {k: ca.DM(np.asarray(x, dtype=float).T) for k, x in result.variables.items()}
    accel: dict[str, Any] = {}
    for group, (q, v, tau) in method.dynamics_points(sym).items():
        qn, vn, taun = (np.asarray(x, dtype=float).T for x in (q, v, tau))
        accel[group] = ca.DM(np.asarray(aba(qn, vn, taun)).reshape(vn.shape).T)
    path = {
        name: PathBlock(family=family, values=np.asarray(expr, dtype=float).T)
        for name, family, expr in method.path_constraints(sym, accel)
    }
    return BoundStructure(unbounded=unbounded, path=MappingProxyType(path))


def _excess(x: Array, lower: Any, upper: Any) -> float:
    return float(np.max(np.maximum(lower - x, x - upper), initial=0.0))


def _defects(result: TrajOptResult, v: Mapping[str, Array], dt: float) -> float | None:
    """Largest collocation defect, with accelerations from ``pin.aba`` (independent path)."""
    from youbot_opt.trajopt.simulate import _batched_aba, robot_view

    problem = result.problem
    view = robot_view(problem.robot)
    if not problem.damping:
        view = view._replace(damping=np.zeros_like(view.damping))
    aba = _batched_aba(view)
    q, qd, tau = v["q"], v["v"], v["tau"]
    a = aba(q, qd, tau).reshape(qd.shape)
    rows: tuple[Array, ...]
    if result.method == "hermite_simpson":
        qm, vm = v["q_mid"], v["v_mid"]
        am = aba(qm, vm, v["tau_mid"]).reshape(vm.shape)
        rows = (
            q[1:] - q[:-1] - dt / 6.0 * (qd[:-1] + 4.0 * vm + qd[1:]),
            qd[1:] - qd[:-1] - dt / 6.0 * (a[:-1] + 4.0 * am + a[1:]),
            qm - 0.5 * (q[:-1] + q[1:]) - dt / 8.0 * (qd[:-1] - qd[1:]),
            vm - 0.5 * (qd[:-1] + qd[1:]) - dt / 8.0 * (a[:-1] - a[1:]),
        )
    elif result.method == "trapezoidal":
        rows = (
            q[1:] - q[:-1] - 0.5 * dt * (qd[:-1] + qd[1:]),
            qd[1:] - qd[:-1] - 0.5 * dt * (a[:-1] + a[1:]),
        )
    else:  # another transcription (e.g. the study code's): no independent defect rule here
        return None
    return max(float(np.max(np.abs(r), initial=0.0)) for r in rows)


def _work(result: TrajOptResult, v: Mapping[str, Array], dt: float) -> float:
    """``W`` by the transcription's quadrature, written out here."""
    p = np.sum(v["tau"] ** 2, axis=1)
    if result.method == "hermite_simpson":
        pm = np.sum(v["tau_mid"] ** 2, axis=1)
        return float(dt / 6.0 * np.sum(p[:-1] + 4.0 * pm + p[1:]))
    return float(0.5 * dt * np.sum(p[:-1] + p[1:]))


def check_result(result: TrajOptResult, *, feasibility_tol: float | None = None) -> ResultCheck:
    """Classify a result independently of IPOPT's flag.

    Starts from IPOPT's own status (``result.solver_status``) and downgrades it
    when the stored solution is not finite (:attr:`SolveStatus.NON_FINITE`),
    malformed or inconsistent with its reported duration, work or objective
    (:attr:`SolveStatus.FAILED`), or -- for a converged solve -- violates a
    variable bound, a boundary state or a collocation defect by more than
    ``feasibility_tol`` (:attr:`SolveStatus.CONSTRAINT_VIOLATION`). The defects
    are recomputed from the decision variables with Pinocchio's ``pin.aba``,
    not with the CasADi dynamics inside the NLP.

    Parameters
    ----------
    result : TrajOptResult
        The result to check.
    feasibility_tol : float, optional
        Largest accepted violation in the unit of each row ([rad], [rad/s],
        [N m], [s]); ``result.feasibility_tol`` by default.

    Returns
    -------
    ResultCheck
        The status the result deserves, with the measured figures.
    """
    tol = result.feasibility_tol if feasibility_tol is None else float(feasibility_tol)
    base = status_from_ipopt(result.solver_status)
    inf = math.inf

    def fail(status: SolveStatus, why: str, finite: bool = True) -> ResultCheck:
        return ResultCheck(status, why, finite, inf, inf, inf)

    problem = result.problem
    n, nv = problem.n_knots, problem.nv
    shapes = {"q": (n, nv), "v": (n, nv), "tau": (n, nv), "dt": (1, 1)}
    if result.method == "hermite_simpson":
        shapes.update({"q_mid": (n - 1, nv), "v_mid": (n - 1, nv), "tau_mid": (n - 1, nv)})
    try:
        v = {k: np.asarray(result.variables[k], dtype=float) for k in shapes}
    except (KeyError, TypeError, ValueError) as exc:
        return fail(SolveStatus.FAILED, f"malformed result: variables lack {exc}")
    bad = {k: x.shape for k, x in v.items() if x.shape != shapes[k]}
    if bad:
        return fail(SolveStatus.FAILED, f"malformed result: variable shapes {bad}, want {shapes}")
    names = ("objective", "duration", "dt", "work", "max_violation")
    scalars = {name: getattr(result, name) for name in names}
    nonfinite = [k for k, x in v.items() if not np.all(np.isfinite(x))]
    nonfinite += [k for k, x in scalars.items() if not math.isfinite(x)]
    if nonfinite:
        why = f"non-finite values in {', '.join(nonfinite)}"
        return fail(SolveStatus.NON_FINITE, why, finite=False)
    dt = float(v["dt"][0, 0])
    b = problem.bounds(result.bound_scale)
    dt_lo, dt_hi = problem.dt_min, problem.dt_max
    if problem.duration is not None:
        dt_lo = dt_hi = problem.duration / (n - 1)
    # Knot values only: midpoint bounds depend on the transcription (HS leaves v_mid free).
    bound = max(_excess(v["q"], b.q_lower, b.q_upper), _excess(v["v"], b.v_lower, b.v_upper))
    bound = max(bound, _excess(v["tau"], b.tau_lower, b.tau_upper))
    bound = max(bound, _excess(np.array(dt), dt_lo, dt_hi))
    start_v, goal_v = result.start.velocity, result.goal.velocity
    boundary = max(
        float(np.max(np.abs(d)))
        for d in (
            v["q"][0] - result.start.q, v["v"][0] - start_v,
            v["q"][-1] - result.goal.q, v["v"][-1] - goal_v,
        )
    )  # fmt: skip
    if not dt > 0.0:
        why, status = f"time step dt = {dt:.3g} s <= 0", SolveStatus.CONSTRAINT_VIOLATION
        return ResultCheck(status if base.success else base, why, True, bound, boundary, inf)
    try:
        found = _defects(result, v, dt)
    except (ValueError, TypeError) as exc:  # a robot of another size
        return fail(SolveStatus.FAILED, f"malformed result: {exc}")
    defect = math.nan if found is None else found  # NaN: not checked
    figures = (True, bound, boundary, defect)
    if found is not None and not math.isfinite(found):
        return ResultCheck(SolveStatus.NON_FINITE, "non-finite dynamics at the solution", *figures)
    # Reported figures = those of the variables (1e-9 relative: summation order only).
    work = _work(result, v, dt)
    expected = {
        "duration": (n - 1) * dt,
        "work": work,
        "objective": result.beta * (n - 1) * dt + (1.0 - result.beta) * work,
    }
    wrong = [
        f"{k} = {scalars[k]:.9g} but the variables give {x:.9g}"
        for k, x in expected.items()
        if not abs(scalars[k] - x) <= 1e-9 * max(1.0, abs(x))
    ]
    worst = {"bound": bound, "boundary state": boundary, "collocation defect": defect}
    over = [
        f"{k} violated by {x:.3g}" for k, x in worst.items() if x > tol or math.isinf(x)
    ]  # NaN: unchecked
    if result.trajectory is None:
        over.append("no trajectory")
    elif not np.array_equal(result.trajectory.q, v["q"]):
        over.append("trajectory knots differ from the variables")
    if base.success and over:
        msg = ", ".join(over + wrong) + f" (feasibility_tol = {tol:.3g})"
        return ResultCheck(SolveStatus.CONSTRAINT_VIOLATION, msg, *figures)
    if wrong:
        return ResultCheck(SolveStatus.FAILED, "inconsistent result: " + "; ".join(wrong), *figures)
    return ResultCheck(base, "", *figures)
