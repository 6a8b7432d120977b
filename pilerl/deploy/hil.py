"""One hardware-in-the-loop run: the runtime here, the simulator bridge in a forked process.

records, summary = run_hil("dannet.onnx", BridgeSettings(...), RuntimeSettings(...))
"""

from __future__ import annotations

import multiprocessing
import os
from pathlib import Path

import torch

from pilerl.sim import get_simulator, make_gym_env

from .bridge import BridgeSettings, run_bridge
from .controllers import DeployedController, load_controller
from .link import LinkFault
from .loop import RuntimeSettings
from .packets import SensorLayout
from .runtime import ControlRuntime


def simulator_layout(simulator: str, env_kwargs: dict) -> tuple[SensorLayout, float]:
    """The simulator's sensor layout and its control rate [Hz]."""
    env = make_gym_env(simulator, **env_kwargs)
    try:
        layout = SensorLayout.from_env(env, get_simulator(simulator).sensor_units)
        return layout, 1.0 / float(env.unwrapped.dt)
    finally:
        env.close()


def runtime_kind(controller_name: str) -> str:
    """``onnx``, ``checkpoint`` or ``scripted``: a label for the logs."""
    if controller_name.endswith(".onnx"):
        return "onnx"
    return "checkpoint" if controller_name.endswith(".pt") else controller_name


def _bridge_process(connection, settings, address, fault) -> None:
    torch.set_num_threads(1)
    try:
        connection.send(("ok", run_bridge(settings, address, fault=fault)))
    except Exception as error:  # noqa: BLE001 - reported to the parent, which raises
        connection.send(("error", f"{type(error).__name__}: {error}"))
    finally:
        connection.close()


def run_hil(
    controller: str | Path | DeployedController,
    bridge: BridgeSettings,
    runtime: RuntimeSettings,
    *,
    run_dir: str | Path | None = None,
    fault: LinkFault | None = None,
    max_seconds: float = 120.0,
    max_idle_s: float = 2.0,
) -> tuple[list[dict], dict]:
    """Serve ``controller`` to a simulated machine; returns (bridge episode records,
    runtime summary). The runtime stops when the bridge's episodes have ended, after
    ``max_idle_s`` without a datagram, or after ``max_seconds``."""
    layout, control_hz = simulator_layout(bridge.simulator, bridge.env_kwargs)
    if abs(control_hz - runtime.control_hz) > 1e-9 or bridge.speedup != runtime.speedup:
        raise ValueError(
            f"run_hil: the simulator steps at {control_hz} Hz x {bridge.speedup} but the "
            f"runtime runs at {runtime.control_hz} Hz x {runtime.speedup}; make them equal"
        )
    if runtime.max_sensor_age_s <= 1.0 / control_hz:
        raise ValueError(
            f"run_hil: the bridge sends one reading per control period ({1 / control_hz:.3f} s);"
            f" a watchdog age of {runtime.max_sensor_age_s} s would call every gap stale"
        )
    if isinstance(controller, str | Path):
        controller = load_controller(
            controller, sensors=layout.names, control_hz=control_hz, simulator=bridge.simulator
        )
    deployed = controller
    kind = runtime_kind(deployed.name)
    server = ControlRuntime(deployed, layout, runtime, run_dir=run_dir, runtime_kind=kind)
    context = multiprocessing.get_context("fork" if os.name == "posix" else None)
    receiver, sender = context.Pipe(duplex=False)
    process = context.Process(
        target=_bridge_process, args=(sender, bridge, server.address, fault), daemon=True
    )
    process.start()
    sender.close()
    try:
        summary = server.run(
            max_seconds=max_seconds, episodes=len(bridge.seeds), max_idle_s=max_idle_s
        )
        if not receiver.poll(max_seconds):
            raise TimeoutError(f"run_hil: the bridge gave no result within {max_seconds} s")
        status, payload = receiver.recv()
    finally:
        process.join(timeout=10)
        if process.is_alive():
            process.kill()
            process.join()
    if status != "ok":
        raise RuntimeError(f"run_hil: the simulator bridge failed: {payload}")
    return payload, summary
