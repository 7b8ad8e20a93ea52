"""Tests of the multi-result replay: several solves side by side or as ghosts, HTML and live."""

from __future__ import annotations

import base64
import json
import re

import numpy as np
import pytest

meshcat = pytest.importorskip("meshcat")
import pinocchio as pin  # noqa: E402
import umsgpack  # noqa: E402

from youbot_opt.exceptions import ParameterError  # noqa: E402
from youbot_opt.reproduction.study1 import study1_problem  # noqa: E402
from youbot_opt.trajopt.result import TrajOptResult  # noqa: E402
from youbot_opt.trajopt.solver import TrajOptSolver  # noqa: E402
from youbot_opt.viz import MeshcatServer  # noqa: E402
from youbot_opt.viz.meshcat.results import (  # noqa: E402
    export_results_html,
    replay_results,
    result_tracks,
)
from youbot_opt.viz.meshcat.scene import GHOST_OPACITY, PLANAR_SPACING  # noqa: E402

BETAS = (0.2, 0.5, 0.9)


@pytest.fixture(scope="module")
def results() -> list[TrajOptResult]:
    """Three real 15-knot study-1 solves at different time weights (different durations)."""
    solver = TrajOptSolver(study1_problem(15))
    out = [solver.solve(beta=b) for b in BETAS]
    assert all(r.success for r in out)
    return out


def _commands(page: str) -> list[dict]:
    """Decode the meshcat commands an exported page replays."""
    blob = re.search(r"var commands = (\[.*?\]);", page, re.S)
    assert blob is not None
    return [umsgpack.unpackb(base64.b64decode(c)) for c in json.loads(blob.group(1))]


def _geometry_translation(robot, q: np.ndarray, go) -> np.ndarray:
    """Position of a geometry object in the base frame, composed by hand from its joint."""
    data = robot.model.createData()
    pin.forwardKinematics(robot.model, data, q)
    return (data.oMi[go.parentJoint] * go.placement).translation


def _server_scene(vis) -> list[dict]:
    """Decode the commands the server keeps for its scene (its own static HTML)."""
    html = vis.static_html()
    blobs = re.findall(r"data:application/octet-binary;base64,([A-Za-z0-9+/=]+)", html)
    return [umsgpack.unpackb(base64.b64decode(b)) for b in blobs]


def test_side_by_side_html_holds_every_result(results, tmp_path):
    """Each result is a labelled copy, spaced in the arm's plane, animated to its own end pose."""
    robot = results[0].problem.robot
    labels = [f"beta = {b} <{i}>" for i, b in enumerate(BETAS)]
    path = export_results_html(results, tmp_path / "front.html", labels=labels)
    page = path.read_text()
    commands = _commands(page)
    nodes = [re.sub(r"[^A-Za-z0-9_.\-]+", "_", lab).strip("_") for lab in labels]
    transforms = {c["path"]: c["matrix"] for c in commands if c["type"] == "set_transform"}
    objects = {c["path"] for c in commands if c["type"] == "set_object"}
    offsets = []
    for node in nodes:
        for go in robot.visual_model.geometryObjects:
            assert f"/meshcat/youbot_opt/{node}/visuals/{go.name}" in objects
        assert f"/meshcat/youbot_opt/{node}/ee_path" in objects
        offsets.append(np.reshape(transforms[f"/meshcat/youbot_opt/{node}"], (4, 4)).T[:3, 3])
    offsets = np.array(offsets)
    # The planar youBot moves in its x-z plane: copies go along +x, centred on the origin,
    # PLANAR_SPACING times the motion's x extent apart (joint origins and tips, by FK here).
    data = robot.model.createData()
    xs = []
    for r in results:
        for q in r.trajectory.q:
            pin.framesForwardKinematics(robot.model, data, q)
            xs += [m.translation[0] for m in data.oMi[1:]]
            xs.append(data.oMf[robot.model.getFrameId(robot.tip_frame)].translation[0])
    step = PLANAR_SPACING * (max(xs) - min(xs))
    np.testing.assert_allclose(offsets[:, 0], [-step, 0.0, step], atol=1e-9)  # float64 exact-ish
    np.testing.assert_allclose(offsets[:, 1:], 0.0, atol=1e-12)
    # The legend names every result (HTML-escaped) next to its colour.
    for lab in labels:
        assert lab.replace("<", "&lt;").replace(">", "&gt;") in page
    assert "side by side" in page
    # The animation ends each copy at its own final pose (held after its own end).
    (animation,) = [c for c in commands if c["type"] == "set_animation"]
    clips = {a["path"]: a["clip"] for a in animation["animations"]}
    end = max(r.duration for r in results)
    for node, r in zip(nodes, results, strict=True):
        for go in robot.visual_model.geometryObjects:
            tracks = clips[f"/meshcat/youbot_opt/{node}/visuals/{go.name}"]["tracks"]
            (position,) = [t for t in tracks if t["name"] == ".position"]
            last = position["keys"][-1]
            assert last["time"] == pytest.approx(end * 30.0, rel=1e-12)  # frame = time * fps
            expected = _geometry_translation(robot, r.trajectory.q[-1], go)
            np.testing.assert_allclose(last["value"], expected, atol=1e-12)


def test_ghost_layout_draws_translucent_copies(results, tmp_path):
    """Ghosts sit on the first copy, translucent; default labels carry the objectives."""
    page = export_results_html(results, tmp_path / "g.html", layout="ghosts").read_text()
    commands = _commands(page)
    ghosts = [c for c in commands if c["type"] == "set_object" and "/ghost_" in c["path"]]
    assert {c["path"].split("/")[3] for c in ghosts} == {"ghost_0", "ghost_1"}
    opacities = [
        material["opacity"]
        for c in ghosts
        if not c["path"].endswith("ee_path")
        for material in c["object"]["materials"]
    ]
    n_geoms = len(results[0].problem.robot.visual_model.geometryObjects)
    assert len(opacities) >= 2 * n_geoms  # every visual of both ghosts has a material
    np.testing.assert_allclose(opacities, GHOST_OPACITY)
    transforms = {c["path"]: c["matrix"] for c in commands if c["type"] == "set_transform"}
    for node in ("ghost_0", "ghost_1"):  # ghosts overlay the first copy, at the origin
        np.testing.assert_allclose(transforms[f"/meshcat/youbot_opt/{node}"][12:15], 0.0)
    for i, r in enumerate(results):
        assert f"{i}: f = {r.objective:.5g}" in page


def test_result_tracks_rejects_bad_input(results):
    """Empty input, wrong label counts, layouts and robotless trajectories raise ParameterError."""
    with pytest.raises(ParameterError, match="at least one result"):
        result_tracks([])
    with pytest.raises(ParameterError, match="one label per result"):
        result_tracks(results, labels=["a"])
    with pytest.raises(ParameterError, match="robot is required"):
        result_tracks([results[0].trajectory])
    with pytest.raises(ParameterError, match="must be a TrajOptResult"):
        result_tracks([object()], robot=results[0].problem.robot)
    with pytest.raises(ParameterError, match="layout must be one of"):
        export_results_html(results, "x.html", layout="grid")
    robot, tracks = result_tracks([results[0].trajectory], robot=results[0].problem.robot)
    assert tracks[0][2] == "run 0" and robot is results[0].problem.robot


def test_live_replay_of_several_results_on_a_loopback_server(results):
    """The live viewer receives one labelled copy per result; the server is stopped after."""
    robot = results[0].problem.robot
    labels = ["slow", "middle", "fast"]
    with MeshcatServer(timeout=20.0) as server:
        vis = replay_results(results, labels=labels, viewer=server.visualizer(), realtime=False)
        scene = _server_scene(vis)
    assert not server.running
    objects = {c["path"] for c in scene if c["type"] == "set_object"}
    for label in labels:
        for go in robot.visual_model.geometryObjects:
            assert f"/meshcat/youbot_opt/{label}/visuals/{go.name}" in objects
    assert any(c["type"] == "set_animation" for c in scene)
