"""Result files edited by an attacker who recomputes every checksum (#29, item 1).

What a loaded result claims is re-established on load against the model and the
caller's tolerances, never the file's: the SHA-256 fields are checksums anyone
can recompute, so each forged file here is written with the package's own
``array_digest``, as an attacker would.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from youbot_opt._files import array_digest
from youbot_opt.exceptions import ResultFileError
from youbot_opt.reproduction.study1 import study1_problem
from youbot_opt.trajopt.certify import Tolerances
from youbot_opt.trajopt.io import load_refined, load_result, save_result
from youbot_opt.trajopt.refine import refine
from youbot_opt.trajopt.solver import TrajOptSolver


@pytest.fixture(scope="module")
def certified_file(tmp_path_factory):
    """A refined, certified youBot plan (8 trapezoidal knots to start) saved with its record."""
    refined = refine(TrajOptSolver(study1_problem(8), "trapezoidal"), beta=0.5)
    assert refined.certified
    path = tmp_path_factory.mktemp("tampered") / "plan.npz"
    return save_result(refined.result, path, refinement=refined.refinement)


def _forge(src: Path, dst: Path, edit) -> Path:
    """Copy ``src`` to ``dst`` with ``edit(meta, arrays)`` applied and checksums recomputed."""
    with np.load(src, allow_pickle=False) as npz:
        arrays = {k: np.array(npz[k]) for k in npz.files}
    meta = json.loads(arrays.pop("metadata").tobytes().decode("utf-8"))
    edit(meta, arrays)
    meta["checksums"] = {k: array_digest(a) for k, a in arrays.items()}
    blob = np.frombuffer(json.dumps(meta).encode("utf-8"), dtype=np.uint8)
    with open(dst, "wb") as handle:
        np.savez_compressed(handle, metadata=blob, **arrays)
    return dst


def _all_tolerances(value: float) -> dict[str, float]:
    return {f.name: value for f in dataclasses.fields(Tolerances)}


def _scale_torques(meta, arrays, factor=1.5):
    for key in list(arrays):
        if key.startswith(("variables__tau", "trajectory__tau")):
            arrays[key] = arrays[key] * factor


def test_the_untouched_file_loads_certified(certified_file):
    """The control: the same file, not edited, loads solved and certified."""
    loaded = load_refined(certified_file)
    assert loaded.result.success and loaded.certified


def test_scaled_torques_with_infinite_file_tolerances_are_refused(certified_file, tmp_path):
    """Torques x1.5, the file's feasibility and certificate tolerances set to 1e300:
    the loader checks at the library's tolerances, so the plan is neither solved
    nor certified, and the message names the file's ignored tolerance."""

    def edit(meta, arrays):
        _scale_torques(meta, arrays)
        meta["feasibility_tol"] = 1e300
        meta["refinement"]["budget"]["tolerances"] = _all_tolerances(1e300)

    path = _forge(certified_file, tmp_path / "x15.npz", edit)
    loaded = load_refined(path)
    assert not loaded.result.success
    assert "collocation defect violated" in loaded.result.message
    assert "not the file's 1e+300" in loaded.result.message
    assert not loaded.certified
    assert load_refined(path).refinement.budget.tolerances.local_position == 1e300  # reported


def test_a_record_that_loosens_the_certificate_does_not_certify(certified_file, tmp_path):
    """The variables left alone, only the trajectory's torques scaled (what the
    certificate simulates) and the record's tolerances set to 1e9: the
    trajectory is rebuilt from the variables and certified at the defaults."""

    def edit(meta, arrays):
        arrays["trajectory__tau"] = arrays["trajectory__tau"] * 1.5
        tolerances = dataclasses.asdict(Tolerances())
        meta["refinement"]["budget"]["tolerances"] = tolerances | {"local_position": 1e9}

    path = _forge(certified_file, tmp_path / "record.npz", edit)
    loaded = load_refined(path)
    assert "trajectory differs from its variables: rebuilt" in loaded.result.message
    np.testing.assert_allclose(
        loaded.result.trajectory.tau, loaded.result.variables["tau"], rtol=0, atol=0
    )
    assert loaded.certified  # the honest variables certify at the default tolerances
    assert "local_position: file 1e+09, used 0.05" in loaded.result.message


def test_a_failing_plan_with_a_forged_record_is_not_certified(certified_file, tmp_path):
    """A certificate-failing motion (torques x1.02, within no certificate tolerance of
    the dynamics) claimed certified with certificate tolerances 1e9 and a
    feasibility tolerance large enough to pass the defect check: the caller's
    defaults refute it."""

    def edit(meta, arrays):
        _scale_torques(meta, arrays, factor=1.02)
        scalars = meta["scalars"]  # reported figures made consistent with the new torques
        scalars["work"] *= 1.02**2
        scalars["objective"] = 0.5 * scalars["duration"] + 0.5 * scalars["work"]
        meta["feasibility_tol"] = 1e9
        meta["refinement"]["budget"]["tolerances"] = _all_tolerances(1e9)

    path = _forge(certified_file, tmp_path / "forged.npz", edit)
    loaded = load_refined(path)
    assert not loaded.certified and not loaded.result.success
    lenient = load_refined(path, feasibility_tol=1e9)  # the caller may choose to be lenient
    assert lenient.result.success
    assert not lenient.certified  # ... but the certificate's defaults still refute it
    assert "not certified" in lenient.refinement.reason


def test_an_unknown_transcription_is_an_error_not_unchecked(certified_file, tmp_path):
    """A method name the loader has no independent defect rule for is refused."""

    def edit(meta, arrays):
        _scale_torques(meta, arrays, factor=3.0)
        meta["method"] = "my_own_rule"

    path = _forge(certified_file, tmp_path / "method.npz", edit)
    with pytest.raises(ResultFileError, match="'my_own_rule' cannot be checked on load"):
        load_result(path)


@pytest.mark.parametrize("bad", [0.0, -1.0, float("nan"), float("inf"), True, "1e-6"])
def test_the_callers_tolerance_is_checked(certified_file, bad):
    from youbot_opt.exceptions import ParameterError

    with pytest.raises(ParameterError, match="feasibility_tol must be a positive finite"):
        load_result(certified_file, feasibility_tol=bad)


def _npy_header(shape: tuple[int, ...]) -> bytes:
    import io

    buffer = io.BytesIO()
    np.lib.format.write_array_header_1_0(
        buffer, {"descr": "<f8", "fortran_order": False, "shape": shape}
    )
    return buffer.getvalue()  # magic string, version and header


def test_a_member_declaring_1e11_floats_is_refused_before_allocating(certified_file, tmp_path):
    """A 1 kB member whose .npy header declares 10^11 floats (800 GB): refused by name."""
    import zipfile

    path = tmp_path / "huge.npz"
    with zipfile.ZipFile(certified_file) as src, zipfile.ZipFile(path, "w") as dst:
        for info in src.infolist():
            if info.filename != "objective_history.npy":
                dst.writestr(info, src.read(info))
        dst.writestr("objective_history.npy", _npy_header((10**11,)) + b"\0" * 800)
    with pytest.raises(ResultFileError, match=r"declares an array of shape \(100000000000,\)"):
        load_result(path)


def test_a_file_larger_than_the_limit_is_refused_unread(certified_file, tmp_path):
    """The total uncompressed size is checked against the limit before any member is read
    (a zip bomb); tested with a small limit, and the library's limit is named."""
    from youbot_opt._files import MAX_RESULT_BYTES, read_npz

    size = certified_file.stat().st_size
    with pytest.raises(ResultFileError, match="more than the limit MAX_RESULT_BYTES = 1000 "):
        read_npz(certified_file, max_bytes=1000)
    assert size < MAX_RESULT_BYTES
    assert read_npz(certified_file).keys() >= {"metadata", "variables__q"}


def test_metadata_nested_1e5_deep_is_a_file_error(certified_file, tmp_path):
    """JSON nested 10^5 deep: a ResultFileError, not a RecursionError."""
    import zipfile

    path = tmp_path / "nested.npz"
    with np.load(certified_file) as npz:
        arrays = {k: np.array(npz[k]) for k in npz.files}
    arrays["metadata"] = np.frombuffer(b"[" * 100_000 + b"]" * 100_000, dtype=np.uint8)
    np.savez_compressed(path, **arrays)
    assert zipfile.is_zipfile(path)
    with pytest.raises(ResultFileError, match="metadata is not valid JSON"):
        load_result(path)
