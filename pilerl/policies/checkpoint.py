"""Saving and loading actors: nothing loaded can run code, allocate without bound or differ.

A checkpoint is one file written by ``pilerl.policies.checkpoint_file.write_checkpoint``
(``torch.save`` of tensors and plain values, with a SHA-256 of the content) and read by
``read_checkpoint`` (zip CRCs, ``torch.load(weights_only=True)``, content checks, the
digest). It holds:

| key | meaning |
|---|---|
| ``format`` | ``"pilerl.actor"`` |
| ``version`` | checkpoint format version (2; version 1, without digest, is still read) |
| ``config`` | ``ActorConfig`` as JSON: controller, sensors, attention sensors, stats |
| ``state_dict`` | the ``SensorPolicy``'s tensors: normaliser buffers, weights or trees |
| ``sha256`` | SHA-256 of everything above |

Loading checks the config against ``MAX_SENSORS``, ``MAX_CONTROLS``, ``MAX_HIDDEN_LAYERS``
and ``MAX_LAYER_WIDTH``, then builds the architecture on the ``meta`` device (no memory)
and checks that the tensors present have exactly its names and shapes, and only then
builds it for real and loads the weights: a small file cannot make the loader allocate
more than the tensors it holds. A random forest's trees are checked as a tree structure
(``pilerl.policies.random_forest``). Building does not draw from torch's global random
generator. Writes are atomic. Every failure is a ``CheckpointError`` naming the file.
"""

from __future__ import annotations

import json
import logging
import math
from pathlib import Path

import torch
from tensordict.nn import TensorDictModule

from pilerl.runs import current_provenance

from .actors import actor_policy, policy_actor
from .checkpoint_file import (
    CheckpointError,
    load_module_state,
    parse_json,
    read_checkpoint,
    write_checkpoint,
)
from .config import ActorConfig
from .policy import SensorPolicy
from .registry import build_policy

log = logging.getLogger(__name__)

CHECKPOINT_FORMAT = "pilerl.actor"
CHECKPOINT_VERSION = 2
LEGACY_VERSIONS = (1,)  # written without a digest: only the zip CRCs vouch for them
MAX_SENSORS = 256  # sensors an actor reads (the pile loader has 9)
MAX_CONTROLS = 64  # size of ``action`` (the pile loader has 3)
MAX_HIDDEN_LAYERS = 16  # layers in a ``hidden`` / ``attention_hidden`` option
MAX_LAYER_WIDTH = 65_536  # units in one hidden layer
WIDTH_OPTIONS = ("hidden", "attention_hidden")
INFINITE_ENTRIES = ("state_dict/controller.threshold",)  # a forest's leaves split at +inf

__all__ = [
    "CHECKPOINT_FORMAT",
    "CHECKPOINT_VERSION",
    "CheckpointError",
    "actor_config_from_json",
    "load_actor",
    "rebuild_policy",
    "save_actor",
]


def _may_be_infinite(where: str) -> bool:
    return where in INFINITE_ENTRIES


def save_actor(path: str | Path, actor: TensorDictModule | SensorPolicy) -> Path:
    """Write ``actor`` (from ``make_actor`` / ``load_actor``, or its ``SensorPolicy``)."""
    policy = actor_policy(actor)
    payload = {
        "format": CHECKPOINT_FORMAT,
        "version": CHECKPOINT_VERSION,
        "config": json.dumps(policy.config.to_json(), allow_nan=False),
        "state_dict": {k: v.detach().cpu().clone() for k, v in policy.state_dict().items()},
        # where it came from: package versions, git commit, the run's datasets, control rate
        "provenance": json.dumps(current_provenance(), default=str),
    }
    return write_checkpoint(path, payload, allow_infinite=_may_be_infinite)


def _read_actor_payload(path: Path) -> dict:
    """The verified payload of an actor checkpoint (see ``checkpoint_file``)."""
    return read_checkpoint(
        path,
        expected_format=CHECKPOINT_FORMAT,
        version=CHECKPOINT_VERSION,
        legacy_versions=LEGACY_VERSIONS,
        allow_infinite=_may_be_infinite,
        what="pilerl actor checkpoint",
    )


def read_provenance(path: str | Path) -> dict:
    """The provenance saved in an actor checkpoint or in an ONNX export's metadata
    (``{}`` for files from before it)."""
    path = Path(path)
    if path.suffix == ".onnx":
        import onnx

        try:
            metadata = onnx.load(str(path), load_external_data=False).metadata_props
        except Exception as error:  # noqa: BLE001 - onnx raises several kinds; name the file
            raise CheckpointError(f"{path}: not a readable ONNX model ({error})") from None
        text = next((p.value for p in metadata if p.key == "pilerl.provenance"), None)
        provenance = {} if text is None else parse_json(path, text, "pilerl.provenance")
        if not isinstance(provenance, dict):
            raise CheckpointError(f"{path}: pilerl.provenance is not a JSON object")
        return provenance
    payload = _read_actor_payload(path)
    if "provenance" not in payload:
        return {}
    provenance = parse_json(path, payload["provenance"], "provenance")
    if not isinstance(provenance, dict):
        raise CheckpointError(f"{path}: provenance is not a JSON object")
    return provenance


def warn_if_other_control_rate(path: str | Path, control_hz: float) -> bool:
    """Warn when a controller runs at another rate than its training data's; True if so.

    A controller cloned at 20 Hz reads sensor changes per step and acts per step: at 3 Hz
    its deltas mean something else. The training rate comes from the checkpoint's
    provenance (``control_hz``: the training data's rate, or the fine-tuning env's).
    """
    trained = read_provenance(path).get("control_hz")
    rates = trained if isinstance(trained, list) else [trained]
    rates = [float(r) for r in rates if isinstance(r, int | float)]
    if not rates or any(math.isclose(r, control_hz, rel_tol=0.01) for r in rates):
        return False
    log.warning(
        "%s was trained at %s Hz but runs at %g Hz here: its actions are per-step deltas, "
        "so expect different behaviour (set env.control_hz to match)",
        path,
        "/".join(f"{r:g}" for r in rates),
        control_hz,
    )
    return True


def load_actor(path: str | Path) -> TensorDictModule:
    """Rebuild a saved actor on the CPU, in eval mode (``.train()`` it to fine-tune)."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such actor checkpoint")
    payload = _read_actor_payload(path)
    config = actor_config_from_json(path, payload.get("config"), "config")
    policy = rebuild_policy(path, config, payload.get("state_dict"), "state_dict")
    return policy_actor(policy).eval()


def actor_config_from_json(path: Path, text: object, field: str) -> ActorConfig:
    """The ``ActorConfig`` saved as JSON text, checked against the bounds first."""
    data = parse_json(path, text, field)
    if not isinstance(data, dict):
        raise CheckpointError(f"{path}: {field} is not a JSON object")
    _check_bounds(path, data, field)
    try:
        return ActorConfig.from_json(data)
    except (KeyError, TypeError, ValueError, AttributeError) as error:
        raise CheckpointError(f"{path}: bad actor {field} ({error})") from None


def rebuild_policy(path: Path, config: ActorConfig, state_dict: object, field: str) -> SensorPolicy:
    """The ``SensorPolicy`` of ``config`` holding ``state_dict``'s tensors.

    The architecture is first built on the ``meta`` device and compared with the tensors
    present (names and shapes, strictly), so a config declaring a huge network fails
    before anything is allocated.
    """
    if not isinstance(state_dict, dict) or not all(
        isinstance(k, str) and isinstance(v, torch.Tensor) for k, v in state_dict.items()
    ):
        raise CheckpointError(f"{path}: {field} is not a mapping of names to tensors")
    try:
        with torch.device("meta"):
            skeleton = build_policy(config)
    except (KeyError, TypeError, ValueError, RuntimeError) as error:
        raise CheckpointError(
            f"{path}: cannot build a {config.controller!r} actor from its config ({error})"
        ) from None
    what = f"{field}: the weights do not fit a {config.controller!r} actor"
    load_module_state(path, skeleton, state_dict, what, assign=True)  # names, shapes, trees
    del skeleton
    with torch.random.fork_rng(devices=[]):  # the weights are overwritten: draw nothing
        policy = build_policy(config)
    load_module_state(path, policy, state_dict, what)
    return policy


def _check_bounds(path: Path, data: dict, field: str) -> None:
    """Sizes that decide how much a rebuilt actor allocates, against sane bounds."""
    for key in ("sensors", "attention_sensors"):
        names = data.get(key)
        if isinstance(names, list) and len(names) > MAX_SENSORS:
            raise CheckpointError(
                f"{path}: {field}.{key} lists {len(names)} sensors (at most {MAX_SENSORS})"
            )
    n_controls = data.get("n_controls")
    if n_controls is not None and not (
        isinstance(n_controls, int) and 1 <= n_controls <= MAX_CONTROLS
    ):
        raise CheckpointError(f"{path}: {field}.n_controls is {n_controls!r} (1 to {MAX_CONTROLS})")
    options = data.get("options", {})
    if not isinstance(options, dict):
        raise CheckpointError(f"{path}: {field}.options is not a mapping")
    for name in WIDTH_OPTIONS:
        if name not in options:
            continue
        value = options[name]
        widths = value if isinstance(value, list) else [value]
        if len(widths) > MAX_HIDDEN_LAYERS or not all(
            isinstance(w, int) and not isinstance(w, bool) and 1 <= w <= MAX_LAYER_WIDTH
            for w in widths
        ):
            raise CheckpointError(
                f"{path}: {field}.options.{name} = {str(value)[:80]}: at most "
                f"{MAX_HIDDEN_LAYERS} layers of 1 to {MAX_LAYER_WIDTH} units"
            )
