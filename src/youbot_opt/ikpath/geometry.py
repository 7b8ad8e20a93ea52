"""Exact planar geometry for the reachability test (internal).

Closed-form nearest points on circular arcs and on the workspace of a 2-link
planar arm with joint limits (angles in [rad], lengths in [m]; ranges
``(lo, width)``, ``width = 2 pi`` the full circle). The 2-link distance is
exact: at ``F = p``, at a fold ``b = k pi`` or on an edge of the angle box,
each an arc (docs/design.md, "Module notes").
"""

from __future__ import annotations

import math
from typing import NamedTuple

TWO_PI = 2.0 * math.pi
_ANGLE_SLACK = 1e-12  # [rad] tolerance when testing whether an angle is in a range


class Nearest2(NamedTuple):
    """Nearest point of a 2-link workspace: distance [m] and the joint angles [rad]."""

    distance: float
    alpha: float
    beta: float


def wrap_into(angle: float, lo: float, width: float) -> float | None:
    """Return the representative of ``angle`` (mod 2 pi) in ``[lo, lo + width]``, or None."""
    t = (angle - lo) % TWO_PI
    if t <= width + _ANGLE_SLACK:
        return lo + min(t, width)
    if t >= TWO_PI - _ANGLE_SLACK:  # just below lo
        return lo
    return None


def nearest_on_arc(
    px: float, py: float, cx: float, cy: float, r: float, lo: float, width: float
) -> tuple[float, float]:
    """Distance from ``p`` to the arc ``c + r e(lo + t)``, ``0 <= t <= width``.

    Returns
    -------
    tuple of float
        ``(distance, t)`` with ``t`` the arc parameter of the nearest point.
    """
    vx, vy = px - cx, py - cy
    d = math.hypot(vx, vy)
    if d == 0.0:
        return r, 0.0
    t = (math.atan2(vy, vx) - lo) % TWO_PI
    if width >= TWO_PI or t <= width:
        return abs(d - r), t
    d0 = math.hypot(px - cx - r * math.cos(lo), py - cy - r * math.sin(lo))
    d1 = math.hypot(px - cx - r * math.cos(lo + width), py - cy - r * math.sin(lo + width))
    return (d0, 0.0) if d0 <= d1 else (d1, width)


def two_link_tip(
    wx: float, wy: float, psi: float, la: float, lb: float, alpha: float, beta: float
) -> tuple[float, float]:
    """Tip of the 2-link arm at (alpha, beta) with base ``w`` and base direction ``psi``."""
    a = psi + alpha
    return (
        wx + la * math.cos(a) + lb * math.cos(a + beta),
        wy + la * math.sin(a) + lb * math.sin(a + beta),
    )


def two_link_ik(
    px: float,
    py: float,
    wx: float,
    wy: float,
    psi: float,
    la: float,
    lb: float,
    a_rng: tuple[float, float],
    b_rng: tuple[float, float],
    elbow_first: float = 1.0,
) -> tuple[float, float] | None:
    """Joint angles within the ranges that put the tip on ``p``, or None.

    ``elbow_first`` (+1 or -1) is the sign of ``beta`` tried first.
    """
    vx, vy = px - wx, py - wy
    r2 = vx * vx + vy * vy
    cb = (r2 - la * la - lb * lb) / (2.0 * la * lb)
    if cb > 1.0 + 1e-12 or cb < -1.0 - 1e-12:
        return None
    b0 = math.acos(min(1.0, max(-1.0, cb)))
    for b in (elbow_first * b0, -elbow_first * b0):
        beta = wrap_into(b, *b_rng)
        if beta is None:
            continue
        if r2 < 1e-24 and abs(la - lb) < 1e-12:  # p = w, folded arm: any alpha works
            return a_rng[0], beta
        gamma = math.atan2(lb * math.sin(beta), la + lb * math.cos(beta))
        alpha = wrap_into(math.atan2(vy, vx) - psi - gamma, *a_rng)
        if alpha is not None:
            return alpha, beta
    return None


def two_link_nearest(
    px: float,
    py: float,
    wx: float,
    wy: float,
    psi: float,
    la: float,
    lb: float,
    a_rng: tuple[float, float],
    b_rng: tuple[float, float],
) -> Nearest2:
    """Exact nearest point to ``p`` of the limited 2-link workspace.

    Parameters
    ----------
    px, py : float
        Query point in [m].
    wx, wy : float
        Base of the 2-link arm in [m].
    psi : float
        Direction of the base frame's x axis in [rad]; ``alpha`` is relative to it.
    la, lb : float
        Link lengths in [m].
    a_rng, b_rng : tuple of float
        ``(lo, width)`` ranges of ``alpha`` (first joint) and ``beta`` (relative
        second joint) in [rad].

    Returns
    -------
    Nearest2
        Distance in [m] (the tip's actual distance from ``p`` at the returned
        angles) and the angles.
    """
    sol = two_link_ik(px, py, wx, wy, psi, la, lb, a_rng, b_rng)
    if sol is not None:
        tx, ty = two_link_tip(wx, wy, psi, la, lb, *sol)
        return Nearest2(math.hypot(tx - px, ty - py), sol[0], sol[1])
    best = Nearest2(math.inf, a_rng[0], b_rng[0])
    a_lo, a_w = a_rng
    b_lo, b_w = b_rng
    if a_w < TWO_PI:  # edges alpha = const: arcs of radius lb about the elbow
        for alpha in (a_lo, a_lo + a_w):
            ex = wx + la * math.cos(psi + alpha)
            ey = wy + la * math.sin(psi + alpha)
            d, t = nearest_on_arc(px, py, ex, ey, lb, psi + alpha + b_lo, b_w)
            if d < best.distance:
                best = Nearest2(d, alpha, b_lo + t)
    betas = [b_lo, b_lo + b_w] if b_w < TWO_PI else []
    k = math.ceil(b_lo / math.pi - 1e-15)
    while k * math.pi <= b_lo + b_w and len(betas) < 8:  # folds b = k pi (singular arm)
        betas.append(k * math.pi)
        k += 1
    for beta in betas:  # beta = const: arcs about w of radius |la + lb e(beta)|
        cx, cy = la + lb * math.cos(beta), lb * math.sin(beta)
        rho = math.hypot(cx, cy)
        gamma = math.atan2(cy, cx)
        d, t = nearest_on_arc(px, py, wx, wy, rho, psi + gamma + a_lo, a_w)
        if d < best.distance:
            best = Nearest2(d, a_lo + t, beta)
    return best
