"""End-to-end latency of the deployment runtime at 20 Hz: ONNX path vs checkpoint path.

The same DANNet (s = 4 sensors, s' = all 7 of the simulator's layout) is served by the
runtime (``pilerl.deploy.ControlRuntime``) in its own process pinned to one core, once
as its ONNX export (onnxruntime, one thread) and once as its checkpoint (its
``inference_actor``: the traced, frozen policy behind a thin ``TensorDictModule``, one
thread). A machine process sends a sensor packet every 50 ms over loopback UDP and
receives the commands. Reported per path:

- in -> out: sensor datagram received -> command datagram sent, on the runtime's clock
  (the runtime's own work: decode, watchdog, inference, encode, send); p50, p99, max;
- jitter: the standard deviation of in -> out, and of the interval between commands;
- round trip: machine sends readings -> machine has the command (adds both UDP hops);
- inference: the controller call alone.

Target: in -> out p99 <= 2 ms with ONNX.

    python benchmarks/deploy_latency.py --cycles 600
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import os
import tempfile
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import torch  # noqa: E402

from pilerl.deploy import ControlRuntime, MachineLink, RuntimeSettings, load_controller  # noqa: E402
from pilerl.deploy.hil import simulator_layout  # noqa: E402
from pilerl.deploy.packets import SensorFlag  # noqa: E402
from pilerl.policies import make_actor, save_actor  # noqa: E402
from pilerl.policies.export import export_onnx  # noqa: E402

CONTROL_HZ = 20.0
RUNTIME_CORE = 0


def _stats(names: list[str]) -> dict:
    return {
        "sensors": {k: {"mean": 1.0, "std": 1.0, "min": -5.0, "max": 5.0} for k in names},
        "action": {"mean": [0.0] * 3, "std": [1.0] * 3, "min": [-1.0] * 3, "max": [1.0] * 3},
        "n_samples": 1,
    }


def _serve(path: str, layout, settings: RuntimeSettings, run_dir: str, ready) -> None:
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {RUNTIME_CORE})
    torch.set_num_threads(1)
    runtime = ControlRuntime(load_controller(path), layout, settings, run_dir=run_dir)
    ready.send(runtime.address)
    runtime.run(max_seconds=600.0, episodes=1, max_idle_s=5.0)


def measure(path: str, layout, cycles: int, run_dir: Path) -> dict:
    """Serve ``path`` in a pinned process and drive it for ``cycles`` readings at 20 Hz."""
    settings = RuntimeSettings(control_hz=CONTROL_HZ, port=0)
    context = multiprocessing.get_context("fork")
    receiver, sender = context.Pipe(duplex=False)
    process = context.Process(target=_serve, args=(path, layout, settings, str(run_dir), sender))
    process.start()
    address = receiver.recv()
    link = MachineLink(layout, address)
    if hasattr(os, "sched_setaffinity") and len(os.sched_getaffinity(0)) > 1:
        os.sched_setaffinity(0, os.sched_getaffinity(0) - {RUNTIME_CORE})
    rng = np.random.default_rng(0)
    middle = (layout.low + layout.high) / 2
    spread = (layout.high - layout.low) / 8
    period = 1.0 / CONTROL_HZ
    round_trips = []
    next_send = time.monotonic()
    for step in range(cycles + 1):
        link.receive_until(next_send)
        readings = middle + spread * rng.uniform(-1, 1, len(middle)).astype(np.float32)
        flags = SensorFlag.EPISODE_START if step == 0 else SensorFlag.NONE
        if step == cycles:
            flags = SensorFlag.EPISODE_END
        sent = time.monotonic()
        seq = link.send_sensors(step, readings, flags)
        if step < cycles:
            link.receive_until(sent + period / 2, answered_seq=seq)
            last = link.received[-1] if link.received else None
            if last is not None and last.packet.answered_seq == seq:
                round_trips.append(last.arrival_s - sent)
        next_send += period
    link.close()
    process.join(timeout=30)
    summary = json.loads((run_dir / "summary.json").read_text())
    trips = np.array(round_trips) * 1e3
    return {
        "cycles": cycles,
        "answered": len(round_trips),
        "in_out": summary["latency"],
        "interval": summary["command_interval"],
        "inference": summary["inference"],
        "round_trip_p50_ms": float(np.percentile(trips, 50)),
        "round_trip_p99_ms": float(np.percentile(trips, 99)),
        "faults": summary["faults"],
        "deadline_misses": summary["deadline_misses"],
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--cycles", type=int, default=600, help="readings per path (20 Hz)")
    args = parser.parse_args()
    torch.set_num_threads(1)
    layout, _ = simulator_layout("pile_loader", {"control_hz": CONTROL_HZ})
    sensors = ["boom_angle", "bucket_angle", "drive_pressure", "telescope_pressure"]
    torch.manual_seed(0)
    actor = make_actor(
        "dannet", sensors=sensors, stats=_stats(layout.names), attention_sensors=layout.names
    )
    with tempfile.TemporaryDirectory() as tmp:
        paths = {
            "onnx": str(export_onnx(actor, f"{tmp}/dannet.onnx")[0]),
            "checkpoint": str(save_actor(f"{tmp}/dannet.pt", actor)),
        }
        results = {
            name: measure(path, layout, args.cycles, Path(tmp) / name)
            for name, path in paths.items()
        }
    print(
        f"\nDANNet, {args.cycles} readings at {CONTROL_HZ:.0f} Hz, runtime pinned to one core "
        f"({os.cpu_count()} cores on this machine)\n"
    )
    print(
        "| path | answered | in->out p50 [ms] | p99 [ms] | max [ms] | jitter (std) [ms] "
        "| command interval std [ms] | round trip p50 / p99 [ms] | inference p50 / p99 [ms] "
        "| faults |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    for name, r in results.items():
        io, inf = r["in_out"], r["inference"]
        print(
            f"| {name} | {r['answered']}/{r['cycles']} | {io['p50_ms']:.3f} | {io['p99_ms']:.3f} "
            f"| {io['max_ms']:.3f} | {io['std_ms']:.3f} | {r['interval']['std_ms']:.3f} "
            f"| {r['round_trip_p50_ms']:.3f} / {r['round_trip_p99_ms']:.3f} "
            f"| {inf['p50_ms']:.3f} / {inf['p99_ms']:.3f} | {r['faults'] or 'none'} |"
        )
    onnx, checkpoint = results["onnx"]["in_out"], results["checkpoint"]["in_out"]
    print(
        f"\ncheckpoint / ONNX in->out: p50 x{checkpoint['p50_ms'] / onnx['p50_ms']:.2f}, "
        f"p99 x{checkpoint['p99_ms'] / onnx['p99_ms']:.2f}; ONNX p99 target 2 ms: "
        f"{'met' if onnx['p99_ms'] <= 2.0 else 'NOT met'}"
    )


if __name__ == "__main__":
    main()
