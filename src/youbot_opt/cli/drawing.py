"""A run's figures drawn in forked processes while the run writes its other files (#27).

:class:`Drawing` forks (Linux) a process that imports the plots and forks the
others (up to :data:`DRAWING_PROCESSES`); they inherit the results in memory and
draw there, each taking the next figure when done, while the caller writes the rest;
:meth:`Drawing.wait` returns the paths in job order once every process ended,
raising a job's error (the child's traceback a note on it) and giving its
warnings and "not drawn" lines here. Without ``fork``: drawn here on wait.
:func:`save_figure` writes one figure atomically. Why: docs/design.md.

>>> drawing = Drawing(folder, [FigureJob("arm.png", plot_arm_2d, (None, result))])  # doctest: +SKIP
"""

from __future__ import annotations

import contextlib
import importlib
import io
import logging
import multiprocessing
import os
import pickle
import signal
import threading
import traceback
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from multiprocessing.connection import Connection
from pathlib import Path
from typing import TYPE_CHECKING

from youbot_opt._files import atomic_writer
from youbot_opt.exceptions import ParameterError
from youbot_opt.sweeps.forked import can_fork, watch_parent

if TYPE_CHECKING:
    from multiprocessing.process import BaseProcess

    from matplotlib.figure import Figure

__all__ = ["FigureJob", "Drawing", "DrawingAhead", "draw_job", "save_figure", "DRAWING_PROCESSES"]

_log = logging.getLogger("youbot_opt.cli.output")  # the "not drawn" lines, as before

DRAWING_PROCESSES = 2
"""The most processes that draw one run's figures (the 2-core target machine: one per core)."""


@dataclass(frozen=True)
class FigureJob:
    """One figure of a run: ``make(*args, **kwargs)`` saved as ``folder/name``.

    ``make`` is the function, or its ``"module:name"`` (imported where the
    figure is drawn: the caller need not load matplotlib). It returns the
    figure, or writes its file itself and returns its path (the replay page),
    or None when it wrote nothing (its warning says why).

    ``optional``: a :class:`~youbot_opt.exceptions.ParameterError` from ``make``
    (e.g. no converged run to draw) is logged and the figure skipped; otherwise
    it propagates like any other error. ``dpi``: the resolution it is saved at.
    """

    name: str
    make: Callable[..., Figure | Path | None] | str
    args: tuple[object, ...] = ()
    kwargs: Mapping[str, object] = field(default_factory=dict)
    optional: bool = True
    dpi: int = 120


def draw_job(folder: Path, job: FigureJob) -> tuple[Path | None, str | None]:
    """Draw and save one figure here; return its path, or None and why it was skipped."""
    make = job.make
    if isinstance(make, str):
        module, _, name = make.partition(":")
        make = getattr(importlib.import_module(module), name)
    try:
        made = make(*job.args, **dict(job.kwargs))
    except ParameterError as exc:
        if not job.optional:
            raise
        return None, f"figure {job.name} not drawn: {exc}"
    if made is None or isinstance(made, Path):  # it wrote its own file (the replay page)
        return made, None
    return save_figure(made, folder, job.name, dpi=job.dpi), None


def save_figure(fig: Figure, folder: str | Path, name: str, *, dpi: int = 120) -> Path:
    """Save a matplotlib figure as ``folder/name`` (PNG unless a suffix is given); close it.

    The file is written atomically (a temporary file renamed over it): a run
    stopped while drawing leaves no half-written figure. A figure with a layout
    engine (the package's figures are constrained) is saved as laid out:
    cropping it to its tight bounding box as well measured half of the time a
    solve's figures took (issue 27). A figure without one is cropped. A figure
    made without pyplot is drawn on Agg directly, and pyplot is imported only to
    close a figure that pyplot manages.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    path = Path(folder) / (name if Path(name).suffix else f"{name}.png")
    if fig.canvas.manager is None:  # not a pyplot figure: draw straight on Agg
        FigureCanvasAgg(fig)
    tight = None if fig.get_layout_engine() is not None else "tight"
    with atomic_writer(path) as handle:
        fig.savefig(handle, format=path.suffix[1:], dpi=dpi, bbox_inches=tight)
    if fig.canvas.manager is not None:
        import matplotlib.pyplot as plt

        plt.close(fig)
    return path


_Drawn = tuple[int, Path | None, str | None, list[warnings.WarningMessage]]


def _draw_jobs(folder: Path, jobs: Sequence[tuple[int, FigureJob]]) -> list[_Drawn]:
    return [_draw_one(folder, i, job) for i, job in jobs]


def _draw_one(folder: Path, i: int, job: FigureJob) -> _Drawn:
    with warnings.catch_warnings(record=True) as caught:
        path, skipped = draw_job(folder, job)
    return i, path, skipped, list(caught)


class _Queue:
    """The jobs' shared queue: the next job to take, and the job each process draws."""

    def __init__(self, ctx: multiprocessing.context.BaseContext, processes: int) -> None:
        self.next = ctx.Value("i", 0)  # the next job to take (under its lock)
        self.current = ctx.Array("i", [-1] * processes, lock=False)  # each process's job

    def take(self, k: int) -> int:
        """Take the next job for process ``k``; return its index."""
        with self.next.get_lock():
            i = self.current[k] = self.next.value
            self.next.value += 1
        return int(i)


def _child(
    conn: Connection,
    folder: Path,
    jobs: list[FigureJob],
    queue: _Queue,
    k: int,
    parent: int,
) -> None:
    """Body of drawing process ``k``: draw the jobs it takes from ``queue`` until none is left.

    Sends ``("ok", drawn)``, or ``("error", (i, exc))`` at job ``i``'s error.
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the parent's to handle
    threading.Thread(target=watch_parent, args=(parent,), daemon=True).start()
    drawn: list[_Drawn] = []
    try:
        try:
            while (i := queue.take(k)) < len(jobs):
                drawn.append(_draw_one(folder, i, jobs[i]))
            message: tuple[str, object] = ("ok", drawn)
        except BaseException as exc:  # noqa: BLE001 - every error goes back to the parent
            exc.add_note("in the figure process:\n" + traceback.format_exc().rstrip())
            message = ("error", (queue.current[k], exc))
        try:
            conn.send(message)
        except Exception as exc:  # noqa: BLE001 - what does not pickle goes as text
            what = message[1][1] if message[0] == "error" else exc  # type: ignore[index]
            error = RuntimeError(f"{type(what).__name__}: {what}")
            conn.send(("error", (queue.current[k], error)))
    finally:
        conn.close()


def _first_child(
    sends: list[Connection], folder: Path, jobs: list[FigureJob], queue: _Queue, parent: int
) -> None:
    """Body of the first drawing process: import the plots, fork the others, draw with them.

    The figures' modules (matplotlib: about 0.6 s) are imported here, once, while
    the caller writes its other files; the processes forked here share them.
    Ended (``Drawing.stop``), it ends those first; it returns once they ended.
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the parent's to handle
    pids: list[int] = []

    def end(signum: int, frame: object) -> None:
        for pid in pids:
            with contextlib.suppress(OSError):
                os.kill(pid, signal.SIGTERM)
                os.waitpid(pid, 0)
        os._exit(1)

    signal.signal(signal.SIGTERM, end)
    if len(sends) > 1:
        for job in jobs:
            if isinstance(job.make, str):
                with contextlib.suppress(Exception):  # raised where the job is drawn
                    importlib.import_module(job.make.partition(":")[0])
    for k in range(1, len(sends)):
        pid = os.fork()
        if pid == 0:  # drawing process k
            signal.signal(signal.SIGTERM, signal.SIG_DFL)
            code = 1
            try:
                for other in (*sends[:k], *sends[k + 1 :]):
                    other.close()
                _child(sends[k], folder, jobs, queue, k, os.getppid())
                code = 0
            finally:
                os._exit(code)
        pids.append(pid)
        sends[k].close()
    try:
        _child(sends[0], folder, jobs, queue, 0, parent)
    finally:
        for pid in pids:
            with contextlib.suppress(ChildProcessError):
                os.waitpid(pid, 0)


class Drawing:
    """The figures of a run, drawn in up to ``processes`` forked processes from construction.

    Parameters
    ----------
    folder : Path
        Where the figures go.
    jobs : sequence of FigureJob
        The figures, in the order :meth:`wait` returns their paths.
    processes : int
        The most drawing processes (each takes the next job when it has drawn
        one: the figures' costs differ, this balances them); 0, or a
        platform without ``fork``: drawn in this process by :meth:`wait`.
    """

    def __init__(
        self, folder: Path, jobs: Sequence[FigureJob], processes: int = DRAWING_PROCESSES
    ) -> None:
        self.folder = folder
        self.jobs = list(jobs)
        self._children: list[tuple[BaseProcess, Connection]] = []  # the first process
        self._others: list[Connection] = []  # the pipes of the processes it forks
        n = min(processes, len(self.jobs))
        if n < 1 or not can_fork():
            return
        ctx = multiprocessing.get_context("fork")  # the children inherit the results
        self._queue = _Queue(ctx, n)  # each takes the next job when done: balanced
        pipes = [ctx.Pipe(duplex=False) for _ in range(n)]
        try:
            proc = ctx.Process(
                target=_first_child,
                args=([send for _, send in pipes], folder, self.jobs, self._queue, os.getpid()),
                name="youbot-opt figures",
                daemon=True,  # ended by multiprocessing when this process exits
            )
            proc.start()
        except BaseException:
            for recv, send in pipes:
                recv.close()
                send.close()
            raise
        for _, send in pipes:
            send.close()
        self._children.append((proc, pipes[0][0]))
        self._others = [recv for recv, _ in pipes[1:]]

    @classmethod
    def _adopt(
        cls,
        folder: Path,
        jobs: Sequence[FigureJob],
        first: tuple[BaseProcess, Connection],
        others: list[Connection],
        queue: _Queue,
    ) -> Drawing:
        """Return a Drawing of processes already running (:meth:`DrawingAhead.draw`)."""
        drawing = cls(folder, jobs, processes=0)
        drawing._children = [first]
        drawing._others = others
        drawing._queue = queue
        return drawing

    def wait(self) -> list[Path | None]:
        """Wait for every figure; return their paths in job order (None: skipped, logged).

        Raises the first error of the jobs (in job order), after every drawing
        process has ended.
        """
        if not self._children:
            drawn = _draw_jobs(self.folder, list(enumerate(self.jobs)))
            return self._report(drawn)
        drawn = []
        errors: list[tuple[int, BaseException]] = []
        proc, first = self._children[0]
        for k, recv in enumerate([first, *self._others]):
            try:
                kind, payload = recv.recv()
            except EOFError:
                i = self._queue.current[k]
                what = self.jobs[i].name if 0 <= i < len(self.jobs) else "the figures"
                how = "ended"
                if k == 0:
                    proc.join()
                    how = f"ended with exit code {proc.exitcode}"
                kind, payload = (
                    "error",
                    (
                        max(i, 0),
                        RuntimeError(f"the process drawing {what} {how} before it reported"),
                    ),
                )
            recv.close()
            if kind == "error":
                assert isinstance(payload, tuple)
                errors.append(payload)
            else:
                assert isinstance(payload, list)
                drawn += payload
        proc.join()  # after the processes it forked
        self._others = []
        self._children = []
        if errors:
            raise min(errors, key=lambda e: e[0])[1]
        return self._report(sorted(drawn, key=lambda d: d[0]))

    def _report(self, drawn: list[_Drawn]) -> list[Path | None]:
        """Give the jobs' warnings and skip lines here; return the paths in job order."""
        for _, _, skipped, caught in drawn:
            for w in caught:
                warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
            if skipped is not None:
                _log.warning("%s", skipped)
        return [path for _, path, _, _ in drawn]

    def stop(self) -> None:
        """Terminate the drawing processes still running (after an error or Ctrl-C here)."""
        for proc, recv in self._children:
            if proc.is_alive():
                proc.terminate()  # it ends the processes it forked first
            proc.join()
            recv.close()
        for recv in self._others:
            recv.close()
        self._children = []
        self._others = []


class _SharedPickler(pickle.Pickler):
    """Pickles the objects of ``shared`` (by identity) as their keys: the receiver has them."""

    def __init__(self, file: io.BytesIO, keys: Mapping[int, str]) -> None:
        super().__init__(file, protocol=pickle.HIGHEST_PROTOCOL)
        self._keys = keys

    def persistent_id(self, obj: object) -> str | None:
        return self._keys.get(id(obj))


class _SharedUnpickler(pickle.Unpickler):
    """Reads what :class:`_SharedPickler` wrote, the shared objects taken from ``shared``."""

    def __init__(self, file: io.BytesIO, shared: Mapping[str, object]) -> None:
        super().__init__(file)
        self._shared = shared

    def persistent_load(self, pid: object) -> object:
        return self._shared[str(pid)]


def _ahead_child(
    commands: Connection,
    parent_end: Connection,
    sends: list[Connection],
    queue: _Queue,
    parent: int,
    shared: Mapping[str, object],
    modules: Sequence[str],
    warm: Callable[[], object] | None,
) -> None:
    """Body of a drawing process forked ahead: import, warm, wait for the jobs, draw them.

    The modules and ``warm()`` (e.g. reading the robot's meshes) are done while
    the run still computes; then the jobs come through ``commands`` (pickled,
    the shared objects by key) and it draws as :func:`_first_child`. An end of
    ``commands`` without jobs (the run ended otherwise) ends it.
    """
    parent_end.close()  # the copy forked with it: else ``commands`` never ends
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the parent's to handle
    threading.Thread(target=watch_parent, args=(parent,), daemon=True).start()
    for module in modules:
        with contextlib.suppress(Exception):  # raised where the job is drawn, if at all
            importlib.import_module(module)
    if warm is not None:
        with contextlib.suppress(Exception):  # raised again where the job needs it
            warm()
    try:
        data = commands.recv_bytes()
    except EOFError:
        os._exit(0)
    commands.close()
    folder, jobs = _SharedUnpickler(io.BytesIO(data), shared).load()
    n = max(1, min(len(sends), len(jobs)))
    for unused in sends[n:]:  # fewer jobs than processes: those report nothing
        unused.send(("ok", []))
        unused.close()
    _first_child(sends[:n], folder, jobs, queue, parent)


class DrawingAhead:
    """Drawing processes forked before the run's results exist, which prepare while it computes.

    The first drawing process imports ``modules`` (matplotlib and the plots,
    about 0.4 s; the replay's meshcat) and calls ``warm()`` (e.g. reads the
    robot's meshes, 0.27 s for ur5) on another core while the run solves and
    certifies; :meth:`draw` then hands it the jobs, pickled with the
    ``shared`` objects (those it inherited, such as the robot) sent by
    reference, and returns the :class:`Drawing` to wait for. Jobs that do not
    pickle, or a platform without ``fork``, are drawn by a plain
    :class:`Drawing`.

    Parameters
    ----------
    shared : sequence of object
        Objects the jobs will reference that exist now (the robot, the
        problem): sent by reference, so the meshes read by ``warm`` are used.
    modules : sequence of str
        Modules to import ahead.
    warm : callable, optional
        Called in the drawing process once the modules are imported.
    processes : int
        The most drawing processes (:class:`Drawing`).
    """

    def __init__(
        self,
        shared: Sequence[object],
        modules: Sequence[str] = (),
        warm: Callable[[], object] | None = None,
        processes: int = DRAWING_PROCESSES,
    ) -> None:
        self._keys = {id(obj): f"shared{i}" for i, obj in enumerate(shared)}
        self._shared = list(shared)  # alive while pickled by identity
        self._processes = processes
        self._proc: BaseProcess | None = None
        if processes < 1 or not can_fork():
            return
        ctx = multiprocessing.get_context("fork")
        self._queue = _Queue(ctx, processes)
        pipes = [ctx.Pipe(duplex=False) for _ in range(processes)]
        commands, self._commands = ctx.Pipe(duplex=False)
        try:
            proc = ctx.Process(
                target=_ahead_child,
                args=(commands, self._commands, [send for _, send in pipes], self._queue,
                      os.getpid(), {self._keys[id(o)]: o for o in shared}, tuple(modules), warm),
                name="youbot-opt figures",
                daemon=True,
            )  # fmt: skip
            proc.start()
        except BaseException:
            for recv, send in pipes:
                recv.close()
                send.close()
            commands.close()
            self._commands.close()
            raise
        commands.close()
        for _, send in pipes:
            send.close()
        self._proc = proc
        self._recvs = [recv for recv, _ in pipes]

    def draw(self, folder: Path, jobs: Sequence[FigureJob]) -> Drawing:
        """Hand ``jobs`` to the drawing processes; return the :class:`Drawing` to wait for.

        Called once. Without a process ahead (none started, or the jobs do not
        pickle), a plain :class:`Drawing` draws them.
        """
        jobs = list(jobs)
        if self._proc is None or not jobs:
            self.stop()
            return Drawing(folder, jobs, self._processes)
        buffer = io.BytesIO()
        try:
            _SharedPickler(buffer, self._keys).dump((folder, jobs))
        except Exception as exc:  # noqa: BLE001 - e.g. a local function as a job: fork now
            _log.debug("figures drawn by processes forked now: the jobs do not pickle (%s)", exc)
            self.stop()
            return Drawing(folder, jobs, self._processes)
        proc = self._proc
        self._commands.send_bytes(buffer.getvalue())
        self._commands.close()
        self._proc = None
        return Drawing._adopt(folder, jobs, (proc, self._recvs[0]), self._recvs[1:], self._queue)

    def stop(self) -> None:
        """End the drawing process if no jobs were handed to it (the run ended otherwise)."""
        if self._proc is None:
            return
        proc, self._proc = self._proc, None
        self._commands.close()  # its end of input: it exits
        proc.join(timeout=5.0)
        if proc.is_alive():
            proc.terminate()
            proc.join()
        for recv in self._recvs:
            recv.close()
