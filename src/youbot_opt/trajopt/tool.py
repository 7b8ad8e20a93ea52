"""Tool constraints of a trajectory problem: kinds, NLP rows, boundary check, certificate (#30).

:class:`KeepAxis` (a tool axis within an angle [rad] of a world direction),
:class:`NearLine` (the tool point within a distance [m] of a segment),
:class:`ToolSpeed` (the tool point's speed [m/s]); :func:`tool_constraint` is the
NLP's path constraint, :func:`check_boundary_tool` refuses a bad start or goal,
:mod:`youbot_opt.trajopt.tool_certificate` certifies a plan between knots (``docs/tool.md``).

>>> upright = KeepAxis(axis=(1, 0, 0), direction=(0, 0, 1), max_angle=0.2)  # [rad]
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import ClassVar

import casadi as ca
import numpy as np
import pinocchio as pin

from youbot_opt._checks import check_positive
from youbot_opt._typing import Array
from youbot_opt.dynamics.symbolic import build_symbolic_model
from youbot_opt.exceptions import ParameterError
from youbot_opt.robot.model import RobotModel
from youbot_opt.trajopt.transcription.path import PathConstraint

__all__ = [
    "KeepAxis",
    "NearLine",
    "ToolConstraint",
    "ToolSpeed",
    "check_boundary_tool",
    "knot_tool",
    "tool_constraint",
    "tool_from_document",
    "tool_measures",
]


def _unit_vector(name: str, value: object) -> Array:
    """Return ``value`` as a finite unit 3-vector (normalised), or raise naming ``name``."""
    try:
        arr = np.array(value, dtype=float).reshape(-1)
    except (TypeError, ValueError) as exc:
        raise ParameterError(f"{name} must be 3 numbers, got {value!r}", name=name) from exc
    norm = float(np.linalg.norm(arr)) if arr.size == 3 and np.all(np.isfinite(arr)) else 0.0
    if norm < 1e-12:
        raise ParameterError(
            f"{name} must be a finite non-zero 3-vector, got {value!r}", name=name, value=value
        )
    out = arr / norm
    out.setflags(write=False)
    return out


def _point(name: str, value: object) -> Array:
    """Return ``value`` as a finite 3-vector in [m], or raise naming ``name``."""
    try:
        arr = np.array(value, dtype=float).reshape(-1)
    except (TypeError, ValueError) as exc:
        raise ParameterError(f"{name} must be 3 numbers [m], got {value!r}", name=name) from exc
    if arr.size != 3 or not np.all(np.isfinite(arr)):
        raise ParameterError(f"{name} must be 3 finite numbers [m], got {value!r}", name=name)
    arr.setflags(write=False)
    return arr


@dataclass(frozen=True, slots=True, kw_only=True, eq=False)
class ToolConstraint:
    """One measure of a tool frame held at or below a limit along the whole motion.

    Attributes
    ----------
    frame : str or None
        The tool frame's name; None (default) is the problem robot's tip frame.
    """

    frame: str | None = None
    kind: ClassVar[str] = ""
    unit: ClassVar[str] = ""

    def __post_init__(self) -> None:
        if type(self) is ToolConstraint:
            raise ParameterError(
                "ToolConstraint is the base of the kinds: use KeepAxis, NearLine or ToolSpeed",
                name="tool",
            )
        if self.frame is not None and (not isinstance(self.frame, str) or not self.frame):
            raise ParameterError(
                f"frame must be a frame name or None, got {self.frame!r}", name="frame"
            )

    def __eq__(self, other: object) -> bool:
        return type(other) is type(self) and other.document() == self.document()  # type: ignore[attr-defined]

    def __hash__(self) -> int:
        return hash(repr(self.document()))

    @property
    def limit(self) -> float:
        """The largest allowed measure, in :attr:`unit`."""
        raise NotImplementedError

    def tool_frame(self, robot: RobotModel) -> str:
        """Return the tool frame's name on ``robot`` (:attr:`frame`, else the robot's tip frame)."""
        return robot.tip_frame if self.frame is None else self.frame

    @property
    def label(self) -> str:
        """Short name for reports (``"keep axis"``, ...)."""
        return self.kind.replace("_", " ")

    def row(self, rot: ca.SX, pos: ca.SX, vel: ca.SX) -> tuple[ca.SX, float, float]:
        """Return the NLP row ``c`` (dimensionless, smooth) and its bounds ``(lower, upper)``."""
        raise NotImplementedError

    def measure(self, rot: Array, pos: Array, vel: Array) -> float:
        """Return the measure of placement ``(R, p)``, point velocity [m/s], in :attr:`unit`."""
        raise NotImplementedError

    def slack(self, tol: float) -> float:
        """How far the measure may exceed :attr:`limit` when its row is off by ``tol``."""
        raise NotImplementedError

    def document(self) -> dict[str, object]:
        """JSON-ready description (read back by :func:`tool_from_document`)."""
        raise NotImplementedError


@dataclass(frozen=True, slots=True, kw_only=True, eq=False)
class KeepAxis(ToolConstraint):
    """Keep a tool axis within ``max_angle`` of a world direction (a cup upright).

    Row: ``(R a) . d >= cos(max_angle)`` (``a``, ``d`` unit vectors).

    Attributes
    ----------
    axis : ndarray, shape (3,)
        The axis in the tool frame (normalised).
    direction : ndarray, shape (3,)
        The world direction (normalised).
    max_angle : float
        Largest angle between them in [rad], in ``(0, pi)``.
    """

    axis: Array
    direction: Array
    max_angle: float
    kind: ClassVar[str] = "keep_axis"
    unit: ClassVar[str] = "rad"

    def __post_init__(self) -> None:
        ToolConstraint.__post_init__(self)
        object.__setattr__(self, "axis", _unit_vector("axis", self.axis))
        object.__setattr__(self, "direction", _unit_vector("direction", self.direction))
        angle = check_positive(self.max_angle, "max_angle", unit="rad")
        if angle >= math.pi:
            raise ParameterError(
                f"max_angle must be < pi rad (180 deg), got {angle:g} rad",
                name="max_angle",
                value=angle,
            )
        object.__setattr__(self, "max_angle", angle)

    @property
    def limit(self) -> float:  # noqa: D102
        return self.max_angle

    def row(self, rot: ca.SX, pos: ca.SX, vel: ca.SX) -> tuple[ca.SX, float, float]:  # noqa: D102
        return (
            ca.dot(rot @ ca.DM(self.axis), ca.DM(self.direction)),
            math.cos(self.max_angle),
            math.inf,
        )

    def measure(self, rot: Array, pos: Array, vel: Array) -> float:  # noqa: D102
        return float(np.arccos(np.clip((rot @ self.axis) @ self.direction, -1.0, 1.0)))

    def slack(self, tol: float) -> float:  # noqa: D102
        return float(np.arccos(max(math.cos(self.max_angle) - tol, -1.0))) - self.max_angle

    def document(self) -> dict[str, object]:  # noqa: D102
        return {
            "kind": self.kind,
            "frame": self.frame,
            "axis": self.axis.tolist(),
            "direction": self.direction.tolist(),
            "max_angle_rad": self.max_angle,
        }


@dataclass(frozen=True, slots=True, kw_only=True, eq=False)
class NearLine(ToolConstraint):
    """Keep the tool point within ``tolerance`` of the world segment ``p0``-``p1`` (a weld).

    Row: ``|p - proj(p)|^2 / tolerance^2 <= 1`` with ``proj`` the clamped
    projection onto the segment: the squared distance to a convex set is
    continuously differentiable (its gradient ``2 (p - proj(p))`` is
    continuous where the clamp switches).

    Attributes
    ----------
    p0, p1 : ndarray, shape (3,)
        The segment's ends in the world frame [m] (equal ends: a point).
    tolerance : float
        Largest distance in [m] (> 0).
    """

    p0: Array
    p1: Array
    tolerance: float
    kind: ClassVar[str] = "near_line"
    unit: ClassVar[str] = "m"

    def __post_init__(self) -> None:
        ToolConstraint.__post_init__(self)
        object.__setattr__(self, "p0", _point("p0", self.p0))
        object.__setattr__(self, "p1", _point("p1", self.p1))
        object.__setattr__(self, "tolerance", check_positive(self.tolerance, "tolerance", unit="m"))

    @property
    def limit(self) -> float:  # noqa: D102
        return self.tolerance

    def _offset(self, pos: ca.SX | Array) -> ca.SX | Array:
        """``p - proj(p)``: the tool point's offset from its closest point of the segment."""
        u = self.p1 - self.p0
        length2 = float(u @ u)
        if length2 == 0.0:
            return pos - self.p0
        if isinstance(pos, ca.SX):
            sym = ca.fmin(ca.fmax(ca.dot(pos - ca.DM(self.p0), ca.DM(u)) / length2, 0.0), 1.0)
            return pos - ca.DM(self.p0) - sym * ca.DM(u)
        s = float(np.clip((pos - self.p0) @ u / length2, 0.0, 1.0))
        return pos - self.p0 - s * u

    def row(self, rot: ca.SX, pos: ca.SX, vel: ca.SX) -> tuple[ca.SX, float, float]:  # noqa: D102
        d = self._offset(pos)
        return ca.dot(d, d) / self.tolerance**2, -math.inf, 1.0

    def measure(self, rot: Array, pos: Array, vel: Array) -> float:  # noqa: D102
        return float(np.linalg.norm(self._offset(np.asarray(pos, dtype=float))))

    def slack(self, tol: float) -> float:  # noqa: D102
        return self.tolerance * (math.sqrt(1.0 + tol) - 1.0)

    def document(self) -> dict[str, object]:  # noqa: D102
        return {
            "kind": self.kind,
            "frame": self.frame,
            "p0_m": self.p0.tolist(),
            "p1_m": self.p1.tolist(),
            "tolerance_m": self.tolerance,
        }


@dataclass(frozen=True, slots=True, kw_only=True, eq=False)
class ToolSpeed(ToolConstraint):
    """Keep the tool point's linear speed at or below ``max_speed``.

    Row: ``|J(q) v|^2 / max_speed^2 <= 1``.

    Attributes
    ----------
    max_speed : float
        Largest speed in [m/s] (> 0).
    """

    max_speed: float
    kind: ClassVar[str] = "tool_speed"
    unit: ClassVar[str] = "m/s"

    def __post_init__(self) -> None:
        ToolConstraint.__post_init__(self)
        object.__setattr__(
            self, "max_speed", check_positive(self.max_speed, "max_speed", unit="m/s")
        )

    @property
    def limit(self) -> float:  # noqa: D102
        return self.max_speed

    def row(self, rot: ca.SX, pos: ca.SX, vel: ca.SX) -> tuple[ca.SX, float, float]:  # noqa: D102
        return ca.dot(vel, vel) / self.max_speed**2, -math.inf, 1.0

    def measure(self, rot: Array, pos: Array, vel: Array) -> float:  # noqa: D102
        return float(np.linalg.norm(vel))

    def slack(self, tol: float) -> float:  # noqa: D102
        return self.max_speed * (math.sqrt(1.0 + tol) - 1.0)

    def document(self) -> dict[str, object]:  # noqa: D102
        return {"kind": self.kind, "frame": self.frame, "max_speed_m_per_s": self.max_speed}


def tool_from_document(doc: dict[str, object]) -> ToolConstraint:
    """Return the constraint a :meth:`ToolConstraint.document` describes.

    Raises
    ------
    ParameterError
        Unknown kind or bad values.
    """
    kind = doc.get("kind")
    frame = doc.get("frame")
    frame = None if frame is None else str(frame)
    if kind == KeepAxis.kind:
        return KeepAxis(
            frame=frame,
            axis=_point("axis", doc["axis"]),
            direction=_point("direction", doc["direction"]),
            max_angle=float(doc["max_angle_rad"]),  # type: ignore[arg-type]
        )
    if kind == NearLine.kind:
        return NearLine(
            frame=frame,
            p0=_point("p0", doc["p0_m"]),
            p1=_point("p1", doc["p1_m"]),
            tolerance=float(doc["tolerance_m"]),  # type: ignore[arg-type]
        )
    if kind == ToolSpeed.kind:
        return ToolSpeed(frame=frame, max_speed=float(doc["max_speed_m_per_s"]))  # type: ignore[arg-type]
    raise ParameterError(f"unknown tool constraint kind {kind!r}", name="tool", value=kind)


def tool_constraint(
    robot: RobotModel, constraints: Sequence[ToolConstraint]
) -> PathConstraint | None:
    """Return the NLP's ``"tool"`` path constraint: one smooth dimensionless row per constraint.

    Kinematics from the CasADi transcription of Pinocchio
    (:meth:`youbot_opt.dynamics.symbolic.SymbolicModel.frame_placement`); the
    tool point's velocity is ``(dp/dq) v``.

    Parameters
    ----------
    robot : RobotModel
        The robot in angle coordinates (the problem's).
    constraints : sequence of ToolConstraint
        The constraints (none: None is returned).

    Returns
    -------
    PathConstraint or None
    """
    if not constraints:
        return None
    symbolic = build_symbolic_model(robot)
    q = ca.SX.sym("q", robot.nv)
    v = ca.SX.sym("v", robot.nv)
    rows, lower, upper = [], [], []
    placements: dict[str, tuple[ca.SX, ca.SX, ca.SX]] = {}
    for c in constraints:
        name = c.tool_frame(robot)
        if name not in placements:
            rot, pos = symbolic.frame_placement(name)(q)
            placements[name] = (rot, pos, ca.jtimes(pos, q, v))
        row, lo, hi = c.row(*placements[name])
        rows.append(row)
        lower.append(lo)
        upper.append(hi)
    function = ca.Function("tool", [q, v], [ca.vertcat(*rows)], ["q", "v"], ["c"])
    return PathConstraint(
        name="tool",
        function=function,
        lower=np.array(lower),
        upper=np.array(upper),
        labels=tuple(f"{c.label} ({c.tool_frame(robot)})" for c in constraints),
    )


def tool_measures(
    robot: RobotModel, constraints: Sequence[ToolConstraint], q: Array, v: Array
) -> Array:
    """Return each constraint's measure at each state, with Pinocchio (not the NLP's CasADi).

    Parameters
    ----------
    robot : RobotModel
        The robot in angle coordinates.
    constraints : sequence of ToolConstraint
        The constraints.
    q, v : ndarray, shape (n, nv) or (nv,)
        Joint positions [rad] and velocities [rad/s].

    Returns
    -------
    ndarray, shape (n, len(constraints))
        Angles [rad], distances [m], speeds [m/s].
    """
    model = robot.model
    data = model.createData()
    q2 = np.atleast_2d(np.asarray(q, dtype=float))
    v2 = np.atleast_2d(np.asarray(v, dtype=float))
    ids = [robot.frame_id(c.tool_frame(robot)) for c in constraints]
    out = np.empty((q2.shape[0], len(constraints)))
    for k in range(q2.shape[0]):
        pin.forwardKinematics(model, data, q2[k], v2[k])
        for i, (c, fid) in enumerate(zip(constraints, ids, strict=True)):
            placement = pin.updateFramePlacement(model, data, fid)
            vel = pin.getFrameVelocity(model, data, fid, pin.LOCAL_WORLD_ALIGNED).linear
            out[k, i] = c.measure(placement.rotation, placement.translation, vel)
    return out


def check_boundary_tool(
    robot: RobotModel,
    constraints: Sequence[ToolConstraint],
    states: Sequence[tuple[str, Array, Array]],
) -> None:
    """Refuse a start or goal that breaks a tool constraint, before any solve.

    Parameters
    ----------
    robot : RobotModel
        The robot in angle coordinates.
    constraints : sequence of ToolConstraint
        The constraints.
    states : sequence of (str, ndarray, ndarray)
        ``("start", q, v)``, ``("goal", q, v)``.

    Raises
    ------
    ParameterError
        ``start: keep axis (gripper_tip) is 0.61 rad, above its limit 0.35 rad``;
        the error's ``name`` is the state, its ``value`` the measure.
    """
    for what, q, v in states:
        values = tool_measures(robot, constraints, q, v)[0]
        for c, value in zip(constraints, values, strict=True):
            if value > c.limit * (1.0 + 1e-9):
                raise ParameterError(
                    f"{what}: {c.label} ({c.tool_frame(robot)}) is {value:.4g} {c.unit}, above its "
                    f"limit {c.limit:.4g} {c.unit}; the motion must start and end inside every "
                    "tool constraint",
                    name=what,
                    value=float(value),
                )


def knot_tool(
    robot: RobotModel, constraints: Sequence[ToolConstraint], q: Array, v: Array
) -> list[tuple[float, int]]:
    """Return each constraint's largest measure over the knots and its knot index."""
    values = tool_measures(robot, constraints, q, v)
    return [(float(values[k, i]), int(k)) for i, k in enumerate(np.argmax(values, axis=0))]
