"""PPO around a cloned actor: TorchRL ``ClipPPOLoss`` + ``GAE`` + a demo regulariser.

The learner's actor is ``make_stochastic_actor(actor)``: a ``TanhNormal`` around the
cloned action with a learned, state-independent scale, so at the start the mean action is
exactly the cloned one. ``ClipPPOLoss`` reads its distribution; the collector runs
``FusedTanhNormalPolicy`` around it (the same parameters and bit-identical samples, in one
forward pass with plain tensors: ``pilerl.policies.collection_policy``). The cloned
network stays in eval mode (no dropout): fine-tuning changes its weights, not its
architecture, and the deterministic action stays the one ``best.pt`` will reproduce.

One ``update`` per collected batch: GAE advantages with the value network, then
``epochs`` passes of minibatches. The actor loss is PPO's clipped objective (plus the
entropy bonus) plus ``regularizer_weight`` times the regulariser; during the first
``critic_warmup_batches`` batches only the value network learns.
"""

from __future__ import annotations

from pathlib import Path

import torch
from tensordict import TensorDictBase
from tensordict.nn import TensorDictModule
from torchrl.objectives import ClipPPOLoss
from torchrl.objectives.value import GAE

from pilerl.policies import actor_policy, make_stochastic_actor
from pilerl.policies.checkpoint_file import (
    CheckpointError,
    load_module_state,
    load_optimizer_state,
)
from pilerl.policies.collection_policy import make_collection_policy

from .config import PPOConfig
from .critics import make_value_network
from .regularizers import make_regularizer


class PPOLearner:
    """Clipped PPO on batches from a TorchRL collector.

    Args:
        actor: the cloned deterministic actor (``load_actor``); trained in place.
        settings: PPO hyper-parameters.
        demos: demonstration transitions (for the ``bc_demo`` regulariser) or ``None``.
        seed: seeds the minibatch order.
    """

    def __init__(
        self,
        actor: TensorDictModule,
        settings: PPOConfig,
        *,
        demos: TensorDictBase | None = None,
        seed: int = 0,
    ) -> None:
        self.settings = settings
        self.policy = actor_policy(actor).eval()
        self.actor = make_stochastic_actor(actor, init_scale=settings.init_scale)
        self._collection_policy = make_collection_policy(self.actor)
        self.critic = make_value_network(self.policy, settings.critic_hidden)
        self.advantage = GAE(
            gamma=settings.gamma,
            lmbda=settings.lmbda,
            value_network=self.critic,
            average_gae=False,
        )
        self.loss = ClipPPOLoss(
            self.actor,
            self.critic,
            clip_epsilon=settings.clip_epsilon,
            entropy_bonus=settings.entropy_coeff > 0,
            entropy_coeff=settings.entropy_coeff if settings.entropy_coeff > 0 else None,
            critic_coeff=settings.critic_coeff,
            loss_critic_type="smooth_l1",
            normalize_advantage=True,
        )
        self.regularizer = make_regularizer(
            settings.regularizer,
            self.policy,
            demos=demos,
            batch_size=settings.regularizer_batch_size,
        )
        self.optimizer = torch.optim.Adam(
            [
                {"params": list(self.actor.parameters()), "lr": settings.actor_lr},
                {"params": list(self.critic.parameters()), "lr": settings.critic_lr},
            ]
        )
        self.generator = torch.Generator().manual_seed(seed)

    @property
    def collection_policy(self) -> TensorDictModule:
        """What the collector runs: ``self.actor``'s samples around the cloned action, fused
        into one forward pass (its parameters)."""
        return self._collection_policy

    def state_dict(self) -> dict[str, object]:
        """What ``last.ckpt`` stores: weights, optimiser and the minibatch-order generator."""
        return {
            "actor": self.actor.state_dict(),
            "critic": self.critic.state_dict(),
            "optimizer": self.optimizer.state_dict(),
            "generator": self.generator.get_state(),
        }

    def load_state_dict(self, state: dict, *, path: Path) -> None:
        """Restore ``state_dict()`` read from ``path``; what does not fit is refused."""
        load_module_state(path, self.actor, state.get("actor"), "learner.actor does not fit")
        load_module_state(path, self.critic, state.get("critic"), "learner.critic does not fit")
        load_optimizer_state(path, self.optimizer, state.get("optimizer"), "learner.optimizer")
        generator = state.get("generator")
        if not isinstance(generator, torch.Tensor) or (
            generator.dtype != torch.uint8 or generator.shape != self.generator.get_state().shape
        ):
            raise CheckpointError(f"{path}: learner.generator is not a generator state")
        self.generator.set_state(generator)

    def regularizer_loss(self, batch: TensorDictBase) -> torch.Tensor:
        """The regulariser on ``batch`` (0 without one), differentiable in the actor."""
        if self.regularizer is None:
            return torch.zeros(())
        return self.regularizer(batch)

    def update(self, batch: TensorDictBase, *, warmup: bool = False) -> dict[str, float]:
        """Learn from one collected batch (time along its last dimension)."""
        settings = self.settings
        with torch.no_grad():
            self.advantage(batch)
        flat = batch.reshape(-1)
        n = flat.numel()
        size = min(settings.minibatch_size, n)
        sums: dict[str, float] = {}
        steps = 0
        for _ in range(settings.epochs):
            order = torch.randperm(n, generator=self.generator)
            for start in range(0, n - size + 1, size):
                minibatch = flat[order[start : start + size]]
                losses = self.loss(minibatch)
                critic_loss = losses["loss_critic"]
                if warmup:
                    total = critic_loss
                    parts = {"loss_critic": critic_loss}
                else:
                    regularizer = self.regularizer_loss(minibatch)
                    objective = losses["loss_objective"]
                    entropy = losses.get("loss_entropy", torch.zeros(()))
                    total = (
                        objective
                        + entropy
                        + critic_loss
                        + settings.regularizer_weight * regularizer
                    )
                    parts = {
                        "loss_objective": objective,
                        "loss_critic": critic_loss,
                        "loss_regularizer": regularizer,
                        "kl_approx": losses.get("kl_approx", torch.zeros(())),
                        "clip_fraction": losses.get("clip_fraction", torch.zeros(())),
                    }
                self.optimizer.zero_grad()
                total.backward()
                torch.nn.utils.clip_grad_norm_(
                    [p for group in self.optimizer.param_groups for p in group["params"]],
                    settings.max_grad_norm,
                )
                self.optimizer.step()
                for name, value in parts.items():
                    sums[name] = sums.get(name, 0.0) + float(value.detach())
                steps += 1
        metrics = {name: value / max(steps, 1) for name, value in sums.items()}
        metrics["exploration_std"] = float(self.exploration_std().mean())
        metrics["warmup"] = float(warmup)
        return metrics

    def exploration_std(self) -> torch.Tensor:
        """The current std of the Normal before the tanh, one per control."""
        for name, parameter in self.actor.named_parameters():
            if name.endswith("state_independent_scale"):  # log std ("exp" mapping)
                return parameter.detach().exp()
        raise RuntimeError("the stochastic actor has no learned scale")
