"""Seeded multistart of trajectory solves, with the distinct local optima (spec ``trajopt.md``).

Owns :func:`run_multistart` (the study's 50 random starts per ``beta``: random
feasible spline guesses, optionally plus the straight line, each seeded from
``SeedSequence(seed).spawn`` so results do not depend on the executor),
:class:`MultistartResult`, :class:`TrajOptOptimum` and :func:`trajectory_distance`.
With ``keep_results=False`` the result holds no start: its tally (counts, optima)
is computed once at the end and the starts are read from the folder.
How starts run is one :class:`~youbot_opt.sweeps.options.SweepOptions`; the job
machinery is :mod:`youbot_opt.trajopt.sweep`.

    ms = run_multistart(solver, 50, beta=0.5, sweep=SweepOptions(workers=4, out="runs/ms"))
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Hashable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from youbot_opt._checks import check_beta, check_bound_scale
from youbot_opt._typing import JSONDict
from youbot_opt.exceptions import ParameterError
from youbot_opt.sweeps.multistart import (
    LazyStarts,
    LocalOptimum,
    Multistart,
    OptimumMembers,
    StartTally,
    tally_starts,
)
from youbot_opt.sweeps.optima import KeepRule, check_tolerances, cluster_optima
from youbot_opt.sweeps.options import SweepOptions
from youbot_opt.sweeps.resume import ShardReport
from youbot_opt.sweeps.store import SweepStore, open_store
from youbot_opt.trajopt.solver import TrajOptSolver
from youbot_opt.trajopt.sweep import (
    StartJobs,
    StartOutcome,
    check_solver,
    default_dt0,
    solve_starts,
    start_seeds,
    start_states,
)
from youbot_opt.trajopt.sweep_store import jobs_making, result_codec, sweep_params
from youbot_opt.trajopt.trajectory import Trajectory

__all__ = [
    "MultistartResult",
    "StartOutcome",
    "StoredStarts",
    "TrajOptOptimum",
    "default_dt0",
    "optima_rule",
    "run_multistart",
    "start_seeds",
    "stored_tally",
    "trajectory_distance",
]

_DEFAULT_TOLS = (1e-5, 1e-2)  # (relative, [rad]) of distinct_optima and optima_rule


@dataclass(frozen=True, slots=True, kw_only=True)
class TrajOptOptimum(LocalOptimum[StartOutcome]):
    """A distinct local optimum of trajectory starts, with its ``T``, ``W`` and seeds.

    Attributes
    ----------
    members : sequence of StartOutcome
        The member starts, lowest objective first: a tuple, or with
        ``keep_results=False`` an :class:`~youbot_opt.sweeps.multistart.OptimumMembers`
        reading each member from the output folder when asked for (only the
        first is held).
    n_starts : int
        Number of starts of the multistart (for :attr:`fraction`).
    """

    @classmethod
    def of(cls, members: Sequence[StartOutcome], n_starts: int) -> TrajOptOptimum:
        """Build a cluster from its members (sorted by objective here)."""
        if not members:
            raise ParameterError("a local optimum needs at least one member", name="members")
        return cls(members=tuple(sorted(members, key=lambda s: s.objective)), n_starts=n_starts)

    @property
    def duration(self) -> float:
        """``T`` of the lowest member in [s]."""
        return self.best.duration

    @property
    def work(self) -> float:
        """``W`` of the lowest member in [N^2 m^2 s]."""
        return self.best.work

    @property
    def seeds(self) -> tuple[int | None, ...]:
        """Seeds of the members (``None`` for the straight line); reads every member."""
        return tuple(s.seed for s in self.members)

    def summary(self, *, seeds: bool = True) -> JSONDict:
        """JSON-ready figures; ``seeds``: also every member's seed (reads every member)."""
        out: JSONDict = {
            "objective": self.objective,
            "duration_s": self.duration,
            "work": self.work,
            "count": self.count,
            "fraction": self.fraction,
            "seed": self.best.seed,
        }
        if seeds:
            out["seeds"] = list(self.seeds)
        out["objective_spread"] = self.objective_spread
        return out

    def __repr__(self) -> str:
        return (
            f"LocalOptimum(objective={self.objective:.6g}, count={self.count}, "
            f"duration={self.duration:.4g}, work={self.work:.4g})"
        )


class StoredStarts(LazyStarts[StartOutcome]):
    """The starts of a ``keep_results=False`` multistart, read from its folder when asked for.

    Start ``i`` is ``outcomes[jobs[i].key]`` each time (its figures from the
    sweep's journal; the kept optima in full), so a result of 10^5 starts
    holds no start. Valid while the output folder is there.
    """

    def __init__(self, jobs: StartJobs, outcomes: Mapping[str, StartOutcome]) -> None:
        super().__init__(len(jobs), lambda j: outcomes[jobs[j].key])

    def __repr__(self) -> str:
        return f"StoredStarts({len(self)} starts)"


def trajectory_distance(a: Trajectory, b: Trajectory, n_samples: int = 201) -> float:
    """RMS joint-position difference of two trajectories on a common normalised time.

    Both are resampled at ``s = linspace(0, 1, n_samples)`` of their own
    durations (``q_a(s T_a)`` against ``q_b(s T_b)``), so motions that follow
    the same path at different speeds are close.

    Parameters
    ----------
    a, b : Trajectory
        Trajectories with the same number of joints.
    n_samples : int
        Number of normalised-time samples (>= 2).

    Returns
    -------
    float
        RMS over samples and joints, in [rad].
    """
    if a.q.shape[1] != b.q.shape[1]:
        raise ParameterError(
            f"trajectories have {a.q.shape[1]} and {b.q.shape[1]} joints", name="b"
        )
    s = np.linspace(0.0, 1.0, max(int(n_samples), 2))
    qa = a(a.t[0] + s * a.duration)
    qb = b(b.t[0] + s * b.duration)
    return float(np.sqrt(np.mean((qa - qb) ** 2)))


def _start_distance(a: StartOutcome, b: StartOutcome) -> float:
    """:func:`trajectory_distance` of two starts' trajectories in [rad] (0 if one has none)."""
    if a.result is None and a.optimum is not None:  # keep_results=False: clustered by the sweep
        return 0.0 if a.optimum == b.key else math.inf
    ta = a.result.trajectory if a.result is not None else None
    tb = b.result.trajectory if b.result is not None else None
    return 0.0 if ta is None or tb is None else trajectory_distance(ta, tb)


def optima_rule(
    group: Callable[[StartOutcome], Hashable] | None = None,
) -> KeepRule[StartOutcome]:
    """Return what a ``keep_results=False`` sweep keeps: the default ``distinct_optima()``.

    Parameters
    ----------
    group : callable ``(start) -> hashable``, optional
        Starts of different groups are clustered apart (e.g. per bound scale).

    Returns
    -------
    KeepRule
        Converged starts by objective, :func:`trajectory_distance`, the default
        tolerances of :meth:`MultistartResult.distinct_optima` (1e-5, 1e-2 rad).
    """
    return KeepRule(
        objective=lambda s: s.objective if s.success else None,
        distance=_start_distance,
        obj_tol=_DEFAULT_TOLS[0],
        dist_tol=_DEFAULT_TOLS[1],
        group=group,
    )


@dataclass(frozen=True, slots=True, kw_only=True)
class MultistartResult(Multistart[StartOutcome, tuple[TrajOptOptimum, ...]]):
    """All starts of a multistart, with the best one and the distinct optima.

    Attributes
    ----------
    starts : sequence of StartOutcome
        Every start, the straight line first (if used), then by index: a
        tuple, or with ``keep_results=False`` a :class:`StoredStarts` reading
        each start's figures from the output folder when asked for.
    beta : float
        Time weight of every solve.
    bound_scale : float
        Bound scale factor of every solve.
    seed : int
        Base seed the start seeds were derived from.
    wall_time : float
        Wall time of the whole run in [s] (resumed starts cost nothing).
    resumed : int
        Number of starts loaded from the output directory instead of solved.
    tally : StartTally or None
        ``keep_results=False``: the counts and the default distinct optima
        (``found``; the best start is the first one's), computed once at the
        end of the sweep; ``best``, ``converged``, ``status_counts()``,
        ``distinct_optima()`` (default tolerances) and ``summary(starts=False)``
        answer from it without reading the starts. ``None`` when the starts are held (a tuple).
    """

    starts: Sequence[StartOutcome]
    beta: float
    bound_scale: float
    seed: int
    wall_time: float = 0.0
    resumed: int = 0
    tally: StartTally[tuple[TrajOptOptimum, ...]] | None = None

    statuses_sorted = True

    def _starts(self) -> Sequence[StartOutcome]:
        return self.starts

    @staticmethod
    def _status(start: StartOutcome) -> str:
        return start.status

    @property
    def best(self) -> StartOutcome | None:
        """Converged start of lowest objective, the first of ties (``None``: none converged)."""
        if self.tally is not None:
            return self.tally.found[0].best if self.tally.found else None
        ok = self.converged
        return min(ok, key=lambda s: s.objective) if ok else None

    def distinct_optima(
        self, obj_tol: float = 1e-5, dist_tol: float = 1e-2
    ) -> tuple[TrajOptOptimum, ...]:
        """Cluster converged starts into distinct local optima.

        Starts are taken in order of increasing objective; each joins the first
        cluster whose lowest member is within ``obj_tol`` (relative,
        ``|f - f_c| <= obj_tol max(1, |f_c|)``) in objective and within
        ``dist_tol`` in :func:`trajectory_distance`, else starts a new cluster
        (:func:`youbot_opt.sweeps.optima.cluster_optima`).
        With ``keep_results=False`` the default tolerances return the optima
        the sweep chose (members read from the folder when asked for); other
        tolerances re-cluster every converged start's figures, keeping the
        sweep's trajectory clusters (a pass over the folder, memory of the
        converged starts).

        Parameters
        ----------
        obj_tol : float
            Relative objective tolerance (dimensionless, finite, > 0; default 1e-5).
        dist_tol : float
            Tolerance in [rad] on :func:`trajectory_distance` (finite, > 0;
            default 1e-2 rad).

        Returns
        -------
        tuple of TrajOptOptimum
            Sorted by objective, lowest first.

        Raises
        ------
        ParameterError
            If a tolerance is not finite and > 0 (named in the error).
        """
        obj_tol, dist_tol = check_tolerances(obj_tol, dist_tol)
        if self.tally is not None and (obj_tol, dist_tol) == _DEFAULT_TOLS:
            return self.tally.found
        clusters = cluster_optima(
            self.converged,
            objective=lambda s: s.objective,
            distance=_start_distance,
            obj_tol=obj_tol,
            dist_tol=dist_tol,
        )
        return tuple(TrajOptOptimum.of(m, self.n_starts) for m in clusters)

    def summary(
        self, obj_tol: float = 1e-5, dist_tol: float = 1e-2, *, starts: bool | None = None
    ) -> JSONDict:
        """JSON-ready summary: rates, status counts, best start, distinct optima, every start.

        Parameters
        ----------
        obj_tol, dist_tol : float
            Tolerances of :meth:`distinct_optima` (relative; [rad]).
        starts : bool, optional
            Include every start's figures (``"starts"``) and every optimum's
            member seeds (``"seeds"``); default: when the starts are held
            (``keep_results=True``). With ``keep_results=False`` they are read
            from the folder (time and output size of the number of starts).
        """
        full = self.tally is None if starts is None else bool(starts)
        best = self.best
        counts = self.status_counts()
        out: JSONDict = {
            "beta": self.beta,
            "bound_scale": self.bound_scale,
            "seed": self.seed,
            "n_starts": self.n_starts,
            "success_rate": self.success_rate,
            "n_converged": self.n_converged,
            "n_errors": counts.get("error", 0),
            "status_counts": counts,
            "resumed": self.resumed,
            "wall_time_s": self.wall_time,
            "best": None if best is None else best.summary(),
            "distinct_optima": [
                o.summary(seeds=full) for o in self.distinct_optima(obj_tol, dist_tol)
            ],
        }
        if full:
            out["starts"] = [s.summary() for s in self.starts]
        return out


def stored_tally(
    jobs: StartJobs,
    outcomes: Mapping[str, StartOutcome],
    clusters: Sequence[Sequence[str]],
    store: SweepStore,
) -> StartTally[tuple[TrajOptOptimum, ...]]:
    """Count the starts of a ``keep_results=False`` sweep once and name its optima.

    Parameters
    ----------
    jobs : StartJobs
        The starts (of one multistart).
    outcomes : mapping
        The sweep's outcomes by key (the kept optima in full).
    clusters : sequence of sequence of str
        The sweep's distinct optima of these starts, as keys, best first.
    store : SweepStore
        The sweep's store (one read of each start's record).

    Returns
    -------
    StartTally
        Counts per status (by status), converged count and the optima with
        lazy members (``found``); the first cluster's representative (lowest
        objective, first in start order) is :attr:`MultistartResult.best`.
    """
    n = len(jobs)
    optima = tuple(
        TrajOptOptimum(members=OptimumMembers(keys, outcomes.__getitem__), n_starts=n)
        for keys in clusters
    )
    return tally_starts(start_states(jobs, store), found=optima, by_status=True)


def run_multistart(
    solver: TrajOptSolver,
    n_starts: int = 50,
    *,
    beta: float = 0.5,
    bound_scale: float = 1.0,
    seed: int = 0,
    include_straight: bool = False,
    dt0: float | None = None,
    sweep: SweepOptions = SweepOptions(),  # noqa: B008 - frozen, so sharing it is safe
) -> MultistartResult | ShardReport:
    """Solve from ``n_starts`` seeded random spline guesses (and the straight line).

    How the starts run (crash-isolated workers, retries, time limits, a
    resumable ``out`` directory) is ``sweep``; the jobs are those of
    :func:`youbot_opt.trajopt.sweep.make_jobs`, and the distinct optima are
    clustered by :func:`youbot_opt.sweeps.optima.cluster_optima`
    (:meth:`MultistartResult.distinct_optima`).

    Parameters
    ----------
    solver : TrajOptSolver
        The built solver, reused for every start (forked workers inherit it;
        other workers build their own once).
    n_starts : int
        Number of random spline starts (the study: 50).
    beta : float
        Time weight in [0, 1] of every start's solve (0.5 by default).
    bound_scale : float
        Bound scale factor (> 0, 1.0 = data sheet), for the guesses and the solves.
    seed : int
        Base seed; start ``i`` uses ``start_seeds(seed, n_starts)[i]``.
    include_straight : bool
        Also solve from the straight-line guess.
    dt0 : float, optional
        Time step of the spline guesses in [s]; default
        :func:`default_dt0`: the study's 0.1 s at 50 knots, and the same guess
        duration (4.9 s) at other knot counts.
    sweep : SweepOptions
        How the starts run: ``executor`` (default ``"process"``), ``workers``
        (default: the CPUs available), ``timeout`` in [s] per start attempt (a
        start still running then is killed with its worker, recorded as failed
        and retried like a crash; not serial), ``max_attempts`` (default 2), ``out``
        (each finished start is saved there and a rerun with the same
        parameters resumes) and ``progress`` ``(done, total, last_start)``.
        ``keep_results=False`` (needs ``out``): no start is held; the starts
        are read from ``out`` when asked for, and the counts per status, the
        best start and the default ``distinct_optima()`` (with member counts;
        only each representative's ``result`` is held) are computed once at
        the end, so the accessors cost nothing per start (see
        :class:`~youbot_opt.sweeps.multistart.StartTally`).

    Returns
    -------
    MultistartResult or ShardReport
        Every start, ``best``, ``success_rate`` and ``distinct_optima()``; a
        shard run (``sweep.shard``) returns its :class:`ShardReport` instead.

    Raises
    ------
    ParameterError
        On bad arguments, or if ``sweep.out`` holds a sweep with other parameters.
    ResultFileError
        If a saved item in ``sweep.out`` is corrupted or from a newer schema.
    """
    tic = time.perf_counter()
    solver = check_solver(solver)
    beta = check_beta(beta)  # before any start runs (each solve checks it again)
    bound_scale = check_bound_scale(bound_scale)
    solver.problem.check_boundary(bound_scale)
    dt0 = default_dt0(solver.problem) if dt0 is None else float(dt0)
    # made when asked for (equal to make_jobs'); keep_results=False: the starts read so too
    jobs = StartJobs(
        n_starts,
        seed=seed,
        beta=beta,
        bound_scale=bound_scale,
        include_straight=include_straight,
        dt0=dt0,
    )
    store = None
    if sweep.directory is not None:
        params = {
            **sweep_params(solver),
            "n_starts": n_starts,
            "beta": beta,
            "bound_scale": bound_scale,
            "seed": seed,
            "include_straight": include_straight,
            "dt0": dt0,
        }
        store = open_store(
            sweep.directory,
            "multistart",
            params,
            result_codec(solver, jobs_making(jobs)),
            clean=sweep.shard is None,
        )
    solved = solve_starts(solver, jobs, store=store, sweep=sweep, keep=optima_rule())
    if isinstance(solved, ShardReport):
        return solved
    outcomes, resumed, clusters = solved
    if sweep.keep_results:
        starts: Sequence[StartOutcome] = tuple(outcomes[j.key] for j in jobs)
        tally = None
    else:  # counted once here; the accessors answer from the tally
        assert store is not None
        starts = StoredStarts(jobs, outcomes)
        tally = stored_tally(jobs, outcomes, clusters, store)
    return MultistartResult(
        starts=starts,
        beta=beta,
        bound_scale=bound_scale,
        seed=seed,
        wall_time=time.perf_counter() - tic,
        resumed=resumed,
        tally=tally,
    )
