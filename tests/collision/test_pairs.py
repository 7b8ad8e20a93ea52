"""Self-collision pairs: adjacency, the shipped SRDF, the caller's exclusions and the report."""

from __future__ import annotations

from pathlib import Path

import pytest

from youbot_opt.collision import pairs_report, self_collision_pairs
from youbot_opt.collision.pairs import find_srdf
from youbot_opt.exceptions import ParameterError
from youbot_opt.robot.model import RobotModel


def test_ur5_pairs_from_its_srdf(ur5: RobotModel):
    """ur5: 28 geometry pairs = 8 adjacent + 4 the shipped SRDF disables + 16 active."""
    pairs = self_collision_pairs(ur5)
    assert pairs.srdf is not None and Path(pairs.srdf).name == "ur5.srdf"
    assert (len(pairs.adjacent), len(pairs.srdf_disabled), len(pairs.active)) == (8, 4, 16)
    assert ("shoulder_link_0", "upper_arm_link_0") in pairs.adjacent
    assert ("base_link_0", "forearm_link_0") in pairs.active
    everything = pairs.active + pairs.adjacent + pairs.srdf_disabled
    assert len(set(everything)) == 8 * 7 // 2


def test_without_srdf_more_pairs_are_active(ur5: RobotModel):
    """srdf=False leaves only the adjacent pairs out."""
    pairs = self_collision_pairs(ur5, srdf=False)
    assert pairs.srdf is None and len(pairs.active) == 20


def test_disable_by_link_and_geometry(ur5: RobotModel):
    """The caller's pairs (link or geometry names) leave the active list, with their reason."""
    pairs = self_collision_pairs(
        ur5, disable=[("base_link", "forearm_link"), ("base_link_0", "wrist_1_link_0")]
    )
    assert ("base_link_0", "forearm_link_0") in pairs.user_disabled
    assert ("base_link_0", "wrist_1_link_0") in pairs.user_disabled
    assert len(pairs.active) == 14


def test_disable_unknown_name_refused(ur5: RobotModel):
    """An unknown name in disable is refused, listing the geometries."""
    with pytest.raises(ParameterError, match=r"disable\[0\]: 'elbow' is neither"):
        self_collision_pairs(ur5, disable=[("elbow", "base_link")])


def test_panda_srdf_found_beside(panda: RobotModel):
    """The panda's SRDF is found in example-robot-data's srdf folder."""
    found = find_srdf(panda)
    assert found is not None and found.name == "panda.srdf"
    assert self_collision_pairs(panda).srdf_disabled


def test_report_lines(ur5: RobotModel):
    """The report's first line gives the counts, then one line per active pair, then one per
    left-out pair with its reason (#28 item 2)."""
    pairs = self_collision_pairs(ur5, disable=[("base_link", "forearm_link")])
    lines = pairs_report(pairs)
    assert lines[0].startswith("self-collision: 15 active pairs (8 adjacent, 4 disabled by SRDF")
    assert len(lines) == 1 + 15 + 8 + 4 + 1 and lines[1] == "  base_link_0 <-> wrist_1_link_0"
    assert "  shoulder_link_0 <-> upper_arm_link_0  disabled (adjacent)" in lines
    assert sum(line.endswith("disabled (SRDF)") for line in lines) == 4
    assert lines[-1] == "  base_link_0 <-> forearm_link_0  disabled (user)"


def test_disable_unknown_link_lists_close_names(ur5: RobotModel):
    """A misspelt link is refused naming it and the close names."""
    with pytest.raises(ParameterError, match=r"'forearm_lnk'.*close names: \['forearm_link'"):
        self_collision_pairs(ur5, disable=[("forearm_lnk", "base_link")])
