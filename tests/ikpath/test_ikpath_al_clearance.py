"""The augmented Lagrangian with clearance rows (#28 item 4, IK half): ur5 and one box.

The ur5 visits (0.4, 0.2, 0.3) and (0.3, -0.3, 0.4) m (the targets of
tests/cli/test_ikpath_clearance_cli.py); a 0.1 m box at (0.3, -0.05, -0.15) m
lies under the forearm's sweep, so with a 0.01 m margin two leg rows
(forearm / box) are active at the solution. IPOPT, with the rows as
constraints of its NLP, is the independent reference; coal's certificate
(:func:`certify_path_clearance`) checks the path along the whole closed loop.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from youbot_opt.collision import Box, Obstacle, Scene
from youbot_opt.collision.clearance import Clearance
from youbot_opt.exceptions import ResultFileError
from youbot_opt.ikpath.clearance import IKClearance, certify_path_clearance
from youbot_opt.ikpath.io import (
    SCHEMA,
    SCHEMA_VERSION,
    encode_document,
    load_result,
    save_result,
)
from youbot_opt.ikpath.methods.al import (
    AL_OPTIONS_3D,
    _clearance_term,
    run_augmented_lagrangian,
)
from youbot_opt.ikpath.methods.sqp import final_phase, first_order_multipliers
from youbot_opt.ikpath.problem import CyclicIKProblem
from youbot_opt.ikpath.result import IKPathResult
from youbot_opt.ikpath.solve import solve
from youbot_opt.ikpath.targets import Target
from youbot_opt.robot.load import load_model
from youbot_opt.robot.source import RobotSource

MARGIN = 0.01  # [m]
TARGETS = (Target(position=(0.4, 0.2, 0.3)), Target(position=(0.3, -0.3, 0.4)))
#: Both methods stop at |c| <= 1e-10 m and a projected gradient <= 1e-8 rad; at a
#: KKT point E changes only at second order, so the same minimum gives E within
#: ~1e-9 rad^2 (measured: 1e-11): 1e-8 leaves room for rounding.
E_TOL = 1e-8


@pytest.fixture(scope="module")
def problem(fit_cache: Path) -> Iterator[CyclicIKProblem]:
    """ur5, two targets, one box under the forearm's sweep (ball fits in ``fit_cache``)."""
    box = Obstacle(name="box", shape=Box(size=(0.1, 0.1, 0.1)), xyz=(0.3, -0.05, -0.15))
    clearance = Clearance(scene=Scene((box,)), margin=MARGIN, self_collision=False)
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("YOUBOT_OPT_CACHE", str(fit_cache))
        yield CyclicIKProblem(robot=load_model("ur5"), targets=TARGETS, clearance=clearance)


@pytest.fixture(scope="module")
def q_free(problem: CyclicIKProblem) -> np.ndarray:
    """The free optimum (no clearance; the AL from the zero vector, E = 1.58936 rad^2)."""
    free = solve(dataclasses.replace(problem, clearance=None), method="al")
    assert free.status.name == "SOLVED", free.message
    return free.configurations


@pytest.fixture(scope="module")
def ipopt(problem: CyclicIKProblem, q_free: np.ndarray) -> IKPathResult:
    """IPOPT from the free optimum."""
    return solve(problem, method="ipopt", x0=q_free)


@pytest.fixture(scope="module")
def al(problem: CyclicIKProblem, q_free: np.ndarray) -> IKPathResult:
    """The AL (``AL_OPTIONS_3D``) from the same start."""
    return solve(problem, method="al", x0=q_free)


def _rows(problem: CyclicIKProblem) -> IKClearance:
    assert problem.clearance_rows is not None
    return problem.clearance_rows


def _assert_feasible(problem: CyclicIKProblem, result: IKPathResult) -> None:
    """Solved, targets met, rows at the margin, and coal certifies the closed path."""
    assert result.status.name == "SOLVED", result.message
    x = result.configurations.ravel()
    assert np.all(problem.targets_met(x))
    assert np.max(problem.residuals(x)) < 1e-9
    assert np.min(_rows(problem).rows(x)) >= MARGIN - 1e-10
    certificate = certify_path_clearance(problem, x)
    assert certificate is not None and certificate.certified
    assert certificate.lower_bound >= MARGIN - 1e-3  # coal's, bisected to 1 mm


def test_al_and_ipopt_from_the_same_start_agree(
    problem: CyclicIKProblem, q_free: np.ndarray, ipopt: IKPathResult, al: IKPathResult
) -> None:
    """The free optimum's legs come within the margin (rows): both bend them the same way."""
    assert np.min(_rows(problem).rows(q_free.ravel())) < MARGIN  # the start breaks the rows
    _assert_feasible(problem, ipopt)
    _assert_feasible(problem, al)
    assert al.method == "al" and "clearance rows >= margin" in al.message
    np.testing.assert_array_equal(al.start, ipopt.start)
    assert al.objective == pytest.approx(ipopt.objective, abs=E_TOL)
    assert al.objective > problem.objective(q_free.ravel())  # the clearance costs motion
    al_there = solve(problem, method="al", x0=ipopt.configurations)  # stays at IPOPT's
    _assert_feasible(problem, al_there)
    assert al_there.objective == pytest.approx(ipopt.objective, abs=E_TOL)


def test_clearance_multipliers_are_complementary(
    problem: CyclicIKProblem, q_free: np.ndarray
) -> None:
    """``nu >= 0``, ``nu > 0`` only on active rows, 0 on inactive ones; KKT holds with them."""
    rows = _rows(problem)
    run = run_augmented_lagrangian(problem, q_free.ravel(), AL_OPTIONS_3D)
    assert run.status.name == "SOLVED", run.message
    nu = run.clearance_multipliers
    g = rows.rows(run.x) - MARGIN
    assert nu.shape == g.shape == (len(rows.labels),)
    assert np.all(nu >= 0.0)
    active = np.abs(g) <= AL_OPTIONS_3D.constraint_tol
    assert np.all(nu[~active] == 0.0)  # exactly: max(0, nu - mu g) on an inactive row
    assert np.any(nu[active] > 1e-3)  # the forearm rows hold the path off the box
    assert {rows.labels[i].split(": ")[1] for i in np.flatnonzero(nu)} == {"forearm_link_0 / box"}
    # Stationarity of E - lambda^T c - nu^T g with the dense Jacobian (not the
    # solver's reverse-mode product) and least-squares lambda.
    ev = problem.evaluate(run.x)
    shifted = ev._replace(gradient=ev.gradient - rows.rows_jacobian(run.x).T @ nu)
    residual = first_order_multipliers(shifted, run.x, problem.lower, problem.upper)[1]
    assert residual <= 1e-7


def test_clearance_term_gradient_matches_central_differences(
    problem: CyclicIKProblem, al: IKPathResult
) -> None:
    """The PHR term's gradient, with rows on both sides of ``g = nu / mu``."""
    rows = _rows(problem)
    rng = np.random.default_rng(3)
    x0 = al.configurations.ravel()
    mu = 1e3
    h = 1e-6
    for _ in range(3):
        x = x0 + rng.uniform(-0.05, 0.05, x0.size)
        g = rows.rows(x) - MARGIN
        nu = rng.uniform(0.0, 2.0, g.size) * (rng.uniform(size=g.size) < 0.5)
        nu[np.argsort(g)[:4]] = 50.0  # the closest rows in the quadratic branch
        quadratic = g < nu / mu
        assert 0 < np.count_nonzero(quadratic) < g.size
        value, grad = _clearance_term(rows, x, nu, mu)
        assert grad is not None
        numeric = np.array(
            [
                (
                    _clearance_term(rows, x + h * e, nu, mu)[0]
                    - _clearance_term(rows, x - h * e, nu, mu)[0]
                )
                / (2 * h)
                for e in np.eye(x.size)
            ]
        )
        np.testing.assert_allclose(grad, numeric, rtol=1e-6, atol=1e-7)
        psi = np.where(quadratic, -nu * g + 0.5 * mu * g**2, -(nu**2) / (2 * mu))
        assert value == pytest.approx(float(np.sum(psi)), rel=1e-12, abs=1e-12)
    # Every row inactive and nu = 0: no term, no gradient.
    assert _clearance_term(rows, x0, np.zeros(len(rows.labels)), mu) == (0.0, None)


def test_inactive_clearance_leaves_the_iterates_unchanged(
    problem: CyclicIKProblem, fit_cache: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A box far away: the same iterates, bit for bit, as without clearance."""
    monkeypatch.setenv("YOUBOT_OPT_CACHE", str(fit_cache))
    far = Obstacle(name="far", shape=Box(size=(0.1, 0.1, 0.1)), xyz=(5.0, 5.0, 5.0))
    cleared = dataclasses.replace(
        problem, clearance=Clearance(scene=Scene((far,)), margin=MARGIN, self_collision=False)
    )
    free = dataclasses.replace(problem, clearance=None)
    assert free.clearance_rows is None and cleared.clearance_rows is not None
    opts = dataclasses.replace(AL_OPTIONS_3D, newton_final=False)  # off with a clearance
    start = np.random.default_rng(0).uniform(-1.0, 1.0, free.n_variables)
    a = run_augmented_lagrangian(free, start, opts)
    b = run_augmented_lagrangian(cleared, start, opts)
    assert a.status.name == b.status.name == "SOLVED"
    assert len(a.history) == len(b.history) and a.inner_iterations == b.inner_iterations
    for ha, hb in zip(a.history, b.history, strict=True):
        np.testing.assert_array_equal(ha.x, hb.x)
        assert ha.objective == hb.objective and ha.violation == hb.violation
    np.testing.assert_array_equal(a.x, b.x)
    np.testing.assert_array_equal(a.multipliers, b.multipliers)
    assert not np.any(b.clearance_multipliers)


#: The clearance rows' multipliers [rad^2/m] at a KKT point solve the stationarity
#: condition ``grad E = J_c^T lambda + J_g^T nu``; both methods stop with a projected
#: gradient <= 1e-8 rad, and the active row's gradient has a component 0.070 m/rad
#: normal to the target rows' (the smallest singular value of the active Jacobian:
#: 0.056 m/rad), so each ``nu`` is determined to ~1e-8 / 0.056 = 2e-7 rad^2/m, 3e-6
#: relative on nu = 0.066 (measured 7e-10): 1e-5 relative leaves room for rounding.
NU_RTOL = 1e-5
#: IPOPT leaves an inactive row nu ~ (final barrier mu) / g: measured <= 3.7e-11.
IPOPT_INACTIVE_NU = 1e-10


def test_al_and_ipopt_clearance_multipliers_agree(
    problem: CyclicIKProblem, ipopt: IKPathResult, al: IKPathResult
) -> None:
    """The result's ``clearance_multipliers``: the same active row, the same multiplier each."""
    rows = _rows(problem)
    assert al.clearance_multipliers is not None and ipopt.clearance_multipliers is not None
    nu_al, nu_ip = al.clearance_multipliers, ipopt.clearance_multipliers
    assert nu_al.shape == nu_ip.shape == (len(rows.labels),)
    assert np.all(nu_al >= 0.0) and np.all(nu_ip >= 0.0)
    x = al.configurations.ravel()
    active = np.flatnonzero(np.abs(rows.rows(x) - MARGIN) <= 1e-9)  # at the margin
    inactive = np.setdiff1d(np.arange(nu_al.size), active)
    assert np.all(nu_al[inactive] == 0.0)
    assert np.all(nu_ip[inactive] < IPOPT_INACTIVE_NU)
    # Two targets: leg 1 is leg 0 walked back, whose rows are leg 0's, built once; one
    # forearm/box row is active (it was two equal rows, whose multipliers were determined
    # only as a sum: IPOPT 0.0325 + 0.0337, the AL 0.0662 + 0).
    assert [rows.labels[i] for i in active] == ["leg 0 step 2: forearm_link_0 / box"]
    ev = problem.evaluate(x)
    s, m, n = ev.jacobian_blocks.shape
    normals = np.zeros((s * m + active.size, s * n))  # the target rows', then the active
    for j in range(s):
        normals[j * m : (j + 1) * m, j * n : (j + 1) * n] = ev.jacobian_blocks[j]
    normals[s * m :] = rows.rows_jacobian(x)[active]
    assert np.linalg.svd(normals, compute_uv=False).min() > 1e-2  # nu determined (0.056)
    np.testing.assert_allclose(nu_al[active], nu_ip[active], rtol=NU_RTOL)
    assert np.all(nu_ip[active] > 1e-2)  # the box costs E: dE/d margin > 0


def test_clearance_multipliers_round_trip_and_forged_ones_are_refused(
    problem: CyclicIKProblem, al: IKPathResult, tmp_path: Path
) -> None:
    """Saved and read back; negative, NaN, short or non-complementary lists refused by key."""
    source = RobotSource.of(problem.robot_model)
    path = save_result(al, tmp_path / "al.json", source)
    back = load_result(path)
    assert back.success and back.clearance_multipliers is not None
    assert al.clearance_multipliers is not None
    np.testing.assert_array_equal(back.clearance_multipliers, al.clearance_multipliers)
    doc = json.loads(path.read_text())
    body = doc["result"]
    nu = list(body["clearance_multipliers"])
    inactive = int(np.flatnonzero(np.asarray(nu) == 0.0)[0])

    def forged(name: str, value: object) -> Path:
        out = tmp_path / f"{name}.json"
        out.write_bytes(
            encode_document(SCHEMA, SCHEMA_VERSION, {**body, "clearance_multipliers": value})
        )
        return out

    negative = nu.copy()
    negative[3] = -0.5
    with pytest.raises(ResultFileError, match=r"clearance_multipliers\[3\] = -0.5 .*>= 0"):
        load_result(forged("negative", negative))
    nan = nu.copy()
    nan[5] = None  # JSON has no NaN: a null entry
    with pytest.raises(ResultFileError, match=r"clearance_multipliers\[5\] = nan .*finite"):
        load_result(forged("nan", nan))
    with pytest.raises(ResultFileError, match=r"clearance_multipliers must be a list of numbers"):
        load_result(forged("text", ["0.1"] * len(nu)))
    with pytest.raises(ResultFileError, match=r"clearance_multipliers has 3 entries"):
        load_result(forged("short", nu[:3]))
    loose = nu.copy()
    loose[inactive] = 1.0  # a row far from the margin cannot hold E up
    with pytest.raises(
        ResultFileError, match=rf"clearance_multipliers\[{inactive}\].*complementary"
    ):
        load_result(forged("loose", loose))
    assert load_result(forged("none", None)).clearance_multipliers is None  # an older file


def test_sqp_phase_with_clearance_rows_polishes_the_al(
    problem: CyclicIKProblem, q_free: np.ndarray, ipopt: IKPathResult, al: IKPathResult
) -> None:
    """``newton_final`` with the AL's active rows as equalities: closer to KKT than the AL alone."""
    rows = _rows(problem)
    assert "SQP steps" in al.message and "clearance rows held as equalities" in al.message
    _assert_feasible(problem, al)
    alone = solve(problem, method="al", x0=q_free, options=dataclasses.replace(
        AL_OPTIONS_3D, newton_final=False))  # fmt: skip
    _assert_feasible(problem, alone)
    assert "SQP" not in alone.message

    def kkt(result: IKPathResult) -> float:
        x = result.configurations.ravel()
        assert result.clearance_multipliers is not None
        ev = problem.evaluate(x)
        jtnu = rows.rows_jacobian(x).T @ result.clearance_multipliers
        return first_order_multipliers(
            ev._replace(gradient=ev.gradient - jtnu), x, problem.lower, problem.upper
        )[1]

    assert kkt(al) < kkt(alone)  # measured 4.5e-11 against 6.4e-9 rad
    assert np.max(problem.residuals(al.configurations.ravel())) < 1e-9
    assert al.objective == pytest.approx(ipopt.objective, abs=E_TOL)  # measured 4e-14


def test_the_final_phase_with_rows_needs_their_multipliers(
    problem: CyclicIKProblem, q_free: np.ndarray
) -> None:
    """``final_phase(rows=...)`` without ``nu`` is refused, naming what is missing."""
    lam = np.zeros(problem.n_constraints)
    with pytest.raises(ValueError, match="needs their multipliers nu"):
        final_phase(
            problem, q_free.ravel(), lam, 10.0, AL_OPTIONS_3D, problem.model.createData(), None,
            start_iteration=1, iterations=1, rows=_rows(problem),
        )  # fmt: skip
