"""pilerl: learn wheel-loader pile loading from demonstrations, then improve it with RL.

Importing pilerl first chooses MuJoCo's offscreen rendering backend (EGL or OSMesa when
there is no display; see :mod:`pilerl.rendering`), then registers every installed
simulator plugin with Gymnasium, so that
``gymnasium.make("pilerl/PileLoading-v0", condition="summer")`` works after ``import pilerl``.
"""

from pilerl.rendering import choose_backend

choose_backend()  # before anything below imports MuJoCo (TorchRL's envs do)

from pilerl.sim import register_gymnasium_envs  # noqa: E402

__version__ = "0.1.0"

register_gymnasium_envs()
