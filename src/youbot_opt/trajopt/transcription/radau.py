r"""Three-stage Radau IIA collocation: L-stable, for stiff joint damping.

Variables: knot ``q, v, tau``, the stage values ``q, v, tau`` at the two inner
Radau nodes of each interval (blocks ``*_stage1``, ``*_stage2``; the third
node is the end knot) and the mean step ``dt``: ``3 nv (3N - 2) + 1``. Per
interval, the collocation equations in integral form (``6 nv`` rows); the knot
torque ``tau_0`` is the first interval's torque quadratic at its start. Position
and velocity are cubics through their knot and stage values, held within their
bounds by their Bernstein control points (linear rows). Why: docs/refinement.md.

    solver = TrajOptSolver(problem, RadauCollocation())
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from types import MappingProxyType
from typing import Any, ClassVar, TypeVar

import casadi as ca
import numpy as np

from youbot_opt._typing import Array
from youbot_opt.exceptions import TranscriptionError
from youbot_opt.trajopt import quadrature
from youbot_opt.trajopt.trajectory import Trajectory
from youbot_opt.trajopt.transcription.base import Transcription

__all__ = ["RadauCollocation"]

_E = TypeVar("_E", ca.SX, ca.MX)  # a CasADi expression: the transcriptions work with both

_STAGES = ("stage1", "stage2")


class RadauCollocation(Transcription):
    r"""Radau IIA collocation (3 stages, order 5, stage order 3) with a free duration.

    With ``h_k = r_k dt`` and the Butcher matrix ``A`` of
    :mod:`youbot_opt.trajopt.quadrature`, per interval ``k`` and node ``i = 1, 2, 3``

    .. math::

        q_{k,i} = q_k + h_k \sum_j A_{ij} v_{k,j}, \qquad
        v_{k,i} = v_k + h_k \sum_j A_{ij} a_{k,j}, \qquad
        a_{k,j} = \mathrm{FD}(q_{k,j}, v_{k,j}, \tau_{k,j}),

    where node 3 is the knot ``k + 1``. The amplification of a damped mode
    ``x' = -\lambda x`` tends to 0 as ``\lambda h \to \infty`` (L-stability), so
    a joint whose damping relaxes far faster than the grid resolves is carried
    on its slow manifold instead of oscillating from interval to interval as
    under the trapezoid (amplification -1) and Hermite-Simpson (+1). The work
    uses the Radau quadrature on the three stage torques (exact for the
    quadratic torque).
    """

    name = "radau"
    interpolation = "radau"
    rule = "radau"
    unbounded: ClassVar[tuple[str, ...]] = ("q_stage1", "v_stage1", "q_stage2", "v_stage2")
    interior_points: ClassVar[Mapping[str, float]] = MappingProxyType(
        {s: float(c) for s, c in zip(_STAGES, quadrature.RADAU_NODES[:2], strict=True)}
    )
    mumps_pivot_order: ClassVar[int] = 2
    """AMF: 10-22 % less time per IPOPT iteration than AMD on ur5 and panda (docs/design.md)."""

    def variable_blocks(self, nv: int, n_knots: int) -> list[tuple[str, int, int]]:
        """Knot and stage ``q, v, tau`` and ``dt``: ``3 nv (3N - 2) + 1`` variables."""
        m = n_knots - 1
        stages = [(f"{x}_{s}", nv, m) for s in _STAGES for x in ("q", "v", "tau")]
        return [("q", nv, n_knots), ("v", nv, n_knots), ("tau", nv, n_knots), *stages, ("dt", 1, 1)]

    def dynamics_points(self, sym: dict[str, _E]) -> dict[str, tuple[_E, _E, _E]]:
        """Evaluate the dynamics at the ``N`` knots and the two inner stages of each interval."""
        points = {"knots": (sym["q"], sym["v"], sym["tau"])}
        for s in _STAGES:
            points[s] = (sym[f"q_{s}"], sym[f"v_{s}"], sym[f"tau_{s}"])
        return points

    def _nodes(self, sym: dict[str, _E], accel: dict[str, _E], what: str) -> list[Any]:
        """Values of ``q``, ``v`` or ``tau`` (or the accelerations, ``a``) at nodes 1, 2, 3."""
        if what == "a":
            return [accel["stage1"], accel["stage2"], accel["knots"][:, 1:]]
        return [sym[f"{what}_stage1"], sym[f"{what}_stage2"], sym[what][:, 1:]]

    def collocation(self, sym: dict[str, _E], accel: dict[str, _E]) -> list[tuple[str, _E]]:
        """Integral-form collocation rows at nodes 1, 2, 3 and the start torque."""
        dt = sym["dt"]
        blocks: list[tuple[str, _E]] = []
        for state, rate, label in (("q", "v", "position"), ("v", "a", "velocity")):
            start = sym[state][:, :-1]
            values = self._nodes(sym, accel, state)
            rates = self._nodes(sym, accel, rate)
            names = (f"collocation_{label}_1", f"collocation_{label}_2", f"defect_{label}")
            for i, name in enumerate(names):  # row 3 of the Butcher matrix: the weights
                blocks.append(
                    (name, values[i] - start - self._step(rates, quadrature.RADAU_BUTCHER[i], dt))
                )
        tau = self._nodes(sym, accel, "tau")
        start_torque = sym["tau"][:, 0] - sum(
            float(w) * t[:, 0] for w, t in zip(quadrature.RADAU_AT_ZERO, tau, strict=True)
        )
        blocks.append(("start_torque", start_torque))
        return blocks

    def _step(self, rates: list[Any], weights: Array, dt: Any) -> Any:
        """``h_k sum_j w_j rates_j`` per interval column."""
        combo = sum(float(w) * r for w, r in zip(weights, rates, strict=True))
        return dt * combo if self.uniform else self.per_interval(combo, dt)

    def path_constraints(
        self, sym: dict[str, _E], accel: dict[str, _E]
    ) -> list[tuple[str, str, _E]]:
        """Bound the inner Bernstein control points of each interval's ``q`` and ``v`` cubics."""
        rows = quadrature.radau_bernstein_inner()
        out: list[tuple[str, str, _E]] = []
        what: str
        label: str
        for what, label in (("v", "velocity"), ("q", "position")):
            values = [sym[what][:, :-1], *self._nodes(sym, accel, what)]
            for side, row in zip(("left", "right"), rows, strict=True):
                expr = sum(float(c) * x for c, x in zip(row, values, strict=True))
                out.append((f"{label}_control_{side}", what, expr))
        return out

    def work_weights(self, n_knots: int) -> list[tuple[str, Array]]:
        """Radau weights ``r_k b_j``: stages 1, 2 and the end knot of each interval."""
        r = self.ratios(n_knots)
        knots = np.concatenate(([0.0], quadrature.RADAU_WEIGHTS[2] * r))
        return [
            ("tau", knots),
            ("tau_stage1", quadrature.RADAU_WEIGHTS[0] * r),
            ("tau_stage2", quadrature.RADAU_WEIGHTS[1] * r),
        ]

    def quadrature(self, n_knots: int) -> tuple[Array, Array | None]:
        """Not a knot-and-midpoint rule: the work weights are :meth:`work_weights`.

        Raises
        ------
        TranscriptionError
            Always: ``(w_knots, w_mid)`` cannot express Radau's stage weights.
        """
        raise TranscriptionError(
            "Radau's work quadrature weights the stage torques: use work_weights(n_knots), "
            "not quadrature()"
        )

    def knot_guess(self, guess: Trajectory, n_knots: int) -> dict[str, Array]:
        """Knot and stage values of ``guess`` on the grid's ``n_knots`` times."""
        dt, t = self.knot_times(guess, n_knots)
        h = np.diff(t)
        values: dict[str, Array] = {
            "q": guess(t),
            "v": guess.velocity(t),
            "tau": guess.torque(t),
            "dt": np.array(dt),
        }
        for s, c in zip(_STAGES, quadrature.RADAU_NODES[:2], strict=True):
            ts = t[:-1] + c * h
            values.update(
                {f"q_{s}": guess(ts), f"v_{s}": guess.velocity(ts), f"tau_{s}": guess.torque(ts)}
            )
        return values

    def trajectory(
        self,
        values: dict[str, Array],
        a: Array,
        accel: Callable[[Array, Array, Array], Array] | None = None,
    ) -> Trajectory:
        """Solution trajectory with the stage values (``accel`` gives their accelerations).

        Raises
        ------
        TypeError
            Without ``accel``: the stage accelerations define the velocity cubic.
        """
        if accel is None:
            raise TypeError("Radau trajectories need accel(q, v, tau) for the stage accelerations")
        dt = float(values["dt"].ravel()[0])
        n = values["q"].shape[0]
        stage_a = [accel(values[f"q_{s}"], values[f"v_{s}"], values[f"tau_{s}"]) for s in _STAGES]
        return Trajectory(
            t=self.solution_times(dt, n),
            q=values["q"],
            v=values["v"],
            a=a,
            tau=values["tau"],
            interpolation="radau",
            v_stages=np.stack([values[f"v_{s}"] for s in _STAGES], axis=1),
            a_stages=np.stack(stage_a, axis=1),
            tau_stages=np.stack([values[f"tau_{s}"] for s in _STAGES], axis=1),
        )
