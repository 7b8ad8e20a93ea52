"""Multistart from the study's vertex-LP starts, and the distinct optima it finds.

Owns the study-1 second-optimum search: :func:`vertex_multistart` solves one
problem from ``K`` seeded :func:`~youbot_opt.reproduction.study_guess.vertex_spline_guess`
starts (the literal reading of the study's random starts) with a built solver,
run as one :class:`~youbot_opt.sweeps.options.SweepOptions` says (a start that
raises is a failed start, the run goes on); :func:`cluster_optima` groups the
converged solves into distinct local optima by objective and trajectory
distance (:func:`youbot_opt.sweeps.optima.cluster_optima`, this search's
tolerances); :func:`search_record` summarises a run for the reproduction's JSON.

    starts = vertex_multistart(solver, 20, beta=0.5, sweep=SweepOptions(max_attempts=1))
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import NamedTuple

from youbot_opt._typing import JSONDict
from youbot_opt.exceptions import ParameterError
from youbot_opt.reproduction.records import ArmSolvers, Variant, record
from youbot_opt.sweeps.optima import cluster_optima as cluster_items
from youbot_opt.sweeps.options import SweepOptions
from youbot_opt.sweeps.pool import Task, TaskOutcome, process_context, run_tasks
from youbot_opt.sweeps.worker_solver import WorkerSolver, hold_solver
from youbot_opt.trajopt.multistart import start_seeds, trajectory_distance
from youbot_opt.trajopt.result import TrajOptResult
from youbot_opt.trajopt.solver import TrajOptSolver
from youbot_opt.trajopt.sweep import check_solver, worker_solver

__all__ = [
    "VertexStart",
    "cluster_optima",
    "converged_results",
    "search_record",
    "vertex_multistart",
]


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


def _solve(handle: WorkerSolver[TrajOptSolver], seed: int, beta: float) -> TrajOptResult:
    """Worker task: one vertex-LP start, solved with this worker's solver."""
    from youbot_opt.reproduction.study_guess import vertex_spline_guess

    solver = handle.get()
    guess = vertex_spline_guess(solver.problem, seed)
    return solver.solve(beta=beta, guess=guess)


def vertex_multistart(
    solver: TrajOptSolver,
    n_starts: int,
    *,
    beta: float,
    seed: int = 0,
    sweep: SweepOptions = SweepOptions(max_attempts=1),  # noqa: B008 - frozen, so safe
) -> list[VertexStart]:
    """Solve ``solver``'s problem from ``n_starts`` seeded vertex-LP starts.

    Parameters
    ----------
    solver : TrajOptSolver
        The built solver (e.g. with the study's transcription).
    n_starts : int
        Number of starts (>= 1).
    beta : float
        Time weight in [0, 1].
    seed : int
        Base seed; start ``i`` uses ``youbot_opt.trajopt.multistart.start_seeds(seed, n)[i]``.
    sweep : SweepOptions
        ``executor``: ``"process"`` (default; each worker holds the solver,
        inherited under fork) or ``"serial"``; ``workers`` (default: the CPUs
        available); ``max_attempts`` (default 1: a failed start is not
        retried); ``progress`` ``(done, total, last_start)`` as each start
        finishes. ``out`` and ``timeout`` are not used.

    Returns
    -------
    list of VertexStart
        In seed order.

    Raises
    ------
    ParameterError
        On an executor other than ``"process"`` or ``"serial"``.
    """
    solver = check_solver(solver)
    sweep = sweep.with_executor("process")
    executor = sweep.executor
    if executor not in ("process", "serial"):
        raise ParameterError(
            f"executor must be 'process' or 'serial', got {executor!r}", name="executor"
        )
    fork = executor == "process" and process_context().get_start_method() == "fork"
    handle = worker_solver(solver, keep=executor == "serial" or fork)
    seeds = start_seeds(seed, n_starts)
    tasks = [
        Task(key=f"start_{i:04d}", fn=_solve, args=(handle, s, beta)) for i, s in enumerate(seeds)
    ]
    by_key = {t.key: s for t, s in zip(tasks, seeds, strict=True)}
    done = [0]

    def tick(outcome: TaskOutcome) -> None:
        if outcome.final:
            done[0] += 1
            if sweep.progress is not None:
                start = VertexStart(
                    seed=by_key[outcome.key], result=outcome.value, error=outcome.error
                )
                sweep.progress(done[0], len(tasks), start)

    outcomes = run_tasks(
        tasks,
        executor=executor,
        workers=sweep.workers,
        initializer=hold_solver if executor == "process" else None,
        initargs=(handle,) if executor == "process" else (),
        max_attempts=sweep.max_attempts,
        on_outcome=tick,
    )
    starts = []
    for task, s in zip(tasks, seeds, strict=True):
        out = outcomes[task.key]
        starts.append(VertexStart(seed=s, result=out.value, error=out.error))
    return starts


def cluster_optima(
    results: Sequence[TrajOptResult],
    objective: Callable[[TrajOptResult], float],
    obj_tol: float = 1e-6,
    dist_tol: float = 1e-2,
) -> list[list[TrajOptResult]]:
    """Group converged results into distinct local optima, lowest objective first.

    Parameters
    ----------
    results : sequence of TrajOptResult
        Solves (failed ones are ignored).
    objective : callable
        The objective to compare (e.g. the study's, with ``T = n dt``).
    obj_tol : float
        Relative objective tolerance (dimensionless, finite, > 0):
        ``|f - f_c| <= obj_tol max(1, |f_c|)``.
    dist_tol : float
        Largest :func:`youbot_opt.trajopt.multistart.trajectory_distance` in [rad] to a
        cluster's representative (finite, > 0).

    Returns
    -------
    list of list of TrajOptResult
        Clusters, each with its lowest-objective member first.
    """
    return cluster_items(
        (r for r in results if r.success),
        objective=objective,
        distance=_result_distance,
        obj_tol=obj_tol,
        dist_tol=dist_tol,
    )


def _result_distance(a: TrajOptResult, b: TrajOptResult) -> float:
    """:func:`youbot_opt.trajopt.multistart.trajectory_distance` of two converged results [rad]."""
    assert a.trajectory is not None and b.trajectory is not None
    return trajectory_distance(a.trajectory, b.trajectory)


def converged_results(starts: Sequence[VertexStart]) -> list[TrajOptResult]:
    """Return the results of the starts that produced one (converged or not)."""
    return [s.result for s in starts if s.result is not None]


def search_record(variant: Variant, starts: list[VertexStart], solvers: ArmSolvers) -> JSONDict:
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
