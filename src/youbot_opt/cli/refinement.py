"""The mesh refinement of a command's plans: the budget of the flags, progress, table, figures.

:func:`refine_result` refines one solved plan (``--no-refine``: nothing) with
the :class:`~youbot_opt.trajopt.refine.RefinementBudget` of the flags,
printing each round on stderr; :func:`refine_many` does it for a study's
labelled plans, each stored in the run folder's ``refined/`` as it is made
(:func:`youbot_opt.trajopt.sweep_store.open_refined`) and reused by a rerun;
:func:`refinement_table` and :func:`refinement_figures` show what the rounds did.

>>> refined = refine_result(solver, result, args)  # doctest: +SKIP
"""

from __future__ import annotations

import argparse
import sys
import warnings
from collections.abc import Callable
from pathlib import Path

from youbot_opt._typing import JSONDict
from youbot_opt.cli.advice import next_step
from youbot_opt.cli.flags import scheduler_address
from youbot_opt.cli.output import draw_figure
from youbot_opt.exceptions import YoubotOptWarning
from youbot_opt.sweeps.pool import Task, TaskOutcome, default_workers, process_context, run_tasks
from youbot_opt.sweeps.store import SweepStore
from youbot_opt.sweeps.worker_solver import WorkerSolver, hold_solver
from youbot_opt.trajopt.refine import Refined, Refinement, RefinementBudget, RefinementRound, refine
from youbot_opt.trajopt.result import TrajOptResult
from youbot_opt.trajopt.solver import TrajOptSolver
from youbot_opt.trajopt.sweep import worker_solver
from youbot_opt.trajopt.sweep_store import open_refined, refined_key

__all__ = [
    "PER_PLAN_FIGURES",
    "REFINED",
    "certificate_processes",
    "refine_many",
    "refine_result",
    "refinement_budget",
    "refinement_figures",
    "refinement_table",
    "scheme_change",
    "round_printer",
]


REFINED = "refined"
"""The run folder's store of refined plans (:func:`refine_many`; a sweep store of kind
``"refined"``, its payloads result files with their refinement record)."""


def certificate_processes() -> int:
    """Return how many processes one plan's certificate uses: 2 on two cores or more, else 1.

    A single plan's command has the machine to itself while it certifies
    (:func:`~youbot_opt.trajopt.certify.certify`'s ``processes``); the plans of
    a study certified in workers keep 1 each.
    """
    return min(2, default_workers())


def refinement_budget(args: argparse.Namespace) -> RefinementBudget:
    """Return the :class:`~youbot_opt.trajopt.refine.RefinementBudget` of the options."""
    return RefinementBudget(
        tolerance=args.error_tol,
        max_rounds=args.max_rounds,
        max_knots=args.max_knots,
        time_limit=args.refine_time,
        fallback=args.refine_fallback,
    )


def refine_result(
    solver: TrajOptSolver,
    result: TrajOptResult | None,
    args: argparse.Namespace,
    quiet: bool = False,
) -> Refined | None:
    """Refine ``result`` (solved on ``solver``'s grid) unless ``--no-refine``; progress: stderr.

    Returns
    -------
    Refined or None
        :func:`~youbot_opt.trajopt.refine.refine`'s result and record; None with
        ``--no-refine`` or when there is no trajectory to refine.
    """
    if not getattr(args, "refine", False) or result is None or result.trajectory is None:
        return None
    return refine(
        solver, first=result, budget=refinement_budget(args), progress=round_printer(quiet),
        processes=certificate_processes(),
    )  # fmt: skip


def round_printer(quiet: bool = False) -> Callable[[RefinementRound], None]:
    """Return the ``progress`` of a refinement: one line per round on stderr (none if ``quiet``)."""
    methods: list[str] = []

    def progress(r: RefinementRound) -> None:
        methods.append(r.method)
        if not quiet:
            verdict = {True: "passes", False: "fails", None: "not run"}[r.certificate_passed]
            scheme = f", {r.method}" if r.method != methods[0] else ""  # the fallback's
            print(
                f"refine: round {r.index}: {r.n_knots} knots, f = {r.objective:.6g}, "
                f"T = {r.duration:.4g} s, max error {r.max_error:.3g}, certificate {verdict}"
                f"{scheme}",
                file=sys.stderr,
                flush=True,
            )

    return progress


def refine_many(
    solver: TrajOptSolver,
    items: list[tuple[str, str, TrajOptResult]],
    args: argparse.Namespace,
    quiet: bool = False,
    folder: Path | None = None,
) -> tuple[list[tuple[TrajOptResult, Refinement | None]], list[str], list[JSONDict]]:
    """Refine the labelled results of a study (``--no-refine``: nothing, empty outputs).

    Parameters
    ----------
    solver : TrajOptSolver
        The study's solver (the results' grid).
    items : list of (str, str, TrajOptResult)
        Each result's label, its key in the study's sweep, and the result.
    args : argparse.Namespace
        The command's flags (``--refine``, the budget).
    quiet : bool
        No progress lines on stderr (a refused stored plan is still reported).
    folder : Path, optional
        The run folder: each refined plan is stored in ``folder/refined`` as it
        is made (keyed by the item's key, its grid plan and the budget), and a
        stored one is reused after the loader's check, the certificate at the
        budget's tolerances and
        :func:`~youbot_opt.trajopt.sweep_store.check_refined`; one that fails
        them is refined again (said on stderr). None: nothing stored. With
        worker processes (``--workers`` not 0) the plans are refined in a pool.

    Returns
    -------
    refined : list of (TrajOptResult, Refinement or None)
        The refined results and their records, in order (the record is None
        for a result without a trajectory, left as it was).
    lines : list of str
        One table line per result: label, knots, ``f``, ``T``, certified or why not.
    summaries : list of dict
        Per result: its label, ``"stored"`` (reused from the run folder) and
        :meth:`Refinement.summary`.
    """
    if not getattr(args, "refine", False) or not items:
        return [], [], []
    budget = refinement_budget(args)
    keys = [refined_key(key, result, budget) for _, key, result in items]
    grids = {k: x for k, (_, _, x) in zip(keys, items, strict=True) if x.trajectory is not None}
    store = (
        None
        if folder is None or not grids
        else open_refined(folder / REFINED, solver, grids, budget)
    )
    refined: list[tuple[TrajOptResult, Refinement | None]] = []
    summaries: list[JSONDict] = []
    lines = [
        f"refined ({budget.describe()}):",
        f"  {'':<14} {'knots':>6} {'f':>12} {'T [s]':>9}  certified",
    ]
    try:
        keyed = list(zip(keys, items, strict=True))
        found = {k: None if store is None else _stored(store, k, x[0]) for k, x in keyed}
        todo = {k: (x[0], x[2]) for k, x in keyed if found[k] is None and k in grids}
        made = _refine_in_workers(solver, todo, args, budget, store, quiet)
        for (label, _, result), key in zip(items, keys, strict=True):
            stored = found[key] is not None
            done = found[key] or made.get(key)
            if not quiet and key not in made:
                print(
                    f"refine: {label}{' (stored)' if stored else ''}", file=sys.stderr, flush=True
                )
            if done is None:
                done = refine_result(solver, result, args, quiet=True)
                if done is not None and store is not None:  # kept at once: a kill loses one
                    store.write_done(key, done, _journal_summary(label, done))
            r, record = (result, None) if done is None else done
            refined.append((r, record))
            verdict = (
                "no trajectory"
                if record is None
                else "yes"
                if record.certified
                else "no: " + record.reason
            )
            lines.append(
                f"  {label:<14} {r.problem.n_knots:>6} {r.objective:>12.6f} {r.duration:>9.4f}  "
                f"{verdict}"
            )
            summary = record.summary() if record else {}
            summaries.append({"label": label, "stored": stored, **summary})
    finally:
        if store is not None:
            store.close()
    return refined, lines, summaries


def _refine_task(
    handle: WorkerSolver[TrajOptSolver], first: TrajOptResult, budget: RefinementBudget
) -> Refined:
    """Worker task: refine one plan on the worker's solver."""
    return refine(handle.get(), first=first, budget=budget)


def _refine_in_workers(
    solver: TrajOptSolver,
    todo: dict[str, tuple[str, TrajOptResult]],
    args: argparse.Namespace,
    budget: RefinementBudget,
    store: SweepStore[Refined] | None,
    quiet: bool,
) -> dict[str, Refined]:
    """Refine the plans ``todo`` (by store key: label, grid plan) in local worker processes.

    Only when the sweep ran in local worker processes (``--workers`` not 0, no
    Dask scheduler) and more than one plan is to be refined; each plan is
    stored as it comes back. A plan whose worker failed is left out (refined
    in this process afterwards, as without workers).
    """
    if len(todo) < 2 or getattr(args, "workers", 0) == 0 or scheduler_address(args):
        return {}
    handle = worker_solver(solver, keep=process_context().get_start_method() == "fork")
    made: dict[str, Refined] = {}

    def keep(outcome: TaskOutcome) -> None:
        if outcome.ok:
            label, refined = todo[outcome.key][0], outcome.value
            made[outcome.key] = refined
            if store is not None:  # kept at once: a kill loses only the plans in progress
                store.write_done(outcome.key, refined, _journal_summary(label, refined))
            if not quiet:
                print(f"refine: {label}", file=sys.stderr, flush=True)

    run_tasks(
        [Task(key=k, fn=_refine_task, args=(handle, x, budget)) for k, (_, x) in todo.items()],
        executor="process",
        workers=min(args.workers or default_workers(), len(todo)),
        initializer=hold_solver,
        initargs=(handle,),
        max_attempts=1,
        on_outcome=keep,
        keep_values=False,
    )
    return made


def _journal_summary(label: str, done: Refined) -> JSONDict:
    """Return what the store's journal line of a refined plan says (the file holds the rest)."""
    result, record = done
    return {
        "label": label,
        "certified": record.certified,
        "n_knots": result.problem.n_knots,
        "objective": result.objective,
        "duration_s": result.duration,
    }


def _stored(store: SweepStore[Refined], key: str, label: str) -> Refined | None:
    """Return the stored plan of ``key`` if it passes its checks, else None (said on stderr)."""
    record = store.record(key) if store.has(key) else None
    if record is None or record.state != "done":
        return None
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        ok = store.verify(key)
    refusals = [w for w in caught if issubclass(w.category, YoubotOptWarning) and not ok]
    for w in caught:  # anything else the check warned about goes on as it was
        if w not in refusals:
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    if not ok:
        why = "; ".join(str(w.message) for w in refusals) or "refused"
        print(f"refine: {label}: stored refined plan not reused ({why}); refining it again",
              file=sys.stderr, flush=True)  # fmt: skip
        return None
    return store.load(key)


PER_PLAN_FIGURES = 3
"""The most refined plans drawn one figure each (:func:`refinement_figures`); more: an overview."""


def refinement_figures(
    folder: Path, refined: list[tuple[TrajOptResult, Refinement | None]], labels: list[str]
) -> list[Path | None]:
    """Draw the refined plans' rounds: ``refinement.png``, or ``refinement_<k>.png`` for a few.

    One plan: ``refinement.png``, its rounds in detail
    (:func:`~youbot_opt.viz.plots.trajopt.plot_refinement`); 2 to
    :data:`PER_PLAN_FIGURES` plans: one such figure each, ``refinement_<k>.png``
    (``k`` from 1 in the order of ``refined``, the title naming the label); more:
    ONE overview ``refinement.png`` of all of them
    (:func:`~youbot_opt.viz.plots.trajopt.plot_refinements`: knots of the first
    and final round, rounds, certified or not), each plan's rounds being in
    ``summary.json``. Plans without a refinement record (no trajectory to refine)
    are skipped. Nothing is drawn when nothing was refined (``--no-refine``).
    """
    if not refined:
        return []
    from youbot_opt.viz.plots.trajopt import plot_refinement, plot_refinements  # matplotlib

    done = [(record, label) for (_, record), label in zip(refined, labels, strict=True) if record]
    if len(done) > PER_PLAN_FIGURES:
        records, names = [r for r, _ in done], [label for _, label in done]
        return [draw_figure(folder, "refinement.png", plot_refinements, records, names)]
    return [
        draw_figure(
            folder,
            "refinement.png" if len(done) == 1 else f"refinement_{k}.png",
            plot_refinement,
            record,
            title=f"{label}: {record.reason}",
        )
        for k, (record, label) in enumerate(done, start=1)
    ]


def scheme_change(record: Refinement) -> str:
    """Say when the refinement's trapezoidal fallback changed the scheme ("" when it did not)."""
    first = record.rounds[0].method if record.rounds else ""
    switched = [r for r in record.rounds if r.method != first]
    if not switched:
        return ""
    return (
        f"{first} -> {switched[0].method} from round {switched[0].index} (a torque switches "
        "between its bounds inside an interval: Hermite-Simpson overshoots it on any grid)"
    )


def refinement_table(result: TrajOptResult, record: Refinement | None = None) -> list[str]:
    """Lines describing a result's grid and certification (its refinement ``record``)."""
    if record is None:
        return [
            f"grid          fixed uniform, {result.problem.n_knots} knots "
            "(--no-refine: not refined, certified once on this grid)"
        ]
    lines = [
        f"certified     {'yes' if record.certified else 'NO'}: {record.reason}",
        f"  {'round':>5} {'knots':>6} {'f':>12} {'T [s]':>9} {'max error':>10} "
        f"{'fb RMS':>7} {'fb peak':>7} {'cert.':>6} {'time [s]':>8}",
    ]
    for r in record.rounds:
        verdict = {True: "pass", False: "fail", None: "-"}[r.certificate_passed]
        lines.append(
            f"  {r.index:>5} {r.n_knots:>6} {r.objective:>12.6f} {r.duration:>9.4f} "
            f"{r.max_error:>10.3g} {r.feedback_rms:>7.3f} {r.feedback_peak:>7.3f} "
            f"{verdict:>6} {r.solve_time + r.check_time:>8.3f}"
        )
    if scheme_change(record):
        lines.append(f"scheme        {scheme_change(record)}")
    if not record.certified:
        lines.append(f"next          {next_step(result, record)}")
    return lines
