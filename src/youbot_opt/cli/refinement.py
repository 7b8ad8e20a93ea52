"""The mesh refinement of a command's plans: the budget of the flags, progress, table, figures.

:func:`refine_result` refines one solved plan (``--no-refine``: nothing) with
the :class:`~youbot_opt.trajopt.refine.RefinementBudget` of the flags,
printing each round on stderr; :func:`refine_many` does it for a study's
labelled plans; :func:`refinement_table` and :func:`refinement_figures` show
what the rounds did.

>>> refined = refine_result(solver, result, args)  # doctest: +SKIP
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from pathlib import Path

from youbot_opt._typing import JSONDict
from youbot_opt.cli.advice import next_step
from youbot_opt.cli.output import draw_figure
from youbot_opt.trajopt.refine import Refined, Refinement, RefinementBudget, RefinementRound, refine
from youbot_opt.trajopt.result import TrajOptResult
from youbot_opt.trajopt.solver import TrajOptSolver

__all__ = [
    "refine_many",
    "refine_result",
    "refinement_budget",
    "refinement_figures",
    "refinement_table",
    "scheme_change",
    "round_printer",
]


def refinement_budget(args: argparse.Namespace) -> RefinementBudget:
    """Return the :class:`~youbot_opt.trajopt.refine.RefinementBudget` of the options."""
    return RefinementBudget(
        tolerance=args.error_tol,
        max_rounds=args.max_rounds,
        max_knots=args.max_knots,
        time_limit=args.refine_time,
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
        solver, first=result, budget=refinement_budget(args), progress=round_printer(quiet)
    )


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
    items: list[tuple[str, TrajOptResult]],
    args: argparse.Namespace,
    quiet: bool = False,
) -> tuple[list[tuple[TrajOptResult, Refinement | None]], list[str], list[JSONDict]]:
    """Refine the labelled results of a study (``--no-refine``: nothing, empty outputs).

    Returns
    -------
    refined : list of (TrajOptResult, Refinement or None)
        The refined results and their records, in order (the record is None
        for a result without a trajectory, left as it was).
    lines : list of str
        One table line per result: label, knots, ``f``, ``T``, certified or why not.
    summaries : list of dict
        Per result: its label and :meth:`Refinement.summary`.
    """
    if not getattr(args, "refine", False) or not items:
        return [], [], []
    refined: list[tuple[TrajOptResult, Refinement | None]] = []
    summaries: list[JSONDict] = []
    lines = [
        f"refined ({refinement_budget(args).describe()}):",
        f"  {'':<14} {'knots':>6} {'f':>12} {'T [s]':>9}  certified",
    ]
    for label, result in items:
        if not quiet:
            print(f"refine: {label}", file=sys.stderr, flush=True)
        done = refine_result(solver, result, args, quiet=True)
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
        summaries.append({"label": label, **(record.summary() if record else {})})
    return refined, lines, summaries


def refinement_figures(
    folder: Path, refined: list[tuple[TrajOptResult, Refinement | None]], labels: list[str]
) -> list[Path | None]:
    """Draw each refined plan's rounds: ``refinement.png``, or ``refinement_<k>.png`` for several.

    Plans without a refinement record (no trajectory to refine) are skipped;
    ``k`` counts from 1 in the order of ``refined``, and the title names the label.
    Nothing is drawn when nothing was refined (``--no-refine``).
    """
    if not refined:
        return []
    from youbot_opt.viz.plots.trajopt import plot_refinement  # matplotlib: only when drawing

    done = [(record, label) for (_, record), label in zip(refined, labels, strict=True) if record]
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
