"""How a solve ended: :class:`SolveStatus`, one enum for both optimisers.

A failed solve is a status, not an exception (Drake, toppra): sweeps keep
going and the result says why. The trajectory optimiser and the IK-path
solver report the same outcomes with the same members; :attr:`success` is
true only for :attr:`~SolveStatus.SOLVED` and
:attr:`~SolveStatus.SOLVED_ACCEPTABLE`.

>>> SolveStatus("solved") is SolveStatus.SOLVED, status_from_ipopt("Solve_Succeeded")
(True, <SolveStatus.SOLVED: 'solved'>)
"""

from __future__ import annotations

import dataclasses
import enum
from collections.abc import Mapping
from types import MappingProxyType
from typing import Any, Protocol, TypeVar, cast

__all__ = [
    "SolveStatus",
    "IPOPT_STATUS",
    "Checkable",
    "Verdict",
    "apply_check",
    "status_from_ipopt",
]


class SolveStatus(enum.Enum):
    """How a solve ended (:attr:`success` only for the first two)."""

    SOLVED = "solved"
    """Converged to the solver's tolerances, and the independent check passed."""
    SOLVED_ACCEPTABLE = "solved_acceptable"
    """IPOPT converged to its ``acceptable_tol`` level; the check passed."""
    MAX_ITERATIONS = "max_iterations"
    """Iteration limit reached before the tolerances were met."""
    MAX_TIME = "max_time"
    """CPU- or wall-time limit reached; the last (or best) iterate is kept."""
    STALLED = "stalled"
    """No further progress possible (penalty at its cap, or IPOPT gave up: restoration
    failed, search direction too small); used by the IK-path solvers."""
    INFEASIBLE = "infeasible"
    """The solver reports the constraints as locally infeasible."""
    NON_FINITE = "non_finite"
    """NaN or inf in the iterate, objective or constraints, or a numerical error inside
    the solver."""
    CONSTRAINT_VIOLATION = "constraint_violation"
    """The solver claimed success but the result failed its independent check
    (constraints, bounds or targets missed, or reported figures that do not belong
    to the solution); the message says why."""
    CRASHED = "crashed"
    """The solve raised an exception or its worker died (sweeps keep going)."""
    FAILED = "failed"
    """Any other solver failure (restoration failed, error in evaluation, ...)."""

    @property
    def success(self) -> bool:
        """True for :attr:`SOLVED` and :attr:`SOLVED_ACCEPTABLE`."""
        return self in (SolveStatus.SOLVED, SolveStatus.SOLVED_ACCEPTABLE)


IPOPT_STATUS: Mapping[str, SolveStatus] = MappingProxyType(
    {
        "Solve_Succeeded": SolveStatus.SOLVED,
        "Solved_To_Acceptable_Level": SolveStatus.SOLVED_ACCEPTABLE,
        "Maximum_Iterations_Exceeded": SolveStatus.MAX_ITERATIONS,
        "Maximum_CpuTime_Exceeded": SolveStatus.MAX_TIME,
        "Maximum_WallTime_Exceeded": SolveStatus.MAX_TIME,
        "Infeasible_Problem_Detected": SolveStatus.INFEASIBLE,
        "Invalid_Number_Detected": SolveStatus.NON_FINITE,
    }
)
"""IPOPT's ``return_status`` strings with a status of their own."""


def status_from_ipopt(
    return_status: str,
    *,
    table: Mapping[str, SolveStatus] = IPOPT_STATUS,
    otherwise: SolveStatus = SolveStatus.FAILED,
) -> SolveStatus:
    """Map IPOPT's ``return_status`` string to a :class:`SolveStatus`.

    Parameters
    ----------
    return_status : str
        ``nlpsol.stats()["return_status"]``.
    table : mapping, optional
        IPOPT strings to statuses (default :data:`IPOPT_STATUS`); a solver
        with its own reading of some strings passes an extended table.
    otherwise : SolveStatus, optional
        Status of a string not in ``table`` (default :attr:`SolveStatus.FAILED`).

    Returns
    -------
    SolveStatus
        The status.
    """
    return table.get(return_status, otherwise)


class Verdict(Protocol):
    """What a result's ``check()`` returns: the status it deserves and why."""

    @property
    def status(self) -> SolveStatus:
        """The status the result deserves."""
        ...

    @property
    def message(self) -> str:
        """What failed (empty if nothing did)."""
        ...

    @property
    def passed(self) -> bool:
        """Whether :attr:`status` is a success."""
        ...


class Checkable(Protocol):
    """A frozen result dataclass with a status, a message and an independent ``check()``."""

    @property
    def status(self) -> SolveStatus:
        """How the solve ended."""
        ...

    @property
    def message(self) -> str:
        """The solver's message."""
        ...

    def check(self) -> Verdict:
        """Re-check the result independently of the solver's flag."""
        ...


ResultT = TypeVar("ResultT", bound=Checkable)


def apply_check(result: ResultT, *, label: str = "") -> ResultT:
    """Return ``result`` with the status its independent check gives it.

    A success claim that ``result.check()`` refutes is downgraded: the check's
    status replaces ``status`` and ``"; <label><why>"`` is appended to
    ``message``. A failure, and a success the check confirms, are returned as
    they are (the check only downgrades).

    Parameters
    ----------
    result : Checkable
        A frozen result dataclass as a solver built it or a loader read it.
    label : str, optional
        Text put before the check's reason in the message.

    Returns
    -------
    Checkable
        ``result`` itself, or a copy with the downgraded status and message.
    """
    if not result.status.success:
        return result
    verdict = result.check()
    if verdict.passed:
        return result
    message = f"{result.message}; {label}{verdict.message}"
    return cast(
        ResultT, dataclasses.replace(cast(Any, result), status=verdict.status, message=message)
    )
