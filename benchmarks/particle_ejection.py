"""Grains thrown out of the particle pile: the scripted expert's scoops with the bucket
plates' current contacts against MuJoCo's default contacts (before session 28's fix), in
the same run.

One thread. The nominal scripted expert (noiseless sensors) scoops from seeded starts on
the particle soil (default resolution unless ``--mouth-grains``) in each condition, twice:

- ``mujoco``: the bucket plates' ``solref`` / ``solimp`` reset to MuJoCo's defaults after
  the env is built (what ``ParticleSoil`` gave them before the fix, at every steel
  friction; the pile's settling in ``bind`` never touches the bucket, so this is the old
  model exactly);
- ``current``: as built (``steel_contact``: the same compliance at every steel friction;
  at summer's tan 25 deg these are MuJoCo's defaults, so summer's two rows are the same
  episodes).

Read at every control step (20 Hz): ``v max`` the fastest grain [m/s], ``z max`` the
highest grain centre [m], ``plate mm`` the deepest grain-bucket-plate contact penetration
[mm], ``ground mm`` the deepest grain-ground one. ``v > 5``: episodes where a grain
went faster than 5 m/s; ``fill`` the mean final fill (mass), ``fills`` per seed; ``rt``:
simulated seconds per CPU second, whole episodes.

    python benchmarks/particle_ejection.py                      # summer, winter_a, winter_c
    python benchmarks/particle_ejection.py --conditions winter_c --seeds 2
    python benchmarks/particle_ejection.py --conditions summer --seeds 1 \
        --overrides '{"material": {"tool_friction_angle_deg": 15.0}}'   # what it depends on

``--overrides``: condition overrides (JSON, as the env's ``condition_overrides``) for
every row, to tell which of a condition's differences the throwing depends on.
"""

from __future__ import annotations

import argparse
import os
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")

import gymnasium as gym  # noqa: E402
import mujoco  # noqa: E402
import numpy as np  # noqa: E402
from pilerl_pile_loader.operator import make_expert  # noqa: E402
from pilerl_pile_loader.soil.particles import BUCKET_GEOMS, MUJOCO_SOLIMP, MUJOCO_SOLREF  # noqa: E402

import pilerl  # noqa: E402,F401  (registers pilerl/PileLoading-v0)

ENV_ID = "pilerl/PileLoading-v0"
THROWN_SPEED_M_S = 5.0
VARIANTS = ("mujoco", "current")


def make_env(
    condition: str, variant: str, mouth_grains: float, overrides: dict | None = None
) -> gym.Env:
    """The particle env; ``variant="mujoco"`` puts MuJoCo's default contacts back on the
    bucket plates."""
    env = gym.make(
        ENV_ID,
        condition=condition,
        soil="particles",
        sensor_noise=0.0,
        soil_options={"mouth_grains": mouth_grains},
        condition_overrides=overrides,
    )
    if variant == "mujoco":
        model = env.unwrapped.model
        names = [
            *BUCKET_GEOMS,
            *(
                ["bucket_bevel"]
                if mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "bucket_bevel") >= 0
                else []
            ),
        ]
        for name in names:
            geom = model.geom(name).id
            model.geom_solref[geom] = MUJOCO_SOLREF
            model.geom_solimp[geom] = MUJOCO_SOLIMP
    return env


def deepest_mm(data: mujoco.MjData, grains: np.ndarray, others: np.ndarray) -> float:
    """Deepest penetration [mm] of a grain-geom contact with a geom in ``others``."""
    n = data.ncon
    g1, g2 = data.contact.geom1[:n], data.contact.geom2[:n]
    pair = (np.isin(g1, grains) & np.isin(g2, others)) | (np.isin(g2, grains) & np.isin(g1, others))
    if not pair.any():
        return 0.0
    return float(max(0.0, -data.contact.dist[:n][pair].min()) * 1000.0)


def scoop(env: gym.Env, seed: int) -> dict[str, float]:
    """One scripted scoop from a seeded start; the maxima read at every control step."""
    sim = env.unwrapped
    soil, model, data = sim.soil, sim.model, sim.data
    # every grain's geoms: a bonded grain's plate and ground contacts are on its unbonded
    # copy, a child body (particles.add_grain), so take the grain bodies and their children
    grain_bodies = np.arange(model.nbody)[soil._bodies]
    of_a_grain = np.isin(np.arange(model.nbody), grain_bodies) | np.isin(
        model.body_parentid, grain_bodies
    )
    grains = np.flatnonzero(of_a_grain[model.geom_bodyid])
    plates = np.array([model.geom(name).id for name in BUCKET_GEOMS])
    ground = np.array([model.geom("ground").id])
    obs, _ = env.reset(seed=seed)
    expert = make_expert(dt=sim.dt)
    expert.reset()
    worst = {"v_max": 0.0, "z_max": 0.0, "plate_mm": 0.0, "ground_mm": 0.0}
    steps, start_cpu = 0, time.process_time()
    while True:
        obs, _, terminated, truncated, info = env.step(expert.act(obs))
        steps += 1
        speeds = np.linalg.norm(data.qvel[soil._dofs].reshape(-1, 3), axis=1)
        now = {
            "v_max": float(speeds.max()),
            "z_max": float(soil.particle_positions()[:, 2].max()),
            "plate_mm": deepest_mm(data, grains, plates),
            "ground_mm": deepest_mm(data, grains, ground),
        }
        worst = {key: max(worst[key], now[key]) for key in worst}
        if terminated or truncated:
            break
    return {
        **worst,
        "fill": float(info["fill_fraction"]),
        "sim_s": steps * sim.dt,
        "cpu_s": time.process_time() - start_cpu,
    }


def main() -> None:
    from pilerl_pile_loader.conditions import overrides_argument

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--conditions", nargs="+", default=["summer", "winter_a", "winter_c"])
    parser.add_argument("--seeds", type=int, default=4, help="seeded scoops per row")
    parser.add_argument("--mouth-grains", type=float, default=6.0)
    parser.add_argument(
        "--overrides", type=overrides_argument, default=None, help="condition overrides (JSON)"
    )
    args = parser.parse_args()
    seeds = list(range(args.seeds))
    header = (
        f"{'condition':>9} {'steel':>8} {'v > 5':>6} {'v max':>6} {'z max':>6} "
        f"{'plate mm':>8} {'ground mm':>9} {'fill':>6} {'rt':>5}  fills | v max | z max per seed"
    )
    print(
        f"mouth grains {args.mouth_grains}, seeds {seeds[0]}-{seeds[-1]}, nominal expert, "
        f"overrides {args.overrides}"
    )
    print(header)
    print("-" * len(header))
    for condition in args.conditions:
        for variant in VARIANTS:
            env = make_env(condition, variant, args.mouth_grains, args.overrides)
            runs = [scoop(env, seed) for seed in seeds]
            env.close()
            fast = sum(r["v_max"] > THROWN_SPEED_M_S for r in runs)
            rt = sum(r["sim_s"] for r in runs) / sum(r["cpu_s"] for r in runs)
            per_seed = " | ".join(
                ", ".join(f"{r[key]:.{digits}f}" for r in runs)
                for key, digits in (("fill", 2), ("v_max", 1), ("z_max", 2))
            )
            print(
                f"{condition:>9} {variant:>8} {fast:>4}/{len(runs)} "
                f"{max(r['v_max'] for r in runs):6.1f} {max(r['z_max'] for r in runs):6.2f} "
                f"{max(r['plate_mm'] for r in runs):8.1f} "
                f"{max(r['ground_mm'] for r in runs):9.1f} "
                f"{np.mean([r['fill'] for r in runs]):6.3f} {rt:5.2f}  {per_seed}",
                flush=True,
            )


if __name__ == "__main__":
    main()
