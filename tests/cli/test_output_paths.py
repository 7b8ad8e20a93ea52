"""Output paths the system refuses (#29): one line naming the path and what it needs, exit 2.

A missing folder, a folder where a file is meant, ``/proc``, a read-only
folder (simulated: these tests may run as root, who writes anywhere), a store
whose ``items/journal`` is a file, a read-only half-finished store, a full disk
(simulated: ``ENOSPC`` from the writes after a few items); the full disk's
store then resumes to the uninterrupted result.
"""

from __future__ import annotations

import builtins
import errno
import io
import json
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from youbot_opt.cli import main

_MS = ["multistart", "--starts", "3", "--knots", "15", "--seed", "5", "--workers", "1",
       "--json", "--quiet"]  # fmt: skip


def _run(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str]:
    code = main(argv)
    return code, capsys.readouterr().err


def _one_line(err: str) -> str:
    lines = [x for x in err.splitlines() if x.startswith("youbot-opt: error:")]
    assert len(lines) == 1, err
    assert "Traceback" not in err
    return lines[0]


def _always() -> bool:
    return True


def _deny(
    monkeypatch: pytest.MonkeyPatch, folder: Path, code: int, *, after: Callable[[], bool] = _always
) -> None:
    """Make writes under ``folder`` fail with ``code`` (once ``after()`` is true).

    Every primitive the library writes with: ``os.open`` for writing, ``open``
    in a writing mode, ``os.mkdir``, ``os.replace`` and ``os.write``.
    """
    root = str(folder.resolve())
    real_open, real_os_open = builtins.open, os.open
    real_mkdir, real_replace = os.mkdir, os.replace

    def under(path: Any) -> bool:
        try:
            return os.path.abspath(os.fspath(path)).startswith(root)
        except TypeError:
            return False

    def fail(path: Any) -> OSError:
        return OSError(code, os.strerror(code), os.fspath(path))

    def os_open(path: Any, flags: int, *a: Any, **k: Any) -> int:
        if flags & (os.O_WRONLY | os.O_RDWR | os.O_CREAT) and under(path) and after():
            raise fail(path)
        return real_os_open(path, flags, *a, **k)

    def b_open(file: Any, mode: str = "r", *a: Any, **k: Any) -> Any:
        if any(c in mode for c in "wax+") and not isinstance(file, int) and under(file) and after():
            raise fail(file)
        return real_open(file, mode, *a, **k)

    def mkdir(path: Any, *a: Any, **k: Any) -> None:
        if under(path) and not os.path.isdir(path) and after is _always:
            raise fail(path)
        real_mkdir(path, *a, **k)

    def replace(src: Any, dst: Any, *a: Any, **k: Any) -> None:
        if under(dst) and after():
            raise fail(dst)
        real_replace(src, dst, *a, **k)

    monkeypatch.setattr(os, "open", os_open)
    monkeypatch.setattr(builtins, "open", b_open)
    monkeypatch.setattr(io, "open", b_open)
    monkeypatch.setattr(os, "mkdir", mkdir)
    monkeypatch.setattr(os, "replace", replace)


def test_robots_out_into_a_missing_folder(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    target = tmp_path / "nowhere" / "rows.json"
    code, err = _run(["robots", "ur5", "--out", str(target)], capsys)
    line = _one_line(err)
    assert code == 2
    assert str(target) in line and "does not exist" in line and ".tmp-" not in line


def test_robots_out_onto_a_folder(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, err = _run(["robots", "ur5", "--out", str(tmp_path)], capsys)
    assert code == 2 and "folder" in _one_line(err) and str(tmp_path) in err


@pytest.mark.skipif(not Path("/proc/self").is_dir(), reason="needs Linux /proc")
def test_robots_out_into_proc(capsys: pytest.CaptureFixture[str]) -> None:
    code, err = _run(["robots", "ur5", "--out", "/proc/rows.json"], capsys)
    line = _one_line(err)
    assert code == 2 and "/proc/rows.json" in line and ".tmp-" not in line


def test_robots_out_into_a_read_only_folder(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    _deny(monkeypatch, tmp_path, errno.EACCES)
    code, err = _run(["robots", "ur5", "--out", str(tmp_path / "rows.json")], capsys)
    line = _one_line(err)
    assert code == 2 and str(tmp_path / "rows.json") in line and "read-only" in line
    assert list(tmp_path.iterdir()) == []


def test_multistart_out_read_only(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    out = tmp_path / "ms"
    out.mkdir()
    _deny(monkeypatch, out, errno.EACCES)
    code, err = _run([*_MS, "--out", str(out)], capsys)
    line = _one_line(err)
    assert code == 2 and str(out) in line and "read-only" in line


def test_store_whose_journal_is_a_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "ms"
    (out / "items").mkdir(parents=True)
    (out / "items" / "journal").write_text("not a folder")
    code, err = _run([*_MS, "--out", str(out)], capsys)
    line = _one_line(err)
    assert code == 2 and str(out / "items" / "journal") in line


def _uninterrupted(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> dict[str, Any]:
    out = tmp_path / "ref"
    code, text = main([*_MS, "--out", str(out)]), capsys.readouterr().out
    assert code == 0
    return json.loads(text)


def _objectives(doc: dict[str, Any]) -> list[float]:
    return [s["objective"] for s in doc["starts"]]


def _half_finished(
    out: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> str:
    """Run the sweep into ``out`` until the disk is full (after a few writes); its error line."""
    writes = {"n": 0}

    def after() -> bool:  # the disk fills after a few writes (manifest, first items ...)
        writes["n"] += 1
        return writes["n"] > 8

    with monkeypatch.context() as m:
        _deny(m, out, errno.ENOSPC, after=after)
        code, err = _run([*_MS, "--out", str(out)], capsys)
    assert code == 2
    return _one_line(err)


def test_read_only_half_finished_store_then_resume(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    ref = _uninterrupted(tmp_path, capsys)
    out = tmp_path / "ms"
    _half_finished(out, capsys, monkeypatch)
    with monkeypatch.context() as m:
        _deny(m, out, errno.EROFS)
        code, err = _run([*_MS, "--out", str(out)], capsys)
    assert code == 2 and str(out) in _one_line(err) and "read-only" in err
    code, text = main([*_MS, "--out", str(out)]), capsys.readouterr().out
    assert code == 0 and _objectives(json.loads(text)) == _objectives(ref)


def test_full_disk_is_one_line_and_the_store_resumes(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    ref = _uninterrupted(tmp_path, capsys)
    out = tmp_path / "ms"
    line = _half_finished(out, capsys, monkeypatch)
    assert str(out) in line and "free space" in line and "resumes" in line
    assert any((out / "items").glob("*/*.npz"))  # half finished: some items are kept
    code, text = main([*_MS, "--out", str(out)]), capsys.readouterr().out
    assert code == 0 and _objectives(json.loads(text)) == _objectives(ref)
