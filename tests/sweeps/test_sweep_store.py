"""Tests of youbot_opt.sweeps.store: atomic writes, resume, manifest checks, schema errors."""

from __future__ import annotations

import io
import json
import os
from pathlib import Path

import numpy as np
import pytest

from youbot_opt.exceptions import ParameterError, ResultFileError
from youbot_opt.sweeps.store import SCHEMA_VERSION, SweepStore, atomic_write_bytes


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
    _save(np.ones(2), store.payload_path("z"))
    assert store.needs_work("z", 2) == (True, 0)


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


@pytest.mark.parametrize(
    "content, match",
    [
        (b"{not json", "not valid JSON"),
        (json.dumps({"key": "a"}).encode(), "schema_version"),
        (json.dumps({"schema_version": SCHEMA_VERSION + 1, "key": "a"}).encode(), "newer"),
        (
            json.dumps({"schema_version": SCHEMA_VERSION, "key": "a", "state": "?"}).encode(),
            "corrupted",
        ),
    ],
)
def test_bad_records_raise_result_file_error(tmp_path: Path, content: bytes, match: str) -> None:
    """Corrupted, schema-less, newer-schema or malformed records raise ResultFileError."""
    store = _store(tmp_path)
    (store.items_dir / "a.json").write_bytes(content)
    with pytest.raises(ResultFileError, match=match):
        store.record("a")
    with pytest.raises(ResultFileError):
        store.needs_work("a", 2)


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
