"""Reachability verdicts against exact geometry and a dense joint-grid oracle."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from youbot_opt.exceptions import ParameterError, UnreachableTarget
from youbot_opt.ikpath.examples import example_problem
from youbot_opt.ikpath.geometry import two_link_nearest
from youbot_opt.ikpath.problem import CyclicIKProblem
from youbot_opt.ikpath.reachability import Reachability
from youbot_opt.ikpath.reachability.planar import (
    check_reachability,
    decide_reachability,
    require_reachable,
)
from youbot_opt.robot.planar import PlanarChain

HALF_PI = math.pi / 2


def _fk(chain, q):
    """Independent numpy FK, q of shape (..., n)."""
    phi = np.cumsum(np.asarray(q) + chain.angle_offset, axis=-1)
    return chain.base + np.stack(
        [np.sum(chain.lengths * np.cos(phi), -1), np.sum(chain.lengths * np.sin(phi), -1)], -1
    )


def test_study_failure_case_is_rejected():
    """An arm of length 7 cannot reach (0, 7.1), with or without limits (distance 0.1)."""
    for lim in (None, HALF_PI):
        chain = PlanarChain(lengths=[3, 2, 2], q_lower=None if lim is None else -lim, q_upper=lim)
        v = decide_reachability(chain, (0.0, 7.1))
        assert v.status is Reachability.UNREACHABLE
        # the annulus gives the exact distance 0.1; the certified bound must not exceed it
        assert v.distance_lower == pytest.approx(0.1, abs=1e-12)
        np.testing.assert_allclose(v.nearest, [0.0, 7.0], atol=1e-12)


def test_boundary_target_reachable_only_at_a_limit():
    """(0, 7) under |theta| <= pi/2 is reachable, only by theta = (pi/2, 0, 0) on the limit."""
    chain = PlanarChain(lengths=[3, 2, 2], q_lower=-HALF_PI, q_upper=HALF_PI)
    v = decide_reachability(chain, (0.0, 7.0))
    assert v.status is Reachability.REACHABLE
    np.testing.assert_allclose(v.witness, [HALF_PI, 0.0, 0.0], atol=1e-9)
    assert np.all(np.abs(v.witness) <= HALF_PI)
    assert np.linalg.norm(_fk(chain, v.witness) - [0.0, 7.0]) <= 1e-9
    assert v.witness_error <= 1e-9


def test_annulus_hole_without_limits():
    """A dominant first link leaves a hole of radius l1 - l2 - l3 = 2: exact verdicts around it."""
    chain = PlanarChain(lengths=[5.0, 1.5, 1.5])
    assert decide_reachability(chain, (1.9, 0.0)).status is Reachability.UNREACHABLE
    assert decide_reachability(chain, (1.9, 0.0)).distance_lower == pytest.approx(0.1, abs=1e-12)
    for p in [(0.0, 2.0), (-2.0000001, 0.0), (5.0, 5.0)]:
        v = decide_reachability(chain, p)
        assert v.reachable
        assert np.linalg.norm(_fk(chain, v.witness) - p) <= 1e-9


def test_example_targets_are_reachable():
    """All targets of the study's examples A and B are reachable, each with a verified witness."""
    for name in "AB":
        prob = example_problem(name)
        for v in check_reachability(prob):
            assert v.reachable
            assert np.all(v.witness >= prob.chain.q_lower) and np.all(
                v.witness <= prob.chain.q_upper
            )
            assert np.linalg.norm(_fk(prob.chain, v.witness) - v.target) <= 1e-9


CHAINS = {
    "study": PlanarChain(lengths=[3, 2, 2], q_lower=-HALF_PI, q_upper=HALF_PI),
    "youbot_like": PlanarChain(
        lengths=[0.155, 0.135, 0.2175],
        q_lower=np.deg2rad([-65, -151, -102.5]),
        q_upper=np.deg2rad([90, 146, 102.5]),
        base=[0.184, 0.147],
        angle_offset=[HALF_PI, 0, 0],
    ),
}


@pytest.mark.parametrize("name", sorted(CHAINS))
def test_verdicts_are_sound_against_a_joint_grid(name):
    """Certified lower bounds never exceed the distance to any grid configuration's tip.

    The oracle is the numpy FK of a 61^3 grid over the joint box: every grid tip is a
    reachable point, so dist(p, grid) >= dist(p, W) >= distance_lower must hold
    (1e-12 for rounding). Reachable verdicts are checked by numpy FK (1e-9), and the
    nearest point found is within the documented refinement gap of the grid's.
    """
    chain = CHAINS[name]
    axes = [np.linspace(lo, hi, 61) for lo, hi in zip(chain.q_lower, chain.q_upper, strict=True)]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    tips = _fk(chain, grid)
    rng = np.random.default_rng(7)
    scale = float(np.sum(chain.lengths))
    inside = _fk(chain, rng.uniform(chain.q_lower, chain.q_upper, (8, 3)))
    targets = np.vstack([rng.uniform(-1.1 * scale, 1.1 * scale, (24, 2)) + chain.base, inside])
    counts = {Reachability.REACHABLE: 0, Reachability.UNREACHABLE: 0}
    for k, p in enumerate(targets):
        v = decide_reachability(chain, p)
        d_grid = float(np.min(np.linalg.norm(tips - p, axis=1)))
        assert v.distance_lower <= d_grid + 1e-12
        assert np.all(v.nearest_q >= chain.q_lower) and np.all(v.nearest_q <= chain.q_upper)
        np.testing.assert_allclose(_fk(chain, v.nearest_q), v.nearest, atol=1e-12)
        if v.reachable:
            assert np.linalg.norm(_fk(chain, v.witness) - p) <= 1e-9
        else:
            assert v.status is Reachability.UNREACHABLE
            assert v.distance_lower > 1e-9
            assert v.distance_upper <= d_grid + max(1e-6, 1e-3 * d_grid) + 1e-12
        if k >= 24:  # tips of in-limit configurations must be found reachable
            assert v.reachable
        counts[v.status] += 1
    assert counts[Reachability.REACHABLE] >= 8 and counts[Reachability.UNREACHABLE] >= 3


@settings(max_examples=60, deadline=None)
@given(
    la=st.floats(0.2, 2.0),
    lb=st.floats(0.2, 2.0),
    a_lo=st.floats(-3.0, 3.0),
    a_w=st.floats(0.1, 6.0),
    b_lo=st.floats(-3.0, 3.0),
    b_w=st.floats(0.1, 6.0),
    px=st.floats(-4.5, 4.5),
    py=st.floats(-4.5, 4.5),
)
def test_two_link_distance_is_exact(la, lb, a_lo, a_w, b_lo, b_w, px, py):
    """The closed-form 2-link distance brackets a 301^2 grid's: exact <= grid <= exact + cover."""
    near = two_link_nearest(px, py, 0.0, 0.0, 0.0, la, lb, (a_lo, a_w), (b_lo, b_w))
    a = np.linspace(a_lo, a_lo + a_w, 301)[:, None]
    b = np.linspace(b_lo, b_lo + b_w, 301)[None, :]
    tx = la * np.cos(a) + lb * np.cos(a + b)
    ty = la * np.sin(a) + lb * np.sin(a + b)
    d_grid = float(np.min(np.hypot(tx - px, ty - py)))
    cover = (la + lb) * a_w / 600 + lb * b_w / 600  # any point is this close to a grid node
    assert near.distance <= d_grid + 1e-12
    assert d_grid <= near.distance + cover + 1e-12
    tip = (
        la * np.cos(near.alpha) + lb * np.cos(near.alpha + near.beta),
        la * np.sin(near.alpha) + lb * np.sin(near.alpha + near.beta),
    )
    assert math.hypot(tip[0] - px, tip[1] - py) == pytest.approx(near.distance, abs=1e-12)


def test_one_and_two_link_chains_use_closed_form():
    """Short limited chains are decided in closed form: arc of a 1-link arm, 2-link edges."""
    one = PlanarChain(lengths=[2.0], q_lower=0.0, q_upper=HALF_PI)
    assert decide_reachability(one, (0.0, 2.0)).reachable
    v = decide_reachability(one, (-2.0, 0.0))
    assert v.method == "closed_form" and v.distance_lower == pytest.approx(
        2 * math.sqrt(2), abs=1e-12
    )
    two = PlanarChain(lengths=[1.0, 1.0], q_lower=[-0.1, 0.0], q_upper=[0.1, 0.5])
    assert decide_reachability(two, (2.0, 0.0)).reachable
    assert not decide_reachability(two, (0.0, 2.0)).reachable


def test_long_chain_budget_gives_undecided_interval():
    """A 7-link chain with a tiny budget reports UNDECIDED with a certified interval."""
    chain = PlanarChain(lengths=[1.0] * 7, q_lower=-math.pi / 3, q_upper=math.pi / 3)
    v = decide_reachability(chain, (-2.0, 1.0), max_evaluations=10)
    assert v.status is Reachability.UNDECIDED
    assert 0.0 <= v.distance_lower <= v.distance_upper
    assert "undecided" in v.describe()
    full = decide_reachability(chain, (-2.0, 1.0))
    assert full.reachable and full.witness_error <= 1e-9


def test_require_reachable_names_target_reach_and_nearest():
    """UnreachableTarget names the target, the reach limits and the nearest point."""
    prob = CyclicIKProblem(
        robot=PlanarChain(lengths=[3, 2, 2], q_lower=-HALF_PI, q_upper=HALF_PI),
        targets=[(3.0, 2.0), (0.0, 7.1), (0.0, 7.0)],
    )
    with pytest.raises(UnreachableTarget) as info:
        require_reachable(prob)
    err = info.value
    assert err.index == 1
    msg = str(err)
    assert "(0, 7.1)" in msg and "|p - base| <= 7" in msg and "nearest reachable point" in msg
    assert err.verdict.status is Reachability.UNREACHABLE


def test_bad_target_raises():
    """A target that is not a finite 2-vector is a ParameterError."""
    with pytest.raises(ParameterError, match="finite 2-vector"):
        decide_reachability(PlanarChain(lengths=[1.0, 1.0]), (1.0, 2.0, 3.0))
    with pytest.raises(ParameterError, match="finite 2-vector"):
        decide_reachability(PlanarChain(lengths=[1.0, 1.0]), (np.nan, 0.0))


def test_corner_evaluation_is_exhaustive_for_box_corners():
    """Every root-box corner tip of a limited 3-link chain is found reachable (1e-9)."""
    chain = CHAINS["study"]
    for corner in itertools.product(*zip(chain.q_lower, chain.q_upper, strict=True)):
        p = _fk(chain, np.array(corner))
        assert decide_reachability(chain, p).reachable
