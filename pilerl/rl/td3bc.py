"""TD3+BC around a cloned actor: TorchRL ``TD3BCLoss``, twin Q, demos mixed into replay.

The actor is the cloned deterministic actor itself (eval mode, no dropout); collection
adds Gaussian noise to its action (``AdditiveGaussianModule``; optimisers, target updates
and noise are ``pilerl.rl.off_policy.TD3Parts``, shared with RLPD). Every gradient step draws
``demo_fraction`` of its batch from the demonstrations (which carry ``next`` readings,
reward and end flags, like a TorchRL rollout) and the rest from the online replay buffer.
TD3+BC's actor loss is ``-lambda * Q(s, pi(s)) + MSE(pi(s), a)`` on that batch, with
``lambda = alpha / mean|Q|``: the BC term is the regulariser that keeps the actor near
the demonstrated (and recently executed) actions.

``state_dict()`` holds the online replay buffer's transitions too, so a resumed run
samples exactly what an uninterrupted one would.
"""

from __future__ import annotations

from pathlib import Path

import torch
from tensordict import TensorDictBase, cat
from tensordict.nn import TensorDictModule
from torchrl.data import Bounded, LazyTensorStorage, TensorDictReplayBuffer
from torchrl.objectives import TD3BCLoss

from pilerl.data import make_replay_buffer
from pilerl.data.schema import END_FLAGS
from pilerl.policies import actor_policy

from .config import TD3BCConfig
from .critics import make_q_network
from .off_policy import LeafLayout, TD3Parts, leaf_name, replay_state, restore_replay

REPLAY_INDEX_KEY = "index"  # TensorDictReplayBuffer stores each transition's index


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
        self.parts = TD3Parts.around(
            self.loss,
            actor,
            self.action_spec,
            tau=settings.tau,
            actor_lr=settings.actor_lr,
            critic_lr=settings.critic_lr,
            exploration_sigma=settings.exploration_sigma,
        )
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
        return self.parts.collection_policy

    def state_dict(self) -> dict[str, object]:
        """What ``last.ckpt`` stores: networks and targets, optimisers, the update count
        (the actor's delay phase) and the online replay buffer's transitions."""
        return {
            **self.parts.state_dict(updates=self.updates),
            "replay": replay_state(self.replay),
        }

    def load_state_dict(self, state: dict, *, path: Path) -> None:
        """Restore ``state_dict()`` read from ``path``; what does not fit is refused."""
        updates = self.parts.load_state_dict(state, path=path)
        restore_replay(
            self.replay,
            state.get("replay"),
            path=path,
            capacity=self.settings.buffer_size,
            layout=self._replay_layout(),
            written_by_buffer=(REPLAY_INDEX_KEY,),
        )
        self.updates = updates

    def _replay_layout(self) -> dict[str, LeafLayout]:
        """What the online buffer stores: sensors, reward and flags [N, 1], the action
        [N, n_u] and the buffer's own index [N]."""
        layout = {REPLAY_INDEX_KEY: LeafLayout(REPLAY_INDEX_KEY, (), torch.int64)}
        for key in self.keys:
            last = key if isinstance(key, str) else key[-1]
            if last in END_FLAGS:
                layout[leaf_name(key)] = LeafLayout(key, (1,), torch.bool)
            else:
                width = self.policy.config.n_controls if key == "action" else 1
                layout[leaf_name(key)] = LeafLayout(key, (width,), torch.float32)
        return layout

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
            self.parts.critic_optimizer.zero_grad()
            q_loss.backward()
            self.parts.critic_optimizer.step()
            sums["loss_qvalue"] = sums.get("loss_qvalue", 0.0) + float(q_loss.detach())
            self.updates += 1
            if not warmup and self.updates % self.settings.policy_delay == 0:
                actor_loss, info = self.loss.actor_loss(data)
                self.parts.actor_optimizer.zero_grad()
                actor_loss.backward()
                self.parts.actor_optimizer.step()
                self.parts.target_updater.step()
                sums["loss_actor"] = sums.get("loss_actor", 0.0) + float(actor_loss.detach())
                sums["bc_loss"] = sums.get("bc_loss", 0.0) + float(info["bc_loss"])
                actor_steps += 1
            elif warmup:
                self.parts.target_updater.step()
        metrics = {"loss_qvalue": sums["loss_qvalue"] / self.settings.updates_per_batch}
        if actor_steps:
            metrics["loss_actor"] = sums["loss_actor"] / actor_steps
            metrics["bc_loss"] = sums["bc_loss"] / actor_steps
        metrics["warmup"] = float(warmup)
        metrics["replay_size"] = float(len(self.replay))
        return metrics
