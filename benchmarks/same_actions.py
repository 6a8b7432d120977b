"""Same actions on both soils: the particle pile against the heightfield under identical
commands, and where the scripted expert's impact cue fires on each (issue #15).

One process, one thread, summer, noiseless sensors, seeded starts (seeds 0..N-1: the same
start on every soil). Soils: ``particles`` (the default pile), ``mouth`` (heightfield,
``intake="mouth"``), ``footprint`` (heightfield, default intake). Fill by mass (the env's
``fill_fraction``); ``vol``: the particle load's bulk volume (as ``fill_measure="volume"``
reads it) at the end of the same episode. Edge depth: the soil's ``cutting_depth_m``.
"Relief": p_d >= ``NEAR_RELIEF_MPA`` (the drive's relief is 25 MPa). p_d is logged at
every physics step (500 Hz) by running MuJoCo's steps one at a time, which gives the same
trajectory as the env's chunked ``mj_step``.

Tables (``--tables``):

- ``scripts``: the open-loop scoop of ``pilerl_pile_loader.open_loop`` (drive in at
  throttle 0.8, lift from ``--lift`` s, curl from ``--curl`` s; pairs, default 3/6 = the
  script as it is, and 4/7): fill per seed; ``d lift`` edge depth when the lift starts;
  ``d relief`` edge depth at the first p_d at relief; ``relief``: share of the physics
  steps from first contact (edge 2 cm deep) to the lift with p_d at relief.
- ``replay``: the nominal expert (styled by ``--style``) on particles and on the mouth
  heightfield; then each
  one's command sequence replayed step for step on the other soils (the last command held
  if the replay outlives it); ``done``: scoops the env counts finished.
- ``cue``: the nominal expert (styled by ``--style``) on particles and the mouth
  heightfield: the three 20 Hz p_d readings that fired its impact cue (the default stall
  cue since session 33; ``--style impact_cue=rise push_again=false``: the rise above the
  felt level held ``impact_hold_s``, session 31's tables in docs/soil_models.md), edge
  depth and forward speed at the cue, the 500 Hz runs of p_d at relief between contact
  and cue; then a fixed push at the expert's approach throttle (boom and bucket held) from
  the same starts: the first run of p_d at relief (ms, edge depth), p_d's lowest in the
  0.3 s after it, where p_d first stays at relief 0.15 s (``sust``), the edge depth where
  the machine stops (speed < 0.05 m/s) and the deepest.
- ``expert`` (not in the default set): the nominal expert, styled by ``--style
  FIELD=VALUE`` (``OperatorStyle`` fields, e.g. ``impact_cue=stall``), on each of
  ``--soils`` under ``--condition``: fill by mass and volume, scoops finished, the cue's
  time after contact and edge depth there (``d cue``), pushes in the fill phase (runs of a
  forward throttle), and the particle episodes' real-time factor (simulated s per wall s;
  logging p_d at 500 Hz included).

    python benchmarks/same_actions.py                       # every table, seeds 0-3
    python benchmarks/same_actions.py --tables replay --seeds 2
    python benchmarks/same_actions.py --tables scripts --lift 3 5 --curl 6 8
    python benchmarks/same_actions.py --tables expert --style impact_cue=stall \
        --condition winter_c --soils particles mouth
"""

from __future__ import annotations

import argparse
import os
import time
from collections.abc import Callable

os.environ.setdefault("OMP_NUM_THREADS", "1")

import gymnasium as gym  # noqa: E402
import numpy as np  # noqa: E402
from pilerl_pile_loader import open_loop  # noqa: E402
from pilerl_pile_loader.operator import OperatorStyle, make_expert  # noqa: E402

import pilerl  # noqa: E402,F401  (registers pilerl/PileLoading-v0)

ENV_ID = "pilerl/PileLoading-v0"
SOILS = {
    "particles": {"soil": "particles"},
    "mouth": {"soil": "heightfield", "soil_options": {"intake": "mouth"}},
    "footprint": {"soil": "heightfield"},
}
NEAR_RELIEF_MPA = 24.0  # p_d at or near the drive's 25 MPa relief
CONTACT_M = 0.02  # the edge is in the pile this deep [m]
STOPPED_M_S = 0.05  # forward speed below which a push has stopped [m/s]
SUSTAINED_S = 0.15  # p_d at relief this long: sustained
AFTER_S = 0.3  # p_d's lowest this long after the first relief run [s]
PUSH_AFTER_CONTACT_S = 2.5  # a fixed push runs this long past the expert's contact [s]
PHASES = ("approach", "fill", "finish")


class _PhysicsLog:
    """Wraps a soil's ``advance`` (the env's physics steps): one physics step at a time,
    the drive pressure and forward speed logged after each."""

    def __init__(self) -> None:
        self.machine = None
        self.p_d: list[float] = []
        self.speed: list[float] = []

    def wrap(self, advance: Callable[..., None]) -> Callable[..., None]:
        def logged(model, data, nstep: int) -> None:
            for _ in range(nstep):
                advance(model, data, 1)
                self.p_d.append(self.machine.drive_pressure_mpa())
                self.speed.append(self.machine.forward_speed())

        return logged


LOG = _PhysicsLog()


def episode(
    env: gym.Env, seed: int, policy: Callable[[int, dict], np.ndarray], max_s: float | None = None
) -> dict:
    """One episode from seeded start ``seed``, ``policy(step, obs)`` -> command: a trace at
    the control rate (the reading each command was decided on) and at the physics rate."""
    sim = env.unwrapped
    obs, _ = env.reset(seed=seed)
    LOG.machine, LOG.p_d, LOG.speed = sim.machine, [], []
    rows: dict[str, list] = {k: [] for k in ("action", "p_d", "depth", "speed", "phase")}
    step, info, start, wall = 0, {}, time.process_time(), time.perf_counter()
    sim.soil.advance = LOG.wrap(sim.soil.advance)  # the bound method, logged
    try:
        while True:
            action = np.asarray(policy(step, obs), np.float32)
            rows["action"].append(action)
            rows["p_d"].append(float(obs["drive_pressure"][0]))
            rows["depth"].append(sim.soil.cutting_depth_m())
            rows["speed"].append(sim.machine.forward_speed())
            rows["phase"].append(getattr(policy, "phase", 0))
            obs, _, terminated, truncated, info = env.step(action)
            step += 1
            if terminated or truncated or (max_s is not None and step * sim.dt >= max_s - 1e-9):
                break
    finally:
        del sim.soil.advance  # the class's own again
    soil = sim.soil
    volume = soil.load_bulk_volume_m3() if hasattr(soil, "load_bulk_volume_m3") else np.nan
    trace = {k: np.asarray(v) for k, v in rows.items()}
    trace.update(
        fill=info["fill_fraction"],
        vol=volume / soil.bucket.rated_volume_m3,
        done=bool(info["scoop_finished"]),
        t=np.arange(step) * sim.dt,
        p_d_phys=np.asarray(LOG.p_d),
        speed_phys=np.asarray(LOG.speed),
        per_step=sim.frame_skip,
        phys_dt=sim.model.opt.timestep,
        cpu_s=time.process_time() - start,
        wall_s=time.perf_counter() - wall,
    )
    return trace


def script_policy(lift_s: float, curl_s: float):
    return lambda step, obs: open_loop.scripted_action(step, lift_from_s=lift_s, curl_from_s=curl_s)


class ExpertPolicy:
    """The nominal scripted expert (``style``: ``OperatorStyle`` fields to set);
    ``phase``: its phase index after the last decision."""

    def __init__(self, dt: float, **style: object) -> None:
        self.expert = make_expert(dt=dt, **style)
        self.expert.reset()
        self.phase = 0

    def __call__(self, step: int, obs: dict) -> np.ndarray:
        action = self.expert.act(obs)
        self.phase = PHASES.index(self.expert.phase)
        return action


def replay_policy(actions: np.ndarray):
    return lambda step, obs: actions[min(step, len(actions) - 1)]


def push_policy(throttle: float):
    return lambda step, obs: np.array([0.0, 0.0, throttle], np.float32)


def runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """(start, length) of each run of True in ``mask``."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(np.int8), [0]])))
    return [(int(a), int(b - a)) for a, b in zip(edges[::2], edges[1::2], strict=True)]


def contact_step(tr: dict) -> int:
    return int(np.argmax(tr["depth"] > CONTACT_M))


def depth_at_phys(tr: dict, k: int) -> float:
    """Edge depth at the control step nearest physics step ``k`` (0-based)."""
    return float(tr["depth"][min(len(tr["depth"]) - 1, round((k + 1) / tr["per_step"]))])


def mean_rows(rows: list) -> np.ndarray:
    """Column means of ``rows``, NaN where a column has no finite value."""
    a = np.array(rows, dtype=float)
    finite = np.isfinite(a)
    total = np.where(finite, a, 0.0).sum(axis=0)
    count = finite.sum(axis=0)
    return np.where(count > 0, total / np.maximum(count, 1), np.nan)


def fills(values) -> str:
    return ", ".join(f"{v:.3f}" for v in values)


def make_env(soil: str, condition: str = "summer") -> gym.Env:
    return gym.make(ENV_ID, condition=condition, sensor_noise=0.0, **SOILS[soil])


def scripts_table(seeds: list[int], pairs: list[tuple[float, float]]) -> None:
    print(
        f"\nopen-loop scoop (drive in at throttle {open_loop.DRIVE_IN[2]}, lift, curl), "
        f"summer, seeds {seeds[0]}-{seeds[-1]}: means (fill per seed)"
    )
    header = (
        f"{'lift/curl s':>11} {'soil':>9} {'fill':>5} {'vol':>5} {'d lift':>6} "
        f"{'d relief':>8} {'relief':>6} {'cpu s':>6}  fills"
    )
    print(header)
    print("-" * len(header))
    for soil in SOILS:
        env = make_env(soil)
        for lift_s, curl_s in pairs:
            rows = []
            for seed in seeds:
                tr = episode(env, seed, script_policy(lift_s, curl_s))
                lift = round(lift_s / env.unwrapped.dt)
                c, n = contact_step(tr), tr["per_step"]
                drive = tr["p_d_phys"][c * n : lift * n] >= NEAR_RELIEF_MPA
                first = np.flatnonzero(drive)
                d_relief = depth_at_phys(tr, c * n + first[0]) if len(first) else np.nan
                rows.append(
                    (tr["fill"], tr["vol"], tr["depth"][lift], d_relief, drive.mean(), tr["cpu_s"])
                )
            m = mean_rows(rows)
            print(
                f"{f'{lift_s:g}/{curl_s:g}':>11} {soil:>9} {m[0]:5.3f} {m[1]:5.3f} {m[2]:6.3f} "
                f"{m[3]:8.3f} {m[4]:6.2f} {m[5]:6.1f}  {fills(r[0] for r in rows)}",
                flush=True,
            )
        env.close()


def replay_table(seeds: list[int], style: dict) -> None:
    print(
        f"\nthe nominal expert ({described(style)}) and its commands replayed, summer, seeds "
        f"{seeds[0]}-{seeds[-1]}"
    )
    header = f"{'commands of':>19} {'run on':>9} {'fill':>5} {'vol':>5} {'done':>5}  fills"
    print(header)
    print("-" * len(header))
    envs = {soil: make_env(soil) for soil in SOILS}
    sources = {}
    for source in ("particles", "mouth"):
        env = envs[source]
        sources[source] = [episode(env, s, ExpertPolicy(env.unwrapped.dt, **style)) for s in seeds]
    plan = [
        ("particles", "particles"),
        ("mouth", "mouth"),
        ("particles", "mouth"),
        ("particles", "footprint"),
        ("mouth", "particles"),
    ]
    for source, target in plan:
        if source == target:
            trs = sources[source]
            who = f"expert on {source}"
        else:
            trs = [
                episode(envs[target], s, replay_policy(tr["action"]))
                for s, tr in zip(seeds, sources[source], strict=True)
            ]
            who = f"{source} expert"
        vol = mean_rows([[tr["vol"]] for tr in trs])[0]
        print(
            f"{who:>19} {target:>9} {np.mean([tr['fill'] for tr in trs]):5.3f} {vol:5.3f} "
            f"{sum(tr['done'] for tr in trs):>2}/{len(trs):<2}  {fills(tr['fill'] for tr in trs)}",
            flush=True,
        )
    for env in envs.values():
        env.close()


def cue_table(seeds: list[int], style: dict) -> None:
    throttle = OperatorStyle(**style).approach_throttle
    print(
        f"\nthe nominal expert's ({described(style)}) impact cue, summer, seeds "
        f"{seeds[0]}-{seeds[-1]} (relief: p_d >= {NEAR_RELIEF_MPA:g} MPa at 500 Hz, between "
        "contact and cue)"
    )
    header = (
        f"{'soil':>9} {'seed':>4} {'cue-contact s':>13} {'p_d readings MPa':>18} "
        f"{'d cue':>5} {'v cue':>5} {'v contact':>9} {'relief runs ms':>14}"
    )
    print(header)
    print("-" * len(header))
    expert_contact_s = {}
    for soil in ("particles", "mouth"):
        env = make_env(soil)
        for seed in seeds:
            tr = episode(env, seed, ExpertPolicy(env.unwrapped.dt, **style))
            cue, c, n = int(np.argmax(tr["phase"] >= 1)), contact_step(tr), tr["per_step"]
            expert_contact_s.setdefault(seed, tr["t"][c])
            relief = tr["p_d_phys"][(c - 1) * n : cue * n] >= NEAR_RELIEF_MPA
            ms = [round(1e3 * length * tr["phys_dt"]) for _, length in runs(relief)]
            readings = " ".join(f"{p:.1f}" for p in tr["p_d"][cue - 2 : cue + 1])
            print(
                f"{soil:>9} {seed:>4} {tr['t'][cue] - tr['t'][c]:13.2f} {readings:>18} "
                f"{tr['depth'][cue]:5.3f} {tr['speed'][cue]:5.2f} {tr['speed'][c]:9.2f} "
                f"{str(ms or '-'):>14}",
                flush=True,
            )
        env.close()

    print(
        f"\nfixed push at throttle {throttle:g} (the expert's approach), boom and bucket held, "
        f"until {PUSH_AFTER_CONTACT_S:g} s past the expert's contact"
    )
    header = (
        f"{'soil':>9} {'seed':>4} {'1st relief ms':>13} {'d 1st':>5} {'p_d min after':>13} "
        f"{'d sust':>6} {'d stop':>6} {'d max':>5}"
    )
    print(header)
    print("-" * len(header))
    for soil in ("particles", "mouth"):
        env = make_env(soil)
        for seed in seeds:
            max_s = expert_contact_s[seed] + PUSH_AFTER_CONTACT_S
            tr = episode(env, seed, push_policy(throttle), max_s=max_s)
            c, n, dt = contact_step(tr), tr["per_step"], tr["phys_dt"]
            base = (c - 1) * n
            relief = runs(tr["p_d_phys"][base:] >= NEAR_RELIEF_MPA)
            start, length = relief[0]
            after = tr["p_d_phys"][base + start + length :][: round(AFTER_S / dt)]
            sust = next((s for s, m in relief if m * dt >= SUSTAINED_S - 1e-9), None)
            stopped = np.flatnonzero(
                (np.arange(len(tr["speed"])) > c) & (tr["speed"] < STOPPED_M_S)
            )
            print(
                f"{soil:>9} {seed:>4} {1e3 * length * dt:13.0f} "
                f"{depth_at_phys(tr, base + start):5.3f} "
                f"{after.min() if len(after) else np.nan:13.1f} "
                f"{depth_at_phys(tr, base + sust) if sust is not None else np.nan:6.3f} "
                f"{tr['depth'][stopped[0]] if len(stopped) else np.nan:6.3f} "
                f"{tr['depth'].max():5.3f}",
                flush=True,
            )
        env.close()


def expert_table(seeds: list[int], soils: list[str], condition: str, style: dict) -> None:
    print(f"\nthe expert ({described(style)}), {condition}, seeds {seeds[0]}-{seeds[-1]}")
    header = (
        f"{'soil':>9} {'seed':>4} {'fill':>5} {'vol':>5} {'done':>4} {'cue-contact s':>13} "
        f"{'d cue':>5} {'p_d cue':>7} {'pushes':>6} {'sim s':>5} {'wall s':>6} {'rtf':>5}"
    )
    print(header)
    print("-" * len(header))
    for soil in soils:
        env = make_env(soil, condition)
        rows = []
        for seed in seeds:
            tr = episode(env, seed, ExpertPolicy(env.unwrapped.dt, **style))
            fill_phase = tr["phase"] == 1
            fired = bool(fill_phase.any())
            cue, c = int(np.argmax(fill_phase)), contact_step(tr)
            pushing = fill_phase & (tr["action"][:, 2] > 0)
            row = (
                tr["fill"],
                tr["vol"],
                float(tr["done"]),
                tr["t"][cue] - tr["t"][c] if fired else np.nan,
                tr["depth"][cue] if fired else np.nan,
                tr["p_d"][cue] if fired else np.nan,
                len(runs(pushing)),
                tr["t"][-1] + env.unwrapped.dt,
                tr["wall_s"],
            )
            rows.append(row)
            print(
                f"{soil:>9} {seed:>4} {row[0]:5.3f} {row[1]:5.3f} {int(row[2]):>4} "
                f"{row[3]:13.2f} {row[4]:5.3f} {row[5]:7.1f} {row[6]:>6} {row[7]:5.1f} "
                f"{row[8]:6.1f} {row[7] / row[8]:5.2f}",
                flush=True,
            )
        m = mean_rows(rows)
        print(
            f"{soil:>9} {'mean':>4} {m[0]:5.3f} {m[1]:5.3f} {m[2] * len(rows):4.0f} "
            f"{m[3]:13.2f} {m[4]:5.3f} {m[5]:7.1f} {m[6]:6.2f} {m[7]:5.1f} {m[8]:6.1f} "
            f"{m[7] / m[8]:5.2f}",
            flush=True,
        )
        env.close()


def described(style: dict) -> str:
    """``style`` (``OperatorStyle`` fields set) as ``FIELD=VALUE`` words; the default's
    name when empty."""
    return " ".join(f"{k}={v}" for k, v in style.items()) or "default"


def style_option(text: str) -> tuple[str, object]:
    """``FIELD=VALUE`` -> (field, value): true/false as booleans, numbers as floats."""
    name, _, value = text.partition("=")
    if value.lower() in ("true", "false"):
        return name, value.lower() == "true"
    try:
        return name, float(value)
    except ValueError:
        return name, value


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seeds", type=int, default=4, help="seeded starts 0..N-1")
    parser.add_argument(
        "--tables",
        nargs="+",
        default=["scripts", "replay", "cue"],
        choices=["scripts", "replay", "cue", "expert"],
    )
    parser.add_argument("--condition", default="summer", help="expert table: the condition")
    parser.add_argument(
        "--soils", nargs="+", default=list(SOILS), choices=list(SOILS), help="expert table"
    )
    parser.add_argument(
        "--style",
        nargs="*",
        type=style_option,
        default=[],
        help="the expert of the replay, cue and expert tables: FIELD=VALUE",
    )
    parser.add_argument("--lift", type=float, nargs="+", default=[open_loop.LIFT_FROM_S, 4.0])
    parser.add_argument("--curl", type=float, nargs="+", default=[open_loop.CURL_FROM_S, 7.0])
    args = parser.parse_args()
    if len(args.lift) != len(args.curl) or min(args.lift) < open_loop.LIFT_FROM_S:
        parser.error(f"--lift and --curl: pairs, lift from {open_loop.LIFT_FROM_S:g} s on")
    seeds = list(range(args.seeds))
    if "scripts" in args.tables:
        scripts_table(seeds, list(zip(args.lift, args.curl, strict=True)))
    if "replay" in args.tables:
        replay_table(seeds, dict(args.style))
    if "cue" in args.tables:
        cue_table(seeds, dict(args.style))
    if "expert" in args.tables:
        expert_table(seeds, args.soils, args.condition, dict(args.style))


if __name__ == "__main__":
    main()
