r"""Trapezoidal direct collocation: the study's transcription, done correctly.

:class:`TrapezoidalCollocation`: decision variables ``q_k, v_k, tau_k`` at the
``N`` knots and the common step ``dt`` (``3 nv N + 1``, the study's ``9n + 1``),
trapezoidal defects on ``q' = v`` and ``v' = FD(q, v, tau)`` (Betts, *Practical
Methods for Optimal Control*, sec. 4.5; spec ``trajopt.md``). Unlike the study's
code, every knot's acceleration is evaluated at that knot's own state and
torque. The equations and counts: the class docstring.
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

__all__ = ["TrapezoidalCollocation"]

_E = TypeVar("_E", ca.SX, ca.MX)  # a CasADi expression: the transcriptions work with both


class TrapezoidalCollocation(Transcription):
    r"""Trapezoidal collocation with a free common time step (the study's scheme).

    For ``N`` knots with a common step ``dt`` (Betts, *Practical Methods for
    Optimal Control*, sec. 4.5; spec ``trajopt.md``; on a non-uniform grid interval
    ``k`` has the step ``r_k dt``, see :class:`Transcription`) the decision variables
    are ``q_k, v_k, tau_k`` (``k = 0 .. N-1``) and ``dt`` -- ``3 nv N + 1`` numbers,
    the study's ``9n + 1`` for the 3-joint youBot -- and the defects are

    .. math::

        q_{k+1} - q_k - \tfrac{dt}{2}(v_k + v_{k+1}) = 0, \qquad
        v_{k+1} - v_k - \tfrac{dt}{2}(a_k + a_{k+1}) = 0, \qquad
        a_k = \mathrm{FD}(q_k, v_k, \tau_k),

    ``2 nv (N - 1)`` equalities, plus ``4 nv`` boundary equalities: the study's
    ``6(n - 1) + 12`` for ``nv = 3``. Unlike the study's code, every knot's
    acceleration is evaluated at that knot's own state and torque. Torque and
    velocity are piecewise linear, position piecewise quadratic; the work uses
    the trapezoidal rule on ``tau . tau``.
    """

    name = "trapezoidal"
    interpolation = "trapezoidal"
    rule = "trapezoidal"
    interior_points: ClassVar[Mapping[str, float]] = MappingProxyType({"midpoints": 0.5})

    def variable_blocks(self, nv: int, n_knots: int) -> list[tuple[str, int, int]]:
        """``q, v, tau`` of shape ``(nv, N)`` and the scalar ``dt``: ``3 nv N + 1`` variables."""
        return [("q", nv, n_knots), ("v", nv, n_knots), ("tau", nv, n_knots), ("dt", 1, 1)]

    def dynamics_points(self, sym: dict[str, _E]) -> dict[str, tuple[_E, _E, _E]]:
        """Evaluate the dynamics at the ``N`` knots."""
        return {"knots": (sym["q"], sym["v"], sym["tau"])}

    def collocation(self, sym: dict[str, _E], accel: dict[str, _E]) -> list[tuple[str, _E]]:
        """Position and velocity defects, ``(nv, N - 1)`` each."""
        q, v, dt = sym["q"], sym["v"], sym["dt"]
        a = accel["knots"]
        if self.uniform:  # the original expressions, operation for operation
            defect_q = q[:, 1:] - q[:, :-1] - 0.5 * dt * (v[:, 1:] + v[:, :-1])
            defect_v = v[:, 1:] - v[:, :-1] - 0.5 * dt * (a[:, 1:] + a[:, :-1])
        else:
            defect_q = q[:, 1:] - q[:, :-1] - 0.5 * self.per_interval(v[:, 1:] + v[:, :-1], dt)
            defect_v = v[:, 1:] - v[:, :-1] - 0.5 * self.per_interval(a[:, 1:] + a[:, :-1], dt)
        return [("defect_position", defect_q), ("defect_velocity", defect_v)]

    def path_points(self, sym: dict[str, _E]) -> dict[str, tuple[_E, _E]]:
        """Evaluate at the knots and at the midpoints of the quadratic position, linear velocity.

        ``q(t_k + h_k / 2) = (q_k + q_{k+1}) / 2 + h_k (v_k - v_{k+1}) / 8``.
        """
        q, v, dt = sym["q"], sym["v"], sym["dt"]
        q_mid = 0.5 * (q[:, :-1] + q[:, 1:]) + self.per_interval(v[:, :-1] - v[:, 1:], dt) / 8
        v_mid = 0.5 * (v[:, :-1] + v[:, 1:])
        return {"knots": (q, v), "midpoints": (q_mid, v_mid)}

    def knot_guess(self, guess: Trajectory, n_knots: int) -> dict[str, Array]:
        """Knot values of ``guess`` resampled on the grid's ``n_knots`` times."""
        dt, t = self.knot_times(guess, n_knots)
        return {"q": guess(t), "v": guess.velocity(t), "tau": guess.torque(t), "dt": np.array(dt)}
