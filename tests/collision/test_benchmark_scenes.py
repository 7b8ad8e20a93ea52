"""The scene benchmark's files (benchmarks/scenes, #28 item 8): they load, and their pairs hold.

No Drake: the scene files are read by ``load_scene``, the robots loaded as the
pairs file says, and each start/goal pair is checked by coal (the
certificate's exact checker): both ends within the limits and at least the
margin from the scene, and the straight joint-space line between them
colliding (the obstacle has to be avoided).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from youbot_opt.collision import Clearance, clearance_checker, load_scene
from youbot_opt.robot.load import load_model

SCENES = Path(__file__).resolve().parents[2] / "benchmarks" / "scenes"
CELLS = [
    f"{robot}_{scene}"
    for robot in ("ur5", "panda")
    for scene in ("pick_place_pillar", "shelf_reach")
]


def _cell(stem: str):
    doc = json.loads((SCENES / f"{stem}_pairs.json").read_text(encoding="utf-8"))
    robot = load_model(doc["robot"], **doc["load_model"])
    scene = load_scene(SCENES / doc["scene"])
    clearance = Clearance(scene=scene, margin=doc["margin_m"], self_collision=False)
    return doc, robot, scene, clearance_checker(robot, clearance)


@pytest.mark.filterwarnings("ignore::UserWarning")
@pytest.mark.parametrize("stem", CELLS)
def test_pairs_ends_in_limits_and_clear(stem: str):
    """>= 20 pairs; both ends within the limits and >= the margin from every obstacle."""
    doc, robot, scene, checker = _cell(stem)
    assert len(scene.obstacles) >= 2
    assert len(doc["pairs"]) >= 20
    lo, hi = robot.model.lowerPositionLimit, robot.model.upperPositionLimit
    for start, goal in doc["pairs"]:
        for q in (np.asarray(start), np.asarray(goal)):
            assert q.shape == (robot.model.nq,)
            assert np.all(q >= lo) and np.all(q <= hi)
            assert checker.distances(robot, q).min() >= doc["margin_m"]


@pytest.mark.slow
@pytest.mark.filterwarnings("ignore::UserWarning")
@pytest.mark.parametrize("stem", CELLS)
def test_pairs_straight_line_collides(stem: str):
    """The straight joint-space line of every pair goes through an obstacle (64 points)."""
    doc, robot, _, checker = _cell(stem)
    for start, goal in doc["pairs"]:
        line = np.linspace(np.asarray(start), np.asarray(goal), 64)
        assert min(checker.distances(robot, q).min() for q in line) < 0
