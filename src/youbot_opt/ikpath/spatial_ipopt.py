"""The spatial cyclic IK path by CasADi + IPOPT with exact derivatives.

The frame's forward kinematics is written symbolically from the Pinocchio
model (joint placements, joint axes, frame placement), so IPOPT gets exact
first and second derivatives; tests check it against Pinocchio's
``framesForwardKinematics``. Orientation rows are ``vex(R_e - R_e^T) / 2``
with ``R_e = R_j^T R`` (same value and Jacobian as ``log3`` at the solution,
hence the same KKT points and multipliers as the augmented Lagrangian), with
``trace(R_e) >= -1/2`` (error below 139 deg) to exclude the spurious ``R_e``
symmetric solutions; approach rows likewise exclude the reversed axis.
"""

from __future__ import annotations

import time

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike

from youbot_opt._typing import Array
from youbot_opt.exceptions import ParameterError
from youbot_opt.ikpath.ipopt import BOUND_SETTINGS
from youbot_opt.ikpath.problem import CyclicIKProblem
from youbot_opt.ikpath.spatial import SpatialIKResult, build_spatial_result
from youbot_opt.nlp.ipopt import IpoptOptions, single_threaded_blas
from youbot_opt.nlp.status import IPOPT_STATUS, SolveStatus, status_from_ipopt

__all__ = ["SpatialIpoptSolver", "frame_expression", "solve_spatial_ipopt"]

_AXES = {"X": (1.0, 0.0, 0.0), "Y": (0.0, 1.0, 0.0), "Z": (0.0, 0.0, 1.0)}


def _joint_axis(problem: CyclicIKProblem, j: int) -> tuple[str, Array]:
    """``("R" | "P", unit axis)`` of active joint ``j`` from its Pinocchio type."""
    joint = problem.model.joints[j]
    name = joint.shortname().removeprefix("JointModel")
    if name in ("RevoluteUnaligned", "RevoluteUnboundedUnaligned", "PrismaticUnaligned"):
        axis = np.asarray(joint.extract().axis, dtype=float)
        return ("P" if name.startswith("P") else "R"), axis / np.linalg.norm(axis)
    if name[-1] in _AXES and name[:-1] in ("R", "RUB", "P"):
        return ("P" if name[0] == "P" else "R"), np.array(_AXES[name[-1]])
    raise ParameterError(
        f"joint {problem.model.names[j]!r} of type {joint.shortname()} is not supported by "
        "the symbolic kinematics",
        name="model",
        value=joint.shortname(),
    )


def frame_expression(problem: CyclicIKProblem, theta: ca.SX) -> tuple[ca.SX, ca.SX]:
    """Symbolic world position (3,) and rotation (3, 3) of the frame at angles ``theta``."""
    rot = ca.SX.eye(3)
    pos = ca.SX.zeros(3)
    for k, j in enumerate(problem.active):
        placement = problem.model.jointPlacements[int(j)]
        pos = pos + rot @ ca.DM(placement.translation)
        rot = rot @ ca.DM(placement.rotation)
        kind, axis = _joint_axis(problem, int(j))
        if kind == "P":
            pos = pos + rot @ ca.DM(axis) * theta[k]
        else:
            skew = ca.DM([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
            rot = rot @ (
                ca.DM.eye(3) + ca.sin(theta[k]) * skew + (1 - ca.cos(theta[k])) * (skew @ skew)
            )
    frame = problem.model.frames[problem.frame_id].placement
    return pos + rot @ ca.DM(frame.translation), rot @ ca.DM(frame.rotation)


class SpatialIpoptSolver:
    """IPOPT solver of one spatial problem, built once and re-solved from many starts.

    Parameters
    ----------
    problem : CyclicIKProblem
        The problem.
    options : IpoptOptions, optional
        Default :meth:`IpoptOptions.for_ikpath` (tol 1e-12, constr_viol_tol 1e-11).
    """

    def __init__(self, problem: CyclicIKProblem, options: IpoptOptions | None = None) -> None:
        self.problem = problem
        self.options = IpoptOptions.for_ikpath() if options is None else options
        s, n = problem.n_targets, problem.n_joints
        x = ca.SX.sym("x", s * n)
        configs = [x[j * n : (j + 1) * n] for j in range(s)]
        w = ca.DM(problem.weights)
        energy = ca.SX(0)
        for j in range(s):
            d = configs[(j + 1) % s] - configs[j]
            energy = energy + 0.5 * ca.dot(d * w, d)
        eqs, ineqs, self._rows = [], [], []
        for j, target in enumerate(problem.targets):
            pos, rot = frame_expression(problem, configs[j])
            if problem.plane is None:
                eqs.append(pos - ca.DM(target.position))
            else:  # a planar robot: the 2 plane coordinates (the third row is identically 0)
                eqs.append(ca.DM(problem.plane.basis.T) @ (pos - ca.DM(target.position)))
            k = problem.position_rows
            rows = list(range(k))
            wt = target.orientation_weight
            if target.rotation is not None:
                r_e = ca.DM(target.rotation).T @ rot
                vex = ca.vertcat(
                    r_e[2, 1] - r_e[1, 2], r_e[0, 2] - r_e[2, 0], r_e[1, 0] - r_e[0, 1]
                )
                eqs.append(wt * 0.5 * vex)
                ineqs.append(ca.trace(r_e) + 0.5)
                rows += [k, k + 1, k + 2]
            elif target.approach is not None:
                axis = rot @ ca.DM(target.approach_axis)
                eqs.append(wt * (ca.DM(target.approach_basis()) @ axis))
                ineqs.append(ca.dot(ca.DM(target.approach), axis))
                rows += [k, k + 1]
            self._rows.append(rows)
        self._n_eq = int(sum(e.shape[0] for e in eqs))
        g = ca.vertcat(*eqs, *ineqs)
        self._lbg = np.zeros(g.shape[0])
        self._ubg = np.r_[np.zeros(self._n_eq), np.full(len(ineqs), np.inf)]
        opts = self.options.to_casadi(True, solver_settings=BOUND_SETTINGS)
        single_threaded_blas()
        self._solver = ca.nlpsol("spatial_ikpath", "ipopt", {"x": x, "f": energy, "g": g}, opts)

    def solve(self, x0: ArrayLike | None = None) -> SpatialIKResult:
        """Solve from ``x0`` (default: zero clipped into the limits)."""
        prob = self.problem
        start = prob.check_start(x0)
        t0 = time.perf_counter()
        sol = self._solver(x0=start, lbx=prob.lower, ubx=prob.upper, lbg=self._lbg, ubg=self._ubg)
        wall = time.perf_counter() - t0
        stats = self._solver.stats()
        ret = str(stats.get("return_status", "unknown"))
        status = status_from_ipopt(ret, table=IPOPT_STATUS, otherwise=SolveStatus.NON_FINITE)
        if ret == "Solved_To_Acceptable_Level":
            status = SolveStatus.SOLVED  # re-checked against the targets' tolerances
        x = np.array(sol["x"], dtype=float).ravel()
        if not np.all(np.isfinite(x)):
            status, x = SolveStatus.NON_FINITE, start
        x = np.clip(x, prob.lower, prob.upper)
        lam_g = -np.array(sol["lam_g"], dtype=float).ravel()[: self._n_eq]
        multipliers = np.zeros((prob.n_targets, prob.block_rows))
        at = 0
        for j, rows in enumerate(self._rows):
            multipliers[j, rows] = lam_g[at : at + len(rows)]
            at += len(rows)
        return build_spatial_result(
            prob,
            method="ipopt",
            status=status,
            x=x,
            multipliers=multipliers,
            iterations=int(stats.get("iter_count", 0)),
            wall_time=wall,
            message=ret,
            start=start,
        )


_CACHE: dict[int, tuple[CyclicIKProblem, SpatialIpoptSolver]] = {}


def solve_spatial_ipopt(problem: CyclicIKProblem, x0: ArrayLike | None = None) -> SpatialIKResult:
    """Solve once by IPOPT (the solver is built once per problem object and reused)."""
    hit = _CACHE.get(id(problem))
    if hit is None or hit[0] is not problem:
        if len(_CACHE) >= 8:
            _CACHE.clear()
        hit = (problem, SpatialIpoptSolver(problem))
        _CACHE[id(problem)] = hit
    return hit[1].solve(x0)
