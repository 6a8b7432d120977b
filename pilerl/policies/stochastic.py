"""A BC actor inside TorchRL's ``ProbabilisticActor`` for policy-gradient fine-tuning.

The deterministic actor already writes ``action_loc`` (u', with action = tanh(u')). The
wrapper runs the same ``SensorPolicy`` (same parameters, nothing rewritten or copied),
writing its deterministic action to ``bc_action`` instead of ``action`` (TorchRL skips
sampling when the parameter modules already write the sampled key), adds one learned,
state-independent log-scale per control and samples

    action ~ TanhNormal(loc=u', scale=exp(log_scale)).

The distribution's deterministic sample is tanh(u'): under
``set_exploration_type(ExplorationType.DETERMINISTIC)`` the stochastic actor acts exactly
like the behaviour-cloned one (up to TorchRL's safe-tanh clamp at 1 - 1e-6).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from tensordict.nn import AddStateIndependentNormalScale, TensorDictModule, TensorDictSequential

from .actors import actor_policy
from .policy import ACTION_KEY, ACTION_LOC_KEY

if TYPE_CHECKING:
    from torchrl.modules import ProbabilisticActor

ACTION_SCALE_KEY = "action_scale"
BC_ACTION_KEY = "bc_action"  # the deterministic actor's action, tanh(action_loc)
INIT_SCALE = 0.2  # initial exploration std in pre-tanh units
SCALE_LB = 1e-4


def make_stochastic_actor(
    actor: TensorDictModule,
    *,
    init_scale: float = INIT_SCALE,
    scale_lb: float = SCALE_LB,
    return_log_prob: bool = True,
) -> ProbabilisticActor:
    """``ProbabilisticActor`` sampling a ``TanhNormal`` around ``actor``'s action.

    Args:
        actor: a neural actor from ``make_actor`` / ``load_actor`` (``rf`` is not
            differentiable and has no pre-tanh output).
        init_scale: initial std of the Normal before the tanh (learned afterwards, one
            value per control, stored as its log in ``state_independent_scale``).
        scale_lb: lower bound on the std.
        return_log_prob: write the sample's log-probability (PPO needs it).

    Dropout stays active in train mode: call ``.eval()`` on ``actor`` (or the result)
    for rollouts that should reproduce the BC action exactly.
    """
    # imported here: torchrl is slow to import and only RL fine-tuning needs it
    from torchrl.data import Bounded
    from torchrl.envs.utils import ExplorationType
    from torchrl.modules import ProbabilisticActor, TanhNormal

    policy = actor_policy(actor)
    if not policy.controller.has_pre_tanh:
        raise ValueError(
            f"controller {policy.config.controller!r} has no pre-tanh output and cannot be "
            "wrapped for policy-gradient fine-tuning"
        )
    if init_scale <= scale_lb:
        raise ValueError(f"init_scale {init_scale} must exceed scale_lb {scale_lb}")
    n_controls = policy.config.n_controls
    deterministic = TensorDictModule(
        policy, in_keys=policy.in_keys, out_keys=[BC_ACTION_KEY, *policy.out_keys[1:]]
    )
    scale = TensorDictModule(
        AddStateIndependentNormalScale(
            n_controls, scale_mapping="exp", scale_lb=scale_lb, init_value=math.log(init_scale)
        ),
        in_keys=[ACTION_LOC_KEY],
        out_keys=[ACTION_LOC_KEY, ACTION_SCALE_KEY],
    )
    return ProbabilisticActor(
        TensorDictSequential(deterministic, scale),
        in_keys={"loc": ACTION_LOC_KEY, "scale": ACTION_SCALE_KEY},
        out_keys=[ACTION_KEY],
        spec=Bounded(low=-1.0, high=1.0, shape=(n_controls,)),
        distribution_class=TanhNormal,
        distribution_kwargs={"low": -1.0, "high": 1.0},
        return_log_prob=return_log_prob,
        default_interaction_type=ExplorationType.DETERMINISTIC,
    )
