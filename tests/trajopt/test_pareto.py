"""Tests of youbot_opt.trajopt.pareto and .bound_scaling: fronts, warm starts, resume, CLI."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from youbot_opt.cli import main
from youbot_opt.cli.studies import parse_values
from youbot_opt.exceptions import ParameterError
from youbot_opt.reproduction.study1 import study1_problem
from youbot_opt.sweeps.options import SweepOptions
from youbot_opt.sweeps.store import stored_record
from youbot_opt.trajopt.bound_scaling import bound_scaling_study
from youbot_opt.trajopt.pareto import (
    DEFAULT_BETAS,
    ParetoFront,
    ParetoPoint,
    dominated_mask,
    pareto_sweep,
)
from youbot_opt.trajopt.solver import TrajOptSolver

N_KNOTS = 20
BETAS = (0.2, 0.5, 0.8)


@pytest.fixture(scope="module")
def solver(study1_solver: TrajOptSolver) -> TrajOptSolver:
    """The session's 20-knot study-1 solver (conftest), built once for all modules."""
    assert study1_solver.problem.n_knots == N_KNOTS
    return study1_solver


@pytest.fixture(scope="module")
def front(solver: TrajOptSolver) -> ParetoFront:
    """A warm-started 3-point sweep, computed once."""
    return pareto_sweep(solver, BETAS)


def _brute_dominated(t: list[float], w: list[float]) -> list[bool]:
    """Reference: the definition, written as a double loop."""
    out = []
    for i in range(len(t)):
        out.append(
            any(
                t[j] <= t[i] and w[j] <= w[i] and (t[j] < t[i] or w[j] < w[i])
                for j in range(len(t))
            )
        )
    return out


def test_dominated_mask_matches_the_definition() -> None:
    """The vectorised mask equals a double loop over the definition on random and tied points."""
    rng = np.random.default_rng(0)
    t = rng.integers(0, 5, 40).astype(float).tolist()  # many ties on purpose
    w = rng.integers(0, 5, 40).astype(float).tolist()
    assert dominated_mask(t, w).tolist() == _brute_dominated(t, w)
    assert dominated_mask([1.0, 1.0], [2.0, 2.0]).tolist() == [False, False]  # equal: neither
    assert dominated_mask([1.0, np.nan], [1.0, 0.0]).tolist() == [False, True]  # NaN: out
    noisy_tie = ([1.3611111, 1.3611110], [16.349019, 16.349019])  # one optimum, solver noise
    assert dominated_mask(*noisy_tie).tolist() == [True, False]  # exact definition
    assert dominated_mask(*noisy_tie, rtol=1e-6).tolist() == [False, False]  # a tie
    assert dominated_mask([1.0, 1.1], [2.0, 2.0], rtol=1e-6).tolist() == [False, True]


def test_default_betas_are_the_studys() -> None:
    """The default weights are 0.05, 0.10, ..., 0.95 (19 points)."""
    np.testing.assert_allclose(DEFAULT_BETAS, np.linspace(0.05, 0.95, 19), atol=1e-12)


def test_warm_started_sweep_matches_cold_solves() -> None:
    """At the study's 50 knots each warm-started point is the optimum a cold solve reaches."""
    # At 50 knots warm and cold solves agreed to < 4e-9 at all 19 study weights when this
    # test was written; coarse grids (e.g. 20 knots) have close-by local optima (8.779507
    # against 8.779559 at beta = 0.5) that warm and cold starts may legitimately split.
    solver50 = TrajOptSolver(study1_problem(50))
    warm = pareto_sweep(solver50, BETAS)
    assert [p.start for p in warm.points] == ["straight", "previous", "previous"]
    for p in warm.points:
        cold = solver50.solve(beta=p.beta)
        assert p.success and cold.success
        # Both converge to IPOPT tol = 1e-8; 1e-7 relative leaves room for the different paths.
        assert p.objective == pytest.approx(cold.objective, rel=1e-7)
        assert p.objective == pytest.approx(p.beta * p.duration + (1 - p.beta) * p.work, rel=1e-12)


def test_front_trades_time_for_work(front: ParetoFront) -> None:
    """More time weight gives a shorter, costlier motion; no point of this front is dominated."""
    t = [p.duration for p in front.points]
    w = [p.work for p in front.points]
    assert t[0] > t[1] > t[2] and w[0] < w[1] < w[2]  # weighted-sum optima are monotone in beta
    assert len(front.nondominated()) == 3 and front.success_rate == 1.0


def test_nondominated_drops_dominated_and_failed_points(front: ParetoFront) -> None:
    """A point worse in T and W, and a failed point, are excluded from nondominated()."""
    good = front.points[1]
    worse = replace(good, beta=0.9, duration=good.duration + 1, work=good.work + 1, dominated=True)
    failed = replace(good, beta=0.95, success=False, status="max_iterations", dominated=True)
    mixed = ParetoFront(points=(good, worse, failed))
    assert mixed.nondominated() == (good,)


def test_interrupted_sweep_resumes_to_the_same_front(solver: TrajOptSolver, tmp_path: Path) -> None:
    """A sweep stopped after 2 points resumes from disk and equals an uninterrupted sweep."""

    def stop_after_two(done: int, total: int, point: ParetoPoint) -> None:
        if done == 2:
            raise KeyboardInterrupt  # stands in for Ctrl-C / a kill between two points

    with pytest.raises(KeyboardInterrupt):
        pareto_sweep(solver, BETAS, sweep=SweepOptions(out=tmp_path, progress=stop_after_two))
    resumed = pareto_sweep(solver, BETAS, sweep=SweepOptions(out=tmp_path))
    full = pareto_sweep(solver, BETAS)
    assert resumed.resumed == 2
    for a, b in zip(resumed.points, full.points, strict=True):
        # Point 3 starts from point 2 as read back from disk: the same numbers, so the same run.
        assert a.objective == pytest.approx(b.objective, rel=0, abs=1e-9)
        assert a.start == b.start
    with pytest.raises(ParameterError, match="betas"):
        pareto_sweep(solver, (0.2, 0.5), sweep=SweepOptions(out=tmp_path))


def test_resumed_front_reloads_the_first_point_multistart(
    solver: TrajOptSolver, tmp_path: Path
) -> None:
    """After a resume, `first` (the first point's multistart) equals the uninterrupted one."""

    def stop_after_one(done: int, total: int, point: ParetoPoint) -> None:
        if done == 1:
            raise KeyboardInterrupt  # a kill right after the first point was saved

    kw = {"first_starts": 2, "seed": 4}
    serial = SweepOptions(executor="serial")
    with pytest.raises(KeyboardInterrupt):
        pareto_sweep(
            solver, BETAS[:2], **kw, sweep=replace(serial, out=tmp_path, progress=stop_after_one)
        )
    resumed = pareto_sweep(solver, BETAS[:2], **kw, sweep=replace(serial, out=tmp_path))
    full = pareto_sweep(solver, BETAS[:2], **kw, sweep=serial)
    assert resumed.resumed == 1 and resumed.first is not None and full.first is not None
    assert resumed.first.resumed == 3  # every start read back from DIR/first_point
    got, ref = resumed.first.summary(), full.first.summary()
    for field in ("beta", "bound_scale", "seed", "n_starts", "success_rate", "n_errors"):
        assert got[field] == ref[field]
    assert [o["count"] for o in got["distinct_optima"]] == [
        o["count"] for o in ref["distinct_optima"]
    ]
    for a, b in zip(resumed.first.starts, full.first.starts, strict=True):
        assert (a.key, a.seed, a.status, a.iterations) == (b.key, b.seed, b.status, b.iterations)
        # Same seeds, same deterministic IPOPT run; the stored result reads back exactly.
        assert a.objective == pytest.approx(b.objective, rel=0, abs=1e-12)
    for a, b in zip(resumed.points, full.points, strict=True):
        assert (a.start, a.status, a.iterations) == (b.start, b.status, b.iterations)
        assert a.objective == pytest.approx(b.objective, rel=0, abs=1e-9)  # as the resume test


def test_crashing_point_is_recorded_failed_retried_once_and_the_sweep_goes_on(
    solver: TrajOptSolver,
    tmp_path: Path,
    faults,  # type: ignore[no-untyped-def]
) -> None:
    """A point whose worker segfaults fails after 2 attempts with the reason; later points solve."""
    faults(crash={"point_001"})
    front = pareto_sweep(solver, BETAS, sweep=SweepOptions(out=tmp_path / "always"))
    a, b, c = front.points
    assert a.success and c.success and not b.success
    assert b.status == "error" and "killed by signal SIGSEGV" in str(b.reason)
    assert c.start == "previous"  # warm-started from point 0, the last converged point
    record = stored_record(tmp_path / "always", "point_001")
    assert record["state"] == "failed" and record["attempts"] == 2
    assert len(record["reasons"]) == 2 and all("crashed" in r for r in record["reasons"])
    # A rerun does not try it a third time (attempts used up) and does not crash.
    again = pareto_sweep(solver, BETAS, sweep=SweepOptions(out=tmp_path / "always"))
    assert again.resumed == 3 and again.points[1].status == "error"

    # Crashing on the first attempt only: the retry succeeds and the front is the usual one.
    faults(crash={"point_001"}, once_dir=tmp_path)
    once = pareto_sweep(solver, BETAS, sweep=SweepOptions(out=tmp_path / "once"))
    full = pareto_sweep(solver, BETAS, sweep=SweepOptions(executor="serial"))
    for p, q in zip(once.points, full.points, strict=True):
        # Same warm starts, same deterministic IPOPT run in another process: 1e-9 as above.
        assert p.objective == pytest.approx(q.objective, rel=0, abs=1e-9)
    record = stored_record(tmp_path / "once", "point_001")
    assert record["state"] == "done" and record["attempts"] == 2
    assert len(record["reasons"]) == 1 and "SIGSEGV" in record["reasons"][0]


def test_hung_point_times_out(solver: TrajOptSolver, faults) -> None:  # type: ignore[no-untyped-def]
    """A point that hangs is killed at the per-point timeout, twice, and the sweep goes on."""
    faults(hang={"point_000"})
    front = pareto_sweep(solver, BETAS[:2], sweep=SweepOptions(timeout=1.0))
    assert front.points[0].status == "error" and front.points[0].reason == "timeout after 1 s"
    assert front.points[1].success and front.points[1].start == "straight"


def test_first_point_multistart_keeps_the_best_start(solver: TrajOptSolver) -> None:
    """With first_starts, point 1 is the best of its multistart and the rest warm-start from it."""
    front = pareto_sweep(
        solver, BETAS[:2], first_starts=2, seed=4, sweep=SweepOptions(executor="serial")
    )
    assert front.first is not None and front.first.n_starts == 3  # 2 splines + straight line
    best = min(s.objective for s in front.first.starts if s.success)
    assert front.points[0].start == "multistart" and front.points[0].objective == best
    assert front.points[1].start == "previous"


def test_pareto_rejects_bad_weights(solver: TrajOptSolver) -> None:
    """Empty, repeated or out-of-range weights raise ParameterError."""
    for bad in ((), (0.5, 0.5), (0.5, 1.2)):
        with pytest.raises(ParameterError):
            pareto_sweep(solver, bad)


def test_bound_scaling_shrinks_feasible_set(solver: TrajOptSolver) -> None:
    """Tighter bounds never lower f, and each active bound equals the scaled data-sheet limit."""
    res = bound_scaling_study(solver, (1.0, 0.9), n_starts=1, sweep=SweepOptions(executor="serial"))
    full, tight = res.rows
    assert full.best is not None and tight.best is not None
    # Scaling shrinks the feasible set (start and goal stay inside): the best f cannot drop.
    assert tight.objective >= full.objective - 1e-8
    robot = solver.problem.robot
    limits = {"velocity": robot.velocity_limit, "torque": robot.effort_limit}
    for row in res.rows:
        assert row.active, "the base case has active speed bounds (the study's Appendix C)"
        for a in row.active:
            family, side = a.name.rsplit("_", 1)
            if family in limits:
                expected = (
                    row.bound_scale * limits[family][a.joint] * (1 if side == "upper" else -1)
                )
                assert a.bound == pytest.approx(expected, rel=1e-12)  # data sheet x scale
                assert abs(a.value - a.bound) <= 1e-5  # active_tol
    assert sum(tight.active_counts().values()) == len(tight.active)


def test_parse_values_ranges_and_lists() -> None:
    """'a:b:step' includes b; lists parse; bad text raises ParameterError."""
    assert parse_values("0.05:0.95:0.05", "betas") == pytest.approx(DEFAULT_BETAS, abs=1e-12)
    assert parse_values("1,0.95,0.9", "scales") == (1.0, 0.95, 0.9)
    for bad in ("0.1:0.2", "0.1:0.5:0", "a,b", "", "nan"):
        with pytest.raises(ParameterError):
            parse_values(bad, "betas")


def test_cli_pareto_and_bounds_json(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    """The pareto and bounds commands print JSON summaries and write resumable output."""
    base = ["--knots", "15", "--workers", "0", "--json", "--quiet"]
    assert main(["pareto", "--betas", "0.4,0.6", "--out", str(tmp_path / "p"), *base]) == 0
    pts = json.loads(capsys.readouterr().out)["points"]
    assert [p["beta"] for p in pts] == [0.4, 0.6] and all(p["success"] for p in pts)
    assert main(["pareto", "--betas", "0.4,0.6", "--out", str(tmp_path / "p"), *base]) == 0
    assert json.loads(capsys.readouterr().out)["resumed"] == 2
    assert main(["bounds", "--scales", "1,0.9", "--starts", "0", *base]) == 0
    rows = json.loads(capsys.readouterr().out)["rows"]
    assert [r["bound_scale"] for r in rows] == [1.0, 0.9]


@pytest.mark.parametrize(
    "argv",
    [
        ["pareto", "--betas", "0.5:0.1:-1"],
        ["pareto", "--betas", "x"],
        ["pareto", "--betas", "0.5,1.5"],
        ["bounds", "--scales", "1,-0.9"],
        ["bounds", "--beta", "-0.1"],
    ],
)
def test_cli_bad_input_exits_2(argv: list[str]) -> None:
    """Bad ranges, weights and scales exit with status 2 before any solve."""
    assert main([*argv, "--quiet"]) == 2
