"""The pile loader's declaration to pilerl: how to build it and its words.

Built from the modules that define the words (``sensors``, ``conditions``, ``task``), so
the declaration cannot drift from the simulator. Those modules are plain dataclasses:
importing this one stays cheap (no MuJoCo) and needs nothing from pilerl.
"""

from __future__ import annotations

from .conditions import CONDITIONS, HELD_OUT
from .failures import EPISODE_INFO, FAILURE_MODES
from .sensors import CONTROL_NAMES, SENSORS
from .task import RewardWeights, reward_parts

WINTER = ("winter_a", "winter_b", "winter_c", "winter_d")  # the paper's winter test days A-D
# how to read a scoop report against the paper (recipes/scoop.py)
REPORT_NOTES = (
    "- The paper's winter failure: wheel slip on ice caps the drive pressure p_d, so an",
    "  operator (or a controller) that waits for p_d to rise before lifting never lifts.",
    "  Compare `peak_drive_pressure_mpa` between summer and the icy conditions (winter_b,",
    "  winter_c): summer reaches the HST relief pressure (25 MPa), ice does not.",
    "- The scripted operator does not wait for that rise: it lifts once the machine stops",
    "  pushing forward (p_d held at the relief, or flat with the wheels turning on ice),",
    "  so on ice it lifts, from a shallower cut (`max_cutting_depth_m`, `fill_fraction`).",
    "- The telescope pressure p_t still rises on ice as the bucket penetrates",
    "  (`peak_telescope_pressure_mpa`), which is why the paper found p_t essential.",
    "- The simulator's numbers are a model's (docs/machine_model.md lists every",
    "  assumption); they are not measurements of the paper's machine.",
)

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
    # 1 since session 33: the stall cue and the second push are the default (0: the rise cue)
    "expert_revision": 1,
    "renders": True,
    "episode_info": dict(EPISODE_INFO),
    "failure_modes": list(FAILURE_MODES),
    "episode_columns": "pilerl_pile_loader.failures:episode_columns",
    "summary_columns": "pilerl_pile_loader.failures:summary_columns",
    # fine-tuning's default mixture: the four winter days and summer, equally likely
    "curriculum": {"winter": 1.0, "summer": 1.0},
    "example_conditions": ["summer", "winter_c"],
    "report_notes": list(REPORT_NOTES),
}
