"""``SensorPolicy``: named sensor readings -> normalised s, s' -> controller -> outputs.

This is the ``nn.Module`` inside every actor's ``TensorDictModule``; its ``config``
(``ActorConfig``) is what a checkpoint stores to rebuild it.
"""

from __future__ import annotations

import torch
from tensordict import TensorDictBase
from torch import nn

from .config import ActorConfig
from .controllers import Controller
from .normalization import InputNormalizer

ACTION_KEY = "action"
ACTION_LOC_KEY = "action_loc"  # u' with u = tanh(u'): the TanhNormal loc for RL
INPUT_MASK_KEY = "input_mask"
OUTPUT_MASK_KEY = "output_mask"


class SensorPolicy(nn.Module):
    """Concatenate the sensor readings, normalise them, run the controller.

    ``forward(*readings)`` takes one tensor [..., 1] per key of ``in_keys`` (in that
    order) and returns one tensor per key of ``out_keys``: ``action`` always,
    ``action_loc`` for neural controllers, ``input_mask`` / ``output_mask`` for the
    attention controllers that produce them.
    """

    s_index: torch.Tensor
    attention_index: torch.Tensor

    def __init__(self, config: ActorConfig, controller: Controller) -> None:
        super().__init__()
        self.config = config
        self.normalizer = InputNormalizer.from_stats(config.input_keys, config.stats)
        self.controller = controller
        keys = config.input_keys
        attention = config.attention_sensors or config.sensors
        # derived from the config: not part of the state_dict
        self.register_buffer(
            "s_index", torch.tensor([keys.index(k) for k in config.sensors]), persistent=False
        )
        self.register_buffer(
            "attention_index", torch.tensor([keys.index(k) for k in attention]), persistent=False
        )
        self._same_inputs = config.attention_sensors in (None, config.sensors)

    @property
    def in_keys(self) -> list[str]:
        return list(self.config.input_keys)

    @property
    def out_keys(self) -> list[str]:
        keys = [ACTION_KEY]
        if self.controller.has_pre_tanh:
            keys.append(ACTION_LOC_KEY)
        if self.controller.has_input_mask:
            keys.append(INPUT_MASK_KEY)
        if self.controller.has_output_mask:
            keys.append(OUTPUT_MASK_KEY)
        return keys

    def normalized_inputs(self, readings: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor | None]:
        """(s, s') from raw readings [..., len(in_keys)]; s' is ``None`` when s' = s."""
        x = self.normalizer(readings)
        s = x.index_select(-1, self.s_index)
        s_att = None if self._same_inputs else x.index_select(-1, self.attention_index)
        return s, s_att

    def controller_inputs(self, data: TensorDictBase) -> tuple[torch.Tensor, torch.Tensor | None]:
        """(s, s') read from a tensordict holding the sensor keys (training helper)."""
        return self.normalized_inputs(self._readings([data[k] for k in self.in_keys]))

    def forward(self, *readings: torch.Tensor) -> tuple[torch.Tensor, ...]:
        s, s_att = self.normalized_inputs(self._readings(readings))
        out = self.controller(s, s_att)
        values = [out.action]
        if self.controller.has_pre_tanh:
            values.append(out.pre_tanh)
        if self.controller.has_input_mask:
            values.append(out.input_mask)
        if self.controller.has_output_mask:
            values.append(out.output_mask)
        return tuple(values)

    def _readings(self, readings) -> torch.Tensor:
        if len(readings) != len(self.in_keys):
            raise ValueError(
                f"SensorPolicy: expected {len(self.in_keys)} readings ({self.in_keys}), "
                f"got {len(readings)}"
            )
        for key, value in zip(self.in_keys, readings, strict=True):
            if value.shape[-1:] != (1,):
                raise ValueError(
                    f"SensorPolicy: sensor {key!r} must have shape [..., 1], got "
                    f"{tuple(value.shape)}"
                )
        return torch.cat([r.float() for r in readings], dim=-1)
