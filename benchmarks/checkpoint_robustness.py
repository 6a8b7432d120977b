"""Case table of checkpoint safety: attacked files and SIGKILLed fine-tuning runs.

    python benchmarks/checkpoint_robustness.py --cases 40 --kills 8 --rounds 2

For each base file (a NNet ``best.pt``, a random-forest ``best.pt``, a TD3+BC
``last.ckpt``) and each attack of ``tests/policies/checkpoint_cases.py`` (bit flips, truncation,
appended bytes, pickled objects, huge declared sizes, NaN/inf), ``--cases`` seeded cases;
a case is clean when the file is refused with ``CheckpointError`` naming it, or loads
identical to the original. Then ``--rounds`` times: the finetune recipe (tiny budget) is
SIGKILLed ``--kills`` times at seeded random moments (each kill is clean when
``last.ckpt`` is absent or whole afterwards), then run to the end (clean when its final
weights equal an uninterrupted run's, with no temporary files and no repeated log rows;
temporary files and a torn log row, as a kill during a write leaves them, are planted
before it).
Prints ``test | cases | clean | defects`` and the defects found.
"""

from __future__ import annotations

import argparse
import collections
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from checkpoint_cases import (  # noqa: E402
    ATTACKS,
    CLEAN,
    Attack,
    actor_huge_edits,
    resumed_state,
    run_huge_edits,
    same_actor,
    same_tree,
    small_actor_file,
    small_forest_file,
    small_run_file,
    verdict,
)
from test_checkpoint_safety import (  # noqa: E402
    assert_run_matches,
    kill_recipe_at_random_moments,
    plant_interrupted_writes,
    recipe_command,
    reference_run,
)

from pilerl.policies import load_actor  # noqa: E402
from pilerl.runtime import limit_threads  # noqa: E402


def attack_rows(root: Path, cases: int) -> list[tuple[str, int, int, list[str]]]:
    nnet, forest = small_actor_file(root), small_forest_file(root)
    (root / "run").mkdir()
    run = small_run_file(nnet, root / "run")
    load_run_state = resumed_state(nnet)
    original_run = load_run_state(run)
    bases = {
        "best.pt (nnet)": (nnet, load_actor, same_actor(nnet), actor_huge_edits(nnet)),
        "best.pt (forest)": (forest, load_actor, same_actor(forest), actor_huge_edits(forest)),
        "last.ckpt (td3bc)": (
            run,
            load_run_state,
            lambda got: same_tree(list(got), list(original_run)),
            run_huge_edits(run),
        ),
    }
    rows = []
    for name, (original, load, same, huge) in bases.items():
        for kind in ATTACKS:
            outcomes = collections.Counter()
            for seed in range(cases):
                scratch = root / f"case_{len(rows)}_{seed}"
                scratch.mkdir()
                target = scratch / original.name
                Attack(kind, seed).apply(original, target, scratch / "code-ran", huge)
                outcomes[verdict(load, target, scratch / "code-ran", same)] += 1
            defects = [f"{k} x{n}" for k, n in outcomes.items() if k not in CLEAN]
            clean = sum(n for k, n in outcomes.items() if k in CLEAN)
            rows.append((f"{name}: {kind}", cases, clean, defects))
    return rows


def kill_rows(root: Path, kills: int, rounds: int) -> list[tuple[str, int, int, list[str]]]:
    checkpoint = small_actor_file(root)
    run_s = reference_run(checkpoint, root / "reference")
    kill_outcomes, resumed_clean, kill_defects, defects = collections.Counter(), 0, [], []
    for round_ in range(rounds):
        run_dir = root / f"killed_{round_}"
        try:
            left = kill_recipe_at_random_moments(
                checkpoint, run_dir, kills=kills, seed=1000 + round_, run_s=run_s
            )
            kill_outcomes.update(left)
        except Exception as error:  # noqa: BLE001 - a broken last.ckpt is the defect counted
            kill_defects.append(f"kill left {type(error).__name__}: {error}")
            continue
        plant_interrupted_writes(run_dir)
        result = subprocess.run(
            recipe_command(checkpoint, run_dir), capture_output=True, text=True, timeout=600
        )
        try:
            assert result.returncode == 0, result.stderr[-500:]
            assert_run_matches(run_dir, root / "reference")
            resumed_clean += 1
        except AssertionError as error:
            defects.append(f"resume: {error}")
    kills_done = sum(kill_outcomes.values())
    left = ", ".join(f"{k} {n}" for k, n in sorted(kill_outcomes.items()))
    return [
        (f"kill -9 of finetune ({left})", kills * rounds, kills_done, kill_defects),
        ("resume after kills: same weights, no leftovers", rounds, resumed_clean, defects),
    ]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", type=int, default=40, help="seeded cases per attack")
    parser.add_argument("--kills", type=int, default=8, help="SIGKILLs per round")
    parser.add_argument("--rounds", type=int, default=2, help="kill-then-resume rounds")
    args = parser.parse_args()
    limit_threads()
    started = time.perf_counter()
    with tempfile.TemporaryDirectory() as scratch:
        root = Path(scratch)
        rows = attack_rows(root, args.cases)
        if args.kills and args.rounds:
            rows += kill_rows(root, args.kills, args.rounds)
    print("| test | cases | clean | defects |")
    print("|---|---|---|---|")
    for name, cases, clean, _ in rows:
        print(f"| {name} | {cases} | {clean} | {cases - clean} |")
    total, clean = sum(r[1] for r in rows), sum(r[2] for r in rows)
    print(f"| **total** | {total} | {clean} | {total - clean} |")
    for name, _, _, defects in rows:
        for defect in defects:
            print(f"defect in {name}: {defect}")
    print(f"({time.perf_counter() - started:.0f} s)")


if __name__ == "__main__":
    main()
