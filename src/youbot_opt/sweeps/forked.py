"""One call computed in a forked process while the caller goes on (:class:`ForkedCall`).

Two independent pieces of work and a second core: the child, forked from the
caller, inherits the data (nothing is pickled on the way in) and computes one;
the caller computes the other. :meth:`ForkedCall.result` returns the child's
value as if the call had run here: its log records, warnings and exception are
given here. Without ``fork`` (not Linux) the call runs in ``result()``.

>>> with ForkedCall(sum, [1, 2, 3]) as call:  # doctest: +SKIP
...     other = work_here()
...     total = call.result()
"""

from __future__ import annotations

import contextlib
import logging
import os
import pickle
import signal
import sys
import threading
import time
import traceback
import warnings
from collections.abc import Callable
from types import TracebackType
from typing import Generic, NoReturn, TypeVar

__all__ = ["ForkedCall", "can_fork", "watch_parent"]

T = TypeVar("T")

PARENT_POLL = 0.2
"""[s] How often a forked process checks that its parent is alive (:func:`watch_parent`)."""

_Warning = tuple[Warning | str, type[Warning], str, int]


def can_fork() -> bool:
    """Whether :class:`ForkedCall` forks here (Linux), rather than calling on ``result()``."""
    return sys.platform.startswith("linux") and hasattr(os, "fork")


def watch_parent(parent: int) -> None:
    """Exit this (forked) process once its parent ``parent`` (a pid) has ended.

    Run in a daemon thread of the child: a parent killed without a chance to
    end its children does not leave them running.
    """
    while True:
        time.sleep(PARENT_POLL)
        if os.getppid() != parent:
            os._exit(1)


def _plain(record: logging.LogRecord) -> logging.LogRecord:
    """Return ``record`` with its message formatted and its traceback as text (picklable)."""
    record.msg = record.getMessage()
    record.args = None
    if record.exc_info:
        record.exc_text = logging.Formatter().formatException(record.exc_info)
        record.exc_info = None
    return record


def _child(
    write: int,
    parent: int,
    fn: Callable[..., object],
    args: tuple[object, ...],
    kwargs: dict[str, object],
) -> NoReturn:
    """Body of the forked process: call, send ``(kind, value, records, warnings)``, exit."""
    code = 1
    try:
        signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the parent's to handle
        threading.Thread(target=watch_parent, args=(parent,), daemon=True).start()
        records: list[logging.LogRecord] = []

        def collect(logger: logging.Logger, record: logging.LogRecord) -> None:
            records.append(_plain(record))

        logging.Logger.callHandlers = collect  # type: ignore[method-assign,assignment] # here only
        with warnings.catch_warnings(record=True) as caught:
            try:
                message: tuple[str, object] = ("ok", fn(*args, **kwargs))
            except BaseException as exc:  # noqa: BLE001 - every error goes back to the caller
                exc.add_note("in the forked process:\n" + traceback.format_exc().rstrip())
                message = ("error", exc)
        seen: list[_Warning] = [(w.message, w.category, w.filename, w.lineno) for w in caught]
        try:
            payload = pickle.dumps((*message, records, seen))
        except Exception as exc:  # noqa: BLE001 - what does not pickle goes as text
            if message[0] == "error":  # the call's own error, as text
                error = RuntimeError(f"{type(message[1]).__name__}: {message[1]}")
            else:
                error = RuntimeError(
                    f"the forked call's value could not be sent back: {type(exc).__name__}: {exc}"
                )
            payload = pickle.dumps(("error", error, records, []))
        with os.fdopen(write, "wb") as stream:
            stream.write(payload)
        code = 0
    finally:
        os._exit(code)


class ForkedCall(Generic[T]):
    """``fn(*args, **kwargs)`` computed in a forked process from construction.

    Parameters
    ----------
    fn : callable
        The call; its value must pickle (it comes back through a pipe).
    *args, **kwargs
        Its arguments, inherited by the child (not pickled).

    Notes
    -----
    Collect the value with :meth:`result` (once). Leaving the ``with`` block, or
    :meth:`cancel`, ends a child whose value was not collected (after an error
    here, or Ctrl-C, which the child ignores). The child watches this process
    and exits if it ends. Without ``fork`` (:func:`can_fork`), :meth:`result`
    makes the call itself.
    """

    def __init__(self, fn: Callable[..., T], *args: object, **kwargs: object) -> None:
        self._call: tuple[Callable[..., T], tuple[object, ...], dict[str, object]] | None = (
            fn,
            args,
            kwargs,
        )
        self._pid: int | None = None
        self._read: int | None = None
        if not can_fork():
            return
        read, write = os.pipe()
        parent = os.getpid()
        try:
            pid = os.fork()
        except BaseException:
            os.close(read)
            os.close(write)
            raise
        if pid == 0:
            os.close(read)
            _child(write, parent, fn, args, kwargs)
        os.close(write)
        self._pid, self._read, self._call = pid, read, None

    def result(self) -> T:
        """Wait for the call; return its value (its records and warnings issued here).

        Raises
        ------
        BaseException
            The call's own exception, or a RuntimeError if the child ended without
            reporting (killed) or its value did not pickle.
        """
        if self._call is not None:  # no fork here: the call runs now
            fn, args, kwargs = self._call
            self._call = None
            return fn(*args, **kwargs)
        if self._pid is None or self._read is None:
            raise RuntimeError("the forked call's result was already collected or cancelled")
        with os.fdopen(self._read, "rb") as stream:
            self._read = None
            data = stream.read()
        _, status = os.waitpid(self._pid, 0)
        self._pid = None
        if not data:
            raise RuntimeError(
                f"the forked process ended before it reported (wait status {status})"
            )
        kind, value, records, seen = pickle.loads(data)
        for record in records:
            logging.getLogger(record.name).handle(record)
        for message, category, filename, lineno in seen:
            warnings.warn_explicit(message, category, filename, lineno)
        if kind == "error":
            raise value
        return value  # type: ignore[no-any-return]

    def cancel(self) -> None:
        """End the child if its value was not collected (nothing otherwise)."""
        self._call = None
        if self._read is not None:
            os.close(self._read)
            self._read = None
        if self._pid is not None:
            with contextlib.suppress(ProcessLookupError):
                os.kill(self._pid, signal.SIGKILL)
            with contextlib.suppress(ChildProcessError):
                os.waitpid(self._pid, 0)
            self._pid = None

    def __enter__(self) -> ForkedCall[T]:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.cancel()
