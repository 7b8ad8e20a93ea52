"""Scene files: a strict JSON reader (:func:`load_scene`) and its writer (:func:`save_scene`).

The schema, with units, is documented in ``docs/scene.md``. Reading is strict
like the URDF loader: a file larger than :data:`MAX_SCENE_BYTES`, duplicate or
unknown keys, non-finite or non-numeric numbers, negative or huge sizes and
more than :data:`~youbot_opt.collision.scene.MAX_OBSTACLES` obstacles are
refused with a :class:`~youbot_opt.exceptions.ParameterError` naming the key
path (``obstacles[2].size[1]``) and the value. Mesh and URDF paths are relative
to the file's folder and must stay inside it.

>>> scene = load_scene("cell.json")  # doctest: +SKIP
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from youbot_opt._checks import shown
from youbot_opt._files import atomic_write_text
from youbot_opt._typing import JSONDict
from youbot_opt.collision.scene import MAX_OBSTACLES, Obstacle, Scene, furniture
from youbot_opt.collision.shapes import Box, Capsule, Cylinder, HalfSpace, Mesh, Shape, Sphere
from youbot_opt.exceptions import ParameterError, YoubotOptError
from youbot_opt.robot.urdf_check.meshes import check_mesh_file

__all__ = [
    "MAX_SCENE_BYTES",
    "SCENE_SCHEMA",
    "SCENE_VERSION",
    "load_scene",
    "save_scene",
    "scene_document",
    "scene_from_document",
]

#: Largest scene file read, in bytes.
MAX_SCENE_BYTES = 1 << 20
#: The ``schema`` field of a scene file and its version.
SCENE_SCHEMA = "youbot_opt.scene"
SCENE_VERSION = 1

_TOP_KEYS = {"schema", "schema_version", "obstacles"}
_POSE_KEYS = {"name", "shape", "xyz", "rpy", "frame"}
#: The keys of each shape besides the pose keys, each required.
_SHAPE_KEYS: dict[str, tuple[str, ...]] = {
    "box": ("size",),
    "sphere": ("radius",),
    "cylinder": ("radius", "length"),
    "capsule": ("radius", "length"),
    "halfspace": (),
    "mesh": ("path",),
    "urdf": ("path",),
}
_OPTIONAL_SHAPE_KEYS: dict[str, tuple[str, ...]] = {"mesh": ("scale",)}


def _refuse(where: str, problem: str, value: object) -> ParameterError:
    return ParameterError(f"{where}: {problem}, got {shown(value)}", name=where, value=value)


def _no_duplicates(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for key, value in pairs:
        if key in out:
            raise _refuse(key, "duplicate key", value)
        out[key] = value
    return out


def _no_constant(text: str) -> float:
    raise _refuse("number", "numbers must be finite (NaN and Infinity are not JSON)", text)


def _number(value: object, where: str) -> float:
    """Return a JSON number (not a bool, not a string) as a float."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise _refuse(where, "must be a number", value)
    return float(value)


def _numbers(value: object, where: str) -> tuple[float, ...]:
    if not isinstance(value, list) or len(value) > 16:
        raise _refuse(where, "must be a list of three numbers", value)
    return tuple(_number(v, f"{where}[{i}]") for i, v in enumerate(value))


def _relative_file(value: object, where: str, folder: Path) -> Path:
    """Return a path relative to the scene's folder that stays inside it."""
    if not isinstance(value, str) or not value or len(value) > 4096:
        raise _refuse(where, "must be a file path relative to the scene file", value)
    path = (folder / value).resolve()
    if not path.is_relative_to(folder.resolve()):
        raise _refuse(where, f"must stay inside the scene file's folder {str(folder)!r}", value)
    if not path.is_file():
        raise _refuse(where, "names no existing file", value)
    return path


def _with_where(where: str, error: ParameterError) -> ParameterError:
    name = f"{where}.{error.name}" if error.name else where
    return ParameterError(f"{where}: {error}", name=name, value=error.value)


def _shape(kind: str, entry: Mapping[str, Any], where: str, folder: Path) -> Shape:
    if kind == "box":
        return Box(size=_numbers(entry["size"], f"{where}.size"))  # type: ignore[arg-type]
    if kind == "sphere":
        return Sphere(radius=_number(entry["radius"], f"{where}.radius"))
    if kind in ("cylinder", "capsule"):
        cls = Cylinder if kind == "cylinder" else Capsule
        radius = _number(entry["radius"], f"{where}.radius")
        return cls(radius=radius, length=_number(entry["length"], f"{where}.length"))
    if kind == "halfspace":
        return HalfSpace()
    scale = _numbers(entry.get("scale", [1.0, 1.0, 1.0]), f"{where}.scale")
    path = _relative_file(entry["path"], f"{where}.path", folder)
    # the URDF loader's mesh policy: format, size, a regular file inside the folder
    checked = check_mesh_file(path, (folder,), referenced_by=f"scene entry {where}")
    return Mesh(path=checked, scale=scale)  # type: ignore[arg-type]


def _obstacles(entry: object, where: str, folder: Path) -> Scene:
    if not isinstance(entry, dict):
        raise _refuse(where, "must be an object", entry)
    kind = entry.get("shape")
    if kind not in _SHAPE_KEYS:
        raise _refuse(f"{where}.shape", f"must be one of {sorted(_SHAPE_KEYS)}", kind)
    allowed = _POSE_KEYS | set(_SHAPE_KEYS[kind]) | set(_OPTIONAL_SHAPE_KEYS.get(kind, ()))
    for key in entry:
        if key not in allowed:
            raise _refuse(
                f"{where}.{key}", f"unknown key for a {kind} (valid: {sorted(allowed)})", key
            )
    for key in ("name", *_SHAPE_KEYS[kind]):
        if key not in entry:
            raise _refuse(
                f"{where}.{key}", f"missing (a {kind} needs {['name', *_SHAPE_KEYS[kind]]})", None
            )
    xyz = _numbers(entry.get("xyz", [0.0, 0.0, 0.0]), f"{where}.xyz")
    rpy = _numbers(entry.get("rpy", [0.0, 0.0, 0.0]), f"{where}.rpy")
    name, frame = entry["name"], entry.get("frame")
    if frame == "world":
        frame = None
    try:
        if kind == "urdf":
            if frame is not None:
                raise _refuse(f"{where}.frame", "furniture is fixed to the world", frame)
            path = _relative_file(entry["path"], f"{where}.path", folder)
            return furniture(path, name=name, xyz=xyz, rpy=rpy)
        shape = _shape(kind, entry, where, folder)
        obstacle = Obstacle(name=name, shape=shape, xyz=xyz, rpy=rpy, frame=frame)  # type: ignore[arg-type]
    except ParameterError as e:
        if e.name is not None and e.name.startswith(where):
            raise
        raise _with_where(where, e) from e
    return Scene((obstacle,))


def load_scene(path: str | os.PathLike[str]) -> Scene:
    """Read a scene file (JSON, schema ``youbot_opt.scene`` version 1, see ``docs/scene.md``).

    Parameters
    ----------
    path : path-like
        The file.

    Returns
    -------
    Scene
        Its obstacles, in file order (a ``"urdf"`` entry adds one per collision geometry).

    Raises
    ------
    ParameterError
        The file is missing, too large, not JSON, or breaks the schema; the
        message names the key path and the value.
    ModelError
        A furniture URDF is refused by the strict URDF loader.
    """
    file = Path(path)
    where = str(file)
    try:
        size = file.stat().st_size
        if not file.is_file():
            raise _refuse(where, "must be a regular file", where)
        if size > MAX_SCENE_BYTES:
            raise _refuse(where, f"a scene file has at most {MAX_SCENE_BYTES} bytes", size)
        text = file.read_bytes()[: MAX_SCENE_BYTES + 1].decode("utf-8")
    except (OSError, UnicodeDecodeError) as e:
        raise ParameterError(
            f"cannot read the scene file {where!r}: {e}", name="path", value=where
        ) from e
    try:
        doc = json.loads(text, object_pairs_hook=_no_duplicates, parse_constant=_no_constant)
    except json.JSONDecodeError as e:
        raise ParameterError(
            f"{where}: not JSON: {e.msg} at line {e.lineno} column {e.colno}",
            name="path",
            value=where,
        ) from e
    return scene_from_document(doc, folder=file.absolute().parent)


def scene_from_document(doc: object, *, folder: str | os.PathLike[str]) -> Scene:
    """Read a scene from the parsed JSON of a scene file (:func:`load_scene`'s checks).

    Parameters
    ----------
    doc : object
        The document (a dict with ``schema``, ``schema_version``, ``obstacles``).
    folder : path-like
        The folder mesh and furniture paths are relative to.

    Returns
    -------
    Scene
        Its obstacles, in document order.

    Raises
    ------
    ParameterError
        The document breaks the schema; the message names the key path.
    """
    where = "scene"
    if not isinstance(doc, dict):
        raise _refuse(where, "must hold a JSON object", doc)
    for key in doc:
        if key not in _TOP_KEYS:
            raise _refuse(key, f"unknown key (valid: {sorted(_TOP_KEYS)})", key)
    if doc.get("schema") != SCENE_SCHEMA:
        raise _refuse("schema", f"must be {SCENE_SCHEMA!r}", doc.get("schema"))
    if doc.get("schema_version") != SCENE_VERSION:
        raise _refuse(
            "schema_version",
            f"must be {SCENE_VERSION} (this youbot_opt reads it)",
            doc.get("schema_version"),
        )
    entries = doc.get("obstacles")
    if not isinstance(entries, list):
        raise _refuse("obstacles", "must be a list of obstacles", entries)
    if len(entries) > MAX_OBSTACLES:
        raise _refuse("obstacles", f"a scene holds at most {MAX_OBSTACLES} obstacles", len(entries))
    scene = Scene()
    for i, entry in enumerate(entries):
        try:
            scene = scene + _obstacles(entry, f"obstacles[{i}]", Path(folder))
        except ParameterError:
            raise
        except YoubotOptError as e:
            e.args = (f"obstacles[{i}]: {e}",)
            raise
    return scene


def _entry(obstacle: Obstacle, folder: Path) -> dict[str, Any]:
    shape = obstacle.shape
    out: dict[str, Any] = {"name": obstacle.name}
    if isinstance(shape, Box):
        out.update(shape="box", size=list(shape.size))
    elif isinstance(shape, Sphere):
        out.update(shape="sphere", radius=shape.radius)
    elif isinstance(shape, Cylinder | Capsule):
        kind = "cylinder" if isinstance(shape, Cylinder) else "capsule"
        out.update(shape=kind, radius=shape.radius, length=shape.length)
    elif isinstance(shape, HalfSpace):
        out.update(shape="halfspace")
    else:
        out.update(shape="mesh", path=os.path.relpath(shape.path, folder), scale=list(shape.scale))
    out.update(xyz=list(obstacle.xyz), rpy=list(obstacle.rpy))
    if obstacle.frame is not None:
        out["frame"] = obstacle.frame
    return out


def save_scene(scene: Scene, path: str | os.PathLike[str]) -> None:
    """Write a scene file that :func:`load_scene` reads back to an equal scene.

    Mesh paths are written relative to the file's folder (meshes must lie
    inside it to be read back); furniture is written as its obstacles.

    Parameters
    ----------
    scene : Scene
        The scene.
    path : path-like
        The file to write (atomically).
    """
    doc = scene_document(scene, folder=Path(path).absolute().parent)
    atomic_write_text(path, json.dumps(doc, indent=2) + "\n")


def scene_document(scene: Scene, *, folder: str | os.PathLike[str]) -> JSONDict:
    """Return the JSON document of a scene file, mesh paths relative to ``folder``."""
    return {
        "schema": SCENE_SCHEMA,
        "schema_version": SCENE_VERSION,
        "obstacles": [_entry(o, Path(folder)) for o in scene.obstacles],
    }
