"""Weighted-sum Pareto sweep of duration against work, warm-started along ``beta``.

The study traced the time/work trade-off by solving ``f = beta T + (1 - beta) W``
for ``beta = 0.05 .. 0.95`` in steps of 0.05 (spec ``trajopt.md``).
:func:`pareto_sweep` solves the weights in order, each from the previous point's
solution, in one crash-isolated worker, saving and resuming with ``sweep.out``;
:meth:`ParetoFront.nondominated` drops the dominated points. (The bound-scaling
study lives in :mod:`youbot_opt.trajopt.bound_scaling`.)

    front = pareto_sweep(solver, (0.1, 0.5, 0.9), sweep=SweepOptions(out="runs/pareto"))
"""

from __future__ import annotations

import contextlib
import logging
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, replace
from functools import partial

import numpy as np

from youbot_opt._checks import check_beta, check_bound_scale
from youbot_opt._typing import JSONDict
from youbot_opt.exceptions import ParameterError
from youbot_opt.sweeps.options import SweepOptions
from youbot_opt.sweeps.pool import Task, TaskOutcome, WorkerPool, process_context, run_tasks
from youbot_opt.sweeps.resume import ShardReport
from youbot_opt.sweeps.store import SweepStore, open_store
from youbot_opt.sweeps.worker_solver import WorkerSolver, hold_solver
from youbot_opt.trajopt.multistart import MultistartResult, run_multistart
from youbot_opt.trajopt.result import TrajOptResult
from youbot_opt.trajopt.solver import TrajOptSolver
from youbot_opt.trajopt.sweep import check_solver, worker_solver
from youbot_opt.trajopt.sweep_store import result_codec, sweep_params

__all__ = [
    "ParetoPoint",
    "ParetoFront",
    "pareto_sweep",
    "dominated_mask",
    "point_key",
    "DEFAULT_BETAS",
]

_log = logging.getLogger(__name__)

DEFAULT_BETAS: tuple[float, ...] = tuple(float(b) for b in np.round(np.arange(1, 20) / 20, 10))
"""The study's weights: 0.05, 0.10, ..., 0.95 (19 points)."""


def dominated_mask(
    duration: Sequence[float], work: Sequence[float], rtol: float = 0.0
) -> np.ndarray:
    """Which points are dominated in (duration, work), both minimised.

    Point ``i`` is dominated if some ``j`` has ``T_j <= T_i`` and ``W_j <= W_i``
    with at least one strict. With ``rtol > 0`` differences within
    ``rtol max(|a|, |b|)`` count as ties, so solver noise on two copies of the
    same solution marks neither as dominated. Non-finite points are marked
    dominated.

    Parameters
    ----------
    duration : sequence of float
        ``T`` in [s].
    work : sequence of float
        ``W`` in [N^2 m^2 s].
    rtol : float
        Relative tie tolerance (>= 0; 0 is the exact definition).

    Returns
    -------
    ndarray of bool
        True where dominated.
    """
    if not rtol >= 0:
        raise ParameterError(f"rtol must be >= 0, got {rtol!r}", name="rtol")
    t = np.asarray(duration, dtype=float)
    w = np.asarray(work, dtype=float)
    finite = np.isfinite(t) & np.isfinite(w)
    tt, ww = np.where(finite, t, 0.0), np.where(finite, w, 0.0)
    tol_t = rtol * np.maximum(np.abs(tt)[None, :], np.abs(tt)[:, None])
    tol_w = rtol * np.maximum(np.abs(ww)[None, :], np.abs(ww)[:, None])
    dt = tt[None, :] - tt[:, None]  # [i, j] = T_j - T_i
    dw = ww[None, :] - ww[:, None]
    le = (dt <= tol_t) & (dw <= tol_w)
    lt = (dt < -tol_t) | (dw < -tol_w)
    dominated = np.any(le & lt & finite[None, :], axis=1)
    return dominated | ~finite


@dataclass(frozen=True, slots=True, kw_only=True)
class ParetoPoint:
    """One weight of the sweep.

    Attributes
    ----------
    beta : float
        Time weight in [0, 1].
    duration : float
        ``T`` in [s] (NaN on error).
    work : float
        ``W`` in [N^2 m^2 s] (NaN on error).
    objective : float
        ``beta T + (1 - beta) W``.
    status : str
        :class:`~youbot_opt.trajopt.result.SolveStatus` value, or ``"error"``.
    success : bool
        Whether the solve converged and passed its checks.
    iterations : int
        IPOPT iterations of the kept solve.
    solve_time : float
        Wall time of the solves of this point in [s].
    start : str
        Where the kept solve started: ``"previous"`` (warm start),
        ``"straight"`` or ``"multistart"`` (best of the first point's starts).
    dominated : bool
        True if another converged point is at least as good in T and W and
        better in one (always True for failed points).
    result : TrajOptResult or None
        The kept solve.
    reason : str or None
        Why the point failed, if it did.
    """

    beta: float
    duration: float
    work: float
    objective: float
    status: str
    success: bool
    iterations: int
    solve_time: float
    start: str
    dominated: bool = False
    result: TrajOptResult | None = None
    reason: str | None = None

    def summary(self) -> JSONDict:
        """JSON-ready figures (everything but the result)."""

        def num(x: float) -> float | None:
            return float(x) if math.isfinite(x) else None

        return {
            "beta": self.beta,
            "duration_s": num(self.duration),
            "work": num(self.work),
            "objective": num(self.objective),
            "status": self.status,
            "success": self.success,
            "iterations": self.iterations,
            "solve_time_s": self.solve_time,
            "start": self.start,
            "dominated": self.dominated,
            "reason": self.reason,
        }


@dataclass(frozen=True, slots=True, kw_only=True)
class ParetoFront:
    """Result of :func:`pareto_sweep`.

    Attributes
    ----------
    points : tuple of ParetoPoint
        One per weight, in sweep order, ``dominated`` marked.
    bound_scale : float
        Bound scale factor of every solve.
    first : MultistartResult or None
        The multistart at the first weight, when one was run.
    wall_time : float
        Wall time of the sweep in [s].
    resumed : int
        Points loaded from the output directory.
    """

    points: tuple[ParetoPoint, ...]
    bound_scale: float = 1.0
    first: MultistartResult | None = None
    wall_time: float = 0.0
    resumed: int = 0

    def nondominated(self) -> tuple[ParetoPoint, ...]:
        """Converged, non-dominated points, by increasing duration."""
        keep = [p for p in self.points if p.success and not p.dominated]
        return tuple(sorted(keep, key=lambda p: (p.duration, p.work)))

    @property
    def success_rate(self) -> float:
        """Fraction of weights whose solve converged."""
        return sum(p.success for p in self.points) / len(self.points) if self.points else 0.0

    def summary(self) -> JSONDict:
        """JSON-ready summary of every point."""
        return {
            "bound_scale": self.bound_scale,
            "n_points": len(self.points),
            "success_rate": self.success_rate,
            "n_nondominated": len(self.nondominated()),
            "resumed": self.resumed,
            "wall_time_s": self.wall_time,
            "points": [p.summary() for p in self.points],
        }


def point_key(k: int) -> str:
    """Return the sweep store's key of the ``k``-th weight's point (from 0): ``point_<kkk>``."""
    return f"point_{k:03d}"


def _point(beta: float, result: TrajOptResult, start: str, solve_time: float) -> ParetoPoint:
    return ParetoPoint(
        beta=beta,
        duration=float(result.duration),
        work=float(result.work),
        objective=float(result.objective),
        status=result.status.value,
        success=result.success,
        iterations=int(result.iterations),
        solve_time=solve_time,
        start=start,
        result=result,
        reason=None if result.success else result.message,
    )


def _error_point(beta: float, reason: str) -> ParetoPoint:
    nan = float("nan")
    return ParetoPoint(
        beta=beta,
        duration=nan,
        work=nan,
        objective=nan,
        status="error",
        success=False,
        iterations=0,
        solve_time=0.0,
        start="none",
        reason=reason,
    )


def _solve_point(
    solver: TrajOptSolver,
    beta: float,
    bound_scale: float,
    previous: TrajOptResult | None,
    cold_fallback: bool,
) -> ParetoPoint:
    """Warm-started solve of one weight, with the straight-line fallback."""
    elapsed = 0.0
    if previous is not None:
        warm = solver.solve(beta=beta, bound_scale=bound_scale, guess=previous)
        elapsed += warm.wall_time
        if warm.success or not cold_fallback:
            return _point(beta, warm, "previous", elapsed)
        _log.info(
            "beta = %g: warm start failed (%s); retrying from the straight line",
            beta,
            warm.status.value,
        )
    cold = solver.solve(beta=beta, bound_scale=bound_scale, guess=None)
    elapsed += cold.wall_time
    if previous is not None and not cold.success:
        return _point(beta, warm, "previous", elapsed)
    return _point(beta, cold, "straight", elapsed)


def _solve_point_task(
    handle: WorkerSolver[TrajOptSolver],
    beta: float,
    bound_scale: float,
    previous: TrajOptResult | None,
    cold_fallback: bool,
) -> ParetoPoint:
    """Worker task: one weight, with this worker's (or the parent's) solver."""
    return _solve_point(handle.get(), beta, bound_scale, previous, cold_fallback)


def _check_betas(betas: Sequence[float] | np.ndarray) -> tuple[float, ...]:
    values = tuple(check_beta(float(b)) for b in np.atleast_1d(np.asarray(betas, dtype=float)))
    if not values:
        raise ParameterError("betas must not be empty", name="betas")
    if len(set(values)) != len(values):
        raise ParameterError(f"betas must be distinct, got {list(values)}", name="betas")
    return values


def pareto_sweep(
    solver: TrajOptSolver,
    betas: Sequence[float] | np.ndarray = DEFAULT_BETAS,
    *,
    bound_scale: float = 1.0,
    first_starts: int = 0,
    seed: int = 0,
    warm_start: bool = True,
    cold_fallback: bool = True,
    dominance_rtol: float = 1e-6,
    sweep: SweepOptions = SweepOptions(),  # noqa: B008 - frozen, so sharing it is safe
) -> ParetoFront | ShardReport:
    """Solve every weight in ``betas`` in order, each warm-started from the previous one.

    One NLP is re-solved with ``beta`` as a parameter, each weight from the
    previous point's solution, optionally from several seeded starts at the
    first point (:func:`youbot_opt.trajopt.multistart.run_multistart`), falling
    back to the straight-line guess where a warm start fails. Unless
    ``sweep.executor="serial"``, the points are solved one after the other in
    one persistent worker process (:class:`youbot_opt.sweeps.pool.WorkerPool`;
    it inherits the built solver under ``fork``), each task carrying the
    previous point's result as its warm start. A point whose worker crashes
    (segfault, out-of-memory kill) or runs past ``sweep.timeout`` is recorded as
    failed with the reason and retried once in a fresh worker; the sweep goes
    on. With ``sweep.out=DIR`` each point is saved as it is solved and a rerun
    resumes from the saved points (:mod:`youbot_opt.sweeps.store`); since each
    point starts from the saved previous one, a resumed sweep gives the same
    points, and the first point's multistart (``first_starts``) is reloaded
    from ``DIR/first_point``. A point is *dominated* if another converged point
    has ``T <=`` and ``W <=`` with one inequality strict (ties within
    ``dominance_rtol``).

    Parameters
    ----------
    solver : TrajOptSolver
        The built solver (reused for every weight).
    betas : sequence of float
        Time weights in [0, 1], distinct, solved in this order (default: the
        study's 0.05 .. 0.95 step 0.05).
    bound_scale : float
        Bound scale factor (> 0).
    first_starts : int
        If > 0, the first weight is solved by a multistart of this many seeded
        spline starts plus the straight line (on ``sweep.executor``), keeping the
        best; else from the straight line.
    seed : int
        Base seed of the first point's multistart.
    warm_start : bool
        Start each weight from the previous solution (else from the straight line).
    cold_fallback : bool
        Where a warm start fails, also try the straight line.
    dominance_rtol : float
        Relative tolerance below which differences in T or W are ties when
        marking dominated points (default 1e-6, above IPOPT's ``tol`` = 1e-8
        noise; 0 for the exact definition).
    sweep : SweepOptions
        ``executor`` and ``workers``: where the first point's multistart runs
        (:func:`youbot_opt.sweeps.pool.run_tasks`); the points run in one
        persistent worker process, crash-isolated, unless ``executor="serial"``
        (then in this process). ``timeout``: wall-clock limit in [s] per point
        (and first-point start) attempt; not serial. ``max_attempts``: per
        point (default 2). ``out``: output directory; each point is saved as it
        is solved, and a rerun resumes. ``progress`` ``(done, total,
        last_point)``: called after each weight. ``keep_results=False`` (needs
        ``out``) applies to the first point's multistart: its starts stay in
        ``out/first_point`` and it holds only its tally, best start and optima.
        The points themselves are always held with their results: they are the
        product (each a plan on the front, replayed and refined, and the next
        weight's warm start), one per weight, so their memory grows with the
        weights (tens; about 70 kB per point at 50 knots), never with starts.

    Returns
    -------
    ParetoFront or ShardReport
        The points with ``dominated`` marked; a shard run (``sweep.shard``,
        which shards the first point's multistart) returns its
        :class:`~youbot_opt.sweeps.resume.ShardReport` instead.

    Raises
    ------
    ParameterError
        On bad arguments, or if ``sweep.out`` holds a sweep with other parameters.
    ResultFileError
        If a saved point is corrupted or from a newer schema.
    """
    tic = time.perf_counter()
    solver = check_solver(solver)
    sweep = sweep.with_executor("process")
    executor, out, max_attempts = sweep.executor, sweep.directory, sweep.max_attempts
    values = _check_betas(betas)
    bound_scale = check_bound_scale(bound_scale)
    if isinstance(first_starts, bool) or not isinstance(first_starts, int) or first_starts < 0:
        raise ParameterError(
            f"first_starts must be an int >= 0, got {first_starts!r}", name="first_starts"
        )
    store: SweepStore | None = None
    if out is not None:
        params = {
            **sweep_params(solver),
            "betas": list(values),
            "bound_scale": bound_scale,
            "first_starts": first_starts,
            "seed": seed,
            "warm_start": warm_start,
            "cold_fallback": cold_fallback,
        }
        making = partial(_point_making, values, bound_scale)
        store = open_store(
            out, "pareto", params, result_codec(solver, making), clean=sweep.shard is None
        )
    points: list[ParetoPoint] = []
    first: MultistartResult | None = None
    previous: TrajOptResult | None = None
    resumed = 0
    fork = process_context().get_start_method() == "fork"
    handle = worker_solver(solver, keep=executor == "serial" or fork)
    with contextlib.ExitStack() as stack:
        pool: WorkerPool | None = None
        for k, beta in enumerate(values):
            key = point_key(k)
            again, attempts = (True, 0) if store is None else store.needs_work(key, max_attempts)
            if not again and store is not None and not _loadable(store, key):
                again, attempts = True, 0  # refused (warned): another sweep's, or torn
            if k == 0 and first_starts > 0:
                # Rerun on resume too: its own store in DIR/first_point loads every start.
                got = run_multistart(
                    solver,
                    first_starts,
                    beta=beta,
                    bound_scale=bound_scale,
                    seed=seed,
                    include_straight=True,
                    sweep=replace(
                        sweep,
                        out=None if out is None else out / "first_point",
                        progress=None,
                    ),
                )
                if isinstance(got, ShardReport):
                    return got
                first = got
            if not again:
                assert store is not None
                point = _load_point(store, key, beta)
                resumed += 1
            elif first is not None and k == 0:
                best = first.best
                if best is not None and best.result is not None:
                    spent = sum(s.solve_time for s in first.starts)
                    point = _point(beta, best.result, "multistart", spent)
                else:
                    point = _error_point(beta, "no start of the first point's multistart converged")
                if store is not None:
                    _write_point(store, key, point, attempts + 1)
            else:
                if pool is None and executor != "serial":
                    pool = stack.enter_context(
                        WorkerPool(1, initializer=hold_solver, initargs=(handle,))
                    )
                guess = previous if warm_start else None
                task = Task(
                    key=key,
                    fn=_solve_point_task,
                    args=(handle, beta, bound_scale, guess, cold_fallback),
                    attempts=attempts,
                )
                outcome = run_tasks(
                    [task],
                    executor="serial" if pool is None else pool,
                    max_attempts=max_attempts,
                    timeout=sweep.timeout,
                    on_outcome=None if store is None else partial(_save_attempt, store),
                )[key]
                point = outcome.value if outcome.ok else _error_point(beta, str(outcome.error))
            points.append(point)
            if point.success and point.result is not None:
                previous = point.result
            if sweep.progress is not None:
                sweep.progress(k + 1, len(values), point)
    mask = dominated_mask(
        [p.duration if p.success else np.nan for p in points],
        [p.work if p.success else np.nan for p in points],
        rtol=dominance_rtol,
    )
    marked = tuple(replace(p, dominated=bool(d)) for p, d in zip(points, mask, strict=True))
    return ParetoFront(
        points=marked,
        bound_scale=bound_scale,
        first=first,
        wall_time=time.perf_counter() - tic,
        resumed=resumed,
    )


def _point_making(
    betas: Sequence[float], bound_scale: float, key: str
) -> dict[str, float | int | None]:
    """Return what makes the point of ``key`` (``point_<k>``): its beta and bound scale."""
    rest = key.removeprefix("point_")
    if key == rest or not rest.isdigit() or int(rest) >= len(betas) or key != point_key(int(rest)):
        raise KeyError(key)
    return {"beta": betas[int(rest)], "bound_scale": bound_scale}


def _write_point(store: SweepStore, key: str, point: ParetoPoint, attempts: int) -> None:
    if point.result is None:
        store.write_failed(key, point.reason or "error", attempts=attempts)
    else:
        store.write_done(key, point.result, point.summary(), attempts=attempts)


def _save_attempt(store: SweepStore, o: TaskOutcome) -> None:
    """Save an attempt of a point as it ends: the point, or the failure's reason."""
    if o.ok:
        _write_point(store, o.key, o.value, o.attempts)
    else:
        store.write_failed(o.key, str(o.error), attempts=o.attempts)


def _loadable(store: SweepStore, key: str) -> bool:
    """Whether a finished point may be loaded: failed, or done and passing the store's checks."""
    record = store.record(key)
    return record is not None and (record.state != "done" or store.verify(key))


def _load_point(store: SweepStore, key: str, beta: float) -> ParetoPoint:
    record = store.record(key)
    assert record is not None
    if record.state == "failed":
        return _error_point(beta, record.reasons[-1] if record.reasons else "failed")
    result: TrajOptResult = store.load(key)
    return _point(beta, result, str(record.summary["start"]), record.number("solve_time_s"))
