"""Files written by youbot_opt at commit 74bfa23 load and resume with today's code.

The fixtures in ``tests/fixtures/files_74bfa23`` were written by that commit
(see the README there); they must never be regenerated. The package refuses
them naming ``scripts/migrate_0_1_0.py``; carried by it (the store's layout,
its IK payloads and the result file), they load and resume with their numbers.
"""

from __future__ import annotations

import dataclasses
import json
import shutil
from collections.abc import Callable
from pathlib import Path

import pytest

from _migrate import REFUSAL, migrate
from youbot_opt.exceptions import ParameterError, ResultFileError, YoubotOptWarning
from youbot_opt.ikpath.examples import example_problem
from youbot_opt.ikpath.io import load_result
from youbot_opt.ikpath.methods.al import ALOptions
from youbot_opt.ikpath.multistart import run_multistart
from youbot_opt.nlp.ipopt import IpoptOptions
from youbot_opt.nlp.status import SolveStatus
from youbot_opt.sweeps.options import SweepOptions

OLD = Path(__file__).resolve().parents[1] / "fixtures" / "files_74bfa23"


def _old_store(tmp_path: Path, edit: Callable[[Path], None] | None = None) -> Path:
    """A copy of the 0.1.0 store (``edit``-ed), carried to today's layout by the script."""
    out = tmp_path / "ik_sweep"
    shutil.copytree(OLD / "ik_sweep", out)
    if edit is not None:
        edit(out / "manifest.json")
    done = migrate(out)  # the flat layout of 0.1.0 to the journal, the IK payloads carried
    assert done.returncode == 0, done.stderr
    return out


def test_old_store_is_refused_naming_the_migration(tmp_path):
    """The flat 0.1.0 store itself is refused by the sweep store, naming the script."""
    out = tmp_path / "ik_sweep"
    shutil.copytree(OLD / "ik_sweep", out)
    with pytest.raises(ResultFileError, match=REFUSAL):
        _resume(out)


def _resume(out: Path, options: IpoptOptions | None = None):
    """Run the multistart that wrote the fixture store (example A, IPOPT, 3 starts, seed 1)."""
    return run_multistart(
        example_problem("A"),
        method="ipopt",
        n_starts=3,
        seed=1,
        options=options,
        sweep=SweepOptions(executor="serial", out=out),
    )


def _resume_refusing_old_starts(out: Path):
    """Resume a carried 0.1.0 store: starts 1 and 2 were drawn by 0.1.0's single generator.

    Their items carry those starts, which are not the starts 1 and 2 this sweep
    draws (per index), so they are refused, warned about and solved again (#29);
    start 0 (the zero start, the same in both) is loaded.
    """
    with pytest.warns(YoubotOptWarning, match=r"start_000[12].*its start is not start [12]"):
        return _resume(out)


def test_old_ipopt_sweep_store_resumes_without_solving_start_0(tmp_path):
    """An IK IPOPT multistart store of 74bfa23 resumes: start 0 loaded, manifest kept.

    Starts 1 and 2 are solved again from today's starts: the result equals a fresh run.
    """
    out = _old_store(tmp_path)
    manifest = (out / "manifest.json").read_text()
    params = json.loads(manifest)["params"]
    assert set(params["options"]) == {
        "type", "tol", "constr_viol_tol", "max_iter", "max_wall_time", "extra"
    }  # fmt: skip
    assert params["start_rng"] == "per-index"  # added by the script
    carried = {p.stem: load_result(p) for p in out.glob("items/*/*.ikpath")}
    assert sorted(carried) == ["start_0000", "start_0001", "start_0002"]
    # The old writer's IKStatus value "success" is carried to SOLVED; E as stored by 74bfa23.
    assert [r.status for r in carried.values()] == [SolveStatus.SOLVED] * 3
    assert min(r.objective for r in carried.values()) == 7.069456165533798
    result = _resume_refusing_old_starts(out)
    assert result.resumed == 1
    assert [r.status for r in result.results] == [SolveStatus.SOLVED] * 3
    assert result.results[0].objective == carried["start_0000"].objective  # loaded, not solved
    fresh = _resume(tmp_path / "fresh")
    assert [r.objective for r in result.results] == [r.objective for r in fresh.results]
    assert result.best.objective == fresh.best.objective
    assert (out / "manifest.json").read_text() == manifest
    assert _resume(out).resumed == 3  # solved again and bound: loaded without a word


def test_old_store_refuses_options_that_differ_in_a_new_field(tmp_path):
    """A field added since 74bfa23 (hessian) set to a non-default value is a parameter change."""
    with pytest.raises(ParameterError, match="parameters differ.*hessian"):
        _resume(_old_store(tmp_path), IpoptOptions.for_ikpath(hessian="limited-memory"))


def test_old_ik_result_file_is_refused_naming_the_migration():
    """The AL result file of 74bfa23 (schema 1) is refused; the message names the script."""
    with pytest.raises(ResultFileError, match=REFUSAL):
        load_result(OLD / "ik_al.json")


def test_old_ik_result_file_migrated_loads_and_passes_the_check(tmp_path):
    """Migrated, the AL result file of 74bfa23 loads with its stored E, SOLVED, re-checks clean."""
    stored = json.loads((OLD / "ik_al.json").read_text())["result"]
    assert stored["status"] == "success"  # the old IKStatus value
    new = tmp_path / "ik_al.json"
    done = migrate("--out", new, OLD / "ik_al.json")
    assert done.returncode == 0, done.stderr
    assert "IK-path result of 0.1.0 carried forward" in done.stdout
    result = load_result(new)
    assert result.status is SolveStatus.SOLVED and result.method == "al"
    assert abs(result.objective - stored["objective"]) <= 1e-12  # recomputed by Pinocchio
    assert result.constraint_tol == ALOptions().constraint_tol  # 0.1.0's default, recorded
    assert result.check().passed


def test_old_store_payload_is_refused_naming_the_migration(tmp_path):
    """An IK payload of the 0.1.0 store, read alone, is refused naming the script too."""
    with pytest.raises(ResultFileError, match=REFUSAL):
        load_result(OLD / "ik_sweep" / "items" / "start_0000.ikpath")


def test_store_with_every_ipopt_field_is_refused_then_carried(tmp_path):
    """A manifest holding every IpoptOptions field (as commit 02cdf49 wrote it) is carried too."""

    def every_field(path: Path) -> None:
        manifest = json.loads(path.read_text())
        defaults = IpoptOptions.for_ikpath()
        later = {"fast_kkt", "linear_solver_library"}  # added after 02cdf49, absent from its files
        full = {
            f.name: getattr(defaults, f.name)
            for f in dataclasses.fields(defaults)
            if f.name not in later
        }
        full = {"type": "IpoptOptions", **full, "extra": {}}
        assert len(full) == 11  # every field, as 02cdf49 wrote them
        manifest["params"]["options"] = full
        path.write_text(json.dumps(manifest, indent=1))

    out = _old_store(tmp_path, every_field)
    assert _resume_refusing_old_starts(out).resumed == 1  # start 0; 1 and 2 drawn by 0.1.0
    # The same form in a store of today's schema is refused, naming the script.
    every_field(out / "manifest.json")
    shutil.rmtree(str(out) + ".0.1.0.bak")
    with pytest.raises(ResultFileError, match=REFUSAL):
        _resume(out)
