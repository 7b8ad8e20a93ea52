"""The output folder of a CLI run: where summaries, figures, replays and results go.

One folder per run: ``--out DIR`` (re-running a sweep there resumes it), or a
new ``youbot_opt_runs/<command>-<UTC date>-<UTC time>``. It holds what the
command has of ``summary.json``, ``result.npz`` (or ``results/``), ``*.png``
and ``replay.html``; sweeps report progress on stderr through
:class:`ProgressLine`.

>>> folder = run_folder("solve", out=None)  # doctest: +SKIP
"""

from __future__ import annotations

import datetime as _dt
import json
import logging
import math
import re
import sys
import time
import warnings
from collections.abc import Callable, Iterable, Mapping, Sequence
from pathlib import Path
from typing import IO, TYPE_CHECKING, TextIO

from youbot_opt._files import atomic_write_text, json_ready
from youbot_opt._typing import JSONDict
from youbot_opt.exceptions import ParameterError, YoubotOptWarning

if TYPE_CHECKING:  # matplotlib, the plots and the replay load when a run draws (issue 27)
    from matplotlib.figure import Figure

    from youbot_opt.cli.drawing import DrawingAhead, FigureJob
    from youbot_opt.trajopt.multistart import MultistartResult
    from youbot_opt.trajopt.problem import TrajOptProblem
    from youbot_opt.trajopt.refine import Refinement
    from youbot_opt.trajopt.result import TrajOptResult

__all__ = [
    "DEFAULT_ROOT",
    "REPLAY",
    "STARTS_FILE",
    "ProgressLine",
    "draw_figure",
    "open_folder",
    "optima_replay",
    "print_json",
    "print_outputs",
    "remove_stale_figures",
    "replay_html",
    "report_outputs",
    "run_folder",
    "solve_drawing_ahead",
    "solve_figures",
    "write_solve_outputs",
    "write_summary",
]

_log = logging.getLogger(__name__)

DEFAULT_ROOT = Path("youbot_opt_runs")
"""Parent of the per-run folders made when no ``--out`` is given (relative to the cwd)."""

REPLAY = "replay.html"
"""The replay page's file name in a run folder."""

STARTS_FILE = "starts.jsonl"
"""A multistart run's per-start rows, one JSON object a line (``summary.json``'s ``starts_file``).

Written by ``youbot-opt ikpath`` and ``youbot-opt multistart`` (JSON Lines).
"""


def run_folder(
    command: str, out: str | Path | None = None, *, root: str | Path | None = None
) -> Path:
    """Create (if needed) and return the output folder of one run.

    Parameters
    ----------
    command
        Sub-command name, used in the default folder name (e.g. ``"solve"``).
    out
        Folder chosen by the user (``--out``); created with its parents and
        reused if it exists (sweeps resume from it).
    root
        Parent of default folders; ``youbot_opt_runs`` in the cwd when omitted.

    Returns
    -------
    Path
        The folder, which exists on return.
    """
    if out is not None:
        folder = Path(out)
        if folder.exists() and not folder.is_dir():
            raise NotADirectoryError(f"--out {folder}: exists and is not a directory")
        folder.mkdir(parents=True, exist_ok=True)
        return folder
    parent = Path(root) if root is not None else DEFAULT_ROOT
    stamp = _dt.datetime.now(_dt.UTC).strftime("%Y%m%d-%H%M%S")
    base = parent / f"{command}-{stamp}"
    for n in range(1, 1000):
        folder = base if n == 1 else base.with_name(f"{base.name}-{n}")
        try:
            folder.mkdir(parents=True, exist_ok=False)
        except FileExistsError:
            continue
        return folder
    raise FileExistsError(f"could not create a new run folder next to {base}")  # pragma: no cover


def write_summary(
    folder: str | Path, summary: Mapping[str, object], name: str = "summary.json"
) -> Path:
    """Write ``summary`` as indented JSON to ``folder/name`` atomically; return the path.

    A sweep's per-start rows are not in it: they go to their own JSON Lines file
    (:func:`~youbot_opt._files.write_json_lines`), so a summary stays small.
    """
    path = Path(folder) / name
    atomic_write_text(path, json.dumps(json_ready(summary), indent=2) + "\n")
    return path


def print_json(doc: Mapping[str, object], stream: IO[str] | None = None) -> None:
    """Print ``doc`` as indented JSON (``--json``) to stdout (or ``stream``)."""
    print(json.dumps(json_ready(doc), indent=2), file=sys.stdout if stream is None else stream)


OWN_FIGURES = re.compile(
    r"(trajectory|arm|convergence|multistart|refinement(_[1-9][0-9]*)?|clearance|tool"
    r"|pareto|bound_scaling"
    r"|ikpath_(workspace|arm|convergence|minima|legs|path3d)"
    r"|repro_(base_case|pareto|refinement))\.png"
)
"""Names of the figures our commands write (``solve``, ``main``, the studies, ``ikpath``,
``reproduce-study1``)."""


def remove_stale_figures(folder: Path, written: Iterable[Path]) -> list[Path]:
    """Remove the figures of an earlier run in a reused ``folder``; return what was removed.

    Only regular files named as our commands name their figures
    (:data:`OWN_FIGURES`, e.g. ``refinement_3.png`` of a study that refined
    three plans) and not among ``written`` are removed: the folder then holds
    the figures its ``summary.json`` lists. Any other file is left alone.
    """
    keep = {Path(f).name for f in written}
    removed = []
    for path in sorted(folder.iterdir()):
        if OWN_FIGURES.fullmatch(path.name) and path.name not in keep and path.is_file():
            if not path.is_symlink():
                path.unlink(missing_ok=True)
                removed.append(path)
    return removed


def print_outputs(
    folder: str | Path, files: Iterable[str | Path] = (), stream: IO[str] | None = None
) -> None:
    """Print the run folder and the files written in it.

    Goes to stderr by default, so that ``--json`` keeps stdout one JSON object.
    """
    out = sys.stderr if stream is None else stream
    folder = Path(folder)
    print(f"output folder: {folder.resolve()}", file=out)
    for f in files:
        p = Path(f)
        try:
            shown = p.relative_to(folder)
        except ValueError:
            shown = p
        print(f"  {shown}", file=out)


class ProgressLine:
    """Progress line of a sweep on stderr: rewritten in place on a terminal, else one per item.

    Parameters
    ----------
    label : str
        Shown first (the command, e.g. ``"multistart"``).
    quiet : bool
        Print nothing.
    stream : text stream, optional
        Where to print (default: stderr).
    """

    def __init__(self, label: str, quiet: bool, stream: TextIO | None = None) -> None:
        self.label = label
        self.quiet = quiet
        self.stream = stream or sys.stderr
        self.tty = self.stream.isatty()
        self.tic = time.perf_counter()

    def __call__(self, done: int, total: int, last: object) -> None:
        """Report item ``done`` of ``total``; ``last`` is the sweep's item (status, objective)."""
        if self.quiet:
            return
        f = getattr(last, "objective", math.nan)
        what = getattr(last, "key", None) or f"beta={getattr(last, 'beta', '?')}"
        line = (
            f"{self.label}: {done}/{total} [{time.perf_counter() - self.tic:6.1f} s] "
            f"{what}: {getattr(last, 'status', '?')} f={f:.6g}"
        )
        end = "" if self.tty else "\n"
        self.stream.write(("\r" if self.tty else "") + line + end)
        self.stream.flush()

    def close(self) -> None:
        """End the in-place line on a terminal."""
        if self.tty and not self.quiet:
            self.stream.write("\n")


def open_folder(command: str, out: str | Path | None) -> Path:
    """Create the run's output folder (:func:`run_folder`).

    Raises
    ------
    ParameterError
        If ``out`` exists and is not a folder, or cannot be created.
    """
    try:
        return run_folder(command, out)
    except OSError as exc:
        raise ParameterError(
            f"cannot use the output folder (--out): {exc}", name="out", value=out
        ) from exc


def draw_figure(
    folder: Path, name: str, make: Callable[..., Figure], *args: object, **kwargs: object
) -> Path | None:
    """Draw and save one figure; a figure that cannot be drawn is logged and skipped."""
    from youbot_opt.cli.drawing import FigureJob, draw_job

    path, skipped = draw_job(folder, FigureJob(name, make, args, kwargs))
    if skipped is not None:
        _log.warning("%s", skipped)
    return path


def solve_figures(
    result: TrajOptResult,
    multistart: MultistartResult | None = None,
    refinement: Refinement | None = None,
) -> list[FigureJob]:
    """Return the figures of a solve (:func:`write_solve_outputs`), in the order they are listed."""
    from youbot_opt.cli.drawing import FigureJob

    plots = "youbot_opt.viz.plots.trajopt:"  # matplotlib loads where the figures are drawn
    jobs = []
    if result.trajectory is not None:
        jobs.append(FigureJob("trajectory.png", plots + "plot_trajectory", (result,)))
        jobs.append(FigureJob("arm.png", plots + "plot_arm_2d", (None, result)))
    if refinement is not None:
        jobs.append(FigureJob("refinement.png", plots + "plot_refinement", (refinement,)))
    runs: MultistartResult | Refinement | list[TrajOptResult] = [result]
    if multistart is not None:  # every start's solve
        runs = multistart
    elif refinement is not None:  # every round's solve
        runs = refinement
    jobs.append(FigureJob("convergence.png", plots + "plot_convergence", (runs,)))
    if multistart is not None:
        jobs.append(
            FigureJob(
                "multistart.png", "youbot_opt.viz.plots.studies:plot_multistart", (multistart,)
            )
        )
    return jobs


def write_solve_outputs(
    folder: Path,
    result: TrajOptResult,
    summary: JSONDict,
    multistart: MultistartResult | None = None,
    *,
    refinement: Refinement | None = None,
    extra_figures: Sequence[FigureJob] = (),
    figures: bool = True,
    ahead: DrawingAhead | None = None,
) -> list[Path]:
    """Write a solve's result, figures, replay and summary into ``folder``.

    The figures and the replay page are drawn in forked processes
    (:class:`~youbot_opt.cli.drawing.Drawing`; the replay first: it reads the
    meshes) while the result is written here; every file exists when this
    returns, and a figure of an earlier run in a reused folder that this run
    does not write is removed (:func:`remove_stale_figures`).

    Parameters
    ----------
    folder : Path
        The run's output folder.
    result : TrajOptResult
        The solution (the best start's after a multistart).
    summary : dict
        The JSON summary; ``"output_folder"`` and ``"files"`` are added.
    multistart : MultistartResult, optional
        The multistart the result comes from: adds its histogram, and the
        replay shows its distinct optima side by side.
    refinement : Refinement, optional
        The record of the refinement that made ``result``: saved with it, drawn
        (``refinement.png``) and summarised (``"refinement"``).
    extra_figures : sequence of FigureJob
        More figures (``clearance.png``, ``tool.png``), listed after the replay.
    figures : bool
        False (``--no-figures``): no figure at all, only the result, the
        replay and the summary.
    ahead : DrawingAhead, optional
        Drawing processes started before the solve (:func:`solve_drawing_ahead`),
        which draw the figures and the replay; by default forked here.

    Returns
    -------
    list of Path
        The files written, ``summary.json`` last.
    """
    from youbot_opt.cli.drawing import Drawing, FigureJob
    from youbot_opt.trajopt.io import save_result

    jobs = [*solve_figures(result, multistart, refinement), *extra_figures] if figures else []
    here = "youbot_opt.cli.output:"
    if multistart is not None:
        jobs.insert(
            0, FigureJob(REPLAY, here + "optima_replay", (folder, multistart), optional=False)
        )
    elif result.trajectory is not None:  # first: the longest job (meshes read, meshcat loaded)
        labels = [f"f = {result.objective:.5g}"]
        jobs.insert(
            0, FigureJob(REPLAY, here + "replay_html", (folder, [result], labels), optional=False)
        )
    drawing = Drawing(folder, jobs) if ahead is None else ahead.draw(folder, jobs)
    try:
        npz = save_result(result, folder / "result.npz", refinement=refinement)
        drawn = dict(zip([j.name for j in jobs], drawing.wait(), strict=True))
    finally:
        drawing.stop()
    replay = drawn.pop(REPLAY, None)
    if refinement is not None:
        summary["refinement"] = refinement.summary()
    extra = {j.name for j in extra_figures}
    files = [npz, *(p for n, p in drawn.items() if n not in extra), replay]
    files += [p for n, p in drawn.items() if n in extra]
    written = [f for f in files if f is not None]
    remove_stale_figures(folder, written)
    summary["output_folder"] = str(folder.resolve())
    summary["files"] = [f.name for f in written] + ["summary.json"]
    written.append(write_summary(folder, summary))
    return written


def solve_drawing_ahead(problem: TrajOptProblem, *, figures: bool) -> DrawingAhead:
    """Start the drawing processes of a solve's outputs before it solves (:class:`DrawingAhead`).

    They import the plots (unless ``figures`` is False) and the replay's
    modules, and read the problem's robot's meshes, on another core while the
    run computes; the problem and its robot are sent to them by reference.
    """
    robot = problem.robot
    from youbot_opt.cli.drawing import DrawingAhead

    modules = ["youbot_opt.viz.meshcat.replay", "youbot_opt.viz.meshcat.results"]
    if figures:
        modules.insert(0, "youbot_opt.viz.plots.trajopt")
    return DrawingAhead([robot, problem], modules, warm=lambda: robot.visual_model)


def optima_replay(
    folder: Path,
    multistart: MultistartResult,
    obj_tol: float = 1e-5,
    dist_tol: float = 1e-2,
    limit: int = 6,
) -> Path | None:
    """Write ``replay.html`` with up to ``limit`` distinct optima of a multistart, side by side."""
    optima = multistart.distinct_optima(obj_tol, dist_tol)[:limit]
    labels = [
        f"optimum {i + 1}: f = {o.objective:.5g}, {o.count} of {o.n_starts} starts"
        for i, o in enumerate(optima)
    ]
    return replay_html(folder, [o.best.result for o in optima], labels)


def replay_html(
    folder: Path, results: Sequence[TrajOptResult | None], labels: Sequence[str]
) -> Path | None:
    """Write ``replay.html``: the results side by side (one: the plain replay).

    A motion too long to replay (over ``MAX_REPLAY_FRAMES`` frames) gets a
    warning and no replay; the run's other files are written.
    """
    from youbot_opt.viz.meshcat.replay import export_html
    from youbot_opt.viz.meshcat.results import export_results_html

    kept = [(r, lab) for r, lab in zip(results, labels, strict=True) if r is not None]
    if not kept or any(r.trajectory is None for r, _ in kept):
        return None
    if len(kept) == 1:
        traj = kept[0][0].trajectory
        assert traj is not None  # checked above
        problem = kept[0][0].problem
        scene = None if problem.clearance is None else problem.clearance.scene
        return replay_or_warn(
            lambda: export_html(problem.robot, traj.t, traj.q, folder / REPLAY, obstacles=scene)
        )
    return replay_or_warn(
        lambda: export_results_html(
            [r for r, _ in kept], folder / REPLAY, labels=[lab for _, lab in kept]
        )
    )


def replay_or_warn(write: Callable[[], Path]) -> Path | None:
    """Return ``write()``, the replay page; a motion too long to replay warns and gives None.

    The limit is ``youbot_opt.viz.meshcat.scene.MAX_REPLAY_FRAMES``; any other
    error propagates.
    """
    try:
        return write()
    except ParameterError as exc:
        if exc.name != "replay_frames":
            raise
        warnings.warn(f"replay.html not written: {exc}", YoubotOptWarning, stacklevel=2)
        return None


def report_outputs(folder: Path, files: list[Path], as_json: bool) -> None:
    """Print the output folder and its files: to stdout, or to stderr under ``--json``."""
    print_outputs(folder, files, stream=sys.stderr if as_json else sys.stdout)
