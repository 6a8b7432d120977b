"""Frames per second of fine-tuning's collection vs raw simulator stepping.

    python benchmarks/collection_speed.py
    python benchmarks/collection_speed.py --checkpoint data/checkpoints/dannet_d_ii/best.pt \
        --frames 8192 --workers 2 --envs 8

Rows (same conditions mixture, same actor, measured in this run):

| row | what |
|---|---|
| raw env | ``ConditionMixtureEnv.step`` with a fixed action: the simulator alone |
| raw env + actor | the same, the cloned actor choosing each action (no TorchRL) |
| Collector, 1 env | TorchRL ``Collector`` over ``GymWrapper``, stochastic actor |
| Collector, E envs | the same over E simulators batched in one ``SimulatorBatchEnv`` |
| MultiSyncCollector | TorchRL multi-process collector, W workers x E envs each |

Ratios are against the raw env row. Without ``--checkpoint`` an untrained DANNet with
unit statistics stands in (same network size). The multi-process row excludes the
workers' start-up (spawned processes import torch, TorchRL and MuJoCo: seconds), measured
from the first batch to the last.

``--cpu`` times the one-process rows with this process's CPU time instead of the wall
clock: on a machine loaded by other jobs the wall clock counts the time the scheduler gave
them; the multi-process row is then left out (its work is in the workers).
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import torch
from tensordict import TensorDict

from pilerl.policies import load_actor, make_actor, make_stochastic_actor
from pilerl.rl.collection import make_collector
from pilerl.rl.envs import ConditionMixtureEnv, TrainingEnvFactory
from pilerl.runtime import limit_threads

CONDITIONS = {"summer": 1.0, "winter_a": 1.0, "winter_b": 1.0, "winter_c": 1.0, "winter_d": 1.0}
REWARDS = {"reward_fill": 1.0, "reward_success": 1.0, "reward_time": 1.0}
SENSORS = ["boom_angle", "bucket_angle", "drive_pressure", "telescope_pressure"]
ATTENTION = [*SENSORS, "boom_pressure", "bucket_pressure", "pump_angle"]


def cloned_actor(checkpoint: str | None):
    if checkpoint:
        return load_actor(checkpoint)
    stats = {"sensors": {name: {"mean": 0.0, "std": 1.0} for name in ATTENTION}}
    return make_actor("dannet", sensors=SENSORS, stats=stats, attention_sensors=ATTENTION).eval()


CLOCKS = {"wall": time.perf_counter, "cpu": time.process_time}


def raw_fps(frames: int, actor=None, *, clock=time.perf_counter) -> float:
    env = ConditionMixtureEnv("pile_loader", {}, CONDITIONS, REWARDS)
    obs, _ = env.reset(seed=0)
    action = np.array([0.2, 0.1, 0.6], dtype=np.float32)
    started = clock()
    for _ in range(frames):
        if actor is not None:
            with torch.no_grad():
                td = TensorDict({k: torch.as_tensor(v) for k, v in obs.items()}, [])
                action = actor(td)["action"].numpy()
        obs, _, terminated, truncated, _ = env.step(action)
        if terminated or truncated:
            obs, _ = env.reset()
    elapsed = clock() - started
    env.close()
    return frames / elapsed


def collector_fps(
    frames: int,
    frames_per_batch: int,
    actor,
    *,
    backend: str,
    workers: int = 1,
    envs: int = 1,
    clock=time.perf_counter,
) -> float:
    policy = make_stochastic_actor(actor)
    factory = TrainingEnvFactory("pile_loader", {}, CONDITIONS, REWARDS, num_envs=envs)
    collector = make_collector(
        factory,
        policy,
        frames_per_batch=frames_per_batch,
        total_frames=frames + frames_per_batch,
        backend=backend,
        workers=workers,
    )
    counted, started = 0, None
    for batch in collector:
        if started is None:  # the first batch pays for start-up: timing starts after it
            started = clock()
            continue
        counted += batch.numel()
    elapsed = clock() - started
    collector.shutdown()
    return counted / elapsed


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--checkpoint", default=None, help="a cloned actor (best.pt)")
    parser.add_argument("--frames", type=int, default=8192, help="frames timed per row")
    parser.add_argument("--frames-per-batch", type=int, default=1024)
    parser.add_argument("--workers", type=int, default=2, help="multi-process collector size")
    parser.add_argument("--envs", type=int, default=8, help="simulators batched per collector")
    parser.add_argument("--cpu", action="store_true", help="one-process rows in CPU time")
    args = parser.parse_args()
    clock = CLOCKS["cpu" if args.cpu else "wall"]
    limit_threads()
    torch.manual_seed(0)
    actor = cloned_actor(args.checkpoint)
    frames, per_batch = args.frames, args.frames_per_batch
    rows = [
        ("raw env (fixed action)", raw_fps(frames, clock=clock)),
        ("raw env + actor", raw_fps(frames, actor, clock=clock)),
        (
            "Collector, 1 env",
            collector_fps(frames, per_batch, actor, backend="single", clock=clock),
        ),
        (
            f"Collector, {args.envs} envs",
            collector_fps(frames, per_batch, actor, backend="single", envs=args.envs, clock=clock),
        ),
    ]
    if not args.cpu:
        rows.append(
            (
                f"MultiSyncCollector, {args.workers}x{args.envs}",
                collector_fps(
                    frames,
                    per_batch,
                    actor,
                    backend="multiprocess",
                    workers=args.workers,
                    envs=args.envs,
                ),
            )
        )
    baseline = rows[0][1]
    unit = "frames/CPU s" if args.cpu else "frames/s"
    print(f"{'row':<28} {unit:>12} {'x raw':>7}")
    for name, fps in rows:
        print(f"{name:<28} {fps:>12.0f} {fps / baseline:>7.2f}")


if __name__ == "__main__":
    main()
