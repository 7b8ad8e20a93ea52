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
from dataclasses import dataclass
from typing import NamedTuple, TypedDict

import numpy as np
from numpy.typing import ArrayLike
from scipy.optimize import Bounds, minimize

from youbot_opt._checks import check_time_limit
from youbot_opt._typing import Array
from youbot_opt.exceptions import ParameterError
from youbot_opt.ikpath.clearance import IKClearance
from youbot_opt.ikpath.methods.best_iterate import pick_best
from youbot_opt.ikpath.methods.bfgs import minimize_bfgs
from youbot_opt.ikpath.methods.sqp import (
    FINAL_PHASE_STEPS,
    NO_ROWS,
    final_phase,
    first_order_multipliers,
    licq_note,
)
from youbot_opt.ikpath.problem import CyclicIKProblem
from youbot_opt.ikpath.result import IKPathResult, OuterIterate, build_result
from youbot_opt.nlp.status import SolveStatus

__all__ = [
    "AL_OPTIONS_3D",
    "ALOptions",
    "ALResultFields",
    "ALRun",
    "run_augmented_lagrangian",
    "solve_augmented_lagrangian",
    "solve_augmented_lagrangian_3d",
]

_log = logging.getLogger(__name__)


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
        (:func:`~youbot_opt.ikpath.methods.sqp.final_phase`); if they meet the
        stopping test the solve ends there, otherwise the AL continues from its own
        iterate as if nothing happened. Needs
        the problem's ``lagrangian_hessian``. Off by
        default (the planar solver is the study's method as published); on for
        3-D problems, whose nearly singular pose Jacobians make the first-order
        multiplier updates crawl (docs/ikpath.md). With clearance rows the rows with
        ``nu > 0`` are held as equalities
        (:func:`~youbot_opt.ikpath.methods.sqp.final_phase` with the rows).
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
    clearance_multipliers: Array = NO_ROWS

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
        if opts.newton_final and violation <= opts.newton_violation:
            lam_start = lam - mu * c if stationarity_al <= stationarity_ls else lam_ls
            final = final_phase(
                problem, x, lam_start, mu, opts, data, deadline,
                start_iteration=k + 1, iterations=FINAL_PHASE_STEPS,
                rows=rows, nu=nu_new,
            )  # fmt: skip
            _log.debug("AL %d: final phase (%d clearance rows): %s", k, nu.size, final.message)
            if final.status is SolveStatus.SOLVED:
                history.extend(final.history)
                status, x, lam = final.status, final.x, final.multipliers
                nu = nu if rows is None else final.clearance_multipliers
                message = f"{final.message}{_clearance_note(rows, x, nu)}"
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
                    f"{licq_note(ev, lam, mu)}"
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
