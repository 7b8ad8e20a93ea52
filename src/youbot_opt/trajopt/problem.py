"""Point-to-point trajectory problem: a plain, immutable spec with no CasADi inside.

A :class:`TrajOptProblem` says *what* to optimise (spec ``trajopt.md``, "The
optimisation problem"): a robot, rest-or-moving start and goal states
(:class:`BoundaryState`), the number of knots, the joint bounds taken from the
model (scaled by ``bound_scale``; :attr:`TrajOptProblem.scaled_bounds`) and
whether the common time step is free
(the study) or the duration fixed. The objective's form is fixed, ``beta T +
(1 - beta) W``; its weight ``beta`` is a solve-time parameter
(:meth:`TrajOptSolver.solve(beta=...) <youbot_opt.trajopt.solver.TrajOptSolver.solve>`).
*How* it is transcribed and solved: :mod:`youbot_opt.trajopt.solver`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from youbot_opt._typing import Array, JSONDict
from youbot_opt.collision.clearance import Clearance
from youbot_opt.dynamics.coordinates import angle_robot
from youbot_opt.exceptions import ParameterError
from youbot_opt.robot.model import BOUND_FAMILIES, BoundFamily, JointBounds, RobotModel
from youbot_opt.trajopt.tool import ToolConstraint

__all__ = [
    "BoundaryState",
    "BoundFamily",
    "JointBounds",
    "TrajOptProblem",
]

_FAMILIES: tuple[str, ...] = BOUND_FAMILIES


def _vector(name: str, value: Any, size: int | None = None) -> Array:
    """Return a finite, read-only float vector, or raise ParameterError naming ``name``."""
    try:
        arr = np.array(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ParameterError(
            f"{name} must be a vector of numbers, got {value!r}", name=name
        ) from exc
    if arr.ndim != 1 or (size is not None and arr.size != size):
        want = f"({size},)" if size is not None else "(n,)"
        raise ParameterError(
            f"{name} must have shape {want}, got {arr.shape}", name=name, value=arr.shape
        )
    if not np.all(np.isfinite(arr)):
        raise ParameterError(f"{name} must be finite, got {arr.tolist()}", name=name, value=arr)
    arr.setflags(write=False)
    return arr


@dataclass(frozen=True, slots=True, kw_only=True)
class BoundaryState:
    """Joint state at the start or the goal of the motion.

    Attributes
    ----------
    q : ndarray, shape (nq,)
        Joint positions in [rad] ([m] for prismatic joints).
    v : ndarray, shape (nv,)
        Joint velocities in [rad/s]; zeros (rest) when omitted.
    """

    q: Array
    v: Array | None = None

    def __post_init__(self) -> None:
        q = _vector("q", self.q)
        object.__setattr__(self, "q", q)
        v = np.zeros(q.size) if self.v is None else self.v
        object.__setattr__(self, "v", _vector("v", v, q.size))

    @property
    def velocity(self) -> Array:
        """Joint velocities in [rad/s] (never None after construction)."""
        assert self.v is not None
        return self.v


@dataclass(frozen=True, slots=True, kw_only=True)
class TrajOptProblem:
    """Point-to-point, time/work-optimal motion of a fixed-base robot.

    Attributes
    ----------
    robot : RobotModel
        The robot (Pinocchio model and its limits, :mod:`youbot_opt.robot.model`).
        A robot with continuous joints is replaced by its angle-coordinate twin
        (:func:`youbot_opt.dynamics.coordinates.angle_robot`): each such joint
        becomes one unbounded angle in [rad] instead of Pinocchio's (cos, sin).
    start, goal : BoundaryState
        Joint states at ``t = 0`` and at ``t = T`` (angle coordinates).
    n_knots : int
        Number of collocation knots ``N`` (>= 2); the study used 50.
    duration : float or None
        Fixed total duration in [s]; ``None`` (default) leaves the common time
        step ``dt`` free, as in the study.
    scaled_bounds : tuple of {"position", "velocity", "torque"}
        Bound families multiplied by ``bound_scale`` (default all three, as in
        the study, which scaled *all* bounds to 100, 95, 90 and 85 % of the data
        sheet). Position bounds are scaled about zero (``s * q_lower``,
        ``s * q_upper``), which is what multiplying the data sheet's numbers
        means; ``("velocity", "torque")`` keeps the data sheet's position range.
    dt_min, dt_max : float
        Bounds on the free time step in [s] (``dt > 0`` in the study).
    damping : bool
        Apply the model's viscous joint damping in the dynamics.
    clearance : Clearance or None
        Keep the motion clear of a scene's obstacles and of the robot itself,
        at the knots and each transcription's interior points; None (default):
        no collision constraints, the NLP of a scene-less problem.
    tool : tuple of ToolConstraint
        Constraints on a tool frame (:mod:`youbot_opt.trajopt.tool`: an axis
        kept near a direction, the tool point near a segment, a tool speed
        limit), held at the knots and interior points and certified between
        them; empty (default): none.
    """

    robot: RobotModel
    start: BoundaryState
    goal: BoundaryState
    n_knots: int = 50
    duration: float | None = None
    scaled_bounds: tuple[BoundFamily, ...] = ("position", "velocity", "torque")
    dt_min: float = 1e-6  # [s]
    dt_max: float = math.inf  # [s]
    damping: bool = True
    clearance: Clearance | None = None
    tool: tuple[ToolConstraint, ...] = ()

    def __post_init__(self) -> None:
        # Continuous joints are planned in angle coordinates (docs/design.md).
        object.__setattr__(self, "robot", angle_robot(self.robot))
        nq, nv = int(self.robot.nq), int(self.robot.nv)
        if nq != nv:
            raise ParameterError(
                f"robot {self.robot.name!r} has nq = {nq} != nv = {nv}; only revolute, "
                "continuous and prismatic joints are supported",
                name="robot",
            )
        for name in ("start", "goal"):
            state = getattr(self, name)
            if not isinstance(state, BoundaryState):
                raise ParameterError(
                    f"{name} must be a BoundaryState, got {type(state).__name__}", name=name
                )
            if state.q.size != nq:
                raise ParameterError(
                    f"{name}.q must have shape ({nq},) for robot {self.robot.name!r}, "
                    f"got {state.q.shape}",
                    name=name,
                    value=state.q.shape,
                )
        if isinstance(self.n_knots, bool) or not isinstance(self.n_knots, int | np.integer):
            raise ParameterError(f"n_knots must be an int, got {self.n_knots!r}", name="n_knots")
        if self.n_knots < 2:
            raise ParameterError(
                f"n_knots must be >= 2, got {self.n_knots}", name="n_knots", value=self.n_knots
            )
        object.__setattr__(self, "n_knots", int(self.n_knots))
        if self.duration is not None:
            if not math.isfinite(self.duration) or self.duration <= 0.0:
                raise ParameterError(
                    f"duration must be finite and > 0 [s] or None (free), got {self.duration!r}",
                    name="duration",
                    value=self.duration,
                )
            object.__setattr__(self, "duration", float(self.duration))
        families = tuple(self.scaled_bounds)
        bad = [f for f in families if f not in _FAMILIES]
        if bad:
            raise ParameterError(
                f"scaled_bounds entries must be among {_FAMILIES}, got {bad}", name="scaled_bounds"
            )
        object.__setattr__(self, "scaled_bounds", families)
        if not (0.0 < self.dt_min < self.dt_max) or math.isnan(self.dt_max):
            raise ParameterError(
                f"need 0 < dt_min < dt_max [s], got dt_min={self.dt_min}, dt_max={self.dt_max}",
                name="dt_min",
            )
        if self.clearance is not None and not isinstance(self.clearance, Clearance):
            raise ParameterError(
                f"clearance must be a Clearance or None, got {type(self.clearance).__name__}",
                name="clearance",
            )
        tool = tuple(self.tool)
        for c in tool:
            if not isinstance(c, ToolConstraint):
                raise ParameterError(
                    f"tool entries must be ToolConstraints, got {type(c).__name__}", name="tool"
                )
            if c.frame is not None:
                self.robot.frame_id(c.frame)  # raises FrameNotFound listing the frames
        object.__setattr__(self, "tool", tool)
        self.check_boundary(1.0)

    # ------------------------------------------------------------------ sizes
    @property
    def nv(self) -> int:
        """Number of joint velocities (= joint positions) of the robot."""
        return int(self.robot.nv)

    # ----------------------------------------------------------------- bounds
    def bounds(self, bound_scale: float = 1.0) -> JointBounds:
        """Joint bounds scaled by ``bound_scale`` (see :attr:`scaled_bounds`).

        Parameters
        ----------
        bound_scale : float
            Factor > 0 applied to each family in :attr:`scaled_bounds`; 1.0 is
            the data sheet.

        Returns
        -------
        JointBounds
            Position [rad], velocity [rad/s] and torque [N m] bounds.
        """
        return self.robot.bounds(bound_scale, families=self.scaled_bounds)

    def check_boundary(
        self,
        bound_scale: float = 1.0,
        start: BoundaryState | None = None,
        goal: BoundaryState | None = None,
    ) -> None:
        """Check that start and goal states lie inside the scaled bounds.

        Raises
        ------
        ParameterError
            Naming the state, joint, value and limit that is violated.
        """
        b = self.bounds(bound_scale)
        for name, state in (("start", start or self.start), ("goal", goal or self.goal)):
            if state.q.size != self.nv:
                raise ParameterError(
                    f"{name}.q must have shape ({self.nv},), got {state.q.shape}", name=name
                )
            for what, x, lo, hi, unit in (
                ("q", state.q, b.q_lower, b.q_upper, "rad"),
                ("v", state.velocity, b.v_lower, b.v_upper, "rad/s"),
            ):
                bad = np.flatnonzero((x < lo) | (x > hi))
                if bad.size:
                    j = int(bad[0])
                    raise ParameterError(
                        f"{name}.{what}[{j}] = {x[j]:.6g} {unit} is outside the bounds "
                        f"[{lo[j]:.6g}, {hi[j]:.6g}] {unit} at bound_scale = {bound_scale:g}",
                        name=f"{name}.{what}",
                        value=float(x[j]),
                    )

    def describe(self) -> JSONDict:
        """JSON-ready description (robot name and URDF path, boundary, sizes)."""
        urdf = getattr(self.robot, "urdf_path", None)
        return {
            "robot": str(self.robot.name),
            "urdf_path": None if urdf is None else str(urdf),
            "nq": int(self.robot.nq),
            "nv": self.nv,
            "start_q": self.start.q.tolist(),
            "start_v": self.start.velocity.tolist(),
            "goal_q": self.goal.q.tolist(),
            "goal_v": self.goal.velocity.tolist(),
            "n_knots": self.n_knots,
            "duration": self.duration,
            "scaled_bounds": list(self.scaled_bounds),
            "dt_min": self.dt_min,
            "dt_max": None if math.isinf(self.dt_max) else self.dt_max,
            "damping": self.damping,
            "model_damping": np.asarray(self.robot.damping, dtype=float).tolist(),
            **({"tool": [c.document() for c in self.tool]} if self.tool else {}),
        }
