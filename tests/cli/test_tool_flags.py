"""``solve``'s tool-constraint flags (#30 item 2): parsing, refusals, the run folder."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from youbot_opt.cli import main
from youbot_opt.cli.parser import parse
from youbot_opt.cli.solve import tool_of
from youbot_opt.exceptions import ParameterError
from youbot_opt.trajopt.tool import KeepAxis, NearLine, ToolSpeed

SWING = ["--start", "-0.5236", "-0.5236", "1.0472", "--goal", "0.5236", "0.5236", "-1.0472"]


def test_flags_build_the_constraints() -> None:
    """Each flag pair becomes its constraint; the tilt is read in degrees."""
    args = parse(
        ["solve", "--keep-axis", "1", "0", "0", "0", "0", "2", "--max-tilt", "10"]
        + ["--line", "0", "0", "0.5", "0.1", "0", "0.5", "--line-tol", "0.01"]
        + ["--tool-speed", "0.4"]
    )
    axis, line, speed = tool_of(args)
    assert isinstance(axis, KeepAxis) and axis.max_angle == pytest.approx(math.radians(10))
    np.testing.assert_allclose(axis.direction, [0, 0, 1])
    assert isinstance(line, NearLine) and line.tolerance == 0.01
    np.testing.assert_allclose(line.p1, [0.1, 0, 0.5])
    assert isinstance(speed, ToolSpeed) and speed.max_speed == 0.4
    assert tool_of(parse(["solve"])) == ()


@pytest.mark.parametrize(
    ("argv", "match"),
    [
        (["--keep-axis", "1", "0", "0", "0", "0", "1"], "--keep-axis needs --max-tilt"),
        (["--max-tilt", "5"], "--max-tilt needs --keep-axis"),
        (["--line-tol", "0.01"], "--line-tol needs --line"),
        (["--tool-speed", "-1"], "max_speed"),
    ],
)
def test_incomplete_or_bad_flags_refused(argv: list[str], match: str) -> None:
    """A flag without its partner, or a bad value, is refused, naming it."""
    with pytest.raises(ParameterError, match=match):
        tool_of(parse(["solve", *argv]))


def test_solve_keeps_the_cup_upright(tmp_path, capsys: pytest.CaptureFixture[str]) -> None:
    """A solve with --keep-axis: certified, the summary lists it, tool.png is written."""
    out = tmp_path / "run"
    argv = ["solve", "--knots", "12", *SWING, "--transcription", "hermite-simpson"]
    argv += ["--keep-axis", "1", "0", "0", "0", "0", "1", "--max-tilt", "2"]
    argv += ["--tool-speed", "0.5", "--out", str(out), "--quiet"]
    assert main(argv) == 0
    text = capsys.readouterr().out
    assert "tool          keep axis (gripper_tip)" in text and "limit 0.5 m/s" in text
    summary = json.loads((out / "summary.json").read_text())
    axis, speed = summary["tool"]
    assert axis["kind"] == "keep_axis" and axis["largest_at_knots"] <= math.radians(2) + 1e-6
    assert speed["max_speed_m_per_s"] == 0.5
    assert summary["certified"]
    assert (out / "tool.png").stat().st_size > 0


def test_start_outside_the_line_refused(capsys: pytest.CaptureFixture[str]) -> None:
    """A start far from the --line: exit 2 and the message names the constraint and value."""
    argv = ["solve", "--knots", "8", *SWING, "--line", "1", "1", "1", "1", "1", "2"]
    assert main([*argv, "--line-tol", "0.01", "--quiet"]) == 2
    assert "start: near line (gripper_tip) is" in capsys.readouterr().err
