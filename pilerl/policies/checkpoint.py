"""Saving and loading actors without pickle code execution.

A checkpoint is one file written with ``torch.save`` and read with
``torch.load(weights_only=True)``, whose restricted unpickler accepts only tensors and
plain containers (no code runs on load). It holds:

| key | meaning |
|---|---|
| ``format`` | ``"pilerl.actor"`` |
| ``version`` | checkpoint format version (1) |
| ``config`` | ``ActorConfig`` as JSON: controller, sensors, attention sensors, stats |
| ``state_dict`` | the ``SensorPolicy``'s tensors: normaliser buffers, weights or trees |

The architecture is rebuilt from ``config`` and the weights loaded strictly. Writes are
atomic (``pilerl.io.atomic_path``).
"""

from __future__ import annotations

import json
from pathlib import Path

import torch
from tensordict.nn import TensorDictModule

from pilerl.io import atomic_path

from .actors import actor_policy, policy_actor
from .config import ActorConfig
from .policy import SensorPolicy
from .registry import build_policy

CHECKPOINT_FORMAT = "pilerl.actor"
CHECKPOINT_VERSION = 1


class CheckpointError(ValueError):
    """A file is not a readable pilerl actor checkpoint; the message says why."""


def save_actor(path: str | Path, actor: TensorDictModule | SensorPolicy) -> Path:
    """Write ``actor`` (from ``make_actor`` / ``load_actor``, or its ``SensorPolicy``)."""
    policy = actor_policy(actor)
    payload = {
        "format": CHECKPOINT_FORMAT,
        "version": CHECKPOINT_VERSION,
        "config": json.dumps(policy.config.to_json(), allow_nan=False),
        "state_dict": {k: v.detach().cpu().clone() for k, v in policy.state_dict().items()},
    }
    path = Path(path)
    with atomic_path(path) as tmp:
        torch.save(payload, tmp)
    return path


def load_actor(path: str | Path) -> TensorDictModule:
    """Rebuild a saved actor on the CPU, in eval mode (``.train()`` it to fine-tune)."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such actor checkpoint")
    try:
        payload = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as error:  # noqa: BLE001 - torch raises many kinds; name the file
        raise CheckpointError(
            f"{path}: not a readable pilerl actor checkpoint ({type(error).__name__}: "
            f"{str(error).splitlines()[0] if str(error) else ''})"
        ) from error
    if not isinstance(payload, dict) or payload.get("format") != CHECKPOINT_FORMAT:
        found = payload.get("format") if isinstance(payload, dict) else type(payload).__name__
        raise CheckpointError(
            f"{path}: not a pilerl actor checkpoint (format {found!r}, expected "
            f"{CHECKPOINT_FORMAT!r})"
        )
    version = payload.get("version")
    if version != CHECKPOINT_VERSION:
        raise CheckpointError(
            f"{path}: checkpoint version {version!r}, this pilerl reads {CHECKPOINT_VERSION}"
        )
    try:
        config = ActorConfig.from_json(json.loads(payload["config"]))
    except (KeyError, TypeError, ValueError) as error:
        raise CheckpointError(f"{path}: bad actor config ({error})") from error
    state_dict = payload.get("state_dict")
    if not isinstance(state_dict, dict):
        raise CheckpointError(f"{path}: no state_dict")
    policy = build_policy(config)
    try:
        policy.load_state_dict(state_dict, strict=True)
    except RuntimeError as error:
        raise CheckpointError(
            f"{path}: weights do not fit a {config.controller!r} actor ({error})"
        ) from error
    return policy_actor(policy).eval()
