"""Comma lists with an empty item, an empty --out, --shard without --out: refused (#29)."""

from __future__ import annotations

import pytest

from youbot_opt.cli import main
from youbot_opt.cli.studies import parse_values
from youbot_opt.exceptions import ParameterError


@pytest.mark.parametrize(
    ("text", "position"), [("0,,1", "item 2 of 3"), ("0,1,", "item 3 of 3"), (",0", "item 1 of 2")]
)
def test_an_empty_list_item_is_an_error_naming_its_position(text, position):
    with pytest.raises(ParameterError, match=position):
        parse_values(text, "betas")


def test_lists_with_spaces_still_parse():
    assert parse_values("0, 0.5 ,1", "betas") == (0.0, 0.5, 1.0)


def _exit_code(argv: list[str]) -> int:
    try:
        return main(argv)
    except SystemExit as exc:  # argparse refused it
        return int(exc.code or 0)


def test_pareto_betas_with_an_empty_item_is_refused(tmp_path, capsys):
    code = _exit_code(["pareto", "--knots", "15", "--betas", "0,,1", "--out", str(tmp_path)])
    assert code == 2
    err = capsys.readouterr().err
    assert "item 2 of 3 is empty" in err and "Traceback" not in err
    assert not any(tmp_path.iterdir())


@pytest.mark.parametrize("command", ["multistart", "pareto", "bounds", "solve"])
@pytest.mark.parametrize("out", ["", "  "])
def test_an_empty_out_is_refused(command, out, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert _exit_code([command, "--knots", "15", "--out", out]) == 2
    err = capsys.readouterr().err
    assert "--out" in err and "empty path" in err
    assert not any(tmp_path.iterdir())


@pytest.mark.parametrize("command", ["multistart", "pareto", "bounds"])
def test_shard_without_out_is_refused(command, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert _exit_code([command, "--knots", "15", "--shard", "1/2"]) == 2
    err = capsys.readouterr().err
    assert "--shard I/K needs --out DIR" in err and "Traceback" not in err
    assert not any(tmp_path.iterdir())
