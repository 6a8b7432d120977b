"""A tiny second simulator plugin: proves that pilerl finds simulators only by name.

A 1-D cart that must stop at a target; pure NumPy, no MuJoCo. It declares every word a
simulator declares (sensors, controls, conditions and a group, reward parts, options,
a scripted expert, the ``info`` it reports, its failure modes and the rule naming them),
so every recipe runs on it (``env=toy_cart``) in seconds: a fast stand-in in tests of
code that takes any simulator. The rest keep their defaults: fine-tuning's default
curriculum is every condition, ``recipes/scoop.py`` shows the first one.
"""

PLUGIN = {
    "name": "toy_cart",
    "gym_id": "pilerl/ToyCart-v0",
    "entry_point": "pilerl_toy_cart.env:ToyCartEnv",
    "description": "1-D cart stopping at a target (test plugin, NumPy only)",
    "sensors": {
        "position": {"unit": "m", "low": -10.0, "high": 10.0},
        "velocity": {"unit": "m/s", "low": -10.0, "high": 10.0},
    },
    "controls": ["force"],
    "conditions": {
        "nominal": "a 10 kg cart on a level track",
        "heavy": "a 25 kg cart",
        "headwind": "a 10 kg cart against a 4 N headwind",
    },
    "condition_groups": {"hard": ["heavy", "headwind"]},
    "reward_parts": ["reward_distance", "reward_success"],
    "success_key": "success",
    "episode_info": {"error_m": "m"},
    "failure_modes": ["overshot", "fell_short"],
    "episode_columns": "pilerl_toy_cart.failures:episode_columns",
    "options": "pilerl_toy_cart.options:ToyCartOptions",
    "scripted_expert": "pilerl_toy_cart.expert:make_expert",
}
