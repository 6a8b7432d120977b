"""How the particle pile's fill converges with resolution, what each resolution costs, and
what the heightfield counts as intake against what passes its bucket mouth.

One run, one thread. The scripted expert (nominal, deterministic style, noiseless sensors)
scoops from N seeded starts (summer unless ``--condition``) on each soil; the same seeds
everywhere.

Heightfield, first table (one row per intake, ``soil_options={"intake": ...}``):

- ``footprint`` (the default) takes every column under the bucket's inside; ``swept`` is
  the volume its mouth swept below the pile surface in the same scoops (as a fill fraction,
  ``measure_mouth=True``), i.e. what geometrically passed the mouth;
- ``mouth`` admits only what the mouth sweeps (docs/soil_models.md);
- ``success``: scoops that finished with fill >= 0.5; ``rt``: real-time factor.

Particles, second table (one row per resolution):

- ``mouth/d``: grain diameters across the bucket mouth; ``grain mm``; ``grains``: moving +
  static core;
- ``fill p``: mean final fill (``fill_measure="count"``, the load's mass at bulk density:
  the same quantity as the heightfield's intake, pile volume taken); ``vol p``: the load's
  bulk volume under its surface (``fill_measure="volume"``) at the end of the same scoops;
- ``p/hf``: ``fill p`` over the default heightfield's fill; ``p/mouth``: over the
  heightfield's fill with ``intake="mouth"``; ``p/m+b``: over the heightfield's with
  ``intake="mouth"`` and ``body_resistance=True``;
- ``succ``: scoops with ``fill p`` >= 0.5 that finished; ``packed``: the fill of a bucket
  packed as densely as the pile (the most a struck bucket reads at this resolution);
- ``rt p``: simulated seconds per CPU second of this one-thread process (whole episodes,
  approach included; CPU time, so that other work on a shared machine does not count);
  ``rt hf``: the same for the default heightfield in this run; ``rt p/hf``; ``wall p``:
  the wall-clock factor, for reference; ``build s``: CPU time to build the particle env.

    python benchmarks/particle_resolution.py                       # 4, 6, 8 grains, 4 seeds
    python benchmarks/particle_resolution.py --mouth-grains 6 --seeds 2
    python benchmarks/particle_resolution.py --mouth-grains 6 --condition winter_a
    python benchmarks/particle_resolution.py --solver-iterations 40 --mouth-grains 8
    python benchmarks/particle_resolution.py --contact-timeconst 0.004  # stiffer grains
    python benchmarks/particle_resolution.py --contact-modulus 5e7  # material-set stiffness
    python benchmarks/particle_resolution.py --contact-modulus 5e7 --bevelled-edge --seeds 2
    python benchmarks/particle_resolution.py --zone-scale 1.3 --mouth-grains 4 6  # larger zone
    python benchmarks/particle_resolution.py --mouth-grains 6 --condition winter_a --no-cohesion
    python benchmarks/particle_resolution.py --intake-only --seeds 16   # every condition
    python benchmarks/particle_resolution.py --penetration --seeds 3     # push tests
    python benchmarks/particle_resolution.py --mouth-grains 6 --condition winter_a \
        --overrides '{"material": {"cohesion_pa": 0}}'   # both soils without cohesion

``--overrides`` (JSON, as the env's ``condition_overrides``) changes the condition's
physical values on every soil of the run, in every mode: ``{"material": {"cohesion_pa":
0}}`` gives both soils the winter preset's material without its cohesion (2-6 kPa).
``--no-cohesion`` keeps only the particle pile's grains loose (its soil option
``cohesion``), the pile as it was before session 29 (docs/soil_models.md, "Comparing the
two soils on the same material" and "Cohesion").

``--intake-only`` prints only the heightfield table, for every condition preset (the
expert's fill and success with either intake, without and with ``body_resistance``; no
particles).

``--penetration`` pushes the bucket into the pile with a fixed throttle (0.6, boom held)
from seeded starts 1.0-1.5 m from the toe, level (bucket held) and curled (full bucket
curl for the first 0.6 s, ~0.4-0.5 rad, then held), for 10 s on every soil: the
heightfield by default, with ``body_resistance=True``, and particles at the default
resolution. ``pen``: the furthest the cutting edge got past the toe line [m], mean over
the seeds; ``/p``: over the particles'.
"""

from __future__ import annotations

import argparse
import os
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")

import gymnasium as gym  # noqa: E402
import numpy as np  # noqa: E402
from pilerl_pile_loader.soil.particles import (  # noqa: E402
    CONTACT_TIMECONST_S,
    GRAIN_CONTACT_MODULUS_PA,
    SOLVER_ITERATIONS,
)

import pilerl  # noqa: E402,F401  (registers pilerl/PileLoading-v0)

ENV_ID = "pilerl/PileLoading-v0"
PUSH_THROTTLE = 0.6  # the issue's drive-in throttle
PUSH_SECONDS = 10.0
PUSH_START_M = (1.0, 1.5)  # cutting edge to toe at reset [m]
PUSH_CURLS_S = {"level": 0.0, "curled": 0.6}  # full curl command for this long first [s]
PUSH_CONDITIONS = ("summer", "winter_a", "winter_c", "winter_d")
BODY = {"body_resistance": True}


def make_expert(dt: float, style: dict | None = None):
    """The pile loader's scripted expert, nominal style (or with ``style``'s
    ``OperatorStyle`` fields changed)."""
    from pilerl_pile_loader.operator import make_expert as plugin_expert

    return plugin_expert(dt=dt, **(style or {}))


def scoop(env: gym.Env, seed: int, expert_style: dict | None = None) -> dict[str, float]:
    """One scripted scoop from a seeded start: final fill (and the soil's extra measures),
    whether it finished, simulated, CPU and wall seconds."""
    obs, _ = env.reset(seed=seed)
    expert = make_expert(env.unwrapped.dt, expert_style)
    expert.reset()
    steps = 0
    start, start_cpu = time.perf_counter(), time.process_time()
    while True:
        obs, _, terminated, truncated, info = env.step(expert.act(obs))
        steps += 1
        if terminated or truncated:
            break
    cpu_s, wall_s = time.process_time() - start_cpu, time.perf_counter() - start
    soil = env.unwrapped.soil
    rated_m3 = soil.bucket.rated_volume_m3
    result = {
        "fill": info["fill_fraction"],
        "finished": float(info["scoop_finished"]),
        "sim_s": steps * env.unwrapped.dt,
        "cpu_s": cpu_s,
        "wall_s": wall_s,
    }
    if hasattr(soil, "mouth_swept_m3"):
        result["swept"] = soil.mouth_swept_m3 / rated_m3
    if hasattr(soil, "load_bulk_volume_m3"):
        result["volume"] = soil.load_bulk_volume_m3() / rated_m3
    return result


def run_scoops(
    seeds: list[int], condition: str = "summer", expert_style: dict | None = None, **env_kwargs
) -> tuple[dict, float, gym.Env]:
    start = time.process_time()
    env = gym.make(ENV_ID, condition=condition, sensor_noise=0.0, **env_kwargs)
    build_s = time.process_time() - start
    runs = [scoop(env, seed, expert_style) for seed in seeds]
    summary = {key: float(np.mean([r[key] for r in runs])) for key in runs[0]}
    summary["success"] = sum(bool(r["finished"]) and r["fill"] >= 0.5 for r in runs)
    summary["rt"] = sum(r["sim_s"] for r in runs) / sum(r["cpu_s"] for r in runs)
    summary["rt_wall"] = sum(r["sim_s"] for r in runs) / sum(r["wall_s"] for r in runs)
    summary["fills"] = [r["fill"] for r in runs]
    return summary, build_s, env


def push_penetration_m(env: gym.Env, seed: int, curl_s: float) -> float:
    """Fixed-throttle push from a seeded start: the furthest the cutting edge got past the
    pile's toe line along world x [m] (the pile's face is normal to x)."""
    env.reset(seed=seed)
    sim = env.unwrapped
    site, toe_x = sim.machine.cutting_edge_site, sim.soil.pile.toe_x_m
    furthest, elapsed = -np.inf, 0.0
    while elapsed < PUSH_SECONDS - 1e-9:
        bucket = 1.0 if elapsed < curl_s - 1e-9 else 0.0
        action = np.array([0.0, bucket, PUSH_THROTTLE], dtype=np.float32)
        _, _, terminated, truncated, info = env.step(action)
        elapsed = info["elapsed_s"]
        furthest = max(furthest, float(sim.data.site_xpos[site][0]) - toe_x)
        if terminated or truncated:
            break
    return furthest


def print_penetration_table(seeds: list[int], *, overrides: dict | None = None) -> None:
    """How far a pushed bucket gets into the pile on each soil, level and curled (with
    ``overrides`` as the condition overrides of every soil)."""
    soils = (
        ("hf default", {"soil": "heightfield"}),
        ("hf body", {"soil": "heightfield", "soil_options": BODY}),
        ("particles", {"soil": "particles"}),
    )
    print(
        f"penetration [m] past the toe, throttle {PUSH_THROTTLE}, boom held, "
        f"{PUSH_SECONDS:.0f} s, seeds {seeds[0]}-{seeds[-1]}"
        + (f", condition overrides {overrides}" if overrides else "")
    )
    header = (
        f"{'condition':>10} {'bucket':>7} "
        + " ".join(f"{name:>10}" for name, _ in soils)
        + f" {'default/p':>9} {'body/p':>6}  per seed (default | body | particles)"
    )
    print(header)
    print("-" * len(header))
    for condition in PUSH_CONDITIONS:
        envs = {
            name: gym.make(
                ENV_ID,
                condition=condition,
                sensor_noise=0.0,
                start_distance_range_m=PUSH_START_M,
                condition_overrides=overrides,
                **kwargs,
            )
            for name, kwargs in soils
        }
        for pose, curl_s in PUSH_CURLS_S.items():
            pens = {
                name: [push_penetration_m(env, seed, curl_s) for seed in seeds]
                for name, env in envs.items()
            }
            mean = {name: float(np.mean(values)) for name, values in pens.items()}
            per_seed = " | ".join(fills_text(values) for values in pens.values())
            print(
                f"{condition:>10} {pose:>7} "
                + " ".join(f"{mean[name]:10.3f}" for name, _ in soils)
                + f" {mean['hf default'] / mean['particles']:9.2f}"
                + f" {mean['hf body'] / mean['particles']:6.2f}  {per_seed}",
                flush=True,
            )
        for env in envs.values():
            env.close()


def fills_text(fills: list[float]) -> str:
    return ", ".join(f"{f:.2f}" for f in fills)


def print_intake_table(
    seeds: list[int], expert_style: dict | None = None, *, overrides: dict | None = None
) -> None:
    """The heightfield's two intakes, without and with resistance over the buried body, on
    every condition preset: mean fill, success and episode length (the nominal expert, or
    with ``expert_style``'s fields changed; ``overrides``: condition overrides)."""
    from pilerl_pile_loader.conditions import CONDITIONS

    n = len(seeds)
    configs = (
        ("fp", {"measure_mouth": True}),
        ("mouth", {"intake": "mouth"}),
        ("fp+body", {"measure_mouth": True, **BODY}),
        ("mouth+body", {"intake": "mouth", **BODY}),
    )
    who = f"the expert with {expert_style}" if expert_style else "the nominal expert"
    print(
        f"heightfield, {n} seeded scoops by {who} per condition: "
        "fill / success / mean episode s (swept: what passed the mouth, fp)"
        + (f"; condition overrides {overrides}" if overrides else "")
    )
    header = f"{'condition':>10} {'swept':>5} " + " ".join(f"{name:>17}" for name, _ in configs)
    print(header)
    print("-" * len(header))
    for condition in CONDITIONS:
        rows = {
            name: run_scoops(
                seeds, condition, expert_style, soil_options=o, condition_overrides=overrides
            )[0]
            for name, o in configs
        }
        cells = " ".join(
            f"{r['fill']:5.3f} {r['success']:>2}/{n:<2} {r['sim_s']:5.1f}" for r in rows.values()
        )
        print(f"{condition:>10} {rows['fp']['swept']:5.3f} {cells}", flush=True)


def expert_options(texts: list[str], parser: argparse.ArgumentParser) -> dict:
    """``--expert-option FIELD=VALUE ...`` as ``OperatorStyle`` fields: numbers as floats,
    true/false as booleans; an unknown field or a malformed pair is a parser error."""
    from dataclasses import fields

    from pilerl_pile_loader.operator import OperatorStyle

    known = {f.name for f in fields(OperatorStyle)} - {"trigger_sensor"}
    style: dict = {}
    for text in texts:
        name, sep, value = text.partition("=")
        if not sep or name not in known:
            parser.error(
                f"--expert-option {text!r}: expected FIELD=VALUE with FIELD one of {sorted(known)}"
            )
        if value.lower() in ("true", "false"):
            style[name] = value.lower() == "true"
        else:
            try:
                style[name] = float(value)
            except ValueError:
                parser.error(f"--expert-option {text!r}: {value!r} is not a number or true/false")
    return style


def contact_modulus(text: str) -> float | None:
    """``--contact-modulus``: a number [Pa] or ``none``."""
    return None if text.lower() == "none" else float(text)


def main() -> None:
    from pilerl_pile_loader.conditions import overrides_argument

    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--mouth-grains", type=float, nargs="+", default=[4.0, 6.0, 8.0])
    parser.add_argument("--seeds", type=int, default=4, help="seeded scoops per row")
    parser.add_argument("--condition", default="summer", help="condition preset of the scoops")
    parser.add_argument(
        "--solver-iterations", type=int, default=None, help="CG iterations (default: the soil's)"
    )
    parser.add_argument(
        "--contact-timeconst",
        type=float,
        default=None,
        help="grain contact time constant [s] (default: the soil's)",
    )
    parser.add_argument(
        "--contact-modulus",
        type=contact_modulus,
        default=None,
        help="grain contact stiffness per metre of diameter [Pa] (docs/soil_models.md "
        f"measured {GRAIN_CONTACT_MODULUS_PA:g}), or 'none' (default): MuJoCo's "
        "mass-normalised contacts",
    )
    parser.add_argument(
        "--bevelled-edge", action="store_true", help="a chamfer on the bucket's cutting edge"
    )
    parser.add_argument(
        "--zone-scale",
        type=float,
        default=None,
        help="particle digging zone scale (extent, half width, active depth; default 1)",
    )
    parser.add_argument(
        "--no-cohesion",
        action="store_true",
        help="loose grains whatever the material's cohesion (particle soil option cohesion)",
    )
    parser.add_argument(
        "--intake-only", action="store_true", help="only the heightfield, every condition"
    )
    parser.add_argument(
        "--penetration", action="store_true", help="fixed-throttle pushes on every soil"
    )
    parser.add_argument(
        "--expert-option",
        nargs="*",
        default=[],
        metavar="FIELD=VALUE",
        help="with --intake-only: change the nominal expert's OperatorStyle fields, e.g. "
        "push_throttle=0.35 (envs/pilerl_pile_loader/operator.py)",
    )
    parser.add_argument(
        "--overrides",
        type=overrides_argument,
        default=None,
        help='condition overrides of every soil (JSON), e.g. \'{"material": {"cohesion_pa": 0}}\'',
    )
    args = parser.parse_args()
    overrides = args.overrides
    expert_style = expert_options(args.expert_option, parser)
    seeds = list(range(args.seeds))
    n = len(seeds)
    if expert_style and not args.intake_only:
        parser.error("--expert-option: only with --intake-only")
    if args.intake_only:
        print_intake_table(seeds, expert_style, overrides=overrides)
        return
    if args.penetration:
        print_penetration_table(seeds, overrides=overrides)
        return

    condition = args.condition
    hf_runs = {
        name: run_scoops(
            seeds,
            condition,
            soil="heightfield",
            soil_options=options,
            condition_overrides=overrides,
        )[0]
        for name, options in (
            ("footprint", {"measure_mouth": True}),
            ("mouth", {"intake": "mouth"}),
            ("fp+body", {"measure_mouth": True, **BODY}),
            ("mouth+body", {"intake": "mouth", **BODY}),
        )
    }
    hf, hf_mouth, hf_mouth_body = hf_runs["footprint"], hf_runs["mouth"], hf_runs["mouth+body"]
    print(
        f"heightfield, {n} seeded {condition} scoops by the nominal expert"
        + (f", condition overrides {overrides}" if overrides else "")
    )
    header = f"{'intake':>10} {'fill':>5} {'swept':>5} {'success':>7} {'rt':>6}  fills"
    print(header)
    print("-" * len(header))
    for name, row in hf_runs.items():
        print(
            f"{name:>10} {row['fill']:5.3f} {row['swept']:5.3f} {row['success']:>4}/{n:<2} "
            f"{row['rt']:6.1f}  {fills_text(row['fills'])}"
        )

    iterations = args.solver_iterations or SOLVER_ITERATIONS
    timeconst = args.contact_timeconst or CONTACT_TIMECONST_S
    modulus = "mass-normalised" if args.contact_modulus is None else f"{args.contact_modulus:g} Pa"
    print(
        f"\nparticles, {iterations} CG iterations per physics step, contact time constant "
        f"{timeconst} s, contact modulus {modulus}, bevelled edge {args.bevelled_edge}, "
        f"zone scale {args.zone_scale or 1.0}, cohesion {not args.no_cohesion}, "
        f"the same {n} starts"
    )
    header = (
        f"{'mouth/d':>7} {'grain mm':>8} {'grains':>9} {'fill p':>6} {'vol p':>5} "
        f"{'p/hf':>5} {'p/mouth':>7} {'p/m+b':>5} {'succ':>5} {'packed':>6} {'rt p':>5} "
        f"{'rt hf':>6} {'rt p/hf':>7} {'wall p':>6} {'build s':>7}  fills p"
    )
    print(header)
    print("-" * len(header))
    for grains in args.mouth_grains:
        options = {
            "mouth_grains": grains,
            "contact_modulus_pa": args.contact_modulus,
            "bevelled_edge": args.bevelled_edge,
        }
        if args.solver_iterations is not None:
            options["solver_iterations"] = args.solver_iterations
        if args.contact_timeconst is not None:
            options["contact_timeconst_s"] = args.contact_timeconst
        if args.zone_scale is not None:
            options["zone_scale"] = args.zone_scale
        if args.no_cohesion:
            options["cohesion"] = False
        p, build_s, env = run_scoops(
            seeds, condition, soil="particles", soil_options=options, condition_overrides=overrides
        )
        soil = env.unwrapped.soil
        count = f"{soil.n_particles}+{len(soil.core)}"
        print(
            f"{soil.mouth_diameters:7.1f} {2000 * soil.radius_m:8.0f} {count:>9} "
            f"{p['fill']:6.3f} {p['volume']:5.3f} {p['fill'] / hf['fill']:5.2f} "
            f"{p['fill'] / hf_mouth['fill']:7.2f} {p['fill'] / hf_mouth_body['fill']:5.2f} "
            f"{p['success']:>2}/{n:<2} "
            f"{soil.packed_bucket_fill:6.2f} {p['rt']:5.2f} {hf['rt']:6.1f} "
            f"{p['rt'] / hf['rt']:7.3f} {p['rt_wall']:6.2f} {build_s:7.1f}  "
            f"{fills_text(p['fills'])}",
            flush=True,
        )
        env.close()


if __name__ == "__main__":
    main()
