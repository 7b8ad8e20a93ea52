"""The summary journal of a sweep store: append-only JSON lines, each with its own checksum.

Owns how a schema-3 :class:`~youbot_opt.sweeps.store.SweepStore` records
outcomes (durability rule: ``docs/scaling.md``, "Crash safety"). Every writer
(a driver run, a shard) appends to its own file ``items/journal/<writer>.jsonl``,
so concurrent shards never share a file; a line is ``<sha256[:16]> <json>``.
A resume reads every journal file: a line that is torn (no newline, e.g. a
power cut mid-write) or whose checksum does not match is skipped, so its item
is recomputed, never accepted. :func:`sync_folder` makes everything written
in a folder's filesystem durable with one call (``syncfs`` on Linux).

    JournalWriter(folder).append([encode_line(record)])   # appended, fsync-ed, closed
"""

from __future__ import annotations

import contextlib
import ctypes
import hashlib
import json
import logging
import os
import sys
import uuid
from collections.abc import Iterable, Iterator, Mapping
from pathlib import Path
from typing import Any, BinaryIO

from youbot_opt._files import fsync_dir

__all__ = [
    "JournalWriter",
    "encode_line",
    "read_journal",
    "read_line",
    "scan_journal",
    "sync_folder",
]

_log = logging.getLogger(__name__)

_DIGEST = 16  # hex characters of SHA-256 that guard a line


def encode_line(record: Mapping[str, object]) -> bytes:
    """Encode ``record`` as one journal line: ``<sha256[:16]> <json>`` and a newline (UTF-8)."""
    text = json.dumps(record, separators=(",", ":"), allow_nan=True)
    digest = hashlib.sha256(text.encode()).hexdigest()[:_DIGEST]
    return f"{digest} {text}\n".encode()


def read_journal(folder: Path) -> tuple[list[dict[str, object]], int]:
    """Every intact line of every journal file in ``folder``, oldest file first.

    Parameters
    ----------
    folder : Path
        The journal folder (missing: nothing recorded yet).

    Returns
    -------
    tuple of (list of dict, int)
        The records (each file in order; files by name) and the number of
        skipped lines (torn or not matching their checksum). Lines carry
        their commit time (``"t"``, ns) by which callers order them.
    """
    if not folder.is_dir():
        return [], 0
    files = sorted(folder.glob("*.jsonl"))
    records: list[dict[str, object]] = []
    bad = 0
    for path in files:
        try:
            data = path.read_bytes()
        except OSError as exc:
            _log.warning("cannot read sweep journal %s: %s", path, exc)
            continue
        for line in _lines(data):
            record = _decode(line)
            if record is None:
                bad += 1
            else:
                records.append(record)
    return records, bad


def scan_journal(files: Iterable[Path]) -> Iterator[tuple[int, int, dict[str, object] | None]]:
    """Stream every line of ``files`` in order, one line in memory at a time.

    Yields
    ------
    tuple of (int, int, dict or None)
        The file's position in ``files``, the line's byte offset in it, and
        its record (``None``: torn or not matching its checksum).
    """
    for number, path in enumerate(files):
        try:
            fh = path.open("rb")
        except OSError as exc:
            _log.warning("cannot read sweep journal %s: %s", path, exc)
            continue
        with fh:
            offset = 0
            for line in fh:
                start, offset = offset, offset + len(line)
                if not line.endswith(b"\n"):  # torn tail (e.g. a power cut mid-write)
                    yield number, start, None
                elif line.strip():
                    yield number, start, _decode(line.rstrip(b"\n"))


def read_line(path: Path | BinaryIO, offset: int) -> dict[str, object] | None:
    """Read the record of the journal line at byte ``offset`` (``None``: unreadable).

    ``path`` is the journal file or a binary file object open on it.
    """
    try:
        if isinstance(path, Path):
            with path.open("rb") as fh:
                fh.seek(offset)
                line = fh.readline()
        else:
            path.seek(offset)
            line = path.readline()
    except (OSError, ValueError):  # ValueError: a closed file
        return None
    return _decode(line.rstrip(b"\n")) if line.endswith(b"\n") else None


def _lines(data: bytes) -> Iterator[bytes]:
    """Complete lines of ``data``; a last line without its newline is torn and counted bad."""
    parts = data.split(b"\n")
    yield from (p for p in parts[:-1] if p)
    if parts[-1]:
        yield b""  # torn tail: decodes to None


def _decode(line: bytes) -> dict[str, object] | None:
    digest, _, text = line.partition(b" ")
    if len(digest) != _DIGEST or hashlib.sha256(text).hexdigest()[:_DIGEST].encode() != digest:
        return None
    try:
        record = json.loads(text)
    except ValueError:
        return None
    return record if isinstance(record, dict) else None


def _load_syncfs() -> Any:  # noqa: ANN401 - a ctypes function or None
    if not sys.platform.startswith("linux"):
        return None
    try:
        fn = ctypes.CDLL(None, use_errno=True).syncfs
    except (OSError, AttributeError):  # pragma: no cover - no glibc syncfs
        return None
    fn.argtypes = [ctypes.c_int]
    return fn


_SYNCFS = _load_syncfs()


def sync_folder(folder: Path, files: Iterable[Path] = ()) -> None:
    """Make every file written in ``folder``'s filesystem durable, renames included.

    Linux: one ``syncfs`` of that filesystem (one flush for a whole batch of
    item files, whoever wrote them on this machine). Elsewhere, or if
    ``syncfs`` fails: ``fsync`` of each of ``files`` and of their folders.
    """
    if _SYNCFS is not None:
        fd = os.open(folder, os.O_RDONLY)
        try:
            if _SYNCFS(fd) == 0:
                return
        finally:
            os.close(fd)
    parents = set()
    for path in files:
        with contextlib.suppress(OSError):
            fd = os.open(path, os.O_RDONLY)
            try:
                os.fsync(fd)
            finally:
                os.close(fd)
        parents.add(path.parent)
    for parent in parents:
        fsync_dir(parent)


class JournalWriter:
    """The journal file of this process in ``folder``, appended to and closed at each write.

    Parameters
    ----------
    folder : Path
        The journal folder (created if missing).
    """

    def __init__(self, folder: Path) -> None:
        folder.mkdir(parents=True, exist_ok=True)
        self.path = folder / f"{os.getpid()}-{uuid.uuid4().hex[:12]}.jsonl"
        self._created = False

    def append(self, lines: list[bytes]) -> int:
        """Append ``lines`` (from :func:`encode_line`) and ``fsync`` the file.

        Returns
        -------
        int
            Byte offset of the first of ``lines`` in :attr:`path`.
        """
        try:
            with self.path.open("ab") as fh:
                start = fh.seek(0, os.SEEK_END)
                fh.write(b"".join(lines))
                fh.flush()
                os.fsync(fh.fileno())
        except OSError as exc:  # a full disk: the error names the journal (a torn line is refused)
            if exc.filename is None and exc.errno is not None:
                exc.filename = str(self.path)
            raise
        if not self._created:  # the new file's entry in its folder, durable once
            fsync_dir(self.path.parent)
            self._created = True
        return start
