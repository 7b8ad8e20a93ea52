"""Tests of the meshcat replay: loopback server, time-outs, live scene, HTML export, mesh policy."""

from __future__ import annotations

import base64
import io
import json
import os
import re
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from PIL import Image

meshcat = pytest.importorskip("meshcat")
import coal  # noqa: E402
import pinocchio as pin  # noqa: E402
import umsgpack  # noqa: E402

from youbot_opt.exceptions import (  # noqa: E402
    FrameNotFound,
    ModelError,
    ParameterError,
    UnsafePathError,
    ViewerError,
)
from youbot_opt.robot.load import load_model  # noqa: E402
from youbot_opt.robot.urdf_check.meshes import (  # noqa: E402
    check_mesh_file,
    dae_texture_references,
    load_mesh_file,
)
from youbot_opt.viz import MeshcatServer, connect, export_html, replay  # noqa: E402
from youbot_opt.viz.meshcat.geometry import set_object_command  # noqa: E402
from youbot_opt.viz.meshcat.replay import scene_html  # noqa: E402

# ------------------------------------------------------------------ helpers


def _listening_addresses(pid: int) -> list[tuple[str, int]]:
    """(address, port) of every TCP socket of ``pid`` in state LISTEN, read from /proc."""
    inodes = set()
    for fd in Path(f"/proc/{pid}/fd").iterdir():
        try:
            match = re.fullmatch(r"socket:\[(\d+)\]", os.readlink(fd))
        except OSError:
            continue
        if match:
            inodes.add(match.group(1))
    found = []
    for table, family in (("tcp", socket.AF_INET), ("tcp6", socket.AF_INET6)):
        for line in Path(f"/proc/{pid}/net/{table}").read_text().splitlines()[1:]:
            fields = line.split()
            local, state, inode = fields[1], fields[3], fields[9]
            if state != "0A" or inode not in inodes:  # 0A = TCP_LISTEN
                continue
            hex_addr, hex_port = local.split(":")
            raw = bytes.fromhex(hex_addr)  # 32-bit words in host (little-endian) order
            packed = b"".join(raw[i : i + 4][::-1] for i in range(0, len(raw), 4))
            found.append((socket.inet_ntop(family, packed), int(hex_port, 16)))
    return found


def _alive(pid: int) -> bool:
    """Whether ``pid`` exists and is not a zombie."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except FileNotFoundError:
        return False
    return stat.rsplit(")", 1)[1].split()[0] != "Z"


def _wait_dead(pid: int, timeout: float) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if not _alive(pid):
            return True
        time.sleep(0.05)
    return not _alive(pid)


def _port(url: str) -> int:
    return int(url.rsplit(":", 1)[1].split("/")[0])


def _server_scene(vis: meshcat.Visualizer) -> list[dict]:
    """Decode the commands the server keeps for its scene (its own static HTML)."""
    html = vis.static_html()
    blobs = re.findall(r"data:application/octet-binary;base64,([A-Za-z0-9+/=]+)", html)
    return [umsgpack.unpackb(base64.b64decode(b)) for b in blobs]


def _page_commands(page: str) -> list[dict]:
    """Decode the commands an exported page replays."""
    blob = re.search(r"var commands = (\[.*?\]);", page, re.S)
    assert blob is not None
    return [umsgpack.unpackb(base64.b64decode(c)) for c in json.loads(blob.group(1))]


def _geometry_pose(robot, q: np.ndarray, go) -> np.ndarray:
    """Pose of a geometry object, composed by hand from the joint placement."""
    data = robot.model.createData()
    pin.forwardKinematics(robot.model, data, q)
    return (data.oMi[go.parentJoint] * go.placement).homogeneous


def _tip(robot, q: np.ndarray) -> np.ndarray:
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, q)
    return data.oMf[robot.model.getFrameId(robot.tip_frame)].translation.copy()


@pytest.fixture(scope="module")
def ur5():
    """The UR5 of example-robot-data (COLLADA visuals)."""
    return load_model("ur5")


@pytest.fixture(scope="module")
def server():
    """One loopback meshcat server for the module, stopped at its end."""
    with MeshcatServer(timeout=20.0) as srv:
        yield srv


def _ramp(robot, n: int, duration: float) -> tuple[np.ndarray, np.ndarray]:
    t = np.linspace(0.0, duration, n)
    q_end = pin.neutral(robot.model) + 0.6
    return t, np.outer(t / duration, q_end) + np.outer(1 - t / duration, pin.neutral(robot.model))


# ------------------------------------------------------------------- server


def test_listening_reader_sees_a_wildcard_bind():
    """The /proc reader reports 0.0.0.0 for a socket bound to all interfaces (it can fail)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
        sock.bind(("0.0.0.0", 0))
        sock.listen()
        assert ("0.0.0.0", sock.getsockname()[1]) in _listening_addresses(os.getpid())


def test_server_listens_on_loopback_only_and_stops(server):
    """All listening sockets of the server are on 127.0.0.1; close() ends it; calls time out."""
    addresses = _listening_addresses(server.pid)
    ports = {port for _, port in addresses}
    assert {_port(server.zmq_url), _port(server.web_url)} <= ports
    assert {address for address, _ in addresses} == {"127.0.0.1"}
    with MeshcatServer() as other:
        pid = other.pid
        vis = other.visualizer(timeout=0.5)
        vis["box"].set_object(meshcat.geometry.Box([0.1, 0.1, 0.1]))  # answered
    assert not other.running
    assert _wait_dead(pid, timeout=0.1)  # close() waited for the process
    with pytest.raises(ProcessLookupError):
        os.kill(pid, 0)
    start = time.monotonic()
    with pytest.raises(ViewerError, match="did not answer within 0.5 s"):
        vis["box"].set_transform(np.eye(4))  # a dead server: time-out, not a hang
    # RCVTIMEO is 0.5 s; 3 s of slack covers a loaded 2-core machine.
    assert 0.45 <= time.monotonic() - start < 3.5
    vis.close()


def test_get_image_of_a_dead_server_raises_viewer_error():
    """get_image() on a stopped server times out with ViewerError (it once was AttributeError)."""
    with MeshcatServer() as other:
        vis = other.visualizer(timeout=0.5)
    start = time.monotonic()
    with pytest.raises(ViewerError, match=r"did not answer within 0.5 s.*needs a browser"):
        vis.get_image()
    # RCVTIMEO is 0.5 s; 3 s of slack covers a loaded 2-core machine.
    assert 0.45 <= time.monotonic() - start < 3.5
    vis.close()


class _BodyFailed(Exception):
    """Raised inside a with block by the test below."""


def test_with_block_that_raises_stops_the_server():
    """An exception in the body of `with MeshcatServer()` stops the server and frees its ports."""
    with pytest.raises(_BodyFailed):
        with MeshcatServer() as srv:
            pid = srv.pid
            ports = {_port(srv.zmq_url), _port(srv.web_url)}
            assert ports <= {port for _, port in _listening_addresses(pid)}  # it was listening
            raise _BodyFailed
    assert not srv.running
    assert _wait_dead(pid, timeout=0.1)  # close() waited for the process
    for port in ports:  # nothing listens there any more: connections are refused
        with socket.socket() as sock:
            assert sock.connect_ex(("127.0.0.1", port)) != 0


def test_call_to_a_port_without_server_times_out():
    """Connecting to an address where no server answers raises ViewerError after the time-out."""
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        port = sock.getsockname()[1]  # free once closed
    start = time.monotonic()
    with pytest.raises(ViewerError, match="did not answer within 0.3 s"):
        connect(f"tcp://127.0.0.1:{port}", timeout=0.3)
    # RCVTIMEO is 0.3 s; 3 s of slack covers a loaded 2-core machine.
    assert 0.25 <= time.monotonic() - start < 3.3


_CHILD = """
import signal, sys, time
from youbot_opt.viz.meshcat.server import MeshcatServer
mode = sys.argv[1]
if mode == "chain":
    def previous(signum, frame):
        print("previous handler ran", flush=True)
        sys.exit(7)
    signal.signal(signal.SIGTERM, previous)
server = MeshcatServer(timeout=20.0)
print(server.pid, flush=True)
if mode != "exit":
    time.sleep(60)
"""


_MODES = {  # mode: (signal sent to the child, expected exit code of the child)
    "default": (signal.SIGTERM, -signal.SIGTERM),  # the default action still ends the child
    "chain": (signal.SIGTERM, 7),  # the previous Python handler runs after the cleanup
    "exit": (None, 0),  # a normal exit: atexit
    "kill": (signal.SIGKILL, -signal.SIGKILL),  # no cleanup code runs: the server sees EOF
}


@pytest.fixture(scope="module")
def children():
    """One child process per mode, each with a server, started together to save time."""
    procs = {
        mode: subprocess.Popen(
            [sys.executable, "-c", _CHILD, mode], stdout=subprocess.PIPE, text=True
        )
        for mode in _MODES
    }
    try:
        yield {mode: (proc, int(proc.stdout.readline())) for mode, proc in procs.items()}
    finally:
        for proc in procs.values():
            proc.kill()
            proc.communicate()


@pytest.mark.parametrize("mode", list(_MODES))
def test_server_stops_with_its_parent(children, mode):
    """The server ends when its parent gets SIGTERM (chaining handlers), exits, or is killed."""
    child, server_pid = children[mode]
    send, returncode = _MODES[mode]
    if send is not None:
        assert _alive(server_pid)
        child.send_signal(send)
    out, _ = child.communicate(timeout=30)
    assert child.returncode == returncode
    assert ("previous handler ran" in out) == (mode == "chain")
    assert _wait_dead(server_pid, timeout=10.0)


# -------------------------------------------------------------- live replay


def test_live_replay_sends_forward_kinematics_in_real_time(ur5, server):
    """Live replay ends at the last knot's poses, lasts the trajectory, draws path and targets."""
    t, q = _ramp(ur5, n=5, duration=0.4)
    targets = np.array([[0.3, 0.2, 0.5], [0.1, -0.4, 0.3]])
    vis = server.visualizer()
    start = time.perf_counter()
    replay(ur5, t, q, viewer=vis, targets=targets, ghosts=[(t, q[::-1])], extra=[(t, q, "b")])
    assert time.perf_counter() - start >= 0.4  # the last pose is sent 0.4 s after the first
    scene = _server_scene(vis)
    transforms = {
        c["path"]: np.reshape(c["matrix"], (4, 4)).T for c in scene if c["type"] == "set_transform"
    }
    objects = {c["path"]: c for c in scene if c["type"] == "set_object"}
    for go in ur5.visual_model.geometryObjects:
        main = transforms[f"/meshcat/youbot_opt/ur5/visuals/{go.name}"]
        ghost = transforms[f"/meshcat/youbot_opt/ghost_0/visuals/{go.name}"]
        # float64 matrices travel exactly (msgpack doubles); 1e-12 allows for rounding only.
        np.testing.assert_allclose(main, _geometry_pose(ur5, q[-1], go), atol=1e-12)
        np.testing.assert_allclose(ghost, _geometry_pose(ur5, q[0], go), atol=1e-12)
    offset_main = transforms["/meshcat/youbot_opt/ur5"][:3, 3]
    offset_b = transforms["/meshcat/youbot_opt/b"][:3, 3]
    reach = max(np.linalg.norm(_tip(ur5, qk)) for qk in q)  # [m] largest tip distance
    # copies centred on the origin, 2.2 reaches apart along y (the documented default)
    np.testing.assert_allclose(offset_b, [0.0, 1.1 * reach, 0.0], atol=1e-12)
    np.testing.assert_allclose(offset_main, -offset_b, atol=1e-12)
    line = objects["/meshcat/youbot_opt/ur5/ee_path"]["object"]["geometries"][0]
    raw = line["data"]["attributes"]["position"]["array"].data
    points = np.frombuffer(raw, dtype=np.float32).reshape(-1, 3)
    expected = np.array([_tip(ur5, qk) for qk in q])
    # float32 vertices: 6e-8 relative rounding on a ~1 m reach.
    np.testing.assert_allclose(points, expected, atol=1e-6)
    for k, target in enumerate(targets):
        np.testing.assert_allclose(
            transforms[f"/meshcat/youbot_opt/ur5/targets/{k}"][:3, 3], target, atol=1e-12
        )


def test_replay_rejects_bad_input(ur5):
    """Bad shapes, orders, rates, robots and viewers raise errors that name the argument."""
    t, q = _ramp(ur5, n=4, duration=1.0)
    with pytest.raises(ParameterError, match=r"q must be a finite array of shape \(N, nq\)"):
        replay(ur5, t, q[:, :3], viewer=object())
    with pytest.raises(ParameterError, match="strictly increasing"):
        replay(ur5, t[::-1], q, viewer=object())
    with pytest.raises(ParameterError, match=r"targets must be a finite \(K, 3\)"):
        replay(ur5, t, q, targets=np.zeros((2, 2)), viewer=object())
    with pytest.raises(ParameterError, match="speed must be a positive"):
        replay(ur5, t, q, speed=0.0)
    with pytest.raises(ParameterError, match="viewer must be None"):
        replay(ur5, t, q, viewer=object())
    with pytest.raises(ParameterError, match="fps must be a positive"):
        scene_html(ur5, t, q, fps=-1.0)
    robot = SimpleNamespace(
        **{k: getattr(ur5, k) for k in ("name", "model", "visual_model", "package_dirs")},
        tip_frame="nope",
    )
    with pytest.raises(FrameNotFound, match="nope"):
        scene_html(robot, t, q)


# ------------------------------------------------------------------- export


def test_export_html_needs_no_server_and_holds_the_motion(ur5, tmp_path, monkeypatch):
    """The page is built without any subprocess, embeds the meshes and keys the FK poses."""

    def no_process(*args, **kwargs):
        raise AssertionError("export_html must not start a process")

    monkeypatch.setattr(subprocess, "Popen", no_process)
    t, q = _ramp(ur5, n=7, duration=0.5)
    fps = 20.0
    path = export_html(ur5, t, q, tmp_path / "ur5.html", fps=fps)
    page = path.read_text(encoding="utf-8")
    main_js = (Path(meshcat.__file__).parent / "viewer/dist/main.min.js").read_text("utf-8")
    assert main_js in page
    template = re.sub(r"var commands = \[.*?\];", "", page.replace(main_js, ""), flags=re.S)
    assert "http" not in template and "src=" not in template  # nothing fetched at view time
    commands = _page_commands(page)
    meshes = {c["path"]: c["object"]["object"] for c in commands if c["type"] == "set_object"}
    for go in ur5.visual_model.geometryObjects:
        mesh = meshes[f"/meshcat/youbot_opt/ur5/visuals/{go.name}"]
        assert mesh["type"] == "_meshfile_object"
        assert mesh["data"] == Path(go.meshPath).read_text(encoding="utf-8")
    (animation,) = [c for c in commands if c["type"] == "set_animation"]
    clips = {a["path"]: a["clip"] for a in animation["animations"]}
    times = np.append(np.arange(0.0, 0.5, 1 / fps), 0.5)  # every 1/fps, and the end
    go = ur5.visual_model.geometryObjects[3]
    clip = clips[f"/meshcat/youbot_opt/ur5/visuals/{go.name}"]
    assert clip["fps"] == fps
    tracks = {track["name"]: track["keys"] for track in clip["tracks"]}
    np.testing.assert_allclose([k["time"] / fps for k in tracks[".position"]], times, atol=1e-12)
    for key_pos, key_quat, time_s in zip(
        tracks[".position"], tracks[".quaternion"], times, strict=True
    ):
        q_ref = np.array([np.interp(time_s, t, q[:, j]) for j in range(ur5.model.nq)])  # revolute
        pose = pin.SE3(_geometry_pose(ur5, q_ref, go))
        quat = pin.Quaternion(pose.rotation).coeffs()  # x, y, z, w as three.js
        np.testing.assert_allclose(key_pos["value"], pose.translation, atol=1e-12)
        sign = np.sign(np.dot(quat, key_quat["value"]))  # q and -q are one rotation
        np.testing.assert_allclose(key_quat["value"], sign * quat, atol=1e-12)


def test_export_html_primitives_and_parameters(tmp_path, youbot):
    """The youBot's boxes and cylinders become meshcat primitives of the URDF size."""
    robot = youbot
    t = np.array([0.0, 1.0])
    q = np.zeros((2, robot.model.nq))
    page = scene_html(robot, t, q)
    objects = {c["path"]: c["object"] for c in _page_commands(page) if c["type"] == "set_object"}
    for go in robot.visual_model.geometryObjects:
        geometry = objects[f"/meshcat/youbot_opt/{robot.name}/visuals/{go.name}"]["geometries"][0]
        if isinstance(go.geometry, coal.Cylinder):
            assert geometry["type"] == "CylinderGeometry"
            assert geometry["height"] == pytest.approx(2 * go.geometry.halfLength, abs=1e-15)
            assert geometry["radiusTop"] == pytest.approx(go.geometry.radius, abs=1e-15)
        else:
            assert isinstance(go.geometry, coal.Box)
            sides = [geometry["width"], geometry["height"], geometry["depth"]]
            np.testing.assert_allclose(sides, 2 * go.geometry.halfSide, atol=1e-15)
    with pytest.raises(ParameterError, match="does not exist"):
        export_html(robot, t, q, tmp_path / "missing" / "x.html")


def _lowered(go, package_dirs=(), opacity=1.0) -> dict:
    command = set_object_command(go, package_dirs, opacity, meshcat.path.Path(("x",)))
    return command.lower()["object"]


def test_geometry_commands_for_spheres_capsules_stl_and_ghost_meshes(ur5, tmp_path):
    """Each shape becomes the meshcat object of its size; ghosts of COLLADA meshes are triangles."""
    placement = pin.SE3.Identity()
    sphere = _lowered(pin.GeometryObject("s", 0, placement, coal.Sphere(0.07)))
    assert sphere["geometries"][0]["type"] == "SphereGeometry"
    assert sphere["geometries"][0]["radius"] == 0.07
    capsule = _lowered(pin.GeometryObject("c", 0, placement, coal.Capsule(0.05, 0.4)))  # lz = 0.4
    raw = capsule["geometries"][0]["data"]["attributes"]["position"]["array"].data
    vertices = np.frombuffer(raw, dtype=np.float32).reshape(-1, 3)
    nearest = np.clip(vertices[:, 2], -0.2, 0.2)  # closest point on the axis segment
    distance = np.hypot(np.hypot(vertices[:, 0], vertices[:, 1]), vertices[:, 2] - nearest)
    np.testing.assert_allclose(distance, 0.05, atol=1e-6)  # float32 vertices
    assert vertices[:, 2].min() == pytest.approx(-0.25) and vertices[:, 2].max() == pytest.approx(
        0.25
    )
    stl = tmp_path / "part.stl"
    stl.write_bytes(b"solid part\nendsolid part\n")
    scale, color = np.array([2.0, 3.0, 4.0]), np.array([1.0, 0.0, 0.0, 0.5])
    go = pin.GeometryObject("p", 0, placement, coal.Sphere(0.1), str(stl), scale, False, color)
    lowered = _lowered(go, (tmp_path,))
    geometry, material = lowered["geometries"][0], lowered["materials"][0]
    assert geometry["type"] == "_meshfile_geometry" and geometry["format"] == "stl"
    assert geometry["data"].data == stl.read_bytes()
    np.testing.assert_array_equal(
        np.diag(np.reshape(lowered["object"]["matrix"], (4, 4))), [2, 3, 4, 1]
    )
    assert material["color"] == 0xFF0000 and material["opacity"] == 0.5 and material["transparent"]
    dae = ur5.visual_model.geometryObjects[1]
    ghost = _lowered(dae, ur5.package_dirs, opacity=0.35)
    raw = ghost["geometries"][0]["data"]["attributes"]["position"]["array"].data
    vertices = np.frombuffer(raw, dtype=np.float32).reshape(-1, 3)
    np.testing.assert_allclose(vertices, dae.geometry.vertices(), atol=1e-6)  # float32 rounding
    assert ghost["materials"][0]["opacity"] == pytest.approx(0.35)


# -------------------------------------------------------------- mesh policy


def _png() -> bytes:
    buffer = io.BytesIO()
    Image.new("RGB", (2, 2), (0, 255, 0)).save(buffer, format="PNG")
    return buffer.getvalue()


_PNG = _png()


def _dae(texture: str) -> str:
    return (
        '<?xml version="1.0"?><COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" '
        f'version="1.4.1"><library_images><image id="i"><init_from>{texture}</init_from>'
        "</image></library_images></COLLADA>"
    )


@pytest.fixture()
def package(tmp_path: Path) -> Path:
    """A package folder with a mesh folder, next to a file outside it."""
    (tmp_path / "pkg" / "meshes").mkdir(parents=True)
    (tmp_path / "pkg" / "meshes" / "ok.png").write_bytes(_PNG)
    (tmp_path / "outside.png").write_bytes(_PNG)
    return tmp_path / "pkg"


@pytest.mark.parametrize(
    ("texture", "rule"),
    [
        ("../../outside.png", "resolve inside the package directories"),
        ("..&#47;..&#47;outside.png", "resolve inside the package directories"),  # XML-encoded
        ("%2E%2E/%2E%2E/outside.png", "resolve inside the package directories"),  # %-encoded
        ("/etc/hostname", "resolve inside the package directories"),
        ("file:///etc/hostname", "resolve inside the package directories"),
        ("http://example.com/x.png", "uses a refused URL form (http:)"),
    ],
)
def test_dae_texture_outside_the_package_is_refused(package, texture, rule):
    """A COLLADA texture that escapes the package or is a URL is refused, naming file and rule."""
    dae = package / "meshes" / "bad.dae"
    dae.write_text(_dae(texture))
    with pytest.raises(ModelError, match=re.escape(rule)) as info:
        load_mesh_file(dae, [package])
    assert str(dae) in str(info.value) and "rule:" in str(info.value)


def test_symlinks_escaping_the_package_are_refused(package):
    """A mesh or texture that is a symlink to a file outside the package is refused."""
    outside_mesh = package.parent / "outside.stl"
    outside_mesh.write_bytes(b"solid x\nendsolid x\n")
    (package / "meshes" / "link.stl").symlink_to(outside_mesh)
    with pytest.raises(ModelError, match="resolves to"):
        check_mesh_file(package / "meshes" / "link.stl", [package])
    (package / "meshes" / "tex.png").symlink_to(package.parent / "outside.png")
    dae = package / "meshes" / "m.dae"
    dae.write_text(_dae("tex.png"))
    with pytest.raises(ModelError, match="resolves to"):
        load_mesh_file(dae, [package])


def test_mesh_policy_accepts_package_files_and_embeds_textures(package):
    """Files inside the package pass; a texture is embedded as a data URI of its exact bytes."""
    dae = package / "meshes" / "m.dae"
    dae.write_text(_dae(" ok.png "))  # whitespace kept in the key, as the browser reads it
    mesh = load_mesh_file(dae, [package])
    assert mesh.format == "dae" and mesh.data == dae.read_bytes()
    uri = mesh.resources[" ok.png "]
    assert uri.startswith("data:image/png;base64,")
    assert base64.b64decode(uri.split(",", 1)[1]) == _PNG
    inline = "data:image/png;base64," + base64.b64encode(_PNG).decode()
    dae.write_text(_dae(inline))
    assert load_mesh_file(dae, [package]).resources == {inline: inline}
    assert dae_texture_references(b"<COLLADA/>") == []


@pytest.mark.parametrize(
    ("mesh", "rule"),
    [
        ("http://example.com/m.stl", "uses a refused URL form (http:)"),
        ("{pkg}/meshes/m.fbx", "mesh formats are .stl, .dae, .obj, .ply"),
        ("{pkg}/../outside.png", "resolve inside the package directories"),
        ("{pkg}/meshes/none.stl", "referenced files exist"),
    ],
)
def test_mesh_files_breaking_the_rules_are_refused(package, mesh, rule):
    """URLs, unsupported formats and files outside the package are refused as meshes."""
    (package / "meshes" / "m.fbx").write_text("Kaydara FBX\n")
    with pytest.raises(ModelError, match=re.escape(rule)):
        check_mesh_file(mesh.format(pkg=package), [package])


def test_texture_a_browser_cannot_decode_is_refused(package):
    """A texture inside the package but in a format browsers do not decode is not embedded."""
    (package / "meshes" / "t.tga").write_bytes(b"\x00" * 18)
    dae = package / "meshes" / "m.dae"
    dae.write_text(_dae("t.tga"))
    assert check_mesh_file(dae, [package]) == dae.resolve()  # the path policy accepts it
    with pytest.raises(UnsafePathError, match=re.escape("embedded textures are .png")):
        load_mesh_file(dae, [package], referenced_by="geometry object 'g'")


_TETRA_PLY = """ply
format ascii 1.0
element vertex 4
property float x
property float y
property float z
element face 4
property list uchar int vertex_indices
end_header
0 0 0
0.1 0 0
0 0.1 0
0 0 0.1
3 0 2 1
3 0 1 3
3 0 3 2
3 1 2 3
"""


def _ply_urdf(mesh: str) -> str:
    return f"""<?xml version="1.0"?>
<robot name="plybot">
  <link name="base"/>
  <link name="arm">
    <inertial>
      <mass value="1.0"/><inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/>
    </inertial>
    <visual><geometry><mesh filename="{mesh}" scale="2 2 2"/></geometry></visual>
  </link>
  <joint name="shoulder" type="revolute">
    <parent link="base"/><child link="arm"/><axis xyz="0 0 1"/>
    <limit lower="-1.5" upper="1.5" effort="10" velocity="2"/>
  </joint>
</robot>
"""


def test_ply_mesh_loads_and_exports_and_outside_is_refused_by_both(tmp_path):
    """A .ply inside the package loads and exports (as STL); outside, both refuse by one rule."""
    package = tmp_path / "pkg"
    (package / "plypkg" / "meshes").mkdir(parents=True)
    (package / "plypkg" / "meshes" / "tetra.ply").write_text(_TETRA_PLY)
    (tmp_path / "outside.ply").write_text(_TETRA_PLY)
    (tmp_path / "robot").mkdir()
    urdf = tmp_path / "robot" / "plybot.urdf"  # load_model adds the URDF's folder to the roots
    urdf.write_text(_ply_urdf("package://plypkg/meshes/tetra.ply"))
    robot = load_model(urdf, package_dirs=[package])
    t, q = _ramp(robot, n=3, duration=1.0)
    page = export_html(robot, t, q, tmp_path / "ply.html").read_text(encoding="utf-8")
    (go,) = robot.visual_model.geometryObjects
    objects = {c["path"]: c["object"] for c in _page_commands(page) if c["type"] == "set_object"}
    (drawn,) = [o for path, o in objects.items() if path.endswith(f"/visuals/{go.name}")]
    geometry = drawn["geometries"][0]
    assert geometry["type"] == "_meshfile_geometry" and geometry["format"] == "stl"
    stl = geometry["data"].data
    assert not stl.startswith(b"solid") and int.from_bytes(stl[80:84], "little") == 4
    corners = np.frombuffer(
        stl[84:], dtype=np.dtype([("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")])
    )
    np.testing.assert_allclose(np.unique(corners["v"].reshape(-1, 3), axis=0).max(), 0.1, atol=1e-7)
    np.testing.assert_allclose(np.linalg.norm(corners["n"], axis=1), 1.0, atol=1e-6)
    np.testing.assert_array_equal(
        np.diag(np.reshape(drawn["object"]["matrix"], (4, 4))), [2, 2, 2, 1]
    )

    outside = str(tmp_path / "outside.ply")
    urdf.write_text(_ply_urdf(outside))
    with pytest.raises(UnsafePathError) as by_loader:
        load_model(urdf, package_dirs=[package])
    visual = pin.GeometryModel()
    visual.addGeometryObject(
        pin.GeometryObject("arm_0", 1, pin.SE3.Identity(), coal.Sphere(0.1), outside)
    )
    crafted = SimpleNamespace(
        name="plybot",
        model=robot.model,
        visual_model=visual,
        package_dirs=(package,),
        tip_frame=robot.tip_frame,
    )
    with pytest.raises(UnsafePathError) as by_replay:
        export_html(crafted, t, q, tmp_path / "refused.html")
    assert (
        by_replay.value.rule
        == by_loader.value.rule
        == "resources resolve inside the package directories"
    )
    assert f"{outside!r} resolves to" in str(by_loader.value) and outside in str(by_replay.value)
    assert not (tmp_path / "refused.html").exists()


def test_export_refuses_a_robot_with_an_escaping_mesh(ur5, package, tmp_path):
    """export_html raises before writing anything when a mesh breaks the policy."""
    dae = package / "meshes" / "bad.dae"
    dae.write_text(_dae("../../outside.png"))
    visual = pin.GeometryModel()
    visual.addGeometryObject(
        pin.GeometryObject("bad", 0, pin.SE3.Identity(), coal.Sphere(0.1), str(dae))
    )
    robot = SimpleNamespace(
        name="crafted",
        model=ur5.model,
        visual_model=visual,
        package_dirs=(package,),
        tip_frame=ur5.tip_frame,
    )
    target = tmp_path / "out.html"
    t, q = _ramp(ur5, n=2, duration=1.0)
    with pytest.raises(ModelError, match="outside.png") as err:
        export_html(robot, t, q, target)
    assert "geometry object 'bad'" in str(err.value)  # names what referenced the mesh
    assert not target.exists()


# ------------------------------------------------------------------ Host header (DNS rebinding)


def _raw_request(port: int, host: str, path: str, *, upgrade: bool) -> str:
    """Send one raw HTTP/1.1 request to 127.0.0.1:port and return the status line."""
    lines = [f"GET {path} HTTP/1.1", f"Host: {host}"]
    if upgrade:
        lines += [
            "Upgrade: websocket",
            "Connection: Upgrade",
            "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==",
            "Sec-WebSocket-Version: 13",
        ]
    else:
        lines.append("Connection: close")
    with socket.create_connection(("127.0.0.1", port), timeout=10.0) as sock:
        sock.sendall(("\r\n".join(lines) + "\r\n\r\n").encode())
        reply = b""
        while b"\r\n" not in reply:
            chunk = sock.recv(4096)
            if not chunk:
                break
            reply += chunk
    return reply.split(b"\r\n", 1)[0].decode()


@pytest.mark.parametrize(
    "host", ["evil.example", "evil.example:{port}", "127.0.0.1:1", "10.0.0.1:{port}"]
)
def test_server_refuses_a_foreign_host_header(server, host):
    port = _port(server.web_url)
    host = host.format(port=port)
    assert " 403 " in _raw_request(port, host, "/", upgrade=True) + " "
    assert " 403 " in _raw_request(port, host, "/static/", upgrade=False) + " "


@pytest.mark.parametrize("name", ["127.0.0.1", "localhost", "[::1]", "LOCALHOST"])
def test_server_accepts_the_loopback_host_header(server, name):
    port = _port(server.web_url)
    assert " 101 " in _raw_request(port, f"{name}:{port}", "/", upgrade=True) + " "
    assert " 200 " in _raw_request(port, f"{name}:{port}", "/static/", upgrade=False) + " "
