"""pilerl: learn wheel-loader pile loading from demonstrations, then improve it with RL.

Importing pilerl registers every installed simulator plugin with Gymnasium, so that
``gymnasium.make("pilerl/PileLoading-v0", condition="summer")`` works after ``import pilerl``.
"""

from pilerl.sim import register_gymnasium_envs

__version__ = "0.1.0"

register_gymnasium_envs()
