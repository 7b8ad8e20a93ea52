"""``solve --waypoints FILE [--closed]`` and ``ikpath ... --timed``: real small runs (#30)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from youbot_opt.cli import main
from youbot_opt.robot.planar import youbot_chain

WAYPOINTS = [[0.3, -0.2, 0.5], [-0.2, 0.4, 0.9]]  # [rad], inside the youBot's limits


@pytest.fixture(autouse=True)
def _in_tmp(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)


def _json(capsys, argv):
    code = main(argv)
    out = capsys.readouterr()
    return code, json.loads(out.out), out.err


def test_solve_through_a_waypoints_file(tmp_path, capsys):
    (tmp_path / "w.csv").write_text(
        "q1,q2,q3\n" + "\n".join(",".join(map(str, r)) for r in WAYPOINTS)
    )
    code, doc, _ = _json(capsys, ["solve", "--waypoints", "w.csv", "--json", "--out", "run"])
    assert code == 0
    timed = doc["timed"]
    # refined by default (docs/timed.md): the rounds are recorded
    assert timed["success"] and timed["certified"] and timed["refined"]
    rounds = timed["refinement"]["rounds"]
    assert timed["refinement"]["reason"] == "certified" and rounds[0]["n_knots"] == 58
    assert rounds[-1]["certificate_passed"] and rounds[-1]["max_error"] <= 1e-3
    assert doc["certified"] and doc["n_knots"] == rounds[-1]["n_knots"]
    assert doc["refinement"]["rounds"] == rounds
    times = timed["waypoint_times_s"]
    assert len(times) == 2 and 0.0 < times[0] < times[1] < timed["duration_s"]
    assert timed["duration_s"] == pytest.approx(sum(timed["segment_durations_s"]), rel=1e-12)
    assert doc["duration_s"] == pytest.approx(timed["duration_s"], rel=1e-12)
    assert doc["method"] == "hermite_simpson" and doc["certificate"] is not None
    saved = json.loads((Path("run") / "summary.json").read_text())
    assert saved["timed"]["waypoint_times_s"] == times
    # the saved plan passes through the waypoints at the reported times
    from youbot_opt.trajopt.io import load_result

    plan = load_result(Path("run") / "result.npz").trajectory
    np.testing.assert_allclose(plan(np.array(times)), WAYPOINTS, atol=1e-6)


def test_solve_waypoints_text_and_closed(tmp_path, capsys):
    (tmp_path / "w.json").write_text(json.dumps({"q": WAYPOINTS}))
    argv = ["solve", "--waypoints", "w.json", "--closed", "--segment-knots", "15"]
    code = main([*argv, "--no-refine", "--out", "run"])
    out = capsys.readouterr().out
    assert code == 0
    assert "timed through 2 waypoints (closed: back to waypoint 1)" in out
    assert "waypoint 2" in out and "duration T" in out and "certificate  passed" in out
    assert "not refined (--no-refine)" in out
    doc = json.loads((Path("run") / "summary.json").read_text())
    assert doc["timed"]["closed"] is True
    from youbot_opt.trajopt.io import load_result

    plan = load_result(Path("run") / "result.npz").trajectory
    np.testing.assert_allclose(plan.q[-1], WAYPOINTS[0], atol=1e-6)
    np.testing.assert_allclose(plan.v[-1], 0.0, atol=1e-6)


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--closed"], "--closed applies with --waypoints only"),
        (["--waypoints", "w.csv", "--starts", "2"], "--starts does not apply with --waypoints"),
        (["--waypoints", "w.csv", "--transcription", "radau"], "'radau'"),
        (["--waypoints", "missing.csv"], "missing.csv"),
        (["--segment-knots", "9"], "--segment-knots applies with --waypoints only"),
        (["--waypoints", "w.csv", "--knots", "30"], "--knots (use --segment-knots) does not"),
        (["--waypoints", "w.csv", "--segment-knots", "1"], "knots_per_segment must be an int >= 2"),
    ],
)
def test_solve_waypoints_refusals(tmp_path, capsys, argv, message):
    (tmp_path / "w.csv").write_text("0.3,-0.2,0.5\n")
    assert main(["solve", *argv]) == 2
    assert message in capsys.readouterr().err


def test_ikpath_timed_youbot(capsys):
    chain = youbot_chain()
    targets = [chain.tip_position(np.array(q)) for q in ([0.3, -0.2, 0.5], [-0.2, 0.4, 0.9])]
    argv = ["ikpath", "--robot", "youbot", "--timed", "--segment-knots", "15", "--json"]
    argv += ["--no-progress", "--no-replay"]
    for x, z in targets:
        argv += ["--target", f"{x:.6f}", f"{z:.6f}"]
    code, doc, _ = _json(capsys, [*argv, "--out", "ik"])
    assert code == 0
    timed = doc["timed"]
    assert timed["success"] and timed["certified"] and timed["closed"] and timed["refined"]
    assert timed["refinement"]["reason"] == "certified"
    # the first configuration is the start: reached at t = 0, the others later, in order
    times = timed["waypoint_times_s"]
    assert times[0] == 0.0 and 0.0 < times[1] < timed["duration_s"]
    assert (Path("ik") / "timed_result.npz").exists()
    from youbot_opt.trajopt.io import load_result

    plan = load_result(Path("ik") / "timed_result.npz").trajectory
    np.testing.assert_allclose(plan(np.array(times)), doc["configurations"], atol=1e-6)
    np.testing.assert_allclose(plan.q[-1], doc["configurations"][0], atol=1e-6)


def test_ikpath_timed_needs_masses(capsys):
    argv = ["ikpath", "--lengths", "1", "1", "--target", "1", "1", "--target", "1.5", "0"]
    assert main([*argv, "--timed", "--no-progress"]) == 2
    assert "--timed needs a robot with masses" in capsys.readouterr().err


def test_ikpath_segment_knots_needs_timed(capsys):
    argv = ["ikpath", "--robot", "youbot", "--target", "0.0", "0.6", "--target", "-0.1", "0.5"]
    assert main([*argv, "--segment-knots", "15", "--no-progress"]) == 2
    assert "--segment-knots applies with --timed only" in capsys.readouterr().err
    assert main([*argv, "--max-rounds", "2", "--no-progress"]) == 2
    assert "--max-rounds applies with --timed only" in capsys.readouterr().err
    assert main([*argv, "--no-refine-fallback", "--no-progress"]) == 2
    assert "--no-refine-fallback applies with --timed only" in capsys.readouterr().err
    assert not Path("youbot_opt_runs").exists()  # refused before the run


def test_solve_waypoints_refines_with_the_usual_flags(tmp_path, capsys):
    """``--max-rounds``, ``--error-tol``: the rounds are printed (stderr and the table)."""
    (tmp_path / "w.json").write_text(json.dumps({"q": WAYPOINTS}))
    argv = ["solve", "--waypoints", "w.json", "--segment-knots", "8", "--max-rounds", "2"]
    code = main([*argv, "--error-tol", "1e-4", "--out", "run"])
    out = capsys.readouterr()
    assert code == 1  # 2 rounds do not reach 1e-4 from 8 knots a segment
    assert "refine: round 0: 22 knots" in out.err and "refine: round 1:" in out.err
    assert "NOT certified" in out.out and "after 2 rounds" in out.out
    assert "  round  knots" in out.out  # the table, printed once, with the result
    assert "refined      2 rounds, NOT certified: max error" in out.out
    doc = json.loads((Path("run") / "summary.json").read_text())
    timed = doc["timed"]
    assert timed["refined"] and not timed["certified"] and not doc["certified"]
    assert [r["round"] for r in timed["refinement"]["rounds"]] == [0, 1]
    assert "error tolerance 0.0001, at most 2 rounds" in timed["refinement"]["budget"]
    # the waypoints stay hit on the refined grid
    assert timed["success"] and timed["waypoint_error_rad"] <= 1e-6


def test_solve_waypoints_falls_back_to_the_trapezoid_on_a_ur5(tmp_path, capsys):
    """A UR5 closed cycle at beta = 1: Hermite-Simpson overshoots, the refinement says so.

    Round 0 (Hermite-Simpson) finds the torque overshoot no grid removes; round 1
    re-solves its knots with the trapezoid (docs/timed.md). Two rounds leave it
    uncertified on the trapezoid's error, and the next step is more rounds.
    """
    ur5 = [[0.0, -1.2, 1.0, -0.5, 0.3, 0.0], [0.8, -0.6, 0.4, -1.2, -0.3, 0.5]]
    (tmp_path / "w.json").write_text(json.dumps({"q": ur5}))
    start = ["--start", *map(str, ur5[0]), "--goal", *map(str, ur5[0])]
    argv = ["solve", "--robot", "ur5", *start, "--waypoints", "w.json", "--closed"]
    code = main([*argv, "--beta", "1", "--max-rounds", "2", "--out", "run"])
    out = capsys.readouterr()
    assert code == 1, out.err
    assert "refine: round 0: 39 knots" in out.err
    assert "refine: round 1: 39 knots" in out.err and "trapezoidal" in out.err.splitlines()[-1]
    assert "scheme        hermite_simpson -> trapezoidal from round 1" in out.out
    assert "next          --max-rounds 4" in out.out
    doc = json.loads((Path("run") / "summary.json").read_text())
    rounds = doc["timed"]["refinement"]["rounds"]
    assert [r["method"] for r in rounds] == ["hermite_simpson", "trapezoidal"]
    assert doc["method"] == "trapezoidal" and doc["timed"]["waypoint_error_rad"] <= 1e-6


def test_the_timed_plans_certificates_take_two_processes(tmp_path, capsys, monkeypatch):
    """``solve --waypoints``: one plan, so its refinement certifies with ``processes=2`` on two
    cores or more, as ``solve`` does (the same figures: tests/trajopt/test_certify.py)."""
    import youbot_opt.cli.refinement as cli_refinement
    import youbot_opt.trajopt.refine as refine_module
    from youbot_opt.trajopt.certify import certify

    asked: list[int] = []

    def recording(*args, processes=1, **kwargs):
        asked.append(processes)
        return certify(*args, processes=processes, **kwargs)

    monkeypatch.setattr(cli_refinement, "default_workers", lambda: 2)
    monkeypatch.setattr(refine_module, "certify", recording)
    (tmp_path / "w.json").write_text(json.dumps({"q": WAYPOINTS}))
    argv = ["solve", "--waypoints", "w.json", "--segment-knots", "15", "--no-figures"]
    code, doc, _ = _json(capsys, [*argv, "--json", "--out", "run"])
    assert code == 0 and doc["certified"]
    assert asked and set(asked) == {2}
