"""IK-path targets: a position (in 3-D or in a planar robot's plane), a pose, or an approach axis.

A :class:`Target` says what the chosen frame must reach: its origin at
``position`` [m] and, optionally, its orientation equal to ``rotation`` (a
pose) or its local ``approach_axis`` pointing along the world direction
``approach`` (an approach axis, e.g. a drill or a suction cup: rotation about
the axis is free). Each target carries the tolerances that decide whether it
is met ([m] and [rad]) and the weight [m/rad] that puts orientation rows into
the constraint's metre scale (see docs/ikpath.md, "3-D targets").
"""

from __future__ import annotations

import csv
import io
import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike

from youbot_opt._checks import shown
from youbot_opt._files import read_input_text
from youbot_opt._typing import Array
from youbot_opt.exceptions import ParameterError

__all__ = [
    "Target",
    "TARGET_KINDS",
    "MAX_TARGETS",
    "MAX_TARGETS_FILE_BYTES",
    "load_targets",
    "position_targets",
    "quaternion_to_matrix",
]

TARGET_KINDS: tuple[str, ...] = ("position", "pose", "approach")
"""Kinds of targets: constraint rows 3, 6 and 5."""


def _vector3(value: ArrayLike, name: str) -> Array:
    arr = np.array(value, dtype=float).reshape(-1)
    if arr.shape != (3,) or not np.all(np.isfinite(arr)):
        raise ParameterError(
            f"{name} must be 3 finite numbers, got {np.asarray(value).tolist()!r}",
            name=name,
            value=value,
        )
    return arr


def quaternion_to_matrix(quat_xyzw: ArrayLike) -> Array:
    """Rotation matrix of a quaternion ``(x, y, z, w)`` (normalised first).

    Raises
    ------
    ParameterError
        If the quaternion is not 4 finite numbers of norm > 1e-9.
    """
    q = np.array(quat_xyzw, dtype=float).reshape(-1)
    if q.shape != (4,) or not np.all(np.isfinite(q)) or np.linalg.norm(q) < 1e-9:
        raise ParameterError(
            f"a quaternion must be 4 finite numbers (x, y, z, w) of nonzero norm, got "
            f"{np.asarray(quat_xyzw).tolist()!r}",
            name="quaternion",
            value=quat_xyzw,
        )
    q = q / np.linalg.norm(q)
    return np.array(pin.Quaternion(q[3], q[0], q[1], q[2]).toRotationMatrix())


@dataclass(frozen=True, slots=True, kw_only=True, eq=False)
class Target:
    """One target of a cyclic IK path (any robot; a planar one: positions in its plane).

    Attributes
    ----------
    position : ndarray, shape (3,) or (2,)
        Position of the frame's origin in the world, in [m]; 2 numbers are the
        plane coordinates of a planar robot (a position target only; the
        problem turns them into a world position on its plane).
    rotation : ndarray, shape (3, 3), optional
        Orientation of the frame in the world (a pose target).
    approach : ndarray, shape (3,), optional
        World direction (normalised here) the frame's ``approach_axis`` must
        point along (an approach target); exclusive with ``rotation``.
    approach_axis : ndarray, shape (3,)
        Axis of the frame (its own coordinates) that must point along
        ``approach``; default z.
    position_tol : float
        Largest accepted distance from ``position`` in [m].
    orientation_tol : float
        Largest accepted orientation error in [rad] (rotation angle of
        ``rotation^T R`` for a pose, angle between the axes for an approach).
    orientation_weight : float
        Scale in [m/rad] of the orientation rows of the constraint (1 m/rad:
        one radian weighs like one metre when the solvers measure violation).
    """

    position: Array
    rotation: Array | None = None
    approach: Array | None = None
    approach_axis: Array = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))
    position_tol: float = 1e-6
    orientation_tol: float = 1e-6
    orientation_weight: float = 1.0

    def __post_init__(self) -> None:
        pos = np.array(self.position, dtype=float).reshape(-1)
        planar = pos.shape == (2,) and self.rotation is None and self.approach is None
        if planar and np.all(np.isfinite(pos)):  # plane coordinates of a planar robot
            object.__setattr__(self, "position", pos)
        else:
            object.__setattr__(self, "position", _vector3(self.position, "position"))
        if self.rotation is not None and self.approach is not None:
            raise ParameterError(
                "a target has either a rotation (pose) or an approach axis, not both",
                name="approach",
                value=self.approach,
            )
        if self.rotation is not None:
            rot = np.array(self.rotation, dtype=float)
            if rot.shape != (3, 3) or not np.all(np.isfinite(rot)):
                raise ParameterError(
                    f"rotation must be a finite 3 x 3 matrix, got shape {rot.shape}",
                    name="rotation",
                    value=self.rotation,
                )
            err = float(np.max(np.abs(rot.T @ rot - np.eye(3))))
            if err > 1e-6 or np.linalg.det(rot) < 0:
                raise ParameterError(
                    f"rotation must be a rotation matrix (R^T R = I to 1e-6, det = +1), "
                    f"got |R^T R - I| = {err:.3g}, det = {np.linalg.det(rot):.6g}",
                    name="rotation",
                    value=self.rotation,
                )
            u, _, vt = np.linalg.svd(rot)  # re-orthonormalise (rounding of the input)
            object.__setattr__(self, "rotation", u @ vt)
        for key in ("approach", "approach_axis"):
            value = getattr(self, key)
            if value is None:
                continue
            vec = _vector3(value, key)
            norm = float(np.linalg.norm(vec))
            if norm < 1e-9:
                raise ParameterError(f"{key} must be a nonzero vector", name=key, value=value)
            object.__setattr__(self, key, vec / norm)
        for key in ("position_tol", "orientation_tol", "orientation_weight"):
            value = float(getattr(self, key))
            if not (value > 0.0 and math.isfinite(value)):
                raise ParameterError(
                    f"{key} must be finite and > 0, got {getattr(self, key)!r}",
                    name=key,
                    value=getattr(self, key),
                )
            object.__setattr__(self, key, value)
        for key in ("position", "rotation", "approach", "approach_axis"):
            value = getattr(self, key)
            if value is not None:
                value.setflags(write=False)

    @classmethod
    def pose(
        cls,
        position: ArrayLike,
        quaternion_xyzw: ArrayLike,
        *,
        position_tol: float = 1e-6,
        orientation_tol: float = 1e-6,
        orientation_weight: float = 1.0,
    ) -> Target:
        """Build a pose target from a position [m] and a quaternion ``(x, y, z, w)``."""
        return cls(
            position=np.asarray(position, dtype=float),
            rotation=quaternion_to_matrix(quaternion_xyzw),
            position_tol=position_tol,
            orientation_tol=orientation_tol,
            orientation_weight=orientation_weight,
        )

    @property
    def kind(self) -> str:
        """``"position"``, ``"pose"`` or ``"approach"``."""
        if self.rotation is not None:
            return "pose"
        return "approach" if self.approach is not None else "position"

    @property
    def n_rows(self) -> int:
        """Constraint rows: 3 (position), 6 (pose), 5 (approach)."""
        return {"position": 3, "pose": 6, "approach": 5}[self.kind]

    def approach_basis(self) -> Array:
        """Two orthonormal world vectors perpendicular to ``approach``, shape (2, 3)."""
        a = self.approach if self.approach is not None else np.array([0.0, 0.0, 1.0])
        helper = np.eye(3)[int(np.argmin(np.abs(a)))]
        b1 = np.cross(a, helper)
        b1 /= np.linalg.norm(b1)
        return np.vstack([b1, np.cross(a, b1)])

    def errors(self, placement: pin.SE3) -> tuple[float, float]:
        """Position error [m] and orientation error [rad] of a frame placement."""
        pos = float(np.linalg.norm(placement.translation - self.position))
        if self.rotation is not None:
            ang = float(np.linalg.norm(pin.log3(self.rotation.T @ placement.rotation)))
        elif self.approach is not None:
            w = placement.rotation @ self.approach_axis
            ang = math.atan2(
                float(np.linalg.norm(np.cross(w, self.approach))), float(w @ self.approach)
            )
        else:
            ang = 0.0
        return pos, ang

    def met(self, placement: pin.SE3) -> bool:
        """Whether a frame placement meets the target within its tolerances."""
        pos, ang = self.errors(placement)
        return pos <= self.position_tol and ang <= self.orientation_tol

    def to_dict(self) -> dict[str, object]:
        """JSON-ready description (positions [m], quaternion x y z w, tolerances)."""
        out: dict[str, object] = {"kind": self.kind, "position": self.position.tolist()}
        if self.rotation is not None:
            quat = pin.Quaternion(self.rotation)
            out["quaternion_xyzw"] = [quat.x, quat.y, quat.z, quat.w]
        if self.approach is not None:
            out["approach"] = self.approach.tolist()
            out["approach_axis"] = self.approach_axis.tolist()
        out.update(
            position_tol=self.position_tol,
            orientation_tol=self.orientation_tol,
            orientation_weight=self.orientation_weight,
        )
        return out


def position_targets(points: ArrayLike) -> tuple[Target, ...]:
    """Position targets at ``points`` [m], shape (s, 3) (world) or (s, 2) (a planar robot's plane).

    Raises
    ------
    ParameterError
        If ``points`` is not (s, 2) or (s, 3) finite numbers.
    """
    arr = np.array(points, dtype=float)
    if arr.ndim != 2 or arr.shape[1] not in (2, 3):
        raise ParameterError(
            f"target points must have shape (s, 2) or (s, 3) [m], got {arr.shape}",
            name="targets",
            value=arr.shape,
        )
    return tuple(Target(position=p) for p in arr)


_CSV_COLUMNS = ("x", "y", "z", "qx", "qy", "qz", "qw", "ax", "ay", "az")
_TOL_KEYS = ("position_tol", "orientation_tol", "orientation_weight")
_GROUPS = {"quaternion": ("qx", "qy", "qz", "qw"), "approach": ("ax", "ay", "az")}
_JSON_KEYS = ("position", "quaternion_xyzw", "approach", "approach_axis", *_TOL_KEYS)

MAX_TARGETS = 1000
"""Most targets a file may hold (the reachability check is quadratic in their number)."""
MAX_TARGETS_FILE_BYTES = 4 * 2**20
"""Largest targets file [bytes] (4 MiB: 1000 targets take under 200 kB)."""


def _number(value: object, where: str, key: str) -> float:
    """``value`` as a float, else a ParameterError naming the row and the column or key."""
    if isinstance(value, bool) or not isinstance(value, int | float | str):
        raise ParameterError(
            f"{where}: {key} must be a number, got {shown(value)}", name="targets", value=key
        )
    try:
        return float(value)
    except ValueError:
        raise ParameterError(
            f"{where}: {key} must be a number, got {shown(value)}", name="targets", value=key
        ) from None


def _target_from_record(rec: object, where: str, defaults: dict[str, float]) -> Target:
    """One target from a JSON object or CSV row (see :func:`load_targets`).

    Unknown keys, partial quaternions or approach directions and values that are
    not numbers are refused, naming the row and the column or key: orientation is
    never dropped without a word.
    """
    if not isinstance(rec, dict):
        raise ParameterError(
            f"{where}: a target is an object with a position, got {shown(rec)}", name="targets"
        )
    given = {k for k, v in rec.items() if v not in (None, "")}
    json_form = "position" in rec or not any(k in rec for k in _CSV_COLUMNS)
    known = _JSON_KEYS if json_form else (*_CSV_COLUMNS, *_TOL_KEYS)
    unknown = sorted(str(k) for k in rec if k not in known)
    if unknown:
        raise ParameterError(
            f"{where}: unknown {'key' if json_form else 'column'} {', '.join(map(repr, unknown))} "
            f"(known: {', '.join(known)})",
            name="targets",
            value=unknown[0],
        )
    kw: dict[str, object] = dict(defaults)
    for key in _TOL_KEYS:
        if key in given:
            kw[key] = _number(rec[key], where, key)
    if json_form:
        if "position" not in given:
            raise ParameterError(f"{where}: a target needs a position [m]", name="targets")
        position = _numbers(rec["position"], where, "position", 3)
        quat = _numbers(rec.get("quaternion_xyzw"), where, "quaternion_xyzw", 4)
        approach = _numbers(rec.get("approach"), where, "approach", 3)
    else:
        missing = [k for k in ("x", "y", "z") if k not in given]
        if missing:
            raise ParameterError(
                f"{where}: a target needs a position; column {', '.join(missing)} is empty",
                name="targets",
            )
        position = [_number(rec[k], where, k) for k in ("x", "y", "z")]
        parts: dict[str, list[float] | None] = {}
        for group, cols in _GROUPS.items():
            have = [c for c in cols if c in given]
            if have and len(have) < len(cols):
                lacking = [c for c in cols if c not in given]
                raise ParameterError(
                    f"{where}: a partial {group} ({', '.join(have)} given, "
                    f"{', '.join(lacking)} empty); give all of {', '.join(cols)} or none",
                    name="targets",
                    value=lacking[0],
                )
            parts[group] = [_number(rec[c], where, c) for c in cols] if have else None
        quat, approach = parts["quaternion"], parts["approach"]
    if quat is not None:
        kw["rotation"] = quaternion_to_matrix(quat)  # type: ignore[arg-type]
    if approach is not None:
        kw["approach"] = approach
        if rec.get("approach_axis") is not None:
            kw["approach_axis"] = rec["approach_axis"]
    try:
        return Target(position=position, **kw)  # type: ignore[arg-type]
    except (ParameterError, TypeError, ValueError) as exc:
        raise ParameterError(f"{where}: {exc}", name="targets") from exc


def _numbers(value: object, where: str, key: str, n: int) -> list[float] | None:
    """Return a JSON list of ``n`` numbers as floats (``None`` stays), else refuse it by name."""
    if value is None:
        return None
    if not isinstance(value, list) or len(value) != n:
        raise ParameterError(
            f"{where}: {key} must be a list of {n} numbers, got {shown(value)}",
            name="targets",
            value=key,
        )
    return [_number(x, where, f"{key}[{i}]") for i, x in enumerate(value)]


def load_targets(path: str | Path, **defaults: float) -> tuple[Target, ...]:
    """Read targets from a CSV or JSON file (by suffix).

    CSV: a header with named columns ``x, y, z`` [m], optionally ``qx, qy, qz, qw``
    (a pose, quaternion), or ``ax, ay, az`` (an approach direction), and per-row
    ``position_tol`` [m], ``orientation_tol`` [rad], ``orientation_weight`` [m/rad].
    JSON: a list (or ``{"targets": [...]}``) of objects with ``position``,
    optional ``quaternion_xyzw`` or ``approach`` (+ ``approach_axis``) and the
    same tolerance keys. ``defaults`` apply where a row gives none.

    Raises
    ------
    ParameterError
        Unknown suffix; a file that is missing, no regular file, over
        :data:`MAX_TARGETS_FILE_BYTES`, not UTF-8, not JSON/CSV or with more
        than :data:`MAX_TARGETS` targets; an unknown column or key, a partial
        quaternion or approach direction, a value that is not a number, or a
        row without a position (the message names the row and the column).
    """
    file = Path(path)
    text = read_input_text(
        file, max_bytes=MAX_TARGETS_FILE_BYTES, what="a targets file", name="targets"
    )
    if file.suffix.lower() == ".json":
        try:
            data = json.loads(text)
        except (json.JSONDecodeError, RecursionError) as exc:
            raise ParameterError(
                f"{file}: not valid JSON ({str(exc)[:200]})", name="targets", value=str(file)
            ) from exc
        records = data.get("targets") if isinstance(data, dict) else data
        if not isinstance(records, list):
            raise ParameterError(
                f"{file}: expected a list of targets or {{'targets': [...]}}",
                name="targets",
                value=str(file),
            )
    elif file.suffix.lower() == ".csv":
        try:
            reader = csv.DictReader(io.StringIO(text))
            columns = [c.strip() for c in reader.fieldnames or ()]
            rows = list(reader)
        except csv.Error as exc:
            raise ParameterError(f"{file}: not a CSV file ({exc})", name="targets") from exc
        for k, row in enumerate(rows):
            if None in row:  # more values than the header names
                raise ParameterError(
                    f"{file.name} row {k + 1}: {len(row[None]) + len(columns)} values for the "
                    f"{len(columns)} columns of the header",
                    name="targets",
                    value=str(file),
                )
        records = [{k.strip(): (v or "").strip() for k, v in row.items() if k} for row in rows]
        unknown = [c for c in columns if c not in (*_CSV_COLUMNS, *_TOL_KEYS)]
        missing = [c for c in ("x", "y", "z") if c not in columns]
        if missing or unknown:
            raise ParameterError(
                f"{file}: the CSV header must name the columns x, y, z (optional "
                f"{', '.join((*_CSV_COLUMNS[3:], *_TOL_KEYS))}); "
                + (f"missing {', '.join(missing)}" if missing else "")
                + ("; " if missing and unknown else "")
                + (f"unknown column {', '.join(map(repr, unknown))}" if unknown else ""),
                name="targets",
                value=str(file),
            )
    else:
        raise ParameterError(
            f"targets file must end in .csv or .json, got {file.name!r}",
            name="targets",
            value=str(file),
        )
    if len(records) > MAX_TARGETS:
        raise ParameterError(
            f"{file}: {len(records)} targets, more than MAX_TARGETS = {MAX_TARGETS}",
            name="targets",
            value=str(file),
        )
    return tuple(
        _target_from_record(rec, f"{file.name} row {k + 1}", defaults)
        for k, rec in enumerate(records)
    )
