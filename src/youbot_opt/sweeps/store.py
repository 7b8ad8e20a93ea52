"""A sweep's results on disk: one payload file per finished item, a summary journal, kill-safe.

A :class:`SweepStore` owns ``DIR/manifest.json`` (the sweep's kind and defining
parameters), the payloads ``DIR/items/<hh>/<key><suffix>`` (fanned out into 256
folders by the first two hex digits of SHA-256 of the key) and the journal
``DIR/items/journal/*.jsonl`` (:mod:`.journal`: one checksummed line per attempt
with summary, binding and payload checksum), indexed by one int per key (records
are read back from their lines). Payloads are written atomically, by the driver
or the worker, durable in groups before their journal lines. :func:`open_store`
opens one with an optimiser's :class:`Codec` (its payload format).

>>> store = open_store(out, "pareto", params, codec)  # doctest: +SKIP
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import logging
import math
import os
import time
import uuid
import warnings
from collections import OrderedDict
from collections.abc import Callable, Iterable, Iterator, Mapping, MutableMapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, BinaryIO, Generic, TypeVar

from youbot_opt._files import (
    TMP_PREFIX,
    atomic_write_bytes,
    check_schema_header,
    fsync_dir,
    json_roundtrip,
)
from youbot_opt.exceptions import ParameterError, ResultFileError, YoubotOptWarning
from youbot_opt.sweeps.index import DiskIndex
from youbot_opt.sweeps.journal import (
    JournalWriter,
    encode_line,
    read_line,
    scan_journal,
    sync_folder,
)
from youbot_opt.sweeps.records import (
    ITEMS,
    JOURNAL,
    RECORD_VERSION,
    ItemRecord,
    ItemWriter,
    WrittenItem,
    check_key,
    fanout_name,
    sha256_file,
    stored_record,
    stored_records,
    write_unsynced,
)
from youbot_opt.sweeps.selection import Clusters

__all__ = [  # the item formats are re-exported: they were defined here before
    "SCHEMA_VERSION",
    "Codec",
    "ItemRecord",
    "ItemWriter",
    "SweepStore",
    "WrittenItem",
    "atomic_write_bytes",
    "check_key",
    "fanout_name",
    "open_store",
    "stored_record",
    "stored_records",
    "write_unsynced",
]

_log = logging.getLogger(__name__)

SCHEMA_VERSION = RECORD_VERSION
"""Version of the manifest written and read by this module (3: fanned-out payloads
and a summary journal; the flat 1 and 2 of 0.1.0 go through ``scripts/migrate_0_1_0.py``)."""

GROUP_ITEMS = 1024
"""Journal lines a grouped store collects before it makes them durable."""
GROUP_SECONDS = 0.1
"""[s] longest a grouped store holds a finished item before making it durable."""
_FLUSH_SHARE = 10.0  # a group waits at most this many times what its flush costs

_MANIFEST = "manifest.json"
_OPTIMA = "optima.json"
_MAX_JOURNALS = 32  # journal files (one per run or shard) merged beyond this
# An index entry is one int: byte offset, journal file number (16 bits), attempts
# (15 bits, saturated) and done (1 bit), so that needs_work reads no line.
_FILE_SHIFT = 16
_FILE_BIT = 1 << _FILE_SHIFT
_FILE_MASK = _FILE_BIT - 1
_STATUS_SHIFT = 16
_MAX_ATTEMPTS = (1 << (_STATUS_SHIFT - 1)) - 1


def _entry(offset: int, number: int, state: str, attempts: int) -> int:
    where = (offset << _FILE_SHIFT) | number
    return (where << _STATUS_SHIFT) | (min(attempts, _MAX_ATTEMPTS) << 1) | (state == "done")


def _where(entry: int) -> tuple[int, int]:
    """Byte offset and journal file number of an index entry."""
    where = entry >> _STATUS_SHIFT
    return where >> _FILE_SHIFT, where & _FILE_MASK


def _time(data: Mapping[str, Any]) -> int:
    """Commit time of a journal line [ns] (0 if it has none)."""
    t = data.get("t", 0)
    return t if isinstance(t, int) else 0


def _read_json(path: Path, what: str) -> dict[str, Any]:
    """Parse a store file, checking its schema version."""
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise ResultFileError(f"cannot read {what} {path}: {exc}") from exc
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ResultFileError(
            f"{what} {path} is corrupted (not valid JSON: {exc}); delete it to recompute"
        ) from exc
    check_schema_header(
        data,
        schema=None,
        supported=SCHEMA_VERSION,
        source=f"{what} {path}",
        remedy="upgrade youbot_opt or use another output directory",
        oldest=SCHEMA_VERSION,
        migrate=str(path.parent),
    )
    return data


R = TypeVar("R")


@dataclass(frozen=True, slots=True, kw_only=True)
class Codec(Generic[R]):
    """How an optimiser's result becomes a store payload and back (one per optimiser).

    Attributes
    ----------
    save : callable ``(result, path)``
        Write a payload file (atomically); a module-level function or partial
        when workers write (it pickles to them).
    load : callable ``(path) -> result``
        Read (and re-check) a payload file.
    suffix : str
        Suffix of the payload files (not ``.json``, which names the records).
    encode : callable ``(result) -> bytes``, optional
        The payload's content, for workers that write without a per-item fsync
        (made durable by group); ``None``: ``save`` writes.
    refuse_old : callable ``(directory)``, optional
        Raise :class:`~youbot_opt.exceptions.ResultFileError` when the folder
        holds a store of this optimiser in an older form (naming the script that
        carries it forward); called before the store is opened.
    check : callable ``(key, result) -> str or None``, optional
        Why a loaded payload is not item ``key`` of this sweep (``None``: it
        is): the payload's own problem parameters, start and figures re-checked
        against the sweep's problem. The journal's checksums only show that a
        line and its payload were not torn; anyone can recompute them, so an
        item copied from another sweep and re-bound passes them. A payload this
        refuses is warned about and recomputed, never loaded.
    """

    save: Callable[[R, Path], object]
    load: Callable[[Path], R]
    suffix: str
    encode: Callable[[R], bytes] | None = None
    refuse_old: Callable[[Path], None] | None = None
    check: Callable[[str, R], str | None] | None = None


def open_store(
    out: str | os.PathLike[str],
    kind: str,
    params: Mapping[str, object],
    codec: Codec[R],
    *,
    clean: bool = True,
) -> SweepStore[R]:
    """Open (or create) the store of one sweep in ``out``, its payloads by ``codec``.

    Parameters
    ----------
    out : path-like
        Output directory (created if missing).
    kind : str
        Kind of sweep (``"multistart"``, ``"pareto"``, ``"ikpath_multistart"``, ...).
    params : mapping
        The sweep's defining parameters (JSON-ready; a rerun with others is refused).
    codec : Codec
        The optimiser's payload format.
    clean : bool
        Remove leftover temporary files (not in a shard run: other shards
        may be writing into the same folder).

    Returns
    -------
    SweepStore
        The store; ``store.resumed`` tells whether the directory held this sweep.

    Raises
    ------
    ParameterError
        If ``out`` holds another kind of sweep or one with other parameters.
    ResultFileError
        If its manifest is corrupted, from a newer schema, or (``codec.refuse_old``)
        from an older version.
    """
    if codec.refuse_old is not None:
        codec.refuse_old(Path(out))
    return SweepStore(
        out,
        kind=kind,
        params=params,
        save=codec.save,
        load=codec.load,
        suffix=codec.suffix,
        clean=clean,
        encode=codec.encode,
        check=codec.check,
    )


class SweepStore(Generic[R]):
    """Output directory of one sweep: manifest, payload files and the summary journal.

    Parameters
    ----------
    directory : path-like
        Output directory; created if missing.
    kind : str
        Kind of sweep (``"multistart"``, ``"pareto"``, ...); part of the manifest.
    params : mapping
        JSON-ready parameters that define the sweep (seeds, knots, betas, ...).
        Reopening the directory with different ``kind`` or ``params`` raises.
    save : callable ``(payload, path)``
        Writes an item's payload to ``path`` atomically (as
        :func:`youbot_opt.trajopt.io.save_result` does); picklable if workers
        are to write their own items.
    load : callable ``(path) -> payload``
        Reads a payload back; should raise ``ResultFileError`` on bad files.
    suffix : str
        Payload file suffix, e.g. ``".npz"``.
    clean : bool
        Remove leftover temporary files of killed writes (default). Shard
        runs sharing the folder pass ``False``; the collecting run cleans.
    encode : callable ``(payload) -> bytes``, optional
        If given, payloads are written from these bytes without a per-item
        ``fsync`` (made durable by group, see :meth:`flush`) instead of by ``save``.
    check : callable ``(key, payload) -> str or None``, optional
        Re-checks a loaded payload against the sweep's own problem (see
        :class:`Codec`); a payload it refuses is recomputed.

    Attributes
    ----------
    resumed : bool
        True if the directory already held this sweep.

    Raises
    ------
    ParameterError
        If the directory holds a sweep with other parameters (the message lists them).
    ResultFileError
        If its manifest is corrupted or of another schema version (one written
        by 0.1.0: the message names ``scripts/migrate_0_1_0.py``).

    Notes
    -----
    Durability (schema 3): each payload is renamed into place atomically; a
    journal line is appended only after the payload is durable (one
    ``syncfs`` per group, then the journal's own ``fsync``). A power cut
    loses at most the last group (at most :data:`GROUP_ITEMS` items or
    :data:`GROUP_SECONDS` of results), which a rerun recomputes; a torn
    journal line fails its checksum and a payload that does not match the
    checksum of its line is refused, so no torn or wrong item is accepted.
    Outside :meth:`grouped` every write is durable at once.
    """

    def __init__(
        self,
        directory: str | os.PathLike[str],
        *,
        kind: str,
        params: Mapping[str, object],
        save: Callable[[R, Path], object],
        load: Callable[[Path], R],
        suffix: str = ".npz",
        clean: bool = True,
        encode: Callable[[R], bytes] | None = None,
        check: Callable[[str, R], str | None] | None = None,
    ) -> None:
        self.directory = Path(directory)
        self.kind = str(kind)
        self.params: dict[str, Any] = json_roundtrip(dict(params))
        self._save = save
        self._load = load
        self._encode = encode
        self._check = check
        self._checked: tuple[str, R] | None = None  # the payload verify() loaded, for load()
        self.suffix = suffix
        self.items_dir = self.directory / ITEMS
        self.items_dir.mkdir(parents=True, exist_ok=True)
        self.binding = hashlib.sha256(
            json.dumps({"kind": self.kind, "params": self.params}, sort_keys=True).encode()
        ).hexdigest()
        # records checked (or written) by this store; fan-out stores remember only the
        # last VERIFIED_CACHE (a selection verifies every converged item once: O(1) memory)
        self._verified = _RecentKeys(None)
        self._refused: set[str] = set()  # records refused: recomputed, never loaded
        # fanout: where the last journal line of each key is, (offset << 16) | file number
        # (a compact index on disk: a record is read back from its line when asked for)
        self._index: MutableMapping[str, int] = DiskIndex()
        self._journals: list[Path] = []  # the journal files the index points into
        self._readers: dict[int, BinaryIO] = {}  # open journal files, by number (reads)
        self._unflushed: dict[str, ItemRecord] = {}  # records whose lines are not durable yet
        # fanout: journal lines not yet durable: (key, state, attempts, line)
        self._lines: list[tuple[str, str, int, bytes]] = []
        self._files: list[Path] = []  # ... and the payloads they point to
        self._group = 0  # depth of grouped() contexts
        # fanout: sum mod 2^256 of the digests of every record (index and unflushed),
        # kept up to date as records change, so fingerprint_all() reads no line
        self._digest_sum = 0
        self._last_flush = time.monotonic()
        self._window = GROUP_SECONDS  # [s] adapted to the cost of a flush
        self._journal: JournalWriter | None = None
        manifest = self.directory / _MANIFEST
        if manifest.exists():
            data = _read_json(manifest, "sweep manifest")
            self._check_manifest(data)
            self.resumed = True
        else:
            body = {
                "schema": "youbot_opt.sweep",
                "schema_version": SCHEMA_VERSION,
                "kind": self.kind,
                "params": self.params,
                "binding": self.binding,
            }
            atomic_write_bytes(manifest, json.dumps(body, indent=1).encode())
            self.resumed = False
        self._verified = _RecentKeys(VERIFIED_CACHE)
        if clean:  # not in shard runs: another shard may be writing one right now
            self._clean_temporaries()
        self._read_journal(compact=clean)
        made = {p.name for p in self.items_dir.iterdir()}
        for i in range(256):  # every fan-out folder, once, so writers never need to
            if f"{i:02x}" not in made:
                (self.items_dir / f"{i:02x}").mkdir(exist_ok=True)

    # ---------------------------------------------------------------- manifest
    def _clean_temporaries(self) -> None:
        # ".tmp-<name>.<random>" (youbot_opt._files) of killed writes
        folders = [self.directory, self.items_dir]
        folders += [p for p in self.items_dir.iterdir() if p.is_dir() and len(p.name) == 2]
        for folder in folders:
            for tmp in folder.glob(f"{TMP_PREFIX}*"):
                with contextlib.suppress(OSError):
                    tmp.unlink()
                    _log.debug("removed leftover temporary file %s", tmp)

    def _check_manifest(self, data: Mapping[str, Any]) -> None:
        path = self.directory / _MANIFEST
        if data.get("kind") != self.kind:
            raise ParameterError(
                f"{self.directory} holds a {data.get('kind')!r} sweep, not a {self.kind!r} "
                "sweep; use another output directory",
                name="out",
                value=str(self.directory),
            )
        old = data.get("params")
        if not isinstance(old, dict):
            raise ResultFileError(f"sweep manifest {path} is corrupted: no 'params' mapping")
        diffs = [
            f"{k}: stored {old.get(k, '<missing>')!r}, now {self.params.get(k, '<missing>')!r}"
            for k in sorted(set(old) | set(self.params))
            if not _same(old.get(k, _MISSING), self.params.get(k, _MISSING))
        ]
        if diffs:
            raise ParameterError(
                f"cannot resume the sweep in {self.directory}: its parameters differ "
                f"({'; '.join(diffs)}); rerun with the stored parameters or choose a new "
                "output directory",
                name="out",
                value=str(self.directory),
            )

    def _read_journal(self, compact: bool) -> None:
        folder = self.items_dir / JOURNAL
        self._journals = sorted(folder.glob("*.jsonl")) if folder.is_dir() else []
        bad = self._scan()
        foreign = self._foreign
        if not (bad or foreign):
            if compact and len(self._journals) > _MAX_JOURNALS:
                self._compact(folder)  # one file per run or shard adds up: merge them
            return
        why = [f"{bad} torn or corrupted journal line(s)"] if bad else []
        if foreign:
            names = ", ".join(repr(k) for k in foreign[:5]) + (", ..." if len(foreign) > 5 else "")
            why.append(f"items {names}: {self._n_foreign} line(s) written by another sweep")
        warnings.warn(
            f"refused {' and '.join(why)} in the sweep in {self.directory}; "
            "those items are recomputed",
            YoubotOptWarning,
            stacklevel=3,
        )
        _log.warning("sweep %s: refused %s", self.directory, "; ".join(why))
        if compact:  # rewrite the journal without them, so they are refused once
            self._compact(folder)

    def _scan(self) -> int:
        """Index the last accepted line of every key (streamed); returns the bad lines."""
        folder = self.items_dir / JOURNAL
        self._index.clear()
        self._digest_sum = 0
        self._foreign: list[str] = []  # the first few keys of lines of another sweep
        self._n_foreign = 0
        bad = 0
        times: dict[str, int] = {}  # commit time of an indexed line, only when a key repeats
        for number, offset, data in scan_journal(self._journals):
            record = self._parse(data, folder)
            if record is None:
                bad += 1
                continue
            if record.sweep != self.binding:
                self._n_foreign += 1
                if len(self._foreign) < 6:
                    self._foreign.append(record.key)
                continue
            assert data is not None
            key = record.key
            t = _time(data)
            prev = self._index.get(key)
            if prev is not None:  # rare (a failed attempt, then another run): the later line wins
                at, num = _where(prev)
                line = read_line(self._journals[num], at)
                old = times.get(key)
                if old is None:
                    old = _time(line) if line is not None else 0
                if t < old:
                    continue
                times[key] = t
                replaced = self._parse(line, folder)
                if replaced is not None:
                    self._digest_sum -= _digest(replaced)
            self._index[key] = _entry(offset, number, record.state, record.attempts)
            self._digest_sum = (self._digest_sum + _digest(record)) % _DIGEST_MOD
        return bad

    @staticmethod
    def _parse(data: Mapping[str, Any] | None, folder: Path) -> ItemRecord | None:
        if data is None:
            return None
        try:
            record = ItemRecord.from_json(data, folder)
            check_key(record.key)
        except (ResultFileError, ParameterError):
            return None
        return record

    def _compact(self, folder: Path) -> None:
        """Replace the journal files by one holding the accepted records (atomic, durable).

        Streamed: the kept lines are copied file by file, one at a time in memory.
        """
        self.flush()
        old = list(self._journals)
        now = time.time_ns()
        target = folder / f"compact-{uuid.uuid4().hex[:12]}.jsonl"
        tmp = folder / f"{TMP_PREFIX}{target.name}.{uuid.uuid4().hex[:8]}"
        try:
            with tmp.open("wb") as fh:
                for number, offset, data in scan_journal(old):
                    if data is None:
                        continue
                    entry = self._index.get(str(data.get("key")))
                    if entry is None or _where(entry) != (offset, number):
                        continue
                    fh.write(encode_line({**data, "t": now}))
                fh.flush()
                os.fsync(fh.fileno())
            os.replace(tmp, target)
        finally:
            with contextlib.suppress(OSError):
                tmp.unlink()
        fsync_dir(folder)  # durable before the old files go
        self._close_readers()
        for path in old:
            if path != target:
                with contextlib.suppress(OSError):
                    path.unlink()
        fsync_dir(folder)
        self._journals = [target]
        self._journal = None
        self._scan()

    # ------------------------------------------------------------------ items
    def payload_path(self, key: str) -> Path:
        """Where the payload of ``key`` is (or will be) stored."""
        return self.items_dir / fanout_name(key, self.suffix)

    def writer(self) -> ItemWriter[R] | None:
        """Return the recipe by which workers write their own payloads."""
        return ItemWriter(str(self.items_dir), self.suffix, self._save, self._encode)

    def record(self, key: str) -> ItemRecord | None:
        """Return the record of ``key``, or ``None`` if the item has not finished yet.

        The store answers from the journal (payloads are checked by
        :meth:`verify` and :meth:`load`).
        """
        return self._indexed(check_key(key))

    def _refuse(self, key: str, where: str, why: str) -> None:
        if self.has(key):
            gone = self._indexed(key)
            if gone is not None:
                self._digest_sum = (self._digest_sum - _digest(gone)) % _DIGEST_MOD
        self._refused.add(key)
        self._index.pop(key, None)
        self._unflushed.pop(key, None)
        warnings.warn(
            f"refused item {key!r} of the sweep in {self.directory} ({where}: {why}); "
            "it is recomputed",
            YoubotOptWarning,
            stacklevel=3,
        )
        _log.warning("refused sweep item %s in %s: %s", key, self.directory, why)

    def _refusal(self, record: ItemRecord, key: str) -> str | None:
        """Why ``record`` does not belong to this sweep (``None``: it does)."""
        if record.key != key:
            return f"it is the record of item {record.key!r}"
        if record.sweep != self.binding:
            return (
                "it was written by another sweep (other parameters)"
                if record.sweep
                else "it carries no sweep binding"
            )
        if record.state != "done":
            return None
        expected = self.payload_path(key).relative_to(self.items_dir).as_posix()
        if record.payload != expected:
            return f"it points to payload {record.payload!r}"
        path = self.items_dir / str(record.payload)
        if not path.exists():
            return f"its payload {path.name} is missing"
        if record.checksum != sha256_file(path):
            return f"its payload {path.name} does not match its checksum (edited or torn)"
        if self._check is None:
            return None
        try:  # what the payload claims, against this sweep's problem (checksums prove nothing)
            payload = self._load(path)
        except ResultFileError as exc:
            return f"its payload {path.name} cannot be read ({exc})"
        why = self._check(key, payload)
        if why is not None:
            return f"its payload {path.name} is not this sweep's item: {why}"
        self._checked = (key, payload)
        return None

    def verify(self, key: str) -> bool:
        """Check a finished item's payload against its checksum (once per store).

        Returns
        -------
        bool
            False if the item is not finished here or was refused (warned,
            and forgotten: it is recomputed); True otherwise.
        """
        record = self.record(key)
        if record is None:
            return False
        if key in self._verified or record.state != "done":
            return True
        why = self._refusal(record, key)
        if why is not None:
            self._refuse(key, "journal", why)
            return False
        self._verified.add(key)
        return True

    def keys(self) -> Iterator[str]:
        """Iterate over the keys of every recorded item (index order)."""
        yield from self._index
        yield from (k for k in self._unflushed if k not in self._index)

    def has(self, key: str) -> bool:
        """Whether ``key`` has a record (from the index, no line read)."""
        return key in self._unflushed or key in self._index

    def _indexed(self, key: str) -> ItemRecord | None:
        """Return the record of ``key``: unflushed, or read back from its journal line."""
        record = self._unflushed.get(key)
        if record is not None:
            return record
        pos = self._index.get(key)
        if pos is None:
            return None
        at, number = _where(pos)
        path = self._journals[number]
        reader = self._readers.get(number)
        if reader is None:
            try:
                reader = self._readers[number] = path.open("rb")
            except OSError:
                reader = None
        record = self._parse(read_line(reader or path, at), path)
        if record is None or record.key != key:
            raise ResultFileError(
                f"the sweep journal {path} changed while the store was open (the line of item "
                f"{key!r} is gone); reopen the store"
            )
        return record

    def records(self) -> dict[str, ItemRecord]:
        """Every item record of the store, by key (sorted)."""
        found = {k: self._indexed(k) for k in sorted(self.keys())}
        return {k: r for k, r in found.items() if r is not None}

    def needs_work(self, key: str, max_attempts: int) -> tuple[bool, int]:
        """Whether ``key`` must be (re)computed, and how many attempts were made.

        Parameters
        ----------
        key : str
            Item key.
        max_attempts : int
            Attempts allowed in total (e.g. 2: a failure is retried once).

        Returns
        -------
        tuple of (bool, int)
            ``(True, 0)`` for a new item, ``(True, n)`` for an item that failed
            ``n < max_attempts`` times, ``(False, n)`` for a done item or one
            that has used up its attempts.
        """
        if key not in self._unflushed:
            entry = self._index.get(check_key(key))
            if entry is None:
                return True, 0
            made = (entry & ((1 << _STATUS_SHIFT) - 1)) >> 1
            if made < _MAX_ATTEMPTS:  # else saturated: read the line
                return (False, made) if entry & 1 else (made < max_attempts, made)
        rec = self.record(key)
        if rec is None:
            return True, 0
        if rec.state == "done":
            return False, rec.attempts
        return rec.attempts < max_attempts, rec.attempts

    def write_done(
        self, key: str, payload: R, summary: Mapping[str, object], *, attempts: int = 1
    ) -> ItemRecord:
        """Save a finished item written here: payload first, then its record.

        Returns
        -------
        ItemRecord
            The record written.
        """
        prev = self.record(key)
        target = self.payload_path(key)
        if self._encode is not None:
            data = self._encode(payload)
            write_unsynced(target, data)
            checksum = hashlib.sha256(data).hexdigest()
        else:
            self._save(payload, target)
            checksum = sha256_file(target)
        record = ItemRecord(
            key=key,
            state="done",
            attempts=attempts,
            reasons=prev.reasons if prev is not None else (),
            summary=json_roundtrip(dict(summary)),
            payload=target.relative_to(self.items_dir).as_posix(),
            sweep=self.binding,
            checksum=checksum,
        )
        self._commit(record, target)
        return record

    def accept(self, key: str, written: WrittenItem, *, attempts: int) -> ItemRecord | None:
        """Record an item whose payload a worker wrote, after checking the file.

        Returns
        -------
        ItemRecord or None
            The record, or ``None`` if the file is missing, misplaced or does
            not match the worker's checksum: the item is refused (with a
            :class:`~youbot_opt.exceptions.YoubotOptWarning`) and not recorded.
        """
        target = self.payload_path(key)
        expected = target.relative_to(self.items_dir).as_posix()
        why = None
        if written.payload != expected:
            why = f"the worker wrote {written.payload!r}, not {expected!r}"
        else:
            try:
                if sha256_file(target) != written.checksum:
                    why = f"its payload {expected} does not match the checksum its worker reported"
            except FileNotFoundError:
                why = f"its payload {expected} is missing"
        if why is not None:  # not recorded; the caller records a failed attempt and reruns
            warnings.warn(
                f"refused item {key!r} of the sweep in {self.directory} (worker-written: "
                f"{why}); it is recomputed",
                YoubotOptWarning,
                stacklevel=2,
            )
            _log.warning("refused sweep item %s in %s: %s", key, self.directory, why)
            return None
        prev = self.record(key)
        record = ItemRecord(
            key=key,
            state="done",
            attempts=attempts,
            reasons=prev.reasons if prev is not None else (),
            summary=json_roundtrip(dict(written.summary)),
            payload=expected,
            sweep=self.binding,
            checksum=written.checksum,
        )
        self._commit(record, target)
        return record

    def write_failed(self, key: str, reason: str, *, attempts: int) -> ItemRecord:
        """Record a failed attempt of ``key`` with its reason.

        Returns
        -------
        ItemRecord
            The record written.
        """
        prev = self.record(key)
        reasons = (*(prev.reasons if prev is not None else ()), str(reason))
        record = ItemRecord(
            key=key, state="failed", attempts=attempts, reasons=reasons, sweep=self.binding
        )
        self._commit(record, None)
        return record

    def _commit(self, record: ItemRecord, payload: Path | None) -> None:
        key = record.key
        self._refused.discard(key)
        old = self._indexed(key) if self.has(key) else None
        self._digest_sum = (
            self._digest_sum - (0 if old is None else _digest(old)) + _digest(record)
        ) % _DIGEST_MOD
        self._unflushed[key] = record
        line = encode_line({**record.to_json(), "t": time.time_ns()})
        self._lines.append((key, record.state, record.attempts, line))
        if payload is not None:
            self._files.append(payload)
        if (
            not self._group
            or len(self._lines) >= GROUP_ITEMS
            or time.monotonic() - self._last_flush >= self._window
        ):
            self.flush()

    def flush(self) -> None:
        """Make the recorded items durable: their payloads first, then their journal lines."""
        tic = time.monotonic()
        if self._lines:
            sync_folder(self.items_dir, self._files)
            if self._journal is None:
                self._journal = JournalWriter(self.items_dir / JOURNAL)
            if self._journal.path not in self._journals[-1:]:
                self._journals.append(self._journal.path)
            number = len(self._journals) - 1
            if number >= _FILE_BIT:  # pragma: no cover - 65536 runs or shards on one store
                raise ResultFileError(
                    f"the sweep in {self.directory} has {number} journal files; reopen it "
                    "without shards running to merge them"
                )
            offset = self._journal.append([item[-1] for item in self._lines])
            for key, state, attempts, line in self._lines:  # durable: read back when asked for
                self._index[key] = _entry(offset, number, state, attempts)
                offset += len(line)
            self._lines, self._files = [], []
            self._unflushed.clear()
            # Wait ~10x a flush's cost before the next (<= 10 % of the time spent
            # flushing), never longer than GROUP_SECONDS: slow items flush one by one.
            cost = time.monotonic() - tic
            self._window = min(GROUP_SECONDS, _FLUSH_SHARE * cost)
        self._last_flush = time.monotonic()

    @contextlib.contextmanager
    def grouped(self) -> Iterator[SweepStore]:
        """Within this context, items become durable in groups; all of them at its exit.

        A group is flushed when it holds :data:`GROUP_ITEMS` items or when
        ten times the cost of the last flush, at most :data:`GROUP_SECONDS`,
        has passed since it (so slow items are each durable as they finish);
        the exit flushes the rest, also on an exception.
        """
        self._group += 1
        try:
            yield self
        finally:
            self._group -= 1
            self.flush()

    def close(self) -> None:
        """Flush and close the journal (safe to call more than once)."""
        self.flush()
        self._journal = None  # a later write starts a new journal file
        self._close_readers()

    def _close_readers(self) -> None:
        readers, self._readers = self._readers, {}
        for fh in readers.values():
            fh.close()

    def __del__(self) -> None:
        with contextlib.suppress(Exception):
            self._close_readers()

    def fingerprint(self, keys: Iterable[str], extra: Mapping[str, object]) -> str:
        """SHA-256 naming the records of ``keys`` as they are now (state, attempts, checksum).

        With ``extra`` (e.g. a selection rule's tolerances) it names what a
        selection over these items depends on (see :meth:`save_selection`).
        """
        digest = hashlib.sha256(json.dumps(extra, sort_keys=True).encode())
        for key in keys:
            rec = self.record(key)
            line = "-" if rec is None else f"{rec.state}:{rec.attempts}:{rec.checksum}"
            digest.update(f"{key}={line}\n".encode())
        return digest.hexdigest()

    def count(self) -> int:
        """Return the number of items with a record (from the index)."""
        return len(self._index) + sum(1 for k in self._unflushed if k not in self._index)

    def fingerprint_all(self, extra: Mapping[str, object]) -> str:
        """SHA-256 naming every record of the store as it is now, and ``extra``; no line read.

        The store keeps the sum (mod 2^256) of one SHA-256 digest per record
        (key, state, attempts, checksum) up to date as records are written,
        replaced or refused, so this costs nothing per item; any change of a
        record changes it. Equal to :meth:`fingerprint` in meaning (not in
        value) when ``keys`` are every key of the store: callers use it after
        checking :meth:`count`.
        """
        digest = hashlib.sha256(json.dumps(extra, sort_keys=True).encode())
        digest.update(f"all:{self.count()}:{self._digest_sum:064x}".encode())
        return digest.hexdigest()

    def save_selection(self, fingerprint: str, clusters: Clusters) -> None:
        """Save the optima chosen over the items named by ``fingerprint`` (``DIR/optima.json``).

        The :class:`~youbot_opt.sweeps.selection.Clusters` is saved as its
        representatives and member counts, its members in
        ``DIR/optima-<fingerprint[:16]>.sqlite`` (written first).
        """
        body: dict[str, Any] = {
            "schema": "youbot_opt.sweep_optima",
            "schema_version": SCHEMA_VERSION,
            "binding": self.binding,
            "fingerprint": fingerprint,
        }
        members = self.directory / f"optima-{fingerprint[:16]}.sqlite"
        clusters.save(members)
        body["representatives"] = list(clusters.representatives)
        body["counts"] = list(clusters.counts)
        body["members"] = members.name
        atomic_write_bytes(self.directory / _OPTIMA, json.dumps(body).encode())
        for old in self.directory.glob("optima-*.sqlite"):  # earlier selections' members
            if old.name != members.name:
                with contextlib.suppress(OSError):
                    old.unlink()

    def selection(self, fingerprint: str) -> Clusters | None:
        """Return the optima saved for exactly these items (``None``: none, or items changed)."""
        try:
            data = json.loads((self.directory / _OPTIMA).read_text(encoding="utf-8"))
        except (OSError, ValueError):
            return None
        if not isinstance(data, dict) or data.get("binding") != self.binding:
            return None
        if data.get("fingerprint") != fingerprint:
            return None
        reps, counts, name = data.get("representatives"), data.get("counts"), data.get("members")
        if not (
            isinstance(reps, list)
            and isinstance(counts, list)
            and isinstance(name, str)
            and len(reps) == len(counts)
            and all(isinstance(k, str) for k in reps)
            and all(isinstance(n, int) and n >= 1 for n in counts)
            and name == f"optima-{fingerprint[:16]}.sqlite"
        ):
            return None  # another selection, or one of 0.1.0 (lists of keys): chosen again
        return Clusters.open(self.directory / name, reps, counts)

    def load(self, key: str) -> R:
        """Load the payload of a done item (checked against its checksum first).

        Raises
        ------
        ResultFileError
            If the item is not done, or its payload is missing, refused or unreadable.
        """
        rec = self.record(key)
        if rec is None or rec.state != "done" or rec.payload is None:
            raise ResultFileError(f"item {key!r} of {self.directory} has no stored result")
        path = self.items_dir / rec.payload
        if not path.exists():
            raise ResultFileError(
                f"item {key!r} is recorded as done but its payload {path} is missing; "
                "delete its record to recompute it"
            )
        if not self.verify(key):
            raise ResultFileError(
                f"item {key!r} of {self.directory} was refused (its payload {path} does not "
                "match its checksum or its sweep's problem); rerun the sweep to recompute it"
            )
        checked, self._checked = self._checked, None
        if checked is not None and checked[0] == key:
            return checked[1]
        return self._load(path)


_MISSING = object()

VERIFIED_CACHE = 4096
"""Payload checks a fan-out store remembers (a forgotten one is re-hashed when loaded again)."""


class _RecentKeys:
    """A set of keys holding at most ``bound`` of them (the most recently added; ``None``: all)."""

    def __init__(self, bound: int | None) -> None:
        self._keys: OrderedDict[str, None] = OrderedDict()
        self._bound = bound

    def __contains__(self, key: object) -> bool:
        return key in self._keys

    def __len__(self) -> int:
        return len(self._keys)

    def add(self, key: str) -> None:
        self._keys[key] = None
        self._keys.move_to_end(key)
        if self._bound is not None and len(self._keys) > self._bound:
            self._keys.popitem(last=False)


_DIGEST_MOD = 1 << 256


def _digest(record: ItemRecord) -> int:
    """One record's share of :meth:`SweepStore.fingerprint_all` (its SHA-256 as an int)."""
    text = f"{record.key}={record.state}:{record.attempts}:{record.checksum}"
    return int.from_bytes(hashlib.sha256(text.encode()).digest(), "big")


def _same(a: Any, b: Any) -> bool:
    """Equality of JSON values with NaN equal to NaN."""
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return True
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    return bool(a == b)
