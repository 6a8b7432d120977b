"""The default pilerl simulator plugin: a MuJoCo wheel loader scooping from a pile.

pilerl finds this plugin through the ``pilerl.simulators`` entry point, which names
``PLUGIN`` (``words.py``): a plain mapping, so the plugin depends on nothing in pilerl.
Importing this package is cheap: the MuJoCo model is built only when an environment is
made.

Rendering is headless by default (``MUJOCO_GL=egl``, set here before MuJoCo is imported
unless the user chose a backend), so ``render_mode="rgb_array"`` works without a display.
"""

import os

os.environ.setdefault("MUJOCO_GL", "egl")

from .words import PLUGIN  # noqa: E402  (after the GL choice, though it imports no MuJoCo)

__all__ = ["PLUGIN"]
