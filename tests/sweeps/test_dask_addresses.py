"""Hostile Dask addresses and scheduler files: one-line errors, within a bound, no hang (#29)."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest

pytest.importorskip("distributed")

from youbot_opt.cli import main  # noqa: E402
from youbot_opt.exceptions import ParameterError  # noqa: E402
from youbot_opt.sweeps.scheduler import (  # noqa: E402
    MAX_ADDRESS_CHARS,
    MAX_SCHEDULER_FILE_BYTES,
    check_scheduler_address,
    connect,
    read_scheduler_file,
)

_MAIN = "import sys; from youbot_opt.cli import main; sys.exit(main(sys.argv[1:]))"
SRC = str(Path(__file__).resolve().parents[2] / "src")


@contextmanager
def listener(mode: str) -> Iterator[int]:
    """A TCP listener on 127.0.0.1 that sends garbage or accepts and stays silent."""
    srv = socket.socket()
    srv.bind(("127.0.0.1", 0))
    srv.listen(8)
    conns: list[socket.socket] = []

    def serve() -> None:
        while True:
            try:
                conn, _ = srv.accept()
            except OSError:
                return
            conns.append(conn)
            if mode == "garbage":
                try:
                    conn.sendall(b"\xff\x00garbage" * 512)
                except OSError:
                    pass

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    try:
        yield srv.getsockname()[1]
    finally:
        srv.shutdown(socket.SHUT_RDWR)  # wakes the accept
        srv.close()
        for conn in conns:
            conn.close()
        thread.join(5)


@pytest.mark.parametrize(
    ("address", "message"),
    [
        ("tcp://", "needs a host and a port"),
        ("tcp://127.0.0.1", "needs a host and a port"),
        ("tcp://127.0.0.1:0", "needs a host and a port"),
        ("tcp://127.0.0.1:99999", "is not SCHEME://HOST:PORT"),
        ("inproc://x", "must start with one of"),
        ("tcp://" + "h" * 5000 + ":8786", f"limit of {MAX_ADDRESS_CHARS}"),
        ("tcp://a b:1", "spaces or control"),
        ("tcp://host:1/path", "nothing more"),
        (8786, "must be a string"),
    ],
)
def test_insane_addresses_are_refused_before_connecting(address, message):
    tic = time.monotonic()
    with pytest.raises(ParameterError, match=message):
        connect(address)
    assert time.monotonic() - tic < 1.0
    with pytest.raises(ParameterError, match=message):
        check_scheduler_address(address)


@pytest.mark.parametrize("mode", ["garbage", "silent"])
def test_a_listener_that_is_not_dask_ends_in_one_error_within_the_bound(mode):
    with listener(mode) as port:
        tic = time.monotonic()
        with pytest.raises(ParameterError) as info:
            connect(f"tcp://127.0.0.1:{port}", timeout=3.0)
        elapsed = time.monotonic() - tic
    assert elapsed < 3.0 + 2.0
    message = str(info.value)
    assert f"tcp://127.0.0.1:{port}" in message and "3 s" in message and "\n" not in message


def test_tls_without_a_context_ends_in_one_error_within_the_bound():
    with listener("silent") as port:
        tic = time.monotonic()
        with pytest.raises(ParameterError, match=f"tls://127.0.0.1:{port}"):
            connect(f"tls://127.0.0.1:{port}", timeout=3.0)
        assert time.monotonic() - tic < 5.0


def test_cli_with_a_garbage_listener_prints_one_line_and_no_traceback(tmp_path):
    with listener("garbage") as port:
        address = f"tcp://127.0.0.1:{port}"
        argv = ["multistart", "--knots", "15", "--starts", "2", "--no-refine", "--quiet",
                "--out", str(tmp_path / "run"), "--scheduler", address]  # fmt: skip
        env = {**os.environ, "PYTHONPATH": SRC}
        tic = time.monotonic()
        proc = subprocess.run(
            [sys.executable, "-c", _MAIN, *argv],
            capture_output=True, text=True, env=env, timeout=120,
        )  # fmt: skip
        elapsed = time.monotonic() - tic
    assert proc.returncode == 2, proc.stderr
    assert "Traceback" not in proc.stderr
    lines = [line for line in proc.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and f"tcp://127.0.0.1:{port}" in lines[0], proc.stderr
    assert elapsed < 60


def _fifo(tmp_path: Path) -> Path:
    fifo = tmp_path / "fifo.json"
    os.mkfifo(fifo)
    return fifo


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (_fifo, "not a regular file"),
        (lambda tmp_path: Path("/dev/zero"), "not a regular file"),
        (lambda tmp_path: tmp_path, "not a regular file"),
        (
            lambda tmp_path: _write(tmp_path, b" " * (MAX_SCHEDULER_FILE_BYTES + 1)),
            f"limit of {MAX_SCHEDULER_FILE_BYTES} bytes",
        ),
        (lambda tmp_path: _write(tmp_path, b"[1, 2]"), "not a Dask scheduler file"),
        (lambda tmp_path: _write(tmp_path, b"[" * 100_000), "not a Dask scheduler file"),
        (lambda tmp_path: _write(tmp_path, b'{"address": "tcp://"}'), "host and a port"),
    ],
)
def test_hostile_scheduler_files_are_refused_without_blocking(tmp_path, make, message, capsys):
    path = make(tmp_path)
    tic = time.monotonic()
    with pytest.raises(ParameterError, match=message):
        read_scheduler_file(path)
    with pytest.raises(ParameterError, match=message):
        connect(scheduler_file=path)
    argv = ["multistart", "--knots", "15", "--starts", "2", "--out", str(tmp_path / "run"),
            "--scheduler-file", str(path)]  # fmt: skip
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err
    assert time.monotonic() - tic < 5.0


def _write(tmp_path: Path, data: bytes) -> Path:
    path = tmp_path / "scheduler.json"
    path.write_bytes(data)
    return path


def test_a_good_scheduler_file_gives_its_address(tmp_path):
    path = _write(tmp_path, b'{"address": "tcp://10.0.0.5:8786", "type": "Scheduler"}')
    assert read_scheduler_file(path) == "tcp://10.0.0.5:8786"
