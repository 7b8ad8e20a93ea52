"""Joint damping is bounded by MAX_JOINT_DAMPING, from the API and from a URDF (#29)."""

from __future__ import annotations

import pytest

from youbot_opt.exceptions import ParameterError
from youbot_opt.robot.load import MAX_JOINT_DAMPING, load_model
from youbot_opt.robot.urdf import urdf_string


def test_the_limit_is_accepted_and_above_it_refused():
    robot = load_model("youbot", damping=MAX_JOINT_DAMPING)
    assert float(robot.model.damping.max()) == MAX_JOINT_DAMPING
    with pytest.raises(ParameterError, match="MAX_JOINT_DAMPING = 1e\\+06"):
        load_model("youbot", damping=MAX_JOINT_DAMPING * 1.0001)


def test_a_urdf_damping_over_the_limit_names_the_joint(tmp_path):
    text = urdf_string(damping=0.1)
    assert 'damping="' in text
    head, tail = text.split('damping="', 1)
    value, rest = tail.split('"', 1)
    path = tmp_path / "stiff.urdf"
    path.write_text(f'{head}damping="1e308"{rest}')
    with pytest.raises(ParameterError, match=r"joint damping over MAX_JOINT_DAMPING.*\(1e\+308\)"):
        load_model(path)
    assert load_model(path, damping=0.1).model.damping.max() == 0.1  # the override wins
