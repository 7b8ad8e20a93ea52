r"""Hermite-Simpson direct collocation, separated form (Betts sec. 4.6.5).

Decision variables: knot states and torques ``q_k, v_k, tau_k`` (``N``
knots), mid-interval states and torques ``q_m, v_m, tau_m`` (``N - 1``
intervals) and the common step ``dt``: ``3 nv (2N - 1) + 1`` numbers. Per
interval, with ``a = FD(q, v, tau)`` at the knots and the midpoint,

.. math::

    q_m = \tfrac12 (q_k + q_{k+1}) + \tfrac{dt}{8} (v_k - v_{k+1}), \qquad
    v_m = \tfrac12 (v_k + v_{k+1}) + \tfrac{dt}{8} (a_k - a_{k+1}),

    q_{k+1} - q_k = \tfrac{dt}{6} (v_k + 4 v_m + v_{k+1}), \qquad
    v_{k+1} - v_k = \tfrac{dt}{6} (a_k + 4 a_m + a_{k+1}),

``4 nv (N - 1)`` equalities plus ``4 nv`` boundary equalities. The torque is
piecewise quadratic through ``tau_k, tau_m, tau_{k+1}``; position and velocity
are cubic Hermite splines; the work uses Simpson's rule on ``tau . tau``.

**Speed bound between knots.** The velocity interpolant on interval ``k`` is
the cubic Hermite spline with end values ``v_k, v_{k+1}`` and end slopes
``a_k, a_{k+1}`` (its value at the midpoint is ``v_m`` by the Hermite midpoint
condition, and its slope there is ``a_m`` by the Simpson defect, so it is the
velocity the collocation equations describe). Bounding ``v`` at the knots and
``v_m`` does not bound it in between: the cubic overshoots near speed-limited
arcs (8 % at 50 knots for the study-1 base case). In Bernstein form on
``s = (t - t_k) / dt``,

.. math::

    v(s) = \sum_{i=0}^{3} b_i \binom{3}{i} s^i (1 - s)^{3 - i}, \quad
    b_0 = v_k,\; b_1 = v_k + \tfrac{dt}{3} a_k,\;
    b_2 = v_{k+1} - \tfrac{dt}{3} a_{k+1},\; b_3 = v_{k+1},

and the Bernstein basis is non-negative and sums to one, so ``v(s)`` is a convex
combination of the control points ``b_i`` (convex-hull property). Holding
``b_1`` and ``b_2`` within the speed bounds (path blocks
``velocity_control_left`` and ``velocity_control_right``, ``nv (N - 1)`` rows
each; ``b_0``, ``b_3`` are the bounded knot velocities) therefore keeps the
whole interpolant within them -- a sufficient condition, not a sampled one.
It is conservative by ``O(dt^2 |dv/dt''|)`` (the control polygon's distance
from the curve), which vanishes as knots are added. The midpoint-velocity
bound is implied (``v_m = (b_0 + 3 b_1 + 3 b_2 + b_3) / 8``) and would make the
active constraints linearly dependent on a speed-limited arc, so ``v_mid``
has no bound of its own.

**Position bound between knots.** The position interpolant is the cubic
Hermite spline with end values ``q_k, q_{k+1}`` and end slopes ``v_k, v_{k+1}``
(its midpoint value is ``q_m`` by the Hermite midpoint condition). The same
argument applies: its Bernstein control points ``q_k + dt/3 v_k`` and
``q_{k+1} - dt/3 v_{k+1}`` are held within the position bounds (path blocks
``position_control_left`` / ``position_control_right``), so the whole cubic
stays within them, and ``q_mid`` (a convex combination of the four control
points) has no bound of its own. The mid-interval torque ``tau_mid`` keeps
its variable bound; the quadratic torque between the three samples is
checked by the certificate (:func:`youbot_opt.trajopt.certify.check_bounds`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from youbot_opt._typing import Array
from youbot_opt.trajopt.trajectory import Trajectory
from youbot_opt.trajopt.transcription.base import Transcription

__all__ = ["HermiteSimpsonCollocation"]


class HermiteSimpsonCollocation(Transcription):
    """Separated Hermite-Simpson collocation with a mid-interval torque."""

    name = "hermite_simpson"
    interpolation = "hermite_simpson"
    rule = "simpson"
    unbounded = ("q_mid", "v_mid")

    def variable_blocks(self, nv: int, n_knots: int) -> list[tuple[str, int, int]]:
        """Knot and midpoint ``q, v, tau`` and ``dt``: ``3 nv (2N - 1) + 1`` variables."""
        m = n_knots - 1
        return [
            ("q", nv, n_knots),
            ("v", nv, n_knots),
            ("tau", nv, n_knots),
            ("q_mid", nv, m),
            ("v_mid", nv, m),
            ("tau_mid", nv, m),
            ("dt", 1, 1),
        ]

    def dynamics_points(self, sym: dict[str, Any]) -> dict[str, tuple[Any, Any, Any]]:
        """Evaluate the dynamics at the ``N`` knots and the ``N - 1`` midpoints."""
        return {
            "knots": (sym["q"], sym["v"], sym["tau"]),
            "midpoints": (sym["q_mid"], sym["v_mid"], sym["tau_mid"]),
        }

    def collocation(self, sym: dict[str, Any], accel: dict[str, Any]) -> list[tuple[str, Any]]:
        """Simpson defects and Hermite midpoint conditions, ``(nv, N - 1)`` each."""
        q, v, dt = sym["q"], sym["v"], sym["dt"]
        qm, vm = sym["q_mid"], sym["v_mid"]
        a, am = accel["knots"], accel["midpoints"]
        q0, q1, v0, v1, a0, a1 = q[:, :-1], q[:, 1:], v[:, :-1], v[:, 1:], a[:, :-1], a[:, 1:]
        if self.uniform:  # the original expressions, operation for operation
            defect_q = q1 - q0 - dt / 6 * (v0 + 4 * vm + v1)
            defect_v = v1 - v0 - dt / 6 * (a0 + 4 * am + a1)
            mid_q = qm - 0.5 * (q0 + q1) - dt / 8 * (v0 - v1)
            mid_v = vm - 0.5 * (v0 + v1) - dt / 8 * (a0 - a1)
        else:
            defect_q = q1 - q0 - self.per_interval(v0 + 4 * vm + v1, dt) / 6
            defect_v = v1 - v0 - self.per_interval(a0 + 4 * am + a1, dt) / 6
            mid_q = qm - 0.5 * (q0 + q1) - self.per_interval(v0 - v1, dt) / 8
            mid_v = vm - 0.5 * (v0 + v1) - self.per_interval(a0 - a1, dt) / 8
        return [
            ("defect_position", defect_q),
            ("defect_velocity", defect_v),
            ("midpoint_position", mid_q),
            ("midpoint_velocity", mid_v),
        ]

    def path_constraints(
        self, sym: dict[str, Any], accel: dict[str, Any]
    ) -> list[tuple[str, str, Any]]:
        """Bound the inner Bernstein control points of each interval's velocity cubic."""
        v, dt, a = sym["v"], sym["dt"], accel["knots"]
        q = sym["q"]
        if self.uniform:
            left = v[:, :-1] + dt / 3 * a[:, :-1]
            right = v[:, 1:] - dt / 3 * a[:, 1:]
            q_left = q[:, :-1] + dt / 3 * v[:, :-1]
            q_right = q[:, 1:] - dt / 3 * v[:, 1:]
        else:
            left = v[:, :-1] + self.per_interval(a[:, :-1], dt) / 3
            right = v[:, 1:] - self.per_interval(a[:, 1:], dt) / 3
            q_left = q[:, :-1] + self.per_interval(v[:, :-1], dt) / 3
            q_right = q[:, 1:] - self.per_interval(v[:, 1:], dt) / 3
        return [
            ("velocity_control_left", "v", left),
            ("velocity_control_right", "v", right),
            ("position_control_left", "q", q_left),
            ("position_control_right", "q", q_right),
        ]

    def knot_guess(self, guess: Trajectory, n_knots: int) -> dict[str, Array]:
        """Knot and midpoint values of ``guess`` on the grid's ``n_knots`` times."""
        dt, t = self.knot_times(guess, n_knots)
        tm = t[:-1] + 0.5 * dt if self.uniform else 0.5 * (t[:-1] + t[1:])
        return {
            "q": guess(t),
            "v": guess.velocity(t),
            "tau": guess.torque(t),
            "q_mid": guess(tm),
            "v_mid": guess.velocity(tm),
            "tau_mid": guess.torque(tm),
            "dt": np.array(dt),
        }
