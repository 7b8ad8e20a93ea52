"""``--srdf`` and ``--disable-pair`` (#28 item 2): solve, multistart, pareto and report."""

from __future__ import annotations

import pytest

from youbot_opt.cli import main
from youbot_opt.cli.flags import clearance_of
from youbot_opt.cli.parser import parse
from youbot_opt.exceptions import ParameterError
from youbot_opt.robot.load import load_model

_SRDF = """<?xml version="1.0"?>
<robot name="ur5">
  <disable_collisions link1="base_link" link2="wrist_1_link" reason="Never"/>
</robot>
"""


@pytest.fixture(scope="module")
def ur5():
    return load_model("ur5")


@pytest.mark.parametrize("command", ["solve", "multistart", "pareto"])
def test_pair_flags_reach_the_clearance(command: str, ur5, tmp_path) -> None:
    """An explicit SRDF replaces the one beside the URDF; --disable-pair adds user pairs."""
    srdf = tmp_path / "cell.srdf"
    srdf.write_text(_SRDF)
    argv = [command, "--margin", "0.01", "--srdf", str(srdf)]
    argv += ["--disable-pair", "base_link", "forearm_link", "--disable-pair", "a_0", "b"]
    with pytest.raises(ParameterError, match="'a_0' is neither"):
        clearance_of(parse(argv), ur5)
    spec = clearance_of(parse(argv[:-3]), ur5)
    assert spec is not None and spec.pairs is not None
    assert spec.pairs.srdf == str(srdf)
    assert spec.pairs.srdf_disabled == (("base_link_0", "wrist_1_link_0"),)
    assert spec.pairs.user_disabled == (("base_link_0", "forearm_link_0"),)
    assert clearance_of(parse([command, "--margin", "0.01"]), ur5).pairs is None  # shipped SRDF


@pytest.mark.parametrize("flags", [["--srdf", "x.srdf"], ["--disable-pair", "a", "b"]])
def test_pair_flags_alone_refused(flags: list[str]) -> None:
    """Without --scene or --margin nothing is checked: the flag is refused, naming it."""
    with pytest.raises(ParameterError, match=f"{flags[0]} needs --scene or --margin"):
        clearance_of(parse(["solve", *flags]))


def test_report_lists_disabled_pairs_with_reason(capsys, tmp_path) -> None:
    """`report --srdf --disable-pair` lists the active and the left-out pairs, each with why."""
    srdf = tmp_path / "cell.srdf"
    srdf.write_text(_SRDF)
    argv = ["report", "--robot", "ur5", "--srdf", str(srdf)]
    assert main([*argv, "--disable-pair", "base_link", "forearm_link"]) == 0
    out = capsys.readouterr().out
    assert f"disabled by SRDF {srdf}" in out
    assert "  base_link_0 <-> wrist_1_link_0  disabled (SRDF)" in out
    assert "  base_link_0 <-> forearm_link_0  disabled (user)" in out
    assert "  shoulder_link_0 <-> upper_arm_link_0  disabled (adjacent)" in out
    assert main([*argv, "--disable-pair", "forearm", "base_link"]) != 0
    err = capsys.readouterr().err
    assert "'forearm'" in err and "forearm_link" in err
