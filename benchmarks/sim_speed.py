"""Simulator speed: control steps/s and simulated seconds per wall second, per soil model.

For each soil model, in one run and with one intra-op thread:

- ``raw mj_step``: ``mujoco.mj_step`` alone on the same compiled model, the same number of
  physics steps (no soil, no Python per step): the ceiling.
- ``simulator loop``: the env's own ``step`` (physics + soil model + sensors), no wrappers.
- ``gymnasium``: ``gymnasium.make`` with its default wrappers.
- ``torchrl``: TorchRL ``GymEnv`` (``make_torchrl_env``) driven by ``rollout`` with a
  plain callable fixed-action policy.
- ``torchrl one process xN``: N simulators in one TorchRL env (``num_envs=N``).
- ``torchrl ParallelEnv P procs xK``: P worker processes (one per core), K simulators each.

The driving is the same for every row: throttle 0.5 with a slow boom/bucket sweep, so the
bucket spends most of the time in the pile; episodes reset when they end.

    python benchmarks/sim_speed.py                    # all soil models
    python benchmarks/sim_speed.py --soil heightfield --seconds 60
"""

from __future__ import annotations

import argparse
import functools
import os
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")

import gymnasium as gym  # noqa: E402
import mujoco  # noqa: E402
import numpy as np  # noqa: E402
import torch  # noqa: E402
from pilerl_pile_loader.soil import SOIL_MODELS  # noqa: E402
from torchrl.envs import ParallelEnv  # noqa: E402

import pilerl  # noqa: E402,F401
from pilerl.sim import make_torchrl_env  # noqa: E402

ACTION = np.array([0.15, 0.1, 0.5], dtype=np.float32)


def fixed_policy():
    """A plain callable policy writing ``ACTION``: measures the env, not a policy module."""
    action = torch.as_tensor(ACTION)

    def policy(tensordict):
        return tensordict.set("action", action.expand(*tensordict.batch_size, 3))

    return policy


def _worker_env(soil: str, num_envs: int):
    torch.set_num_threads(1)
    return make_torchrl_env(soil=soil, sensor_noise=0.0, num_envs=num_envs)


def timed(fn) -> float:
    start = time.perf_counter()
    fn()
    return time.perf_counter() - start


def bench_soil(soil: str, steps: int, batch: int) -> list[tuple[str, float, float, int]]:
    """Rows (name, wall seconds, simulated seconds, envs)."""
    rows = []
    env = gym.make("pilerl/PileLoading-v0", soil=soil, sensor_noise=0.0)
    raw = env.unwrapped
    dt = raw.dt

    def loop(stepper):
        env.reset(seed=0)
        for _ in range(steps):
            *_, terminated, truncated, _ = stepper(ACTION)
            if terminated or truncated:
                env.reset()

    loop(env.step)  # warm up
    rows.append(("simulator loop", timed(lambda: loop(raw.step)), steps * dt, 1))
    rows.append(("gymnasium", timed(lambda: loop(env.step)), steps * dt, 1))

    model, data = raw.model, raw.data
    n_physics = steps * raw.frame_skip
    rows.insert(
        0,
        ("raw mj_step", timed(lambda: mujoco.mj_step(model, data, nstep=n_physics)), steps * dt, 1),
    )

    policy = fixed_policy()
    tenv = make_torchrl_env(soil=soil, sensor_noise=0.0, seed=0)
    tenv.rollout(5, policy)
    rows.append(
        (
            "torchrl",
            timed(lambda: tenv.rollout(steps, policy, break_when_any_done=False)),
            steps * dt,
            1,
        )
    )
    tenv.close()

    def batched_row(name: str, benv, n_envs: int) -> None:
        benv.set_seed(0)
        benv.rollout(3, policy)
        steps_each = max(steps // n_envs, 1)
        wall = timed(lambda: benv.rollout(steps_each, policy, break_when_any_done=False))
        rows.append((name, wall, steps_each * dt * n_envs, n_envs))
        benv.close()

    batched_row(
        f"torchrl one process x{batch}",
        make_torchrl_env(soil=soil, sensor_noise=0.0, num_envs=batch),
        batch,
    )
    workers = os.cpu_count() or 2
    batched_row(
        f"torchrl ParallelEnv {workers} procs x1",
        ParallelEnv(workers, functools.partial(_worker_env, soil, 1)),
        workers,
    )
    per_worker = max(batch // workers, 1)
    batched_row(
        f"torchrl ParallelEnv {workers} procs x{per_worker}",
        ParallelEnv(workers, functools.partial(_worker_env, soil, per_worker)),
        workers * per_worker,
    )
    env.close()
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--soil", choices=sorted(SOIL_MODELS), action="append")
    parser.add_argument("--seconds", type=float, default=40.0, help="simulated seconds per row")
    parser.add_argument("--batch", type=int, default=4, help="simulators in the batched rows")
    args = parser.parse_args()
    torch.set_num_threads(1)
    steps = int(args.seconds / 0.05)
    print(
        f"threads: torch={torch.get_num_threads()}, OMP={os.environ['OMP_NUM_THREADS']}; "
        f"{steps} control steps at 20 Hz (500 Hz physics) per row; cores={os.cpu_count()}"
    )
    for soil in args.soil or sorted(SOIL_MODELS):
        rows = bench_soil(soil, steps, args.batch)
        baseline = {name: wall / sim for name, wall, sim, _ in rows}
        print(f"\n### soil = {soil}\n")
        print("| path | control steps/s | sim s per wall s | vs raw mj_step | vs simulator loop |")
        print("|---|---:|---:|---:|---:|")
        for name, wall, sim, _ in rows:
            rate = sim / wall
            print(
                f"| {name} | {sim / 0.05 / wall:,.0f} | {rate:.1f} | "
                f"{baseline['raw mj_step'] / (wall / sim):.2f} | "
                f"{baseline['simulator loop'] / (wall / sim):.2f} |"
            )


if __name__ == "__main__":
    main()
