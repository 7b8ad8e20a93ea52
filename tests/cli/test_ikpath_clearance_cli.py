"""``youbot-opt ikpath --scene`` (#28 item 7, the IK half): a UR5, two targets, one box."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from youbot_opt.cli import main
from youbot_opt.collision import Box, Obstacle, Scene, save_scene
from youbot_opt.exceptions import ParameterError, ResultFileError
from youbot_opt.ikpath.clearance import certify_path_clearance
from youbot_opt.ikpath.io import SCHEMA, SCHEMA_VERSION, encode_document, load_result

_UR5 = ["ikpath", "--robot", "ur5", "--target", "0.4", "0.2", "0.3", "--target", "0.3", "-0.3"]
_UR5 += ["0.4"]
MARGIN = 0.01  # [m]


@pytest.fixture(autouse=True)
def _in_tmp(tmp_path: Path, fit_cache: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Run in a temporary cwd; ball fits cached for the session, never in the user's cache."""
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("YOUBOT_OPT_CACHE", str(fit_cache))


def _scene(tmp_path: Path) -> Path:
    """A box between the two targets, off the straight line of the free legs."""
    box = Obstacle(name="box", shape=Box(size=(0.1, 0.1, 0.1)), xyz=(0.55, 0.0, 0.1))
    path = tmp_path / "scene.json"
    save_scene(Scene((box,)), path)
    return path


def test_scene_run_reports_the_closest_pair(tmp_path: Path, capsys) -> None:
    out = tmp_path / "run"
    argv = [*_UR5, "--scene", str(_scene(tmp_path)), "--margin", str(MARGIN)]
    argv += ["--no-self-collision", "--starts", "2", "--start-kind", "coherent"]
    argv += ["--out", str(out), "--no-replay", "--no-progress"]
    assert main(argv) == 0
    text = capsys.readouterr().out
    assert "clearance: closest pair " in text and "(coal), leg " in text
    summary = json.loads((out / "summary.json").read_text())
    clearance = summary["clearance"]
    assert clearance["margin_m"] == MARGIN and clearance["obstacles"] == ["box"]
    assert clearance["self_collision"] is False and clearance["scene"].endswith("scene.json")
    assert clearance["closest_pair"][1] == "box"
    assert clearance["certified"] is True
    assert clearance["closest_m"] >= MARGIN - 1e-3  # coal's, certified within 1 mm
    assert clearance["closest_leg"] in (0, 1) and 0 <= clearance["closest_fraction"] < 1
    # result.json records the scene and margin; loading re-checks with coal at the caller's margin
    saved = json.loads((out / "result.json").read_text())["result"]["clearance"]
    assert saved["margin"] == MARGIN and saved["self_collision"] is False
    assert [o["name"] for o in saved["scene"]["obstacles"]] == ["box"]
    best = load_result(out / "result.json")
    assert best.success and best.problem.clearance is not None
    assert best.problem.clearance.margin == MARGIN
    # the certificate is the result's: the summary's, the file's, the loaded one's
    assert best.clearance == certify_path_clearance(best.problem, best.configurations)
    assert best.clearance is not None and best.clearance.closest_distance == clearance["closest_m"]
    doc = json.loads((out / "result.json").read_text())
    assert doc["result"]["clearance_certificate"]["closest_m"] == clearance["closest_m"]
    doc["result"]["clearance_certificate"].update(certified=False, closest_m=99.0)
    (out / "edited.json").write_bytes(encode_document(SCHEMA, SCHEMA_VERSION, doc["result"]))
    edited = load_result(out / "edited.json")  # recomputed, never the file's
    assert edited.success and edited.clearance == best.clearance
    far = clearance["closest_m"] + 0.05  # more than the path keeps
    with pytest.raises(ResultFileError, match=r"does not keep the caller's clearance"):
        load_result(out / "result.json", margin=far)
    with pytest.raises(ParameterError, match="margin must be"):
        load_result(out / "result.json", margin=-1.0)


def test_scene_run_by_the_augmented_lagrangian(tmp_path: Path, capsys) -> None:
    """``--method al`` holds the clearance rows too (PHR terms, docs/ikpath.md)."""
    out = tmp_path / "run"
    argv = [*_UR5, "--scene", str(_scene(tmp_path)), "--margin", str(MARGIN), "--method", "al"]
    argv += ["--no-self-collision", "--starts", "2", "--start-kind", "coherent"]
    argv += ["--out", str(out), "--no-replay", "--no-progress"]
    assert main(argv) == 0
    assert "clearance: closest pair " in capsys.readouterr().out
    summary = json.loads((out / "summary.json").read_text())
    assert summary["clearance"]["certified"] is True
    assert summary["clearance"]["closest_m"] >= MARGIN - 1e-3
    best = load_result(out / "result.json")
    assert best.success and best.method == "al" and best.problem.clearance is not None


@pytest.mark.parametrize(
    "flags", [["--margin", "0.01"], ["--scene", "s.json"], ["--disable-pair", "a", "b"]]
)
def test_planar_targets_refuse_the_scene_flags(flags: list[str], capsys) -> None:
    argv = ["ikpath", "--lengths", "1", "1", "--target", "1", "1", "--target", "1", "-1"]
    assert main([*argv, *flags, "--no-progress"]) == 2
    assert "needs a 3-D robot" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("flags", "where"),
    [
        (["--method", "al"], "process"),
        (["--method", "al", "--scene", "s.json"], "serial"),
        (["--method", "al", "--margin", "0.01"], "serial"),
        (["--method", "ipopt", "--scene", "s.json"], "serial"),
        (["--method", "al", "--scene", "s.json", "--starts", "4"], "process"),
    ],
)
def test_automatic_al_starts_with_a_clearance_run_in_this_process(
    flags: list[str], where: str
) -> None:
    """A pooled result carries its problem, whose clearance rows are rebuilt on arrival."""
    from youbot_opt.cli.ikpath import _executor
    from youbot_opt.cli.parser import parse

    assert _executor(parse([*_UR5, *flags]), spatial=True) == where
