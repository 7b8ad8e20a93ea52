"""Seeded multistart of IK-path solves, run in parallel, with the distinct local minima.

Start 0 is the study's zero vector (clipped into the limits). The others are
drawn in the parent process from ``numpy.random.default_rng(seed)``, so they
do not depend on the executor, in one of two ways:

* ``"uniform"``: every variable uniform in ``[max(l, -pi), min(u, pi)]``;
* ``"feasible"`` (default): each configuration is a random exact IK solution
  of its target within the limits (first ``n - 2`` angles uniform in their
  ranges, the last two in closed form with a random elbow; redrawn up to 50
  times, else the reachability witness), and unlimited joints are shifted by
  multiples of 2 pi so that the cyclic sum of squared steps is smallest
  for the drawn configurations.
  Uniform starts put independent 2 pi windings into the configurations and
  many of them end in minima that differ from a better one only by such
  windings; feasible starts sample the elbow branches and the redundancy
  instead. Starts are solved in chunks (one IPOPT build per chunk) on a
``concurrent.futures`` executor, a process pool by default. A start that
raises becomes a ``CRASHED`` result; a chunk lost to a broken executor makes
its starts ``CRASHED`` too; the run itself never dies of it.

Successful results are clustered into local minima: two results are the same
minimum when their ``E`` agree to ``e_tol`` (relative) and their
configurations agree to ``q_tol`` [rad] modulo the symmetry of ``E`` and the
constraints (adding ``2 pi k_i`` to joint ``i`` in every configuration).
"""

from __future__ import annotations

import logging
import math
import os
import time
from collections.abc import Callable, Sequence
from concurrent.futures import Executor, ProcessPoolExecutor, as_completed
from dataclasses import dataclass

import numpy as np

from youbot_opt._typing import Array
from youbot_opt.exceptions import ParameterError
from youbot_opt.ikpath._geometry import two_link_ik
from youbot_opt.ikpath.augmented_lagrangian import ALOptions, solve_augmented_lagrangian
from youbot_opt.ikpath.ipopt import IpoptIKSolver, IpoptOptions, check_degrees_of_freedom
from youbot_opt.ikpath.problem import CyclicIKProblem
from youbot_opt.ikpath.reachability import ReachVerdict, _theta_ranges
from youbot_opt.ikpath.result import IKPathResult, IKStatus, build_result
from youbot_opt.ikpath.solve import Method, check_method, check_targets

__all__ = [
    "LocalMinimum",
    "MultistartResult",
    "Progress",
    "cluster_minima",
    "configuration_distance",
    "make_starts",
    "run_multistart",
]

_log = logging.getLogger(__name__)

START_KINDS: tuple[str, ...] = ("feasible", "uniform")

Progress = Callable[[int, int, float], None]
"""``progress(done, total, best_objective)``, called in the parent after each chunk."""


@dataclass(frozen=True, slots=True, kw_only=True, eq=False)
class LocalMinimum:
    """One distinct local minimum found by multistart.

    Attributes
    ----------
    objective : float
        ``E`` of the representative in [rad^2].
    count : int
        Number of starts that converged to it.
    start_indices : tuple of int
        Which starts (0 = the zero vector).
    result : IKPathResult
        Representative (lowest ``E`` in the cluster).
    """

    objective: float
    count: int
    start_indices: tuple[int, ...]
    result: IKPathResult


@dataclass(frozen=True, slots=True, kw_only=True, eq=False)
class MultistartResult:
    """All starts of a multistart run and the minima they found.

    Attributes
    ----------
    problem : CyclicIKProblem
        The problem.
    method : str
        ``"al"`` or ``"ipopt"``.
    seed : int
        Seed of the random starts.
    results : tuple of IKPathResult
        One per start, in start order.
    minima : tuple of LocalMinimum
        Distinct minima of the successful starts, best (lowest E) first.
    verdicts : tuple of ReachVerdict
        Reachability verdicts of the targets (empty if not checked).
    wall_time : float
        Elapsed time in [s].
    n_workers : int
        Parallel workers used.
    """

    problem: CyclicIKProblem
    method: str
    seed: int
    results: tuple[IKPathResult, ...]
    minima: tuple[LocalMinimum, ...]
    verdicts: tuple[ReachVerdict, ...]
    wall_time: float
    n_workers: int

    @property
    def n_starts(self) -> int:
        """Number of starts."""
        return len(self.results)

    @property
    def n_success(self) -> int:
        """Number of successful starts."""
        return sum(r.success for r in self.results)

    @property
    def best(self) -> IKPathResult:
        """Best successful result, or the start with the smallest residual if none succeeded."""
        if self.minima:
            return self.minima[0].result
        return min(self.results, key=lambda r: (r.max_residual(), r.objective))

    @property
    def best_count(self) -> int:
        """How many starts found the best minimum."""
        return self.minima[0].count if self.minima else 0

    def status_counts(self) -> dict[str, int]:
        """Count the starts per :class:`IKStatus` value."""
        counts: dict[str, int] = {}
        for r in self.results:
            counts[r.status.value] = counts.get(r.status.value, 0) + 1
        return counts

    def starts_per_second(self) -> float:
        """Throughput in [1/s]."""
        return self.n_starts / self.wall_time if self.wall_time > 0 else math.inf

    def distinct_optima(self, e_tol: float = 1e-6, q_tol: float = 1e-3) -> tuple[LocalMinimum, ...]:
        """Re-cluster the successful results with other tolerances (see :func:`cluster_minima`)."""
        return cluster_minima(self.results, e_tol=e_tol, q_tol=q_tol)


def configuration_distance(qa: Array, qb: Array) -> float:
    """Largest joint difference in [rad] between two (s, n) paths modulo common 2 pi shifts.

    Joint ``i`` of every configuration may be shifted by the same ``2 pi k_i``
    (``E`` and the constraints are invariant under it); ``k_i`` is chosen to
    minimise the difference.
    """
    diff = np.asarray(qa, dtype=float) - np.asarray(qb, dtype=float)
    shift = 2.0 * np.pi * np.round(np.median(diff, axis=0) / (2.0 * np.pi))
    return float(np.max(np.abs(diff - shift)))


def cluster_minima(
    results: Sequence[IKPathResult], *, e_tol: float = 1e-6, q_tol: float = 1e-3
) -> tuple[LocalMinimum, ...]:
    """Group successful results into distinct local minima, best first.

    Parameters
    ----------
    results : sequence of IKPathResult
        Results in start order (index = start index).
    e_tol : float
        Relative tolerance on ``E`` (``|dE| <= e_tol * max(1, E)``).
    q_tol : float
        Tolerance in [rad] on :func:`configuration_distance`.

    Returns
    -------
    tuple of LocalMinimum
        Sorted by objective.
    """
    order = sorted(
        (i for i, r in enumerate(results) if r.success), key=lambda i: results[i].objective
    )
    groups: list[list[int]] = []
    for i in order:
        r = results[i]
        for g in groups:
            rep = results[g[0]]
            if abs(r.objective - rep.objective) <= e_tol * max(1.0, abs(rep.objective)) and (
                configuration_distance(r.configurations, rep.configurations) <= q_tol
            ):
                g.append(i)
                break
        else:
            groups.append([i])
    return tuple(
        LocalMinimum(
            objective=results[g[0]].objective,
            count=len(g),
            start_indices=tuple(sorted(g)),
            result=results[g[0]],
        )
        for g in groups
    )


def make_starts(
    problem: CyclicIKProblem,
    n_starts: int,
    seed: int,
    *,
    kind: str = "feasible",
    verdicts: Sequence[ReachVerdict] = (),
) -> Array:
    """Draw the starts: the zero vector (clipped), then seeded random ones; (n_starts, n s).

    Parameters
    ----------
    problem : CyclicIKProblem
        The problem.
    n_starts : int
        Number of starts (>= 1).
    seed : int
        Seed of ``numpy.random.default_rng``.
    kind : {"feasible", "uniform"}
        How random starts are drawn (see the module docstring).
    verdicts : sequence of ReachVerdict
        Reachability verdicts; their witnesses are the fallback of ``"feasible"``.

    Raises
    ------
    ParameterError
        If ``n_starts < 1`` or ``kind`` is unknown.
    """
    if int(n_starts) != n_starts or n_starts < 1:
        raise ParameterError(
            f"n_starts must be an integer >= 1, got {n_starts!r}", name="n_starts", value=n_starts
        )
    if kind not in START_KINDS:
        raise ParameterError(
            f"unknown start kind {kind!r}; choose one of {', '.join(START_KINDS)}",
            name="starts",
            value=kind,
        )
    rng = np.random.default_rng(seed)
    lo = np.maximum(problem.lower, -np.pi)
    hi = np.minimum(problem.upper, np.pi)
    lo, hi = np.minimum(lo, hi), np.maximum(lo, hi)
    starts = rng.uniform(lo, hi, size=(int(n_starts), problem.n_variables))
    if kind == "feasible":
        for k in range(1, int(n_starts)):
            starts[k] = _feasible_start(problem, rng, starts[k], verdicts)
    starts = np.clip(starts, problem.lower, problem.upper)
    starts[0] = problem.default_start()
    return starts


def _feasible_start(
    problem: CyclicIKProblem,
    rng: np.random.Generator,
    fallback: Array,
    verdicts: Sequence[ReachVerdict],
) -> Array:
    """One start made of random exact IK solutions, unwrapped across configurations."""
    chain = problem.chain
    n = chain.n
    ranges = _theta_ranges(chain, problem.use_limits) or [
        (-np.pi + o, 2 * np.pi) for o in chain.angle_offset
    ]
    q = fallback.reshape(problem.n_targets, n).copy()
    lengths = chain.lengths
    for j, p in enumerate(problem.targets):
        for _ in range(50):
            theta = np.array([r[0] + rng.uniform(0.0, r[1]) for r in ranges])
            if n == 1:  # unique solution; the witness below holds it
                continue
            phi = np.cumsum(theta[: n - 2])
            w = chain.base + np.sum(
                lengths[: n - 2, None] * np.column_stack([np.cos(phi), np.sin(phi)]), axis=0
            )
            psi = float(phi[-1]) if n > 2 else 0.0
            sol = two_link_ik(
                float(p[0]),
                float(p[1]),
                float(w[0]),
                float(w[1]),
                psi,
                float(lengths[n - 2]),
                float(lengths[n - 1]),
                ranges[n - 2],
                ranges[n - 1],
                elbow_first=1.0 if rng.uniform() < 0.5 else -1.0,
            )
            if sol is not None:
                theta[n - 2], theta[n - 1] = sol
                q[j] = theta - chain.angle_offset
                break
        else:
            if j < len(verdicts) and verdicts[j].witness is not None:
                q[j] = verdicts[j].witness
    if problem.use_limits:
        periodic = ~(np.isfinite(chain.q_lower) & np.isfinite(chain.q_upper))
    else:
        periodic = np.ones(n, dtype=bool)
    for i in np.flatnonzero(periodic):
        q[:, i] = _best_windings(q[:, i])
    return q.ravel()


def _best_windings(col: Array) -> Array:
    """Shift entries by multiples of 2 pi to minimise the cyclic sum of squared steps.

    The steps ``d_j`` (closing step included) are taken in ``(-pi, pi]``; they
    must sum to zero, so ``K = sum(d) / 2 pi`` of them move by ``-2 pi sign(K)``:
    the largest ones (smallest for ``K < 0``), which is optimal because the cost
    is convex in each step.
    """
    steps = np.roll(col, -1) - col
    steps = (steps + np.pi) % (2 * np.pi) - np.pi
    turns = int(round(float(np.sum(steps)) / (2 * np.pi)))
    order = np.argsort(steps)
    if turns > 0:
        steps[order[-turns:]] -= 2 * np.pi
    elif turns < 0:
        steps[order[:-turns]] += 2 * np.pi
    return col[0] + np.r_[0.0, np.cumsum(steps[:-1])]


def _constraint_tol(method: str, options: ALOptions | IpoptOptions | None) -> float:
    """Return the largest accepted ``|c_i|`` in [m] of ``method`` with ``options``."""
    if method == "al":
        return (options if isinstance(options, ALOptions) else ALOptions()).constraint_tol
    return (options if isinstance(options, IpoptOptions) else IpoptOptions()).constr_viol_tol


def _crashed(
    problem: CyclicIKProblem,
    method: str,
    options: ALOptions | IpoptOptions | None,
    x0: Array,
    message: str,
) -> IKPathResult:
    return build_result(
        problem,
        method=method,
        status=IKStatus.CRASHED,
        x=x0,
        multipliers=np.zeros(2 * problem.n_targets),
        iterations=0,
        inner_iterations=0,
        wall_time=0.0,
        message=message,
        start=x0,
        constraint_tol=_constraint_tol(method, options),
    )


def _solve_chunk(
    problem: CyclicIKProblem,
    method: str,
    options: ALOptions | IpoptOptions | None,
    starts: Array,
) -> list[IKPathResult]:
    """Solve several starts (worker side); exceptions become CRASHED results."""
    out: list[IKPathResult] = []
    solver: IpoptIKSolver | None = None
    for x0 in starts:
        try:
            if method == "al":
                out.append(solve_augmented_lagrangian(problem, x0, options))  # type: ignore[arg-type]
            else:
                if solver is None:
                    solver = IpoptIKSolver(problem, options)  # type: ignore[arg-type]
                out.append(solver.solve(problem, x0))
        except Exception as exc:  # noqa: BLE001 - one bad start must not end the run
            out.append(_crashed(problem, method, options, x0, f"{type(exc).__name__}: {exc}"))
    return out


def run_multistart(
    problem: CyclicIKProblem,
    *,
    method: Method = "al",
    n_starts: int = 100,
    seed: int = 0,
    starts: str = "feasible",
    options: ALOptions | IpoptOptions | None = None,
    executor: Executor | None = None,
    max_workers: int | None = None,
    chunk_size: int | None = None,
    progress: Progress | None = None,
    check_reachability: bool = True,
    e_tol: float = 1e-6,
    q_tol: float = 1e-3,
) -> MultistartResult:
    """Solve from ``n_starts`` seeded starts in parallel and report the distinct minima.

    Parameters
    ----------
    problem : CyclicIKProblem
        The problem.
    method : {"al", "ipopt"}
        Solver.
    n_starts : int
        Number of starts (start 0 is the zero vector).
    seed : int
        Seed of the random starts.
    starts : {"feasible", "uniform"}
        How random starts are drawn (see the module docstring).
    options : ALOptions or IpoptOptions, optional
        Settings of the method.
    executor : concurrent.futures.Executor, optional
        Where to run the chunks; not shut down here. By default a
        ``ProcessPoolExecutor`` with ``max_workers`` processes is created and
        shut down (``max_workers = 1`` runs in this process without a pool).
    max_workers : int, optional
        Workers of the default pool (default: ``os.cpu_count()``).
    chunk_size : int, optional
        Starts per task (default: about four tasks per worker, at most 25).
    progress : callable, optional
        ``progress(done, total, best_objective)`` after each chunk.
    check_reachability : bool
        Decide every target's reachability first (raises ``UnreachableTarget``).
    e_tol, q_tol : float
        Clustering tolerances (see :func:`cluster_minima`).

    Returns
    -------
    MultistartResult
        All results in start order and the distinct minima, best first.

    Raises
    ------
    ParameterError
        For an unknown method, foreign options, ``max_workers < 1``, or
        ``method="ipopt"`` on a chain with fewer than 2 free joints.
    UnreachableTarget
        If ``check_reachability`` and a target is unreachable.
    """
    check_method(method, options)
    if method == "ipopt":
        check_degrees_of_freedom(problem)
    verdicts = check_targets(problem) if check_reachability else ()
    x0s = make_starts(problem, n_starts, seed, kind=starts, verdicts=verdicts)
    workers = int(max_workers or os.cpu_count() or 1)
    if workers < 1:
        raise ParameterError(
            f"max_workers must be >= 1, got {max_workers!r}", name="max_workers", value=max_workers
        )
    size = chunk_size or max(1, min(25, math.ceil(len(x0s) / (4 * workers))))
    chunks = [(i, x0s[i : i + size]) for i in range(0, len(x0s), size)]
    results: list[IKPathResult | None] = [None] * len(x0s)
    best = math.inf
    done = 0
    t0 = time.perf_counter()

    def collect(first: int, chunk_results: list[IKPathResult]) -> None:
        nonlocal best, done
        for k, r in enumerate(chunk_results):
            results[first + k] = r
            if r.success:
                best = min(best, r.objective)
        done += len(chunk_results)
        if progress is not None:
            progress(done, len(x0s), best)

    if executor is None and workers == 1:
        for first, chunk in chunks:
            collect(first, _solve_chunk(problem, method, options, chunk))
        n_used = 1
    else:
        own = executor is None
        pool = ProcessPoolExecutor(max_workers=workers) if executor is None else executor
        n_used = workers if own else int(getattr(executor, "_max_workers", 0) or 0)
        try:
            futures = {
                pool.submit(_solve_chunk, problem, method, options, chunk): (first, chunk)
                for first, chunk in chunks
            }
            for fut in as_completed(futures):
                first, chunk = futures[fut]
                try:
                    chunk_results = fut.result()
                except Exception as exc:  # noqa: BLE001 - a lost chunk must not end the run
                    _log.warning("multistart chunk at start %d failed: %s", first, exc)
                    msg = f"chunk failed: {type(exc).__name__}: {exc}"
                    chunk_results = [_crashed(problem, method, options, x0, msg) for x0 in chunk]
                collect(first, chunk_results)
        finally:
            if own:
                pool.shutdown(wait=True, cancel_futures=True)
    final = tuple(r for r in results if r is not None)
    return MultistartResult(
        problem=problem,
        method=method,
        seed=int(seed),
        results=final,
        minima=cluster_minima(final, e_tol=e_tol, q_tol=q_tol),
        verdicts=verdicts,
        wall_time=time.perf_counter() - t0,
        n_workers=n_used,
    )
