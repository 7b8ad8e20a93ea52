r"""Three-stage Radau IIA collocation: nodes, Butcher matrix, interpolation bases.

On the local time ``s in [0, 1]`` of an interval the stages sit at the right
Radau nodes ``c = ((4 - sqrt 6) / 10, (4 + sqrt 6) / 10, 1)``. A state's
derivative is the quadratic through its three stage values, ``x'(s) = sum_j
l_j(s) x'_j``, so ``x(s) = x_0 + h sum_j I_j(s) x'_j`` with ``I_j`` the
integrals of the Lagrange basis ``l_j``; ``A[i, j] = I_j(c_i)`` is the Butcher
matrix and ``B = A[-1]`` the quadrature weights (Hairer & Wanner, *Solving
ODEs II*, sec. IV.5). The method is L-stable (docs/refinement.md, "Stiff joint
damping").
"""

from __future__ import annotations

from math import comb

import numpy as np
from numpy.polynomial import polynomial as P

from youbot_opt._typing import Array

__all__ = ["NODES", "BUTCHER", "WEIGHTS", "basis", "integral", "bernstein_inner", "AT_ZERO"]

NODES: Array = np.array([(4.0 - np.sqrt(6.0)) / 10.0, (4.0 + np.sqrt(6.0)) / 10.0, 1.0])
"""Stage nodes ``c_j`` on the interval's local time (dimensionless)."""


def _lagrange() -> list[Array]:
    """Power-series coefficients of the Lagrange basis on :data:`NODES`."""
    polys = []
    for j, cj in enumerate(NODES):
        others = np.delete(NODES, j)
        coef = P.polyfromroots(others)
        polys.append(coef / P.polyval(cj, coef))
    return polys


_BASIS = _lagrange()
_INTEGRALS = [P.polyint(c) for c in _BASIS]  # zero at s = 0


def basis(s: Array) -> Array:
    """Lagrange basis ``l_j(s)`` at local times ``s``: shape (len(s), 3)."""
    s = np.asarray(s, dtype=float)
    return np.stack([P.polyval(s, c) for c in _BASIS], axis=-1)


def integral(s: Array) -> Array:
    """Integrals ``I_j(s) = int_0^s l_j`` at local times ``s``: shape (len(s), 3)."""
    s = np.asarray(s, dtype=float)
    return np.stack([P.polyval(s, c) for c in _INTEGRALS], axis=-1)


BUTCHER: Array = integral(NODES)
"""Butcher matrix ``A[i, j] = I_j(c_i)``, shape (3, 3)."""

WEIGHTS: Array = BUTCHER[-1].copy()
"""Quadrature weights ``b_j = I_j(1)`` (sum 1; exact for degree <= 4)."""

AT_ZERO: Array = basis(np.array([0.0]))[0]
"""``l_j(0)``: the stage quadratic extrapolated to the interval's start."""


def _bernstein_inner() -> Array:
    """Rows mapping values at ``(0, c_1, c_2, 1)`` to a cubic's inner Bernstein points."""
    s = np.concatenate(([0.0], NODES))
    vander = np.array([[comb(3, i) * x**i * (1.0 - x) ** (3 - i) for i in range(4)] for x in s])
    return np.linalg.inv(vander)[1:3]


_INNER = _bernstein_inner()


def bernstein_inner() -> Array:
    """Matrix (2, 4): the cubic through values at ``(0, c_1, c_2, 1)`` -> its control points 1, 2.

    The cubic is a convex combination of its four Bernstein control points;
    points 0 and 3 are its end values, so bounding these two rows (and the
    ends) keeps the whole cubic within the bounds.
    """
    return _INNER.copy()


for _arr in (NODES, BUTCHER, WEIGHTS, AT_ZERO, _INNER):
    _arr.setflags(write=False)
