"""Outcome of a trajectory solve: :class:`TrajOptResult`, :class:`SolveStats`, active bounds.

A failed solve is a status, not an exception (Drake, toppra), so sweeps keep
going; :meth:`TrajOptResult.raise_for_status` turns it into
:class:`~youbot_opt.exceptions.SolveFailed` on demand. Constructing a result
does no work: the independent check lives in :mod:`youbot_opt.trajopt.check`
and :meth:`TrajOptResult.check` runs it on demand. The sign convention of the
multipliers is in the :class:`TrajOptResult` docstring.

>>> result.raise_for_status().active_bounds(tol=1e-6)  # doctest: +SKIP
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np

from youbot_opt._typing import Array, JSONDict
from youbot_opt.dynamics.numeric import batched_aba
from youbot_opt.exceptions import ParameterError, SolveFailed
from youbot_opt.nlp.ipopt import IpoptOptions
from youbot_opt.nlp.status import SolveStatus, status_from_ipopt
from youbot_opt.robot.model import JointBounds
from youbot_opt.trajopt.check import ResultCheck, check_result
from youbot_opt.trajopt.export.samples import SampledTrajectory, sample_trajectory
from youbot_opt.trajopt.problem import BoundaryState, TrajOptProblem
from youbot_opt.trajopt.trajectory import Trajectory

__all__ = [
    "SolveStatus",
    "TrajOptResult",
    "ActiveBound",
    "BoundStructure",
    "PathBlock",
    "ResultCheck",
    "SolveStats",
    "status_from_ipopt",
    "DEFAULT_FEASIBILITY_TOL",
]

DEFAULT_FEASIBILITY_TOL = 1e-6
"""Largest constraint or bound violation a successful result may have (units of each row)."""


class ActiveBound(NamedTuple):
    """One active bound of the solution (the study's Appendix C rows).

    Attributes
    ----------
    name : str
        ``"<family>_<side>"`` for a variable bound (e.g. ``"velocity_upper"``)
        or ``"<path block>_<side>"`` for a path-inequality row of ``g``
        (e.g. ``"velocity_control_left_upper"``).
    knot : int
        Knot (or interval, for ``*_mid`` families and path blocks) index, 0-based.
    joint : int
        Joint index, 0-based (0 for ``dt``).
    value : float
        Value of the variable or row at the solution (unit of the bound).
    bound : float
        The bound it touches.
    multiplier : float
        Its multiplier: ``max(lam_x, 0)`` / ``min(lam_x, 0)`` for an upper /
        lower variable bound, the signed ``lam_g`` for a path row (> 0 at an
        upper bound, < 0 at a lower one; :class:`TrajOptResult` Notes); NaN if the solve
        returned none.
    """

    name: str
    knot: int
    joint: int
    value: float
    bound: float
    multiplier: float


class PathBlock(NamedTuple):
    """An inequality block of the NLP's constraint vector ``g``, at the solution.

    Attributes
    ----------
    family : str
        Variable family whose (scaled) bounds the rows must stay within:
        ``"q"``, ``"v"`` or ``"tau"``.
    values : ndarray, shape (count, nv)
        Row values at the solution, in the family's unit.
    """

    family: str
    values: Array


class BoundStructure(NamedTuple):
    """Which bounds the NLP of a result actually has (besides ``lbx``/``ubx`` of every block).

    Attributes
    ----------
    unbounded : tuple of str
        Variable blocks without bounds of their own (Hermite-Simpson's ``v_mid``).
    path : mapping of str to PathBlock
        Inequality blocks of ``g`` by name (Hermite-Simpson's
        ``velocity_control_left`` / ``_right``); empty for trapezoidal collocation.
    """

    unbounded: tuple[str, ...]
    path: Mapping[str, PathBlock]


@dataclass(frozen=True, slots=True, kw_only=True)
class SolveStats:
    """What IPOPT reported about one solve (not about the solution).

    Attributes
    ----------
    solver_status : str
        IPOPT's own ``return_status`` string (``"error"`` if the call raised).
    iterations : int
        IPOPT iterations.
    wall_time, cpu_time : float
        Time spent in the solve call (not the NLP build) in [s].
    objective_history : ndarray, shape (iterations + 1,)
        IPOPT's objective per iteration (from ``stats()["iterations"]["obj"]``).
    """

    solver_status: str
    iterations: int = 0
    wall_time: float = 0.0
    cpu_time: float = 0.0
    objective_history: Array = field(default_factory=lambda: np.zeros(0))


@dataclass(frozen=True, slots=True, kw_only=True)
class TrajOptResult:
    r"""Solution (or best iterate) of one trajectory solve.

    Attributes
    ----------
    problem : TrajOptProblem
        The problem that was solved.
    method : str
        Transcription name.
    backend : str
        Dynamics backend name.
    status : SolveStatus
        Outcome; see :attr:`success`.
    message : str
        Human-readable outcome (IPOPT's return status and any failed check).
    trajectory : Trajectory or None
        Time grid [s], q [rad], v [rad/s], a [rad/s^2], tau [N m]; ``None``
        only if the iterate is not finite.
    variables : mapping of str to ndarray
        Every decision-variable block, knot-major (``"q"`` (N, nv), ``"dt"`` (1, 1), ...).
    duration : float
        True duration ``T = (N - 1) dt`` in [s].
    dt : float
        Mean time step ``T / (N - 1)`` in [s] (the common step of a uniform grid).
    work : float
        ``W`` (integral of ``tau . tau``) in [N^2 m^2 s] by the transcription's rule.
    objective : float
        ``beta T + (1 - beta) W``, recomputed from the variables.
    beta, bound_scale : float
        Time weight and bound scale factor of this solve.
    start, goal : BoundaryState
        Boundary states of this solve.
    stats : SolveStats
        IPOPT's report: ``solver_status``, ``iterations``, ``wall_time``,
        ``cpu_time``, ``objective_history`` (each also a property of the result).
    max_violation : float
        Largest violation of any equality (defects, boundary conditions) or
        bound, recomputed from the solution (units of each constraint).
    multipliers : mapping of str to ndarray
        Lagrange multipliers by name and knot (sign convention in Notes).
    guess : Trajectory or None
        The initial guess used.
    options : IpoptOptions
        Solver options used.
    seed : int or None
        Seed of the random guess, when one was used.
    feasibility_tol : float
        Largest violation (units of each constraint) a successful result may
        have; :meth:`check` applies it. The solver passes its own
        ``TrajOptSolver(feasibility_tol=...)``.
    bound_structure : BoundStructure or None
        The NLP's unbounded blocks and path-inequality rows, as the solver
        built them; ``None`` (e.g. a loaded result) re-derives them from the
        transcription named by :attr:`method` (:meth:`bound_structure_of`).
    grid : ndarray, shape (N - 1,), or None
        Each interval's fraction of ``T`` on a non-uniform grid (they sum to 1;
        interval ``k`` lasts ``(N - 1) grid[k] dt``); ``None`` for the uniform grid.
        A refined grid's record of rounds is returned beside the result by
        :func:`youbot_opt.trajopt.refine.refine` (:class:`~youbot_opt.trajopt.refine.Refined`).

    Notes
    -----
    Constructing a result does no work. The solver and
    :func:`~youbot_opt.trajopt.io.load_result` run the independent check
    (:func:`youbot_opt.trajopt.check.checked`) and set :attr:`status` and
    :attr:`message` from it; :meth:`check` re-runs it on demand (e.g. after
    ``dataclasses.replace``).

    Multiplier sign convention (CasADi's, checked against IPOPT in
    ``tests/trajopt/test_solve.py``). The gradient of the Lagrangian

    .. math::

        L(x, \lambda_g, \lambda_x) = f(x) + \lambda_g^\top g(x) + \lambda_x^\top x

    vanishes at the solution, and every multiplier ``lam`` of a row with bounds
    ``lb <= row <= ub`` (a variable of ``x`` or a row of ``g``) is

    * ``> 0`` when the row sits at its **upper** bound ``ub``,
    * ``< 0`` when it sits at its **lower** bound ``lb``,
    * ``0`` (up to IPOPT's barrier parameter) when neither is active,

    and is the sensitivity of the optimal objective to the bound it touches,
    with the same sign for both sides:

    .. math::

        \frac{\partial f^*}{\partial\, ub} = -\lambda \le 0, \qquad
        \frac{\partial f^*}{\partial\, lb} = -\lambda \ge 0,

    so ``|lam|`` is the rate (objective unit per bound unit) at which the
    objective falls when the bound is relaxed (upper bound raised, lower bound
    lowered). The multiplier blocks are named as follows:

    * ``multipliers["<family>_upper"]`` = ``max(lam_x, 0)`` and
      ``multipliers["<family>_lower"]`` = ``min(lam_x, 0)`` of a variable family
      (``position``, ``velocity``, ``torque``, ``position_mid``, ..., ``dt``),
      knot-major; upper-bound multipliers are >= 0, lower-bound ones <= 0. A
      block without bounds of its own (Hermite-Simpson's ``q_mid``, ``v_mid``) has zeros.
    * Equality blocks of ``g`` (``defect_*``, ``midpoint_*``, ``start_position``,
      ``goal_velocity``, ...) carry ``lam_g`` unchanged: ``d f* / d c = -lam_g``
      for a right-hand side ``c`` (e.g. a start position).
    * Inequality path blocks of ``g`` (Hermite-Simpson's ``velocity_control_left``
      and ``velocity_control_right``, held within the speed bounds, and
      ``position_control_left`` / ``position_control_right`` within the position
      bounds) carry ``lam_g`` unchanged, signed as above: > 0 where the row is at
      the upper bound, < 0 at the lower one.

    :meth:`TrajOptResult.active_bounds` reports exactly the bounds the NLP has:
    variable bounds of the bounded blocks and the path-inequality rows, each with
    its signed multiplier.
    """

    problem: TrajOptProblem
    method: str
    backend: str
    status: SolveStatus
    message: str
    trajectory: Trajectory | None
    variables: Mapping[str, Array]
    duration: float
    dt: float
    work: float
    objective: float
    beta: float
    bound_scale: float
    start: BoundaryState
    goal: BoundaryState
    stats: SolveStats
    max_violation: float
    multipliers: Mapping[str, Array]
    guess: Trajectory | None = None
    options: IpoptOptions = field(default_factory=IpoptOptions)
    seed: int | None = None
    feasibility_tol: float = DEFAULT_FEASIBILITY_TOL
    bound_structure: BoundStructure | None = field(default=None, compare=False)
    grid: Array | None = None

    def step_ratios(self) -> Array:
        """Step ratios ``r_k = h_k / dt`` of the grid, shape ``(N - 1,)`` (ones if uniform)."""
        n = self.problem.n_knots
        if self.grid is None:
            return np.ones(n - 1)
        return (n - 1) * np.asarray(self.grid, dtype=float)

    @property
    def solver_status(self) -> str:
        """IPOPT's own ``return_status`` string (:attr:`SolveStats.solver_status`)."""
        return self.stats.solver_status

    @property
    def iterations(self) -> int:
        """IPOPT iterations (:attr:`SolveStats.iterations`)."""
        return self.stats.iterations

    @property
    def wall_time(self) -> float:
        """Wall time of the solve call in [s] (:attr:`SolveStats.wall_time`)."""
        return self.stats.wall_time

    @property
    def cpu_time(self) -> float:
        """CPU time of the solve call in [s] (:attr:`SolveStats.cpu_time`)."""
        return self.stats.cpu_time

    @property
    def objective_history(self) -> Array:
        """IPOPT's objective per iteration (:attr:`SolveStats.objective_history`)."""
        return self.stats.objective_history

    def check(self, *, feasibility_tol: float | None = None) -> ResultCheck:
        """Re-check the result independently of IPOPT's flag and of the NLP.

        This is :func:`youbot_opt.trajopt.check.check_result` (see there for
        what is checked): bounds, boundary states, the collocation defects by
        ``pin.aba`` and the reported T, W and f. The result itself is not changed.

        Parameters
        ----------
        feasibility_tol : float, optional
            Largest accepted violation in the unit of each row ([rad], [rad/s],
            [N m], [s]); :attr:`feasibility_tol` by default.

        Returns
        -------
        ResultCheck
            The status the result deserves, with the measured figures.
        """
        return check_result(self, feasibility_tol=feasibility_tol)

    @property
    def success(self) -> bool:
        """True if IPOPT converged and :meth:`check` passed (finite, feasible)."""
        return self.status.success

    def raise_for_status(self) -> TrajOptResult:
        """Return ``self`` if successful, else raise :class:`SolveFailed` carrying it.

        Raises
        ------
        SolveFailed
            If :attr:`success` is false.
        """
        if not self.success:
            raise SolveFailed(
                f"trajectory solve failed with status {self.status.value}: {self.message}",
                result=self,
            )
        return self

    def sample(self, rate_hz: float) -> SampledTrajectory:
        """Sample the plan at a controller's rate with its transcription's own interpolants.

        Parameters
        ----------
        rate_hz : float
            Controller rate in [Hz], > 0.

        Returns
        -------
        SampledTrajectory
            Time from the start [s], q, v, a, tau per sample, with the joint
            names and units of the robot
            (:func:`~youbot_opt.trajopt.export.samples.sample_trajectory`).

        Raises
        ------
        ParameterError
            If the result has no trajectory or ``rate_hz`` is not > 0.
        """
        if self.trajectory is None:
            raise ParameterError(
                f"cannot sample a result without a finite trajectory (status {self.status.value})",
                name="trajectory",
            )
        return sample_trajectory(self.trajectory, self.problem.robot, rate_hz)

    def bounds(self) -> JointBounds:
        """Return the scaled joint bounds of this solve."""
        return self.problem.bounds(self.bound_scale)

    def bound_structure_of(self) -> BoundStructure:
        """Return the NLP's unbounded blocks and path rows (stored, or re-derived).

        Re-derivation evaluates the path expressions of the transcription named
        :attr:`method` at the stored variables, with accelerations from
        ``pin.aba``; an unregistered transcription is assumed to have neither.
        """
        if self.bound_structure is not None:
            return self.bound_structure
        return _derive_structure(self)

    def active_bounds(self, tol: float = 1e-6) -> list[ActiveBound]:
        """Bounds of the NLP within ``tol`` of their row (the study's Appendix C).

        Only bounds the NLP has are reported: ``lbx``/``ubx`` of every bounded
        variable block (not those of :attr:`BoundStructure.unbounded`, whose
        limits are enforced through path rows) and the path-inequality rows of
        ``g`` with their ``lam_g``.

        Parameters
        ----------
        tol : float
            Distance from the bound, in the bound's unit, below which it counts
            as active.

        Returns
        -------
        list of ActiveBound
            Sorted by name, knot and joint.
        """
        b = self.bounds()
        limits: dict[str, tuple[Array, Array]] = {
            "q": (b.q_lower, b.q_upper),
            "v": (b.v_lower, b.v_upper),
            "tau": (b.tau_lower, b.tau_upper),
        }
        dt_hi = self.problem.dt_max
        dt_lo = self.problem.dt_min
        if self.problem.duration is not None:
            dt_lo = dt_hi = self.problem.duration / (self.problem.n_knots - 1)
        limits["dt"] = (np.array([dt_lo]), np.array([dt_hi]))
        from youbot_opt.trajopt.transcription.base import BOUND_NAMES, variable_family

        structure = self.bound_structure_of()
        rows: list[ActiveBound] = []

        def collect(name: str, values: Array, bound: Array, side: str, lam: Array | None) -> None:
            gap = values - bound if side == "lower" else bound - values
            bound = np.broadcast_to(bound, values.shape)
            for knot, joint in zip(*np.nonzero(np.isfinite(gap) & (gap <= tol)), strict=True):
                rows.append(
                    ActiveBound(
                        name=name,
                        knot=int(knot),
                        joint=int(joint),
                        value=float(values[knot, joint]),
                        bound=float(bound[knot, joint]),
                        multiplier=float("nan") if lam is None else float(lam[knot, joint]),
                    )
                )

        for block, values in self.variables.items():
            if block in structure.unbounded:
                continue
            family = BOUND_NAMES[block]
            lo, hi = limits[variable_family(block)]
            for side, bound in (("lower", lo), ("upper", hi)):
                name = f"{family}_{side}"
                collect(name, values, bound, side, self.multipliers.get(name))
        for block, path in structure.path.items():
            lo, hi = limits[path.family]
            lam_g = self.multipliers.get(block)
            for side, bound in (("lower", lo), ("upper", hi)):
                collect(f"{block}_{side}", path.values, bound, side, lam_g)
        return sorted(rows, key=lambda r: (r.name, r.knot, r.joint))

    def summary(self) -> JSONDict:
        """JSON-ready figures of the solve.

        ``"certified"`` is False: a result alone is never certified;
        :meth:`youbot_opt.trajopt.refine.Refined.summary` reports the verdict of
        a refinement.
        """

        def num(x: float) -> float | None:
            return float(x) if math.isfinite(x) else None

        return {
            "status": self.status.value,
            "success": self.success,
            "message": self.message,
            "method": self.method,
            "backend": self.backend,
            "robot": str(self.problem.robot.name),
            "n_knots": self.problem.n_knots,
            "beta": self.beta,
            "bound_scale": self.bound_scale,
            "objective": num(self.objective),
            "duration_s": num(self.duration),
            "dt_s": num(self.dt),
            "work": num(self.work),
            "iterations": self.iterations,
            "solve_time_s": self.wall_time,
            "cpu_time_s": self.cpu_time,
            "max_violation": num(self.max_violation),
            "uniform_grid": self.grid is None,
            "certified": False,  # a bare result is never certified: Refined.summary() says
            **self._clearance_summary(),
            **self._tool_summary(),
        }

    def _tool_summary(self) -> JSONDict:
        """``{"tool": [...]}``: each tool constraint, its limit and its largest knot value."""
        q, v = self.variables.get("q"), self.variables.get("v")
        tool = self.problem.tool
        if not tool or q is None or v is None or not np.all(np.isfinite(q)):
            return {}
        from youbot_opt.trajopt.tool import knot_tool

        found = knot_tool(self.problem.robot, tool, q, v)
        tip = self.problem.robot.tip_frame
        return {
            "tool": [
                {**c.document(), "label": f"{c.label} ({c.frame or tip})", "unit": c.unit,
                 "limit": c.limit, "largest_at_knots": value, "knot": k}
                for c, (value, k) in zip(tool, found, strict=True)
            ]
        }  # fmt: skip

    def _clearance_summary(self) -> JSONDict:
        """``{"clearance": ...}``: coal's closest pair at the knots and the margin, if any."""
        spec = self.problem.clearance
        q = self.variables.get("q")
        if spec is None or q is None or not np.all(np.isfinite(q)):
            return {}
        from youbot_opt.trajopt.clearance import knot_clearance

        found = knot_clearance(self.problem, q)
        if found is None:
            return {}
        distance, pair, knot = found
        return {
            "clearance": {
                "margin_m": spec.margin,
                "closest_m": distance,
                "closest_pair": list(pair),
                "knot": knot,
                "obstacles": [o.name for o in spec.scene.obstacles],
                "self_collision": spec.self_collision,
            }
        }


def _transcription_named(method: str) -> Any:
    """Return the transcription named ``method``, or None if it is not registered."""
    from youbot_opt.trajopt.transcription import get_transcription  # imports CasADi

    try:
        return get_transcription(method)
    except ParameterError:
        return None


def _derive_structure(result: TrajOptResult) -> BoundStructure:
    """Return the :class:`BoundStructure` of a result, from its transcription's name.

    Parameters
    ----------
    result : TrajOptResult
        A result whose :attr:`~TrajOptResult.bound_structure` was not stored
        (for example one loaded from a file).

    Returns
    -------
    BoundStructure
        The unbounded variable blocks and the path-inequality rows of the NLP.
    """
    import casadi as ca

    from youbot_opt.trajopt.transcription.base import Transcription

    method = _transcription_named(result.method)
    if method is not None and result.grid is not None:
        method = method.with_fractions(result.grid)
    if method is None:
        return BoundStructure(unbounded=(), path={})
    unbounded = tuple(method.unbounded)
    if type(method).path_constraints is Transcription.path_constraints:  # none
        return BoundStructure(unbounded=unbounded, path={})
    aba = batched_aba(result.problem.robot, damping=result.problem.damping)
    sym = {k: ca.DM(np.asarray(x, dtype=float).T) for k, x in result.variables.items()}
    accel: JSONDict = {}
    for group, (q, v, tau) in method.dynamics_points(sym).items():
        qn, vn, taun = (np.asarray(x, dtype=float).T for x in (q, v, tau))
        accel[group] = ca.DM(np.asarray(aba(qn, vn, taun)).reshape(vn.shape).T)
    path = {
        name: PathBlock(family=family, values=np.asarray(expr, dtype=float).T)
        for name, family, expr in method.path_constraints(sym, accel)
    }
    return BoundStructure(unbounded=unbounded, path=path)
