"""Tests of youbot_opt.sweeps.optima: the one greedy clustering of local optima."""

from __future__ import annotations

import numpy as np
import pytest

from youbot_opt.exceptions import ParameterError
from youbot_opt.sweeps.optima import KeepRule, check_tolerances, cluster_optima


def _cluster(items, obj_tol=1e-6, dist_tol=1e-3):  # type: ignore[no-untyped-def]
    return cluster_optima(
        items,
        objective=lambda p: p[0],
        distance=lambda a, b: abs(a[1] - b[1]),
        obj_tol=obj_tol,
        dist_tol=dist_tol,
    )


def test_items_join_the_first_cluster_within_both_tolerances() -> None:
    """Same objective and close: one cluster; same objective but far: two; lowest first."""
    items = [(2.0, 0.0), (1.0, 5.0), (1.0 + 5e-7, 5.0005), (1.0, 9.0)]
    clusters = _cluster(items)
    assert clusters == [[(1.0, 5.0), (1.0 + 5e-7, 5.0005)], [(1.0, 9.0)], [(2.0, 0.0)]]


def test_objective_tolerance_is_relative_above_one_and_absolute_below() -> None:
    """|f - f_c| <= obj_tol max(1, |f_c|): at f = 1e-3, 1e-6 apart joins; at f = 1e3, 1e-3."""
    assert len(_cluster([(1e-3, 0.0), (1e-3 + 1e-6, 0.0)])) == 1
    assert len(_cluster([(1e-3, 0.0), (1e-3 + 1.1e-6, 0.0)])) == 2
    assert len(_cluster([(1e3, 0.0), (1e3 + 9e-4, 0.0)])) == 1
    assert len(_cluster([(1e3, 0.0), (1e3 + 1.1e-3, 0.0)])) == 2


def test_distance_is_measured_to_the_representative_only() -> None:
    """A chain of close items splits where it leaves dist_tol of the cluster's first member."""
    items = [(1.0, 0.0), (1.0, 0.0008), (1.0, 0.0016)]
    assert _cluster(items) == [[(1.0, 0.0), (1.0, 0.0008)], [(1.0, 0.0016)]]


@pytest.mark.parametrize("bad", [0.0, -1.0, float("nan"), float("inf")])
@pytest.mark.parametrize("name", ["obj_tol", "dist_tol"])
def test_tolerances_not_finite_and_positive_are_refused(name: str, bad: float) -> None:
    """A zero, negative, NaN or infinite tolerance raises ParameterError naming it, also
    when a KeepRule with a distance is made; the best-only rule has no tolerances."""
    with pytest.raises(ParameterError, match=f"{name} must be a finite number > 0") as info:
        _cluster([(1.0, 0.0)], **{name: bad})
    assert info.value.name == name
    assert info.value.value is bad
    tols = {"obj_tol": 1e-6, "dist_tol": 1e-3, name: bad}
    with pytest.raises(ParameterError, match=name):
        KeepRule(objective=lambda p: p[0], distance=lambda a, b: 0.0, **tols)
    assert KeepRule(objective=lambda p: p[0], **tols).distance is None
    with pytest.raises(ParameterError, match=name):
        check_tolerances(**tols)


def test_check_tolerances_returns_floats() -> None:
    """Integers and numpy scalars are taken as floats; a bool is refused."""
    assert check_tolerances(1, np.float32(0.5)) == (1.0, 0.5)
    with pytest.raises(ParameterError, match="obj_tol"):
        check_tolerances(True, 1.0)
