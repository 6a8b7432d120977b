"""Do the pressures tell "bucket in the pile" from "driving up to it", in every condition?

The measurement of issue #15: drive at the pile with throttle 0.6, boom and bucket held,
from ``--starts`` seeded starts per condition (default 6), 8 s each, at 20 Hz with the
default sensor noise. Samples with ``cutting_depth_m`` > 5 cm are "contact", samples with
depth 0 "no contact" (the few in between are left out). Per condition it prints:

- ``p_t AUC`` / ``p_d AUC``: ROC AUC of the telescope / drive pressure as a contact
  detector (1 = separates perfectly, 0.5 = no information, < 0.5 = reads backwards);
- ``p_d p90``: the drive pressure's 90th percentile in contact [MPa], and ``/summer``,
  its ratio to summer's (the slip cap: well below 1 on ice);
- ``p_t med``: the telescope pressure's median in contact and without [MPa];
- ``p_d rip``: the drive pressure's ripple in contact, the median of its change between
  consecutive 20 Hz samples [MPa] (the 0.15 MPa sensor noise alone gives ~0.14 MPa): whether the
  pressure a controller reads is a machine's or a series of impacts.

``--soil particles`` measures on the particle pile instead (slow: ~0.4x real time), and
``--overrides JSON`` changes the condition's physical values (the env's
``condition_overrides``), e.g. the particle pile's loose material on the heightfield:

    python benchmarks/sensor_separability.py --conditions summer winter_c --starts 4 \
        --overrides '{"material": {"cohesion_pa": 0}}'
    python benchmarks/sensor_separability.py --conditions summer winter_c --starts 4 \
        --soil particles

With ``--baseline PATH`` (another checkout of the repository, e.g. one made with
``git worktree add /tmp/before <commit before the change>``) the same
measurement runs on that checkout's simulator in a subprocess and the table shows both,
BEFORE (the baseline) and AFTER (this checkout):

    python benchmarks/sensor_separability.py
    python benchmarks/sensor_separability.py --baseline /tmp/before --starts 6
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

CONDITIONS = ("summer", "winter_a", "winter_b", "winter_c", "winter_d")
THROTTLE = 0.6
SECONDS = 8.0
CONTACT_DEPTH_M = 0.05


def measure(
    conditions: tuple[str, ...],
    starts: int,
    *,
    soil: str = "heightfield",
    overrides: dict | None = None,
) -> dict[str, dict[str, float]]:
    """The drive-in measurement of this process's simulator, per condition, on ``soil``
    with ``overrides`` as the condition overrides."""
    import gymnasium as gym
    import numpy as np
    from sklearn.metrics import roc_auc_score

    import pilerl  # noqa: F401  (registers pilerl/PileLoading-v0)

    results = {}
    for condition in conditions:
        env = gym.make(
            "pilerl/PileLoading-v0", condition=condition, soil=soil, condition_overrides=overrides
        ).unwrapped
        rows, ripple = [], []
        for seed in range(starts):
            previous = None  # the last sample's drive pressure, if it was in contact
            obs, info = env.reset(seed=seed)
            while info["elapsed_s"] < SECONDS - 1e-9:
                obs, _, terminated, truncated, info = env.step(
                    np.array([0.0, 0.0, THROTTLE], dtype=np.float32)
                )
                depth, drive = info["cutting_depth_m"], float(obs["drive_pressure"][0])
                rows.append((depth, drive, float(obs["telescope_pressure"][0])))
                in_contact = depth > CONTACT_DEPTH_M
                if in_contact and previous is not None:
                    ripple.append(abs(drive - previous))
                previous = drive if in_contact else None
                if terminated or truncated:
                    break
        env.close()
        depth, p_d, p_t = np.array(rows).T
        contact, free = depth > CONTACT_DEPTH_M, depth == 0.0
        if not (contact.any() and free.any()):
            raise SystemExit(
                f"{condition}: {contact.sum()} contact and {free.sum()} no-contact samples; "
                "both are needed for an AUC (use more --starts)"
            )
        labels = np.r_[np.ones(contact.sum()), np.zeros(free.sum())]
        results[condition] = {
            "p_t_auc": float(roc_auc_score(labels, np.r_[p_t[contact], p_t[free]])),
            "p_d_auc": float(roc_auc_score(labels, np.r_[p_d[contact], p_d[free]])),
            "p_d_p90": float(np.percentile(p_d[contact], 90)),
            "p_t_contact": float(np.median(p_t[contact])),
            "p_t_free": float(np.median(p_t[free])),
            "p_d_ripple": float(np.median(ripple)) if ripple else float("nan"),
        }
    return results


def measure_checkout(root: Path, conditions: tuple[str, ...], starts: int) -> dict:
    """Run ``measure`` on another checkout's code in a subprocess (its own imports)."""
    env = {**os.environ, "PYTHONPATH": f"{root}{os.pathsep}{root / 'envs'}"}
    code = (
        f"import json, sys; sys.path.insert(0, {str(Path(__file__).parent)!r}); "
        "from sensor_separability import measure; "
        f"print(json.dumps(measure({tuple(conditions)!r}, {starts})))"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], env=env, cwd=root, capture_output=True, text=True
    )
    if out.returncode != 0:
        raise SystemExit(f"baseline measurement in {root} failed:\n{out.stderr}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def table(label: str, results: dict[str, dict[str, float]]) -> list[str]:
    summer_p90 = results.get("summer", {}).get("p_d_p90")
    lines = []
    for condition, r in results.items():
        ratio = f"{r['p_d_p90'] / summer_p90:7.2f}" if summer_p90 else "      -"
        lines.append(
            f"{label:<7}{condition:<10}{r['p_t_auc']:>8.2f}{r['p_d_auc']:>8.2f}"
            f"{r['p_d_p90']:>9.1f}{ratio}{r['p_t_contact']:>10.2f}{r['p_t_free']:>9.2f}"
            f"{r.get('p_d_ripple', float('nan')):>9.2f}"
        )
    return lines


def main() -> None:
    # imported here, not at the top: a --baseline checkout imports this module with its code
    from pilerl_pile_loader.conditions import overrides_argument

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--baseline", type=Path, help="checkout to measure as BEFORE")
    parser.add_argument("--starts", type=int, default=6, help="seeded starts per condition")
    parser.add_argument("--conditions", nargs="+", default=list(CONDITIONS))
    parser.add_argument("--soil", choices=("heightfield", "particles"), default="heightfield")
    parser.add_argument(
        "--overrides", type=overrides_argument, default=None, help="condition overrides (JSON)"
    )
    args = parser.parse_args()
    if args.baseline is not None and (args.soil != "heightfield" or args.overrides):
        parser.error("--baseline: measures the default heightfield only (no --soil, --overrides)")
    if args.starts < 1:
        parser.error(f"--starts: must be >= 1, got {args.starts}")
    unknown = sorted(set(args.conditions) - set(CONDITIONS))
    if unknown:
        parser.error(f"--conditions: unknown {unknown}; known: {list(CONDITIONS)}")
    if args.baseline is not None and not (args.baseline / "envs" / "pilerl_pile_loader").is_dir():
        parser.error(f"--baseline: {args.baseline} is not a checkout of this repository")
    conditions = tuple(args.conditions)
    header = (
        f"{'':<7}{'condition':<10}{'p_t AUC':>8}{'p_d AUC':>8}{'p_d p90':>9}{'/summer':>7}"
        f"{'p_t med c':>10}{'p_t med':>9}{'p_d rip':>9}"
    )
    lines = [header]
    if args.baseline is not None:
        lines += table("BEFORE", measure_checkout(args.baseline.resolve(), conditions, args.starts))
    after = measure(conditions, args.starts, soil=args.soil, overrides=args.overrides)
    lines += table("AFTER" if args.baseline is not None else "", after)
    print(
        f"drive-in on the {args.soil} soil: throttle {THROTTLE}, boom and bucket held, "
        f"{args.starts} starts x {SECONDS:.0f} s per condition; contact = depth > "
        f"{CONTACT_DEPTH_M * 100:.0f} cm"
        + (f"; condition overrides {args.overrides}" if args.overrides else "")
    )
    print("\n".join(lines))


if __name__ == "__main__":
    main()
