"""Read-only measurements behind README.md's "Why, as far as measured".

Run from the repository root after the Exp. 1-3 sweeps:
    python docs/results/paper/measure_reasons.py
It prints, per cell (controller, inputs, data, summer or winter A-D pooled): episodes,
successes, median fill, median first boom lift and penetration time (s), median episode
length (s), finished scoops, median peak wheel slip (m/s) and the failure modes; then
paired sign tests over the same (training seed, condition, start) and the demonstrations'
success by operator style; and, where they were run, the D_I checks (README, "D_I fails
for every trainer"): NNetV2 and RF with p_t on D_II, D_I and D_I of the successful
demonstrations only, and NNetV2 on D_I at the paper's 150 epochs. Writes nothing.

The D_I checks' sweeps (about 25 and 20 minutes on one core):
    python recipes/build_dataset.py dataset=d_i dataset.successful_only=true \
        out_dir=data/datasets/d_i_success_summer
    D=data/datasets
    python recipes/train_bc.py --multirun +experiment=exp2_data_and_pt seed=0,1,2 \
        policy=nnetv2,rf sensors=s_pt evaluation.workers=1 evaluation.videos=false \
        train_data=$D/d_ii_summer,$D/d_i_summer,$D/d_i_success_summer \
        hydra.sweep.dir=multirun/d_i_check
    python recipes/train_bc.py --multirun +experiment=exp2_data_and_pt seed=0,1,2 \
        policy=nnetv2 sensors=s_pt train_data=data/datasets/d_i_summer gradient_steps=null \
        evaluation.workers=1 evaluation.videos=false hydra.sweep.dir=multirun/d_i_150_epochs
"""

from __future__ import annotations

import csv
import json
import statistics
from collections import Counter
from math import comb
from pathlib import Path

SWEEPS = ["exp1_summer_to_winter", "exp2_data_and_pt", "exp3_attention"]
# the D_I checks' sweeps, where run (the 150-epoch sweep's seed 2 may run on its own, in
# d_i_150_epochs_seed2, beside seeds 0-1 on a second core)
D_I_CHECKS = ["d_i_check", "d_i_150_epochs", "d_i_150_epochs_seed2"]
Cell = tuple[str, str, str]


def cell_of(settings: dict) -> Cell:
    """(controller, inputs, dataset) of one job's saved settings."""
    inputs = "s" + ("+pt" if "telescope_pressure" in settings["sensors.s"] else "")
    inputs += "+s'" if settings["sensors.s_prime"] else ""
    data = "D_I" if "d_i_" in settings["train_data"] else "D_II"
    return settings["policy.name"], inputs, data


def d_i_check_cell_of(settings: dict) -> Cell:
    """(controller, inputs, dataset) of a D_I check's job: the dataset named by what
    distinguishes it (D_I of the successful demonstrations, or at 150 epochs)."""
    policy, inputs, data = cell_of(settings)
    if "d_i_success" in settings["train_data"]:
        data = "D_I successful only"
    elif data == "D_I" and settings["gradient_steps"] is None:
        data = f"D_I {settings['epochs']} epochs"
    return policy, inputs, data


def load_episodes(
    root: Path, sweeps: list[str] = SWEEPS, cell_of_job=cell_of, refuse_repeats: bool = False
) -> dict[Cell, dict[tuple, dict]]:
    """Every evaluated episode per cell (``cell_of_job`` of each job's settings), keyed by
    (training seed, condition, episode). A cell two sweeps share (Exp. 1's cells are also
    in Exp. 2) keeps the later sweep's episodes; with ``refuse_repeats`` a repeated key
    (the same seed of a cell in two sweeps) fails instead."""
    cells: dict[Cell, dict[tuple, dict]] = {}
    for sweep in sweeps:
        for run in sorted((root / "multirun" / sweep).glob("*/run.json")):
            table = run.parent / "evaluation" / "episodes.csv"
            if not table.exists():  # a job still running (or never evaluated)
                continue
            settings = json.loads(run.read_text())["settings"]
            episodes = cells.setdefault(cell_of_job(settings), {})
            with open(table) as f:
                for row in csv.DictReader(f):
                    key = (settings["seed"], row["condition"], row["episode"])
                    if refuse_repeats and key in episodes:
                        raise SystemExit(f"{run.parent}: seed {key[0]} evaluated twice")
                    episodes[key] = row
    return cells


def median(rows: list[dict], column: str) -> float:
    values = [float(r[column]) for r in rows if r[column] not in ("", "nan")]
    return statistics.median(values) if values else float("nan")


def sign_test_p(a: int, b: int) -> float:
    """Two-sided exact sign test on a and b discordant pairs."""
    n = a + b
    return min(1.0, 2 * sum(comb(n, i) for i in range(min(a, b) + 1)) / 2**n) if n else 1.0


def main() -> None:
    root = Path.cwd()
    cells = load_episodes(root)
    print("cell | test | n | ok | fill | lift s | pen s | len s | done | slip | failures")
    for cell, episodes in sorted(cells.items()):
        for test in ("summer", "winter"):
            rows = [r for k, r in episodes.items() if (k[1] == "summer") == (test == "summer")]
            if not rows:
                continue
            modes = Counter(r["failure_mode"] for r in rows if r["failure_mode"] != "success")
            print(
                " ".join(cell), test, len(rows), sum(r["success"] == "True" for r in rows),
                f"{median(rows, 'fill_fraction'):.2f} {median(rows, 'first_lift_s'):.1f}",
                f"{median(rows, 'penetration_s'):.1f} {median(rows, 'elapsed_s'):.1f}",
                sum(r["scoop_finished"] == "True" for r in rows),
                f"{median(rows, 'max_wheel_slip_m_s'):.2f}", dict(modes),
            )  # fmt: skip
    pairs = [
        (("nnetv2", "s+pt", "D_II"), ("nnetv2", "s", "D_II")),
        (("rf", "s+pt", "D_II"), ("rf", "s", "D_II")),
        (("rf", "s+pt", "D_I"), ("rf", "s", "D_I")),
        (("dannet", "s+pt+s'", "D_II"), ("nnetv2", "s+pt", "D_II")),
        (("annet", "s+pt+s'", "D_II"), ("nnetv2", "s+pt", "D_II")),
        (("dannet", "s+pt+s'", "D_I"), ("nnetv2", "s+pt", "D_I")),
        (("annet", "s+pt", "D_II"), ("annet", "s", "D_II")),
        (("dannet", "s+pt", "D_II"), ("dannet", "s", "D_II")),
    ]
    print("\npaired over (training seed, winter day, start): A vs B")
    for a_cell, b_cell in pairs:
        a_ok, b_ok = paired_winter(cells[a_cell], cells[b_cell])
        a_only = sum(a and not b for a, b in zip(a_ok, b_ok, strict=True))
        b_only = sum(b and not a for a, b in zip(a_ok, b_ok, strict=True))
        print(
            " ".join(a_cell), f"{sum(a_ok)}/{len(a_ok)} vs", " ".join(b_cell),
            f"{sum(b_ok)}/{len(b_ok)}: {a_only} vs {b_only} better,"
            f"sign test p={sign_test_p(a_only, b_only):.2g}",
        )  # fmt: skip
    print("\ndemonstrations (data/demos/summer): success, samples, ran to 30 s, style")
    demos = json.loads((root / "data/demos/summer/index.json").read_text())["episodes"]
    for success in (True, False):
        group = [d for d in demos if d["success"] is success]
        style = Counter(operator_kind(d["operator"]["style"]) for d in group)
        print(
            "successful" if success else "failed", len(group),
            sum(d["n_samples"] for d in group),
            sum(d["n_samples"] / d["rate_hz"] >= 29.9 for d in group), dict(style),
        )  # fmt: skip
    print_d_i_checks(root)


def paired_winter(a: dict[tuple, dict], b: dict[tuple, dict]) -> tuple[list, list]:
    """Success of two cells' episodes on their shared winter keys (training seed, winter
    day, start), in the same order: two lists of booleans."""
    keys = [k for k in a.keys() & b.keys() if k[1].startswith("winter")]
    return [a[k]["success"] == "True" for k in keys], [b[k]["success"] == "True" for k in keys]


def operator_kind(style: dict) -> str:
    """The kind of a drawn operator (``operator.sample_style``): hesitant, jumpy, timid
    (curls 3-4 rad of floor pitch per rad of lift where the others curl 1.8) or other."""
    if style["hesitant"]:
        return "hesitant"
    if style["jumpy"]:
        return "jumpy"
    return "timid" if style["curl_per_lift"] > 2.0 else "other"


def print_d_i_checks(root: Path) -> None:
    """Winter A-D pooled success per D_I check cell, and paired sign tests against the
    same controller on D_I and on D_II (same training seed, day and start)."""
    present = [s for s in D_I_CHECKS if (root / "multirun" / s).is_dir()]
    if not present:
        return
    cells = load_episodes(root, present, d_i_check_cell_of, refuse_repeats=True)
    print("\nD_I checks (" + ", ".join(present) + "): winter A-D pooled")
    for cell, episodes in sorted(cells.items()):
        winter = {k: r for k, r in episodes.items() if k[1].startswith("winter")}
        rows = list(winter.values())
        per_seed = Counter(k[0] for k, r in winter.items() if r["success"] == "True")
        seeds = sorted({k[0] for k in episodes})
        modes = Counter(r["failure_mode"] for r in rows if r["failure_mode"] != "success")
        print(
            " ".join(cell), f"{sum(r['success'] == 'True' for r in rows)}/{len(rows)}",
            "per seed", [per_seed[s] for s in seeds], f"fill {median(rows, 'fill_fraction'):.2f}",
            f"lift {median(rows, 'first_lift_s'):.1f} s", dict(modes),
        )  # fmt: skip
    for cell in sorted(cells):
        for base in ("D_I", "D_II"):
            other = (cell[0], cell[1], base)
            if cell[2] in ("D_I", "D_II") or other not in cells:
                continue
            a_ok, b_ok = paired_winter(cells[cell], cells[other])
            a_only = sum(a and not b for a, b in zip(a_ok, b_ok, strict=True))
            b_only = sum(b and not a for a, b in zip(a_ok, b_ok, strict=True))
            print(
                " ".join(cell), "vs", base, f"({len(a_ok)} pairs): {a_only} vs {b_only}",
                f"better, sign test p={sign_test_p(a_only, b_only):.2g}",
            )  # fmt: skip


if __name__ == "__main__":
    main()
