"""Process-level settings every recipe applies first."""

from __future__ import annotations

import os

import torch

DEFAULT_THREADS = 1  # the target machines have 2 cores: parallelise with processes


def limit_threads(threads: int = DEFAULT_THREADS) -> None:
    """One intra-op thread (PyTorch, OpenMP, BLAS) unless the user chose otherwise.

    Measured on the 2-core machines: PyTorch's default thread count made a small MLP's
    forward pass 57x slower when the other core was busy.
    """
    for variable in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
        os.environ.setdefault(variable, str(threads))
    torch.set_num_threads(int(os.environ["OMP_NUM_THREADS"]))
