"""The process-wide mesh cache: a robot loaded again reads what is on disk, never a stale mesh.

The reference is the file itself: the triangle written to the STL, compared with
the vertices Pinocchio's geometry holds after each load.
"""

from __future__ import annotations

import os
import struct
from pathlib import Path

import numpy as np
import pytest

from youbot_opt.robot.load import load_model
from youbot_opt.robot.urdf_check import geometry_cache
from youbot_opt.robot.urdf_check.geometry_cache import clear_mesh_cache, mesh_loader

URDF = """<?xml version="1.0"?>
<robot name="cached">
  <link name="base"/>
  <link name="arm">
    <inertial>
      <origin xyz="0 0 0.1" rpy="0 0 0"/>
      <mass value="1.0"/>
      <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.001"/>
    </inertial>
    <visual><geometry><mesh filename="meshes/tri.stl"/></geometry></visual>
    <collision><geometry><mesh filename="meshes/tri.stl"/></geometry></collision>
  </link>
  <joint name="shoulder" type="revolute">
    <parent link="base"/>
    <child link="arm"/>
    <axis xyz="0 1 0"/>
    <limit lower="-1.5" upper="1.5" effort="10" velocity="2"/>
  </joint>
</robot>
"""


def _write_triangle(path: Path, size: float, mtime_ns: int) -> None:
    """A one-triangle binary STL with legs ``size`` [m] along x and y, stamped ``mtime_ns``."""
    corners = [0.0, 0.0, 0.0, size, 0.0, 0.0, 0.0, size, 0.0]
    record = struct.pack("<12fH", 0.0, 0.0, 1.0, *corners, 0)
    path.write_bytes(b"binary STL".ljust(80, b" ") + struct.pack("<I", 1) + record)
    os.utime(path, ns=(mtime_ns, mtime_ns))


def _extent(model: object) -> list[float]:
    """Largest vertex coordinate [m] of each mesh geometry of a Pinocchio GeometryModel."""
    return [
        float(np.asarray(g.geometry.vertices()).max())
        for g in model.geometryObjects  # type: ignore[attr-defined]
    ]


@pytest.fixture
def robot_file(tmp_path: Path) -> tuple[Path, Path]:
    (tmp_path / "meshes").mkdir()
    urdf = tmp_path / "cached.urdf"
    urdf.write_text(URDF)
    return urdf, tmp_path / "meshes" / "tri.stl"


def test_an_edited_mesh_is_read_again_within_the_same_second(
    robot_file: tuple[Path, Path],
) -> None:
    """Rewritten 100 ns later with the same size: the second load sees the new triangle.

    coal's own cache compares whole seconds; ours compares the stamp in ns and
    the size, so this edit (same second, same byte count) must not be missed.
    """
    urdf, stl = robot_file
    second = 1_700_000_000 * 10**9
    _write_triangle(stl, 0.25, second + 100)
    first = load_model(urdf, package_dirs=[urdf.parent])
    assert _extent(first.visual_model) == [0.25] and _extent(first.collision_model) == [0.25]
    again = load_model(urdf, package_dirs=[urdf.parent])  # unchanged: same mesh
    assert _extent(again.collision_model) == [0.25]

    _write_triangle(stl, 0.5, second + 200)
    edited = load_model(urdf, package_dirs=[urdf.parent])
    assert _extent(edited.visual_model) == [0.5] and _extent(edited.collision_model) == [0.5]
    assert _extent(first.collision_model) == [0.25]  # a model loaded earlier keeps its mesh


def test_a_full_cache_starts_again_and_still_reads_correctly(
    robot_file: tuple[Path, Path], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Past MAX_CACHED_FILES files the cache empties; loads stay correct."""
    monkeypatch.setattr(geometry_cache, "MAX_CACHED_FILES", 1)
    clear_mesh_cache()
    urdf, stl = robot_file
    _write_triangle(stl, 0.3, 1_700_000_000 * 10**9)
    other = tmp_path / "other.stl"
    _write_triangle(other, 0.7, 1_700_000_000 * 10**9)
    with mesh_loader([other]) as loader:
        assert float(np.asarray(loader.load(os.fspath(other), np.ones(3)).vertices()).max()) == (
            pytest.approx(0.7, abs=1e-7)  # float32 in the STL
        )
    robot = load_model(urdf, package_dirs=[urdf.parent])
    assert _extent(robot.collision_model) == [pytest.approx(0.3, abs=1e-7)]
