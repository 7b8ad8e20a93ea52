"""A sweep's results on disk, one file per finished item, safe against kills.

A :class:`SweepStore` owns ``DIR/manifest.json`` (the sweep's kind and
defining parameters) and ``DIR/items/<key>.json`` plus ``<key><suffix>`` (one
record and one payload per finished item, saved by caller-supplied callables).
Every write is atomic; reopening a directory resumes it when the parameters
match and refuses it otherwise. Crash safety, resuming and the schema-2
binding are explained in docs/design.md, "Module notes".

>>> store = SweepStore(out, kind="pareto", params=params, save=save, load=load)  # doctest: +SKIP
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import logging
import math
import os
import re
import warnings
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

from youbot_opt._files import TMP_PREFIX, atomic_write_bytes, check_schema_header, json_roundtrip
from youbot_opt.exceptions import ParameterError, ResultFileError, YoubotOptWarning

__all__ = ["SweepStore", "ItemRecord", "SCHEMA_VERSION", "atomic_write_bytes", "check_key"]

_log = logging.getLogger(__name__)

SCHEMA_VERSION = 2
"""Version of the manifest and item-record format written by this module (2: bound items)."""

_MANIFEST = "manifest.json"
_ITEMS = "items"
_KEY = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]{0,99}$")

ItemState = Literal["done", "failed"]


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
    )
    return data


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
        File name of the payload inside ``items/`` (``None`` for failures).
    sweep : str or None
        Binding of the sweep that wrote the record (``None``: schema 1).
    checksum : str or None
        SHA-256 (hex) of the payload file (``None`` for failures and schema 1).
    """

    key: str
    state: ItemState
    attempts: int
    reasons: tuple[str, ...] = ()
    summary: Mapping[str, Any] = field(default_factory=dict)
    payload: str | None = None
    sweep: str | None = None
    checksum: str | None = None

    def to_json(self) -> dict[str, Any]:
        """Return the record as written to disk."""
        return {
            "schema": "youbot_opt.sweep_item",
            "schema_version": SCHEMA_VERSION,
            "key": self.key,
            "state": self.state,
            "attempts": self.attempts,
            "reasons": list(self.reasons),
            "summary": dict(self.summary),
            "payload": self.payload,
            "sweep": self.sweep,
            "checksum": self.checksum,
        }

    @classmethod
    def from_json(cls, data: Mapping[str, Any], path: Path) -> ItemRecord:
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
            attempts = int(data["attempts"])
            if attempts < 1:
                raise ValueError(f"attempts {attempts}")
            payload = data.get("payload")
            if state == "done" and not isinstance(payload, str):
                raise ValueError("a done item needs a payload file name")
            return cls(
                key=str(data["key"]),
                state=state,
                attempts=attempts,
                reasons=tuple(str(r) for r in data.get("reasons", ())),
                summary=dict(data.get("summary") or {}),
                payload=payload,
                sweep=None if data.get("sweep") is None else str(data["sweep"]),
                checksum=None if data.get("checksum") is None else str(data["checksum"]),
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise ResultFileError(f"item record {path} is corrupted: {exc}") from exc


class SweepStore:
    """Output directory of one sweep: manifest plus one record (and payload) per item.

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
        Writes an item's payload to ``path`` (must write atomically, as
        :func:`youbot_opt.trajopt.io.save_result` does).
    load : callable ``(path) -> payload``
        Reads a payload back; should raise ``ResultFileError`` on bad files.
    suffix : str
        Payload file suffix, e.g. ``".npz"``.
    clean : bool
        Remove leftover temporary files of killed writes (default). Shard
        runs sharing the folder pass ``False``; the collecting run cleans.

    Raises
    ------
    ParameterError
        If the directory holds a sweep with other parameters (the message lists them).
    ResultFileError
        If its manifest is corrupted or from a newer schema.
    """

    def __init__(
        self,
        directory: str | os.PathLike[str],
        *,
        kind: str,
        params: Mapping[str, Any],
        save: Callable[[Any, Path], object],
        load: Callable[[Path], Any],
        suffix: str = ".npz",
        clean: bool = True,
    ) -> None:
        self.directory = Path(directory)
        self.kind = str(kind)
        self.params: dict[str, Any] = json_roundtrip(dict(params))
        self._save = save
        self._load = load
        self.suffix = suffix
        self.items_dir = self.directory / _ITEMS
        self.items_dir.mkdir(parents=True, exist_ok=True)
        if clean:  # not in shard runs: another shard may be writing one right now
            self._clean_temporaries()
        self.binding = hashlib.sha256(
            json.dumps({"kind": self.kind, "params": self.params}, sort_keys=True).encode()
        ).hexdigest()
        self._verified: set[str] = set()  # records checked (or written) by this store
        self._refused: set[str] = set()  # records refused: recomputed, never loaded
        manifest = self.directory / _MANIFEST
        if manifest.exists():
            data = _read_json(manifest, "sweep manifest")
            self._check_manifest(data)
            # A schema-1 store has no binding: its items resume unverified, as they always did.
            self.verifies = int(data.get("schema_version", 1)) >= 2
            self.resumed = True
        else:
            self.verifies = True
            body = {
                "schema": "youbot_opt.sweep",
                "schema_version": SCHEMA_VERSION,
                "kind": self.kind,
                "params": self.params,
                "binding": self.binding,
            }
            atomic_write_bytes(manifest, json.dumps(body, indent=1).encode())
            self.resumed = False

    # ---------------------------------------------------------------- manifest
    def _clean_temporaries(self) -> None:
        # Ours (".tmp-<name>.<random>", youbot_opt._files) and the older
        # ".<name>.<random>.tmp" ones that youbot_opt.trajopt.io used to leave.
        for folder in (self.directory, self.items_dir):
            for tmp in (*folder.glob(f"{TMP_PREFIX}*"), *folder.glob(".*.tmp")):
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

    # ------------------------------------------------------------------ items
    def _record_path(self, key: str) -> Path:
        return self.items_dir / f"{check_key(key)}.json"

    def payload_path(self, key: str) -> Path:
        """Where the payload of ``key`` is (or will be) stored."""
        return self.items_dir / f"{check_key(key)}{self.suffix}"

    def record(self, key: str) -> ItemRecord | None:
        """Return the record of ``key``, or ``None`` if the item has not finished yet.

        Raises
        ------
        ResultFileError
            If the record is corrupted or from a newer schema.
        """
        path = self._record_path(key)
        if not path.exists():
            return None
        record = ItemRecord.from_json(_read_json(path, "item record"), path)
        if not self.verifies:
            if record.key != key:
                raise ResultFileError(f"item record {path} is for key {record.key!r}, not {key!r}")
            return record
        if key in self._verified:
            return record
        if key in self._refused:
            return None
        why = self._refusal(record, key)
        if why is not None:
            self._refused.add(key)
            warnings.warn(
                f"refused item {key!r} of the sweep in {self.directory} ({path.name}: {why}); "
                "it is recomputed",
                YoubotOptWarning,
                stacklevel=2,
            )
            _log.warning("refused sweep item %s: %s", path, why)
            return None
        self._verified.add(key)
        return record

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
        if record.payload != self.payload_path(key).name:
            return f"it points to payload {record.payload!r}"
        path = self.items_dir / str(record.payload)
        if not path.exists():
            return f"its payload {path.name} is missing"
        if record.checksum != _sha256(path):
            return f"its payload {path.name} does not match its checksum (edited or torn)"
        return None

    def records(self) -> dict[str, ItemRecord]:
        """Every item record in the directory, by key (sorted)."""
        out: dict[str, ItemRecord] = {}
        for path in sorted(self.items_dir.glob("*.json")):
            rec = self.record(path.stem)
            if rec is not None:
                out[rec.key] = rec
        return out

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
        rec = self.record(key)
        if rec is None:
            return True, 0
        if rec.state == "done":
            return False, rec.attempts
        return rec.attempts < max_attempts, rec.attempts

    def write_done(
        self, key: str, payload: Any, summary: Mapping[str, Any], *, attempts: int = 1
    ) -> ItemRecord:
        """Save a finished item: payload first, then its record (both atomic).

        Returns
        -------
        ItemRecord
            The record written.
        """
        prev = self.record(key)
        target = self.payload_path(key)
        self._save(payload, target)
        record = ItemRecord(
            key=key,
            state="done",
            attempts=attempts,
            reasons=prev.reasons if prev is not None else (),
            summary=json_roundtrip(dict(summary)),
            payload=target.name,
            sweep=self.binding,
            checksum=_sha256(target),
        )
        self._write_record(record)
        self._refused.discard(key)
        self._verified.add(key)
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
        self._write_record(record)
        self._refused.discard(key)
        self._verified.add(key)
        return record

    def _write_record(self, record: ItemRecord) -> None:
        body = json.dumps(record.to_json(), indent=1, allow_nan=True).encode()
        atomic_write_bytes(self._record_path(record.key), body)

    def load(self, key: str) -> Any:
        """Load the payload of a done item.

        Raises
        ------
        ResultFileError
            If the item is not done, or its payload is missing or unreadable.
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
        return self._load(path)


_MISSING = object()


def _sha256(path: Path) -> str:
    """SHA-256 (hex) of a file's bytes."""
    digest = hashlib.sha256()
    with path.open("rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def _same(a: Any, b: Any) -> bool:
    """Equality of JSON values with NaN equal to NaN."""
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return True
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    return bool(a == b)
