"""`youbot-opt solve`'s defaults: the transcription per robot, what to try when uncertified."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from youbot_opt.cli import build_parser, main
from youbot_opt.cli.advice import next_step
from youbot_opt.cli.parser import DEFAULT_TRANSCRIPTION
from youbot_opt.cli.solve import transcription
from youbot_opt.nlp.status import SolveStatus
from youbot_opt.reproduction.study1 import study1_problem
from youbot_opt.trajopt.refine import RefinementBudget, refine
from youbot_opt.trajopt.solver import TrajOptSolver


@pytest.mark.parametrize(
    ("argv", "expected"),
    [
        (["solve"], "trapezoidal"),
        (["solve", "--robot", "youbot", "--transcription", "hermite-simpson"], "hermite_simpson"),
        (["solve", "--robot", "ur5"], DEFAULT_TRANSCRIPTION),
        (["solve", "--robot", "youbot", "--lock", "arm_joint_1=0"], DEFAULT_TRANSCRIPTION),
        (["solve", "--robot", "ur5", "--transcription", "trapezoidal"], "trapezoidal"),
    ],
)
def test_the_study_youbot_keeps_its_trapezoid_and_other_robots_get_radau(argv, expected):
    """No --transcription: the study's youBot is solved as the study was, other robots L-stable."""
    assert DEFAULT_TRANSCRIPTION == "radau"
    assert transcription(build_parser().parse_args(argv)) == expected


def test_the_help_names_each_default():
    """--help says which robot gets which scheme."""
    (action,) = [
        a
        for a in build_parser()._subparsers._group_actions[0].choices["solve"]._actions  # type: ignore[union-attr]
        if a.dest == "transcription"
    ]
    assert "trapezoidal for the study's youBot" in action.help
    assert "radau for any other robot" in action.help


@pytest.fixture(scope="module")
def one_round():
    """The study's 15-knot trapezoid with a one-round budget: uncertified, error still high."""
    solver = TrajOptSolver(study1_problem(15), "trapezoidal")
    return refine(solver, beta=0.5, budget=RefinementBudget(max_rounds=1))


def test_an_exhausted_round_budget_suggests_more_rounds(one_round):
    """One round, not certified: the error had no chance to fall, so --max-rounds 2."""
    assert not one_round.certified
    assert next_step(*one_round).startswith("--max-rounds 2")


def test_errors_that_do_not_fall_suggest_radau_then_a_multistart(one_round):
    """A trapezoid whose error rose over the last round -> radau; under radau -> --starts."""
    result, record = one_round
    first = record.rounds[0]
    rounds = (first, dataclasses.replace(first, index=1, max_error=2.0 * first.max_error))
    rising = dataclasses.replace(record, rounds=rounds)
    assert next_step(result, rising).startswith("--transcription radau (L-stable; the error")
    as_radau = dataclasses.replace(result, method="radau")
    assert next_step(as_radau, rising).startswith("a multistart: --starts 8")


def test_a_failed_solve_suggests_a_multistart(one_round):
    """No successful solve to refine: other starts."""
    result, record = one_round
    failed = dataclasses.replace(result, status=SolveStatus.INFEASIBLE)
    assert not failed.success
    assert next_step(failed, record).startswith("a multistart: --starts 8")


def test_an_uncertified_run_prints_the_next_step(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """The table of an uncertified run ends its refinement lines with 'next ...'."""
    monkeypatch.chdir(tmp_path)
    assert main(["solve", "--knots", "15", "--max-rounds", "1", "--quiet"]) == 1
    out = capsys.readouterr().out
    assert "next          --max-rounds 2 (the error was still falling)" in out


def test_unresolved_damping_suggests_radau(one_round, monkeypatch: pytest.MonkeyPatch):
    """A damping rate of 561 1/s (the iiwa's joint 7) on this grid: rate x h > 2 -> radau."""
    import youbot_opt.cli.advice as advice
    import youbot_opt.dynamics.numeric as numeric

    monkeypatch.setattr(
        advice, "damping_rate", lambda *a, **k: numeric.DampingRate(rate=561.0, joint="j7")
    )
    text = next_step(*one_round)
    assert text.startswith("--transcription radau (L-stable; j7's damping relaxes at 561 1/s")
    assert "> 2, unresolved" in text


@pytest.mark.parametrize("command", ["solve", "multistart", "pareto", "bounds"])
def test_no_refine_fallback_keeps_hermite_simpson_in_the_budget(command):
    """``--no-refine-fallback`` is ``RefinementBudget(fallback=False)``; the default falls back."""
    from youbot_opt.cli.refinement import refinement_budget

    parse = build_parser().parse_args
    assert refinement_budget(parse([command])).fallback is True
    assert refinement_budget(parse([command, "--no-refine-fallback"])).fallback is False
    assert refinement_budget(parse([command, "--no-refine-fallback"])) == RefinementBudget(
        fallback=False
    )


@pytest.mark.parametrize("hessian", ["exact", "limited-memory"])
def test_solve_takes_the_hessian_and_records_it(hessian, tmp_path, capsys):
    """``--hessian`` reaches IPOPT: the plan is the library's with that Hessian, and says so.

    The command's objective equals a library solve with ``IpoptOptions(hessian=...)``
    on the same problem (1e-9 relative: the same NLP, options and start, so the same
    IPOPT steps), and the run's summary records the Hessian it used.
    """
    import json

    from youbot_opt.nlp.ipopt import IpoptOptions

    argv = ["solve", "--knots", "15", "--no-refine", "--no-figures", "--hessian", hessian]
    assert main([*argv, "--json", "--out", str(tmp_path / "run")]) == 0
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["hessian"] == hessian
    options = IpoptOptions(hessian=hessian)
    expected = TrajOptSolver(study1_problem(15), "trapezoidal", options).solve(beta=0.5)
    assert expected.success
    assert summary["objective"] == pytest.approx(expected.objective, rel=1e-9)
    capsys.readouterr()


def test_the_default_hessian_is_the_exact_one(tmp_path, capsys):
    """No ``--hessian``: the exact Hessian (the symbolic backend has it), recorded as such."""
    import json

    argv = ["solve", "--knots", "15", "--no-refine", "--no-figures", "--json"]
    assert main([*argv, "--out", str(tmp_path / "run")]) == 0
    assert json.loads((tmp_path / "run" / "summary.json").read_text())["hessian"] == "exact"
    capsys.readouterr()


@pytest.mark.parametrize(("cores", "processes"), [(4, 2), (2, 2), (1, 1)])
@pytest.mark.parametrize("refined", [True, False])
def test_a_single_plans_certificate_takes_two_processes_where_there_are_two_cores(
    cores, processes, refined, tmp_path, capsys, monkeypatch
):
    """``solve`` certifies its one plan with ``certify(processes=2)`` on two cores or more
    (the one-interval integrations beside the tracking simulations), 1 on one core; refined
    (the refinement's certificates) or not (``--no-refine``: the plan's own certificate)."""
    import youbot_opt.cli.refinement as cli_refinement
    import youbot_opt.cli.trajopt_text as cli_text
    import youbot_opt.trajopt.refine as refine_module
    from youbot_opt.trajopt.certify import certify

    asked: list[int] = []

    def recording(*args, processes=1, **kwargs):
        asked.append(processes)
        return certify(*args, processes=processes, **kwargs)

    monkeypatch.setattr(cli_refinement, "default_workers", lambda: cores)
    monkeypatch.setattr(refine_module, "certify", recording)
    monkeypatch.setattr(cli_text, "certify", recording)
    argv = ["solve", "--knots", "15", "--no-figures", "--json", "--out", str(tmp_path / "run")]
    main(argv if refined else [*argv, "--no-refine"])
    capsys.readouterr()
    assert asked and set(asked) == {processes}
