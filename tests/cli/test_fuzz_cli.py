"""Argument fuzzing of every ``youbot-opt`` command (issue 16, item 5).

Hypothesis draws command lines -- a command, then options with hostile values
(huge, negative, NaN, empty, malformed, 10,001 link lengths, corpus URDFs past
the size limits) or ordinary ones -- and each runs in a forked child with a
4 GiB memory cap and a wall-clock time-out (``_run_cli_in_subprocess.py``).
Every run must end with exit code 0, 1 or 2, never a traceback or a signal; a
run that exits 2 ends with one clear ``error:`` line. A run still going at its
time-out (a valid, long computation) is killed and counted, not failed.
Derandomized with a fixed budget, so CI runs the same command lines each time.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from collections import Counter
from collections.abc import Iterator
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from youbot_opt.cli import build_parser

HERE = Path(__file__).resolve().parent
HELPER = HERE / "_run_cli_in_subprocess.py"
CORPUS = HERE.parent / "robot" / "urdf_corpus"
#: Command lines per CI run (~40 s on 2 busy cores, time-outs included); FUZZ_EXAMPLES=N for
#: a longer local campaign.
N_EXAMPLES = int(os.environ.get("FUZZ_EXAMPLES", "40"))
TIMEOUT = 3.0  # [s] wall clock per command line: refusals take < 1 s
SKIPPED = {"--scheduler", "--scheduler-file", "-h", "--help"}  # network; help is tested elsewhere
INTS = ["0", "-1", "1", "2", "3", "7", "1000000000", "10000000", "99999999999999999999999",
        "nan", "x", "", "1e3", "-0", "007", "+5"]  # fmt: skip
FLOATS = ["nan", "inf", "-inf", "0", "-1", "1e308", "1e-320", "0.5", "1", "2", "x", "",
          "1e999", "-0.0", "3.14159", "1,5"]  # fmt: skip
STRINGS = ["", "x", "../fuzz_out", "fuzz_out", "/nonexistent/x", "/dev/null", "/dev/zero", "ur5",
           "youbot", "panda", "é", "a" * 300, "-", "0:1:0", "0:1:1e-9", "0:1:1e-12", "0:1:-0.1",
           "1,2,3", "nan", "0.5", "1:0:0.1", "0.05:0.95:0.05", "J=nan", "joint=1", "2/3",
           "0/0", "5/3",
           str(CORPUS / "limits" / "joints_1001_star.urdf"),
           str(CORPUS / "physics" / "subnormal_mass_and_inertia.urdf"),
           str(CORPUS / "valid" / "rotated_inertial.urdf")]  # fmt: skip
STATS: Counter[str] = Counter()


def _commands() -> dict[str, list[argparse.Action]]:
    parser = build_parser()
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return {
                name: [a for a in sub._actions if not set(a.option_strings) & SKIPPED]
                for name, sub in action.choices.items()
            }
    raise AssertionError("no sub-commands")


COMMANDS = _commands()


@st.composite
def command_lines(draw: st.DrawFn) -> list[str]:
    """A command and up to five options with hostile or ordinary values."""
    name = draw(st.sampled_from(sorted(COMMANDS)))
    argv = [name]
    actions = COMMANDS[name]
    for action in draw(st.lists(st.sampled_from(actions), max_size=5, unique_by=id)):
        flag = action.option_strings[0] if action.option_strings else None
        if action.nargs == 0:
            argv.append(flag)  # type: ignore[arg-type]
            continue
        if action.choices:
            pool = [*map(str, action.choices), "bogus"]
        elif action.type is int:
            pool = INTS
        elif action.type is float:
            pool = FLOATS
        else:
            pool = STRINGS
        if action.nargs in ("+", "*"):
            if flag == "--lengths" and draw(st.booleans()):
                values = ["0.1"] * 10_001  # the 10,000-link arm
            else:
                values = draw(st.lists(st.sampled_from(pool), min_size=1, max_size=4))
        else:
            values = [draw(st.sampled_from(pool))]
        if flag is not None:
            argv += [flag, *values]
        else:
            argv += values
    return argv


@pytest.fixture(scope="module")
def cli_runner() -> Iterator[subprocess.Popen[str]]:
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}
    env = {k: v for k, v in env.items() if not k.startswith("YOUBOT_OPT_MAX")}
    proc = subprocess.Popen(
        [sys.executable, str(HELPER)], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True,
        env=env,
    )  # fmt: skip
    yield proc
    assert proc.stdin is not None
    proc.stdin.close()
    proc.wait(timeout=60)
    print(f"\nCLI fuzz outcomes: {dict(STATS)}")


@pytest.mark.slow
@settings(
    max_examples=N_EXAMPLES,
    derandomize=True,
    deadline=None,
    database=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
@given(argv=command_lines())
def test_random_command_lines_exit_cleanly(
    argv: list[str], cli_runner: subprocess.Popen[str], tmp_path_factory: pytest.TempPathFactory
) -> None:
    """Exit 0, 1 or 2; no traceback, no signal; exit 2 ends with one ``error:`` line."""
    cwd = tmp_path_factory.mktemp("cli_fuzz", numbered=True)
    assert cli_runner.stdin is not None and cli_runner.stdout is not None
    cli_runner.stdin.write(json.dumps({"argv": argv, "cwd": str(cwd), "timeout": TIMEOUT}) + "\n")
    cli_runner.stdin.flush()
    run = json.loads(cli_runner.stdout.readline())
    STATS["inputs"] += 1
    STATS[f"{argv[0]}:{'timeout' if run['timeout'] else run['code']}"] += 1
    shown = [a if len(a) < 80 else a[:40] + "..." for a in argv[:12]]
    detail = (shown, run["code"], run["signal"], run["stderr"][-1500:])
    assert "Traceback" not in run["stderr"], detail
    assert run["signal"] is None, detail
    if run["timeout"]:
        return  # a valid run, still computing: killed by the harness, not a failure
    assert run["code"] in (0, 1, 2), detail
    if run["code"] == 2:
        last = run["stderr"].strip().splitlines()[-1]
        assert "error:" in last and len(last) < 2000, detail
