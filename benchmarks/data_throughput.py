"""Demonstration data throughput: recording, and replay-buffer sampling.

1. Recording: scripted episodes at ``--record-hz`` into an ``EpisodeStore`` with 1 and
   with 2 worker processes: simulated seconds recorded per wall second, samples/s.
2. Sampling: batches of 512 from a TorchRL ``TensorDictReplayBuffer`` (uniform, in
   memory and memory-mapped; slices) next to plain tensor indexing of the same data
   (``data[torch.randint(...)]``) in the same run: samples/s and the ratio.

    python benchmarks/data_throughput.py
    python benchmarks/data_throughput.py --episodes 8 --record-hz 500 --samples 700000
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time

import torch  # noqa: E402
from tensordict import TensorDict  # noqa: E402

from pilerl.data import EpisodeStore, RecordingPlan, make_replay_buffer  # noqa: E402
from pilerl.data.recorder import record_demonstrations  # noqa: E402
from pilerl.sim import make_gym_env  # noqa: E402

BATCH = 512


def bench_recording(episodes: int, record_hz: float, workers: int) -> tuple[float, int, float]:
    """(wall s, samples, simulated s) for recording ``episodes`` episodes."""
    env = make_gym_env("pile_loader").unwrapped
    plan = RecordingPlan(
        "pile_loader", {"condition": "summer", "control_hz": record_hz}, n_episodes=episodes, seed=0
    )
    with tempfile.TemporaryDirectory() as tmp:
        store = EpisodeStore.create(
            tmp + "/demos", sensors=env.sensor_units, controls=list(env.control_names)
        )
        start = time.perf_counter()
        record_demonstrations(store, plan, workers=workers, progress=False)
        wall = time.perf_counter() - start
        samples = store.n_samples
        sim_s = sum(m.n_samples / m.rate_hz for m in store.episodes)
    return wall, samples, sim_s


def synthetic_dataset(n: int) -> TensorDict:
    """``n`` transitions shaped like the pile loader's (7 sensors, 3 controls)."""
    names = [
        "boom_angle",
        "bucket_angle",
        "drive_pressure",
        "telescope_pressure",
        "boom_pressure",
        "bucket_pressure",
        "pump_angle",
    ]
    generator = torch.Generator().manual_seed(0)
    sensors = {k: torch.randn(n, 1, generator=generator) for k in names}
    episode = torch.arange(n) // 5000
    return TensorDict(
        {
            **sensors,
            "action": torch.rand(n, 3, generator=generator) * 2 - 1,
            "episode": episode,
            "step": torch.arange(n) % 5000,
            "next": TensorDict(
                {
                    **{k: v.clone() for k, v in sensors.items()},
                    "reward": torch.zeros(n, 1),
                    "done": torch.zeros(n, 1, dtype=torch.bool),
                },
                [n],
            ),
        },
        [n],
    )


def samples_per_second(draw, seconds: float = 2.0) -> float:
    draw()  # warm up
    n, start = 0, time.perf_counter()
    while time.perf_counter() - start < seconds:
        draw()
        n += BATCH
    return n / (time.perf_counter() - start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=4)
    parser.add_argument("--record-hz", type=float, default=500.0)
    parser.add_argument("--samples", type=int, default=709_368, help="the paper's D_I size")
    args = parser.parse_args()
    torch.set_num_threads(1)
    print(f"torch threads=1, cores={os.cpu_count()}")

    print(f"\n### Recording: {args.episodes} summer episodes at {args.record_hz:g} Hz\n")
    print("| workers | wall s | samples | samples/s | sim s per wall s | vs 1 worker |")
    print("|---:|---:|---:|---:|---:|---:|")
    base = None
    for workers in (1, 2):
        wall, samples, sim_s = bench_recording(args.episodes, args.record_hz, workers)
        base = base or sim_s / wall
        print(
            f"| {workers} | {wall:.1f} | {samples:,} | {samples / wall:,.0f} | "
            f"{sim_s / wall:.1f} | {sim_s / wall / base:.2f} |"
        )

    print(f"\n### Sampling batches of {BATCH} from {args.samples:,} transitions\n")
    data = synthetic_dataset(args.samples)
    n = args.samples
    rows = [("plain tensor indexing", lambda: data[torch.randint(n, (BATCH,))])]
    memory = make_replay_buffer(data, batch_size=BATCH)
    rows.append(("TensorDictReplayBuffer uniform, memory", memory.sample))
    with tempfile.TemporaryDirectory() as tmp:
        memmap = make_replay_buffer(data, batch_size=BATCH, storage="memmap", scratch_dir=tmp)
        rows.append(("TensorDictReplayBuffer uniform, memmap", memmap.sample))
        slices = make_replay_buffer(data, batch_size=BATCH, sampler="slices", slice_len=32)
        rows.append(("TensorDictReplayBuffer slices of 32", slices.sample))
        print("| path | samples/s | vs plain indexing |")
        print("|---|---:|---:|")
        baseline = None
        for name, draw in rows:
            rate = samples_per_second(draw)
            baseline = baseline or rate
            print(f"| {name} | {rate:,.0f} | {rate / baseline:.2f} |")


if __name__ == "__main__":
    main()
