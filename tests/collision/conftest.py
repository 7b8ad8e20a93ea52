"""Fixtures of the collision tests: robots, a scene and their collision models, built once."""

from __future__ import annotations

import warnings
from pathlib import Path

import pytest

from youbot_opt.collision import Box, Cylinder, HalfSpace, Obstacle, Scene, Sphere
from youbot_opt.collision.model import CollisionModel, build_collision_model
from youbot_opt.robot.model import RobotModel


@pytest.fixture(autouse=True)
def _fit_cache_env(fit_cache: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """During each collision test, fits are cached in :func:`fit_cache` (restored after)."""
    monkeypatch.setenv("YOUBOT_OPT_CACHE", str(fit_cache))


@pytest.fixture(scope="session")
def ur5() -> RobotModel:
    """The ur5 of example-robot-data (meshes and a box), loaded once."""
    from youbot_opt.robot.load import load_model

    return load_model("ur5")


@pytest.fixture(scope="session")
def panda() -> RobotModel:
    """The panda of example-robot-data (meshes and finger boxes), loaded once."""
    from youbot_opt.robot.load import load_model

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # its mimic finger joint is locked with a warning
        return load_model("panda")


@pytest.fixture(scope="session")
def cell() -> Scene:
    """A floor, a pillar, a tilted box, a ball and a capsule around the arm."""
    from youbot_opt.collision import Capsule

    return Scene(
        (
            Obstacle(name="floor", shape=HalfSpace(), xyz=(0.0, 0.0, -0.01)),
            Obstacle(name="pillar", shape=Cylinder(radius=0.05, length=1.0), xyz=(0.4, 0.2, 0.5)),
            Obstacle(
                name="crate",
                shape=Box(size=(0.3, 0.3, 0.3)),
                xyz=(-0.3, 0.4, 0.3),
                rpy=(0.3, 0.2, 0.1),
            ),
            Obstacle(name="ball", shape=Sphere(radius=0.1), xyz=(0.0, -0.5, 0.5)),
            Obstacle(
                name="rail",
                shape=Capsule(radius=0.04, length=0.6),
                xyz=(-0.4, -0.3, 0.6),
                rpy=(1.2, 0.0, 0.4),
            ),
        )
    )


@pytest.fixture(scope="session")
def ur5_cell(ur5: RobotModel, cell: Scene, fit_cache: Path) -> CollisionModel:
    """The ur5's collision model in the cell (self pairs from its SRDF)."""
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("YOUBOT_OPT_CACHE", str(fit_cache))
        return build_collision_model(ur5, cell)
