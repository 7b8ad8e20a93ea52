"""The result of an IK-path solve: status, optimum, target errors, history, replay hooks.

A failed solve is a status, not an exception (Drake style): the result keeps
the best iterate the solver reached. Constructing a result does no work: the
solvers and the loader assemble it with :func:`build_result`, which runs the
re-check (:meth:`IKPathResult.check`) and sets the status (:func:`checked`).

>>> result = solve(problem).raise_for_status()  # doctest: +SKIP
>>> result.check().passed, result.joint_path(20).q.shape
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import NamedTuple

import numpy as np
import pinocchio as pin

from youbot_opt._typing import Array
from youbot_opt.collision.clearance import ClearanceCertificate
from youbot_opt.exceptions import ParameterError, SolveFailed
from youbot_opt.ikpath.clearance import certify_path_clearance
from youbot_opt.ikpath.problem import CyclicIKProblem
from youbot_opt.nlp.status import SolveStatus, apply_check

__all__ = [
    "SolveStatus",
    "OuterIterate",
    "IKPathResult",
    "IKResultCheck",
    "JointPath",
    "build_result",
    "checked",
]


class OuterIterate(NamedTuple):
    """One outer iteration of a solver, kept for convergence plots.

    Attributes
    ----------
    iteration : int
        0-based outer iteration index.
    x : ndarray, shape (s, n)
        Configurations in [rad] after this iteration.
    objective : float
        ``E`` in [rad^2].
    violation : float
        Largest constraint violation in [m] (inf-norm of ``c``; the augmented
        Lagrangian with clearance rows ``g >= 0``: also ``|min(g, nu / mu)|``).
    stationarity : float
        Inf-norm of the (projected) gradient of the Lagrangian used by the solver.
    penalty : float
        Penalty parameter ``mu`` (augmented Lagrangian) or barrier ``mu`` (IPOPT).
    inner_iterations : int
        Inner (BFGS / L-BFGS-B) iterations spent in this outer iteration (0 for IPOPT).
    """

    iteration: int
    x: Array
    objective: float
    violation: float
    stationarity: float
    penalty: float
    inner_iterations: int


class IKResultCheck(NamedTuple):
    """Verdict of :meth:`IKPathResult.check`: the status a result deserves and why.

    Attributes
    ----------
    status : SolveStatus
        The result's status, downgraded (to :attr:`SolveStatus.NON_FINITE` or
        :attr:`SolveStatus.CONSTRAINT_VIOLATION`) when a claimed success fails.
    message : str
        What failed (empty if nothing did).
    """

    status: SolveStatus
    message: str

    @property
    def passed(self) -> bool:
        """Whether :attr:`status` is a success."""
        return self.status.success


class JointPath(NamedTuple):
    """A sampled joint-space path.

    Attributes
    ----------
    s : ndarray, shape (N,)
        Path parameter: target ``j`` is at ``s = j`` (0-based); ``s = n_targets``
        closes the cycle back at target 0.
    q : ndarray, shape (N, n)
        Joint angles in [rad].
    """

    s: Array
    q: Array


@dataclass(frozen=True, slots=True, kw_only=True, eq=False)
class IKPathResult:
    """Result of one IK-path solve, on any robot (planar or 3-D).

    Attributes
    ----------
    problem : CyclicIKProblem
        The problem solved.
    method : str
        ``"al"`` (augmented Lagrangian) or ``"ipopt"``.
    status : SolveStatus
        Outcome.
    configurations : ndarray, shape (s, n)
        Final (or best) configurations in [rad].
    objective : float
        ``E`` at :attr:`configurations` in [rad^2], recomputed by the problem.
    position_errors : ndarray, shape (s,)
        Per target ``|F(q_j) - p_j|`` in [m], recomputed with Pinocchio.
    orientation_errors : ndarray, shape (s,)
        Per target orientation (or approach-axis) error in [rad] (zero for a
        position target, so always zero on a planar chain's targets).
    limit_violation : float
        Largest joint-limit violation in [rad] (0 if none or no limits).
    multipliers : ndarray, shape (s, m)
        Multipliers ``lambda`` of the target constraints with the sign convention
        ``grad E = sum_j J_j^T lambda_j`` at a KKT point without active bounds
        (i.e. the Lagrangian is ``E - lambda . c``); ``m = 2`` on a planar chain.
    iterations : int
        Outer iterations (augmented Lagrangian) or IPOPT iterations.
    inner_iterations : int
        Total inner iterations (0 for IPOPT).
    wall_time : float
        Solve time in [s].
    message : str
        Solver message (on a failure of a 3-D solve it names the blocking target).
    start : ndarray, shape (s, n)
        Initial guess in [rad].
    constraint_tol : float or None
        Largest ``|c_i|`` in [m] the planar methods accept at a solution
        (``ALOptions.constraint_tol`` or ``IpoptOptions.constr_viol_tol``): the
        check then allows ``sqrt(2) * constraint_tol`` per position error. None
        (the general methods): every target must be met within its own
        ``position_tol`` and ``orientation_tol``.
    history : tuple of OuterIterate
        Per outer iteration record (may be empty).
    clearance : ClearanceCertificate or None
        coal's certificate of the closed joint path at the problem's margin
        (:func:`~youbot_opt.ikpath.clearance.certify_path_clearance`), computed
        by :func:`build_result` (so by every solve and on loading); a claimed
        success whose path it does not certify is downgraded. None without a
        clearance (or without pairs).
    clearance_multipliers : ndarray, shape (n_rows,), or None
        Multipliers ``nu >= 0`` of the clearance rows ``g = rows(x) - margin >= 0``
        (:class:`~youbot_opt.ikpath.clearance.IKClearance`, same order) in
        [rad^2/m]: the sensitivity of E to the margin of each row, ``dE/d margin_i``
        at a KKT point (sign convention ``grad E = J^T lambda + J_g^T nu``); zero
        on an inactive row. None without a clearance (or from a method that gives none).

    Notes
    -----
    Construction only converts the arrays (read-only) and validates
    ``constraint_tol``; it runs no check, also not after
    ``dataclasses.replace``. The solvers and :func:`~youbot_opt.ikpath.io.load_result`
    build results with :func:`build_result`, which re-checks a claimed success
    (:meth:`check`) and downgrades it (:func:`checked`); a downgraded result
    says why in :attr:`message`. Pass a hand-made or replaced result through
    :func:`checked` to give it the status it deserves.
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
    inner_iterations: int = 0
    wall_time: float
    message: str
    start: Array
    constraint_tol: float | None = None
    history: tuple[OuterIterate, ...] = field(default=())
    clearance: ClearanceCertificate | None = None
    clearance_multipliers: Array | None = None

    def __post_init__(self) -> None:
        for key in (
            "configurations",
            "position_errors",
            "orientation_errors",
            "multipliers",
            "start",
        ):
            arr = np.array(getattr(self, key), dtype=float)
            arr.setflags(write=False)
            object.__setattr__(self, key, arr)
        if self.clearance_multipliers is not None:
            nu = np.array(self.clearance_multipliers, dtype=float).ravel()
            nu.setflags(write=False)
            object.__setattr__(self, "clearance_multipliers", nu)
        tol = self.constraint_tol
        if tol is not None and not (tol > 0.0 and math.isfinite(tol)):
            raise ParameterError(
                f"constraint_tol must be None or finite and > 0 [m], got {tol!r}",
                name="constraint_tol",
                value=tol,
            )

    def check(self) -> IKResultCheck:
        """Re-check the result independently of the solver's flag.

        Every number must be finite (else :attr:`SolveStatus.NON_FINITE`),
        every target error recomputed by Pinocchio from :attr:`configurations`
        must be within ``sqrt(2) * constraint_tol`` plus rounding (or, with no
        ``constraint_tol``, within the target's tolerances), the joint limits
        must hold exactly, and the reported ``objective``, target errors and
        ``limit_violation`` must be those of the configurations (else
        :attr:`SolveStatus.CONSTRAINT_VIOLATION`). A failure keeps its status
        (the check only downgrades a success). The result itself is not changed.

        Returns
        -------
        IKResultCheck
            The status the result deserves and what failed.
        """
        verdict = _recheck(self)
        if verdict is None:
            return IKResultCheck(self.status, "")
        status, why = verdict
        return IKResultCheck(status if self.status.success else self.status, why)

    @property
    def success(self) -> bool:
        """Whether :attr:`status` is a success (:attr:`SolveStatus.success`)."""
        return self.status.success

    @property
    def E(self) -> float:  # noqa: N802 - the study's symbol
        """Alias of :attr:`objective` (the study's symbol), in [rad^2]."""
        return self.objective

    @property
    def model(self) -> pin.Model:
        """Pinocchio model of the robot (for replay)."""
        return self.problem.model

    @property
    def visual_model(self) -> pin.GeometryModel:
        """Visual model of the robot (for replay)."""
        return self.problem.visual_model

    def max_position_error(self) -> float:
        """Largest target position error in [m]."""
        return float(np.max(self.position_errors))

    def max_orientation_error(self) -> float:
        """Largest target orientation error in [rad]."""
        return float(np.max(self.orientation_errors))

    def raise_for_status(self) -> IKPathResult:
        """Return ``self`` if successful, else raise :class:`SolveFailed` carrying it."""
        if not self.success:
            raise SolveFailed(
                f"IK-path solve ({self.method}) ended with status {self.status.value}: "
                f"{self.message}; E = {self.objective:.6g}, largest position error "
                f"{self.max_position_error():.3g} m, limit violation "
                f"{self.limit_violation:.3g} rad",
                result=self,
            )
        return self

    def tip_positions(self) -> Array:
        """Tip positions in [m] of :attr:`configurations`, shape (s, 2), by Pinocchio."""
        return self.problem.tip_positions(self.configurations)

    def joint_path(self, samples_per_segment: int = 20) -> JointPath:
        """Joint-space path through the configurations, closed back to the first.

        Consecutive configurations are joined by straight lines in joint space
        (the motion whose squared length ``E`` sums).

        Parameters
        ----------
        samples_per_segment : int
            Samples per segment (>= 1); the end point of the cycle is included.

        Returns
        -------
        JointPath
            ``s`` of shape (s_targets * samples_per_segment + 1,) and ``q`` of
            shape (N, n) in [rad]; ``q[k * samples_per_segment]`` is configuration
            ``k`` and the last row equals the first.

        Raises
        ------
        ParameterError
            If ``samples_per_segment < 1``.
        """
        m = int(samples_per_segment)
        if m < 1 or m != samples_per_segment:
            raise ParameterError(
                f"samples_per_segment must be an integer >= 1, got {samples_per_segment!r}",
                name="samples_per_segment",
                value=samples_per_segment,
            )
        q = self.configurations
        closed = np.vstack([q, q[:1]])
        s_knots = np.arange(closed.shape[0], dtype=float)
        s = np.linspace(0.0, float(q.shape[0]), q.shape[0] * m + 1)
        path = np.column_stack([np.interp(s, s_knots, closed[:, i]) for i in range(q.shape[1])])
        return JointPath(s, path)

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
        """Return a few human-readable lines describing the result."""
        if self.constraint_tol is not None:
            errors = f"largest position error {self.max_position_error():.3g} m"
        else:
            errors = (
                f"largest position error {self.max_position_error():.3g} m, orientation "
                f"error {self.max_orientation_error():.3g} rad"
            )
        lines = [
            f"method {self.method}: {self.status.value} ({self.message})",
            f"E = {self.objective:.10g} rad^2, {errors}, "
            f"limit violation {self.limit_violation:.3g} rad",
            f"{self.iterations} iterations ({self.inner_iterations} inner), "
            f"{self.wall_time * 1e3:.1f} ms",
        ]
        return "\n".join(lines)

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


def _target_errors(problem: CyclicIKProblem, q: Array, planar: bool) -> tuple[Array, Array]:
    """Position [m] and orientation [rad] errors per target, by Pinocchio.

    ``planar``: the chain's tip against the targets' points (orientation zero);
    otherwise every target's own errors (``framesForwardKinematics``).
    """
    if planar:
        return problem.residuals(q), np.zeros(problem.n_targets)
    return problem.errors(q)


def _recheck(result: IKPathResult) -> tuple[SolveStatus, str] | None:
    """Status a claimed success deserves, with the reason, or None if it holds.

    Recomputes the target errors (Pinocchio), E and the limit violation from the
    configurations; see the Notes of :class:`IKPathResult`.
    """
    problem = result.problem
    q = result.configurations
    figures: dict[str, Array | float] = {
        "configurations": q,
        "objective": result.objective,
        "position_errors": result.position_errors,
        "orientation_errors": result.orientation_errors,
        "limit_violation": result.limit_violation,
        "multipliers": result.multipliers,
    }
    if result.clearance_multipliers is not None:
        figures["clearance_multipliers"] = result.clearance_multipliers
    nonfinite = [k for k, v in figures.items() if not np.all(np.isfinite(v))]
    if nonfinite:
        return SolveStatus.NON_FINITE, f"non-finite values in {', '.join(nonfinite)}"
    want = (problem.n_targets, problem.n_joints)
    shapes = (result.position_errors.shape, result.orientation_errors.shape)
    if q.shape != want or shapes != ((want[0],), (want[0],)):
        return SolveStatus.CONSTRAINT_VIOLATION, (
            f"configurations of shape {q.shape} and target errors of shapes "
            f"{shapes[0]}, {shapes[1]}, expected {want} and ({want[0]},)"
        )
    tol = result.constraint_tol
    pos, ang = _target_errors(problem, q, tol is not None)
    energy = problem.objective(q)
    excess = problem.limit_violation(q)
    wrong = []
    if tol is not None:
        chain = problem.planar_chain
        # Rounding of the tip position [m]: Pinocchio vs the solver's own kinematics
        # (the same Pinocchio calls for AL, CasADi's closed form for IPOPT) differ by
        # a few ulps of the largest coordinate; 1e-12 per metre of reach covers it.
        scale = 1.0 + float(np.sum(chain.lengths)) + float(np.max(np.abs(chain.base)))
        allowed = math.sqrt(2.0) * tol + 1e-12 * scale  # |c_j|_2 <= sqrt(2) |c|_inf
        worst = int(np.argmax(pos))
        if pos[worst] > allowed:
            wrong.append(
                f"target {worst} missed by {pos[worst]:.3g} m > {allowed:.3g} m "
                f"(sqrt(2) * constraint_tol {tol:.3g} m + rounding)"
            )
    else:
        pt = np.array([t.position_tol for t in problem.targets])
        ot = np.array([t.orientation_tol for t in problem.targets])
        miss = np.maximum(pos / pt, ang / ot)
        worst = int(np.argmax(miss))
        if miss[worst] > 1.0:
            wrong.append(
                f"target {worst} missed: position error {pos[worst]:.3g} m (tol "
                f"{pt[worst]:.3g}), orientation error {ang[worst]:.3g} rad (tol {ot[worst]:.3g})"
            )
    if excess > 0.0:
        wrong.append(f"joint limits violated by {excess:.3g} rad")
    nu = result.clearance_multipliers
    if nu is not None and np.any(nu < 0.0):
        wrong.append(f"clearance multipliers negative (down to {float(np.min(nu)):.3g} rad^2/m)")
    cert = result.clearance
    if cert is not None and not cert.certified:
        a, b = cert.closest_pair
        wrong.append(
            f"path closer than the clearance margin {cert.margin:g} m (coal): {a} / {b} at "
            f"{cert.closest_distance:.4g} m, leg {int(cert.closest_time)}"
        )
    # Reported figures against the recomputed ones: build_result computes them
    # with these very calls, so only a changed field makes them differ; 1e-9
    # (in [rad^2] relative, in [m] and [rad]) is the tolerance of the result files.
    if not abs(result.objective - energy) <= 1e-9 * max(1.0, abs(energy)):
        wrong.append(f"reported E = {result.objective:.12g} rad^2, recomputed {energy:.12g}")
    if not (
        np.all(np.abs(result.position_errors - pos) <= 1e-9)
        and np.all(np.abs(result.orientation_errors - ang) <= 1e-9)
    ):
        wrong.append("reported target errors differ from the recomputed ones by more than 1e-9")
    if not abs(result.limit_violation - excess) <= 1e-9:
        wrong.append(
            f"reported limit violation {result.limit_violation:.3g} rad, recomputed {excess:.3g}"
        )
    return (SolveStatus.CONSTRAINT_VIOLATION, "; ".join(wrong)) if wrong else None


def checked(result: IKPathResult) -> IKPathResult:
    """Return ``result`` with the status its :meth:`~IKPathResult.check` gives it.

    A refuted success is downgraded, with ``"; re-check failed: <why>"``
    appended to its message (:func:`~youbot_opt.nlp.status.apply_check`).

    Parameters
    ----------
    result : IKPathResult
        A result as assembled by a solver or read from a file.

    Returns
    -------
    IKPathResult
        ``result`` itself, or a copy with the downgraded status and message.
    """
    return apply_check(result, label="re-check failed: ")


def build_result(
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
    inner_iterations: int = 0,
    constraint_tol: float | None = None,
    history: tuple[OuterIterate, ...] = (),
    clearance_multipliers: Array | None = None,
) -> IKPathResult:
    """Assemble an :class:`IKPathResult`, recomputing E, target errors and limit violation.

    With a clearance, coal certifies the closed path at the problem's margin
    (:attr:`IKPathResult.clearance`). The target errors come from Pinocchio
    through the problem, independently of the solver's own constraint
    evaluation (CasADi for IPOPT). ``constraint_tol``
    [m] is the planar methods' largest accepted ``|c_i|`` (None: the targets'
    own tolerances decide); a claimed success is re-checked against it and
    downgraded if it fails (:func:`checked`). ``clearance_multipliers`` [rad^2/m]
    are kept only when the problem has clearance rows. A failed solve without
    ``constraint_tol`` names its blocking target (the largest relative miss)
    in the message.
    """
    q = problem.as_configurations(x)
    pos, ang = _target_errors(problem, q, constraint_tol is not None)
    # coal's certificate of the closed path (~10 ms on ur5 and a box, against
    # seconds of a solve): every result carries it, not only a multistart's best.
    certificate = None if problem.clearance_rows is None else certify_path_clearance(problem, q)
    result = checked(
        IKPathResult(
            problem=problem,
            method=method,
            status=status,
            configurations=q,
            objective=problem.objective(q),
            position_errors=pos,
            orientation_errors=ang,
            limit_violation=problem.limit_violation(q),
            multipliers=np.asarray(multipliers, dtype=float).reshape(problem.n_targets, -1),
            iterations=int(iterations),
            inner_iterations=int(inner_iterations),
            wall_time=float(wall_time),
            message=message,
            start=problem.as_configurations(start, name="start"),
            constraint_tol=None if constraint_tol is None else float(constraint_tol),
            history=history,
            clearance=certificate,
            clearance_multipliers=(
                None
                if problem.clearance_rows is None or clearance_multipliers is None
                else np.asarray(clearance_multipliers, dtype=float)
            ),
        )
    )
    if constraint_tol is None and not result.success:
        pt = np.array([t.position_tol for t in problem.targets])
        ot = np.array([t.orientation_tol for t in problem.targets])
        worst = int(np.argmax(np.maximum(pos / pt, ang / ot)))
        blocking = (
            f"; blocking target {worst}: position error {pos[worst]:.3g} m "
            f"(tol {pt[worst]:.3g}), orientation error {ang[worst]:.3g} rad (tol {ot[worst]:.3g})"
        )
        result = replace(result, message=result.message + blocking)
    return result
