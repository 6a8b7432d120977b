"""Stepping many simulators at once: a simulator class's optional ``step_many``.

A plugin's ``gymnasium.Env`` class may define the classmethod

    step_many(envs, actions) -> list of (observation, reward, terminated, truncated, info)

which steps each of ``envs`` (instances of the class, each its own simulator) with its
action and returns, for each, exactly what ``env.step(action)`` returns, leaving each
simulator in exactly the state its own ``step`` leaves it in. It lets a simulator share
work between the simulators of one batched env (the pile loader computes the soil
updates of all of them in one vectorised pass). A class without it is stepped one by one,
as before (docs/simulator_plugins.md, "Stepping many simulators at once").

``step_together`` is how pilerl steps a batch: ``SimulatorBatchEnv`` calls it with the
simulators a step moves, and an env that holds simulators of its own (fine-tuning's
``ConditionMixtureEnv``) may pass it on from its own ``step_many``. It looks through
``gymnasium.make``'s two wrappers once they pass a step straight through
(``OrderEnforcing`` after a reset, ``PassiveEnvChecker`` after its checks of the first
two steps); any other wrapper (``TimeLimit``, a user's) is stepped through its own
``step``, so a wrapper is never skipped while it does anything.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import gymnasium as gym
from gymnasium.wrappers import OrderEnforcing, PassiveEnvChecker

STEP_MANY = "step_many"  # the optional classmethod of a simulator class


def step_together(envs: Sequence[gym.Env], actions: Sequence[Any]) -> list[tuple]:
    """``[env.step(action) for env, action in zip(envs, actions)]``, with the simulators
    whose class defines ``step_many`` stepped through it, two or more of a class at a time
    (one alone takes its own ``step``)."""
    if len(envs) != len(actions):
        raise ValueError(f"step_together: {len(envs)} simulators but {len(actions)} actions")
    if len(envs) == 1:
        return [envs[0].step(actions[0])]
    results: list[tuple | None] = [None] * len(envs)
    groups: dict[type, list[tuple[int, gym.Env]]] = {}
    for i, env in enumerate(envs):
        core = batch_steppable(env)
        if core is None:
            results[i] = env.step(actions[i])
        else:
            groups.setdefault(type(core), []).append((i, core))
    for cls, members in groups.items():
        if len(members) == 1:
            i, _ = members[0]
            results[i] = envs[i].step(actions[i])
            continue
        cores, moves = [core for _, core in members], [actions[i] for i, _ in members]
        stepped = getattr(cls, STEP_MANY)(cores, moves)
        if len(stepped) != len(members):
            raise RuntimeError(
                f"{cls.__name__}.step_many returned {len(stepped)} results for "
                f"{len(members)} simulators"
            )
        for (i, _), result in zip(members, stepped, strict=True):
            results[i] = result
    return results  # type: ignore[return-value]


def batch_steppable(env: gym.Env) -> gym.Env | None:
    """The simulator under ``env``'s pass-through wrappers if its class has ``step_many``
    and every wrapper on the way passes a step straight through now; else ``None``."""
    while isinstance(env, gym.Wrapper):
        if not _passes_steps_through(env):
            return None
        env = env.env
    return env if callable(getattr(type(env), STEP_MANY, None)) else None


def _passes_steps_through(wrapper: gym.Wrapper) -> bool:
    """Whether ``wrapper``'s ``step`` now only calls its env's (``gymnasium.make``'s two)."""
    if type(wrapper) is OrderEnforcing:
        return wrapper.has_reset
    if type(wrapper) is PassiveEnvChecker:
        return wrapper.checked_step and wrapper.checked_data_reuse
    return False
