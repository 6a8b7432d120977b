"""Command line: the runtime, the simulator bridge, and the fault-injection table.

    python -m pilerl.deploy runtime dannet.onnx --port 47000 --run-dir runs/deploy
    python -m pilerl.deploy bridge --port 47000 --episodes 3 --speedup 5
    python -m pilerl.deploy rearm --port 47000          # resume after a fault
    python -m pilerl.deploy faults dannet.onnx --cases 3 --speedup 4

The Hydra recipe ``recipes/deploy.py`` calls the same functions. No default is restated
here: each option's default is the field of the deploy settings (``pilerl.deploy.config``)
that the recipe's ``conf/deploy.yaml`` fills, so both start from the same values.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys

from pilerl.runtime import limit_threads
from pilerl.sim.settings import settings_class

from .config import DeployConfig, HilConfig, RuntimeConfig

RUNTIME = RuntimeConfig()
HIL = HilConfig()
# the deploy settings' simulator, with its declared options' defaults (control_hz ...)
ENV = settings_class(
    next(f for f in dataclasses.fields(DeployConfig) if f.name == "env").default_factory().simulator
)()
CLI_RUN_DIR = "outputs/deploy/cli"


def _env_kwargs(args) -> dict:
    return {"condition": args.condition, "control_hz": args.control_hz}


def build_parser() -> argparse.ArgumentParser:
    """The four commands and their options (defaults: the deploy settings')."""
    parser = argparse.ArgumentParser(prog="python -m pilerl.deploy", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)
    runtime = sub.add_parser("runtime", help="serve a controller over UDP")
    runtime.add_argument("controller", help=".onnx export, .pt checkpoint or 'scripted'")
    runtime.add_argument("--host", default=RUNTIME.host)
    runtime.add_argument("--port", type=int, default=RUNTIME.port)
    runtime.add_argument("--run-dir", default=CLI_RUN_DIR)
    runtime.add_argument("--max-seconds", type=float, default=RUNTIME.max_seconds)
    runtime.add_argument("--episodes", type=int, default=RUNTIME.episodes)
    runtime.add_argument("--max-sensor-age", type=float, default=RUNTIME.max_sensor_age_s)
    bridge = sub.add_parser("bridge", help="run the simulator as the machine")
    bridge.add_argument("--runtime-host", default=RUNTIME.host)
    bridge.add_argument("--port", type=int, default=RUNTIME.port, help="the runtime's port")
    bridge.add_argument("--episodes", type=int, default=1)
    bridge.add_argument("--seed", type=int, default=HIL.seed, help="evaluator base seed")
    rearm = sub.add_parser("rearm", help="ask a runtime to resume after a fault")
    rearm.add_argument("--runtime-host", default=RUNTIME.host)
    rearm.add_argument("--port", type=int, default=RUNTIME.port, help="the runtime's port")
    faults = sub.add_parser("faults", help="fault-injection table against the simulator")
    faults.add_argument("controller")
    faults.add_argument("--cases", type=int, default=1)
    faults.add_argument("--max-sensor-age", type=float, default=RUNTIME.max_sensor_age_s)
    for p in (runtime, bridge, rearm, faults):
        p.add_argument("--control-hz", type=float, default=ENV.control_hz)
        p.add_argument("--speedup", type=float, default=RUNTIME.speedup)
        p.add_argument("--condition", default=ENV.condition)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    limit_threads()
    try:
        if args.command == "runtime":
            summary = serve(args)
            print(json.dumps(summary, indent=1))
        elif args.command == "bridge":
            from .bridge import BridgeSettings, run_bridge

            settings = BridgeSettings(
                simulator=ENV.simulator,
                env_kwargs=_env_kwargs(args),
                seeds=tuple(args.seed * 100_000 + i for i in range(args.episodes)),
                speedup=args.speedup,
            )
            for record in run_bridge(settings, (args.runtime_host, args.port)):
                keys = ("seed", "success", "fill_fraction", "steps", "late_commands")
                print(json.dumps({k: record[k] for k in keys}))
        elif args.command == "rearm":
            from .hil import simulator_layout
            from .link import MachineLink

            layout, _ = simulator_layout(ENV.simulator, _env_kwargs(args))
            link = MachineLink(layout, (args.runtime_host, args.port))
            link.send_rearm()
            link.close()
            print(f"re-arm sent to {args.runtime_host}:{args.port}")
        else:
            from .faults import fault_table, format_table
            from .hil import simulator_layout
            from .loop import RuntimeSettings

            _, control_hz = simulator_layout(ENV.simulator, _env_kwargs(args))
            settings = RuntimeSettings(
                control_hz=control_hz,  # the simulator's actual rate
                max_sensor_age_s=args.max_sensor_age,
                speedup=args.speedup,
            )
            outcomes = fault_table(
                args.controller,
                env_kwargs=_env_kwargs(args),
                runtime=settings,
                cases=args.cases,
                simulator=ENV.simulator,
            )
            print(format_table(outcomes))
            return 1 if any(o["crashed"] for o in outcomes) else 0
    except (ValueError, FileNotFoundError, OSError) as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    return 0


def serve(args) -> dict:
    from .controllers import load_controller
    from .hil import runtime_kind, simulator_layout
    from .loop import RuntimeSettings
    from .runtime import ControlRuntime

    layout, _ = simulator_layout(ENV.simulator, _env_kwargs(args))
    settings = RuntimeSettings(
        control_hz=args.control_hz,
        max_sensor_age_s=args.max_sensor_age,
        speedup=args.speedup,
        host=args.host,
        port=args.port,
    )
    controller = load_controller(args.controller, sensors=layout.names, control_hz=args.control_hz)
    kind = runtime_kind(controller.name)
    runtime = ControlRuntime(controller, layout, settings, run_dir=args.run_dir, runtime_kind=kind)
    print(f"serving {controller.name} on {runtime.address[0]}:{runtime.address[1]}", flush=True)
    return runtime.run(max_seconds=args.max_seconds, episodes=args.episodes)


if __name__ == "__main__":
    sys.exit(main())
