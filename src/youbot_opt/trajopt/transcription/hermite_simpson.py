r"""Hermite-Simpson direct collocation, separated form (Betts sec. 4.6.5).

Variables: knot and mid-interval ``q, v, tau`` and the mean step ``dt``
(``3 nv (2N - 1) + 1``); per interval the Simpson defects and the Hermite
midpoint conditions (``4 nv (N - 1)`` equalities). Position and velocity are
cubic Hermite splines, the torque is quadratic; the whole position and
velocity cubics are held within their bounds by bounding their Bernstein
control points (path blocks ``position_control_*``, ``velocity_control_*``).
The derivation, and why the separated form is kept, are in docs/collocation.md.

    solver = TrajOptSolver(problem, HermiteSimpsonCollocation())
"""

from __future__ import annotations

from collections.abc import Mapping
from types import MappingProxyType
from typing import ClassVar, TypeVar

import casadi as ca
import numpy as np

from youbot_opt._typing import Array
from youbot_opt.trajopt.trajectory import Trajectory
from youbot_opt.trajopt.transcription.base import Transcription

__all__ = ["HermiteSimpsonCollocation"]

_E = TypeVar("_E", ca.SX, ca.MX)  # a CasADi expression: the transcriptions work with both


class HermiteSimpsonCollocation(Transcription):
    """Separated Hermite-Simpson collocation with a mid-interval torque."""

    name = "hermite_simpson"
    interpolation = "hermite_simpson"
    rule = "simpson"
    unbounded: ClassVar[tuple[str, ...]] = ("q_mid", "v_mid")
    interior_points: ClassVar[Mapping[str, float]] = MappingProxyType({"midpoints": 0.5})

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

    def dynamics_points(self, sym: dict[str, _E]) -> dict[str, tuple[_E, _E, _E]]:
        """Evaluate the dynamics at the ``N`` knots and the ``N - 1`` midpoints."""
        return {
            "knots": (sym["q"], sym["v"], sym["tau"]),
            "midpoints": (sym["q_mid"], sym["v_mid"], sym["tau_mid"]),
        }

    def collocation(self, sym: dict[str, _E], accel: dict[str, _E]) -> list[tuple[str, _E]]:
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
        self, sym: dict[str, _E], accel: dict[str, _E]
    ) -> list[tuple[str, str, _E]]:
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
