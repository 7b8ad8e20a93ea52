"""Sweeps on a real Dask cluster of worker processes on 127.0.0.1 (issue #15).

Each test starts and stops its cluster's processes itself. Checked: results
identical to the local pool (trajectory and IK multistarts), batches with
per-item crash accounting (a segfaulting item charged, its batch mates not),
a worker killed mid-sweep, the scheduler killed mid-sweep (a clear error,
then a resume) and the driver killed mid-sweep (resume): nothing lost,
nothing duplicated, every result equal to an uninterrupted run.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from _faults import faulty, slow_square

distributed = pytest.importorskip("distributed")

from youbot_opt.exceptions import ParameterError  # noqa: E402
from youbot_opt.ikpath.examples import example_problem  # noqa: E402
from youbot_opt.ikpath.multistart import run_multistart as ik_multistart  # noqa: E402
from youbot_opt.sweeps.options import SweepOptions  # noqa: E402
from youbot_opt.sweeps.pool import Task, run_tasks  # noqa: E402
from youbot_opt.sweeps.resume import run_resumable  # noqa: E402
from youbot_opt.sweeps.scheduler import ClusterLostError, cluster_threads, connect  # noqa: E402
from youbot_opt.sweeps.store import SweepStore, stored_records  # noqa: E402

TESTS = str(Path(__file__).resolve().parents[1])


@pytest.fixture(scope="module")
def cluster():
    """Two single-threaded worker processes on loopback, stopped after the module."""
    with distributed.LocalCluster(
        n_workers=2,
        threads_per_worker=1,
        processes=True,
        host="127.0.0.1",
        dashboard_address=None,
    ) as c:
        yield c


@pytest.fixture()
def client(cluster):
    with distributed.Client(cluster, set_as_default=False) as cl:
        cl.wait_for_workers(2, timeout=60)
        yield cl


def test_dask_results_equal_the_local_pool(client, cluster):
    """IK (AL and IPOPT) on a Client and on an address: the local pool's results, bit for bit."""
    prob = example_problem("B")
    local = {}
    for method in ("al", "ipopt"):
        local[method] = ik_multistart(
            prob, method=method, n_starts=24, seed=2, sweep=SweepOptions(workers=2)
        )
        remote = ik_multistart(
            prob, method=method, n_starts=24, seed=2, sweep=SweepOptions(executor=client)
        )
        assert remote.n_workers == cluster_threads(client) == 2  # sized from the cluster
        for a, b in zip(local[method].results, remote.results, strict=True):
            assert a.objective == b.objective and a.status == b.status
            np.testing.assert_array_equal(a.configurations, b.configurations)
    by_address = ik_multistart(
        prob, n_starts=24, seed=2, sweep=SweepOptions(executor=cluster.scheduler_address)
    )
    assert [r.objective for r in by_address.results] == [r.objective for r in local["al"].results]


def test_trajectory_multistart_equals_the_local_pool(client):
    """A 15-knot study-1 multistart: same objectives and trajectories on Dask as in the pool."""
    from youbot_opt.reproduction.study1 import study1_problem
    from youbot_opt.trajopt.multistart import run_multistart
    from youbot_opt.trajopt.solver import TrajOptSolver

    solver = TrajOptSolver(study1_problem(15))
    local = run_multistart(solver, 4, seed=3, sweep=SweepOptions(workers=2))
    remote = run_multistart(solver, 4, seed=3, sweep=SweepOptions(executor=client, batch_size=2))
    for a, b in zip(local.starts, remote.starts, strict=True):
        assert (a.key, a.status, a.objective) == (b.key, b.status, b.objective)
        np.testing.assert_array_equal(a.result.trajectory.q, b.result.trajectory.q)


def test_dask_workers_write_their_own_items_into_a_shared_folder(client, tmp_path):
    """worker_writes=True on Dask: the workers write the payloads, the driver checks and records.

    Loopback workers share the folder. Results equal the local pool's; every
    recorded payload matches the SHA-256 of its journal line.
    """
    from youbot_opt.sweeps.records import sha256_file

    prob = example_problem("B")
    shared = SweepOptions(executor=client, worker_writes=True, out=tmp_path)
    got = ik_multistart(prob, n_starts=12, seed=2, sweep=shared)
    ref = ik_multistart(prob, n_starts=12, seed=2, sweep=SweepOptions(executor="serial"))
    assert [r.objective for r in got.results] == [r.objective for r in ref.results]
    records = stored_records(tmp_path)
    assert len(records) == 12
    assert all(sha256_file(tmp_path / "items" / str(r.payload)) == r.checksum for r in records)


def test_a_crash_is_charged_to_one_item_of_its_batch(client):
    """Item k3 segfaults its worker every time: it alone fails, after exactly max_attempts."""
    tasks = faulty([Task(key=f"k{i}", fn=slow_square, args=(float(i), 0.0)) for i in range(8)],
                   crash={"k3"})  # fmt: skip
    seen = []

    def deaths() -> int:
        return int(
            client.run_on_scheduler(lambda dask_scheduler: dask_scheduler._workers_removed_total)
        )

    before = deaths()
    got = run_tasks(tasks, executor=client, batch_size=4, max_attempts=2, on_outcome=seen.append)
    # Dask's own re-runs after a death are refused: the batch k0-k3 dies once (charged to
    # nobody; its items then run alone), then k3 kills one worker per attempt: 3 deaths.
    assert deaths() - before == 3
    assert {k: o.value for k, o in got.items() if o.ok} == {
        f"k{i}": float(i * i) for i in range(8) if i != 3
    }
    assert not got["k3"].ok and "Dask worker died" in got["k3"].error
    assert got["k3"].attempts == 2
    assert [o.key for o in seen].count("k3") == 2  # each attempt charged once
    assert all(o.attempts == 1 for o in seen if o.key != "k3")  # batch mates never charged
    client.wait_for_workers(2, timeout=60)


def _store(out: Path) -> SweepStore:
    def save(value: float, path: Path) -> None:
        path.write_text(json.dumps(value))

    return SweepStore(
        out,
        kind="squares",
        params={"n": 16},
        save=save,
        load=lambda p: json.loads(p.read_text()),
        suffix=".val",
    )


def _square_sweep(out: Path, executor, seconds: float = 0.0):  # type: ignore[no-untyped-def]
    store = _store(out)
    tasks = [Task(key=f"i{i:02d}", fn=slow_square, args=(float(i), seconds)) for i in range(16)]
    return run_resumable(
        tasks,
        store=store,
        options=SweepOptions(executor=executor, batch_size=1),
        load=lambda key: store.load(key),
        convert=lambda o: o.value,
        payload=lambda key, v: (v, {"value": v}),
    )


EXPECTED = {f"i{i:02d}": float(i * i) for i in range(16)}


def test_a_worker_killed_mid_sweep_loses_nothing(client, tmp_path):
    """SIGKILL one worker while items run: the nanny restarts it; every item saved once."""
    pids = client.run(os.getpid)
    killer_done = []

    def kill_later() -> None:
        while len(stored_records(tmp_path)) < 3:
            time.sleep(0.01)
        os.kill(next(iter(pids.values())), signal.SIGKILL)
        killer_done.append(True)

    import threading

    t = threading.Thread(target=kill_later, daemon=True)
    t.start()
    got = _square_sweep(tmp_path, client, seconds=0.15)
    t.join(10)
    assert killer_done == [True]
    assert got.items == EXPECTED  # nothing lost
    done = sorted(r.key for r in stored_records(tmp_path) if r.state == "done")
    assert done == sorted(EXPECTED)  # nothing duplicated: one done record per item
    # The killed worker's item was re-run by Dask or charged and retried: at most 2 attempts.
    assert all(1 <= a <= 2 for a in got.attempts.values())
    client.wait_for_workers(2, timeout=60)


def _spawn(args: list[str], env: dict[str, str]) -> subprocess.Popen:  # type: ignore[type-arg]
    return subprocess.Popen(
        args, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True
    )


def _stop(procs: list[subprocess.Popen]) -> None:  # type: ignore[type-arg]
    for p in procs:
        try:
            os.killpg(p.pid, signal.SIGKILL)  # the session: the process and its children
        except ProcessLookupError:
            pass
        p.wait(timeout=30)


@pytest.mark.slow
def test_scheduler_killed_mid_sweep_says_what_was_saved_then_resumes(tmp_path):
    """SIGKILL the scheduler: ClusterLostError naming the saved items; a rerun completes."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([TESTS, os.environ.get("PYTHONPATH", "")])}
    sched_file = tmp_path / "scheduler.json"
    dask = [sys.executable, "-m", "distributed.cli.dask_scheduler"]
    procs = [_spawn([*dask, "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                     "--scheduler-file", str(sched_file)], env)]  # fmt: skip
    try:
        deadline = time.monotonic() + 60
        while not sched_file.exists() and time.monotonic() < deadline:
            time.sleep(0.1)
        worker = [
            sys.executable,
            "-m",
            "distributed.cli.dask_worker",
            "--nworkers",
            "2",
            "--nthreads",
            "1",
            "--no-dashboard",
            "--scheduler-file",
            str(sched_file),
        ]
        procs.append(_spawn(worker, env))
        client = connect(scheduler_file=sched_file)
        client.wait_for_workers(2, timeout=60)
        out = tmp_path / "run"

        def kill_later() -> None:
            while len(stored_records(out)) < 4:
                time.sleep(0.01)
            os.kill(procs[0].pid, signal.SIGKILL)

        import threading

        threading.Thread(target=kill_later, daemon=True).start()
        with pytest.raises(ClusterLostError, match=r"items are saved in .*run.*resume"):
            _square_sweep(out, client, seconds=0.2)
        client.close(timeout=5)
    finally:
        _stop(procs)
    saved = len({r.key for r in stored_records(out)})
    assert 4 <= saved < 16
    again = _square_sweep(out, "serial")
    assert again.items == EXPECTED and again.resumed == saved
    assert all(a == 1 for a in again.attempts.values())  # nothing was run twice


@pytest.mark.slow
def test_driver_killed_mid_sweep_resumes_on_the_cluster(cluster, tmp_path):
    """SIGKILL the CLI driving an IK sweep on --scheduler twice; the rerun equals a local run."""
    from _sigkill import kill_repeatedly

    out = tmp_path / "ik"
    cmd = [sys.executable, "-m", "youbot_opt", "ikpath", "--example", "B", "--starts", "60",
           "--seed", "5", "--method", "ipopt", "--out", str(out), "--json",
           "--scheduler", cluster.scheduler_address]  # fmt: skip
    summary = kill_repeatedly(cmd, out, n_kills=2, seed=0)
    local = ik_multistart(example_problem("B"), method="ipopt", n_starts=60, seed=5,
                          sweep=SweepOptions(workers=2))  # fmt: skip
    assert len({r.key for r in stored_records(out)}) == 60  # nothing lost
    assert summary is not None
    resumed = ik_multistart(example_problem("B"), method="ipopt", n_starts=60, seed=5,
                            sweep=SweepOptions(executor="serial", out=out))  # fmt: skip
    assert resumed.resumed == 60
    assert [r.objective for r in resumed.results] == [r.objective for r in local.results]


def test_bad_scheduler_settings_are_refused_clearly(tmp_path):
    with pytest.raises(ParameterError, match="executor must be"):
        SweepOptions(executor="tcp:/typo")
    with pytest.raises(ParameterError, match="does not exist"):
        connect(scheduler_file=tmp_path / "none.json")
    with pytest.raises(ParameterError, match="exactly one"):
        connect()
    with pytest.raises(ParameterError, match="batch_size"):
        SweepOptions(batch_size=0)


def test_cli_runs_a_sweep_on_a_scheduler_file(cluster, tmp_path, capsys):
    """``multistart --scheduler-file``: the items run on the cluster; the rerun resumes them."""
    from youbot_opt.cli import main

    sched = tmp_path / "scheduler.json"
    sched.write_text(json.dumps({"address": cluster.scheduler_address}))
    argv = ["multistart", "--knots", "15", "--starts", "3", "--no-refine", "--quiet", "--json",
            "--out", str(tmp_path / "run"), "--scheduler-file", str(sched)]  # fmt: skip
    assert main(argv) == 0
    first = json.loads(capsys.readouterr().out)
    assert main(argv) == 0
    again = json.loads(capsys.readouterr().out)
    assert len({r.key for r in stored_records(tmp_path / "run")}) == 3
    assert first["best"] == again["best"]


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--scheduler", "localhost:8786"], "must be an address such as tcp://"),
        (["--scheduler-file", "no/such/file.json"], "does not exist"),
        (["--scheduler", "tcp://127.0.0.1:9", "--workers", "0"], "--workers 0"),
    ],
)
def test_cli_refuses_bad_scheduler_flags(extra, message, tmp_path, capsys):
    from youbot_opt.cli import main

    argv = ["multistart", "--knots", "15", "--starts", "2", "--out", str(tmp_path), *extra]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err


@pytest.mark.slow
def test_shards_into_one_folder_then_collect(tmp_path):
    """``ikpath --shard 1/2`` and ``2/2`` into one folder, then a plain run collects, equal.

    A job array without Dask: each shard solves its share and exits 0; the run
    without ``--shard`` loads every item (resumed = all) and reports what a
    single run reports. (Subprocesses, as a job array runs them.)
    """
    out = tmp_path / "ik"
    argv = [
        sys.executable,
        "-m",
        "youbot_opt",
        "ikpath",
        "--example",
        "B",
        "--starts",
        "10",
        "--seed",
        "4",
        "--workers",
        "1",
        "--no-progress",
        "--json",
        "--out",
        str(out),
    ]

    def run(*extra: str) -> subprocess.CompletedProcess:  # type: ignore[type-arg]
        done = subprocess.run([*argv, *extra], capture_output=True, text=True, timeout=300)
        assert done.returncode == 0, done.stderr
        return done

    assert "shard 1/2: ran 5 item(s); 5 of 10 items are finished" in run("--shard", "1/2").stderr
    assert "10 of 10 items are finished" in run("--shard", "2/2").stderr
    collected = json.loads(run().stdout)
    single = ik_multistart(example_problem("B"), n_starts=10, seed=4, sweep=SweepOptions(workers=1))
    assert collected["resumed"] == 10 and collected["E"] == single.best.objective
    with pytest.raises(ParameterError, match="needs out="):
        SweepOptions(shard=(1, 2))
    with pytest.raises(ParameterError, match="1 <= i <= k"):
        SweepOptions(shard=(3, 2), out=tmp_path)
