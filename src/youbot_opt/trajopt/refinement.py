"""The record of a mesh refinement: its budget, its rounds, its verdict.

Plain frozen data, kept apart from :mod:`youbot_opt.trajopt.refine` (the loop)
so that :class:`~youbot_opt.trajopt.result.TrajOptResult` can carry a
:class:`Refinement` without importing the solver. The budget says when the
loop stops; each round keeps its grid, its interval errors and the
certificate's figures, for the tables and :func:`youbot_opt.viz.plots.trajopt.plot_refinement`.

>>> result.refinement.rounds[-1].n_knots  # doctest: +SKIP
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from youbot_opt._checks import check_int, check_positive, check_time_limit, check_unit_interval
from youbot_opt._typing import Array
from youbot_opt.exceptions import ParameterError
from youbot_opt.trajopt.certificate import Certificate, Tolerances

__all__ = ["Refinement", "RefinementBudget", "RefinementRound"]


@dataclass(frozen=True, slots=True)
class RefinementBudget:
    """Tolerance and limits of :func:`refine`.

    Attributes
    ----------
    tolerance : float
        Largest relative collocation error of any interval (dimensionless,
        :attr:`CollocationError.relative`); 1e-3 by default.
    max_rounds : int
        Largest number of solves (the first grid counts as round 0).
    max_knots : int
        Largest grid; a round that would exceed it is not solved.
    time_limit : float or None
        Wall time in [s] after which no new round starts (None: no limit); it
        also caps each round's IPOPT solves (``max_wall_time``: what is left; a
        round stopped by it returns the previous round's plan, uncertified, and
        says so) and the certificate's simulations (``certify(time_limit=...)``
        gets what is left), whose certificate is then incomplete and fails.
    max_pieces : int
        Most pieces one interval is split into per round (halved, down to 2,
        while the next grid would exceed ``max_knots``).
    certify : bool
        Also require the forward-simulation certificate to pass.
    certify_every_round : bool
        Certify every round, for the history (default); ``False`` certifies
        only the rounds whose errors are within the tolerance (faster; the
        other rounds then have no certificate figures).
    tolerances : Tolerances or None
        The certificate's thresholds (its defaults when None).
    safety : float
        Intervals are split so that their predicted error is ``safety *
        tolerance`` (in (0, 1]; a margin for what the prediction misses): 1 by default.
    """

    tolerance: float = 1e-3
    max_rounds: int = 8
    max_knots: int = 1000
    time_limit: float | None = None
    max_pieces: int = 16
    certify: bool = True
    certify_every_round: bool = True
    tolerances: Tolerances | None = None
    safety: float = 1.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "tolerance", check_positive(self.tolerance, "tolerance"))
        object.__setattr__(self, "max_rounds", check_int(self.max_rounds, "max_rounds", minimum=1))
        object.__setattr__(self, "max_knots", check_int(self.max_knots, "max_knots", minimum=2))
        object.__setattr__(self, "max_pieces", check_int(self.max_pieces, "max_pieces", minimum=2))
        object.__setattr__(self, "time_limit", check_time_limit(self.time_limit, "time_limit"))
        safety = check_unit_interval(
            self.safety, "safety", note=" and > 0 (1 = split to the tolerance)"
        )
        if safety == 0.0:
            raise ParameterError(
                "safety must be > 0 (1 = split to the tolerance), got 0.0",
                name="safety",
                value=self.safety,
            )
        object.__setattr__(self, "safety", safety)

    def describe(self) -> str:
        """One line: the tolerance and the limits."""
        limit = "none" if self.time_limit is None else f"{self.time_limit:g} s"
        return (
            f"error tolerance {self.tolerance:g}, at most {self.max_rounds} rounds, "
            f"{self.max_knots} knots, time limit {limit}"
        )


@dataclass(frozen=True, slots=True)
class RefinementRound:
    """One solve of a refinement.

    Attributes
    ----------
    index : int
        Round number (0 = the starting grid).
    n_knots : int
        Knots of this round's grid.
    status : str
        The solve's status value.
    objective, duration : float
        ``f`` and ``T`` [s] of the solve.
    max_error : float
        Largest relative interval error.
    t : ndarray, shape (n_knots,)
        The grid [s].
    errors : ndarray, shape (n_knots - 1,)
        Relative error of each interval.
    certificate_passed : bool or None
        The certificate's verdict (None: not certified, e.g. a failed solve).
    failures : tuple of str
        The certificate's failed checks.
    feedback_rms, feedback_peak, local_position : float
        Certificate figures: worst RMS and peak feedback/plan torque ratios,
        worst one-interval position error [rad] (NaN when not certified).
    iterations : int
        IPOPT iterations.
    solve_time, check_time : float
        Wall time [s] of the build and solve, and of the error estimate and certificate.
    """

    index: int
    n_knots: int
    status: str
    objective: float
    duration: float
    max_error: float
    t: Array
    errors: Array
    certificate_passed: bool | None
    failures: tuple[str, ...]
    feedback_rms: float
    feedback_peak: float
    local_position: float
    iterations: int
    solve_time: float
    check_time: float

    def summary(self) -> dict[str, object]:
        """JSON-ready figures of the round (arrays left out)."""

        def num(x: float) -> float | None:
            return float(x) if math.isfinite(x) else None

        return {
            "round": self.index,
            "n_knots": self.n_knots,
            "status": self.status,
            "objective": num(self.objective),
            "duration_s": num(self.duration),
            "max_error": num(self.max_error),
            "certificate_passed": self.certificate_passed,
            "failures": list(self.failures),
            "feedback_rms": num(self.feedback_rms),
            "feedback_peak": num(self.feedback_peak),
            "local_position_rad": num(self.local_position),
            "iterations": self.iterations,
            "solve_time_s": self.solve_time,
            "check_time_s": self.check_time,
        }


@dataclass(frozen=True, slots=True)
class Refinement:
    """The record of a refinement, stored in :attr:`TrajOptResult.refinement`.

    Attributes
    ----------
    certified : bool
        Every interval within the tolerance, the solve successful and (if the
        budget asks for it) the certificate passed.
    reason : str
        Why it stopped: ``"certified"`` or which check failed and the budget.
    budget : RefinementBudget
        The tolerance and limits used.
    rounds : tuple of RefinementRound
        Every round, first to last.
    elapsed : float
        Total wall time [s].
    certificate : Certificate or None
        The last round's certificate.
    """

    certified: bool
    reason: str
    budget: RefinementBudget
    rounds: tuple[RefinementRound, ...]
    elapsed: float
    certificate: Certificate | None = field(default=None, compare=False)

    def summary(self) -> dict[str, object]:
        """JSON-ready record (per-round figures, no arrays)."""
        return {
            "certified": self.certified,
            "reason": self.reason,
            "budget": self.budget.describe(),
            "elapsed_s": self.elapsed,
            "rounds": [r.summary() for r in self.rounds],
        }
