"""Test-wide settings: headless rendering and one intra-op thread (2-core machines)."""

import os

os.environ.setdefault("MUJOCO_GL", "egl")

import torch  # noqa: E402

torch.set_num_threads(1)
