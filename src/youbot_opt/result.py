"""Outcome of a trajectory solve: :class:`TrajOptResult` and :class:`SolveStatus`.

A failed solve is a status, not an exception (Drake, toppra), so sweeps keep
going; :meth:`TrajOptResult.raise_for_status` turns it into
:class:`~youbot_opt.exceptions.SolveFailed` on demand.

Multiplier sign convention (CasADi's): the gradient of the Lagrangian

.. math::

    L(x, \\lambda_g, \\lambda_x) = f(x) + \\lambda_g^\\top g(x) + \\lambda_x^\\top x

vanishes at the solution. ``lam_x`` is > 0 at an active upper bound and < 0 at
an active lower bound; ``multipliers["<family>_upper"]`` holds ``max(lam_x, 0)``
and ``multipliers["<family>_lower"]`` holds ``min(lam_x, 0)`` of the family's
variables (so lower-bound multipliers are <= 0). Each multiplier is the
sensitivity ``d f* / d b`` of the optimal objective to its bound ``b`` with the
sign flipped for lower bounds, i.e. ``-lam`` is the rate at which the objective
would fall per unit of bound relaxation (upper bound raised or lower bound
lowered, in the bound's unit). Equality blocks (``defect_*``,
``start_position``, ...) carry ``lam_g`` unchanged.
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
from youbot_opt.options import IpoptOptions
from youbot_opt.problem import BoundaryState, JointBounds, TrajOptProblem
from youbot_opt.trajectory import Trajectory

__all__ = ["SolveStatus", "TrajOptResult", "ActiveBound", "status_from_ipopt"]


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
        Bound name, e.g. ``"velocity_upper"``.
    knot : int
        Knot (or interval, for ``*_mid`` families) index, 0-based.
    joint : int
        Joint index, 0-based (0 for ``dt``).
    value : float
        Variable value at the solution (unit of the family).
    bound : float
        The bound it touches.
    multiplier : float
        ``lam_x`` of that variable (sign convention in the module docstring).
    """

    name: str
    knot: int
    joint: int
    value: float
    bound: float
    multiplier: float


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

    @property
    def success(self) -> bool:
        """True if IPOPT converged and the solution is finite and within bounds."""
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
        """The scaled joint bounds of this solve."""
        return self.problem.bounds(self.bound_scale)

    def active_bounds(self, tol: float = 1e-6) -> list[ActiveBound]:
        """Bounds within ``tol`` of their variable (the study's Appendix C).

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
        from youbot_opt.transcription.base import BOUND_NAMES

        rows: list[ActiveBound] = []
        for block, values in self.variables.items():
            family = BOUND_NAMES[block]
            lo, hi = limits[block.removesuffix("_mid")]
            for side, bound in (("lower", lo), ("upper", hi)):
                name = f"{family}_{side}"
                lam = self.multipliers.get(name)
                gap = values - bound if side == "lower" else bound - values
                for knot, joint in zip(*np.nonzero(np.isfinite(gap) & (gap <= tol)), strict=True):
                    rows.append(
                        ActiveBound(
                            name=name,
                            knot=int(knot),
                            joint=int(joint),
                            value=float(values[knot, joint]),
                            bound=float(np.broadcast_to(bound, values.shape)[knot, joint]),
                            multiplier=float("nan") if lam is None else float(lam[knot, joint]),
                        )
                    )
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
