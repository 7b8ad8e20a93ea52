r"""The cyclic IK-path problem (study 2, spec ``ikpath.md``; any robot, issue 14).

A frame of a robot visits targets in order and returns to the first with the
least joint motion :math:`E = \tfrac12 \sum_j \Delta q_j^T W \Delta q_j`
(cyclic), meeting every target and the joint limits. :class:`CyclicIKProblem`
is a pure specification on a :class:`~youbot_opt.robot.model.RobotModel` or a
:class:`~youbot_opt.robot.planar.PlanarChain`: it evaluates E, the constraints
and their derivatives (from Pinocchio) but holds no solver state.

>>> chain = PlanarChain(lengths=[3, 2, 2])  # doctest: +SKIP
>>> problem = CyclicIKProblem(robot=chain, targets=[(-1, 5), (-3, 3), (3, 2)])  # doctest: +SKIP
"""

from __future__ import annotations

import hashlib
import math
import pickle
import threading
from collections import OrderedDict
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, NamedTuple, cast

import numpy as np
import numpy.typing as npt
import pinocchio as pin
from numpy.typing import ArrayLike

from youbot_opt._typing import Array
from youbot_opt.collision.clearance import Clearance
from youbot_opt.exceptions import ModelError, ParameterError
from youbot_opt.ikpath.clearance import (
    DEFAULT_LEG_SAMPLES,
    IKClearance,
    require_path_clearance,
)
from youbot_opt.ikpath.targets import Target
from youbot_opt.robot.model import RobotModel
from youbot_opt.robot.planar import PlanarChain, Plane, chain_from_robot, motion_plane

__all__ = [
    "CyclicIKProblem",
    "Evaluation",
    "path_configurations",
    "require_within_limits",
]


class Evaluation(NamedTuple):
    """Objective, constraints and their derivatives at one point.

    Attributes
    ----------
    objective : float
        ``E`` in [rad^2].
    gradient : ndarray, shape (s * n,)
        ``dE/dx`` in [rad].
    constraints : ndarray, shape (m * s,)
        ``c(x)`` stacked per target, in [m] (planar: ``F(q_j) - p_j``, ``m = 2``;
        3-D problems: ``m`` rows per target, see docs/ikpath.md).
    jacobian_blocks : ndarray, shape (s, m, n)
        ``dc_j/dq_j`` in [m/rad]; ``dc/dx`` is block diagonal with these blocks.
    """

    objective: float
    gradient: Array
    constraints: Array
    jacobian_blocks: Array


def require_within_limits(
    x: Array, lower: Array, upper: Array, joint_labels: list[str], unit: str = ""
) -> None:
    """Raise ParameterError naming the first entry of the start ``x`` outside its limits.

    Parameters
    ----------
    x : ndarray, shape (n s,)
        A start, configuration-major.
    lower, upper : ndarray, shape (n s,)
        The limits in [rad] (or [m] for prismatic joints).
    joint_labels : list of str
        How each of the ``n`` joints is named in the message.
    unit : str
        Unit appended to the quoted numbers (``" rad"`` or ``""``).
    """
    bad = np.flatnonzero((x < lower) | (x > upper))
    if bad.size:
        k = int(bad[0])
        j, i = divmod(k, len(joint_labels))
        raise ParameterError(
            f"the start x0 violates the joint limits: configuration {j}, joint "
            f"{joint_labels[i]} is {x[k]:.6g}{unit}, expected within "
            f"[{lower[k]:.6g}, {upper[k]:.6g}]{unit}",
            name="x0",
            value=x[k],
        )


def path_configurations(x: ArrayLike, n_targets: int, n_joints: int, name: str = "x") -> Array:
    """Return a path ``x`` (shape (n s,) or (s, n)) as a finite (s, n) array in [rad].

    Parameters
    ----------
    x : array_like, shape (n s,) or (s, n)
        Joint angles of the ``s`` path points in [rad].
    n_targets : int
        Number ``s`` of path points (targets).
    n_joints : int
        Number ``n`` of joints (active angles) per point.
    name : str, optional
        Name of ``x`` in error messages.

    Raises
    ------
    ParameterError
        If the size is not ``n s`` or an entry is not finite.
    """
    arr = np.array(x, dtype=float)
    if arr.size != n_targets * n_joints or arr.ndim not in (1, 2):
        raise ParameterError(
            f"{name} must have shape ({n_targets * n_joints},) or "
            f"({n_targets}, {n_joints}), got {arr.shape}",
            name=name,
            value=arr.shape,
        )
    if not np.all(np.isfinite(arr)):
        raise ParameterError(f"{name} must be finite", name=name, value=arr)
    return arr.reshape(n_targets, n_joints)


_PIN_BIG = 1e10  # a URDF/Pinocchio limit beyond this is "no limit"


@dataclass(frozen=True, slots=True, kw_only=True, eq=False)
class CyclicIKProblem:
    r"""Minimum-motion cyclic joint path of a robot frame through targets.

    .. math::

        \min_{Q} \; E(Q) = \tfrac12 \sum_{j=1}^{s} (q_{j+1} - q_j)^T W (q_{j+1} - q_j),
        \quad q_{s+1} \equiv q_1, \qquad
        \text{s.t. target } j \text{ met at } q_j,\; \ell \le q_j \le u.

    ``Q`` is the ``(s, n)`` array of the active joints' angles; solvers work on
    its row-major flattening ``x = Q.ravel()`` (``n s`` unknowns) and ``m``
    constraint rows per target (position 3, pose 6, approach 5; on a planar
    robot a position has 2 rows, its plane coordinates, and an orientation is
    one angle about the plane's normal: a pose 3 rows, an approach 3 or 2, see
    :meth:`orientation_basis`). Continuous joints are never wrapped.

    Attributes
    ----------
    robot : RobotModel or PlanarChain
        The robot (``load_model("ur5")``), or a planar chain of study 2 (its
        exact reachability verdicts, closed-form IPOPT kinematics and feasible
        starts are then used). A bare ``pinocchio.Model`` is wrapped
        (:meth:`RobotModel.from_pin_model`). Its joints that move ``frame`` must
        be 1-DoF (revolute, continuous, prismatic).
    robot_model : RobotModel
        The robot as a RobotModel (a chain's :meth:`PlanarChain.robot`).
    targets : tuple of Target
        Targets in visiting order (``s >= 2``). A position of 2 numbers is a
        planar robot's plane coordinates [m] (:attr:`plane`); it is stored as
        the world position. Bare points (2 or 3 numbers) are accepted as
        position targets.
    frame : str
        Frame that visits the targets (default: the robot's tip frame).
    use_limits : bool
        Whether joint limits are constraints.
    q_lower, q_upper : ndarray, shape (n,), optional
        Joint limits of the active joints in [rad] (or [m]); default the
        robot's (continuous joints: unlimited).
    joint_weights : ndarray, shape (n,), optional
        Diagonal ``W`` of the cost (default ones).
    clearance : Clearance or None
        Clearance the joint path keeps from a scene and from the robot itself
        (#28), at the targets' configurations and along the legs between them
        (straight lines in joint space, closing the cycle); the general IPOPT
        method holds it (:mod:`youbot_opt.ikpath.clearance`).
    leg_samples : int
        Interior samples ``K`` per leg of the clearance rows (``K + 1`` steps
        per leg; more: less conservative, more rows).
    clearance_rows : IKClearance or None
        The clearance rows built from :attr:`clearance` (None without).
    chain : PlanarChain or None
        The planar chain the problem was built on or, for a RobotModel that is
        planar for ``frame`` with position targets only, its chain
        (:func:`~youbot_opt.robot.planar.chain_from_robot`, with the problem's
        limits); None otherwise. The planar methods (exact reachability,
        closed-form IPOPT, feasible starts) need it.
    model : pinocchio.Model
        The robot's kinematic model.
    plane : Plane or None
        The plane the frame moves in when the robot is planar for it
        (:func:`~youbot_opt.robot.planar.motion_plane`), else None. A planar
        robot's position rows are the 2 plane coordinates of the error
        (``plane.basis.T (p - p_j)``), not 3: the third is identically zero and
        would leave IPOPT more equations than unknowns. Its position targets
        must lie in the plane (within their ``position_tol``).
    target_points : ndarray, shape (s, 2) or (s, 3)
        Target positions in [m]: plane coordinates on a planar robot, else world.
    neutral_rotation : ndarray, shape (3, 3)
        World rotation of the frame at :attr:`neutral`.
    """

    robot: RobotModel | PlanarChain
    targets: tuple[Target, ...]
    frame: str = ""
    use_limits: bool = True
    q_lower: Array | None = None
    q_upper: Array | None = None
    joint_weights: Array | None = None
    clearance: Clearance | None = None
    leg_samples: int = DEFAULT_LEG_SAMPLES
    robot_model: RobotModel = field(init=False)
    chain: PlanarChain | None = field(init=False)
    model: pin.Model = field(init=False)
    frame_id: int = field(init=False)
    active: Array = field(init=False)
    neutral: Array = field(init=False)
    continuous: Array = field(init=False)
    plane: Plane | None = field(init=False)
    target_points: Array = field(init=False)
    neutral_rotation: Array = field(init=False)
    clearance_rows: IKClearance | None = field(init=False, repr=False)
    _rows_key: str | None = field(init=False, repr=False, compare=False, default=None)

    def __post_init__(self) -> None:
        robot: object = self.robot
        chain = None
        if isinstance(robot, PlanarChain):
            chain, robot = robot, robot.robot()
        elif isinstance(robot, pin.Model):
            robot = RobotModel.from_pin_model(robot)
            object.__setattr__(self, "robot", robot)
        if not isinstance(robot, RobotModel):
            raise ParameterError(
                "robot must be a RobotModel (load_model(...)), a PlanarChain or a "
                f"pinocchio.Model, got {type(robot).__name__}",
                name="robot",
                value=type(robot).__name__,
            )
        model = robot.model
        frame = str(self.frame) if self.frame else robot.tip_frame
        if not model.existFrame(frame):
            names = ", ".join(f.name for f in model.frames)
            raise ParameterError(
                f"the model has no frame {frame!r}; frames: {names}",
                name="frame",
                value=frame,
            )
        fid = int(model.getFrameId(frame))
        support = [j for j in model.supports[model.frames[fid].parentJoint] if j > 0]
        idx_v, cont = [], []
        for j in support:
            joint = model.joints[j]
            if joint.nv != 1 or joint.nq not in (1, 2):
                raise ParameterError(
                    f"joint {model.names[j]!r} ({joint.shortname()}) has nq = {joint.nq}, "
                    f"nv = {joint.nv}; the cyclic IK path supports 1-DoF joints only "
                    "(revolute, continuous, prismatic)",
                    name="robot",
                    value=model.names[j],
                )
            idx_v.append(joint.idx_v)
            cont.append(joint.nq == 2)
        if not idx_v:
            raise ParameterError(f"no joint moves frame {frame!r}", name="frame", value=frame)
        active = np.array([model.joints[j].idx_q for j in support])
        n = len(support)
        cont_arr = np.array(cont)
        if chain is not None:
            lo, hi = np.array(chain.q_lower), np.array(chain.q_upper)
        else:
            lo = np.array([model.lowerPositionLimit[i] for i in active])
            hi = np.array([model.upperPositionLimit[i] for i in active])
            unlimited = cont_arr | (lo <= -_PIN_BIG) | (hi >= _PIN_BIG) | (lo >= hi)
            lo = np.where(unlimited, -np.inf, lo)
            hi = np.where(unlimited, np.inf, hi)
        for key, default in (("q_lower", lo), ("q_upper", hi)):
            value = getattr(self, key)
            arr = default if value is None else np.broadcast_to(np.array(value, float), (n,)).copy()
            if np.any(np.isnan(arr)):
                raise ParameterError(f"{key} must not be NaN", name=key, value=value)
            arr.setflags(write=False)
            object.__setattr__(self, key, arr)
        assert self.q_lower is not None and self.q_upper is not None
        if np.any(self.q_lower > self.q_upper):
            raise ParameterError(
                f"q_lower must be <= q_upper, got {self.q_lower} > {self.q_upper}",
                name="q_lower",
                value=self.q_lower,
            )
        weights = np.ones(n) if self.joint_weights is None else np.array(self.joint_weights, float)
        if weights.shape != (n,) or not np.all(np.isfinite(weights)) or np.any(weights <= 0):
            raise ParameterError(
                f"joint_weights must be {n} finite positive numbers, got {self.joint_weights!r}",
                name="joint_weights",
                value=self.joint_weights,
            )
        weights.setflags(write=False)
        neutral = pin.neutral(model)
        for j in range(1, model.njoints):  # joints off the frame's chain: clipped neutral
            joint = model.joints[j]
            if joint.nq == 1 and j not in support:
                i = joint.idx_q
                lo_i, hi_i = model.lowerPositionLimit[i], model.upperPositionLimit[i]
                if lo_i <= hi_i:
                    neutral[i] = min(max(neutral[i], lo_i), hi_i)
        plane = motion_plane(model, fid, neutral)
        targets, points = _check_targets(self.targets, plane, frame)
        if chain is not None and any(t.kind != "position" for t in targets):
            raise ParameterError(
                "a PlanarChain's targets are positions; load the chain as a RobotModel "
                "for pose or approach targets",
                name="targets",
                value=[t.kind for t in targets],
            )
        if chain is None and plane is not None and all(t.kind == "position" for t in targets):
            try:  # a planar RobotModel: its chain, for the exact planar methods
                chain = chain_from_robot(robot, frame).with_limits(self.q_lower, self.q_upper)
            except ModelError:
                chain = None
        for key, value in (
            ("robot_model", robot),
            ("frame", frame),
            ("targets", targets),
            ("use_limits", bool(self.use_limits)),
            ("joint_weights", weights),
            ("chain", chain),
            ("model", model),
            ("frame_id", fid),
            ("active", np.array(support)),
            ("neutral", neutral),
            ("continuous", cont_arr),
            ("plane", plane),
            ("target_points", points),
            ("neutral_rotation", _frame_rotation(model, fid, neutral)),
        ):
            object.__setattr__(self, key, value)
        object.__setattr__(self, "clearance_rows", self._build_clearance())
        require_path_clearance(self, None)  # a target point inside an obstacle

    def _build_clearance(self) -> IKClearance | None:
        """Check :attr:`clearance` and :attr:`leg_samples`; build the rows (None without)."""
        if self.clearance is None:
            return None
        if not isinstance(self.clearance, Clearance):
            raise ParameterError(
                f"clearance must be a Clearance or None, got {type(self.clearance).__name__}",
                name="clearance",
                value=type(self.clearance).__name__,
            )
        k = self.leg_samples
        if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or not 0 <= k <= 1000:
            raise ParameterError(
                f"leg_samples must be an integer in [0, 1000], got {k!r}",
                name="leg_samples",
                value=k,
            )
        object.__setattr__(self, "leg_samples", int(k))
        key: str | None = getattr(_REBUILDING, "key", None)
        if key is not None:
            cached = _BUILT_ROWS.get(key)
            if cached is not None:
                _BUILT_ROWS.move_to_end(key)
                object.__setattr__(self, "_rows_key", key)
                return cached
        rows = IKClearance.build(self, self.clearance, int(k))
        if key is not None:
            object.__setattr__(self, "_rows_key", key)
            _remember_rows(key, rows)
        return rows

    def _clearance_key(self, robot: RobotModel | PlanarChain) -> str | None:
        """Digest of what :meth:`IKClearance.build` reads (None without a clearance).

        The robot (its model and collision geometry, packed by its pickle), the
        frame, the clearance (scene, margin, self-collision), the leg samples and
        the targets' count: equal digests mean equal rows. Computed once per problem.
        """
        if self.clearance_rows is None:
            return None
        key = self._rows_key
        if key is None:
            made_of = (robot, self.frame, self.clearance, self.leg_samples, self.n_targets)
            key = hashlib.sha256(pickle.dumps(made_of, protocol=5)).hexdigest()
            object.__setattr__(self, "_rows_key", key)
            _remember_rows(key, self.clearance_rows)
        return key

    def __reduce__(self) -> tuple[Any, ...]:
        """Pickle by the defining fields, the robot's meshes left out or packed.

        The visual geometry never travels (RobotModel's pickle leaves it home);
        the collision geometry travels packed when a clearance needs it (the
        robot's pickle: its meshes as arrays, ur5's 9.9 MB as 0.14 MB), else
        not at all.
        """
        robot: RobotModel | PlanarChain
        if isinstance(self.robot, PlanarChain) or self.clearance is not None:
            robot = self.robot
        else:
            robot = self.robot_model.replace(collision_model=pin.GeometryModel())
        spec = {
            "robot": robot,
            "targets": self.targets,
            "frame": self.frame,
            "use_limits": self.use_limits,
            "q_lower": self.q_lower,
            "q_upper": self.q_upper,
            "joint_weights": self.joint_weights,
            "clearance": self.clearance,
            "leg_samples": self.leg_samples,
        }
        return (_rebuild_problem, (spec, self._clearance_key(robot)))

    @property
    def planar_chain(self) -> PlanarChain:
        """The :attr:`chain` the planar methods need (exact reachability, closed-form IPOPT).

        Raises
        ------
        ParameterError
            If the robot is not a planar chain for the frame (or has pose targets).
        """
        if self.chain is None:
            raise ParameterError(
                f"this needs a planar robot with position targets; robot "
                f"{self.robot_model.name!r} is not planar for frame {self.frame!r}",
                name="robot",
                value=self.robot_model.name,
            )
        return self.chain

    @property
    def visual_model(self) -> pin.GeometryModel:
        """The robot's visual geometry (for replay)."""
        return self.robot_model.visual_model

    # -- sizes and bounds ------------------------------------------------------------
    @property
    def n_targets(self) -> int:
        """Number of targets ``s``."""
        return len(self.targets)

    @property
    def n_joints(self) -> int:
        """Number of active joints ``n``."""
        return int(self.active.size)

    @property
    def n_variables(self) -> int:
        """Number of unknowns ``n s``."""
        return self.n_targets * self.n_joints

    @property
    def position_rows(self) -> int:
        """Rows of a position error: 2 on a planar robot (its plane coordinates), else 3."""
        return 3 if self.plane is None else 2

    def orientation_basis(self, target: Target) -> Array | None:
        """Directions the orientation error of ``target`` is measured along on a planar robot.

        A planar robot's frame turns about the plane's normal ``n`` only: its
        orientation is one angle, so a pose target constrains that angle (one
        row, the error ``log3(R_j^T R)`` along ``R_j^T n``) and an approach
        target's axis ``R a`` either keeps its direction (``a`` along the
        frame's ``R^T n``: no row, the target is met or missed whatever the
        angle) or turns in the plane (one row, ``R a`` along ``n x d``). The
        other rows would be constant (zero for a target the robot can meet).

        Returns
        -------
        ndarray, shape (k, 3), or None
            The ``k`` directions (``k`` = 1 or 0), or None: every row (a robot
            that is not planar, or a position target).
        """
        if self.plane is None or target.kind == "position":
            return None
        n = self.plane.normal
        if target.rotation is not None:
            return (target.rotation.T @ n)[None, :]
        axis = self.neutral_rotation @ target.approach_axis
        if np.linalg.norm(np.cross(n, axis)) <= 1e-12:
            return np.zeros((0, 3))
        across = np.cross(n, np.asarray(target.approach, dtype=float))
        size = float(np.linalg.norm(across))
        if size <= 1e-12:  # d along n while the axis turns in the plane: never met
            return self.plane.basis.T[:1]
        return (across / size)[None, :]

    def rows_of(self, target: Target) -> int:
        """Constraint rows of ``target`` on this robot (position rows + orientation rows)."""
        basis = self.orientation_basis(target)
        if basis is None:
            return target.n_rows - 3 + self.position_rows
        return self.position_rows + basis.shape[0]

    @property
    def block_rows(self) -> int:
        """Rows per constraint block ``m`` (largest target; others padded with zeros)."""
        return max(self.rows_of(t) for t in self.targets)

    @property
    def n_constraints(self) -> int:
        """Number of constraint rows ``m s`` (padding included)."""
        return self.block_rows * self.n_targets

    @property
    def joint_names(self) -> tuple[str, ...]:
        """Names of the active joints."""
        return tuple(self.model.names[int(j)] for j in self.active)

    @property
    def bounded(self) -> bool:
        """Whether finite joint limits are constraints of this problem."""
        assert self.q_lower is not None and self.q_upper is not None
        return self.use_limits and bool(
            np.any(np.isfinite(self.q_lower)) or np.any(np.isfinite(self.q_upper))
        )

    @property
    def lower(self) -> Array:
        """Lower bound on ``x`` [rad], shape (n s,); -inf where unlimited."""
        assert self.q_lower is not None
        if not self.use_limits:
            return np.full(self.n_variables, -np.inf)
        return np.tile(self.q_lower, self.n_targets)

    @property
    def upper(self) -> Array:
        """Upper bound on ``x`` [rad], shape (n s,); +inf where unlimited."""
        assert self.q_upper is not None
        if not self.use_limits:
            return np.full(self.n_variables, np.inf)
        return np.tile(self.q_upper, self.n_targets)

    def create_data(self) -> pin.Data:
        """Return a fresh ``pinocchio.Data``."""
        return self.model.createData()

    def with_targets(self, targets: Sequence[Target]) -> CyclicIKProblem:
        """Return the same robot, frame, limits and weights with other targets."""
        return CyclicIKProblem(
            robot=self.robot,
            frame=self.frame,
            targets=tuple(targets),
            use_limits=self.use_limits,
            q_lower=self.q_lower,
            q_upper=self.q_upper,
            joint_weights=self.joint_weights,
            clearance=self.clearance,
            leg_samples=self.leg_samples,
        )

    # -- kinematics -------------------------------------------------------------------
    def configuration(self, theta: ArrayLike) -> Array:
        """Pinocchio configuration (nq,) of active joint angles ``theta`` (n,) in [rad].

        A continuous joint's angle ``a`` becomes ``(cos a, sin a)``; other joints
        keep their (clipped) neutral value.
        """
        theta = np.asarray(theta, dtype=float)
        q = self.neutral.copy()
        for k, j in enumerate(self.active):
            i = self.model.joints[int(j)].idx_q
            if self.continuous[k]:
                q[i], q[i + 1] = math.cos(theta[k]), math.sin(theta[k])
            else:
                q[i] = theta[k]
        return q

    def placement(self, theta: ArrayLike, data: pin.Data | None = None) -> pin.SE3:
        """World placement of the frame at active angles ``theta``."""
        data = self.create_data() if data is None else data
        pin.framesForwardKinematics(self.model, data, self.configuration(theta))
        return data.oMf[self.frame_id].copy()

    def as_configurations(self, x: ArrayLike, name: str = "x") -> Array:
        """Return ``x`` as a finite (s, n) array in [rad] (:func:`path_configurations`)."""
        return path_configurations(x, self.n_targets, self.n_joints, name)

    def block(self, j: int, theta: Array, data: pin.Data) -> tuple[Array, Array]:
        """Constraint rows ``c_j`` (m,) and Jacobian (m, n) of target ``j`` at ``theta``.

        Position rows are ``p - p_j`` (Jacobian ``R J_v`` from the LOCAL frame
        Jacobian), on a planar robot ``B^T (p - p_j)`` with ``B = plane.basis``;
        pose rows ``w log3(R_j^T R)`` with Jacobian ``w Jlog3 J_w``;
        approach rows ``w b_k^T R a`` with Jacobian ``-w b_k^T R [a]_x J_w``; on a
        planar robot the orientation rows along :meth:`orientation_basis` only.
        """
        target = self.targets[j]
        m, n = self.block_rows, self.n_joints
        q = self.configuration(theta)
        pin.computeJointJacobians(self.model, data, q)  # also the joint placements
        pin.updateFramePlacement(self.model, data, self.frame_id)
        jac = pin.getFrameJacobian(self.model, data, self.frame_id, pin.LOCAL)
        jac = np.reshape(jac, (6, -1))[:, self.active_v]
        oMf = data.oMf[self.frame_id]
        rot = oMf.rotation
        c = np.zeros(m)
        block = np.zeros((m, n))
        if self.plane is None:
            c[:3] = oMf.translation - target.position
            block[:3] = rot @ jac[:3]
        else:
            axes = self.plane.basis.T
            c[:2] = axes @ (oMf.translation - target.position)
            block[:2] = axes @ (rot @ jac[:3])
        k = self.position_rows
        w = target.orientation_weight
        planar = self.orientation_basis(target)
        if target.rotation is not None:
            r_err = target.rotation.T @ rot
            if planar is None:
                c[k : k + 3] = w * pin.log3(r_err)
                block[k : k + 3] = w * (pin.Jlog3(r_err) @ jac[3:])
            else:  # one angle about the plane's normal
                c[k] = w * float(planar[0] @ pin.log3(r_err))
                block[k] = w * (planar[0] @ pin.Jlog3(r_err) @ jac[3:])
        elif target.approach is not None:
            basis = target.approach_basis() if planar is None else planar
            r = basis.shape[0]
            a = target.approach_axis
            c[k : k + r] = w * (basis @ (rot @ a))
            block[k : k + r] = -w * (basis @ rot @ pin.skew(a) @ jac[3:])
        return c, block

    @property
    def weights(self) -> Array:
        """Diagonal of ``W``, shape (n,)."""
        return cast(Array, self.joint_weights)

    @property
    def active_v(self) -> Array:
        """Velocity indices of the active joints."""
        return np.array([self.model.joints[int(j)].idx_v for j in self.active])

    @property
    def row_mask(self) -> npt.NDArray[np.bool_]:
        """Which of the ``m`` rows of each block are constraints (False: padding), (s, m)."""
        mask = np.zeros((self.n_targets, self.block_rows), dtype=bool)
        for j, target in enumerate(self.targets):
            mask[j, : self.rows_of(target)] = True
        return mask

    def lagrangian_hessian(
        self, x: ArrayLike, multipliers: ArrayLike, data: pin.Data | None = None
    ) -> Array:
        """Hessian of ``E - lambda^T c`` at ``x``, shape (n s, n s), in [rad^2/rad^2].

        ``d2E`` is exact (the cyclic difference matrix times ``W``); each target's
        ``sum_k lambda_jk d2c_jk`` is a central difference of the analytic Jacobian
        block (step 1e-5 rad: truncation ~1e-10 |c'''|, rounding ~1e-11 |J|; used
        only for Newton steps, whose convergence is checked on exact residuals).
        """
        q = self.as_configurations(x)
        lam = np.asarray(multipliers, dtype=float).reshape(self.n_targets, self.block_rows)
        data = self.create_data() if data is None else data
        s, n = q.shape
        w = np.diag(self.weights)
        hess = np.zeros((s * n, s * n))
        for j in range(s):  # leg j -> j + 1 (cyclic); s = 2 adds both legs to one pair
            a, b = slice(j * n, (j + 1) * n), slice(((j + 1) % s) * n, ((j + 1) % s + 1) * n)
            hess[a, a] += w
            hess[b, b] += w
            hess[a, b] -= w
            hess[b, a] -= w
        h = 1e-5
        for j in range(s):
            if not np.any(lam[j]):
                continue
            curv = np.empty((n, n))
            for i in range(n):
                step = np.zeros(n)
                step[i] = h
                plus = self.block(j, q[j] + step, data)[1]
                minus = self.block(j, q[j] - step, data)[1]
                curv[:, i] = lam[j] @ (plus - minus) / (2.0 * h)
            hess[j * n : (j + 1) * n, j * n : (j + 1) * n] -= 0.5 * (curv + curv.T)
        return hess

    def objective(self, x: ArrayLike) -> float:
        """``E = 1/2 sum_j dq_j^T W dq_j`` (cyclic), never wrapped, in [rad^2]."""
        q = self.as_configurations(x)
        d = np.roll(q, -1, axis=0) - q
        return 0.5 * float(np.sum(d * d * self.weights))

    def objective_gradient(self, x: ArrayLike) -> Array:
        """``dE/dx`` in [rad], shape (n s,): ``W (2 q_j - q_{j-1} - q_{j+1})`` per block."""
        q = self.as_configurations(x)
        return ((2.0 * q - np.roll(q, 1, axis=0) - np.roll(q, -1, axis=0)) * self.weights).ravel()

    def tip_positions(self, x: ArrayLike, data: pin.Data | None = None) -> Array:
        """Frame positions in [m] as the targets give them, shape (s, 2) or (s, 3).

        Plane coordinates on a planar robot (a chain's ``tip_position``), world
        coordinates otherwise; by Pinocchio forward kinematics.
        """
        q = self.as_configurations(x)
        data = self.create_data() if data is None else data
        if isinstance(self.robot, PlanarChain):
            return np.array([self.robot.tip_position(qj, data) for qj in q])
        pts = np.array([self.placement(qj, data).translation for qj in q])
        return pts if self.plane is None else pts @ self.plane.basis

    def residuals(self, x: ArrayLike, data: pin.Data | None = None) -> Array:
        """Per-target position miss ``|F(q_j) - p_j|`` in [m], shape (s,)."""
        return np.linalg.norm(self.tip_positions(x, data) - self.target_points, axis=1)

    def evaluate(self, x: ArrayLike, data: pin.Data | None = None) -> Evaluation:
        """Objective, gradient, constraints and Jacobian blocks (s, m, n) at ``x``."""
        q = self.as_configurations(x)
        data = self.create_data() if data is None else data
        if isinstance(self.robot, PlanarChain):
            return self._evaluate_chain(q, data)
        s = q.shape[0]
        c = np.empty((s, self.block_rows))
        blocks = np.empty((s, self.block_rows, self.n_joints))
        for j in range(s):
            c[j], blocks[j] = self.block(j, q[j], data)
        nxt = q[np.r_[1:s, 0]]
        prv = q[np.r_[s - 1, 0 : s - 1]]
        diff = nxt - q
        w = self.weights
        grad = ((2.0 * q - prv - nxt) * w).ravel()
        return Evaluation(0.5 * float(np.sum(diff * diff * w)), grad, c.ravel(), blocks)

    def _evaluate_chain(self, q: Array, data: pin.Data) -> Evaluation:
        """:meth:`evaluate` on a PlanarChain: 2 rows per target, world-aligned Jacobian."""
        chain = cast(PlanarChain, self.robot)
        s, n = q.shape
        c = np.empty((s, 2))
        blocks = np.empty((s, 2, n))
        model, fid = chain.model, chain.tip_frame_id
        frame = pin.LOCAL_WORLD_ALIGNED
        for j in range(s):  # hot loop: Pinocchio directly (q[j] is validated above)
            jac = pin.computeFrameJacobian(model, data, q[j], fid, frame)
            blocks[j] = np.reshape(jac, (6, n))[:2]  # a 1-joint model returns shape (6,)
            c[j] = data.oMf[fid].translation[:2] - self.target_points[j]
        nxt = q[np.r_[1:s, 0]]
        prv = q[np.r_[s - 1, 0 : s - 1]]
        diff = nxt - q
        grad = (2.0 * q - prv - nxt).ravel()
        return Evaluation(0.5 * float(np.sum(diff * diff)), grad, c.ravel(), blocks)

    def constraints(self, x: ArrayLike, data: pin.Data | None = None) -> Array:
        """Constraint rows ``c(x)`` (m s,), padding included."""
        q = self.as_configurations(x)
        data = self.create_data() if data is None else data
        if isinstance(self.robot, PlanarChain):
            return (self.tip_positions(q, data) - self.target_points).ravel()
        return np.concatenate([self.block(j, q[j], data)[0] for j in range(q.shape[0])])

    def errors(self, x: ArrayLike) -> tuple[Array, Array]:
        """Per-target position [m] and orientation [rad] errors by ``framesForwardKinematics``."""
        q = self.as_configurations(x)
        data = self.create_data()
        out = np.array([t.errors(self.placement(q[j], data)) for j, t in enumerate(self.targets)])
        return out[:, 0], out[:, 1]

    def targets_met(self, x: ArrayLike) -> npt.NDArray[np.bool_]:
        """Per-target bool: within its position and orientation tolerances."""
        pos, ang = self.errors(x)
        pt = np.array([t.position_tol for t in self.targets])
        ot = np.array([t.orientation_tol for t in self.targets])
        return (pos <= pt) & (ang <= ot)

    def limit_violation(self, x: ArrayLike) -> float:
        """Largest joint-limit violation in [rad] (0 within limits or unlimited)."""
        xv = self.as_configurations(x).ravel()
        return float(max(0.0, np.max(np.maximum(self.lower - xv, xv - self.upper))))

    def default_start(self) -> Array:
        """Return the zero vector clipped into the limits, shape (n s,)."""
        return np.clip(np.zeros(self.n_variables), self.lower, self.upper)

    def check_start(self, x0: ArrayLike | None, *, generated: bool = False) -> Array:
        """Validate a start (``None``: :meth:`default_start`), shape (n s,).

        A user's start (``generated=False``) with a configuration in collision
        is refused; the default start and the starts a multistart generates
        (``generated=True``) may collide (IPOPT accepts infeasible starts).

        Raises
        ------
        ParameterError
            Wrong size, not finite, outside the limits (names the entry), or a
            user's start in collision (with a clearance).
        """
        if x0 is None:
            return self.default_start()
        x = self.as_configurations(x0, name="x0").ravel().copy()
        if isinstance(self.robot, PlanarChain):
            labels, unit = [str(i) for i in range(self.n_joints)], " rad"
        else:
            labels, unit = [repr(name) for name in self.joint_names], ""
        require_within_limits(x, self.lower, self.upper, labels, unit=unit)
        if not generated:
            require_path_clearance(self, x)
        return x

    def reach_radius(self) -> tuple[Array, float]:
        """Centre [m] and radius [m] of a sphere that contains every frame position.

        The centre is the first active joint's origin (fixed: nothing moves
        it); the radius sums, along the chain, the distances between
        consecutive joint origins, the frame's offset and the largest travel
        of prismatic joints (triangle inequality; any joint angles).
        """
        data = self.create_data()
        pin.framesForwardKinematics(self.model, data, self.configuration(np.zeros(self.n_joints)))
        first = int(self.active[0])
        centre = data.oMi[first].translation.copy()
        radius = 0.0
        for j in self.active[1:]:
            radius += float(np.linalg.norm(self.model.jointPlacements[int(j)].translation))
        for k, j in enumerate(self.active):
            joint = self.model.joints[int(j)]
            if joint.shortname().startswith("JointModelP"):
                lo, hi = self.q_lower[k], self.q_upper[k]  # type: ignore[index]
                radius += float(max(abs(lo), abs(hi)))
        # Fixed joints between active ones are folded into jointPlacements; the frame's
        # offset from its parent joint closes the chain.
        radius += float(np.linalg.norm(self.model.frames[self.frame_id].placement.translation))
        return centre, radius


def _frame_rotation(model: pin.Model, frame_id: int, q: Array) -> Array:
    """World rotation (3, 3) of frame ``frame_id`` at configuration ``q``."""
    data = model.createData()
    pin.framesForwardKinematics(model, data, q)
    return np.array(data.oMf[frame_id].rotation)


def _check_targets(
    raw: Sequence[Target | ArrayLike] | ArrayLike, plane: Plane | None, frame: str
) -> tuple[tuple[Target, ...], Array]:
    """Targets (points become position targets) and their positions, validated.

    Raises
    ------
    ParameterError
        Fewer than 2 targets, a point of the wrong size or not finite, a
        2-number point on a robot that is not planar, a target off the plane.
    """
    items = list(raw) if isinstance(raw, (Sequence, np.ndarray)) else [raw]
    if isinstance(raw, np.ndarray) and raw.ndim == 1:
        items = [raw]
    targets: list[Target] = []
    points: list[Array] = []
    want = "(s, 3) (world)" if plane is None else "(s, 2) (plane coordinates) or (s, 3) (world)"
    for item in items:
        if isinstance(item, Target) and item.position.size == 3:
            targets.append(item)
            points.append(item.position if plane is None else item.position @ plane.basis)
            continue
        tol = item.position_tol if isinstance(item, Target) else None
        point = np.array(item.position if isinstance(item, Target) else item, dtype=float)
        if point.ndim != 1 or point.size not in (2, 3) or (point.size == 2 and plane is None):
            raise ParameterError(
                f"targets must be Target objects or points of shape {want} in [m], got "
                f"{np.asarray(raw, dtype=object).tolist()!r}",
                name="targets",
                value=raw,
            )
        if not np.all(np.isfinite(point)):
            raise ParameterError(
                f"target points must be finite, got {point.tolist()}", name="targets", value=point
            )
        if point.size == 2:
            assert plane is not None
            world = plane.basis @ point + plane.normal * plane.offset
            targets.append(
                Target(position=world) if tol is None else Target(position=world, position_tol=tol)
            )
            points.append(point)
        else:
            targets.append(Target(position=point))
            points.append(point if plane is None else point @ plane.basis)
    if len(targets) < 2:
        raise ParameterError(
            f"a cyclic path needs at least 2 targets, got {len(targets)}",
            name="targets",
            value=len(targets),
        )
    if plane is not None:
        for j, target in enumerate(targets):
            off = plane.distance(target.position)
            if off > target.position_tol:
                raise ParameterError(
                    f"frame {frame!r} moves in the plane {plane.normal.tolist()} . p = "
                    f"{plane.offset:.6g} m (its joints turn about parallel axes); target "
                    f"{j} lies {off:.3g} m off it (position_tol {target.position_tol:.3g} m) "
                    "and cannot be reached",
                    name="targets",
                    value=j,
                )
    out = np.array(points, dtype=float)
    out.setflags(write=False)
    return tuple(targets), out


_ROWS_KEPT = 8
"""Built clearance rows a process keeps (least recently used dropped first)."""

_BUILT_ROWS: OrderedDict[str, IKClearance] = OrderedDict()
"""Per process: clearance rows by :meth:`CyclicIKProblem._clearance_key`, so an
unpickled problem (a pool worker's start, a result sent back) reuses the rows
its process built for an equal problem instead of rebuilding them (~0.5 s)."""

_REBUILDING = threading.local()
"""The rows key of the problem :func:`_rebuild_problem` is unpickling, per thread (a
thread-pool executor may unpickle several problems at once)."""


def _remember_rows(key: str, rows: IKClearance | None) -> None:
    if rows is None:
        return
    _BUILT_ROWS[key] = rows
    _BUILT_ROWS.move_to_end(key)
    while len(_BUILT_ROWS) > _ROWS_KEPT:
        _BUILT_ROWS.popitem(last=False)


def _rebuild_problem(spec: dict[str, Any], rows_key: str | None = None) -> CyclicIKProblem:
    _REBUILDING.key = rows_key
    try:
        return CyclicIKProblem(**spec)
    finally:
        _REBUILDING.key = None
