"""Solving the spatial cyclic IK path: one solve (AL or IPOPT) and the multistart.

:func:`solve_spatial` runs the study's augmented Lagrangian (projected BFGS
inner solver, :func:`~youbot_opt.ikpath.augmented_lagrangian.run_augmented_lagrangian`)
or CasADi + IPOPT (:mod:`.spatial_ipopt`) on a
:class:`~youbot_opt.ikpath.spatial.SpatialIKProblem`; a failed solve keeps the
best iterate and names the blocking target. :func:`run_spatial_multistart`
solves from the greedy, coherent and random starts of
:func:`~youbot_opt.ikpath.spatial.make_spatial_starts` (optionally on a
process pool) and clusters the distinct minima.
"""

from __future__ import annotations

import math
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from youbot_opt._typing import Array
from youbot_opt.exceptions import ParameterError
from youbot_opt.ikpath.augmented_lagrangian import ALOptions, run_augmented_lagrangian
from youbot_opt.ikpath.spatial import (
    SPATIAL_AL_OPTIONS,
    SpatialIKProblem,
    SpatialIKResult,
    build_spatial_result,
    make_spatial_starts,
    require_spatial_reachable,
)
from youbot_opt.ikpath.spatial_ipopt import solve_spatial_ipopt
from youbot_opt.sweeps.cluster import cluster_optima

__all__ = ["SpatialMultistart", "run_spatial_multistart", "solve_spatial"]


# -- solving ----------------------------------------------------------------------------------
def solve_spatial(
    problem: SpatialIKProblem,
    *,
    method: str = "al",
    x0: ArrayLike | None = None,
    options: ALOptions | None = None,
    check_reachability: bool = False,
) -> SpatialIKResult:
    """Solve once from ``x0`` (default zero, clipped) by ``"al"`` or ``"ipopt"``.

    Raises
    ------
    UnreachableTarget
        If ``check_reachability`` and a target is certified unreachable.
    ParameterError
        Unknown method or bad start.
    """
    if check_reachability:
        require_spatial_reachable(problem)
    if method == "ipopt":
        return solve_spatial_ipopt(problem, x0)
    if method != "al":
        raise ParameterError(
            f"unknown method {method!r}; choose al or ipopt", name="method", value=method
        )
    opts = SPATIAL_AL_OPTIONS if options is None else options
    start = problem.check_start(x0)
    run = run_augmented_lagrangian(problem, start, opts)
    return build_spatial_result(problem, **run.result_fields(start))


@dataclass(frozen=True, slots=True, kw_only=True, eq=False)
class SpatialMultistart:
    """Results of a spatial multistart.

    Attributes
    ----------
    results : tuple of SpatialIKResult
        In start order.
    minima : tuple of tuple of int
        Start indices of each distinct minimum (successful results), best first;
        the first index of each is its lowest-E member.
    wall_time : float
        In [s].
    workers : int
        Processes used.
    """

    results: tuple[SpatialIKResult, ...]
    minima: tuple[tuple[int, ...], ...]
    wall_time: float
    workers: int

    @property
    def best(self) -> SpatialIKResult:
        """The best successful result, else the result closest to meeting the targets."""
        if self.minima:
            return self.results[self.minima[0][0]]
        return min(
            self.results,
            key=lambda r: float(np.max(r.position_errors) + np.max(r.orientation_errors)),
        )

    @property
    def starts_per_second(self) -> float:
        """Throughput in [1/s]."""
        return len(self.results) / self.wall_time if self.wall_time > 0 else math.inf


def _solve_one(args: tuple[SpatialIKProblem, str, Array]) -> SpatialIKResult:
    problem, method, x0 = args
    return solve_spatial(problem, method=method, x0=x0)


def run_spatial_multistart(
    problem: SpatialIKProblem,
    *,
    method: str = "al",
    n_starts: int = 16,
    seed: int = 0,
    workers: int = 1,
    e_tol: float = 1e-6,
    q_tol: float = 1e-3,
) -> SpatialMultistart:
    """Solve from :func:`make_spatial_starts` and cluster the distinct minima.

    Two successes are one minimum when ``E`` agrees to ``e_tol`` (relative) and
    the angles to ``q_tol`` [rad] (continuous joints modulo a common 2 pi shift).
    ``workers > 1`` runs the starts in a process pool.
    """
    t0 = time.perf_counter()
    x0s = make_spatial_starts(problem, n_starts, seed)
    jobs = [(problem, method, x0) for x0 in x0s]
    if workers > 1:
        with ProcessPoolExecutor(max_workers=int(workers)) as pool:
            results = tuple(pool.map(_solve_one, jobs))
    else:
        results = tuple(_solve_one(job) for job in jobs)

    def distance(a: int, b: int) -> float:
        diff = results[a].configurations - results[b].configurations
        shift = np.where(
            problem.continuous, 2 * np.pi * np.round(np.median(diff, axis=0) / (2 * np.pi)), 0.0
        )
        return float(np.max(np.abs(diff - shift)))

    groups = cluster_optima(
        (i for i, r in enumerate(results) if r.success),
        objective=lambda i: results[i].objective,
        distance=distance,
        obj_tol=e_tol,
        dist_tol=q_tol,
    )
    return SpatialMultistart(
        results=results,
        minima=tuple(tuple(g) for g in groups),
        wall_time=time.perf_counter() - t0,
        workers=int(workers),
    )
