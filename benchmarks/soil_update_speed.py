"""Microseconds per heightfield soil update, in the states a scoop passes through.

    python benchmarks/soil_update_speed.py
    python benchmarks/soil_update_speed.py --simulators 8 --repeats 7

N pile loaders (the five conditions in turn, seeds 0..N-1) are driven by a fixed script
(drive in, then lift and curl) to a state, and their soil models are updated from that
state again and again (the pile, the load and the spill restored before each round):

- ``approach``: right after reset, the bucket before the pile: the intake finds nothing;
- ``digging``: 60-90 control steps in, the bucket in the pile with room left: the intake
  carves the pile every update.

Rows: ``one by one`` (each soil's ``update``, as a simulator's step calls it) and, where
the soil model has ``update_many`` (the batched update tried for issue #18, commit 16b2edf
of branch s25-soilbatch; not in the code since, docs/performance.md), ``together`` (one
call for the N soils). Each figure is the median over ``--repeats`` rounds of the time per
soil update, wall clock and process CPU time, the restore subtracted (timed alone).
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from collections.abc import Callable

os.environ.setdefault("OMP_NUM_THREADS", "1")

import gymnasium as gym  # noqa: E402
from pilerl_pile_loader.open_loop import scripted_action  # noqa: E402

import pilerl  # noqa: E402,F401

CONDITIONS = ("summer", "winter_a", "winter_b", "winter_c", "winter_d")
STATES = {"approach": (0,), "digging": (60, 70, 80, 90)}  # control steps driven, by sim
SOIL_DT_S = 0.025  # the default soil update interval (40 Hz)


def soils_in_state(n: int, steps: tuple[int, ...]) -> list:
    """The soil models of ``n`` simulators, simulator i driven ``steps[i % len]`` steps."""
    soils = []
    for i in range(n):
        env = gym.make(
            "pilerl/PileLoading-v0", condition=CONDITIONS[i % len(CONDITIONS)], sensor_noise=0.0
        ).unwrapped
        env.reset(seed=i)
        for step in range(steps[i % len(steps)]):
            *_, terminated, truncated, _ = env.step(scripted_action(step))
            if terminated or truncated:
                break
        soils.append(env.soil)
    return soils


def per_update_us(
    soils: list, paths: dict[str, Callable[[], None]], rounds: int, updates: int
) -> dict[str, tuple[float, float]]:
    """Each path's (wall, CPU) microseconds per soil update (a path updates all soils once),
    restore subtracted; the paths timed in turn each round, medians over ``rounds``."""
    saved = [(s.heights.copy(), s.bucket_load_kg, s.spilled_kg) for s in soils]

    def restore() -> None:
        for soil, (heights, load, spilled) in zip(soils, saved, strict=True):
            soil.heights[:] = heights
            soil.bucket_load_kg, soil.spilled_kg = load, spilled

    def timed(body: Callable[[], None]) -> tuple[float, float]:
        wall, cpu = time.perf_counter(), time.process_time()
        for _ in range(updates):
            restore()
            body()
        return time.perf_counter() - wall, time.process_time() - cpu

    scale = 1e6 / (updates * len(soils))
    samples: dict[str, list[tuple[float, float]]] = {name: [] for name in paths}
    for _ in range(rounds):
        for name, run in paths.items():
            base_wall, base_cpu = timed(lambda: None)
            wall, cpu = timed(run)
            samples[name].append(((wall - base_wall) * scale, (cpu - base_cpu) * scale))
    restore()
    return {
        name: (statistics.median(w for w, _ in got), statistics.median(c for _, c in got))
        for name, got in samples.items()
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--simulators", type=int, default=8)
    parser.add_argument("--repeats", type=int, default=5, help="rounds; the median is shown")
    parser.add_argument("--updates", type=int, default=300, help="updates of all soils a round")
    args = parser.parse_args()
    print(
        f"{args.simulators} simulators; load average before: "
        + ", ".join(f"{v:.1f}" for v in os.getloadavg())
    )
    print("| state | path | wall us per update | CPU us per update | vs one by one (wall) |")
    print("|---|---|---:|---:|---:|")
    for state, steps in STATES.items():
        soils = soils_in_state(args.simulators, steps)
        paths = {"one by one": lambda soils=soils: [s.update(SOIL_DT_S) for s in soils]}
        update_many = getattr(type(soils[0]), "update_many", None)
        if update_many is not None:
            paths["together"] = lambda soils=soils, many=update_many: many(
                soils, [SOIL_DT_S] * len(soils)
            )
        rows = per_update_us(soils, paths, args.repeats, args.updates)
        alone_wall = rows["one by one"][0]
        for name, (wall, cpu) in rows.items():
            print(f"| {state} | {name} | {wall:.1f} | {cpu:.1f} | {alone_wall / wall:.2f} |")
    print("load average after: " + ", ".join(f"{v:.1f}" for v in os.getloadavg()))


if __name__ == "__main__":
    main()
