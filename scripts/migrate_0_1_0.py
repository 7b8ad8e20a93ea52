"""Carry files and sweep stores written by youbot_opt 0.1.0 forward to the current format.

Until 1.0 the package reads one format, the one it writes (ARCHITECTURE rule 11);
this script holds the reading of the older ones. It carries:

- a trajectory result file (``.npz``, schema ``youbot_opt.trajopt_result`` 1) to
  schema 2: the robot's source recorded, ``beta`` a solve-time figure only;
- a sweep store (a folder with ``manifest.json``, schema ``youbot_opt.sweep``):
  the flat layout of schemas 1 and 2 (one record file per item) to the fan-out
  layout and summary journal of schema 3, every payload and summary kept (a
  Pareto point's summary gains the start and solve time it lacked); the
  manifest of a trajectory sweep names its robot by the SHA-256 of its URDF
  (not its path) and its problem carries no ``beta``; its payloads are carried
  as result files are. Other payloads (IK paths) are copied unchanged. Cached
  optima (``optima.json``) are left out: the sweep chooses them again. An IK
  multistart's manifest gains ``start_rng`` and names only the IPOPT fields that
  differ from their default; its summaries' 0.1.0 statuses get today's values.
  Its items are kept as they are: on resume, those whose start is not the start
  the sweep now draws for their key (0.1.0 drew starts 1, 2, ... from one
  generator) are refused, warned about and solved again (#29); start 0 resumes.
- an IK-path result file (``.json``, schema ``youbot_opt.ikpath_result`` 1 or
  ``youbot_opt.spatial_ikpath_result`` 1) to ``youbot_opt.ikpath_result`` 2: the
  status values of 0.1.0 (``"success"``, ...) renamed, a planar file's
  ``constraint_tol`` recorded; also the IK payloads of a sweep store.

Each PATH is carried in place and the original kept beside it as
``PATH.0.1.0.bak`` (refused if that exists), or, with ``--out``, written to a
new path (refused if it exists). Nothing is overwritten silently: the new form
is written to a temporary path first and renamed into place. A path already in
the current format is left alone (and said so).

    python scripts/migrate_0_1_0.py runs/multistart-1 result.npz
    python scripts/migrate_0_1_0.py --urdf my_arm.urdf old_sweep   # its URDF has moved
    python scripts/migrate_0_1_0.py --out new.npz old.npz
    python scripts/migrate_0_1_0.py ik_result.json

Exit status: 0 when every path was carried or already current, 1 otherwise.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
import uuid
import zipfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from youbot_opt._files import atomic_writer, json_digest, json_roundtrip
from youbot_opt.ikpath.io import SCHEMA as IK_SCHEMA
from youbot_opt.ikpath.io import SCHEMA_VERSION as IK_VERSION
from youbot_opt.ikpath.methods.al import ALOptions
from youbot_opt.nlp.ipopt import IpoptOptions
from youbot_opt.robot.catalogue import available_robots
from youbot_opt.robot.source import RobotSource, urdf_digest
from youbot_opt.sweeps.records import ItemRecord
from youbot_opt.sweeps.store import SCHEMA_VERSION as STORE_VERSION
from youbot_opt.sweeps.store import SweepStore
from youbot_opt.trajopt.io import SCHEMA as RESULT_SCHEMA
from youbot_opt.trajopt.io import SCHEMA_VERSION as RESULT_VERSION
from youbot_opt.trajopt.result import DEFAULT_FEASIBILITY_TOL

BACKUP = ".0.1.0.bak"
STORE_SCHEMA = "youbot_opt.sweep"
ITEM_SCHEMA = "youbot_opt.sweep_item"


class MigrationError(Exception):
    """A path that cannot be carried forward (the message says why)."""


# ------------------------------------------------------------------ result files
def read_result(path: Path) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """Return the metadata and arrays of a trajectory result file, of any schema."""
    try:
        with np.load(path, allow_pickle=False) as npz:
            arrays = {key: np.array(npz[key]) for key in npz.files}
    except (OSError, ValueError, zipfile.BadZipFile, EOFError) as exc:
        raise MigrationError(f"not a readable .npz file: {exc}") from exc
    if "metadata" not in arrays:
        raise MigrationError("no metadata entry: not a youbot_opt result file")
    meta = json.loads(arrays.pop("metadata").tobytes().decode("utf-8"))
    if not isinstance(meta, dict) or meta.get("schema") != RESULT_SCHEMA:
        raise MigrationError(f"not a trajectory result file (schema {meta.get('schema')!r})")
    return meta, arrays


def result_is_current(path: Path) -> bool:
    """Return whether the result file is already of the current schema version."""
    return read_result(path)[0].get("schema_version") == RESULT_VERSION


def carry_result(source: Path, target: Path) -> None:
    """Write the result file ``source`` (schema 1) to ``target`` in the current schema."""
    meta, arrays = read_result(source)
    version = meta.get("schema_version")
    if version == RESULT_VERSION:
        shutil.copyfile(source, target)
        return
    if version != 1:
        raise MigrationError(f"trajectory result of unknown schema version {version!r}")
    problem = dict(meta["problem"])
    beta = meta.get("beta", problem.get("beta"))  # 0.1.0: the problem's time weight
    if beta is None:
        raise MigrationError("no beta recorded (neither the file's nor its problem's)")
    problem.pop("beta", None)
    if "robot_source" not in meta:  # 0.1.0 before the robot's source: by name or URDF path
        name = problem["robot"]
        old = name if name in available_robots() else problem.get("urdf_path")
        meta["robot_source"] = None if old is None else RobotSource(source=str(old)).to_json()
    meta.update(
        problem=problem,
        beta=float(beta),
        schema_version=RESULT_VERSION,
        feasibility_tol=meta.get("feasibility_tol", DEFAULT_FEASIBILITY_TOL),
        refinement=meta.get("refinement"),
    )
    payload = json.dumps(meta, allow_nan=True, sort_keys=True).encode("utf-8")
    arrays["metadata"] = np.frombuffer(payload, dtype=np.uint8)
    with atomic_writer(target) as handle:
        np.savez_compressed(handle, **arrays)  # type: ignore[arg-type]


# ------------------------------------------------------------------ sweep stores
def read_manifest(folder: Path) -> dict[str, Any]:
    """Return the manifest of a sweep store, of any schema version."""
    try:
        data = json.loads((folder / "manifest.json").read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise MigrationError(f"unreadable sweep manifest: {exc}") from exc
    if not isinstance(data, dict) or data.get("schema") != STORE_SCHEMA:
        raise MigrationError("manifest.json is not a youbot_opt sweep manifest")
    version = data.get("schema_version")
    if version not in (1, 2, STORE_VERSION):
        raise MigrationError(f"sweep store of unknown schema version {version!r}")
    return data


def flat_records(folder: Path) -> dict[str, ItemRecord]:
    """Return the item records of a flat store (schemas 1 and 2: ``items/<key>.json``)."""
    records = {}
    for path in sorted((folder / "items").glob("*.json")):
        data = json.loads(path.read_text(encoding="utf-8"))
        if not isinstance(data, dict) or data.get("schema") != ITEM_SCHEMA:
            raise MigrationError(f"{path} is not a sweep item record")
        records[str(data["key"])] = ItemRecord(
            key=str(data["key"]),
            state=data["state"],
            attempts=int(data["attempts"]),
            reasons=tuple(str(r) for r in data.get("reasons", ())),
            summary=dict(data.get("summary") or {}),
            payload=data.get("payload"),
        )
    return records


def journal_records(folder: Path, manifest: dict[str, Any]) -> dict[str, ItemRecord]:
    """Return the item records of a schema-3 store, read by the current store."""

    def refuse(*_: object) -> None:
        raise MigrationError("read only")

    store = SweepStore(
        folder,
        kind=manifest["kind"],
        params=manifest["params"],
        save=refuse,
        load=refuse,
        clean=False,
    )
    try:
        return {k: r for k, r in store.records().items() if r is not None}
    finally:
        store.close()


def trajectory_params(params: dict[str, Any], urdf: Path | None) -> dict[str, Any]:
    """Return a trajectory sweep's parameters as the current package records them."""
    problem = dict(params["problem"])
    problem.pop("beta", None)  # 0.1.0 problems carried a default time weight
    if "urdf_sha256" not in problem:  # 0.1.0 before robots were identified by content
        path = problem.pop("urdf_path", None)
        if path is None:
            problem["urdf_sha256"] = None  # a robot built in memory
        else:
            found = Path(path) if Path(path).is_file() else urdf
            if found is None or not found.is_file():
                raise MigrationError(
                    f"its robot's URDF {path} is gone: pass --urdf FILE (the same robot's "
                    "URDF; it is identified by the SHA-256 of its content from now on)"
                )
            problem["urdf_sha256"] = urdf_digest(found, str(problem.get("robot", "robot")))
    problem.pop("urdf_path", None)
    return {**params, "problem": problem}


def carry_store(source: Path, target: Path, urdf: Path | None) -> None:
    """Write the sweep store ``source`` to the new folder ``target`` in the current format."""
    manifest = read_manifest(source)
    version = manifest["schema_version"]
    records = flat_records(source) if version < 3 else journal_records(source, manifest)
    params = manifest["params"]
    trajectory = isinstance(params.get("problem"), dict) and "start_q" in params["problem"]
    if trajectory:
        params = trajectory_params(params, urdf)
    ik = manifest["kind"] == IK_SWEEP_KIND
    if ik:
        params = ik_params(params)
    payloads = [r.payload for r in records.values() if r.payload is not None]
    suffix = Path(payloads[0]).suffix if payloads else ".npz"
    carry: Callable[[Path, Path], None] = (
        carry_result if trajectory and suffix == ".npz" else carry_ik
    )
    target.mkdir()
    store = SweepStore(
        target,
        kind=manifest["kind"],
        params=json_roundtrip(params),
        save=lambda old, new: carry(old, Path(new)),
        load=lambda p: p,
        suffix=suffix,
    )
    try:
        for key, record in records.items():
            summary = dict(record.summary)
            if ik or manifest["kind"] == IK_SWEEP_KIND_3D:
                summary = ik_summary(summary)
            if trajectory and manifest["kind"] == "pareto":  # 0.1.0 points: warm-started
                summary.setdefault("start", "previous")
                summary.setdefault("solve_time_s", 0.0)
            if record.state == "done" and record.payload is not None:
                store.write_done(
                    key, source / "items" / record.payload, summary, attempts=record.attempts
                )
            else:
                for reason in record.reasons or ("failed",):
                    store.write_failed(key, reason, attempts=record.attempts)
    finally:
        store.close()
    for other in source.iterdir():  # a run folder's own files (summary, figures) come along
        if other.name not in ("manifest.json", "items", "optima.json", "optima_members.json"):
            (shutil.copytree if other.is_dir() else shutil.copy2)(other, target / other.name)


def store_is_current(folder: Path) -> bool:
    """Return whether the store is current (schema, and its sweep recorded as now)."""
    manifest = read_manifest(folder)
    if manifest["schema_version"] != STORE_VERSION:
        return False
    problem = manifest["params"].get("problem")
    if isinstance(problem, dict) and "start_q" in problem:
        return "beta" not in problem and "urdf_path" not in problem
    if manifest["kind"] == IK_SWEEP_KIND and ik_params(manifest["params"]) != manifest["params"]:
        return False
    return ik_payloads_are_current(folder, manifest)


def _copy(source: Path, target: Path) -> None:
    shutil.copyfile(source, target)


# ------------------------------------------------------------------ IK-path sweep stores
IK_SWEEP_KIND = "ikpath_multistart"
IK_SWEEP_KIND_3D = "spatial_ikpath_multistart"  # the 3-D IK multistart's store kind
IK_SCHEMA_3D = "youbot_opt.spatial_ikpath_result"  # 0.1.0: a 3-D result's own schema
IK_STATUS = {  # the IKStatus values of 0.1.0 -> SolveStatus values (results and summaries)
    "success": "solved",
    "time_limit": "max_time",
    "numerical_error": "non_finite",
    "check_failed": "constraint_violation",
}


def read_ik_result(path: Path) -> dict[str, Any]:
    """Return the JSON document of an IK-path result file, of any schema (checksum checked)."""
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise MigrationError(f"not a readable JSON file: {exc}") from exc
    if not isinstance(doc, dict) or doc.get("schema") not in (IK_SCHEMA, IK_SCHEMA_3D):
        raise MigrationError("not an IK-path result file")
    body = doc.get("result")
    if not isinstance(body, dict) or doc.get("sha256") != json_digest(body):
        raise MigrationError("checksum mismatch: the IK-path result file is corrupt")
    return doc


def is_ik_result(path: Path) -> bool:
    """Return whether ``path`` is a JSON file of an IK-path result schema (old or current)."""
    try:
        return read_ik_result(path) is not None
    except MigrationError:
        return False


def ik_result_is_current(path: Path) -> bool:
    """Return whether the IK-path result file is already of the current schema."""
    doc = read_ik_result(path)
    return doc["schema"] == IK_SCHEMA and doc.get("schema_version") == IK_VERSION


def _ik_constraint_tol(method: str) -> float:
    """Return the ``|c_i|`` tolerance [m] 0.1.0 solved a planar file with (not recorded)."""
    if method == "ipopt":
        return float(IpoptOptions.for_ikpath().constr_viol_tol)  # type: ignore[arg-type]
    return ALOptions().constraint_tol


def carry_ik_result(source: Path, target: Path) -> None:
    """Write the IK-path result file ``source`` (0.1.0) to ``target`` in the current schema."""
    doc = read_ik_result(source)
    if doc["schema"] == IK_SCHEMA and doc.get("schema_version") == IK_VERSION:
        shutil.copyfile(source, target)
        return
    if doc.get("schema_version") != 1:
        raise MigrationError(
            f"IK-path result of unknown schema version {doc.get('schema_version')!r}"
        )
    body = dict(doc["result"])
    body["status"] = IK_STATUS.get(body["status"], body["status"])
    if "chain" in body:  # a planar method's result: its tolerance recorded from now on
        body.setdefault("constraint_tol", _ik_constraint_tol(str(body["method"])))
    new = {
        **doc,
        "schema": IK_SCHEMA,
        "schema_version": IK_VERSION,
        "sha256": json_digest(body),
        "result": body,
    }
    with atomic_writer(target) as handle:
        handle.write((json.dumps(new, indent=1, allow_nan=False) + "\n").encode())


def carry_ik(source: Path, target: Path) -> None:
    """Carry a sweep store's payload: an IK-path result file as above, any other copied."""
    if is_ik_result(source):
        carry_ik_result(source, target)
    else:
        _copy(source, target)


def ik_payloads_are_current(folder: Path, manifest: dict[str, Any]) -> bool:
    """Return whether every IK-path payload of a current-schema store is current too."""
    for record in journal_records(folder, manifest).values():
        payload = None if record.payload is None else folder / "items" / record.payload
        if payload is not None and is_ik_result(payload) and not ik_result_is_current(payload):
            return False
    return True


def file_kind(path: Path) -> str:
    """Return what the file ``path`` holds: ``"IK-path result"`` or ``"trajectory result"``."""
    return "IK-path result" if is_ik_result(path) else "trajectory result"


FILE_KINDS: dict[str, tuple[Callable[[Path], bool], Callable[[Path, Path], None]]] = {
    "trajectory result": (result_is_current, carry_result),
    "IK-path result": (ik_result_is_current, carry_ik_result),
}
"""Per kind of file: whether it is current, and how it is carried forward."""


def ik_params(params: dict[str, Any]) -> dict[str, Any]:
    """Return an IK multistart's manifest parameters in today's form.

    Its starts are drawn per index (``start_rng``; a store of 0.1.0 drew them
    from one generator: the starts it did not finish are drawn anew, and a
    finished one whose item carries another start is refused on resume and
    solved again), and its
    IPOPT settings name only the fields that differ from their IK default
    (commit 02cdf49 wrote every field).
    """
    from youbot_opt.ikpath.sweep import options_json
    from youbot_opt.nlp.ipopt import IpoptOptions

    params = dict(params)
    params.setdefault("start_rng", "per-index")
    options = params.get("options")
    if isinstance(options, dict) and options.get("type") == "IpoptOptions":
        fields = {k: v for k, v in options.items() if k != "type"}
        params["options"] = json_roundtrip(options_json("ipopt", IpoptOptions.for_ikpath(**fields)))
    return params


def ik_summary(summary: dict[str, Any]) -> dict[str, Any]:
    """Return an IK start's journal summary with today's status value."""
    status = summary.get("status")
    return {**summary, "status": IK_STATUS.get(status, status)}


# ------------------------------------------------------------------ the command
def migrate(path: Path, out: Path | None, urdf: Path | None) -> str:
    """Carry one path forward; return the line to print (raise MigrationError on failure)."""
    store = path.is_dir()
    if store and not (path / "manifest.json").is_file():
        raise MigrationError("a folder without manifest.json: not a sweep store")
    if not store and not path.is_file():
        raise MigrationError("no such file or folder")
    what = "sweep store" if store else file_kind(path)
    if store_is_current(path) if store else FILE_KINDS[what][0](path):
        return f"{path}: already current ({what}), left alone"
    target = out if out is not None else path
    backup = Path(str(path) + BACKUP)
    if out is not None and (out.exists() or out.is_symlink()):
        raise MigrationError(f"{out} exists; choose a new path (nothing is overwritten)")
    if out is None and (backup.exists() or backup.is_symlink()):
        raise MigrationError(f"the backup {backup} exists; move it away first")
    tmp = target.with_name(f".migrating-{target.name}.{uuid.uuid4().hex[:8]}")
    try:
        if store:
            carry_store(path, tmp, urdf)
        else:
            FILE_KINDS[what][1](path, tmp)
        if out is None:
            path.rename(backup)  # the original first: it is never lost
        if store:
            tmp.rename(target)  # refused by the system if a non-empty folder appeared there
        else:
            os.link(tmp, target)  # never replaces a file that appeared meanwhile
    finally:
        if tmp.is_dir():
            shutil.rmtree(tmp, ignore_errors=True)
        else:
            tmp.unlink(missing_ok=True)
    kept = f" (the 0.1.0 original kept as {backup})" if out is None else ""
    return f"{path}: {what} of 0.1.0 carried forward to {target}{kept}"


def main(argv: list[str] | None = None) -> int:
    """Run the command; return its exit status."""
    parser = argparse.ArgumentParser(
        prog="python scripts/migrate_0_1_0.py",
        description="Carry result files and sweep stores written by youbot_opt 0.1.0 forward.",
    )
    parser.add_argument("paths", nargs="+", type=Path, metavar="PATH")
    parser.add_argument(
        "--out", type=Path, help="write the carried form here (one PATH only), not in place"
    )
    parser.add_argument(
        "--urdf", type=Path, help="the robot's URDF, for a trajectory sweep whose URDF has moved"
    )
    args = parser.parse_args(argv)
    if args.out is not None and len(args.paths) != 1:
        parser.error("--out takes one PATH")
    failed = 0
    for path in args.paths:
        try:
            print(migrate(path, args.out, args.urdf))
        except (MigrationError, OSError, KeyError, TypeError, ValueError) as exc:
            print(f"{path}: not carried: {exc}", file=sys.stderr)
            failed += 1
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
