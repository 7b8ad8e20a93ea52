"""Visualisation: meshcat replay, live and as standalone HTML.

The names of ``__init__.pyi`` are imported on first use (``lazy_loader``), so
``import youbot_opt.viz`` does not import meshcat, zmq and tornado.
:func:`replay` / :func:`export_html` play joint trajectories;
:func:`replay_results` / :func:`export_results_html` trajectory results;
:func:`replay_ikpath` / :func:`export_ikpath_html` IK paths;
:class:`MeshcatServer` and :func:`connect` the loopback server and its client.
The mesh policy (``load_mesh_file``) lives in :mod:`youbot_opt.robot.urdf_check.meshes`.

>>> export_results_html([result], "replay.html")  # doctest: +SKIP
"""

import lazy_loader

__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
