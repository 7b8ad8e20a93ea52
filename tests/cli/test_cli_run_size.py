"""Size limits of command lines (issue 16, item 1): refused before anything is built, exit 2.

The memory estimates are products of the sizes and the per-unit constants of
:mod:`youbot_opt.cli.run_size`; the expected verdicts below are those products
worked by hand against a memory limit set through ``YOUBOT_OPT_MEMORY_LIMIT_GB``.
"""

from __future__ import annotations

import pytest

from youbot_opt.cli import main
from youbot_opt.cli.run_size import BYTES_PER_KNOT_JOINT, check_ikpath_size, check_trajopt_size
from youbot_opt.exceptions import ParameterError


@pytest.fixture(autouse=True)
def one_gib(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("YOUBOT_OPT_MEMORY_LIMIT_GB", "1")
    monkeypatch.delenv("YOUBOT_OPT_MAX_IK_LINKS", raising=False)


def test_trajopt_estimate_against_the_limit() -> None:
    """5,000 knots x 3 joints x 64 KiB = 0.92 GiB passes 1 GiB; 5,500 knots (1.01 GiB) fail."""
    assert 5000 * 3 * BYTES_PER_KNOT_JOINT < 2**30 < 5500 * 3 * BYTES_PER_KNOT_JOINT
    check_trajopt_size(n_knots=5000, nq=3)
    with pytest.raises(
        ParameterError, match=r"--knots 5,500 with 3 joints would need about 1\.0 GiB"
    ):
        check_trajopt_size(n_knots=5500, nq=3)
    with pytest.raises(ParameterError, match="--max-knots 6,000"):
        check_trajopt_size(n_knots=50, nq=3, max_knots=6000)
    with pytest.raises(ParameterError, match="--starts 1,000,000 of 50 knots"):
        check_trajopt_size(n_knots=50, nq=3, n_starts=10**6)  # 1e6 x (4096 + 8 x 50 x 11) B


def test_ikpath_links_and_starts() -> None:
    check_ikpath_size(n_starts=1000, n_links=100, n_targets=5)
    with pytest.raises(ParameterError, match="YOUBOT_OPT_MAX_IK_LINKS"):
        check_ikpath_size(n_starts=1, n_links=101, n_targets=5)
    with pytest.raises(ParameterError, match="--starts 1,000,000,000 would need about"):
        check_ikpath_size(n_starts=10**9, n_links=3, n_targets=5)


def test_memory_limit_variable_is_checked(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("YOUBOT_OPT_MEMORY_LIMIT_GB", "lots")
    with pytest.raises(ParameterError, match="YOUBOT_OPT_MEMORY_LIMIT_GB='lots'"):
        check_trajopt_size(n_knots=50, nq=3)


@pytest.mark.parametrize(
    ("argv", "fragment"),
    [
        (["solve", "--knots", "10000000"], "--knots 10,000,000 with 3 joints would need about"),
        (["solve", "--starts", "1000000000"], "--starts 1,000,000,000 of 50 knots would need"),
        (["multistart", "--knots", "10000000"], "--knots 10,000,000 with 3 joints"),
        (["ikpath", "--example", "A", "--starts", "1000000000"], "--starts 1,000,000,000 would"),
        (["ikpath", "--lengths", *["0.1"] * 10_000, "--target", "0", "1"], "10,000 links"),
        (["pareto", "--betas", "0:1:1e-12"], "gives 1,000,000,000,001 values, more than"),
        (["bounds", "--scales", "0.5:1:1e-13"], "YOUBOT_OPT_MAX_SWEEP_VALUES"),
    ],
)
def test_absurd_sizes_exit_2_with_one_line(
    argv: list[str], fragment: str, capsys: pytest.CaptureFixture[str]
) -> None:
    """The issue's command lines: one error line naming the size and the limit, exit 2."""
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("youbot-opt: error: ")
    assert fragment in err[0]


def test_memory_error_is_a_last_resort_line(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """A MemoryError or RecursionError no limit foresaw: one line and exit 2, no traceback."""
    import youbot_opt.cli.report as report

    for error in (MemoryError, RecursionError):

        def boom(args: object, error: type[BaseException] = error) -> int:
            raise error()

        monkeypatch.setattr(report, "run", boom)
        assert main(["report"]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "out of" in err[0]
