"""Multistart from the study's vertex-LP starts, and the distinct optima it finds.

:func:`vertex_multistart` solves one problem from ``K`` seeded
:func:`~youbot_opt.reproduction.study_guess.vertex_spline_guess` starts (the
literal reading of the study's random starts) on a process pool
(:func:`youbot_opt.sweeps.tasks.run_tasks`; a start that raises is a failed start,
the run goes on), and :func:`cluster_optima` groups the converged solves into
distinct local optima by objective and trajectory distance, as
:meth:`youbot_opt.trajopt.multistart.MultistartResult.distinct_optima` does for the
main API's starts; :func:`search_record` summarises a run for the
reproduction's JSON (statuses, each optimum with its seeds and certificates).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any, Literal, NamedTuple

from youbot_opt.exceptions import ParameterError
from youbot_opt.trajopt.multistart import start_seeds, trajectory_distance
from youbot_opt.nlp.ipopt import IpoptOptions
from youbot_opt.sweeps.tasks import Task, run_tasks
from youbot_opt.trajopt.problem import TrajOptProblem
from youbot_opt.reproduction.records import ArmSolvers, Variant, record
from youbot_opt.trajopt.result import TrajOptResult
from youbot_opt.trajopt.solver import TrajOptSolver
from youbot_opt.trajopt.transcription import Transcription

__all__ = [
    "VertexStart",
    "cluster_optima",
    "converged_results",
    "search_record",
    "vertex_multistart",
]

_WORKER: dict[str, TrajOptSolver] = {}
"""The solver of this worker process (built once by :func:`_init_worker`)."""


class VertexStart(NamedTuple):
    """One start: its seed and result (``None`` with the reason if it raised).

    Attributes
    ----------
    seed : int
        Seed of the vertex-LP guess.
    result : TrajOptResult or None
        The solve.
    error : str or None
        Why the start failed to produce a result.
    """

    seed: int
    result: TrajOptResult | None
    error: str | None = None


def _init_worker(problem: TrajOptProblem, method: Transcription, options: IpoptOptions) -> None:
    _WORKER["solver"] = TrajOptSolver(problem, method, options)


def _solve(seed: int, beta: float) -> TrajOptResult:
    from youbot_opt.reproduction.study_guess import vertex_spline_guess

    solver = _WORKER["solver"]
    guess = vertex_spline_guess(solver.problem, seed)
    return solver.solve(beta=beta, guess=guess)


def vertex_multistart(
    problem: TrajOptProblem,
    method: Transcription,
    options: IpoptOptions,
    n_starts: int,
    *,
    beta: float,
    seed: int = 0,
    executor: Literal["process", "serial"] = "process",
    workers: int | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> list[VertexStart]:
    """Solve ``problem`` from ``n_starts`` seeded vertex-LP starts.

    Parameters
    ----------
    problem : TrajOptProblem
        The problem.
    method : Transcription
        Its transcription (e.g. the study's).
    options : IpoptOptions
        Solver options.
    n_starts : int
        Number of starts (>= 1).
    beta : float
        Time weight in [0, 1].
    seed : int
        Base seed; start ``i`` uses ``youbot_opt.trajopt.multistart.start_seeds(seed, n)[i]``.
    executor : {"process", "serial"}
        Where starts run: a process pool (each worker builds the solver once)
        or this process.
    workers : int, optional
        Parallel starts (default: the CPUs available).
    progress : callable ``(done, total)``, optional
        Called as each start finishes.

    Returns
    -------
    list of VertexStart
        In seed order.

    Raises
    ------
    ParameterError
        On an unknown ``executor``.
    """
    if executor not in ("process", "serial"):
        raise ParameterError(
            f"executor must be 'process' or 'serial', got {executor!r}", name="executor"
        )
    seeds = start_seeds(seed, n_starts)
    tasks = [Task(key=f"start_{i:04d}", fn=_solve, args=(s, beta)) for i, s in enumerate(seeds)]
    done = [0]

    def tick(outcome: Any) -> None:
        if outcome.final:
            done[0] += 1
            if progress is not None:
                progress(done[0], len(tasks))

    if executor == "serial":
        _init_worker(problem, method, options)
    try:
        outcomes = run_tasks(
            tasks, executor=executor, workers=workers, initializer=_init_worker,
            initargs=(problem, method, options), max_attempts=1, on_outcome=tick,
        )  # fmt: skip
    finally:
        _WORKER.clear()
    starts = []
    for task, s in zip(tasks, seeds, strict=True):
        out = outcomes[task.key]
        starts.append(VertexStart(seed=s, result=out.value, error=out.error))
    return starts


def cluster_optima(
    results: Sequence[TrajOptResult],
    objective: Callable[[TrajOptResult], float],
    obj_tol: float = 1e-6,
    traj_tol: float = 1e-2,
) -> list[list[TrajOptResult]]:
    """Group converged results into distinct local optima, lowest objective first.

    Parameters
    ----------
    results : sequence of TrajOptResult
        Solves (failed ones are ignored).
    objective : callable
        The objective to compare (e.g. the study's, with ``T = n dt``).
    obj_tol : float
        Relative objective tolerance: ``|f - f_c| <= obj_tol max(1, |f_c|)``.
    traj_tol : float
        Largest :func:`youbot_opt.trajopt.multistart.trajectory_distance` in [rad] within a cluster.

    Returns
    -------
    list of list of TrajOptResult
        Clusters, each with its lowest-objective member first.
    """
    clusters: list[list[TrajOptResult]] = []
    for r in sorted((r for r in results if r.success), key=objective):
        for members in clusters:
            rep = members[0]
            f_rep = objective(rep)
            if abs(objective(r) - f_rep) > obj_tol * max(1.0, abs(f_rep)):
                continue
            assert r.trajectory is not None and rep.trajectory is not None
            if trajectory_distance(r.trajectory, rep.trajectory) <= traj_tol:
                members.append(r)
                break
        else:
            clusters.append([r])
    return clusters


def converged_results(starts: Sequence[VertexStart]) -> list[TrajOptResult]:
    """Return the results of the starts that produced one (converged or not)."""
    return [s.result for s in starts if s.result is not None]


def search_record(
    variant: Variant, starts: list[VertexStart], solvers: ArmSolvers
) -> dict[str, Any]:
    """JSON-ready summary of a vertex-LP multistart: statuses and each optimum's record.

    Parameters
    ----------
    variant : Variant
        What was solved.
    starts : list of VertexStart
        The starts (:func:`~youbot_opt.reproduction.search.vertex_multistart`).
    solvers : ArmSolvers
        Source of the arm models for the certificates.

    Returns
    -------
    dict
        ``n_starts``, ``success_rate``, ``statuses``, ``errors`` (start failures
        with their reasons), and ``optima``: per optimum its ``count``,
        ``fraction``, the guess ``seeds`` of its members (best first) and the
        :func:`record` of its best member (certificates included), lowest
        objective first.
    """
    results = converged_results(starts)
    statuses: dict[str, int] = {}
    for s in starts:
        key = s.result.status.value if s.result is not None else "error"
        statuses[key] = statuses.get(key, 0) + 1
    n = len(starts)
    seed_of = {id(s.result): s.seed for s in starts if s.result is not None}
    optima = [
        {
            "count": len(m),
            "fraction": len(m) / n,
            "seeds": [seed_of[id(r)] for r in m],
            **record(variant, m[0], solvers),
        }
        for m in cluster_optima(results, variant.objective)
    ]
    return {
        "n_starts": n,
        "success_rate": sum(r.success for r in results) / n if n else 0.0,
        "statuses": statuses,
        "errors": [f"seed {s.seed}: {s.error}" for s in starts if s.result is None],
        "optima": optima,
    }
