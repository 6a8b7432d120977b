"""Single-observation action latency of a controller: p50 / p99 per path.

The same DANNet (s = 4 sensors, s' = all 7) answers one observation at a time through:
the TensorDict actor (what TorchRL rollouts call), the bare ``SensorPolicy`` module, the
``torch.export`` program, and the ONNX model in onnxruntime, in one run, one thread.

    python benchmarks/actor_latency.py
"""

from __future__ import annotations

import os
import tempfile
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import onnxruntime  # noqa: E402
import torch  # noqa: E402
from tensordict import TensorDict  # noqa: E402

from pilerl.policies import make_actor  # noqa: E402
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
    torch.set_num_threads(1)
    torch.manual_seed(0)
    actor = make_actor("dannet", sensors=SENSORS, stats=STATS, attention_sensors=ALL)
    policy = actor.module.eval()
    readings = {k: torch.tensor([[1.0]]) for k in actor.in_keys}
    observation = TensorDict(readings, batch_size=[1])
    with tempfile.TemporaryDirectory() as tmp:
        program = torch.export.load(export_program(actor, f"{tmp}/a.pt2")).module()
        onnx_path, _ = export_onnx(actor, f"{tmp}/a.onnx")
        options = onnxruntime.SessionOptions()
        options.intra_op_num_threads = options.inter_op_num_threads = 1
        session = onnxruntime.InferenceSession(str(onnx_path), options)
    feeds = {k: v.numpy() for k, v in readings.items()}
    args = tuple(readings.values())
    with torch.no_grad():
        rows = [
            ("TensorDict actor", lambda: actor(observation.clone())),
            ("SensorPolicy module", lambda: policy(*args)),
            ("torch.export program", lambda: program(*args)),
            ("ONNX (onnxruntime)", lambda: session.run(["action"], feeds)),
        ]
        print("DANNet, one observation per call, 1 thread\n")
        print("| path | p50 us | p99 us | speed-up vs TensorDict actor (p50) |")
        print("|---|---:|---:|---:|")
        base = None
        for name, call in rows:
            t = latencies_us(call)
            p50, p99 = np.percentile(t, [50, 99])
            base = base or p50
            print(f"| {name} | {p50:.0f} | {p99:.0f} | {base / p50:.2f} |")


if __name__ == "__main__":
    main()
