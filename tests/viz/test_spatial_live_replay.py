"""Live meshcat replay of a spatial IK path (issue 14): robot, target markers, closed cycle."""

from __future__ import annotations

import base64
import re

import numpy as np
import pytest

meshcat = pytest.importorskip("meshcat")
import pinocchio as pin  # noqa: E402
import umsgpack  # noqa: E402

from youbot_opt.ikpath.problem import CyclicIKProblem  # noqa: E402
from youbot_opt.ikpath.result import build_result  # noqa: E402
from youbot_opt.ikpath.targets import Target  # noqa: E402
from youbot_opt.nlp.status import SolveStatus  # noqa: E402
from youbot_opt.robot.load import load_model  # noqa: E402
from youbot_opt.viz import MeshcatServer  # noqa: E402
from youbot_opt.viz.meshcat.ikpath import (  # noqa: E402
    replay_ikpath,
    replay_robot,
)

_INERTIAL = (  # the loader checks that M(q) is positive definite
    '<inertial><mass value="1"/><inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" '
    'izz="0.1"/></inertial>'
)
_URDF = (  # a 3-joint spatial arm (z, y, y) with primitive visuals
    '<robot name="arm3"><link name="base"/>'
    + "".join(
        f'<joint name="j{i}" type="revolute"><parent link="{p}"/><child link="l{i}"/>'
        f'<origin xyz="0 0 {z}"/><axis xyz="{ax}"/>'
        '<limit lower="-3" upper="3" effort="1" velocity="1"/></joint>'
        f'<link name="l{i}">{_INERTIAL}<visual><origin xyz="0 0 0.15"/><geometry>'
        '<cylinder radius="0.03" length="0.3"/></geometry></visual></link>'
        for i, (p, z, ax) in enumerate(
            (("base", 0.1, "0 0 1"), ("l0", 0.1, "0 1 0"), ("l1", 0.3, "0 1 0"))
        )
    )
    + '<joint name="tip_joint" type="fixed"><parent link="l2"/><child link="tip"/>'
    '<origin xyz="0 0 0.3"/></joint><link name="tip"/></robot>'
)


def _server_scene(vis) -> list[dict]:
    """Decode the commands a live server keeps for its scene."""
    html = vis.static_html()
    blobs = re.findall(r"data:application/octet-binary;base64,([A-Za-z0-9+/=]+)", html)
    return [umsgpack.unpackb(base64.b64decode(b)) for b in blobs]


def test_live_spatial_replay_draws_the_targets_and_ends_at_the_first_configuration(tmp_path):
    """The server binds 127.0.0.1 only and is stopped at the end of the block."""
    path = tmp_path / "arm3.urdf"
    path.write_text(_URDF)
    robot = load_model(path, tip_frame="tip")
    base = CyclicIKProblem(
        robot=robot.model,
        frame="tip",
        targets=(Target(position=(0, 0, 0)), Target(position=(0, 0, 0))),
    )
    q = np.array([[0.0, 0.4, 0.8], [1.2, -0.3, 0.9], [-1.0, 0.6, -0.5]])
    p = [base.placement(theta) for theta in q]
    problem = base.with_targets(  # met exactly by q: a pose, an approach and a position
        (
            Target(position=p[0].translation, rotation=p[0].rotation),
            Target(position=p[1].translation, approach=p[1].rotation[:, 2]),
            Target(position=p[2].translation),
        )
    )
    result = build_result(
        problem,
        method="ipopt",
        status=SolveStatus.SOLVED,
        x=q.ravel(),
        multipliers=np.zeros(problem.n_constraints),
        iterations=0,
        wall_time=0.0,
        message="exact",
        start=q.ravel(),
    )
    assert result.success
    with MeshcatServer(timeout=20.0) as server:
        assert server.zmq_url.startswith("tcp://127.0.0.1:")
        vis = server.visualizer()
        replay_ikpath(result, robot, viewer=vis, segment_time=0.02, realtime=True)
        scene = _server_scene(vis)
        vis.close()
    assert not server.running
    shown = replay_robot(result, robot)
    root = f"/meshcat/ikpath/{shown.name}"
    transforms = {
        c["path"]: np.reshape(c["matrix"], (4, 4)).T for c in scene if c["type"] == "set_transform"
    }
    # The cycle is closed: the last pose streamed is configuration 1 again. Reference:
    # Pinocchio's forward kinematics composed by hand with each visual's placement;
    # float64 matrices travel exactly (msgpack doubles), 1e-12 allows for rounding only.
    data = robot.model.createData()
    pin.forwardKinematics(robot.model, data, problem.configuration(q[0]))
    links = [g for g in shown.visual_model.geometryObjects if not g.name.startswith("target")]
    assert len(links) == 3
    for go in links:
        want = (data.oMi[go.parentJoint] * go.placement).homogeneous
        np.testing.assert_allclose(transforms[f"{root}/visuals/{go.name}"], want, atol=1e-12)
    # Markers: a sphere on every target; a triad along the pose target's rotation columns,
    # one rod along the approach direction, nothing more for the position target.
    names = {go.name for go in shown.visual_model.geometryObjects}
    assert names - {go.name for go in links} == {
        "target_1",
        "target_1_axis_0",
        "target_1_axis_1",
        "target_1_axis_2",
        "target_2",
        "target_2_axis_0",
        "target_3",
    }
    for j, target in enumerate(problem.targets):
        sphere = transforms[f"{root}/visuals/target_{j + 1}"]
        np.testing.assert_allclose(sphere[:3, 3], target.position, atol=1e-12)
    z = [transforms[f"{root}/visuals/target_1_axis_{k}"][:3, 2] for k in range(3)]
    np.testing.assert_allclose(np.column_stack(z), p[0].rotation, atol=1e-12)
    rod = transforms[f"{root}/visuals/target_2_axis_0"][:3, 2]
    np.testing.assert_allclose(rod, p[1].rotation[:, 2], atol=1e-12)
