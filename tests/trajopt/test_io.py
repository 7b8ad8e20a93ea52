"""Tests of result files (youbot_opt.trajopt.io): round trip, schema checks, atomic writes."""

from __future__ import annotations

import json

import numpy as np
import pytest

from youbot_opt.exceptions import ResultFileError
from youbot_opt.nlp.ipopt import IpoptOptions
from youbot_opt.reproduction.study1 import study1_problem
from youbot_opt.robot.load import load_model
from youbot_opt.trajopt.io import SCHEMA_VERSION, load_result, save_result
from youbot_opt.trajopt.result import SolveStatus
from youbot_opt.trajopt.solver import solve


@pytest.fixture(scope="module")
def youbot():
    return load_model("youbot", damping=0.1)


@pytest.fixture(scope="module")
def result(youbot):
    return solve(study1_problem(12, robot=youbot, duration=None), method="hermite_simpson", seed=7)


def _assert_same(a, b):
    assert a.status is b.status and a.method == b.method and a.backend == b.backend
    assert a.seed == b.seed and a.options == b.options and a.iterations == b.iterations
    for name in ("duration", "dt", "work", "objective", "beta", "bound_scale", "max_violation"):
        assert getattr(a, name) == getattr(b, name), name
    for group in ("variables", "multipliers"):
        ga, gb = getattr(a, group), getattr(b, group)
        assert ga.keys() == gb.keys()
        for key in ga:
            np.testing.assert_array_equal(ga[key], gb[key], err_msg=key)
    np.testing.assert_array_equal(a.objective_history, b.objective_history)
    for name in ("trajectory", "guess"):
        ta, tb = getattr(a, name), getattr(b, name)
        assert ta.interpolation == tb.interpolation
        for field in ("t", "q", "v", "a", "tau"):
            np.testing.assert_array_equal(getattr(ta, field), getattr(tb, field))
    assert a.problem.describe() == b.problem.describe()


def test_round_trip_is_exact(result, tmp_path):
    """Every array, scalar and the problem survive save/load bit for bit."""
    path = save_result(result, tmp_path / "run")
    assert path.name == "run.npz"
    loaded = load_result(path)
    _assert_same(result, loaded)
    np.testing.assert_array_equal(loaded.trajectory.tau_mid, result.trajectory.tau_mid)
    # the reloaded robot carries the saved damping (0.1 N m s/rad)
    np.testing.assert_array_equal(loaded.problem.robot.damping, [0.1, 0.1, 0.1])
    np.testing.assert_array_equal(loaded.trajectory(0.123), result.trajectory(0.123))


def test_failed_result_round_trip(youbot, tmp_path):
    """A failed (iteration-capped) result is saved and reloaded with its status."""
    failed = solve(study1_problem(8, robot=youbot), options=IpoptOptions(max_iter=1))
    assert failed.status is SolveStatus.MAX_ITERATIONS
    _assert_same(failed, load_result(save_result(failed, tmp_path / "failed.npz"), robot=youbot))


def _rewrite_metadata(path, change):
    with np.load(path, allow_pickle=False) as npz:
        arrays = {k: np.array(npz[k]) for k in npz.files}
    meta = json.loads(arrays["metadata"].tobytes().decode())
    change(meta)
    arrays["metadata"] = np.frombuffer(json.dumps(meta).encode(), dtype=np.uint8)
    np.savez(path, **arrays)


def test_newer_schema_is_refused(result, tmp_path):
    """A file of schema version SCHEMA_VERSION + 1 raises ResultFileError asking for an upgrade."""
    path = save_result(result, tmp_path / "new.npz")
    _rewrite_metadata(path, lambda m: m.update(schema_version=SCHEMA_VERSION + 1))
    with pytest.raises(ResultFileError, match=f"schema version {SCHEMA_VERSION + 1}.*upgrade"):
        load_result(path)


def test_foreign_schema_is_refused(result, tmp_path):
    """A file of another schema raises ResultFileError naming it."""
    path = save_result(result, tmp_path / "other.npz")
    _rewrite_metadata(path, lambda m: m.update(schema="something.else"))
    with pytest.raises(ResultFileError, match="unknown schema 'something.else'"):
        load_result(path)


def test_changed_array_fails_its_checksum(result, tmp_path):
    """An array altered after saving is caught by its SHA-256 checksum."""
    path = save_result(result, tmp_path / "bad.npz")
    with np.load(path, allow_pickle=False) as npz:
        arrays = {k: np.array(npz[k]) for k in npz.files}
    arrays["variables__tau"] = arrays["variables__tau"] + 1e-12
    np.savez(path, **arrays)
    with pytest.raises(ResultFileError, match="checksum mismatch in array 'variables__tau'"):
        load_result(path)


def test_truncated_file_is_refused(result, tmp_path):
    """A truncated file raises ResultFileError, not a zipfile/numpy error."""
    path = save_result(result, tmp_path / "cut.npz")
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    with pytest.raises(ResultFileError, match="not a readable result file"):
        load_result(path)


def test_missing_file_and_directory(result, tmp_path):
    """Loading a missing file or saving into a missing directory raises ResultFileError."""
    with pytest.raises(ResultFileError, match="does not exist"):
        load_result(tmp_path / "nope.npz")
    with pytest.raises(ResultFileError, match="does not exist"):
        save_result(result, tmp_path / "no_dir" / "x.npz")


def test_write_is_atomic(result, tmp_path, monkeypatch):
    """A write that fails midway leaves the previous file intact and no temporary file."""
    path = save_result(result, tmp_path / "keep.npz")
    before = path.read_bytes()

    def boom(*args, **kwargs):
        raise OSError("disk full")

    monkeypatch.setattr(np, "savez_compressed", boom)
    with pytest.raises(ResultFileError, match="disk full"):
        save_result(result, path)
    assert path.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["keep.npz"]


def test_feasibility_tolerance_is_the_callers_not_the_files(tmp_path) -> None:
    """A loaded result is judged at the caller's tolerance (the library's default unless
    passed); the file's own tolerance is named in the message, never used (#29)."""
    import dataclasses

    from youbot_opt.reproduction.study1 import study1_problem
    from youbot_opt.trajopt.io import load_result, save_result
    from youbot_opt.trajopt.result import DEFAULT_FEASIBILITY_TOL
    from youbot_opt.trajopt.solver import TrajOptSolver

    result = TrajOptSolver(study1_problem(10), "trapezoidal").solve(beta=0.5)
    loose = dataclasses.replace(result, feasibility_tol=1e-4)
    path = save_result(loose, tmp_path / "r.npz")
    back = load_result(path, robot=result.problem.robot)
    assert back.feasibility_tol == DEFAULT_FEASIBILITY_TOL
    assert "not the file's 0.0001" in back.message
    assert back.status == loose.status
    asked = load_result(path, robot=result.problem.robot, feasibility_tol=1e-4)
    assert asked.feasibility_tol == 1e-4
    assert asked.status == loose.status
