"""TD3+BC around a cloned actor: TorchRL ``TD3BCLoss``, twin Q, demos mixed into replay.

The actor is the cloned deterministic actor itself (eval mode, no dropout); collection
adds Gaussian noise to its action (``AdditiveGaussianModule``). Every gradient step draws
``demo_fraction`` of its batch from the demonstrations (which carry ``next`` readings,
reward and end flags, like a TorchRL rollout) and the rest from the online replay buffer.
TD3+BC's actor loss is ``-lambda * Q(s, pi(s)) + MSE(pi(s), a)`` on that batch, with
``lambda = alpha / mean|Q|``: the BC term is the regulariser that keeps the actor near
the demonstrated (and recently executed) actions.
"""

from __future__ import annotations

import torch
from tensordict import TensorDictBase, cat
from tensordict.nn import TensorDictModule, TensorDictSequential
from torchrl.data import Bounded, LazyTensorStorage, TensorDictReplayBuffer
from torchrl.modules import AdditiveGaussianModule
from torchrl.objectives import SoftUpdate, TD3BCLoss

from pilerl.data import make_replay_buffer
from pilerl.policies import actor_policy

from .config import TD3BCConfig
from .critics import make_q_network


class TD3BCLearner:
    """TD3+BC on batches from a TorchRL collector.

    Args:
        actor: the cloned deterministic actor (``load_actor``); trained in place.
        settings: TD3+BC hyper-parameters.
        demos: demonstration transitions (needed when ``demo_fraction > 0``).
    """

    def __init__(
        self,
        actor: TensorDictModule,
        settings: TD3BCConfig,
        *,
        demos: TensorDictBase | None = None,
    ) -> None:
        self.settings = settings
        self.policy = actor_policy(actor).eval()
        self.actor = actor
        n_controls = self.policy.config.n_controls
        self.action_spec = Bounded(low=-1.0, high=1.0, shape=(n_controls,))
        self.loss = TD3BCLoss(
            actor,
            make_q_network(self.policy, settings.critic_hidden),
            action_spec=self.action_spec,
            num_qvalue_nets=2,
            policy_noise=settings.policy_noise,
            noise_clip=settings.noise_clip,
            alpha=settings.alpha,
            loss_function="l2",
        )
        self.loss.make_value_estimator(gamma=settings.gamma)
        self.target_updater = SoftUpdate(self.loss, tau=settings.tau)
        self.actor_optimizer = torch.optim.Adam(
            list(self.loss.actor_network_params.values(True, True)), lr=settings.actor_lr
        )
        self.critic_optimizer = torch.optim.Adam(
            list(self.loss.qvalue_network_params.values(True, True)), lr=settings.critic_lr
        )
        self.exploration = AdditiveGaussianModule(
            self.action_spec,
            sigma_init=float(settings.exploration_sigma),
            sigma_end=float(settings.exploration_sigma),
            annealing_num_steps=1,
        )
        self._collection_policy = TensorDictSequential(actor, self.exploration)
        self.keys = sorted(self.loss.in_keys, key=str)
        self.demo_batch = round(settings.batch_size * settings.demo_fraction)
        self.online_batch = settings.batch_size - self.demo_batch
        self.replay = TensorDictReplayBuffer(
            storage=LazyTensorStorage(settings.buffer_size), batch_size=max(self.online_batch, 1)
        )
        self.demo_replay = None
        if self.demo_batch > 0:
            if demos is None:
                raise ValueError("TD3+BC: demo_fraction > 0 needs demonstrations")
            missing = [k for k in self.keys if k not in demos.keys(True)]
            if missing:
                raise KeyError(f"demos: no {missing} (TD3+BC needs next readings and reward)")
            demo_data = demos.select(*self.keys)
            if torch.isnan(demo_data["next", "reward"]).any():
                raise ValueError("demos: some rewards are NaN (imported logs): use demo_fraction 0")
            self.demo_replay = make_replay_buffer(demo_data, batch_size=self.demo_batch)
        self.updates = 0

    @property
    def collection_policy(self) -> TensorDictModule:
        """What the collector runs (the actor plus Gaussian exploration noise)."""
        return self._collection_policy

    def checkpoint_components(self) -> dict[str, object]:
        """Objects with ``state_dict`` that ``last.ckpt`` stores and restores."""
        return {
            "loss": self.loss,
            "actor_optimizer": self.actor_optimizer,
            "critic_optimizer": self.critic_optimizer,
        }

    def sample(self) -> TensorDictBase:
        """One training batch: online transitions and demonstrations."""
        parts = []
        if self.online_batch > 0 and len(self.replay) > 0:
            parts.append(self.replay.sample().select(*self.keys))
        if self.demo_replay is not None:
            parts.append(self.demo_replay.sample().select(*self.keys))
        if not parts:
            raise RuntimeError("TD3+BC: nothing to learn from yet (empty replay, no demos)")
        return cat(parts, 0) if len(parts) > 1 else parts[0]

    def update(self, batch: TensorDictBase, *, warmup: bool = False) -> dict[str, float]:
        """Store one collected batch, then ``updates_per_batch`` gradient steps."""
        online = batch.reshape(-1).select(*self.keys)
        online.set(("next", "reward"), online["next", "reward"].float())
        self.replay.extend(online)
        sums: dict[str, float] = {}
        actor_steps = 0
        for _ in range(self.settings.updates_per_batch):
            data = self.sample()
            q_loss, _ = self.loss.qvalue_loss(data)
            self.critic_optimizer.zero_grad()
            q_loss.backward()
            self.critic_optimizer.step()
            sums["loss_qvalue"] = sums.get("loss_qvalue", 0.0) + float(q_loss.detach())
            self.updates += 1
            if not warmup and self.updates % self.settings.policy_delay == 0:
                actor_loss, info = self.loss.actor_loss(data)
                self.actor_optimizer.zero_grad()
                actor_loss.backward()
                self.actor_optimizer.step()
                self.target_updater.step()
                sums["loss_actor"] = sums.get("loss_actor", 0.0) + float(actor_loss.detach())
                sums["bc_loss"] = sums.get("bc_loss", 0.0) + float(info["bc_loss"])
                actor_steps += 1
            elif warmup:
                self.target_updater.step()
        metrics = {"loss_qvalue": sums["loss_qvalue"] / self.settings.updates_per_batch}
        if actor_steps:
            metrics["loss_actor"] = sums["loss_actor"] / actor_steps
            metrics["bc_loss"] = sums["bc_loss"] / actor_steps
        metrics["warmup"] = float(warmup)
        metrics["replay_size"] = float(len(self.replay))
        return metrics
