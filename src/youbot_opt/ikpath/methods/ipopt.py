"""The IPOPT method: the cyclic IK path's NLP in CasADi, solved by IPOPT.

Independent of the augmented Lagrangian in kinematics (CasADi expressions: a
planar chain's closed form, or a robot frame's kinematics written symbolically
from the Pinocchio model), derivatives (CasADi's exact Hessian) and algorithm
(IPOPT's interior point on the joint box); only the problem data are shared.
:class:`IpoptIKSolver` (planar chains, the targets as parameters) and
:class:`IpoptIKSolver3D` (any robot) are built once and re-solved. Why this
makes a check: docs/design.md, "Module notes".

>>> result = IpoptIKSolver(problem).solve(None, x0)  # doctest: +SKIP
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from types import MappingProxyType

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike

from youbot_opt._typing import Array
from youbot_opt.exceptions import ParameterError
from youbot_opt.ikpath.methods.best_iterate import pick_best
from youbot_opt.ikpath.problem import CyclicIKProblem
from youbot_opt.ikpath.result import (
    IKPathResult,
    OuterIterate,
    build_result,
)
from youbot_opt.nlp.best_iterate import NlpsolIterationCallback
from youbot_opt.nlp.ipopt import IpoptOptions, IpoptValue, single_threaded_blas
from youbot_opt.nlp.status import IPOPT_STATUS, SolveStatus, status_from_ipopt

__all__ = [
    "BOUND_SETTINGS",
    "check_degrees_of_freedom",
    "check_options",
    "frame_expression",
    "IpoptIKSolver",
    "IpoptOptions",
    "solve_ipopt",
    "solve_ipopt_3d",
    "target_rows",
    "IpoptIKSolver3D",
]

_STATUS: Mapping[str, SolveStatus] = MappingProxyType(
    {
        **IPOPT_STATUS,
        "Solved_To_Acceptable_Level": SolveStatus.SOLVED,  # re-checked in solve()
        "Search_Direction_Becomes_Too_Small": SolveStatus.STALLED,
        "Restoration_Failed": SolveStatus.STALLED,
    }
)
# Not listed, hence NON_FINITE (a numerical failure): "Not_Enough_Degrees_Of_Freedom" says
# nothing about feasibility, and check_degrees_of_freedom() refuses such problems before
# IPOPT runs.

BOUND_SETTINGS: Mapping[str, IpoptValue] = MappingProxyType(
    {
        "bound_relax_factor": 0.0,
        "honor_original_bounds": "yes",
        # IPOPT moves a bound by slack_move * max(1, |bound|) when a slack gets tiny
        # (default eps^(3/4) = 1.8e-12), so x can end that far outside the limits.
        # solve() projects x back; with 1e-14 the projection moves the tip by at
        # most ~1e-14 rad * reach, far below constr_viol_tol (with the default,
        # 2.8e-12 rad at l = pi/2 moved a 7 m arm's tip by 4e-11 m > 1e-11 m).
        "slack_move": 1e-14,
    }
)
"""IPOPT settings of the IK-path NLP: the joint limits hold exactly (``extra`` overrides)."""


def check_options(options: IpoptOptions | None) -> IpoptOptions:
    """Return the IPOPT options of an IK-path solve (``None``: :meth:`IpoptOptions.for_ikpath`).

    Raises
    ------
    ParameterError
        If ``options`` is not an :class:`IpoptOptions`, has no ``constr_viol_tol``
        (the solver's success criterion in [m]) or ``max_iter < 1``.
    """
    if options is None:
        return IpoptOptions.for_ikpath()
    if not isinstance(options, IpoptOptions):
        raise ParameterError(
            f"options must be IpoptOptions, got {type(options).__name__}",
            name="options",
            value=options,
        )
    if options.constr_viol_tol is None or options.max_iter < 1:
        raise ParameterError(
            "IK-path IPOPT needs constr_viol_tol (the accepted target miss in [m]) and "
            f"max_iter >= 1, got constr_viol_tol={options.constr_viol_tol!r}, "
            f"max_iter={options.max_iter!r}; use IpoptOptions.for_ikpath(...) for the "
            "IK-path defaults (tol 1e-12, constr_viol_tol 1e-11 m)",
            name="options",
            value=options,
        )
    return options


class _IterateRecorder(NlpsolIterationCallback):
    """IPOPT iteration callback keeping each iterate (x, f, g) for the history."""

    def __init__(self, nx: int, ng: int, n_par: int) -> None:
        self.records: list[tuple[Array, float, Array]] = []
        super().__init__("ikpath_ipopt_recorder", nx, ng, n_par)

    def record(self, values: dict[str, Array]) -> None:
        """Keep the iterate's configurations, E and constraint values."""
        self.records.append((values["x"], float(values["f"][0]), values["g"]))


def check_degrees_of_freedom(problem: CyclicIKProblem) -> None:
    """Refuse a problem IPOPT cannot take: fewer free unknowns than target equations.

    Each target gives 2 equations and each configuration has ``n_free`` free
    joints (joints whose limits coincide are fixed), so IPOPT needs
    ``n_free >= 2``; otherwise it stops with ``Not_Enough_Degrees_Of_Freedom``
    and reports a feasible problem as infeasible. Such a chain (one link, say)
    has its configurations fixed by the targets up to ``2 pi`` windings; the
    augmented Lagrangian method (``method="al"``) handles it.

    Raises
    ------
    ParameterError
        If fewer than 2 joints are free.
    """
    if problem.bounded:
        free = int(np.count_nonzero(problem.planar_chain.q_lower < problem.planar_chain.q_upper))
    else:
        free = problem.n_joints
    if free < 2:
        s = problem.n_targets
        raise ParameterError(
            f"method 'ipopt' needs at least 2 free joints, got {free} (of "
            f"{problem.n_joints}): {free * s} unknowns for {2 * s} target equations, which "
            "IPOPT refuses (Not_Enough_Degrees_Of_Freedom) even when the targets are "
            "reachable; use method='al' for this chain",
            name="method",
            value="ipopt",
        )


def _project_onto_box(x: Array, lower: Array, upper: Array) -> tuple[Array, float]:
    """Clip IPOPT's ``x`` into ``[lower, upper]``; return it and the largest move in [rad].

    Even with ``bound_relax_factor = 0`` IPOPT may end a few 1e-12 rad outside
    a bound that is active at the solution: when a slack ``x - l`` becomes
    tiny compared with machine precision it moves the bound by ``slack_move``
    (default ``eps^(3/4) max(1, |l|)``, 2.9e-12 rad for ``l = pi/2``) per
    occurrence. The projection undoes that move. It is not trusted blindly:
    the result recomputes E and the residuals (Pinocchio) at the projected
    point and re-checks a claimed success against the solver's tolerance, and
    the limits must then hold exactly.
    """
    clipped = np.clip(x, lower, upper)
    return clipped, float(np.max(np.abs(clipped - x))) if x.size else 0.0


def _tip_expression(problem: CyclicIKProblem, q: ca.SX) -> ca.SX:
    """CasADi tip position of the chain at one configuration ``q`` (n,)."""
    chain = problem.planar_chain
    phi = ca.SX(0)
    x, y = ca.SX(float(chain.base[0])), ca.SX(float(chain.base[1]))
    for i in range(chain.n):
        phi = phi + q[i] + float(chain.angle_offset[i])
        x = x + float(chain.lengths[i]) * ca.cos(phi)
        y = y + float(chain.lengths[i]) * ca.sin(phi)
    return ca.vertcat(x, y)


class IpoptIKSolver:
    """IPOPT solver of one problem structure, built once and re-solved.

    Parameters
    ----------
    problem : CyclicIKProblem
        Fixes the chain, the number of targets and whether limits apply; the
        targets themselves are NLP parameters.
    options : IpoptOptions, optional
        IPOPT settings (default :meth:`IpoptOptions.for_ikpath`); they must set
        ``constr_viol_tol`` [m].

    Raises
    ------
    ParameterError
        If fewer than 2 joints are free (see :func:`check_degrees_of_freedom`),
        or for options without ``constr_viol_tol`` (see :func:`check_options`).
    """

    def __init__(self, problem: CyclicIKProblem, options: IpoptOptions | None = None) -> None:
        check_degrees_of_freedom(problem)
        self.problem = problem
        self.options = check_options(options)
        self._constraint_tol = float(self.options.constr_viol_tol)  # type: ignore[arg-type]
        s, n = problem.n_targets, problem.n_joints
        x = ca.SX.sym("x", s * n)
        p = ca.SX.sym("targets", 2 * s)
        configs = [x[j * n : (j + 1) * n] for j in range(s)]
        energy = ca.SX(0)
        for j in range(s):
            d = configs[(j + 1) % s] - configs[j]
            energy = energy + 0.5 * ca.dot(d, d)
        g = ca.vertcat(
            *[_tip_expression(problem, configs[j]) - p[2 * j : 2 * j + 2] for j in range(s)]
        )
        self._recorder = _IterateRecorder(s * n, 2 * s, 2 * s)
        opts = self.options.to_casadi(True, solver_settings=BOUND_SETTINGS)
        opts["iteration_callback"] = self._recorder
        single_threaded_blas()
        self._solver = ca.nlpsol(
            "ikpath_ipopt", "ipopt", {"x": x, "p": p, "f": energy, "g": g}, opts
        )

    def solve(
        self, problem: CyclicIKProblem | None = None, x0: ArrayLike | None = None
    ) -> IKPathResult:
        """Solve from ``x0`` (default: the problem's zero start).

        Parameters
        ----------
        problem : CyclicIKProblem, optional
            A problem with the same structure (other targets allowed); the
            construction problem by default.
        x0 : array_like, shape (n s,) or (s, n), optional
            Start in [rad].

        Returns
        -------
        IKPathResult
            ``method = "ipopt"``; the history has one entry per IPOPT iteration.

        Raises
        ------
        ParameterError
            If ``problem`` has another structure or ``x0`` is invalid.
        """
        prob = self.problem if problem is None else problem
        if (
            prob.planar_chain is not self.problem.planar_chain
            or prob.n_targets != self.problem.n_targets
            or prob.bounded != self.problem.bounded
        ):
            raise ParameterError(
                "problem must have the chain, number of targets and limits this solver was "
                "built for",
                name="problem",
                value=prob,
            )
        start = prob.check_start(x0)
        self._recorder.records.clear()
        t0 = time.perf_counter()
        sol = self._solver(
            x0=start, p=prob.target_points.ravel(), lbx=prob.lower, ubx=prob.upper, lbg=0.0, ubg=0.0
        )
        wall = time.perf_counter() - t0
        stats = self._solver.stats()
        ret = str(stats.get("return_status", "unknown"))
        x = np.array(sol["x"], dtype=float).ravel()
        status = status_from_ipopt(ret, table=_STATUS, otherwise=SolveStatus.NON_FINITE)
        message = ret
        if not np.all(np.isfinite(x)):
            status, x = SolveStatus.NON_FINITE, start
        else:
            x, moved = _project_onto_box(x, prob.lower, prob.upper)
            if moved > 0.0:
                message = f"{ret}; projected onto the joint limits (moved {moved:.2g} rad)"
        if status is SolveStatus.SOLVED and ret != "Solve_Succeeded":
            # IPOPT's "acceptable" level uses its own (loose, user-settable) tolerances:
            # a success only if the targets are met to constr_viol_tol (Pinocchio check;
            # x is already projected onto the limits).
            worst = float(np.max(prob.residuals(x)))
            if worst > self._constraint_tol:
                status = SolveStatus.STALLED
        if status is not SolveStatus.SOLVED and np.all(np.isfinite(x)):
            visited = (
                _project_onto_box(rx, prob.lower, prob.upper)[0]
                for rx, _, _ in self._recorder.records
            )
            x, note = pick_best(prob, x, visited, self._constraint_tol)
            message = f"{message}; {note}" if note else message
        its = stats.get("iterations", {})
        history = tuple(
            OuterIterate(
                k,
                rx.reshape(prob.n_targets, prob.n_joints),
                rf,
                float(np.max(np.abs(rg))) if rg.size else 0.0,
                float(its["inf_du"][k]) if k < len(its.get("inf_du", [])) else float("nan"),
                float(its["mu"][k]) if k < len(its.get("mu", [])) else float("nan"),
                0,
            )
            for k, (rx, rf, rg) in enumerate(self._recorder.records)
        )
        return build_result(
            prob,
            method="ipopt",
            status=status,
            x=x,
            multipliers=-np.array(sol["lam_g"], dtype=float).ravel(),
            iterations=int(stats.get("iter_count", len(history))),
            inner_iterations=0,
            wall_time=wall,
            message=message,
            start=start,
            constraint_tol=self._constraint_tol,
            history=history,
        )


def solve_ipopt(
    problem: CyclicIKProblem, x0: ArrayLike | None = None, options: IpoptOptions | None = None
) -> IKPathResult:
    """Solve the cyclic IK-path problem once with IPOPT (builds the NLP each call).

    Parameters
    ----------
    problem : CyclicIKProblem
        The problem.
    x0 : array_like, optional
        Start in [rad]; the zero vector (clipped into the limits) by default.
    options : IpoptOptions, optional
        IPOPT settings (default :meth:`IpoptOptions.for_ikpath`).

    Returns
    -------
    IKPathResult
        ``method = "ipopt"``.

    Raises
    ------
    ParameterError
        If fewer than 2 joints are free (see :func:`check_degrees_of_freedom`).
    """
    return IpoptIKSolver(problem, options).solve(problem, x0)


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


def target_rows(
    problem: CyclicIKProblem, j: int, pos: ca.SX, rot: ca.SX
) -> tuple[ca.SX, list[ca.SX], list[int]]:
    """Equality rows, inequalities (``>= 0``) and row indices of target ``j`` at (pos, rot).

    ``pos`` and ``rot`` are the frame's symbolic position and rotation
    (:func:`frame_expression`); the rows are the NLP's (position, ``vex`` of the
    orientation error or the approach rows, see :class:`IpoptIKSolver3D`), the
    indices say which of the target's ``block_rows`` they are.
    """
    target = problem.targets[j]
    eqs: list[ca.SX] = []
    ineqs: list[ca.SX] = []
    if problem.plane is None:
        eqs.append(pos - ca.DM(target.position))
    else:  # a planar robot: the 2 plane coordinates (the third row is identically 0)
        eqs.append(ca.DM(problem.plane.basis.T) @ (pos - ca.DM(target.position)))
    k = problem.position_rows
    rows = list(range(k))
    wt = target.orientation_weight
    planar = problem.orientation_basis(target)  # a planar robot: one angle
    if target.rotation is not None:
        r_e = ca.DM(target.rotation).T @ rot
        vex = ca.vertcat(r_e[2, 1] - r_e[1, 2], r_e[0, 2] - r_e[2, 0], r_e[1, 0] - r_e[0, 1])
        if planar is None:
            eqs.append(wt * 0.5 * vex)
            rows += [k, k + 1, k + 2]
        else:
            eqs.append(wt * 0.5 * (ca.DM(planar) @ vex))
            rows += [k]
        ineqs.append(ca.trace(r_e) + 0.5)
    elif target.approach is not None:
        basis = target.approach_basis() if planar is None else planar
        if basis.shape[0]:  # none: the axis keeps its direction (met or not)
            axis = rot @ ca.DM(target.approach_axis)
            eqs.append(wt * (ca.DM(basis) @ axis))
            ineqs.append(ca.dot(ca.DM(target.approach), axis))
            rows += list(range(k, k + basis.shape[0]))
    return ca.vertcat(*eqs), ineqs, rows


class IpoptIKSolver3D:
    """IPOPT solver of one 3-D problem (any robot), built once and re-solved from many starts.

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
        for j in range(s):
            eq, ineq, rows = target_rows(problem, j, *frame_expression(problem, configs[j]))
            eqs.append(eq)
            ineqs += ineq
            self._rows.append(rows)
        self._n_eq = int(sum(e.shape[0] for e in eqs))
        self._n_ineq = len(ineqs)
        clear = problem.clearance_rows  # rows >= the margin (docs/ikpath.md, "Clearance")
        clear_rows = clear.function(x) if clear is not None else ca.SX(0, 1)
        margin = clear.spec.margin if clear is not None else 0.0
        g = ca.vertcat(*eqs, *ineqs, clear_rows)
        self._lbg = np.r_[np.zeros(self._n_eq + len(ineqs)), np.full(clear_rows.shape[0], margin)]
        self._ubg = np.r_[np.zeros(self._n_eq), np.full(len(ineqs) + clear_rows.shape[0], np.inf)]
        opts = self.options.to_casadi(True, solver_settings=BOUND_SETTINGS)
        single_threaded_blas()
        self._solver = ca.nlpsol("ikpath_3d", "ipopt", {"x": x, "f": energy, "g": g}, opts)

    def solve(self, x0: ArrayLike | None = None, *, generated: bool = False) -> IKPathResult:
        """Solve from ``x0`` (default: zero clipped into the limits).

        ``generated``: a start the multistart made (may collide; a user's may not).
        """
        prob = self.problem
        start = prob.check_start(x0, generated=generated)
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
        lam_all = -np.array(sol["lam_g"], dtype=float).ravel()
        lam_g = lam_all[: self._n_eq]
        # The clearance rows' lam_g (CasADi's Lagrangian f + lam_g^T g: <= 0 on a row at
        # its lower bound) as nu = -lam_g >= 0, the AL's convention; IPOPT's interior
        # point leaves inactive rows ~ barrier mu / g (tiny, > 0: 3e-13..3e-11 on ur5 and a
        # box); a rounding of the wrong sign is set to 0.
        nu = np.maximum(lam_all[self._n_eq + self._n_ineq :], 0.0)
        multipliers = np.zeros((prob.n_targets, prob.block_rows))
        at = 0
        for j, rows in enumerate(self._rows):
            multipliers[j, rows] = lam_g[at : at + len(rows)]
            at += len(rows)
        return build_result(
            prob,
            method="ipopt",
            status=status,
            x=x,
            multipliers=multipliers,
            iterations=int(stats.get("iter_count", 0)),
            wall_time=wall,
            message=ret,
            start=start,
            clearance_multipliers=nu,
        )


_CACHE: dict[int, tuple[CyclicIKProblem, IpoptIKSolver3D]] = {}


def solve_ipopt_3d(problem: CyclicIKProblem, x0: ArrayLike | None = None) -> IKPathResult:
    """Solve once by IPOPT (the solver is built once per problem object and reused)."""
    hit = _CACHE.get(id(problem))
    if hit is None or hit[0] is not problem:
        if len(_CACHE) >= 8:
            _CACHE.clear()
        hit = (problem, IpoptIKSolver3D(problem))
        _CACHE[id(problem)] = hit
    return hit[1].solve(x0)
