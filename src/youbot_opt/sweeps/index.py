"""The key index of a sweep store, on disk: ``key -> int`` in a private SQLite database.

A schema-3 :class:`~youbot_opt.sweeps.store.SweepStore` keeps one integer
per item (where its journal line is, state, attempts). A ``dict`` costs ~140 B
per item; :class:`DiskIndex` keeps it in a private temporary SQLite database
(``sqlite3.connect("")``: deleted when closed, pages beyond a 2 MiB cache
spill to a temporary file), so the driver's memory does not grow with the
sweep. A cache of the journal, rebuilt at every open: no durability needed.
Rationale and figures: ``docs/scaling.md``.

    index = DiskIndex(); index["a"] = 7; assert index.get("a") == 7
"""

from __future__ import annotations

import sqlite3
import threading
from collections.abc import Iterator, MutableMapping

__all__ = ["CACHE_KIB", "DiskIndex"]

CACHE_KIB = 2048
"""SQLite page cache of one index [KiB]; the rest of the index stays on disk."""

_PAGE = 1024
"""Keys read per query while iterating (the index may change between pages)."""


class DiskIndex(MutableMapping[str, int]):
    """A ``str -> int`` mapping in a private temporary SQLite database.

    Iteration is in key order and tolerates changes made while iterating
    (keys are read :data:`_PAGE` at a time after the last one seen). Values
    are signed 64-bit integers. Safe to use from several threads (one lock).
    """

    def __init__(self) -> None:
        self._lock = threading.Lock()
        db = sqlite3.connect("", isolation_level=None, check_same_thread=False)
        db.execute(f"PRAGMA cache_size = -{CACHE_KIB}")
        db.execute("PRAGMA journal_mode = OFF")
        db.execute("PRAGMA synchronous = OFF")
        db.execute("CREATE TABLE idx (k TEXT PRIMARY KEY, v INTEGER NOT NULL) WITHOUT ROWID")
        self._db: sqlite3.Connection | None = db

    def _conn(self) -> sqlite3.Connection:
        if self._db is None:
            raise ValueError("the sweep index is closed")
        return self._db

    def __getitem__(self, key: str) -> int:
        got = self.get(key)
        if got is None:
            raise KeyError(key)
        return got

    def get(self, key: str, default: int | None = None) -> int | None:  # type: ignore[override]
        """Return the value of ``key``, or ``default`` (one indexed lookup)."""
        if not isinstance(key, str):
            return default
        with self._lock:
            row = self._conn().execute("SELECT v FROM idx WHERE k = ?", (key,)).fetchone()
        return default if row is None else int(row[0])

    def __setitem__(self, key: str, value: int) -> None:
        with self._lock:
            self._conn().execute(
                "INSERT INTO idx (k, v) VALUES (?, ?) ON CONFLICT (k) DO UPDATE SET v = excluded.v",
                (key, int(value)),
            )

    def __delitem__(self, key: str) -> None:
        with self._lock:
            cur = self._conn().execute("DELETE FROM idx WHERE k = ?", (key,))
        if cur.rowcount == 0:
            raise KeyError(key)

    def __contains__(self, key: object) -> bool:
        return isinstance(key, str) and self.get(key) is not None

    def __iter__(self) -> Iterator[str]:
        last: str | None = None
        while True:
            with self._lock:
                db = self._conn()
                if last is None:
                    rows = db.execute("SELECT k FROM idx ORDER BY k LIMIT ?", (_PAGE,)).fetchall()
                else:
                    rows = db.execute(
                        "SELECT k FROM idx WHERE k > ? ORDER BY k LIMIT ?", (last, _PAGE)
                    ).fetchall()
            if not rows:
                return
            for (key,) in rows:
                yield key
            last = rows[-1][0]

    def __len__(self) -> int:
        with self._lock:
            return int(self._conn().execute("SELECT count(*) FROM idx").fetchone()[0])

    def clear(self) -> None:
        """Remove every key."""
        with self._lock:
            self._conn().execute("DELETE FROM idx")

    def close(self) -> None:
        """Close (and so delete) the database; the index is unusable afterwards."""
        with self._lock:
            db, self._db = self._db, None
        if db is not None:
            db.close()

    def __del__(self) -> None:
        try:
            self.close()
        except Exception:  # noqa: BLE001, S110 - interpreter shutdown
            pass
