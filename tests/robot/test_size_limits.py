"""load_model's size limits by keyword (SizeLimits), the environment variables as defaults."""

from __future__ import annotations

from pathlib import Path

import pytest

from youbot_opt.exceptions import ParameterError, UnsafeURDFError, YoubotOptWarning
from youbot_opt.robot.load import load_model
from youbot_opt.robot.urdf_check.size import MAX_DOF, MAX_JOINTS, MAX_TREE_DEPTH, SizeLimits
from youbot_opt.robot.urdf_check.xml import MAX_XML_DEPTH, MAX_XML_ELEMENTS

INERTIAL = (
    '<inertial><mass value="1"/>'
    '<inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial>'
)
LIMIT = '<limit lower="-1" upper="1" effort="1" velocity="1"/>'


def _arm(tmp_path: Path, *, joints: int = 3, nesting: int = 0, mimic: bool = False) -> Path:
    """A chain of ``joints`` revolute joints, a Gazebo block nested ``nesting`` deep."""
    body = []
    for i in range(1, joints + 1):
        tag = '<mimic joint="j1"/>' if mimic and i == joints else ""
        body.append(
            f'<link name="l{i}">{INERTIAL}</link><joint name="j{i}" type="revolute">'
            f'<parent link="l{i - 1}"/><child link="l{i}"/><origin xyz="0 0 0.1"/>'
            f'<axis xyz="0 1 0"/>{LIMIT}{tag}</joint>'
        )
    block = "<gazebo>" + "<g>" * nesting + "</g>" * nesting + "</gazebo>" if nesting else ""
    text = (
        f'<?xml version="1.0"?>\n<robot name="arm"><link name="l0"/>{"".join(body)}{block}</robot>'
    )
    path = tmp_path / "arm.urdf"
    path.write_text(text)
    return path


@pytest.fixture
def no_env(monkeypatch: pytest.MonkeyPatch) -> pytest.MonkeyPatch:
    for name in ("JOINTS", "DOF", "TREE_DEPTH", "XML_DEPTH", "XML_ELEMENTS"):
        monkeypatch.delenv(f"YOUBOT_OPT_MAX_{name}", raising=False)
    return monkeypatch


def test_size_limits_by_keyword_override_the_environment(
    tmp_path: Path, no_env: pytest.MonkeyPatch
) -> None:
    """Each limit holds by keyword; keyword beats environment variable beats default."""
    path = _arm(tmp_path, joints=3)
    assert load_model(path).nv == 3  # defaults: 1000 joints, 100 dof, depth 500
    with pytest.raises(
        UnsafeURDFError,
        match=r"3 degrees of freedom, more than the limit of 2 .*SizeLimits\(max_dof=",
    ):
        load_model(path, size_limits=SizeLimits(max_dof=2))
    with pytest.raises(UnsafeURDFError, match=r"has 3 joints, more than the limit of 2"):
        load_model(path, size_limits=SizeLimits(max_joints=2))
    with pytest.raises(UnsafeURDFError, match=r"chain of 3 joints, deeper than the limit of 2"):
        load_model(path, size_limits=SizeLimits(max_tree_depth=2))
    no_env.setenv("YOUBOT_OPT_MAX_DOF", "2")
    with pytest.raises(UnsafeURDFError, match="limit of 2"):
        load_model(path)  # the environment sets the default ...
    assert load_model(path, size_limits=SizeLimits(max_dof=3)).nv == 3  # ... the keyword wins
    no_env.setenv("YOUBOT_OPT_MAX_DOF", "many")
    with pytest.raises(ParameterError, match="YOUBOT_OPT_MAX_DOF='many' is not an integer >= 1"):
        load_model(path)


def test_xml_limits_by_keyword_reach_the_mimic_reader(
    tmp_path: Path, no_env: pytest.MonkeyPatch
) -> None:
    """A 150-deep Gazebo block loads with max_xml_depth=200, mimic joint included (read twice)."""
    path = _arm(tmp_path, joints=2, nesting=150, mimic=True)
    with pytest.raises(
        UnsafeURDFError, match=r"XML nesting exceeds the limit of 100 .*max_xml_depth"
    ):
        load_model(path)
    with pytest.warns(YoubotOptWarning, match="mimic"):
        robot = load_model(path, size_limits=SizeLimits(max_xml_depth=200))
    assert robot.nv == 1  # the mimic joint is locked
    with pytest.raises(UnsafeURDFError, match="element count exceeds the limit of 10"):
        load_model(path, size_limits=SizeLimits(max_xml_depth=200, max_xml_elements=10))


@pytest.mark.parametrize("bad", [0, -3, 2.5, True, "10", float("nan")])
def test_bad_size_limits_name_the_value(bad: object) -> None:
    """A limit that is not an integer >= 1 is refused when the SizeLimits is built, naming it."""
    with pytest.raises(
        ParameterError, match=rf"size limit max_joints must be an integer >= 1 .*got {bad!r}"
    ):
        SizeLimits(max_joints=bad)  # type: ignore[arg-type]


def test_size_limits_must_be_a_size_limits(tmp_path: Path) -> None:
    """A dict or a number for size_limits is refused with the expected type."""
    with pytest.raises(ParameterError, match="size_limits must be a SizeLimits .* got dict"):
        load_model(_arm(tmp_path), size_limits={"max_joints": 5})  # type: ignore[arg-type]


def test_resolved_limits_report_the_defaults(no_env: pytest.MonkeyPatch) -> None:
    """resolved() gives the keyword, else the environment variable, else the module constant."""
    assert SizeLimits().resolved() == SizeLimits(
        max_joints=MAX_JOINTS, max_dof=MAX_DOF, max_tree_depth=MAX_TREE_DEPTH,
        max_xml_depth=MAX_XML_DEPTH, max_xml_elements=MAX_XML_ELEMENTS,
    )  # fmt: skip
    no_env.setenv("YOUBOT_OPT_MAX_JOINTS", "5000")
    assert SizeLimits().resolved().max_joints == 5000
    assert SizeLimits(max_joints=7).resolved().max_joints == 7
