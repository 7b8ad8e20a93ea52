r"""The collocation rules' numbers, once: quadrature weights, interval bases, Radau IIA.

Weights of the work ``W = dt sum_k w_k tau_k . tau_k`` (trapezoid, Simpson) on
uniform and non-uniform grids; the bases of the state derivative along one
interval (:func:`collocation_basis`: linear, the Hermite-Simpson quadratic,
the Radau quadratic) and composite Gauss-Legendre nodes to integrate them. Radau
IIA (3 stages): nodes ``c = ((4 - sqrt 6) / 10, (4 + sqrt 6) / 10, 1)``, the
Butcher matrix ``A[i, j] = I_j(c_i)`` of the Lagrange basis integrals and the
weights ``b = A[-1]`` (Hairer & Wanner, *Solving ODEs II*, sec. IV.5).

>>> w_knots, w_mid = quadrature_weights("simpson", n_knots=50)  # doctest: +SKIP
"""

from __future__ import annotations

from math import comb
from typing import Literal

import numpy as np
from numpy.polynomial import polynomial as P

from youbot_opt._typing import Array
from youbot_opt.exceptions import ParameterError

__all__ = [
    "QuadratureRule",
    "RADAU_AT_ZERO",
    "RADAU_BUTCHER",
    "RADAU_NODES",
    "RADAU_WEIGHTS",
    "collocation_basis",
    "gauss_legendre",
    "grid_weights",
    "quadrature_weights",
    "radau_basis",
    "radau_bernstein_inner",
    "radau_integral",
]

QuadratureRule = Literal["trapezoidal", "simpson", "radau"]
"""Quadrature rule of a transcription's work."""


def grid_weights(rule: QuadratureRule, ratios: Array) -> tuple[Array, Array | None]:
    """Quadrature weights (in units of the mean step) on intervals of step ratios ``ratios``.

    Parameters
    ----------
    rule : {"trapezoidal", "simpson"}
        Quadrature rule of the transcription.
    ratios : ndarray, shape (N - 1,)
        Each interval's step divided by the mean step (ones on a uniform grid).

    Returns
    -------
    w_knots : ndarray, shape (N,)
        Weights of the knot values (dimensionless, multiplied by ``dt`` in [s]).
    w_mid : ndarray, shape (N - 1,) or None
        Weights of the mid-interval values (Simpson only).

    Raises
    ------
    ParameterError
        On an unknown rule.
    """
    r = np.asarray(ratios, dtype=float)
    w = np.zeros(r.size + 1)
    w[:-1] += 0.5 * r
    w[1:] += 0.5 * r
    if rule == "trapezoidal":
        return w, None
    if rule == "simpson":
        return w / 3.0, 4.0 / 6.0 * r
    raise ParameterError(
        f"rule must be 'trapezoidal' or 'simpson', got {rule!r}", name="rule", value=rule
    )


def quadrature_weights(rule: QuadratureRule, n_knots: int) -> tuple[Array, Array | None]:
    """Weights ``(w_knots, w_mid)`` with ``W = dt * (w_knots . p + w_mid . p_mid)``, uniform grid.

    Parameters
    ----------
    rule : {"trapezoidal", "simpson"}
        Quadrature rule of the transcription.
    n_knots : int
        Number of knots ``N`` (>= 2).

    Returns
    -------
    w_knots : ndarray, shape (N,)
        Weights of the knot powers ``p_k = tau_k . tau_k`` (dimensionless,
        multiplied by ``dt`` in [s]).
    w_mid : ndarray, shape (N - 1,) or None
        Weights of the mid-interval powers (Simpson only).

    Raises
    ------
    ParameterError
        On an unknown rule or fewer than 2 knots.
    """
    if n_knots < 2:
        raise ParameterError(f"n_knots must be >= 2, got {n_knots}", name="n_knots", value=n_knots)
    return grid_weights(rule, np.ones(n_knots - 1))


def gauss_legendre(segments: int, points: int) -> tuple[Array, Array]:
    """Nodes in [0, 1] and weights (summing to 1) of composite Gauss-Legendre quadrature."""
    x, w = np.polynomial.legendre.leggauss(points)
    nodes = [(j + 0.5 * (x + 1.0)) / segments for j in range(segments)]
    weights = [0.5 * w / segments for _ in range(segments)]
    return np.concatenate(nodes), np.concatenate(weights)


def collocation_basis(method: str, s: Array) -> tuple[Array, Array]:
    """Return the derivative basis ``L`` and its integral ``I`` at ``s`` in [0, 1] (rows: nodes).

    Trapezoidal: linear through the values at ``s = 0, 1``; Hermite-Simpson:
    quadratic through ``s = 0, 1/2, 1`` (columns: start, [mid,] end); Radau:
    quadratic through its three nodes (:func:`radau_basis`).
    """
    if method == "radau":
        return radau_basis(s), radau_integral(s)
    if method == "trapezoidal":
        basis = np.stack([1.0 - s, s], axis=1)
        integral = np.stack([s - 0.5 * s**2, 0.5 * s**2], axis=1)
        return basis, integral
    basis = np.stack([2 * (s - 0.5) * (s - 1.0), -4 * s * (s - 1.0), 2 * s * (s - 0.5)], axis=1)
    integral = np.stack(
        [
            2 * (s**3 / 3 - 0.75 * s**2 + 0.5 * s),
            -4 * (s**3 / 3 - 0.5 * s**2),
            2 * (s**3 / 3 - 0.25 * s**2),
        ],
        axis=1,
    )
    return basis, integral


# --------------------------------------------------------------- Radau IIA
RADAU_NODES: Array = np.array([(4.0 - np.sqrt(6.0)) / 10.0, (4.0 + np.sqrt(6.0)) / 10.0, 1.0])
"""Radau IIA stage nodes ``c_j`` on the interval's local time (dimensionless)."""


def _lagrange() -> list[Array]:
    """Power-series coefficients of the Lagrange basis on :data:`RADAU_NODES`."""
    polys = []
    for j, cj in enumerate(RADAU_NODES):
        others = np.delete(RADAU_NODES, j)
        coef = P.polyfromroots(others)
        polys.append(coef / P.polyval(cj, coef))
    return polys


_BASIS = _lagrange()
_INTEGRALS = [P.polyint(c) for c in _BASIS]  # zero at s = 0


def radau_basis(s: Array) -> Array:
    """Lagrange basis ``l_j(s)`` at local times ``s``: shape (len(s), 3)."""
    s = np.asarray(s, dtype=float)
    return np.stack([P.polyval(s, c) for c in _BASIS], axis=-1)


def radau_integral(s: Array) -> Array:
    """Integrals ``I_j(s) = int_0^s l_j`` at local times ``s``: shape (len(s), 3)."""
    s = np.asarray(s, dtype=float)
    return np.stack([P.polyval(s, c) for c in _INTEGRALS], axis=-1)


RADAU_BUTCHER: Array = radau_integral(RADAU_NODES)
"""Butcher matrix ``A[i, j] = I_j(c_i)``, shape (3, 3)."""

RADAU_WEIGHTS: Array = RADAU_BUTCHER[-1].copy()
"""Quadrature weights ``b_j = I_j(1)`` (sum 1; exact for degree <= 4)."""

RADAU_AT_ZERO: Array = radau_basis(np.array([0.0]))[0]
"""``l_j(0)``: the stage quadratic extrapolated to the interval's start."""


def _bernstein_inner() -> Array:
    """Rows mapping values at ``(0, c_1, c_2, 1)`` to a cubic's inner Bernstein points."""
    s = np.concatenate(([0.0], RADAU_NODES))
    vander = np.array([[comb(3, i) * x**i * (1.0 - x) ** (3 - i) for i in range(4)] for x in s])
    return np.linalg.inv(vander)[1:3]


_INNER = _bernstein_inner()


def radau_bernstein_inner() -> Array:
    """Matrix (2, 4): the cubic through values at ``(0, c_1, c_2, 1)`` -> its control points 1, 2.

    The cubic is a convex combination of its four Bernstein control points;
    points 0 and 3 are its end values, so bounding these two rows (and the
    ends) keeps the whole cubic within the bounds.
    """
    return _INNER.copy()


for _arr in (RADAU_NODES, RADAU_BUTCHER, RADAU_WEIGHTS, RADAU_AT_ZERO, _INNER):
    _arr.setflags(write=False)
