"""Tests of the ``export`` command body (youbot_opt.cli.export.run_export)."""

from __future__ import annotations

import argparse

import numpy as np
import pytest

from youbot_opt.cli.export import run_export
from youbot_opt.exceptions import ParameterError
from youbot_opt.nlp.ipopt import IpoptOptions
from youbot_opt.reproduction.study1 import study1_problem
from youbot_opt.trajopt.export import read_csv, read_json, read_ros2_message, read_rosbag
from youbot_opt.trajopt.io import save_result
from youbot_opt.trajopt.solver import solve

RATE = 250.0  # [Hz]


@pytest.fixture(scope="module")
def result(youbot):
    """A 12-knot Hermite-Simpson study-1 plan."""
    return solve(study1_problem(12, robot=youbot), method="hermite_simpson", seed=0)


@pytest.fixture()
def run(result, tmp_path):
    """A run folder holding the plan as result.npz."""
    save_result(result, tmp_path / "result.npz")
    return tmp_path


def _args(run, fmt, **extra):
    values = {"run": str(run), "format": fmt, "rate": RATE, "out": None, "topic": None}
    return argparse.Namespace(**{**values, **extra})


READERS = {"csv": read_csv, "json": read_json, "ros2": read_ros2_message, "rosbag": read_rosbag}
NAMES = {
    "csv": "trajectory_250hz.csv",
    "json": "trajectory_250hz.json",
    "ros2": "trajectory_250hz.ros2.json",
    "rosbag": "trajectory_250hz_bag",
}


@pytest.mark.parametrize("fmt", ["csv", "json", "ros2", "rosbag"])
def test_export_writes_the_sampled_plan(result, run, fmt, capsys):
    """Each format is written beside the result and reads back as result.sample(rate)."""
    if fmt == "rosbag":
        pytest.importorskip("rosbags")
    assert run_export(_args(run, fmt)) == 0
    out = run / NAMES[fmt]
    assert str(out) in capsys.readouterr().out
    back = READERS[fmt](out)
    expected = result.sample(RATE)
    np.testing.assert_allclose(back.time, expected.time, rtol=0, atol=1e-9)
    for name in ("q", "v", "a", "tau"):
        np.testing.assert_array_equal(getattr(back, name), getattr(expected, name))


def test_export_out_and_result_file(result, run, tmp_path):
    """RUN_FOLDER may be the .npz itself, and --out chooses the file."""
    target = tmp_path / "plan.csv"
    assert run_export(_args(run / "result.npz", "csv", out=str(target))) == 0
    assert read_csv(target).n_samples == result.sample(RATE).n_samples


def test_export_refuses_bad_input(run, tmp_path):
    """Unknown formats, empty folders and bad rates are ParameterErrors naming the problem."""
    with pytest.raises(ParameterError, match="--format"):
        run_export(_args(run, "xml"))
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(ParameterError, match="no result.npz"):
        run_export(_args(empty, "csv"))
    with pytest.raises(ParameterError, match="rate_hz"):
        run_export(_args(run, "csv", rate=-1.0))


def test_export_refuses_a_failed_result_unless_allowed(youbot, tmp_path):
    """A result that fails its check on load is exported only with --allow-failed."""
    failed = solve(study1_problem(8, robot=youbot), options=IpoptOptions(max_iter=2))
    assert not failed.success
    save_result(failed, tmp_path / "result.npz")
    with pytest.raises(ParameterError, match="allow-failed"):
        run_export(_args(tmp_path, "json"))
    assert run_export(_args(tmp_path, "json", allow_failed=True)) == 0


def test_the_command_line_runs_export(result, run, capsys):
    """`youbot-opt export RUN --format csv --rate 250` as a user types it (through main)."""
    from youbot_opt.cli import main

    assert main(["export", str(run), "--format", "csv", "--rate", "250"]) == 0
    back = read_csv(run / NAMES["csv"])
    np.testing.assert_array_equal(back.q, result.sample(RATE).q)
    with pytest.raises(SystemExit) as info:  # argparse's choices
        main(["export", str(run), "--format", "xml"])
    assert info.value.code == 2
    assert "invalid choice: 'xml'" in capsys.readouterr().err
