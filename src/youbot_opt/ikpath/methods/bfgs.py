"""BFGS with a strong-Wolfe line search (Nocedal and Wright, *Numerical Optimization*).

The study's inner solver, written here: Algorithm 6.1 (BFGS on the inverse
Hessian, initial scaling eq. 6.20) with the line search of Algorithms
3.5/3.6; near a minimiser the sufficient-decrease test falls back to Hager
and Zhang's approximate Wolfe test so the gradient reaches 1e-9 and below
(docs/design.md, "Module notes").

>>> minimize_bfgs(fun_and_grad, x0, gtol=1e-9)  # doctest: +SKIP
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import NamedTuple

import numpy as np

from youbot_opt._typing import Array

__all__ = ["BFGSResult", "LineSearchResult", "minimize_bfgs", "strong_wolfe_line_search"]

FunGrad = Callable[[Array], tuple[float, Array]]


class LineSearchResult(NamedTuple):
    """Outcome of a line search.

    Attributes
    ----------
    alpha : float
        Step length accepted (0 on failure).
    f : float
        Function value at the step.
    g : ndarray
        Gradient at the step.
    evaluations : int
        Function/gradient evaluations used.
    success : bool
        Whether the strong Wolfe conditions hold at ``alpha``, or sufficient
        decrease holds at ``alpha = alpha_max`` (a step capped by a bound).
    """

    alpha: float
    f: float
    g: Array
    evaluations: int
    success: bool


class BFGSResult(NamedTuple):
    """Outcome of :func:`minimize_bfgs`.

    Attributes
    ----------
    x : ndarray
        Final iterate.
    f : float
        Function value at ``x``.
    g : ndarray
        Gradient at ``x``.
    iterations : int
        BFGS iterations.
    evaluations : int
        Function/gradient evaluations.
    converged : bool
        Whether ``max|g| <= gtol``.
    message : str
        Why the iteration stopped.
    """

    x: Array
    f: float
    g: Array
    iterations: int
    evaluations: int
    converged: bool
    message: str


def _cubic_min(a: float, fa: float, da: float, b: float, fb: float, db: float) -> float:
    """Minimiser of the cubic interpolating (a, fa, da), (b, fb, db); NaN if none (eq. 3.59)."""
    if a == b:
        return math.nan
    d1 = da + db - 3.0 * (fa - fb) / (a - b)
    disc = d1 * d1 - da * db
    if disc < 0.0:
        return math.nan
    d2 = math.copysign(math.sqrt(disc), b - a)
    den = db - da + 2.0 * d2
    if den == 0.0:
        return math.nan
    return b - (b - a) * (db + d2 - d1) / den


def strong_wolfe_line_search(
    fun: FunGrad,
    x: Array,
    f0: float,
    g0: Array,
    p: Array,
    *,
    alpha0: float = 1.0,
    c1: float = 1e-4,
    c2: float = 0.9,
    alpha_max: float = 1e8,
    max_evaluations: int = 40,
    f_noise: float = 1e-13,
) -> LineSearchResult:
    """Find a step satisfying the strong Wolfe conditions (N&W Algorithms 3.5 and 3.6).

    Parameters
    ----------
    fun : callable
        ``fun(x) -> (f, grad)``.
    x, f0, g0 : ndarray, float, ndarray
        Current point, value and gradient.
    p : ndarray
        Descent direction (``g0 @ p < 0``).
    alpha0 : float
        First trial step.
    c1, c2 : float
        Sufficient-decrease and curvature constants, ``0 < c1 < c2 < 1``.
    alpha_max : float
        Largest step tried.
    max_evaluations : int
        Evaluation budget.
    f_noise : float
        Relative rounding level of ``f`` below which the approximate Wolfe
        sufficient-decrease test is used (0 disables it).

    Returns
    -------
    LineSearchResult
        On failure ``success`` is False and the best sufficient-decrease point
        found (possibly ``alpha = 0``) is returned.
    """
    dphi0 = float(g0 @ p)
    evals = 0
    eps_f = f_noise * (1.0 + abs(f0))

    def decreases(alpha: float, f: float, d: float) -> bool:
        """Sufficient decrease (exact, or approximate within the rounding level of f)."""
        if not math.isfinite(f):
            return False
        if f <= f0 + c1 * alpha * dphi0:
            return True
        return f <= f0 + eps_f and d <= (1.0 - 2.0 * c1) * -dphi0

    def phi(alpha: float) -> tuple[float, Array, float]:
        nonlocal evals
        evals += 1
        f, g = fun(x + alpha * p)
        return float(f), g, float(g @ p)

    def zoom(
        lo: tuple[float, float, Array, float], hi: tuple[float, float, float]
    ) -> LineSearchResult:
        a_lo, f_lo, g_lo, d_lo = lo
        a_hi, f_hi, d_hi = hi
        while evals < max_evaluations:
            width = a_hi - a_lo
            trial = _cubic_min(a_lo, f_lo, d_lo, a_hi, f_hi, d_hi)
            left, right = min(a_lo, a_hi), max(a_lo, a_hi)
            margin = 0.1 * abs(width)
            if not math.isfinite(trial) or not (left + margin <= trial <= right - margin):
                trial = 0.5 * (a_lo + a_hi)
            if abs(width) <= 1e-16 * max(1.0, abs(a_lo)):
                break
            f_t, g_t, d_t = phi(trial)
            if not decreases(trial, f_t, d_t) or f_t > f_lo + eps_f:
                a_hi, f_hi, d_hi = trial, f_t, d_t
            else:
                if abs(d_t) <= -c2 * dphi0:
                    return LineSearchResult(trial, f_t, g_t, evals, True)
                if d_t * (a_hi - a_lo) >= 0.0:
                    a_hi, f_hi, d_hi = a_lo, f_lo, d_lo
                a_lo, f_lo, g_lo, d_lo = trial, f_t, g_t, d_t
        return LineSearchResult(a_lo, f_lo, g_lo, evals, False)

    prev = (0.0, f0, g0, dphi0)
    alpha = alpha0
    first = True
    while evals < max_evaluations:
        f_a, g_a, d_a = phi(alpha)
        if not decreases(alpha, f_a, d_a) or (not first and f_a > prev[1] + eps_f):
            return zoom(prev, (alpha, f_a if math.isfinite(f_a) else math.inf, d_a))
        if abs(d_a) <= -c2 * dphi0:
            return LineSearchResult(alpha, f_a, g_a, evals, True)
        if d_a >= 0.0:
            return zoom((alpha, f_a, g_a, d_a), (prev[0], prev[1], prev[3]))
        if alpha >= alpha_max:  # step capped (e.g. by a bound): sufficient decrease holds
            return LineSearchResult(alpha, f_a, g_a, evals, True)
        prev = (alpha, f_a, g_a, d_a)
        alpha = min(2.0 * alpha, alpha_max)
        first = False
    return LineSearchResult(prev[0], prev[1], prev[2], evals, False)


def minimize_bfgs(
    fun: FunGrad,
    x0: Array,
    *,
    lower: Array | None = None,
    upper: Array | None = None,
    gtol: float = 1e-8,
    max_iterations: int = 1000,
    c1: float = 1e-4,
    c2: float = 0.9,
    deadline: float | None = None,
) -> BFGSResult:
    """Minimise a smooth function with BFGS and a strong-Wolfe line search (N&W Alg. 6.1).

    With bounds the method is an active-set projected quasi-Newton method:
    variables at a bound whose gradient points out of the box are held fixed
    (the *binding* set), the BFGS direction acts on the others, and the step
    length is capped where the first free variable reaches its bound (that
    variable is then set exactly to the bound). The inverse Hessian restarts
    whenever the binding set changes. Iterates never leave the box.

    Parameters
    ----------
    fun : callable
        ``fun(x) -> (f, grad)`` with ``grad`` of the shape of ``x``.
    x0 : ndarray, shape (m,)
        Start point (inside the bounds).
    lower, upper : ndarray, shape (m,), optional
        Bounds (+-inf allowed); ``None`` means unbounded.
    gtol : float
        Stop when the projected gradient satisfies ``max|x - P(x - grad)| <= gtol``
        (``max|grad|`` without bounds).
    max_iterations : int
        Iteration limit.
    c1, c2 : float
        Wolfe constants (``0 < c1 < c2 < 1``; 0.9 is the quasi-Newton default).
    deadline : float, optional
        ``time.perf_counter()`` value in [s] after which no further iteration
        starts (message ``"time limit reached"``; ``converged`` then tells
        whether the gradient test holds at the returned iterate).

    Returns
    -------
    BFGSResult
        Final iterate and diagnostics. ``converged`` is False when the iteration
        limit is hit or no step decreases ``f`` even along the steepest descent
        direction (machine precision reached).
    """
    x = np.array(x0, dtype=float)
    m = x.size
    lo = np.full(m, -np.inf) if lower is None else np.asarray(lower, dtype=float)
    hi = np.full(m, np.inf) if upper is None else np.asarray(upper, dtype=float)
    x = np.clip(x, lo, hi)
    f, g = fun(x)
    evals = 1
    eye = np.eye(m)
    h_inv = eye.copy()
    fresh = True  # inverse Hessian is the identity and awaits the eq. 6.20 scaling
    binding_prev: Array | None = None
    for it in range(max_iterations):
        pg = x - np.clip(x - g, lo, hi)
        pgnorm = float(np.max(np.abs(pg))) if m else 0.0
        if not math.isfinite(f) or not math.isfinite(pgnorm):
            return BFGSResult(x, f, g, it, evals, False, "non-finite function or gradient")
        if pgnorm <= gtol:
            return BFGSResult(x, f, g, it, evals, True, "gradient below tolerance")
        if deadline is not None and time.perf_counter() >= deadline:
            return BFGSResult(x, f, g, it, evals, False, "time limit reached")
        binding = ((x <= lo) & (g > 0.0)) | ((x >= hi) & (g < 0.0))
        if binding_prev is not None and np.any(binding != binding_prev):
            h_inv, fresh = eye.copy(), True
        binding_prev = binding
        free = ~binding
        p = _direction(h_inv, g, free)
        if not float(g @ p) < 0.0 or _leaves_box(x, p, lo, hi):
            h_inv, fresh = eye.copy(), True
            p = np.where(free, -g, 0.0)
        gnorm = float(np.linalg.norm(p))
        alpha0 = min(1.0, 1.0 / gnorm) if fresh else 1.0
        alpha_max = _max_step(x, p, lo, hi)
        ls = strong_wolfe_line_search(
            fun, x, f, g, p, alpha0=min(alpha0, alpha_max), c1=c1, c2=c2, alpha_max=alpha_max
        )
        evals += ls.evaluations
        if not ls.success and not fresh:
            h_inv, fresh = eye.copy(), True
            p = np.where(free, -g, 0.0)
            alpha_max = _max_step(x, p, lo, hi)
            alpha0 = min(1.0, 1.0 / float(np.linalg.norm(p)), alpha_max)
            ls = strong_wolfe_line_search(
                fun, x, f, g, p, alpha0=alpha0, c1=c1, c2=c2, alpha_max=alpha_max
            )
            evals += ls.evaluations
        if ls.alpha == 0.0 or not ls.f <= f + 1e-13 * (1.0 + abs(f)):
            return BFGSResult(x, f, g, it, evals, False, "line search found no decrease")
        x_new = x + ls.alpha * p
        if ls.alpha >= alpha_max:  # a free variable reached its bound: put it there exactly
            x_new = _snap(x_new, p, x, alpha_max, lo, hi)
        x_new = np.clip(x_new, lo, hi)
        s = x_new - x
        y = ls.g - g
        x, f, g = x_new, ls.f, ls.g
        sy = float(s @ y)
        if sy > 1e-14 * float(np.linalg.norm(s) * np.linalg.norm(y)) and sy > 0.0:
            if fresh:
                h_inv = (sy / float(y @ y)) * eye
                fresh = False
            hy = h_inv @ y
            h_inv += ((sy + float(y @ hy)) / sy**2) * np.outer(s, s) - (
                np.outer(hy, s) + np.outer(s, hy)
            ) / sy
        if not ls.success and fresh:
            pgnorm = float(np.max(np.abs(x - np.clip(x - g, lo, hi))))
            converged = pgnorm <= gtol
            return BFGSResult(x, f, g, it + 1, evals, converged, "line search failed (precision)")
    pgnorm = float(np.max(np.abs(x - np.clip(x - g, lo, hi)))) if m else 0.0
    return BFGSResult(x, f, g, max_iterations, evals, pgnorm <= gtol, "iteration limit reached")


def _direction(h_inv: Array, g: Array, free: Array) -> Array:
    """Quasi-Newton direction on the free variables (zero on the binding ones)."""
    if np.all(free):
        return -(h_inv @ g)
    p = np.zeros_like(g)
    idx = np.flatnonzero(free)
    p[idx] = -(h_inv[np.ix_(idx, idx)] @ g[idx])
    return p


def _leaves_box(x: Array, p: Array, lo: Array, hi: Array) -> bool:
    """Whether ``p`` points out of the box from a variable already at its bound."""
    return bool(np.any(((x <= lo) & (p < 0.0)) | ((x >= hi) & (p > 0.0))))


def _max_step(x: Array, p: Array, lo: Array, hi: Array) -> float:
    """Largest ``alpha`` keeping ``x + alpha p`` in the box (``inf`` if unbounded)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        to_lo = np.where(p < 0.0, (lo - x) / p, np.inf)
        to_hi = np.where(p > 0.0, (hi - x) / p, np.inf)
    step = float(np.min(np.minimum(to_lo, to_hi))) if x.size else math.inf
    return min(step, 1e8)


def _snap(x_new: Array, p: Array, x: Array, alpha: float, lo: Array, hi: Array) -> Array:
    """Put the variables whose bound limited the step exactly on that bound."""
    with np.errstate(divide="ignore", invalid="ignore"):
        to_lo = np.where(p < 0.0, (lo - x) / p, np.inf)
        to_hi = np.where(p > 0.0, (hi - x) / p, np.inf)
    tol = 1e-12 * max(1.0, alpha)
    out = x_new.copy()
    out[to_lo <= alpha + tol] = lo[to_lo <= alpha + tol]
    out[to_hi <= alpha + tol] = hi[to_hi <= alpha + tol]
    return out
