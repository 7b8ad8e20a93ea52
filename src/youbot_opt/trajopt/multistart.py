"""Seeded multistart of trajectory solves, with the distinct local optima (spec ``trajopt.md``).

Owns :func:`run_multistart` (the study's 50 random starts per ``beta``: random
feasible spline guesses, optionally plus the straight line, each seeded from
``SeedSequence(seed).spawn`` so results do not depend on the executor),
:class:`MultistartResult`, :class:`LocalOptimum` and :func:`trajectory_distance`.
With ``keep_results=False`` the result holds no start: its tally (counts, optima)
is computed once at the end and the starts are read from the folder.
How starts run is one :class:`~youbot_opt.sweeps.options.SweepOptions`; the job
machinery is :mod:`youbot_opt.trajopt.sweep`.

    ms = run_multistart(solver, 50, beta=0.5, sweep=SweepOptions(workers=4, out="runs/ms"))
"""

from __future__ import annotations

import math
import time
from collections import Counter
from collections.abc import Callable, Hashable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from youbot_opt._checks import check_beta, check_bound_scale
from youbot_opt._typing import JSONDict
from youbot_opt.exceptions import ParameterError
from youbot_opt.sweeps.multistart import StartTally, tally_starts
from youbot_opt.sweeps.optima import KeepRule, cluster_optima
from youbot_opt.sweeps.options import SweepOptions
from youbot_opt.sweeps.resume import ShardReport
from youbot_opt.sweeps.store import SweepStore, open_store
from youbot_opt.trajopt.solver import TrajOptSolver
from youbot_opt.trajopt.stored_starts import ConvergedStarts, OptimumMembers, StoredStarts
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
    "LocalOptimum",
    "MultistartResult",
    "StartOutcome",
    "StoredStarts",
    "default_dt0",
    "optima_rule",
    "run_multistart",
    "start_seeds",
    "stored_tally",
    "trajectory_distance",
]

_DEFAULT_TOLS = (1e-5, 1e-2)  # (relative, [rad]) of distinct_optima and optima_rule


@dataclass(frozen=True, slots=True, kw_only=True)
class LocalOptimum:
    """A cluster of converged starts that reached the same local optimum.

    Attributes
    ----------
    members : sequence of StartOutcome
        The member starts, lowest objective first: a tuple, or with
        ``keep_results=False`` a sequence of the member count reading each
        member from the output folder when asked for (only the first is held).
    n_starts : int
        Number of starts of the multistart (for :attr:`fraction`).
    """

    members: Sequence[StartOutcome]
    n_starts: int

    @classmethod
    def of(cls, members: Sequence[StartOutcome], n_starts: int) -> LocalOptimum:
        """Build a cluster from its members (sorted by objective here)."""
        if not members:
            raise ParameterError("a local optimum needs at least one member", name="members")
        return cls(members=tuple(sorted(members, key=lambda s: s.objective)), n_starts=n_starts)

    @property
    def best(self) -> StartOutcome:
        """The lowest member (its ``result`` is the representative trajectory)."""
        return self.members[0]

    @property
    def objective(self) -> float:
        """Lowest objective among the members."""
        return self.best.objective

    @property
    def duration(self) -> float:
        """``T`` of the lowest member in [s]."""
        return self.best.duration

    @property
    def work(self) -> float:
        """``W`` of the lowest member in [N^2 m^2 s]."""
        return self.best.work

    @property
    def count(self) -> int:
        """Number of member starts."""
        return len(self.members)

    @property
    def fraction(self) -> float:
        """``count`` over the number of starts of the multistart."""
        return self.count / max(self.n_starts, 1)

    @property
    def seeds(self) -> tuple[int | None, ...]:
        """Seeds of the members (``None`` for the straight line); reads every member."""
        return tuple(s.seed for s in self.members)

    @property
    def objective_spread(self) -> float:
        """Largest objective minus smallest among the members (the last member's)."""
        return self.members[-1].objective - self.best.objective

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
class MultistartResult:
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
    tally: StartTally[tuple[LocalOptimum, ...]] | None = None

    @property
    def n_starts(self) -> int:
        """Number of starts."""
        return len(self.starts)

    @property
    def n_converged(self) -> int:
        """Number of starts whose solve succeeded."""
        if self.tally is not None:
            return self.tally.n_converged
        return sum(s.success for s in self.starts)

    @property
    def converged(self) -> Sequence[StartOutcome]:
        """Starts whose solve succeeded, in start order.

        A tuple; with ``keep_results=False`` a sequence of the counted length
        that reads the starts from the folder as it is iterated (nothing held).
        """
        if self.tally is not None:
            return ConvergedStarts(self.starts, self.tally.n_converged)
        return tuple(s for s in self.starts if s.success)

    @property
    def success_rate(self) -> float:
        """Fraction of starts that converged (0 if there are none)."""
        return self.n_converged / self.n_starts if self.n_starts else 0.0

    @property
    def best(self) -> StartOutcome | None:
        """Converged start of lowest objective, the first of ties (``None``: none converged)."""
        if self.tally is not None:
            return self.tally.found[0].best if self.tally.found else None
        ok = self.converged
        return min(ok, key=lambda s: s.objective) if ok else None

    def status_counts(self) -> dict[str, int]:
        """Return the number of starts per status (``"error"``: raised or crashed), by status."""
        if self.tally is not None:
            return dict(self.tally.status_counts)
        return dict(sorted(Counter(s.status for s in self.starts).items()))

    def distinct_optima(
        self, objective_tol: float = 1e-5, traj_tol: float = 1e-2
    ) -> tuple[LocalOptimum, ...]:
        """Cluster converged starts into distinct local optima.

        Starts are taken in order of increasing objective; each joins the first
        cluster whose lowest member is within ``objective_tol`` (relative,
        ``|f - f_c| <= objective_tol max(1, |f_c|)``) in objective and within
        ``traj_tol`` in :func:`trajectory_distance`, else starts a new cluster.
        With ``keep_results=False`` the default tolerances return the optima
        the sweep chose (members read from the folder when asked for); other
        tolerances re-cluster every converged start's figures, keeping the
        sweep's trajectory clusters (a pass over the folder, memory of the
        converged starts).

        Parameters
        ----------
        objective_tol : float
            Relative objective tolerance (> 0).
        traj_tol : float
            Trajectory distance tolerance in [rad] (> 0).

        Returns
        -------
        tuple of LocalOptimum
            Sorted by objective, lowest first.
        """
        if not (objective_tol > 0 and traj_tol > 0):
            raise ParameterError(
                f"objective_tol and traj_tol must be > 0, got {objective_tol!r}, {traj_tol!r}",
                name="objective_tol",
            )
        if self.tally is not None and (objective_tol, traj_tol) == _DEFAULT_TOLS:
            return self.tally.found
        clusters = cluster_optima(
            self.converged,
            objective=lambda s: s.objective,
            distance=_start_distance,
            obj_tol=objective_tol,
            dist_tol=traj_tol,
        )
        return tuple(LocalOptimum.of(m, self.n_starts) for m in clusters)

    def summary(
        self, objective_tol: float = 1e-5, traj_tol: float = 1e-2, *, starts: bool | None = None
    ) -> JSONDict:
        """JSON-ready summary: rates, status counts, best start, distinct optima, every start.

        Parameters
        ----------
        objective_tol, traj_tol : float
            Tolerances of :meth:`distinct_optima`.
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
                o.summary(seeds=full) for o in self.distinct_optima(objective_tol, traj_tol)
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
) -> StartTally[tuple[LocalOptimum, ...]]:
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
        LocalOptimum(members=OptimumMembers(keys, outcomes), n_starts=n) for keys in clusters
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
