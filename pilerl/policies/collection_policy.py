"""The stochastic actor's sampling path in one forward: what a collector runs for PPO.

``make_stochastic_actor`` gives a TorchRL ``ProbabilisticActor``: the losses
(``ClipPPOLoss``) read its distribution. Collecting with it costs, per call, a
``TensorDictSequential`` of two ``TensorDictModule``s, a ``TanhNormal`` (an
``Independent(Normal)`` under a ``TransformedDistribution``, argument checks included) and
TorchRL's sampling dispatch: 460 us a call on a batch of 8 against 114 us for the network
itself, and 201 us for this module (CPU time, hot loop; docs/performance.md).

``FusedTanhNormalPolicy`` wraps that same actor (its parameters, not copies: the learner's
updates act at once) and, when the exploration type is ``RANDOM``, computes with plain
tensors exactly what ``ProbabilisticActor`` computes, operation for operation (TorchRL
0.14 ``TanhNormal.rsample_and_log_prob``, tensordict's ``AddStateIndependentNormalScale``):

    loc, bc_action, masks = SensorPolicy(readings)          # the same call
    scale = exp(log_scale.expand_as(loc)).clamp_min(scale_lb)
    u = loc + eps * scale,  eps = torch.empty(loc.shape).normal_()
    action = clamp(tanh(u), -(1 - 1e-6), 1 - 1e-6)           # TorchRL's safe tanh
    log_prob = sum(Normal(loc, scale).log_prob(u)) - sum(2 (log 2 - u - softplus(-2u)))

It draws from torch's generator in the same order (dropout, if on, then the noise), so the
same RNG state gives bit-identical ``action``, ``action_log_prob``, ``action_loc``,
``action_scale``, ``bc_action`` and masks (tests/policies/test_collection_policy.py). In
any other exploration type it calls the ``ProbabilisticActor`` itself.
"""

from __future__ import annotations

import math

import torch
from tensordict import TensorDictBase
from tensordict.nn import (
    AddStateIndependentNormalScale,
    TensorDictModule,
    TensorDictModuleBase,
    TensorDictSequential,
)
from torch.nn import functional as F  # noqa: N812
from torchrl.envs.utils import ExplorationType, exploration_type
from torchrl.modules import ProbabilisticActor, TanhNormal
from torchrl.modules.distributions.utils import safetanh_noeps

from .policy import ACTION_KEY, ACTION_LOC_KEY, SensorPolicy
from .stochastic import ACTION_SCALE_KEY

LOG_SQRT_2PI = math.log(math.sqrt(2 * math.pi))  # as torch.distributions.Normal spells it
LOG_2 = math.log(2.0)


class FusedTanhNormalPolicy(TensorDictModuleBase):
    """``actor`` (from ``make_stochastic_actor``) sampling in one forward pass.

    Args:
        actor: the learner's ``ProbabilisticActor``; held as ``self.actor``, so this module's
            parameters are the actor's, under the same names prefixed ``actor.``.

    Raises:
        TypeError: ``actor`` is not shaped as ``make_stochastic_actor`` builds it (the
            fused arithmetic would not be the actor's).
    """

    def __init__(self, actor: ProbabilisticActor) -> None:
        super().__init__()
        self._check_layout(actor)
        self.actor = actor
        self.in_keys = list(actor.in_keys)
        self.out_keys = list(actor.out_keys)
        self._policy_out_keys = list(actor.module[0].module[0].out_keys)
        self._log_prob_key = actor.module[1].log_prob_key
        # the actor's parts, looked up once (a tuple: not registered a second time)
        self._parts = (actor.module[0].module[0].module, actor.module[0].module[1].module)

    @property
    def policy(self) -> SensorPolicy:
        """The cloned network (``bc_action``, ``action_loc``, masks)."""
        return self._parts[0]

    @property
    def scale(self) -> AddStateIndependentNormalScale:
        """The learned state-independent log-scale."""
        return self._parts[1]

    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        if exploration_type() is not ExplorationType.RANDOM:
            return self.actor(tensordict)
        policy, scale_module = self._parts
        outputs = policy(*[tensordict.get(key) for key in self.in_keys])
        loc = outputs[1]  # action_loc: u' of the cloned action tanh(u')
        scale = torch.exp(scale_module.state_independent_scale.expand_as(loc)).clamp_min(
            scale_module.scale_lb
        )
        noise = torch.empty(loc.shape, dtype=loc.dtype, device=loc.device).normal_()
        pre_tanh = loc + noise * scale
        action = _safe_tanh(pre_tanh)
        normal_log_prob = -((pre_tanh - loc) ** 2) / (2 * scale**2) - scale.log() - LOG_SQRT_2PI
        log_abs_det_jacobian = 2.0 * (LOG_2 - pre_tanh - F.softplus(-2.0 * pre_tanh))
        log_prob = _sum_last(normal_log_prob) - _sum_last(log_abs_det_jacobian)
        for key, value in zip(self._policy_out_keys, outputs, strict=True):
            tensordict.set(key, value)
        tensordict.set(ACTION_SCALE_KEY, scale)
        tensordict.set(ACTION_KEY, action)
        tensordict.set(self._log_prob_key, log_prob)
        return tensordict

    @staticmethod
    def _check_layout(actor: ProbabilisticActor) -> None:
        where = "FusedTanhNormalPolicy"
        if not isinstance(actor, ProbabilisticActor) or len(actor.module) != 2:
            raise TypeError(f"{where}: needs make_stochastic_actor's actor, got {type(actor)}")
        params, sampler = actor.module
        if not (
            isinstance(params, TensorDictSequential)
            and len(params.module) == 2
            and isinstance(params.module[0], TensorDictModule)
            and isinstance(params.module[0].module, SensorPolicy)
            and isinstance(params.module[1].module, AddStateIndependentNormalScale)
            and params.module[1].module.scale_mapping == "exp"
            and list(params.module[0].out_keys[1:2]) == [ACTION_LOC_KEY]
        ):
            raise TypeError(
                f"{where}: the actor's parameter modules are not make_stochastic_actor's "
                "(SensorPolicy writing action_loc, then an exp-mapped state-independent scale)"
            )
        kwargs = sampler.distribution_kwargs
        if not (
            sampler.distribution_class is TanhNormal
            and set(kwargs) == {"low", "high"}
            and (kwargs["low"], kwargs["high"]) == (-1.0, 1.0)
            and sampler.return_log_prob
            and sampler.num_samples is None
        ):
            raise TypeError(
                f"{where}: the actor does not sample TanhNormal(low=-1, high=1) with its "
                f"log-probability (distribution {sampler.distribution_class}, kwargs {kwargs})"
            )


def _safe_tanh(pre_tanh: torch.Tensor) -> torch.Tensor:
    """TorchRL's ``SafeTanhTransform``: tanh clamped to 1 - eps (``finfo.resolution``).

    Its autograd function (custom backward) costs ~0.1 ms a call to bind its arguments;
    without gradients the same forward arithmetic is called directly.
    """
    if torch.is_grad_enabled():
        return safetanh_noeps(pre_tanh)
    limit = 1.0 - torch.finfo(pre_tanh.dtype).resolution
    return pre_tanh.tanh().clamp(-limit, limit)


def _sum_last(value: torch.Tensor) -> torch.Tensor:
    """Sum over the control dimension as ``torch.distributions`` does (``_sum_rightmost``)."""
    return value.reshape(value.shape[:-1] + (-1,)).sum(-1)


def make_collection_policy(actor: ProbabilisticActor) -> FusedTanhNormalPolicy:
    """What a collector runs for ``actor``: ``FusedTanhNormalPolicy(actor)``."""
    return FusedTanhNormalPolicy(actor)
