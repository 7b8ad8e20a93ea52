"""Tests of youbot_opt.trajopt.multistart: seeds, clustering, parallel = serial, failures, CLI."""

from __future__ import annotations

import json
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from youbot_opt.cli import main
from youbot_opt.exceptions import ParameterError
from youbot_opt.sweeps.options import SweepOptions
from youbot_opt.trajopt.multistart import (
    MultistartResult,
    StartOutcome,
    run_multistart,
    start_seeds,
    trajectory_distance,
)
from youbot_opt.trajopt.solver import TrajOptSolver
from youbot_opt.trajopt.trajectory import Trajectory

N_KNOTS = 20  # small problem: the tests check the machinery, not the study's figures


@pytest.fixture(scope="module")
def solver(study1_solver: TrajOptSolver) -> TrajOptSolver:
    """The session's 20-knot study-1 solver (conftest), built once for all modules."""
    assert study1_solver.problem.n_knots == N_KNOTS
    return study1_solver


def _line(q0: np.ndarray, q1: np.ndarray, duration: float, n: int = 11) -> Trajectory:
    t = np.linspace(0.0, duration, n)
    q = q0 + np.outer(t / duration, q1 - q0)
    v = np.tile((q1 - q0) / duration, (n, 1))
    return Trajectory(t=t, q=q, v=v, a=np.zeros_like(q), tau=np.zeros_like(q))


def _start(key: str, objective: float, traj: Trajectory | None) -> StartOutcome:
    result = None if traj is None else SimpleNamespace(trajectory=traj)
    return StartOutcome(
        key=key,
        index=0,
        seed=int(key[-1]),
        guess="spline",
        status="solved",
        success=True,
        objective=objective,
        duration=1.0,
        work=1.0,
        iterations=1,
        solve_time=0.0,
        guess_time=0.0,
        result=result,  # type: ignore[arg-type]
    )


def test_start_seeds_are_reproducible_and_prefix_stable() -> None:
    """Seeds come from SeedSequence.spawn: reproducible, distinct, start i independent of n."""
    ten = start_seeds(7, 10)
    assert ten == start_seeds(7, 10)
    assert ten[:4] == start_seeds(7, 4)
    assert len(set(ten)) == 10
    expected = [
        int(c.generate_state(1, dtype=np.uint32)[0]) for c in np.random.SeedSequence(7).spawn(3)
    ]
    assert list(ten[:3]) == expected
    with pytest.raises(ParameterError, match="seed"):
        start_seeds(-1, 3)


def test_trajectory_distance_ignores_speed_and_measures_offsets() -> None:
    """Same path at another speed is at distance 0; a constant offset c is at distance c."""
    q0, q1 = np.array([0.0, 0.5, -1.0]), np.array([1.0, -0.5, 0.0])
    slow, fast = _line(q0, q1, 4.0), _line(q0, q1, 1.5, n=31)
    assert trajectory_distance(slow, fast) == pytest.approx(0.0, abs=1e-12)  # exact lines
    shifted = _line(q0 + 0.03, q1 + 0.03, 2.0)
    assert trajectory_distance(slow, shifted) == pytest.approx(0.03, rel=1e-9)  # RMS of c


def test_distinct_optima_cluster_by_objective_and_trajectory() -> None:
    """Equal f and path -> one optimum; equal f but another path, or another f -> separate."""
    q0, q1 = np.zeros(3), np.ones(3)
    a = _line(q0, q1, 2.0)
    b = _line(q0 + 0.2, q1 + 0.2, 2.0)  # distance 0.2 rad > dist_tol
    starts = (
        _start("s1", 9.0, a),
        _start("s2", 9.0 + 1e-8, _line(q0, q1, 2.5)),  # same path and f: joins s1
        _start("s3", 9.0, b),
        _start("s4", 11.0, a),
    )
    ms = MultistartResult(starts=starts, beta=0.5, bound_scale=1.0, seed=0)
    optima = ms.distinct_optima(obj_tol=1e-6, dist_tol=1e-2)
    assert [(o.objective, o.count) for o in optima] == [(9.0, 2), (9.0, 1), (11.0, 1)]
    assert optima[0].seeds == (1, 2)
    assert ms.best is not None and ms.best.key == "s1"
    assert ms.success_rate == 1.0


@pytest.mark.parametrize("bad", [0.0, -1e-3, float("nan"), float("inf")])
@pytest.mark.parametrize("name", ["obj_tol", "dist_tol"])
def test_distinct_optima_refuses_tolerances_not_finite_and_positive(name: str, bad: float) -> None:
    """obj_tol and dist_tol must be finite and > 0 (a zero dist_tol would make every start its
    own optimum): ParameterError naming the argument, from distinct_optima and summary."""
    a = _line(np.zeros(3), np.ones(3), 2.0)
    ms = MultistartResult(starts=(_start("s1", 9.0, a),), beta=0.5, bound_scale=1.0, seed=0)
    for method in (ms.distinct_optima, ms.summary):
        with pytest.raises(ParameterError, match=f"{name} must be a finite number > 0") as info:
            method(**{name: bad})  # type: ignore[operator]
        assert info.value.name == name


def test_parallel_equals_serial_and_reproduces_single_solves(solver: TrajOptSolver) -> None:
    """Process-pool and serial multistarts agree exactly; each start equals its own direct solve."""
    from youbot_opt.trajopt.spline_guess import random_spline_guess

    calls: list[tuple[int, int]] = []
    kw = {"beta": 0.5, "seed": 3, "include_straight": True}
    par = run_multistart(
        solver,
        3,
        **kw,
        sweep=SweepOptions(
            executor="process", workers=2, progress=lambda d, n, s: calls.append((d, n))
        ),
    )
    ser = run_multistart(solver, 3, **kw, sweep=SweepOptions(executor="serial"))
    assert [s.key for s in par.starts] == ["straight", "start_0000", "start_0001", "start_0002"]
    assert sorted(calls) == [(1, 4), (2, 4), (3, 4), (4, 4)]
    for p, s in zip(par.starts, ser.starts, strict=True):
        assert (p.seed, p.status, p.iterations) == (s.seed, s.status, s.iterations)
        assert p.objective == pytest.approx(s.objective, rel=1e-12)  # same IPOPT run: identical
    # Independent reference: the start's seed fed by hand to the spline guess and the solver.
    s1 = par.starts[2]
    p = solver.problem
    dt0 = 4.9 / (N_KNOTS - 1)  # the documented default: the study's 4.9 s guess duration
    guess = random_spline_guess(p.robot, p.start, p.goal, p.n_knots, seed=s1.seed, dt=dt0)
    direct = solver.solve(beta=0.5, guess=guess)
    assert s1.objective == pytest.approx(direct.objective, rel=1e-12)
    assert par.best is not None
    assert par.best.objective == min(s.objective for s in par.starts if s.success)
    assert par.success_rate == sum(s.success for s in par.starts) / 4


def test_a_failing_start_does_not_stop_the_run(
    solver: TrajOptSolver, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A start whose guess raises is an 'error' start with its reason, tried twice."""
    import youbot_opt.trajopt.spline_guess as sg

    real = sg.random_spline_guess
    bad_seed = start_seeds(0, 2)[1]

    def flaky(robot, start, goal, n_knots, *, seed, **kw):  # type: ignore[no-untyped-def]
        if seed == bad_seed:
            raise RuntimeError("LP solver exploded")
        return real(robot, start, goal, n_knots, seed=seed, **kw)

    monkeypatch.setattr(sg, "random_spline_guess", flaky)
    with ThreadPoolExecutor(max_workers=1) as pool:  # a caller-supplied executor
        res = run_multistart(solver, 2, beta=0.5, seed=0, sweep=SweepOptions(executor=pool))
    ok, bad = res.starts
    assert ok.success and bad.status == "error" and bad.attempts == 2
    assert bad.reason == "RuntimeError: LP solver exploded"
    assert res.success_rate == 0.5
    assert np.isnan(bad.objective) and bad.result is None


def test_bad_arguments_raise_parameter_error(solver: TrajOptSolver) -> None:
    """Bad counts, weights, scales and inputs raise ParameterError naming the argument."""
    with pytest.raises(ParameterError, match="n_starts"):
        run_multistart(solver, -1, sweep=SweepOptions(executor="serial"))
    with pytest.raises(ParameterError, match="beta"):
        run_multistart(solver, 1, beta=1.5, sweep=SweepOptions(executor="serial"))
    with pytest.raises(ParameterError, match="bound_scale"):
        run_multistart(solver, 1, bound_scale=0.0, sweep=SweepOptions(executor="serial"))
    with pytest.raises(ParameterError, match="expected a TrajOptSolver, got str"):
        run_multistart("youbot", 1)  # type: ignore[arg-type]


def test_cli_multistart_json(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """`youbot-opt multistart --json` prints a summary whose best equals the best start."""
    monkeypatch.chdir(tmp_path)  # its default output folder lands there
    code = main(
        ["multistart", "--starts", "2", "--knots", "15", "--workers", "0", "--json", "--quiet"]
    )
    assert code == 0
    summary = json.loads(capsys.readouterr().out)
    objectives = [s["objective"] for s in summary["starts"] if s["success"]]
    assert summary["best"]["objective"] == min(objectives)
    assert summary["n_starts"] == 2 and sum(o["count"] for o in summary["distinct_optima"]) == len(
        objectives
    )


@pytest.mark.parametrize("refine", [True, False])
def test_cli_multistart_reports_the_refined_plan(
    refine: bool,
    capsys: pytest.CaptureFixture[str],
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """trajectory.png and result.npz show the refined plan (--no-refine: the best start's grid)."""
    import youbot_opt.cli.studies as plots  # the command module imports the name it draws with
    from youbot_opt.trajopt.io import load_refined, load_result

    drawn: list[Any] = []
    real = plots.plot_trajectory

    def spy(result: Any, *args: Any, **kw: Any) -> Any:  # noqa: ANN401 - a figure
        drawn.append(result)
        return real(result, *args, **kw)

    monkeypatch.setattr(plots, "plot_trajectory", spy)
    argv = ["multistart", "--starts", "2", "--knots", "15", "--workers", "0", "--quiet"]
    argv += ["--json", "--out", str(tmp_path / "ms"), *([] if refine else ["--no-refine"])]
    assert main(argv) == 0
    summary = json.loads(capsys.readouterr().out)
    (plan,) = drawn
    saved = load_result(tmp_path / "ms" / "result.npz")
    assert "result.npz" in summary["files"] and "trajectory.png" in summary["files"]
    np.testing.assert_array_equal(saved.trajectory.q, plan.trajectory.q)
    assert summary["plan"]["objective"] == plan.objective == saved.objective
    assert summary["plan"]["n_knots"] == plan.problem.n_knots
    if refine:  # the refinement's last round, certified: not the best start on 15 knots
        refinement = load_refined(tmp_path / "ms" / "result.npz").refinement
        assert refinement.certified and summary["plan"]["certified"]
        assert summary["refinement"][0]["rounds"][-1]["n_knots"] == plan.problem.n_knots
        assert plan.objective == summary["refinement"][0]["rounds"][-1]["objective"]
    else:
        assert not summary["plan"]["certified"] and plan.problem.n_knots == 15
        assert plan.objective == summary["best"]["objective"]


@pytest.mark.parametrize(
    "argv",
    [
        ["--starts", "-3"],
        ["--beta", "2"],
        ["--knots", "1"],
        ["--workers", "-1"],
        ["--starts", "x"],
        ["--obj-tol", "0"],
        ["--dist-tol", "-1e-2"],
    ],
)
def test_cli_multistart_bad_input_exits_2(argv: list[str]) -> None:
    """Bad command-line values exit with status 2."""
    try:
        code = main(["multistart", "--quiet", *argv])
    except SystemExit as exc:  # argparse's own type errors
        code = int(exc.code or 0)
    assert code == 2
