r"""Adaptive mesh refinement until the plan is certified: :func:`refine`, its record.

Each round solves on the current grid, measures every interval's collocation
error (:mod:`youbot_opt.trajopt.mesh`) and certifies the plan
(:func:`youbot_opt.trajopt.certify.certify`). Intervals over the tolerance are
split at ``e ~ h^m`` (:mod:`youbot_opt.trajopt.mesh`);
the next round starts from the previous solution (:func:`transfer_start`) until
certified or the :class:`RefinementBudget` runs out. :func:`refine` returns the
result and the :class:`Refinement` (its rounds) as :class:`Refined`. See docs/refinement.md.

>>> result, refinement = refine(TrajOptSolver(problem))  # doctest: +SKIP
"""

from __future__ import annotations

import dataclasses
import logging
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from youbot_opt._checks import check_int, check_positive, check_time_limit, check_unit_interval
from youbot_opt._typing import Array
from youbot_opt.collision.clearance import ClearanceCertificate, clearance_checker
from youbot_opt.collision.exact import ExactChecker
from youbot_opt.dynamics.numeric import STIFF_RATIO, damping_rate
from youbot_opt.exceptions import ParameterError, SolveFailed
from youbot_opt.nlp.status import SolveStatus
from youbot_opt.trajopt.certify import BoundCheck, Certificate, Tolerances, certify, check_bounds
from youbot_opt.trajopt.clearance import certify_plan_clearance
from youbot_opt.trajopt.mesh import (
    ERROR_EXPONENTS,
    CollocationError,
    collocation_error,
    observed_exponents,
    predicted_knots,
    solution_moved,
    split_grid,
    switching_intervals,
)
from youbot_opt.trajopt.quadrature import grid_weights
from youbot_opt.trajopt.result import TrajOptResult
from youbot_opt.trajopt.solver import BoundaryLike, GuessLike, TrajOptSolver
from youbot_opt.trajopt.tool_certificate import ToolCertificate, certify_plan_tool
from youbot_opt.trajopt.transcription.base import BOUND_NAMES

__all__ = [
    "BoundChecks",
    "FALLBACK",
    "Refined",
    "Refinement",
    "RefinementBudget",
    "RefinementRound",
    "refine",
    "overshoot_note",
    "stiffness_note",
    "torque_overshoot",
    "transfer_start",
]

_log = logging.getLogger(__name__)


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
        Run the certificate's forward simulation on every round, for the
        history. ``False`` (default) decides cheaply: the collocation error
        estimate first, the simulation only on the rounds whose errors are
        within the tolerance (the plans that may pass) and on the last round,
        so the plan returned always has its full certificate, and a plan is
        never called certified without it. The other rounds have no
        certificate figures; they get the certificate's bound checks alone
        (``certificate_passed`` False if one fails, else None), which the
        ``fallback`` needs.
    tolerances : Tolerances or None
        The certificate's thresholds (its defaults when None).
    safety : float
        Intervals are split so that their predicted error is ``safety *
        tolerance`` (in (0, 1]; a margin for what the prediction misses): 1 by default.
    fallback : bool
        When a Hermite-Simpson round fails the certificate by a torque
        overshoot no grid can remove (:func:`overshoot_note`), continue with the
        trapezoidal scheme on the same grid, warm-started from that round's
        plan, within the same budget (default); ``False`` keeps
        Hermite-Simpson and ends uncertified, the reason naming the scheme to use.
    """

    tolerance: float = 1e-3
    max_rounds: int = 8
    max_knots: int = 1000
    time_limit: float | None = None
    max_pieces: int = 16
    certify: bool = True
    certify_every_round: bool = False
    tolerances: Tolerances | None = None
    safety: float = 1.0
    fallback: bool = True

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
        if not isinstance(self.fallback, bool):
            raise ParameterError(
                f"fallback must be True or False, got {self.fallback!r}", name="fallback"
            )

    def describe(self) -> str:
        """One line: the tolerance and the limits."""
        limit = "none" if self.time_limit is None else f"{self.time_limit:g} s"
        return (
            f"error tolerance {self.tolerance:g}, at most {self.max_rounds} rounds, "
            f"{self.max_knots} knots, time limit {limit}"
            + ("" if self.fallback else ", no trapezoidal fallback")
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
    objective_history : ndarray, shape (iterations + 1,)
        IPOPT's objective per iteration of the round's solve (iteration 0: its start).
    method : str
        The round's transcription (it changes once when the budget's ``fallback`` acts).
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
    objective_history: Array = field(default_factory=lambda: np.zeros(0), compare=False)
    method: str = ""

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
            "method": self.method,
        }


@dataclass(frozen=True, slots=True)
class Refinement:
    """The record of a refinement: its verdict, budget and rounds (:attr:`Refined.refinement`).

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


class Refined(NamedTuple):
    """What :func:`refine` returns: the refined result and the record of its rounds.

    Attributes
    ----------
    result : TrajOptResult
        The last round's result (the status stays the solve's own; the
        message names why the plan is not certified, when it is not).
    refinement : Refinement
        The record: verdict, reason, budget and every round.
    """

    result: TrajOptResult
    refinement: Refinement

    @property
    def certified(self) -> bool:
        """True only if the collocation error and (if asked) the certificate both passed."""
        return self.refinement.certified

    def summary(self) -> dict[str, object]:
        """Return the result's :meth:`~TrajOptResult.summary` with the refinement's verdict."""
        return {**self.result.summary(), "certified": self.certified}

    def require_certified(self) -> TrajOptResult:
        """Return :attr:`result` if the plan is :attr:`certified`, else raise :class:`SolveFailed`.

        The result's status and ``success`` stay the solver's verdict (a plan
        IPOPT solved but refinement could not certify is still "solved"), so
        ``result.raise_for_status()`` accepts it; this is the stricter check.

        Raises
        ------
        SolveFailed
            If the solve failed, or if refinement stopped uncertified (the
            message names the failed check and the budget).
        """
        self.result.raise_for_status()
        if not self.certified:
            why = self.refinement.reason.removeprefix("not certified: ")
            raise SolveFailed(
                f"trajectory {self.result.status.value}, NOT certified: {why}", result=self.result
            )
        return self.result


FALLBACK = "trapezoidal"
"""The scheme :func:`refine` continues with when Hermite-Simpson cannot pass the
certificate (:func:`overshoot_note`; ``RefinementBudget.fallback``): its torque is
linear between knots and cannot overshoot."""


def stiffness_note(
    result: TrajOptResult, error: CollocationError, tolerance: float, exponent: float | Array
) -> str:
    """Say why a grid cannot resolve the joint damping, with numbers ("" if it can).

    A grid is stiff when the fastest damping rate (:func:`damping_rate`) times its
    longest interval exceeds :data:`STIFF_RATIO`: the velocities relax faster
    than any interval resolves. Trapezoidal and Hermite-Simpson collocation are
    A-stable but not L-stable (their amplification tends to -1 and +1 for
    infinitely stiff modes), so what the grid does not resolve is carried along
    the motion instead of decaying, and the error falls more slowly than
    ``h^m`` (docs/refinement.md, "Stiff joint damping"). The note gives the
    rate, the joint, ``rate * h``, the exponent seen at the worst interval and
    the knots :func:`predicted_knots` would need at it, and for those two
    schemes points to the L-stable Radau IIA collocation (``method="radau"``).
    """
    if result.trajectory is None:
        return ""
    stiff = damping_rate(result.problem.robot, result.trajectory.q, damping=result.problem.damping)
    h = float(np.max(error.steps))
    if stiff.rate * h <= STIFF_RATIO:
        return ""
    worst = error.worst_interval
    m = float(np.broadcast_to(np.asarray(exponent, dtype=float), error.relative.shape)[worst])
    needed = predicted_knots(error.relative, tolerance, exponent)
    return (
        f"; stiff joint damping: {stiff.joint or 'a joint'} relaxes at up to {stiff.rate:.3g} 1/s "
        f"(time constant {1.0 / stiff.rate:.2g} s), rate x longest interval = {stiff.rate * h:.3g} "
        f"(unresolved above {STIFF_RATIO:g}); the worst interval's error falls like h^{m:.2g}, "
        f"so about {needed:.2g} knots would be needed"
        + (
            ""
            if result.method == "radau"
            else "; the L-stable Radau collocation (method='radau', --transcription radau) "
            "carries such a joint on its slow motion"
        )
    )


class BoundChecks(NamedTuple):
    """The certificate's bound checks alone (no simulation), of a round over the tolerance.

    Refinement runs the forward simulation only on rounds within the error
    tolerance and on the last one (docs/refinement.md); the other rounds get these
    checks, which :func:`torque_overshoot` and :func:`overshoot_note` read as they
    read a :class:`~youbot_opt.trajopt.certify.Certificate`'s.

    Attributes
    ----------
    bounds : tuple of BoundCheck
        Velocity and torque bounds at knots and between them (20 samples an interval).
    tolerances : Tolerances
        The tolerances the checks are judged by (relative, dimensionless).
    """

    bounds: tuple[BoundCheck, ...]
    tolerances: Tolerances


def _bound_checks(result: TrajOptResult, tolerances: Tolerances | None) -> BoundChecks | None:
    """Return the certificate's bound checks of a plan (None without a trajectory).

    The same :func:`~youbot_opt.trajopt.certify.check_bounds` call :func:`certify`
    makes (the result's bounds, 20 samples per interval), without its simulations.
    """
    if result.trajectory is None:
        return None
    checks = check_bounds(result.trajectory, result.bounds())
    return BoundChecks(checks, Tolerances() if tolerances is None else tolerances)


def torque_overshoot(
    result: TrajOptResult, cert: Certificate | BoundChecks | None
) -> BoundCheck | None:
    """Return the torque overshoot no grid removes from a Hermite-Simpson plan (None if none).

    The certificate's first failed between-knots torque check, when the plan's
    active bounds switch inside an interval: :func:`overshoot_note`'s case.
    """
    if cert is None or result.method != "hermite_simpson" or result.trajectory is None:
        return None
    limit = cert.tolerances.between_bound
    over = [
        b
        for b in cert.bounds
        if b.quantity == "torque" and b.where == "between" and not b.relative <= limit
    ]
    if not over or not np.any(switching_intervals(result)):
        return None
    return over[0]


def overshoot_note(result: TrajOptResult, cert: Certificate | BoundChecks | None) -> str:
    """Say why splitting cannot pass a Hermite-Simpson torque overshoot ("" if not the case).

    Hermite-Simpson's torque is the quadratic through an interval's knot and
    midpoint torques. Where a torque switches between its bounds inside an
    interval (a bang-bang arc, at ``beta`` near 1) the quadratic through
    ``u, u, -u`` peaks at ``1.25 u`` however short the interval, so the
    certificate's between-knots torque check keeps failing, by up to 25 % of
    the half range, whatever the grid. The trapezoidal scheme's torque is
    linear between knots and cannot overshoot (docs/timed.md measures both).
    """
    b = torque_overshoot(result, cert)
    if b is None:
        return ""
    return (
        f"; joint {b.joint}'s torque switches between its bounds inside an interval (worst at "
        f"t = {b.time:.4g} s): the Hermite-Simpson quadratic overshoots there by up to 25 % "
        "however short the interval, so splitting cannot pass the between-knots torque check; "
        "the trapezoidal transcription (linear torque, --transcription trapezoidal) can"
    )


def _knot_weights(t: Array) -> Array:
    h = np.diff(t)
    return grid_weights("trapezoidal", h)[0]


def transfer_start(
    old: TrajOptResult, solver: TrajOptSolver, parent: NDArray[np.intp], t_new: Array
) -> tuple[Array, Array, Array]:
    """Primal-dual start on ``solver``'s NLP from ``old``, interpolated onto ``t_new``.

    Primal: ``old``'s trajectory sampled at the new knots (and midpoints).
    Duals: a defect or boundary multiplier approximates the costate and is
    copied from the parent interval; a pointwise bound multiplier is a density
    times its quadrature weight, so knot ones are interpolated as densities
    (per trapezoidal weight) and re-weighted, interval ones shared among the pieces.
    Rows tied to no knot or interval (the boundary conditions, the pinned
    waypoints of :mod:`youbot_opt.trajopt.timed`) keep their multipliers.
    """
    nlp, method = solver.nlp, solver.method
    n_new = t_new.size
    if old.trajectory is None:  # the loop stops before: no error estimate without one
        raise ParameterError("cannot transfer a result without a trajectory", name="old")
    values = method.knot_guess(old.trajectory, n_new)
    x0 = nlp.variables.pack(values)
    t_old = old.trajectory.t
    pieces = np.bincount(parent, minlength=t_old.size - 1)[parent][:, None]
    w_old, w_new = _knot_weights(t_old), _knot_weights(t_new)
    lam_x_blocks: dict[str, Array] = {}
    for name, block in nlp.variables.blocks.items():
        family = BOUND_NAMES[name]
        lam = old.multipliers[f"{family}_lower"] + old.multipliers[f"{family}_upper"]
        if name == "dt":
            lam_x_blocks[name] = lam
        elif block.count == n_new:  # knot block: densities at the knots
            density = lam / w_old[:, None]
            lam_x_blocks[name] = (
                np.stack(
                    [np.interp(t_new, t_old, density[:, j]) for j in range(block.width)], axis=1
                )
                * w_new[:, None]
            )
        else:  # interval block
            lam_x_blocks[name] = lam[parent] / pieces
    lam_g_blocks: dict[str, Array] = {}
    for name, block in nlp.constraints.blocks.items():
        lam = np.asarray(old.multipliers[name], dtype=float)
        if block.count == 1 or block.count not in (n_new - 1, n_new):  # rows of no knot
            lam_g_blocks[name] = lam
        elif name in nlp.path_limits and block.count == n_new:  # knot rows: densities
            density = lam / w_old[:, None]
            lam_g_blocks[name] = (
                np.stack(
                    [np.interp(t_new, t_old, density[:, j]) for j in range(block.width)], axis=1
                )
                * w_new[:, None]
            )
        elif name in nlp.path_bounds or name in nlp.path_limits:
            lam_g_blocks[name] = lam[parent] / pieces
        else:
            lam_g_blocks[name] = lam[parent]
    return x0, nlp.variables.pack(lam_x_blocks), nlp.constraints.pack(lam_g_blocks)


class _Checks(NamedTuple):
    """What a round measured of its plan (:func:`_check`)."""

    error: CollocationError | None
    cert: Certificate | None
    clear: ClearanceCertificate | None
    tool: tuple[ToolCertificate, ...]
    bounds: BoundChecks | None  # the bound checks alone, when the certificate was not run


def _certificate(
    result: TrajOptResult, budget: RefinementBudget, deadline: float | None, processes: int
) -> Certificate | None:
    """Return the full certificate (forward simulation) within the time budget's rest."""
    limit = None if deadline is None else deadline - time.perf_counter()
    if limit is not None and limit <= 0.0:  # none left: not certified, said by the caller
        return None
    return certify(result, tolerances=budget.tolerances, time_limit=limit, processes=processes)


def _check(
    result: TrajOptResult,
    budget: RefinementBudget,
    deadline: float | None,
    checker: ExactChecker | None = None,
    processes: int = 1,
) -> _Checks:
    """Error estimate first; the forward simulation only when the plan may pass.

    The certificate (:func:`certify`) runs when every interval is within the
    tolerance, or on every round with ``budget.certify_every_round``; a plan
    over the tolerance cannot be certified this round, so it gets only the
    certificate's bound checks (no simulation; a failed one fails the round's
    certificate, and a Hermite-Simpson torque overshoot among them calls the
    trapezoidal fallback). The clearance and tool certificates, which also
    choose the intervals to split, run every round.
    """
    error: CollocationError | None = None
    cert: Certificate | None = None
    clear: ClearanceCertificate | None = None
    tool: tuple[ToolCertificate, ...] = ()
    bounds: BoundChecks | None = None
    if result.trajectory is not None:
        error = collocation_error(result)
        wanted = budget.certify_every_round or error.max <= budget.tolerance
        if result.success and budget.certify and wanted:
            cert = _certificate(result, budget, deadline, processes)
        elif result.success and budget.certify:
            bounds = _bound_checks(result, budget.tolerances)
        spec = result.problem.clearance
        if result.success and checker is not None and spec is not None:
            clear = certify_plan_clearance(
                result.trajectory, result.problem.robot, checker, margin=spec.margin
            )
        if cert is not None and cert.tool:
            tool = cert.tool
        elif result.success and result.problem.tool:
            tool = certify_plan_tool(result.trajectory, result.problem.robot, result.problem.tool)
    return _Checks(error, cert, clear, tool, bounds)


def _record(
    index: int, result: TrajOptResult, checks: _Checks, solve_time: float, check_time: float
) -> RefinementRound:
    """Return the round's record of its plan and checks."""
    error, cert, clear, tool = checks.error, checks.cert, checks.clear, checks.tool
    failures = () if cert is None else tuple(cert.failures())
    if clear is not None and not clear.certified:
        t, a, b, d = min(clear.failures, key=lambda f: f[3])
        failures += (f"clearance {d:.3g} m < margin {clear.margin:g} m at t = {t:.4g} s "
                     f"({a!r} / {b!r}, coal)",)  # fmt: skip
    if cert is None or not cert.tool:  # the certificate's failures list its own
        failures += tuple(c.describe() for c in tool if not c.certified)
    passed = None if cert is None else cert.ok
    if cert is None and checks.bounds is not None:  # a failed bound check fails the certificate
        tol = checks.bounds.tolerances
        over = [
            f"bound {c.quantity}, {'at' if c.where == 'knots' else 'between'} knots (relative) "
            f"= {c.relative:.3g} > {limit:.3g}"
            for c in checks.bounds.bounds
            if not c.relative
            <= (limit := tol.knot_bound if c.where == "knots" else tol.between_bound)
        ]
        failures += tuple(over)
        passed = False if over else None
    if clear is not None:
        passed = clear.certified and (passed is None or passed)
    if tool:
        passed = all(c.certified for c in tool) and (passed is None or passed)
    nan = math.nan
    return RefinementRound(
        index=index,
        n_knots=result.problem.n_knots,
        status=result.status.value,
        objective=result.objective,
        duration=result.duration,
        max_error=error.max if error is not None else nan,
        t=error.t if error is not None else np.zeros(0),
        errors=error.relative if error is not None else np.zeros(0),
        certificate_passed=passed,
        failures=failures,
        feedback_rms=nan if cert is None else cert.feedback_rms,
        feedback_peak=nan if cert is None else cert.feedback_peak,
        local_position=nan if cert is None else cert.local_position_max,
        iterations=result.iterations,
        solve_time=solve_time,
        check_time=check_time,
        objective_history=np.asarray(result.objective_history, dtype=float),
        method=result.method,
    )


def _report(
    rounds: list[RefinementRound],
    record: RefinementRound,
    check_time: float,
    progress: Callable[[RefinementRound], None] | None,
) -> None:
    """Append the round (with its check time), log it and tell ``progress``."""
    record = dataclasses.replace(record, check_time=check_time)
    rounds.append(record)
    _log.info(
        "refinement round %d: %d knots, f = %.6g, T = %.4g s, max error %.3g, certificate %s",
        record.index, record.n_knots, record.objective, record.duration, record.max_error,
        record.certificate_passed,
    )  # fmt: skip
    if progress is not None:
        progress(record)


def _clearance_errors(
    error: CollocationError,
    clear: ClearanceCertificate | None,
    tolerance: float,
    tool: tuple[ToolCertificate, ...] = (),
) -> Array:
    """Interval errors raised above ``tolerance`` where the clearance or a tool certificate fails.

    The intervals holding a failing sample are split like those whose
    collocation error is too large (the new knots and midpoints are constrained).
    """
    errors = np.array(error.relative, dtype=float)
    times = [] if clear is None else [f[0] for f in clear.failures]
    times += [f[0] for c in tool for f in c.failures]
    if not times:
        return errors
    t = np.asarray(error.t, dtype=float)
    for time_ in times:
        k = int(np.clip(np.searchsorted(t, time_, side="right") - 1, 0, errors.size - 1))
        errors[k] = max(errors[k], 4.0 * tolerance)
    return errors


def refine(
    solver: TrajOptSolver,
    *,
    beta: float = 0.5,
    bound_scale: float = 1.0,
    guess: GuessLike = None,
    start: BoundaryLike | None = None,
    goal: BoundaryLike | None = None,
    seed: int | None = None,
    budget: RefinementBudget | None = None,
    progress: Callable[[RefinementRound], None] | None = None,
    first: TrajOptResult | None = None,
    processes: int = 1,
) -> Refined:
    """Solve, then refine the grid until the plan is certified or the budget runs out.

    A Hermite-Simpson round whose torque overshoots between knots where no grid
    can remove it (:func:`torque_overshoot`) is followed by the trapezoidal
    scheme on the same knots (:data:`FALLBACK`, warm-started from that plan),
    within the same budget, unless ``budget.fallback`` is False.

    Parameters
    ----------
    solver : TrajOptSolver
        The starting grid (its problem's ``n_knots`` and its transcription's grid).
    beta, bound_scale, guess, start, goal, seed
        As :meth:`TrajOptSolver.solve`; the guess is used in round 0 only.
    budget : RefinementBudget, optional
        Tolerance and limits (:class:`RefinementBudget` defaults).
    progress : callable, optional
        Called with each :class:`RefinementRound` as it completes.
    first : TrajOptResult, optional
        A result already solved on ``solver``'s grid (e.g. the best start of a
        multistart): round 0 uses it instead of solving again. Its ``beta``,
        bound scale and boundary states then override the arguments.
    processes : int, optional
        Processes each certificate's simulations may use (:func:`certify`'s
        ``processes``; 1 by default, as in a sweep's workers; the command line
        gives a single plan 2 on a machine with two cores or more).

    Returns
    -------
    Refined
        The last round's result and the :class:`Refinement` record:
        ``refinement.certified`` is True for a certified plan; otherwise
        ``refinement.reason`` (also appended to the result's message) names the
        failed check and the budget. The result's status stays the solve's own.

    Raises
    ------
    ParameterError
        On a bad solver or budget, or any bad argument of the solve.
    """
    if not isinstance(solver, TrajOptSolver):
        raise ParameterError(
            f"solver must be a TrajOptSolver, got {type(solver).__name__}", name="solver"
        )
    budget = RefinementBudget() if budget is None else budget
    if not isinstance(budget, RefinementBudget):
        raise ParameterError("budget must be a RefinementBudget", name="budget")
    processes = check_int(processes, "processes", minimum=1)
    exponent = ERROR_EXPONENTS.get(solver.method.name)
    if exponent is None:
        raise ParameterError(
            f"no error estimate for transcription {solver.method.name!r}", name="solver"
        )
    tic = time.perf_counter()
    deadline = None if budget.time_limit is None else tic + budget.time_limit
    if first is not None:
        if not isinstance(first, TrajOptResult) or first.problem.n_knots != solver.problem.n_knots:
            raise ParameterError(
                "first must be a TrajOptResult solved on the solver's grid "
                f"({solver.problem.n_knots} knots)",
                name="first",
            )
        result, seed = first, first.seed
        beta, bound_scale, start, goal = first.beta, first.bound_scale, first.start, first.goal
        solve_time = first.wall_time
    else:
        result = solver.solve(
            beta=beta, bound_scale=bound_scale, guess=guess, start=start, goal=goal, seed=seed
        )
        solve_time = time.perf_counter() - tic + solver.build_time
    kwargs = {"beta": beta, "bound_scale": bound_scale, "start": start, "goal": goal, "seed": seed}
    rounds: list[RefinementRound] = []
    tolerance = budget.tolerance
    cert: Certificate | None = None
    exponents: float | Array = float(exponent)
    split: tuple[Array, NDArray[np.intp], float] | None = None  # previous errors, parents, T
    spec = solver.problem.clearance
    checker = None if spec is None else clearance_checker(solver.problem.robot, spec)
    clear: ClearanceCertificate | None = None
    tool: tuple[ToolCertificate, ...] = ()
    while True:
        check_tic = time.perf_counter()
        checks = _check(result, budget, deadline, checker, processes)
        error, cert, clear, tool = checks.error, checks.cert, checks.clear, checks.tool
        record = _record(len(rounds), result, checks, solve_time, 0.0)
        if (
            error is not None
            and split is not None
            and not solution_moved(split[2], result.duration)
        ):
            stretch = result.duration / split[2]  # every interval's h changed by this factor
            exponents = observed_exponents(split[0], error.relative, split[1], exponents, stretch)
        elif error is not None:  # first or moved solution: a bound switch inside lowers m
            exponents = np.where(switching_intervals(result), 1.0, float(exponent))
        reason = ""
        if error is None or not result.success:
            reason = f"the solve of round {record.index} failed ({result.status.value})"
        elif (
            error.max <= budget.tolerance
            and (not budget.certify or (cert is not None and cert.ok))
            and (clear is None or clear.certified)
            and all(c.certified for c in tool)
        ):
            reason = "certified"
        if reason or error is None:
            _report(rounds, record, time.perf_counter() - check_tic, progress)
            break
        clipped = (clear is not None and not clear.certified) or not all(c.certified for c in tool)
        if error.max <= tolerance and not clipped:  # certificate failed: split tighter
            tolerance = 0.25 * error.max
        why = (
            f"max error {error.max:.3g} > {budget.tolerance:g}"
            if error.max > budget.tolerance
            else f"certificate failed ({'; '.join(record.failures)})"
            if cert is not None or clipped
            else "no time left for the certificate"
        )
        overshoot = overshoot_note(result, cert if cert is not None else checks.bounds)
        switch = budget.fallback and bool(overshoot)
        if switch:  # no grid passes Hermite-Simpson here: the trapezoid on the same knots
            h = np.diff(error.t)
            fractions, parent = h / h.sum(), np.arange(h.size, dtype=np.intp)
        else:
            errors = _clearance_errors(error, clear, budget.safety * tolerance, tool)
            cap = budget.max_pieces
            while True:  # a grid beyond max_knots: fewer pieces per interval first, then stop
                fractions, parent = split_grid(
                    error.t, errors, budget.safety * tolerance, exponents, cap
                )
                if fractions.size + 1 <= budget.max_knots or cap == 2:
                    break
                cap = max(2, cap // 2)
        split = None if switch else (error.relative, parent, result.duration)
        n_new = fractions.size + 1
        elapsed = time.perf_counter() - tic
        if len(rounds) + 1 >= budget.max_rounds:
            reason = f"{why} after {len(rounds) + 1} rounds"
        elif n_new > budget.max_knots:
            reason = f"{why}; the next grid needs {n_new} knots"
        elif budget.time_limit is not None and elapsed >= budget.time_limit:
            reason = f"{why} after {elapsed:.3g} s"
        if reason:
            if cert is None and result.success and budget.certify:
                # the plan returned has its full certificate, certified or not
                cert = _certificate(result, budget, deadline, processes)
                checks = checks._replace(cert=cert, tool=cert.tool or tool if cert else tool)
                record = _record(record.index, result, checks, solve_time, 0.0)
                overshoot = overshoot_note(result, cert if cert is not None else checks.bounds)
            note = stiffness_note(result, error, budget.tolerance, exponents) + overshoot
            reason = f"not certified: {reason}{note} (budget: {budget.describe()})"
            _report(rounds, record, time.perf_counter() - check_tic, progress)
            break
        _report(rounds, record, time.perf_counter() - check_tic, progress)
        round_tic = tic + elapsed
        left = None if budget.time_limit is None else budget.time_limit - elapsed  # > 0 here
        if switch:
            _log.info("refinement: %s; continuing with the trapezoidal scheme", overshoot[2:])
            solver = solver.with_method(FALLBACK, max_wall_time=left)
            exponent = ERROR_EXPONENTS[FALLBACK]
            exponents, tolerance = float(exponent), budget.tolerance
        else:
            solver = solver.on_grid(fractions, max_wall_time=left)  # shares dynamics, kernels
        t_new = solver.method.solution_times(result.duration / (n_new - 1), n_new)
        try:
            initial = transfer_start(result, solver, parent, t_new)
        except KeyError:  # no multipliers (a failed solve): primal only
            initial = None
        previous = result
        result = solver.solve(guess=previous.trajectory, initial=initial, **kwargs)  # type: ignore[arg-type]
        out_of_time = result.status is SolveStatus.MAX_TIME and deadline is not None
        if not result.success and initial is not None and not out_of_time:  # cold, same guess
            result = solver.solve(guess=previous.trajectory, warm_start=False, **kwargs)  # type: ignore[arg-type]
            out_of_time = result.status is SolveStatus.MAX_TIME and deadline is not None
        solve_time = time.perf_counter() - round_tic
        if out_of_time and budget.time_limit is not None:  # keep the last grid's plan, say why
            reason = (
                f"not certified: {why}; the time limit ran out in round {len(rounds)}'s solve "
                f"({n_new} knots, {solve_time:.3g} s), so round {len(rounds) - 1}'s plan is "
                f"returned (budget: {budget.describe()})"
            )
            result = previous
            break
    refinement = Refinement(
        certified=reason == "certified",
        reason=reason,
        budget=budget,
        rounds=tuple(rounds),
        elapsed=time.perf_counter() - tic,
        certificate=cert,
    )
    message = result.message if refinement.certified else f"{result.message}; {reason}"
    return Refined(dataclasses.replace(result, message=message), refinement)
