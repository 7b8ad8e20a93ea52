"""The JSON scene file: round trip, and strict refusals naming the key path and the value."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from youbot_opt.collision import Box, Capsule, Cylinder, HalfSpace, Mesh, Obstacle, Scene, Sphere
from youbot_opt.collision.scene_file import MAX_SCENE_BYTES, load_scene, save_scene
from youbot_opt.exceptions import ModelError, ParameterError, UnsafePathError

HEADER = {"schema": "youbot_opt.scene", "schema_version": 1}


def _write(tmp_path: Path, obstacles: object, **extra: object) -> Path:
    path = tmp_path / "scene.json"
    path.write_text(json.dumps({**HEADER, "obstacles": obstacles, **extra}))
    return path


def _stl(path: Path) -> None:
    """Write an ASCII STL tetrahedron of 0.1 m."""
    v = [(0, 0, 0), (0.1, 0, 0), (0, 0.1, 0), (0, 0, 0.1)]
    faces = [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)]
    lines = ["solid t"]
    for f in faces:
        lines += ["facet normal 0 0 0", "outer loop"]
        lines += [f"vertex {v[i][0]} {v[i][1]} {v[i][2]}" for i in f]
        lines += ["endloop", "endfacet"]
    path.write_text("\n".join([*lines, "endsolid t"]) + "\n")


def test_round_trip(tmp_path: Path):
    """save_scene then load_scene gives an equal scene (every shape, a carried one)."""
    _stl(tmp_path / "tet.stl")
    scene = Scene(
        (
            Obstacle(name="floor", shape=HalfSpace()),
            Obstacle(name="table", shape=Box(size=(1.2, 0.8, 0.04)), xyz=(0.6, 0.0, 0.4)),
            Obstacle(name="ball", shape=Sphere(radius=0.1), xyz=(0.0, 0.5, 0.5)),
            Obstacle(name="post", shape=Cylinder(radius=0.05, length=1.0), rpy=(0.1, 0.2, 0.3)),
            Obstacle(name="held", shape=Capsule(radius=0.02, length=0.1), frame="tool0"),
            Obstacle(name="tet", shape=Mesh(path=tmp_path / "tet.stl", scale=(2.0, 2.0, 2.0))),
        )
    )
    save_scene(scene, tmp_path / "cell.json")
    assert load_scene(tmp_path / "cell.json") == scene


def test_example_in_docs_loads():
    """The example of docs/scene.md is a valid scene file."""
    text = (Path(__file__).parents[2] / "docs" / "scene.md").read_text()
    example = text.split("```json\n", 1)[1].split("```", 1)[0]
    doc = json.loads(example)
    assert doc["schema"] == "youbot_opt.scene"
    assert all("shape" in o for o in doc["obstacles"])


@pytest.mark.parametrize(
    ("obstacles", "match"),
    [
        ([{"name": "a", "shape": "box", "size": [1, -2, 1]}], r"obstacles\[0\].*size\[1\].*-2"),
        ([{"name": "a", "shape": "box", "size": [1, 1]}], r"size\[2\]|three numbers"),
        (
            [{"name": "a", "shape": "sphere", "radius": "big"}],
            r"obstacles\[0\]\.radius: must be a number, got 'big'",
        ),
        (
            [{"name": "a", "shape": "sphere", "radius": True}],
            r"obstacles\[0\]\.radius: must be a number",
        ),
        (
            [{"name": "a", "shape": "sphere", "radius": 0.1, "colour": "red"}],
            r"obstacles\[0\]\.colour: unknown key",
        ),
        ([{"name": "a", "shape": "cone", "radius": 0.1}], r"obstacles\[0\]\.shape: must be one of"),
        ([{"shape": "sphere", "radius": 0.1}], r"obstacles\[0\]\.name: missing"),
        (
            [{"name": "a", "shape": "sphere", "radius": 0.1, "xyz": [0, 0, 1e9]}],
            r"xyz\[2\] must be within",
        ),
        (
            [{"name": "a", "shape": "mesh", "path": "../../etc/passwd"}],
            r"obstacles\[0\]\.path: must stay inside",
        ),
        (
            [{"name": "a", "shape": "mesh", "path": "nope.stl"}],
            r"obstacles\[0\]\.path: names no existing file",
        ),
        (
            [{"name": "a", "shape": "halfspace"}, {"name": "a", "shape": "halfspace"}],
            "'a' appears twice",
        ),
        ("floor", r"obstacles: must be a list"),
    ],
)
def test_bad_entries_refused(tmp_path: Path, obstacles: object, match: str):
    """A bad entry raises a ParameterError naming its key path and value."""
    with pytest.raises(ParameterError, match=match):
        load_scene(_write(tmp_path, obstacles))


def test_unknown_top_key_and_schema_refused(tmp_path: Path):
    """Unknown top-level keys, another schema or version are refused."""
    with pytest.raises(ParameterError, match="lights: unknown key"):
        load_scene(_write(tmp_path, [], lights=[]))
    path = tmp_path / "other.json"
    path.write_text(
        json.dumps({"schema": "youbot_opt.scene", "schema_version": 2, "obstacles": []})
    )
    with pytest.raises(ParameterError, match="schema_version: must be 1"):
        load_scene(path)


def test_non_finite_and_duplicate_keys_refused(tmp_path: Path):
    """NaN/Infinity and a duplicate key are refused (json would accept both)."""
    path = tmp_path / "nan.json"
    path.write_text(
        '{"schema": "youbot_opt.scene", "schema_version": 1, "obstacles": '
        '[{"name": "a", "shape": "sphere", "radius": NaN}]}'
    )
    with pytest.raises(ParameterError, match="NaN"):
        load_scene(path)
    path.write_text(
        '{"schema": "youbot_opt.scene", "schema_version": 1, "obstacles": [], "obstacles": []}'
    )
    with pytest.raises(ParameterError, match="obstacles: duplicate key"):
        load_scene(path)


def test_huge_count_and_huge_file_refused(tmp_path: Path):
    """More than MAX_OBSTACLES entries, or a file over MAX_SCENE_BYTES, is refused."""
    many = [{"name": f"o{i}", "shape": "halfspace"} for i in range(1001)]
    with pytest.raises(ParameterError, match="at most 1000 obstacles, got 1001"):
        load_scene(_write(tmp_path, many))
    path = tmp_path / "big.json"
    path.write_text(" " * (MAX_SCENE_BYTES + 1))
    with pytest.raises(ParameterError, match=f"at most {MAX_SCENE_BYTES} bytes"):
        load_scene(path)
    with pytest.raises(ParameterError, match="not JSON"):
        (tmp_path / "bad.json").write_text("{")
        load_scene(tmp_path / "bad.json")


def test_mesh_entry_follows_the_mesh_policy(tmp_path: Path):
    """A mesh of a format the URDF loader refuses is refused naming the scene entry."""
    (tmp_path / "part.txt").write_text("solid")
    path = _write(tmp_path, [{"name": "part", "shape": "mesh", "path": "part.txt"}])
    with pytest.raises(UnsafePathError, match=r"obstacles\[0\]"):
        load_scene(path)


def test_furniture_entry(tmp_path: Path):
    """A "urdf" entry adds the file's geometry; a refused URDF names the entry."""
    (tmp_path / "shelf.urdf").write_text(
        '<robot name="shelf"><link name="base"><collision><geometry><box size="0.4 1 0.02"/>'
        "</geometry></collision></link></robot>"
    )
    path = _write(
        tmp_path, [{"name": "shelf", "shape": "urdf", "path": "shelf.urdf", "xyz": [1, 0, 0]}]
    )
    scene = load_scene(path)
    assert len(scene) == 1 and scene.obstacles[0].shape == Box(size=(0.4, 1.0, 0.02))
    assert math.isclose(scene.obstacles[0].xyz[0], 1.0)
    (tmp_path / "bad.urdf").write_text("<robot name='x'><link name='a'/><link name='a'/></robot>")
    with pytest.raises(ModelError, match=r"obstacles\[0\]"):
        load_scene(_write(tmp_path, [{"name": "bad", "shape": "urdf", "path": "bad.urdf"}]))
