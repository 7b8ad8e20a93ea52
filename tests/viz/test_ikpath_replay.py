"""Meshcat replay of IK-path results (HTML export and live) and their save/load round trip."""

from __future__ import annotations

import base64
import json
import re
from pathlib import Path

import numpy as np
import pytest

meshcat = pytest.importorskip("meshcat")
import pinocchio as pin  # noqa: E402
import umsgpack  # noqa: E402

from youbot_opt._files import json_digest  # noqa: E402
from youbot_opt.exceptions import ParameterError, ResultFileError  # noqa: E402
from youbot_opt.ikpath.examples import example_problem  # noqa: E402
from youbot_opt.ikpath.io import load_result, save_result  # noqa: E402
from youbot_opt.ikpath.solve import solve  # noqa: E402
from youbot_opt.viz import MeshcatServer  # noqa: E402
from youbot_opt.viz.meshcat.ikpath import (  # noqa: E402
    export_ikpath_html,
    replay_ikpath,
    replay_robot,
    replay_track,
)


@pytest.fixture(scope="module")
def result_a():
    """Example A solved by the augmented Lagrangian from the zero start."""
    res = solve(example_problem("A"))
    assert res.success
    return res


def _page_commands(page: str) -> list[dict]:
    """Decode the scene commands an exported page replays."""
    blob = re.search(r"var commands = (\[.*?\]);", page, re.S)
    assert blob is not None
    return [umsgpack.unpackb(base64.b64decode(c)) for c in json.loads(blob.group(1))]


def _server_scene(vis) -> list[dict]:
    """Decode the commands a live server keeps for its scene."""
    html = vis.static_html()
    blobs = re.findall(r"data:application/octet-binary;base64,([A-Za-z0-9+/=]+)", html)
    return [umsgpack.unpackb(base64.b64decode(b)) for b in blobs]


def _pose(chain, q, go) -> np.ndarray:
    """Pose of a visual geometry object composed by hand from the joint placement."""
    data = chain.model.createData()
    pin.forwardKinematics(chain.model, data, q)
    return (data.oMi[go.parentJoint] * go.placement).homogeneous


def test_replay_track_closes_the_cycle_with_a_time_per_segment(result_a, tmp_path):
    """Knots at j * segment_time, the first configuration repeated at the end; bad input named."""
    t, q = replay_track(result_a, segment_time=0.5)
    np.testing.assert_array_equal(t, 0.5 * np.arange(6))
    np.testing.assert_array_equal(q[:5], result_a.configurations)
    np.testing.assert_array_equal(q[5], result_a.configurations[0])
    with pytest.raises(ParameterError, match="segment_time must be a positive"):
        replay_track(result_a, segment_time=0.0)
    with pytest.raises(ParameterError, match="number of targets"):
        export_ikpath_html(result_a, tmp_path / "x.html", others=[solve(_three_targets())])


def _three_targets():
    from youbot_opt.ikpath.problem import CyclicIKProblem

    prob = example_problem("A")
    return CyclicIKProblem(robot=prob.chain, targets=prob.target_points[:3])


def test_html_export_of_example_a_holds_the_animation_and_the_targets(result_a, tmp_path):
    """The page keys the linear joint-space path, draws the tip path and marks the targets.

    Key frames are float64 poses of Pinocchio FK (exact transfer: 1e-12); the tip
    path is float32 (6e-8 relative on a 7 m reach: 2e-6 m).
    """
    fps = 10.0
    path = export_ikpath_html(result_a, tmp_path / "a.html", segment_time=0.5, fps=fps)
    page = path.read_text(encoding="utf-8")
    commands = _page_commands(page)
    chain = result_a.problem.chain
    root = f"/meshcat/ikpath/{chain.name}"
    objects = {c["path"]: c for c in commands if c["type"] == "set_object"}
    transforms = {
        c["path"]: np.reshape(c["matrix"], (4, 4)).T
        for c in commands
        if c["type"] == "set_transform"
    }
    targets3 = np.column_stack([result_a.problem.target_points, np.zeros(5)])
    for k, p in enumerate(targets3):  # the viewer's markers and the robot's own spheres
        assert f"{root}/targets/{k}" in objects
        np.testing.assert_allclose(transforms[f"{root}/targets/{k}"][:3, 3], p, atol=1e-12)
        assert f"{root}/visuals/target_{k + 1}" in objects
    (anim,) = [c for c in commands if c["type"] == "set_animation"]
    clips = {a["path"]: a["clip"] for a in anim["animations"]}
    q_closed = np.vstack([result_a.configurations, result_a.configurations[:1]])
    for go in chain.visual_model.geometryObjects:
        clip = clips[f"{root}/visuals/{go.name}"]
        tracks = {tr["name"]: tr["keys"] for tr in clip["tracks"]}
        times = np.array([k["time"] / fps for k in tracks[".position"]])
        assert times[-1] == pytest.approx(2.5, abs=1e-12)  # 5 segments of 0.5 s
        for time_s in (0.0, 0.7, 1.0, 2.2, 2.5):  # knots and points between them
            (i,) = np.flatnonzero(np.isclose(times, time_s, atol=1e-9))
            j, frac = divmod(time_s / 0.5, 1.0)
            j = int(j)
            q_ref = q_closed[j] if j == 5 else (1 - frac) * q_closed[j] + frac * q_closed[j + 1]
            expected = _pose(chain, q_ref, go)[:3, 3]
            np.testing.assert_allclose(tracks[".position"][i]["value"], expected, atol=1e-12)
    line = objects[f"{root}/ee_path"]["object"]["geometries"][0]
    raw = line["data"]["attributes"]["position"]["array"].data
    points = np.frombuffer(raw, dtype=np.float32).reshape(-1, 3)
    for p in targets3:  # the tip passes through every target
        assert np.min(np.linalg.norm(points - p, axis=1)) < 2e-6


def test_live_replay_of_example_a_on_a_loopback_server(result_a):
    """Live replay ends back at configuration 1 (closed cycle) with the targets drawn.

    The server binds 127.0.0.1 only and is stopped at the end of the block.
    """
    with MeshcatServer(timeout=20.0) as server:
        assert server.zmq_url.startswith("tcp://127.0.0.1:")
        assert server.web_url.startswith("http://127.0.0.1:")
        vis = server.visualizer()
        replay_ikpath(result_a, viewer=vis, segment_time=0.02, realtime=True)
        scene = _server_scene(vis)
        vis.close()
    assert not server.running
    chain = result_a.problem.chain
    root = f"/meshcat/ikpath/{chain.name}"
    transforms = {
        c["path"]: np.reshape(c["matrix"], (4, 4)).T for c in scene if c["type"] == "set_transform"
    }
    robot = replay_robot(result_a)
    for go in robot.visual_model.geometryObjects:
        # float64 matrices travel exactly (msgpack doubles); 1e-12 allows for rounding only.
        np.testing.assert_allclose(
            transforms[f"{root}/visuals/{go.name}"],
            _pose(chain, result_a.configurations[0], go),
            atol=1e-12,
        )
    for k, p in enumerate(result_a.problem.target_points):
        np.testing.assert_allclose(transforms[f"{root}/targets/{k}"][:3, 3], [*p, 0.0], atol=1e-12)


def test_save_and_load_round_trip(result_a, tmp_path):
    """Every field survives the JSON file exactly (repr floats round-trip)."""
    path = save_result(result_a, tmp_path / "res")
    assert path.name == "res.json"
    back = load_result(path)
    assert back.status is result_a.status and back.method == result_a.method
    for key in ("configurations", "position_errors", "orientation_errors", "multipliers", "start"):
        np.testing.assert_array_equal(getattr(back, key), getattr(result_a, key))
    assert back.objective == result_a.objective
    assert back.problem.chain.n == 3 and not back.problem.chain.bounded
    np.testing.assert_array_equal(back.problem.target_points, result_a.problem.target_points)
    assert len(back.history) == len(result_a.history)
    np.testing.assert_array_equal(back.history[-1].x, result_a.history[-1].x)
    bounded = solve(example_problem("B"))
    back_b = load_result(save_result(bounded, tmp_path / "b.json"))
    np.testing.assert_array_equal(back_b.problem.chain.q_upper, np.full(3, np.pi / 2))


def _rewrite(path: Path, edit) -> None:
    doc = json.loads(path.read_text())
    edit(doc)
    path.write_text(json.dumps(doc))


def test_load_refuses_newer_corrupt_or_foreign_files(result_a, tmp_path):
    """A newer schema, a changed number, another schema or non-JSON: ResultFileError."""
    path = save_result(result_a, tmp_path / "r.json")
    _rewrite(path, lambda d: d.update(schema_version=3))
    with pytest.raises(ResultFileError, match="schema version 3 is newer"):
        load_result(path)
    path = save_result(result_a, tmp_path / "r.json")
    _rewrite(path, lambda d: d["result"]["configurations"][0].__setitem__(0, 0.5))
    with pytest.raises(ResultFileError, match="checksum mismatch"):
        load_result(path)
    path = save_result(result_a, tmp_path / "r.json")

    def consistent_lie(doc):  # a changed E with a matching checksum: caught by the recheck
        doc["result"]["objective"] += 1e-6
        doc["sha256"] = json_digest(doc["result"])

    _rewrite(path, consistent_lie)
    with pytest.raises(ResultFileError, match="disagree with the ones recomputed"):
        load_result(path)
    path = save_result(result_a, tmp_path / "r.json")
    _rewrite(path, lambda d: d.update(schema="youbot_opt.trajopt_result"))
    with pytest.raises(ResultFileError, match="unknown schema"):
        load_result(path)
    path.write_text("{not json")
    with pytest.raises(ResultFileError, match="cannot read"):
        load_result(path)


def test_one_replay_for_every_robot(result_a, tmp_path):
    """A planar chain is drawn on its links unless a robot is given; a 3-D one on its robot."""
    from youbot_opt.ikpath.problem import CyclicIKProblem
    from youbot_opt.ikpath.targets import Target
    from youbot_opt.robot.load import load_model

    on_chain = replay_robot(result_a)
    assert on_chain.model is result_a.problem.planar_chain.model and on_chain.package_dirs == ()
    robot = result_a.problem.robot_model  # the chain as a RobotModel: drawn as any robot
    on_robot = replay_robot(result_a, robot)
    names = [g.name for g in on_robot.visual_model.geometryObjects]
    assert {f"target_{j + 1}" for j in range(5)} <= set(names)
    t, q = replay_track(result_a, 0.5, robot)
    assert q.shape == (5 * 12 + 1, result_a.problem.model.nq) and t[-1] == 2.5
    ur5 = load_model("ur5")
    problem = CyclicIKProblem(
        robot=ur5, frame=ur5.tip_frame, targets=(Target(position=(0.3, 0.2, 0.4)),) * 2
    )
    res = solve(problem, x0=np.zeros(2 * problem.n_joints))
    shown = replay_robot(res)  # the problem's own robot, its visuals and a marker per target
    assert shown.model is problem.model and shown.name == ur5.name
    assert len(shown.visual_model.geometryObjects) == len(ur5.visual_model.geometryObjects) + 2
    page = export_ikpath_html(res, tmp_path / "ur5.html", segment_time=0.5)
    assert page.stat().st_size > 0
