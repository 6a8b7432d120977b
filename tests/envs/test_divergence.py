"""A diverged simulation stops the episode with a clear error instead of going on."""

from __future__ import annotations

import numpy as np
import pytest
from pilerl_pile_loader.env import PileLoadingEnv


@pytest.mark.parametrize("field", ["qpos", "qvel", "act"])
def test_a_non_finite_state_is_an_error_not_a_silent_reset(field):
    # MuJoCo resets a NaN state to the model's initial pose (and only warns): without the
    # check the episode went on from the start pose as if nothing had happened
    env = PileLoadingEnv()
    env.reset(seed=0)
    getattr(env.data, field)[:] = np.nan
    with pytest.raises(RuntimeError, match="simulation diverged: MuJoCo found a non-finite"):
        env.step(np.zeros(3, dtype=np.float32))
    env.reset(seed=0)  # a new episode starts clean
    env.step(np.zeros(3, dtype=np.float32))


def test_the_soil_names_a_non_finite_bucket_position():
    # a NaN position fails every "near the pile" comparison: without the check the soil
    # took its far-from-the-pile path and wrote NaN soil forces into the model
    env = PileLoadingEnv()
    env.reset(seed=0)
    env.data.xpos[env.machine.bucket_body] = np.nan
    with pytest.raises(RuntimeError, match="heightfield soil got a non-finite bucket position"):
        env.soil.update(0.05)
