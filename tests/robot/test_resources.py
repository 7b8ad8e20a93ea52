"""Tests of the one resource policy (robot/urdf_check/resources.py): loader and replay."""

from __future__ import annotations

from pathlib import Path

import pytest

from youbot_opt.exceptions import ParameterError, ResourceNotFoundError, UnsafePathError
from youbot_opt.robot.urdf_check.resources import (
    PATH_RULE,
    allowed_roots,
    check_mesh,
    in_mesh,
    is_inline_image,
    resolve_in_folder,
)
from youbot_opt.robot.urdf_check.xml import Site

WHERE = Site("robot.urdf", "<mesh>", 3)


def test_allowed_roots_raise_or_skip_a_missing_folder(tmp_path: Path) -> None:
    """The loader refuses a missing package folder; the replay may leave it out."""
    with pytest.raises(ParameterError, match="not an existing folder"):
        allowed_roots([tmp_path, tmp_path / "gone"])
    assert allowed_roots([tmp_path, tmp_path / "gone"], skip_missing=True) == (tmp_path.resolve(),)


def test_inline_images_are_recognised() -> None:
    """Only data:image/ URIs count as inline images (whitespace and case ignored)."""
    assert is_inline_image("  DATA:image/png;base64,AAAA ")
    assert not is_inline_image("data:model/stl;base64,AAAA")
    assert not is_inline_image("image.png")


def test_reference_in_a_mesh_folder_tries_both_forms(tmp_path: Path) -> None:
    """As written and percent-decoded: one existing form is enough, every form stays inside."""
    (tmp_path / "a%20b.png").write_bytes(b"x")
    (tmp_path / "c d.png").write_bytes(b"x")
    root = tmp_path.resolve()
    assert resolve_in_folder("a%20b.png", [root], root, WHERE) == (root / "a%20b.png",)
    assert resolve_in_folder("c%20d.png", [root], root, WHERE) == (root / "c d.png",)
    with pytest.raises(ResourceNotFoundError, match="does not exist"):
        resolve_in_folder("none.png", [root], root, WHERE)
    with pytest.raises(UnsafePathError, match="outside") as info:
        resolve_in_folder("%2e%2e/x.png", [root / "sub"], root, WHERE)
    assert info.value.rule == PATH_RULE


def test_ply_is_a_mesh_format_and_fbx_is_not(tmp_path: Path) -> None:
    """The loader's formats are the replay's: .ply passes (the replay converts it), .fbx fails."""
    root = tmp_path.resolve()
    (root / "m.ply").write_text("ply\n")
    (root / "m.fbx").write_text("fbx\n")
    assert check_mesh(root / "m.ply", [root], WHERE) == ()
    with pytest.raises(UnsafePathError, match=r"mesh formats are \.stl, \.dae, \.obj, \.ply"):
        check_mesh(root / "m.fbx", [root], WHERE)


def test_error_inside_a_mesh_keeps_class_and_rule(tmp_path: Path) -> None:
    """in_mesh re-sites an error at the referencing element, keeping class, rule and message."""
    inner = UnsafePathError("m.dae:4: <init_from>: bad [rule: r]", path="m.dae", line=4, rule="r")
    outer = in_mesh(inner, WHERE, tmp_path / "m.dae")
    assert type(outer) is UnsafePathError and outer.rule == "r"
    assert (outer.path, outer.element, outer.line) == WHERE
    assert str(outer).startswith("robot.urdf:3: <mesh>: the mesh ") and str(outer).endswith(
        str(inner)
    )
