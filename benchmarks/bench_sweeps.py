"""Time the sweeps on the local process pool and on a local Dask cluster, and the driver's cost.

Run ``python benchmarks/bench_sweeps.py [--quick] [--items N] [--json]``. In one
run, so the ratios compare like with like (issue #15):

* the 200-start trajectory multistart (study 1, beta = 0.5, 50 knots) on the
  local pool of 2 worker processes (baseline) and on a 2-worker Dask
  ``LocalCluster`` (worker processes, 1 thread each, on 127.0.0.1); target:
  Dask overhead <= 15 %; the per-start results must be identical;
* the 1000-start IK-path multistart (example B, AL) on the same two;
* the driver's cost per item: trivial items (``math.sqrt``) through
  :func:`~youbot_opt.sweeps.resume.run_resumable` in this process, without and
  with the on-disk store (serial: the driver also writes every item; on the
  local pool: workers write their items, the driver checks and records them),
  and on the Dask cluster (batches of 64); goal >= 2000 items/s;
* an ``--items``-item trivial sweep (default 10^4, the issue's 10^5 with
  ``--items 100000``) through the real store with ``keep_results=False``:
  items/s, the driver's peak traced memory (``tracemalloc``) of a 10^4-item
  sweep against the ``--items`` one (flat = within a few MB), RSS at every
  tenth (it also counts the SQLite index and selection, whose page caches
  tracemalloc does not see: 2 MiB each), and the time to resume the store.

* ``--traj-starts 1000,10000`` (``--traj-only``: this section alone): a real
  trajectory multistart (study 1, ``--traj-knots`` knots, default 6, pool of 2)
  with ``keep_results=False`` at each size, and ``keep_results=True`` where it
  fits (``--traj-keep-max``, default 10^4), in the same run: starts/s, the
  driver's peak traced memory (workers are not traced), RSS growth; and the
  cost of ``best``, ``distinct_optima()`` and ``summary()`` on the lean
  result, answered from its tally, against the walk over every stored start
  that the same result without its tally does (what they cost before the tally).

* ``--pools`` (``--pools-only``: this section alone): the crash-isolating pool
  (:func:`~youbot_opt.sweeps.pool.run_tasks` on ``executor="process"``) against
  the maintained candidates, pebble's ``ProcessPool`` and loky's reusable
  executor, each used directly with 2 workers, in the same run: throughput of
  trivial items and of 20 ms items (items/s, ratio to the pool), crash
  isolation (of 24 items, one SIGKILLs and one segfaults its worker: which
  items fail, whether the rest finish), and the per-item time-out (one item of
  24 hangs, limit 0.5 s: is it cut, is only it charged, the wall time).

``--store-only`` leaves out the Dask and solver sections (no cluster started).
``--quick``: 40 trajectory starts, 200 IK starts, 2000 store items. Wall times
on a shared 2-core machine are noisy (20-100 % between runs when other
processes compete): each sweep runs ``--repeat`` times (default 3) on both
executors, interleaved, and the fastest run of each counts.
"""

from __future__ import annotations

import argparse
import ctypes
import dataclasses
import json
import math
import os
import signal
import tempfile
import time
import tracemalloc
from pathlib import Path
from typing import Any

from youbot_opt.ikpath.examples import example_problem
from youbot_opt.ikpath.multistart import run_multistart as ik_multistart
from youbot_opt.reproduction.study1 import study1_problem
from youbot_opt.sweeps.optima import KeepRule
from youbot_opt.sweeps.options import SweepOptions
from youbot_opt.sweeps.pool import Task
from youbot_opt.sweeps.resume import run_resumable
from youbot_opt.sweeps.store import ItemRecord, SweepStore
from youbot_opt.sweeps.tasks import TaskSequence
from youbot_opt.trajopt.multistart import run_multistart
from youbot_opt.trajopt.solver import TrajOptSolver

TARGET_OVERHEAD = 0.15  # Dask wall / pool wall - 1, at most
GOAL_ITEMS_PER_S = 2000.0  # driver cost per item, goal


def _rss_mb() -> float:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024.0
    return math.nan


def _timed(fn):  # type: ignore[no-untyped-def]
    tic = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - tic


def _encode(value: float) -> bytes:
    return repr(value).encode()


def _save(value: float, path: Path) -> None:
    path.write_bytes(_encode(value))


def _load(path: Path) -> float:
    return float(path.read_text())


def _describe(key: str, args: tuple[Any, ...], value: float) -> tuple[float, dict[str, float]]:
    return value, {"v": value}


def _light(key: str, record: ItemRecord) -> float:
    return float(record.summary["v"]) if record.state == "done" else math.nan


_BEST: KeepRule[float] = KeepRule(objective=lambda v: -v)  # keep_results=False: the largest


def _task(i: int) -> Task:
    return Task(key=f"i{i:06d}", fn=math.sqrt, args=(float(i),))


def _trivial(  # type: ignore[no-untyped-def]
    n: int, out: Path | None, executor, samples: list | None = None, *, keep: bool = True
):
    store = None
    if out is not None:
        store = SweepStore(
            out, kind="bench", params={"n": n}, save=_save, load=_load, suffix=".txt",
            encode=_encode,
        )  # fmt: skip
    # keep_results=False: tasks made as they are needed (a TaskSequence), as a real
    # sweep of that size would pass them; keep_results=True: a list, as before
    tasks = TaskSequence(n, _task) if not keep else [_task(i) for i in range(n)]
    step = max(1, n // 10)

    def on_final(key: str, value: float, done: int) -> None:
        if samples is not None and done % step == 0:
            samples.append(round(_rss_mb(), 1))

    got = run_resumable(
        tasks,
        store=store,
        options=SweepOptions(
            executor=executor,
            batch_size=64,
            out=out,
            keep_results=keep,
            workers=2 if executor == "process" else None,
        ),  # fmt: skip
        load=lambda key: store.load(key),  # type: ignore[union-attr]
        convert=lambda o: o.value,
        payload=lambda key, v: (v, {"v": v}),
        on_final=on_final,
        describe=_describe,
        light=_light,
        keep=_BEST,
    )
    if store is not None:
        store.close()
    return got


def _peak_mb(fn) -> float:  # type: ignore[no-untyped-def]
    """Peak memory traced while ``fn`` runs, in [MB] (tracemalloc: Python allocations)."""
    tracemalloc.start()
    try:
        fn()
        return tracemalloc.get_traced_memory()[1] / 2**20
    finally:
        tracemalloc.stop()


def store_section(n_store: int, rows: dict[str, float]) -> list[float]:
    """The big keep_results=False sweep through the real store; returns the RSS samples."""
    with tempfile.TemporaryDirectory(dir=Path.cwd()) as tmp:
        n = 20_000
        _, t = _timed(lambda: _trivial(n, Path(tmp) / "serial", "serial"))
        rows["driver_items_per_s_store"] = n / t
        _, t = _timed(lambda: _trivial(n, Path(tmp) / "pool", "process"))
        rows["pool_items_per_s_store"] = n / t
        _, t = _timed(lambda: _trivial(n, Path(tmp) / "pool_lazy", "process", keep=False))
        rows["pool_items_per_s_store_lazy"] = n / t
    with tempfile.TemporaryDirectory(dir=Path.cwd()) as tmp:
        small = min(10_000, n_store)
        rows["peak_mb_small"] = _peak_mb(lambda: _trivial(small, Path(tmp) / "a", "serial",
                                                          keep=False))  # fmt: skip
        rows["peak_mb_items"] = _peak_mb(lambda: _trivial(n_store, Path(tmp) / "b", "serial",
                                                          keep=False))  # fmt: skip
        rows["peak_small_items"] = small
    with tempfile.TemporaryDirectory(dir=Path.cwd()) as tmp:
        samples: list[float] = []
        _, t_run = _timed(lambda: _trivial(n_store, Path(tmp) / "big", "serial", samples,
                                           keep=False))  # fmt: skip
        got, t_resume = _timed(lambda: _trivial(n_store, Path(tmp) / "big", "serial", keep=False))
        assert got.resumed == n_store
        rows["store_items"] = n_store
        rows["store_run_s"], rows["store_resume_s"] = t_run, t_resume
        rows["store_items_per_s"] = n_store / t_run
        rows["store_rss_growth_mb"] = samples[-1] - samples[0] if samples else math.nan
        folders = [p for p in (Path(tmp) / "big" / "items").iterdir() if p.name != "journal"]
        rows["store_files_per_folder_max"] = max(len(list(f.iterdir())) for f in folders)
    return samples


def _timed_peak(fn):  # type: ignore[no-untyped-def]
    """``fn()``, its wall time [s] and the peak memory traced meanwhile [MB] (this process)."""
    tracemalloc.start()
    tic = time.perf_counter()
    try:
        out = fn()
        return out, time.perf_counter() - tic, tracemalloc.get_traced_memory()[1] / 2**20
    finally:
        tracemalloc.stop()


def traj_keep_section(sizes: list[int], keep_max: int, knots: int) -> list[dict[str, Any]]:
    """Real trajectory multistarts with keep_results=False (and True where it fits)."""
    # forked pool workers would inherit tracing; only the driver is measured
    os.register_at_fork(after_in_child=tracemalloc.stop)
    solver = TrajOptSolver(study1_problem(knots))
    run_multistart(solver, 2, seed=99, sweep=SweepOptions(executor="serial"))  # warm imports
    out: list[dict[str, Any]] = []
    for n in sizes:
        for keep in (False, True) if n <= keep_max else (False,):
            with tempfile.TemporaryDirectory(dir=Path.cwd()) as tmp:
                sweep = SweepOptions(workers=2, out=Path(tmp) / "ms", keep_results=keep)
                rss0 = _rss_mb()
                ms, t, peak = _timed_peak(lambda n=n, sweep=sweep: run_multistart(
                    solver, n, seed=0, sweep=sweep))  # fmt: skip
                row: dict[str, Any] = {
                    "n": n, "keep_results": keep, "run_s": t, "starts_per_s": n / t,
                    "peak_mb": peak, "rss_growth_mb": _rss_mb() - rss0,
                    "optima": len(ms.distinct_optima()), "converged": ms.n_converged,
                }  # fmt: skip
                if not keep:  # the accessors, from the tally and by walking every start
                    walk = dataclasses.replace(ms, tally=None)
                    for name, res in (("tally", ms), ("walk", walk)):
                        for what, call in (
                            ("best", lambda r=res: r.best),
                            ("optima", lambda r=res: r.distinct_optima()),
                            ("summary", lambda r=res: r.summary()),
                        ):
                            _, t_call, mb = _timed_peak(call)
                            row[f"{what}_{name}_s"], row[f"{what}_{name}_mb"] = t_call, mb
                    same = (walk.best.key, [o.count for o in walk.distinct_optima()]) == (
                        ms.best.key, [o.count for o in ms.distinct_optima()])  # fmt: skip
                    row["accessors_agree"] = same
                out.append(row)
                print(json.dumps(row), flush=True)
    return out


def traj_report(rows: list[dict[str, Any]], knots: int) -> None:
    """Print the trajectory keep_results table."""
    print(f"trajectory multistart, study 1 at {knots} knots, pool of 2 workers:")
    print(f"{'starts':>8}{'keep':>7}{'run [s]':>9}{'starts/s':>10}{'peak [MB]':>11}"
          f"{'RSS +[MB]':>11}{'optima':>8}")  # fmt: skip
    for r in rows:
        print(f"{r['n']:>8}{str(r['keep_results']):>7}{r['run_s']:>9.1f}{r['starts_per_s']:>10.0f}"
              f"{r['peak_mb']:>11.1f}{r['rss_growth_mb']:>11.1f}{r['optima']:>8}")  # fmt: skip
    for r in rows:
        if r["keep_results"]:
            continue
        cells = ", ".join(
            f"{what} {r[f'{what}_tally_s'] * 1e3:.2f} ms / {r[f'{what}_tally_mb']:.2f} MB "
            f"(walk {r[f'{what}_walk_s'] * 1e3:.0f} ms / {r[f'{what}_walk_mb']:.1f} MB)"
            for what in ("best", "optima", "summary")
        )
        print(f"accessors at {r['n']} starts, keep_results=False (tally vs walk): {cells}; "
              f"agree: {r['accessors_agree']}")  # fmt: skip


# ------------------------------------------------------------ pool candidates
_POOL_N_CRASH = 24  # items of the crash and time-out scenarios
_POOL_SLOW = 0.02  # [s] one "20 ms" item
_POOL_TIMEOUT = 0.5  # [s] the per-item limit of the time-out scenario


def _slow_item(i: int) -> int:
    time.sleep(_POOL_SLOW)
    return i


def _crash_item(i: int) -> int:
    """Item 5 SIGKILLs its worker, item 11 segfaults it; the rest sleep 20 ms."""
    if i == 5:
        os.kill(os.getpid(), signal.SIGKILL)
    if i == 11:
        ctypes.string_at(0)  # SIGSEGV
    return _slow_item(i)


def _hang_item(i: int) -> int:
    """Item 7 hangs for an hour; the rest sleep 20 ms."""
    if i == 7:
        time.sleep(3600)
    return _slow_item(i)


def _run_ours(fn, n: int, timeout: float | None):  # type: ignore[no-untyped-def]
    """Today's pool: returns {i: "ok" | reason} of the first attempt (max_attempts=1)."""
    from youbot_opt.sweeps.pool import run_tasks

    tasks = [Task(key=str(i), fn=fn, args=(i,)) for i in range(n)]
    out = run_tasks(tasks, executor="process", workers=2, max_attempts=1, timeout=timeout)
    return {int(k): "ok" if o.ok else str(o.error) for k, o in out.items()}


def _run_pebble(fn, n: int, timeout: float | None):  # type: ignore[no-untyped-def]
    """pebble's ProcessPool (fork), every item scheduled with its own time-out."""
    from pebble import ProcessPool

    from youbot_opt.sweeps.pool import process_context

    got: dict[int, str] = {}
    with ProcessPool(max_workers=2, context=process_context()) as pool:
        futures = {i: pool.schedule(fn, args=(i,), timeout=timeout) for i in range(n)}
        for i, fut in futures.items():
            try:
                fut.result()
                got[i] = "ok"
            except Exception as exc:  # noqa: BLE001 - the reason is what is measured
                got[i] = f"{type(exc).__name__}: {exc}"
    return got


def _run_loky(fn, n: int, timeout: float | None):  # type: ignore[no-untyped-def]
    """loky's reusable executor (it has no per-item time-out: ``timeout`` caps the wait)."""
    from loky import get_reusable_executor

    got: dict[int, str] = {}
    ex = get_reusable_executor(max_workers=2)
    futures = {i: ex.submit(fn, i) for i in range(n)}
    for i, fut in futures.items():
        try:
            fut.result(timeout=None if timeout is None else timeout * n)
            got[i] = "ok"
        except Exception as exc:  # noqa: BLE001 - the reason is what is measured
            got[i] = f"{type(exc).__name__}: {str(exc)[:60]}"
    if any(v != "ok" for v in got.values()) and timeout is not None:
        ex.shutdown(wait=False, kill_workers=True)  # a hung worker is only ended here
    return got


_POOLS = {"ours": _run_ours, "pebble": _run_pebble, "loky": _run_loky}


def _bad_init() -> None:
    raise ValueError("no solver")


def _idle_death(name: str) -> bool:
    """A kept pool whose only worker is SIGKILLed while idle: does the next item still run?"""
    from youbot_opt.sweeps.pool import WorkerPool, process_context, run_tasks

    def again(submit) -> bool:  # type: ignore[no-untyped-def]
        pid = submit()
        os.kill(pid, signal.SIGKILL)
        time.sleep(0.3)
        try:
            return submit() != pid
        except Exception:  # noqa: BLE001 - a broken pool is the answer
            return False

    if name == "ours":
        with WorkerPool(1) as pool:
            return again(lambda: run_tasks([Task(key="p", fn=os.getpid)], executor=pool)["p"].value)
    if name == "pebble":
        from pebble import ProcessPool

        with ProcessPool(max_workers=1, context=process_context()) as pp:
            return again(lambda: pp.schedule(os.getpid).result(timeout=10))
    from loky import get_reusable_executor

    return again(lambda: get_reusable_executor(max_workers=1).submit(os.getpid).result(timeout=10))


def _init_failure(name: str) -> str:
    """The workers' initializer raises: how is the item told (within 10 s)?"""
    from youbot_opt.sweeps.pool import process_context, run_tasks

    try:
        if name == "ours":
            out = run_tasks([Task(key="p", fn=os.getpid)], initializer=_bad_init, max_attempts=1)
            return str(out["p"].error)
        if name == "pebble":
            from pebble import ProcessPool

            with ProcessPool(max_workers=1, context=process_context(), initializer=_bad_init) as pp:
                pp.schedule(os.getpid).result(timeout=10)
        else:
            from loky import get_reusable_executor

            ex = get_reusable_executor(max_workers=1, initializer=_bad_init)
            ex.submit(os.getpid).result(timeout=10)
            ex.shutdown(wait=False, kill_workers=True)
        return "ran without its initializer"
    except TimeoutError:
        return "no answer within 10 s (workers restarted in a loop)"
    except Exception as exc:  # noqa: BLE001 - the reason is what is measured
        return f"{type(exc).__name__}: {str(exc)[:60]}"


def pool_section(repeat: int, n_trivial: int) -> dict[str, dict[str, Any]]:
    """Every candidate on the same scenarios, interleaved; the fastest run of each counts."""
    res: dict[str, dict[str, Any]] = {name: {} for name in _POOLS}
    n_slow = 100
    for run in _POOLS.values():  # warm: imports and the first workers
        run(math.sqrt, 4, None)
    for _ in range(repeat):
        for name, run in _POOLS.items():
            _, t = _timed(lambda run=run: run(math.sqrt, n_trivial, None))
            res[name]["trivial_items_per_s"] = max(
                res[name].get("trivial_items_per_s", 0), n_trivial / t
            )
            _, t = _timed(lambda run=run: run(_slow_item, n_slow, None))
            res[name]["slow_items_per_s"] = max(res[name].get("slow_items_per_s", 0), n_slow / t)
    ideal = 2 / _POOL_SLOW
    for name, run in _POOLS.items():
        res[name]["idle_death_survived"] = _idle_death(name)
        res[name]["init_failure"] = _init_failure(name)
        res[name]["slow_efficiency"] = res[name]["slow_items_per_s"] / ideal
        got, t = _timed(lambda run=run: run(_crash_item, _POOL_N_CRASH, None))
        failed = sorted(i for i, v in got.items() if v != "ok")
        res[name]["crash_failed"] = failed
        res[name]["crash_isolated"] = failed == [5, 11]
        res[name]["crash_reasons"] = sorted({got[i][:70] for i in failed})
        res[name]["crash_s"] = t
        if name == "loky":
            res[name]["timeout_isolated"] = False
            res[name]["timeout_note"] = "no per-item time-out in loky"
            continue
        got, t = _timed(lambda run=run: run(_hang_item, _POOL_N_CRASH, _POOL_TIMEOUT))
        failed = sorted(i for i, v in got.items() if v != "ok")
        res[name]["timeout_failed"] = failed
        res[name]["timeout_isolated"] = failed == [7]
        res[name]["timeout_reasons"] = sorted({got[i][:70] for i in failed})
        res[name]["timeout_s"] = t
    return res


def pool_report(res: dict[str, dict[str, Any]], n_trivial: int) -> None:
    """Print the candidates' table with their ratios to today's pool (same run)."""
    base = res["ours"]
    print("worker pools, 2 workers, measured in this run (ratio to today's pool):")
    print(f"{'pool':<8}{f'{n_trivial} trivial [1/s]':>22}{'100 x 20 ms [1/s]':>24}"
          f"{'crash isolated':>16}{'time-out isolated':>19}")  # fmt: skip
    for name, r in res.items():
        fast = r["trivial_items_per_s"]
        t1 = f"{fast:.0f} (x{fast / base['trivial_items_per_s']:.2f})"
        t2 = (
            f"{r['slow_items_per_s']:.0f} (x{r['slow_items_per_s'] / base['slow_items_per_s']:.2f})"
        )
        print(f"{name:<8}{t1:>22}{t2:>24}{str(r['crash_isolated']):>16}"
              f"{str(r['timeout_isolated']):>19}")  # fmt: skip
    for name, r in res.items():
        print(f"{name}: a kept pool survives an idle worker's death: {r['idle_death_survived']}; "
              f"a failing initializer: {r['init_failure']}")  # fmt: skip
        print(f"{name}: crash scenario {r['crash_s']:.2f} s, failed {r['crash_failed']} "
              f"{r['crash_reasons']}")  # fmt: skip
        if "timeout_s" in r:
            print(f"{name}: time-out scenario {r['timeout_s']:.2f} s, failed "
                  f"{r['timeout_failed']} {r['timeout_reasons']}")  # fmt: skip
        else:
            print(f"{name}: {r['timeout_note']}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="smaller sweeps")
    parser.add_argument("--items", type=int, default=None, help="store sweep size (1e4)")
    parser.add_argument("--json", action="store_true", help="print the figures as JSON too")
    parser.add_argument(
        "--repeat",
        type=int,
        default=3,
        help="runs of each sweep on each executor, interleaved; the fastest counts (default 3)",
    )
    parser.add_argument(
        "--skip-ik", action="store_true", help="leave out the IK sweeps (the longest part)"
    )
    parser.add_argument(
        "--store-only", action="store_true", help="only the store sections (no Dask, no solvers)"
    )
    parser.add_argument(
        "--traj-starts", default=None, help="sizes of the trajectory keep_results section"
    )
    parser.add_argument("--traj-keep-max", type=int, default=10_000, help="largest full run")
    parser.add_argument("--traj-knots", type=int, default=6, help="knots of that problem")
    parser.add_argument("--traj-only", action="store_true", help="only that section")
    parser.add_argument("--pools", action="store_true", help="the pool candidates too")
    parser.add_argument("--pools-only", action="store_true", help="only the pool candidates")
    args = parser.parse_args()
    if args.pools or args.pools_only:
        n_trivial = 500 if args.quick else 2000
        pools = pool_section(args.repeat, n_trivial)
        pool_report(pools, n_trivial)
        if args.json:
            print(json.dumps(pools, indent=1))
        if args.pools_only:
            return
    if args.traj_starts or args.traj_only:
        sizes = [int(float(x)) for x in (args.traj_starts or "1000,10000").split(",")]
        traj = traj_keep_section(sizes, args.traj_keep_max, args.traj_knots)
        traj_report(traj, args.traj_knots)
        if args.traj_only:
            return
    n_traj, n_ik = (40, 200) if args.quick else (200, 1000)
    n_store = args.items or (2000 if args.quick else 10_000)
    rows: dict[str, float] = {}
    if not args.store_only:
        cluster_section(args, n_traj, n_ik, rows)
    samples = store_section(n_store, rows)
    report(rows, n_traj, n_ik, n_store, samples)
    if args.json:
        print(json.dumps(rows, indent=1))


def cluster_section(  # type: ignore[no-untyped-def]
    args, n_traj: int, n_ik: int, rows: dict[str, float]
) -> None:
    """The solver sweeps on the pool and on Dask, and the driver's cost without a store."""
    from distributed import Client, LocalCluster

    solver = TrajOptSolver(study1_problem(50))
    prob = example_problem("B")
    with (
        LocalCluster(
            n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
            dashboard_address=None,
        ) as cluster,
        Client(cluster) as client,
    ):  # fmt: skip
        client.wait_for_workers(2)
        # warm both: imports and the first solver build happen outside the timings
        run_multistart(solver, 2, seed=99, sweep=SweepOptions(executor=client))
        ik_multistart(prob, n_starts=4, seed=99, sweep=SweepOptions(executor=client))
        for name, run in (
            ("traj", lambda ex: run_multistart(solver, n_traj, beta=0.5, seed=0,
                                               sweep=SweepOptions(executor=ex, workers=2))),
            ("ik", lambda ex: ik_multistart(prob, n_starts=n_ik, seed=0,
                                            sweep=SweepOptions(executor=ex, workers=2))),
        ):  # fmt: skip
            if name == "ik" and args.skip_ik:
                continue
            t_pool = t_dask = math.inf
            for _ in range(args.repeat):  # interleaved: both see the same machine load
                pool, t = _timed(lambda run=run: run("process"))
                t_pool = min(t_pool, t)
                dask, t = _timed(lambda run=run: run(client))
                t_dask = min(t_dask, t)
            if name == "traj":
                same = [s.objective for s in pool.starts] == [s.objective for s in dask.starts]
            else:
                same = [r.objective for r in pool.results] == [r.objective for r in dask.results]
            rows[f"{name}_pool_s"], rows[f"{name}_dask_s"] = t_pool, t_dask
            rows[f"{name}_overhead"] = t_dask / t_pool - 1.0
            rows[f"{name}_identical"] = float(same)

        n_driver = 20_000 if not args.quick else 5000
        _, t = _timed(lambda: _trivial(n_driver, None, "serial"))
        rows["driver_items_per_s_nostore"] = n_driver / t
        _, t = _timed(lambda: _trivial(n_driver, None, client))
        rows["dask_items_per_s_nostore"] = n_driver / t


def report(  # type: ignore[no-untyped-def]
    rows: dict[str, float], n_traj: int, n_ik: int, n_store: int, samples: list[float]
) -> None:
    """Print the table."""
    print(f"{'sweep':<34}{'local pool [s]':>16}{'Dask [s]':>12}{'overhead':>10}{'identical':>10}")
    for name, label in (
        ("traj", f"trajectory, {n_traj} starts"),
        ("ik", f"IK path, {n_ik} starts"),
    ):
        if f"{name}_pool_s" not in rows:
            continue
        ok = "yes" if rows[f"{name}_identical"] else "NO"
        print(
            f"{label:<34}{rows[f'{name}_pool_s']:>16.2f}{rows[f'{name}_dask_s']:>12.2f}"
            f"{rows[f'{name}_overhead']:>+10.0%}{ok:>10}"
        )
    if "traj_pool_s" in rows or "ik_pool_s" in rows:
        print(f"target: Dask overhead <= {TARGET_OVERHEAD:.0%}")
    if "driver_items_per_s_nostore" in rows:
        print(
            f"driver cost without a store: {rows['driver_items_per_s_nostore']:.0f} items/s "
            f"in-process, {rows['dask_items_per_s_nostore']:.0f} items/s on Dask"
        )
    print(
        f"driver cost through the on-disk store: {rows['driver_items_per_s_store']:.0f} items/s "
        f"serial (the driver writes), {rows['pool_items_per_s_store']:.0f} items/s on the "
        f"local pool (workers write; goal >= {GOAL_ITEMS_PER_S:.0f}), "
        f"{rows['pool_items_per_s_store_lazy']:.0f} items/s on the pool with "
        f"keep_results=False (chunks of lazily made tasks)"
    )
    print(
        f"store sweep of {n_store} trivial items, keep_results=False: {rows['store_run_s']:.1f} s "
        f"({rows['store_items_per_s']:.0f} items/s), resume {rows['store_resume_s']:.2f} s; "
        f"peak traced memory {rows['peak_mb_small']:.1f} MB at {rows['peak_small_items']:.0f} "
        f"items vs {rows['peak_mb_items']:.1f} MB at {n_store} (SQLite caches, <= 2 x 2 MiB, "
        f"not traced); RSS at each tenth {samples} MB "
        f"(growth {rows['store_rss_growth_mb']:.1f} MB); at most "
        f"{rows['store_files_per_folder_max']:.0f} files per item folder"
    )


if __name__ == "__main__":
    main()
