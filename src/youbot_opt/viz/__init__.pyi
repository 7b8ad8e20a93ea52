"""Public names of :mod:`youbot_opt.viz`, listed once (read by ``lazy_loader``)."""

from .meshcat.ikpath import (
    export_ikpath_html as export_ikpath_html,
    replay_ikpath as replay_ikpath,
    replay_track as replay_track,
)
from .meshcat.replay import export_html as export_html, replay as replay, scene_html as scene_html
from .meshcat.results import (
    export_results_html as export_results_html,
    replay_results as replay_results,
)
from .meshcat.server import MeshcatServer as MeshcatServer, connect as connect
