"""Where a control step spends its time: cProfile's top entries of a simulator path.

Paths (fixed action, no sensor noise, the default pile loader, one thread):

- ``loop``: the env's own ``step`` in a plain loop (physics, soil model, sensors, info);
- ``torchrl``: ``make_torchrl_env().rollout`` (one simulator, batch ``[]``);
- ``batch4``: ``make_torchrl_env(num_envs=4).rollout`` (one tensordict for 4 simulators).

The profile is taken after one untimed run (imports, compiled models), sorted by own
time and by cumulative time; ``--out`` writes the text (docs/performance/ keeps them).
cProfile inflates Python-heavy code more than ``mj_step``: read it for where the time goes,
and ``benchmarks/sim_speed.py`` for the speed.

    python benchmarks/sim_profile.py loop --out docs/performance/sim_step_profile_after.txt
    python benchmarks/sim_profile.py torchrl --steps 800
"""

from __future__ import annotations

import argparse
import cProfile
import io
import os
import pstats
import sys
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
    num_envs = 4 if path == "batch4" else 1
    env = make_torchrl_env(sensor_noise=0.0, seed=0, num_envs=num_envs)
    env.rollout(3, policy)
    return lambda: env.rollout(steps // num_envs, policy, break_when_any_done=False)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("path", choices=["loop", "torchrl", "batch4"])
    parser.add_argument("--steps", type=int, default=800, help="control steps profiled")
    parser.add_argument("--top", type=int, default=25)
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    torch.set_num_threads(1)
    run = path_runner(args.path, args.steps)
    run()  # untimed: warm caches
    profile = cProfile.Profile()
    profile.enable()
    run()
    profile.disable()
    text = io.StringIO()
    text.write(f"# {args.path}: {args.steps} control steps (python {' '.join(sys.argv)})\n")
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
