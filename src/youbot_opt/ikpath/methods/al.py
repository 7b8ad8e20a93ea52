"""The study's method: augmented Lagrangian with a quasi-Newton inner solver.

Nocedal and Wright, *Numerical Optimization* (2nd ed.), Algorithm 17.4
(bound-constrained Lagrangian method) on ``E(x)`` with the target constraints
``c(x) = 0``, the joint box and, with a clearance, the rows ``g(x) >= 0`` by
Powell-Hestenes-Rockafellar terms; the inner solver is
:func:`~youbot_opt.ikpath.methods.bfgs.minimize_bfgs` (or SciPy's L-BFGS-B). Spec
``docs/ikpath.md``; the outer loop, the stopping test, the stall rules and the
inequality rows in docs/design.md, "Module notes". 3-D problems switch on a final
phase of SQP steps (``ALOptions.newton_final``; with clearance rows, the AL's active set).

>>> result = solve_augmented_lagrangian(problem, x0, ALOptions())  # doctest: +SKIP
"""

from __future__ import annotations

import dataclasses
import logging
import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import NamedTuple, TypedDict

import numpy as np
import numpy.typing as npt
import pinocchio as pin
from numpy.typing import ArrayLike
from scipy.optimize import Bounds, minimize

from youbot_opt._checks import check_time_limit
from youbot_opt._typing import Array
from youbot_opt.exceptions import ParameterError
from youbot_opt.ikpath.clearance import IKClearance
from youbot_opt.ikpath.methods.best_iterate import pick_best
from youbot_opt.ikpath.methods.bfgs import minimize_bfgs
from youbot_opt.ikpath.problem import CyclicIKProblem, Evaluation
from youbot_opt.ikpath.result import IKPathResult, OuterIterate, build_result
from youbot_opt.nlp.status import SolveStatus

__all__ = [
    "AL_OPTIONS_3D",
    "ALOptions",
    "ALResultFields",
    "ALRun",
    "first_order_multipliers",
    "run_augmented_lagrangian",
    "solve_augmented_lagrangian",
    "solve_augmented_lagrangian_3d",
]

_log = logging.getLogger(__name__)
_NO_ROWS = np.zeros(0)  # the clearance multipliers of a problem without clearance rows
_NO_ROWS.flags.writeable = False


@dataclass(frozen=True, slots=True, kw_only=True)
class ALOptions:
    """Settings of the augmented Lagrangian method.

    Attributes
    ----------
    penalty_initial : float
        ``mu_0`` (N&W: 10).
    penalty_growth : float
        Factor applied to ``mu`` when the constraints did not improve enough.
    penalty_max : float
        Give up (status ``STALLED``) when ``mu`` would exceed this.
    constraint_tol : float
        ``eta*``: largest accepted ``|c_i|`` in [m].
    stationarity_tol : float
        ``omega*``: largest accepted projected-gradient entry of ``L_A`` in [rad].
    max_outer_iterations : int
        Outer iteration limit.
    max_inner_iterations : int
        Iteration limit of each inner solve.
    stall_increases : int
        Consecutive penalty increases without a 10 % reduction of the
        violation after which the start is declared locally infeasible.
    inner : {"bfgs", "lbfgsb"}
        Inner solver for the bound-constrained case (unlimited problems always
        use BFGS): the projected BFGS of :mod:`youbot_opt.ikpath.methods.bfgs` or SciPy's
        L-BFGS-B.
    max_wall_time : float or None
        Wall-clock limit of the whole solve in [s] (``None``: no limit). Checked
        before every inner iteration; when it is reached the solve stops with
        status ``MAX_TIME`` and the last iterate (unless that iterate already
        meets the stopping test). The overshoot is at most one inner iteration.
    initial_multipliers : {"zero", "least_squares"}
        ``lambda_0``: zero (N&W, the study) or the least-squares estimate at the
        start (:func:`first_order_multipliers`; from a start that meets the targets,
        such as the greedy path, the first inner solve then stays near them).
    retry_least_squares : bool
        After a failed run with ``lambda_0 = 0``, run once more from the same start
        with the least-squares ``lambda_0`` (:func:`run_augmented_lagrangian`).
    newton_final : bool
        Safeguarded final phase: after an outer iteration with ``max |c_i| <=
        newton_violation``, up to 30 SQP (Newton-KKT) steps with the exact Hessian of
        the Lagrangian and the augmented Lagrangian as merit function
        (:func:`_final_phase`); if they meet the stopping test the solve ends there,
        otherwise the AL continues from its own iterate as if nothing happened. Needs
        the problem's ``lagrangian_hessian``. Off by
        default (the planar solver is the study's method as published); on for
        3-D problems, whose nearly singular pose Jacobians make the first-order
        multiplier updates crawl (docs/ikpath.md). With clearance rows the rows with
        ``nu > 0`` are held as equalities (:func:`_final_phase_cleared`).
    newton_violation : float
        ``max |c_i|`` in [m] at which the final phase is tried.
    """

    penalty_initial: float = 10.0
    penalty_growth: float = 10.0
    penalty_max: float = 1e8
    constraint_tol: float = 1e-10
    stationarity_tol: float = 1e-8
    max_outer_iterations: int = 100
    max_inner_iterations: int = 1000
    stall_increases: int = 3
    inner: str = "bfgs"
    max_wall_time: float | None = None
    initial_multipliers: str = "zero"
    retry_least_squares: bool = False
    newton_final: bool = False
    newton_violation: float = 1e-1

    def __post_init__(self) -> None:
        check_time_limit(self.max_wall_time, "ALOptions.max_wall_time")
        if self.initial_multipliers not in ("zero", "least_squares"):
            raise ParameterError(
                "ALOptions.initial_multipliers must be 'zero' or 'least_squares', got "
                f"{self.initial_multipliers!r}",
                name="initial_multipliers",
                value=self.initial_multipliers,
            )
        if self.inner not in ("bfgs", "lbfgsb"):
            raise ParameterError(
                f"ALOptions.inner must be 'bfgs' or 'lbfgsb', got {self.inner!r}",
                name="inner",
                value=self.inner,
            )
        checks = {
            "penalty_initial": self.penalty_initial > 0,
            "penalty_growth": self.penalty_growth > 1,
            "penalty_max": self.penalty_max >= self.penalty_initial,
            "constraint_tol": self.constraint_tol > 0,
            "stationarity_tol": self.stationarity_tol > 0,
            "max_outer_iterations": self.max_outer_iterations >= 1,
            "max_inner_iterations": self.max_inner_iterations >= 1,
            "stall_increases": self.stall_increases >= 1,
            "newton_violation": self.newton_violation > 0,
        }
        for key, ok in checks.items():
            if not ok:
                raise ParameterError(
                    f"ALOptions.{key} = {getattr(self, key)!r} is invalid "
                    "(penalties > 0, growth > 1, tolerances > 0, iteration limits >= 1)",
                    name=key,
                    value=getattr(self, key),
                )


def solve_augmented_lagrangian(
    problem: CyclicIKProblem, x0: ArrayLike | None = None, options: ALOptions | None = None
) -> IKPathResult:
    """Solve the cyclic IK-path problem by the augmented Lagrangian method.

    Parameters
    ----------
    problem : CyclicIKProblem
        The problem; its joint limits are honoured when ``problem.bounded``.
    x0 : array_like, shape (n s,) or (s, n), optional
        Start in [rad]; the zero vector (clipped into the limits) by default.
    options : ALOptions, optional
        Method settings.

    Returns
    -------
    IKPathResult
        ``method = "al"``; the history has one :class:`OuterIterate` per outer
        iteration. Failures are statuses, the last iterate is kept.

    Raises
    ------
    ParameterError
        If ``x0`` has the wrong shape or violates the joint limits.
    """
    opts = ALOptions() if options is None else options
    start = problem.check_start(x0)
    run = run_augmented_lagrangian(problem, start, opts)
    return build_result(
        problem,
        **run.result_fields(start),
        inner_iterations=run.inner_iterations,
        constraint_tol=opts.constraint_tol,
    )


def solve_augmented_lagrangian_3d(
    problem: CyclicIKProblem,
    x0: ArrayLike | None = None,
    options: ALOptions | None = None,
    *,
    generated: bool = False,
) -> IKPathResult:
    """Solve by the augmented Lagrangian as a general method (any robot, any clearance).

    What :func:`~youbot_opt.ikpath.solve.solve` does with ``method="al"`` on a
    problem it does not give to the planar methods: :data:`AL_OPTIONS_3D` by
    default, a result judged by the targets' own tolerances (no ``constraint_tol``).

    Parameters
    ----------
    problem : CyclicIKProblem
        The problem (its clearance rows, if any, are held).
    x0 : array_like, shape (n s,) or (s, n), optional
        Start in [rad]; the zero vector (clipped into the limits) by default.
    options : ALOptions, optional
        Method settings (default :data:`AL_OPTIONS_3D`).
    generated : bool
        A start a multistart made: it may collide (a user's may not,
        :meth:`CyclicIKProblem.check_start`).

    Returns
    -------
    IKPathResult
        ``method = "al"``; failures are statuses.
    """
    opts = AL_OPTIONS_3D if options is None else options
    start = problem.check_start(x0, generated=generated)
    run = run_augmented_lagrangian(problem, start, opts)
    return build_result(problem, **run.result_fields(start), inner_iterations=run.inner_iterations)


class ALRun(NamedTuple):
    """Raw outcome of :func:`run_augmented_lagrangian` (before a result is built).

    Attributes
    ----------
    status : SolveStatus
        Outcome.
    message : str
        Why the method stopped.
    x : ndarray, shape (n s,)
        Final (or best) iterate in [rad].
    multipliers : ndarray, shape (s m,)
        Multiplier estimates (sign convention ``grad E = J^T lambda``).
    history : tuple of OuterIterate
        One record per outer iteration.
    inner_iterations : int
        Total inner iterations.
    wall_time : float
        Time in [s].
    clearance_multipliers : ndarray, shape (n_rows,)
        Multipliers ``nu >= 0`` of the clearance rows ``rows(x) - margin >= 0``
        (:class:`~youbot_opt.ikpath.clearance.IKClearance`, same order; sign
        convention ``grad E = J^T lambda + J_g^T nu``); zero on a row the
        stopping test found inactive; empty without clearance rows.
    """

    status: SolveStatus
    message: str
    x: Array
    multipliers: Array
    history: tuple[OuterIterate, ...]
    inner_iterations: int
    wall_time: float
    clearance_multipliers: Array = _NO_ROWS

    def result_fields(self, start: Array) -> ALResultFields:
        """Return the keywords the result builders share for this run from ``start`` [rad].

        Both :func:`~youbot_opt.ikpath.result.build_result` and the 3-D
        ``build_result`` take them (``method = "al"``).
        """
        return ALResultFields(
            method="al",
            status=self.status,
            x=self.x,
            multipliers=self.multipliers,
            iterations=len(self.history),
            wall_time=self.wall_time,
            message=self.message,
            start=start,
            history=self.history,
            clearance_multipliers=self.clearance_multipliers,
        )


class ALResultFields(TypedDict):
    """Result-builder keywords of one :class:`ALRun` (see :meth:`ALRun.result_fields`)."""

    method: str
    status: SolveStatus
    x: Array
    multipliers: Array
    iterations: int
    wall_time: float
    message: str
    start: Array
    history: tuple[OuterIterate, ...]
    clearance_multipliers: Array


def run_augmented_lagrangian(problem: CyclicIKProblem, start: Array, opts: ALOptions) -> ALRun:
    """Run the augmented Lagrangian loop on a problem from a checked start.

    Every :class:`CyclicIKProblem`, planar chain or 3-D robot, plugs in: the constraints are ``s``
    blocks of ``m`` rows (``m = jacobian_blocks.shape[1]``), each with its own
    Jacobian block, which is all the loop and :func:`first_order_multipliers` use.
    With ``opts.retry_least_squares`` a failed run with ``lambda_0 = 0`` is followed
    by one from the same start with the least-squares ``lambda_0`` (the second
    run's outcome is returned; times and inner iterations add up).
    """
    first = _run_augmented_lagrangian(problem, start, opts)
    if (
        first.status.success
        or not opts.retry_least_squares
        or opts.initial_multipliers == "least_squares"
        or first.status is SolveStatus.MAX_TIME
    ):
        return first
    left = None if opts.max_wall_time is None else opts.max_wall_time - first.wall_time
    if left is not None and left <= 0.0:
        return first
    retry_opts = dataclasses.replace(opts, initial_multipliers="least_squares", max_wall_time=left)
    second = _run_augmented_lagrangian(problem, start, retry_opts)
    return second._replace(
        message=f"{second.message} (retried with least-squares lambda_0 after: "
        f"{first.status.value})",
        inner_iterations=first.inner_iterations + second.inner_iterations,
        wall_time=first.wall_time + second.wall_time,
    )


def _run_augmented_lagrangian(problem: CyclicIKProblem, start: Array, opts: ALOptions) -> ALRun:
    """One run of the loop of :func:`run_augmented_lagrangian` (no retry)."""
    t0 = time.perf_counter()
    deadline = None if opts.max_wall_time is None else t0 + float(opts.max_wall_time)
    data = problem.create_data()
    lower, upper = problem.lower, problem.upper
    bounded = problem.bounded
    s = problem.n_targets
    lam = np.zeros(problem.n_constraints)
    if opts.initial_multipliers == "least_squares":
        lam = first_order_multipliers(problem.evaluate(start, data), start, lower, upper)[0]
    mu = opts.penalty_initial
    omega, eta = 1.0 / mu, 1.0 / mu**0.1
    rows = _clearance_rows(problem)
    nu = np.zeros(0 if rows is None else len(rows.labels))  # clearance multipliers, >= 0

    def lagrangian(x: Array) -> tuple[float, Array]:
        ev = problem.evaluate(x, data)
        c = ev.constraints
        weight = (mu * c - lam).reshape(s, -1)  # d L_A / d c
        value = ev.objective - float(lam @ c) + 0.5 * mu * float(c @ c)
        grad = ev.gradient + np.einsum("jkn,jk->jn", ev.jacobian_blocks, weight).ravel()
        if rows is not None:
            term, term_grad = _clearance_term(rows, x, nu, mu)
            value += term
            if term_grad is not None:
                grad = grad + term_grad
        return value, grad

    x = start.copy()
    history: list[OuterIterate] = []
    inner_total = 0
    best_violation, stalls = math.inf, 0
    status, message = SolveStatus.MAX_ITERATIONS, "outer iteration limit reached"
    for k in range(opts.max_outer_iterations):
        x_new, inner_its, inner_msg = _inner_solve(
            lagrangian, x, lower, upper, bounded, omega, opts, deadline
        )
        inner_total += inner_its
        if not np.all(np.isfinite(x_new)):
            status, message = SolveStatus.NON_FINITE, f"non-finite iterate ({inner_msg})"
            break
        x = x_new
        ev = problem.evaluate(x, data)
        c = ev.constraints
        violation = float(np.max(np.abs(c)))
        _, grad = lagrangian(x)
        nu_new, ev_ls = nu, ev
        if rows is not None:  # inequality rows: violation and complementarity min(g, nu/mu)
            g = _slack(rows, x)
            nu_new = np.maximum(nu - mu * g, 0.0)
            violation = max(violation, float(np.max(np.abs(np.minimum(g, nu / mu)))))
            if np.any(nu_new):
                jtnu = rows.rows_jacobian_transposed(x, nu_new)
                ev_ls = ev._replace(gradient=ev.gradient - jtnu)
        # Stationarity with the AL's own estimate lam - mu c, and with the
        # least-squares estimate at x; either multiplier vector certifies a KKT point.
        lam_ls, stationarity_ls = first_order_multipliers(ev_ls, x, lower, upper)
        stationarity_al = float(np.max(np.abs(x - np.clip(x - grad, lower, upper))))
        stationarity = min(stationarity_al, stationarity_ls)
        history.append(
            OuterIterate(
                k, x.reshape(s, -1).copy(), ev.objective, violation, stationarity, mu, inner_its
            )
        )
        _log.debug(
            "AL %d: E=%.10g |c|=%.3g pg=%.3g mu=%.3g inner=%d (%s)",
            k,
            ev.objective,
            violation,
            stationarity,
            mu,
            inner_its,
            inner_msg,
        )
        if not (math.isfinite(violation) and math.isfinite(stationarity)):
            status, message = SolveStatus.NON_FINITE, "non-finite constraint or gradient"
            break
        if (
            violation <= eta
            and violation <= opts.constraint_tol
            and stationarity <= opts.stationarity_tol
        ):
            lam = lam - mu * c if stationarity_al <= stationarity_ls else lam_ls
            nu = nu_new
            status = SolveStatus.SOLVED
            message = (
                f"|c| = {violation:.2e} <= {opts.constraint_tol:g} and projected "
                f"gradient {stationarity:.2e} <= {opts.stationarity_tol:g}"
                f"{_clearance_note(rows, x, nu)}"
            )
            break
        if _past(deadline):
            status = SolveStatus.MAX_TIME
            message = (
                f"wall-time limit {opts.max_wall_time:g} s reached with |c| = {violation:.2e} m, "
                f"projected gradient {stationarity:.2e} ({inner_msg})"
            )
            break
        if opts.newton_final and rows is not None and violation <= opts.newton_violation:
            final = _final_phase_cleared(
                problem,
                rows,
                x,
                lam - mu * c if stationarity_al <= stationarity_ls else lam_ls,
                nu_new,
                mu,
                opts,
                data,
                deadline,
                start_iteration=k + 1,
                iterations=_FINAL_PHASE_STEPS,
            )
            _log.debug("AL %d: final phase with clearance rows: %s", k, final.message)
            if final.status is SolveStatus.SOLVED:
                history.extend(final.history)
                status, x, lam = final.status, final.x, final.multipliers
                nu = final.clearance_multipliers
                message = f"{final.message}{_clearance_note(rows, x, nu)}"
                break
        if opts.newton_final and rows is None and violation <= opts.newton_violation:
            final = _final_phase(
                problem,  # type: ignore[arg-type]
                x,
                lam - mu * c if stationarity_al <= stationarity_ls else lam_ls,
                mu,
                opts,
                data,
                deadline,
                start_iteration=k + 1,
                iterations=_FINAL_PHASE_STEPS,
            )
            _log.debug("AL %d: final phase: %s", k, final.message)
            if final.status is SolveStatus.SOLVED:
                history.extend(final.history)
                status, message, x, lam = final.status, final.message, final.x, final.multipliers
                break
        if violation <= eta:
            # An inner solve that could not move (its line search lost in the rounding
            # of L_A) leaves c unchanged; repeating lam - mu c would then drift the
            # multipliers by mu c per iteration, so restart from the estimate at x.
            lam = lam - mu * c if inner_its > 0 else lam_ls
            nu = nu_new
            eta = max(eta / mu**0.9, opts.constraint_tol)
            omega = max(omega / mu, opts.stationarity_tol)
        else:
            stalls = stalls + 1 if violation > 0.9 * best_violation else 0
            best_violation = min(best_violation, violation)
            if stalls >= opts.stall_increases:
                status = SolveStatus.INFEASIBLE
                message = (
                    f"locally infeasible: |c| = {violation:.3g} m did not decrease over "
                    f"{stalls} penalty increases (mu = {mu:.3g})"
                )
                break
            if mu * opts.penalty_growth > opts.penalty_max:
                status = SolveStatus.STALLED
                message = (
                    f"penalty would exceed {opts.penalty_max:g} with |c| = {violation:.2e} m"
                    f"{_licq_note(ev, lam, mu)}"
                )
                break
            mu *= opts.penalty_growth
            eta = max(1.0 / mu**0.1, opts.constraint_tol)
            omega = max(1.0 / mu, opts.stationarity_tol)
    if status is not SolveStatus.SOLVED and history and np.all(np.isfinite(x)):
        visited = (h.x.ravel() for h in history)
        x, note = pick_best(problem, x, visited, opts.constraint_tol)  # type: ignore[arg-type]
        message = f"{message}; {note}" if note else message
    return ALRun(status, message, x, lam, tuple(history), inner_total, time.perf_counter() - t0, nu)


def _clearance_rows(problem: CyclicIKProblem) -> IKClearance | None:
    """Return the problem's clearance rows, or None (no clearance, or no pair to keep apart)."""
    rows = problem.clearance_rows
    return None if rows is None or not rows.labels else rows


def _clearance_term(
    rows: IKClearance, x: Array, nu: Array, mu: float
) -> tuple[float, Array | None]:
    """Powell-Hestenes-Rockafellar term of the clearance rows and its gradient (None: zero).

    With ``g = rows(x) - margin >= 0`` and multipliers ``nu >= 0`` the term is
    ``sum_i psi(g_i, nu_i, mu)``, ``psi = -nu g + mu/2 g^2`` where ``g <= nu/mu``,
    else ``-nu^2 / (2 mu)`` (Nocedal and Wright, sec. 17.4: the slacks eliminated), written as
    ``(|max(0, nu - mu g)|^2 - |nu|^2) / (2 mu)``; its gradient is
    ``-J_g^T max(0, nu - mu g)`` (reverse mode; not formed where every row is
    inactive, ``max(0, nu - mu g) = 0``).
    """
    shift = np.maximum(nu - mu * _slack(rows, x), 0.0)
    value = (float(shift @ shift) - float(nu @ nu)) / (2.0 * mu)
    if not np.any(shift):
        return value, None
    return value, -rows.rows_jacobian_transposed(x, shift)


def _slack(rows: IKClearance, x: Array) -> Array:
    """``g(x) = rows(x) - margin`` [m], to be kept ``>= 0``."""
    return rows.rows(x) - rows.spec.margin


def _clearance_note(rows: IKClearance | None, x: Array, nu: Array) -> str:
    """Return the clearance part of a success message (``""`` without clearance rows)."""
    if rows is None:
        return ""
    g = _slack(rows, x)
    return (
        f"; clearance rows >= margin - {max(0.0, -float(np.min(g))):.2e} m, "
        f"{int(np.count_nonzero(nu))} of {g.size} with a multiplier > 0"
    )


class _FinalPhase(NamedTuple):
    """Outcome of :func:`_final_phase` (``sqp_steps``: Newton-KKT steps taken)."""

    status: SolveStatus
    message: str
    x: Array
    multipliers: Array
    history: list[OuterIterate]
    sqp_steps: int
    clearance_multipliers: Array = _NO_ROWS


def _final_phase(
    problem: CyclicIKProblem,
    x: Array,
    lam: Array,
    mu: float,
    opts: ALOptions,
    data: pin.Data,
    deadline: float | None,
    *,
    start_iteration: int,
    iterations: int,
) -> _FinalPhase:
    """Run the safeguarded final phase: SQP steps with the augmented Lagrangian as merit.

    From the AL iterate and its multipliers, Newton steps ``(p, p_lam)`` on the KKT
    system ``grad E = J^T lam``, ``c = 0`` (Nocedal and Wright, eq. 18.9) with the
    Hessian of :meth:`CyclicIKProblem.lagrangian_hessian`, shifted by ``delta I`` where
    needed to be positive definite on the null space of ``J`` (a minimiser, not a
    saddle). Joints at a limit whose Lagrangian gradient, or whose step, points out
    of the box are held there (the projected BFGS's binding set). The multipliers
    are the step's, ``lam + p_lam``; the step length comes from Armijo backtracking
    on ``L_A(., lam + p_lam; mu)`` (N&W, sec. 18.5: its slope is ``-p^T H p - mu |c|^2``,
    and ``mu`` grows tenfold while it is not negative). Steps are capped at 0.5 rad
    per joint. The stopping test and its multipliers are the main loop's.
    """
    lower, upper = problem.lower, problem.upper
    s = problem.n_targets
    history: list[OuterIterate] = []
    x = np.asarray(x, dtype=float).copy()
    lam = np.asarray(lam, dtype=float).copy()

    def merit(xk: Array, lk: Array) -> float:
        ck = problem.constraints(xk, data)
        return problem.objective(xk) - float(lk @ ck) + 0.5 * mu * float(ck @ ck)

    steps = 0
    for k in range(start_iteration, start_iteration + max(iterations, 1)):
        ev = problem.evaluate(x, data)
        c = ev.constraints
        jac = _dense_jacobian(ev)
        grad_l = ev.gradient - jac.T @ lam
        violation = float(np.max(np.abs(c)))
        lam_ls, stationarity_ls = first_order_multipliers(ev, x, lower, upper)
        stationarity_own = float(np.max(np.abs(x - np.clip(x - grad_l, lower, upper))))
        stationarity = min(stationarity_own, stationarity_ls)
        history.append(
            OuterIterate(k, x.reshape(s, -1).copy(), ev.objective, violation, stationarity, mu, 0)
        )
        _log.debug(
            "AL %d (SQP phase): E=%.10g |c|=%.3g pg=%.3g mu=%.3g",
            k,
            ev.objective,
            violation,
            stationarity,
            mu,
        )

        if not (math.isfinite(violation) and math.isfinite(stationarity)):
            message = "non-finite constraint or gradient"
            return _FinalPhase(SolveStatus.NON_FINITE, message, x, lam, history, steps)
        if violation <= opts.constraint_tol and stationarity <= opts.stationarity_tol:
            lam = lam if stationarity_own <= stationarity_ls else lam_ls
            message = (
                f"|c| = {violation:.2e} <= {opts.constraint_tol:g} and projected "
                f"gradient {stationarity:.2e} <= {opts.stationarity_tol:g} (final phase from "
                f"outer iteration {start_iteration}: {steps} SQP steps)"
            )
            return _FinalPhase(SolveStatus.SOLVED, message, x, lam, history, steps)
        if _past(deadline):
            message = (
                f"wall-time limit {opts.max_wall_time:g} s reached in the final phase with "
                f"|c| = {violation:.2e} m, projected gradient {stationarity:.2e}"
            )
            return _FinalPhase(SolveStatus.MAX_TIME, message, x, lam, history, steps)
        with np.errstate(over="ignore", invalid="ignore"):
            hess = problem.lagrangian_hessian(x, lam, data)
        free = ~(((x <= lower) & (grad_l > 0.0)) | ((x >= upper) & (grad_l < 0.0)))
        for _ in range(x.size + 1):  # joints at a limit that the step pushes out are fixed
            step = _sqp_step(jac, hess, grad_l, c, free)
            if step is None:
                message = "singular or non-finite KKT system in the final phase"
                return _FinalPhase(SolveStatus.STALLED, message, x, lam, history, steps)
            p, rows, dlam = step
            out = free & (((x <= lower) & (p < 0.0)) | ((x >= upper) & (p > 0.0)))
            if not np.any(out):
                break
            free = free & ~out
        lam_new = lam.copy()
        lam_new[rows] += dlam
        # Slope of the merit along p: (grad E - J^T lam_new) p - mu |c|^2 = -p^T H p - mu |c|^2.
        slope_e = float((ev.gradient - jac.T @ lam_new) @ p)
        slope_c = float((jac.T @ c) @ p)
        while not slope_e + mu * slope_c < 0.0:  # not a descent direction: raise mu
            if mu * opts.penalty_growth > _MERIT_PENALTY_MAX:
                message = (
                    f"merit penalty would exceed {_MERIT_PENALTY_MAX:g} with |c| = "
                    f"{violation:.2e} m in the final phase{_licq_note(ev, lam, mu)}"
                )
                return _FinalPhase(SolveStatus.STALLED, message, x, lam, history, steps)
            mu *= opts.penalty_growth
        slope = slope_e + mu * slope_c
        x_new = _merit_backtrack(x, p, lower, upper, slope, merit, lam_new)
        if x_new is None:
            message = (
                f"no decrease of the merit function in the final phase with |c| = "
                f"{violation:.2e} m{_licq_note(ev, lam, mu)}"
            )
            return _FinalPhase(SolveStatus.STALLED, message, x, lam, history, steps)
        steps += 1
        x, lam = x_new, lam_new
    return _FinalPhase(
        SolveStatus.MAX_ITERATIONS, "outer iteration limit reached", x, lam, history, steps
    )


def _final_phase_cleared(
    problem: CyclicIKProblem,
    rows: IKClearance,
    x: Array,
    lam: Array,
    nu: Array,
    mu: float,
    opts: ALOptions,
    data: pin.Data,
    deadline: float | None,
    *,
    start_iteration: int,
    iterations: int,
) -> _FinalPhase:
    """Run the final phase of :func:`_final_phase` with clearance rows, by the AL's active set.

    The rows with ``nu > 0`` enter the KKT system as equalities ``g_i = 0`` (with
    their multipliers; a row whose gradient depends on the target rows' and the rows
    already taken, as when more rows are active than the path has free directions, is
    left out and checked like an inactive one). The Hessian adds ``-sum nu_i d2 g_i``
    (central differences of the reverse-mode ``J_g^T nu``). The phase ends without a
    result (the AL goes on from its own iterate) when a step would give an active row
    ``nu < 0`` (the active set changed) or leave an inactive row below
    ``margin - constraint_tol``. It succeeds only at a point meeting the main loop's
    stopping test with every row.
    """
    lower, upper = problem.lower, problem.upper
    s = problem.n_targets
    m = lam.size
    margin = rows.spec.margin
    history: list[OuterIterate] = []
    x = np.asarray(x, dtype=float).copy()
    kept = _independent_rows(problem, rows, x, nu, data)
    others = np.setdiff1d(np.arange(nu.size), kept)
    y = np.concatenate([np.asarray(lam, dtype=float), nu[kept]])

    def stacked(xk: Array) -> Array:
        return np.concatenate([problem.constraints(xk, data), rows.rows(xk)[kept] - margin])

    def merit(xk: Array, yk: Array) -> float:
        hk = stacked(xk)
        return problem.objective(xk) - float(yk @ hk) + 0.5 * mu * float(hk @ hk)

    def ended(status: SolveStatus, why: str, steps: int) -> _FinalPhase:
        return _FinalPhase(status, why, x, y[:m], history, steps)

    steps = 0
    for k in range(start_iteration, start_iteration + max(iterations, 1)):
        ev = problem.evaluate(x, data)
        g = rows.rows(x) - margin
        h = np.concatenate([ev.constraints, g[kept]])
        jg = rows.rows_jacobian(x)[kept]
        jac = np.vstack([_dense_jacobian(ev), jg])
        nu_full = np.zeros(nu.size)
        nu_full[kept] = y[m:]
        grad_l = ev.gradient - jac.T @ y
        below = max(0.0, -float(np.min(g[others]))) if others.size else 0.0
        violation = max(float(np.max(np.abs(h))), below)
        shifted = ev._replace(gradient=ev.gradient - jg.T @ y[m:])
        lam_ls, stationarity_ls = first_order_multipliers(shifted, x, lower, upper)
        stationarity_own = float(np.max(np.abs(x - np.clip(x - grad_l, lower, upper))))
        stationarity = min(stationarity_own, stationarity_ls)
        history.append(
            OuterIterate(k, x.reshape(s, -1).copy(), ev.objective, violation, stationarity, mu, 0)
        )
        if not (math.isfinite(violation) and math.isfinite(stationarity)):
            return ended(SolveStatus.NON_FINITE, "non-finite constraint or gradient", steps)
        if violation <= opts.constraint_tol and stationarity <= opts.stationarity_tol:
            lam_out = y[:m] if stationarity_own <= stationarity_ls else lam_ls
            message = (
                f"|c| = {violation:.2e} <= {opts.constraint_tol:g} and projected "
                f"gradient {stationarity:.2e} <= {opts.stationarity_tol:g} (final phase from "
                f"outer iteration {start_iteration}: {steps} SQP steps, {kept.size} clearance "
                "rows held as equalities)"
            )
            return _FinalPhase(SolveStatus.SOLVED, message, x, lam_out, history, steps, nu_full)
        if _past(deadline):
            return ended(SolveStatus.MAX_TIME, "wall-time limit in the final phase", steps)
        with np.errstate(over="ignore", invalid="ignore"):
            hess = problem.lagrangian_hessian(x, y[:m], data) - _rows_hessian(rows, x, nu_full)
        free = ~(((x <= lower) & (grad_l > 0.0)) | ((x >= upper) & (grad_l < 0.0)))
        for _ in range(x.size + 1):
            step = _sqp_step(jac, hess, grad_l, h, free)
            if step is None:
                return ended(SolveStatus.STALLED, "singular KKT system in the final phase", steps)
            p, taken, dy = step
            out = free & (((x <= lower) & (p < 0.0)) | ((x >= upper) & (p > 0.0)))
            if not np.any(out):
                break
            free = free & ~out
        y_new = y.copy()
        y_new[taken] += dy
        if np.any(y_new[m:] < 0.0):
            return ended(SolveStatus.STALLED, "a clearance row left the active set", steps)
        slope_e = float((ev.gradient - jac.T @ y_new) @ p)
        slope_c = float((jac.T @ h) @ p)
        while not slope_e + mu * slope_c < 0.0:
            if mu * opts.penalty_growth > _MERIT_PENALTY_MAX:
                return ended(SolveStatus.STALLED, "merit penalty limit in the final phase", steps)
            mu *= opts.penalty_growth
        slope = slope_e + mu * slope_c
        x_new = _merit_backtrack(x, p, lower, upper, slope, merit, y_new)
        if x_new is None:
            return ended(SolveStatus.STALLED, "no decrease of the merit function", steps)
        g_new = rows.rows(x_new) - margin
        if others.size and float(np.min(g_new[others])) < -opts.constraint_tol:
            i = int(others[np.argmin(g_new[others])])
            why = f"the step takes inactive row {rows.labels[i]!r} below the margin"
            return ended(SolveStatus.STALLED, why, steps)
        steps += 1
        x, y = x_new, y_new
    return ended(SolveStatus.MAX_ITERATIONS, "outer iteration limit reached", steps)


def _independent_rows(
    problem: CyclicIKProblem, rows: IKClearance, x: Array, nu: Array, data: pin.Data
) -> npt.NDArray[np.int_]:
    """Rows with ``nu > 0`` whose gradients are independent of the target rows' and each other's.

    Taken by decreasing ``nu``; a row is left out when its gradient adds a singular
    value below 1e-6 of the largest (a dependent row: its multiplier would not be determined).
    """
    jc = _dense_jacobian(problem.evaluate(x, data))
    basis = jc[np.any(jc != 0.0, axis=1)]
    candidates = np.flatnonzero(nu > 0.0)
    if not candidates.size:
        return candidates
    jg = rows.rows_jacobian(x)
    kept = []
    for i in candidates[np.argsort(-nu[candidates], kind="stable")]:
        trial = np.vstack([basis, jg[i]])
        sv = np.linalg.svd(trial, compute_uv=False)
        if sv.size == trial.shape[0] and sv[-1] > 1e-6 * sv[0]:
            basis = trial
            kept.append(int(i))
    return np.array(sorted(kept), dtype=int)


_ROW_HESSIAN_STEP = 1e-6  # central-difference step [rad] of the clearance rows' Hessian


def _rows_hessian(rows: IKClearance, x: Array, w: Array) -> Array:
    """``sum_i w_i d2 g_i`` at ``x`` (symmetric), by central differences of ``J_g^T w``."""
    n = x.size
    out = np.zeros((n, n))
    if not np.any(w):
        return out
    for j in range(n):
        e = np.zeros(n)
        e[j] = _ROW_HESSIAN_STEP
        plus = rows.rows_jacobian_transposed(x + e, w)
        minus = rows.rows_jacobian_transposed(x - e, w)
        out[:, j] = (plus - minus) / (2.0 * _ROW_HESSIAN_STEP)
    return 0.5 * (out + out.T)


_FINAL_PHASE_STEPS = 30  # SQP steps of one attempt of the final phase
_MERIT_PENALTY_MAX = 1e14  # largest mu of the final phase's merit function
_MERIT_BACKTRACKS = 40  # halvings of an SQP step before the final phase gives up
_NEWTON_MAX_STEP = 0.5  # largest step of one joint [rad] in the final phase


def _merit_backtrack(
    x: Array,
    p: Array,
    lower: Array,
    upper: Array,
    slope: float,
    merit: Callable[[Array, Array], float],
    multipliers: Array,
) -> Array | None:
    """Backtrack an SQP step ``p`` on ``merit(., multipliers)`` (Armijo 1e-4; None: no decrease).

    The first step is cut to :data:`_NEWTON_MAX_STEP` [rad] per joint and to the
    bounds; each trial is clipped to ``[lower, upper]``; ``slope`` is the merit's
    directional derivative along ``p`` (negative). Shared by both final phases.
    """
    alpha = min(1.0, _NEWTON_MAX_STEP / max(float(np.max(np.abs(p))), 1e-300))
    with np.errstate(divide="ignore", invalid="ignore"):
        to_lo = np.where(p < 0.0, (lower - x) / p, np.inf)
        to_hi = np.where(p > 0.0, (upper - x) / p, np.inf)
    alpha = min(alpha, float(np.min(np.minimum(to_lo, to_hi))))
    phi0 = merit(x, multipliers)
    noise = 1e-13 * (1.0 + abs(phi0))
    for _ in range(_MERIT_BACKTRACKS):
        x_new = np.clip(x + alpha * p, lower, upper)
        if merit(x_new, multipliers) <= phi0 + 1e-4 * alpha * slope + noise:
            return x_new
        alpha *= 0.5
    return None


def _sqp_step(
    jac: Array, hess: Array, grad_l: Array, c: Array, free: npt.NDArray[np.bool_]
) -> tuple[Array, npt.NDArray[np.bool_], Array] | None:
    """Newton step ``(p, rows, d_lam)`` of the KKT system on the ``free`` joints, or None.

    Zero rows of ``J`` (padding, the z row of a planar chain) drop out; the Hessian
    is shifted to be positive definite on the null space of ``J`` (:func:`_inertia_shift`).
    None also where the remaining rows of ``J`` are (nearly) dependent (rank below
    their number at 1e-10 relative): the KKT matrix is then singular to working
    precision and its solution's multipliers are noise of any size (they overflowed
    ``J^T lam`` on ur5 with 12 targets, a target's joints held at limits).
    """
    rows = np.any(jac[:, free] != 0.0, axis=1)
    a = jac[np.ix_(rows, free)]
    h = hess[np.ix_(free, free)]
    if not (np.all(np.isfinite(h)) and np.all(np.isfinite(grad_l)) and np.all(np.isfinite(a))):
        return None
    if a.size:
        sv = np.linalg.svd(a, compute_uv=False)
        if sv.size < a.shape[0] or sv[-1] <= 1e-10 * max(1.0, float(sv[0])):
            return None
    try:
        h = h + _inertia_shift(a, h) * np.eye(h.shape[0])
        kkt = np.block([[h, a.T], [a, np.zeros((a.shape[0], a.shape[0]))]])
        sol = np.linalg.solve(kkt, -np.concatenate([grad_l[free], c[rows]]))
    except np.linalg.LinAlgError:
        return None
    nf = h.shape[0]
    if not np.all(np.isfinite(sol)):
        return None
    p = np.zeros(jac.shape[1])
    p[free] = sol[:nf]
    return p, rows, -sol[nf:]


def _inertia_shift(a: Array, h: Array) -> float:
    """Return ``delta >= 0`` making ``h + delta I`` positive definite on the null space of ``a``.

    Zero when the smallest eigenvalue of the reduced Hessian exceeds ``1e-8`` of
    the Hessian's scale, else that eigenvalue's deficit plus ``1e-4`` of the scale.
    """
    if h.size == 0:
        return 0.0
    _, sv, vt = np.linalg.svd(a) if a.size else (None, np.zeros(0), np.zeros((0, h.shape[0])))
    rank = int(np.count_nonzero(sv > 1e-10 * max(1.0, float(sv[0]) if sv.size else 1.0)))
    z = vt[rank:].T if a.size else np.eye(h.shape[0])
    if z.shape[1] == 0:
        return 0.0
    smallest = float(np.linalg.eigvalsh(z.T @ h @ z)[0])
    scale = max(1.0, float(np.max(np.abs(h))))
    return 0.0 if smallest > 1e-8 * scale else 1e-4 * scale - smallest


def _dense_jacobian(ev: Evaluation) -> Array:
    """``dc/dx`` (m s, n s) from its diagonal blocks."""
    s, m, n = ev.jacobian_blocks.shape
    jac = np.zeros((s * m, s * n))
    for j in range(s):
        jac[j * m : (j + 1) * m, j * n : (j + 1) * n] = ev.jacobian_blocks[j]
    return jac


_SINGULAR_RATIO = 1e-2  # sigma_min / sigma_max of a tip Jacobian below which LICQ is lost


def _licq_note(ev: Evaluation, lam: Array, mu: float) -> str:
    """Explain a stall at a (nearly) singular tip Jacobian, or return ``""``.

    At the target ``j`` with the largest violation, if the 2 x n tip Jacobian
    has ``sigma_min <= 1e-2 sigma_max`` the arm is (nearly) straight: the
    constraint gradients are (nearly) dependent, LICQ fails, and at a target
    reachable only by that arm (a point on the workspace boundary) no
    multipliers exist. The violation there is second order in the distance
    to the straight arm, so the penalty reduces it only like ``mu^(-2/3)``
    and ``|lambda_j| ~ mu |c_j|`` grows without bound; no finite ``mu`` meets
    ``constraint_tol``.
    """
    m = ev.jacobian_blocks.shape[1]
    c = np.abs(ev.constraints.reshape(-1, m)).max(axis=1)
    j = int(np.argmax(c))
    block = ev.jacobian_blocks[j]
    block = block[np.any(block != 0.0, axis=1)]  # padding rows of a 3-D block are zero
    sv = np.linalg.svd(block, compute_uv=False) if block.size else np.zeros(0)
    if sv.size < 2 or sv[-1] > _SINGULAR_RATIO * sv[0]:
        return ""
    lam_j = float(np.linalg.norm((lam - mu * ev.constraints).reshape(-1, m)[j]))
    return (
        f"; target {j + 1}: the tip Jacobian is nearly singular (singular values "
        f"{sv[0]:.3g}, {sv[-1]:.2g} m/rad: a straight or folded arm), so LICQ fails "
        f"(|lambda_{j + 1}| = {lam_j:.3g} grows with the penalty: no multipliers exist "
        "if the target is reachable only by that arm, e.g. on the workspace boundary) "
        "and the penalty reduces |c| only like mu^(-2/3) (see docs/ikpath.md)"
    )


def first_order_multipliers(
    ev: Evaluation, x: Array, lower: Array, upper: Array
) -> tuple[Array, float]:
    """Least-squares multiplier estimate at ``x`` and the KKT residual it gives.

    ``dc/dx`` is block diagonal, so each target's two multipliers solve their own
    least-squares problem ``min || (grad_j E - J_j^T lambda_j)_F ||`` over the joints
    ``F`` of ``q_j`` strictly inside the limits (Nocedal and Wright, eq. 18.21). The
    residual is the projected gradient of the Lagrangian ``E - lambda^T c``:
    unlike the augmented Lagrangian's gradient it has no component along the
    stiff constraint normals (curvature ``mu |J|^2``), whose rounding noise
    grows with the penalty.

    Parameters
    ----------
    ev : Evaluation
        Objective, constraints and Jacobian blocks at ``x``.
    x : ndarray, shape (n s,)
        Point in [rad], inside ``[lower, upper]``.
    lower, upper : ndarray, shape (n s,)
        Joint limits in [rad] (infinite where unbounded).

    Returns
    -------
    multipliers : ndarray, shape (m s,)
        ``lambda`` in [rad^2/m] (sign convention ``grad E = J^T lambda``).
    residual : float
        ``max | x - P(x - (grad E - J^T lambda)) |`` in [rad].
    """
    s, m, n = ev.jacobian_blocks.shape
    gradient = ev.gradient.reshape(s, n)
    free = ((x > lower) & (x < upper)).reshape(s, n)
    lam = np.zeros((s, m))
    for j in range(s):
        if free[j].any():
            lam[j] = np.linalg.lstsq(
                ev.jacobian_blocks[j][:, free[j]].T, gradient[j, free[j]], rcond=None
            )[0]
    residual = ev.gradient - np.einsum("jkn,jk->jn", ev.jacobian_blocks, lam).ravel()
    return lam.ravel(), float(np.max(np.abs(x - np.clip(x - residual, lower, upper))))


def _past(deadline: float | None) -> bool:
    """Whether the wall-clock ``deadline`` (``time.perf_counter`` value) has passed."""
    return deadline is not None and time.perf_counter() >= deadline


def _inner_solve(
    fun: object,
    x: Array,
    lower: Array,
    upper: Array,
    bounded: bool,
    gtol: float,
    opts: ALOptions,
    deadline: float | None = None,
) -> tuple[Array, int, str]:
    """Minimise ``L_A`` from ``x`` to projected-gradient tolerance ``gtol`` (until ``deadline``)."""
    if not bounded or opts.inner == "bfgs":
        res = minimize_bfgs(
            fun,  # type: ignore[arg-type]
            x,
            lower=lower if bounded else None,
            upper=upper if bounded else None,
            gtol=gtol,
            max_iterations=opts.max_inner_iterations,
            deadline=deadline,
        )
        return res.x, res.iterations, res.message

    def stop_at_deadline(intermediate_result: object) -> None:
        if _past(deadline):
            raise StopIteration  # SciPy >= 1.11 ends the run and returns the iterate

    out = minimize(
        fun,  # type: ignore[arg-type]
        x,
        jac=True,
        method="L-BFGS-B",
        bounds=Bounds(lower, upper),
        options={
            "gtol": gtol,
            "ftol": 0.0,
            "maxiter": opts.max_inner_iterations,
            "maxcor": 20,
        },
        callback=None if deadline is None else stop_at_deadline,
    )
    return np.clip(out.x, lower, upper), int(out.nit), str(out.message)


AL_OPTIONS_3D = ALOptions(penalty_initial=1e3, newton_final=True, retry_least_squares=True)
"""Default AL settings of the 3-D problem: ``mu_0 = 1e3`` (with ``mu_0 = 10`` the
motion term of a 6-joint arm with 2 pi limits outweighs the penalty and the first
inner solves leave the targets for good; measured on ur5, docs/ikpath.md) and the
safeguarded final SQP phase (``newton_final``: nearly singular pose Jacobians make
the first-order multiplier updates crawl) and, after a failed run, one retry with
least-squares initial multipliers (``retry_least_squares``)."""
