"""A calibrated critic for RLPD: demonstration values held at least at their return.

Measured on the main job's clone (``docs/results/finetune/README.md``): the RLPD critics
valued the demonstrations' filling steps at -0.28..-0.57 where their discounted return is
+0.97. The TD target follows the current actor's next action, so once the actor lifts the
boom early, the critic learns that ending a scoop at once is worth more than filling it,
and the actor follows.

In the spirit of Cal-QL (Nakamoto et al., "Cal-QL: Calibrated Offline RL Pre-Training for
Efficient Online Fine-Tuning", NeurIPS 2023), which keeps learned Q values at least at
the Monte-Carlo return of the policy that collected the data, the TD target of a
demonstration transition is raised to that transition's Monte-Carlo discounted return
(``max(r + gamma * Q'(s', pi(s')), G_demo)``, the lower bound on the target used by
optimality tightening, He et al., ICLR 2017). The demonstrations show the bound is
reachable: their own actions from that state earned ``G_demo``. Online transitions keep
the plain TD target. Cal-QL bounds the conservative penalty of CQL instead; RLPD has no
such penalty, so the bound acts on the target. TorchRL has no calibrated critic; this is
ours: the returns (``monte_carlo_returns``, computed once from the replay's demonstration
rewards) and a wrapper of the loss's value estimator (``DemoReturnFloor``, ``calibrate``).
"""

from __future__ import annotations

import torch
from tensordict import TensorDictBase
from torch import nn

# replay keys of a calibrated learner: the demonstration's discounted return from this
# transition, and whether it is known (False for online data and for demonstration
# episodes that do not end terminated: their return after the cut is unknown)
MC_RETURN = "mc_return"
MC_RETURN_KNOWN = "mc_return_known"


def monte_carlo_returns(demos: TensorDictBase, gamma: float) -> tuple[torch.Tensor, torch.Tensor]:
    """Each demonstration transition's discounted return to the end of its episode.

    ``G_t = r_t + gamma * G_{t+1}`` within an episode, ``G_t = r_t`` at its terminal step
    (``("next", "terminated")``). Episodes are the consecutive rows of one ``episode`` id
    (a new id or an end flag starts the next one); an episode whose last row is not
    terminated (truncated, or cut off) has no known return.

    Args:
        demos: flat demonstration transitions, episodes in order, with ``episode``,
            ``("next", "reward")``, ``("next", "terminated")`` and ``("next", "done")``.
        gamma: discount per transition (the learner's ``gamma``), in (0, 1].

    Returns:
        ``(returns, known)``: float32 ``[N]`` (0 where not known) and bool ``[N]``.
    """
    if not 0 < gamma <= 1:
        raise ValueError(f"monte_carlo_returns: gamma must lie in (0, 1], got {gamma}")
    if demos.batch_dims != 1:
        raise ValueError(f"monte_carlo_returns: demos must be flat, got {demos.batch_size}")
    reward = demos["next", "reward"].reshape(-1).double()
    terminated = demos["next", "terminated"].reshape(-1).bool()
    done = demos["next", "done"].reshape(-1).bool() | terminated
    episode = demos["episode"].reshape(-1)
    if torch.isnan(reward).any():
        raise ValueError("monte_carlo_returns: some demonstration rewards are NaN")
    n = reward.numel()
    returns = torch.zeros(n, dtype=torch.float64)
    known = torch.zeros(n, dtype=torch.bool)
    following, following_known = 0.0, False
    for t in range(n - 1, -1, -1):
        last_of_episode = t == n - 1 or bool(done[t]) or bool(episode[t + 1] != episode[t])
        if last_of_episode:
            following, following_known = 0.0, bool(terminated[t])
        following = float(reward[t]) + gamma * following
        returns[t], known[t] = following, following_known
    return torch.where(known, returns, 0.0).float(), known


def calibrate(loss: nn.Module) -> DemoReturnFloor:
    """Wrap ``loss``'s value estimator (after ``make_value_estimator``) in a
    ``DemoReturnFloor``; returns it. The estimator is a submodule of the TorchRL loss
    (``_value_estimator``): ``nn.Module.__setattr__`` would register a module assigned to
    the public ``value_estimator`` property as a new submodule beside it, unused."""
    floor = DemoReturnFloor(loss.value_estimator)
    loss._value_estimator = floor
    return floor


class DemoReturnFloor(nn.Module):
    """A TorchRL value estimator whose target is at least the demonstration's return.

    Wraps the loss's estimator (``calibrate(loss)``):
    ``value_estimate`` returns the wrapped target, raised to ``MC_RETURN`` where
    ``MC_RETURN_KNOWN``. ``raised_share`` is the share of the last batch it raised.
    """

    def __init__(self, estimator: nn.Module) -> None:
        super().__init__()
        self.estimator = estimator
        self.raised_share = 0.0

    def value_estimate(self, tensordict: TensorDictBase, **kwargs) -> torch.Tensor:
        target = self.estimator.value_estimate(tensordict, **kwargs)
        floor = tensordict[MC_RETURN].reshape(target.shape).to(target.dtype)
        known = tensordict[MC_RETURN_KNOWN].reshape(target.shape)
        raised = known & (floor > target)
        self.raised_share = float(raised.float().mean())
        return torch.where(raised, floor, target)

    def __getattr__(self, name: str):
        try:
            return super().__getattr__(name)
        except AttributeError:
            return getattr(super().__getattr__("estimator"), name)
