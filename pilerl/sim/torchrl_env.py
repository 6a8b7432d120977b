"""Simulators as TorchRL environments.

``make_torchrl_env`` wraps a plugin's Gymnasium env for TorchRL: every sensor of a ``Dict``
observation becomes its own key of the tensordict (``boom_angle``, ``drive_pressure``...),
so actors read sensors by name. Observations stay float32.

- ``num_envs=1``: TorchRL ``GymEnv``, batch size ``[]``.
- ``num_envs=N``: N simulators stepped in this process by Gymnasium's ``SyncVectorEnv``
  (same-step autoreset, as TorchRL requires) under TorchRL's ``GymWrapper``, batch size
  ``[N]``. TorchRL's per-step bookkeeping is then paid once for N simulators, which is
  the cheap way to batch on a 2-core machine (benchmarks/sim_speed.py measures it next to
  ``ParallelEnv``).

``device`` defaults to ``None``: the simulators run on the CPU, and a TorchRL env given an
explicit device casts every step's output with ``.to(device)`` (measured: ~0.4 ms of a
~1.3 ms step).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import gymnasium as gym

from .registry import DEFAULT_SIMULATOR, get_simulator, register_gymnasium_envs

if TYPE_CHECKING:
    from torchrl.envs import EnvBase


def make_torchrl_env(
    name: str = DEFAULT_SIMULATOR,
    *,
    num_envs: int = 1,
    device: str | None = None,
    seed: int | None = None,
    **kwargs,
) -> EnvBase:
    """A TorchRL env around simulator ``name``; ``kwargs`` go to the simulator."""
    from torchrl.envs import GymEnv, GymWrapper  # imported here: torchrl is slow to import

    if num_envs < 1:
        raise ValueError(f"make_torchrl_env: num_envs must be >= 1, got {num_envs}")
    plugin = get_simulator(name)
    register_gymnasium_envs()
    if num_envs == 1:
        env = GymEnv(plugin.gym_id, device=device, **kwargs)
    else:
        vector_env = gym.vector.SyncVectorEnv(
            [lambda: gym.make(plugin.gym_id, **kwargs)] * num_envs,
            autoreset_mode=gym.vector.AutoresetMode.SAME_STEP,
        )
        env = GymWrapper(vector_env, device=device)
    if seed is not None:
        env.set_seed(seed)
    return env
