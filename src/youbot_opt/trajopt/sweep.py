"""Start jobs of the trajectory sweeps: seeds, guesses, worker solvers, stored outcomes.

The machinery behind :func:`youbot_opt.trajopt.multistart.run_multistart`, the Pareto
sweep's first point and :func:`youbot_opt.trajopt.bound_scaling.bound_scaling_study`:

* :func:`start_seeds` derives start ``i``'s seed from a base seed with
  :class:`numpy.random.SeedSequence` (``spawn``), independent of the executor;
* a start job builds its random spline guess
  (:func:`youbot_opt.trajopt.spline_guess.random_spline_guess`, at the scaled bounds)
  or uses the straight line, and solves with the worker's
  :class:`~youbot_opt.trajopt.solver.TrajOptSolver`: inherited from the parent under
  ``fork``, else built once by the pool initializer and cached per process
  (per thread for thread pools);
* :func:`solve_starts` runs the jobs through :func:`youbot_opt.sweeps.tasks.run_tasks`,
  saving each finished start to a :class:`~youbot_opt.sweeps.store.SweepStore`
  and loading the ones a previous run finished;
* :class:`StartOutcome` is one start's figures and result.
"""

from __future__ import annotations

import logging
import math
import os
import threading
import time
import uuid
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np

from youbot_opt.exceptions import ParameterError
from youbot_opt.nlp.ipopt import IpoptOptions
from youbot_opt.sweeps.tasks import ExecutorLike, Task, TaskOutcome, process_context, run_tasks
from youbot_opt.trajopt.problem import TrajOptProblem
from youbot_opt.trajopt.result import TrajOptResult
from youbot_opt.trajopt.solver import TrajOptSolver
from youbot_opt.sweeps.store import SweepStore
from youbot_opt.trajopt.trajectory import Trajectory

__all__ = [
    "StartOutcome",
    "default_dt0",
    "make_jobs",
    "solve_starts",
    "start_seeds",
    "sweep_params",
]

_log = logging.getLogger(__name__)

GuessKind = Literal["spline", "straight"]
ProgressFn = Callable[[int, int, "StartOutcome"], None]

# Per-process (and per-thread) solver of pool workers: set by the pool
# initializer, read by every start the worker runs. This is the only
# module-level state, and it exists only inside worker processes/threads.
_WORKER = threading.local()


# ---------------------------------------------------------------- solver spec
@dataclass(frozen=True, slots=True, kw_only=True)
class _SolverSpec:
    """Everything a worker needs to build (or find) the solver; pickles without it."""

    problem: TrajOptProblem
    method: Any
    options: IpoptOptions
    backend: str
    token: str
    prebuilt: TrajOptSolver | None = field(default=None, compare=False)

    @classmethod
    def of(cls, solver: TrajOptSolver, *, keep: bool) -> _SolverSpec:
        return cls(
            problem=solver.problem,
            method=solver.method,
            options=solver.options,
            backend=solver.backend,
            token=uuid.uuid4().hex,
            prebuilt=solver if keep else None,
        )

    def __getstate__(self) -> tuple[Any, ...]:
        return (self.problem, self.method, self.options, self.backend, self.token)

    def __setstate__(self, state: tuple[Any, ...]) -> None:
        for name, value in zip(
            ("problem", "method", "options", "backend", "token"), state, strict=True
        ):
            object.__setattr__(self, name, value)
        object.__setattr__(self, "prebuilt", None)

    def solver(self) -> TrajOptSolver:
        """Return the prebuilt solver, this worker's cached one, or a new one (then cached)."""
        if self.prebuilt is not None:
            return self.prebuilt
        if getattr(_WORKER, "token", None) != self.token:
            _WORKER.solver = TrajOptSolver(self.problem, self.method, self.options, self.backend)
            _WORKER.token = self.token
        solver: TrajOptSolver = _WORKER.solver
        return solver


def _init_worker_solver(spec: _SolverSpec) -> None:
    """Pool initializer: hold the solver for every start this worker runs."""
    _WORKER.solver = spec.solver()
    _WORKER.token = spec.token


@dataclass(frozen=True, slots=True, kw_only=True)
class _StartJob:
    key: str
    index: int
    seed: int | None
    guess: GuessKind
    beta: float
    bound_scale: float
    dt0: float


def _solve_start(spec: _SolverSpec, job: _StartJob) -> tuple[TrajOptResult, float]:
    """Worker task: build the start's guess and solve; returns the result and guess time [s]."""
    solver = spec.solver()
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
        The result (``None`` on error).
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

    def summary(self) -> dict[str, Any]:
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


def _as_solver(
    solver_or_problem: TrajOptSolver | TrajOptProblem,
    method: Any,
    options: IpoptOptions | None,
    backend: str,
) -> TrajOptSolver:
    if isinstance(solver_or_problem, TrajOptSolver):
        return solver_or_problem
    if isinstance(solver_or_problem, TrajOptProblem):
        return TrajOptSolver(solver_or_problem, method, options, backend)
    raise ParameterError(
        f"expected a TrajOptSolver or a TrajOptProblem, got {type(solver_or_problem).__name__}",
        name="solver_or_problem",
    )


def _store_for(
    out: str | os.PathLike[str], kind: str, params: dict[str, Any], solver: TrajOptSolver
) -> SweepStore:
    """Open a store whose payloads are trajectory results (:mod:`youbot_opt.trajopt.io` files)."""
    from youbot_opt.trajopt.io import load_result, save_result

    robot = solver.problem.robot

    def load(path: Path) -> TrajOptResult:
        return load_result(path, robot=robot)

    return SweepStore(out, kind=kind, params=params, save=save_result, load=load, suffix=".npz")


def sweep_params(solver: TrajOptSolver) -> dict[str, Any]:
    """JSON-ready description of the solver a sweep runs (part of its manifest)."""
    return {
        "problem": solver.problem.describe(),
        "method": solver.method.name,
        "backend": solver.backend,
        "options": solver.options.to_dict(),
    }


def solve_starts(
    solver: TrajOptSolver,
    jobs: Sequence[_StartJob],
    *,
    store: SweepStore | None,
    executor: ExecutorLike,
    workers: int | None,
    progress: ProgressFn | None,
    max_attempts: int,
    timeout: float | None = None,
) -> tuple[dict[str, StartOutcome], int]:
    """Run start jobs (loading finished ones from ``store``); outcomes by key and resumed count.

    ``timeout`` is the wall-clock limit in [s] per start attempt
    (:func:`youbot_opt.sweeps.tasks.run_tasks`; ``None``: no limit).
    """
    outcomes: dict[str, StartOutcome] = {}
    todo: list[Task] = []
    by_key = {job.key: job for job in jobs}
    own_pool = executor == "process"
    fork = own_pool and process_context().get_start_method() == "fork"
    # The spec travels with every task; pickling drops its prebuilt solver, so
    # pool workers use the one their initializer set (inherited under fork).
    spec = _SolverSpec.of(solver, keep=executor == "serial" or fork)
    for job in jobs:
        attempts = 0
        if store is not None:
            again, attempts = store.needs_work(job.key, max_attempts)
            if not again:
                outcomes[job.key] = _load_start(store, job)
                continue
        todo.append(Task(key=job.key, fn=_solve_start, args=(spec, job), attempts=attempts))
    resumed = len(outcomes)
    total = len(jobs)

    def record(o: TaskOutcome) -> None:
        job = by_key[o.key]
        if o.ok:
            result, guess_time = o.value
            start = StartOutcome._from(job, result, guess_time, o.attempts)
            if store is not None:
                store.write_done(job.key, result, start.summary(), attempts=o.attempts)
        else:
            start = StartOutcome._error(job, str(o.error), o.attempts)
            if store is not None:
                store.write_failed(job.key, str(o.error), attempts=o.attempts)
        if o.final:
            outcomes[job.key] = start
            if progress is not None:
                progress(len(outcomes), total, start)

    run_tasks(
        todo,
        executor=executor,
        workers=workers,
        initializer=_init_worker_solver if own_pool else None,
        initargs=(spec,) if own_pool else (),
        max_attempts=max_attempts,
        on_outcome=record,
        timeout=timeout,
    )
    return outcomes, resumed


def _load_start(store: SweepStore, job: _StartJob) -> StartOutcome:
    record = store.record(job.key)
    assert record is not None
    if record.state == "failed":
        reason = record.reasons[-1] if record.reasons else "failed"
        return StartOutcome._error(job, reason, record.attempts)
    result: TrajOptResult = store.load(job.key)
    guess_time = float(record.summary.get("guess_time_s") or 0.0)
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
    if isinstance(n_starts, bool) or not isinstance(n_starts, int) or n_starts < 0:
        raise ParameterError(f"n_starts must be an int >= 0, got {n_starts!r}", name="n_starts")
    if n_starts == 0 and not include_straight:
        raise ParameterError("need n_starts >= 1 or include_straight=True", name="n_starts")
    if not (math.isfinite(dt0) and dt0 > 0):
        raise ParameterError(f"dt0 must be > 0 [s], got {dt0!r}", name="dt0")
    jobs = []
    if include_straight:
        jobs.append(
            _StartJob(
                key=f"{prefix}straight",
                index=-1,
                seed=None,
                guess="straight",
                beta=beta,
                bound_scale=bound_scale,
                dt0=dt0,
            )
        )
    for i, s in enumerate(start_seeds(seed, n_starts)):
        jobs.append(
            _StartJob(
                key=f"{prefix}start_{i:04d}",
                index=i,
                seed=s,
                guess="spline",
                beta=beta,
                bound_scale=bound_scale,
                dt0=dt0,
            )
        )
    return jobs
