"""Tests of youbot_opt.sweeps.store: atomic writes, resume, manifest checks, schema errors.

Also the schema-3 layout: payloads fanned out into ``items/<hh>/``, the summary
journal (torn and foreign lines refused), group commits, and the flat stores of 0.1.0
refused (``scripts/migrate_0_1_0.py`` carries them forward).
"""

from __future__ import annotations

import io
import json
import os
from pathlib import Path

import numpy as np
import pytest

from youbot_opt.exceptions import ParameterError, ResultFileError, YoubotOptWarning
from youbot_opt.sweeps.journal import encode_line
from youbot_opt.sweeps.store import SCHEMA_VERSION, SweepStore, atomic_write_bytes, stored_records


def _save(payload: np.ndarray, path: Path) -> None:
    """Payload writer for the tests: an .npy file, written atomically."""
    buf = io.BytesIO()
    np.save(buf, payload)
    atomic_write_bytes(path, buf.getvalue())


def _load(path: Path) -> np.ndarray:
    try:
        return np.load(path)
    except ValueError as exc:
        raise ResultFileError(f"bad payload {path}") from exc


def _store(tmp_path: Path, **params: object) -> SweepStore:
    return SweepStore(
        tmp_path / "sweep",
        kind="demo",
        params={"seed": 0, "betas": [0.1, 0.2], **params},
        save=_save,
        load=_load,
        suffix=".npy",
    )


def test_atomic_write_replaces_and_leaves_no_temporary(tmp_path: Path) -> None:
    """An atomic write replaces the content and leaves no temporary file behind."""
    target = tmp_path / "f.bin"
    atomic_write_bytes(target, b"old")
    atomic_write_bytes(target, b"new content")
    assert target.read_bytes() == b"new content"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["f.bin"]


def test_atomic_write_interrupted_keeps_old_file(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A write that dies before the rename keeps the old content intact (no torn file)."""
    target = tmp_path / "f.bin"
    atomic_write_bytes(target, b"old")

    def boom(src: str, dst: str) -> None:
        raise KeyboardInterrupt  # stands in for a kill between write and rename

    monkeypatch.setattr(os, "replace", boom)
    with pytest.raises(KeyboardInterrupt):
        atomic_write_bytes(target, b"half-written new content")
    monkeypatch.undo()
    assert target.read_bytes() == b"old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["f.bin"]


def test_done_items_are_loaded_on_reopen(tmp_path: Path) -> None:
    """A reopened store reports done items as finished and returns their payload bit for bit."""
    store = _store(tmp_path)
    payload = np.random.default_rng(0).normal(size=(5, 3))
    store.write_done("item_1", payload, {"objective": 1.5})
    again = _store(tmp_path)
    assert again.resumed and not store.resumed
    assert again.needs_work("item_1", 2) == (False, 1)
    assert again.needs_work("item_2", 2) == (True, 0)
    np.testing.assert_array_equal(again.load("item_1"), payload)  # exact: binary round trip
    assert again.record("item_1").summary == {"objective": 1.5}
    assert list(again.records()) == ["item_1"]


def test_failed_items_are_retried_until_max_attempts(tmp_path: Path) -> None:
    """A failure recorded once is retried (max_attempts=2); after two it is final, reasons kept."""
    store = _store(tmp_path)
    store.write_failed("x", "worker crashed", attempts=1)
    assert store.needs_work("x", 2) == (True, 1)
    store.write_failed("x", "worker crashed again", attempts=2)
    assert store.needs_work("x", 2) == (False, 2)
    assert store.record("x").reasons == ("worker crashed", "worker crashed again")
    store.write_done("y", np.zeros(1), {}, attempts=2)
    assert store.record("y").state == "done"


def test_orphan_payload_without_record_is_recomputed(tmp_path: Path) -> None:
    """A payload written just before a kill (no record yet) does not count as finished."""
    store = _store(tmp_path)
    store.payload_path("z").parent.mkdir(exist_ok=True)
    _save(np.ones(2), store.payload_path("z"))
    assert store.needs_work("z", 2) == (True, 0)
    assert _store(tmp_path).needs_work("z", 2) == (True, 0)


def test_leftover_temporaries_are_removed_on_open(tmp_path: Path) -> None:
    """Temporary files left by a killed write are cleaned when the store is reopened."""
    store = _store(tmp_path)
    stray = store.items_dir / ".tmp-item_1.json.abc123"
    stray.write_bytes(b"{partial")
    _store(tmp_path)
    assert not stray.exists()


def test_resume_with_other_parameters_is_an_error(tmp_path: Path) -> None:
    """Reopening with different parameters names each difference; another kind is refused."""
    _store(tmp_path)
    with pytest.raises(ParameterError, match=r"seed: stored 0, now 1"):
        _store(tmp_path, seed=1)
    with pytest.raises(ParameterError, match="holds a 'demo' sweep"):
        SweepStore(tmp_path / "sweep", kind="pareto", params={}, save=_save, load=_load)


def test_bad_manifest_raises_result_file_error(tmp_path: Path) -> None:
    """A newer-schema or corrupted manifest stops the resume with ResultFileError."""
    _store(tmp_path)
    manifest = tmp_path / "sweep" / "manifest.json"
    data = json.loads(manifest.read_text())
    manifest.write_text(json.dumps({**data, "schema_version": SCHEMA_VERSION + 1}))
    with pytest.raises(ResultFileError, match="newer"):
        _store(tmp_path)
    manifest.write_text('{"schema_version": 1, "kind": "demo", "para')
    with pytest.raises(ResultFileError, match="not valid JSON"):
        _store(tmp_path)


def test_missing_payload_of_done_item_raises(tmp_path: Path) -> None:
    """A done record whose payload vanished raises ResultFileError naming the file."""
    store = _store(tmp_path)
    store.write_done("a", np.zeros(3), {})
    store.payload_path("a").unlink()
    with pytest.raises(ResultFileError, match="missing"):
        store.load("a")


@pytest.mark.parametrize("key", ["", "../x", "a/b", ".hidden", "x" * 101, "sp ace"])
def test_bad_keys_are_refused(tmp_path: Path, key: str) -> None:
    """Keys that are not file-name safe raise ParameterError."""
    store = _store(tmp_path)
    with pytest.raises(ParameterError, match="item key"):
        store.write_failed(key, "r", attempts=1)


def test_payloads_fan_out_and_the_journal_holds_the_records(tmp_path: Path) -> None:
    """Schema 3: payloads in items/<hh>/ (hh: SHA-256 of the key), records in the journal."""
    import hashlib

    store = _store(tmp_path)
    with store.grouped():
        for i in range(40):
            store.write_done(f"item_{i:03d}", np.full(2, float(i)), {"i": i})
    hh = hashlib.sha256(b"item_007").hexdigest()[:2]
    assert store.payload_path("item_007") == store.items_dir / hh / "item_007.npy"
    assert store.record("item_007").payload == f"{hh}/item_007.npy"
    folders = {p.parent.name for p in store.items_dir.glob("*/*.npy")}
    assert len(folders) > 10  # 40 keys over 256 folders: spread out, not one flat folder
    assert not list(store.items_dir.glob("*.json")) and not list(store.items_dir.glob("*.npy"))
    stray = store.items_dir / hh / ".tmp-item_999.npy.x1y2"  # a worker killed mid-write
    stray.write_bytes(b"half")
    again = _store(tmp_path)
    assert not stray.exists()
    assert [r.summary["i"] for r in again.records().values()] == list(range(40))
    np.testing.assert_array_equal(again.load("item_039"), np.full(2, 39.0))
    assert {r.key for r in stored_records(tmp_path / "sweep")} == set(again.records())


def test_grouped_writes_become_durable_at_the_group_end(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Inside grouped() the journal lags behind; its exit (also by an exception) flushes."""
    from youbot_opt.sweeps import store as store_module

    monkeypatch.setattr(store_module, "GROUP_SECONDS", 60.0)  # no flush by time in this test
    store = _store(tmp_path)
    with pytest.raises(KeyboardInterrupt), store.grouped():
        store.write_done("a", np.zeros(1), {})
        store.write_failed("b", "crashed", attempts=1)
        assert _store(tmp_path).records() == {}  # not yet in the journal: a kill recomputes them
        raise KeyboardInterrupt
    assert list(_store(tmp_path).records()) == ["a", "b"]
    store.write_done("c", np.zeros(1), {})  # outside a group: durable at once
    assert "c" in _store(tmp_path).records()


def test_torn_and_foreign_journal_lines_are_refused(tmp_path: Path) -> None:
    """A torn last line, an edited line and a line of another sweep are skipped with a warning."""
    store = _store(tmp_path)
    for key in ("a", "b", "c"):
        store.write_done(key, np.zeros(1), {"k": key})
    store.close()
    journal = next((store.items_dir / "journal").glob("*.jsonl"))
    lines = journal.read_bytes().splitlines(keepends=True)
    edited = lines[1].replace(b'"k":"b"', b'"k":"B"')  # same length, checksum now wrong
    foreign = encode_line({**json.loads(lines[2].split(b" ", 1)[1]), "sweep": "0" * 64})
    journal.write_bytes(lines[0] + edited + foreign + b'0123456789abcdef {"key":')
    refused = r"2 torn or corrupted journal line.*and items 'c': 1 line.*another sweep"
    with pytest.warns(YoubotOptWarning, match=refused):
        again = _store(tmp_path)
    assert list(again.records()) == ["a"]
    assert again.needs_work("b", 2) == (True, 0) and again.needs_work("c", 2) == (True, 0)
    import warnings

    with warnings.catch_warnings():  # the journal was compacted: refused once, not every time
        warnings.simplefilter("error", YoubotOptWarning)
        assert list(_store(tmp_path).records()) == ["a"]


def test_a_payload_not_matching_its_journal_checksum_is_refused(tmp_path: Path) -> None:
    """verify() refuses (warning) an edited payload; the item then needs work again."""
    store = _store(tmp_path)
    store.write_done("a", np.arange(3.0), {})
    _save(np.arange(3.0) + 1, store.payload_path("a"))  # edited after it was recorded
    again = _store(tmp_path)
    with pytest.warns(YoubotOptWarning, match=r"refused item 'a'.*checksum"):
        assert not again.verify("a")
    assert again.needs_work("a", 2) == (True, 0)


@pytest.mark.parametrize("version", [1, 2])
def test_flat_stores_of_0_1_0_are_refused_naming_the_migration(
    tmp_path: Path, version: int
) -> None:
    """A flat store (schema 1 or 2, 0.1.0) is refused; the message names the script and folder."""
    folder = tmp_path / "sweep"
    folder.mkdir()
    body = {"schema": "youbot_opt.sweep", "schema_version": version, "kind": "demo",
            "params": {"seed": 0, "betas": [0.1, 0.2]}}  # fmt: skip
    (folder / "manifest.json").write_text(json.dumps(body))
    want = (
        rf"written by youbot_opt 0\.1\.0 \(schema {version}\); "
        rf"run `python scripts/migrate_0_1_0\.py {folder}` to carry it forward"
    )
    with pytest.raises(ResultFileError, match=want):
        _store(tmp_path)
