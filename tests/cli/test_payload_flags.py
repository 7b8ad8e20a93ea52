"""The payload flags of solve and report: the model carries the payload (#30 item 1)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from youbot_opt.cli import main
from youbot_opt.robot.load import load_model
from youbot_opt.robot.model import RobotModel


def _gravity(capsys) -> np.ndarray:
    line = next(
        ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("gravity torque")
    )
    return np.array([float(x) for x in line.split("[")[1].split("]")[0].split()])


def test_report_with_a_point_mass_adds_m_jt_g(capsys):
    """N(q) grows by -m J^T g, J the tip's linear Jacobian (the printed 6 decimals)."""
    assert main(["report", "--robot", "youbot"]) == 0
    bare = _gravity(capsys)
    assert main(["report", "--robot", "youbot", "--payload-mass", "0.5"]) == 0
    out_loaded = _gravity(capsys)
    robot: RobotModel = load_model("youbot")
    from youbot_opt.robot.params import STUDY_Q_START

    q = np.asarray(STUDY_Q_START, dtype=float)
    data = robot.model.createData()
    frame = robot.model.getFrameId(robot.tip_frame)
    jac = pin.computeFrameJacobian(robot.model, data, q, frame, pin.LOCAL_WORLD_ALIGNED)[:3]
    expected = bare - 0.5 * jac.T @ robot.model.gravity.linear
    np.testing.assert_allclose(out_loaded, expected, atol=2e-6)  # two 6-decimal roundings


def test_report_names_the_payload(capsys):
    argv = [
        "report",
        "--robot",
        "youbot",
        "--payload-mass",
        "0.25",
        "--payload-com",
        "0",
        "0",
        "0.01",
    ]
    assert main(argv) == 0
    assert (
        "payload: 0.25 kg at [0.0, 0.0, 0.01] m in frame 'gripper_tip'" in capsys.readouterr().out
    )


def test_payload_flags_without_a_mass_are_refused(capsys):
    assert main(["report", "--payload-inertia", "1", "1", "1"]) == 2
    assert "--payload-inertia given without --payload-mass" in capsys.readouterr().err


def test_a_payload_that_is_no_rigid_body_is_refused(capsys):
    argv = ["report", "--payload-mass", "1", "--payload-inertia", "1", "1", "5"]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and "inertia" in err
