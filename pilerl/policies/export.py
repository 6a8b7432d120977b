"""Export a trained neural controller for deployment: ONNX and ``torch.export``.

The exported graph takes one input per sensor, named like the observation keys
(``boom_angle`` ...; shape [batch, 1], raw physical units), and returns the actor's
outputs by name (``action``, ``action_loc`` and the attention masks). Input normalisation
is inside the graph. ``export_onnx`` checks the file with onnxruntime against PyTorch
before returning.

    python -m pilerl.policies.export outputs/train_bc/.../best.pt --onnx dannet.onnx
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
import torch
from tensordict.nn import TensorDictModule

from pilerl.io import atomic_path

from .actors import actor_policy, example_readings
from .checkpoint import load_actor, read_provenance
from .policy import SensorPolicy
from .random_forest import RandomForestController

TOLERANCE = 1e-5  # max |onnxruntime - PyTorch| on the action
CHECK_ROWS = 64


class ExportError(ValueError):
    """The controller cannot be exported, or the export does not match PyTorch."""


def _exportable(actor: TensorDictModule | SensorPolicy) -> SensorPolicy:
    policy = actor_policy(actor)
    if isinstance(policy.controller, RandomForestController):
        raise ExportError(
            "the random forest is not exported (its trees are data-dependent "
            "gathers); export a neural controller"
        )
    return policy.eval()


def _dynamic_batch(policy: SensorPolicy) -> tuple:
    batch = torch.export.Dim("batch")
    return (tuple({0: batch} for _ in policy.in_keys),)


def export_program(actor: TensorDictModule | SensorPolicy, path: str | Path) -> Path:
    """Save a ``torch.export`` program (``.pt2``; load with ``torch.export.load``)."""
    policy = _exportable(actor)
    program = torch.export.export(
        policy, example_readings(policy, 4), dynamic_shapes=_dynamic_batch(policy)
    )
    path = Path(path)
    with atomic_path(path) as tmp:
        torch.export.save(program, tmp)
    return path


def export_onnx(
    actor: TensorDictModule | SensorPolicy, path: str | Path, *, provenance: dict | None = None
) -> tuple[Path, float]:
    """Write one self-contained ONNX file and check it; returns (path, max action error).

    The weights are stored inside the file (these controllers are far below ONNX's 2 GB
    limit), so copying the ``.onnx`` alone is enough. The check loads the written bytes in
    onnxruntime, away from the directory it was written in, and compares its actions with
    PyTorch's; nothing is written when it differs. ``provenance`` (e.g. the checkpoint's:
    package versions, git commit, training rate) is kept in the model's metadata as JSON
    under ``pilerl.provenance``.
    """
    import onnx
    import onnxruntime
    from onnx.external_data_helper import uses_external_data

    policy = _exportable(actor)
    path = Path(path)
    with atomic_path(path) as tmp:
        torch.onnx.export(
            policy,
            example_readings(policy, 4),
            str(tmp),
            input_names=policy.in_keys,
            output_names=policy.out_keys,
            dynamic_shapes=_dynamic_batch(policy),
            dynamo=True,
            external_data=False,
            verbose=False,
        )
        model = onnx.load(str(tmp), load_external_data=False)
        external = [t.name for t in model.graph.initializer if uses_external_data(t)]
        if external:
            raise ExportError(f"{path}: weights {external[:3]} were written outside the file")
        if provenance is not None:
            entry = model.metadata_props.add()
            entry.key, entry.value = "pilerl.provenance", json.dumps(provenance, default=str)
            onnx.save(model, str(tmp))
        session = onnxruntime.InferenceSession(tmp.read_bytes())  # the bytes alone
        readings = example_readings(policy, CHECK_ROWS, seed=1)
        feeds = {key: r.numpy() for key, r in zip(policy.in_keys, readings, strict=True)}
        onnx_action = session.run(["action"], feeds)[0]
        with torch.no_grad():
            torch_action = policy(*readings)[0].numpy()
        error = float(np.abs(onnx_action - torch_action).max())
        if not error <= TOLERANCE:
            raise ExportError(
                f"{path}: onnxruntime differs from PyTorch by {error:.2e} "
                f"(> {TOLERANCE:.0e}); nothing written"
            )
    return path, error


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="Export a saved actor (best.pt).")
    parser.add_argument("checkpoint")
    parser.add_argument("--onnx", help="write an ONNX model here")
    parser.add_argument("--pt2", help="write a torch.export program here")
    args = parser.parse_args(argv)
    if not (args.onnx or args.pt2):
        parser.error("give --onnx and/or --pt2")
    try:
        actor = load_actor(args.checkpoint)
        if args.onnx:
            provenance = read_provenance(args.checkpoint)
            path, error = export_onnx(actor, args.onnx, provenance=provenance)
            print(f"{path}: checked with onnxruntime, max action error {error:.1e}")
        if args.pt2:
            print(f"{export_program(actor, args.pt2)}: torch.export program")
    except (ValueError, FileNotFoundError) as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
