"""Behaviour-cloning training throughput: pilerl's ``train_bc`` vs a hand-written loop.

Both train the same DANNet (s = 4 sensors, s' = all 7) with RAdam, batch 512, lr 1e-3,
MSE, on the same data, one thread, in the same run; the ratio is pilerl / plain. The last
row projects the paper's schedule (709,368 samples x 150 epochs) from pilerl's rate.

    python benchmarks/bc_throughput.py --samples 100000 --epochs 2
"""

from __future__ import annotations

import argparse
import os
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")

import torch  # noqa: E402
from tensordict import TensorDict  # noqa: E402

from pilerl.policies import make_actor  # noqa: E402
from pilerl.training import BCSettings, train_bc, train_bc_ensemble  # noqa: E402

SENSORS = ["boom_angle", "bucket_angle", "drive_pressure", "telescope_pressure"]
ALL = SENSORS + ["boom_pressure", "bucket_pressure", "pump_angle"]
STATS = {
    "sensors": {k: {"mean": 0.0, "std": 1.0, "min": -5.0, "max": 5.0} for k in ALL},
    "action": {"mean": [0.0] * 3, "std": [1.0] * 3, "min": [-1.0] * 3, "max": [1.0] * 3},
    "n_samples": 1,
}
PAPER_SAMPLES, PAPER_EPOCHS = 709_368, 150


def dataset(n: int) -> TensorDict:
    generator = torch.Generator().manual_seed(0)
    sensors = {k: torch.randn(n, 1, generator=generator) for k in ALL}
    action = torch.tanh(sensors["drive_pressure"] - sensors["telescope_pressure"]).expand(n, 3)
    return TensorDict({**sensors, "action": action.clone()}, [n])


def fresh_actor():
    torch.manual_seed(0)
    return make_actor("dannet", sensors=SENSORS, stats=STATS, attention_sensors=ALL)


def plain_loop(data: TensorDict, epochs: int) -> float:
    """The same training written directly against the modules (the baseline)."""
    policy = fresh_actor().module
    optimizer = torch.optim.RAdam(policy.parameters(), lr=1e-3)
    readings = torch.cat([data[k] for k in policy.in_keys], -1)
    target = data["action"]
    n = data.batch_size[0]
    start = time.perf_counter()
    for epoch in range(epochs):
        policy.train()
        order = torch.randperm(n, generator=torch.Generator().manual_seed(epoch))
        for i in range(0, n, 512):
            idx = order[i : i + 512]
            s, s_att = policy.normalized_inputs(readings[idx])
            loss = ((policy.controller(s, s_att).action - target[idx]) ** 2).mean()
            optimizer.zero_grad()
            loss.backward()
            optimizer.step()
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=100_000)
    parser.add_argument("--epochs", type=int, default=2)
    args = parser.parse_args()
    torch.set_num_threads(1)
    data = dataset(args.samples)
    plain = plain_loop(data, args.epochs)
    start = time.perf_counter()
    train_bc(fresh_actor(), data, None, BCSettings(epochs=args.epochs), progress=False)
    pilerl = time.perf_counter() - start
    total = args.samples * args.epochs
    print(f"DANNet, batch 512, RAdam, {args.samples:,} samples x {args.epochs} epochs, 1 thread\n")
    print("| path | wall s | samples/s | vs plain loop |")
    print("|---|---:|---:|---:|")
    print(f"| plain PyTorch loop | {plain:.1f} | {total / plain:,.0f} | 1.00 |")
    print(
        f"| pilerl train_bc (BCLoss) | {pilerl:.1f} | {total / pilerl:,.0f} | "
        f"{plain / pilerl:.2f} |"
    )
    one = pilerl
    seeds = 8
    start = time.perf_counter()
    train_bc_ensemble(
        fresh_actor().module.config,
        list(range(seeds)),
        data,
        None,
        BCSettings(epochs=args.epochs),
        progress=False,
    )
    ensemble = time.perf_counter() - start
    print(
        f"| {seeds}-seed ensemble (torch.func) | {ensemble:.1f} | "
        f"{total * seeds / ensemble:,.0f} | {seeds * one / ensemble:.2f}x vs {seeds} x one seed |"
    )
    projected = PAPER_SAMPLES * PAPER_EPOCHS / (total / pilerl)
    print(
        f"\nPaper schedule ({PAPER_SAMPLES:,} samples x {PAPER_EPOCHS} epochs) at pilerl's "
        f"rate: {projected / 60:.0f} min on one core"
    )


if __name__ == "__main__":
    main()
