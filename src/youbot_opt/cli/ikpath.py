"""``youbot-opt ikpath``: minimum-motion cyclic joint path through targets, on any robot.

Planar targets X Y [m] (``--example``, ``--lengths``, ``--robot youbot``) or
3-D ones (X Y Z, an approach or a pose, ``--targets FILE``, any other
``--robot``, ``--tip-frame``): every target's reachability is decided first
(exit 2 with the certificate of an unreachable one), then the resumable
multistart runs into the run folder's sweep store (progress on stderr) and the
folder gets the figures, ``result.json``, ``starts.jsonl``, ``summary.json``
and ``replay.html`` (:mod:`youbot_opt.cli.ikpath_text`). Exit 0: best start
succeeded; 1: failed. Details: docs/ikpath.md.

    youbot-opt ikpath --example A --starts 200
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from collections.abc import Callable
from dataclasses import replace
from functools import partial
from pathlib import Path
from typing import TextIO, cast

import numpy as np

from youbot_opt._typing import JSONDict
from youbot_opt.cli.drawing import Drawing, FigureJob
from youbot_opt.cli.flags import clearance_of, loading_options, report_shard, scheduler_address
from youbot_opt.cli.ikpath_text import (
    StartsFile,
    add_result_3d,
    clearance_summary,
    planar_summary,
    print_3d,
    print_planar,
    residual_field,
    summary_3d,
    warn_undecided_3d,
    warn_undecided_planar,
    write_starts,
)
from youbot_opt.cli.output import (
    STARTS_FILE,
    print_json,
    print_outputs,
    remove_stale_figures,
    replay_or_warn,
    run_folder,
    write_summary,
)
from youbot_opt.cli.parser import PLANAR_REACH_EVALUATIONS, START_KIND_NAMES
from youbot_opt.cli.run_size import check_ikpath_size
from youbot_opt.cli.warning_lines import flush_warnings
from youbot_opt.collision.clearance import Clearance
from youbot_opt.exceptions import ParameterError
from youbot_opt.ikpath.examples import example_problem
from youbot_opt.ikpath.io import RobotSource, save_result
from youbot_opt.ikpath.methods.al import AL_OPTIONS_3D, ALOptions
from youbot_opt.ikpath.multistart import MultistartResult, run_multistart
from youbot_opt.ikpath.problem import CyclicIKProblem
from youbot_opt.ikpath.reachability import Reachability
from youbot_opt.ikpath.reachability.general import check_reachability_3d
from youbot_opt.ikpath.reachability.planar import ReachVerdict, check_reachability
from youbot_opt.ikpath.result import IKPathResult
from youbot_opt.ikpath.starts import AUTOMATIC_TIME_BUDGET, BRANCH_KIND
from youbot_opt.ikpath.targets import Target, load_targets, position_targets, quaternion_to_matrix
from youbot_opt.nlp.ipopt import IpoptOptions
from youbot_opt.robot.load import load_model
from youbot_opt.robot.model import RobotModel
from youbot_opt.robot.planar import PlanarChain, youbot_chain
from youbot_opt.sweeps.options import SweepOptions
from youbot_opt.sweeps.resume import ShardReport
from youbot_opt.viz.meshcat.ikpath import export_ikpath_html
from youbot_opt.viz.meshcat.scene import RobotLike

__all__ = ["SPATIAL_DEFAULT_START_KIND", "StartProgress", "run", "start_sweep"]

SPATIAL_DEFAULT_START_KIND = "mixed"
"""``--start-kind`` of spatial runs when none is given."""


class StartProgress:
    """Progress of the starts on stderr: a bar on a terminal, else a line per tenth."""

    def __init__(self, stream: TextIO | None = None) -> None:
        self.stream = sys.stderr if stream is None else stream
        self.tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self.tic = time.perf_counter()
        self.shown = -1
        self.open = False  # a bar is on the terminal without its line end

    def __call__(self, done: int, total: int, best: float) -> None:
        """Report ``done`` of ``total`` starts and the best ``E`` so far [rad^2]."""
        best_txt = f"{best:.10g} rad^2" if math.isfinite(best) else "none converged yet"
        elapsed = time.perf_counter() - self.tic
        if self.tty:
            width = 30
            fill = int(width * done / total)
            self.stream.write(
                f"\r[{'#' * fill}{'.' * (width - fill)}] {done}/{total} starts, "
                f"best E {best_txt}, {elapsed:.1f} s"
            )
            self.open = done != total
            if done == total:
                self.stream.write("\n")
        else:
            tenth = 10 * done // total
            if tenth == self.shown and done != total:
                return
            self.shown = tenth
            self.stream.write(
                f"ikpath: {done}/{total} starts done, best E {best_txt}, {elapsed:.1f} s\n"
            )
        self.stream.flush()

    def end(self) -> None:
        """End the bar's line if the run ended before every start (a time budget)."""
        if self.open:
            self.stream.write("\n")
            self.stream.flush()
            self.open = False


def start_sweep(args: argparse.Namespace, folder: Path, executor: str) -> SweepOptions:
    """Return how the starts of the command line run, and say on stderr where they are saved.

    Parameters
    ----------
    args : argparse.Namespace
        ``--starts`` (None: automatic), ``--workers`` (default: 1 below 8 starts or
        serial automatic starts, else the CPUs),
        ``--no-progress``, ``--shard`` and ``--keep-results/--no-keep-results``.
    folder : Path
        The run folder: the sweep store, which a rerun with ``--out`` resumes.
    executor : str
        A Dask scheduler address, ``"process"`` (several starts: a crashing
        start cannot end the run) or ``"serial"``.
    """
    workers = args.workers
    if workers is None and (args.starts is None or args.starts < 8):
        workers = 1 if executor == "serial" or args.starts is not None else None
    if not args.no_progress:
        count = "automatic starts" if args.starts is None else f"{args.starts} start(s)"
        if args.starts is None and args.start_kind in (None, BRANCH_KIND):
            budget = args.time_budget or AUTOMATIC_TIME_BUDGET
            count += f" (time budget {budget:g} s)"
        print(
            f"ikpath: {count}, each saved to {folder.resolve() / 'items'} as it "
            f"finishes (rerun with --out {folder} to resume)",
            file=sys.stderr,
        )
    return SweepOptions(
        executor=executor,
        workers=workers,
        progress=None if args.no_progress else StartProgress(),
        out=folder,
        shard=args.shard,
        keep_results=getattr(args, "keep_results", True),
    )


def _end_progress(sweep: SweepOptions) -> None:
    """End the progress bar's line (a time budget may stop the starts before the last)."""
    if isinstance(sweep.progress, StartProgress):
        sweep.progress.end()


# ------------------------------------------------------------------ the problem
def _spatial_mode(args: argparse.Namespace) -> bool:
    """Whether the command line asks for the spatial problem (see the usage text)."""
    if args.tip_frame or args.targets_file:
        return True
    if args.robot is not None and args.robot != "youbot":
        return True
    return any(len(t) != 2 for t in args.target or ())


def _planar_problem(args: argparse.Namespace) -> CyclicIKProblem:
    """Build the planar problem of the command line."""
    if args.example:
        if args.lengths or args.target or args.robot:
            raise ParameterError(
                "--example fixes the arm and targets; drop --lengths/--target/--robot",
                name="example",
                value=args.example,
            )
        base = example_problem(args.example)
        chain, targets = base.planar_chain, base.target_points
    else:
        if not args.target:
            raise ParameterError(
                "give --example A|B or at least two --target X Y", name="target", value=None
            )
        targets = np.array(args.target)
        if args.robot:
            if args.lengths:
                raise ParameterError(
                    "--robot fixes the lengths", name="lengths", value=args.lengths
                )

            chain = youbot_chain()
        elif args.lengths:
            chain = PlanarChain(lengths=args.lengths)
        else:
            raise ParameterError("give --lengths, --robot or --example", name="lengths", value=None)
    if args.limit is not None or args.lower is not None or args.upper is not None:
        if args.limit is not None and not args.limit > 0:
            raise ParameterError(
                f"--limit must be > 0, got {args.limit}", name="limit", value=args.limit
            )
        lower = (
            args.lower
            if args.lower is not None
            else (-args.limit if args.limit is not None else chain.q_lower)
        )
        upper = (
            args.upper
            if args.upper is not None
            else (args.limit if args.limit is not None else chain.q_upper)
        )
        chain = chain.with_limits(lower, upper)
    return CyclicIKProblem(
        robot=chain, targets=position_targets(targets), use_limits=not args.no_limits
    )


def _targets_3d(args: argparse.Namespace) -> tuple[Target, ...]:
    """Targets from ``--target`` (3, 6 or 7 numbers) and ``--targets FILE``.

    Raises
    ------
    ParameterError
        For a ``--target`` of another length, or both sources at once.
    """
    tol = {"position_tol": args.tol, "orientation_tol": args.orientation_tol}
    if args.targets_file and args.target:
        raise ParameterError(
            "give targets either with --target or with --targets FILE, not both",
            name="target",
            value=args.targets_file,
        )
    if args.targets_file:
        return load_targets(args.targets_file, **tol)
    out = []
    for k, t in enumerate(args.target or ()):
        if len(t) == 3:
            out.append(Target(position=t, **tol))
        elif len(t) == 6:
            out.append(Target(position=t[:3], approach=t[3:], **tol))
        elif len(t) == 7:
            out.append(Target(position=t[:3], rotation=quaternion_to_matrix(t[3:]), **tol))
        else:
            raise ParameterError(
                f"--target {k + 1} has {len(t)} numbers; spatial targets take X Y Z, "
                "X Y Z AX AY AZ or X Y Z QX QY QZ QW",
                name="target",
                value=t,
            )
    return tuple(out)


def _check_flags_3d(args: argparse.Namespace) -> str | None:
    """Refuse the planar-only flags; return the start kind (None: the robot kind's)."""
    if args.example or args.lengths:
        raise ParameterError(
            "--example/--lengths describe planar chains; spatial targets need --robot",
            name="robot",
            value=args.robot,
        )
    if args.reach_evaluations is not None and args.reach_evaluations < 1:
        raise ParameterError(
            f"--reach-evaluations must be >= 1, got {args.reach_evaluations}",
            name="reach_evaluations",
            value=args.reach_evaluations,
        )
    kind = args.start_kind
    if kind not in (None, "mixed", "coherent", "random", "feasible", BRANCH_KIND):
        raise ParameterError(
            f"--start-kind {kind} is a planar start kind; spatial targets take mixed "
            "(default), coherent or random",
            name="start_kind",
            value=kind,
        )
    if args.max_wall_time is not None and not (
        math.isfinite(args.max_wall_time) and args.max_wall_time > 0
    ):
        raise ParameterError(
            f"--max-wall-time must be a positive time in [s], got {args.max_wall_time}",
            name="max_wall_time",
            value=args.max_wall_time,
        )
    return kind


def _problem_3d(
    args: argparse.Namespace, robot: RobotModel, clearance: Clearance | None = None
) -> CyclicIKProblem:
    """Build the 3-D problem of the command line on the loaded ``robot`` (and ``--scene``)."""
    frame = args.tip_frame or robot.tip_frame
    targets = _targets_3d(args)
    if len(targets) < 2:
        raise ParameterError(
            f"a cyclic path needs at least 2 targets, got {len(targets)}",
            name="target",
            value=len(targets),
        )
    lower = upper = None
    if args.limit is not None:
        if not args.limit > 0:
            raise ParameterError(f"--limit must be > 0, got {args.limit}", name="limit")
        lower, upper = -args.limit, args.limit
    lower = args.lower if args.lower is not None else lower
    upper = args.upper if args.upper is not None else upper
    n = CyclicIKProblem(robot=robot, frame=frame, targets=targets).n_joints
    return CyclicIKProblem(
        robot=robot,
        frame=frame,
        targets=targets,
        use_limits=not args.no_limits,
        q_lower=None if lower is None else np.broadcast_to(lower, (n,)),
        q_upper=None if upper is None else np.broadcast_to(upper, (n,)),
        clearance=clearance,
    )


def _options_3d(args: argparse.Namespace) -> ALOptions | IpoptOptions | None:
    """Solver options of ``--method`` with ``--max-wall-time`` (None: the defaults)."""
    if args.max_wall_time is None:
        return None
    if args.method == "al":
        return replace(AL_OPTIONS_3D, max_wall_time=args.max_wall_time)

    return IpoptOptions.for_ikpath(max_wall_time=args.max_wall_time)


def _start_kind_3d(kind: str | None, problem: CyclicIKProblem, n_starts: int | None) -> str:
    """Return the start kind: ``branches`` (automatic starts), ``feasible`` or ``mixed``.

    ``feasible`` (the planar starts) for a planar robot, else ``mixed``.
    """
    if kind is None and n_starts is None:
        return BRANCH_KIND
    if kind is None:
        return "feasible" if problem.chain is not None else SPATIAL_DEFAULT_START_KIND
    if kind == "feasible" and problem.chain is None:
        raise ParameterError(
            f"--start-kind feasible is a planar start kind; robot {problem.robot_model.name!r} "
            f"is not planar for frame {problem.frame!r}: spatial targets take mixed (default), "
            "coherent or random",
            name="start_kind",
            value=kind,
        )
    return kind


# ------------------------------------------------------------------ the runs
def _executor(args: argparse.Namespace, spatial: bool) -> str:
    """Where the starts run: a Dask scheduler, a process pool, or this process.

    Automatic starts run here unless they are AL solves of spatial targets
    (about 0.1 s each, against IPOPT's 0.01 s and the planar methods' ms: a pool
    pays off only for them) without a clearance (each worker builds the clearance
    rows once, about 0.5 s on ur5 and one box, more than the AL's 0.1-0.2 s per
    start; results sent back reuse the parent's rows, ikpath/problem.py).
    """
    address = scheduler_address(args)
    if address:
        return address
    if args.starts is None:
        clear = args.scene is not None or args.margin is not None
        return "process" if spatial and args.method == "al" and not clear else "serial"
    return "process" if args.starts > 1 else "serial"


_PLOTS = "youbot_opt.viz.plots.ikpath:"  # matplotlib loads where the figures are drawn


def _figure(name: str, make: str, *args: object) -> FigureJob:
    """Return the job drawing ``viz.plots.ikpath``'s ``make(*args)``; its errors propagate."""
    return FigureJob(name, _PLOTS + make, args, optional=False)


def _draw_while(
    args: argparse.Namespace, folder: Path, jobs: list[FigureJob], rest: Callable[[], list[Path]]
) -> tuple[list[Path], list[Path]]:
    """Draw ``jobs`` (none with ``--no-figures``) in other processes while ``rest()`` writes.

    Returns the figures written and what ``rest`` returned; every file exists then.
    """
    drawing = Drawing(folder, [] if args.no_figures else jobs)  # drawn elsewhere from here on
    try:
        written = rest()
        drawn = drawing.wait()
    finally:
        drawing.stop()
    return [p for p in drawn if p is not None], written


def _planar_outputs(
    args: argparse.Namespace,
    folder: Path,
    problem: CyclicIKProblem,
    verdicts: tuple[ReachVerdict, ...],
    ms: MultistartResult | None,
) -> list[Path]:
    """Write a planar run's figures, replay and saved result; return the folder's files."""
    jobs = [_figure("ikpath_workspace.png", "plot_workspace", problem, verdicts)]
    if ms is None:
        return _draw_while(args, folder, jobs, list)[0]
    best = ms.best
    jobs.append(_figure("ikpath_arm.png", "plot_path", best))
    if best.history:
        jobs.append(_figure("ikpath_convergence.png", "plot_convergence", best))
    jobs.append(_figure("ikpath_minima.png", "plot_minima", ms))

    def rest() -> list[Path]:
        files = [save_result(best, folder / "result.json")]
        files.append(folder / STARTS_FILE)
        if not args.no_replay:
            page = replay_or_warn(
                lambda: export_ikpath_html(
                    best, folder / "replay.html", segment_time=args.segment_time
                )
            )
            files += [page] if page is not None else []
        return files + [folder / "manifest.json", folder / "items"]  # the starts' sweep store

    figures, files = _draw_while(args, folder, jobs, rest)
    return figures + files


def _finish(
    args: argparse.Namespace,
    folder: Path,
    doc: JSONDict,
    files: list[Path],
    print_text: Callable[[], None],
    errors: list[str],
) -> None:
    """Write ``summary.json`` (naming the files), print it or its text, the folder and errors.

    A reused ``--out`` keeps no figure of an earlier run that this one did not write.
    """
    remove_stale_figures(folder, files)
    doc["output_folder"] = str(folder.resolve())
    doc["files"] = [f.name for f in files] + ["summary.json"]
    files.append(write_summary(folder, doc))
    if args.json:
        print_json(doc)
    else:
        print_text()
    print_outputs(folder, files)
    for error in errors:
        print(f"youbot-opt: error: {error}", file=sys.stderr)


def _time_path(
    args: argparse.Namespace,
    robot: RobotModel | None,
    best: IKPathResult,
    folder: Path,
    doc: JSONDict,
    files: list[Path],
    print_text: Callable[[], None],
) -> tuple[Callable[[], None], bool]:
    """Time the best path (``--timed``, docs/timed.md); return the printer, whether it passed."""
    if not args.timed:
        return print_text, True
    if not best.success:
        doc["timed"] = {"status": "not run: the IK path failed"}
        return print_text, False
    from youbot_opt.cli.timed import time_ik_path

    assert robot is not None  # --timed: the youBot (planar) or the spatial run's robot

    entry, lines, written, ok = time_ik_path(
        robot, best.configurations, folder, knots_per_segment=args.segment_knots, args=args
    )
    doc["timed"] = entry
    files += written

    def text() -> None:
        print_text()
        print("\n".join(["", *lines]), flush=True)

    return text, ok


_CLEARANCE_FLAGS = ("scene", "margin", "no_self_collision", "srdf", "disable_pair")


def _refuse_clearance_planar(args: argparse.Namespace) -> None:
    """Refuse ``--scene`` and its companions on planar targets (the chains have no geometry)."""
    given = [f for f in _CLEARANCE_FLAGS if getattr(args, f, None) not in (None, False, [])]
    if given:
        flag = "--" + given[0].replace("_", "-")
        raise ParameterError(
            f"{flag} needs a 3-D robot (--robot NAME with X Y Z targets): the planar chains of "
            "--example, --lengths and --robot youbot with X Y targets have no collision geometry",
            name=given[0],
        )


def _run_planar(args: argparse.Namespace) -> int:
    """Run a planar IK path; return the exit status."""
    _refuse_clearance_planar(args)
    if args.timed and (args.robot != "youbot" or args.example):
        raise ParameterError(
            "--timed needs a robot with masses: --robot youbot (planar) or a URDF robot; "
            "the arms of --lengths and --example are kinematic only",
            name="timed",
        )
    if args.method is None:
        args.method = "al"
    if args.start_kind is None:
        args.start_kind = BRANCH_KIND if args.starts is None else "feasible"
    elif args.start_kind not in (*START_KIND_NAMES, BRANCH_KIND):
        raise ParameterError(
            f"--start-kind {args.start_kind} is a spatial start kind; planar targets take "
            f"{' or '.join(START_KIND_NAMES)}",
            name="start_kind",
            value=args.start_kind,
        )
    if args.reach_evaluations is None:
        args.reach_evaluations = PLANAR_REACH_EVALUATIONS
    problem = _planar_problem(args)
    if args.reach_evaluations < 1:
        raise ParameterError(
            f"--reach-evaluations must be >= 1, got {args.reach_evaluations}",
            name="reach_evaluations",
            value=args.reach_evaluations,
        )
    verdicts = check_reachability(problem, max_evaluations=args.reach_evaluations)
    unreachable = [v for v in verdicts if v.status is Reachability.UNREACHABLE]
    folder = run_folder("ikpath", args.out)
    ms = None
    if not unreachable:
        warn_undecided_planar(verdicts)
        options: ALOptions | IpoptOptions | None = None
        if args.max_wall_time is not None:
            kind = ALOptions if args.method == "al" else IpoptOptions.for_ikpath
            options = kind(max_wall_time=args.max_wall_time)
        # With --scheduler / --scheduler-file the starts run on that Dask cluster.
        executor = _executor(args, spatial=False)
        sweep = start_sweep(args, folder, executor)
        got = run_multistart(
            problem,
            method=args.method,
            options=options,
            n_starts=args.starts,
            seed=args.seed,
            starts=args.start_kind,
            verdicts=verdicts,
            time_budget=args.time_budget,
            sweep=sweep,
        )
        _end_progress(sweep)
        if isinstance(got, ShardReport):  # --shard I/K solved its share
            return report_shard(got)
        ms = got
    starts = None if ms is None else write_starts(folder, ms.results, ms.attempts, residual_field)
    doc = planar_summary(args, problem, verdicts, ms, starts)
    files = _planar_outputs(args, folder, problem, verdicts, ms)
    crashed = [] if starts is None else starts.crashed
    errors = [v.describe() for v in unreachable]
    text: Callable[[], None] = partial(print_planar, doc, crashed)
    timed_ok = True
    if ms is not None:
        robot = load_model("youbot") if args.timed else None
        text, timed_ok = _time_path(args, robot, ms.best, folder, doc, files, text)
    _finish(args, folder, doc, files, text, errors)
    if ms is None:
        return 2
    return 0 if ms.best.success and timed_ok else 1


def _run_3d(args: argparse.Namespace) -> int:
    """Run an IK path with 3-D targets; return the exit status."""
    kind = _check_flags_3d(args)
    if args.method is None:  # IPOPT: exact Hessians, 10-40x faster per spatial solve
        args.method = "ipopt"
    robot = load_model(args.robot or "youbot", tip_frame=args.tip_frame, **loading_options(args))
    flush_warnings()  # the loader's warnings, grouped, before the run
    clearance = clearance_of(args, robot)  # held by both methods (docs/ikpath.md)
    problem = _problem_3d(args, robot, clearance)
    kind = _start_kind_3d(kind, problem, args.starts)
    frame = problem.frame
    targets = problem.targets
    options = _options_3d(args)
    executor = _executor(args, spatial=True)
    budget = {} if args.reach_evaluations is None else {"interval_boxes": args.reach_evaluations}
    verdicts = check_reachability_3d(problem, **budget)
    folder = run_folder("ikpath", args.out)
    doc = summary_3d(args, problem, robot.name, verdicts)
    unreachable = [v for v in verdicts if v.status is Reachability.UNREACHABLE]
    files: list[Path] = []
    code = 2
    starts: StartsFile | None = None
    if not unreachable:
        warn_undecided_3d(verdicts)
        sweep = start_sweep(args, folder, executor)
        ms = run_multistart(
            problem,
            planar=False,
            method=args.method,
            n_starts=args.starts,
            seed=args.seed,
            starts=kind,
            options=options,
            verdicts=verdicts,
            time_budget=args.time_budget,
            sweep=sweep,
        )
        _end_progress(sweep)
        if isinstance(ms, ShardReport):  # --shard I/K solved its share
            return report_shard(ms)
        best = ms.best
        starts = write_starts(folder, ms.results, ms.attempts)
        add_result_3d(doc, args, ms, kind, starts)
        if clearance is not None:
            doc["clearance"] = clearance_summary(clearance, args.scene, best.clearance)
        source = RobotSource.of(robot, strict=not args.lenient)
        jobs = [
            _figure("ikpath_legs.png", "plot_leg_motion", best),
            _figure("ikpath_path3d.png", "plot_path", best),
        ]

        def replay() -> list[Path]:
            if args.no_replay:
                return []
            page = replay_or_warn(
                lambda: export_ikpath_html(
                    best,
                    folder / "replay.html",
                    robot=cast("RobotLike", robot),
                    segment_time=args.segment_time,
                )
            )
            return [page] if page is not None else []

        figures, pages = _draw_while(
            args,
            folder,
            jobs,
            lambda: [save_result(best, folder / "result.json", source), *replay()],
        )
        files += [pages[0], *figures, *pages[1:]]  # result.json, the figures, the replay
        files += [starts.path, folder / "manifest.json", folder / "items"]  # the starts
        code = 0 if best.success else 1
    else:
        doc.update(status="unreachable", E=None, result=None)
    errors = [f"unreachable: {v.message}" for v in unreachable]
    text: Callable[[], None]
    text = partial(print_3d, doc, robot.name, frame, len(targets), args.method, starts)
    if not unreachable:
        text, timed_ok = _time_path(args, robot, best, folder, doc, files, text)
        code = code if timed_ok else 1
    _finish(args, folder, doc, files, text, errors)
    return code


def _check_time_budget(args: argparse.Namespace) -> None:
    """Refuse a ``--time-budget`` that is no positive, finite time, or comes with ``--starts``."""
    budget = args.time_budget
    if budget is None:
        return
    if not (math.isfinite(budget) and budget > 0):
        raise ParameterError(
            f"--time-budget must be a positive, finite time in [s], got {budget}",
            name="time_budget",
            value=budget,
        )
    asked = (
        f"--starts {args.starts}" if args.starts is not None else f"--start-kind {args.start_kind}"
    )
    if args.starts is not None or args.start_kind not in (None, BRANCH_KIND):
        raise ParameterError(
            f"--time-budget applies to the automatic starts only (no --starts, no --start-kind "
            f"but branches); the starts of {asked} all run",
            name="time_budget",
            value=budget,
        )


def run(args: argparse.Namespace) -> int:
    """Run ``youbot-opt ikpath``; returns the exit code (0 ok, 1 failed, 2 unreachable)."""
    if not (math.isfinite(args.segment_time) and args.segment_time > 0):
        raise ParameterError(
            f"--segment-time must be a positive duration in [s], got {args.segment_time}",
            name="segment_time",
            value=args.segment_time,
        )
    if args.segment_knots is not None and not args.timed:
        raise ParameterError("--segment-knots applies with --timed only", name="segment_knots")
    if not args.timed:
        refine_flags = (
            ("--no-refine", not args.refine),
            ("--error-tol", args.error_tol != 1e-3),
            ("--max-rounds", args.max_rounds != 8),
            ("--max-knots", args.max_knots != 1000),
            ("--refine-time", args.refine_time is not None),
            ("--no-refine-fallback", not args.refine_fallback),
        )
        for flag, given in refine_flags:
            if given:
                raise ParameterError(f"{flag} applies with --timed only", name="timed")
    _check_time_budget(args)
    check_ikpath_size(
        n_starts=64 if args.starts is None else args.starts,
        n_links=len(args.lengths or ()),
        n_targets=len(args.target or ()),
    )
    return _run_3d(args) if _spatial_mode(args) else _run_planar(args)
