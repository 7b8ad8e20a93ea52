r"""Cyclic least-motion IK paths for any robot: 3-D targets, poses, joint limits.

:class:`SpatialIKProblem` (issue 14): a frame of a Pinocchio model visits
:class:`~youbot_opt.ikpath.targets.SpatialTarget` s in order and returns to the
first with the least joint motion ``1/2 sum_j dq_j^T W dq_j`` (cyclic), subject
to meeting every target and the joint limits; continuous joints are never
wrapped. Also the result type and the greedy damped-least-squares baseline.
Formulation, conventions and the solvers' behaviour: docs/ikpath.md
("Spatial targets").
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import cast

import numpy as np
import numpy.typing as npt
import pinocchio as pin
from numpy.typing import ArrayLike

from youbot_opt._typing import Array
from youbot_opt.exceptions import ParameterError
from youbot_opt.ikpath.augmented_lagrangian import ALOptions
from youbot_opt.ikpath.problem import Evaluation, path_configurations, require_within_limits
from youbot_opt.ikpath.result import OuterIterate
from youbot_opt.ikpath.targets import SpatialTarget
from youbot_opt.nlp.status import SolveStatus
from youbot_opt.robot.planar import Plane, motion_plane

__all__ = [
    "SPATIAL_AL_OPTIONS",
    "SpatialIKProblem",
    "SpatialIKResult",
    "dls_ik",
    "greedy_path",
    "random_theta",
]

_PIN_BIG = 1e10  # a URDF/Pinocchio limit beyond this is "no limit"

SPATIAL_AL_OPTIONS = ALOptions(penalty_initial=1e3, newton_final=True, retry_least_squares=True)
"""Default AL settings of the spatial problem: ``mu_0 = 1e3`` (with ``mu_0 = 10`` the
motion term of a 6-joint arm with 2 pi limits outweighs the penalty and the first
inner solves leave the targets for good; measured on ur5, docs/ikpath.md) and the
safeguarded final SQP phase (``newton_final``: nearly singular pose Jacobians make
the first-order multiplier updates crawl) and, after a failed run, one retry with
least-squares initial multipliers (``retry_least_squares``)."""


@dataclass(frozen=True, slots=True, kw_only=True, eq=False)
class SpatialIKProblem:
    """Minimum-motion cyclic joint path of a robot frame through spatial targets.

    Attributes
    ----------
    model : pinocchio.Model
        The robot (e.g. ``load_model("ur5").model``); its joints that move
        ``frame`` must be 1-DoF (revolute, continuous, prismatic).
    frame : str
        Name of the frame that visits the targets.
    targets : tuple of SpatialTarget
        Targets in visiting order (``s >= 2``).
    use_limits : bool
        Whether joint limits are constraints.
    q_lower, q_upper : ndarray, shape (n,), optional
        Joint limits of the active joints in [rad] (or [m]); default the
        model's (continuous joints: unlimited).
    joint_weights : ndarray, shape (n,), optional
        Diagonal ``W`` of the cost (default ones).
    plane : Plane or None
        The plane the frame moves in when the robot is planar for it
        (:func:`~youbot_opt.robot.planar.motion_plane`), else None. A planar
        robot's position rows are the 2 plane coordinates of the error
        (``plane.basis.T (p - p_j)``), not 3: the third is identically zero and
        would leave IPOPT more equations than unknowns. Its position targets
        must lie in the plane (within their ``position_tol``).
    """

    model: pin.Model
    frame: str
    targets: tuple[SpatialTarget, ...]
    use_limits: bool = True
    q_lower: Array | None = None
    q_upper: Array | None = None
    joint_weights: Array | None = None
    frame_id: int = field(init=False)
    active: Array = field(init=False)
    neutral: Array = field(init=False)
    continuous: Array = field(init=False)
    plane: Plane | None = field(init=False)

    def __post_init__(self) -> None:
        model = self.model
        if not isinstance(model, pin.Model):
            raise ParameterError(
                f"model must be a pinocchio.Model, got {type(model).__name__}",
                name="model",
                value=model,
            )
        if not model.existFrame(self.frame):
            names = ", ".join(f.name for f in model.frames)
            raise ParameterError(
                f"the model has no frame {self.frame!r}; frames: {names}",
                name="frame",
                value=self.frame,
            )
        fid = int(model.getFrameId(self.frame))
        targets = tuple(self.targets)
        if len(targets) < 2 or not all(isinstance(t, SpatialTarget) for t in targets):
            raise ParameterError(
                f"targets must be at least 2 SpatialTarget, got {len(targets)} items",
                name="targets",
                value=len(targets),
            )
        support = [j for j in model.supports[model.frames[fid].parentJoint] if j > 0]
        idx_v, cont = [], []
        for j in support:
            joint = model.joints[j]
            if joint.nv != 1 or joint.nq not in (1, 2):
                raise ParameterError(
                    f"joint {model.names[j]!r} ({joint.shortname()}) has nq = {joint.nq}, "
                    f"nv = {joint.nv}; the spatial IK path supports 1-DoF joints only "
                    "(revolute, continuous, prismatic)",
                    name="model",
                    value=model.names[j],
                )
            idx_v.append(joint.idx_v)
            cont.append(joint.nq == 2)
        if not idx_v:
            raise ParameterError(
                f"no joint moves frame {self.frame!r}", name="frame", value=self.frame
            )
        active = np.array([model.joints[j].idx_q for j in support])
        n = len(support)
        lo = np.array([model.lowerPositionLimit[i] for i in active])
        hi = np.array([model.upperPositionLimit[i] for i in active])
        cont_arr = np.array(cont)
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
        if plane is not None:
            for j, target in enumerate(targets):
                off = plane.distance(target.position)
                if off > target.position_tol:
                    raise ParameterError(
                        f"frame {self.frame!r} moves in the plane {plane.normal.tolist()} . p = "
                        f"{plane.offset:.6g} m (its joints turn about parallel axes); target "
                        f"{j} lies {off:.3g} m off it (position_tol {target.position_tol:.3g} m) "
                        "and cannot be reached",
                        name="targets",
                        value=j,
                    )
        for key, value in (
            ("targets", targets),
            ("use_limits", bool(self.use_limits)),
            ("joint_weights", weights),
            ("frame_id", fid),
            ("active", np.array(support)),
            ("neutral", neutral),
            ("continuous", cont_arr),
            ("plane", plane),
        ):
            object.__setattr__(self, key, value)

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

    def rows_of(self, target: SpatialTarget) -> int:
        """Constraint rows of ``target`` on this robot (position rows + orientation rows)."""
        return target.n_rows - 3 + self.position_rows

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

    def with_targets(self, targets: Sequence[SpatialTarget]) -> SpatialIKProblem:
        """Return the same robot, frame, limits and weights with other targets."""
        return SpatialIKProblem(
            model=self.model,
            frame=self.frame,
            targets=tuple(targets),
            use_limits=self.use_limits,
            q_lower=self.q_lower,
            q_upper=self.q_upper,
            joint_weights=self.joint_weights,
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
        approach rows ``w b_k^T R a`` with Jacobian ``-w b_k^T R [a]_x J_w``.
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
        if target.rotation is not None:
            r_err = target.rotation.T @ rot
            c[k : k + 3] = w * pin.log3(r_err)
            block[k : k + 3] = w * (pin.Jlog3(r_err) @ jac[3:])
        elif target.approach is not None:
            basis = target.approach_basis()
            a = target.approach_axis
            c[k : k + 2] = w * (basis @ (rot @ a))
            block[k : k + 2] = -w * (basis @ rot @ pin.skew(a) @ jac[3:])
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

    def evaluate(self, x: ArrayLike, data: pin.Data | None = None) -> Evaluation:
        """Objective, gradient, constraints and Jacobian blocks (s, m, n) at ``x``."""
        q = self.as_configurations(x)
        data = self.create_data() if data is None else data
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

    def constraints(self, x: ArrayLike, data: pin.Data | None = None) -> Array:
        """Constraint rows ``c(x)`` (m s,), padding included."""
        q = self.as_configurations(x)
        data = self.create_data() if data is None else data
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

    def check_start(self, x0: ArrayLike | None) -> Array:
        """Validate a start (``None``: :meth:`default_start`), shape (n s,).

        Raises
        ------
        ParameterError
            Wrong size, not finite, or outside the limits (names the entry).
        """
        if x0 is None:
            return self.default_start()
        x = self.as_configurations(x0, name="x0").ravel().copy()
        labels = [repr(name) for name in self.joint_names]
        require_within_limits(x, self.lower, self.upper, labels)
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


# -- results ----------------------------------------------------------------------------
@dataclass(frozen=True, slots=True, kw_only=True, eq=False)
class SpatialIKResult:
    """Result of one spatial IK-path solve.

    Attributes
    ----------
    problem : SpatialIKProblem
        The problem.
    method : str
        ``"al"`` or ``"ipopt"``.
    status : SolveStatus
        Outcome; a success means every target is met within its tolerances
        (checked with ``framesForwardKinematics``) and the limits hold.
    configurations : ndarray, shape (s, n)
        Active joint angles in [rad].
    objective : float
        ``E`` in [rad^2].
    position_errors, orientation_errors : ndarray, shape (s,)
        Per target, in [m] and [rad].
    limit_violation : float
        In [rad].
    multipliers : ndarray, shape (s, m)
        Constraint multipliers (``grad E = J^T lambda``).
    iterations : int
        Outer (AL) or IPOPT iterations.
    wall_time : float
        In [s].
    message : str
        Solver message (names the blocking target on failure).
    start : ndarray, shape (s, n)
        Start in [rad].
    history : tuple of OuterIterate
        Per-iteration records.
    """

    problem: SpatialIKProblem
    method: str
    status: SolveStatus
    configurations: Array
    objective: float
    position_errors: Array
    orientation_errors: Array
    limit_violation: float
    multipliers: Array
    iterations: int
    wall_time: float
    message: str
    start: Array
    history: tuple[OuterIterate, ...] = ()

    @property
    def success(self) -> bool:
        """Whether the status is a success."""
        return self.status.success

    def leg_motion(self) -> Array:
        """Joint motion per leg ``q_{j+1} - q_j`` (closing leg last), shape (s, n), [rad]."""
        q = self.configurations
        return np.roll(q, -1, axis=0) - q

    def frame_path(self, samples_per_leg: int = 20) -> Array:
        """Frame positions [m] along straight joint-space legs, shape (s * k + 1, 3)."""
        q = self.configurations
        closed = np.vstack([q, q[:1]])
        data = self.problem.create_data()
        pts = []
        for j in range(q.shape[0]):
            for t in np.linspace(0.0, 1.0, samples_per_leg, endpoint=False):
                theta = (1 - t) * closed[j] + t * closed[j + 1]
                pts.append(self.problem.placement(theta, data).translation)
        pts.append(self.problem.placement(closed[-1], data).translation)
        return np.array(pts)

    def summary(self) -> str:
        """Return a few human-readable lines."""
        return "\n".join(
            [
                f"method {self.method}: {self.status.value} ({self.message})",
                f"E = {self.objective:.10g} rad^2; largest position error "
                f"{np.max(self.position_errors):.3g} m, orientation error "
                f"{np.max(self.orientation_errors):.3g} rad; limit violation "
                f"{self.limit_violation:.3g} rad",
                f"{self.iterations} iterations, {self.wall_time * 1e3:.1f} ms",
            ]
        )

    def to_dict(self) -> dict[str, object]:
        """JSON-ready summary of the result."""
        return {
            "method": self.method,
            "status": self.status.value,
            "success": self.success,
            "message": self.message,
            "objective_rad2": self.objective,
            "configurations_rad": self.configurations.tolist(),
            "joint_names": list(self.problem.joint_names),
            "position_errors_m": self.position_errors.tolist(),
            "orientation_errors_rad": self.orientation_errors.tolist(),
            "limit_violation_rad": self.limit_violation,
            "iterations": self.iterations,
            "wall_time_s": self.wall_time,
            "frame": self.problem.frame,
            "targets": [t.to_dict() for t in self.problem.targets],
        }


def build_spatial_result(
    problem: SpatialIKProblem,
    *,
    method: str,
    status: SolveStatus,
    x: Array,
    multipliers: Array,
    iterations: int,
    wall_time: float,
    message: str,
    start: Array,
    history: tuple[OuterIterate, ...] = (),
) -> SpatialIKResult:
    """Assemble a result; a claimed success is re-checked by ``framesForwardKinematics``.

    Success needs every target within its tolerances and the limits to hold
    exactly (else the status becomes ``CONSTRAINT_VIOLATION``). On failure the
    message names the target that blocks the path (the largest relative miss).
    """
    q = problem.as_configurations(x)
    pos, ang = problem.errors(q)
    excess = problem.limit_violation(q)
    pt = np.array([t.position_tol for t in problem.targets])
    ot = np.array([t.orientation_tol for t in problem.targets])
    miss = np.maximum(pos / pt, ang / ot)
    worst = int(np.argmax(miss))
    if status.success and (miss[worst] > 1.0 or excess > 0.0):
        status = SolveStatus.CONSTRAINT_VIOLATION
        message = f"{message}; re-check failed"
    if not status.success:
        message = (
            f"{message}; blocking target {worst}: position error {pos[worst]:.3g} m "
            f"(tol {pt[worst]:.3g}), orientation error {ang[worst]:.3g} rad (tol {ot[worst]:.3g})"
        )
    return SpatialIKResult(
        problem=problem,
        method=method,
        status=status,
        configurations=q.copy(),
        objective=problem.objective(q),
        position_errors=pos,
        orientation_errors=ang,
        limit_violation=excess,
        multipliers=np.asarray(multipliers, float).reshape(problem.n_targets, -1),
        iterations=int(iterations),
        wall_time=float(wall_time),
        message=message,
        start=problem.as_configurations(start, name="start").copy(),
        history=history,
    )


# -- damped least squares (greedy baseline, witnesses, coherent starts) -------------------
def dls_ik(
    problem: SpatialIKProblem,
    j: int,
    theta0: ArrayLike,
    *,
    damping: float = 1e-2,
    max_iterations: int = 300,
    tol: float = 1e-12,
    data: pin.Data | None = None,
    restarts: int = 8,
) -> tuple[Array, bool]:
    """Solve target ``j`` alone from ``theta0`` by damped least squares (clipped to the limits).

    Levenberg-Marquardt steps ``dq = -J^T (J J^T + lambda^2 I)^{-1} c`` on the
    target's constraint rows, projected on the joint box; ``lambda`` starts at
    ``damping`` and is raised tenfold when a step does not reduce ``|c|``
    (lowered again after a success). If the target is not met, up to
    ``restarts`` seeds are tried (seeded by ``j``), alternately ``theta0 + N(0, 0.5 rad)``
    and uniform in the limits (clipped to ``[-pi, pi]``).
    Returns the angles and whether the target is met within its tolerances.
    """
    data = problem.create_data() if data is None else data
    lo = problem.lower[: problem.n_joints]
    hi = problem.upper[: problem.n_joints]
    theta = np.clip(np.array(theta0, dtype=float), lo, hi)
    target = problem.targets[j]
    c, jac = problem.block(j, theta, data)
    cost = float(c @ c)
    lam = float(damping)
    for _ in range(max_iterations):
        if cost <= tol**2 or lam > 1e6:
            break
        # J^T (J J^T + lam^2 I)^-1 c through the SVD of J: the same step, also where
        # J J^T is singular to working precision (more rows than the chain can move)
        u, sv, vt = np.linalg.svd(jac, full_matrices=False)
        trial = np.clip(theta - vt.T @ (sv / (sv**2 + lam**2) * (u.T @ c)), lo, hi)
        c_t, jac_t = problem.block(j, trial, data)
        cost_t = float(c_t @ c_t)
        if cost_t < cost:
            theta, c, jac, cost = trial, c_t, jac_t, cost_t
            lam = max(lam / 10.0, 1e-9)
        else:
            lam *= 10.0
    met = target.met(problem.placement(theta, data))
    if not met and restarts > 0:  # stuck (a singular or folded arm): perturbed seeds
        rng = np.random.default_rng(j)
        for k in range(restarts):
            if k % 2 == 0:  # near the start (keeps the path coherent)
                seed = np.clip(np.asarray(theta0, float) + rng.normal(0.0, 0.5, theta.size), lo, hi)
            else:  # anywhere in the limits (a start trapped against a limit)
                seed = random_theta(problem, rng)
            alt, ok = dls_ik(
                problem,
                j,
                seed,
                damping=damping,
                max_iterations=max_iterations,
                tol=tol,
                data=data,
                restarts=0,
            )
            if ok:
                return alt, True
    return theta, met


def greedy_path(problem: SpatialIKProblem, theta0: ArrayLike | None = None) -> tuple[Array, bool]:
    """Solve each target by DLS from the previous configuration (the common practice).

    The common practice: each target solved by DLS from the previous configuration.

    Returns the (s, n) configurations and whether every target was met.
    """
    data = problem.create_data()
    theta = (
        problem.default_start()[: problem.n_joints] if theta0 is None else np.asarray(theta0, float)
    )
    out, ok = [], True
    for j in range(problem.n_targets):
        theta, met = dls_ik(problem, j, theta, data=data)
        out.append(theta)
        ok = ok and met
    return np.array(out), ok


def random_theta(problem: SpatialIKProblem, rng: np.random.Generator) -> Array:
    """Joint angles uniform in the limits clipped to ``[-pi, pi]`` [rad] (shape (n,))."""
    lo = np.maximum(problem.lower[: problem.n_joints], -np.pi)
    hi = np.minimum(problem.upper[: problem.n_joints], np.pi)
    return rng.uniform(np.minimum(lo, hi), np.maximum(lo, hi))
