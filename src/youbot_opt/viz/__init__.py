"""Visualisation: meshcat replay, live and as standalone HTML.

The names are imported on first use, so ``import youbot_opt.viz`` does not
import meshcat, zmq and tornado. :func:`replay` / :func:`export_html` play
joint trajectories; :func:`replay_results` / :func:`export_results_html`
trajectory results; :func:`replay_ikpath` / :func:`export_ikpath_html` IK
paths; :class:`MeshcatServer` and :func:`connect` the loopback server and its
client; :func:`load_mesh_file` the mesh policy.

>>> export_results_html([result], "replay.html")  # doctest: +SKIP
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from youbot_opt.robot.urdf_check.meshes import check_mesh_file, load_mesh_file
    from youbot_opt.viz.meshcat.ikpath import export_ikpath_html, replay_ikpath, replay_track
    from youbot_opt.viz.meshcat.replay import export_html, replay, scene_html
    from youbot_opt.viz.meshcat.results import export_results_html, replay_results
    from youbot_opt.viz.meshcat.server import MeshcatServer, connect

__all__ = [
    "replay",
    "export_html",
    "scene_html",
    "replay_results",
    "export_results_html",
    "MeshcatServer",
    "connect",
    "check_mesh_file",
    "load_mesh_file",
    "replay_ikpath",
    "export_ikpath_html",
    "replay_track",
]

_SOURCES = {
    "replay": "youbot_opt.viz.meshcat.replay",
    "export_html": "youbot_opt.viz.meshcat.replay",
    "scene_html": "youbot_opt.viz.meshcat.replay",
    "replay_results": "youbot_opt.viz.meshcat.results",
    "export_results_html": "youbot_opt.viz.meshcat.results",
    "MeshcatServer": "youbot_opt.viz.meshcat.server",
    "connect": "youbot_opt.viz.meshcat.server",
    "check_mesh_file": "youbot_opt.robot.urdf_check.meshes",
    "load_mesh_file": "youbot_opt.robot.urdf_check.meshes",
    "replay_ikpath": "youbot_opt.viz.meshcat.ikpath",
    "export_ikpath_html": "youbot_opt.viz.meshcat.ikpath",
    "replay_track": "youbot_opt.viz.meshcat.ikpath",
}


def __getattr__(name: str) -> Any:
    """Import a public name of this package on first use (PEP 562)."""
    if name not in _SOURCES:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(importlib.import_module(_SOURCES[name]), name)


def __dir__() -> list[str]:
    return sorted(__all__)
