"""Warnings on the command line (youbot_opt.cli.warning_lines): one line each, grouped."""

from __future__ import annotations

import re
import subprocess
import sys
import warnings
from pathlib import Path

import pytest

from youbot_opt.cli.warning_lines import flush_warnings, group_warnings, warnings_as_lines
from youbot_opt.exceptions import YoubotOptWarning

PLANAR = Path(__file__).resolve().parents[2] / "urdf" / "youbot_arm_planar.urdf"


def test_identical_messages_are_one_line_with_a_count() -> None:
    """Three identical messages -> "<message> (x3)"; a lone one stays as it is."""
    assert group_warnings(["a b", "lone", "a b", "a b"]) == ["a b (x3)", "lone"]


def test_messages_differing_in_names_paths_and_numbers_are_one_kind() -> None:
    """Same words, other quoted names, elements, paths and numbers: the first and the others."""
    messages = [
        f"/x/arm.urdf:{line}: <{tag}> of link 'l{k}': /x/m{k}.obj:4: 'm{k}.mtl' is missing"
        for k, (line, tag) in enumerate([(15, "visual"), (23, "collision"), (42, "visual")])
    ]
    assert group_warnings([*messages, "other"]) == [
        f"{messages[0]} (and 2 more like it: 'l1', 'l2')",
        "other",
    ]
    many = [f"link 'l{k}' mass {k}.5 kg" for k in range(7)]
    assert group_warnings(many) == [
        "link 'l0' mass 0.5 kg (and 6 more like it: 'l1', 'l2', 'l3', 'l4', ...)"
    ]


def test_warnings_as_lines_prints_on_leaving_and_on_flush(
    capsys: pytest.CaptureFixture[str],
) -> None:
    """Held inside, printed as "youbot-opt: warning: ..." at flush_warnings() and on leaving."""
    with warnings_as_lines():
        warnings.simplefilter("always")
        warnings.warn("first\nsecond line", YoubotOptWarning, stacklevel=1)
        assert capsys.readouterr().err == ""
        flush_warnings()
        assert capsys.readouterr().err == "youbot-opt: warning: first second line\n"
        warnings.warn("late", RuntimeWarning, stacklevel=1)
    assert capsys.readouterr().err == "youbot-opt: warning: late\n"
    flush_warnings()  # outside: nothing held, nothing printed
    assert capsys.readouterr().err == ""


def test_the_command_line_prints_a_line_per_kind_of_warning_without_source_lines(
    tmp_path: Path,
) -> None:
    """Three meshes without their .mtl: one grouped line, no category, file or source line."""
    (tmp_path / "m.obj").write_text("mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    mesh = '<visual><geometry><mesh filename="m.obj"/></geometry></visual>'
    text = re.sub(r'(<link name="arm_link_\d">)', r"\1" + mesh, PLANAR.read_text())
    assert text.count(mesh) == 3
    (tmp_path / "arm.urdf").write_text(text)
    proc = subprocess.run(
        [sys.executable, "-m", "youbot_opt", "report", "--robot", str(tmp_path / "arm.urdf")],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr
    lines = proc.stderr.splitlines()
    assert len(lines) == 1, proc.stderr
    assert lines[0].startswith("youbot-opt: warning: ") and "material library 'm.mtl'" in lines[0]
    assert lines[0].endswith("(and 2 more like it: 'arm_link_2', 'arm_link_3')")
    assert "YoubotOptWarning" not in proc.stderr and ".py:" not in proc.stderr
