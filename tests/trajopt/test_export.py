"""Tests of the export to a controller (youbot_opt.trajopt.export): samples, files, ROS 2."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

from youbot_opt.exceptions import ParameterError, ResultFileError
from youbot_opt.reproduction.study1 import study1_problem
from youbot_opt.robot.model import RobotModel
from youbot_opt.trajopt.certify import Tolerances, certify, check_bounds
from youbot_opt.trajopt.export import (
    SampledTrajectory,
    read_csv,
    read_json,
    read_ros2_message,
    read_rosbag,
    sample_trajectory,
    write_csv,
    write_json,
    write_ros2_message,
    write_rosbag,
)
from youbot_opt.trajopt.problem import BoundaryState, TrajOptProblem
from youbot_opt.trajopt.solver import solve

METHODS = ("trapezoidal", "hermite_simpson", "radau")
RATE = 200.0  # [Hz]


@pytest.fixture(scope="module")
def results(youbot):
    """One 20-knot study-1 solve per transcription."""
    return {m: solve(study1_problem(20, robot=youbot), method=m, seed=0) for m in METHODS}


@pytest.fixture(scope="module")
def samples(results):
    """The Hermite-Simpson plan at 200 Hz."""
    return results["hermite_simpson"].sample(RATE)


def _assert_same(a: SampledTrajectory, b: SampledTrajectory, *, time_atol: float = 0.0) -> None:
    assert a.joint_names == b.joint_names
    np.testing.assert_allclose(a.time, b.time, rtol=0, atol=time_atol)
    for name in ("q", "v", "a", "tau"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)


@pytest.mark.parametrize("method", METHODS)
def test_acceleration_is_the_derivative_of_the_velocity_interpolant(results, method):
    """Trajectory.acceleration is d/dt of Trajectory.velocity (central differences, 1e-6)."""
    traj = results[method].trajectory
    inner = (traj.t[:-1] + np.outer([0.13, 0.5, 0.91], np.diff(traj.t))).ravel()
    eps = 1e-6  # [s]
    fd = (traj.velocity(inner + eps) - traj.velocity(inner - eps)) / (2 * eps)
    np.testing.assert_allclose(traj.acceleration(inner), fd, atol=1e-6)


def test_hermite_simpson_acceleration_equals_the_knot_accelerations(results):
    """Hermite-Simpson's acceleration interpolant passes through a at the knots (1e-12)."""
    traj = results["hermite_simpson"].trajectory
    np.testing.assert_allclose(traj.acceleration(traj.t[:-1]), traj.a[:-1], atol=1e-12)


@pytest.mark.parametrize("method", METHODS)
def test_samples_are_the_plans_own_interpolants(results, youbot, method):
    """Samples are the plan's interpolants on a uniform clock from 0 that ends at T (exact)."""
    result = results[method]
    traj = result.trajectory
    s = result.sample(RATE)
    assert s.interpolation == method and s.rate_hz == RATE and s.robot == youbot.name
    assert s.joint_names == youbot.joint_names
    assert [u.position for u in s.units] == ["rad"] * 3
    assert s.time[0] == 0.0 and s.time[-1] == pytest.approx(traj.duration, abs=1e-12)
    np.testing.assert_allclose(np.diff(s.time)[:-1], 1.0 / RATE, rtol=0, atol=1e-12)
    assert 0.0 < s.time[-1] - s.time[-2] <= 1.0 / RATE + 1e-12
    clock = traj.t[0] + s.time
    np.testing.assert_allclose(s.q, traj(clock), atol=1e-12)
    np.testing.assert_allclose(s.v, traj.velocity(clock), atol=1e-12)
    np.testing.assert_allclose(s.a, traj.acceleration(clock), atol=1e-12)
    np.testing.assert_allclose(s.tau, traj.torque(clock), atol=1e-12)
    # the motion starts and ends at the plan's boundary states
    np.testing.assert_allclose(s.q[[0, -1]], traj.q[[0, -1]], atol=1e-12)
    np.testing.assert_allclose(s.v[[0, -1]], traj.v[[0, -1]], atol=1e-12)


@pytest.mark.parametrize("method", METHODS)
def test_sampled_motion_stays_within_the_certificate_tolerances_of_the_plan(results, method):
    """A controller interpolating the samples follows the plan within the certificate's tols."""
    result = results[method]
    traj = result.trajectory
    tol = Tolerances()
    motion = result.sample(RATE).as_trajectory()
    fine = np.linspace(traj.t[0], traj.t[-1], 4001)
    assert np.max(np.abs(motion(fine - traj.t[0]) - traj(fine))) <= tol.tracking_position
    assert np.max(np.abs(motion.velocity(fine - traj.t[0]) - traj.velocity(fine))) <= (
        tol.local_velocity
    )
    for check in check_bounds(motion, result.bounds()):
        limit = tol.knot_bound if check.where == "knots" else tol.between_bound
        assert check.relative <= limit, check


@pytest.mark.parametrize("method", ["hermite_simpson", "radau"])
def test_samples_of_a_certified_plan_are_certified(results, method):
    """The sampled motion of a certified plan passes the certificate itself (pin.aba, tracking)."""
    result = results[method]
    assert certify(result).ok
    motion = result.sample(RATE).as_trajectory()
    cert = certify(
        motion, result.problem.robot, bounds=result.bounds(), damping=result.problem.damping
    )
    assert cert.ok, cert.failures()


def test_rate_must_be_positive(results):
    """A rate that is not a finite positive number is a ParameterError naming rate_hz."""
    for bad in (0.0, -5.0, float("nan"), float("inf"), "fast"):
        with pytest.raises(ParameterError, match="rate_hz"):
            results["trapezoidal"].sample(bad)


def test_a_rate_slower_than_the_plan_gives_start_and_end(results):
    """At a rate below 1 / T the samples are the start and the end."""
    s = results["trapezoidal"].sample(0.1)
    assert s.n_samples == 2 and s.time[0] == 0.0


def test_csv_round_trip_and_header(samples, tmp_path):
    """CSV reads back bit for bit; the header names each joint with its unit."""
    path = write_csv(samples, tmp_path / "plan.csv")
    header = path.read_text().splitlines()[0].split(",")
    assert header[0] == "time [s]"
    assert header[1] == f"{samples.joint_names[0]}.q [rad]"
    assert f"{samples.joint_names[2]}.a [rad/s^2]" in header
    assert header[-1] == f"{samples.joint_names[-1]}.tau [N m]"
    back = read_csv(path)
    _assert_same(samples, back)
    assert back.units == samples.units
    assert back.rate_hz == pytest.approx(RATE, rel=1e-9)


def test_json_round_trip_and_schema(samples, tmp_path):
    """JSON reads back bit for bit with the package's schema header and checksum."""
    path = write_json(samples, tmp_path / "plan.json")
    doc = json.loads(path.read_text())
    assert doc["schema"] == "youbot_opt.trajectory_samples" and doc["schema_version"] == 1
    assert doc["samples"]["units"]["tau"] == ["N m"] * 3
    back = read_json(path)
    _assert_same(samples, back)
    assert (back.rate_hz, back.robot, back.interpolation) == (
        samples.rate_hz,
        samples.robot,
        samples.interpolation,
    )
    doc["samples"]["q"][3][1] += 1e-3
    path.write_text(json.dumps(doc))
    with pytest.raises(ResultFileError, match="checksum"):
        read_json(path)


def test_ros2_message_round_trip(samples, tmp_path):
    """The JointTrajectory message file reads back exactly (times to the nanosecond)."""
    path = write_ros2_message(samples, tmp_path / "plan.msg.json")
    back = read_ros2_message(path)
    _assert_same(samples, back, time_atol=1e-9)
    doc = json.loads(path.read_text())
    assert doc["joint_names"] == list(samples.joint_names)
    assert set(doc["points"][1]) == {
        "positions",
        "velocities",
        "accelerations",
        "effort",
        "time_from_start",
    }
    assert doc["points"][1]["time_from_start"] == {"sec": 0, "nanosec": 5_000_000}


def test_ros2_message_is_yaml_that_ros2_topic_pub_reads(samples, tmp_path):
    """Read as YAML 1.1 (PyYAML, as ros2 topic pub does), every value is a float, not a string."""
    yaml = pytest.importorskip("yaml")
    tiny = SampledTrajectory(
        time=[0.0, 1e-5, 2.0],
        q=[[1e-20, 0.0, -3.0], [1.0, 2.0, 3.0], [1e20, 1e-7, -0.5]],
        v=np.zeros((3, 3)),
        a=np.zeros((3, 3)),
        tau=np.ones((3, 3)),
        joint_names=samples.joint_names,
        units=samples.units,
        rate_hz=1e5,
    )
    for s in (tiny, samples):
        path = write_ros2_message(s, tmp_path / "m.yaml")
        doc = yaml.safe_load(path.read_text())
        values = [x for p in doc["points"] for k in ("positions", "effort") for x in p[k]]
        assert all(isinstance(x, float) for x in values)
        np.testing.assert_array_equal(np.array([p["positions"] for p in doc["points"]]), s.q)


def test_rosbag_round_trip(samples, tmp_path):
    """A rosbag2 written with rosbags reads back exactly (times to the nanosecond)."""
    pytest.importorskip("rosbags")
    bag = write_rosbag(samples, tmp_path / "plan_bag")
    assert (bag / "metadata.yaml").is_file()
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".tmp-")]
    _assert_same(samples, read_rosbag(bag), time_atol=1e-9)
    with pytest.raises(ResultFileError, match="exists"):
        write_rosbag(samples, bag)


def test_prismatic_joints_are_in_metres(slider, tmp_path):
    """A prismatic joint's columns are in m, m/s, m/s^2 and N, and read back so."""
    robot = RobotModel.from_pin_model(slider)
    problem = TrajOptProblem(
        robot=robot,
        start=BoundaryState(q=[0.0], v=[0.0]),
        goal=BoundaryState(q=[1.0], v=[0.0]),
        n_knots=11,
    )
    s = sample_trajectory(solve(problem).raise_for_status().trajectory, robot, 100.0)
    header = write_csv(s, tmp_path / "x.csv").read_text().splitlines()[0]
    assert header == "time [s],x.q [m],x.v [m/s],x.a [m/s^2],x.tau [N]"
    assert read_csv(tmp_path / "x.csv").units == s.units == robot.joint_units()


def test_readers_refuse_other_files(samples, tmp_path):
    """Readers raise ResultFileError on a file that is not theirs."""
    other = tmp_path / "other.csv"
    other.write_text("a,b\n1,2\n3,4\n")
    with pytest.raises(ResultFileError, match="time"):
        read_csv(other)
    with pytest.raises(ResultFileError):
        read_json(other)
    with pytest.raises(ResultFileError):
        read_ros2_message(write_json(samples, tmp_path / "s.json"))
    with pytest.raises(ResultFileError, match="does not exist"):
        write_csv(samples, tmp_path / "missing" / "x.csv")


def test_read_json_document_parses_the_file_or_says_it_cannot_read_it(tmp_path):
    """read_json_document returns what the text says; missing, non-UTF-8 or non-JSON files raise.

    Both JSON readers (samples and ROS 2 message) report such files with its wording.
    """
    from youbot_opt.trajopt.export.files import read_json_document

    good = tmp_path / "good.json"
    good.write_text('{"a": [1, 2.5, null], "b": "x", "c": true}\n', encoding="utf-8")
    assert read_json_document(good) == {"a": [1, 2.5, None], "b": "x", "c": True}
    scalar = tmp_path / "scalar.json"
    scalar.write_text("3.25", encoding="utf-8")
    assert read_json_document(scalar) == 3.25
    bad_json = tmp_path / "bad.json"
    bad_json.write_text("{not json", encoding="utf-8")
    bad_utf8 = tmp_path / "latin1.json"
    bad_utf8.write_bytes(b'{"a": "\xe9"}')
    missing = tmp_path / "missing.json"
    for path in (bad_json, bad_utf8, missing):
        for reader in (read_json_document, read_json, read_ros2_message):
            with pytest.raises(ResultFileError, match="^" + re.escape(f"cannot read {path}: ")):
                reader(path)
