"""Output folders of `youbot-opt` runs: main job, solve, multistart, pareto, bounds.

Each command runs in-process in a temporary working directory and must leave
one folder with ``summary.json``, its figures (valid, non-empty PNGs),
``replay.html`` (the standalone meshcat animation) and the saved result(s),
and say where the folder is.
"""

from __future__ import annotations

import base64
import json
import re
from pathlib import Path

import numpy as np
import pytest
import umsgpack
from PIL import Image

from youbot_opt._files import read_json_lines
from youbot_opt.cli import main
from youbot_opt.trajopt.io import load_result

SOLVE_KEYS = {"status", "objective", "duration_s", "work", "iterations", "solve_time_s"}
QUICK = ["--knots", "15"]  # small problems: the outputs, not the numbers, are under test


@pytest.fixture(autouse=True)
def _in_tmp(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Run every command in a fresh working directory (default folders land there)."""
    monkeypatch.chdir(tmp_path)


def _only_run_folder(command: str) -> Path:
    (folder,) = Path("youbot_opt_runs").iterdir()
    assert re.fullmatch(rf"{command}-\d{{8}}-\d{{6}}", folder.name)
    return folder


def _check_png(path: Path) -> None:
    """The file is a PNG of a drawn figure (not empty, not one flat colour)."""
    with Image.open(path) as image:
        assert image.format == "PNG" and image.width > 300 and image.height > 200
        pixels = np.asarray(image.convert("L"))
    assert pixels.std() > 5.0  # [grey levels] axes, curves and text


def _replay_nodes(path: Path) -> tuple[set[str], bool]:
    """Scene nodes of an exported replay, and whether it holds an animation."""
    page = path.read_text()
    blob = re.search(r"var commands = (\[.*?\]);", page, re.S)
    assert blob is not None and "MeshCat.Viewer" in page
    commands = [umsgpack.unpackb(base64.b64decode(c)) for c in json.loads(blob.group(1))]
    nodes = {c["path"].split("/")[3] for c in commands if c["type"] == "set_object"}
    return nodes, any(c["type"] == "set_animation" for c in commands)


def _check_folder(folder: Path, summary: dict, pngs: list[str]) -> None:
    assert summary["output_folder"] == str(folder.resolve())
    for name in summary["files"]:
        assert (folder / name).exists(), name
    for name in pngs:
        assert name in summary["files"]
        _check_png(folder / name)
    assert json.loads((folder / "summary.json").read_text()) == summary


def test_main_job_writes_its_run_folder(capsys: pytest.CaptureFixture[str]) -> None:
    """`youbot-opt` solves the base case, prints the summary table and where the outputs are."""
    assert main([]) == 0
    out = capsys.readouterr().out
    folder = _only_run_folder("main")
    summary = json.loads((folder / "summary.json").read_text())
    assert SOLVE_KEYS | {"certificate", "active_bounds", "build_time_s"} <= set(summary)
    assert summary["status"] == "solved" and summary["certified"] is True
    assert summary["refinement"]["rounds"][0]["n_knots"] == 50  # refined from 50 knots
    assert f"objective f   {summary['objective']:.6f}" in out
    assert f"output folder: {folder.resolve()}" in out
    pngs = ["trajectory.png", "arm.png", "convergence.png", "refinement.png"]
    _check_folder(folder, summary, pngs)
    result = load_result(folder / "result.npz")
    assert result.objective == summary["objective"]  # the saved result is the one summarised
    nodes, animated = _replay_nodes(folder / "replay.html")
    assert nodes == {"youbot"} and animated


def test_solve_json_prints_one_object_and_saves_the_run(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    """`solve --json`: stdout is exactly one JSON object; the listing goes to stderr."""
    assert main(["solve", *QUICK, "--json", "--out", "run"]) == 0
    captured = capsys.readouterr()
    summary = json.loads(captured.out)  # the whole of stdout: one object
    assert SOLVE_KEYS <= set(summary) and summary["status"] == "solved"
    cert = summary["certificate"]
    assert {"local_position_max_rad", "feedback_rms_ratio", "tracking_position_error_rad"} <= set(
        cert
    )
    folder = tmp_path / "run"
    assert f"output folder: {folder.resolve()}" in captured.err
    _check_folder(folder, summary, ["trajectory.png", "arm.png", "convergence.png"])
    assert summary["files"] == [
        "result.npz", "trajectory.png", "arm.png", "refinement.png", "convergence.png",
        "replay.html", "summary.json",
    ]  # fmt: skip
    assert load_result(folder / "result.npz").iterations == summary["iterations"]


def test_solve_failure_exits_1_and_still_saves(capsys: pytest.CaptureFixture[str]) -> None:
    """A solve stopped by the iteration cap exits 1 with its status in the saved summary."""
    assert main(["solve", *QUICK, "--max-iter", "2", "--json"]) == 1
    summary = json.loads(capsys.readouterr().out)
    assert summary["status"] == "max_iterations" and not summary["success"]
    folder = _only_run_folder("solve")
    assert load_result(folder / "result.npz").status.value == "max_iterations"


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["solve", "--knots", "1"], "--knots must be >= 2"),
        (["solve", "--beta", "1.5"], "beta must be in [0, 1]"),
        (["solve", "--start", "0", "0", "0"], "--start and --goal"),
        (["solve", "--starts", "0"], "--starts must be >= 1"),
        (["solve", "--robot", "no_such_robot"], "no_such_robot"),
        (["solve", *QUICK, "--out", "a_file"], "output folder"),
        (["multistart", "--starts", "-1"], "--starts must be >= 0"),
        (["pareto", "--betas", "0.5,2"], "beta"),
    ],
)
def test_bad_input_exits_2_without_a_run_folder(
    argv: list[str], message: str, capsys: pytest.CaptureFixture[str]
) -> None:
    """Bad input exits 2 with a message naming the value, and leaves no run folder."""
    Path("a_file").write_text("not a folder")
    assert main(argv) == 2
    assert message in capsys.readouterr().err
    assert not Path("youbot_opt_runs").exists()


def test_solve_with_starts_replays_the_distinct_optima(capsys: pytest.CaptureFixture[str]) -> None:
    """`solve --starts 3` adds the multistart histogram; the replay holds one copy per optimum."""
    assert main(["solve", "--knots", "20", "--starts", "3", "--guess", "spline"]) == 0
    folder = _only_run_folder("solve")
    summary = json.loads((folder / "summary.json").read_text())
    assert summary["multistart"]["n_starts"] == 3
    _check_folder(folder, summary, ["multistart.png", "convergence.png", "trajectory.png"])
    nodes, animated = _replay_nodes(folder / "replay.html")
    assert animated and nodes and all(n.startswith("optimum_") for n in nodes)
    assert "side by side" in (folder / "replay.html").read_text()


def test_multistart_records_the_hessian_it_ran(capsys: pytest.CaptureFixture[str]) -> None:
    """`multistart --hessian limited-memory`: IPOPT's L-BFGS runs, and the summary says so."""
    argv = ["multistart", "--starts", "2", *QUICK, "--workers", "0", "--quiet", "--json"]
    assert main([*argv, "--hessian", "limited-memory"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["hessian"] == "limited-memory"
    assert summary["best"] is not None


def test_multistart_folder_resumes(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    """`multistart --out DIR` writes figures, replay and a store that a rerun resumes from."""
    argv = ["multistart", "--starts", "2", *QUICK, "--workers", "0", "--quiet", "--out", "ms"]
    assert main(argv) == 0
    out = capsys.readouterr().out
    folder = tmp_path / "ms"
    assert f"output folder: {folder.resolve()}" in out and "rerun with --out ms" in out
    summary = json.loads((folder / "summary.json").read_text())
    _check_folder(folder, summary, ["multistart.png", "convergence.png", "trajectory.png"])
    assert (folder / "manifest.json").exists()  # the sweep store shares the run folder
    assert len(list((folder / "items").glob("*/*.npz"))) == 2  # fanned out: items/<hh>/
    assert summary["starts_file"] == "starts.jsonl" and "starts.jsonl" in summary["files"]
    rows = list(read_json_lines(folder / "starts.jsonl"))  # one row a start, as summary's
    assert [{k: v for k, v in r.items() if k != "optimum"} for r in rows] == summary["starts"]
    assert [r["optimum"] for r in rows] == [None, None]  # results kept: no representative
    nodes, animated = _replay_nodes(folder / "replay.html")
    assert animated and len(nodes) == len(summary["distinct_optima"])
    assert main([*argv, "--json"]) == 0
    again = json.loads(capsys.readouterr().out)
    assert again["resumed"] == 2
    assert again["best"]["objective"] == summary["best"]["objective"]
    assert [r["stored"] for r in again["refinement"]] == [True]  # the refined plan: kept
    assert again["plan"] == summary["plan"]


def test_multistart_exits_1_when_the_plan_is_not_certified(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    """Refinement out of budget (no knots beyond 15): saved, says why, exits 1 (as `solve`)."""
    argv = ["multistart", "--starts", "2", *QUICK, "--max-knots", "15", "--workers", "0"]
    assert main([*argv, "--quiet", "--json", "--out", str(tmp_path / "ms")]) == 1
    summary = json.loads(capsys.readouterr().out)
    (record,) = summary["refinement"]
    assert not record["certified"] and "15 knots" in record["reason"]
    assert (tmp_path / "ms" / "result.npz").exists()  # the plan is still saved


def test_pareto_and_bounds_folders(capsys: pytest.CaptureFixture[str]) -> None:
    """`pareto` and `bounds` write their figure, one per refined plan, and a side-by-side replay."""
    base = [*QUICK, "--workers", "0", "--quiet", "--json"]
    assert main(["pareto", "--betas", "0.3,0.7", *base]) == 0
    front = json.loads(capsys.readouterr().out)
    assert front["hessian"] == "exact"  # the default, recorded
    folder = Path(front["output_folder"])
    _check_folder(folder, front, ["pareto.png", "refinement_1.png", "refinement_2.png"])
    nodes, _ = _replay_nodes(folder / "replay.html")
    assert len(nodes) == 2 and all(n.startswith("beta_0.") for n in nodes)
    page = (folder / "replay.html").read_text()
    assert len(front["refinement"]) == 2
    for record in front["refinement"]:  # labelled "beta = 0.3"; the refined plan is replayed
        assert record["certified"]
        assert f"{record['label']}: T = {record['rounds'][-1]['duration_s']:.3f} s" in page
    assert main(["bounds", "--scales", "1,0.9", "--starts", "0", *base]) == 0
    study = json.loads(capsys.readouterr().out)
    assert study["hessian"] == "exact"
    folder = Path(study["output_folder"])
    _check_folder(folder, study, ["bound_scaling.png", "refinement_1.png", "refinement_2.png"])
    page = (folder / "replay.html").read_text()
    assert [r["label"] for r in study["refinement"]] == ["scale 1.000", "scale 0.900"]
    for scale, record in zip(("100%", "90%"), study["refinement"], strict=True):
        final = record["rounds"][-1]["objective"]  # the refined plan is replayed
        assert f"{scale} bounds: f = {final:.5g}" in page


def _timeless(x: object) -> object:
    """``x`` without wall/CPU times and folder names (they differ between two runs)."""
    if isinstance(x, dict):
        return {
            k: _timeless(v)
            for k, v in x.items()
            if not (k.endswith("time_s") or k in ("elapsed_s", "output_folder"))
        }
    if isinstance(x, list):
        return [_timeless(v) for v in x]
    return x


def test_multistart_no_keep_results_reports_what_keeping_them_does(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    """--no-keep-results (starts left in the folder): the same best, optima and refined plan.

    The lean summary leaves out the per-start list and the optima's member
    seeds (both would walk every start); everything else is equal to the bit.
    """
    argv = ["multistart", "--starts", "4", *QUICK, "--workers", "0", "--quiet", "--json"]
    assert main([*argv, "--out", str(tmp_path / "keep")]) == 0
    kept = json.loads(capsys.readouterr().out)
    assert main([*argv, "--no-keep-results", "--out", str(tmp_path / "lean")]) == 0
    lean = json.loads(capsys.readouterr().out)
    assert "starts" in kept and "starts" not in lean
    kept_rows = list(read_json_lines(tmp_path / "keep" / "starts.jsonl"))
    lean_rows = list(read_json_lines(tmp_path / "lean" / "starts.jsonl"))
    assert [r["key"] for r in lean_rows] == [r["key"] for r in kept["starts"]]  # still written
    best = min((r for r in lean_rows if r["success"]), key=lambda r: r["objective"])
    assert best["key"] == lean["best"]["key"] and best["optimum"] == best["key"]
    assert {r["optimum"] for r in lean_rows if r["success"]} <= {r["key"] for r in lean_rows}
    assert _timeless([{**r, "optimum": None} for r in lean_rows]) == _timeless(kept_rows)
    for optimum in kept["distinct_optima"]:
        optimum.pop("seeds")
    kept.pop("starts")
    assert _timeless(lean) == _timeless(kept)
