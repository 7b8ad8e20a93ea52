"""The replay scene finds the tip frame when a fixed joint and a link share its name."""

from __future__ import annotations

import warnings

import numpy as np
import pinocchio as pin

from youbot_opt.robot.load import load_model
from youbot_opt.viz.meshcat.scene import ee_points


def test_tip_points_on_a_robot_with_a_shared_frame_name():
    """z1's tip 'gripperStator' names a joint and a link; the path uses the link (as FK does)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        robot = load_model("z1", tip_frame="gripperStator")
    model, data = robot.model, robot.model.createData()
    rng = np.random.default_rng(0)
    q = rng.uniform(-0.5, 0.5, size=(2, robot.nq))
    points = ee_points(robot, np.array([0.0, 1.0]), q, np.array([0.0, 1.0]))
    frame = robot.frame_id("gripperStator")
    assert model.frames[frame].type == pin.FrameType.BODY
    for qk, point in zip(q, points, strict=True):
        pin.framesForwardKinematics(model, data, qk)
        np.testing.assert_allclose(point, data.oMf[frame].translation, atol=1e-12)
