"""The study's method: augmented Lagrangian with a quasi-Newton inner solver.

Nocedal and Wright, *Numerical Optimization* (2nd ed.), Algorithm 17.4
(bound-constrained Lagrangian method) on ``E(x)`` with the ``2 s`` target
constraints ``c(x) = 0`` and the joint box; the inner solver is
:func:`~youbot_opt.ikpath.bfgs.minimize_bfgs` (or SciPy's L-BFGS-B). Spec
``docs/ikpath.md``; the outer loop, the stopping test and the stall rules are
in docs/design.md, "Module notes".

>>> result = solve_augmented_lagrangian(problem, x0, ALOptions())  # doctest: +SKIP
"""

from __future__ import annotations

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
from youbot_opt.ikpath.best_iterate import pick_best
from youbot_opt.ikpath.bfgs import minimize_bfgs
from youbot_opt.ikpath.problem import ALProblem, CyclicIKProblem, Evaluation
from youbot_opt.ikpath.result import IKPathResult, OuterIterate, build_result
from youbot_opt.nlp.status import SolveStatus

__all__ = [
    "ALOptions",
    "ALResultFields",
    "ALRun",
    "first_order_multipliers",
    "run_augmented_lagrangian",
    "solve_augmented_lagrangian",
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
        use BFGS): the projected BFGS of :mod:`youbot_opt.ikpath.bfgs` or SciPy's
        L-BFGS-B.
    max_wall_time : float or None
        Wall-clock limit of the whole solve in [s] (``None``: no limit). Checked
        before every inner iteration; when it is reached the solve stops with
        status ``MAX_TIME`` and the last iterate (unless that iterate already
        meets the stopping test). The overshoot is at most one inner iteration.
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

    def __post_init__(self) -> None:
        check_time_limit(self.max_wall_time, "ALOptions.max_wall_time")
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
    """

    status: SolveStatus
    message: str
    x: Array
    multipliers: Array
    history: tuple[OuterIterate, ...]
    inner_iterations: int
    wall_time: float

    def result_fields(self, start: Array) -> ALResultFields:
        """Return the keywords the result builders share for this run from ``start`` [rad].

        Both :func:`~youbot_opt.ikpath.result.build_result` and the spatial
        ``build_spatial_result`` take them (``method = "al"``).
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


def run_augmented_lagrangian(problem: ALProblem, start: Array, opts: ALOptions) -> ALRun:
    """Run the augmented Lagrangian loop on any :class:`ALProblem` from a checked start.

    The planar :class:`CyclicIKProblem` and the spatial problem of
    :mod:`youbot_opt.ikpath.spatial` both plug in: the constraints are ``s``
    blocks of ``m`` rows (``m = jacobian_blocks.shape[1]``), each with its own
    Jacobian block, which is all the loop and :func:`first_order_multipliers` use.
    """
    t0 = time.perf_counter()
    deadline = None if opts.max_wall_time is None else t0 + float(opts.max_wall_time)
    data = problem.create_data()
    lower, upper = problem.lower, problem.upper
    bounded = problem.bounded
    s = problem.n_targets
    lam = np.zeros(problem.n_constraints)
    mu = opts.penalty_initial
    omega, eta = 1.0 / mu, 1.0 / mu**0.1

    def lagrangian(x: Array) -> tuple[float, Array]:
        ev = problem.evaluate(x, data)
        c = ev.constraints
        weight = (mu * c - lam).reshape(s, -1)  # d L_A / d c
        value = ev.objective - float(lam @ c) + 0.5 * mu * float(c @ c)
        grad = ev.gradient + np.einsum("jkn,jk->jn", ev.jacobian_blocks, weight).ravel()
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
        # Stationarity with the AL's own estimate lam - mu c, and with the
        # least-squares estimate at x; either multiplier vector certifies a KKT point.
        lam_ls, stationarity_ls = first_order_multipliers(ev, x, lower, upper)
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
            status = SolveStatus.SOLVED
            message = (
                f"|c| = {violation:.2e} <= {opts.constraint_tol:g} and projected "
                f"gradient {stationarity:.2e} <= {opts.stationarity_tol:g}"
            )
            break
        if _past(deadline):
            status = SolveStatus.MAX_TIME
            message = (
                f"wall-time limit {opts.max_wall_time:g} s reached with |c| = {violation:.2e} m, "
                f"projected gradient {stationarity:.2e} ({inner_msg})"
            )
            break
        if violation <= eta:
            # An inner solve that could not move (its line search lost in the rounding
            # of L_A) leaves c unchanged; repeating lam - mu c would then drift the
            # multipliers by mu c per iteration, so restart from the estimate at x.
            lam = lam - mu * c if inner_its > 0 else lam_ls
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
    return ALRun(status, message, x, lam, tuple(history), inner_total, time.perf_counter() - t0)


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
    block = block[np.any(block != 0.0, axis=1)]  # padding rows of a spatial block are zero
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
