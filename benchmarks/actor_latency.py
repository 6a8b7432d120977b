"""Single-observation action latency of a controller: p50 / p99 per path.

The same DANNet (s = 4 sensors, s' = all 7) answers one observation at a time through:
the TensorDict actor (what TorchRL rollouts call; a fresh tensordict per call, as a
rollout step gives), the same with ``inference_actor`` (traced, frozen), the bare
``SensorPolicy`` module, its traced graph, the ``torch.export`` program, and the ONNX
model in onnxruntime, in one run, one thread. Each path is timed in ``--repeats``
interleaved rounds; the table gives the median over rounds of each round's percentiles, and
the ratios are taken round by round (the machine may be shared).

    python benchmarks/actor_latency.py
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import onnxruntime  # noqa: E402
import torch  # noqa: E402
from tensordict import TensorDict  # noqa: E402

from pilerl.policies import make_actor  # noqa: E402
from pilerl.policies.actors import inference_actor  # noqa: E402
from pilerl.policies.export import export_onnx, export_program  # noqa: E402

SENSORS = ["boom_angle", "bucket_angle", "drive_pressure", "telescope_pressure"]
ALL = SENSORS + ["boom_pressure", "bucket_pressure", "pump_angle"]
STATS = {
    "sensors": {k: {"mean": 1.0, "std": 1.0, "min": -5.0, "max": 5.0} for k in ALL},
    "action": {"mean": [0.0] * 3, "std": [1.0] * 3, "min": [-1.0] * 3, "max": [1.0] * 3},
    "n_samples": 1,
}
CALLS = 3000


def latencies_us(call) -> np.ndarray:
    for _ in range(200):
        call()
    times = np.empty(CALLS)
    for i in range(CALLS):
        start = time.perf_counter()
        call()
        times[i] = time.perf_counter() - start
    return times * 1e6


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    torch.set_num_threads(1)
    torch.manual_seed(0)
    actor = make_actor("dannet", sensors=SENSORS, stats=STATS, attention_sensors=ALL)
    policy = actor.module.eval()
    fast = inference_actor(actor)
    readings = {k: torch.tensor([[1.0]]) for k in actor.in_keys}
    observation = TensorDict(readings, batch_size=[1])
    with tempfile.TemporaryDirectory() as tmp:
        program = torch.export.load(export_program(actor, f"{tmp}/a.pt2")).module()
        onnx_path, _ = export_onnx(actor, f"{tmp}/a.onnx")
        options = onnxruntime.SessionOptions()
        options.intra_op_num_threads = options.inter_op_num_threads = 1
        session = onnxruntime.InferenceSession(str(onnx_path), options)
    feeds = {k: v.numpy() for k, v in readings.items()}
    values = tuple(readings.values())
    paths = {
        "TensorDict actor": lambda: actor(observation.clone()),
        "inference_actor (traced, frozen)": lambda: fast(observation.clone()),
        "SensorPolicy module (bare)": lambda: policy(*values),
        "traced graph alone": lambda: fast.module(*values),
        "torch.export program": lambda: program(*values),
        "ONNX (onnxruntime)": lambda: session.run(["action"], feeds),
    }
    rounds: dict[str, list[np.ndarray]] = {name: [] for name in paths}
    with torch.no_grad():
        for _ in range(args.repeats):
            for name, call in paths.items():
                rounds[name].append(np.percentile(latencies_us(call), [50, 90, 99]))
    median = {name: np.median(np.stack(r), axis=0) for name, r in rounds.items()}

    def ratio(name: str, base: str, column: int) -> float:
        per_round = [a[column] / b[column] for a, b in zip(rounds[name], rounds[base], strict=True)]
        return float(np.median(per_round))

    print(f"DANNet, one observation per call, 1 thread, median of {args.repeats} rounds\n")
    print(
        "| path | p50 us | p90 us | p99 us | p50 speed-up vs TensorDict actor "
        "| p50 / p99 vs bare module |"
    )
    print("|---|---:|---:|---:|---:|---:|")
    bare = "SensorPolicy module (bare)"
    for name in paths:
        p50, p90, p99 = median[name]
        speed_up = 1 / ratio(name, "TensorDict actor", 0)
        vs_bare = f"{ratio(name, bare, 0):.2f} / {ratio(name, bare, 2):.2f}"
        print(f"| {name} | {p50:.0f} | {p90:.0f} | {p99:.0f} | {speed_up:.2f} | {vs_bare} |")


if __name__ == "__main__":
    main()
