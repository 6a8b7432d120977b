"""How the particle pile's fill converges with resolution, and what each resolution costs.

For each resolution (grain diameters across the bucket mouth), in one run and one thread:
N seeded summer scoops by the scripted expert (its nominal, deterministic style) on the
particle pile, and the same N seeded starts on the heightfield pile. Per row:

- ``grain mm``: grain diameter; ``mouth/d``: bucket mouth (cutting edge to lip) over it;
- ``grains``: moving grains + static core spheres;
- ``fill p`` / ``fill hf``: mean final fill fraction on particles / on the heightfield;
  ``p/hf``: their ratio;
- ``hf mouth``: the part of the heightfield's fill that entered while the bucket mouth was
  below the undisturbed pile surface (the rest entered through the bucket's plates: the
  heightfield takes every column under the bucket's inside, whichever way it came in);
  ``p/mouth``: particles over that part;
- ``packed``: the fill of a bucket packed as densely as the pile at this resolution (the
  most a struck bucket reads; grains along the plates leave gaps);
- ``rt p``: real-time factor on particles, simulated seconds per CPU second of this
  one-thread process (whole episodes, approach included; CPU time, so that other work on
  a shared machine does not count); ``rt hf``: the same on the heightfield in this run;
  ``rt p/hf``: their ratio; ``wall p``: the wall-clock real-time factor, for reference;
- ``build s``: CPU time to build the particle env (lattice, compile, settle).

    python benchmarks/particle_resolution.py                       # 4, 6, 8 grains, 4 seeds
    python benchmarks/particle_resolution.py --mouth-grains 6 --seeds 2
    python benchmarks/particle_resolution.py --solver-iterations 20
"""

from __future__ import annotations

import argparse
import os
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")

import gymnasium as gym  # noqa: E402
import numpy as np  # noqa: E402
from pilerl_pile_loader.soil.particles import SOLVER_ITERATIONS  # noqa: E402

import pilerl  # noqa: E402,F401  (registers pilerl/PileLoading-v0)

ENV_ID = "pilerl/PileLoading-v0"


def make_expert(dt: float):
    """The pile loader's scripted expert, nominal style."""
    from pilerl_pile_loader.operator import make_expert as plugin_expert

    return plugin_expert(dt=dt)


def mouth_depth_m(env: gym.Env) -> float:
    """How far [m] the lower end of the bucket mouth lies below the undisturbed pile surface
    (negative: the whole mouth is above it)."""
    u = env.unwrapped
    soil, data = u.soil, u.data
    rotation = data.xmat[u.machine.bucket_body].reshape(3, 3)
    origin = data.xpos[u.machine.bucket_body]
    depths = []
    for x, z in (soil.bucket.cutting_edge_xz, soil.bucket.lip_xz):
        point = origin + rotation @ np.array([x, 0.0, z])
        surface = soil.pile.surface_height(point[:1], point[1:2], soil.repose_angle_rad)[0]
        depths.append(surface - point[2])
    return max(depths)


def scoop(env: gym.Env, seed: int) -> dict[str, float]:
    """One scripted scoop from a seeded start: final fill, fill gained through the mouth,
    simulated and wall seconds."""
    obs, _ = env.reset(seed=seed)
    expert = make_expert(env.unwrapped.dt)
    expert.reset()
    fill, mouth_fill, steps = 0.0, 0.0, 0
    start, start_cpu = time.perf_counter(), time.process_time()
    while True:
        obs, _, terminated, truncated, info = env.step(expert.act(obs))
        steps += 1
        gain = info["fill_fraction"] - fill
        fill = info["fill_fraction"]
        if gain > 0 and mouth_depth_m(env) > 0.0:
            mouth_fill += gain
        if terminated or truncated:
            break
    return {
        "fill": fill,
        "mouth_fill": mouth_fill,
        "sim_s": steps * env.unwrapped.dt,
        "cpu_s": time.process_time() - start_cpu,
        "wall_s": time.perf_counter() - start,
    }


def run_scoops(seeds: list[int], **env_kwargs) -> tuple[dict[str, float], float, gym.Env]:
    start = time.process_time()
    env = gym.make(ENV_ID, condition="summer", sensor_noise=0.0, **env_kwargs)
    build_s = time.process_time() - start
    runs = [scoop(env, seed) for seed in seeds]
    mean = {
        "fill": float(np.mean([r["fill"] for r in runs])),
        "mouth_fill": float(np.mean([r["mouth_fill"] for r in runs])),
        "rt": sum(r["sim_s"] for r in runs) / sum(r["cpu_s"] for r in runs),
        "rt_wall": sum(r["sim_s"] for r in runs) / sum(r["wall_s"] for r in runs),
        "fills": [r["fill"] for r in runs],
    }
    return mean, build_s, env


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--mouth-grains", type=float, nargs="+", default=[4.0, 6.0, 8.0])
    parser.add_argument("--seeds", type=int, default=4, help="seeded scoops per row")
    parser.add_argument(
        "--solver-iterations", type=int, default=None, help="CG iterations (default: the soil's)"
    )
    args = parser.parse_args()
    seeds = list(range(args.seeds))

    hf, _, _ = run_scoops(seeds, soil="heightfield")
    print(
        f"heightfield, {len(seeds)} seeded summer scoops: fill {hf['fill']:.3f} "
        f"(through the mouth {hf['mouth_fill']:.3f}), {hf['rt']:.1f}x real time; "
        f"fills {', '.join(f'{f:.2f}' for f in hf['fills'])}"
    )
    header = (
        f"{'mouth/d':>7} {'grain mm':>8} {'grains':>11} {'fill p':>6} {'fill hf':>7} "
        f"{'p/hf':>5} {'hf mouth':>8} {'p/mouth':>7} {'packed':>6} {'rt p':>5} {'rt hf':>6} "
        f"{'rt p/hf':>7} {'wall p':>6} {'build s':>7}  fills p"
    )
    iterations = args.solver_iterations or SOLVER_ITERATIONS
    print(f"particles, {iterations} CG iterations per physics step")
    print(header)
    print("-" * len(header))
    for grains in args.mouth_grains:
        options = {"mouth_grains": grains}
        if args.solver_iterations is not None:
            options["solver_iterations"] = args.solver_iterations
        p, build_s, env = run_scoops(seeds, soil="particles", soil_options=options)
        soil = env.unwrapped.soil
        count = f"{soil.n_particles}+{len(soil.core)}"
        print(
            f"{soil.mouth_diameters:7.1f} {2000 * soil.radius_m:8.0f} {count:>11} "
            f"{p['fill']:6.3f} {hf['fill']:7.3f} {p['fill'] / hf['fill']:5.2f} "
            f"{hf['mouth_fill']:8.3f} {p['fill'] / hf['mouth_fill']:7.2f} "
            f"{soil.packed_bucket_fill:6.2f} {p['rt']:5.2f} {hf['rt']:6.1f} "
            f"{p['rt'] / hf['rt']:7.3f} {p['rt_wall']:6.2f} {build_s:7.1f}  "
            f"{', '.join(f'{f:.2f}' for f in p['fills'])}",
            flush=True,
        )
        env.close()


if __name__ == "__main__":
    main()
