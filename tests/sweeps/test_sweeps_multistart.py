"""The one multistart tally and result base of the sweep engine, on both optimisers' kinds."""

from __future__ import annotations

from youbot_opt.sweeps.multistart import StartTally, tally_starts


def test_tally_counts_in_one_pass_with_the_optimisers_own_figure() -> None:
    outcomes = [("max_iter", False), ("solved", True), ("error", False), ("solved", True)]
    tally = tally_starts(iter(outcomes), found=3)  # an iterator: read once
    assert tally == StartTally(
        n_starts=4, n_converged=2, status_counts={"max_iter": 1, "solved": 2, "error": 1}, found=3
    )
    assert list(tally.status_counts) == ["max_iter", "solved", "error"]  # first appearance
    by_status = tally_starts(outcomes, found=("optima",), by_status=True)
    assert list(by_status.status_counts) == ["error", "max_iter", "solved"]
    assert by_status.found == ("optima",)


def test_tally_of_no_start() -> None:
    tally = tally_starts([], found=None)
    assert (tally.n_starts, tally.n_converged, dict(tally.status_counts)) == (0, 0, {})
