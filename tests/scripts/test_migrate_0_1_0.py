"""``scripts/migrate_0_1_0.py``, run as a user runs it: refusals, no-ops, the stores it carries."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from _migrate import REFUSAL, migrate
from youbot_opt.exceptions import ResultFileError
from youbot_opt.sweeps.records import stored_records
from youbot_opt.sweeps.store import SCHEMA_VERSION, SweepStore

OLD = Path(__file__).resolve().parents[1] / "fixtures" / "files_74bfa23"


def test_refuses_to_overwrite_the_out_path(tmp_path: Path) -> None:
    """``--out`` that exists is refused; neither file changes; exit status 1."""
    target = tmp_path / "there.npz"
    target.write_bytes(b"mine")
    done = migrate(OLD / "traj_study1_n12.npz", "--out", target)
    assert done.returncode == 1
    assert "exists" in done.stderr and "nothing is overwritten" in done.stderr
    assert target.read_bytes() == b"mine"


def test_refuses_when_the_backup_exists(tmp_path: Path) -> None:
    """In place, the backup path must be free: an existing one is never replaced."""
    old = Path(shutil.copy(OLD / "traj_study1_n12.npz", tmp_path / "r.npz"))
    backup = tmp_path / "r.npz.0.1.0.bak"
    backup.write_bytes(b"an earlier backup")
    done = migrate(old)
    assert done.returncode == 1 and f"the backup {backup} exists" in done.stderr
    assert backup.read_bytes() == b"an earlier backup"
    assert old.read_bytes() == (OLD / "traj_study1_n12.npz").read_bytes()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.npz", "r.npz.0.1.0.bak"]


def test_a_current_file_and_store_are_left_alone(tmp_path: Path) -> None:
    """A second run finds everything current: says so, changes nothing, makes no backup."""
    shutil.copy(OLD / "traj_study1_n12.npz", tmp_path / "r.npz")
    assert migrate(tmp_path / "r.npz").returncode == 0
    data = (tmp_path / "r.npz").read_bytes()
    store = _flat_demo_store(tmp_path / "s")
    assert migrate(store).returncode == 0
    files = sorted(p.name for p in tmp_path.iterdir())
    again = migrate(tmp_path / "r.npz", store)
    assert again.returncode == 0, again.stderr
    assert again.stdout.count("already current") == 2
    assert (tmp_path / "r.npz").read_bytes() == data
    assert sorted(p.name for p in tmp_path.iterdir()) == files


def test_a_path_it_does_not_know_fails_alone(tmp_path: Path) -> None:
    """A missing path and a folder that is no store are named; the others are still carried."""
    shutil.copy(OLD / "traj_study1_n12.npz", tmp_path / "r.npz")
    (tmp_path / "plain").mkdir()
    done = migrate(tmp_path / "missing.npz", tmp_path / "plain", tmp_path / "r.npz")
    assert done.returncode == 1
    assert "missing.npz: not carried: no such file" in done.stderr
    assert "plain: not carried: a folder without manifest.json" in done.stderr
    assert "r.npz: trajectory result of 0.1.0 carried forward" in done.stdout


def _flat_demo_store(folder: Path, version: int = 2) -> Path:
    """A flat store of schema ``version`` as 0.1.0 wrote it: a done item, a failed one."""
    items = folder / "items"
    items.mkdir(parents=True)
    manifest = {"schema": "youbot_opt.sweep", "schema_version": version, "kind": "demo",
                "params": {"n": 3}}  # fmt: skip
    (folder / "manifest.json").write_text(json.dumps(manifest))
    (items / "a.txt").write_text("payload of a")
    for key, body in (
        ("a", {"state": "done", "attempts": 1, "summary": {"x": 1.5}, "payload": "a.txt"}),
        ("b", {"state": "failed", "attempts": 2, "reasons": ["boom", "again"]}),
    ):
        record = {"schema": "youbot_opt.sweep_item", "schema_version": version, "key": key}
        (items / f"{key}.json").write_text(json.dumps({**record, **body}))
    (folder / "summary.json").write_text("{}")  # a run folder's own file
    return folder


def _open(folder: Path) -> SweepStore:
    return SweepStore(
        folder, kind="demo", params={"n": 3}, save=lambda *_: None, load=Path.read_text,
        suffix=".txt",
    )  # fmt: skip


@pytest.mark.parametrize("version", [1, 2])
def test_flat_store_is_refused_then_carried_to_the_journal(tmp_path: Path, version: int) -> None:
    """A flat store (schema 1 or 2): refused; migrated, every record and payload kept."""
    folder = _flat_demo_store(tmp_path / "s", version)
    with pytest.raises(ResultFileError, match=REFUSAL + f"{folder}`"):
        _open(folder)
    done = migrate(folder)
    assert done.returncode == 0, done.stderr
    assert f"{folder}: sweep store of 0.1.0 carried forward" in done.stdout
    store = _open(folder)
    assert json.loads((folder / "manifest.json").read_text())["schema_version"] == SCHEMA_VERSION
    assert store.resumed and store.needs_work("a", 2) == (False, 1)
    assert store.needs_work("b", 2) == (False, 2) and store.needs_work("b", 3) == (True, 2)
    assert store.load("a") == "payload of a"
    records = {r.key: r for r in stored_records(folder)}
    assert dict(records["a"].summary) == {"x": 1.5}
    assert records["b"].reasons == ("boom", "again")
    assert (folder / "summary.json").read_text() == "{}"
    assert (tmp_path / "s.0.1.0.bak" / "items" / "a.json").is_file()
