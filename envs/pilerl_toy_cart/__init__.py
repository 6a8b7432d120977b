"""A tiny second simulator plugin: proves that pilerl finds simulators only by name.

A 1-D cart that must stop at a target; pure NumPy, no MuJoCo. Useful as a fast stand-in
in tests of code that takes any simulator.
"""

PLUGIN = {
    "name": "toy_cart",
    "gym_id": "pilerl/ToyCart-v0",
    "entry_point": "pilerl_toy_cart.env:ToyCartEnv",
    "description": "1-D cart stopping at a target (test plugin, NumPy only)",
}
