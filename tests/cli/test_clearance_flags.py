"""``--scene``, ``--margin``, ``--no-self-collision`` (#28 item 4) and the report's pairs."""

from __future__ import annotations

import base64
import json
import re
from pathlib import Path

import pytest
import umsgpack

from youbot_opt.cli import main
from youbot_opt.cli.flags import clearance_of
from youbot_opt.cli.parser import parse
from youbot_opt.collision import Obstacle, Scene, Sphere, save_scene
from youbot_opt.exceptions import ParameterError


@pytest.fixture(autouse=True)
def _fit_cache(fit_cache: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Sphere fits are cached in a temporary folder during each test, never the user's."""
    monkeypatch.setenv("YOUBOT_OPT_CACHE", str(fit_cache))


@pytest.mark.parametrize("command", ["solve", "multistart", "pareto"])
def test_flags_build_the_clearance(command: str, tmp_path) -> None:
    """The scene file, the margin and the self-collision switch reach the problem's Clearance."""
    scene = Scene((Obstacle(name="ball", shape=Sphere(radius=0.03), xyz=(0.2, 0.0, 0.7)),))
    save_scene(scene, tmp_path / "scene.json")
    args = parse([command, "--scene", str(tmp_path / "scene.json"), "--margin", "0.02"])
    spec = clearance_of(args)
    assert spec is not None and spec.scene == scene
    assert spec.margin == 0.02 and spec.self_collision
    args = parse([command, "--scene", str(tmp_path / "scene.json"), "--no-self-collision"])
    spec = clearance_of(args)
    assert spec is not None and spec.margin == 0.0 and not spec.self_collision
    assert clearance_of(parse([command])) is None  # no flag: the scene-less problem


@pytest.mark.parametrize("command", ["solve", "multistart", "pareto"])
def test_end_window_flag(command: str) -> None:
    """--end-window reaches the Clearance (default 0.1); out of [0, 0.5] or alone refused."""
    assert clearance_of(parse([command, "--margin", "0.01"])).end_window == 0.1
    spec = clearance_of(parse([command, "--margin", "0.01", "--end-window", "0"]))
    assert spec is not None and spec.end_window == 0.0
    with pytest.raises(ParameterError, match=r"end_window must be in \[0, 0.5\].*got 0.6"):
        clearance_of(parse([command, "--margin", "0.01", "--end-window", "0.6"]))
    with pytest.raises(ParameterError, match="--end-window needs --scene"):
        clearance_of(parse([command, "--end-window", "0.2"]))


def test_ikpath_has_no_end_window() -> None:
    """A cyclic IK path has no fixed ends: ikpath does not take --end-window."""
    assert not hasattr(parse(["ikpath", "--margin", "0.01"]), "end_window")
    with pytest.raises(SystemExit):
        parse(["ikpath", "--margin", "0.01", "--end-window", "0.1"])


def test_no_self_collision_alone_refused() -> None:
    """--no-self-collision without --scene has nothing to check: refused, naming it."""
    with pytest.raises(ParameterError, match="--no-self-collision needs --scene"):
        clearance_of(parse(["solve", "--no-self-collision"]))


def test_negative_margin_refused(tmp_path) -> None:
    """A negative margin is refused, naming it."""
    with pytest.raises(ParameterError, match="margin"):
        clearance_of(parse(["solve", "--margin", "-0.1"]))


def test_report_lists_self_collision_pairs(capsys: pytest.CaptureFixture[str]) -> None:
    """`report` prints the active self-collision pairs of a robot with collision geometry."""
    assert main(["report", "--robot", "ur5"]) == 0
    out = capsys.readouterr().out
    assert "self-collision:" in out and "active pairs" in out


def test_solve_summary_names_closest_pair(tmp_path) -> None:
    """A solve with a scene writes the closest pair and its clearance into summary.json."""
    scene = Scene((Obstacle(name="ball", shape=Sphere(radius=0.03), xyz=(0.184, 0.0, 0.6745)),))
    save_scene(scene, tmp_path / "scene.json")
    out = tmp_path / "run"
    argv = ["solve", "--knots", "12", "--scene", str(tmp_path / "scene.json"), "--margin", "0.01"]
    argv += ["--no-self-collision", "--no-refine", "--out", str(out), "--quiet"]
    assert main(argv) == 0
    summary = json.loads((out / "summary.json").read_text())
    clearance = summary["clearance"]
    assert clearance["closest_pair"][1] == "ball"
    assert clearance["closest_m"] >= 0.01 - 1e-6 and clearance["margin_m"] == 0.01
    assert (out / "clearance.png").stat().st_size > 0  # the clearance-over-time figure
    page = (out / "replay.html").read_text(encoding="utf-8")
    blob = re.search(r"var commands = (\[.*?\]);", page, re.S)
    assert blob is not None
    commands = [umsgpack.unpackb(base64.b64decode(c)) for c in json.loads(blob.group(1))]
    drawn = {c["path"] for c in commands if c["type"] == "set_object"}
    assert any(path.endswith("/obstacles/ball") for path in drawn)  # the scene is replayed


def test_solve_with_a_scene_refines_its_plan(tmp_path) -> None:
    """Refinement (on by default) of a plan with a scene runs its rounds and certifies.

    Before b151fac the finer grids' solvers lacked the coal checker that the plan's ends
    are checked with, and the command ended in an AttributeError.
    """
    scene = Scene((Obstacle(name="ball", shape=Sphere(radius=0.03), xyz=(0.184, 0.0, 0.6745)),))
    save_scene(scene, tmp_path / "scene.json")
    out = tmp_path / "run"
    argv = ["solve", "--knots", "12", "--scene", str(tmp_path / "scene.json"), "--margin", "0.01"]
    argv += ["--no-self-collision", "--out", str(out), "--quiet"]
    assert main(argv) == 0
    summary = json.loads((out / "summary.json").read_text())
    refinement = summary["refinement"]
    assert refinement["certified"] is True, refinement
    assert summary["clearance"]["closest_m"] >= 0.01 - 1e-6
