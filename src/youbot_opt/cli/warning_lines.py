"""Warnings on the command line: one line each, ``youbot-opt: warning: <message>``, grouped.

Library code warns with ``warnings.warn(..., YoubotOptWarning)``; Python's
default display adds the category, the file, line and source line that warned.
:func:`warnings_as_lines` holds a command's warnings and prints each group once
without them: identical messages as one line ending ``(x11)``, messages that
differ only in quoted names, elements, paths and numbers (meshes missing their
``.mtl``) as the first and ``(and 10 more like it: 'b', ...)``.
:func:`flush_warnings` prints what is held so far (after loading the robot).

>>> with warnings_as_lines():  # doctest: +SKIP
...     robot = load_model("panda.urdf", strict=False)
"""

from __future__ import annotations

import re
import sys
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from typing import TextIO

__all__ = ["flush_warnings", "group_warnings", "warnings_as_lines"]

_PREFIX = "youbot-opt: warning: "
# What varies between warnings of one kind: quoted names, elements (<visual>, <collision>),
# paths (with :line) and numbers.
_VARYING = re.compile(
    r"'[^']*'|\"[^\"]*\"|(?:<[^<>]*>)+"
    r"|(?:[A-Za-z]:)?[\w.~-]*[/\\][^\s:;,'\"()]*"
    r"|-?\d+(?:\.\d*)?(?:[eE][-+]?\d+)?"
)

_QUOTED = re.compile(r"'[^']*'")
_LISTED = 4  # other names listed for a group of warnings of one kind


def _kind(message: str) -> str:
    return "".join(_VARYING.sub("_", message).split())  # numpy pads numbers with spaces


def group_warnings(messages: list[str]) -> list[str]:
    """Return one line per group of messages, in the order each group first appeared.

    Parameters
    ----------
    messages : list of str
        Warning messages, in the order they were raised.

    Returns
    -------
    list of str
        ``"<message>"`` for a message alone, ``"<message> (xN)"`` for N identical
        ones, ``"<first> (and N-1 more like it: 'b', 'c', ...)"`` for N of one
        kind (equal but for quoted names, elements, paths and numbers; the other values of
        the first quoted name that varies are listed, four at most).
    """
    groups: dict[str, list[str]] = {}
    for message in messages:
        groups.setdefault(_kind(message), []).append(message)
    lines = []
    for group in groups.values():
        first, n = group[0], len(group)
        if n == 1:
            lines.append(first)
        elif all(m == first for m in group):
            lines.append(f"{first} (x{n})")
        else:
            lines.append(f"{first} (and {n - 1} more like it{_names(group)})")
    return lines


def _names(group: list[str]) -> str:
    """``": 'b', 'c', ..."``: the other values of the first quoted name that varies."""
    quoted = [_QUOTED.findall(m) for m in group]
    for slot in range(min(len(q) for q in quoted)):
        values = list(dict.fromkeys(q[slot] for q in quoted))
        if len(values) > 1:
            shown = values[1 : 1 + _LISTED]
            return ": " + ", ".join(shown) + (", ..." if len(values) > 1 + _LISTED else "")
    return ""


class _Held:
    """The warnings of a command, held until :meth:`flush`."""

    def __init__(self) -> None:
        self.messages: list[str] = []

    def show(
        self,
        message: Warning | str,
        category: type[Warning],
        filename: str,
        lineno: int,
        file: TextIO | None = None,
        line: str | None = None,
    ) -> None:
        """Hold one warning (the signature of :func:`warnings.showwarning`)."""
        self.messages.append(" ".join(str(message).split()))  # one line

    def flush(self) -> None:
        """Print the held warnings grouped, one line each, on stderr; hold none."""
        lines, self.messages = group_warnings(self.messages), []
        for line in lines:
            print(_PREFIX + line, file=sys.stderr, flush=True)


@contextmanager
def warnings_as_lines() -> Iterator[None]:
    """Hold the warnings raised inside and print them grouped, one line each, on leaving.

    Warning filters stay as they were (``-W error`` still raises); only how a
    shown warning is printed changes, and only inside.
    """
    held = _Held()
    with warnings.catch_warnings():
        warnings.showwarning = held.show
        try:
            yield
        finally:
            held.flush()


def flush_warnings() -> None:
    """Print the warnings held so far by the enclosing :func:`warnings_as_lines` (if any)."""
    held = getattr(warnings.showwarning, "__self__", None)
    if isinstance(held, _Held):
        held.flush()
