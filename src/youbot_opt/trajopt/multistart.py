"""Seeded multistart of trajectory solves, with the distinct local optima (spec ``trajopt.md``).

Owns :func:`run_multistart` (the study's 50 random starts per ``beta``: random
feasible spline guesses, optionally plus the straight line, each seeded from
``SeedSequence(seed).spawn`` so results do not depend on the executor),
:class:`MultistartResult`, :class:`LocalOptimum` and :func:`trajectory_distance`.
How starts run is one :class:`~youbot_opt.sweeps.options.SweepOptions`; the job
machinery is :mod:`youbot_opt.trajopt.sweep`.

    ms = run_multistart(solver, 50, beta=0.5, sweep=SweepOptions(workers=4, out="runs/ms"))
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Hashable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, overload

import numpy as np

from youbot_opt.exceptions import ParameterError
from youbot_opt.sweeps.cluster import KeepRule, cluster_optima
from youbot_opt.sweeps.options import SweepOptions
from youbot_opt.trajopt.objectives import check_beta
from youbot_opt.trajopt.problem import check_bound_scale
from youbot_opt.trajopt.solver import TrajOptSolver
from youbot_opt.trajopt.sweep import (
    StartJobs,
    StartOutcome,
    check_solver,
    default_dt0,
    open_store,
    solve_starts,
    start_seeds,
    sweep_params,
)
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
    "trajectory_distance",
]


@dataclass(frozen=True, slots=True, kw_only=True)
class LocalOptimum:
    """A cluster of converged starts that reached the same local optimum.

    Attributes
    ----------
    members : tuple of StartOutcome
        The member starts, lowest objective first.
    n_starts : int
        Number of starts of the multistart (for :attr:`fraction`).
    """

    members: tuple[StartOutcome, ...]
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
        """Seeds of the members (``None`` for the straight line)."""
        return tuple(s.seed for s in self.members)

    @property
    def objective_spread(self) -> float:
        """Largest objective minus smallest among the members."""
        return self.members[-1].objective - self.best.objective

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
        obj_tol=1e-5,
        dist_tol=1e-2,
        group=group,
    )


class StoredStarts(Sequence[StartOutcome]):
    """The starts of a ``keep_results=False`` multistart, read from its folder when asked for.

    Start ``i`` is ``outcomes[jobs[i].key]`` each time (its figures from the
    sweep's journal; the kept optima in full), so a result of 10^5 starts
    holds no start. Valid while the output folder is there.
    """

    def __init__(self, jobs: StartJobs, outcomes: Mapping[str, StartOutcome]) -> None:
        self._jobs, self._outcomes = jobs, outcomes

    def __len__(self) -> int:
        return len(self._jobs)

    @overload
    def __getitem__(self, i: int) -> StartOutcome: ...
    @overload
    def __getitem__(self, i: slice) -> tuple[StartOutcome, ...]: ...
    def __getitem__(self, i: int | slice) -> StartOutcome | tuple[StartOutcome, ...]:
        if isinstance(i, slice):
            return tuple(self[j] for j in range(len(self))[i])
        return self._outcomes[self._jobs[i].key]

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Sequence):
            return NotImplemented
        return len(self) == len(other) and all(a == b for a, b in zip(self, other, strict=True))

    __hash__ = None  # type: ignore[assignment]

    def __repr__(self) -> str:
        return f"StoredStarts({len(self)} starts)"


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
    """

    starts: Sequence[StartOutcome]
    beta: float
    bound_scale: float
    seed: int
    wall_time: float = 0.0
    resumed: int = 0

    @property
    def n_starts(self) -> int:
        """Number of starts."""
        return len(self.starts)

    @property
    def converged(self) -> tuple[StartOutcome, ...]:
        """Starts whose solve succeeded."""
        return tuple(s for s in self.starts if s.success)

    @property
    def success_rate(self) -> float:
        """Fraction of starts that converged (0 if there are none)."""
        return len(self.converged) / self.n_starts if self.starts else 0.0

    @property
    def best(self) -> StartOutcome | None:
        """Converged start with the lowest objective (``None`` if none converged)."""
        ok = self.converged
        return min(ok, key=lambda s: s.objective) if ok else None

    def distinct_optima(
        self, obj_tol: float = 1e-5, traj_tol: float = 1e-2
    ) -> tuple[LocalOptimum, ...]:
        """Cluster converged starts into distinct local optima.

        Starts are taken in order of increasing objective; each joins the first
        cluster whose lowest member is within ``obj_tol`` (relative,
        ``|f - f_c| <= obj_tol max(1, |f_c|)``) in objective and within
        ``traj_tol`` in :func:`trajectory_distance`, else starts a new cluster.

        Parameters
        ----------
        obj_tol : float
            Relative objective tolerance (> 0).
        traj_tol : float
            Trajectory distance tolerance in [rad] (> 0).

        Returns
        -------
        tuple of LocalOptimum
            Sorted by objective, lowest first.
        """
        if not (obj_tol > 0 and traj_tol > 0):
            raise ParameterError(
                f"obj_tol and traj_tol must be > 0, got {obj_tol!r}, {traj_tol!r}", name="obj_tol"
            )
        clusters = cluster_optima(
            self.converged,
            objective=lambda s: s.objective,
            distance=_start_distance,
            obj_tol=obj_tol,
            dist_tol=traj_tol,
        )
        return tuple(LocalOptimum.of(m, self.n_starts) for m in clusters)

    def summary(self, obj_tol: float = 1e-5, traj_tol: float = 1e-2) -> dict[str, Any]:
        """JSON-ready summary: rates, best start, distinct optima, every start's figures."""
        best = self.best
        return {
            "beta": self.beta,
            "bound_scale": self.bound_scale,
            "seed": self.seed,
            "n_starts": self.n_starts,
            "success_rate": self.success_rate,
            "n_errors": sum(s.status == "error" for s in self.starts),
            "resumed": self.resumed,
            "wall_time_s": self.wall_time,
            "best": None if best is None else best.summary(),
            "distinct_optima": [
                {
                    "objective": o.objective,
                    "duration_s": o.duration,
                    "work": o.work,
                    "count": o.count,
                    "fraction": o.fraction,
                    "seeds": list(o.seeds),
                    "objective_spread": o.objective_spread,
                }
                for o in self.distinct_optima(obj_tol, traj_tol)
            ],
            "starts": [s.summary() for s in self.starts],
        }


def run_multistart(
    solver: TrajOptSolver,
    n_starts: int = 50,
    *,
    beta: float | None = None,
    bound_scale: float = 1.0,
    seed: int = 0,
    include_straight: bool = False,
    dt0: float | None = None,
    sweep: SweepOptions = SweepOptions(),  # noqa: B008 - frozen, so sharing it is safe
) -> MultistartResult:
    """Solve from ``n_starts`` seeded random spline guesses (and the straight line).

    How the starts run (crash-isolated workers, retries, time limits, a
    resumable ``out`` directory) is ``sweep``; the jobs are those of
    :func:`youbot_opt.trajopt.sweep.make_jobs`, and the distinct optima are
    clustered by :func:`youbot_opt.sweeps.cluster.cluster_optima`
    (:meth:`MultistartResult.distinct_optima`).

    Parameters
    ----------
    solver : TrajOptSolver
        The built solver, reused for every start (forked workers inherit it;
        other workers build their own once).
    n_starts : int
        Number of random spline starts (the study: 50).
    beta : float, optional
        Time weight in [0, 1]; the problem's default when omitted.
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
        ``keep_results=False`` (needs ``out``): every start keeps its figures
        but only the best start and each default ``distinct_optima()``
        representative keep their ``result`` in memory (the rest stay in ``out``).

    Returns
    -------
    MultistartResult
        Every start, ``best``, ``success_rate`` and ``distinct_optima()``.

    Raises
    ------
    ParameterError
        On bad arguments, or if ``sweep.out`` holds a sweep with other parameters.
    ResultFileError
        If a saved item in ``sweep.out`` is corrupted or from a newer schema.
    """
    tic = time.perf_counter()
    solver = check_solver(solver)
    beta = solver.problem.objective.beta if beta is None else check_beta(beta)
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
        store = open_store(sweep.directory, "multistart", params, solver, clean=sweep.shard is None)
    outcomes, resumed = solve_starts(solver, jobs, store=store, sweep=sweep, keep=optima_rule())
    return MultistartResult(
        starts=tuple(outcomes[j.key] for j in jobs)
        if sweep.keep_results
        else StoredStarts(jobs, outcomes),
        beta=beta,
        bound_scale=bound_scale,
        seed=seed,
        wall_time=time.perf_counter() - tic,
        resumed=resumed,
    )
