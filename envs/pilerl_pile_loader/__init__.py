"""The default pilerl simulator plugin: a MuJoCo wheel loader scooping from a pile.

pilerl finds this plugin through the ``pilerl.simulators`` entry point, which names
``PLUGIN``: a plain mapping, so the plugin depends on nothing in pilerl. Importing this
package is cheap: the MuJoCo model is built only when an environment is made.

Rendering is headless by default (``MUJOCO_GL=egl``, set here before MuJoCo is imported
unless the user chose a backend), so ``render_mode="rgb_array"`` works without a display.
"""

import os

os.environ.setdefault("MUJOCO_GL", "egl")

PLUGIN = {
    "name": "pile_loader",
    "gym_id": "pilerl/PileLoading-v0",
    "entry_point": "pilerl_pile_loader.env:PileLoadingEnv",
    "description": "MuJoCo wheel loader (Avant 635 class), heightfield or particle pile",
}
