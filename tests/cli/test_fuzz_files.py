"""File and option fuzzing beyond the command line (#29 item 7).

Hypothesis draws hostile inputs for the surfaces a user hands the library as
files or strings: target files (CSV and JSON), saved results (trajectory
``.npz`` and IK JSON: bytes cut, flipped and metadata fields replaced), sweep
stores (journal lines re-encoded with the library's own checksum, so they pass
it, with fields replaced) and the Dask options (addresses, scheduler files).
Each must end in a result or a library error
(:class:`~youbot_opt.exceptions.YoubotOptError`, one line), never another
exception; derandomized with a fixed budget, so CI draws the same inputs.
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from youbot_opt.exceptions import YoubotOptError

N_EXAMPLES = int(os.environ.get("FUZZ_EXAMPLES", "40"))
SETTINGS = settings(
    max_examples=N_EXAMPLES,
    derandomize=True,
    deadline=None,
    database=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
)

# JSON values a hostile file puts where another value belongs
HOSTILE: list[Any] = [None, True, -1, 0, 2**63, 1e308, -1e308, "nan", "x", "", "é" * 50, [],
                      [1, 2], {}, {"a": 1}, [[[]]], "a" * 5000, 0.5, [0.1, 0.2, 0.3]]  # fmt: skip
JSON_VALUES = st.recursive(
    st.sampled_from(HOSTILE) | st.floats(allow_nan=True) | st.text(max_size=20),
    lambda inner: (
        st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=8), inner, max_size=4)
    ),
    max_leaves=12,
)


def _clean(call: Callable[[], object]) -> None:
    """Run ``call``: a value or a one-line library error, never another exception."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            call()
        except YoubotOptError as exc:
            assert "\n" not in str(exc).strip() or "Traceback" not in str(exc)
            assert len(str(exc)) < 20_000, str(exc)[:200]


def _replace(doc: Any, path: list[int], value: Any) -> Any:
    """Replace the node of ``doc`` chosen by ``path`` (indices into its children) by ``value``."""
    if not path or not isinstance(doc, dict | list) or not doc:
        return value
    keys = list(doc) if isinstance(doc, dict) else list(range(len(doc)))
    key = keys[path[0] % len(keys)]
    out = dict(doc) if isinstance(doc, dict) else list(doc)
    out[key] = _replace(doc[key], path[1:], value)  # type: ignore[index]
    return out


# ---------------------------------------------------------------- target files
CSV_CELLS = ["0.3", "0", "-0.2", "", "nan", "inf", "x", "1e308", "0,5", " ", '"1"', "é", "1" * 400]
CSV_HEADERS = ["x", "y", "z", "qx", "qy", "qz", "qw", "QX", "ax", "ay", "az", "position_tol",
               "orientation_tol", "orientation_weight", "bogus", "", "x "]  # fmt: skip


@pytest.mark.slow
@SETTINGS
@given(
    header=st.lists(st.sampled_from(CSV_HEADERS), min_size=0, max_size=8),
    rows=st.lists(st.lists(st.sampled_from(CSV_CELLS), max_size=9), max_size=5),
    raw=st.binary(max_size=40),
)
def test_fuzz_target_csv(
    header: list[str], rows: list[list[str]], raw: bytes, tmp_path: Path
) -> None:
    from youbot_opt.ikpath.targets import load_targets

    path = tmp_path / "t.csv"
    text = "\n".join([",".join(header), *(",".join(r) for r in rows)]).encode() + raw
    path.write_bytes(text)
    _clean(lambda: load_targets(path))


@pytest.mark.slow
@SETTINGS
@given(doc=JSON_VALUES, where=st.lists(st.integers(0, 9), max_size=4), value=JSON_VALUES)
def test_fuzz_target_json(doc: Any, where: list[int], value: Any, tmp_path: Path) -> None:
    from youbot_opt.ikpath.targets import load_targets

    good = {"targets": [{"position": [0.3, 0.0, 0.4], "quaternion_xyzw": [0, 0, 0, 1]},
                        {"position": [0.2, 0.1, 0.4], "position_tol": 1e-4}]}  # fmt: skip
    path = tmp_path / "t.json"
    for body in (doc, _replace(good, where, value)):
        path.write_text(json.dumps(body, allow_nan=True))
        _clean(lambda: load_targets(path))


# ---------------------------------------------------------------- result loaders
@pytest.fixture(scope="module")
def saved_results(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """One solved trajectory result (.npz) and one IK result (JSON), with their robots."""
    from youbot_opt.ikpath.examples import example_problem
    from youbot_opt.ikpath.io import save_result as save_ik
    from youbot_opt.ikpath.solve import solve as solve_ik
    from youbot_opt.reproduction.study1 import study1_problem
    from youbot_opt.trajopt.io import save_result
    from youbot_opt.trajopt.solver import TrajOptSolver

    folder = tmp_path_factory.mktemp("fuzz_results")
    problem = study1_problem(8)
    result = TrajOptSolver(problem).solve(beta=0.5)
    save_result(result, folder / "r.npz")
    ik = solve_ik(example_problem("A"))
    save_ik(ik, folder / "ik.json")
    return {"folder": folder, "robot": problem.robot}


@pytest.mark.slow
@SETTINGS
@given(
    cut=st.integers(0, 4000),
    flips=st.lists(st.tuples(st.integers(0, 10**6), st.integers(1, 255)), max_size=4),
    where=st.lists(st.integers(0, 30), min_size=1, max_size=4),
    value=JSON_VALUES,
    mode=st.sampled_from(["bytes", "metadata"]),
)
def test_fuzz_trajectory_result_file(
    saved_results: dict[str, Any],
    cut: int,
    flips: list[tuple[int, int]],
    where: list[int],
    value: Any,
    mode: str,
    tmp_path: Path,
) -> None:
    from youbot_opt.trajopt.io import load_result

    src = saved_results["folder"] / "r.npz"
    path = tmp_path / "r.npz"
    if mode == "bytes":
        data = bytearray(src.read_bytes())
        data = data[: max(0, len(data) - cut)] if cut % 2 else data
        for at, x in flips:
            if data:
                data[at % len(data)] ^= x
        path.write_bytes(bytes(data))
    else:  # a metadata field replaced, the file otherwise intact
        with np.load(src) as z:
            arrays = {k: z[k] for k in z.files}
        meta = json.loads(arrays["metadata"].tobytes())
        meta = _replace(meta, where, value)
        arrays["metadata"] = np.frombuffer(json.dumps(meta, allow_nan=True).encode(), np.uint8)
        with path.open("wb") as fh:
            np.savez(fh, **arrays)  # type: ignore[arg-type]
    _clean(lambda: load_result(path, robot=saved_results["robot"]))
    _clean(lambda: load_result(path))


@pytest.mark.slow
@SETTINGS
@given(where=st.lists(st.integers(0, 30), min_size=1, max_size=5), value=JSON_VALUES,
       cut=st.integers(0, 300))  # fmt: skip
def test_fuzz_ik_result_file(
    saved_results: dict[str, Any], where: list[int], value: Any, cut: int, tmp_path: Path
) -> None:
    from youbot_opt.ikpath.io import load_result

    doc = json.loads((saved_results["folder"] / "ik.json").read_text())
    path = tmp_path / "ik.json"
    text = json.dumps(_replace(doc, where, value), allow_nan=True)
    path.write_text(text[: len(text) - cut] if cut % 3 == 0 else text)
    _clean(lambda: load_result(path))


# ---------------------------------------------------------------- sweep stores
def _codec() -> Any:
    from youbot_opt.sweeps.store import Codec, atomic_write_bytes

    def save(value: Any, path: Path) -> None:
        atomic_write_bytes(path, json.dumps(value).encode())

    def load(path: Path) -> Any:
        return json.loads(path.read_text())

    return Codec(save=save, load=load, suffix=".val")


@pytest.fixture(scope="module")
def store_template(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A small store: 3 done items and a failed one."""
    from youbot_opt.sweeps.store import open_store

    out = tmp_path_factory.mktemp("fuzz_store") / "s"
    store = open_store(out, "fuzz", {"n": 4}, _codec())
    for i in range(3):
        store.write_done(f"item_{i}", {"v": i}, {"objective": float(i)})
    store.write_failed("item_3", "boom", attempts=1)
    store.close()
    return out


@pytest.mark.slow
@SETTINGS
@given(
    line=st.integers(0, 3),
    where=st.lists(st.integers(0, 20), min_size=1, max_size=3),
    value=JSON_VALUES,
    manifest=st.booleans(),
)
def test_fuzz_sweep_store(
    store_template: Path, line: int, where: list[int], value: Any, manifest: bool, tmp_path: Path
) -> None:
    """A line re-encoded with our checksum (it passes it) or the manifest, a field replaced."""
    from youbot_opt.sweeps.journal import encode_line, read_journal
    from youbot_opt.sweeps.store import open_store

    out = Path(tempfile.mkdtemp(dir=tmp_path)) / "s"  # one per example
    shutil.copytree(store_template, out)
    if manifest:
        doc = json.loads((out / "manifest.json").read_text())
        (out / "manifest.json").write_text(json.dumps(_replace(doc, where, value), allow_nan=True))
    else:
        folder = out / "items" / "journal"
        lines, _ = read_journal(folder)
        lines[line % len(lines)] = _replace(lines[line % len(lines)], where, value)
        for old in folder.iterdir():
            old.unlink()
        (folder / "forged.jsonl").write_bytes(b"".join(encode_line(x) for x in lines))

    def resume() -> None:
        store = open_store(out, "fuzz", {"n": 4}, _codec())
        for i in range(4):
            key = f"item_{i}"
            store.needs_work(key, 2)
            if store.verify(key):
                rec = store.record(key)
                if rec is not None and rec.state == "done":
                    store.load(key)
        store.close()

    _clean(resume)


# ---------------------------------------------------------------- Dask options
@pytest.mark.slow
@SETTINGS
@given(
    address=st.text(max_size=60)
    | st.sampled_from(["tcp://", "tls://", "inproc://x", "tcp://" + "h" * 5000 + ":1",
                       "tcp://127.0.0.1:1", "ucx://[::1]:8786", "tcp://[::1:1", "tcp://a:b"]),
    content=st.binary(max_size=80) | JSON_VALUES.map(lambda v: json.dumps(v).encode()),
)  # fmt: skip
def test_fuzz_dask_options(address: str, content: bytes, tmp_path: Path) -> None:
    """Addresses are checked without connecting; scheduler files are read bounded."""
    from youbot_opt.sweeps.scheduler import check_scheduler_address, read_scheduler_file

    _clean(lambda: check_scheduler_address(address))
    path = tmp_path / "scheduler.json"
    path.write_bytes(content)
    _clean(lambda: read_scheduler_file(path))
