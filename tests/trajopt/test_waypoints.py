"""Tests of the waypoint spec (trajopt.waypoints, #30 item 3): shape, limits, files."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from youbot_opt.exceptions import ParameterError
from youbot_opt.reproduction.study1 import study1_problem
from youbot_opt.trajopt.waypoints import MAX_WAYPOINTS, Waypoints, load_waypoints


@pytest.fixture(scope="module")
def problem(youbot):
    return study1_problem(robot=youbot)


def test_visits_open_and_closed():
    q = np.array([[0.1, 0.2, 0.3], [0.4, 0.5, 0.6]])
    open_ = Waypoints(q=q)
    assert open_.count == 2 and not open_.closed
    np.testing.assert_array_equal(open_.visits, q)
    closed = Waypoints(q=q, closed=True)
    np.testing.assert_array_equal(closed.visits, [q[0], q[1], q[0]])
    assert not closed.q.flags.writeable


@pytest.mark.parametrize(
    "q, match",
    [
        (np.zeros(3), r"shape \(k, nq\)"),
        (np.zeros((0, 3)), r"shape \(k, nq\)"),
        (np.zeros((1, 2, 3)), r"shape \(k, nq\)"),
        ([[0.0, 1.0], [math.nan, 0.0]], r"waypoint row 2: q\[0\] = nan is not finite"),
        ([["a", 1.0]], "array of numbers"),
        (np.zeros((MAX_WAYPOINTS + 1, 2)), "MAX_WAYPOINTS"),
    ],
)
def test_bad_shapes_refused(q, match):
    with pytest.raises(ParameterError, match=match):
        Waypoints(q=q)


def test_closed_must_be_bool():
    with pytest.raises(ParameterError, match="closed must be a bool"):
        Waypoints(q=np.zeros((1, 2)), closed="yes")  # type: ignore[arg-type]


def test_check_width_and_limits_name_the_row(problem):
    bounds = problem.bounds()
    ok = Waypoints(q=np.vstack([problem.start.q, problem.goal.q]))
    ok.check(bounds, robot_name="youbot")
    with pytest.raises(ParameterError, match=r"must have 3 columns .*'youbot'.*\(2, 2\)"):
        Waypoints(q=np.zeros((2, 2))).check(bounds, robot_name="youbot")
    q = np.vstack([problem.start.q, problem.goal.q, problem.goal.q])
    q[2, 1] = bounds.q_upper[1] + 0.01
    with pytest.raises(ParameterError, match=r"waypoint row 3: q\[1\] = .* outside") as info:
        Waypoints(q=q).check(bounds)
    assert info.value.value == 3


def test_from_configurations_closes_by_default():
    conf = np.arange(6.0).reshape(3, 2)
    w = Waypoints.from_configurations(conf)
    assert w.closed
    np.testing.assert_array_equal(w.visits[-1], conf[0])
    assert not Waypoints.from_configurations(conf, closed=False).closed


def test_load_csv_with_and_without_header(tmp_path):
    (tmp_path / "w.csv").write_text("j1,j2\n0.1,0.2\n\n0.3,0.4\n")
    w = load_waypoints(tmp_path / "w.csv")
    np.testing.assert_array_equal(w.q, [[0.1, 0.2], [0.3, 0.4]])
    assert not w.closed
    (tmp_path / "n.csv").write_text("0.1,0.2\n0.3,0.4\n")
    assert load_waypoints(tmp_path / "n.csv", closed=True).closed


def test_load_json_list_and_object(tmp_path):
    (tmp_path / "a.json").write_text(json.dumps([[0.1, 0.2], [0.3, 0.4]]))
    np.testing.assert_array_equal(load_waypoints(tmp_path / "a.json").q, [[0.1, 0.2], [0.3, 0.4]])
    (tmp_path / "b.json").write_text(json.dumps({"q": [[1, 2]], "closed": True}))
    w = load_waypoints(tmp_path / "b.json")
    assert w.closed and w.q.dtype == float
    assert not load_waypoints(tmp_path / "b.json", closed=False).closed


@pytest.mark.parametrize(
    "name, text, match",
    [
        ("r.csv", "0.1,0.2\n0.3\n", "waypoint 2 has 1 values, the first has 2"),
        ("x.csv", "a,b\n0.1,zz\n", r"x.csv row 2 column 2: 'zz' is not a number"),
        ("i.csv", "0.1,inf\n", "row 1 column 2: 'inf' is not finite"),
        ("e.csv", "a,b\n", "no waypoints"),
        ("k.json", '{"q": [[1]], "speed": 2}', r"unknown key\(s\) \['speed'\]"),
        ("c.json", '{"q": [[1]], "closed": 1}', "'closed' must be true or false"),
        ("s.json", '[[1, "2"]]', r"s.json row 1 column 2: '2' is not a number"),
        ("t.json", "[[1], 2]", "row 2: expected a list of numbers"),
        ("n.json", "{", "not valid JSON"),
        ("w.txt", "1,2\n", r"must end in .csv or .json"),
    ],
)
def test_bad_files_refused(tmp_path, name, text, match):
    (tmp_path / name).write_text(text)
    with pytest.raises(ParameterError, match=match):
        load_waypoints(tmp_path / name)


def test_missing_file_refused(tmp_path):
    with pytest.raises(ParameterError, match="missing.csv"):
        load_waypoints(tmp_path / "missing.csv")
