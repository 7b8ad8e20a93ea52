"""Bounded-memory selection of optima and the on-disk key index (#15 item 3, flat driver memory).

References: ``select_optima`` (the in-memory greedy rule, itself checked
against ``cluster_optima`` in test_scaling_store.py) must be reproduced
exactly by ``stream_optima`` -- same representatives, members, order, loads --
including ties in objective, non-converged items and groups; ``DiskIndex``
against a plain ``dict`` under the same random operations. Trivial items:
the whole file runs in about a second.
"""

from __future__ import annotations

import json
import math
import random
from pathlib import Path

import pytest
from test_scaling_store import RULE, _sweep

from youbot_opt.sweeps.index import DiskIndex
from youbot_opt.sweeps.optima import KeepRule, select_optima
from youbot_opt.sweeps.selection import Clusters, stream_optima
from youbot_opt.sweeps.store import SweepStore


def _values(n: int) -> dict[str, list[float]]:
    # exact ties in objective (i % 5 repeats) so the item order decides, NaN = not converged
    return {f"k{i:04d}": [math.nan if i % 11 == 4 else 0.25 * (i % 5), float(i % 3)]
            for i in range(n)}  # fmt: skip


@pytest.mark.parametrize(
    "rule",
    [
        RULE,
        KeepRule(objective=RULE.objective),  # the best only
        KeepRule(objective=RULE.objective, group=lambda v: v[1] if v[1] != 1.0 else "one"),
        KeepRule(
            objective=RULE.objective,
            distance=RULE.distance,
            obj_tol=RULE.obj_tol,
            dist_tol=RULE.dist_tol,
            group=lambda v: int(v[0] * 4) % 2 if not math.isnan(v[0]) else -1,
        ),
    ],
    ids=["distance", "best", "best-per-group", "distance-per-group"],
)
def test_stream_optima_equals_select_optima(rule: KeepRule[list[float]]) -> None:
    """Same clusters (keys, order, counts) and the same items loaded in the same order."""
    values = _values(5000)  # > one 4096-row batch: the paging is exercised
    loads_ref: list[str] = []
    loads: list[str] = []
    kept_ref, ref = select_optima(values, rule, lambda k: loads_ref.append(k) or values[k])  # type: ignore[func-returns-value]
    kept, got = stream_optima(values, rule, lambda k: loads.append(k) or values[k])  # type: ignore[func-returns-value]
    assert [list(c) for c in got] == ref
    assert got.counts == [len(c) for c in ref] and got.representatives == [c[0] for c in ref]
    assert list(kept) == list(kept_ref) and loads == loads_ref
    assert got[-1][len(ref[-1]) - 1] == ref[-1][-1] and got == ref


def test_saved_members_are_read_back_and_checked(tmp_path: Path) -> None:
    """Clusters.save then open gives the same clusters; a file with other counts is refused."""
    values = _values(300)
    _, got = stream_optima(values, RULE, values.__getitem__)
    path = tmp_path / "members.sqlite"
    got.save(path)
    back = Clusters.open(path, list(got.representatives), list(got.counts))
    assert back is not None and back == got
    assert Clusters.open(path, list(got.representatives), [c + 1 for c in got.counts]) is None
    assert Clusters.open(tmp_path / "missing.sqlite", [], []) is None


def test_an_optima_file_of_0_1_0_is_chosen_again(tmp_path: Path) -> None:
    """optima.json with the clusters as lists (0.1.0) is not read: the optima are chosen again."""
    out = tmp_path / "run"
    first = _sweep(out, keep=False)
    optima = json.loads((out / "optima.json").read_text())
    assert isinstance(first.clusters, Clusters) and "clusters" not in optima
    assert (out / optima["members"]).is_file()
    lists = [list(c) for c in first.clusters]
    (out / optima["members"]).unlink()
    for key in ("representatives", "counts", "members"):
        del optima[key]
    (out / "optima.json").write_text(json.dumps({**optima, "clusters": lists}))
    loads: list[str] = []
    again = _sweep(out, keep=False, loads=loads)
    assert isinstance(again.clusters, Clusters)
    assert [list(c) for c in again.clusters] == lists
    assert set(loads) > {c[0] for c in lists}  # every converged start compared again
    assert "clusters" not in json.loads((out / "optima.json").read_text())  # saved as now


def test_disk_index_behaves_as_a_dict() -> None:
    """Random sets, updates, deletions and lookups agree with a dict; iteration in key order."""
    rng = random.Random(3)
    index, ref = DiskIndex(), {}
    for _ in range(3000):
        key = f"k{rng.randrange(500)}"
        op = rng.random()
        if op < 0.6:
            value = rng.randrange(-(2**62), 2**62)
            index[key], ref[key] = value, value
        elif op < 0.8:
            assert index.pop(key, None) == ref.pop(key, None)
        else:
            assert index.get(key) == ref.get(key) and (key in index) == (key in ref)
    assert len(index) == len(ref) and list(index) == sorted(ref)
    assert dict(index.items()) == ref
    index.clear()
    assert len(index) == 0 and list(index) == []
    index.close()
    with pytest.raises(ValueError, match="closed"):
        index.get("k1")


def test_a_store_index_iterates_while_it_changes(tmp_path: Path) -> None:
    """Keys recorded while the store's keys are iterated do not break the iteration."""
    store = SweepStore(tmp_path, kind="t", params={}, save=lambda v, p: p.write_text(str(v)),
                       load=lambda p: p.read_text(), suffix=".txt")  # fmt: skip
    with store.grouped():
        for i in range(2500):
            store.write_failed(f"a{i:04d}", "x", attempts=1)
    seen = []
    for n, key in enumerate(store.keys()):
        seen.append(key)
        if n == 10:
            store.write_failed("b0", "x", attempts=1)  # after every a*: seen later
    assert seen[:2500] == [f"a{i:04d}" for i in range(2500)] and "b0" in seen


@pytest.mark.parametrize("straight", [True, False])
def test_lazy_start_jobs_equal_make_jobs(straight: bool) -> None:
    """StartJobs(i) equals make_jobs' job i (seeds from SeedSequence.spawn); keys map back."""
    from youbot_opt.trajopt.sweep import StartJobs, make_jobs

    kw = {"seed": 7, "beta": 0.5, "bound_scale": 0.9, "include_straight": straight, "dt0": 0.1}
    ref = make_jobs(12, prefix="s1_", **kw)  # type: ignore[arg-type]
    lazy = StartJobs(12, prefix="s1_", **kw)  # type: ignore[arg-type]
    assert len(lazy) == len(ref) and list(lazy) == ref and lazy[-1] == ref[-1]
    assert all(lazy.job(j.key) == j for j in ref)
    for bad in ("s1_start_0012", "start_0001", "s1_start_1", "s1_straight" * (not straight)):
        with pytest.raises(KeyError):
            lazy.job(bad)
