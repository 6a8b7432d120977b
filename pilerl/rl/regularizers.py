"""Terms that keep a fine-tuned actor near the demonstrations.

- ``DemoBCRegularizer``: mean squared error between the actor's deterministic action and
  the demonstrated action, on batches drawn from the demonstrations (TorchRL replay
  buffer).
- ``FrozenActorRegularizer``: mean squared error between the actor's deterministic action
  and the frozen cloned actor's action, on the states the fine-tuning visits.

Both return a scalar in squared action units (actions lie in [-1, 1]), differentiable with
respect to the actor's parameters.
"""

from __future__ import annotations

import copy

import torch
from tensordict import TensorDictBase

from pilerl.data import make_replay_buffer
from pilerl.policies import ACTION_KEY, SensorPolicy

from .config import REGULARIZERS


def _action(policy: SensorPolicy, data: TensorDictBase) -> torch.Tensor:
    return policy(*[data[k] for k in policy.in_keys])[0]


class DemoBCRegularizer:
    """MSE to demonstrated actions on demo batches of ``batch_size`` transitions."""

    name = "bc_demo"

    def __init__(self, policy: SensorPolicy, demos: TensorDictBase, *, batch_size: int) -> None:
        present = set(demos.keys())
        missing = [k for k in (*policy.in_keys, ACTION_KEY) if k not in present]
        if missing:
            raise KeyError(f"demos: no {missing} for the actor's inputs and the action")
        self.policy = policy
        self.buffer = make_replay_buffer(
            demos.select(*policy.in_keys, ACTION_KEY), batch_size=batch_size
        )

    def __call__(self, batch: TensorDictBase) -> torch.Tensor:
        demo = self.buffer.sample()
        return torch.nn.functional.mse_loss(_action(self.policy, demo), demo[ACTION_KEY])


class FrozenActorRegularizer:
    """MSE to a frozen copy of the cloned actor, on the visited states of ``batch``."""

    name = "frozen_actor"

    def __init__(self, policy: SensorPolicy) -> None:
        self.policy = policy
        self.frozen = copy.deepcopy(policy).eval().requires_grad_(False)

    def __call__(self, batch: TensorDictBase) -> torch.Tensor:
        with torch.no_grad():
            target = _action(self.frozen, batch)
        return torch.nn.functional.mse_loss(_action(self.policy, batch), target)


def make_regularizer(
    name: str, policy: SensorPolicy, *, demos: TensorDictBase | None, batch_size: int
) -> DemoBCRegularizer | FrozenActorRegularizer | None:
    """``bc_demo``, ``frozen_actor`` or ``none`` (``None``)."""
    if name == "bc_demo":
        if demos is None:
            raise ValueError("regularizer 'bc_demo' needs demonstrations")
        return DemoBCRegularizer(policy, demos, batch_size=batch_size)
    if name == "frozen_actor":
        return FrozenActorRegularizer(policy)
    if name == "none":
        return None
    raise ValueError(f"unknown regularizer {name!r}; known: {list(REGULARIZERS)}")
