"""``youbot-opt ikpath`` in spatial mode (issue 14): store, shards, resume, flags, loader."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from youbot_opt._files import read_json_lines
from youbot_opt.cli import main
from youbot_opt.ikpath.io import load_result


def _starts(doc: dict) -> list[dict]:
    """The per-start rows of a run: its ``starts.jsonl``, named in the summary."""
    return list(read_json_lines(Path(doc["output_folder"]) / doc["starts_file"]))


_UR5 = ["ikpath", "--robot", "ur5", "--target", "0.4", "0.2", "0.3", "--target", "0.3", "-0.3"]
_UR5 += ["0.4", "--target", "0.5", "0", "0.2"]


@pytest.fixture(autouse=True)
def _in_tmp(tmp_path, monkeypatch):
    """Run every command in a temporary cwd: default run folders land there."""
    monkeypatch.chdir(tmp_path)


def test_shards_then_collect_then_resume_and_result_json_reloads(capsys, tmp_path):
    out = tmp_path / "run"
    argv = [*_UR5, "--method", "ipopt", "--starts", "3", "--start-kind", "coherent"]
    argv += ["--out", str(out), "--no-replay"]
    assert main([*argv, "--shard", "1/2"]) == 0  # starts 0 and 2, then stop
    assert "shard 1/2: ran 2 item(s); 2 of 3 items are finished" in capsys.readouterr().err
    assert main([*argv, "--json"]) == 0
    cap = capsys.readouterr()
    doc = json.loads(cap.out)
    assert cap.err.startswith(f"ikpath: 3 start(s), each saved to {out.resolve() / 'items'}")
    assert "ikpath: 3/3 starts done" in cap.err  # progress (no tty: a line per tenth)
    assert doc["resumed"] == 2 and doc["start_kind"] == "coherent" and doc["retried"] == []
    assert [o["attempts"] for o in _starts(doc)] == [1, 1, 1]
    assert {"manifest.json", "items", "result.json"} <= set(doc["files"])
    # result.json reloads on its own (robot "ur5" from the file) and passes the FK re-check
    best = load_result(out / "result.json")
    assert best.success and best.objective == doc["E"]
    assert best.problem.joint_names == tuple(doc["joints"])
    assert main([*argv, "--json", "--no-progress"]) == 0
    again = json.loads(capsys.readouterr().out)
    assert again["resumed"] == 3 and again["E"] == doc["E"]


@pytest.mark.parametrize(
    ("extra", "match"),
    [
        (["--reach-evaluations", "0"], "--reach-evaluations must be >= 1, got 0"),
        (["--start-kind", "feasible"], "--start-kind feasible is a planar start kind"),
        (["--max-wall-time", "-1"], "--max-wall-time must be a positive time"),
    ],
)
def test_flags_spatial_mode_cannot_honour_are_refused(capsys, extra, match):
    assert main([*_UR5, *extra]) == 2
    assert match in capsys.readouterr().err


def test_a_spatial_start_kind_is_refused_on_a_planar_problem(capsys):
    assert main(["ikpath", "--example", "A", "--start-kind", "coherent"]) == 2
    assert "--start-kind coherent is a spatial start kind" in capsys.readouterr().err


def test_max_wall_time_stops_each_spatial_solve(capsys):
    argv = [*_UR5, "--max-wall-time", "1e-9", "--json", "--no-progress", "--no-replay"]
    assert main(argv) == 1  # the AL stops at its first check of the clock
    doc = json.loads(capsys.readouterr().out)
    assert doc["status"] == "max_time" and doc["max_wall_time"] == 1e-9


def test_reach_evaluations_is_the_interval_search_budget(capsys, monkeypatch):
    from youbot_opt.cli import ikpath as ikpath_command
    from youbot_opt.ikpath.reachability import general as spatial_reachability

    real, seen = spatial_reachability.check_reachability_3d, []

    def spy(problem, **kw):
        seen.append(kw)
        return real(problem, **kw)

    monkeypatch.setattr(ikpath_command, "check_reachability_3d", spy)
    argv = [*_UR5, "--method", "ipopt", "--reach-evaluations", "64", "--json", "--no-replay"]
    assert main(argv) == 0
    assert seen == [{"interval_boxes": 64}]
    verdicts = json.loads(capsys.readouterr().out)["reachability"]
    assert [v["verdict"] for v in verdicts] == ["reachable"] * 3


def test_spatial_names_and_budgets_of_the_parser_match_the_library():
    from youbot_opt.cli import parser as ikpath
    from youbot_opt.ikpath.reachability.general import (
        DEFAULT_INTERVAL_BOXES,
        DEFAULT_INTERVAL_SECONDS,
    )
    from youbot_opt.ikpath.starts import START_KINDS_3D

    assert ikpath.SPATIAL_START_KIND_NAMES == START_KINDS_3D
    assert ikpath.SPATIAL_REACH_BOXES == DEFAULT_INTERVAL_BOXES
    assert ikpath.SPATIAL_REACH_SECONDS == DEFAULT_INTERVAL_SECONDS


@pytest.mark.slow
def test_scheduler_file_runs_the_spatial_starts_on_a_dask_cluster(capsys, tmp_path):
    """Two worker processes on 127.0.0.1: same best E as the local run; a rerun resumes."""
    distributed = pytest.importorskip("distributed")
    argv = [*_UR5, "--method", "ipopt", "--starts", "3", "--json", "--no-replay"]
    argv += ["--no-progress"]
    assert main([*argv, "--out", str(tmp_path / "local")]) == 0
    local = json.loads(capsys.readouterr().out)
    with distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1", dashboard_address=None
    ) as cluster:
        sched = tmp_path / "scheduler.json"
        sched.write_text(json.dumps({"address": cluster.scheduler_address}))
        argv += ["--scheduler-file", str(sched), "--out", str(tmp_path / "dask")]
        assert main(argv) == 0
        remote = json.loads(capsys.readouterr().out)
        assert main(argv) == 0
        again = json.loads(capsys.readouterr().out)
    assert remote["resumed"] == 0 and again["resumed"] == 3
    # The same IPOPT from the same starts in other processes: E equal to rounding.
    assert [o["status"] for o in _starts(remote)] == [o["status"] for o in _starts(local)]
    assert remote["E"] == pytest.approx(local["E"], rel=1e-10)
    assert again["E"] == remote["E"]


def test_a_planar_urdf_gets_the_planar_feasible_starts_by_default(capsys, tmp_path):
    """#25 item 4: a planar 2-link URDF through the spatial command starts where the planar
    multistart does (start kind feasible) and IPOPT solves it (2 rows per target)."""
    inertial = (
        '<inertial><mass value="1"/><inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" '
        'izz="0.1"/></inertial>'
    )
    joints = "".join(
        f'<joint name="j{i}" type="revolute"><parent link="{p}"/><child link="l{i}"/>'
        f'<origin xyz="{x} 0 0"/><axis xyz="0 0 1"/>'
        '<limit lower="-2.5" upper="2.5" effort="1" velocity="1"/></joint>'
        f'<link name="l{i}">{inertial}</link>'
        for i, (p, x) in enumerate([("base", 0.0), ("l0", 1.0)])
    )
    path = tmp_path / "planar2.urdf"
    path.write_text(
        f'<robot name="planar2"><link name="base"/>{joints}<joint name="tip_joint" '
        'type="fixed"><parent link="l1"/><child link="tip"/><origin xyz="0.8 0 0"/></joint>'
        '<link name="tip"/></robot>'
    )
    argv = ["ikpath", "--robot", str(path), "--tip-frame", "tip", "--method", "ipopt"]
    argv += ["--target", "1.5", "0.2", "0", "--target", "0.3", "1.4", "0", "--starts", "4"]
    argv += ["--out", str(tmp_path / "run"), "--json", "--no-progress", "--no-replay"]
    assert main(argv) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["start_kind"] == "feasible" and doc["status"] == "solved"


def test_frame_is_refused_with_a_message_naming_tip_frame(capsys):
    """``ikpath --frame`` is no alias: argparse exits 2 with one line naming --tip-frame."""
    with pytest.raises(SystemExit) as exc:
        main([*_UR5, "--frame", "tool0"])
    assert exc.value.code == 2
    last = capsys.readouterr().err.strip().splitlines()[-1]
    assert last.endswith("error: --frame is not an option: use --tip-frame F"), last


def test_start_rows_go_to_starts_jsonl_and_not_to_the_summary(capsys, tmp_path):
    """A JSON object a line per start in starts.jsonl, named by summary.json; --json omits them."""
    out = tmp_path / "run"
    argv = [*_UR5, "--method", "ipopt", "--starts", "2", "--start-kind", "coherent"]
    assert main([*argv, "--out", str(out), "--no-replay", "--no-progress", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    summary = json.loads((out / "summary.json").read_text())
    assert "start_outcomes" not in doc and "start_outcomes" not in summary
    assert doc["starts_file"] == summary["starts_file"] == "starts.jsonl"
    assert "starts.jsonl" in summary["files"]
    lines = (out / "starts.jsonl").read_text().splitlines()
    rows = [json.loads(line) for line in lines]
    assert [r["index"] for r in rows] == [0, 1]
    assert all(set(r) == {"index", "status", "E", "attempts", "message"} for r in rows)
