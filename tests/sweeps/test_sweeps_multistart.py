"""The one multistart tally and result base of the sweep engine, on both optimisers' kinds."""

from __future__ import annotations

import enum
from collections.abc import Sequence
from dataclasses import dataclass

import pytest

from youbot_opt.sweeps.multistart import (
    ConvergedStarts,
    LazyStarts,
    LocalOptimum,
    Multistart,
    OptimumMembers,
    StartTally,
    tally_starts,
)


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


@dataclass(frozen=True)
class _Figures:
    """A start kind with a string status (as trajopt's ``StartOutcome``)."""

    index: int
    objective: float
    success: bool
    status: str


class _Status(enum.Enum):
    SOLVED = "solved"
    MAX_ITER = "max_iter"


@dataclass(frozen=True, eq=False)
class _Path:
    """A start kind with an enum status and a computed success (as ``IKPathResult``)."""

    objective: float
    status: _Status

    @property
    def success(self) -> bool:
        return self.status is _Status.SOLVED


@dataclass(frozen=True, slots=True, kw_only=True)
class _SortedResult(Multistart[_Figures, int]):
    starts: Sequence[_Figures]
    tally: StartTally[int] | None = None

    statuses_sorted = True

    def _starts(self) -> Sequence[_Figures]:
        return self.starts

    @staticmethod
    def _status(start: _Figures) -> str:
        return start.status


@dataclass(frozen=True, slots=True, kw_only=True, eq=False)
class _PathResult(Multistart[_Path, int]):
    results: Sequence[_Path]
    tally: StartTally[int] | None = None

    def _starts(self) -> Sequence[_Path]:
        return self.results

    @staticmethod
    def _status(start: _Path) -> str:
        return start.status.value


def _figures() -> tuple[_Figures, ...]:
    return (
        _Figures(0, 3.0, True, "solved"),
        _Figures(1, 9.0, False, "max_iter"),
        _Figures(2, 1.0, True, "solved"),
        _Figures(3, 2.0, False, "error"),
    )


def _paths() -> tuple[_Path, ...]:
    return (_Path(4.0, _Status.MAX_ITER), _Path(2.0, _Status.SOLVED), _Path(2.5, _Status.SOLVED))


def test_multistart_answers_from_its_starts_on_both_start_kinds() -> None:
    ms = _SortedResult(starts=_figures())
    assert (ms.n_starts, ms.n_converged, ms.success_rate) == (4, 2, 0.5)
    assert [s.index for s in ms.converged] == [0, 2]
    assert list(ms.status_counts().items()) == [("error", 1), ("max_iter", 1), ("solved", 2)]
    paths = _paths()
    ik = _PathResult(results=paths)
    assert (ik.n_starts, ik.n_converged, ik.success_rate) == (3, 2, 2 / 3)
    assert ik.converged == paths[1:]
    assert list(ik.status_counts().items()) == [("max_iter", 1), ("solved", 2)]  # as met
    assert _PathResult(results=()).success_rate == 0.0


def test_multistart_with_a_tally_reads_no_start_to_count() -> None:
    """A lean result answers from its tally; ``converged`` reads the starts only when iterated."""
    reads: list[int] = []
    figures = _figures()

    def read(j: int) -> _Figures:
        reads.append(j)
        return figures[j]

    starts = LazyStarts(len(figures), read)
    tally = tally_starts(((f.status, f.success) for f in figures), found=2, by_status=True)
    ms = _SortedResult(starts=starts, tally=tally)
    assert (ms.n_starts, ms.n_converged, ms.success_rate) == (4, 2, 0.5)
    assert ms.status_counts() == _SortedResult(starts=figures).status_counts()
    converged = ms.converged
    assert isinstance(converged, ConvergedStarts) and len(converged) == 2 and reads == []
    assert converged == (figures[0], figures[2]) and converged[1] is figures[2]
    assert "2 converged start(s)" in repr(converged)
    with pytest.raises(IndexError, match="converged start"):
        converged[2]


def test_lazy_starts_equal_a_tuple_and_slice_to_tuples() -> None:
    figures = _figures()
    starts = LazyStarts(len(figures), figures.__getitem__)
    assert starts == figures and starts[-1] is figures[-1] and starts[1:3] == figures[1:3]
    assert isinstance(starts[::2], tuple)
    with pytest.raises(IndexError, match="4 start"):
        starts[4]


def test_local_optimum_on_both_start_kinds() -> None:
    figures = _figures()
    best, other = figures[2], figures[0]
    opt = LocalOptimum(members=(best, other), n_starts=4)
    assert (opt.best, opt.objective, opt.count, opt.fraction) == (best, 1.0, 2, 0.5)
    assert opt.objective_spread == 2.0
    assert opt.summary() == {
        "objective": 1.0,
        "count": 2,
        "fraction": 0.5,
        "objective_spread": 2.0,
    }
    paths = _paths()
    minimum = LocalOptimum(members=(paths[1],), n_starts=0)
    assert minimum.best is paths[1] and minimum.objective_spread == 0.0
    assert minimum.fraction == 1.0  # no start count: over at least one


def test_optimum_members_are_read_by_key_when_asked_for() -> None:
    figures = {f"start_{f.index:04d}": f for f in _figures()}
    reads: list[str] = []

    def read(key: str) -> _Figures:
        reads.append(key)
        return figures[key]

    members = OptimumMembers(["start_0002", "start_0000"], read)
    opt = LocalOptimum(members=members, n_starts=4)
    assert opt.count == 2 and reads == []
    assert opt.best.index == 2 and reads == ["start_0002"]
    assert [m.index for m in members] == [2, 0] and members == (
        figures["start_0002"],
        figures["start_0000"],
    )
    assert members[::-1] == (figures["start_0000"], figures["start_0002"])
    assert "2 member start(s)" in repr(members)


def test_both_optimisers_specialise_the_one_result_and_optimum() -> None:
    from youbot_opt.ikpath import multistart as ik
    from youbot_opt.trajopt import multistart as traj

    for module in (ik, traj):
        assert issubclass(module.MultistartResult, Multistart)
    assert issubclass(ik.IKPathOptimum, LocalOptimum)
    assert issubclass(traj.TrajOptOptimum, LocalOptimum)
    assert issubclass(traj.StoredStarts, LazyStarts)
