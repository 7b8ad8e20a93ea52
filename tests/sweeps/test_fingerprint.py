"""The store's incremental fingerprint (#15): kept up to date as records change, no line read.

Reference: the definition recomputed independently from the records on disk
(``stored_records`` reads the journal files themselves): the sum mod 2^256 of
SHA-256(``key=state:attempts:checksum``) over the sweep's records. Exact
equalities: the fingerprint is a pure function of the records.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import pytest

from youbot_opt.exceptions import YoubotOptWarning
from youbot_opt.sweeps.store import SweepStore, stored_records


def _store(out: Path) -> SweepStore:
    return SweepStore(
        out,
        kind="points",
        params={"n": 3},
        save=lambda v, p: p.write_bytes(v),
        load=lambda p: p.read_bytes(),
        suffix=".pt",
        encode=lambda v: v,
    )


def _reference(out: Path, extra: dict[str, object]) -> str:
    """The fingerprint of the records on disk, from its definition."""
    records = {r.key: r for r in stored_records(out)}.values()  # every line: the last wins
    total = 0
    for r in records:
        text = f"{r.key}={r.state}:{r.attempts}:{r.checksum}"
        total += int.from_bytes(hashlib.sha256(text.encode()).digest(), "big")
    digest = hashlib.sha256(json.dumps(extra, sort_keys=True).encode())
    digest.update(f"all:{len(records)}:{total % (1 << 256):064x}".encode())
    return digest.hexdigest()


def test_fingerprint_all_follows_every_change_and_survives_a_reopen(tmp_path: Path) -> None:
    out = tmp_path / "run"
    extra = {"obj_tol": 1e-6}
    store = _store(out)
    with store.grouped():
        store.write_done("a", b"1", {"f": 1.0})
        store.write_failed("b", "crashed", attempts=1)
        store.write_done("b", b"2", {"f": 2.0}, attempts=2)  # replaces b's failed record
        store.write_failed("c", "crashed", attempts=1)
        during = store.fingerprint_all(extra)  # unflushed records count too
    first = store.fingerprint_all(extra)
    assert during == first == _reference(out, extra) and store.count() == 3
    assert _store(out).fingerprint_all(extra) == first  # rebuilt from the journal: equal
    assert store.fingerprint_all({"obj_tol": 1e-3}) != first  # the rule is part of it

    store.write_done("c", b"3", {"f": 3.0}, attempts=2)  # a changed record
    second = store.fingerprint_all(extra)
    assert second != first and second == _reference(out, extra)
    assert _store(out).fingerprint_all(extra) == second

    # A payload edited on disk: the reopened store refuses the item when verifying it,
    # forgets it, and its fingerprint is the one without that record.
    reopened = _store(out)
    (out / "items" / str(reopened.record("a").payload)).write_bytes(b"edited")  # type: ignore[union-attr]
    with pytest.warns(YoubotOptWarning, match="refused item 'a'"):
        assert not reopened.verify("a")
    without_a = reopened.fingerprint_all(extra)
    assert without_a not in (first, second) and reopened.count() == 2
    reopened.write_done("a", b"1", {"f": 1.0})  # recomputed: the same record as before
    assert reopened.fingerprint_all(extra) == second == _reference(out, extra)
