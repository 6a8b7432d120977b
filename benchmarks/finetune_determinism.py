"""Max |dw| between fine-tuning runs with the same seed (PPO, ``single`` collection).

    python benchmarks/finetune_determinism.py --frames 512

Runs ``finetune`` twice with the same seed on a freshly initialised NNetV2 (synthetic
normalisation statistics, no dataset needed) and prints the largest weight difference
between the two ``final.pt``, next to the largest change from the starting weights (the
scale of what fine-tuning moved). Uses only the public API, so it runs on older pilerl
versions too (for a before / after comparison).
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import torch

from pilerl.loggers import LoggerConfig
from pilerl.policies import actor_policy, load_actor, make_actor, save_actor
from pilerl.rl import (
    CollectionConfig,
    CurriculumConfig,
    CurriculumStage,
    EvaluationConfig,
    FinetuneConfig,
    PPOConfig,
    finetune,
)
from pilerl.runtime import limit_threads

S = ["boom_angle", "bucket_angle", "drive_pressure", "telescope_pressure"]
STATS = {
    "sensors": {name: {"mean": 0.0, "std": 1.0} for name in S},
    "action": {"mean": [0.0, 0.0, 0.0], "std": [1.0, 1.0, 1.0]},
}


def run_config(checkpoint: Path, run_dir: Path, frames: int, seed: int) -> FinetuneConfig:
    return FinetuneConfig(
        checkpoint=str(checkpoint),
        demos=None,
        algorithm=PPOConfig(frames_per_batch=128, epochs=2, minibatch_size=64),
        curriculum=CurriculumConfig(
            stages=[CurriculumStage(frames=frames, conditions={"winter_c": 1.0, "summer": 1.0})]
        ),
        reward_weights={"reward_fill": 1.0, "reward_success": 1.0, "reward_time": 1.0},
        collection=CollectionConfig(envs_per_worker=4),
        evaluation=EvaluationConfig(
            groups={"winter": ["winter_c"]}, every_frames=0, episodes=1, final_episodes=1
        ),
        logger=LoggerConfig(backend="none"),
        seed=seed,
        output_dir=str(run_dir),
    )


def max_abs_difference(a: dict, b: dict) -> float:
    return max(float((a[k].float() - b[k].float()).abs().max()) for k in a)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=512, help="frames per run")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    limit_threads()
    root = Path(tempfile.mkdtemp(prefix="determinism_"))
    torch.manual_seed(0)
    checkpoint = save_actor(root / "cloned.pt", make_actor("nnetv2", sensors=S, stats=STATS))
    weights, seconds = [], []
    for run in ("a", "b"):
        started = time.perf_counter()
        finetune(run_config(checkpoint, root / run, args.frames, args.seed), root / run)
        seconds.append(time.perf_counter() - started)
        weights.append(actor_policy(load_actor(root / run / "final.pt")).state_dict())
    start = actor_policy(load_actor(checkpoint)).state_dict()
    print("| quantity | value |")
    print("|---|---|")
    print(f"| frames per run | {args.frames} |")
    print(f"| run time a, b [s] | {seconds[0]:.1f}, {seconds[1]:.1f} |")
    print(f"| max abs dw, same seed | {max_abs_difference(weights[0], weights[1]):.3g} |")
    print(f"| max abs dw, start -> run a | {max_abs_difference(weights[0], start):.3g} |")


if __name__ == "__main__":
    main()
