"""Numeric flags are range-checked at parse time; the error names flag, value and range (#29)."""

from __future__ import annotations

import pytest

from youbot_opt.cli import main


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["solve", "--seed", "-1"], "--seed must be in 0..4294967295, got -1"),
        (["multistart", "--seed", "-1"], "--seed must be in 0..4294967295, got -1"),
        (
            ["solve", "--max-iter", "2147483648"],
            "--max-iter must be in 0..2147483647, got 2147483648",
        ),
        (["solve", "--max-iter", "x"], "--max-iter must be an integer in 0..2147483647"),
        (["multistart", "--obj-tol", "0"], "--obj-tol must be in (0, 1.79769e+308], got 0"),
        (["multistart", "--dist-tol", "-0.1"], "--dist-tol must be in (0, 1.79769e+308], got -0.1"),
        (["multistart", "--dist-tol", "nan"], "--dist-tol must be in (0, 1.79769e+308], got nan"),
        (["multistart", "--obj-tol", "inf"], "--obj-tol must be in (0, 1.79769e+308], got inf"),
        (["multistart", "--traj-tol", "1e-2"], "unrecognized arguments: --traj-tol"),
    ],
)
def test_out_of_range_numbers_are_refused_at_parse_time(argv, message, tmp_path, capsys):
    with pytest.raises(SystemExit) as info:
        main([*argv, "--out", str(tmp_path / "run")])
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err
    assert not (tmp_path / "run").exists()
