"""``last.ckpt``: everything a fine-tuning run needs to continue exactly, in one verified file.

Written with ``pilerl.policies.checkpoint_file.write_checkpoint`` (atomic ``torch.save``
of tensors and plain values with a SHA-256) and read with ``read_checkpoint`` (zip CRCs,
``torch.load(weights_only=True)``, content checks, digest): no pickled object can run on
resume, and a damaged file is refused with ``CheckpointError``. It holds:

| key | what |
|---|---|
| ``progress`` | the run's bookkeeping (frames, batches, evaluations...) as JSON |
| ``learner`` | the learner's ``state_dict()``: modules, optimisers, generators, replay |
| ``rng`` | torch's, NumPy's and Python's global generator states, as tensors |

A kill at any moment leaves the previous ``last.ckpt`` or the new one (the write is a
rename); ``remove_partial_writes`` removes the temporary file a kill may leave.
"""

from __future__ import annotations

import json
import random
from pathlib import Path

import numpy as np
import torch

from pilerl.policies.checkpoint_file import CheckpointError, parse_json, read_checkpoint
from pilerl.policies.checkpoint_file import write_checkpoint as _write

RUN_FORMAT = "pilerl.finetune_run"
RUN_VERSION = 1


def save_run(path: Path, *, progress: dict, learner_state: dict) -> None:
    """Write ``last.ckpt`` atomically."""
    _write(
        path,
        {
            "format": RUN_FORMAT,
            "version": RUN_VERSION,
            "progress": json.dumps(progress, allow_nan=False),
            "learner": learner_state,
            "rng": global_rng_state(),
        },
    )


def load_run(path: Path) -> tuple[dict, dict, dict]:
    """(progress, learner state, RNG state) of a verified ``last.ckpt``.

    A file in another format (e.g. the TorchRL ``Checkpoint`` archive that pilerl wrote
    before) is refused with a ``CheckpointError`` naming it.
    """
    payload = read_checkpoint(
        path, expected_format=RUN_FORMAT, version=RUN_VERSION, what="pilerl fine-tuning checkpoint"
    )
    progress = parse_json(path, payload.get("progress"), "progress")
    learner, rng = payload.get("learner"), payload.get("rng")
    if not isinstance(progress, dict) or not isinstance(learner, dict) or not isinstance(rng, dict):
        raise CheckpointError(f"{path}: progress, learner or rng missing")
    return progress, learner, rng


def global_rng_state() -> dict:
    """torch's, NumPy's and Python's global generator states, as tensors and numbers."""
    kind, keys, position, has_gauss, gauss = np.random.get_state()  # noqa: NPY002 - the global one
    version, python_state, python_gauss = random.getstate()
    return {
        "torch": torch.get_rng_state(),
        "numpy": {
            "kind": str(kind),
            "keys": torch.from_numpy(keys.astype(np.int64)),
            "position": int(position),
            "has_gauss": int(has_gauss),
            "gauss": float(gauss),
        },
        "python": {
            "version": int(version),
            "state": torch.tensor(python_state, dtype=torch.int64),
            "gauss": python_gauss,
        },
    }


def set_global_rng_state(path: Path, state: dict) -> None:
    """Restore ``global_rng_state()``; anything that is not such a state is refused."""
    try:
        torch_state, numpy_state, python_state = state["torch"], state["numpy"], state["python"]
        if not isinstance(torch_state, torch.Tensor) or (
            torch_state.dtype != torch.uint8 or torch_state.shape != torch.get_rng_state().shape
        ):
            raise TypeError("torch state is not the generator's byte tensor")
        keys = numpy_state["keys"]
        words = python_state["state"]
        if not (isinstance(keys, torch.Tensor) and isinstance(words, torch.Tensor)):
            raise TypeError("NumPy or Python state is not a tensor")
        numpy_tuple = (
            numpy_state["kind"],
            keys.numpy().astype(np.uint32),
            numpy_state["position"],
            numpy_state["has_gauss"],
            numpy_state["gauss"],
        )
        python_tuple = (
            python_state["version"],
            tuple(int(w) for w in words.tolist()),
            python_state["gauss"],
        )
        np.random.RandomState().set_state(numpy_tuple)  # validate before changing anything
        random.Random().setstate(python_tuple)
    except (KeyError, TypeError, ValueError, OverflowError, AttributeError) as error:
        raise CheckpointError(f"{path}: rng is not a saved generator state ({error})") from None
    torch.set_rng_state(torch_state)
    np.random.set_state(numpy_tuple)  # noqa: NPY002 - the global one
    random.setstate(python_tuple)


def remove_partial_writes(run_dir: Path, names: list[str]) -> list[Path]:
    """Delete the temporary files a kill during an atomic write of ``names`` left behind.

    ``pilerl.io.atomic_path`` writes ``.<stem>.<random><suffix>`` beside the target and
    renames it; a SIGKILL before the rename leaves it. Only this run's own files are
    written in ``run_dir``, so such a file is never another writer's work in progress.
    """
    removed = []
    for name in names:
        target = Path(name)
        for leftover in run_dir.glob(f".{target.stem}.*{target.suffix}"):
            if leftover.is_file():
                leftover.unlink(missing_ok=True)
                removed.append(leftover)
    return removed
