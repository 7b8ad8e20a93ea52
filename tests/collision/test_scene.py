"""The Scene API: frozen, composable, validated; furniture from a URDF."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from youbot_opt.collision import (
    Box,
    Capsule,
    Cylinder,
    HalfSpace,
    Obstacle,
    Scene,
    Sphere,
    furniture,
)
from youbot_opt.exceptions import ParameterError


def test_scene_is_frozen_and_composable():
    """`scene + other`, `+ obstacle` and `with_obstacle` make new scenes; the old is unchanged."""
    a = Scene((Obstacle(name="floor", shape=HalfSpace()),))
    b = Scene((Obstacle(name="ball", shape=Sphere(radius=0.1), xyz=(1.0, 0.0, 0.0)),))
    both = a + b
    more = both.with_obstacle(Obstacle(name="post", shape=Cylinder(radius=0.1, length=1.0)))
    assert both.names == ("floor", "ball")
    assert more.names == ("floor", "ball", "post")
    assert a.names == ("floor",)
    with pytest.raises(dataclasses.FrozenInstanceError):
        a.obstacles = ()  # type: ignore[misc]
    assert more.obstacle("post").shape == Cylinder(radius=0.1, length=1.0)


def test_duplicate_names_refused():
    """Two obstacles of one name are refused, naming it."""
    o = Obstacle(name="box", shape=Box(size=(1, 1, 1)))
    with pytest.raises(ParameterError, match="'box' appears twice"):
        Scene((o,)) + o


@pytest.mark.parametrize(
    ("make", "match"),
    [
        (lambda: Box(size=(1.0, -0.1, 1.0)), r"size\[1\] must be finite and > 0 \[m\], got -0.1"),
        (lambda: Box(size=(1.0, 1.0)), "size must be three numbers"),
        (lambda: Sphere(radius=math.nan), "radius must be"),
        (lambda: Sphere(radius=1e9), "radius must be at most 1000"),
        (lambda: Capsule(radius=0.1, length=0.0), "length must be finite and > 0"),
        (lambda: Obstacle(name="", shape=HalfSpace()), "name must be a non-empty text"),
        (lambda: Obstacle(name="a", shape="box"), "shape must be a Box"),  # type: ignore[arg-type]
        (
            lambda: Obstacle(name="a", shape=HalfSpace(), xyz=(0, 0, math.inf)),
            r"xyz\[2\] must be finite",
        ),
        (
            lambda: Obstacle(name="a", shape=HalfSpace(), rpy=(0, 100, 0)),
            r"rpy\[1\] must be within",
        ),
    ],
)
def test_bad_values_refused(make, match):
    """Negative, non-finite, huge and ill-shaped values raise a ParameterError naming the field."""
    with pytest.raises(ParameterError, match=match):
        make()


def test_pose_rotation_follows_urdf_rpy():
    """An obstacle's rotation is URDF's fixed-axis roll-pitch-yaw (Rz Ry Rx)."""
    o = Obstacle(name="a", shape=HalfSpace(), rpy=(0.0, 0.0, math.pi / 2))
    np.testing.assert_allclose(o.rotation @ [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], atol=1e-15)


FURNITURE = """<?xml version="1.0"?>
<robot name="table">
  <link name="base">
    <collision><origin xyz="0 0 0.7" rpy="0 0 0"/>
      <geometry><box size="1.2 0.8 0.04"/></geometry></collision>
    <collision><origin xyz="0.5 0.3 0.35" rpy="0 0 0"/>
      <geometry><cylinder radius="0.03" length="0.7"/></geometry></collision>
  </link>
</robot>
"""


def test_furniture_from_urdf(tmp_path: Path):
    """A table URDF's collision geometries become world obstacles, placed with the table's pose."""
    path = tmp_path / "table.urdf"
    path.write_text(FURNITURE)
    scene = furniture(path, name="table", xyz=(1.0, 0.0, 0.0), rpy=(0.0, 0.0, math.pi / 2))
    assert len(scene) == 2
    top, leg = scene.obstacles
    assert top.name.startswith("table/") and top.shape == Box(size=(1.2, 0.8, 0.04))
    assert leg.shape == Cylinder(radius=0.03, length=0.7)
    np.testing.assert_allclose(top.xyz, (1.0, 0.0, 0.7), atol=1e-12)
    np.testing.assert_allclose(leg.xyz, (1.0 - 0.3, 0.5, 0.35), atol=1e-12)  # yaw 90 deg
    assert all(o.frame is None for o in scene.obstacles)
