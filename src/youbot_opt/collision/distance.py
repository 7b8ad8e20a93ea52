"""Signed distances in CasADi: balls against primitives and against balls, smooth where needed.

Every function takes CasADi (or numeric) expressions and returns expressions;
nothing here knows a robot. Norms are smoothed as ``sqrt(|x|^2 + eps^2) - eps``
with :data:`NORM_EPS`, which is never larger than ``|x|`` (conservative) and
at most ``eps`` below it; the minimum over many balls is the log-sum-exp
soft minimum, never larger than the true minimum and at most ``tau log n``
below it. Distances to a box or a cylinder are C1 outside the solid.

>>> d = point_box_distance(x, half=np.array([0.5, 0.5, 0.5]))  # doctest: +SKIP
"""

from __future__ import annotations

from typing import TypeVar

import casadi as ca
import numpy as np

from youbot_opt._typing import Array

__all__ = [
    "NORM_EPS",
    "point_box_distance",
    "point_capsule_distance",
    "point_cylinder_distance",
    "point_halfspace_distance",
    "point_point_distance",
    "smooth_norm",
    "soft_min",
]

#: A CasADi expression: the result has the argument's type (DM listed first: DM in, DM out);
#: a DM point may join an SX or MX one, as CasADi's own operators allow.
_E = TypeVar("_E", ca.DM, ca.SX, ca.MX)
#: Smoothing length of the norm in [m] (distances are at most this much low).
NORM_EPS = 1e-6


def smooth_norm(x: _E) -> _E:
    """Return ``sqrt(|x|^2 + eps^2) - eps`` [m]: smooth, in ``[|x| - eps, |x|]``."""
    return ca.sqrt(ca.sumsqr(x) + NORM_EPS**2) - NORM_EPS


def soft_min(values: _E, tau: float) -> _E:
    """Return ``-tau log sum exp(-v / tau)``: in ``[min v - tau log n, min v]``.

    Parameters
    ----------
    values : casadi expression, shape (n,)
        Distances in [m].
    tau : float
        Smoothing length in [m]; 0 gives the exact (non-smooth) minimum.
    """
    n = values.shape[0]
    if n == 1:
        return values[0]
    if tau == 0.0:
        return ca.mmin(values)
    low = ca.mmin(values)  # shift for a stable exponent; the result is exact in low
    return low - tau * ca.log(ca.sum1(ca.exp(-(values - low) / tau)))


def point_point_distance(x: _E, center: _E | ca.DM) -> _E:
    """Distance [m] between two points (smoothed norm)."""
    return smooth_norm(x - center)


def point_halfspace_distance(x: _E) -> _E:
    """Signed distance [m] of a point (in the half-space's frame) to ``z <= 0``."""
    return x[2]


def _outside_inside(q: _E) -> _E:
    """``|max(q, 0)| + min(max_i q_i, 0)``: the signed distance of a box-like gap ``q``."""
    n = q.shape[0]
    outside = smooth_norm(ca.fmax(q, 0))
    inside = q[0]
    for i in range(1, n):
        inside = ca.fmax(inside, q[i])
    return outside + ca.fmin(inside, 0)


def point_box_distance(x: _E, half: Array) -> _E:
    """Signed distance [m] of a point (in the box's frame) to a box of half sizes ``half`` [m]."""
    return _outside_inside(ca.fabs(x) - ca.DM(np.asarray(half, dtype=float)))


def point_cylinder_distance(x: _E, radius: float, half_length: float) -> _E:
    """Signed distance [m] of a point (in the cylinder's frame) to a cylinder about z."""
    rho = smooth_norm(x[0:2])
    return _outside_inside(ca.vertcat(rho - radius, ca.fabs(x[2]) - half_length))


def point_capsule_distance(x: _E, radius: float, half_length: float) -> _E:
    """Signed distance [m] of a point (in the capsule's frame) to a capsule about z."""
    z = ca.fmin(ca.fmax(x[2], -half_length), half_length)
    return smooth_norm(x - ca.vertcat(0, 0, z)) - radius
