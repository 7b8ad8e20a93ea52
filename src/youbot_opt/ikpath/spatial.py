r"""The 3-D solve's result and the damped-least-squares baseline (issue 14).

:class:`SpatialIKResult` is what :func:`~youbot_opt.ikpath.spatial_solve.solve`
returns for a :class:`~youbot_opt.ikpath.problem.CyclicIKProblem` (per-target
position and orientation errors, checked by ``framesForwardKinematics``);
:func:`dls_ik` and :func:`greedy_path` are the common practice (each target by
DLS from the previous configuration), also used for witnesses and starts.
Formulation, conventions and the solvers' behaviour: docs/ikpath.md
("Spatial targets").
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike

from youbot_opt._typing import Array
from youbot_opt.ikpath.methods.al import ALOptions
from youbot_opt.ikpath.problem import CyclicIKProblem
from youbot_opt.ikpath.result import OuterIterate
from youbot_opt.nlp.status import SolveStatus

__all__ = [
    "SPATIAL_AL_OPTIONS",
    "SpatialIKResult",
    "dls_ik",
    "greedy_path",
    "random_theta",
]

SPATIAL_AL_OPTIONS = ALOptions(penalty_initial=1e3, newton_final=True, retry_least_squares=True)
"""Default AL settings of the spatial problem: ``mu_0 = 1e3`` (with ``mu_0 = 10`` the
motion term of a 6-joint arm with 2 pi limits outweighs the penalty and the first
inner solves leave the targets for good; measured on ur5, docs/ikpath.md) and the
safeguarded final SQP phase (``newton_final``: nearly singular pose Jacobians make
the first-order multiplier updates crawl) and, after a failed run, one retry with
least-squares initial multipliers (``retry_least_squares``)."""


# -- results ----------------------------------------------------------------------------
@dataclass(frozen=True, slots=True, kw_only=True, eq=False)
class SpatialIKResult:
    """Result of one spatial IK-path solve.

    Attributes
    ----------
    problem : CyclicIKProblem
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

    problem: CyclicIKProblem
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
    problem: CyclicIKProblem,
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
    problem: CyclicIKProblem,
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


def greedy_path(problem: CyclicIKProblem, theta0: ArrayLike | None = None) -> tuple[Array, bool]:
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


def random_theta(problem: CyclicIKProblem, rng: np.random.Generator) -> Array:
    """Joint angles uniform in the limits clipped to ``[-pi, pi]`` [rad] (shape (n,))."""
    lo = np.maximum(problem.lower[: problem.n_joints], -np.pi)
    hi = np.minimum(problem.upper[: problem.n_joints], np.pi)
    return rng.uniform(np.minimum(lo, hi), np.maximum(lo, hi))
