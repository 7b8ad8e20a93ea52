"""The independent check of a trajectory result: :func:`check_result`, :func:`checked`.

A result may call itself a success only if IPOPT converged *and* this check,
which does not use the NLP, agrees: every number finite, every variable within
its bounds, the first and last knots at the start and goal, the collocation
defects recomputed with ``pin.aba`` vanishing, T, W and f following from the
variables. The solver and the loader pass every result through :func:`checked`;
:meth:`~youbot_opt.trajopt.result.TrajOptResult.check` is :func:`check_result`.

>>> result = checked(result)  # status and message now the check's  # doctest: +SKIP
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import NamedTuple, Protocol

import numpy as np

from youbot_opt._typing import Array
from youbot_opt.dynamics.numeric import batched_aba
from youbot_opt.nlp.status import ResultT, SolveStatus, apply_check, status_from_ipopt
from youbot_opt.trajopt import quadrature
from youbot_opt.trajopt.problem import BoundaryState, TrajOptProblem
from youbot_opt.trajopt.trajectory import Trajectory

__all__ = ["ResultCheck", "CheckedSolution", "check_result", "checked"]


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
    clearance : float
        Smallest exact (coal) distance [m] of a checked pair at the knots, for a
        problem with a :class:`~youbot_opt.trajopt.problem.Clearance`; NaN without.
    """

    status: SolveStatus
    message: str
    finite: bool
    bound_violation: float
    boundary_violation: float
    defect: float
    clearance: float = math.nan

    @property
    def passed(self) -> bool:
        """Whether :attr:`status` is a success."""
        return self.status.success


class CheckedSolution(Protocol):
    """What :func:`check_result` reads of a result (a ``TrajOptResult`` has all of it).

    The members are those of :class:`~youbot_opt.trajopt.result.TrajOptResult`
    of the same names, with the same units and shapes.
    """

    @property
    def problem(self) -> TrajOptProblem:
        """The problem that was solved."""
        ...

    @property
    def method(self) -> str:
        """Transcription name (``"trapezoidal"``, ``"hermite_simpson"``, ...)."""
        ...

    @property
    def solver_status(self) -> str:
        """IPOPT's own ``return_status`` string."""
        ...

    @property
    def variables(self) -> Mapping[str, Array]:
        """Every decision-variable block, knot-major."""
        ...

    @property
    def grid(self) -> Array | None:
        """Interval fractions of ``T``, shape (N - 1,), or None for the uniform grid."""
        ...

    @property
    def trajectory(self) -> Trajectory | None:
        """The solution's trajectory (its knots must be the variables)."""
        ...

    @property
    def start(self) -> BoundaryState:
        """Start state of this solve."""
        ...

    @property
    def goal(self) -> BoundaryState:
        """Goal state of this solve."""
        ...

    @property
    def beta(self) -> float:
        """Time weight in [0, 1]."""
        ...

    @property
    def bound_scale(self) -> float:
        """Bound scale factor (1.0 = data sheet)."""
        ...

    @property
    def objective(self) -> float:
        """Reported ``beta T + (1 - beta) W``."""
        ...

    @property
    def duration(self) -> float:
        """Reported duration ``T`` in [s]."""
        ...

    @property
    def dt(self) -> float:
        """Reported mean time step in [s]."""
        ...

    @property
    def work(self) -> float:
        """Reported ``W`` in [N^2 m^2 s]."""
        ...

    @property
    def max_violation(self) -> float:
        """Reported largest constraint violation (units of each row)."""
        ...

    @property
    def feasibility_tol(self) -> float:
        """Largest violation a successful result may have (units of each row)."""
        ...

    def step_ratios(self) -> Array:
        """Step ratios ``h_k / dt`` of the grid, shape (N - 1,)."""
        ...


def _excess(x: Array, lower: Array | float, upper: Array | float) -> float:
    """Largest amount by which ``x`` leaves ``[lower, upper]`` (0 if inside)."""
    return float(np.max(np.maximum(lower - x, x - upper), initial=0.0))


def _defects(result: CheckedSolution, v: Mapping[str, Array], dt: float) -> float | None:
    """Largest collocation defect, with accelerations from ``pin.aba`` (independent path)."""
    problem = result.problem
    aba = batched_aba(problem.robot, damping=problem.damping)
    q, qd, tau = v["q"], v["v"], v["tau"]
    a = aba(q, qd, tau).reshape(qd.shape)
    h: float | Array = dt
    if result.grid is not None:  # interval steps h_k = r_k dt as a column
        h = dt * result.step_ratios()[:, None]
    rows: tuple[Array, ...]
    if result.method == "hermite_simpson":
        qm, vm = v["q_mid"], v["v_mid"]
        am = aba(qm, vm, v["tau_mid"]).reshape(vm.shape)
        rows = (
            q[1:] - q[:-1] - h / 6.0 * (qd[:-1] + 4.0 * vm + qd[1:]),
            qd[1:] - qd[:-1] - h / 6.0 * (a[:-1] + 4.0 * am + a[1:]),
            qm - 0.5 * (q[:-1] + q[1:]) - h / 8.0 * (qd[:-1] - qd[1:]),
            vm - 0.5 * (qd[:-1] + qd[1:]) - h / 8.0 * (a[:-1] - a[1:]),
        )
    elif result.method == "trapezoidal":
        rows = (
            q[1:] - q[:-1] - 0.5 * h * (qd[:-1] + qd[1:]),
            qd[1:] - qd[:-1] - 0.5 * h * (a[:-1] + a[1:]),
        )
    elif result.method == "radau":
        stages = [(v[f"q_stage{i}"], v[f"v_stage{i}"], v[f"tau_stage{i}"]) for i in (1, 2)]
        nodes_q = [s[0] for s in stages] + [q[1:]]
        nodes_v = [s[1] for s in stages] + [qd[1:]]
        nodes_a = [aba(*s).reshape(qd[1:].shape) for s in stages] + [a[1:]]
        nodes_tau = [s[2] for s in stages] + [tau[1:]]
        rows = tuple(
            x[i] - x0 - h * sum(quadrature.RADAU_BUTCHER[i, j] * dx[j] for j in range(3))
            for x, x0, dx in ((nodes_q, q[:-1], nodes_v), (nodes_v, qd[:-1], nodes_a))
            for i in range(3)
        ) + (tau[:1] - sum(quadrature.RADAU_AT_ZERO[j] * nodes_tau[j][:1] for j in range(3)),)
    else:  # another transcription (e.g. the study code's): no independent defect rule here
        return None
    return max(float(np.max(np.abs(r), initial=0.0)) for r in rows)


def _work(result: CheckedSolution, v: Mapping[str, Array], dt: float) -> float:
    """``W`` by the transcription's quadrature, written out here."""
    p = np.sum(v["tau"] ** 2, axis=1)
    if result.method == "radau":  # Radau weights on stages 1, 2 and the end knot
        h = dt * (result.step_ratios() if result.grid is not None else np.ones(p.size - 1))
        p1, p2 = (np.sum(v[f"tau_stage{i}"] ** 2, axis=1) for i in (1, 2))
        b = quadrature.RADAU_WEIGHTS
        return float(np.sum(h * (b[0] * p1 + b[1] * p2 + b[2] * p[1:])))
    if result.grid is not None:
        h = dt * result.step_ratios()
        if result.method == "hermite_simpson":
            pm = np.sum(v["tau_mid"] ** 2, axis=1)
            return float(np.sum(h / 6.0 * (p[:-1] + 4.0 * pm + p[1:])))
        return float(np.sum(0.5 * h * (p[:-1] + p[1:])))
    if result.method == "hermite_simpson":
        pm = np.sum(v["tau_mid"] ** 2, axis=1)
        return float(dt / 6.0 * np.sum(p[:-1] + 4.0 * pm + p[1:]))
    return float(0.5 * dt * np.sum(p[:-1] + p[1:]))


def _knot_clearance(problem: TrajOptProblem, q: Array, tol: float) -> tuple[float, str]:
    """Smallest exact clearance [m] at the knots, and why it falls short of the margin.

    Coal's distances (:mod:`youbot_opt.collision.exact`), not the NLP's balls;
    the NLP's conservative distances are >= the margin at the knots, so coal's
    are too, up to the feasibility tolerance ``tol`` [m].
    """
    spec = problem.clearance
    if spec is None:
        return math.nan, ""
    from youbot_opt.trajopt.clearance import knot_clearance

    found = knot_clearance(problem, q)
    if found is None:
        return math.nan, ""
    low, (a, b), k = found
    if low >= spec.margin - tol:
        return low, ""
    return low, (
        f"clearance {low:.4g} m < margin {spec.margin:g} m at knot {k} ({a!r} / {b!r}, coal)"
    )


def _knot_tool(problem: TrajOptProblem, q: Array, v: Array, tol: float) -> list[str]:
    """Each tool constraint the knots break (Pinocchio's measures; ``tol``: the rows' slack)."""
    if not problem.tool:
        return []
    from youbot_opt.trajopt.tool import knot_tool

    found = knot_tool(problem.robot, problem.tool, q, v)
    return [
        f"{c.label} {value:.4g} {c.unit} > limit {c.limit:g} {c.unit} at knot {k}"
        for c, (value, k) in zip(problem.tool, found, strict=True)
        if value > c.limit + c.slack(tol)
    ]


def check_result(result: CheckedSolution, *, feasibility_tol: float | None = None) -> ResultCheck:
    """Re-check a result independently of IPOPT's flag and of the NLP.

    Starts from IPOPT's own status (``result.solver_status``) and downgrades it
    when the stored solution is not finite (:attr:`SolveStatus.NON_FINITE`),
    malformed or inconsistent with its reported duration, work or objective
    (:attr:`SolveStatus.FAILED`), or -- for a converged solve -- violates a
    variable bound, a boundary state or a collocation defect by more than
    ``feasibility_tol`` (:attr:`SolveStatus.CONSTRAINT_VIOLATION`). The
    defects are recomputed from the decision variables with Pinocchio's
    ``pin.aba`` (:func:`~youbot_opt.dynamics.numeric.batched_aba`), not with
    the CasADi dynamics inside the NLP. The result itself is not changed.

    Parameters
    ----------
    result : TrajOptResult
        The result to check (any :class:`CheckedSolution`).
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
    elif result.method == "radau":
        shapes.update({f"{x}_stage{i}": (n - 1, nv) for x in ("q", "v", "tau") for i in (1, 2)})
    try:
        v = {k: np.asarray(result.variables[k], dtype=float) for k in shapes}
    except (KeyError, TypeError, ValueError) as exc:
        return fail(SolveStatus.FAILED, f"malformed result: variables lack {exc}")
    if result.grid is not None and np.shape(result.grid) != (n - 1,):
        return fail(SolveStatus.FAILED, f"malformed result: grid shape {np.shape(result.grid)}")
    bad = {k: x.shape for k, x in v.items() if x.shape != shapes[k]}
    if bad:
        return fail(SolveStatus.FAILED, f"malformed result: variable shapes {bad}, want {shapes}")
    scalars = {
        "objective": result.objective,
        "duration": result.duration,
        "dt": result.dt,
        "work": result.work,
        "max_violation": result.max_violation,
    }
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
    clearance, short = _knot_clearance(problem, v["q"], tol)
    if short:
        over.append(short)
    over += _knot_tool(problem, v["q"], v["v"], tol)
    if result.trajectory is None:
        over.append("no trajectory")
    elif not np.array_equal(result.trajectory.q, v["q"]):
        over.append("trajectory knots differ from the variables")
    if base.success and over:
        msg = ", ".join(over + wrong) + f" (feasibility_tol = {tol:.3g})"
        return ResultCheck(SolveStatus.CONSTRAINT_VIOLATION, msg, *figures, clearance)
    if wrong:
        why = "inconsistent result: " + "; ".join(wrong)
        return ResultCheck(SolveStatus.FAILED, why, *figures, clearance)
    return ResultCheck(base, "", *figures, clearance)


def checked(result: ResultT) -> ResultT:
    """Return ``result`` with the status its independent check gives it.

    A success claim that the check refutes is downgraded: the check's status
    replaces ``result.status`` and its reason is appended to ``result.message``.
    A failure stays as it is (the check only downgrades), and so does a success
    the check confirms.

    Parameters
    ----------
    result : TrajOptResult
        A result as built by the solver or read from a file.

    Returns
    -------
    TrajOptResult
        ``result`` itself, or a copy with the downgraded status and message.
    """
    return apply_check(result)
