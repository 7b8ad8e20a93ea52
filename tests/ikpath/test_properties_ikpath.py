"""Property tests of the IK-path API: an honest status, or a documented error.

Hypothesis draws planar chains (1-4 links, with and without joint limits),
reachable targets (tip positions of random configurations) and arbitrary ones,
both methods and small iteration caps. Every call must raise a documented
error (:class:`UnreachableTarget`; :class:`ParameterError` when IPOPT is asked
to solve a 1-link chain) or return a result
whose success is confirmed by :func:`~youbot_opt.ikpath.check.check_ik_result`
(closed-form kinematics, not Pinocchio or CasADi). Invalid inputs (lengths,
limits, targets, NaN/inf, shapes, options, starts) raise ParameterError.
Runs are derandomized and database-free.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from youbot_opt.exceptions import ParameterError, SolveFailed, UnreachableTarget
from youbot_opt.ikpath import ALOptions, CyclicIKProblem, IpoptOptions, PlanarChain, solve
from youbot_opt.ikpath.check import check_ik_result

PROPERTY = settings(
    deadline=None,
    derandomize=True,
    database=None,
    suppress_health_check=[HealthCheck.too_slow],
)
_SPECIAL = st.sampled_from([math.nan, math.inf, -math.inf])


def _residual_tol(method: str, options: Any) -> float:
    """Largest residual [m] a success may have: the solver's |c_i| tolerance on a 2-vector.

    Both methods stop on the inf-norm of c (AL: constraint_tol; IPOPT:
    constr_viol_tol), so the Euclidean residual is at most sqrt(2) times it;
    1e-12 m is added for the rounding between Pinocchio and the closed form.
    """
    if method == "al":
        tol = (options or ALOptions()).constraint_tol
    else:
        tol = (options or IpoptOptions.for_ikpath()).constr_viol_tol
    return math.sqrt(2.0) * tol + 1e-12


@st.composite
def _problems(draw: st.DrawFn) -> tuple[CyclicIKProblem, bool]:
    """(problem, all targets are tip positions of configurations within the limits)."""
    n = draw(st.integers(1, 4))
    lengths = draw(st.lists(st.floats(0.2, 2.0), min_size=n, max_size=n))
    limited = draw(st.booleans())
    lower = upper = None
    if limited:
        lower = draw(st.lists(st.floats(-math.pi, 0.0), min_size=n, max_size=n))
        upper = draw(st.lists(st.floats(0.05, math.pi), min_size=n, max_size=n))
    chain = PlanarChain(lengths=lengths, q_lower=lower, q_upper=upper)
    s = draw(st.integers(2, 4))
    reachable = draw(st.booleans())
    if reachable:
        lo = np.full(n, -math.pi) if lower is None else np.array(lower)
        hi = np.full(n, math.pi) if upper is None else np.array(upper)
        fractions = draw(st.lists(st.floats(0.0, 1.0), min_size=n * s, max_size=n * s))
        q = lo + (hi - lo) * np.array(fractions).reshape(s, n)
        targets = [chain.tip_position(qj) for qj in q]
    else:
        reach = float(np.sum(lengths))
        coords = st.floats(-1.5 * reach, 1.5 * reach)
        targets = draw(st.lists(st.tuples(coords, coords), min_size=s, max_size=s))
    return CyclicIKProblem(robot=chain, targets=targets), reachable


_AL = st.builds(
    ALOptions,
    max_outer_iterations=st.sampled_from([1, 3, 100]),
    max_inner_iterations=st.sampled_from([2, 50, 1000]),
)
_IPOPT = st.builds(IpoptOptions.for_ikpath, max_iter=st.sampled_from([1, 5, 3000]))


@settings(PROPERTY, max_examples=40)
@given(problem=_problems(), method=st.sampled_from(["al", "ipopt"]), data=st.data())
def test_ik_status_matches_independent_check_or_documented_error(problem, method, data) -> None:
    """Valid problems: UnreachableTarget, or a result whose success check_ik_result confirms."""
    prob, reachable = problem
    options = data.draw(st.one_of(st.none(), _AL if method == "al" else _IPOPT), label="options")
    try:
        result = solve(prob, method=method, options=options)
    except UnreachableTarget as exc:
        assert not reachable, f"reachable targets reported unreachable: {exc}"
        assert 0 <= exc.index < prob.n_targets and str(exc)
        event("raised UnreachableTarget")
        return
    except ParameterError as exc:
        # Documented: IPOPT refuses chains with fewer than 2 free joints (1 link here).
        assert method == "ipopt" and prob.n_joints == 1, exc
        assert "method='al'" in str(exc)
        event("ipopt refused a 1-link chain")
        return
    event(f"{method}: {result.status.value} ({'reachable' if reachable else 'arbitrary'} targets)")
    assert np.all(np.isfinite(result.configurations)), "the best iterate is finite"
    check = check_ik_result(result, residual_tol=_residual_tol(method, options))
    if result.success:
        assert check.passed, (result.message, check)
    else:
        assert result.message
        with pytest.raises(SolveFailed) as info:
            result.raise_for_status()
        assert info.value.result is result
        # Even a failed result reports the figures of its own configurations.
        relaxed = check_ik_result(result, residual_tol=math.inf, limit_tol=1e-12)
        assert relaxed.passed, relaxed


_BAD_CHAIN: dict[str, st.SearchStrategy[Any]] = {
    "lengths": st.one_of(
        st.lists(st.floats(-2.0, 0.0), min_size=1, max_size=3),
        st.tuples(st.floats(0.5, 1.0), _SPECIAL).map(list),
        st.just([]),
        st.just([[1.0, 1.0]]),
    ),
    "q_lower": st.one_of(st.just([0.5, 0.5]), st.tuples(st.just(math.nan), st.just(0.0))),
    "base": st.one_of(st.tuples(_SPECIAL, st.just(0.0)), st.just([0.0, 0.0, 0.0])),
}
_BAD_PROBLEM: dict[str, st.SearchStrategy[Any]] = {
    "targets": st.one_of(
        st.just([(1.0, 0.5)]),
        st.just([(1.0, 0.5, 0.3), (0.5, 1.0, 0.0)]),  # off the plane (3-D in it is valid)
        st.tuples(st.tuples(_SPECIAL, st.just(0.5)), st.just((0.5, 1.0))).map(list),
    ),
    "method": st.sampled_from(["bfgs", "", "IPOPT"]),
    "options": st.sampled_from(["ipopt-options-for-al", "al-options-for-ipopt"]),
    "x0": st.one_of(
        st.just([0.0, 0.0, 0.0]),
        st.just([math.nan, 0.0, 0.0, 0.0]),
        st.just([5.0, 0.0, 0.0, 0.0]),
    ),
}


@settings(PROPERTY, max_examples=40)
@given(field=st.sampled_from(sorted({**_BAD_CHAIN, **_BAD_PROBLEM})), data=st.data())
def test_one_invalid_ik_input_raises_parameter_error(field, data) -> None:
    """One invalid input (length, limit, base, target, method, options, start): ParameterError."""
    value = data.draw({**_BAD_CHAIN, **_BAD_PROBLEM}[field], label=field)
    chain_args: dict[str, Any] = dict(lengths=[1.0, 1.0], q_lower=-2.0, q_upper=[0.2, 2.0])
    call: dict[str, Any] = dict(method="al", options=None, x0=None)
    targets: Any = [(1.0, 0.5), (0.5, 1.0)]
    if field in _BAD_CHAIN:
        chain_args[field] = value
    elif field == "targets":
        targets = value
    elif field == "options":
        call["method"] = "al" if value == "ipopt-options-for-al" else "ipopt"
        call["options"] = IpoptOptions.for_ikpath() if call["method"] == "al" else ALOptions()
    else:
        call[field] = value
    with pytest.raises(ParameterError) as info:
        solve(CyclicIKProblem(robot=PlanarChain(**chain_args), targets=targets), **call)
    assert str(info.value)


@pytest.fixture(scope="module")
def solved_ik():
    """The study's example solved by both methods."""
    chain = PlanarChain(lengths=[3, 2, 2], q_lower=-1.5708, q_upper=1.5708)
    problem = CyclicIKProblem(robot=chain, targets=[(-1, 5), (-3, 3), (-3, -4), (0, 5), (3, 2)])
    return {m: solve(problem, method=m).raise_for_status() for m in ("al", "ipopt")}


@settings(PROPERTY, max_examples=40)
@given(
    method=st.sampled_from(["al", "ipopt"]),
    row=st.integers(0, 4),
    joint=st.integers(0, 2),
    corruption=st.one_of(_SPECIAL, st.floats(1e-6, 1.0), st.floats(-1.0, -1e-6)),
)
def test_corrupted_ik_result_fails_the_check(solved_ik, method, row, joint, corruption) -> None:
    """NaN/inf or a moved joint angle (> 1e-6 rad) in a solved path fails check_ik_result."""
    good = solved_ik[method]
    assert check_ik_result(good).passed
    q = np.array(good.configurations)
    q[row, joint] = corruption if not math.isfinite(corruption) else q[row, joint] + corruption
    check = check_ik_result(dataclasses.replace(good, configurations=q))
    assert not check.passed and check.message


def test_ipopt_acceptable_level_with_large_residual_is_not_a_success(solved_ik) -> None:
    """IPOPT stopping at its 'acceptable' level with targets missed by metres is no success."""
    problem = solved_ik["ipopt"].problem
    loose = {"acceptable_iter": 1, "acceptable_constr_viol_tol": 1e20}
    loose |= {"acceptable_tol": 1e20, "acceptable_dual_inf_tol": 1e20}
    loose |= {"acceptable_compl_inf_tol": 1e20}
    result = solve(problem, method="ipopt", options=IpoptOptions.for_ikpath(extra=loose))
    assert result.message == "Solved_To_Acceptable_Level"
    assert not check_ik_result(result).passed  # the targets are missed (9.3 m measured)
    assert not result.success


def test_one_link_chain_is_solved_or_fails_with_a_status() -> None:
    """A 1-link chain with reachable targets: the AL method returns a result, no ValueError."""
    chain = PlanarChain(lengths=[1.0])
    problem = CyclicIKProblem(robot=chain, targets=[(1.0, 0.0), (0.0, 1.0)])
    result = solve(problem, method="al")
    # Each target fixes the single angle: q = 0 and q = pi/2, E = (pi/2)^2.
    assert result.success
    np.testing.assert_allclose(result.objective, (math.pi / 2) ** 2, rtol=1e-8)
