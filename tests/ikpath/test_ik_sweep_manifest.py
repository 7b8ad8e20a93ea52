"""The one manifest rule of the planar and spatial IK sweep stores (ikpath.sweep.options_json)."""

from __future__ import annotations

from dataclasses import replace

import pytest

from youbot_opt.exceptions import ParameterError
from youbot_opt.ikpath.methods.al import AL_OPTIONS_3D, ALOptions
from youbot_opt.ikpath.problem import CyclicIKProblem
from youbot_opt.ikpath.sweep import SWEEP_KIND_3D, options_json, result_codec, store_params
from youbot_opt.ikpath.targets import Target
from youbot_opt.robot.load import load_model
from youbot_opt.sweeps.store import SweepStore, open_store


@pytest.fixture(scope="module")
def ur5_problem() -> CyclicIKProblem:
    """UR5 through two positions (the store only describes the problem; nothing is solved)."""
    robot = load_model("ur5")
    return CyclicIKProblem(
        robot=robot.model,
        frame=robot.tip_frame,
        targets=(
            Target(position=(0.4, 0.1, 0.3)),
            Target(position=(0.3, -0.2, 0.4)),
        ),
    )


def test_options_json_omits_exactly_the_final_phase_fields_that_hold_the_default():
    """Planar defaults stay compact (old manifests); the spatial defaults write their changes."""
    planar = options_json("al", None)
    assert planar == options_json("al", ALOptions())
    for name in ("initial_multipliers", "retry_least_squares", "newton_final", "newton_violation"):
        assert name not in planar
    spatial = options_json("al", AL_OPTIONS_3D)
    assert spatial["newton_final"] is True and spatial["retry_least_squares"] is True
    assert "initial_multipliers" not in spatial and "newton_violation" not in spatial
    assert spatial["penalty_initial"] == 1e3


def test_spatial_store_resumes_with_the_defaults_and_refuses_other_settings(ur5_problem, tmp_path):
    """None and the explicit spatial defaults bind the same store; a changed setting is refused.

    ``newton_final=False`` is the ALOptions default, so the compact rule leaves
    it out of the manifest: the store must still tell it from the spatial
    default (True), which it writes out.
    """
    kw = {"method": "al", "n_starts": 4, "seed": 0, "kind": "mixed"}
    first = _open_3d(tmp_path, ur5_problem, options=None, **kw)
    assert not first.resumed
    again = _open_3d(tmp_path, ur5_problem, options=AL_OPTIONS_3D, **kw)
    assert again.resumed
    changed = replace(AL_OPTIONS_3D, newton_final=False)
    with pytest.raises(ParameterError, match="newton_final"):
        _open_3d(tmp_path, ur5_problem, options=changed, **kw)


def _open_3d(out, problem, *, options, **kw) -> SweepStore:  # type: ignore[no-untyped-def]
    """Open the store of a multistart of ``problem`` by the general methods."""
    params = store_params(problem, planar=False, options=options, **kw)
    return open_store(out, SWEEP_KIND_3D, params, result_codec(problem, planar=False))
