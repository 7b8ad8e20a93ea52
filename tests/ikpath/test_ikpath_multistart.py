"""Multistart: seeded starts, parallel = serial, failures contained, minima clustered."""

from __future__ import annotations

from concurrent.futures import Future, ThreadPoolExecutor

import numpy as np
import pytest
from test_ikpath_solvers import LA, LB, TARGETS_2, _two_link_optimum

from youbot_opt.exceptions import ParameterError, ResultFileError
from youbot_opt.ikpath import sweep as sweep_mod
from youbot_opt.ikpath.examples import example_problem
from youbot_opt.ikpath.multistart import (
    cluster_minima,
    configuration_distance,
    make_starts,
    run_multistart,
)
from youbot_opt.ikpath.problem import CyclicIKProblem
from youbot_opt.nlp.status import SolveStatus
from youbot_opt.robot.planar import PlanarChain
from youbot_opt.sweeps.options import SweepOptions


@pytest.fixture(scope="module")
def two_link():
    return CyclicIKProblem(robot=PlanarChain(lengths=[LA, LB]), targets=TARGETS_2)


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
    res = run_multistart(
        two_link, method=method, n_starts=40, seed=0, sweep=SweepOptions(workers=1)
    )
    assert min(m.objective for m in res.minima) >= e_star - 1e-9
    assert res.best.objective == pytest.approx(e_star, abs=1e-9)
    assert configuration_distance(res.best.configurations, q_star) < 1e-6
    assert res.best_count >= 1
    assert sum(m.count for m in res.minima) == res.n_converged
    assert [m.objective for m in res.minima] == sorted(m.objective for m in res.minima)


@pytest.mark.slow
def test_process_pool_equals_serial_and_reports_progress(two_link):
    """A 2-process pool gives the serial run's per-start results; progress counts every start."""
    calls = []
    serial = run_multistart(two_link, n_starts=8, seed=1, sweep=SweepOptions(workers=1))
    pooled = run_multistart(
        two_link,
        n_starts=8,
        seed=1,
        sweep=SweepOptions(
            workers=2, progress=lambda done, total, best: calls.append((done, total, best))
        ),
    )
    # Same start, same deterministic solver in another process: equal to rounding (1e-12).
    np.testing.assert_allclose(
        [r.objective for r in pooled.results], [r.objective for r in serial.results], atol=1e-12
    )
    assert pooled.n_workers == 2 and pooled.attempts == (1,) * 8
    assert [c[0] for c in calls] == list(range(1, 9)) and all(c[1] == 8 for c in calls)
    bests = [c[2] for c in calls]
    assert bests == sorted(bests, reverse=True)  # the best so far never gets worse
    assert bests[-1] == pytest.approx(serial.best.objective, abs=1e-12)


def test_a_raising_start_is_retried_once_then_crashed(two_link, monkeypatch):
    """A start that always raises is tried twice, then CRASHED with the reason; others succeed."""
    real = sweep_mod.solve_augmented_lagrangian
    calls = []

    def flaky(problem, x0, options):
        if np.allclose(x0, 0.0):
            calls.append(1)
            raise RuntimeError("boom")
        return real(problem, x0, options)

    monkeypatch.setattr(sweep_mod, "solve_augmented_lagrangian", flaky)
    res = run_multistart(two_link, n_starts=4, seed=0, sweep=SweepOptions(workers=1))
    assert res.results[0].status is SolveStatus.CRASHED
    assert res.results[0].message == "RuntimeError: boom"
    assert len(calls) == 2 and res.attempts == (2, 1, 1, 1)
    assert all(r.success for r in res.results[1:])
    assert res.status_counts() == {"crashed": 1, "solved": 3}


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


def test_a_lost_start_is_retried_on_any_executor(two_link):
    """The start whose future fails is retried and succeeds; the others are charged nothing."""
    reference = run_multistart(two_link, n_starts=4, seed=0, sweep=SweepOptions(workers=1))
    with _LosingExecutor() as pool:
        res = run_multistart(two_link, n_starts=4, seed=0, sweep=SweepOptions(executor=pool))
    assert res.attempts == (2, 1, 1, 1)
    assert all(r.success for r in res.results)
    # Same starts, same solver, threads of this process: equal to rounding (1e-12).
    np.testing.assert_allclose(
        [r.objective for r in res.results], [r.objective for r in reference.results], atol=1e-12
    )


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
    res = run_multistart(two_link, n_starts=10, seed=2, sweep=SweepOptions(workers=1))
    merged = cluster_minima(res.results, obj_tol=1e6, dist_tol=1e6)
    assert len(merged) == 1 and merged[0].count == res.n_converged
    again = res.distinct_optima()  # default tolerances: the same clustering as res.minima
    assert [(m.objective, m.count, m.start_indices) for m in again] == [
        (m.objective, m.count, m.start_indices) for m in res.minima
    ]
    assert all(a.result is m.result for a, m in zip(again, res.minima, strict=True))
    # Distinct means distinct: no two representatives agree in E (1e-6 rel.) and q (1e-3 rad).
    for i, a in enumerate(again):
        for b in again[i + 1 :]:
            assert abs(a.objective - b.objective) > 1e-6 * max(1.0, abs(a.objective)) or (
                configuration_distance(a.result.configurations, b.result.configurations) > 1e-3
            )
    assert sum(m.count for m in again) == res.n_converged
    # The counts (and members) the clustering gave before its tolerances were named
    # obj_tol / dist_tol (objective_tol / q_tol then), at the defaults and a coarser pair.
    assert [m.count for m in again] == [2, 1, 1, 1, 1, 1, 1, 1, 1]
    coarse = res.distinct_optima(obj_tol=0.1, dist_tol=3.0)
    assert [m.start_indices for m in coarse] == [(4, 6), (0,), (1,), (9,), (7, 8), (2,), (3, 5)]
    assert [m.start_indices for m in cluster_minima(res.results, obj_tol=0.1, dist_tol=3.0)] == [
        m.start_indices for m in coarse
    ]


@pytest.mark.parametrize("bad", [0.0, -1e-3, float("nan"), float("inf")])
@pytest.mark.parametrize("name", ["obj_tol", "dist_tol"])
def test_tolerances_not_finite_and_positive_are_refused(two_link, tmp_path, name, bad):
    """obj_tol and dist_tol must be finite and > 0: ParameterError naming the argument, from
    cluster_minima, distinct_optima and run_multistart (before any start runs)."""
    with pytest.raises(ParameterError, match=f"{name} must be a finite number > 0") as info:
        cluster_minima([], **{name: bad})
    assert info.value.name == name
    out = tmp_path / "run"
    with pytest.raises(ParameterError, match=f"{name} must be a finite number > 0"):
        run_multistart(two_link, n_starts=2, sweep=SweepOptions(workers=1, out=out), **{name: bad})
    assert not out.exists()
    res = run_multistart(two_link, n_starts=2, seed=0, sweep=SweepOptions(workers=1))
    with pytest.raises(ParameterError, match=name):
        res.distinct_optima(**{name: bad})


def test_starts_are_per_index_and_old_stores_are_carried_by_the_script(tmp_path):
    """Start k does not depend on n_starts; a store without start_rng is refused, then migrated."""
    import json
    import shutil

    from _migrate import REFUSAL, migrate

    prob = example_problem("B")
    np.testing.assert_array_equal(make_starts(prob, 12, seed=3)[:5], make_starts(prob, 5, seed=3))
    # An old store: its manifest names no start_rng. The package refuses it, naming the script.
    run_multistart(prob, n_starts=4, seed=3, sweep=SweepOptions(workers=1, out=tmp_path))
    manifest = tmp_path / "manifest.json"
    doc = json.loads(manifest.read_text())
    del doc["params"]["start_rng"]
    manifest.write_text(json.dumps(doc))
    shutil.rmtree(tmp_path / "items")  # its items go; the manifest stays
    with pytest.raises(ResultFileError, match=REFUSAL):
        run_multistart(prob, n_starts=4, seed=3, sweep=SweepOptions(workers=1, out=tmp_path))
    done = migrate(tmp_path)
    assert done.returncode == 0, done.stderr
    assert json.loads(manifest.read_text())["params"]["start_rng"] == "per-index"
    # Its unfinished starts are drawn per index now.
    old = run_multistart(prob, n_starts=4, seed=3, sweep=SweepOptions(workers=1, out=tmp_path))
    new = make_starts(prob, 4, seed=3)
    np.testing.assert_array_equal([np.ravel(r.start) for r in old.results], new)
