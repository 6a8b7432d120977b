"""Where does the summer operator start lifting, and can a winter push reach that reading?

The measurement behind Exp. 2's verdict "p_t does not restore RF in winter"
(docs/results/paper/README.md). A controller cloned from summer demonstrations lifts where
the demonstrations lift; if no winter push ever produces those readings, no input set can
make it lift there, p_t included. Four parts:

1. **Onsets**, from a recorded summer dataset (``--demos``, e.g. the paper campaign's
   ``data/datasets/d_ii_summer``): each episode's first lift (the first sample after
   ``SETTLE_S`` with boom command > ``LIFT_COMMAND``): p10 / p50 / p90 of the drive and
   telescope pressures there, and of their maxima before it (the readings the operator
   pushed through without lifting).
2. **Pushes**, per condition and throttle (``--conditions``, ``--throttles``): drive at
   the pile from ``--starts`` seeded starts, boom and bucket held, ``PUSH_S`` each at
   20 Hz with the default sensor noise; in contact (cutting depth > 5 cm) the 90th
   percentile of p_d and of p_t (the steady push, capped by the tyres' grip on ice) and p_t's
   peak in the first second of contact (the impact, which the machine's momentum drives,
   not its grip). ``reach p_d`` / ``reach p_t``: the share of summer onsets whose reading is
   at or below that condition's peak in contact (0: no onset reading is ever reached).
3. **What the demonstrations do at a winter push's drive pressure** (``--band``, default
   10-14 MPa, winter_c's capped push): their samples with p_d in the band, split into
   pushing (boom command <= ``LIFT_COMMAND``, throttle > ``PUSHING_THROTTLE``) and lifting
   (boom command > ``LIFT_COMMAND``), with p_t's p10 / p50 / p90 for each: whether p_t
   tells a controller which of the two an ice push looks like.
4. **Controllers** (``--checkpoint``, repeatable): the boom command at the approach posture
   (median boom and bucket angle over the second before each onset) on a grid of drive and
   telescope pressures: what a cloned controller does with each reading a winter push gives.

    python benchmarks/lift_cue.py --demos data/datasets/d_ii_summer
    python benchmarks/lift_cue.py --demos data/datasets/d_ii_summer --throttles 0.2 0.6 \
        --checkpoint multirun/exp2_data_and_pt/0/best.pt \
        --checkpoint multirun/exp2_data_and_pt/2/best.pt

The pushes take well under a second of CPU each (the default 5 conditions x 2 throttles x
3 starts: about 10 s).
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

CONDITIONS = ("summer", "winter_a", "winter_b", "winter_c", "winter_d")
SETTLE_S = 0.5  # the first lift is looked for after this [s] (the valves settle at reset)
LIFT_COMMAND = 0.1  # a boom command above this is a lift
POSTURE_WINDOW_S = 1.0  # the approach posture: the median angles over this before the onset [s]
PUSH_S = 10.0  # each push [s]
PUSHING_THROTTLE = 0.1  # a sample that does not lift, with the throttle above this, pushes
BAND_MPA = (10.0, 14.0)  # part 3's default drive-pressure band: winter_c's capped push
CONTACT_DEPTH_M = 0.05  # in contact: the cutting edge this deep (benchmarks/sensor_separability.py)
IMPACT_WINDOW_S = 1.0  # the impact: p_t's peak within this of first contact [s]
GRID_DRIVE_MPA = (4.0, 8.0, 10.0, 12.0, 14.0, 17.0, 20.0, 25.0)
GRID_TELESCOPE_MPA = (0.5, 1.0, 1.5, 2.0, 2.5, 3.0, 4.5, 6.0)


def lift_onsets(frame: pd.DataFrame) -> pd.DataFrame:
    """One row per episode of ``frame`` (``pilerl.data.export.episodes_to_frame``'s columns)
    that lifts: the readings at its first lift, their maxima before it, and the approach
    posture. Episodes that never lift are left out."""
    rows = []
    for episode, samples in frame.groupby("episode", sort=True):
        time_s = samples["time_s"].to_numpy()
        lifting = np.flatnonzero(
            (samples["u_boom"].to_numpy() > LIFT_COMMAND) & (time_s > SETTLE_S)
        )
        if lifting.size == 0:
            continue
        at = int(lifting[0])
        before = samples.iloc[:at] if at > 0 else samples.iloc[:1]
        posture = samples[(time_s >= time_s[at] - POSTURE_WINDOW_S) & (time_s < time_s[at])]
        posture = posture if len(posture) else samples.iloc[at : at + 1]
        rows.append(
            {
                "episode": episode,
                "time_s": float(time_s[at]),
                "drive_mpa": float(samples["drive_pressure"].iloc[at]),
                "telescope_mpa": float(samples["telescope_pressure"].iloc[at]),
                "drive_max_before_mpa": float(before["drive_pressure"].max()),
                "telescope_max_before_mpa": float(before["telescope_pressure"].max()),
                "boom_angle_rad": float(posture["boom_angle"].median()),
                "bucket_angle_rad": float(posture["bucket_angle"].median()),
            }
        )
    return pd.DataFrame(rows)


def band_split(frame: pd.DataFrame, band_mpa: tuple[float, float]) -> dict[str, pd.Series]:
    """The telescope pressures [MPa] of ``frame``'s samples with the drive pressure inside
    ``band_mpa`` (inclusive), split into ``pushing`` and ``lifting`` (module docstring)."""
    low, high = band_mpa
    inside = frame[(frame["drive_pressure"] >= low) & (frame["drive_pressure"] <= high)]
    lifting = inside["u_boom"] > LIFT_COMMAND
    pushing = ~lifting & (inside["u_throttle"] > PUSHING_THROTTLE)
    return {
        "pushing": inside.loc[pushing, "telescope_pressure"],
        "lifting": inside.loc[lifting, "telescope_pressure"],
    }


def push(condition: str, throttle: float, starts: int) -> dict[str, float]:
    """Drive at the pile on ``condition`` at ``throttle``, boom and bucket held, from seeds
    0 .. ``starts`` - 1: p_d and p_t in contact (90th percentiles and peaks) and p_t's
    impact peak [MPa]."""
    import gymnasium as gym

    import pilerl  # noqa: F401  (registers pilerl/PileLoading-v0)

    env = gym.make("pilerl/PileLoading-v0", condition=condition).unwrapped
    drive, telescope, impacts = [], [], []
    for seed in range(starts):
        _, info = env.reset(seed=seed)
        contact_s = None
        impact = np.nan
        while info["elapsed_s"] < PUSH_S - 1e-9:
            obs, _, terminated, truncated, info = env.step(
                np.array([0.0, 0.0, throttle], dtype=np.float32)
            )
            p_d, p_t = float(obs["drive_pressure"][0]), float(obs["telescope_pressure"][0])
            if info["cutting_depth_m"] > 0.0 and contact_s is None:
                contact_s = info["elapsed_s"]
            if contact_s is not None and info["elapsed_s"] - contact_s <= IMPACT_WINDOW_S:
                impact = p_t if np.isnan(impact) else max(impact, p_t)
            if info["cutting_depth_m"] > CONTACT_DEPTH_M:
                drive.append(p_d)
                telescope.append(p_t)
            if terminated or truncated:
                break
        impacts.append(impact)
    env.close()
    if not drive:
        raise SystemExit(
            f"{condition}, throttle {throttle}: the bucket never reached {CONTACT_DEPTH_M} m "
            f"deep in {PUSH_S:.0f} s (use a larger throttle)"
        )
    return {
        "drive_p90": float(np.percentile(drive, 90)),
        "drive_max": float(np.max(drive)),
        "telescope_p90": float(np.percentile(telescope, 90)),
        "telescope_max": float(np.nanmax([np.max(telescope), *impacts])),
        "impact": float(np.nanmean(impacts)),
    }


def boom_response(checkpoint: Path, posture: tuple[float, float]) -> np.ndarray:
    """The boom command of the actor in ``checkpoint`` at the approach ``posture`` (boom,
    bucket angle [rad]) on the ``GRID_DRIVE_MPA`` x ``GRID_TELESCOPE_MPA`` grid; an actor
    without p_t reads the drive pressure only (its rows repeat across the columns)."""
    import torch
    from tensordict import TensorDict

    from pilerl.policies.checkpoint import load_actor

    actor = load_actor(checkpoint)
    drive, telescope = np.meshgrid(GRID_DRIVE_MPA, GRID_TELESCOPE_MPA, indexing="ij")
    n = drive.size
    readings = {
        "boom_angle": np.full(n, posture[0]),
        "bucket_angle": np.full(n, posture[1]),
        "drive_pressure": drive.ravel(),
        "telescope_pressure": telescope.ravel(),
    }
    unknown = sorted(set(actor.in_keys) - set(readings))
    if unknown:
        raise SystemExit(f"{checkpoint}: reads {unknown}; this grid sets {sorted(readings)}")
    td = TensorDict(
        {k: torch.as_tensor(readings[k], dtype=torch.float32).reshape(n, 1) for k in actor.in_keys},
        batch_size=[n],
    )
    with torch.no_grad():
        boom = actor(td)["action"][:, 0].numpy()
    return boom.reshape(drive.shape)


def _quantiles(values: pd.Series) -> str:
    p10, p50, p90 = np.percentile(values, [10, 50, 90])
    return f"{p10:6.2f} {p50:6.2f} {p90:6.2f}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--demos", type=Path, required=True, help="a recorded summer dataset")
    parser.add_argument("--conditions", nargs="+", default=list(CONDITIONS))
    parser.add_argument("--throttles", nargs="+", type=float, default=[0.2, 0.6])
    parser.add_argument("--starts", type=int, default=3, help="seeded starts per push")
    parser.add_argument(
        "--band",
        type=float,
        nargs=2,
        default=list(BAND_MPA),
        metavar=("LOW", "HIGH"),
        help="part 3's drive-pressure band [MPa]",
    )
    parser.add_argument("--checkpoint", type=Path, action="append", default=[])
    args = parser.parse_args()
    if args.starts < 1:
        parser.error(f"--starts: must be >= 1, got {args.starts}")
    bad = [t for t in args.throttles if not 0.0 < t <= 1.0]
    if bad:
        parser.error(f"--throttles: each must be in (0, 1], got {bad}")
    if not 0.0 <= args.band[0] < args.band[1]:
        parser.error(f"--band: needs 0 <= LOW < HIGH, got {args.band}")
    unknown = sorted(set(args.conditions) - set(CONDITIONS))
    if unknown:
        parser.error(f"--conditions: unknown {unknown}; known: {list(CONDITIONS)}")
    missing = [str(p) for p in [args.demos, *args.checkpoint] if not p.exists()]
    if missing:
        parser.error(f"not found: {missing}")

    from pilerl.data.export import episodes_to_frame
    from pilerl.data.store import EpisodeStore

    frame = episodes_to_frame(EpisodeStore.open(args.demos))
    onsets = lift_onsets(frame)
    if onsets.empty:
        raise SystemExit(f"{args.demos}: no episode lifts (boom command > {LIFT_COMMAND})")
    print(f"1. first lifts of {args.demos}: {len(onsets)} episodes, p10 / p50 / p90 [MPa]")
    print(f"   p_d at the lift          {_quantiles(onsets['drive_mpa'])}")
    print(f"   p_t at the lift          {_quantiles(onsets['telescope_mpa'])}")
    print(f"   p_d, most before it      {_quantiles(onsets['drive_max_before_mpa'])}")
    print(f"   p_t, most before it      {_quantiles(onsets['telescope_max_before_mpa'])}")
    print(f"   time of the lift [s]     {_quantiles(onsets['time_s'])}")

    print(
        f"\n2. pushes: boom and bucket held, {args.starts} starts x {PUSH_S:.0f} s; in contact "
        f"(depth > {CONTACT_DEPTH_M * 100:.0f} cm) [MPa]; reach = share of the first lifts at "
        "or below the peak"
    )
    print(
        f"   {'condition':<10}{'throttle':>9}{'p_d p90':>9}{'p_t p90':>9}{'p_t impact':>11}"
        f"{'reach p_d':>10}{'reach p_t':>10}"
    )
    for condition in args.conditions:
        for throttle in args.throttles:
            r = push(condition, throttle, args.starts)
            reach_d = float((onsets["drive_mpa"] <= r["drive_max"]).mean())
            reach_t = float((onsets["telescope_mpa"] <= r["telescope_max"]).mean())
            print(
                f"   {condition:<10}{throttle:>9.2f}{r['drive_p90']:>9.1f}"
                f"{r['telescope_p90']:>9.2f}{r['impact']:>11.2f}{reach_d:>10.2f}{reach_t:>10.2f}",
                flush=True,
            )

    low, high = args.band
    print(f"\n3. the demonstrations' samples with p_d {low:g}-{high:g} MPa: p_t p10 / p50 / p90")
    for kind, telescope in band_split(frame, (low, high)).items():
        spread = _quantiles(telescope) if len(telescope) else "   (none)"
        print(f"   {kind:<8} {len(telescope):>7} samples  {spread}")

    posture = (float(onsets["boom_angle_rad"].median()), float(onsets["bucket_angle_rad"].median()))
    for checkpoint in args.checkpoint:
        grid = boom_response(checkpoint, posture)
        print(
            f"\n4. {checkpoint}: boom command at the approach posture (boom {posture[0]:.3f}, "
            f"bucket {posture[1]:.3f} rad); rows p_d, columns p_t [MPa]"
        )
        print("   " + " " * 8 + "".join(f"{t:>6.1f}" for t in GRID_TELESCOPE_MPA))
        for drive, row in zip(GRID_DRIVE_MPA, grid, strict=True):
            print(f"   p_d {drive:4.0f}" + "".join(f"{v:>6.2f}" for v in row))


if __name__ == "__main__":
    main()
