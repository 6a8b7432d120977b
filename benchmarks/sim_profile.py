"""Where a control step spends its time: cProfile's top entries of a simulator path.

Paths (fixed action, no sensor noise, the default pile loader, one thread):

- ``loop``: the env's own ``step`` in a plain loop (physics, soil model, sensors, info);
- ``torchrl``: ``make_torchrl_env().rollout`` (one simulator, batch ``[]``);
- ``batch4``: ``make_torchrl_env(num_envs=4).rollout`` (one tensordict for 4 simulators).
- ``collect8``: fine-tuning's collection as ``benchmarks/collection_speed.py`` row 4: a
  TorchRL ``Collector`` over 8 ``ConditionMixtureEnv`` simulators batched in one
  ``SimulatorBatchEnv``, the stochastic untrained DANNet acting through PPO's fused
  sampler (``--steps`` frames, batches of 1024).

The profile is taken after one untimed run (imports, compiled models), sorted by own
time and by cumulative time; ``--out`` writes the text (docs/performance/ keeps them).
cProfile inflates Python-heavy code more than ``mj_step``: read it for where the time goes,
and ``benchmarks/sim_speed.py`` for the speed. ``--cpu`` times with the process's CPU time
instead of the wall clock, so that other processes on a loaded machine do not show up as
time spent in whatever was running when they took the core.

    python benchmarks/sim_profile.py loop --out docs/performance/sim_step_profile_after.txt
    python benchmarks/sim_profile.py torchrl --steps 800
    python benchmarks/sim_profile.py collect8 --steps 2048 --cpu
"""

from __future__ import annotations

import argparse
import cProfile
import io
import os
import pstats
import sys
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import gymnasium as gym  # noqa: E402
import numpy as np  # noqa: E402
import torch  # noqa: E402

import pilerl  # noqa: E402,F401
from pilerl.sim import make_torchrl_env  # noqa: E402

ACTION = np.array([0.15, 0.1, 0.5], dtype=np.float32)


def path_runner(path: str, steps: int):
    """A callable running ``steps`` control steps along ``path``."""
    action = torch.as_tensor(ACTION)

    def policy(tensordict):
        return tensordict.set("action", action.expand(*tensordict.batch_size, 3))

    if path == "loop":
        env = gym.make("pilerl/PileLoading-v0", sensor_noise=0.0).unwrapped
        env.reset(seed=0)

        def run() -> None:
            for _ in range(steps):
                *_, terminated, truncated, _ = env.step(ACTION)
                if terminated or truncated:
                    env.reset()

        return run
    if path == "collect8":
        return collector_runner(steps)
    num_envs = 4 if path == "batch4" else 1
    env = make_torchrl_env(sensor_noise=0.0, seed=0, num_envs=num_envs)
    env.rollout(3, policy)
    return lambda: env.rollout(steps // num_envs, policy, break_when_any_done=False)


def collector_runner(frames: int):
    """``collection_speed.py``'s row 4: a Collector over 8 batched training simulators."""
    sys.path.insert(0, str(Path(__file__).parent))
    from collection_speed import CONDITIONS, REWARDS, cloned_actor, collection_policy

    from pilerl.rl.collection import make_collector
    from pilerl.rl.envs import TrainingEnvFactory

    torch.manual_seed(0)
    factory = TrainingEnvFactory("pile_loader", {}, CONDITIONS, REWARDS, num_envs=8)
    per_batch = min(frames, 1024)
    collector = make_collector(
        factory,
        collection_policy(cloned_actor(None), "fused"),  # what PPO collects with
        frames_per_batch=per_batch,
        total_frames=10**9,  # as many batches as asked for
        backend="single",
        workers=1,
    )
    batches = iter(collector)

    def run() -> None:
        for _ in range(max(frames // per_batch, 1)):
            next(batches)

    return run


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("path", choices=["loop", "torchrl", "batch4", "collect8"])
    parser.add_argument("--steps", type=int, default=800, help="control steps profiled")
    parser.add_argument("--top", type=int, default=25)
    parser.add_argument("--out", type=Path, default=None)
    parser.add_argument("--cpu", action="store_true", help="time with the process's CPU time")
    args = parser.parse_args()
    torch.set_num_threads(1)
    run = path_runner(args.path, args.steps)
    run()  # untimed: warm caches
    profile = cProfile.Profile(time.process_time) if args.cpu else cProfile.Profile()
    profile.enable()
    run()
    profile.disable()
    text = io.StringIO()
    what = "frames" if args.path == "collect8" else "control steps"
    clock = "CPU time" if args.cpu else "wall clock"
    text.write(f"# {args.path}: {args.steps} {what}, {clock} (python {' '.join(sys.argv)})\n")
    stats = pstats.Stats(profile, stream=text)
    stats.sort_stats("tottime").print_stats(args.top)
    stats.sort_stats("cumulative").print_stats(args.top + 10)
    report = text.getvalue()
    for prefix in sorted({str(Path(p).parent) for p in (torch.__file__, np.__file__)}):
        report = report.replace(str(Path(prefix).parent) + "/", "")
    report = report.replace(str(Path.cwd()) + "/", "")
    if args.out:
        args.out.write_text(report)
    print(report)


if __name__ == "__main__":
    main()
