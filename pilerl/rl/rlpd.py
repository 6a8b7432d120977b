"""RLPD-style off-policy fine-tuning with the demonstrations in the replay.

The parts, after Ball et al., "Efficient Online RL with Offline Data" (RLPD, ICML 2023):

- **symmetric sampling**: every gradient step's batch is ``demo_fraction`` (0.5)
  demonstrations and the rest online transitions, drawn by TorchRL's
  ``OfflineToOnlineReplayBuffer`` (an exact split on every batch);
- **LayerNorm critics** in an **ensemble** of ``critic_ensemble`` Q networks, trained by
  TorchRL's ``TD3Loss`` (the TD target is the ensemble's minimum; RLPD's SAC takes the
  minimum of a random pair of 10; TorchRL's ``TD3Loss`` has no subset, so the ensemble is
  smaller, 4 by default);
- a **high update-to-data ratio**: ``utd_ratio`` critic steps per collected frame;
- a **critic warm-up**: the first ``critic_warmup_batches`` batches are the clone's own
  rollouts (plus exploration noise); they train the critics only (at
  ``warmup_utd_ratio``), so the first actor update follows a critic that has seen the
  clone's scoops;
- optionally **residual RL** (``residual=True``, ``pilerl.rl.residual``): the clone is
  frozen and a small residual actor, zero at the start, learns a bounded correction;
- optionally a **calibrated critic** (``calibrated_critic=True``,
  ``pilerl.rl.calibration``): the TD target of a demonstration transition is at least
  its Monte-Carlo discounted return (after Cal-QL, Nakamoto et al. 2023).

The actor is deterministic (TD3's), so collection adds Gaussian noise
(``AdditiveGaussianModule``; optimisers, target updates and noise are
``pilerl.rl.off_policy.TD3Parts``, shared with TD3+BC). ``state_dict()`` holds the online
replay's transitions, so a resumed run samples what an uninterrupted one would.
"""

from __future__ import annotations

from pathlib import Path

import torch
from tensordict import TensorDictBase
from tensordict.nn import TensorDictModule
from torchrl.data import Bounded, LazyTensorStorage, OfflineToOnlineReplayBuffer, ReplayBuffer
from torchrl.objectives import TD3Loss

from pilerl.policies import actor_policy

from .calibration import MC_RETURN, MC_RETURN_KNOWN, calibrate, monte_carlo_returns
from .config import RLPDConfig
from .critics import make_q_network
from .off_policy import TD3Parts, layout_of, replay_state, restore_replay
from .residual import make_residual_actor


class RLPDLearner:
    """RLPD-style learner on batches from a TorchRL collector.

    Args:
        actor: the cloned deterministic actor (``load_actor``); trained in place, or
            frozen under a residual actor (``settings.residual``).
        settings: the learner's settings.
        demos: demonstration transitions (with ``next`` readings, reward and end flags).
    """

    def __init__(
        self, actor: TensorDictModule, settings: RLPDConfig, *, demos: TensorDictBase | None
    ) -> None:
        self.settings = settings
        self.clone_policy = actor_policy(actor).eval()
        if settings.residual:
            self.actor = make_residual_actor(
                actor, settings.residual_hidden, scale=settings.residual_scale
            )
        else:
            self.actor = actor
        n_controls = self.clone_policy.config.n_controls
        self.action_spec = Bounded(low=-1.0, high=1.0, shape=(n_controls,))
        self.loss = TD3Loss(
            self.actor,
            make_q_network(
                self.clone_policy, settings.critic_hidden, layer_norm=settings.critic_layer_norm
            ),
            action_spec=self.action_spec,
            num_qvalue_nets=settings.critic_ensemble,
            policy_noise=settings.policy_noise,
            noise_clip=settings.noise_clip,
            loss_function="l2",
        )
        self.loss.make_value_estimator(gamma=settings.gamma)
        if settings.calibrated_critic:
            calibrate(self.loss)
        self.parts = TD3Parts.around(
            self.loss,
            self.actor,
            self.action_spec,
            tau=settings.tau,
            actor_lr=settings.actor_lr,
            critic_lr=settings.critic_lr,
            exploration_sigma=settings.exploration_sigma,
        )
        self.keys = sorted(self.loss.in_keys, key=str)
        # what the replay stores: the loss's keys (and, calibrated, the demo returns)
        self.stored_keys = list(self.keys)
        if settings.calibrated_critic:
            self.stored_keys += [MC_RETURN, MC_RETURN_KNOWN]
        if demos is None:
            raise ValueError("RLPD: needs demonstrations (demos: a dataset directory)")
        missing = [k for k in self.keys if k not in demos.keys(True)]
        if missing:
            raise KeyError(f"demos: no {missing} (RLPD needs next readings and reward)")
        if torch.isnan(demos["next", "reward"]).any():
            raise ValueError("demos: some rewards are NaN (imported logs): RLPD needs rewards")
        demo_data = self._as_stored(demos, demo_returns=self._demo_returns(demos))
        # online transitions go through _as_stored too: the demos' leaves are the layout
        self.stored_layout = layout_of(demo_data)
        offline = ReplayBuffer(storage=LazyTensorStorage(demo_data.numel()))
        offline.extend(demo_data)
        self.replay = OfflineToOnlineReplayBuffer(
            offline,
            online_capacity=settings.buffer_size,
            offline_fraction=settings.demo_fraction,
            batch_size=settings.batch_size,
        )
        self.updates = 0

    @property
    def collection_policy(self) -> TensorDictModule:
        """What the collector runs (the actor plus Gaussian exploration noise)."""
        return self.parts.collection_policy

    @property
    def deterministic_actor(self) -> TensorDictModule:
        """The actor to evaluate and save (the residual actor, or the clone trained)."""
        return self.actor

    def _demo_returns(self, demos: TensorDictBase) -> tuple[torch.Tensor, torch.Tensor] | None:
        """The demonstrations' Monte-Carlo returns (calibrated critic only)."""
        if not self.settings.calibrated_critic:
            return None
        if "episode" not in demos:
            raise KeyError("demos: no 'episode' ids (the calibrated critic needs episodes)")
        return monte_carlo_returns(demos.reshape(-1), self.settings.gamma)

    def _as_stored(
        self,
        data: TensorDictBase,
        *,
        demo_returns: tuple[torch.Tensor, torch.Tensor] | None = None,
    ) -> TensorDictBase:
        """The loss's keys of ``data``, flat, with a float32 reward (as stored online);
        calibrated, with the demonstrations' returns (online data: none known)."""
        stored = data.reshape(-1).select(*self.keys)
        stored.set(("next", "reward"), stored["next", "reward"].float())
        if self.settings.calibrated_critic:
            n = stored.numel()
            returns, known = demo_returns or (torch.zeros(n), torch.zeros(n, dtype=torch.bool))
            stored.set(MC_RETURN, returns)
            stored.set(MC_RETURN_KNOWN, known)
        return stored

    # ------------------------------------------------------------------ learning
    def update(self, batch: TensorDictBase, *, warmup: bool = False) -> dict[str, float]:
        """Store one collected batch, then ``utd_ratio`` critic steps per frame (during the
        warm-up ``warmup_utd_ratio`` and no actor step), an actor step every
        ``policy_delay``."""
        online = self._as_stored(batch)
        self.replay.extend(online)
        steps = self.settings.updates_for(online.numel(), warmup=warmup)
        q_sum, actor_sum, actor_steps, raised_sum = 0.0, 0.0, 0, 0.0
        for _ in range(steps):
            data = self.replay.sample()
            q_loss, _ = self.loss.value_loss(data)
            self.parts.critic_optimizer.zero_grad()
            q_loss.backward()
            self.parts.critic_optimizer.step()
            q_sum += float(q_loss.detach())
            if self.settings.calibrated_critic:
                raised_sum += self.loss.value_estimator.raised_share
            self.updates += 1
            if not warmup and self.updates % self.settings.policy_delay == 0:
                actor_loss, _ = self.loss.actor_loss(data)
                self.parts.actor_optimizer.zero_grad()
                actor_loss.backward()
                self.parts.actor_optimizer.step()
                actor_sum += float(actor_loss.detach())
                actor_steps += 1
            self.parts.target_updater.step()
        metrics = {
            "loss_qvalue": q_sum / steps,
            "warmup": float(warmup),
            "updates": float(steps),
            "replay_size": float(len(self.replay.online_buffer)),
        }
        if actor_steps:
            metrics["loss_actor"] = actor_sum / actor_steps
        if self.settings.calibrated_critic:
            metrics["calibration_raised_share"] = raised_sum / steps
        return metrics

    # ------------------------------------------------------------------ checkpoints
    def state_dict(self) -> dict[str, object]:
        """What ``last.ckpt`` stores: networks and targets, optimisers, the update count
        and the online replay's transitions with its writer position."""
        return {
            **self.parts.state_dict(updates=self.updates),
            "replay": replay_state(self.replay.online_buffer),
        }

    def load_state_dict(self, state: dict, *, path: Path) -> None:
        """Restore ``state_dict()`` read from ``path``; what does not fit is refused."""
        updates = self.parts.load_state_dict(state, path=path)
        restore_replay(
            self.replay.online_buffer,
            state.get("replay"),
            path=path,
            capacity=self.settings.buffer_size,
            layout=self.stored_layout,
        )
        self.updates = updates
