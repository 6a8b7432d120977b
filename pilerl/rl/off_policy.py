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
a resumed run needs to continue bit for bit. Both learners also checkpoint their online
replay buffer the same way (``replay_state`` / ``restore_replay``): the stored
transitions in storage order and the writer's position, every leaf checked against the
layout the learner stores before anything is written into the buffer.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import torch
from tensordict import TensorDict, TensorDictBase
from tensordict.nn import TensorDictModule, TensorDictSequential
from torchrl.data import Bounded, ReplayBuffer
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


NestedKey = str | tuple[str, ...]


@dataclass(frozen=True)
class LeafLayout:
    """One stored leaf of a replay buffer: its key, the shape of one transition's value
    (without the leading transition dimension) and its dtype."""

    key: NestedKey
    per_transition: tuple[int, ...]
    dtype: torch.dtype


def leaf_name(key: NestedKey) -> str:
    """A nested key as one checkpoint entry name: ``("next", "reward")`` -> ``next/reward``."""
    return "/".join((key,) if isinstance(key, str) else key)


def layout_of(stored: TensorDictBase) -> dict[str, LeafLayout]:
    """The layout of every leaf of ``stored`` (a batch of transitions, batch dim first)."""
    return {
        leaf_name(key): LeafLayout(key, tuple(value.shape[1:]), value.dtype)
        for key, value in stored.items(include_nested=True, leaves_only=True)
    }


def replay_state(buffer: ReplayBuffer) -> dict[str, object]:
    """A replay buffer's checkpoint entry: its transitions in storage order (one tensor per
    leaf), their number and the writer's position (cursor, write count)."""
    size = len(buffer)
    data = {}
    if size:
        data = {
            leaf_name(key): value.contiguous()
            for key, value in buffer.storage[:size].items(include_nested=True, leaves_only=True)
        }
    return {"size": size, "data": data, "writer": dict(buffer._writer.state_dict())}


def restore_replay(
    buffer: ReplayBuffer,
    state: object,
    *,
    path: Path,
    capacity: int,
    layout: Mapping[str, LeafLayout],
    written_by_buffer: tuple[str, ...] = (),
) -> None:
    """Refill the empty ``buffer`` exactly as ``replay_state`` saved it.

    ``written_by_buffer`` names leaves the buffer writes itself on ``extend`` (a
    ``TensorDictReplayBuffer``'s ``index``): checked like the others, not passed back.

    Every part is checked first (entry ``learner.replay`` of ``path``): the transition
    count within ``capacity``, the writer's cursor and write count, the leaves' names
    against ``layout`` and each leaf's dtype and shape ``[size, *per_transition]``. What does
    not fit raises ``CheckpointError`` naming the file and the leaf; nothing is written.
    """
    if not isinstance(state, dict) or not isinstance(state.get("data"), dict):
        raise CheckpointError(f"{path}: learner.replay is not a replay buffer state")
    size, data, writer = state.get("size"), state["data"], state.get("writer")
    if not isinstance(size, int) or isinstance(size, bool) or not 0 <= size <= capacity:
        raise CheckpointError(
            f"{path}: learner.replay holds {size!r} transitions (buffer size {capacity})"
        )
    if (
        not isinstance(writer, dict)
        or not all(
            isinstance(writer.get(k), int) and not isinstance(writer[k], bool) and writer[k] >= 0
            for k in ("_cursor", "_write_count")
        )
        or writer["_cursor"] >= capacity
    ):
        raise CheckpointError(f"{path}: learner.replay has no valid writer position")
    cursor, writes = writer["_cursor"], writer["_write_count"]
    if cursor != writes % capacity or size != min(writes, capacity):
        raise CheckpointError(
            f"{path}: learner.replay's writer (cursor {cursor}, {writes} writes) does not fit "
            f"its {size} transitions in a buffer of {capacity}"
        )
    if len(buffer) != 0:
        raise ValueError(f"restore_replay: the buffer already holds {len(buffer)} transitions")
    if size == 0:
        return
    if set(data) != set(layout):
        raise CheckpointError(
            f"{path}: learner.replay holds {sorted(data)}, expected {sorted(layout)}"
        )
    for name, value in data.items():
        want = layout[name]
        want_shape = (size, *want.per_transition)
        if not isinstance(value, torch.Tensor):
            raise CheckpointError(f"{path}: learner.replay/{name} is not a tensor")
        if tuple(value.shape) != want_shape or value.dtype != want.dtype:
            raise CheckpointError(
                f"{path}: learner.replay/{name} is {value.dtype}{tuple(value.shape)}, "
                f"expected {want.dtype}{want_shape}"
            )
    transitions = {layout[n].key: v for n, v in data.items() if n not in written_by_buffer}
    buffer.extend(TensorDict(transitions, batch_size=[size]))
    buffer._writer.load_state_dict(writer)
