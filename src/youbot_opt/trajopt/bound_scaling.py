"""Sensitivity of the optimum to the bounds: the study's bound-scaling sweep.

The study scaled all bounds to 100, 95, 90 and 85 % of the data sheet and
re-solved the ``beta = 0.5`` problem (spec ``trajopt.md``).
:func:`bound_scaling_study` does that with a few seeded starts per scale and
reports per scale the best ``T``, ``W``, ``f`` and the active bounds of the best
solution; with ``SweepOptions(out=DIR)`` every start is saved as it finishes.

    res = bound_scaling_study(solver, (1.0, 0.9), n_starts=5, sweep=SweepOptions(workers=4))
"""

from __future__ import annotations

import math
import time
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass

from youbot_opt._checks import check_beta, check_bound_scale
from youbot_opt._typing import JSONDict
from youbot_opt.exceptions import ParameterError
from youbot_opt.sweeps.options import SweepOptions
from youbot_opt.sweeps.resume import ShardReport
from youbot_opt.sweeps.store import open_store
from youbot_opt.trajopt.multistart import (
    MultistartResult,
    StoredStarts,
    optima_rule,
    stored_tally,
)
from youbot_opt.trajopt.result import ActiveBound
from youbot_opt.trajopt.solver import TrajOptSolver
from youbot_opt.trajopt.sweep import (
    StartJobChain,
    StartJobs,
    StartOutcome,
    check_solver,
    default_dt0,
    solve_starts,
)
from youbot_opt.trajopt.sweep_store import jobs_making, result_codec, sweep_params

__all__ = ["BoundScalingRow", "BoundScalingResult", "bound_scaling_study", "DEFAULT_SCALES"]

DEFAULT_SCALES: tuple[float, ...] = (1.0, 0.95, 0.90, 0.85)
"""The study's bound scale factors."""


@dataclass(frozen=True, slots=True, kw_only=True)
class BoundScalingRow:
    """All starts at one bound scale and the best of them.

    Attributes
    ----------
    bound_scale : float
        Scale factor of the bounds (1.0 = data sheet).
    multistart : MultistartResult
        Every start at this scale.
    active : tuple of ActiveBound
        Active bounds of the best solution (within ``active_tol``).
    """

    bound_scale: float
    multistart: MultistartResult
    active: tuple[ActiveBound, ...] = ()

    @property
    def best(self) -> StartOutcome | None:
        """Best converged start (``None`` if none converged)."""
        return self.multistart.best

    def _best_value(self, name: str) -> float:
        best = self.best
        return float(getattr(best, name)) if best is not None else math.nan

    @property
    def objective(self) -> float:
        """Best objective ``f`` (NaN if no start converged)."""
        return self._best_value("objective")

    @property
    def duration(self) -> float:
        """``T`` of the best solution in [s]."""
        return self._best_value("duration")

    @property
    def work(self) -> float:
        """``W`` of the best solution in [N^2 m^2 s]."""
        return self._best_value("work")

    def active_counts(self) -> dict[str, int]:
        """Count the active bounds per family (``"velocity_upper"``: 3, ...)."""
        return dict(sorted(Counter(a.name for a in self.active).items()))

    def summary(self) -> JSONDict:
        """JSON-ready figures of this scale."""

        def num(x: float) -> float | None:
            return float(x) if math.isfinite(x) else None

        return {
            "bound_scale": self.bound_scale,
            "objective": num(self.objective),
            "duration_s": num(self.duration),
            "work": num(self.work),
            "success_rate": self.multistart.success_rate,
            "n_optima": len(self.multistart.distinct_optima()),
            "active_counts": self.active_counts(),
            "active": [a._asdict() for a in self.active],
        }


@dataclass(frozen=True, slots=True, kw_only=True)
class BoundScalingResult:
    """Result of :func:`bound_scaling_study`.

    Attributes
    ----------
    rows : tuple of BoundScalingRow
        One per scale, in the order given.
    beta : float
        Time weight of every solve.
    seed : int
        Base seed of the starts (the same at every scale).
    wall_time : float
        Wall time of the study in [s].
    """

    rows: tuple[BoundScalingRow, ...]
    beta: float
    seed: int
    wall_time: float = 0.0

    def summary(self) -> JSONDict:
        """JSON-ready summary of every scale."""
        return {
            "beta": self.beta,
            "seed": self.seed,
            "wall_time_s": self.wall_time,
            "rows": [r.summary() for r in self.rows],
        }


def bound_scaling_study(
    solver: TrajOptSolver,
    scales: Sequence[float] = DEFAULT_SCALES,
    *,
    beta: float = 0.5,
    n_starts: int = 5,
    seed: int = 0,
    include_straight: bool = True,
    dt0: float | None = None,
    active_tol: float = 1e-5,
    sweep: SweepOptions = SweepOptions(),  # noqa: B008 - frozen, so sharing it is safe
) -> BoundScalingResult | ShardReport:
    """Solve the problem with every bound scaled by each factor in ``scales``.

    Every scale gets the same start seeds, plus the straight line; all scales'
    starts share one executor. Which bound families are scaled is the problem's
    choice (:attr:`~youbot_opt.trajopt.problem.TrajOptProblem.scaled_bounds`; by
    default position, velocity and torque, as in the study). With
    ``SweepOptions(out=DIR)`` every start is saved as it finishes and a rerun
    resumes.

    Parameters
    ----------
    solver : TrajOptSolver
        The built solver (bounds are solve-time parameters, so it is reused).
    scales : sequence of float
        Distinct bound scale factors > 0 (default: the study's 1.0, 0.95, 0.90, 0.85).
    beta : float
        Time weight in [0, 1].
    n_starts : int
        Seeded random spline starts per scale (same seeds at every scale).
    seed : int
        Base seed.
    include_straight : bool
        Also start from the straight line at every scale.
    dt0 : float, optional
        Time step of the spline guesses in [s] (default
        :func:`youbot_opt.trajopt.multistart.default_dt0`).
    active_tol : float
        Distance from a bound, in its unit, below which it counts as active.
    sweep : SweepOptions
        How the starts of all scales run, as in
        :func:`youbot_opt.trajopt.multistart.run_multistart` (``progress`` counts
        starts over all scales). ``keep_results=False`` (needs ``out``): each
        row's multistart holds no start (they are read from ``out``), only its
        counts, best start and distinct optima, computed once per scale, so
        memory does not grow with ``n_starts``; the rows themselves (one per
        scale, tens at most) are held.

    Returns
    -------
    BoundScalingResult or ShardReport
        One row per scale; a shard run (``sweep.shard``) returns its
        :class:`~youbot_opt.sweeps.resume.ShardReport` instead.

    Raises
    ------
    ParameterError
        On bad arguments (e.g. a scale at which start or goal leave the bounds),
        or if ``sweep.out`` holds a sweep with other parameters.
    """
    tic = time.perf_counter()
    solver = check_solver(solver)
    beta = check_beta(beta)
    values = tuple(check_bound_scale(s) for s in scales)
    if not values or len(set(values)) != len(values):
        raise ParameterError(
            f"scales must be non-empty and distinct, got {list(scales)}", name="scales"
        )
    for s in values:
        solver.problem.check_boundary(s)
    dt0 = default_dt0(solver.problem) if dt0 is None else float(dt0)
    jobs_by_scale = [
        StartJobs(
            n_starts,
            seed=seed,
            beta=beta,
            bound_scale=s,
            include_straight=include_straight,
            dt0=dt0,
            prefix=f"scale{i:02d}_",
        )
        for i, s in enumerate(values)
    ]
    chain = StartJobChain(jobs_by_scale)  # made when asked for: keep_results=False holds none
    store = None
    if sweep.directory is not None:
        params = {
            **sweep_params(solver),
            "scales": list(values),
            "beta": beta,
            "n_starts": n_starts,
            "seed": seed,
            "include_straight": include_straight,
            "dt0": dt0,
        }
        store = open_store(
            sweep.directory,
            "bounds",
            params,
            result_codec(solver, jobs_making(chain)),
            clean=sweep.shard is None,
        )
    solved = solve_starts(
        solver,
        chain,
        store=store,
        sweep=sweep,
        keep=optima_rule(group=lambda start: start.key.split("_", 1)[0]),  # per scale
    )
    if isinstance(solved, ShardReport):
        return solved
    outcomes, _, clusters = solved
    rows = []
    for s, jobs in zip(values, jobs_by_scale, strict=True):
        if sweep.keep_results:
            ms = MultistartResult(
                starts=tuple(outcomes[j.key] for j in jobs), beta=beta, bound_scale=s, seed=seed
            )
        else:  # like run_multistart's: starts read from the folder, counted once per scale
            assert store is not None
            mine = [c for c in clusters if c[0].startswith(jobs.prefix)]  # grouped per scale
            ms = MultistartResult(
                starts=StoredStarts(jobs, outcomes),
                beta=beta,
                bound_scale=s,
                seed=seed,
                tally=stored_tally(jobs, outcomes, mine, store),
            )
        best = ms.best
        active = (
            () if best is None or best.result is None else best.result.active_bounds(active_tol)
        )
        rows.append(BoundScalingRow(bound_scale=s, multistart=ms, active=tuple(active)))
    return BoundScalingResult(
        rows=tuple(rows), beta=beta, seed=seed, wall_time=time.perf_counter() - tic
    )
