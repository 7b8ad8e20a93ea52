r"""Outcome of a trajectory solve: :class:`TrajOptResult` and :class:`SolveStatus`.

A failed solve is a status, not an exception (Drake, toppra), so sweeps keep
going; :meth:`TrajOptResult.raise_for_status` turns it into
:class:`~youbot_opt.exceptions.SolveFailed` on demand.

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
  block without bounds of its own (Hermite-Simpson's ``v_mid``) has zeros.
* Equality blocks of ``g`` (``defect_*``, ``midpoint_*``, ``start_position``,
  ``goal_velocity``, ...) carry ``lam_g`` unchanged: ``d f* / d c = -lam_g``
  for a right-hand side ``c`` (e.g. a start position).
* Inequality path blocks of ``g`` (Hermite-Simpson's ``velocity_control_left``
  and ``velocity_control_right``, held within the speed bounds) carry
  ``lam_g`` unchanged, signed as above: > 0 where the row is at the upper
  speed bound, < 0 at the lower one.

:meth:`TrajOptResult.active_bounds` reports exactly the bounds the NLP has:
variable bounds of the bounded blocks and the path-inequality rows, each with
its signed multiplier.
"""

from __future__ import annotations

import enum
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np

from youbot_opt._typing import Array
from youbot_opt.exceptions import SolveFailed
from youbot_opt.nlp.ipopt import IpoptOptions
from youbot_opt.trajopt.problem import BoundaryState, JointBounds, TrajOptProblem
from youbot_opt.trajopt.trajectory import Trajectory

__all__ = [
    "SolveStatus",
    "TrajOptResult",
    "ActiveBound",
    "BoundStructure",
    "PathBlock",
    "ResultCheck",
    "check_result",
    "status_from_ipopt",
    "DEFAULT_FEASIBILITY_TOL",
]

DEFAULT_FEASIBILITY_TOL = 1e-6
"""Largest constraint or bound violation a successful result may have (units of each row)."""


class SolveStatus(enum.Enum):
    """How a solve ended (``success`` only for the first two)."""

    SOLVED = "solved"
    """IPOPT converged to ``tol`` and the solution passed the independent checks."""
    SOLVED_ACCEPTABLE = "solved_acceptable"
    """IPOPT converged to its ``acceptable_tol`` level; checks passed."""
    MAX_ITERATIONS = "max_iterations"
    """Iteration cap reached; the last iterate is returned."""
    MAX_TIME = "max_time"
    """CPU- or wall-time cap reached."""
    INFEASIBLE = "infeasible"
    """IPOPT detected local infeasibility (e.g. torque bounds too tight)."""
    NON_FINITE = "non_finite"
    """NaN or inf in the solution, objective or constraints."""
    CONSTRAINT_VIOLATION = "constraint_violation"
    """IPOPT reported convergence but the solution violates constraints or bounds."""
    FAILED = "failed"
    """Any other solver failure (restoration failed, error in evaluation, ...)."""

    @property
    def success(self) -> bool:
        """True for :attr:`SOLVED` and :attr:`SOLVED_ACCEPTABLE`."""
        return self in (SolveStatus.SOLVED, SolveStatus.SOLVED_ACCEPTABLE)


_IPOPT_STATUS: dict[str, SolveStatus] = {
    "Solve_Succeeded": SolveStatus.SOLVED,
    "Solved_To_Acceptable_Level": SolveStatus.SOLVED_ACCEPTABLE,
    "Maximum_Iterations_Exceeded": SolveStatus.MAX_ITERATIONS,
    "Maximum_CpuTime_Exceeded": SolveStatus.MAX_TIME,
    "Maximum_WallTime_Exceeded": SolveStatus.MAX_TIME,
    "Infeasible_Problem_Detected": SolveStatus.INFEASIBLE,
    "Invalid_Number_Detected": SolveStatus.NON_FINITE,
}


def status_from_ipopt(return_status: str) -> SolveStatus:
    """Map IPOPT's ``return_status`` string to a :class:`SolveStatus`."""
    return _IPOPT_STATUS.get(return_status, SolveStatus.FAILED)


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
        upper bound, < 0 at a lower one; module docstring); NaN if the solve
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
class TrajOptResult:
    """Solution (or best iterate) of one trajectory solve.

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
    solver_status : str
        IPOPT's own ``return_status`` string.
    trajectory : Trajectory or None
        Time grid [s], q [rad], v [rad/s], a [rad/s^2], tau [N m]; ``None``
        only if the iterate is not finite.
    variables : mapping of str to ndarray
        Every decision-variable block, knot-major (``"q"`` (N, nv), ``"dt"`` (1, 1), ...).
    duration : float
        True duration ``T = (N - 1) dt`` in [s].
    dt : float
        Common time step in [s].
    work : float
        ``W`` (integral of ``tau . tau``) in [N^2 m^2 s] by the transcription's rule.
    objective : float
        ``beta T + (1 - beta) W``, recomputed from the variables.
    beta, bound_scale : float
        Time weight and bound scale factor of this solve.
    start, goal : BoundaryState
        Boundary states of this solve.
    iterations : int
        IPOPT iterations.
    wall_time, cpu_time : float
        Time spent in the solve call (not the NLP build) in [s].
    objective_history : ndarray, shape (iterations + 1,)
        IPOPT's objective per iteration (from ``stats()["iterations"]["obj"]``).
    max_violation : float
        Largest violation of any equality (defects, boundary conditions) or
        bound, recomputed from the solution (units of each constraint).
    multipliers : mapping of str to ndarray
        Lagrange multipliers by name and knot (see the module docstring).
    guess : Trajectory or None
        The initial guess used.
    options : IpoptOptions
        Solver options used.
    seed : int or None
        Seed of the random guess, when one was used.
    feasibility_tol : float
        Largest violation (units of each constraint) a successful result may
        have; :func:`check_result` applies it. The solver passes its own
        ``TrajOptSolver(feasibility_tol=...)``.
    bound_structure : BoundStructure or None
        The NLP's unbounded blocks and path-inequality rows, as the solver
        built them; ``None`` (e.g. a loaded result) re-derives them from the
        transcription named by :attr:`method` (:meth:`bound_structure_of`).

    A success claim is re-checked on construction by :func:`check_result` (also
    after ``dataclasses.replace`` or loading); if the check fails, its status
    and message replace :attr:`status` and :attr:`message`.
    """

    problem: TrajOptProblem
    method: str
    backend: str
    status: SolveStatus
    message: str
    solver_status: str
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
    iterations: int
    wall_time: float
    cpu_time: float
    objective_history: Array
    max_violation: float
    multipliers: Mapping[str, Array]
    guess: Trajectory | None = None
    options: IpoptOptions = field(default_factory=IpoptOptions)
    seed: int | None = None
    feasibility_tol: float = DEFAULT_FEASIBILITY_TOL
    bound_structure: BoundStructure | None = field(default=None, compare=False)

    def __post_init__(self) -> None:
        if not self.status.success:
            return
        from youbot_opt.trajopt.check import check_result

        check = check_result(self)
        if not check.passed:
            object.__setattr__(self, "status", check.status)
            object.__setattr__(self, "message", f"{self.message}; {check.message}")

    @property
    def success(self) -> bool:
        """True if IPOPT converged and :func:`check_result` passed (finite, feasible)."""
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
        from youbot_opt.trajopt.check import derive_structure

        return derive_structure(self)

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
        from youbot_opt.trajopt.transcription.base import BOUND_NAMES

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
            lo, hi = limits[block.removesuffix("_mid")]
            for side, bound in (("lower", lo), ("upper", hi)):
                name = f"{family}_{side}"
                collect(name, values, bound, side, self.multipliers.get(name))
        for block, path in structure.path.items():
            lo, hi = limits[path.family]
            lam_g = self.multipliers.get(block)
            for side, bound in (("lower", lo), ("upper", hi)):
                collect(f"{block}_{side}", path.values, bound, side, lam_g)
        return sorted(rows, key=lambda r: (r.name, r.knot, r.joint))

    def summary(self) -> dict[str, Any]:
        """JSON-ready figures of the solve."""

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
        }


# Re-exported for the callers that import them from here.
from youbot_opt.trajopt.check import ResultCheck, check_result  # noqa: E402
