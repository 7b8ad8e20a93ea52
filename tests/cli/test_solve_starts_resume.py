"""``solve --starts K --out D`` saves its starts in ``D/starts``: a rerun resumes (#29)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from youbot_opt.cli import main

_ARGS = ["solve", "--starts", "2", "--knots", "15", "--workers", "0", "--no-refine", "--json"]


def _solve(out: Path, capsys: pytest.CaptureFixture[str], *extra: str) -> tuple[int, str, str]:
    code = main([*_ARGS, "--out", str(out), *extra])
    got = capsys.readouterr()
    return code, got.out, got.err


def test_solve_starts_out_is_resumable(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, text, _ = _solve(tmp_path, capsys)
    assert code == 0
    first = json.loads(text)
    assert first["multistart"]["resumed"] == 0
    assert (tmp_path / "starts" / "manifest.json").is_file()
    code, text, _ = _solve(tmp_path, capsys)
    again = json.loads(text)
    assert code == 0 and again["multistart"]["resumed"] == len(first["multistart"]["starts"])
    assert again["objective"] == first["objective"]
    assert [s["objective"] for s in again["multistart"]["starts"]] == [
        s["objective"] for s in first["multistart"]["starts"]
    ]


def test_solve_starts_out_with_other_parameters_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert _solve(tmp_path, capsys)[0] == 0
    code, _, err = _solve(tmp_path, capsys, "--beta", "0.3")
    assert code == 2
    assert "beta: stored 0.5, now 0.3" in err and str(tmp_path / "starts") in err
