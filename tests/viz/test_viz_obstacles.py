"""Obstacles of a Scene in the meshcat replay: live server and standalone HTML (#28 item 6)."""

from __future__ import annotations

import base64
import json
import re
from types import SimpleNamespace

import numpy as np
import pytest

meshcat = pytest.importorskip("meshcat")
import pinocchio as pin  # noqa: E402
import umsgpack  # noqa: E402

from youbot_opt.collision.scene import Obstacle, Scene  # noqa: E402
from youbot_opt.collision.shapes import (  # noqa: E402
    Box,
    Capsule,
    Cylinder,
    HalfSpace,
    Mesh,
    Sphere,
)
from youbot_opt.exceptions import FrameNotFound, ParameterError  # noqa: E402
from youbot_opt.robot.load import load_model  # noqa: E402
from youbot_opt.viz import MeshcatServer, replay  # noqa: E402
from youbot_opt.viz.meshcat.geometry import OBSTACLE_COLORS, OBSTACLE_OPACITY  # noqa: E402
from youbot_opt.viz.meshcat.replay import scene_html  # noqa: E402
from youbot_opt.viz.meshcat.results import export_results_html  # noqa: E402

_TETRA = """solid t
facet normal 0 0 -1
outer loop
vertex 0 0 0
vertex 0 1 0
vertex 1 0 0
endloop
endfacet
facet normal 0 -1 0
outer loop
vertex 0 0 0
vertex 1 0 0
vertex 0 0 1
endloop
endfacet
facet normal -1 0 0
outer loop
vertex 0 0 0
vertex 0 0 1
vertex 0 1 0
endloop
endfacet
facet normal 1 1 1
outer loop
vertex 1 0 0
vertex 0 1 0
vertex 0 0 1
endloop
endfacet
endsolid t
"""


@pytest.fixture(scope="module")
def ur5():
    return load_model("ur5")


@pytest.fixture
def cell(ur5, tmp_path) -> Scene:
    """One obstacle of every kind, and a box held by the tip frame."""
    stl = tmp_path / "tetra.stl"
    stl.write_text(_TETRA)
    return Scene(
        (
            Obstacle(name="table", shape=Box(size=(0.8, 0.6, 0.05)), xyz=(0.5, 0.0, -0.03)),
            Obstacle(name="ball", shape=Sphere(radius=0.1), xyz=(0.4, 0.4, 0.3)),
            Obstacle(
                name="post",
                shape=Cylinder(radius=0.05, length=0.6),
                xyz=(-0.4, 0.3, 0.3),
                rpy=(0.3, 0.0, 0.0),
            ),  # fmt: skip
            Obstacle(name="bar", shape=Capsule(radius=0.03, length=0.4), xyz=(0.0, -0.5, 0.6)),
            Obstacle(name="floor", shape=HalfSpace(), xyz=(0.0, 0.0, -0.1)),
            Obstacle(name="rock", shape=Mesh(path=stl, scale=(0.2, 0.2, 0.2)), xyz=(0.3, -0.4, 0)),
            Obstacle(
                name="held box",
                shape=Box(size=(0.1, 0.1, 0.1)),
                xyz=(0.0, 0.0, 0.06),
                rpy=(0.0, 0.0, 0.5),
                frame=ur5.tip_frame,
            ),  # fmt: skip
        )
    )


def _ramp(robot, n: int, duration: float) -> tuple[np.ndarray, np.ndarray]:
    t = np.linspace(0.0, duration, n)
    q_end = pin.neutral(robot.model) + 0.6
    return t, np.outer(t / duration, q_end) + np.outer(1 - t / duration, pin.neutral(robot.model))


def _commands(page: str) -> list[dict]:
    blob = re.search(r"var commands = (\[.*?\]);", page, re.S)
    assert blob is not None
    return [umsgpack.unpackb(base64.b64decode(c)) for c in json.loads(blob.group(1))]


def _pose(obstacle: Obstacle) -> np.ndarray:
    return pin.SE3(obstacle.rotation, obstacle.translation).homogeneous


def _held_pose(robot, q: np.ndarray, obstacle: Obstacle) -> np.ndarray:
    """Pose of the held box, composed by hand from the tip frame's placement."""
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, q)
    frame_ids = [
        i
        for i, f in enumerate(robot.model.frames)
        if f.name == obstacle.frame and f.type == pin.FrameType.BODY
    ] or [robot.model.getFrameId(obstacle.frame)]
    return data.oMf[frame_ids[0]].homogeneous @ _pose(obstacle)


def test_html_draws_every_obstacle_kind_and_moves_the_held_box(ur5, cell):
    """World obstacles are placed once with their pose; the held box is keyed at the tip."""
    t, q = _ramp(ur5, n=5, duration=0.5)
    fps = 10.0
    commands = _commands(scene_html(ur5, t, q, fps=fps, obstacles=cell))
    objects = {c["path"]: c["object"] for c in commands if c["type"] == "set_object"}
    transforms = {
        c["path"]: np.reshape(c["matrix"], (4, 4)).T
        for c in commands
        if c["type"] == "set_transform"
    }
    root = "/meshcat/youbot_opt/ur5"
    kinds = {"table": "Box", "ball": "Sphere", "post": "Cylinder", "bar": "Capsule",
             "floor": "HalfSpace", "rock": "Mesh"}  # fmt: skip
    for name, kind in kinds.items():
        obj = objects[f"{root}/obstacles/{name}"]
        (material,) = obj["materials"]
        assert material["color"] == OBSTACLE_COLORS[kind]
        assert material["opacity"] == OBSTACLE_OPACITY and material["transparent"]
        # float64 matrices travel exactly; 1e-12 allows for rounding only.
        np.testing.assert_allclose(
            transforms[f"{root}/obstacles/{name}"], _pose(cell.obstacle(name)), atol=1e-12
        )
    table = objects[f"{root}/obstacles/table"]["geometries"][0]
    assert (table["width"], table["height"], table["depth"]) == pytest.approx((0.8, 0.6, 0.05))
    assert objects[f"{root}/obstacles/ball"]["geometries"][0]["radius"] == pytest.approx(0.1)
    post = objects[f"{root}/obstacles/post"]["geometries"][0]
    assert post["height"] == pytest.approx(0.6) and post["radiusTop"] == pytest.approx(0.05)
    floor = objects[f"{root}/obstacles/floor"]
    # the slab's top face is the plane: shifted down by half its depth (three.js column order)
    slab = np.reshape(floor["object"]["matrix"], (4, 4)).T
    assert slab[2, 3] == pytest.approx(-floor["geometries"][0]["depth"] / 2)
    rock = objects[f"{root}/obstacles/rock"]["geometries"][0]
    vertices = np.frombuffer(rock["data"]["attributes"]["position"]["array"].data, np.float32)
    assert np.max(vertices) == pytest.approx(0.2)  # the scale is applied
    assert f"{root}/carried/held_box" in objects
    (animation,) = [c for c in commands if c["type"] == "set_animation"]
    clips = {a["path"]: a["clip"] for a in animation["animations"]}
    assert not any("/obstacles/" in path for path in clips)  # world obstacles do not move
    tracks = {tr["name"]: tr["keys"] for tr in clips[f"{root}/carried/held_box"]["tracks"]}
    times = np.append(np.arange(0.0, 0.5, 1 / fps), 0.5)
    held = cell.obstacle("held box")
    for key_pos, key_quat, time_s in zip(
        tracks[".position"], tracks[".quaternion"], times, strict=True
    ):
        q_ref = np.array([np.interp(time_s, t, q[:, j]) for j in range(ur5.model.nq)])
        pose = pin.SE3(_held_pose(ur5, q_ref, held))
        quat = pin.Quaternion(pose.rotation).coeffs()
        np.testing.assert_allclose(key_pos["value"], pose.translation, atol=1e-12)
        sign = np.sign(np.dot(quat, key_quat["value"]))
        np.testing.assert_allclose(key_quat["value"], sign * quat, atol=1e-12)


def test_live_replay_draws_obstacles_with_each_copy(ur5, cell):
    """Real server: world obstacles under the main and side copies, not the ghost; held box last."""
    t, q = _ramp(ur5, n=4, duration=0.3)
    with MeshcatServer(timeout=20.0) as server:
        vis = server.visualizer()
        replay(ur5, t, q, viewer=vis, obstacles=cell, ghosts=[(t, q[::-1])], extra=[(t, q, "b")])
        html = vis.static_html()
    blobs = re.findall(r"data:application/octet-binary;base64,([A-Za-z0-9+/=]+)", html)
    scene = [umsgpack.unpackb(base64.b64decode(b)) for b in blobs]
    paths = {c["path"] for c in scene if c["type"] == "set_object"}
    transforms = {
        c["path"]: np.reshape(c["matrix"], (4, 4)).T for c in scene if c["type"] == "set_transform"
    }
    for copy in ("ur5", "b"):
        assert f"/meshcat/youbot_opt/{copy}/obstacles/table" in paths
        np.testing.assert_allclose(
            transforms[f"/meshcat/youbot_opt/{copy}/obstacles/ball"],
            _pose(cell.obstacle("ball")),
            atol=1e-12,
        )
    assert not any(p.startswith("/meshcat/youbot_opt/ghost_0/obstacles") for p in paths)
    held = cell.obstacle("held box")
    np.testing.assert_allclose(
        transforms["/meshcat/youbot_opt/ur5/carried/held_box"],
        _held_pose(ur5, q[-1], held),
        atol=1e-12,
    )
    np.testing.assert_allclose(
        transforms["/meshcat/youbot_opt/ghost_0/carried/held_box"],
        _held_pose(ur5, q[0], held),
        atol=1e-12,
    )


def test_result_replay_takes_the_problem_scene(ur5, cell, tmp_path):
    """export_results_html draws the first result's problem scene unless told otherwise."""
    t, q = _ramp(ur5, n=4, duration=0.3)
    result = SimpleNamespace(
        problem=SimpleNamespace(robot=ur5, clearance=SimpleNamespace(scene=cell)),
        trajectory=SimpleNamespace(t=t, q=q),
        objective=1.0,
    )
    page = export_results_html([result, result], tmp_path / "r.html", labels=["a", "b"])
    paths = {c["path"] for c in _commands(page.read_text()) if c["type"] == "set_object"}
    assert "/meshcat/youbot_opt/a/obstacles/table" in paths
    assert "/meshcat/youbot_opt/b/carried/held_box" in paths
    none = Scene()
    page = export_results_html([result], tmp_path / "n.html", labels=["a"], obstacles=none)
    paths = {c["path"] for c in _commands(page.read_text()) if c["type"] == "set_object"}
    assert not any("obstacles" in p or "carried" in p for p in paths)


def test_obstacles_refused_with_a_reason(ur5):
    t, q = _ramp(ur5, n=3, duration=0.2)
    lost = Scene((Obstacle(name="lost", shape=Sphere(radius=0.1), frame="no_such_frame"),))
    with pytest.raises(FrameNotFound, match="no_such_frame"):
        scene_html(ur5, t, q, obstacles=lost)
    with pytest.raises(ParameterError, match="obstacles must be a Scene"):
        scene_html(ur5, t, q, obstacles=[Obstacle(name="x", shape=Sphere(radius=0.1))])
