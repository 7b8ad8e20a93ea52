"""The help texts: plain text, runnable examples, fast to print, and consistent choices."""

from __future__ import annotations

import argparse
import math
import re
import shlex
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import pytest

from youbot_opt.cli import build_parser
from youbot_opt.cli.pareto_table import distinct_points, pareto_summary, pareto_table, table_number

README = Path(__file__).resolve().parents[2] / "README.md"
SPHINX = re.compile(r"``|:(mod|func|class|meth|attr|data|exc|obj):`")
HEAVY = ("numpy", "casadi", "pinocchio", "scipy", "matplotlib", "meshcat")


def _help_texts() -> dict[str, str]:
    """The --help text of the top-level parser and of every sub-command."""
    parser = build_parser()
    texts = {"": parser.format_help()}
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                texts[name] = sub.format_help()
    return texts


def _examples() -> list[tuple[str, list[str]]]:
    """Every ``youbot-opt ...`` example line printed in a --help, as (command, argv)."""
    found = []
    for name, text in _help_texts().items():
        for line in text.splitlines():
            words = shlex.split(line) if line.startswith("    youbot-opt ") else []
            if name and words[1:2] == [name] and not any(w.startswith("[") for w in words):
                found.append((name, words[1:]))
    return found


def test_every_command_has_help():
    """The parser has the documented commands, each with a help text."""
    assert set(_help_texts()) >= {"", "main", "solve", "report", "pareto", "ikpath"}


@pytest.mark.parametrize("command", sorted(_help_texts()))
def test_help_is_plain_text(command):
    """No Sphinx markup (double backticks, :mod:/:func:/... roles) in any --help."""
    text = _help_texts()[command]
    assert not SPHINX.search(text), SPHINX.search(text)


def test_help_examples_are_found():
    """The example extraction finds the ikpath examples (so the run test is not vacuous)."""
    assert sum(name == "ikpath" for name, _ in _examples()) >= 4


@pytest.mark.parametrize("argv", [a for _, a in _examples()], ids=" ".join)
def test_help_example_runs_and_exits_0(argv, tmp_path):
    """Each example printed in a --help runs and exits 0 (with a temporary --out)."""
    extra = [] if "--out" in argv else ["--out", str(tmp_path / "run")]
    proc = subprocess.run(
        [sys.executable, "-m", "youbot_opt", *argv, *extra],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]


_NO_HEAVY = """
import sys
from youbot_opt.cli import main
try:
    main({argv!r})
except SystemExit:
    pass
print("HEAVY:", *sorted({{m.split(".")[0] for m in sys.modules}} & set({heavy!r})))
"""


@pytest.mark.parametrize(
    ("argv", "heavy"),
    [
        (["--help"], HEAVY),
        (["ikpath", "--help"], HEAVY),
        (["solve", "--help"], HEAVY),
        (["report", "--help"], HEAVY),
        (["pareto", "--help"], HEAVY),
        (["main", "--help"], HEAVY),
        (["reproduce-study1", "--help"], HEAVY),
        # An error message cuts long values with _checks.MAX_SHOWN_CHARS: _checks imports NumPy.
        (["solve", "--no-such-option"], HEAVY[1:]),
        (["ikpath", "--method", "nope"], HEAVY[1:]),
        (["ikpath", "--frame", "tool0"], HEAVY[1:]),
    ],
    ids=lambda v: " ".join(v) if isinstance(v, list) else "",
)
def test_help_and_argument_errors_import_no_solver(argv, heavy):
    """Parsing --help imports none of NumPy, CasADi, Pinocchio, SciPy, matplotlib, meshcat.

    An argument error imports no solver either (NumPy only). This is structural: the speed
    itself is measured in benchmarks/bench_cli.py.
    """
    code = _NO_HEAVY.format(argv=argv, heavy=heavy)
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip().splitlines()[-1] == "HEAVY:", proc.stdout[-500:]


def test_parser_choices_match_the_library():
    """The choices spelled out in the CLI (to keep --help fast) equal the library's."""
    from typing import get_args

    from youbot_opt.cli import parser
    from youbot_opt.ikpath.examples import EXAMPLES
    from youbot_opt.ikpath.solve import METHODS
    from youbot_opt.ikpath.starts import START_KINDS
    from youbot_opt.nlp.ipopt import LINEAR_SOLVERS, HessianMode

    assert parser.EXAMPLE_NAMES == tuple(sorted(EXAMPLES))
    assert parser.METHOD_NAMES == tuple(METHODS)
    assert parser.START_KIND_NAMES == tuple(START_KINDS)
    assert parser.LINEAR_SOLVER_NAMES == LINEAR_SOLVERS
    assert parser.HESSIAN_NAMES == get_args(HessianMode)


def _point(beta, duration, work, success=True, dominated=False):
    return SimpleNamespace(
        beta=beta,
        duration=duration,
        work=work,
        objective=beta * duration + (1 - beta) * work,
        status="solved" if success else "error",
        success=success,
        iterations=5,
        start="previous",
        dominated=dominated,
        summary=lambda: {"beta": beta},
    )


def _front():
    # The study-1 front's high-beta end, as measured: three weights give the same solution
    # (T and W agree to 2e-10 relative).
    points = (
        _point(0.80, 1.3766645938738038, 16.2812004540111),
        _point(0.85, 1.3611110987882373, 16.349019245941378),
        _point(0.90, 1.3611110981845729, 16.34901924514988),
        _point(0.95, 1.3611110980524788, 16.349019248188462),
        _point(0.99, float("nan"), float("nan"), success=False, dominated=True),
    )
    return SimpleNamespace(
        points=points,
        resumed=0,
        wall_time=0.5,
        summary=lambda: {"n_points": len(points)},
    )


def test_pareto_identical_points_are_one_point():
    """Weights whose T and W agree within 1e-6 relative are one distinct point."""
    groups = distinct_points(_front().points)
    assert [[p.beta for p in g] for g in groups] == [[0.80], [0.85, 0.90, 0.95]]
    # A tolerance below the measured 2e-10 spread separates them again.
    assert len(distinct_points(_front().points, rtol=1e-12)) == 4


def test_pareto_table_counts_distinct_points_and_gives_w_its_unit():
    """The printed table says 4 non-dominated, 2 distinct, maps weights to points, W in units."""
    lines = pareto_table(_front())
    assert "4 non-dominated, 2 distinct points" in lines[0]
    assert "W [N^2 m^2 s]" in lines[1]
    rows = {line.split()[0]: line.split() for line in lines[2:7]}
    assert rows["0.850"][6] == rows["0.900"][6] == rows["0.950"][6] == "P2"
    assert rows["0.800"][6] == "P1" and rows["0.990"][6] == "-"
    assert lines[-1].startswith("P2: one point for beta = 0.85, 0.9, 0.95")
    summary = pareto_summary(_front())
    assert summary["n_distinct"] == 2 and summary["distinct_rtol"] == 1e-6
    assert summary["distinct_points"][1]["betas"] == [0.85, 0.90, 0.95]


def test_table_number_prints_a_dash_for_a_failed_solve():
    """Sweep tables (pareto, bounds) print finite numbers with their spec, '-' for NaN or inf."""
    assert table_number(1.3611110987882373, ".4f") == "1.3611"
    assert table_number(16.349019245941378, ".5f") == "16.34902"
    assert table_number(-2.5e-7, ".3g") == "-2.5e-07"
    assert [table_number(x, ".4f") for x in (math.nan, math.inf, -math.inf)] == ["-"] * 3
    row = pareto_table(_front())[6]  # beta = 0.99 did not converge: T, W and f are dashes
    assert row.split()[:4] == ["0.990", "-", "-", "-"]


def test_readme_unreachable_command_is_refused(tmp_path):
    """The README's (0, 7.1) command runs and exits 2 with a certified distance bound."""
    match = re.search(r"`(youbot-opt ikpath [^`]*--target 0 7\.1[^`]*)`", README.read_text())
    assert match, "README gives the (0, 7.1) command"
    argv = shlex.split(match.group(1))[1:]
    proc = subprocess.run(
        [sys.executable, "-m", "youbot_opt", *argv, "--out", str(tmp_path / "run")],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert "unreachable" in proc.stdout + proc.stderr


def test_solve_other_robot_without_start_goal_says_why(capsys, tmp_path):
    """solve --robot double_pendulum without --start/--goal exits 2 and says they are needed."""
    from youbot_opt.cli import main

    code = main(["solve", "--robot", "double_pendulum", "--out", str(tmp_path / "run")])
    err = capsys.readouterr().err
    assert code == 2
    assert "--start and --goal" in err and "only the youbot has a default motion" in err


OTHERS_FLAGS = {"robots"}  # its help names the flags of the commands that take a robot


@pytest.mark.parametrize("command", sorted(set(_help_texts()) - {""} - OTHERS_FLAGS))
def test_every_flag_a_help_names_is_an_option_of_that_command(command):
    """A --help names only flags its command accepts (main --help once named --knots)."""
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction)).choices[
        command
    ]
    accepted = {flag for action in sub._actions for flag in action.option_strings}
    text = re.sub(r"(--[\w-]*-)\n\s*", r"\1", _help_texts()[command])  # a flag wrapped at "-"
    named = set(re.findall(r"(?<![\w-])--[a-z][a-z0-9-]*", text))
    assert named <= accepted, sorted(named - accepted)


def test_no_refine_help_says_the_plan_is_certified_once():
    """--no-refine's help says what the run does: one certificate on the fixed grid."""
    for command in ("main", "solve"):
        text = " ".join(_help_texts()[command].split())
        assert "never certified" not in text
        assert "certified once on" in text, command


def test_single_start_solve_on_another_robot_suggests_a_multistart(capsys, tmp_path):
    """One start on a robot other than the youBot: one line says it is a local optimum, and how."""
    from youbot_opt.cli import main

    argv = ["solve", "--knots", "20", "--no-refine", "--out"]
    ur5 = ["--robot", "ur5", "--start", "0", "0", "0", "0", "0", "0"]
    ur5 += ["--goal", "1", "-0.5", "0.5", "0", "0", "0"]
    main([*argv, str(tmp_path / "ur5"), *ur5])
    out = capsys.readouterr().out
    hints = [line for line in out.splitlines() if "--starts" in line]
    assert len(hints) == 1 and "local optimum" in hints[0], out
    main([*argv, str(tmp_path / "youbot")])  # the study's base case: its optimum is known
    assert "--starts" not in capsys.readouterr().out


def test_every_command_has_a_module_and_a_run_function():
    """parser.COMMANDS names each command of the parser once, with a callable in its module."""
    import importlib

    from youbot_opt.cli.parser import COMMANDS

    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    assert list(sub.choices) == list(COMMANDS)
    for module, function in COMMANDS.values():
        assert callable(getattr(importlib.import_module(f"youbot_opt.cli.{module}"), function))


_ONLY_CHOSEN = """
import sys
from youbot_opt.cli import main
main(["robots", "--names"])
print("CLI:", *sorted(m for m in sys.modules if m.startswith("youbot_opt.cli.")))
"""


def test_main_imports_only_the_chosen_command_module():
    """``youbot-opt robots`` imports the robots module, not solve's, studies' or ikpath's."""
    proc = subprocess.run([sys.executable, "-c", _ONLY_CHOSEN], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    loaded = set(proc.stdout.strip().splitlines()[-1].split()[1:])
    assert "youbot_opt.cli.robots" in loaded
    assert not loaded & {f"youbot_opt.cli.{m}" for m in ("solve", "studies", "ikpath", "output")}


_SOLVE_PATH = """
import sys
import youbot_opt.cli.solve
print("LOADED:", *sorted(m for m in sys.modules if m.split(".")[0] in {heavy!r}
      or m in {light!r}))
"""


def test_solve_command_imports_nothing_it_does_not_need_yet():
    """Importing the solve command (what ``youbot-opt solve`` runs first) imports no SciPy,
    matplotlib or meshcat, nor the reproduction's runs and the sweeps' figures (issue 27).

    SciPy comes with the certificate's integration (or a spline start, or a sphere fit),
    matplotlib with the figures, meshcat with the replay. Pinocchio and CasADi are needed at
    once (the robot and the NLP); coal is imported by Pinocchio's own bindings, so it is
    not checked here.
    """
    heavy = ["scipy", "matplotlib", "meshcat"]
    light = ["youbot_opt.reproduction.runs", "youbot_opt.viz.plots.studies"]
    code = _SOLVE_PATH.format(heavy=heavy, light=light)
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip().splitlines()[-1] == "LOADED:"
