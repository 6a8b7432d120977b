"""Feed-forward controllers u = F(s): NNet (Halbach et al. 2019) and NNetV2 (revised paper).

Every controller takes the normalised sensor vector ``s`` [..., n_s] (and, for attention
controllers, ``s_att`` = s' [..., n_s']) and returns a ``ControllerOutput``: the action
``u`` in [-1, 1] [..., n_u], its pre-tanh value (u = tanh(pre_tanh)), and the attention
masks where there are any. Leading dimensions are free: [B, n_s] and [n_s] both work.

Initialisation (the paper: "Kaiming initialization"): every ``nn.Linear`` gets
``kaiming_normal_`` with ``mode="fan_in"`` and zero bias; the gain follows the
nonlinearity that reads the layer's output: ``relu`` (sqrt 2) before a ReLU, ``tanh``
(5/3) before NNet's tanh hidden layer, and ``linear`` (1) for output layers, whose
output goes into the final tanh or a softmax (a larger gain would start them saturated).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import ClassVar, NamedTuple

import torch
from torch import nn

NNET_HIDDEN = 5  # Halbach et al. 2019: s-5-u
NNETV2_HIDDEN = (200, 200, 10)  # revised paper: s-200-200-10-u
DROPOUT = 0.35  # revised paper: on the two last hidden layers
DROPOUT_LAYERS = 2


class ControllerOutput(NamedTuple):
    """What a controller returns; masks are ``None`` where the controller has none.

    Attributes:
        action: u in [-1, 1], [..., n_u].
        pre_tanh: u' with u = tanh(u') [..., n_u]; ``None`` for non-neural controllers.
        input_mask: m, softmax over the n_s controller inputs [..., n_s] (ANNet, DANNet).
        output_mask: m_u, softmax over the n_u controls [..., n_u] (DANNet).
    """

    action: torch.Tensor
    pre_tanh: torch.Tensor | None = None
    input_mask: torch.Tensor | None = None
    output_mask: torch.Tensor | None = None


class Controller(nn.Module):
    """Base class: ``forward(s, s_att=None) -> ControllerOutput``.

    Class attributes say which optional outputs a controller fills, so that an actor
    knows which tensordict keys to write.
    """

    has_pre_tanh: ClassVar[bool] = True
    has_input_mask: ClassVar[bool] = False
    has_output_mask: ClassVar[bool] = False
    differentiable: ClassVar[bool] = True

    def forward(self, s: torch.Tensor, s_att: torch.Tensor | None = None) -> ControllerOutput:
        raise NotImplementedError


def kaiming_linear_(layer: nn.Linear, *, nonlinearity: str) -> None:
    """Kaiming-normal (fan-in) weights for the given following nonlinearity, zero bias."""
    nn.init.kaiming_normal_(layer.weight, mode="fan_in", nonlinearity=nonlinearity)
    if layer.bias is not None:
        nn.init.zeros_(layer.bias)


def relu_mlp(
    n_inputs: int, hidden: Sequence[int], *, dropout: float, dropout_layers: int
) -> nn.Sequential:
    """Linear-ReLU blocks; the last ``dropout_layers`` blocks end with ``Dropout(dropout)``."""
    layers: list[nn.Module] = []
    width = n_inputs
    for i, size in enumerate(hidden):
        linear = nn.Linear(width, size)
        kaiming_linear_(linear, nonlinearity="relu")
        layers += [linear, nn.ReLU()]
        if i >= len(hidden) - dropout_layers and dropout > 0:
            layers.append(nn.Dropout(dropout))
        width = size
    return nn.Sequential(*layers)


class NNet(Controller):
    """Halbach et al. 2019: one hidden layer of 5 tanh units, tanh output (s-5-u).

    The hidden tanh is MATLAB's default for a feed-forward net (``tansig``); the output
    tanh keeps u in [-1, 1] (MATLAB's default output would be linear). Trained with
    Levenberg-Marquardt by default (``pilerl.policies.levenberg_marquardt``).
    """

    def __init__(self, n_inputs: int, n_controls: int = 3, *, hidden: int = NNET_HIDDEN) -> None:
        super().__init__()
        self.hidden = nn.Linear(n_inputs, hidden)
        self.output = nn.Linear(hidden, n_controls)
        kaiming_linear_(self.hidden, nonlinearity="tanh")
        kaiming_linear_(self.output, nonlinearity="linear")

    def forward(self, s: torch.Tensor, s_att: torch.Tensor | None = None) -> ControllerOutput:
        pre_tanh = self.output(torch.tanh(self.hidden(s)))
        return ControllerOutput(torch.tanh(pre_tanh), pre_tanh)


class NNetV2(Controller):
    """Revised paper: s-200-200-10-u, ReLU after each hidden layer, dropout 0.35 on the
    last two hidden layers, tanh output. Also the controller body F of ANNet and DANNet.
    """

    def __init__(
        self,
        n_inputs: int,
        n_controls: int = 3,
        *,
        hidden: Sequence[int] = NNETV2_HIDDEN,
        dropout: float = DROPOUT,
        dropout_layers: int = DROPOUT_LAYERS,
    ) -> None:
        super().__init__()
        self.body = relu_mlp(n_inputs, hidden, dropout=dropout, dropout_layers=dropout_layers)
        self.output = nn.Linear(hidden[-1], n_controls)
        kaiming_linear_(self.output, nonlinearity="linear")

    def forward(self, s: torch.Tensor, s_att: torch.Tensor | None = None) -> ControllerOutput:
        pre_tanh = self.output(self.body(s))
        return ControllerOutput(torch.tanh(pre_tanh), pre_tanh)
