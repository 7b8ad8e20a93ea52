"""youbot_opt._files: atomic writes, JSON sanitising and the schema header."""

from __future__ import annotations

import enum
import json
import math
import os
from pathlib import Path

import numpy as np
import pytest

from youbot_opt._files import (
    TMP_PREFIX,
    array_digest,
    atomic_write_bytes,
    atomic_write_text,
    atomic_writer,
    check_schema_header,
    json_digest,
    json_ready,
    json_roundtrip,
    schema_header,
    software_versions,
)
from youbot_opt._version import __version__
from youbot_opt.exceptions import ParameterError, ResultFileError


# ------------------------------------------------------------------ atomic writes
def test_atomic_write_bytes_and_text_replace_the_file(tmp_path: Path) -> None:
    """Bytes and text land whole; no temporary file is left beside the target."""
    target = tmp_path / "f.json"
    atomic_write_bytes(target, b"old")
    atomic_write_text(target, "n\u00e9w\n")
    assert target.read_bytes() == "n\u00e9w\n".encode()
    assert [p.name for p in tmp_path.iterdir()] == ["f.json"]


@pytest.mark.parametrize("exc", [OSError("disk full"), KeyboardInterrupt()])
def test_atomic_write_failure_keeps_old_file_and_no_temporary(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, exc: BaseException
) -> None:
    """A write that dies before the rename leaves the old content and no temporary file."""
    target = tmp_path / "f.bin"
    atomic_write_bytes(target, b"old")

    def boom(src: str, dst: str) -> None:
        raise exc

    monkeypatch.setattr(os, "replace", boom)
    with pytest.raises(type(exc)):
        atomic_write_bytes(target, b"new")
    monkeypatch.undo()
    assert target.read_bytes() == b"old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["f.bin"]


def test_atomic_writer_failure_inside_the_block_removes_the_temporary(tmp_path: Path) -> None:
    """An exception raised by the writer's caller leaves no file at all."""
    target = tmp_path / "r.npz"
    with pytest.raises(ValueError, match="half"), atomic_writer(target) as handle:
        handle.write(b"partial")
        assert any(p.name.startswith(TMP_PREFIX + "r.npz.") for p in tmp_path.iterdir())
        raise ValueError("half written")
    assert list(tmp_path.iterdir()) == []


def test_atomic_write_missing_directory_raises(tmp_path: Path) -> None:
    """The target's folder must exist."""
    with pytest.raises(OSError):
        atomic_write_bytes(tmp_path / "no" / "f", b"x")


def test_atomic_write_gives_the_mode_of_a_plain_open(tmp_path: Path) -> None:
    """A new file gets 0o666 less the umask (figures and results alike), not mkstemp's 0o600."""
    old = os.umask(0o022)
    try:
        atomic_write_text(tmp_path / "new.json", "{}")
        with open(tmp_path / "plain.txt", "w") as handle:
            handle.write("x")
    finally:
        os.umask(old)
    assert (tmp_path / "new.json").stat().st_mode & 0o777 == 0o644
    assert (tmp_path / "plain.txt").stat().st_mode & 0o777 == 0o644


def test_atomic_write_keeps_the_mode_of_the_file_it_replaces(tmp_path: Path) -> None:
    """Replacing a regular file keeps its permission bits."""
    target = tmp_path / "keep.txt"
    target.write_text("old")
    target.chmod(0o640)
    atomic_write_text(target, "new")
    assert target.read_text() == "new"
    assert target.stat().st_mode & 0o777 == 0o640


def test_atomic_write_refuses_a_symbolic_link(tmp_path: Path) -> None:
    """A link planted where a file will be written is refused; its target is untouched."""
    victim = tmp_path / "victim.txt"
    victim.write_text("precious")
    link = tmp_path / "summary.json"
    link.symlink_to(victim)
    with pytest.raises(ParameterError, match="symbolic link"):
        atomic_write_text(link, "{}")
    assert victim.read_text() == "precious"
    assert link.is_symlink()
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(TMP_PREFIX)] == []


@pytest.mark.parametrize("kind", ["fifo", "folder", "device"])
def test_atomic_write_refuses_what_is_not_a_regular_file(tmp_path: Path, kind: str) -> None:
    """A FIFO, a folder or a device node is never replaced by a file."""
    if kind == "fifo":
        target = tmp_path / "pipe"
        os.mkfifo(target)
    elif kind == "folder":
        target = tmp_path / "folder"
        target.mkdir()
    else:
        target = Path("/dev/null")
        if not target.exists():
            pytest.skip("no /dev/null here")
    with pytest.raises(ParameterError, match="refusing to write"):
        atomic_write_bytes(target, b"x")
    if kind == "device":
        assert target.is_char_device()
    else:
        assert not target.is_file()


# ------------------------------------------------------------------ JSON
class _Colour(enum.Enum):
    RED = "red"


def test_json_ready_converts_numpy_paths_enums_and_non_finite() -> None:
    """numpy scalars/arrays, paths and enums become plain JSON; NaN and inf become None."""
    value = {
        1: np.float64(1.5),
        "i": np.int64(3),
        "b": np.bool_(True),
        "f32_nan": np.float32("nan"),
        "arr": np.array([[1.0, np.inf], [-np.inf, np.nan]]),
        "t": (np.float32(0.25), math.nan),
        "p": Path("a/b"),
        "e": _Colour.RED,
        "s": "x",
        "n": None,
    }
    out = json_ready(value)
    assert out == {
        "1": 1.5,
        "i": 3,
        "b": True,
        "f32_nan": None,
        "arr": [[1.0, None], [None, None]],
        "t": [0.25, None],
        "p": "a/b",
        "e": "red",
        "s": "x",
        "n": None,
    }
    assert type(out["i"]) is int and type(out["b"]) is bool
    json.dumps(out, allow_nan=False)  # strict JSON


def test_json_roundtrip_keeps_non_finite_and_refuses_numpy() -> None:
    """json_roundtrip is JSON's own reading back: NaN stays NaN, tuples become lists."""
    out = json_roundtrip({"a": (1, 2.5), "b": math.inf, "c": math.nan})
    assert out["a"] == [1, 2.5] and out["b"] == math.inf and math.isnan(out["c"])
    with pytest.raises(TypeError):
        json_roundtrip({"a": np.int64(1)})


# ------------------------------------------------------------------ schema header
def test_software_versions_and_header_order() -> None:
    """The header holds schema, version, versions, then the checksums, in that order."""
    versions = software_versions(np)
    assert versions == {"youbot_opt": __version__, "numpy": np.__version__}
    header = schema_header("youbot_opt.demo", 2, versions, sha256="ab")
    assert list(header) == ["schema", "schema_version", "versions", "sha256"]
    assert header["schema_version"] == 2
    assert schema_header("x", 1)["versions"] == {"youbot_opt": __version__}


def test_header_checksum_round_trip(tmp_path: Path) -> None:
    """A document written with its checksum reads back, checks and verifies; a change is seen."""
    body = {"b": [1.0, 2.0], "a": {"z": 1, "y": None}}
    doc = {**schema_header("youbot_opt.demo", 1, sha256=json_digest(body)), "result": body}
    path = tmp_path / "doc.json"
    atomic_write_text(path, json.dumps(doc, indent=1, allow_nan=False))
    back = json.loads(path.read_text())
    assert check_schema_header(back, schema="youbot_opt.demo", supported=1, source="doc") == 1
    assert back["sha256"] == json_digest(back["result"])  # key order does not matter
    back["result"]["b"][0] = 1.5
    assert back["sha256"] != json_digest(back["result"])
    with pytest.raises(ValueError):
        json_digest({"x": math.nan})


def test_array_digest_is_the_contiguous_bytes_digest() -> None:
    """array_digest depends on the values, not on the memory layout."""
    a = np.arange(6.0).reshape(2, 3)
    assert array_digest(a) == array_digest(np.asfortranarray(a))
    assert array_digest(a) != array_digest(a + 1.0)
    assert len(array_digest(a)) == 64


@pytest.mark.parametrize(
    ("doc", "match"),
    [
        ({"schema": "other", "schema_version": 1}, "unknown schema 'other', expected 'demo'"),
        ([1, 2], "unknown schema 'list'"),
        ({"schema": "demo"}, "no valid 'schema_version'.*1..2, got None"),
        ({"schema": "demo", "schema_version": True}, "schema_version"),
        ({"schema": "demo", "schema_version": 0}, "schema_version"),
        (
            {"schema": "demo", "schema_version": 3, "versions": {"youbot_opt": "9.9"}},
            r"schema version 3 is newer.*1\.\.2.*written by youbot_opt 9\.9; upgrade",
        ),
    ],
)
def test_check_schema_header_refuses(doc: object, match: str) -> None:
    """Another schema, a missing/invalid or a newer version raise ResultFileError."""
    with pytest.raises(ResultFileError, match=match):
        check_schema_header(doc, schema="demo", supported=2, source="f.json")


def test_check_schema_header_without_name_and_with_remedy() -> None:
    """schema=None checks the version alone; the remedy ends the newer-version message."""
    assert check_schema_header({"schema_version": 2}, schema=None, supported=2, source="s") == 2
    with pytest.raises(ResultFileError, match="newer.*; use another folder$"):
        check_schema_header(
            {"schema_version": 3}, schema=None, supported=2, source="s", remedy="use another folder"
        )


def test_check_schema_header_refuses_a_version_older_than_oldest_naming_the_script() -> None:
    """Below ``oldest`` (a 0.1.0 file): the message names scripts/migrate_0_1_0.py and the path."""
    doc = {"schema": "demo", "schema_version": 1}
    assert check_schema_header(doc, schema="demo", supported=2, source="f.json") == 1
    want = (
        r"^f\.json: written by youbot_opt 0\.1\.0 \(schema 1\); "
        r"run `python scripts/migrate_0_1_0\.py f\.json` to carry it forward$"
    )
    with pytest.raises(ResultFileError, match=want):
        check_schema_header(doc, schema="demo", supported=2, oldest=2, source="f.json")
    with pytest.raises(ResultFileError, match=r"migrate_0_1_0\.py run/a`"):
        check_schema_header(
            doc, schema="demo", supported=2, oldest=2, source="f.json", migrate="run/a"
        )
