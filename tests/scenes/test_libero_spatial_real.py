"""LIBERO-Spatial on LIBERO's complete asset tree (skipped where ``indgen setup libero`` did not install it): the
real black bowl is open-topped and 10.6 cm wide, so the oracle pinches its wall (``grasp_clearance.rim_offset``)."""

from __future__ import annotations

import pytest

from scenes.family import get_scene
from tests.fixtures.levels import level_env

pytest.importorskip("libero")

pytestmark = pytest.mark.filterwarnings("ignore::UserWarning")
SCENE, TASK = "libero_spatial", "on_the_ramekin"


def test_the_oracle_lifts_the_real_bowl_by_its_wall(real):
    """Grasped over its centre, the open fingers closed on air inside the bowl (no_grasp on 9 of the 10 tasks at
    level 0); at a wall's middle the oracle places it on the plate."""
    from indgen_vla.app.certify.certify_levels import run_oracle_episode
    from indgen_vla.core.protocol.seeding import episode_seed
    from scenes.oracles import oracle_for

    env = level_env(SCENE, task=TASK, axis="scale", level=0, cameras=())
    try:
        seed = episode_seed(0, SCENE, TASK, "scale", 0, 0)
        env.reset(seed=seed, options={"episode": 0})
        s = env.privileged_state()
        assert abs(s.target.grasp_xy[1] - s.pick.pos[1]) > 0.03  # at a wall, not over the hollow centre
        assert s.target.grasp_z > s.pick.top - 0.03  # near the rim
        ok, steps = run_oracle_episode(env, oracle_for(get_scene(SCENE)), seed, 0)
        assert ok, steps
    finally:
        env.close()
