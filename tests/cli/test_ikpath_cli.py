"""``youbot-opt ikpath``: JSON output, exit codes, plots."""

from __future__ import annotations

import base64
import json
import re
from pathlib import Path

import numpy as np
import pytest
import umsgpack

from youbot_opt._files import read_json_lines
from youbot_opt.cli import main
from youbot_opt.ikpath.io import load_result


def _starts(doc: dict) -> list[dict]:
    """The per-start rows of a run: its ``starts.jsonl``, named in the summary."""
    return list(read_json_lines(Path(doc["output_folder"]) / doc["starts_file"]))


@pytest.fixture(autouse=True)
def _in_tmp(tmp_path, monkeypatch):
    """Run every command in a temporary cwd: default run folders land there."""
    monkeypatch.chdir(tmp_path)


def _json(capsys, argv):
    code = main(argv)
    out = capsys.readouterr()
    return code, json.loads(out.out), out.err


def test_example_b_json(capsys):
    """Example B from the zero start: success, E = 15.6058914, limits met, all targets reachable."""
    code, doc, _ = _json(
        capsys,
        ["ikpath", "--example", "B", "--starts", "1", "--json", "--no-progress", "--no-replay"],
    )
    assert code == 0
    assert doc["status"] == "solved"
    assert doc["E"] == pytest.approx(15.6058914, abs=1e-6)
    q = np.array(doc["configurations"])
    assert q.shape == (5, 3) and np.all(np.abs(q) <= np.pi / 2)
    assert doc["max_residual"] < 1e-9
    assert [v["verdict"] for v in doc["reachability"]] == ["reachable"] * 5


def test_unreachable_target_exits_2_with_verdict(capsys):
    """The study's (0, 7.1) for l = (3, 2, 2) stops the command with status 2 and the verdict."""
    argv = [
        "ikpath",
        "--lengths",
        "3",
        "2",
        "2",
        "--limit",
        "1.5707963267948966",
        "--target",
        "0",
        "7.1",
        "--target",
        "0",
        "7",
        "--json",
    ]
    code, doc, err = _json(capsys, argv)
    assert code == 2
    assert doc["status"] == "unreachable"
    assert [v["verdict"] for v in doc["reachability"]] == ["unreachable", "reachable"]
    np.testing.assert_allclose(doc["reachability"][1]["witness"], [np.pi / 2, 0, 0], atol=1e-9)
    assert "unreachable" in err and "(0, 7.1)" in err
    files = sorted(p.name for p in Path(doc["output_folder"]).iterdir())
    assert files == ["ikpath_workspace.png", "summary.json"]


@pytest.mark.parametrize(
    ("argv", "match"),
    [
        (["--lengths", "3", "-2", "2", "--target", "1", "1", "--target", "2", "2"], "lengths"),
        (["--lengths", "3", "2", "--target", "1", "1"], "at least 2 targets"),
        (
            [
                "--lengths",
                "3",
                "2",
                "--lower",
                "1",
                "--upper",
                "0",
                "--target",
                "1",
                "1",
                "--target",
                "2",
                "2",
            ],
            "q_lower",
        ),
        (["--target", "1", "1", "--target", "2", "2"], "--lengths"),
    ],
)
def test_bad_input_exits_2(capsys, argv, match):
    """Bad lengths, one target, crossed limits, missing arm: exit 2 naming the problem."""
    assert main(["ikpath", *argv]) == 2
    assert match in capsys.readouterr().err


def test_text_summary_and_run_folder(capsys, tmp_path):
    """The text summary names the best E and the study's value; --out gets every output."""
    out = tmp_path / "run"
    code = main(
        ["ikpath", "--example", "A", "--starts", "2", "--workers", "1", "--out", str(out),
         "--no-progress"]
    )  # fmt: skip
    captured = capsys.readouterr()
    assert code == 0
    assert "best: E = 0.8405135867" in captured.out and "study reported E = 0.905" in captured.out
    assert f"output folder: {out.resolve()}" in captured.err
    pngs = sorted(p.name for p in out.glob("*.png"))
    assert pngs == [
        "ikpath_arm.png",
        "ikpath_convergence.png",
        "ikpath_minima.png",
        "ikpath_workspace.png",
    ]
    assert all((out / p).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" for p in pngs)
    summary = json.loads((out / "summary.json").read_text())
    saved = load_result(out / "result.json")
    assert saved.objective == summary["E"]
    np.testing.assert_array_equal(saved.configurations, summary["configurations"])
    page = (out / "replay.html").read_text(encoding="utf-8")
    blob = re.search(r"var commands = (\[.*?\]);", page, re.S)
    kinds = [umsgpack.unpackb(base64.b64decode(c))["type"] for c in json.loads(blob.group(1))]
    assert kinds.count("set_animation") == 1
    assert sorted(summary["files"]) == sorted(p.name for p in out.iterdir())


def test_json_stdout_is_the_summary_and_default_folder_is_new(capsys, tmp_path):
    """--json prints one object equal to summary.json; without --out a new folder per run."""
    argv = ["ikpath", "--example", "B", "--json", "--no-progress", "--no-replay"]
    code, first, err = _json(capsys, argv)
    assert code == 0 and "output folder:" in err
    code, second, _ = _json(capsys, argv)
    assert code == 0
    folders = sorted((tmp_path / "youbot_opt_runs").iterdir())
    assert len(folders) == 2 and all(f.name.startswith("ikpath-") for f in folders)
    assert first["output_folder"] != second["output_folder"]
    for doc in (first, second):
        folder = tmp_path / "youbot_opt_runs" / doc["output_folder"].rsplit("/", 1)[1]
        assert json.loads((folder / "summary.json").read_text()) == doc
        assert not (folder / "replay.html").exists()


def test_wall_time_cap_is_reported_as_time_limit(capsys):
    """--max-wall-time 1e-9: the solve stops at once with status time_limit and exit code 1."""
    argv = ["ikpath", "--example", "B", "--max-wall-time", "1e-9", "--json", "--no-progress"]
    code, doc, _ = _json(capsys, [*argv, "--no-replay"])
    assert code == 1
    assert doc["status"] == "max_time"
    assert np.all(np.isfinite(np.array(doc["configurations"])))


def test_ipopt_on_a_one_link_chain_is_refused_with_advice(capsys):
    """A 1-link chain with --method ipopt: exit 2, the message suggests method='al'."""
    argv = ["ikpath", "--lengths", "1", "--target", "1", "0", "--target", "0", "1"]
    code = main([*argv, "--method", "ipopt", "--no-progress", "--no-replay"])
    err = capsys.readouterr().err
    assert code == 2 and "at least 2 free joints" in err and "method='al'" in err


def test_undecided_target_warns_with_interval_and_still_solves(capsys):
    """A budget too small to decide: a stderr warning with the certified interval; JSON says so."""
    argv = ["ikpath", "--lengths", *["1"] * 7, "--limit", "1.0471975511965976"]
    argv += ["--target", "-2", "1", "--target", "3", "1", "--reach-evaluations", "10"]
    code, doc, err = _json(capsys, [*argv, "--json", "--no-replay", "--no-progress"])
    first = doc["reachability"][0]
    assert first["verdict"] == "undecided" and doc["reachability_undecided"] == [0]
    assert doc["reachability"][1]["verdict"] == "reachable"
    lo, hi = first["distance_lower"], first["distance_upper"]
    assert 0.0 <= lo <= hi
    assert "warning: reachability of target p1 = (-2, 1) is undecided" in err
    assert f"[{lo:.6g}, {hi:.6g}] m" in err and "--reach-evaluations" in err
    assert doc["E"] is not None and code == (0 if doc["status"] == "solved" else 1)  # solved
    assert main([*argv[:-1], "0", "--no-progress"]) == 2
    assert "--reach-evaluations must be >= 1, got 0" in capsys.readouterr().err


def test_starts_show_progress_name_the_folder_and_resume(capsys, tmp_path):
    """--starts 20: folder named before solving, progress per tenth; a rerun loads every start."""
    out = tmp_path / "run"
    argv = ["ikpath", "--example", "B", "--starts", "20", "--workers", "2", "--out", str(out)]
    code, doc, err = _json(capsys, [*argv, "--json", "--no-replay"])
    assert code == 0 and doc["resumed"] == 0 and doc["retried"] == []
    lines = err.splitlines()
    assert lines[0].startswith(f"ikpath: 20 start(s), each saved to {out.resolve() / 'items'}")
    done = [int(ln.split()[1].split("/")[0]) for ln in lines if " starts done, best E " in ln]
    assert done == [1, *range(2, 21, 2)]  # the first start, then a line per tenth (no tty)
    assert [o["index"] for o in _starts(doc)] == list(range(20))
    assert all(o["attempts"] == 1 for o in _starts(doc))
    assert {"manifest.json", "items"} <= set(doc["files"])
    code, again, err = _json(capsys, [*argv, "--json", "--no-replay"])
    assert code == 0 and again["resumed"] == 20
    assert "ikpath: 20/20 starts done" in err
    assert [o["E"] for o in _starts(again)] == [o["E"] for o in _starts(doc)]


def test_single_start_prints_one_run(capsys):
    """With --starts 1 (the study's zero start) the text reads as one run, and says so."""
    code = main(["ikpath", "--example", "A", "--starts", "1", "--no-progress", "--no-replay"])
    out = capsys.readouterr().out
    assert code == 0
    assert "one start (the zero vector)" in out and "result: E = 0.8405135867" in out
    assert "certainty: one start, nothing to compare with" in out
    assert "multistart:" not in out and "zero start" not in out and "best:" not in out


def test_spatial_csv_targets_with_a_pose_solve_on_ur5(capsys, tmp_path):
    """--robot ur5 --targets FILE (named CSV columns, one quaternion): exit 0, run folder."""
    csv_file = tmp_path / "stations.csv"
    csv_file.write_text(
        "x,y,z,qx,qy,qz,qw\n0.4,0.2,0.3,,,,\n0.3,-0.3,0.4,1,0,0,0\n0.5,0.0,0.2,,,,\n"
    )
    argv = ["ikpath", "--robot", "ur5", "--targets", str(csv_file), "--starts", "2"]
    code, doc, err = _json(capsys, [*argv, "--no-replay", "--json"])
    assert code == 0 and doc["status"] == "solved"
    assert [t["kind"] for t in doc["targets"]] == ["position", "pose", "position"]
    assert max(doc["result"]["orientation_errors_rad"]) <= 1e-6
    assert max(doc["result"]["position_errors_m"]) <= 1e-6
    files = sorted(p.name for p in Path(doc["output_folder"]).iterdir())
    assert files == [
        "ikpath_legs.png",
        "ikpath_path3d.png",
        "items",  # the starts, in the sweep store
        "manifest.json",
        "result.json",
        "starts.jsonl",  # one JSON object a line per start
        "summary.json",
    ]


def test_spatial_unreachable_target_exits_2_with_its_certificate(capsys):
    argv = ["ikpath", "--robot", "ur5", "--target", "3", "0", "0", "--target", "0.4", "0.2", "0.3"]
    code, doc, err = _json(capsys, [*argv, "--json"])
    assert code == 2 and doc["status"] == "unreachable"
    assert doc["reachability"][0]["verdict"] == "unreachable"
    assert doc["reachability"][0]["distance"] > doc["reachability"][0]["reach"]
    assert "reach sphere" in err


def test_spatial_target_of_wrong_length_exits_2(capsys):
    argv = ["ikpath", "--robot", "ur5", "--target", "1", "2", "3", "4", "--target", "0", "0", "1"]
    assert main(argv) == 2
    assert "spatial targets take X Y Z" in capsys.readouterr().err


def test_a_reused_folder_keeps_no_stale_ikpath_figure(capsys, tmp_path):
    """An earlier run's ikpath figures this run does not write go; foreign files stay."""
    out = tmp_path / "run"
    out.mkdir()
    for name in ("ikpath_arm.png", "ikpath_minima.png", "ikpath_path3d.png", "notes.png"):
        (out / name).write_bytes(b"old")
    argv = ["ikpath", "--lengths", "3", "2", "2", "--target", "0", "7.1", "--target", "0", "7",
            "--out", str(out), "--json"]  # fmt: skip
    code, doc, _ = _json(capsys, argv)
    assert code == 2 and doc["status"] == "unreachable"  # only the workspace figure is drawn
    assert sorted(p.name for p in out.iterdir()) == [
        "ikpath_workspace.png", "notes.png", "summary.json"
    ]  # fmt: skip
    assert doc["files"] == ["ikpath_workspace.png", "summary.json"]


def test_no_figures_after_a_run_with_them(capsys, tmp_path):
    """`--no-figures` into the folder of a run with figures: no ikpath_*.png left, others stay."""
    out = tmp_path / "run"
    argv = ["ikpath", "--example", "B", "--json", "--no-progress", "--no-replay",
            "--out", str(out)]  # fmt: skip
    code, doc, _ = _json(capsys, argv)
    assert code == 0 and "ikpath_workspace.png" in doc["files"]
    (out / "notes.png").write_bytes(b"not ours")
    code, doc, _ = _json(capsys, [*argv, "--no-figures"])
    assert code == 0 and not [f for f in doc["files"] if f.endswith(".png")]
    assert not list(out.glob("ikpath_*.png"))
    assert (out / "notes.png").read_bytes() == b"not ours"
    assert "result.json" in doc["files"] and (out / "result.json").is_file()


def test_figures_are_drawn_in_another_process_and_there_on_return(capsys, tmp_path, monkeypatch):
    """The figures are drawn by `cli.drawing.Drawing` (forked): every one listed is there."""
    import os

    from youbot_opt.viz.plots import ikpath as plots

    notes = tmp_path / "pids"
    notes.mkdir()
    drawn = plots.plot_workspace

    def noting(*args, **kwargs):
        (notes / str(os.getpid())).touch()
        return drawn(*args, **kwargs)

    monkeypatch.setattr(plots, "plot_workspace", noting)
    out = tmp_path / "run"
    argv = ["ikpath", "--example", "B", "--json", "--no-progress", "--no-replay",
            "--out", str(out)]  # fmt: skip
    code, doc, _ = _json(capsys, argv)
    assert code == 0
    pngs = [f for f in doc["files"] if f.endswith(".png")]
    assert pngs[0] == "ikpath_workspace.png" and len(pngs) >= 3
    assert all((out / f).stat().st_size > 0 for f in pngs)
    drawers = {p.name for p in notes.iterdir()}
    assert drawers and str(os.getpid()) not in drawers


def test_a_failing_figure_is_raised_here(tmp_path, monkeypatch):
    """An error drawing an ikpath figure (in its drawing process) is raised by the command."""
    from youbot_opt.viz.plots import ikpath as plots

    def fails(*args, **kwargs):
        raise RuntimeError("the minima figure broke")

    monkeypatch.setattr(plots, "plot_minima", fails)
    argv = ["ikpath", "--example", "B", "--no-progress", "--no-replay", "--out", str(tmp_path)]
    with pytest.raises(RuntimeError, match="the minima figure broke") as caught:
        main(argv)
    assert any("in the figure process" in note for note in caught.value.__notes__)
