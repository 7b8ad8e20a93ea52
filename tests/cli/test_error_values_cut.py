"""Errors echo at most MAX_SHOWN_CHARS of a user's value, then its length (#29)."""

from __future__ import annotations

import pytest

from youbot_opt._checks import MAX_SHOWN_CHARS, shown
from youbot_opt.cli import main

LONG = "x" * 100_000


@pytest.mark.parametrize(
    "argv",
    [
        ["multistart", "--knots", "15", "--starts", "2", "--scheduler", LONG],
        ["multistart", "--knots", "15", "--starts", "2", f"--scheduler={LONG}"],
        ["multistart", "--knots", "15", "--starts", "2", "--scheduler", "tcp://" + LONG],
        ["multistart", "--knots", LONG],
        ["solve", "--knots", "1" * 100_000 + "a"],
        ["multistart", "--knots", "15", "--shard", LONG],
        ["multistart", "--knots", "15", "--scheduler", "tcp://a " + LONG],
    ],
)
def test_cli_errors_cut_a_long_value(argv, capsys, tmp_path):
    argv = [*argv, "--out", str(tmp_path)]
    try:
        code = main(argv)
    except SystemExit as exc:  # argparse refuses it
        code = exc.code
    assert code == 2
    err = capsys.readouterr().err
    assert "x" * (MAX_SHOWN_CHARS + 1) not in err and "1" * (MAX_SHOWN_CHARS + 1) not in err
    assert len(err) < 3000, err[:500]


def test_shown_cuts_after_the_limit_and_names_the_length():
    assert shown("abc") == "'abc'"
    text = shown("y" * 100_000)
    assert text.startswith("'" + "y" * (MAX_SHOWN_CHARS - 1))
    assert text.endswith("… (100000 characters)")
    assert len(text) < MAX_SHOWN_CHARS + 40
