"""Multistart: seeded starts, parallel = serial, failures contained, minima clustered."""

from __future__ import annotations

from concurrent.futures import Future, ThreadPoolExecutor

import numpy as np
import pytest

from test_ikpath_solvers import LA, LB, TARGETS_2, _two_link_optimum
from youbot_opt.exceptions import ParameterError
from youbot_opt.ikpath import multistart as ms_mod
from youbot_opt.ikpath.chain import PlanarChain
from youbot_opt.ikpath.examples import example_problem
from youbot_opt.ikpath.multistart import (
    cluster_minima,
    configuration_distance,
    make_starts,
    run_multistart,
)
from youbot_opt.ikpath.problem import CyclicIKProblem
from youbot_opt.ikpath.result import IKStatus


@pytest.fixture(scope="module")
def two_link():
    return CyclicIKProblem(chain=PlanarChain(lengths=[LA, LB]), targets=TARGETS_2)


def test_starts_are_seeded_and_feasible():
    """Start 0 is zero; the same seed gives the same starts; feasible starts meet the targets."""
    prob = example_problem("B")
    a = make_starts(prob, 6, seed=3)
    np.testing.assert_array_equal(a, make_starts(prob, 6, seed=3))
    np.testing.assert_array_equal(a[0], 0.0)
    assert not np.array_equal(a, make_starts(prob, 6, seed=4))
    assert np.all(a >= prob.lower) and np.all(a <= prob.upper)
    for x in a[1:]:
        assert prob.residuals(x).max() < 1e-9  # exact IK by closed form
    u = make_starts(prob, 6, seed=3, kind="uniform")
    assert np.all(u >= prob.lower) and np.all(u <= prob.upper)
    with pytest.raises(ParameterError, match="choose one of feasible, uniform"):
        make_starts(prob, 3, seed=0, kind="grid")
    with pytest.raises(ParameterError, match="n_starts"):
        make_starts(prob, 0, seed=0)


@pytest.mark.parametrize("method", ["al", "ipopt"])
def test_multistart_finds_enumerated_global_optimum(two_link, method):
    """40 seeded starts: no minimum below the enumerated optimum, and the best equals it (1e-9).

    A 2-link arm has isolated IK solutions, so the starts' elbow draws (16 combinations)
    decide what is found; 40 starts miss the best one with probability (15/16)^39 < 0.1.
    """
    e_star, q_star = _two_link_optimum(TARGETS_2)
    res = run_multistart(two_link, method=method, n_starts=40, seed=0, max_workers=1)
    assert min(m.objective for m in res.minima) >= e_star - 1e-9
    assert res.best.objective == pytest.approx(e_star, abs=1e-9)
    assert configuration_distance(res.best.configurations, q_star) < 1e-6
    assert res.best_count >= 1
    assert sum(m.count for m in res.minima) == res.n_success
    assert [m.objective for m in res.minima] == sorted(m.objective for m in res.minima)


@pytest.mark.slow
def test_process_pool_equals_serial_and_reports_progress(two_link):
    """A 2-process pool gives the serial run's per-start results; progress reaches the total."""
    calls = []
    serial = run_multistart(two_link, n_starts=8, seed=1, max_workers=1)
    pooled = run_multistart(
        two_link,
        n_starts=8,
        seed=1,
        max_workers=2,
        chunk_size=2,
        progress=lambda done, total, best: calls.append((done, total, best)),
    )
    np.testing.assert_allclose(
        [r.objective for r in pooled.results], [r.objective for r in serial.results], atol=1e-12
    )
    assert pooled.n_workers == 2
    assert [c[0] for c in calls] == [2, 4, 6, 8] and all(c[1] == 8 for c in calls)
    assert calls[-1][2] == pytest.approx(serial.best.objective)


def test_a_crashing_start_does_not_end_the_run(two_link, monkeypatch):
    """An exception in one start becomes a CRASHED result; the other starts still succeed."""
    real = ms_mod.solve_augmented_lagrangian

    def flaky(problem, x0, options):
        if np.allclose(x0, 0.0):
            raise RuntimeError("boom")
        return real(problem, x0, options)

    monkeypatch.setattr(ms_mod, "solve_augmented_lagrangian", flaky)
    res = run_multistart(two_link, n_starts=4, seed=0, max_workers=1)
    assert res.results[0].status is IKStatus.CRASHED
    assert "RuntimeError: boom" in res.results[0].message
    assert all(r.success for r in res.results[1:])
    assert res.status_counts()["crashed"] == 1


class _LosingExecutor(ThreadPoolExecutor):
    """An executor whose first task is lost (as if its worker process died)."""

    def __init__(self) -> None:
        super().__init__(max_workers=1)
        self.lost = False

    def submit(self, fn, /, *args, **kwargs):  # type: ignore[override]
        if not self.lost:
            self.lost = True
            fut: Future = Future()
            fut.set_exception(OSError("worker died"))
            return fut
        return super().submit(fn, *args, **kwargs)


def test_a_lost_chunk_does_not_end_the_run(two_link):
    """Starts of a chunk whose future fails are CRASHED; any executor can be passed."""
    with _LosingExecutor() as pool:
        res = run_multistart(two_link, n_starts=4, seed=0, executor=pool, chunk_size=2)
    assert [r.status for r in res.results[:2]] == [IKStatus.CRASHED] * 2
    assert "worker died" in res.results[0].message
    assert all(r.success for r in res.results[2:])


def test_configuration_distance_ignores_common_2pi_shifts(rng):
    """Shifting one joint by 2 pi in every configuration is the same path; in one only is not."""
    q = rng.uniform(-1, 1, (5, 3))
    shifted = q.copy()
    shifted[:, 1] += 2 * np.pi
    assert configuration_distance(q, shifted) < 1e-12
    single = q.copy()
    single[2, 1] += 2 * np.pi
    assert configuration_distance(q, single) > 1.0


def test_clustering_merges_equal_minima(two_link):
    """Results within the tolerances form one minimum whose count is the number of members."""
    res = run_multistart(two_link, n_starts=10, seed=2, max_workers=1)
    merged = cluster_minima(res.results, e_tol=1e6, q_tol=1e6)
    assert len(merged) == 1 and merged[0].count == res.n_success
    assert res.distinct_optima() == res.minima or len(res.distinct_optima()) == len(res.minima)
