"""The augmented Lagrangian's final phase: safeguarded SQP steps on the KKT system.

Once the AL iterate is nearly feasible, Newton steps on ``grad E = J^T lam``,
``c = 0`` (Nocedal and Wright, eq. 18.9) with an inertia-corrected Hessian, the
joint box held by a binding set, and Armijo backtracking on the augmented
Lagrangian as merit (N&W, sec. 18.5); with clearance rows, the AL's active set
held as equalities. Also the least-squares multiplier estimate and the LICQ note
both the AL loop and this phase use. Rationale: docs/ikpath.md.

>>> phase = final_phase(problem, x, lam, mu, opts, data, None,
...                     start_iteration=1, iterations=30)  # doctest: +SKIP
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable
from typing import NamedTuple, Protocol

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from youbot_opt._typing import Array
from youbot_opt.ikpath.clearance import IKClearance
from youbot_opt.ikpath.problem import CyclicIKProblem, Evaluation
from youbot_opt.ikpath.result import OuterIterate
from youbot_opt.nlp.status import SolveStatus

__all__ = [
    "FINAL_PHASE_STEPS",
    "FinalPhase",
    "FinalPhaseOptions",
    "NO_ROWS",
    "final_phase",
    "first_order_multipliers",
    "licq_note",
]

_log = logging.getLogger(__name__)

NO_ROWS = np.zeros(0)
"""The clearance multipliers of a problem without clearance rows (read-only, empty)."""
NO_ROWS.flags.writeable = False


class FinalPhaseOptions(Protocol):
    """The settings the final phase reads (``ALOptions`` of the AL method has them)."""

    @property
    def constraint_tol(self) -> float:
        """Largest ``|c|`` [m] of a solution."""

    @property
    def stationarity_tol(self) -> float:
        """Largest projected Lagrangian gradient [rad] of a solution."""

    @property
    def penalty_growth(self) -> float:
        """Factor by which the merit's penalty ``mu`` grows when a step is not a descent."""

    @property
    def max_wall_time(self) -> float | None:
        """Wall-time limit [s] of the whole solve (named in the message when reached)."""


class FinalPhase(NamedTuple):
    """Outcome of :func:`final_phase` (``sqp_steps``: Newton-KKT steps taken)."""

    status: SolveStatus
    message: str
    x: Array
    multipliers: Array
    history: list[OuterIterate]
    sqp_steps: int
    clearance_multipliers: Array = NO_ROWS


def final_phase(
    problem: CyclicIKProblem,
    x: Array,
    lam: Array,
    mu: float,
    opts: FinalPhaseOptions,
    data: pin.Data,
    deadline: float | None,
    *,
    start_iteration: int,
    iterations: int,
    rows: IKClearance | None = None,
    nu: Array | None = None,
) -> FinalPhase:
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

    With clearance ``rows`` and their AL multipliers ``nu`` (one per row, >= 0), the
    AL's active rows are held as equalities (:func:`_final_phase_with_rows`).
    """
    if rows is not None:
        if nu is None:
            raise ValueError("the final phase with clearance rows needs their multipliers nu")
        return _final_phase_with_rows(
            problem, rows, x, lam, nu, mu, opts, data, deadline,
            start_iteration=start_iteration, iterations=iterations,
        )  # fmt: skip
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
            return FinalPhase(SolveStatus.NON_FINITE, message, x, lam, history, steps)
        if violation <= opts.constraint_tol and stationarity <= opts.stationarity_tol:
            lam = lam if stationarity_own <= stationarity_ls else lam_ls
            message = (
                f"|c| = {violation:.2e} <= {opts.constraint_tol:g} and projected "
                f"gradient {stationarity:.2e} <= {opts.stationarity_tol:g} (final phase from "
                f"outer iteration {start_iteration}: {steps} SQP steps)"
            )
            return FinalPhase(SolveStatus.SOLVED, message, x, lam, history, steps)
        if deadline is not None and time.perf_counter() >= deadline:
            message = (
                f"wall-time limit {opts.max_wall_time:g} s reached in the final phase with "
                f"|c| = {violation:.2e} m, projected gradient {stationarity:.2e}"
            )
            return FinalPhase(SolveStatus.MAX_TIME, message, x, lam, history, steps)
        with np.errstate(over="ignore", invalid="ignore"):
            hess = problem.lagrangian_hessian(x, lam, data)
        step = _held_step(jac, hess, grad_l, c, x, lower, upper)
        if step is None:
            message = "singular or non-finite KKT system in the final phase"
            return FinalPhase(SolveStatus.STALLED, message, x, lam, history, steps)
        p, kkt_rows, dlam = step
        lam_new = lam.copy()
        lam_new[kkt_rows] += dlam
        # Slope of the merit along p: (grad E - J^T lam_new) p - mu |c|^2 = -p^T H p - mu |c|^2.
        slope_e = float((ev.gradient - jac.T @ lam_new) @ p)
        slope_c = float((jac.T @ c) @ p)
        while not slope_e + mu * slope_c < 0.0:  # not a descent direction: raise mu
            if mu * opts.penalty_growth > _MERIT_PENALTY_MAX:
                message = (
                    f"merit penalty would exceed {_MERIT_PENALTY_MAX:g} with |c| = "
                    f"{violation:.2e} m in the final phase{licq_note(ev, lam, mu)}"
                )
                return FinalPhase(SolveStatus.STALLED, message, x, lam, history, steps)
            mu *= opts.penalty_growth
        slope = slope_e + mu * slope_c
        x_new = _merit_backtrack(x, p, lower, upper, slope, merit, lam_new)
        if x_new is None:
            message = (
                f"no decrease of the merit function in the final phase with |c| = "
                f"{violation:.2e} m{licq_note(ev, lam, mu)}"
            )
            return FinalPhase(SolveStatus.STALLED, message, x, lam, history, steps)
        steps += 1
        x, lam = x_new, lam_new
    return FinalPhase(
        SolveStatus.MAX_ITERATIONS, "outer iteration limit reached", x, lam, history, steps
    )


def _final_phase_with_rows(
    problem: CyclicIKProblem,
    rows: IKClearance,
    x: Array,
    lam: Array,
    nu: Array,
    mu: float,
    opts: FinalPhaseOptions,
    data: pin.Data,
    deadline: float | None,
    *,
    start_iteration: int,
    iterations: int,
) -> FinalPhase:
    """Run the final phase of :func:`final_phase` with clearance rows, by the AL's active set.

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

    def ended(status: SolveStatus, why: str, steps: int) -> FinalPhase:
        return FinalPhase(status, why, x, y[:m], history, steps)

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
            return FinalPhase(SolveStatus.SOLVED, message, x, lam_out, history, steps, nu_full)
        if deadline is not None and time.perf_counter() >= deadline:
            return ended(SolveStatus.MAX_TIME, "wall-time limit in the final phase", steps)
        with np.errstate(over="ignore", invalid="ignore"):
            hess = problem.lagrangian_hessian(x, y[:m], data) - _rows_hessian(rows, x, nu_full)
        step = _held_step(jac, hess, grad_l, h, x, lower, upper)
        if step is None:
            return ended(SolveStatus.STALLED, "singular KKT system in the final phase", steps)
        p, taken, dy = step
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


FINAL_PHASE_STEPS = 30  # SQP steps of one attempt of the final phase
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


def _held_step(
    jac: Array, hess: Array, grad_l: Array, c: Array, x: Array, lower: Array, upper: Array
) -> tuple[Array, npt.NDArray[np.bool_], Array] | None:
    """Newton step of :func:`_sqp_step` with the joints at a limit held there, or None.

    A joint at a limit whose Lagrangian gradient ``grad_l`` points out of the box
    ``[lower, upper]`` [rad] is held from the start (the projected BFGS's binding
    set); one whose step points out is held and the step solved again. Shared by
    both final phases.
    """
    free = ~(((x <= lower) & (grad_l > 0.0)) | ((x >= upper) & (grad_l < 0.0)))
    step = None
    for _ in range(x.size + 1):
        step = _sqp_step(jac, hess, grad_l, c, free)
        if step is None:
            return None
        p = step[0]
        out = free & (((x <= lower) & (p < 0.0)) | ((x >= upper) & (p > 0.0)))
        if not np.any(out):
            break
        free = free & ~out
    return step


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


def licq_note(ev: Evaluation, lam: Array, mu: float) -> str:
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
