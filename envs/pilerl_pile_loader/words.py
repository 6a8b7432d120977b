"""The pile loader's declaration to pilerl: how to build it and its words.

Built from the modules that define the words (``sensors``, ``conditions``, ``task``), so
the declaration cannot drift from the simulator. Those modules are plain dataclasses:
importing this one stays cheap (no MuJoCo) and needs nothing from pilerl.
"""

from __future__ import annotations

from .conditions import CONDITIONS, HELD_OUT
from .sensors import CONTROL_NAMES, SENSORS
from .task import RewardWeights, reward_parts

WINTER = ("winter_a", "winter_b", "winter_c", "winter_d")  # the paper's winter test days A-D

PLUGIN = {
    "name": "pile_loader",
    "gym_id": "pilerl/PileLoading-v0",
    "entry_point": "pilerl_pile_loader.env:PileLoadingEnv",
    "description": "MuJoCo wheel loader (Avant 635 class), heightfield or particle pile",
    "sensors": {s.name: {"unit": s.unit, "low": s.low, "high": s.high} for s in SENSORS},
    "controls": list(CONTROL_NAMES),
    "conditions": {name: c.description for name, c in (CONDITIONS | HELD_OUT).items()},
    "condition_groups": {"winter": list(WINTER), "held_out": list(HELD_OUT)},
    "reward_parts": list(
        reward_parts(
            RewardWeights(),
            fill_gain=0.0,
            spilled_fraction_gain=0.0,
            seconds=0.0,
            work_kj=0.0,
            succeeded=False,
        )
    ),
    "success_key": "success",
    "fill_key": "fill_fraction",
    "options": "pilerl_pile_loader.options:PileLoaderOptions",
    "scripted_expert": "pilerl_pile_loader.operator:make_expert",
    "renders": True,
}
