"""What TD3+BC and RLPD share: a TD3-style loss's optimisers, target updates and exploration.

Both learners train a deterministic actor and a Q ensemble with a TorchRL TD3 loss
(``TD3BCLoss`` or ``TD3Loss``). Around that loss they need the same TorchRL parts, built
here once (``TD3Parts``):

- two Adam optimisers, one over the loss's actor parameters, one over its Q parameters
  (a residual actor's frozen clone has no gradient, so Adam leaves it alone);
- ``SoftUpdate`` of the target networks (``tau`` per step);
- Gaussian exploration noise on the actor's action while collecting
  (``AdditiveGaussianModule``, a constant ``sigma`` in action units of [-1, 1]);

and the checkpoint entries of these parts (``state_dict`` / ``load_state_dict``), which
a resumed run needs to continue bit for bit.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import torch
from tensordict.nn import TensorDictModule, TensorDictSequential
from torchrl.data import Bounded
from torchrl.modules import AdditiveGaussianModule
from torchrl.objectives import LossModule, SoftUpdate

from pilerl.policies.checkpoint_file import (
    CheckpointError,
    load_module_state,
    load_optimizer_state,
)

OPTIMIZERS = ("actor_optimizer", "critic_optimizer")


@dataclass
class TD3Parts:
    """The TorchRL parts around a TD3-style ``loss`` (see the module docstring).

    Attributes:
        loss: the TD3 loss (actor, Q ensemble and their targets).
        target_updater: soft target updates of ``loss``.
        actor_optimizer, critic_optimizer: Adam over the actor's / the critics' parameters.
        exploration: the Gaussian noise added to the action while collecting.
        collection_policy: what the collector runs (the actor, then the noise).
    """

    loss: LossModule
    target_updater: SoftUpdate
    actor_optimizer: torch.optim.Adam
    critic_optimizer: torch.optim.Adam
    exploration: AdditiveGaussianModule
    collection_policy: TensorDictSequential

    @classmethod
    def around(
        cls,
        loss: LossModule,
        actor: TensorDictModule,
        action_spec: Bounded,
        *,
        tau: float,
        actor_lr: float,
        critic_lr: float,
        exploration_sigma: float,
    ) -> TD3Parts:
        """Build the parts for ``loss`` (whose value estimator is made) and its ``actor``."""
        target_updater = SoftUpdate(loss, tau=tau)
        actor_optimizer = torch.optim.Adam(
            list(loss.actor_network_params.values(True, True)), lr=actor_lr
        )
        critic_optimizer = torch.optim.Adam(
            list(loss.qvalue_network_params.values(True, True)), lr=critic_lr
        )
        exploration = AdditiveGaussianModule(
            action_spec,
            sigma_init=float(exploration_sigma),
            sigma_end=float(exploration_sigma),
            annealing_num_steps=1,
        )
        return cls(
            loss=loss,
            target_updater=target_updater,
            actor_optimizer=actor_optimizer,
            critic_optimizer=critic_optimizer,
            exploration=exploration,
            collection_policy=TensorDictSequential(actor, exploration),
        )

    def state_dict(self, *, updates: int) -> dict[str, object]:
        """The checkpoint entries: networks and targets, optimisers, exploration, and the
        learner's gradient step count (the actor's delay phase)."""
        return {
            "loss": self.loss.state_dict(),
            "actor_optimizer": self.actor_optimizer.state_dict(),
            "critic_optimizer": self.critic_optimizer.state_dict(),
            "exploration": self.exploration.state_dict(),
            "updates": updates,
        }

    def load_state_dict(self, state: dict, *, path: Path) -> int:
        """Restore ``state_dict()``'s entries read from ``path``, each checked to fit;
        returns the gradient step count."""
        load_module_state(path, self.loss, state.get("loss"), "learner.loss does not fit")
        load_module_state(
            path, self.exploration, state.get("exploration"), "learner.exploration does not fit"
        )
        for name in OPTIMIZERS:
            load_optimizer_state(path, getattr(self, name), state.get(name), f"learner.{name}")
        updates = state.get("updates")
        if not isinstance(updates, int) or isinstance(updates, bool) or updates < 0:
            raise CheckpointError(f"{path}: learner.updates is {updates!r}, not a count")
        return updates
