"""Does the pile loader need 500 Hz physics? Seeded expert scoops at several physics rates.

The default model steps MuJoCo at 500 Hz (``physics_hz``, and the env refuses less). Halving
it would halve the simulator's cost, so this checks what the physics needs: the nominal
scripted expert scoops the same seeded starts (same conditions, same sensor noise draws)
at each rate, and the table compares what a scoop produces against the finest rate:

- fill: the final bucket fill fraction; success: the scoop's success flag;
- peak drive / telescope / boom pressure [MPa]: the forces the machine felt;
- seconds: the episode's simulated length.

Rates below 500 Hz are built here by lifting the env's floor for this script only
(``--rates 1000 500 250 200``); 250 Hz at 20 Hz control gives 12 physics steps per control
step (a 0.048 s control period), 200 Hz gives 10 (0.05 s, as the default).

    python benchmarks/physics_rate.py                      # 2 conditions x 6 seeds
    python benchmarks/physics_rate.py --seeds 3 --rates 1000 500 250
"""

from __future__ import annotations

import argparse
import math
import os
from collections.abc import Sequence

os.environ.setdefault("OMP_NUM_THREADS", "1")

import gymnasium as gym  # noqa: E402
import numpy as np  # noqa: E402
import pilerl_pile_loader.env as pile_loader_env  # noqa: E402
from pilerl_pile_loader.operator import make_expert  # noqa: E402

import pilerl  # noqa: E402,F401  (registers pilerl/PileLoading-v0)

PRESSURES = ("drive_pressure", "telescope_pressure", "boom_pressure")
MAX_SECONDS = 40.0


def allow_rate_below_floor() -> None:
    """Let this script build the env below its 500 Hz floor (the check stays for users)."""
    check = pile_loader_env._check_rates

    def relaxed(control_hz: float, physics_hz: float, soil_hz: float) -> None:
        check(control_hz, max(physics_hz, 500.0), soil_hz)
        if not (math.isfinite(physics_hz) and physics_hz >= control_hz):
            raise ValueError(f"physics_hz: must be >= control_hz, got {physics_hz}")

    pile_loader_env._check_rates = relaxed


def scoop(condition: str, seed: int, physics_hz: float) -> dict[str, float]:
    """One expert scoop; what it produced."""
    env = gym.make("pilerl/PileLoading-v0", condition=condition, physics_hz=physics_hz)
    obs, info = env.reset(seed=seed)
    expert = make_expert(dt=env.unwrapped.dt)
    peaks = dict.fromkeys(PRESSURES, 0.0)
    while True:
        obs, _, terminated, truncated, info = env.step(expert.act(obs))
        for name in PRESSURES:
            peaks[name] = max(peaks[name], float(obs[name][0]))
        if terminated or truncated or info["elapsed_s"] >= MAX_SECONDS:
            break
    env.close()
    return {
        "fill": float(info["fill_fraction"]),
        "success": float(info["success"]),
        **{f"peak {name} MPa": value for name, value in peaks.items()},
        "seconds": float(info["elapsed_s"]),
    }


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rates", type=float, nargs="+", default=[1000.0, 500.0, 250.0, 200.0])
    parser.add_argument("--conditions", nargs="+", default=["summer", "winter_c"])
    parser.add_argument("--seeds", type=int, default=6, help="seeded starts per condition")
    args = parser.parse_args(argv)
    allow_rate_below_floor()
    reference = max(args.rates)
    runs = {
        rate: [scoop(c, seed, rate) for c in args.conditions for seed in range(args.seeds)]
        for rate in args.rates
    }
    keys = list(runs[reference][0])
    n = len(runs[reference])
    print(
        f"{n} expert scoops ({args.seeds} seeds x {args.conditions}); reference "
        f"{reference:g} Hz. Each cell: mean over scoops [mean |difference| from the reference]"
    )
    print("| physics Hz | " + " | ".join(keys) + " | same success |")
    print("|---:|" + "---:|" * len(keys) + "---:|")
    for rate in args.rates:
        cells = []
        for key in keys:
            values = np.array([r[key] for r in runs[rate]])
            ref = np.array([r[key] for r in runs[reference]])
            cells.append(f"{values.mean():.3f} [{np.abs(values - ref).mean():.3f}]")
        pairs = zip(runs[rate], runs[reference], strict=True)
        same = sum(r["success"] == s["success"] for r, s in pairs)
        print(f"| {rate:g} | " + " | ".join(cells) + f" | {same}/{n} |")


if __name__ == "__main__":
    main()
