"""Numbers past any physical meaning are refused with the limit named, not a traceback (#29).

Before: ``--damping 1e308 --transcription auto`` ended in numpy's LinAlgError,
``--bound-scale 1e308`` in matplotlib's ValueError after a NaN solve, and
``bounds --scales 1e308`` solved with infinite bounds.
"""

from __future__ import annotations

import pytest

from youbot_opt.cli import main


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (
            ["solve", "--damping", "1e308", "--transcription", "auto"],
            "damping must be in [0, MAX_JOINT_DAMPING = 1e+06] N m s/rad, got 1e+308",
        ),
        (
            ["solve", "--bound-scale", "1e308"],
            "bound_scale must be at most MAX_BOUND_SCALE = 1000 (1.0 = data sheet), got 1e+308",
        ),
        (
            ["bounds", "--scales", "1,1e308"],
            "bound_scale must be at most MAX_BOUND_SCALE = 1000 (1.0 = data sheet), got 1e+308",
        ),
    ],
)
def test_huge_physical_numbers_are_refused(argv, message, tmp_path, capsys):
    extra = ["--no-refine"] if argv[0] == "solve" else []
    assert main([*argv, *extra, "--out", str(tmp_path / "run")]) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err
