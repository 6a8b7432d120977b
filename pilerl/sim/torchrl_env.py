"""Simulators as TorchRL environments.

``make_torchrl_env`` wraps a plugin's Gymnasium env with TorchRL's ``GymEnv``: every
sensor of a ``Dict`` observation becomes its own key of the tensordict (``boom_angle``,
``drive_pressure``...), so actors read sensors by name. Observations stay float32.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .registry import DEFAULT_SIMULATOR, get_simulator, register_gymnasium_envs

if TYPE_CHECKING:
    from torchrl.envs import GymEnv


def make_torchrl_env(
    name: str = DEFAULT_SIMULATOR, *, device: str = "cpu", seed: int | None = None, **kwargs
) -> GymEnv:
    """A TorchRL ``GymEnv`` around simulator ``name``; ``kwargs`` go to the simulator."""
    from torchrl.envs import GymEnv  # imported here: torchrl is slow to import

    plugin = get_simulator(name)
    register_gymnasium_envs()
    env = GymEnv(plugin.gym_id, device=device, **kwargs)
    if seed is not None:
        env.set_seed(seed)
    return env
