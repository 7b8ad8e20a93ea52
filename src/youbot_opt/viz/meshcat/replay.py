"""Replay joint trajectories in meshcat: live in a viewer, or as one standalone HTML file.

Inputs are plain arrays: a time grid ``t`` (N,) in [s] and configurations
``q`` (N, nq), interpolated with ``pin.interpolate``; several results can be
overlaid as ghosts or shown side by side. :func:`export_html` needs no server:
the recorded scene commands and meshcat's viewer script go into one HTML file
that plays offline (``#t=<seconds>`` shows that pose, paused). Meshes follow
:mod:`youbot_opt.robot.urdf_check.meshes`; see docs/design.md, "Module notes".

>>> export_html(robot, t, q, "replay.html")  # doctest: +SKIP
"""

from __future__ import annotations

import base64
import json
import logging
import re
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import meshcat
import numpy as np
import umsgpack

from youbot_opt._typing import Array
from youbot_opt.collision.scene import Scene
from youbot_opt.exceptions import ParameterError
from youbot_opt.viz.meshcat import scene
from youbot_opt.viz.meshcat.scene import RobotLike
from youbot_opt.viz.meshcat.server import MeshcatServer, connect

__all__ = ["replay", "export_html", "scene_html"]

logger = logging.getLogger(__name__)


class _Recorder:
    """Duck-types a meshcat window: keeps each command packed as a server would receive it."""

    def __init__(self) -> None:
        self.commands: list[bytes] = []

    def send(self, command: Any) -> None:
        self.commands.append(umsgpack.packb(command.lower()))


_HTML = """<!DOCTYPE html>
<html>
<head><meta charset="utf-8"><title>@TITLE@</title>
<style>body { margin: 0; } #meshcat-pane { width: 100vw; height: 100vh; overflow: hidden; }</style>
</head>
<body>
<div id="meshcat-pane"></div>@LEGEND@
<div id="no-webgl" style="display: none; position: absolute; top: 40%; left: 10%; right: 10%;
 padding: 1em; font: 16px sans-serif; color: #000; background: #fd8; border: 2px solid #a60">
This replay needs WebGL, which this browser has turned off or does not support, so nothing
can be drawn. Open the file in a browser with WebGL (or hardware acceleration) enabled. For
a headless screenshot, run Chromium with
<code>--headless --use-angle=swiftshader --enable-unsafe-swiftshader</code>.</div>
<script>
function youbotOptNoWebGL() {  // a visible message instead of a blank page
  document.getElementById("no-webgl").style.display = "block";
}
(function () {
  var canvas = document.createElement("canvas");
  var gl = null;
  try { gl = canvas.getContext("webgl2") || canvas.getContext("webgl"); } catch (e) { gl = null; }
  window.youbotOptHasWebGL = !!gl;
  if (!gl) { youbotOptNoWebGL(); }
})();
</script>
<script>@MAIN_MIN_JS@</script>
<script>
(function () {
  if (!window.youbotOptHasWebGL) { return; }
  var commands = @COMMANDS@;
  var viewer;
  try {
    viewer = new MeshCat.Viewer(document.getElementById("meshcat-pane"));
  } catch (e) {
    youbotOptNoWebGL();
    throw e;
  }
  window.viewer = viewer;
  for (var i = 0; i < commands.length; i++) {  // in order, synchronously
    var raw = atob(commands[i]);
    var bytes = new Uint8Array(raw.length);
    for (var j = 0; j < raw.length; j++) { bytes[j] = raw.charCodeAt(j); }
    viewer.handle_command_bytearray(bytes);
  }
  var target = @TARGET@;  // orbit target, in three.js's y-up world frame
  viewer.controls.target.set(target[0], target[1], target[2]);
  viewer.controls.update();
  var seek = /[#?&]t=([-+0-9.eE]+)/.exec(window.location.hash + window.location.search);
  if (seek) { viewer.animator.pause(); viewer.animator.seek(parseFloat(seek[1])); }
})();
</script>
</body>
</html>
"""


def _viewer(
    viewer: meshcat.Visualizer | MeshcatServer | str | None,
) -> tuple[meshcat.Visualizer, bool]:
    if viewer is None:
        vis = connect()
        logger.info("meshcat viewer started: open %s", vis.url())
        return vis, True
    if isinstance(viewer, str):
        return connect(viewer), False
    if isinstance(viewer, MeshcatServer):
        return viewer.visualizer(), False
    if isinstance(viewer, meshcat.Visualizer):
        return viewer, False
    raise ParameterError(
        "viewer must be None (start a server), a ZeroMQ URL, a MeshcatServer or a "
        f"meshcat.Visualizer; got {type(viewer).__name__}",
        name="viewer",
    )


def replay(
    robot: RobotLike,
    t: Array,
    q: Array,
    *,
    viewer: meshcat.Visualizer | MeshcatServer | str | None = None,
    frame_path: str = "youbot_opt",
    ee_path: bool = True,
    targets: Array | None = None,
    ghosts: Sequence[tuple[Array, Array]] = (),
    extra: Sequence[tuple[Array, Array, str]] = (),
    spacing: Array | None = None,
    realtime: bool = True,
    speed: float = 1.0,
    label: str | None = None,
    obstacles: Scene | None = None,
) -> meshcat.Visualizer:
    """Play a trajectory in a live meshcat viewer.

    Parameters
    ----------
    robot : RobotLike
        The robot (``youbot_opt.robot.model.RobotModel`` or the same attributes).
    t : ndarray, shape (N,)
        Strictly increasing knot times in [s].
    q : ndarray, shape (N, nq)
        Configurations at the knots in [rad] (or [m] for prismatic joints).
    viewer : meshcat.Visualizer, MeshcatServer, str or None
        Where to draw: a client, a server, a ZeroMQ URL, or None to start a
        loopback server owned by the returned client (``close()`` stops it).
    frame_path : str
        Scene path under which everything is drawn; it is cleared first.
    ee_path : bool
        Draw the path of ``robot.tip_frame`` as a line.
    targets : ndarray, shape (K, 3), optional
        End-effector targets in [m], drawn as small spheres.
    ghosts : sequence of (t, q)
        Further trajectories drawn translucent over the first one.
    extra : sequence of (t, q, label)
        Further trajectories drawn as copies side by side, named ``label``.
    spacing : ndarray, shape (3,), optional
        Offset in [m] between side-by-side copies; 2.2 reaches along y by default.
    realtime : bool
        True: send the poses knot by knot at the pace of the time grid (this
        call takes the trajectory's duration / ``speed``). False: send the
        whole motion as a meshcat animation that the browser plays and that
        can be scrubbed; the call returns at once.
    speed : float
        Playback speed factor for ``realtime`` (2.0 plays twice as fast).
    label : str, optional
        Scene name of the main copy; default: the robot's name.
    obstacles : Scene, optional
        Obstacles drawn with the copies (semi-transparent, a colour per kind):
        world-fixed ones placed once, those carried by a robot frame moving
        with it.

    Returns
    -------
    meshcat.Visualizer
        The client used; ``url()`` is the address to open in a browser.

    Raises
    ------
    ParameterError
        If an array has the wrong shape or ``speed`` is not positive.
    ModelError
        If a mesh breaks the mesh policy or a geometry cannot be drawn.
    ViewerError
        If the server does not answer.
    """
    if not (np.isfinite(speed) and speed > 0):
        raise ParameterError(
            f"speed must be a positive factor, got {speed!r}", name="speed", value=speed
        )
    scene.check_robot(robot)
    runs = scene.layout_runs(
        robot, t, q, ghosts=ghosts, extra=extra, spacing=spacing, root=frame_path, label=label
    )
    runs = scene.attach_obstacles(robot, runs, obstacles)
    checked_targets = scene.check_targets(targets)
    vis, owned = _viewer(viewer)
    try:
        _play(vis, robot, runs, frame_path, ee_path, checked_targets, realtime, speed, owned)
    except BaseException:
        if owned:  # nobody else can reach the server we started
            vis.close()
        raise
    return vis


def _play(
    vis: meshcat.Visualizer,
    robot: RobotLike,
    runs: Sequence[scene.Run],
    frame_path: str,
    ee_path: bool,
    targets: Array | None,
    realtime: bool,
    speed: float,
    set_camera: bool,
) -> None:
    """Draw the scene in a live viewer, then stream the poses or send the animation."""
    times = np.unique(np.concatenate([run.t for run in runs]))
    vis[frame_path].delete()
    nodes = scene.build_scene(vis, robot, runs, ee_path=ee_path, targets=targets, ee_times=times)
    if set_camera:
        scene.set_camera(vis, scene.scene_points(robot, runs, times), centred=False)
    scene.show_at(vis, robot, runs, nodes, float(times[0]))
    if not realtime:
        fps = 30.0  # [1/s] key frames of the browser-side animation
        animation = scene.animation(vis, robot, runs, nodes, scene.frame_times(runs, fps), fps)
        vis.set_animation(animation, play=True)
        return
    start = time.perf_counter()
    for time_s in times[1:]:
        delay = start + (time_s - times[0]) / speed - time.perf_counter()
        if delay > 0:
            time.sleep(delay)
        scene.show_at(vis, robot, runs, nodes, float(time_s))


def scene_html(
    robot: RobotLike,
    t: Array,
    q: Array,
    *,
    fps: float = 30.0,
    ee_path: bool = True,
    targets: Array | None = None,
    ghosts: Sequence[tuple[Array, Array]] = (),
    extra: Sequence[tuple[Array, Array, str]] = (),
    spacing: Array | None = None,
    loop: bool = True,
    frame_path: str = "youbot_opt",
    obstacles: Scene | None = None,
) -> str:
    """Build the standalone HTML page of an animated replay (no server needed).

    Parameters are those of :func:`export_html`, without ``path``.

    Returns
    -------
    str
        The page.
    """
    if not (np.isfinite(fps) and fps > 0):
        raise ParameterError(
            f"fps must be a positive frame rate in [1/s], got {fps!r}", name="fps", value=fps
        )
    scene.check_robot(robot)
    runs = scene.layout_runs(
        robot, t, q, ghosts=ghosts, extra=extra, spacing=spacing, root=frame_path
    )
    runs = scene.attach_obstacles(robot, runs, obstacles)
    checked_targets = scene.check_targets(targets)
    return standalone_page(
        robot, runs, fps=fps, ee_path=ee_path, targets=checked_targets, loop=loop
    )


def standalone_page(
    robot: RobotLike,
    runs: Sequence[scene.Run],
    *,
    fps: float,
    ee_path: bool,
    targets: Array | None,
    loop: bool,
    legend: str = "",
) -> str:
    """Record the scene and animation of ``runs`` and return the standalone page."""
    times = scene.frame_times(runs, fps)
    recorder = _Recorder()
    vis = meshcat.Visualizer(window=recorder)
    nodes = scene.build_scene(vis, robot, runs, ee_path=ee_path, targets=targets, ee_times=times)
    target = scene.set_camera(vis, scene.scene_points(robot, runs, times), centred=True)
    scene.show_at(vis, robot, runs, nodes, float(times[0]))
    animation = scene.animation(vis, robot, runs, nodes, times, fps)
    vis.set_animation(animation, play=True, repetitions=float("inf") if loop else 1)
    main_js = (Path(meshcat.__file__).parent / "viewer" / "dist" / "main.min.js").read_text("utf-8")
    commands = json.dumps([base64.b64encode(c).decode("ascii") for c in recorder.commands])
    title = re.sub(r"[<>&\"']", "_", f"{robot.name} replay")
    target_three = json.dumps([target[0], target[2], -target[1]])  # three.js is y-up
    page = _HTML.replace("@TITLE@", title).replace("@COMMANDS@", commands)
    page = page.replace("@TARGET@", target_three).replace("@LEGEND@", legend)
    return page.replace("@MAIN_MIN_JS@", main_js)  # last: the script is not searched for markers


def export_html(
    robot: RobotLike,
    t: Array,
    q: Array,
    path: str | Path,
    *,
    fps: float = 30.0,
    ee_path: bool = True,
    targets: Array | None = None,
    ghosts: Sequence[tuple[Array, Array]] = (),
    extra: Sequence[tuple[Array, Array, str]] = (),
    spacing: Array | None = None,
    loop: bool = True,
    frame_path: str = "youbot_opt",
    obstacles: Scene | None = None,
) -> Path:
    """Write a standalone HTML file that plays the trajectory offline.

    The file holds meshcat's viewer script, the robot's meshes (as the mesh
    policy allows) and the animation; it needs no server or network. Opened
    as ``file.html#t=1.5`` it shows the pose 1.5 s after the start, paused.

    Parameters
    ----------
    robot : RobotLike
        The robot (``youbot_opt.robot.model.RobotModel`` or the same attributes).
    t : ndarray, shape (N,)
        Strictly increasing knot times in [s].
    q : ndarray, shape (N, nq)
        Configurations at the knots in [rad] (or [m] for prismatic joints).
    path : str or Path
        The HTML file to write; its folder must exist.
    fps : float
        Key frames per [s]. Between knots, configurations are interpolated on
        the configuration space; between key frames, the browser interpolates
        link poses (positions linearly, orientations by slerp).
    ee_path : bool
        Draw the path of ``robot.tip_frame`` as a line.
    targets : ndarray, shape (K, 3), optional
        End-effector targets in [m], drawn as small spheres.
    ghosts : sequence of (t, q)
        Further trajectories drawn translucent over the first one.
    extra : sequence of (t, q, label)
        Further trajectories drawn as copies side by side, named ``label``.
    spacing : ndarray, shape (3,), optional
        Offset in [m] between side-by-side copies; 2.2 reaches along y by default.
    loop : bool
        Play the animation in a loop (True) or once.
    frame_path : str
        Scene path under which everything is drawn.
    obstacles : Scene, optional
        Obstacles drawn with the copies, as in :func:`replay`.

    Returns
    -------
    Path
        The file written.

    Raises
    ------
    ParameterError
        If an array has the wrong shape, ``fps`` is not positive, or the
        folder of ``path`` does not exist.
    ModelError
        If a mesh breaks the mesh policy or a geometry cannot be drawn.
    """
    target = html_target(path)
    page = scene_html(
        robot, t, q, fps=fps, ee_path=ee_path, targets=targets, ghosts=ghosts, extra=extra,
        spacing=spacing, loop=loop, frame_path=frame_path, obstacles=obstacles,
    )  # fmt: skip
    return write_page(target, page)


def html_target(path: str | Path) -> Path:
    """Return ``path`` as the HTML file to write, checked before any work is done.

    Raises
    ------
    ParameterError
        If the folder of ``path`` does not exist.
    """
    target = Path(path)
    if not target.parent.is_dir():
        raise ParameterError(
            f"folder {str(target.parent)!r} of the HTML file does not exist", name="path"
        )
    return target


def write_page(target: Path, page: str) -> Path:
    """Write the HTML ``page`` to ``target`` (UTF-8), log its size and return ``target``."""
    target.write_text(page, encoding="utf-8")
    logger.info("wrote %s (%.1f MB)", target, len(page) / 1e6)
    return target
