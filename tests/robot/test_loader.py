"""Tests of the strict URDF loader: the hostile corpus, reference robots and the rules.

The corpus (``tests/robot/urdf_corpus``, listed in ``manifest.json`` with the expected
error class and a message fragment for each file) is loaded file by file in
child processes with a memory and a time cap (``tests/robot/_load_in_subprocess.py``).
Mesh fixtures that cannot live in git (symlinks, a FIFO, a folder named like a
mesh) are made in a temporary copy of the corpus package.
"""

from __future__ import annotations

import importlib.metadata
import json
import math
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given
from hypothesis import strategies as st
from lxml import etree

from youbot_opt.exceptions import (
    InvalidModelError,
    ModelError,
    ParameterError,
    ResourceNotFoundError,
    RobotNotFound,
    UnsafePathError,
    UnsafeURDFError,
    URDFError,
    URDFSyntaxError,
    YoubotOptWarning,
)
from youbot_opt.robot.load import load_model
from youbot_opt.robot.urdf_check import loader
from youbot_opt.robot.urdf_check.loader import (
    check_model,
    check_urdf_text,
    load_urdf_strict,
    read_description,
)
from youbot_opt.robot.urdf_check.resources import check_mesh
from youbot_opt.robot.urdf_check.size import SizeLimits
from youbot_opt.robot.urdf_check.xml import Site, parse_number, parse_xml_strict

HERE = Path(__file__).resolve().parent
CORPUS = HERE / "urdf_corpus"
MANIFEST = json.loads((CORPUS / "manifest.json").read_text())
HELPER = HERE / "_load_in_subprocess.py"
ERROR_CLASSES = {
    "URDFSyntaxError",
    "UnsafeURDFError",
    "UnsafePathError",
    "ResourceNotFoundError",
    "URDFStructureError",
    "InvalidModelError",
}
ROBOTS = Path(
    str(
        importlib.metadata.distribution("example-robot-data").locate_file(
            "cmeel.prefix/share/example-robot-data/robots"
        )
    )
)
ROBOT_DIRS = [ROBOTS, ROBOTS.parent.parent]  # robots/ and share/ (package://example-robot-data/...)
YOUBOT = HERE.parents[1] / "urdf" / "youbot_arm_planar.urdf"
REFERENCE_ROBOTS = {
    "ur5": ROBOTS / "ur_description/urdf/ur5_robot.urdf",
    "panda": ROBOTS / "panda_description/urdf/panda.urdf",
    "double_pendulum": ROBOTS / "double_pendulum_description/urdf/double_pendulum.urdf",
    "youbot": YOUBOT,
}


def _make_corpus_packages(root: Path) -> Path:
    """Copy the corpus package to ``root`` and add the fixtures git cannot hold."""
    packages = root / "packages"
    shutil.copytree(CORPUS / "pkg", packages)
    meshes = packages / "corpus_pkg" / "meshes"
    outside = root / "outside"
    outside.mkdir()
    shutil.copy(meshes / "box.stl", outside / "secret.stl")
    (meshes / "escape.stl").symlink_to(outside / "secret.stl")
    (meshes / "zero.stl").symlink_to("/dev/zero")
    (meshes / "inside_link.stl").symlink_to("box.stl")
    os.mkfifo(meshes / "fifo.stl")
    (meshes / "folder.stl").mkdir()
    return packages


@pytest.fixture(scope="module")
def corpus_packages(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return _make_corpus_packages(tmp_path_factory.mktemp("corpus"))


@pytest.fixture(scope="module")
def subprocess_reports(corpus_packages: Path) -> dict[str, dict]:
    """Load every corpus file and reference robot in capped child processes, once."""
    jobs = [
        {"id": e["file"], "path": str(CORPUS / e["file"]), "package_dirs": [str(corpus_packages)]}
        for e in MANIFEST
    ]
    jobs += [
        {"id": name, "path": str(path), "package_dirs": [str(d) for d in ROBOT_DIRS]}
        for name, path in REFERENCE_ROBOTS.items()
        if path.exists()
    ]
    jobs += [
        {"id": "selftest-allocate", "selftest": "allocate"},
        {"id": "selftest-sleep", "selftest": "sleep", "timeout": 1},
    ]
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}
    done = subprocess.run(
        [sys.executable, str(HELPER)],
        input=json.dumps(jobs),
        capture_output=True,
        text=True,
        timeout=600,
        env=env,
        check=True,
    )
    reports = [json.loads(line) for line in done.stdout.splitlines()]
    return {r["id"]: r for r in reports}


def test_manifest_covers_the_corpus() -> None:
    """Every corpus file is listed, >= 40 are hostile and every error class is exercised."""
    on_disk = {p.relative_to(CORPUS).as_posix() for p in CORPUS.rglob("*.urdf")}
    listed = [e["file"] for e in MANIFEST]
    assert sorted(listed) == sorted(on_disk)
    assert len(set(listed)) == len(listed)
    expected = {e["expect"] for e in MANIFEST}
    assert expected == ERROR_CLASSES | {"ok"}
    assert sum(e["expect"] != "ok" for e in MANIFEST) >= 40
    assert all(e["expect"] == "ok" or e["match"] for e in MANIFEST)
    # every hostile mesh or texture reference states the URDF element its error must name
    on_meshes = [e for e in MANIFEST if e["file"].startswith(("paths/", "missing/"))]
    assert all("element" in e for e in on_meshes)


@pytest.mark.parametrize("entry", MANIFEST, ids=[e["file"] for e in MANIFEST])
def test_corpus_file(entry: dict, subprocess_reports: dict[str, dict]) -> None:
    """In a capped child, the file loads or fails with exactly the expected class and rule."""
    report = subprocess_reports[entry["file"]]
    assert report["outcome"] in ("ok", "error"), report  # no time-out, kill or crash
    got = report.get("error_class", "ok")
    assert got == entry["expect"], report.get("message")
    if got != "ok":
        message = report["message"]
        assert entry["match"] in message
        # Every error is raised from the URDF file and names it, the element and the rule,
        # also when the broken rule lies inside a mesh the element references.
        assert report["error_path"] == str(CORPUS / entry["file"])
        assert entry["file"] in message
        assert report["error_element"] and f": {report['error_element']}: " in message
        assert report["error_rule"] and message.endswith(f"[rule: {report['error_rule']}]")
        if "element" in entry:  # a mesh or texture reference: the exact element, at its line
            assert report["error_element"] == entry["element"]
            lines = (CORPUS / entry["file"]).read_text().splitlines()
            assert "filename=" in lines[report["error_line"] - 1]
        if "it references breaks a rule" in message:  # re-raised with the mesh's error chained
            assert report["cause_class"] == got


def test_child_process_caps_are_enforced(subprocess_reports: dict[str, dict]) -> None:
    """The harness really caps memory (8 GiB allocation fails) and wall time (1 s sleep killed)."""
    assert subprocess_reports["selftest-allocate"]["error_class"] == "MemoryError"
    assert subprocess_reports["selftest-sleep"]["outcome"] == "timeout"
    assert subprocess_reports["selftest-sleep"]["seconds"] < 5.0  # killed near its 1 s cap


def _movable_joint_count(path: Path) -> int:
    tree = etree.parse(str(path), etree.XMLParser(resolve_entities=False, no_network=True))
    return sum(j.get("type") != "fixed" for j in tree.getroot().findall("joint"))


@pytest.mark.parametrize("name", sorted(REFERENCE_ROBOTS))
def test_reference_robot_loads_in_child(name: str, subprocess_reports: dict[str, dict]) -> None:
    """ur5, panda, double_pendulum and the youBot load, with one q per movable joint of the file."""
    path = REFERENCE_ROBOTS[name]
    if not path.exists():
        pytest.skip(f"{path} not generated yet")
    report = subprocess_reports[name]
    assert report["outcome"] == "ok", report
    assert report["nq"] == _movable_joint_count(path)  # all are revolute/prismatic: nq 1 each


@pytest.mark.parametrize("name", ["ur5", "panda", "double_pendulum"])
def test_reference_robot_matches_its_file(name: str) -> None:
    """Loaded masses and meshes agree with an independent lxml reading of the file."""
    path = REFERENCE_ROBOTS[name]
    loaded = load_urdf_strict(path, ROBOT_DIRS)
    root = etree.parse(str(path)).getroot()
    file_mass = sum(float(m.get("value")) for m in root.iter("mass"))
    model_mass = sum(inertia.mass for inertia in loaded.model.inertias)
    # a sum of ~10 masses in another order: round-off ~1e-15 relative
    np.testing.assert_allclose(model_mass, file_mass, rtol=1e-12)
    visual_meshes = root.findall("link/visual/geometry/mesh")
    mesh_paths = [g.meshPath for g in loaded.visual_model.geometryObjects]
    assert len(mesh_paths) == len(visual_meshes)
    for mesh_path in mesh_paths:
        assert Path(mesh_path) in loaded.resources
        assert Path(mesh_path).is_relative_to(ROBOTS.resolve())
        assert Path(mesh_path).is_file()


def test_collada_textures_of_example_robot_data_pass_the_path_rules() -> None:
    """anymal_c's .dae textures (ur5/panda .dae have none) resolve inside, as lxml lists them."""
    meshes = sorted((ROBOTS / "anymal_c_simple_description/meshes").glob("*.dae"))
    assert meshes
    ns = {"c": "http://www.collada.org/2005/11/COLLADASchema"}
    for dae in meshes:
        listed = (
            etree.parse(str(dae)).getroot().xpath("//c:library_images//c:init_from", namespaces=ns)
        )
        expected = {(dae.parent / e.text.strip()).resolve() for e in listed}
        found = set(check_mesh(dae.resolve(), [ROBOTS.resolve()], Site(str(dae), "<mesh>", None)))
        assert found == expected
        assert expected  # each of these meshes is textured


def test_every_truncation_is_a_syntax_error() -> None:
    """Each of the ~3500 proper prefixes of double_pendulum.urdf is refused as malformed XML."""
    data = REFERENCE_ROBOTS["double_pendulum"].read_bytes()
    end = data.rindex(b"</robot>") + len(b"</robot>")
    parse_xml_strict(data, "whole")  # the complete file parses
    for k in range(end):
        with pytest.raises(URDFSyntaxError):
            parse_xml_strict(data[:k], f"prefix {k}")


@given(st.floats(allow_nan=False, allow_infinity=False))
def test_parse_number_reads_every_finite_float(x: float) -> None:
    """repr() and %.17e of any finite float parse back to exactly that float."""
    where = Site("f", "<e>", 1)
    assert parse_number(repr(x), where, "a") == x
    assert parse_number(f"{x:.17e}", where, "a") == x


@given(st.text(max_size=12) | st.from_regex(r"\s*[-+]?[0-9_.,eEx]{0,8}\s*", fullmatch=True))
def test_parse_number_accepts_exactly_finite_decimals(text: str) -> None:
    """parse_number accepts a string iff float() reads it finitely and it uses only 0-9 + - . e E.

    Surrounding ASCII blanks are allowed; anything else (``1_0``, ``nan``, ``1,5``,
    Unicode digits or spaces) is refused although ``float`` may read it.
    """
    try:
        reference = float(text)
    except ValueError:
        reference = math.nan
    ascii_decimal = set(text.strip(" \t\r\n")) <= set("0123456789+-.eE")
    should_accept = ascii_decimal and math.isfinite(reference)
    try:
        value = parse_number(text, Site("f", "<e>", 1), "a")
    except InvalidModelError:
        assert not should_accept
    else:
        assert should_accept and value == reference


def test_errors_name_file_element_line_and_rule() -> None:
    """A rule violation reports the file, the element with its link, the line and the rule."""
    path = CORPUS / "physics" / "mass_nan.urdf"
    line = next(i for i, s in enumerate(path.read_text().splitlines(), 1) if 'value="nan"' in s)
    with pytest.raises(InvalidModelError) as info:
        check_urdf_text(path, [])
    error = info.value
    assert (error.path, error.line) == (str(path), line)
    assert error.element == "<mass> of link 'arm'"
    assert error.rule
    assert str(error).startswith(f"{path}:{line}: <mass> of link 'arm': value='nan'")


def test_check_urdf_text_keeps_source_lines(corpus_packages: Path) -> None:
    """The returned tree's elements carry the line numbers of the file."""
    path = CORPUS / "valid" / "minimal.urdf"
    tree = check_urdf_text(path, [corpus_packages])
    lines = path.read_text().splitlines()
    joint = tree.getroot().find("joint")
    assert joint is not None
    assert lines[joint.sourceline - 1].strip().startswith('<joint name="shoulder"')


def test_pinocchio_silently_drops_a_bad_inertial_and_check_model_catches_it() -> None:
    """Pinocchio loads mass '1,5' as a massless link; check_model compares with the file."""
    valid = (CORPUS / "valid" / "minimal.urdf").read_text()
    broken = valid.replace('<mass value="1.0"/>', '<mass value="1,5"/>')
    model = pin.buildModelFromXML(broken)
    assert model.inertias[1].mass == 0.0  # the silent drop this loader exists for
    tree = parse_xml_strict(valid.encode(), "minimal.urdf")
    with pytest.raises(InvalidModelError, match="add up to 1.0 kg"):
        check_model(model, tree, "minimal.urdf")
    check_model(pin.buildModelFromXML(valid), tree, "minimal.urdf")  # the faithful model passes


def test_urdf_path_must_be_a_small_regular_file(tmp_path: Path, monkeypatch) -> None:
    """Devices, FIFOs, folders and too large files are refused unread; missing is not found."""
    fifo = tmp_path / "robot.urdf"
    os.mkfifo(fifo)
    for path in ("/dev/zero", fifo, tmp_path):
        with pytest.raises(UnsafeURDFError, match="not a regular file"):
            load_urdf_strict(path, [])
    with pytest.raises(RobotNotFound, match="does not exist"):
        load_urdf_strict(tmp_path / "missing.urdf", [])
    monkeypatch.setattr(loader, "MAX_URDF_BYTES", 100)
    with pytest.raises(UnsafeURDFError, match="larger than 100 bytes"):
        load_urdf_strict(CORPUS / "valid" / "minimal.urdf", [])


@pytest.mark.parametrize("kind", ["URDF", "MJCF"])
def test_read_description_parses_as_lxml_and_names_the_kind(
    kind: str, tmp_path: Path, monkeypatch
) -> None:
    """read_description: the tree lxml reads; missing, special, DOCTYPE, unreadable: refused."""
    path = CORPUS / "valid" / "minimal.urdf"
    tree = read_description(path, kind, SizeLimits())
    reference = etree.parse(str(path), etree.XMLParser(remove_comments=True, remove_pis=True))
    assert [(e.tag, e.sourceline, dict(e.attrib)) for e in tree.iter()] == [
        (e.tag, e.sourceline, dict(e.attrib)) for e in reference.iter()
    ]
    missing = tmp_path / "missing.xml"
    with pytest.raises(RobotNotFound, match=f"^{kind} file '{missing}' does not exist$"):
        read_description(missing, kind, SizeLimits())
    fifo = tmp_path / "robot.xml"
    os.mkfifo(fifo)
    with pytest.raises(UnsafeURDFError, match=f"{kind} '{fifo}' is not a regular file"):
        read_description(fifo, kind, SizeLimits())
    with pytest.raises(UnsafeURDFError, match="DOCTYPE"):
        read_description(CORPUS / "unsafe_xml" / "plain_doctype.urdf", kind, SizeLimits())
    with pytest.raises(UnsafeURDFError):
        read_description(path, kind, SizeLimits(max_xml_elements=1))

    def unreadable(*args: object) -> bytes:
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(loader, "read_regular_file", unreadable)
    with pytest.raises(ModelError, match=f"^cannot read {kind} file '{path}': .*Permission denied"):
        read_description(path, kind, SizeLimits())


def test_load_model_names_a_fifo_or_a_device_for_what_it_is(tmp_path: Path) -> None:
    """load_model on a FIFO or a device says what the path is (it is never opened)."""
    fifo = tmp_path / "robot.urdf"
    os.mkfifo(fifo)
    for path, kind in ((fifo, "a FIFO"), ("/dev/zero", "a character device")):
        with pytest.raises(RobotNotFound, match=f"nor an existing URDF file .*is {kind}"):
            load_model(path)


def test_a_name_too_long_for_a_path_is_not_found() -> None:
    """A source longer than the file system allows (OSError ENAMETOOLONG) is not found, by name.

    Found by the command-line fuzzer (``report --robot aaaa...``): ``Path.is_file``
    raised instead of answering False.
    """
    from youbot_opt.robot.load import load_model

    with pytest.raises(RobotNotFound, match="nor an existing URDF file"):
        load_model("a" * 5000)


def test_package_dirs_must_be_existing_folders(tmp_path: Path) -> None:
    """A missing package folder or a bare string instead of a sequence is a ParameterError."""
    urdf = CORPUS / "valid" / "single_link.urdf"
    with pytest.raises(ParameterError, match="not an existing folder"):
        load_urdf_strict(urdf, [tmp_path / "nowhere"])
    with pytest.raises(ParameterError, match="sequence of folders"):
        load_urdf_strict(urdf, str(tmp_path))  # type: ignore[arg-type]


def test_ros_package_path_is_not_consulted(corpus_packages: Path, monkeypatch) -> None:
    """Pinocchio alone finds package:// meshes via ROS_PACKAGE_PATH; the strict loader does not."""
    urdf = CORPUS / "valid" / "minimal.urdf"
    monkeypatch.setenv("ROS_PACKAGE_PATH", str(corpus_packages))
    text = urdf.read_text()
    model = pin.buildModelFromXML(text)
    found = pin.buildGeomFromUrdfString(model, text, pin.GeometryType.VISUAL)
    assert Path(found.geometryObjects[0].meshPath).is_file()  # Pinocchio looked there
    with pytest.raises(ResourceNotFoundError):
        load_urdf_strict(urdf, [])


def test_geometry_uses_the_checked_real_paths(corpus_packages: Path) -> None:
    """A mesh reached through an inside symlink is loaded from the checked real path."""
    loaded = load_urdf_strict(CORPUS / "valid" / "symlink_inside.urdf", [corpus_packages])
    real = (corpus_packages / "corpus_pkg" / "meshes" / "box.stl").resolve()
    assert [g.meshPath for g in loaded.visual_model.geometryObjects] == [str(real)]
    assert loaded.resources == (real,)


def test_textured_collada_lists_its_texture(corpus_packages: Path) -> None:
    """A .dae texture is checked and reported; the effect's image-id <init_from> is not a path."""
    loaded = load_urdf_strict(CORPUS / "valid" / "textured_dae.urdf", [corpus_packages])
    meshes = (corpus_packages / "corpus_pkg" / "meshes").resolve()
    assert loaded.resources == (meshes / "textured.dae", meshes / "tex.png")


def test_missing_obj_material_library_only_warns(tmp_path: Path) -> None:
    """An .obj whose mtllib is missing loads with a warning naming the URDF element and the .obj."""
    package = _make_corpus_packages(tmp_path)
    (package / "corpus_pkg" / "meshes" / "tetra.mtl").unlink()
    urdf = CORPUS / "valid" / "obj_with_material.urdf"
    line = next(i for i, s in enumerate(urdf.read_text().splitlines(), 1) if "tetra.obj" in s)
    obj = (package / "corpus_pkg" / "meshes" / "tetra.obj").resolve()
    element = "<visual><geometry><mesh filename='package://corpus_pkg/meshes/tetra.obj'>"
    expected = f"{urdf}:{line}: {element} of link 'arm': {obj}:2: material library 'tetra.mtl'"
    with pytest.warns(YoubotOptWarning, match=re.escape(expected) + " is missing"):
        loaded = load_urdf_strict(urdf, [package])
    assert loaded.model.nq == 1


def test_error_inside_a_mesh_is_raised_from_the_urdf_element(corpus_packages: Path) -> None:
    """A .dae texture escaping is reported at the URDF's <mesh>, the .dae's error chained."""
    urdf = CORPUS / "paths" / "dae_texture_dotdot.urdf"
    dae = (corpus_packages / "corpus_pkg" / "meshes" / "evil_texture_dotdot.dae").resolve()
    urdf_line = next(
        i for i, s in enumerate(urdf.read_text().splitlines(), 1) if "evil_texture_dotdot" in s
    )
    dae_line = next(i for i, s in enumerate(dae.read_text().splitlines(), 1) if "etc/passwd" in s)
    with pytest.raises(UnsafePathError) as info:
        load_urdf_strict(urdf, [corpus_packages])
    error, cause = info.value, info.value.__cause__
    assert (error.path, error.line) == (str(urdf), urdf_line)
    assert error.element == (
        "<visual><geometry><mesh filename='package://corpus_pkg/meshes/evil_texture_dotdot.dae'>"
        " of link 'arm'"
    )
    assert isinstance(cause, UnsafePathError)  # same class, the original kept as the cause
    assert (cause.path, cause.line, cause.element) == (str(dae), dae_line, "<init_from>")
    assert error.rule == cause.rule == "resources resolve inside the package directories"
    assert str(error).startswith(f"{urdf}:{urdf_line}: {error.element}: the mesh {str(dae)!r}")
    assert str(error).endswith(str(cause))


@pytest.mark.parametrize(
    ("dae", "detail"),
    [
        (
            "evil_texture_dotdot",
            "<init_from>: '../../../../../../../../../../etc/passwd' resolves to",
        ),
        ("evil_texture_http", "<init_from>: reference 'http://example.com/tex.png' uses a refused"),
        ("missing_texture", "no_such_texture.png', which does not exist"),
        ("broken", ": document: not well-formed XML"),
    ],
)
def test_meshcat_policy_names_the_referencing_object_mesh_texture_and_rule(
    corpus_packages: Path, dae: str, detail: str
) -> None:
    """The HTML export's mesh policy refuses the corpus's bad .dae files as informatively."""
    from youbot_opt.robot.urdf_check.meshes import load_mesh_file

    mesh = corpus_packages / "corpus_pkg" / "meshes" / f"{dae}.dae"
    who = "robot 'corpus', visual geometry 'arm_0'"
    with pytest.raises(URDFError) as info:
        load_mesh_file(mesh, [corpus_packages], referenced_by=who)
    message, error = str(info.value), info.value
    assert message.startswith(f"{mesh}: {who}: the mesh '{mesh.resolve()}' it references")
    assert f"{mesh.resolve()}:" in message and detail in message  # the .dae, its line, the texture
    assert error.rule and message.endswith(f"[rule: {error.rule}]")
    assert type(error.__cause__) is type(error)


@pytest.mark.parametrize(
    "entry",
    [e for e in MANIFEST if "element" in e and "<mesh " in e["element"]],
    ids=lambda e: e["file"],
)
def test_replay_and_loader_refuse_each_hostile_mesh_by_the_same_rule(
    corpus_packages: Path, subprocess_reports: dict[str, dict], entry: dict
) -> None:
    """Each hostile mesh reference of the corpus is refused by the replay as by the loader."""
    from youbot_opt.robot.urdf_check.meshes import load_mesh_file

    ref = re.search(r"filename='([^']*)'", entry["element"]).group(1)  # as in the file
    report = subprocess_reports[entry["file"]]
    with pytest.raises(URDFError) as info:
        load_mesh_file(ref, [corpus_packages], referenced_by="geometry object 'arm_0'")
    assert type(info.value).__name__ == report["error_class"] == entry["expect"]
    assert info.value.rule == report["error_rule"]
    assert entry["match"] in str(info.value)


def test_replay_accepts_every_mesh_the_loader_accepts(corpus_packages: Path) -> None:
    """The valid corpus files' meshes (stl, dae with texture, obj, symlink inside) embed."""
    from youbot_opt.robot.urdf_check.meshes import load_mesh_file

    valid = [CORPUS / e["file"] for e in MANIFEST if e["expect"] == "ok"]
    for urdf in valid:
        loaded = load_urdf_strict(urdf, [corpus_packages])
        for go in loaded.visual_model.geometryObjects:
            if Path(go.meshPath).suffix:
                mesh = load_mesh_file(go.meshPath, [corpus_packages])
                assert mesh.data and mesh.path == Path(go.meshPath)


@pytest.mark.parametrize(
    ("name", "joint", "array", "expected"),
    [
        ("minimal", "shoulder", "lowerPositionLimit", "revolute joint 'shoulder' has the lower"),
        ("minimal", "shoulder", "upperPositionLimit", "revolute joint 'shoulder' has the upper"),
        ("minimal", "shoulder", "velocityLimit", "'shoulder' has the velocity limit (on |v|)"),
        ("minimal", "shoulder", "effortLimit", "'shoulder' has the effort limit (on |tau|)"),
        ("continuous_and_prismatic", "slide", "upperPositionLimit", "prismatic joint 'slide'"),
        ("continuous_and_prismatic", "shoulder", "velocityLimit", "the file gives no limit"),
        ("mimic_and_continuous_limit", "finger_joint", "lowerPositionLimit", "'finger_joint'"),
        ("mimic_and_continuous_limit", "spin", "effortLimit", "continuous joint 'spin' has"),
        ("floating_and_planar", "free", "velocityLimit", "floating joint 'free' has the velocity"),
        ("floating_and_planar", "slide_plane", "effortLimit", "planar joint 'slide_plane'"),
    ],
)
def test_check_model_compares_joint_limits_with_the_file(
    name: str, joint: str, array: str, expected: str
) -> None:
    """A model whose limit is not the file's <limit> (or finite where the file has none) fails."""
    text = (CORPUS / "valid" / f"{name}.urdf").read_text()
    tree = parse_xml_strict(text.encode(), f"{name}.urdf")
    check_model(pin.buildModelFromXML(text), tree, f"{name}.urdf")  # the faithful model passes
    model = pin.buildModelFromXML(text)
    joint_id = model.getJointId(joint)
    index = (model.idx_qs if "Position" in array else model.idx_vs)[joint_id]
    values = getattr(model, array).copy()
    # 1e-6 on limits of order 1 is 1e6 times the loader's 1e-12 relative tolerance
    values[index] = values[index] + 1e-6 if np.isfinite(values[index]) else 5.0
    setattr(model, array, values)
    with pytest.raises(InvalidModelError, match=re.escape(expected)) as info:
        check_model(model, tree, f"{name}.urdf")
    assert info.value.rule.startswith("the model's joint limits are the file's <limit>")


def test_mimic_joint_built_as_mimic_has_no_own_limits() -> None:
    """With mimic=True the mimicking joint has no coordinates: its <limit> is not compared."""
    text = (CORPUS / "valid" / "mimic_and_continuous_limit.urdf").read_text()
    model = pin.buildModelFromXML(text, mimic=True)
    assert model.nvs[model.getJointId("finger_joint")] == 0
    check_model(model, parse_xml_strict(text.encode(), "mimic.urdf"), "mimic.urdf")


@pytest.mark.parametrize("name", sorted(REFERENCE_ROBOTS))
def test_reference_robot_limits_match_an_lxml_reading(name: str) -> None:
    """The loaded position, velocity and effort limits are the <limit> values lxml reads."""
    path = REFERENCE_ROBOTS[name]
    if not path.exists():
        pytest.skip(f"{path} not generated yet")
    model = load_urdf_strict(path, ROBOT_DIRS).model
    movable = 0
    for joint in etree.parse(str(path)).getroot().findall("joint"):
        assert joint.get("type") in ("revolute", "prismatic", "fixed")  # all these robots have
        if joint.get("type") == "fixed":
            continue
        movable += 1
        limit = joint.find("limit")
        joint_id = model.getJointId(joint.get("name"))
        iq, iv = model.idx_qs[joint_id], model.idx_vs[joint_id]
        got = (
            model.lowerPositionLimit[iq],
            model.upperPositionLimit[iq],
            model.velocityLimit[iv],
            model.effortLimit[iv],
        )
        want = tuple(float(limit.get(k, "0")) for k in ("lower", "upper", "velocity", "effort"))
        assert got == want  # the same decimals read by correctly rounded parsers: exactly equal
    assert movable == model.nv


def test_escape_is_checked_before_existence(corpus_packages: Path, tmp_path: Path) -> None:
    """A reference leaving the package is unsafe even when its target does not exist."""
    text = (CORPUS / "valid" / "minimal.urdf").read_text()
    urdf = tmp_path / "robot.urdf"
    urdf.write_text(text.replace("package://corpus_pkg/meshes/box.stl", "/no/such/dir/x.stl"))
    with pytest.raises(UnsafePathError, match="outside"):
        check_urdf_text(urdf, [corpus_packages])


def test_c_stderr_is_captured_and_restored(capfd: pytest.CaptureFixture[str]) -> None:
    """C-level writes to fd 2 during a build are captured, and fd 2 works normally afterwards."""
    with loader._c_stderr_captured() as captured:
        os.write(2, b"urdfdom says hello\n")
    os.write(2, b"after\n")
    assert captured == ["urdfdom says hello"]
    assert capfd.readouterr().err == "after\n"


def test_every_error_is_a_model_error() -> None:
    """The new classes sit under ModelError, so existing handlers keep catching them."""
    for name in ERROR_CLASSES:
        cls = getattr(sys.modules["youbot_opt.exceptions"], name)
        assert issubclass(cls, URDFError) and issubclass(cls, ModelError)


# --- inertia policy: warn on welded links, refuse on moving ones unless lenient (issue 12) ----

_POLICY_URDF = """<robot name="policy">
  <link name="base"/>
  <link name="camera"><inertial><mass value="{cam_mass}"/>
    <inertia ixx="0.001" ixy="0" ixz="0" iyy="0.001" iyz="0" izz="{cam_izz}"/></inertial></link>
  <link name="arm"><inertial><origin xyz="0.2 0 0"/><mass value="1"/>
    <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="{arm_izz}"/></inertial></link>
  <link name="tool"><inertial><mass value="0"/>
    <inertia ixx="{tool_i}" ixy="0" ixz="0" iyy="{tool_i}" iyz="0" izz="{tool_i}"/>
  </inertial></link>
  <joint name="cam_mount" type="fixed"><parent link="base"/><child link="camera"/></joint>
  <joint name="j1" type="revolute"><parent link="base"/><child link="arm"/><axis xyz="0 0 1"/>
    <limit lower="-1" upper="1" effort="10" velocity="1"/></joint>
  <joint name="tool_mount" type="fixed"><parent link="arm"/><child link="tool"/>
    <origin xyz="0.4 0 0"/></joint>
</robot>
"""


def _policy_file(tmp_path: Path, **values: float) -> Path:
    fields = {"cam_mass": 0.1, "cam_izz": 0.001, "arm_izz": 0.01, "tool_i": 0.0} | values
    path = tmp_path / "policy.urdf"
    path.write_text(_POLICY_URDF.format(**fields))
    return path


def test_implausible_inertia_on_a_welded_link_loads_with_a_warning(tmp_path: Path) -> None:
    """A camera welded to the world breaking I1 + I2 >= I3 warns (file, link, rule), loads."""
    path = _policy_file(tmp_path, cam_izz=0.005)
    with pytest.warns(YoubotOptWarning) as record:
        loaded = load_urdf_strict(path, [tmp_path])
    (message,) = [str(w.message) for w in record]
    assert str(path) in message and "link 'camera'" in message
    assert "[rule: principal moments obey the triangle inequality]" in message
    assert "welded to the world" in message and "0.1 kg" in message
    assert loaded.model.nq == 1


def test_implausible_inertia_on_a_moving_link_is_refused_unless_lenient(tmp_path: Path) -> None:
    """A moving link's non-PSD inertia is refused, the message saying how to opt in."""
    path = _policy_file(tmp_path, arm_izz=-0.05)  # about the joint: -0.05 + 1 * 0.2^2 < 0
    with pytest.raises(InvalidModelError, match="link 'arm'") as info:
        load_urdf_strict(path, [tmp_path])
    assert info.value.rule == "inertia is positive semidefinite"
    assert "strict=False" in str(info.value) and "--lenient" in str(info.value)
    with pytest.warns(YoubotOptWarning, match=r"link 'arm'.*strict=False \(--lenient\)"):
        with pytest.raises(InvalidModelError, match="M\\(q\\) is singular"):
            load_urdf_strict(path, [tmp_path], strict=False)  # M(q) indefinite: still refused
    ok = _policy_file(tmp_path, arm_izz=0.03)  # triangle broken, M(q) still positive definite
    with pytest.warns(YoubotOptWarning, match="triangle inequality"):
        assert load_urdf_strict(ok, [tmp_path], strict=False).model.nq == 1


def test_massless_body_with_inertia_says_what_it_adds_to_its_parent(tmp_path: Path) -> None:
    """A massless tool with inertia on a fixed joint: the warning names the parent's joint
    and what Pinocchio adds to its body, which is what the model holds."""
    path = _policy_file(tmp_path, tool_i=0.002)
    with pytest.raises(InvalidModelError, match="mass = 0 implies inertia = 0"):
        load_urdf_strict(path, [tmp_path])
    with pytest.warns(YoubotOptWarning) as record:
        loaded = load_urdf_strict(path, [tmp_path], strict=False)
    (message,) = [str(w.message) for w in record]
    assert "link 'tool'" in message and "body of moving joint 'j1'" in message
    assert "adds 0 kg and rotational inertia" in message
    body = loaded.model.inertias[loaded.model.getJointId("j1")]
    # arm: 0.01 + m d^2 = 0.01 + 1 * 0.2^2 about z at the joint; the tool adds 0.002 kg m^2.
    inertia_z = body.inertia[2, 2] + body.mass * (body.lever[0] ** 2 + body.lever[1] ** 2)
    assert body.mass == 1.0 and abs(inertia_z - (0.01 + 0.04 + 0.002)) < 1e-15


def test_locked_joints_weld_the_links_behind_them(tmp_path: Path) -> None:
    """Behind a locked joint, an implausible inertia can change nothing: a warning only."""
    from youbot_opt.robot.load import load_model

    path = _policy_file(tmp_path, arm_izz=0.03)
    with pytest.raises(InvalidModelError, match="link 'arm'"):
        load_model(path)
    with pytest.warns(YoubotOptWarning, match="link 'arm' is welded to the world"):
        assert load_model(path, lock_joints={"j1": 0.5}).nq == 0
