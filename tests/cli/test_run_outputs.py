"""The run folder of `youbot-opt solve` with its figures drawn in other processes (#27 item 2).

The figures are drawn in forked processes while the result and the replay are
written (:class:`youbot_opt.cli.drawing.Drawing`): the folder must still hold
every listed file when the command returns, a figure that cannot be written must
fail the command with the one-line error, ``--no-figures`` writes none, and a
reused ``--out`` keeps no figure of an earlier run that ``summary.json`` does not
list.
"""

from __future__ import annotations

import errno
import json
import logging
import os
import stat
import time
import warnings
from pathlib import Path

import pytest

from youbot_opt.cli import main
from youbot_opt.cli.drawing import Drawing, DrawingAhead, FigureJob
from youbot_opt.cli.output import remove_stale_figures
from youbot_opt.exceptions import ParameterError, YoubotOptWarning

QUICK = ["--knots", "15"]
SOLVE_FILES = [
    "result.npz", "trajectory.png", "arm.png", "refinement.png", "convergence.png",
    "replay.html", "summary.json",
]  # fmt: skip


@pytest.fixture(autouse=True)
def _in_tmp(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)


def _summary(folder: Path) -> dict[str, object]:
    return json.loads((folder / "summary.json").read_text())


def test_solve_folder_is_complete_when_the_command_returns(tmp_path: Path) -> None:
    """Every listed file exists, is a regular file of mode 644 (umask 022), no temporary left."""
    old = os.umask(0o022)
    try:
        assert main(["solve", *QUICK, "--quiet", "--out", "run"]) == 0
    finally:
        os.umask(old)
    folder = tmp_path / "run"
    assert _summary(folder)["files"] == SOLVE_FILES
    for name in SOLVE_FILES:
        info = (folder / name).stat()
        assert stat.S_ISREG(info.st_mode) and info.st_size > 0
        assert stat.S_IMODE(info.st_mode) == 0o644, name
    assert sorted(p.name for p in folder.iterdir()) == sorted(SOLVE_FILES)  # no .tmp-*


def test_solve_no_figures_writes_no_png(tmp_path: Path) -> None:
    """`--no-figures`: the result, the replay and the summary only."""
    assert main(["solve", *QUICK, "--quiet", "--no-figures", "--out", "run"]) == 0
    folder = tmp_path / "run"
    assert _summary(folder)["files"] == ["result.npz", "replay.html", "summary.json"]
    assert not list(folder.glob("*.png"))


def test_main_no_figures_after_a_run_with_them(tmp_path: Path) -> None:
    """`youbot-opt main --no-figures` into a folder of an earlier main run: no png is left."""
    assert main(["main", "--out", "run"]) == 0
    folder = tmp_path / "run"
    assert _summary(folder)["files"] == SOLVE_FILES
    assert main(["main", "--no-figures", "--out", "run"]) == 0
    assert _summary(folder)["files"] == ["result.npz", "replay.html", "summary.json"]
    assert not list(folder.glob("*.png"))
    assert sorted(p.name for p in folder.iterdir()) == ["replay.html", "result.npz", "summary.json"]


def test_a_figure_that_cannot_be_written_fails_with_one_line(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    """A full disk while a figure is saved (in the drawing process): exit 2, one line naming it."""
    import youbot_opt.viz.plots.trajopt as plots

    def full(*args: object, **kwargs: object) -> None:
        raise OSError(errno.ENOSPC, "No space left on device", str(tmp_path / "run" / "arm.png"))

    monkeypatch.setattr(plots, "plot_arm_2d", full)  # inherited by the forked process
    assert main(["solve", *QUICK, "--quiet", "--out", "run"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("youbot-opt: error: cannot use ")
    assert "arm.png" in err[0] and "free space" in err[0]
    assert not (tmp_path / "run" / "summary.json").exists()  # the run did not complete


def test_reused_folder_keeps_no_stale_figure(tmp_path: Path) -> None:
    """A rerun into the same --out removes our figures it did not write, nothing else."""
    folder = tmp_path / "run"
    folder.mkdir()
    for name in ("refinement_2.png", "multistart.png", "pareto.png", "notes.png", "arm.svg"):
        (folder / name).write_bytes(b"earlier run")
    assert main(["solve", *QUICK, "--quiet", "--out", "run"]) == 0
    assert _summary(folder)["files"] == SOLVE_FILES
    pngs = sorted(p.name for p in folder.glob("*.png"))
    listed = sorted(str(n) for n in SOLVE_FILES if n.endswith(".png"))
    assert pngs == sorted([*listed, "notes.png"])  # not ours: left alone
    assert (folder / "arm.svg").exists()
    assert main(["solve", *QUICK, "--quiet", "--no-refine", "--out", "run"]) == 0
    assert not (folder / "refinement.png").exists()  # the refined run's, not this one's
    assert sorted(p.name for p in folder.glob("*.png")) == [
        "arm.png", "convergence.png", "notes.png", "trajectory.png",
    ]  # fmt: skip


def test_remove_stale_figures_leaves_links_and_others(tmp_path: Path) -> None:
    """Only regular files with our figure names and not written now go."""
    for name in ("refinement_1.png", "refinement_7.png", "refinement_x.png", "tool.png"):
        (tmp_path / name).write_bytes(b"x")
    (tmp_path / "clearance.png").symlink_to(tmp_path / "tool.png")
    removed = remove_stale_figures(tmp_path, [tmp_path / "refinement_1.png"])
    assert sorted(p.name for p in removed) == ["refinement_7.png", "tool.png"]
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "clearance.png", "refinement_1.png", "refinement_x.png",
    ]  # fmt: skip


# ------------------------------------------------------------- Drawing itself
def _figure(label: str) -> object:
    from matplotlib.figure import Figure

    fig = Figure(figsize=(4, 3))
    fig.add_subplot().set_title(label)
    return fig


def _raises(message: str) -> object:
    raise ValueError(message)


def _skipped() -> object:
    raise ParameterError("nothing to draw", name="result")


def _warns(label: str) -> object:
    warnings.warn(f"careful with {label}", YoubotOptWarning, stacklevel=1)
    return _figure(label)


def _sleeps() -> object:
    time.sleep(60)
    return _figure("late")


def test_drawing_returns_paths_in_job_order(tmp_path: Path) -> None:
    """Paths in job order across processes; a skipped figure is None and logged."""
    jobs = [FigureJob(f"f{k}.png", _figure, (f"figure {k}",)) for k in range(3)]
    jobs.insert(1, FigureJob("skip.png", _skipped))
    drawing = Drawing(tmp_path, jobs, processes=2)
    try:
        paths = drawing.wait()
    finally:
        drawing.stop()
    assert paths == [tmp_path / "f0.png", None, tmp_path / "f1.png", tmp_path / "f2.png"]
    assert all(p.stat().st_size > 0 for p in paths if p is not None)


def test_drawing_gives_warnings_and_skip_lines_here(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """A child's warnings are warned again here; its "not drawn" line logged here."""
    drawing = Drawing(tmp_path, [FigureJob("w.png", _warns, ("w",)), FigureJob("s.png", _skipped)])
    with caplog.at_level(logging.WARNING), pytest.warns(YoubotOptWarning, match="careful with w"):
        assert drawing.wait() == [tmp_path / "w.png", None]
    assert "figure s.png not drawn: nothing to draw" in caplog.text


def test_drawing_raises_the_childs_error(tmp_path: Path) -> None:
    """An error in a drawing process is raised by wait(), with the child's traceback as a note."""
    drawing = Drawing(
        tmp_path, [FigureJob("a.png", _figure, ("a",)), FigureJob("b.png", _raises, ("bad",))]
    )
    try:
        with pytest.raises(ValueError, match="bad") as caught:
            drawing.wait()
    finally:
        drawing.stop()
    assert any("in the figure process" in note for note in caught.value.__notes__)
    required = FigureJob("c.png", _skipped, optional=False)
    with pytest.raises(ParameterError, match="nothing to draw"):
        Drawing(tmp_path, [required]).wait()


def test_drawing_stop_leaves_no_process(tmp_path: Path) -> None:
    """stop() (the caller's finally on an error or Ctrl-C) terminates a drawing process."""
    drawing = Drawing(tmp_path, [FigureJob("late.png", _sleeps)], processes=1)
    children = [proc for proc, _ in drawing._children]
    assert children and all(p.is_alive() for p in children)
    drawing.stop()
    assert not any(p.is_alive() for p in children)
    assert not (tmp_path / "late.png").exists()


def test_a_reused_study_folder_keeps_no_stale_refinement_figure(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A study rerun into the folder of one that drew per-plan figures: those are gone."""
    folder = tmp_path / "run"
    folder.mkdir()
    for name in ("refinement_1.png", "refinement_2.png", "bound_scaling.png"):
        (folder / name).write_bytes(b"earlier run")
    argv = ["pareto", "--betas", "0.5", "--knots", "15", "--workers", "0", "--quiet", "--json"]
    assert main([*argv, "--out", str(folder)]) == 0
    summary = json.loads(capsys.readouterr().out)
    pngs = sorted(p.name for p in folder.glob("*.png"))
    assert pngs == sorted(f for f in summary["files"] if f.endswith(".png"))
    assert "refinement.png" in pngs and "refinement_1.png" not in pngs


@pytest.mark.parametrize("command", ["multistart", "pareto", "bounds"])
def test_study_commands_take_no_figures(command: str) -> None:
    """The study sweeps take `--no-figures` as solve and main do."""
    from youbot_opt.cli.parser import parse

    assert parse([command, "--no-figures"]).no_figures is True
    assert parse([command]).no_figures is False


def test_multistart_no_figures_after_a_run_with_them(tmp_path: Path) -> None:
    """A reused `multistart --out` rerun with `--no-figures`: no png of ours left, others kept."""
    argv = ["multistart", "--starts", "2", *QUICK, "--workers", "0", "--quiet", "--out", "ms"]
    assert main(argv) == 0
    folder = tmp_path / "ms"
    pngs = ["refinement.png", "multistart.png", "convergence.png", "trajectory.png"]
    assert [f for f in _summary(folder)["files"] if str(f).endswith(".png")] == pngs  # type: ignore[attr-defined]
    (folder / "notes.png").write_bytes(b"not ours")
    before = sorted(p.name for p in folder.iterdir())
    assert main([*argv, "--no-figures"]) == 0
    files = _summary(folder)["files"]
    assert not [f for f in files if str(f).endswith(".png")]  # type: ignore[attr-defined]
    assert sorted(p.name for p in folder.iterdir()) == sorted(set(before) - set(pngs))
    assert (folder / "notes.png").read_bytes() == b"not ours"


def _sleeps_noting(note: str) -> object:
    Path(note).write_text(str(os.getpid()))
    time.sleep(60)
    return _figure("late")


def test_drawing_stop_ends_the_processes_the_first_one_forked(tmp_path: Path) -> None:
    """stop() with two drawing processes: the one the first forked ends too (no orphan)."""
    notes = [tmp_path / f"pid{k}" for k in range(2)]
    jobs = [FigureJob(f"late{k}.png", _sleeps_noting, (str(n),)) for k, n in enumerate(notes)]
    drawing = Drawing(tmp_path, jobs, processes=2)
    deadline = time.monotonic() + 30
    while not all(n.exists() and n.read_text() for n in notes) and time.monotonic() < deadline:
        time.sleep(0.05)
    pids = {int(n.read_text()) for n in notes}
    assert len(pids) == 2 and os.getpid() not in pids  # two processes, neither this one
    drawing.stop()
    for pid in pids:
        with pytest.raises(ProcessLookupError):
            os.kill(pid, 0)
    assert not list(tmp_path.glob("late*.png"))


def test_drawing_spreads_the_jobs_over_its_processes(tmp_path: Path) -> None:
    """Every job is drawn once, outside this process; an error of any job is raised here."""
    seen: list[str] = []

    def noting(label: str) -> object:
        fig = _figure(label)
        seen.append(label)  # in the drawing process's copy only
        return fig

    jobs = [FigureJob(f"f{k}.png", noting, (f"figure {k}",)) for k in range(5)]
    drawing = Drawing(tmp_path, jobs, processes=2)
    try:
        paths = drawing.wait()
    finally:
        drawing.stop()
    assert paths == [tmp_path / f"f{k}.png" for k in range(5)] and not seen
    assert all(p.stat().st_size > 0 for p in paths if p is not None)
    failing = [FigureJob(f"g{k}.png", _figure, (f"g{k}",)) for k in range(4)]
    failing.insert(3, FigureJob("bad.png", _raises, ("bad figure",)))
    drawing = Drawing(tmp_path, failing, processes=2)
    try:
        with pytest.raises(ValueError, match="bad figure"):
            drawing.wait()
    finally:
        drawing.stop()


# ------------------------------------------------------------- DrawingAhead
class _Shared:
    """An object a run holds before its results exist (its robot); warmed ahead."""

    warmed_by: int | None = None


def _writes_note(folder: Path, shared: _Shared) -> Path:
    """A job that writes its own file (as the replay page does): who warmed ``shared``."""
    path = folder / "note.txt"
    path.write_text(f"{shared.warmed_by} {os.getpid()}")
    return path


def _writes_nothing() -> None:
    return None


def test_drawing_ahead_warms_the_shared_objects_and_draws_the_jobs_handed_later(
    tmp_path: Path,
) -> None:
    """The process forked ahead warms ``shared`` and gets it by reference with the jobs.

    The job sees the warmed object (the warming process's pid, not this one's,
    where ``warmed_by`` stays None); a job that writes its own file returns its
    path, one that writes nothing None; figures come back in job order.
    """
    shared = _Shared()
    ahead = DrawingAhead([shared], ["matplotlib.figure"], warm=lambda: _warm(shared))
    jobs = [
        FigureJob("note.txt", _writes_note, (tmp_path, shared), optional=False),
        FigureJob("f0.png", _figure, ("f0",)),
        FigureJob("none.html", _writes_nothing),
        FigureJob("f1.png", _figure, ("f1",)),
    ]
    drawing = ahead.draw(tmp_path, jobs)
    try:
        paths = drawing.wait()
    finally:
        drawing.stop()
        ahead.stop()
    assert paths == [tmp_path / "note.txt", tmp_path / "f0.png", None, tmp_path / "f1.png"]
    warmed_by, drawn_by = (int(x) for x in (tmp_path / "note.txt").read_text().split())
    assert shared.warmed_by is None and os.getpid() not in (warmed_by, drawn_by)
    assert (tmp_path / "f1.png").stat().st_size > 0


def _warm(shared: _Shared) -> None:
    shared.warmed_by = os.getpid()


@pytest.mark.parametrize("n_jobs", [1, 3])
def test_drawing_ahead_with_fewer_or_more_jobs_than_processes(tmp_path: Path, n_jobs: int) -> None:
    """One job on two processes does not wait for the idle one; three share two processes."""
    ahead = DrawingAhead([], processes=2)
    jobs = [FigureJob(f"f{k}.png", _figure, (f"f{k}",)) for k in range(n_jobs)]
    drawing = ahead.draw(tmp_path, jobs)
    try:
        assert drawing.wait() == [tmp_path / f"f{k}.png" for k in range(n_jobs)]
    finally:
        drawing.stop()


def test_drawing_ahead_draws_jobs_that_do_not_pickle_by_forking_then(tmp_path: Path) -> None:
    """A local function as a job cannot be sent: the figures are drawn as a plain Drawing."""
    ahead = DrawingAhead([])
    process = ahead._proc

    def local(label: str) -> object:
        return _figure(label)

    drawing = ahead.draw(tmp_path, [FigureJob("local.png", local, ("local",))])
    try:
        assert drawing.wait() == [tmp_path / "local.png"]
    finally:
        drawing.stop()
    assert process is not None and not process.is_alive()  # the one ahead was ended


def test_drawing_ahead_stopped_without_jobs_leaves_no_process() -> None:
    """A run that ends before its outputs (an error) stops the process ahead: none is left."""
    ahead = DrawingAhead([], ["matplotlib.figure"])
    process = ahead._proc
    assert process is not None and process.is_alive()
    ahead.stop()
    assert not process.is_alive() and process.exitcode == 0
    ahead.stop()  # twice: nothing to do
