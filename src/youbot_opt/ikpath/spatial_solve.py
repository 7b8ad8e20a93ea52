"""The 3-D cyclic IK multistart: resumable, on the sweep engine the planar one uses.

:func:`run_spatial_multistart` solves (:func:`~youbot_opt.ikpath.solve.solve`
with the general methods) from
:func:`~youbot_opt.ikpath.starts.make_starts_3d` under one
:class:`~youbot_opt.sweeps.options.SweepOptions` (process pool or Dask, crash
retry, progress, shards), saving every start in a
:class:`~youbot_opt.sweeps.store.SweepStore` (kind ``"spatial_ikpath_multistart"``,
payloads in the format of :mod:`.io`) that a rerun resumes, and
clusters the distinct minima.
"""

from __future__ import annotations

import functools
import math
import os
import time
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from youbot_opt._typing import Array
from youbot_opt.exceptions import ParameterError
from youbot_opt.ikpath.io import (
    encode_result,
    load_result,
    problem_spec_3d,
)
from youbot_opt.ikpath.methods.al import AL_OPTIONS_3D, ALOptions
from youbot_opt.ikpath.methods.ipopt import IpoptIKSolver3D
from youbot_opt.ikpath.multistart import resolve_executor
from youbot_opt.ikpath.problem import CyclicIKProblem
from youbot_opt.ikpath.reachability.planar import check_reachability
from youbot_opt.ikpath.result import IKPathResult, build_result
from youbot_opt.ikpath.solve import check_method, solve
from youbot_opt.ikpath.starts import (
    START_KINDS_3D,
    PlanarStarts,
    Starts3D,
    check_start_request,
    make_starts_3d,
)
from youbot_opt.ikpath.stored import StartTally
from youbot_opt.ikpath.sweep import (
    StartSolvers,
    crashed_result,
    options_json,
    progress_callbacks,
    solve_starts,
    starts_params,
    starts_store,
    status_counts,
    stream_starts,
)
from youbot_opt.nlp.ipopt import IpoptOptions
from youbot_opt.sweeps.optima import cluster_optima
from youbot_opt.sweeps.options import SweepOptions
from youbot_opt.sweeps.resume import ShardReport
from youbot_opt.sweeps.store import SweepStore
from youbot_opt.sweeps.worker_solver import WorkerSolver

__all__ = [
    "SPATIAL_SWEEP_KIND",
    "SpatialMultistart",
    "open_spatial_store",
    "run_spatial_multistart",
]

SPATIAL_SWEEP_KIND = "spatial_ikpath_multistart"
"""``kind`` of the sweep store of spatial multistarts (in its ``manifest.json``)."""

_PAYLOAD_SUFFIX = ".spatial"  # JSON of encode_result (".json" names the records)


# -- multistart -------------------------------------------------------------------------------
@dataclass(frozen=True, slots=True, kw_only=True, eq=False)
class SpatialMultistart:
    """Results of a spatial multistart.

    Attributes
    ----------
    results : sequence of IKPathResult
        In start order (``crashed`` for a start that failed every attempt): a
        tuple, or with ``keep_results=False`` a
        :class:`~youbot_opt.ikpath.stored.StoredResults` holding the minima's
        results and loading any other from :attr:`output` when indexed.
    minima : tuple of sequence of int
        Start indices of each distinct minimum (successful results), best first;
        the first index of each is its lowest-E member (``keep_results=False``:
        :class:`~youbot_opt.ikpath.stored.ClusterIndices`, read when iterated).
    wall_time : float
        In [s].
    workers : int
        Starts in flight at once.
    method : str
        ``"al"`` or ``"ipopt"``.
    seed : int
        Seed of the starts.
    start_kind : str
        How the starts were drawn (:data:`~youbot_opt.ikpath.starts.START_KINDS_3D`).
    attempts : sequence of int
        Attempts per start, earlier runs on the same output included.
    resumed : int
        Starts loaded from the output directory instead of solved.
    output : Path or None
        Output directory the starts were saved to.
    tally : StartTally or None
        ``keep_results=False``: counts and the start closest to the targets,
        gathered in one pass at the end of the run; ``None`` otherwise.
    """

    results: Sequence[IKPathResult]
    minima: tuple[Sequence[int], ...]
    wall_time: float
    workers: int
    method: str = "al"
    seed: int = 0
    start_kind: str = "mixed"
    attempts: Sequence[int] = ()
    resumed: int = 0
    output: Path | None = None
    tally: StartTally | None = None

    @property
    def best(self) -> IKPathResult:
        """The best successful result, else the result closest to meeting the targets."""
        return self.results[self.best_index]

    @property
    def best_index(self) -> int:
        """Start index of :attr:`best`."""
        if self.minima:
            return self.minima[0][0]
        if self.tally is not None:
            return self.tally.closest
        best = min(
            self.results,
            key=lambda r: float(np.max(r.position_errors) + np.max(r.orientation_errors)),
        )
        return self.results.index(best)

    @property
    def n_success(self) -> int:
        """Number of successful starts."""
        if self.tally is not None:
            return self.tally.n_success
        return sum(r.success for r in self.results)

    @property
    def starts_per_second(self) -> float:
        """Throughput in [1/s]."""
        return len(self.results) / self.wall_time if self.wall_time > 0 else math.inf

    def status_counts(self) -> dict[str, int]:
        """Count the starts per status value."""
        if self.tally is not None:
            return dict(self.tally.status_counts)
        return status_counts(self.results)


def open_spatial_store(
    out: str | os.PathLike[str],
    problem: CyclicIKProblem,
    *,
    method: str,
    options: ALOptions | IpoptOptions | None,
    n_starts: int,
    seed: int,
    kind: str,
    clean: bool = True,
) -> SweepStore:
    """Open (or create) the output directory of one spatial multistart.

    The manifest holds the problem (:func:`~youbot_opt.ikpath.io.problem_spec_3d`:
    robot fingerprint, frame, targets, limits, weights), method, options,
    ``n_starts``, ``seed`` and start kind; reopening with any of them changed
    raises. Stored starts are reloaded with the same forward-kinematics
    re-check as :func:`~youbot_opt.ikpath.io.load_result`.

    Raises
    ------
    ParameterError
        If ``out`` holds another kind of sweep or one with other parameters.
    ResultFileError
        If its manifest is corrupted or from a newer schema.
    """
    if options is None and method == "al":
        options = AL_OPTIONS_3D  # the defaults of solve(planar=False), written out
    spec = problem_spec_3d(problem)
    params = starts_params(spec, method, options_json(method, options), n_starts, seed, kind)
    load = functools.partial(load_result, robot=problem.model)
    return starts_store(out, SPATIAL_STARTS, params, load, clean)


def _solve_al(problem: CyclicIKProblem, options: ALOptions | None, x0: Array) -> IKPathResult:
    """Worker task: one start with the AL (exceptions propagate: they are retried)."""
    result = solve(problem, method="al", x0=x0, options=options, planar=False)
    assert isinstance(result, IKPathResult)
    return result


def _solve_ipopt(handle: WorkerSolver[IpoptIKSolver3D], x0: Array) -> IKPathResult:
    """Worker task: one start with this worker's IPOPT solver (built once per worker)."""
    return handle.get().solve(x0)


def _crashed(
    problem: CyclicIKProblem,
    method: str,
    options: ALOptions | IpoptOptions | None,
    x0: Array,
    message: str,
) -> IKPathResult:
    return crashed_result(build_result, problem, method, x0, message)


def _figures(result: IKPathResult) -> dict[str, Any]:
    """Figures of a start's record summary: its largest target errors in [m] and [rad]."""
    return {
        "max_position_error": float(np.max(result.position_errors)),
        "max_orientation_error": float(np.max(result.orientation_errors)),
    }


SPATIAL_STARTS: StartSolvers[CyclicIKProblem, IKPathResult] = StartSolvers(
    solve_al=_solve_al,
    ipopt_solver=IpoptIKSolver3D,
    solve_ipopt=_solve_ipopt,
    crashed=_crashed,
    figures=_figures,
    store_kind=SPATIAL_SWEEP_KIND,
    suffix=_PAYLOAD_SUFFIX,
    encode=encode_result,
)
"""How :func:`~youbot_opt.ikpath.sweep.solve_starts` solves the starts of a spatial problem."""


def run_spatial_multistart(
    problem: CyclicIKProblem,
    *,
    method: str = "al",
    n_starts: int = 16,
    seed: int = 0,
    starts: str | None = None,
    options: ALOptions | IpoptOptions | None = None,
    workers: int | None = None,
    objective_tol: float = 1e-6,
    q_tol: float = 1e-3,
    sweep: SweepOptions = SweepOptions(),  # noqa: B008 - frozen, so sharing it is safe
) -> SpatialMultistart | ShardReport:
    """Solve from :func:`make_starts_3d` and cluster the distinct minima.

    Parameters
    ----------
    problem : CyclicIKProblem
        The problem.
    method : {"al", "ipopt"}
        Solver.
    n_starts, seed : int
        Number of starts (start 0 is the greedy DLS path) and their seed.
    starts : {"mixed", "coherent", "random", "feasible"}, optional
        Start kind (:mod:`youbot_opt.ikpath.starts`); ``"feasible"``, a planar
        robot's only (:attr:`CyclicIKProblem.chain`), draws the planar
        multistart's starts (random exact IK solutions, the reachability
        witnesses as fallback), so both find the same optima (issue 25, item 4).
        Default: ``"feasible"`` for a planar robot, else ``"mixed"``.
    options : ALOptions or IpoptOptions, optional
        Settings of the method (``max_wall_time`` [s] bounds each start's solve).
    workers : int, optional
        Shortcut for ``sweep.workers`` (default: 1, serial, unless ``sweep`` says otherwise).
    objective_tol, q_tol : float
        Two successes are one minimum when ``E`` agrees to ``objective_tol`` (relative)
        and the angles to ``q_tol`` [rad] (continuous joints modulo a common 2 pi shift).
    sweep : SweepOptions
        How the starts run, as for the planar
        :func:`~youbot_opt.ikpath.multistart.run_multistart`: ``executor``
        (process pool, serial, a caller's pool, a Dask client or scheduler
        address), ``workers``, ``timeout`` [s] per attempt, ``max_attempts``
        (a start that raises or whose worker dies is retried; out of attempts
        it becomes a ``crashed`` result), ``out`` (every finished start saved
        there; a rerun with the same parameters resumes), ``shard``,
        ``progress`` ``(done, total, best_objective)`` and ``keep_results``
        (``False``: only the minima's results held, the rest read from ``out``
        when indexed; as for the planar multistart).

    Returns
    -------
    SpatialMultistart or ShardReport
        Results in start order and the distinct minima; a shard run
        (``sweep.shard``) returns its :class:`~youbot_opt.sweeps.resume.ShardReport`
        instead (its share is saved in ``sweep.out``).

    Raises
    ------
    ParameterError
        Unknown method or start kind, options of the other method, ``workers``
        contradicting ``sweep.workers``, or an ``out`` holding another sweep.
    ResultFileError
        If a stored start is corrupted, or disagrees with the problem.
    """
    t0 = time.perf_counter()
    check_method(method, options)
    if starts is None:
        starts = "feasible" if problem.chain is not None else "mixed"
    check_start_request(n_starts, starts, (*START_KINDS_3D, "feasible"))
    if starts == "feasible" and problem.chain is None:
        raise ParameterError(
            f"start kind 'feasible' needs a planar robot; {problem.robot_model.name!r} is not "
            f"planar for frame {problem.frame!r}: use mixed, coherent or random",
            name="starts",
            value=starts,
        )
    if workers is not None:
        if sweep.workers is not None and sweep.workers != workers:
            raise ParameterError(
                f"workers={workers} contradicts sweep.workers={sweep.workers}",
                name="workers",
                value=workers,
            )
        sweep = replace(sweep, workers=int(workers))
    elif sweep.workers is None and sweep.executor is None:
        sweep = replace(sweep, workers=1)
    x0s: Array | Starts3D | PlanarStarts
    if starts == "feasible":
        verdicts = check_reachability(problem)
        x0s = PlanarStarts(problem, n_starts, seed, kind="feasible", verdicts=verdicts)
        if sweep.keep_results:
            x0s = np.array([x0s[k] for k in range(len(x0s))])
    elif sweep.keep_results:
        x0s = make_starts_3d(problem, n_starts, seed, kind=starts)
    else:  # each start drawn as its task is made
        x0s = Starts3D(problem, n_starts, seed, kind=starts)
    executor, n_workers = resolve_executor(sweep)
    sweep = replace(sweep, executor=executor, workers=n_workers)
    store = None
    if sweep.out is not None:
        store = open_spatial_store(
            sweep.out,
            problem,
            method=method,
            options=options,
            n_starts=len(x0s),
            seed=int(seed),
            kind=starts,
            clean=sweep.shard is None,
        )
    on_resumed, on_final = progress_callbacks(sweep.progress, len(x0s))

    def distance_of(a: IKPathResult, b: IKPathResult) -> float:
        diff = a.configurations - b.configurations
        shift = np.where(
            problem.continuous, 2 * np.pi * np.round(np.median(diff, axis=0) / (2 * np.pi)), 0.0
        )
        return float(np.max(np.abs(diff - shift)))

    tally: StartTally | None = None
    results: Sequence[IKPathResult]
    minima: tuple[Sequence[int], ...]
    if not sweep.keep_results:
        assert store is not None  # SweepOptions requires out= with keep_results=False
        streamed = stream_starts(
            problem,
            x0s,
            method=method,
            options=options,
            sweep=sweep,
            solvers=SPATIAL_STARTS,
            store=store,
            distance=distance_of,
            objective_tol=objective_tol,
            q_tol=q_tol,
            by_objective=False,
            on_resumed=on_resumed,
            on_final=on_final,
        )
        if isinstance(streamed, ShardReport):
            return streamed
        results, attempts, resumed = streamed.results, streamed.attempts, streamed.resumed
        minima, tally = streamed.minima, streamed.tally
    else:
        outcome = solve_starts(
            problem,
            np.asarray(x0s),  # drawn together by make_starts when keep_results=True
            method=method,
            options=options,
            sweep=sweep,
            solvers=SPATIAL_STARTS,
            store=store,
            on_resumed=on_resumed,
            on_final=on_final,
        )
        if isinstance(outcome, ShardReport):
            return outcome
        results, attempts, resumed = outcome.results, outcome.attempts, outcome.resumed
        groups = cluster_optima(
            (i for i, r in enumerate(results) if r.success),
            objective=lambda i: results[i].objective,
            distance=lambda a, b: distance_of(results[a], results[b]),
            obj_tol=objective_tol,
            dist_tol=q_tol,
        )
        minima = tuple(tuple(g) for g in groups)
    return SpatialMultistart(
        results=results,
        minima=minima,
        wall_time=time.perf_counter() - t0,
        workers=n_workers,
        method=method,
        seed=int(seed),
        start_kind=starts,
        attempts=attempts,
        resumed=resumed,
        output=None if store is None else store.directory,
        tally=tally,
    )
