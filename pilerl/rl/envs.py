"""Training environments: a mixture of conditions, rewarded from named reward parts.

``ConditionMixtureEnv`` is a Gymnasium env that holds one simulator per condition and,
at every reset, draws the condition of the coming episode from the mixture's weights. Its
reward is the weighted sum of the named reward parts the simulator reports in ``info``
(``reward_fill``, ``reward_success``...). ``make_training_env`` wraps it for TorchRL
(``GymWrapper``) and copies ``success`` and the reward parts from ``info`` into every
step's tensordict, so a collected batch tells how training episodes went.

The condition is drawn from the env's own generator. It is seeded when the env is built
(``seed``), so the very first reset, which TorchRL collectors make before they can be
seeded, is already reproducible: the same seed replays the same conditions and starts.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import gymnasium as gym
import numpy as np
import torch
from gymnasium.utils import seeding
from torchrl.data import Unbounded
from torchrl.envs import GymWrapper, default_info_dict_reader

from pilerl.sim import get_simulator, make_gym_env
from pilerl.sim.torchrl_env import SimulatorBatchEnv

SUCCESS_KEY = "success"
SCOOP_SUCCESS_KEY = "scoop_success"  # ``success`` as a plain float (a batched env's column)
TIPPED_KEY = "tipped"  # the simulator's ``info`` flag of a tipped machine (NaN if none)
# ``info`` columns of a batched training env (``SimulatorBatchEnv``): scoops are counted from them
BATCH_INFO_KEYS = (SCOOP_SUCCESS_KEY, TIPPED_KEY)
CONDITION_INDEX_KEY = "condition_index"
SEED_RANGE = 2**31 - 1


class ConditionMixtureEnv(gym.Env):
    """One simulator per condition; each episode runs in a condition drawn by weight.

    Args:
        simulator: plugin name.
        env_kwargs: simulator arguments except ``condition``.
        conditions: condition (or condition group: each member gets its weight) ->
            relative weight (>= 0, not all zero).
        reward_weights: reward part name (an ``info`` key) -> multiplier; the reward is
            ``sum(weight * info[part])``.
        seed: seeds the generator of conditions and starts (``None``: OS entropy, until a
            ``reset(seed=...)``).
    """

    metadata = {"render_modes": ["rgb_array"]}

    def __init__(
        self,
        simulator: str,
        env_kwargs: Mapping[str, object],
        conditions: Mapping[str, float],
        reward_weights: Mapping[str, float],
        *,
        seed: int | None = None,
    ) -> None:
        super().__init__()
        if seed is not None:
            self._np_random, self._np_random_seed = seeding.np_random(seed)
        if not conditions:
            raise ValueError("ConditionMixtureEnv: conditions is empty")
        self.plugin = get_simulator(simulator)
        conditions = self.plugin.resolve_mixture(conditions, where="ConditionMixtureEnv")
        weights = np.array([float(w) for w in conditions.values()])
        if not (np.isfinite(weights).all() and (weights >= 0).all() and weights.sum() > 0):
            raise ValueError(
                f"ConditionMixtureEnv: condition weights must be finite, >= 0 and not all 0, "
                f"got {dict(conditions)}"
            )
        if not reward_weights:
            raise ValueError("ConditionMixtureEnv: reward_weights names no reward part")
        self.condition_names = list(conditions)
        self.probabilities = weights / weights.sum()
        self.reward_weights = {str(k): float(v) for k, v in reward_weights.items()}
        self._envs = {
            name: make_gym_env(simulator, **dict(env_kwargs), condition=name)
            for name, w in conditions.items()
            if w > 0
        }
        first = next(iter(self._envs.values()))
        self.observation_space = first.observation_space
        self.action_space = first.action_space
        self.dt = float(first.unwrapped.dt)
        self.condition = self.condition_names[int(np.argmax(self.probabilities))]
        self._checked_parts = False

    @property
    def active(self) -> gym.Env:
        """The simulator of the current episode's condition."""
        return self._envs[self.condition]

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        index = int(self.np_random.choice(len(self.condition_names), p=self.probabilities))
        self.condition = self.condition_names[index]
        obs, info = self.active.reset(seed=int(self.np_random.integers(SEED_RANGE)))
        return obs, self._reported(info)

    def step(self, action):
        obs, _, terminated, truncated, info = self.active.step(action)
        reward = self.training_reward(info)
        return obs, reward, terminated, truncated, self._reported(info)

    def training_reward(self, info: Mapping[str, float]) -> float:
        """``sum(weight * info[part])`` over the configured reward parts."""
        if not self._checked_parts:
            missing = sorted(set(self.reward_weights) - set(info))
            if missing:
                raise KeyError(
                    f"reward_weights: the simulator reports no reward part(s) {missing}; "
                    f"it declares {list(self.plugin.reward_parts)}"
                )
            self._checked_parts = True
        return float(sum(w * float(info[part]) for part, w in self.reward_weights.items()))

    def render(self):
        return self.active.render()

    def close(self):
        for env in self._envs.values():
            env.close()

    def _reported(self, info: dict) -> dict:
        """``info`` plus the condition index and ``success`` (from the simulator's declared
        success key); the keys TorchRL copies as float32 [1]."""
        success = info.get(self.plugin.success_key, False)
        info = {
            **info,
            SUCCESS_KEY: success,
            SCOOP_SUCCESS_KEY: float(success),
            CONDITION_INDEX_KEY: self.condition_names.index(self.condition),
        }
        for key in info_keys(self.reward_weights):
            info[key] = np.array([float(info.get(key, 0.0))], dtype=np.float32)
        return info


def info_keys(reward_weights: Mapping[str, float]) -> list[str]:
    """Entries copied into every step: success, condition index, reward parts."""
    return [SUCCESS_KEY, CONDITION_INDEX_KEY, *reward_weights]


def make_training_env(
    simulator: str,
    env_kwargs: Mapping[str, object],
    conditions: Mapping[str, float],
    reward_weights: Mapping[str, float],
    *,
    num_envs: int = 1,
    seed: int | None = None,
    variants: Sequence[Mapping[str, object]] = (),
):
    """A TorchRL env around ``num_envs`` ``ConditionMixtureEnv`` simulators.

    Simulator ``i`` is seeded with ``seed + i`` when it is built (``None``: unseeded) and,
    if ``variants`` are given, built with ``env_kwargs`` updated by ``variants[i % n]``
    (e.g. half the simulators on another soil model; ``num_envs`` must be a multiple of
    their number, so every variant gets as many simulators).

    - ``num_envs=1``: ``GymWrapper``, batch size ``[]``. Each step's tensordict carries the
      sensors by name, ``reward`` (the weighted parts) and, from ``info``, ``success``,
      ``condition_index`` and every named reward part (float32, shape [1]).
    - ``num_envs=N``: ``pilerl.sim.torchrl_env.SimulatorBatchEnv``, batch size ``[N]``: N
      simulators stepped in a loop, TorchRL's per-step cost and the actor's forward pass
      paid once for all N (much faster on CPU); sensors, reward, end flags and ``info``
      [N, 2]: success and ``tipped`` (``BATCH_INFO_KEYS``), to count scoops.
    """
    if variants and num_envs % len(variants):
        raise ValueError(
            f"make_training_env: num_envs ({num_envs}) must be a multiple of the number of "
            f"variants ({len(variants)})"
        )
    seeds = iter(range(seed, seed + num_envs)) if seed is not None else None
    built = iter(range(num_envs))

    def make_mixture() -> ConditionMixtureEnv:
        i = next(built)
        kwargs = {**env_kwargs, **variants[i % len(variants)]} if variants else env_kwargs
        return ConditionMixtureEnv(
            simulator,
            kwargs,
            conditions,
            reward_weights,
            seed=None if seeds is None else next(seeds),
        )

    if num_envs > 1:
        return SimulatorBatchEnv(make_mixture, num_envs, info_keys=BATCH_INFO_KEYS)
    mixture = make_mixture()
    env = GymWrapper(mixture)
    keys = info_keys(reward_weights)
    reader = default_info_dict_reader(
        keys, spec={k: Unbounded(shape=(1,), dtype=torch.float32) for k in keys}
    )
    env.set_info_dict_reader(reader)
    return env


class TrainingEnvFactory:
    """A picklable ``create_env_fn`` for collectors (also in worker processes).

    ``seed`` seeds the simulators it builds (``make_training_env``); ``seeded(s)`` is the
    same factory with another seed (one per collector worker). ``variants``: simulator
    options that simulator ``i`` of each batch takes in turn (``make_training_env``).
    """

    def __init__(
        self,
        simulator: str,
        env_kwargs: Mapping[str, object],
        conditions: Mapping[str, float],
        reward_weights: Mapping[str, float],
        *,
        num_envs: int = 1,
        seed: int | None = None,
        variants: Sequence[Mapping[str, object]] = (),
    ) -> None:
        self.simulator = simulator
        self.env_kwargs = dict(env_kwargs)
        self.conditions = dict(conditions)
        self.reward_weights = dict(reward_weights)
        self.num_envs = num_envs
        self.seed = seed
        self.variants = [dict(v) for v in variants]

    def seeded(self, seed: int | None) -> TrainingEnvFactory:
        """This factory building simulators seeded from ``seed``."""
        return TrainingEnvFactory(
            self.simulator,
            self.env_kwargs,
            self.conditions,
            self.reward_weights,
            num_envs=self.num_envs,
            seed=seed,
            variants=self.variants,
        )

    def __call__(self):
        return make_training_env(
            self.simulator,
            self.env_kwargs,
            self.conditions,
            self.reward_weights,
            num_envs=self.num_envs,
            seed=self.seed,
            variants=self.variants,
        )
