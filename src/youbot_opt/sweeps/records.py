"""One item of a sweep store on disk: its key, its record, its payload file, read anywhere.

Owns the formats a :class:`~youbot_opt.sweeps.store.SweepStore` writes per
item, separately from the store itself so that workers and monitors need no
store: :func:`check_key`, :class:`ItemRecord` (one journal line),
:func:`fanout_name` (``items/<hh>/<key><suffix>``),
:func:`write_unsynced` (atomic, no per-item fsync), :class:`ItemWriter` and
:class:`WrittenItem` (a worker writing its own payload and reporting its
SHA-256), and :func:`stored_records` (every record of a folder, no parameter
check). Layout and durability rule: ``docs/scaling.md``.

    name, sha = ItemWriter(items_dir, ".npz", save, None).write("start_0007", result)
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import re
import tempfile
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Generic, Literal, TypeVar

from youbot_opt._files import TMP_PREFIX
from youbot_opt.exceptions import ParameterError, ResultFileError
from youbot_opt.sweeps.journal import read_journal

__all__ = [
    "ITEMS",
    "JOURNAL",
    "RECORD_VERSION",
    "ItemRecord",
    "ItemWriter",
    "WrittenItem",
    "check_key",
    "fanout_name",
    "sha256_file",
    "stored_record",
    "stored_records",
    "write_unsynced",
]

RECORD_VERSION = 3
"""Schema version written into item records (the store's manifest version)."""
ITEMS = "items"
"""Folder of a store that holds its items."""
JOURNAL = "journal"
"""Folder inside ``items/`` that holds the summary journal (schema 3)."""

_KEY = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]{0,99}$")

ItemState = Literal["done", "failed"]

P = TypeVar("P")
"""The payload type of a store's items (a result an optimiser writes)."""
V = TypeVar("V")
"""The type of a task's value."""


def check_key(key: str) -> str:
    """Validate an item key (a file-name-safe string), returning it.

    Raises
    ------
    ParameterError
        If ``key`` is not 1-100 characters of ``[A-Za-z0-9._-]`` starting alphanumeric.
    """
    if not isinstance(key, str) or not _KEY.match(key):
        raise ParameterError(
            f"item key must be 1-100 characters of [A-Za-z0-9._-] starting with a letter "
            f"or digit, got {key!r}",
            name="key",
            value=key,
        )
    return key


@dataclass(frozen=True, slots=True, kw_only=True)
class ItemRecord:
    """What the store knows about one item.

    Attributes
    ----------
    key : str
        Item key.
    state : {"done", "failed"}
        ``"done"``: the item produced a payload (which may itself describe a
        failed solve); ``"failed"``: it raised or its worker crashed.
    attempts : int
        Attempts made so far (>= 1).
    reasons : tuple of str
        Why each failed attempt failed, oldest first.
    summary : mapping
        JSON-ready figures of the item (empty for failures).
    payload : str or None
        Path of the payload relative to ``items/`` (``"3f/start_0007.npz"``),
        ``None`` for failures.
    sweep : str or None
        Binding of the sweep that wrote the record (a record without one is refused).
    checksum : str or None
        SHA-256 (hex) of the payload file (``None`` for failures).
    """

    key: str
    state: ItemState
    attempts: int
    reasons: tuple[str, ...] = ()
    summary: Mapping[str, object] = field(default_factory=dict)
    payload: str | None = None
    sweep: str | None = None
    checksum: str | None = None

    def to_json(self, version: int = RECORD_VERSION) -> dict[str, object]:
        """Return the record as written to disk (a journal line)."""
        return {
            "schema": "youbot_opt.sweep_item",
            "schema_version": version,
            "key": self.key,
            "state": self.state,
            "attempts": self.attempts,
            "reasons": list(self.reasons),
            "summary": dict(self.summary),
            "payload": self.payload,
            "sweep": self.sweep,
            "checksum": self.checksum,
        }

    def number(self, name: str, default: float | None = None) -> float:
        """Return the summary's figure ``name`` as a float (a JSON ``null`` reads as NaN).

        Parameters
        ----------
        name : str
            Key of the figure in :attr:`summary` (e.g. ``"solve_time_s"``, in the
            unit its name gives).
        default : float or None
            Returned when the key is absent; ``None``: an absent key is an error.

        Raises
        ------
        ResultFileError
            If the figure is absent (without a default) or neither a number nor
            the text of one.
        """
        if name not in self.summary:
            if default is None:
                raise ResultFileError(f"item {self.key!r}: its summary has no {name!r}")
            return default
        value = self.summary[name]
        if value is None:
            return float("nan")
        if isinstance(value, bool) or not isinstance(value, (int, float, str)):
            raise ResultFileError(
                f"item {self.key!r}: summary {name!r} = {value!r} is not a number"
            )
        try:
            return float(value)
        except ValueError as exc:
            raise ResultFileError(
                f"item {self.key!r}: summary {name!r} = {value!r} is not a number"
            ) from exc

    @classmethod
    def from_json(cls, data: Mapping[str, object], path: Path) -> ItemRecord:
        """Parse a record read from ``path``.

        Raises
        ------
        ResultFileError
            If a field is missing or of the wrong type.
        """
        try:
            state = data["state"]
            if state not in ("done", "failed"):
                raise ValueError(f"state {state!r}")
            attempts = data["attempts"]
            if not isinstance(attempts, (int, float, str)):
                raise TypeError(f"attempts {attempts!r}")
            attempts = int(attempts)
            if attempts < 1:
                raise ValueError(f"attempts {attempts}")
            payload = data.get("payload")
            if state == "done" and not isinstance(payload, str):
                raise ValueError("a done item needs a payload file name")
            return cls(
                key=str(data["key"]),
                state=state,
                attempts=attempts,
                reasons=tuple(str(r) for r in _listed(data.get("reasons", ()))),
                summary=_mapping(data.get("summary")),
                payload=payload if isinstance(payload, str) else None,
                sweep=None if data.get("sweep") is None else str(data["sweep"]),
                checksum=None if data.get("checksum") is None else str(data["checksum"]),
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise ResultFileError(f"item record {path} is corrupted: {exc}") from exc


def _listed(value: object) -> tuple[object, ...]:
    if not isinstance(value, Iterable):
        raise TypeError(f"expected a list, got {type(value).__name__}")
    return tuple(value)


def _mapping(value: object) -> dict[str, object]:
    if not value:
        return {}
    if not isinstance(value, Mapping):
        raise TypeError(f"expected a mapping, got {type(value).__name__}")
    return dict(value)


def _commit_time(line: Mapping[str, object]) -> int:
    t = line.get("t", 0)
    return t if isinstance(t, int) else 0


def fanout_name(key: str, suffix: str) -> str:
    """Payload path of ``key`` relative to ``items/``: ``"<hh>/<key><suffix>"``.

    ``hh`` is the first two hex digits of SHA-256 of the key: 256 folders, stable
    across runs and machines, so 10^5 items put about 400 files in each.
    """
    return f"{hashlib.sha256(check_key(key).encode()).hexdigest()[:2]}/{key}{suffix}"


def write_unsynced(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically (temporary file, :func:`os.replace`) without fsync.

    A kill leaves the old file or the new one, never a torn one; durability
    comes later, for a whole group of items at once (:meth:`SweepStore.flush`).
    """
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f"{TMP_PREFIX}{path.name}.")
    try:
        with os.fdopen(fd, "wb") as handle:
            handle.write(data)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


@dataclass(frozen=True, slots=True)
class WrittenItem(Generic[V]):
    """What a worker reports after writing its own item's payload (see :class:`ItemWriter`).

    Attributes
    ----------
    payload : str
        Payload path relative to ``items/``.
    checksum : str
        SHA-256 (hex) of the bytes the worker wrote.
    summary : dict
        JSON-ready figures of the item.
    value : object
        The task's value, or ``None`` when the driver keeps no results.
    """

    payload: str
    checksum: str
    summary: dict[str, object]
    value: V | None = None


@dataclass(frozen=True, slots=True)
class ItemWriter(Generic[P]):
    """A picklable recipe by which a worker writes an item's payload into a store's folder.

    The driver then checks the file against the reported checksum before it
    records the item (:meth:`SweepStore.accept`), so a wrong or torn file is
    refused, never recorded.

    Attributes
    ----------
    items_dir : str
        The store's ``items/`` folder (shared with the workers).
    suffix : str
        Payload suffix.
    save : callable ``(payload, path)`` or None
        The store's payload writer (used when ``encode`` is ``None``).
    encode : callable ``(payload) -> bytes`` or None
        The store's payload encoder (written without per-item fsync).
    """

    items_dir: str
    suffix: str
    save: Callable[[P, Path], object] | None
    encode: Callable[[P], bytes] | None

    def write(self, key: str, payload: P) -> tuple[str, str]:
        """Write ``payload`` as the item ``key``; returns its relative path and SHA-256."""
        name = fanout_name(key, self.suffix)
        path = Path(self.items_dir) / name  # its folder exists: made when the store opened
        if self.encode is not None:
            data = self.encode(payload)
            write_unsynced(path, data)
            return name, hashlib.sha256(data).hexdigest()
        assert self.save is not None
        self.save(payload, path)
        return name, sha256_file(path)


def stored_records(directory: str | os.PathLike[str]) -> list[ItemRecord]:
    """Every item record in a sweep folder, oldest first, read without opening the store.

    For monitors and tests (e.g. counting finished items while a sweep runs):
    the intact journal lines in commit order (an item retried has one line
    per attempt). Nothing is checked against a
    sweep's parameters; :class:`SweepStore` does that.

    Parameters
    ----------
    directory : path-like
        The sweep's output folder (``out``).

    Returns
    -------
    list of ItemRecord
        The records (empty if the folder holds none yet).
    """
    journal = Path(directory) / ITEMS / JOURNAL
    out = []
    lines = read_journal(journal)[0]
    lines.sort(key=_commit_time)
    for data in lines:
        with contextlib.suppress(ResultFileError):
            out.append(ItemRecord.from_json(data, journal))
    return out


def stored_record(directory: str | os.PathLike[str], key: str) -> dict[str, object] | None:
    """Return the latest record of ``key`` in a sweep folder as JSON (``None``: none).

    For monitors and tests: the fields of :meth:`ItemRecord.to_json`
    (``state``, ``attempts``, ``reasons``, ``summary``, ``payload``, ...).
    """
    found = [r for r in stored_records(directory) if r.key == key]
    return found[-1].to_json() if found else None


def sha256_file(path: Path) -> str:
    """SHA-256 (hex) of a file's bytes."""
    digest = hashlib.sha256()
    with path.open("rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()
