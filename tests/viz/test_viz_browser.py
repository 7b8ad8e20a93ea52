"""Render exported replay pages in headless Chromium and check the pixels.

One screenshot holds six panels (iframes of the exported pages, each seeked
with ``#t=``): the youBot at the start and at the end of a motion, the youBot
scene without its visuals (the reference background: same camera, grid, axes
and path), the UR5 (COLLADA meshes) and its scene without visuals, and a
COLLADA quad whose only colour is an embedded green texture.

Without Chromium the test is skipped locally, and fails when ``CI`` is set
(``scripts/install_browser.sh`` installs Debian's ``chromium``).
"""

from __future__ import annotations

import io
import os
import shutil
import subprocess
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

pytest.importorskip("meshcat")
import coal  # noqa: E402
import matplotlib.image  # noqa: E402
import pinocchio as pin  # noqa: E402
from PIL import Image  # noqa: E402

from youbot_opt.robot.load import load_model  # noqa: E402
from youbot_opt.viz import export_html  # noqa: E402

pytestmark = pytest.mark.browser

PANEL = 320  # [px] side of each square panel
PANELS = ("youbot_start", "youbot_end", "youbot_empty", "ur5", "ur5_empty", "texture")
DURATION = 2.0  # [s] of the youBot motion


def _chromium() -> str:
    for name in ("chromium", "chromium-browser", "google-chrome"):
        path = shutil.which(name)
        if path:
            return path
    message = "headless Chromium not found; run scripts/install_browser.sh"
    if os.environ.get("CI"):
        pytest.fail(message + " (CI is set, so this is a failure, not a skip)")
    pytest.skip(message)


_QUAD_DAE = """<?xml version="1.0" encoding="utf-8"?>
<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">
  <asset><unit name="meter" meter="1"/><up_axis>Z_UP</up_axis></asset>
  <library_images><image id="tex-image"><init_from>textures/green.png</init_from></image>
  </library_images>
  <library_effects><effect id="tex-effect"><profile_COMMON>
    <newparam sid="tex-surface"><surface type="2D"><init_from>tex-image</init_from></surface>
    </newparam>
    <newparam sid="tex-sampler"><sampler2D><source>tex-surface</source></sampler2D></newparam>
    <technique sid="common"><lambert><diffuse><texture texture="tex-sampler" texcoord="UV"/>
    </diffuse></lambert></technique>
  </profile_COMMON></effect></library_effects>
  <library_materials><material id="tex-material"><instance_effect url="#tex-effect"/></material>
  </library_materials>
  <library_geometries><geometry id="quad"><mesh>
    <source id="quad-pos"><float_array id="quad-pos-a" count="12">
      -0.5 -0.5 0  0.5 -0.5 0  0.5 0.5 0  -0.5 0.5 0</float_array>
      <technique_common><accessor source="#quad-pos-a" count="4" stride="3">
        <param name="X" type="float"/><param name="Y" type="float"/><param name="Z" type="float"/>
      </accessor></technique_common></source>
    <source id="quad-uv"><float_array id="quad-uv-a" count="8">0 0 1 0 1 1 0 1</float_array>
      <technique_common><accessor source="#quad-uv-a" count="4" stride="2">
        <param name="S" type="float"/><param name="T" type="float"/>
      </accessor></technique_common></source>
    <vertices id="quad-vtx"><input semantic="POSITION" source="#quad-pos"/></vertices>
    <triangles material="tex-material" count="2">
      <input semantic="VERTEX" source="#quad-vtx" offset="0"/>
      <input semantic="TEXCOORD" source="#quad-uv" offset="1" set="0"/>
      <p>0 0 1 1 2 2 0 0 2 2 3 3</p>
    </triangles>
  </mesh></geometry></library_geometries>
  <library_visual_scenes><visual_scene id="scene"><node id="quad-node">
    <instance_geometry url="#quad"><bind_material><technique_common>
      <instance_material symbol="tex-material" target="#tex-material">
        <bind_vertex_input semantic="UV" input_semantic="TEXCOORD" input_set="0"/>
      </instance_material>
    </technique_common></bind_material></instance_geometry>
  </node></visual_scene></library_visual_scenes>
  <scene><instance_visual_scene url="#scene"/></scene>
</COLLADA>
"""


def _with_visuals(robot, visual_model: pin.GeometryModel, package_dirs=None) -> SimpleNamespace:
    return SimpleNamespace(
        name=robot.name,
        model=robot.model,
        visual_model=visual_model,
        package_dirs=robot.package_dirs if package_dirs is None else package_dirs,
        tip_frame=robot.tip_frame,
    )


def _textured_robot(robot, folder: Path) -> SimpleNamespace:
    """The UR5's kinematics with one visual: a 1 m quad on the floor, textured green."""
    (folder / "textures").mkdir(parents=True)
    buffer = io.BytesIO()
    Image.new("RGB", (8, 8), (0, 255, 0)).save(buffer, format="PNG")
    (folder / "textures" / "green.png").write_bytes(buffer.getvalue())
    (folder / "quad.dae").write_text(_QUAD_DAE, encoding="utf-8")
    visual = pin.GeometryModel()
    placement = pin.SE3(np.eye(3), np.array([0.0, 0.0, 0.01]))
    quad = pin.GeometryObject(
        "quad", 0, placement, coal.Box(1.0, 1.0, 0.01), str(folder / "quad.dae")
    )
    visual.addGeometryObject(quad)
    return _with_visuals(robot, visual, package_dirs=(folder,))


def _pixels_off(a: np.ndarray, b: np.ndarray, threshold: float = 0.15) -> np.ndarray:
    """Pixels whose colour differs by more than ``threshold`` (RGB in [0, 1]), eroded by 2 px.

    The erosion removes one- and two-pixel lines (anti-aliasing seams, the thin
    path line), so only filled areas count.
    """
    mask = np.abs(a - b).sum(axis=-1) > threshold
    eroded = mask.copy()
    for dy in range(-2, 3):
        for dx in range(-2, 3):
            eroded[2:-2, 2:-2] &= mask[
                2 + dy : mask.shape[0] - 2 + dy, 2 + dx : mask.shape[1] - 2 + dx
            ]
    eroded[:2], eroded[-2:], eroded[:, :2], eroded[:, -2:] = False, False, False, False
    return eroded


def test_exported_pages_render_the_robot_and_seek_in_time(tmp_path, youbot):
    """Chromium draws the robots and the texture, and two seek times give two pictures."""
    chromium = _chromium()
    ur5 = load_model("ur5")
    t = np.linspace(0.0, DURATION, 21)
    q_end = np.array([0.8, -1.0, 1.2])  # [rad], inside the joint limits
    q = np.outer(0.5 - 0.5 * np.cos(np.pi * t / DURATION), q_end)
    t_ur5 = np.array([0.0, 1.0])
    q_ur5 = np.array([pin.neutral(ur5.model), pin.neutral(ur5.model) + [0.5, -0.8, 0.9, 0, 0, 0]])
    empty = pin.GeometryModel()
    pages = {
        "youbot": export_html(youbot, t, q, tmp_path / "youbot.html"),
        "youbot_empty": export_html(_with_visuals(youbot, empty), t, q, tmp_path / "yb0.html"),
        "ur5": export_html(ur5, t_ur5, q_ur5, tmp_path / "ur5.html"),
        "ur5_empty": export_html(_with_visuals(ur5, empty), t_ur5, q_ur5, tmp_path / "ur0.html"),
        "texture": export_html(
            _textured_robot(ur5, tmp_path / "pkg"), t_ur5, q_ur5, tmp_path / "tex.html"
        ),
    }
    sources = {
        "youbot_start": f"{pages['youbot'].name}#t=0",
        "youbot_end": f"{pages['youbot'].name}#t={DURATION}",
        "youbot_empty": f"{pages['youbot_empty'].name}#t=0",
        "ur5": f"{pages['ur5'].name}#t=1",
        "ur5_empty": f"{pages['ur5_empty'].name}#t=1",
        "texture": f"{pages['texture'].name}#t=0",
    }
    frames = "".join(
        f'<iframe src="{sources[name]}" width="{PANEL}" height="{PANEL}" '
        'style="border:0;margin:0;padding:0;display:block;float:left"></iframe>'
        for name in PANELS
    )
    board = tmp_path / "board.html"
    board.write_text(f'<!DOCTYPE html><html><body style="margin:0">{frames}</body></html>')
    screenshot = tmp_path / "board.png"
    command = [
        chromium, "--headless", "--no-sandbox", "--disable-gpu", "--use-angle=swiftshader",
        "--enable-unsafe-swiftshader", "--disable-quic", "--no-first-run",
        "--disable-background-networking", "--disable-component-update", "--disable-sync",
        "--hide-scrollbars", f"--user-data-dir={tmp_path / 'profile'}",
        f"--screenshot={screenshot}", f"--window-size={PANEL * len(PANELS)},{PANEL}",
        "--virtual-time-budget=3000", board.as_uri(),
    ]  # fmt: skip
    subprocess.run(command, check=True, timeout=180, capture_output=True)
    image = matplotlib.image.imread(screenshot)[..., :3]
    panels = {name: image[:, k * PANEL : (k + 1) * PANEL] for k, name in enumerate(PANELS)}
    middle = (slice(PANEL // 5, 4 * PANEL // 5), slice(PANEL // 5, 4 * PANEL // 5))

    def drawn(name: str, reference: str) -> float:
        """Fraction of the middle region where ``name`` differs from its reference."""
        return float(_pixels_off(panels[name], panels[reference])[middle].mean())

    # A panel identical to its reference gives exactly 0 (measured: 0.0 for two renders of one
    # page, 0.2 % between two different robot-less scenes). Measured with robots: youBot 32 %,
    # UR5 10 % of the middle region; 1 % separates "drawn" from "not drawn" with margin.
    assert drawn("youbot_start", "youbot_empty") > 0.01
    assert drawn("youbot_end", "youbot_empty") > 0.01
    assert drawn("ur5", "ur5_empty") > 0.01
    # The tip moves by 0.31 m and every link turns: the two times differ on a robot-sized area
    # (measured 12 %).
    assert drawn("youbot_end", "youbot_start") > 0.01
    # The quad's only colour is the embedded texture: green (0, 1, 0) lit by meshcat's lights.
    # Measured: 29 % of the middle region; 0.2 % (the y axis line) in the texture-less UR5 panel.
    green = panels["texture"][..., 1] - panels["texture"][..., [0, 2]].max(axis=-1)
    assert (green[middle] > 0.3).mean() > 0.01


def test_page_without_webgl_shows_a_visible_message(tmp_path, youbot):
    """With WebGL turned off, the page shows its message (DOM and pixels), not a blank page."""
    chromium = _chromium()
    t = np.linspace(0.0, DURATION, 5)
    q = np.outer(t / DURATION, [0.8, -1.0, 1.2])  # [rad]
    page = export_html(youbot, t, q, tmp_path / "youbot.html")
    common = [
        chromium, "--headless", "--no-sandbox", "--disable-gpu", "--disable-3d-apis",
        "--disable-webgl", "--disable-quic", "--no-first-run", "--disable-background-networking",
        "--disable-component-update", "--disable-sync", "--hide-scrollbars",
        f"--user-data-dir={tmp_path / 'profile'}", f"--window-size={PANEL},{PANEL}",
        "--virtual-time-budget=2000",
    ]  # fmt: skip
    dom = subprocess.run(
        [*common, "--dump-dom", page.as_uri()], check=True, timeout=180, capture_output=True
    ).stdout.decode("utf-8", "replace")
    assert 'id="no-webgl" style="display: block;' in dom
    assert "This replay needs WebGL" in dom
    screenshot = tmp_path / "no_webgl.png"
    subprocess.run(
        [*common, f"--screenshot={screenshot}", page.as_uri()],
        check=True,
        timeout=180,
        capture_output=True,
    )
    image = matplotlib.image.imread(screenshot)[..., :3]
    # The message box is orange-yellow (#fd8 = (1, 0.87, 0.53)) on the white page: a blank page
    # has no such pixel. Measured: 35 % of the 320 px square (also with --use-gl=swiftshader),
    # 0 % when WebGL works; 1 % separates the two with margin.
    box = (image[..., 0] > 0.9) & (np.abs(image[..., 1] - 0.87) < 0.08) & (image[..., 2] < 0.65)
    assert box.mean() > 0.01
