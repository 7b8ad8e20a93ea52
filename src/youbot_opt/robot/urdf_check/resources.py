"""The one policy for files a robot description references: meshes, textures, material libraries.

Both the strict loader and the meshcat replay ask this module.
:func:`resolve_reference` resolves a reference as Pinocchio does and requires a
regular file inside the package directories; :func:`check_mesh` checks a mesh's
format and resolves the files it names (a ``.dae`` file's textures, an ``.obj``
file's ``mtllib``) from its folder by the same rules. Errors are
:class:`~youbot_opt.exceptions.URDFError` subclasses naming file, element and rule.

>>> check_mesh(resolve_reference(ref, roots, roots, where), roots, where)  # doctest: +SKIP
"""

from __future__ import annotations

import os
import re
import stat
import warnings
from collections.abc import Iterator, Sequence
from pathlib import Path
from urllib.parse import unquote

from lxml import etree

from youbot_opt.exceptions import (
    ParameterError,
    ResourceNotFoundError,
    UnsafePathError,
    URDFError,
    YoubotOptWarning,
)
from youbot_opt.robot.urdf_check.xml import Site, fail, local_name, parse_xml_strict

__all__ = [
    "MESH_SUFFIXES",
    "MAX_RESOURCE_BYTES",
    "PATH_RULE",
    "allowed_roots",
    "check_mesh",
    "in_mesh",
    "is_inline_image",
    "read_regular_file",
    "resolve_in_folder",
    "resolve_reference",
]

#: Mesh formats accepted (each parsed by assimp through coal); others are refused.
MESH_SUFFIXES: tuple[str, ...] = (".stl", ".dae", ".obj", ".ply")
#: Largest mesh or texture file accepted, in [bytes].
MAX_RESOURCE_BYTES: int = 256 * 2**20
_SCHEME = re.compile(r"([A-Za-z][A-Za-z0-9+.-]*):")
#: The rule every resolved reference obeys.
PATH_RULE = "resources resolve inside the package directories"
_INLINE_IMAGE = "data:image/"


def allowed_roots(
    package_dirs: Sequence[str | os.PathLike[str]], *, skip_missing: bool = False
) -> tuple[Path, ...]:
    """Resolve the package directories (symlinks followed).

    Parameters
    ----------
    package_dirs : sequence of path-like
        Folders meshes and textures may come from.
    skip_missing : bool
        Leave out folders that do not exist instead of raising (the replay
        draws a robot whose package folder has since been removed, as long
        as none of its meshes is needed).

    Returns
    -------
    tuple of Path
        Their real absolute paths, in the given order.

    Raises
    ------
    ParameterError
        If one of them is not an existing directory (and not ``skip_missing``).
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
            if skip_missing:
                continue
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

    As Pinocchio does: ``package://pkg/rest`` and relative paths give the first
    existing ``d/rest`` over ``search_dirs``; ``file:///abs`` and ``/abs`` the
    path itself; other schemes are refused. With symlinks followed the file
    must be a regular file inside ``roots`` of at most :data:`MAX_RESOURCE_BYTES`.

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
            ResourceNotFoundError, where, f"{ref!r}: no package directory to look in", PATH_RULE
        )
    real = Path(os.path.realpath(chosen))
    if not any(real.is_relative_to(root) for root in roots):
        problem = (
            f"{ref!r} resolves to {os.fspath(real)!r}, outside {[os.fspath(r) for r in roots]}"
        )
        raise fail(UnsafePathError, where, problem, PATH_RULE)
    if not os.path.exists(real):  # False, not OSError, for a name too long (issue 16 fuzzing)
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


def is_inline_image(ref: str) -> bool:
    """Whether a texture reference is an inline ``data:image/...`` URI (it names no file).

    Parameters
    ----------
    ref : str
        The reference as written.

    Returns
    -------
    bool
        True for ``data:image/...`` (any case, surrounding whitespace ignored).
    """
    return ref.strip().lower().startswith(_INLINE_IMAGE)


def resolve_in_folder(
    ref: str, roots: Sequence[Path], folder: Path, where: Site
) -> tuple[Path, ...]:
    """Resolve a reference made inside a mesh file (a texture, a material library).

    The reference is tried as written and percent-decoded: every form that
    exists must stay inside ``roots``; one existing form is enough (a file may
    be literally named ``a%20b.png``).

    Parameters
    ----------
    ref : str
        The reference as written in the mesh file (stripped).
    roots : sequence of Path
        Real paths of the allowed package directories.
    folder : Path
        Real path of the mesh file's folder: relative references start there.
    where : Site
        The mesh file, line and element holding the reference.

    Returns
    -------
    tuple of Path
        The real paths of the forms that exist (as written first), at least one.

    Raises
    ------
    UnsafePathError
        As :func:`resolve_reference`, for any form.
    ResourceNotFoundError
        If no form names an existing file (the error of the first form).
    """
    resolved, missing = [], []
    for variant in dict.fromkeys([ref, unquote(ref)]):
        try:
            resolved.append(resolve_reference(variant, roots, [folder], where))
        except ResourceNotFoundError as e:
            missing.append(e)
    if not resolved:
        raise missing[0]
    return tuple(resolved)


def _collada_textures(tree: etree._ElementTree, path: str) -> list[tuple[str, Site]]:
    """List the text of ``<init_from>`` (and 1.5's ``<init_from><ref>``) in images.

    meshcat's viewer reads every tag containing "init_from" in ``<library_images>``;
    each such element's own text (without its children's) is one reference, listed
    in the order the elements close.
    """
    found = []
    for _, elem in etree.iterwalk(tree.getroot(), events=("end",)):
        local = local_name(elem.tag)
        if not ("init_from" in local or local == "ref"):
            continue
        if not any(local_name(a.tag) in ("image", "library_images") for a in elem.iterancestors()):
            continue
        text = "".join([elem.text or "", *(child.tail or "" for child in elem)]).strip()
        if text:
            found.append((text, Site(path, f"<{local}>", elem.sourceline)))
    return found


def _obj_material_refs(data: bytes, path: Path) -> Iterator[tuple[str, Site]]:
    for number, line in enumerate(data.splitlines(), start=1):
        words = line.strip()
        if words.startswith(b"mtllib"):
            names = words[len(b"mtllib") :].decode("utf-8", errors="replace").strip()
            where = Site(os.fspath(path), "mtllib", number)
            if names:  # assimp reads the rest of the line as one file name
                yield names, where


def check_mesh(
    real: Path,
    roots: Sequence[Path],
    where: Site,
    *,
    inline_images: bool = False,
    material_warning: bool = True,
) -> tuple[Path, ...]:
    """Check a resolved mesh's format and the files it references.

    The mesh must have one of :data:`MESH_SUFFIXES`. A ``.dae`` file's textures
    (``<init_from>``/``<ref>`` in images) and an ``.obj`` file's ``mtllib`` are
    resolved from the mesh's folder by the rules of :func:`resolve_reference`.

    Parameters
    ----------
    real : Path
        Real path of the mesh, from :func:`resolve_reference`.
    roots : sequence of Path
        Real paths of the allowed package directories.
    where : Site
        What references the mesh (a URDF element, a geometry object), for errors.
    inline_images : bool
        Accept ``data:image/...`` COLLADA textures, which name no file (the
        replay passes them to the browser as they are; assimp cannot read
        them, so the loader refuses them as a URL form).
    material_warning : bool
        Warn about a missing ``.obj`` material library (assimp then uses a
        default material; the replay never reads material libraries).

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
    the ``.dae``'s XML) name the mesh file, line and element; callers re-raise
    them from ``where`` with :func:`in_mesh`. The warning for a missing
    ``.obj`` material library names both.
    """
    suffix = real.suffix.lower()
    if suffix not in MESH_SUFFIXES:
        problem = f"mesh {os.fspath(real)!r} has the refused format {suffix or '(none)'!r}"
        raise fail(UnsafePathError, where, problem, f"mesh formats are {', '.join(MESH_SUFFIXES)}")
    if suffix not in (".dae", ".obj"):
        return ()
    data = read_regular_file(real, MAX_RESOURCE_BYTES, where, "mesh")
    if suffix == ".dae":
        textures = _collada_textures(
            parse_xml_strict(data, os.fspath(real), long_text=True), os.fspath(real)
        )
        refs = [(r, s) for r, s in textures if not (inline_images and is_inline_image(r))]
    else:
        refs = list(_obj_material_refs(data, real))
    found: list[Path] = []
    for ref, ref_site in refs:
        try:
            found.extend(resolve_in_folder(ref, roots, real.parent, ref_site))
        except ResourceNotFoundError:
            if suffix == ".dae":
                raise
            if material_warning:  # assimp falls back to a default material
                at = f":{where.line}" if where.line is not None else ""
                warnings.warn(
                    f"{where.path}{at}: {where.element}: {ref_site.path}:{ref_site.line}: "
                    f"material library {ref!r} is missing; assimp will use a default material",
                    YoubotOptWarning,
                    stacklevel=3,
                )
    return tuple(dict.fromkeys(found))


def in_mesh(error: URDFError, where: Site, mesh: Path) -> URDFError:
    """Re-raise a rule broken inside a mesh file from what references the mesh.

    Parameters
    ----------
    error : URDFError
        The error, naming the mesh file, line and element.
    where : Site
        What references the mesh (a URDF element, a geometry object).
    mesh : Path
        The mesh file.

    Returns
    -------
    URDFError
        Of the same class and rule, sited at ``where``; its message keeps the
        mesh file's own site and problem.
    """
    line = f":{where.line}" if where.line is not None else ""
    message = (
        f"{where.path}{line}: {where.element}: the mesh {os.fspath(mesh)!r} it references "
        f"breaks a rule: {error}"
    )
    return type(error)(
        message, path=where.path, element=where.element, line=where.line, rule=error.rule
    )
