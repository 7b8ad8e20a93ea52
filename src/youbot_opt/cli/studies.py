"""``youbot-opt multistart | pareto | bounds``: the study-1 sweeps from the command line.

Each prints progress on stderr and a table on stdout (``--json``: one JSON
object), writes an output folder (:mod:`youbot_opt.cli.output`) that a rerun
with the same ``--out`` resumes, and refines the reported plans until
certified (``--no-refine`` keeps the grid). Exit codes: 0 done, 1 no solve
converged or a refined plan not certified (still saved), 2 bad input (folder
contents: docs/design.md, "Module notes"). Usage::

    youbot-opt multistart --starts 50 --beta 0.5 --knots 50 --seed 0 --workers 2 --out DIR
    youbot-opt pareto --betas 0.05:0.95:0.05 --out DIR
    youbot-opt bounds --scales 1,0.95,0.9,0.85 --out DIR
"""

from __future__ import annotations

import argparse
import dataclasses
import itertools
import json
import math
import sys
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

import numpy as np

from youbot_opt._checks import check_beta, check_bound_scale
from youbot_opt._files import json_ready, write_json_lines
from youbot_opt._typing import JSONDict
from youbot_opt.cli.flags import clearance_of, ipopt_options, report_shard, scheduler_address
from youbot_opt.cli.output import (
    STARTS_FILE,
    ProgressLine,
    draw_figure,
    open_folder,
    optima_replay,
    remove_stale_figures,
    replay_html,
    report_outputs,
    write_summary,
)
from youbot_opt.cli.pareto_table import pareto_summary, pareto_table, table_number
from youbot_opt.cli.refinement import REFINED, refine_many, refinement_figures
from youbot_opt.cli.run_size import check_sweep_values, check_trajopt_size
from youbot_opt.exceptions import ParameterError
from youbot_opt.reproduction.study1 import study1_problem
from youbot_opt.sweeps.options import SweepOptions
from youbot_opt.sweeps.resume import ShardReport
from youbot_opt.trajopt.bound_scaling import bound_scaling_study
from youbot_opt.trajopt.io import save_result
from youbot_opt.trajopt.multistart import run_multistart
from youbot_opt.trajopt.pareto import pareto_sweep, point_key
from youbot_opt.trajopt.refine import Refinement
from youbot_opt.trajopt.result import TrajOptResult
from youbot_opt.trajopt.solver import TrajOptSolver
from youbot_opt.trajopt.sweep import StartOutcome
from youbot_opt.viz.plots import (
    plot_bound_scaling,
    plot_convergence,
    plot_multistart,
    plot_pareto,
    plot_trajectory,
)

__all__ = ["bounds", "multistart", "parse_values", "pareto"]


def parse_values(text: str, name: str) -> tuple[float, ...]:
    """Parse ``"a:b:step"`` (inclusive of ``b``) or ``"x,y,z"`` into floats.

    Raises
    ------
    ParameterError
        If the text is neither form, a list item is empty (its position is
        named), a number is not finite, or ``step <= 0``.
    """
    try:
        if ":" in text:
            parts = [float(p) for p in text.split(":")]
            if len(parts) != 3:
                raise ValueError("need start:stop:step")
            start, stop, step = parts
            if not (math.isfinite(step) and step > 0):
                raise ValueError(f"step must be > 0, got {step}")
            check_sweep_values((stop - start) / step + 1, name)  # before the array is made
            values = np.round(np.arange(start, stop + 0.5 * step, step), 10)
        else:
            items = text.split(",")
            for position, item in enumerate(items, start=1):
                if not item.strip():
                    raise ValueError(f"item {position} of {len(items)} is empty")
            values = np.array([float(p) for p in items])
    except ValueError as exc:
        raise ParameterError(
            f"--{name} must be 'start:stop:step' or a comma-separated list, got {text!r} ({exc})",
            name=name,
            value=text,
        ) from exc
    if values.size == 0 or not np.all(np.isfinite(values)):
        raise ParameterError(f"--{name} must list finite numbers, got {text!r}", name=name)
    return tuple(float(v) for v in values)


# ------------------------------------------------------------------ helpers
def _solver(args: argparse.Namespace) -> TrajOptSolver:

    problem = study1_problem(args.knots)
    clearance = clearance_of(args, problem.robot)
    if clearance is not None:
        problem = dataclasses.replace(problem, clearance=clearance)
    check_trajopt_size(
        n_knots=args.knots,
        nq=problem.robot.nq,
        # every start's task is listed up front: pareto's --first-starts counts too
        n_starts=max(getattr(args, "starts", 1) or 1, getattr(args, "first_starts", 1) or 1),
        max_knots=args.max_knots if getattr(args, "refine", False) else 0,
    )
    method = args.transcription.replace("-", "_")
    return TrajOptSolver(problem, method, ipopt_options(args), args.backend)


def _check(
    args: argparse.Namespace, betas: tuple[float, ...] = (), scales: tuple[float, ...] = ()
) -> None:
    """Validate cheap arguments before the (slow) solver build."""
    if args.knots < 2:
        raise ParameterError(f"--knots must be >= 2, got {args.knots}", name="knots")
    if args.workers is not None and args.workers < 0:
        raise ParameterError(f"--workers must be >= 0, got {args.workers}", name="workers")
    if args.item_timeout is not None:
        if not (math.isfinite(args.item_timeout) and args.item_timeout > 0):
            raise ParameterError(
                f"--item-timeout must be > 0 [s], got {args.item_timeout}", name="item_timeout"
            )
        if args.workers == 0:
            raise ParameterError(
                "--item-timeout needs worker processes (--workers >= 1), got --workers 0",
                name="item_timeout",
            )
    if getattr(args, "shard", None) is not None and args.out is None:
        raise ParameterError(
            "--shard I/K needs --out DIR: every shard and the collecting run must use the "
            "same folder",
            name="shard",
        )

    for name in ("starts", "first_starts"):
        value = getattr(args, name, None)
        if value is not None and value < 0:
            raise ParameterError(f"--{name.replace('_', '-')} must be >= 0, got {value}", name=name)
    for b in (*betas, *([args.beta] if hasattr(args, "beta") else [])):
        check_beta(b)
    for s in (*scales, *([args.bound_scale] if hasattr(args, "bound_scale") else [])):
        check_bound_scale(s)


def _sweep(args: argparse.Namespace, progress: ProgressLine, folder: Path) -> SweepOptions:
    """How the sweep runs: ``--workers`` (0 = serial), ``--item-timeout``, ``--out``, Dask."""
    executor: str = "serial" if args.workers == 0 else "process"
    executor = scheduler_address(args) or executor  # --scheduler / --scheduler-file: Dask
    workers = None if args.workers == 0 else args.workers
    return SweepOptions(
        executor=executor,
        workers=workers,
        timeout=args.item_timeout,
        out=folder,
        progress=progress,
        shard=args.shard,
        keep_results=args.keep_results,
    )


def _all_certified(plans: list[tuple[TrajOptResult, Refinement | None]]) -> bool:
    """Whether every refined plan is certified (vacuously true with ``--no-refine``)."""
    return all(record is not None and record.certified for _, record in plans)


_STORE = ("manifest.json", "items")  # the sweep store's files, at the top of the run folder


def _figure(
    args: argparse.Namespace, folder: Path, name: str, make: Callable[..., Any], *data: object
) -> Path | None:
    """Draw one figure into ``folder``, or none with ``--no-figures``."""
    return None if args.no_figures else draw_figure(folder, name, make, *data)


def _refinement_figures(
    args: argparse.Namespace,
    folder: Path,
    refined: list[tuple[TrajOptResult, Refinement | None]],
    labels: list[str],
) -> list[Path | None]:
    """Draw the refined plans' figures (:func:`refinement_figures`); none with ``--no-figures``."""
    return [] if args.no_figures else refinement_figures(folder, refined, labels)


def _emit(
    args: argparse.Namespace,
    folder: Path,
    summary: JSONDict,
    table: list[str],
    files: list[Path | None],
    solver: TrajOptSolver,
) -> None:
    """Write summary.json, print the table (or the JSON) and where the outputs are.

    The summary also records the Hessian IPOPT ran (``"hessian"``, ``--hessian``).
    """
    summary["hessian"] = solver.hessian
    written = [f for f in files if f is not None]
    remove_stale_figures(folder, written)  # a reused --out: an earlier run's refinement_<k>.png
    stores = [*_STORE, *([REFINED] if (folder / REFINED).is_dir() else [])]
    summary["output_folder"] = str(folder.resolve())
    folders = [f"{name}/" for name in stores[1:]]
    summary["files"] = [f.name for f in written] + [_STORE[0], *folders, "summary.json"]
    written += [folder / name for name in stores] + [write_summary(folder, summary)]
    if args.json:
        print(json.dumps(json_ready(summary), indent=1, default=str))
    else:
        print("\n".join(table))
        print()
    report_outputs(folder, written, args.json)
    stream = sys.stderr if args.json else sys.stdout
    print(f"rerun with --out {folder} to resume", file=stream)


def _write_starts(folder: Path, starts: Iterable[StartOutcome]) -> Path:
    """Write one JSON object per start to ``folder/starts.jsonl``; return the path.

    Each row is the start's :meth:`~youbot_opt.trajopt.sweep.StartOutcome.summary`
    (``key``, ``index``, ``seed``, ``guess``, ``status``, ``success``, ``objective``,
    ``duration_s``, ``work`` [N^2 m^2 s], ``iterations``, ``solve_time_s``,
    ``guess_time_s``, ``attempts``, ``reason``: the rows of ``summary.json``'s
    ``starts``) and ``optimum`` (``--no-keep-results``: the key of its distinct
    optimum's representative; else null). Streamed: a million starts never sit in memory.
    """
    path = folder / STARTS_FILE
    write_json_lines(path, ({**s.summary(), "optimum": s.optimum} for s in starts))
    return path


# ----------------------------------------------------------------- commands
def multistart(args: argparse.Namespace) -> int:
    """Run ``youbot-opt multistart``; returns the exit code."""
    _check(args)
    solver = _solver(args)
    folder = open_folder("multistart", args.out)  # the sweep store shares it
    prog = ProgressLine("multistart", args.quiet)
    res = run_multistart(
        solver,
        args.starts,
        beta=args.beta,
        bound_scale=args.bound_scale,
        seed=args.seed,
        include_straight=args.straight,
        sweep=_sweep(args, prog, folder),
    )
    prog.close()
    if isinstance(res, ShardReport):  # --shard I/K solved its share
        return report_shard(res)
    optima = res.distinct_optima(args.obj_tol, args.dist_tol)
    table = [
        f"multistart: beta = {res.beta:g}, {res.n_starts} starts (seed {res.seed}), "
        f"success rate {100 * res.success_rate:.0f} %, {res.resumed} resumed, "
        f"{res.wall_time:.2f} s",
        f"{'optimum':>7} {'f':>12} {'T [s]':>9} {'W':>10} {'count':>6} {'share':>6}",
    ]
    for i, o in enumerate(optima):
        table.append(
            f"{i:>7} {o.objective:>12.6f} {o.duration:>9.4f} {o.work:>10.4f} "
            f"{o.count:>6} {100 * o.fraction:>5.0f}%"
        )
    failed = (s for s in res.starts if not s.success)  # streamed with --no-keep-results
    for s in itertools.islice(failed, 10):
        table.append(f"  not converged: {s.key} (seed {s.seed}): {s.status}: {s.reason}")
    summary = res.summary(args.obj_tol, args.dist_tol)
    summary["starts_file"] = STARTS_FILE
    starts_file = _write_starts(folder, res.starts)
    best = (
        [("best start", res.best.key, res.best.result)]
        if res.best is not None and res.best.result
        else []
    )
    quiet = args.quiet or args.json
    refined, lines, summary["refinement"] = refine_many(solver, best, args, quiet, folder)
    table += lines
    labels = [label for label, *_ in best]
    files: list[Path | None] = _refinement_figures(args, folder, refined, labels)
    files.append(starts_file)
    if res.best is not None and res.best.result is not None:
        plan, record = refined[0] if refined else (res.best.result, None)  # --no-refine: grid's
        summary["plan"] = {**plan.summary(), "certified": record is not None and record.certified}
        files += [
            save_result(plan, folder / "result.npz", refinement=record),
            _figure(args, folder, "multistart.png", plot_multistart, res),
            _figure(args, folder, "convergence.png", plot_convergence, res),
            _figure(args, folder, "trajectory.png", plot_trajectory, plan),
            optima_replay(folder, res, args.obj_tol, args.dist_tol),
        ]
    _emit(args, folder, summary, table, files, solver)
    return 0 if res.best is not None and _all_certified(refined) else 1


def pareto(args: argparse.Namespace) -> int:
    """Run ``youbot-opt pareto``; returns the exit code."""
    betas = parse_values(args.betas, "betas")
    _check(args, betas=betas)
    solver = _solver(args)
    folder = open_folder("pareto", args.out)  # the sweep store shares it
    prog = ProgressLine("pareto", args.quiet)
    front = pareto_sweep(
        solver,
        betas,
        bound_scale=args.bound_scale,
        first_starts=args.first_starts,
        seed=args.seed,
        sweep=_sweep(args, prog, folder),
    )
    prog.close()
    if isinstance(front, ShardReport):  # --shard I/K solved its share of the first point
        return report_shard(front)

    table = pareto_table(front)  # distinct points counted, W with its unit
    best = [p for p in front.nondominated() if p.result is not None]
    keys = {id(p): point_key(k) for k, p in enumerate(front.points)}  # the store's, by point
    items = [(f"beta = {p.beta:g}", keys[id(p)], p.result) for p in best if p.result is not None]
    plans, lines, refined = refine_many(solver, items, args, args.quiet or args.json, folder)
    table += lines
    labels = [label for label, *_ in items]
    files: list[Path | None] = _refinement_figures(args, folder, plans, labels)
    if best:
        picks = sorted({round(i * (len(best) - 1) / 4) for i in range(5)})  # ends + 3 between
        picks.sort(key=lambda i: best[i].beta)
        grid = [x for *_, x in items]  # the grid's plans (--no-refine), else the refined ones
        shown = [([p for p, _ in plans] or grid)[i] for i in picks]
        labels = [
            f"beta = {best[i].beta:g}: T = {x.duration:.3f} s, W = {x.work:.4g}"
            for i, x in zip(picks, shown, strict=True)
        ]
        files += [
            _figure(args, folder, "pareto.png", plot_pareto, front),
            replay_html(folder, shown, labels),
        ]
    _emit(args, folder, {**pareto_summary(front), "refinement": refined}, table, files, solver)
    return 0 if front.nondominated() and _all_certified(plans) else 1


def bounds(args: argparse.Namespace) -> int:
    """Run ``youbot-opt bounds``; returns the exit code."""
    scales = parse_values(args.scales, "scales")
    _check(args, scales=scales)
    solver = _solver(args)
    folder = open_folder("bounds", args.out)  # the sweep store shares it
    prog = ProgressLine("bounds", args.quiet)
    res = bound_scaling_study(
        solver,
        scales,
        beta=args.beta,
        n_starts=args.starts,
        seed=args.seed,
        sweep=_sweep(args, prog, folder),
    )
    prog.close()
    if isinstance(res, ShardReport):  # --shard I/K solved its share
        return report_shard(res)
    table = [
        f"bound scaling: beta = {res.beta:g}, {args.starts} starts + straight line per scale, "
        f"{res.wall_time:.2f} s",
        f"{'scale':>6} {'f':>11} {'T [s]':>9} {'W':>11} {'conv.':>6}  active bounds",
    ]
    for r in res.rows:
        active = ", ".join(f"{k} x{n}" for k, n in r.active_counts().items()) or "-"
        table.append(
            f"{r.bound_scale:>6.3f} {table_number(r.objective, '.5f'):>11} "
            f"{table_number(r.duration, '.4f'):>9} {table_number(r.work, '.4f'):>11} "
            f"{100 * r.multistart.success_rate:>5.0f}%  {active}"
        )
    files: list[Path | None] = []
    solved = [
        (r, r.best.key, r.best.result)
        for r in res.rows
        if r.best is not None and r.best.result is not None
    ]
    items = [(f"scale {r.bound_scale:.3f}", key, x) for r, key, x in solved]
    plans, lines, refined = refine_many(solver, items, args, args.quiet or args.json, folder)
    table += lines
    files += _refinement_figures(args, folder, plans, [label for label, *_ in items])
    if solved:
        shown = [p for p, _ in plans] or [x for *_, x in solved]  # --no-refine: the grid's
        labels = [
            f"{r.bound_scale:.0%} bounds: f = {x.objective:.5g}"
            for (r, *_), x in zip(solved, shown, strict=True)
        ]
        files += [
            _figure(args, folder, "bound_scaling.png", plot_bound_scaling, res),
            replay_html(folder, shown, labels),
        ]
    _emit(args, folder, {**res.summary(), "refinement": refined}, table, files, solver)
    return 0 if all(r.best is not None for r in res.rows) and _all_certified(plans) else 1
