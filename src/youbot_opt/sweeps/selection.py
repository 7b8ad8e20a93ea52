"""The distinct optima of a ``keep_results=False`` sweep, chosen in bounded memory.

:func:`stream_optima` applies the greedy rule of
:func:`~youbot_opt.sweeps.optima.select_optima` (items by increasing
objective, ties in item order, each joining the first cluster whose
representative is near) without a list of the items: the ranking is an
external sort in a private SQLite database, members go to a table of it.
:class:`Clusters` holds representatives and counts; members are read back on
demand, and saved next to ``optima.json`` so a resume need not choose again.

    kept, clusters = stream_optima(items, rule, load); clusters[0][0]  # the best key
"""

from __future__ import annotations

import contextlib
import math
import os
import sqlite3
import uuid
from collections.abc import Callable, Hashable, Iterator, Mapping, Sequence
from pathlib import Path
from typing import TypeVar

from youbot_opt._files import fsync_dir
from youbot_opt.sweeps.index import CACHE_KIB
from youbot_opt.sweeps.lazy import LazySequence, ListEquality
from youbot_opt.sweeps.optima import KeepRule

__all__ = ["ClusterKeys", "Clusters", "stream_optima"]

T = TypeVar("T")

_BATCH = 4096
"""Rows written or read per SQLite call."""


def _connect(path: str) -> sqlite3.Connection:
    db = sqlite3.connect(path, isolation_level=None, check_same_thread=False)
    db.execute(f"PRAGMA cache_size = -{CACHE_KIB}")
    return db


class ClusterKeys(ListEquality, LazySequence[str]):
    """The keys of one cluster, its representative first, read from the membership table."""

    def __init__(self, owner: Clusters, number: int) -> None:
        self._owner, self._number = owner, number

    def __len__(self) -> int:
        return self._owner.counts[self._number]

    def _slice(self, s: slice) -> Sequence[str]:
        return list(self)[s]  # one pass over the table

    def _index_error(self, i: int, n: int) -> str:
        return f"cluster {self._number} has {n} member(s), got index {i}"

    def _item(self, j: int) -> str:
        if j == 0:
            return self._owner.representatives[self._number]
        return self._owner._member(self._number, j)

    def __iter__(self) -> Iterator[str]:
        return self._owner._members(self._number)

    def __repr__(self) -> str:
        return f"ClusterKeys({self[0]!r}, +{len(self) - 1} member(s))"


class Clusters(ListEquality, LazySequence[ClusterKeys]):
    """Distinct optima as keys: representatives and member counts in memory, members on disk.

    Attributes
    ----------
    representatives : list of str
        Key of each cluster's representative (its lowest-objective item),
        clusters in the order of :func:`~youbot_opt.sweeps.optima.select_optima`.
    counts : list of int
        Number of members of each cluster (the representative included).
    """

    def __init__(self, db: sqlite3.Connection, representatives: list[str], counts: list[int]):
        self._db = db
        self.representatives, self.counts = representatives, counts
        self._reps: dict[str, str] | None = None

    @classmethod
    def _new(cls) -> Clusters:
        db = _connect("")
        db.execute("PRAGMA journal_mode = OFF")
        db.execute("PRAGMA synchronous = OFF")
        db.execute(
            "CREATE TABLE m (c INTEGER NOT NULL, j INTEGER NOT NULL, k TEXT NOT NULL, "
            "PRIMARY KEY (c, j)) WITHOUT ROWID"
        )
        db.execute("CREATE INDEX m_k ON m (k)")  # optimum_of: a member's cluster
        return cls(db, [], [])

    @classmethod
    def open(cls, path: Path, representatives: list[str], counts: list[int]) -> Clusters | None:
        """Open saved members read-only; ``None`` if the file is missing or does not match."""
        if not path.is_file():
            return None
        try:
            db = sqlite3.connect(f"file:{path}?mode=ro", uri=True, check_same_thread=False)
            rows = db.execute("SELECT c, count(*) + 1 FROM m GROUP BY c").fetchall()
        except sqlite3.Error:
            return None
        stored = dict(rows)
        if any(stored.get(c, 1) != n for c, n in enumerate(counts)) or any(
            c >= len(counts) for c in stored
        ):
            db.close()
            return None
        return cls(db, representatives, counts)

    def save(self, path: Path) -> None:
        """Write the membership table to ``path`` (atomic and durable)."""
        tmp = path.with_name(f".tmp-{path.name}.{uuid.uuid4().hex[:8]}")
        try:
            dest = sqlite3.connect(tmp)
            try:
                self._db.backup(dest)
                dest.execute("PRAGMA journal_mode = DELETE")
            finally:
                dest.close()
            with tmp.open("rb+") as fh:
                os.fsync(fh.fileno())
            os.replace(tmp, path)
        finally:
            with contextlib.suppress(OSError):
                tmp.unlink()
        fsync_dir(path.parent)

    def optimum_of(self, key: str) -> str | None:
        """Key of the representative of ``key``'s cluster (``None``: in no cluster)."""
        if self._reps is None or len(self._reps) != len(self.representatives):
            self._reps = {k: k for k in self.representatives}
        if key in self._reps:
            return key
        row = self._db.execute("SELECT c FROM m WHERE k = ? LIMIT 1", (key,)).fetchone()
        return None if row is None else self.representatives[int(row[0])]

    def _add(self, rows: list[tuple[int, int, str]]) -> None:
        self._db.executemany("INSERT INTO m (c, j, k) VALUES (?, ?, ?)", rows)
        rows.clear()

    def _member(self, number: int, j: int) -> str:
        row = self._db.execute("SELECT k FROM m WHERE c = ? AND j = ?", (number, j)).fetchone()
        if row is None:
            raise IndexError(f"cluster {number} has no member {j} on disk")
        return str(row[0])

    def _members(self, number: int) -> Iterator[str]:
        yield self.representatives[number]
        last = 0
        while True:
            rows = self._db.execute(
                "SELECT j, k FROM m WHERE c = ? AND j > ? ORDER BY j LIMIT ?",
                (number, last, _BATCH),
            ).fetchall()
            if not rows:
                return
            yield from (str(k) for _, k in rows)
            last = rows[-1][0]

    def members_in_key_order(self, number: int) -> Iterator[str]:
        """Iterate over the keys of cluster ``number`` sorted by key (the representative included).

        One sorted read of the membership table (held open while iterating),
        for callers whose keys sort as their items' order (fixed-width indices).
        """
        if not 0 <= number < len(self.representatives):
            raise IndexError(f"{len(self.representatives)} cluster(s), got index {number}")
        rep: str | None = self.representatives[number]
        rows = self._db.execute("SELECT k FROM m WHERE c = ? ORDER BY k", (number,))
        try:
            while True:
                page = rows.fetchmany(_BATCH)
                if not page:
                    break
                for (key,) in page:
                    if rep is not None and rep < key:
                        yield rep
                        rep = None
                    yield str(key)
            if rep is not None:
                yield rep
        finally:
            rows.close()

    def __len__(self) -> int:
        return len(self.representatives)

    noun = "cluster"

    def _item(self, j: int) -> ClusterKeys:
        return ClusterKeys(self, j)

    def __repr__(self) -> str:
        return f"Clusters({len(self)} optima, {sum(self.counts)} member(s))"


def stream_optima(
    items: Mapping[str, T], rule: KeepRule[T], load: Callable[[str], T]
) -> tuple[dict[str, T], Clusters]:
    """Choose the distinct optima as ``select_optima`` does, in memory bounded by the optima.

    Parameters
    ----------
    items : mapping of str to item
        Light items (their summaries), by key; iterated twice at most.
    rule : KeepRule
        Objective, distance, tolerances and groups (tolerances checked when the
        rule was made).
    load : callable ``(key) -> item``
        The full item of a key; called only where ``select_optima`` calls it.

    Returns
    -------
    tuple of (dict, Clusters)
        The full representatives by key and the clusters, equal to
        ``select_optima``'s (same representatives, members, order).
    """
    out = Clusters._new()
    db = out._db
    db.execute("CREATE TEMP TABLE r (g INTEGER, f REAL, p INTEGER, k TEXT)")
    groups: dict[Hashable, int] = {}
    rows: list[tuple[int, float, int, str]] = []
    for pos, (key, item) in enumerate(items.items()):
        # groups numbered by first appearance, as select_optima orders them
        g = 0 if rule.group is None else groups.setdefault(rule.group(item), len(groups))
        f = rule.objective(item)
        if f is None or math.isnan(f):
            continue
        rows.append((g, float(f), pos, key))
        if len(rows) >= _BATCH:
            db.executemany("INSERT INTO r VALUES (?, ?, ?, ?)", rows)
            rows.clear()
    db.executemany("INSERT INTO r VALUES (?, ?, ?, ?)", rows)
    rows.clear()
    kept: dict[str, T] = {}
    members: list[tuple[int, int, str]] = []
    group = -1
    reps: list[tuple[float, int, T]] = []  # this group's representatives: objective, cluster, item
    # an external sort (SQLite spills to a temporary file), read row by row while the
    # members are written to another table of the same database
    ranked = db.execute("SELECT g, f, p, k FROM r ORDER BY g, f, p")
    while True:
        page = ranked.fetchmany(_BATCH)
        if not page:
            break
        for g, f, _, key in page:
            if g != group:
                group, reps = g, []
            if rule.distance is None:  # the best of each group, every other item its member
                if not reps:
                    full = load(key)
                    reps.append((f, len(out.representatives), full))
                    kept[key] = full
                    out.representatives.append(key)
                    out.counts.append(1)
                    continue
                number = reps[0][1]
            else:
                near = [r for r in reps if abs(f - r[0]) <= rule.obj_tol * max(1.0, abs(r[0]))]
                full = load(key)
                number = next(
                    (n for _, n, rep in near if rule.distance(full, rep) <= rule.dist_tol), -1
                )
                if number < 0:
                    reps.append((f, len(out.representatives), full))
                    kept[key] = full
                    out.representatives.append(key)
                    out.counts.append(1)
                    continue
            members.append((number, out.counts[number], key))
            out.counts[number] += 1
            if len(members) >= _BATCH:
                out._add(members)
    out._add(members)
    ranked.close()
    db.execute("DROP TABLE r")
    return kept, out
