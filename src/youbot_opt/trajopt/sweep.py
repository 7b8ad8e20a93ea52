"""Start jobs of the trajectory sweeps: seeds, guesses, stored outcomes (spec ``trajopt.md``).

Owns what the trajectory multistart, the Pareto sweep's first point and the
bound-scaling study add to the robot-agnostic sweep engine (:mod:`youbot_opt.sweeps`):
:func:`start_seeds`, :func:`make_jobs` (:class:`StartJobs`, :class:`StartJobChain`:
jobs made from their index), the worker task that solves a job's guess with the
worker's solver, and :func:`solve_starts`, the resumable start loop as
:class:`StartOutcome` s (:func:`start_states` reads a stored sweep's statuses). Their
store is :mod:`youbot_opt.trajopt.sweep_store`.

    outcomes, resumed, _ = solve_starts(solver, make_jobs(8, seed=0, beta=0.5, bound_scale=1.0,
                                        include_straight=True, dt0=0.1), store=None, sweep=opts)
"""

from __future__ import annotations

import contextlib
import dataclasses
import logging
import math
import time
from collections.abc import Callable, Iterator, MutableMapping, Sequence
from dataclasses import dataclass
from typing import Any, Literal, NamedTuple

import numpy as np

from youbot_opt._typing import JSONDict
from youbot_opt.exceptions import ParameterError, ResultFileError
from youbot_opt.sweeps.lazy import LazySequence
from youbot_opt.sweeps.optima import KeepRule
from youbot_opt.sweeps.options import SweepOptions
from youbot_opt.sweeps.pool import Task, TaskOutcome, process_context
from youbot_opt.sweeps.resume import ShardReport, run_resumable
from youbot_opt.sweeps.selection import Clusters
from youbot_opt.sweeps.store import ItemRecord, SweepStore
from youbot_opt.sweeps.tasks import TaskSequence
from youbot_opt.sweeps.worker_solver import WorkerSolver, hold_solver
from youbot_opt.trajopt.problem import TrajOptProblem
from youbot_opt.trajopt.result import TrajOptResult
from youbot_opt.trajopt.solver import TrajOptSolver
from youbot_opt.trajopt.trajectory import Trajectory

__all__ = [
    "SolvedStarts",
    "StartJobChain",
    "StartJobs",
    "StartOutcome",
    "check_solver",
    "default_dt0",
    "make_jobs",
    "solve_starts",
    "start_seeds",
    "start_states",
    "worker_solver",
]

_log = logging.getLogger(__name__)

GuessKind = Literal["spline", "straight"]


def worker_solver(solver: TrajOptSolver, *, keep: bool) -> WorkerSolver[TrajOptSolver]:
    """Return the handle of ``solver`` that travels with every task of one run.

    Parameters
    ----------
    solver : TrajOptSolver
        The built solver.
    keep : bool
        Keep the built solver in the handle (serial runs, and pools forked
        from this process, which inherit it); otherwise each worker builds
        its own once (per thread for thread pools).

    Returns
    -------
    WorkerSolver
        ``TrajOptSolver(problem, method, options, backend)`` as a recipe.
    """
    return WorkerSolver.of(
        TrajOptSolver,
        solver.problem,
        solver.method,
        solver.options,
        solver.backend,
        prebuilt=solver if keep else None,
    )


@dataclass(frozen=True, slots=True, kw_only=True)
class _StartJob:
    key: str
    index: int
    seed: int | None
    guess: GuessKind
    beta: float
    bound_scale: float
    dt0: float


def _solve_start(
    handle: WorkerSolver[TrajOptSolver], job: _StartJob
) -> tuple[TrajOptResult, float]:
    """Worker task: build the start's guess and solve; returns the result and guess time [s]."""
    solver = handle.get()
    problem = solver.problem
    tic = time.perf_counter()
    guess: Trajectory | None = None
    if job.guess == "spline":
        from youbot_opt.trajopt.spline_guess import random_spline_guess

        guess = random_spline_guess(
            problem.robot,
            problem.start,
            problem.goal,
            problem.n_knots,
            seed=job.seed,
            dt=job.dt0,
            bounds=problem.bounds(job.bound_scale),
            damping=problem.damping,
        )
    guess_time = time.perf_counter() - tic
    result = solver.solve(beta=job.beta, bound_scale=job.bound_scale, guess=guess, seed=job.seed)
    return result, guess_time


# ---------------------------------------------------------------- outcomes
@dataclass(frozen=True, slots=True, kw_only=True)
class StartOutcome:
    """One start of a multistart: its figures and its result.

    Attributes
    ----------
    key : str
        Item key (``"start_0007"``, ``"straight"``).
    index : int
        Start index (-1 for the straight-line start).
    seed : int or None
        Seed of the random spline guess (``None`` for the straight line).
    guess : {"spline", "straight"}
        Kind of initial guess.
    status : str
        :class:`~youbot_opt.trajopt.result.SolveStatus` value, or ``"error"`` if the
        start raised or its worker crashed.
    success : bool
        True if the solve converged and passed the result's checks.
    objective : float
        ``beta T + (1 - beta) W`` (NaN on error).
    duration : float
        Motion duration ``T`` in [s] (NaN on error).
    work : float
        ``W`` in [N^2 m^2 s] (NaN on error).
    iterations : int
        IPOPT iterations.
    solve_time : float
        Wall time of the solve in [s].
    guess_time : float
        Wall time spent building the guess in [s].
    attempts : int
        Attempts made (a failure is retried once).
    reason : str or None
        Why the start failed (error, or the solver's message for a failed solve).
    result : TrajOptResult or None
        The result (``None`` on error, and for starts whose result a
        ``keep_results=False`` sweep left in its output directory).
    optimum : str or None
        ``keep_results=False`` only: key of the representative of the start's
        distinct optimum (its own key for a representative), else ``None``.
    """

    key: str
    index: int
    seed: int | None
    guess: GuessKind
    status: str
    success: bool
    objective: float
    duration: float
    work: float
    iterations: int
    solve_time: float
    guess_time: float
    attempts: int = 1
    reason: str | None = None
    result: TrajOptResult | None = None
    optimum: str | None = None

    def summary(self) -> JSONDict:
        """JSON-ready figures (everything but the result; NaN becomes ``None``)."""

        def num(x: float) -> float | None:
            return float(x) if math.isfinite(x) else None

        return {
            "key": self.key,
            "index": self.index,
            "seed": self.seed,
            "guess": self.guess,
            "status": self.status,
            "success": self.success,
            "objective": num(self.objective),
            "duration_s": num(self.duration),
            "work": num(self.work),
            "iterations": self.iterations,
            "solve_time_s": self.solve_time,
            "guess_time_s": self.guess_time,
            "attempts": self.attempts,
            "reason": self.reason,
        }

    @classmethod
    def _from(
        cls, job: _StartJob, result: TrajOptResult, guess_time: float, attempts: int
    ) -> StartOutcome:
        return cls(
            key=job.key,
            index=job.index,
            seed=job.seed,
            guess=job.guess,
            status=result.status.value,
            success=result.success,
            objective=float(result.objective),
            duration=float(result.duration),
            work=float(result.work),
            iterations=int(result.iterations),
            solve_time=float(result.wall_time),
            guess_time=float(guess_time),
            attempts=attempts,
            reason=None if result.success else result.message,
            result=result,
        )

    @classmethod
    def _error(cls, job: _StartJob, reason: str, attempts: int) -> StartOutcome:
        nan = float("nan")
        return cls(
            key=job.key,
            index=job.index,
            seed=job.seed,
            guess=job.guess,
            status="error",
            success=False,
            objective=nan,
            duration=nan,
            work=nan,
            iterations=0,
            solve_time=0.0,
            guess_time=0.0,
            attempts=attempts,
            reason=reason,
        )


# ------------------------------------------------------------------ running
def start_seeds(seed: int, n_starts: int) -> tuple[int, ...]:
    """Seeds of the random starts: ``SeedSequence(seed).spawn(n_starts)``, one 32-bit word each.

    Parameters
    ----------
    seed : int
        Base seed (>= 0).
    n_starts : int
        Number of seeds.

    Returns
    -------
    tuple of int
        Independent seeds; start ``i``'s seed does not depend on ``n_starts``.
    """
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0:
        raise ParameterError(f"seed must be an int >= 0, got {seed!r}", name="seed")
    children = np.random.SeedSequence(int(seed)).spawn(int(n_starts))
    return tuple(int(c.generate_state(1, dtype=np.uint32)[0]) for c in children)


def check_solver(solver: object) -> TrajOptSolver:
    """Return ``solver`` if it is a built :class:`~youbot_opt.trajopt.solver.TrajOptSolver`.

    Raises
    ------
    ParameterError
        Otherwise (a problem too: build it once with ``TrajOptSolver(problem)``).
    """
    if isinstance(solver, TrajOptSolver):
        return solver
    hint = " (build one: TrajOptSolver(problem))" if isinstance(solver, TrajOptProblem) else ""
    raise ParameterError(
        f"expected a TrajOptSolver, got {type(solver).__name__}{hint}", name="solver", value=solver
    )


class SolvedStarts(NamedTuple):
    """What :func:`solve_starts` returns."""

    outcomes: MutableMapping[str, StartOutcome]
    """The outcome of every start, by key (``keep_results=False``: read from the store
    when asked for, the kept optima in full)."""
    resumed: int
    """Starts loaded from the store instead of solved."""
    clusters: Sequence[Sequence[str]] = ()
    """``keep_results=False``: the distinct optima of ``keep`` as keys, each
    representative first, best optimum first (members read from the store's
    optima file when asked for); empty otherwise."""


def solve_starts(
    solver: TrajOptSolver,
    jobs: Sequence[_StartJob],
    *,
    store: SweepStore | None,
    sweep: SweepOptions,
    keep: KeepRule[StartOutcome] | None = None,
) -> SolvedStarts | ShardReport:
    """Run start jobs, loading the finished ones from ``store``.

    Parameters
    ----------
    solver : TrajOptSolver
        The built solver (inherited by forked workers, else rebuilt once per worker).
    jobs : sequence
        From :func:`make_jobs`, or a :class:`StartJobs` / :class:`StartJobChain`
        (with ``keep_results=False`` no job is then held).
    store : SweepStore, optional
        Where every attempt is saved and finished starts are loaded from.
    sweep : SweepOptions
        Executor, workers, timeout [s] per attempt, attempts; ``progress``
        ``(done, total, last_start)`` is called as each start is final;
        ``keep_results=False`` keeps results only for ``keep``'s optima.
    keep : KeepRule, optional
        Which results ``keep_results=False`` keeps (default: the best start
        of each ``(beta, bound_scale)``); the other starts have ``result=None``.

    Returns
    -------
    SolvedStarts or ShardReport
        The outcomes by key (``keep_results=False``: read from ``store`` when
        asked for), the number of starts loaded from ``store`` and the optima;
        a shard run (``sweep.shard``) returns its :class:`ShardReport`.
    """
    sweep = sweep.with_executor("process")
    executor = sweep.executor
    own_pool = executor == "process"
    fork = own_pool and process_context().get_start_method() == "fork"
    # The handle travels with every task; pickling drops its prebuilt solver, so
    # pool workers use the one their initializer set (inherited under fork).
    handle = worker_solver(solver, keep=executor == "serial" or fork)
    # On Dask the recipe (problem included) goes once per worker with the
    # initializer; each task then carries only the handle's token.
    send_once = own_pool or sweep.distributed
    sent = handle.by_token() if sweep.distributed else handle
    made_lazily = isinstance(jobs, StartJobs | StartJobChain)
    lazy = made_lazily and not sweep.keep_results
    job_of: Callable[[str], _StartJob] = (
        jobs.job  # type: ignore[attr-defined]
        if made_lazily
        else {job.key: job for job in jobs}.__getitem__
    )

    def make_task(i: int) -> Task:
        job = jobs[i]
        return Task(key=job.key, fn=_solve_start, args=(sent, job))

    # keep_results=False with StartJobs: tasks made as they are needed (none is held)
    tasks = TaskSequence(len(jobs), make_task) if lazy else [make_task(i) for i in range(len(jobs))]
    progress = sweep.progress
    optimum_of: list[Callable[[str], str | None]] = []  # set once the optima are chosen

    def light(key: str, record: ItemRecord) -> StartOutcome:
        start = _light_start(job_of(key), record)
        rep = optimum_of[0](key) if optimum_of else None
        return start if rep is None else dataclasses.replace(start, optimum=rep)

    def convert(o: TaskOutcome) -> StartOutcome:
        job = job_of(o.key)
        if o.ok:
            result, guess_time = o.value
            return StartOutcome._from(job, result, guess_time, o.attempts)
        return StartOutcome._error(job, str(o.error), o.attempts)

    def on_final(key: str, start: StartOutcome, done: int) -> None:
        if progress is not None:
            progress(done, len(jobs), start)

    if keep is None:
        keep = KeepRule(
            objective=lambda s: s.objective if s.success else None,
            group=lambda s: (job_of(s.key).beta, job_of(s.key).bound_scale),
        )
    got = run_resumable(
        tasks,
        store=store,
        options=sweep,
        load=lambda key: _load_start(store, job_of(key)),  # type: ignore[arg-type]
        convert=convert,
        payload=lambda key, start: (start.result, start.summary()),
        initializer=hold_solver if send_once else None,
        initargs=(handle,) if send_once else (),
        on_final=on_final,
        describe=_describe_start,
        light=light,
        keep=keep,
    )
    if isinstance(got, ShardReport):  # a shard run: its share is saved, nothing to collect
        return got
    items = got.items
    clusters = got.clusters
    if isinstance(clusters, Clusters):  # keep_results=False: each start's optimum, read lazily
        optimum_of.append(clusters.optimum_of)
        for rep in clusters.representatives:  # the kept optima, held in full
            items[rep] = dataclasses.replace(items[rep], optimum=rep)
    return SolvedStarts(items, got.resumed, clusters)


def start_states(jobs: Sequence[_StartJob], store: SweepStore) -> Iterator[tuple[str, bool]]:
    """Yield each finished start's status and success from its record in ``store``.

    One pass over the jobs reading each start's summary from the store's
    journal (as :class:`StartOutcome` s read back are made), holding nothing
    per start: what a ``keep_results=False`` multistart counts once
    (:func:`~youbot_opt.sweeps.multistart.tally_starts`). A start that failed
    every attempt is ``("error", False)``.

    Raises
    ------
    ResultFileError
        If a start has no record in ``store`` (it has not finished).
    """
    for job in jobs:
        record = store.record(job.key)
        if record is None:
            raise ResultFileError(f"start {job.key!r} has no record in {store.directory}")
        if record.state == "failed":
            yield "error", False
        else:
            yield str(record.summary["status"]), bool(record.summary["success"])


def _describe_start(
    key: str, args: tuple[Any, ...], value: tuple[TrajOptResult, float]
) -> tuple[TrajOptResult, JSONDict]:
    """Worker side: the payload (the result) and summary of a solved start."""
    job: _StartJob = args[1]
    result, guess_time = value
    return result, StartOutcome._from(job, result, guess_time, 1).summary()


def _light_start(job: _StartJob, record: ItemRecord) -> StartOutcome:
    """Return a finished start from its stored summary alone (``result=None``)."""
    if record.state == "failed":
        return StartOutcome._error(job, record.reasons[-1] if record.reasons else "failed",
                                   record.attempts)  # fmt: skip
    s = record.summary
    num = record.number
    return StartOutcome(
        key=job.key,
        index=job.index,
        seed=job.seed,
        guess=job.guess,
        status=str(s["status"]),
        success=bool(s["success"]),
        objective=num("objective"),
        duration=num("duration_s"),
        work=num("work"),
        iterations=int(num("iterations")),
        solve_time=num("solve_time_s"),
        guess_time=num("guess_time_s"),
        attempts=record.attempts,
        reason=None if s.get("reason") is None else str(s["reason"]),
    )


def _load_start(store: SweepStore, job: _StartJob) -> StartOutcome:
    record = store.record(job.key)
    assert record is not None
    if record.state == "failed":
        reason = record.reasons[-1] if record.reasons else "failed"
        return StartOutcome._error(job, reason, record.attempts)
    result: TrajOptResult = store.load(job.key)
    guess_time = record.number("guess_time_s", default=0.0)
    return StartOutcome._from(job, result, guess_time, record.attempts)


def default_dt0(problem: TrajOptProblem) -> float:
    """Time step in [s] of the random spline guesses: the study's 0.1 s at 50 knots.

    The guess duration ``(N - 1) dt0`` is held at
    :data:`youbot_opt.trajopt.guess.DEFAULT_GUESS_DURATION` (4.9 s) for every
    knot count ``N`` (a fixed problem duration, if set, wins), so coarse
    problems get guesses slow enough to respect the speed limits.
    """
    from youbot_opt.trajopt.guess import DEFAULT_GUESS_DURATION

    total = problem.duration if problem.duration is not None else DEFAULT_GUESS_DURATION
    return total / (problem.n_knots - 1)


def make_jobs(
    n_starts: int,
    *,
    seed: int,
    beta: float,
    bound_scale: float,
    include_straight: bool,
    dt0: float,
    prefix: str = "",
) -> list[_StartJob]:
    """Make the start jobs of one multistart (straight line first, then seeded splines)."""
    return list(
        StartJobs(
            n_starts,
            seed=seed,
            beta=beta,
            bound_scale=bound_scale,
            include_straight=include_straight,
            dt0=dt0,
            prefix=prefix,
        )
    )


class StartJobs(LazySequence[_StartJob]):
    """The start jobs of one multistart made when asked for; equal to :func:`make_jobs`'s.

    Job ``i`` is built from its index alone (start ``k``'s seed is
    ``SeedSequence(seed, spawn_key=(k,))``, the ``k``-th child
    :func:`start_seeds` spawns), so a ``keep_results=False`` sweep of 10^6
    starts never holds its jobs. Parameters as :func:`make_jobs`.
    """

    def __init__(
        self,
        n_starts: int,
        *,
        seed: int,
        beta: float,
        bound_scale: float,
        include_straight: bool,
        dt0: float,
        prefix: str = "",
    ) -> None:
        if isinstance(n_starts, bool) or not isinstance(n_starts, int) or n_starts < 0:
            raise ParameterError(f"n_starts must be an int >= 0, got {n_starts!r}", name="n_starts")
        if n_starts == 0 and not include_straight:
            raise ParameterError("need n_starts >= 1 or include_straight=True", name="n_starts")
        if not (math.isfinite(dt0) and dt0 > 0):
            raise ParameterError(f"dt0 must be > 0 [s], got {dt0!r}", name="dt0")
        start_seeds(seed, 0)  # checks the seed
        self._n, self._seed, self._straight = n_starts, int(seed), bool(include_straight)
        self._common = {"beta": beta, "bound_scale": bound_scale, "dt0": dt0}
        self._prefix = prefix

    @property
    def prefix(self) -> str:
        """Prefix of the jobs' keys."""
        return self._prefix

    def __len__(self) -> int:
        return self._n + self._straight

    noun = "start job"

    def _item(self, j: int) -> _StartJob:
        if self._straight and j == 0:
            return _StartJob(key=f"{self._prefix}straight", index=-1, seed=None,
                             guess="straight", **self._common)  # fmt: skip
        k = j - self._straight
        child = np.random.SeedSequence(self._seed, spawn_key=(k,))
        return _StartJob(key=f"{self._prefix}start_{k:04d}", index=k, guess="spline",
                         seed=int(child.generate_state(1, dtype=np.uint32)[0]),
                         **self._common)  # fmt: skip

    def job(self, key: str) -> _StartJob:
        """Return the job of ``key`` (``KeyError`` if it is not one of these jobs)."""
        rest = key[len(self._prefix) :] if key.startswith(self._prefix) else None
        if rest == "straight" and self._straight:
            return self[0]
        if rest is not None and rest.startswith("start_") and rest[6:].isdigit():
            k = int(rest[6:])
            if k < self._n and f"start_{k:04d}" == rest:
                return self[k + self._straight]
        raise KeyError(key)


class StartJobChain(LazySequence[_StartJob]):
    """Several :class:`StartJobs` in a row (e.g. one per bound scale), made when asked for.

    Parameters
    ----------
    parts : sequence of StartJobs
        With distinct key prefixes.
    """

    def __init__(self, parts: Sequence[StartJobs]) -> None:
        self.parts = tuple(parts)
        self._ends = np.cumsum([len(p) for p in self.parts], dtype=np.int64)

    def __len__(self) -> int:
        return int(self._ends[-1]) if self.parts else 0

    noun = "start job"

    def _item(self, j: int) -> _StartJob:
        part = int(np.searchsorted(self._ends, j, side="right"))
        return self.parts[part][j - (int(self._ends[part - 1]) if part else 0)]

    def job(self, key: str) -> _StartJob:
        """Return the job of ``key`` (``KeyError`` if it is not one of these jobs)."""
        for part in self.parts:
            if key.startswith(part.prefix):
                with contextlib.suppress(KeyError):
                    return part.job(key)
        raise KeyError(key)
