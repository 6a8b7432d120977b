"""Attention controllers of the revised paper: ANNet (input mask) and DANNet (dual mask).

An attention network A reads the attention inputs s' (the controller inputs s unless
more sensors are given) through s'-64-64 (ReLU, dropout 0.35 on both hidden layers) and
emits a softmax mask m over the n_s controller inputs; DANNet's second head also emits
m_u, a softmax over the n_u controls:

    ANNet:   m = softmax(A(s')),                     u = tanh(F'(s * m))
    DANNet:  m, m_u = softmax(A(s')), softmax(A_u(s')),  u = tanh(m_u * F'(s * m))

where F' is an NNetV2 before its output tanh (``*`` is the element-wise product).
"""

from __future__ import annotations

from collections.abc import Sequence

import torch
from torch import nn

from .controllers import (
    DROPOUT,
    NNETV2_HIDDEN,
    Controller,
    ControllerOutput,
    NNetV2,
    kaiming_linear_,
    relu_mlp,
)

ATTENTION_HIDDEN = (64, 64)  # revised paper: s'-64-64-m


class AttentionNet(nn.Module):
    """A: s'-64-64-m with an optional second head for m_u; masks are softmaxes."""

    def __init__(
        self,
        n_attention_inputs: int,
        n_inputs: int,
        n_controls: int | None = None,
        *,
        hidden: Sequence[int] = ATTENTION_HIDDEN,
        dropout: float = DROPOUT,
    ) -> None:
        super().__init__()
        self.trunk = relu_mlp(
            n_attention_inputs, hidden, dropout=dropout, dropout_layers=len(hidden)
        )
        self.input_head = nn.Linear(hidden[-1], n_inputs)
        kaiming_linear_(self.input_head, nonlinearity="linear")
        self.output_head: nn.Linear | None = None
        if n_controls is not None:
            self.output_head = nn.Linear(hidden[-1], n_controls)
            kaiming_linear_(self.output_head, nonlinearity="linear")

    def forward(self, s_att: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor | None]:
        """(m [..., n_s], m_u [..., n_u] or ``None``)."""
        features = self.trunk(s_att)
        input_mask = torch.softmax(self.input_head(features), dim=-1)
        output_mask = None
        if self.output_head is not None:
            output_mask = torch.softmax(self.output_head(features), dim=-1)
        return input_mask, output_mask


class ANNet(Controller):
    """Single attention: u = tanh(F'(s * m)), m = softmax(A(s'))."""

    has_input_mask = True
    dual = False

    def __init__(
        self,
        n_inputs: int,
        n_controls: int = 3,
        *,
        n_attention_inputs: int | None = None,
        attention_hidden: Sequence[int] = ATTENTION_HIDDEN,
        hidden: Sequence[int] = NNETV2_HIDDEN,
        dropout: float = DROPOUT,
    ) -> None:
        super().__init__()
        self.attention = AttentionNet(
            n_attention_inputs or n_inputs,
            n_inputs,
            n_controls if self.dual else None,
            hidden=attention_hidden,
            dropout=dropout,
        )
        self.network = NNetV2(n_inputs, n_controls, hidden=hidden, dropout=dropout)

    def forward(self, s: torch.Tensor, s_att: torch.Tensor | None = None) -> ControllerOutput:
        input_mask, _ = self.attention(s if s_att is None else s_att)
        inner = self.network(s * input_mask)
        return ControllerOutput(inner.action, inner.pre_tanh, input_mask)


class DANNet(ANNet):
    """Dual attention: u = tanh(m_u * u'), u' = F'(s * m); m, m_u from one A, two heads."""

    has_output_mask = True
    dual = True

    def forward(self, s: torch.Tensor, s_att: torch.Tensor | None = None) -> ControllerOutput:
        input_mask, output_mask = self.attention(s if s_att is None else s_att)
        assert output_mask is not None  # dual: the second head exists
        pre_tanh = output_mask * self.network(s * input_mask).pre_tanh
        return ControllerOutput(torch.tanh(pre_tanh), pre_tanh, input_mask, output_mask)
