"""Where the meshes and textures of a URDF may come from (issue 6, item 1).

A reference is resolved as Pinocchio resolves it (``pinocchio::retrieveResourcePath``):

* ``package://pkg/rest`` (and ``model://``): the first ``d + "/pkg/rest"``
  that exists, for ``d`` in the package directories, in order;
* a relative path: the first ``d + "/path"`` that exists (Pinocchio does not
  look next to the URDF);
* ``file:///abs/path`` and ``/abs/path``: the path itself;
* any other scheme (``http://``, ``https://``, ``ftp://``, ``data:`` ...) is refused.

The resolved path, with every symlink followed, must lie inside one of the
allowed package directories and be a regular file (not a device such as
``/dev/zero``, a FIFO or a directory) of at most :data:`MAX_RESOURCE_BYTES`.
Meshes must be one of :data:`MESH_SUFFIXES`. Meshes can reference further
files, which are checked by the same rules:

* COLLADA (``.dae``): every ``<init_from>`` (or ``<ref>``, COLLADA 1.5) inside
  ``<image>`` or ``<library_images>`` is a texture URI, relative to the ``.dae`` file's
  folder (Pinocchio's meshcat viewer reads these files and sends them to the
  browser). The ``.dae`` itself is parsed with the strict parser, so a
  ``DOCTYPE`` there is refused too. Percent-encoded URIs are checked both as
  written and decoded.
* Wavefront (``.obj``): every ``mtllib`` material library (read by assimp);
  a missing library only warns (:class:`~youbot_opt.exceptions.YoubotOptWarning`),
  as assimp then uses a default material.

The checks run before loading; a file swapped between the check and the load
by someone with write access to the package directories is out of scope.
"""

from __future__ import annotations

import os
import re
import stat
import warnings
from collections.abc import Iterator, Sequence
from pathlib import Path
from urllib.parse import unquote

from youbot_opt.exceptions import (
    ParameterError,
    ResourceNotFoundError,
    UnsafePathError,
    URDFError,
    YoubotOptWarning,
)
from youbot_opt.robot.strict.xml import Site, fail, scan_xml_strict

__all__ = [
    "MESH_SUFFIXES",
    "MAX_RESOURCE_BYTES",
    "allowed_roots",
    "resolve_reference",
    "check_mesh",
    "read_regular_file",
]

#: Mesh formats accepted (each parsed by assimp through coal); others are refused.
MESH_SUFFIXES: tuple[str, ...] = (".stl", ".dae", ".obj", ".ply")
#: Largest mesh or texture file accepted, in [bytes].
MAX_RESOURCE_BYTES: int = 256 * 2**20
_SCHEME = re.compile(r"([A-Za-z][A-Za-z0-9+.-]*):")
_PATH_RULE = "resources resolve inside the package directories"


def allowed_roots(package_dirs: Sequence[str | os.PathLike[str]]) -> tuple[Path, ...]:
    """Resolve the package directories (symlinks followed).

    Parameters
    ----------
    package_dirs : sequence of path-like
        Folders meshes and textures may come from.

    Returns
    -------
    tuple of Path
        Their real absolute paths, in the given order.

    Raises
    ------
    ParameterError
        If one of them is not an existing directory.
    """
    if isinstance(package_dirs, str | os.PathLike):
        raise ParameterError(
            f"package_dirs must be a sequence of folders, got the single path {package_dirs!r}",
            name="package_dirs",
            value=package_dirs,
        )
    roots = []
    for d in package_dirs:
        real = Path(os.path.realpath(d))
        if not real.is_dir():
            raise ParameterError(
                f"package directory {os.fspath(d)!r} is not an existing folder",
                name="package_dirs",
                value=d,
            )
        roots.append(real)
    return tuple(roots)


def read_regular_file(
    path: Path,
    max_bytes: int,
    where: Site,
    kind: str,
    error: type[URDFError] = UnsafePathError,
) -> bytes:
    """Read a file only if it is a regular file of at most ``max_bytes``.

    Parameters
    ----------
    path : Path
        The file (symlinks are followed).
    max_bytes : int
        Size limit in [bytes].
    where : Site
        What referenced the file, for error messages.
    kind : str
        What the file is (``"URDF"``, ``"mesh"`` ...), for error messages.
    error : type
        Error class raised when a rule is broken.

    Returns
    -------
    bytes
        The content.

    Raises
    ------
    URDFError
        Of class ``error``, if the file is a device, FIFO, socket or folder,
        or is larger than ``max_bytes``.
    """
    # O_NONBLOCK: opening a FIFO must not wait for a writer; fstat then refuses it.
    fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
    if not stat.S_ISREG(os.fstat(fd).st_mode):
        os.close(fd)
        problem = (
            f"{kind} {os.fspath(path)!r} is not a regular file (device, FIFO, socket or folder)"
        )
        raise fail(error, where, problem, "files are regular files")
    with os.fdopen(fd, "rb") as f:
        data = f.read(max_bytes + 1)
    if len(data) > max_bytes:
        problem = f"{kind} {os.fspath(path)!r} is larger than {max_bytes} bytes"
        raise fail(error, where, problem, f"files are at most {max_bytes} bytes")
    return data


def _candidates(ref: str, search_dirs: Sequence[Path], where: Site) -> list[str]:
    scheme = _SCHEME.match(ref)
    if scheme is None:
        if os.path.isabs(ref):
            return [ref]
        return [f"{d}/{ref}" for d in search_dirs]
    name, rest = scheme.group(1).lower(), ref[scheme.end() :]
    if name in ("package", "model") and rest.startswith("//"):
        return [f"{d}/{rest[2:]}" for d in search_dirs]
    if name == "file" and rest.startswith("//") and os.path.isabs(rest[2:]):
        return [rest[2:]]
    problem = f"reference {ref!r} uses a refused URL form ({name}:)"
    rule = "references are package://, file:///absolute, absolute or relative paths"
    raise fail(UnsafePathError, where, problem, rule)


def resolve_reference(
    ref: str, roots: Sequence[Path], search_dirs: Sequence[Path], where: Site
) -> Path:
    """Resolve one mesh or texture reference and check where it lands.

    Parameters
    ----------
    ref : str
        The reference as written (``package://...``, a path, a URI).
    roots : sequence of Path
        Real paths of the allowed package directories.
    search_dirs : sequence of Path
        Folders ``package://`` and relative references are looked up in, in order.
    where : Site
        The referencing element, for error messages.

    Returns
    -------
    Path
        The real path of an existing regular file inside ``roots``.

    Raises
    ------
    UnsafePathError
        Refused URL scheme, resolution outside ``roots`` (``..``, absolute
        paths, symlinks), not a regular file, or larger than
        :data:`MAX_RESOURCE_BYTES`.
    ResourceNotFoundError
        If an allowed reference names no existing file.
    """
    candidates = _candidates(ref, search_dirs, where)
    chosen = next(
        (c for c in candidates if os.path.exists(c)), candidates[0] if candidates else None
    )
    if chosen is None:
        raise fail(
            ResourceNotFoundError, where, f"{ref!r}: no package directory to look in", _PATH_RULE
        )
    real = Path(os.path.realpath(chosen))
    if not any(real.is_relative_to(root) for root in roots):
        problem = (
            f"{ref!r} resolves to {os.fspath(real)!r}, outside {[os.fspath(r) for r in roots]}"
        )
        raise fail(UnsafePathError, where, problem, _PATH_RULE)
    if not real.exists():
        problem = f"{ref!r} resolves to {os.fspath(real)!r}, which does not exist"
        raise fail(ResourceNotFoundError, where, problem, "referenced files exist")
    info = real.stat()
    if not stat.S_ISREG(info.st_mode):
        problem = f"{ref!r} resolves to {os.fspath(real)!r}, which is not a regular file"
        raise fail(
            UnsafePathError,
            where,
            problem,
            "resources are regular files (no devices, FIFOs, folders)",
        )
    if info.st_size > MAX_RESOURCE_BYTES:
        problem = f"{ref!r} resolves to a file of {info.st_size} bytes"
        raise fail(
            UnsafePathError, where, problem, f"resources are at most {MAX_RESOURCE_BYTES} bytes"
        )
    return real


def _local(tag: str) -> str:
    return tag.rsplit("}", 1)[-1].rsplit(":", 1)[-1]


class _ColladaTextures:
    """Collects the text of ``<init_from>`` (and 1.5's ``<init_from><ref>``) in images."""

    def __init__(self, path: str) -> None:
        self.path = path
        self.open: list[tuple[str, int, list[str] | None]] = []  # (local tag, line, text)
        self.found: list[tuple[str, Site]] = []

    def start(self, tag: str, attrs: dict[str, str], line: int) -> None:
        local = _local(tag)
        in_image = any(t in ("image", "library_images") for t, _, _ in self.open)
        # meshcat's viewer reads every tag containing "init_from" in <library_images>
        collect = in_image and ("init_from" in local or local == "ref")
        self.open.append((local, line, [] if collect else None))

    def data(self, text: str) -> None:
        if self.open and (parts := self.open[-1][2]) is not None:
            parts.append(text)

    def end(self, tag: str) -> None:
        local, line, parts = self.open.pop()
        if parts is not None and "".join(parts).strip():
            self.found.append(("".join(parts).strip(), Site(self.path, f"<{local}>", line)))


def _obj_material_refs(data: bytes, path: Path) -> Iterator[tuple[str, Site]]:
    for number, line in enumerate(data.splitlines(), start=1):
        words = line.strip()
        if words.startswith(b"mtllib"):
            names = words[len(b"mtllib") :].decode("utf-8", errors="replace").strip()
            where = Site(os.fspath(path), "mtllib", number)
            if names:  # assimp reads the rest of the line as one file name
                yield names, where


def check_mesh(real: Path, roots: Sequence[Path], where: Site) -> tuple[Path, ...]:
    """Check a resolved mesh's format and the files it references.

    Parameters
    ----------
    real : Path
        Real path of the mesh, from :func:`resolve_reference`.
    roots : sequence of Path
        Real paths of the allowed package directories.
    where : Site
        The URDF element referencing the mesh, for error messages.

    Returns
    -------
    tuple of Path
        Real paths of the textures and material libraries the mesh references.

    Raises
    ------
    UnsafePathError, ResourceNotFoundError
        From :func:`resolve_reference`, for the mesh's own references, or if
        the format is not in :data:`MESH_SUFFIXES`.
    UnsafeURDFError, URDFSyntaxError
        If a ``.dae`` file has a ``DOCTYPE`` or is not well-formed XML.

    Notes
    -----
    Errors about the mesh file itself (format, size, not a regular file) name
    ``where``. Errors found *inside* the mesh (a texture, a material library,
    the ``.dae``'s XML) name the mesh file, line and element (their ``path`` is
    the mesh); :func:`youbot_opt.robot.strict.loader.load_urdf_strict` re-raises them from
    ``where`` with the same class and rule. The warning for a missing ``.obj``
    material library names both.
    """
    suffix = real.suffix.lower()
    if suffix not in MESH_SUFFIXES:
        problem = f"mesh {os.fspath(real)!r} has the refused format {suffix or '(none)'!r}"
        raise fail(UnsafePathError, where, problem, f"mesh formats are {', '.join(MESH_SUFFIXES)}")
    if suffix not in (".dae", ".obj"):
        return ()
    data = read_regular_file(real, MAX_RESOURCE_BYTES, where, "mesh")
    if suffix == ".dae":
        textures = _ColladaTextures(os.fspath(real))
        scan_xml_strict(data, os.fspath(real), textures)
        refs = textures.found
    else:
        refs = list(_obj_material_refs(data, real))
    found: list[Path] = []
    for ref, ref_site in refs:
        # Every form must stay inside; one existing form is enough (a file may be
        # literally named "a%20b.png").
        resolved, missing = [], []
        for variant in dict.fromkeys([ref, unquote(ref)]):
            try:
                resolved.append(resolve_reference(variant, roots, [real.parent], ref_site))
            except ResourceNotFoundError as e:
                missing.append(e)
        if resolved:
            found.extend(resolved)
        elif suffix == ".dae":
            raise missing[0]
        else:  # assimp falls back to a default material when the library is missing
            at = f":{where.line}" if where.line is not None else ""
            warnings.warn(
                f"{where.path}{at}: {where.element}: {ref_site.path}:{ref_site.line}: "
                f"material library {ref!r} is missing; assimp will use a default material",
                YoubotOptWarning,
                stacklevel=3,
            )
    return tuple(dict.fromkeys(found))
