"""``youbot-opt ikpath``: JSON output, exit codes, plots."""

from __future__ import annotations

import json

import numpy as np
import pytest

from youbot_opt.cli import main


def _json(capsys, argv):
    code = main(argv)
    out = capsys.readouterr()
    return code, json.loads(out.out), out.err


def test_example_b_json(capsys):
    """Example B from the zero start: success, E = 15.6058914, limits met, all targets reachable."""
    code, doc, _ = _json(capsys, ["ikpath", "--example", "B", "--json", "--no-progress"])
    assert code == 0
    assert doc["status"] == "success"
    assert doc["E"] == pytest.approx(15.6058914, abs=1e-6)
    q = np.array(doc["configurations"])
    assert q.shape == (5, 3) and np.all(np.abs(q) <= np.pi / 2)
    assert doc["max_residual"] < 1e-9
    assert [v["verdict"] for v in doc["reachability"]] == ["reachable"] * 5


def test_unreachable_target_exits_2_with_verdict(capsys):
    """The study's (0, 7.1) for l = (3, 2, 2) stops the command with status 2 and the verdict."""
    argv = [
        "ikpath",
        "--lengths",
        "3",
        "2",
        "2",
        "--limit",
        "1.5707963267948966",
        "--target",
        "0",
        "7.1",
        "--target",
        "0",
        "7",
        "--json",
    ]
    code, doc, err = _json(capsys, argv)
    assert code == 2
    assert doc["status"] == "unreachable"
    assert [v["verdict"] for v in doc["reachability"]] == ["unreachable", "reachable"]
    np.testing.assert_allclose(doc["reachability"][1]["witness"], [np.pi / 2, 0, 0], atol=1e-9)
    assert "unreachable" in err and "(0, 7.1)" in err


@pytest.mark.parametrize(
    ("argv", "match"),
    [
        (["--lengths", "3", "-2", "2", "--target", "1", "1", "--target", "2", "2"], "lengths"),
        (["--lengths", "3", "2", "--target", "1", "1"], "at least 2 targets"),
        (
            [
                "--lengths",
                "3",
                "2",
                "--lower",
                "1",
                "--upper",
                "0",
                "--target",
                "1",
                "1",
                "--target",
                "2",
                "2",
            ],
            "q_lower",
        ),
        (["--target", "1", "1", "--target", "2", "2"], "--lengths"),
    ],
)
def test_bad_input_exits_2(capsys, argv, match):
    """Bad lengths, one target, crossed limits, missing arm: exit 2 naming the problem."""
    assert main(["ikpath", *argv]) == 2
    assert match in capsys.readouterr().err


def test_text_summary_and_plots(capsys, tmp_path):
    """The text summary names the best E and the study's value; --out writes PNG files."""
    code = main(
        [
            "ikpath",
            "--example",
            "A",
            "--starts",
            "2",
            "--workers",
            "1",
            "--out",
            str(tmp_path),
            "--no-progress",
        ]
    )
    text = capsys.readouterr().out
    assert code == 0
    assert "best: E = 0.8405135867" in text and "study reported E = 0.905" in text
    pngs = sorted(p.name for p in tmp_path.glob("*.png"))
    assert pngs == [
        "ikpath_arm.png",
        "ikpath_convergence.png",
        "ikpath_minima.png",
        "ikpath_workspace.png",
    ]
    assert all((tmp_path / p).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" for p in pngs)
