"""Can a controller learn the demonstrations from its sensors? Operators side by side.

Records ``--episodes`` demonstrations per operator at ``--hz`` (episode i: env seed
``seed * 100_000 + i`` and an operator style drawn from ``default_rng([seed, i])``, as the
recorder does), then prints, per operator:

- R² boom / bucket / throttle: the share of each command's variance that gradient-boosted
  trees explain from the four controller sensors <boom_angle, bucket_angle, drive_pressure,
  telescope_pressure> now and 0.25 / 0.5 / 1.0 s earlier, cross-validated by episode
  (``pilerl.evaluation.metrics.explainable_variance``); ``now only``: without the history.
- mean episode length [s], and separately of the full and of the other episodes, share of
  samples with exactly one active control (|u| > 0.05), success rate and mean fill, beside
  the paper's values (its 72 summer demonstrations: 709,368 samples at 500 Hz = 19.7 s each,
  88 % single-control, 52 of 72 full = 72 %; D_II, the 52 full ones at 20 Hz, has 16,322
  samples = 15.7 s each, which leaves 30.1 s for each of the other 20 if D_II keeps whole
  episodes).

Operators: ``before`` = the timer-driven ``pilerl.operators`` operator (while it exists),
``after`` = the pile loader's own expert (``pilerl_pile_loader.operator.make_expert``),
``after+dart`` = the same with ``executed_noise`` (the labels stay clean; the table
scores the labels).

    python benchmarks/demo_explainability.py                         # 24 summer episodes
    python benchmarks/demo_explainability.py --operators after --episodes 12 --hz 10
    python benchmarks/demo_explainability.py --operators after --soil-option intake=mouth \
        --expert-option crowd_fill=true --condition winter_a \
        --overrides '{"material": {"cohesion_pa": 0}}'
"""

from __future__ import annotations

import argparse
import os
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")

import gymnasium as gym  # noqa: E402
import numpy as np  # noqa: E402
from pilerl_pile_loader.conditions import overrides_argument  # noqa: E402
from pilerl_pile_loader.operator import make_expert  # noqa: E402

import pilerl  # noqa: E402,F401  (registers the simulator)
from pilerl.evaluation.metrics import explainable_variance  # noqa: E402

CONTROLLER_SENSORS = ("boom_angle", "bucket_angle", "drive_pressure", "telescope_pressure")
HISTORY_S = (0.25, 0.5, 1.0)
ACTIVE = 0.05  # |u| above this is an active control
PAPER = {"length_s": 709_368 / 72 / 500, "single": 0.88, "success": 52 / 72}
PAPER["full_s"] = 16_322 / 52 / 20  # D_II: the 52 full demonstrations at 20 Hz
PAPER["other_s"] = (709_368 / 500 - 16_322 / 20) / 20  # the rest of D_I's time
DART_NOISE = 0.1


def build_operator(
    kind: str,
    dt: float,
    rng: np.random.Generator,
    trigger_sensor: str,
    expert_options: dict[str, object] | None = None,
):
    if kind == "before":
        try:
            from pilerl.operators import ScriptedScoopOperator, sample_style
        except ImportError as error:  # removed: run this script on a checkout of 0acad0f
            raise SystemExit(
                f"operator 'before' (the timer-driven one) is not in this checkout: {error}; "
                "measure it on commit 0acad0f"
            ) from error
        style = sample_style(rng, trigger_sensor=trigger_sensor)
        return ScriptedScoopOperator(style, dt=dt)
    noise = DART_NOISE if kind == "after+dart" else 0.0
    return make_expert(
        dt=dt,
        rng=rng,
        trigger_sensor=trigger_sensor,
        executed_noise=noise,
        **(expert_options or {}),
    )


def soil_options(pairs: list[str], flag: str = "--soil-option") -> dict[str, object]:
    """``--soil-option KEY=VALUE`` pairs as the simulator's ``soil_options`` (``true`` and
    ``false`` as booleans, numbers as floats, anything else as text); ``flag`` names the
    option in errors (``--expert-option`` pairs are read the same way)."""
    options: dict[str, object] = {}
    for pair in pairs:
        key, sep, text = pair.partition("=")
        if not sep or not key:
            raise SystemExit(f"{flag}: expected KEY=VALUE, got {pair!r}")
        if text in ("true", "false"):
            options[key] = text == "true"
        else:
            try:
                options[key] = float(text)
            except ValueError:
                options[key] = text
    return options


def record(kind: str, args: argparse.Namespace) -> dict:
    """Record ``args.episodes`` episodes with operator ``kind``; readings, labels, results."""
    env = gym.make(
        "pilerl/PileLoading-v0",
        condition=args.condition,
        control_hz=args.hz,
        soil_options=soil_options(args.soil_option),
        condition_overrides=args.overrides,
    )
    dt = float(env.unwrapped.dt)
    expert_options = soil_options(args.expert_option, "--expert-option")
    episodes, lengths, successes, fills = [], [], [], []
    for i in range(args.episodes):
        rng = np.random.default_rng([args.seed, i])
        operator = build_operator(kind, dt, rng, args.trigger, expert_options)
        operator.reset()
        obs, _ = env.reset(seed=args.seed * 100_000 + i)
        readings = {name: [] for name in CONTROLLER_SENSORS}
        labels = []
        while True:
            for name in CONTROLLER_SENSORS:
                readings[name].append(float(obs[name][0]))
            executed = operator.act(obs)
            labels.append(getattr(operator, "last_label", executed))
            obs, _, terminated, truncated, info = env.step(executed)
            if terminated or truncated:
                break
        episodes.append(({k: np.array(v) for k, v in readings.items()}, np.array(labels)))
        lengths.append(float(info["elapsed_s"]))
        successes.append(bool(info["success"]))
        fills.append(float(info["fill_fraction"]))
    env.close()
    return {"episodes": episodes, "dt": dt, "lengths": lengths, "success": successes, "fill": fills}


def measure(recording: dict) -> dict:
    episodes, dt = recording["episodes"], recording["dt"]
    labels = np.concatenate([a for _, a in episodes])
    active = (np.abs(labels) > ACTIVE).sum(axis=1)
    return {
        "r2": explainable_variance(episodes, dt=dt, history_s=HISTORY_S),
        "r2_now": explainable_variance(episodes, dt=dt, history_s=()),
        "length_s": float(np.mean(recording["lengths"])),
        "full_s": _mean_where(recording["lengths"], recording["success"], True),
        "other_s": _mean_where(recording["lengths"], recording["success"], False),
        "single": float(np.mean(active == 1)),
        "success": float(np.mean(recording["success"])),
        "fill": float(np.mean(recording["fill"])),
        "fill_capped": float(np.mean(np.asarray(recording["fill"]) >= 1.09)),
    }


def _mean_where(values: list[float], flags: list[bool], flag: bool) -> float:
    chosen = [v for v, f in zip(values, flags, strict=True) if f == flag]
    return float(np.mean(chosen)) if chosen else float("nan")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--operators", default="before,after,after+dart")
    parser.add_argument("--episodes", type=int, default=24)
    parser.add_argument("--hz", type=float, default=20.0)
    parser.add_argument("--condition", default="summer")
    parser.add_argument("--trigger", default="drive_pressure")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--soil-option",
        nargs="*",
        default=[],
        help="KEY=VALUE soil options, e.g. body_resistance=true intake=mouth (docs/soil_models.md)",
    )
    parser.add_argument(
        "--expert-option",
        nargs="*",
        default=[],
        help="KEY=VALUE options of the pile loader's expert (operators after, after+dart), "
        "e.g. crowd_fill=true (docs/operators.md)",
    )
    parser.add_argument(
        "--overrides",
        type=overrides_argument,
        default=None,
        help='condition overrides as JSON, e.g. \'{"material": {"cohesion_pa": 0}}\'',
    )
    args = parser.parse_args()

    print(
        f"{args.episodes} {args.condition} episodes per operator at {args.hz:g} Hz, seed "
        f"{args.seed}; soil {soil_options(args.soil_option)}, expert "
        f"{soil_options(args.expert_option, '--expert-option')}, overrides {args.overrides}; "
        f"R²: episode-wise {min(4, args.episodes)}-fold CV, sensors "
        f"{CONTROLLER_SENSORS} + history {HISTORY_S} s"
    )
    header = (
        f"{'operator':<11} {'R² boom':>8} {'bucket':>7} {'throttle':>8} | {'now only':>17} | "
        f"{'length s':>8} {'full':>5} {'other':>5} {'single':>7} {'success':>7} {'fill':>5} "
        f"{'fill≥1.09':>9} {'wall s':>6}"
    )
    print(header)
    print("-" * len(header))
    for kind in args.operators.split(","):
        start = time.perf_counter()
        m = measure(record(kind, args))
        wall = time.perf_counter() - start
        r2, now = m["r2"], m["r2_now"]
        print(
            f"{kind:<11} {r2[0]:8.2f} {r2[1]:7.2f} {r2[2]:8.2f} | "
            f"{now[0]:5.2f} {now[1]:5.2f} {now[2]:5.2f} | {m['length_s']:8.1f} "
            f"{m['full_s']:5.1f} {m['other_s']:5.1f} {m['single']:7.0%} {m['success']:7.0%} "
            f"{m['fill']:5.2f} {m['fill_capped']:9.0%} "
            f"{wall:6.0f}"
        )
    print(
        f"{'paper':<11} {'':>8} {'':>7} {'':>8} | {'':>17} | {PAPER['length_s']:8.1f} "
        f"{PAPER['full_s']:5.1f} {PAPER['other_s']:5.1f} {PAPER['single']:7.0%} "
        f"{PAPER['success']:7.0%}"
    )


if __name__ == "__main__":
    main()
