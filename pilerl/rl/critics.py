"""Value and Q networks over named, normalised sensor readings.

Both reuse the cloned actor's normalisation statistics (``ActorConfig.stats``), so the
critic sees the same z-scored inputs as the actor; the statistics are buffers (not
trained). Every reading the actor reads is an input, also the attention-only ones.
"""

from __future__ import annotations

from collections.abc import Sequence

import torch
from torch import nn
from torchrl.modules import MLP, ValueOperator

from pilerl.policies import ACTION_KEY, InputNormalizer, SensorPolicy

STATE_VALUE_KEY = "state_value"
STATE_ACTION_VALUE_KEY = "state_action_value"


class SensorCritic(nn.Module):
    """``MLP([normalised readings, action?]) -> one value``.

    Args:
        sensors: sensor keys, in the order of ``forward``'s readings.
        stats: dataset statistics (``stats["sensors"][name]["mean" / "std"]``).
        hidden: hidden layer widths.
        n_actions: action size appended after the readings (0 for a state value).
        layer_norm: LayerNorm after each hidden layer (RLPD's critics: bounded Q values
            off the data's support).
    """

    def __init__(
        self,
        sensors: Sequence[str],
        stats: dict,
        hidden: Sequence[int],
        *,
        n_actions: int = 0,
        layer_norm: bool = False,
    ) -> None:
        super().__init__()
        if not hidden or any(int(h) < 1 for h in hidden):
            raise ValueError(f"SensorCritic: hidden widths must be >= 1, got {list(hidden)}")
        self.sensors = list(sensors)
        self.n_actions = n_actions
        self.normalizer = InputNormalizer.from_stats(self.sensors, stats)
        widths = [{"normalized_shape": int(h)} for h in hidden]
        norm = {"norm_class": nn.LayerNorm, "norm_kwargs": widths} if layer_norm else {}
        self.mlp = MLP(
            in_features=len(self.sensors) + n_actions,
            out_features=1,
            num_cells=[int(h) for h in hidden],
            activation_class=nn.Tanh,
            **norm,
        )

    def forward(self, *inputs: torch.Tensor) -> torch.Tensor:
        readings = torch.cat(inputs[: len(self.sensors)], dim=-1)
        x = self.normalizer(readings)
        if self.n_actions:
            x = torch.cat([x, inputs[len(self.sensors)]], dim=-1)
        return self.mlp(x)


def make_value_network(policy: SensorPolicy, hidden: Sequence[int]) -> ValueOperator:
    """State-value network ``V(sensors)`` writing ``state_value`` (for PPO / GAE)."""
    keys = policy.in_keys
    return ValueOperator(
        SensorCritic(keys, policy.config.stats, hidden),
        in_keys=keys,
        out_keys=[STATE_VALUE_KEY],
    )


def make_q_network(
    policy: SensorPolicy, hidden: Sequence[int], *, layer_norm: bool = False
) -> ValueOperator:
    """Action-value network ``Q(sensors, action)`` writing ``state_action_value``."""
    keys = policy.in_keys
    critic = SensorCritic(
        keys, policy.config.stats, hidden, n_actions=policy.config.n_controls, layer_norm=layer_norm
    )
    return ValueOperator(
        critic,
        in_keys=[*keys, ACTION_KEY],
        out_keys=[STATE_ACTION_VALUE_KEY],
    )
