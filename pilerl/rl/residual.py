"""Residual RL on a frozen cloned actor: ``u = clip(u_clone(s) + scale * tanh(r(s, u_clone)))``.

TorchRL has no residual policy, so this is our own, small: ``ResidualPolicy`` keeps the
cloned ``SensorPolicy`` frozen (no gradient reaches it) and learns a small MLP ``r`` over
the normalised readings and the clone's action. ``r``'s last layer starts at zero, so the
residual actor at initialisation acts exactly as the clone, and the learner can only move
away from the clone as far as ``scale`` allows.

A residual actor is not a ``SensorPolicy``, so it has its own checkpoint file
(``save_residual_actor`` / ``load_residual_actor``, format ``pilerl.residual_actor``: the
clone's config and weights beside the residual's) and its own evaluation controller
(``ResidualWeights``, what evaluation workers receive). ``controller_for`` picks the
controller of any actor, in memory or saved.
"""

from __future__ import annotations

import io
import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import torch
from tensordict.nn import TensorDictModule, TensorDictModuleBase
from torch import nn
from torchrl.modules import MLP

from pilerl.evaluation.evaluator import ActorController, ActorWeights
from pilerl.policies import ACTION_KEY, InputNormalizer, SensorPolicy, actor_policy
from pilerl.policies.checkpoint_file import (
    CheckpointError,
    CheckpointFormatError,
    load_module_state,
    parse_json,
    read_checkpoint,
    write_checkpoint,
)
from pilerl.sim.rollout import RowByRow
from pilerl.sim.torchrl_env import SimulatorBatchEnv

RESIDUAL_FORMAT = "pilerl.residual_actor"
RESIDUAL_VERSION = 1


class ResidualPolicy(nn.Module):
    """The frozen clone's action plus a bounded, learned correction.

    Args:
        clone: the cloned actor's ``SensorPolicy`` (frozen here: eval mode, no gradient).
        hidden: hidden layer widths of the residual MLP.
        scale: the largest correction per control (action units; actions are in [-1, 1]).
    """

    def __init__(self, clone: SensorPolicy, hidden: Sequence[int], *, scale: float) -> None:
        super().__init__()
        self.clone = clone.eval()
        for parameter in self.clone.parameters():
            parameter.requires_grad_(False)
        self.hidden = [int(h) for h in hidden]
        self.scale = float(scale)
        n_controls = clone.config.n_controls
        self.normalizer = InputNormalizer.from_stats(clone.in_keys, clone.config.stats)
        self.residual = MLP(
            in_features=len(clone.in_keys) + n_controls,
            out_features=n_controls,
            num_cells=self.hidden,
            activation_class=nn.Tanh,
        )
        last = self.residual[-1]
        nn.init.zeros_(last.weight)  # r = 0 at the start: the residual actor is the clone
        nn.init.zeros_(last.bias)

    @property
    def in_keys(self) -> list[str]:
        return self.clone.in_keys

    def train(self, mode: bool = True) -> ResidualPolicy:
        super().train(mode)
        self.clone.eval()  # the clone never changes (no dropout either)
        return self

    def forward(self, *readings: torch.Tensor) -> torch.Tensor:
        with torch.no_grad():
            clone_action = self.clone(*readings)[0]
        x = self.normalizer(torch.cat([r.float() for r in readings], dim=-1))
        correction = self.scale * torch.tanh(self.residual(torch.cat([x, clone_action], -1)))
        return (clone_action + correction).clamp(-1.0, 1.0)


def make_residual_actor(
    actor: TensorDictModule | SensorPolicy, hidden: Sequence[int], *, scale: float
) -> TensorDictModule:
    """A residual actor (``TensorDictModule`` writing ``action``) on a cloned actor."""
    policy = ResidualPolicy(actor_policy(actor), hidden, scale=scale)
    return TensorDictModule(policy, in_keys=policy.in_keys, out_keys=[ACTION_KEY])


def residual_policy(actor: nn.Module) -> ResidualPolicy | None:
    """The ``ResidualPolicy`` inside ``actor``, or ``None`` for any other actor."""
    module = actor.module if isinstance(actor, TensorDictModule) else actor
    return module if isinstance(module, ResidualPolicy) else None


@dataclass(frozen=True)
class ResidualWeights:
    """A residual actor as plain data, acting deterministically (evaluation workers).

    Attributes:
        clone: the frozen clone's weights.
        residual: the residual MLP's and its normaliser's ``state_dict``, ``torch.save``d.
        hidden, scale: the residual's settings.
        name: the controller's name in the records.
    """

    clone: ActorWeights
    residual: bytes
    hidden: tuple[int, ...]
    scale: float
    name: str = "residual"

    @classmethod
    def of(cls, actor: nn.Module, *, name: str = "residual") -> ResidualWeights:
        policy = residual_policy(actor)
        if policy is None:
            raise TypeError(f"expected a residual actor, got {type(actor).__name__}")
        own = {k: v for k, v in policy.state_dict().items() if not k.startswith("clone.")}
        buffer = io.BytesIO()
        torch.save({k: v.detach().cpu().clone() for k, v in own.items()}, buffer)
        return cls(
            clone=ActorWeights.of(policy.clone),
            residual=buffer.getvalue(),
            hidden=tuple(policy.hidden),
            scale=policy.scale,
            name=name,
        )

    def build(self) -> TensorDictModule:
        clone = actor_policy(self.clone.build())
        actor = make_residual_actor(clone, self.hidden, scale=self.scale)
        own = torch.load(io.BytesIO(self.residual), weights_only=True)
        actor.module.load_state_dict({**own, **_prefixed(clone.state_dict(), "clone.")})
        return actor.eval()

    def policy(self, env: SimulatorBatchEnv) -> TensorDictModuleBase:
        """The actor, acting on each simulator of ``env`` alone (``RowByRow``)."""
        return RowByRow(self.build())


def _prefixed(state: dict, prefix: str) -> dict:
    return {prefix + k: v for k, v in state.items()}


def save_residual_actor(path: str | Path, actor: nn.Module) -> Path:
    """Write a residual actor: the clone's config and weights and the residual's."""
    policy = residual_policy(actor)
    if policy is None:
        raise TypeError(f"expected a residual actor, got {type(actor).__name__}")
    payload = {
        "format": RESIDUAL_FORMAT,
        "version": RESIDUAL_VERSION,
        "config": json.dumps(policy.clone.config.to_json(), allow_nan=False),
        "residual": json.dumps({"hidden": policy.hidden, "scale": policy.scale}),
        "state_dict": {k: v.detach().cpu().clone() for k, v in policy.state_dict().items()},
    }
    return write_checkpoint(path, payload)


def load_residual_actor(path: str | Path, what: str = "residual actor") -> TensorDictModule:
    """Rebuild a saved residual actor on the CPU, in eval mode."""
    from pilerl.policies.checkpoint import rebuild_policy
    from pilerl.policies.config import ActorConfig

    path = Path(path)
    payload = read_checkpoint(
        path, expected_format=RESIDUAL_FORMAT, version=RESIDUAL_VERSION, what=what
    )
    settings = parse_json(path, payload.get("residual"), "residual")
    if not isinstance(settings, dict) or set(settings) != {"hidden", "scale"}:
        raise CheckpointError(f"{path}: residual settings are {settings!r}")
    state = payload.get("state_dict")
    if not isinstance(state, dict):
        raise CheckpointError(f"{path}: state_dict is not a mapping")
    config = ActorConfig.from_json(parse_json(path, payload.get("config"), "config"))
    clone_state = {k[len("clone.") :]: v for k, v in state.items() if k.startswith("clone.")}
    clone = rebuild_policy(path, config, clone_state, "state_dict (clone)")
    actor = make_residual_actor(clone, settings["hidden"], scale=settings["scale"])
    load_module_state(path, actor.module, state, "state_dict does not fit")
    return actor.eval()


def controller_for(actor: nn.Module | str | Path):
    """The evaluation controller of an actor in memory or saved (residual or cloned).

    A saved file is read by the checked reader (``read_checkpoint``) as a residual actor;
    only a sound file of another format (a cloned actor's checkpoint, checked again by its
    own reader) is handed on as a cloned actor. A damaged file fails here.
    """
    if isinstance(actor, str | Path):
        try:
            probe = "actor checkpoint (residual or cloned)"
            return ResidualWeights.of(load_residual_actor(actor, what=probe))
        except CheckpointFormatError:
            return ActorController(str(actor))
    if residual_policy(actor) is not None:
        return ResidualWeights.of(actor)
    return ActorWeights.of(actor)


def save_any_actor(path: str | Path, actor: nn.Module) -> Path:
    """``save_residual_actor`` for a residual actor, ``save_actor`` for any other."""
    from pilerl.policies import save_actor

    if residual_policy(actor) is not None:
        return save_residual_actor(path, actor)
    return save_actor(path, actor)
