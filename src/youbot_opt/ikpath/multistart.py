"""Seeded multistart of IK-path solves, with the distinct local minima (spec ``ikpath.md``).

Owns :func:`run_multistart` (any robot: a planar chain by the planar methods, any
other by the general ones, as :func:`~youbot_opt.ikpath.solve.solve` chooses),
:class:`MultistartResult`, :class:`IKPathOptimum`, :func:`configuration_distance`
and :func:`cluster_minima`. The starts are drawn in the parent process, so they
do not depend on the executor; how they run (crash-isolated workers, one retry,
resumable ``out`` directory) is one :class:`~youbot_opt.sweeps.options.SweepOptions`
(:mod:`youbot_opt.ikpath.sweep`).

    ms = run_multistart(problem, n_starts=100, sweep=SweepOptions(workers=4, out="runs/ik"))
"""

from __future__ import annotations

import functools
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import numpy.typing as npt

from youbot_opt._typing import Array
from youbot_opt.exceptions import ParameterError
from youbot_opt.ikpath.dls import random_theta
from youbot_opt.ikpath.methods.al import ALOptions
from youbot_opt.ikpath.methods.ipopt import IpoptOptions, check_degrees_of_freedom
from youbot_opt.ikpath.problem import CyclicIKProblem
from youbot_opt.ikpath.reachability.general import ReachVerdict3D
from youbot_opt.ikpath.reachability.planar import ReachVerdict, require_reachable
from youbot_opt.ikpath.reachability.planar import check_reachability as check_planar
from youbot_opt.ikpath.result import IKPathResult
from youbot_opt.ikpath.solve import Method, check_method, check_targets, uses_planar_methods
from youbot_opt.ikpath.starts import (
    AUTOMATIC_TIME_BUDGET,
    BRANCH_KIND,
    START_KINDS,
    START_KINDS_3D,
    BranchStarts,
    PlanarStarts,
    Starts3D,
    check_start_request,
    check_time_budget,
    make_starts,
    make_starts_3d,
    periodic_joints,
)
from youbot_opt.ikpath.stored import ClusterIndices, StoredResults
from youbot_opt.ikpath.sweep import (
    PLANAR_STARTS,
    STARTS_3D,
    SWEEP_KIND,
    SWEEP_KIND_3D,
    minima_rule,
    progress_callbacks,
    result_codec,
    solve_starts,
    store_params,
    stream_starts,
)
from youbot_opt.sweeps.multistart import LocalOptimum, Multistart, OptimumMembers, StartTally
from youbot_opt.sweeps.optima import check_tolerances, cluster_optima
from youbot_opt.sweeps.options import SweepOptions, resolve_executor
from youbot_opt.sweeps.resume import ShardReport
from youbot_opt.sweeps.selection import Clusters
from youbot_opt.sweeps.store import open_store

__all__ = [
    "IKPathOptimum",
    "MultistartResult",
    "Progress",
    "START_KINDS",
    "cluster_minima",
    "configuration_distance",
    "free_joints",
    "make_starts",
    "minimum_distance",
    "run_multistart",
]

Progress = Callable[[int, int, float], None]
"""``progress(done, total, best_objective)``, called in the parent as starts finish.

``best_objective`` is the lowest ``E`` in [rad^2] of the successful starts so far
(``inf`` before the first). Starts loaded from an output directory are reported
in one call before the first solve.
"""


@dataclass(frozen=True, slots=True, kw_only=True, eq=False)
class IKPathOptimum(LocalOptimum[IKPathResult]):
    """One distinct local minimum found by multistart, with its start indices.

    Attributes
    ----------
    members : sequence of IKPathResult
        The member results, the representative (lowest ``E`` in [rad^2]) first,
        then by ``E``: a tuple, or with ``keep_results=False`` an
        :class:`~youbot_opt.sweeps.multistart.OptimumMembers` loading each
        from the output folder when asked for (the representative is held).
    n_starts : int
        Number of starts of the multistart (for :attr:`fraction`).
    start_indices : sequence of int
        Which starts, ascending (0 = the zero vector): a tuple, or with
        ``keep_results=False`` a :class:`~youbot_opt.ikpath.stored.ClusterIndices`
        read from the output folder when iterated.
    """

    start_indices: Sequence[int]

    @property
    def result(self) -> IKPathResult:
        """The representative (lowest ``E`` in the cluster): :attr:`best`."""
        return self.best


@dataclass(frozen=True, slots=True, kw_only=True, eq=False)
class MultistartResult(Multistart[IKPathResult, int]):
    """All starts of a multistart run and the minima they found.

    Attributes
    ----------
    problem : CyclicIKProblem
        The problem.
    method : str
        ``"al"`` or ``"ipopt"``.
    seed : int
        Seed of the random starts.
    start_kind : str
        How the random starts were drawn (:data:`~youbot_opt.ikpath.starts.START_KINDS`,
        :data:`~youbot_opt.ikpath.starts.START_KINDS_3D`).
    planar : bool
        Whether the planar methods solved the starts (else the general ones).
    results : sequence of IKPathResult
        One per start, in start order: a tuple, or with ``keep_results=False``
        a :class:`~youbot_opt.ikpath.stored.StoredResults` that holds the
        minima's results and loads any other from :attr:`output` when indexed
        (valid while that folder is there).
    minima : tuple of IKPathOptimum
        Distinct minima of the successful starts, best (lowest E) first.
    verdicts : tuple of ReachVerdict
        Planar reachability verdicts of the targets (empty if not checked).
    wall_time : float
        Elapsed time in [s].
    n_workers : int
        Parallel workers used.
    attempts : sequence of int
        Attempts per start, in start order, earlier runs on the same output
        included (2: the start failed once and was retried); empty if unknown
        (``keep_results=False``: read from the output folder when indexed).
    resumed : int
        Starts loaded from the output directory instead of solved.
    output : Path or None
        Output directory the starts were saved to (``None``: not saved).
    tally : StartTally or None
        ``keep_results=False``: counts and (``found``) the index of the start
        closest to the targets,
        gathered in one pass at the end of the run; ``None`` otherwise.
    obj_tol, dist_tol : float
        The clustering tolerances :attr:`minima` were chosen with (relative; [rad]).
    time_budget : float or None
        The automatic starts' wall-time budget in [s] (``None``: starts asked for,
        which all run).
    not_run : int
        Planned starts the time budget left unrun (0: every planned start ran);
        they follow the starts of :attr:`results` (see :attr:`planned_starts`).
    """

    problem: CyclicIKProblem
    method: str
    seed: int
    start_kind: str
    planar: bool
    results: Sequence[IKPathResult]
    minima: tuple[IKPathOptimum, ...]
    verdicts: tuple[ReachVerdict, ...]
    wall_time: float
    n_workers: int
    attempts: Sequence[int] = ()
    resumed: int = 0
    output: Path | None = None
    tally: StartTally[int] | None = None
    obj_tol: float = 1e-6
    dist_tol: float = 1e-3
    time_budget: float | None = None
    not_run: int = 0

    def _starts(self) -> Sequence[IKPathResult]:
        return self.results

    @staticmethod
    def _status(start: IKPathResult) -> str:
        return start.status.value

    @property
    def planned_starts(self) -> int:
        """Number of starts planned: those that ran and those the time budget left unrun."""
        return self.n_starts + self.not_run

    @property
    def budget_reached(self) -> bool:
        """Whether the time budget stopped the run before every planned start ran."""
        return self.not_run > 0

    @property
    def best(self) -> IKPathResult:
        """Best successful result, or the start closest to the targets if none succeeded.

        Closest: the smallest position plus orientation error (0 on the planar
        methods); ties go to the smaller ``E``, then to the lower start index.
        """
        if self.minima:
            return self.minima[0].result
        if self.tally is not None:
            return self.results[self.tally.found]
        return min(
            self.results,
            key=lambda r: (r.max_position_error() + r.max_orientation_error(), r.objective),
        )

    @property
    def best_index(self) -> int:
        """Start index of :attr:`best` (no search through the folder)."""
        if self.tally is not None and not self.minima:
            return self.tally.found
        return self.results.index(self.best)  # StoredResults: found among the held ones

    @property
    def best_count(self) -> int:
        """How many starts found the best minimum."""
        return self.minima[0].count if self.minima else 0

    def starts_per_second(self) -> float:
        """Throughput in [1/s]."""
        return self.n_starts / self.wall_time if self.wall_time > 0 else math.inf

    def distinct_optima(
        self, obj_tol: float = 1e-6, dist_tol: float = 1e-3
    ) -> tuple[IKPathOptimum, ...]:
        """Re-cluster the successful results with other tolerances (see :func:`cluster_minima`).

        With ``keep_results=False`` the run's own tolerances return :attr:`minima`;
        others re-cluster from the output folder, streamed (each successful
        start's result loaded once, one at a time; the members go to a
        temporary table), with the same result as ``keep_results=True``.

        Parameters
        ----------
        obj_tol : float
            Relative tolerance on ``E`` (dimensionless, finite, > 0; default 1e-6).
        dist_tol : float
            Tolerance in [rad] on :func:`minimum_distance` (finite, > 0; default
            1e-3 rad).

        Returns
        -------
        tuple of IKPathOptimum
            Sorted by objective, best first.

        Raises
        ------
        ParameterError
            If a tolerance is not finite and > 0 (named in the error).
        """
        obj_tol, dist_tol = check_tolerances(obj_tol, dist_tol)
        results = self.results
        distance = minimum_distance(self.problem, planar=self.planar)
        if not isinstance(results, StoredResults):
            return cluster_minima(results, obj_tol=obj_tol, dist_tol=dist_tol, distance=distance)
        if (obj_tol, dist_tol) == (self.obj_tol, self.dist_tol):
            return self.minima
        kept, clusters = results.cluster(minima_rule(obj_tol, dist_tol, distance))
        reps = {_key_index(k): s.result for k, s in kept.items() if s.result is not None}
        return _stored_minima(clusters, reps, results)


def configuration_distance(qa: Array, qb: Array) -> float:
    """Largest joint difference in [rad] between two (s, n) paths modulo common 2 pi shifts.

    Joint ``i`` of every configuration may be shifted by the same ``2 pi k_i``
    (``E`` and the constraints are invariant under it); ``k_i`` is chosen to
    minimise the difference.
    """
    diff = np.asarray(qa, dtype=float) - np.asarray(qb, dtype=float)
    shift = 2.0 * np.pi * np.round(np.median(diff, axis=0) / (2.0 * np.pi))
    return float(np.max(np.abs(diff - shift)))


def minimum_distance(
    problem: CyclicIKProblem, *, planar: bool
) -> Callable[[IKPathResult, IKPathResult], float]:
    """Return how far apart two results of ``problem`` are, in [rad], for telling minima apart.

    The planar methods: :func:`configuration_distance` (every joint modulo a
    common 2 pi shift); the general ones: the largest joint difference with the
    revolute joints modulo a common 2 pi shift (the same E, the same targets met)
    and the joints that move no target (:func:`free_joints`: a wrist turning
    about the tool axis of position targets) modulo any common shift, so one
    path is one minimum however often it was found shifted.
    """
    if planar:
        return _planar_distance
    n = problem.n_joints
    revolute = periodic_joints(problem) | (problem.upper[:n] - problem.lower[:n] >= 2 * np.pi)
    revolute &= ~np.array([_prismatic(problem, int(j)) for j in problem.active])
    return functools.partial(_distance_3d, revolute, free_joints(problem))


def free_joints(problem: CyclicIKProblem, samples: int = 3) -> npt.NDArray[np.bool_]:
    """Joints that move no target's rows at ``samples`` seeded configurations, shape (n,)."""
    rng = np.random.default_rng(0)
    data = problem.create_data()
    moves = np.zeros(problem.n_joints)
    for _ in range(samples):
        theta = random_theta(problem, rng)
        for j in range(problem.n_targets):
            moves = np.maximum(moves, np.max(np.abs(problem.block(j, theta, data)[1]), axis=0))
    return moves < 1e-9


def _prismatic(problem: CyclicIKProblem, joint: int) -> bool:
    return bool(problem.model.joints[joint].shortname().startswith("JointModelP"))


def _planar_distance(a: IKPathResult, b: IKPathResult) -> float:
    return configuration_distance(a.configurations, b.configurations)


def _distance_3d(
    revolute: npt.NDArray[np.bool_], free: npt.NDArray[np.bool_], a: IKPathResult, b: IKPathResult
) -> float:
    diff = a.configurations - b.configurations
    median = np.median(diff, axis=0)
    shift = np.where(revolute, 2 * np.pi * np.round(median / (2 * np.pi)), 0.0)
    shift = np.where(free, median, shift)
    return float(np.max(np.abs(diff - shift)))


def cluster_minima(
    results: Sequence[IKPathResult],
    *,
    obj_tol: float = 1e-6,
    dist_tol: float = 1e-3,
    distance: Callable[[IKPathResult, IKPathResult], float] | None = None,
) -> tuple[IKPathOptimum, ...]:
    """Group successful results into distinct local minima, best first.

    Two successful results are the same minimum when their ``E`` agree to
    ``obj_tol`` (relative) and their configurations to ``dist_tol`` [rad] modulo
    common 2 pi shifts (:func:`configuration_distance`): the shared rule
    :func:`youbot_opt.sweeps.optima.cluster_optima` over the successes, each
    cluster an :class:`IKPathOptimum`.

    Parameters
    ----------
    results : sequence of IKPathResult
        Results in start order (index = start index).
    obj_tol : float
        Relative tolerance on ``E`` (dimensionless, finite, > 0):
        ``|E - E_c| <= obj_tol max(1, |E_c|)``.
    dist_tol : float
        Tolerance in [rad] on ``distance`` (finite, > 0).
    distance : callable ``(a, b) -> float``, optional
        How far apart two results are in [rad] (default: :func:`configuration_distance`
        of their configurations; see :func:`minimum_distance`).

    Returns
    -------
    tuple of IKPathOptimum
        Sorted by objective.

    Raises
    ------
    ParameterError
        If a tolerance is not finite and > 0 (named in the error).
    """
    groups = cluster_optima(
        (i for i, r in enumerate(results) if r.success),
        objective=lambda i: results[i].objective,
        distance=lambda i, j: (distance or _planar_distance)(results[i], results[j]),
        obj_tol=obj_tol,
        dist_tol=dist_tol,
    )
    return tuple(
        IKPathOptimum(
            members=tuple(results[i] for i in g),
            n_starts=len(results),
            start_indices=tuple(sorted(g)),
        )
        for g in groups
    )


def run_multistart(
    problem: CyclicIKProblem,
    *,
    method: Method = "al",
    n_starts: int | None = None,
    seed: int = 0,
    starts: str | None = None,
    options: ALOptions | IpoptOptions | None = None,
    planar: bool | None = None,
    check_reachability: bool = True,
    obj_tol: float = 1e-6,
    dist_tol: float = 1e-3,
    verdicts: Sequence[ReachVerdict] | Sequence[ReachVerdict3D] | None = None,
    workers: int | None = None,
    time_budget: float | None = None,
    sweep: SweepOptions = SweepOptions(),  # noqa: B008 - frozen, so sharing it is safe
) -> MultistartResult | ShardReport:
    """Solve from ``n_starts`` seeded starts in parallel and report the distinct minima.

    A problem with a planar chain (:attr:`CyclicIKProblem.chain`) is solved by
    the planar methods, any other (or ``planar=False``) by the general ones,
    as :func:`~youbot_opt.ikpath.solve.solve` chooses.

    Parameters
    ----------
    problem : CyclicIKProblem
        The problem.
    method : {"al", "ipopt"}
        Solver.
    n_starts : int, optional
        Number of starts. Default (with ``starts`` None): the automatic starts,
        start 0, the witnesses of ``verdicts`` and the cheapest coherent IK
        branches, at most :func:`~youbot_opt.ikpath.starts.start_budget`
        (:class:`~youbot_opt.ikpath.starts.BranchStarts`); with a ``starts`` kind,
        100 on the planar methods, else 16. Start 0 is the study's zero vector
        (planar) or the greedy DLS path (general).
    seed : int
        Seed of the random starts, drawn in this process (one seeded generator
        per start index), so they do not depend on the executor.
    starts : str, optional
        How random starts are drawn (:mod:`youbot_opt.ikpath.starts`): the
        planar methods' ``"feasible"`` (default) or ``"uniform"``; the general
        ones' ``"mixed"`` (default), ``"coherent"``, ``"random"`` or, on a
        planar robot only, ``"feasible"`` (the planar starts: random exact IK
        solutions, the reachability witnesses as fallback; default there).
        ``"branches"`` (both; the default when ``n_starts`` is None): the
        automatic starts, then the robot kind's random ones.
    options : ALOptions or IpoptOptions, optional
        Settings of the method (``max_wall_time`` [s] bounds each start's solve).
    planar : bool, optional
        Use the planar methods (default: when the problem has a chain); False
        solves a planar robot by the general methods.
    check_reachability : bool
        Planar methods: decide every target's reachability first (raises
        ``UnreachableTarget``, warns about undecided ones); ignored when
        ``verdicts`` are given.
    obj_tol : float
        Relative tolerance on ``E`` of the clustering into minima (dimensionless,
        finite, > 0; see :func:`cluster_minima`).
    dist_tol : float
        Tolerance in [rad] on :func:`minimum_distance` of the clustering (finite, > 0).
    verdicts : sequence of ReachVerdict or ReachVerdict3D, optional
        Their witnesses make a start of the automatic starts. Planar methods:
        verdicts of the targets already decided by the caller (e.g. with
        another budget); used instead of deciding again (an unreachable one
        still raises). Their witnesses are the fallback of
        feasible starts.
    workers : int, optional
        Shortcut for ``sweep.workers`` (contradicting it raises).
    time_budget : float, optional
        Automatic starts only (``n_starts`` None): wall time in [s], counted from
        this call, after which no new start begins (default
        :data:`~youbot_opt.ikpath.starts.AUTOMATIC_TIME_BUDGET`, 20 s). Starts
        running then finish; at least one start runs. The result holds the
        starts that ran, in start order, and :attr:`MultistartResult.not_run`
        counts the rest; a rerun on the same ``sweep.out`` loads the finished
        starts and goes on with the others. Starts asked for (``n_starts``
        given, or another ``starts`` kind) all run: a budget with them is refused.
    sweep : SweepOptions
        How the starts run. ``executor``: a process pool owned by this call
        and rebuilt if a worker dies, ``"serial"``, a Dask client or scheduler
        address, or the caller's pool or executor (not shut down here);
        default ``"serial"`` when ``workers`` is 1, else ``"process"``.
        ``workers``: starts in flight (default: the planar methods, the CPUs
        available or the caller's pool size; the general ones, 1).
        ``max_attempts``: per start, earlier runs on ``out`` included (default
        2; out of attempts a start becomes a ``crashed`` result).
        ``timeout`` [s] per start attempt (worker pools only). ``out``: each
        finished start is saved there as it completes (``manifest.json``,
        ``items/``), and a rerun with the same problem, method, options,
        ``n_starts``, ``seed`` and ``starts`` resumes. ``progress``:
        ``(done, total, best_objective)`` as starts finish (see
        :data:`Progress`). ``keep_results=False`` (needs ``out``): each start
        is drawn when its task is made, and only the distinct minima's results
        are held; ``results`` and ``attempts`` read the output folder when
        indexed, and the counts and the fallback best come from one pass over
        the journal (:mod:`youbot_opt.ikpath.stored`).

    Returns
    -------
    MultistartResult or ShardReport
        All results in start order and the distinct minima, best first; a
        shard run (``sweep.shard``) returns its
        :class:`~youbot_opt.sweeps.resume.ShardReport` instead.

    Raises
    ------
    ParameterError
        For an unknown method or start kind, foreign options, ``method="ipopt"``
        on a chain with fewer than 2 free joints, ``planar=True`` without a
        chain or with a clearance, ``workers`` contradicting ``sweep.workers``, an ``out``
        holding another sweep, a ``time_budget`` that is not a positive,
        finite time or comes with starts asked for, or a tolerance that is not
        finite and > 0 (checked before any start runs).
    UnreachableTarget
        Planar methods: if ``check_reachability`` and a target is unreachable.
    ResultFileError
        If a file in ``out`` is corrupted, from a newer schema or from 0.1.0.
    """
    t0 = time.perf_counter()
    check_method(method, options)
    obj_tol, dist_tol = check_tolerances(obj_tol, dist_tol)
    use_planar = uses_planar_methods(problem, method, planar)
    if workers is not None:
        if sweep.workers is not None and sweep.workers != workers:
            raise ParameterError(
                f"workers={workers} contradicts sweep.workers={sweep.workers}",
                name="workers",
                value=workers,
            )
        sweep = replace(sweep, workers=int(workers))
    if starts is None and n_starts is None:
        starts = BRANCH_KIND
    budget = _time_budget(time_budget, automatic=starts == BRANCH_KIND and n_starts is None)
    if use_planar:
        problem.planar_chain  # noqa: B018 - raises ParameterError without a chain
        return _run_planar(
            problem, t0, method=method, n_starts=n_starts, seed=seed,
            starts="feasible" if starts is None else starts, options=options,
            check_reachability=check_reachability, obj_tol=obj_tol, dist_tol=dist_tol,
            verdicts=verdicts, sweep=sweep, budget=budget,  # type: ignore[arg-type]
        )  # fmt: skip
    if starts is None:
        starts = "feasible" if problem.chain is not None else "mixed"
    return _run_3d(
        problem, t0, method=method, n_starts=n_starts, seed=seed, starts=starts,
        options=options, obj_tol=obj_tol, dist_tol=dist_tol, verdicts=verdicts,
        sweep=sweep, budget=budget,
    )  # fmt: skip


def _time_budget(time_budget: float | None, *, automatic: bool) -> float | None:
    """Return the time budget in [s] of a run (``None``: none; starts asked for all run)."""
    if time_budget is None:
        return AUTOMATIC_TIME_BUDGET if automatic else None
    budget = check_time_budget(time_budget)
    if not automatic:
        raise ParameterError(
            f"time_budget={time_budget!r} applies to the automatic starts only (n_starts "
            "None, starts None or 'branches'); starts asked for all run",
            name="time_budget",
            value=time_budget,
        )
    return budget


def _run_planar(
    problem: CyclicIKProblem,
    t0: float,
    *,
    method: Method,
    n_starts: int | None,
    seed: int,
    starts: str,
    options: ALOptions | IpoptOptions | None,
    check_reachability: bool,
    obj_tol: float,
    dist_tol: float,
    verdicts: Sequence[ReachVerdict] | None,
    sweep: SweepOptions,
    budget: float | None,
) -> MultistartResult | ShardReport:
    """:func:`run_multistart` by the planar methods."""
    if method == "ipopt":
        check_degrees_of_freedom(problem)
    found: tuple[ReachVerdict, ...] = ()
    if verdicts is not None:
        found = require_reachable(problem, tuple(verdicts))  # type: ignore[arg-type]
    elif check_reachability:
        found = check_targets(problem)
    x0s: Array | PlanarStarts | BranchStarts
    if starts == BRANCH_KIND:
        x0s = BranchStarts(problem, n_starts, seed, verdicts=found, planar=True)
        if sweep.keep_results:
            x0s = _drawn(x0s)
    elif not sweep.keep_results:  # each start drawn as its task is made
        x0s = PlanarStarts(problem, _count(n_starts, 100), seed, kind=starts, verdicts=found)
    else:
        x0s = make_starts(problem, _count(n_starts, 100), seed, kind=starts, verdicts=found)
    executor, n_workers = resolve_executor(sweep)
    return _run(
        problem, t0, x0s, method=method, seed=seed, starts=starts, options=options,
        planar=True, verdicts=found, obj_tol=obj_tol, dist_tol=dist_tol,
        sweep=replace(sweep, executor=executor, workers=n_workers), budget=budget,
    )  # fmt: skip


def _run_3d(
    problem: CyclicIKProblem,
    t0: float,
    *,
    method: Method,
    n_starts: int | None,
    seed: int,
    starts: str,
    options: ALOptions | IpoptOptions | None,
    obj_tol: float,
    dist_tol: float,
    verdicts: Sequence[ReachVerdict] | Sequence[ReachVerdict3D] | None,
    sweep: SweepOptions,
    budget: float | None,
) -> MultistartResult | ShardReport:
    """:func:`run_multistart` by the general methods."""
    if starts != BRANCH_KIND or n_starts is not None:
        check_start_request(
            _count(n_starts, 16), starts, (*START_KINDS_3D, "feasible", BRANCH_KIND)
        )
    if starts == "feasible" and problem.chain is None:
        raise ParameterError(
            f"start kind 'feasible' needs a planar robot; {problem.robot_model.name!r} is not "
            f"planar for frame {problem.frame!r}: use mixed, coherent or random",
            name="starts",
            value=starts,
        )
    if sweep.workers is None and sweep.executor is None:
        sweep = replace(sweep, workers=1)
    x0s: Array | Starts3D | PlanarStarts | BranchStarts
    if starts == BRANCH_KIND:
        x0s = BranchStarts(problem, n_starts, seed, verdicts=verdicts or ())
        if sweep.keep_results:
            x0s = _drawn(x0s)
    elif starts == "feasible":
        found = check_planar(problem)
        x0s = PlanarStarts(problem, _count(n_starts, 16), seed, kind="feasible", verdicts=found)
        if sweep.keep_results:
            x0s = _drawn(x0s)
    elif sweep.keep_results:
        x0s = make_starts_3d(problem, _count(n_starts, 16), seed, kind=starts)
    else:  # each start drawn as its task is made
        x0s = Starts3D(problem, _count(n_starts, 16), seed, kind=starts)
    executor, n_workers = resolve_executor(sweep)
    return _run(
        problem, t0, x0s, method=method, seed=seed, starts=starts, options=options,
        planar=False, verdicts=(), obj_tol=obj_tol, dist_tol=dist_tol,
        sweep=replace(sweep, executor=executor, workers=n_workers), budget=budget,
    )  # fmt: skip


def _drawn(starts: PlanarStarts | BranchStarts) -> Array:
    """Every start of a lazy sequence, drawn now: ``(n_starts, n s)`` [rad] (or [m])."""
    return np.array([starts[k] for k in range(len(starts))])


def _run(
    problem: CyclicIKProblem,
    t0: float,
    x0s: Array | PlanarStarts | Starts3D | BranchStarts,
    *,
    method: Method,
    seed: int,
    starts: str,
    options: ALOptions | IpoptOptions | None,
    planar: bool,
    verdicts: tuple[ReachVerdict, ...],
    obj_tol: float,
    dist_tol: float,
    sweep: SweepOptions,
    budget: float | None,
) -> MultistartResult | ShardReport:
    """Solve the starts ``x0s`` (``sweep`` resolved) and cluster the minima.

    ``budget`` [s]: no start begins later than ``t0 + budget`` (``None``: every start runs).
    """
    store = None
    if sweep.out is not None:
        params = store_params(
            problem, planar=planar, method=method, options=options, n_starts=len(x0s),
            seed=seed, kind=starts,
        )  # fmt: skip
        store = open_store(
            sweep.out,
            SWEEP_KIND if planar else SWEEP_KIND_3D,
            params,
            result_codec(problem, planar=planar, starts=x0s),
            clean=sweep.shard is None,
        )
    solvers = PLANAR_STARTS if planar else STARTS_3D
    distance = minimum_distance(problem, planar=planar)
    on_resumed, on_final = progress_callbacks(sweep.progress, len(x0s))
    results: Sequence[IKPathResult]
    attempts: Sequence[int]
    tally: StartTally[int] | None = None
    deadline = None if budget is None else t0 + budget - time.perf_counter() + time.monotonic()
    if not sweep.keep_results:
        assert store is not None  # SweepOptions requires out= with keep_results=False
        streamed = stream_starts(
            problem, x0s, method=method, options=options, sweep=sweep, solvers=solvers,
            store=store, distance=distance, obj_tol=obj_tol, dist_tol=dist_tol,
            on_resumed=on_resumed, on_final=on_final, deadline=deadline,
        )  # fmt: skip
        if isinstance(streamed, ShardReport):
            return streamed
        results, attempts, resumed = streamed.results, streamed.attempts, streamed.resumed
        not_run = streamed.not_run
        minima = _stored_minima(streamed.minima, streamed.kept, streamed.results)
        tally = streamed.tally
    else:  # the starts were drawn together
        outcome = solve_starts(
            problem, np.asarray(x0s), method=method, options=options, sweep=sweep,
            solvers=solvers, store=store, on_resumed=on_resumed, on_final=on_final,
            deadline=deadline,
        )  # fmt: skip
        if isinstance(outcome, ShardReport):
            return outcome
        results, attempts, resumed = outcome.results, outcome.attempts, outcome.resumed
        not_run = outcome.not_run
        minima = cluster_minima(
            outcome.results, obj_tol=obj_tol, dist_tol=dist_tol, distance=distance
        )
    return MultistartResult(
        problem=problem,
        method=method,
        seed=int(seed),
        start_kind=starts,
        planar=planar,
        results=results,
        minima=minima,
        verdicts=verdicts,
        wall_time=time.perf_counter() - t0,
        n_workers=int(sweep.workers or 1),
        attempts=attempts,
        resumed=resumed,
        output=None if store is None else store.directory,
        tally=tally,
        obj_tol=obj_tol,
        dist_tol=dist_tol,
        time_budget=budget,
        not_run=not_run,
    )


def _count(n_starts: int | None, default: int) -> int:
    return default if n_starts is None else n_starts


def _stored_minima(
    minima: Sequence[ClusterIndices] | Clusters,
    kept: dict[int, IKPathResult],
    results: Sequence[IKPathResult],
) -> tuple[IKPathOptimum, ...]:
    """Return the :class:`IKPathOptimum` s of a ``keep_results=False`` selection (lazy members).

    ``kept``: the representatives by start index (held); the other members
    are read from ``results`` (the output folder) when asked for.
    """
    if isinstance(minima, Clusters):
        minima = tuple(
            ClusterIndices(minima, c, _key_index, sorted_order=False) for c in range(len(minima))
        )

    def read(i: int) -> IKPathResult:
        return kept[i] if i in kept else results[i]

    return tuple(
        IKPathOptimum(
            members=OptimumMembers(members, read),
            n_starts=len(results),
            start_indices=members.ascending(),
        )
        for members in minima
    )


def _key_index(key: str) -> int:
    return int(key.rsplit("_", 1)[1])
