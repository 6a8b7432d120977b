"""Deploy an exported controller: the UDP runtime with its watchdog, or a HIL run.

    python recipes/deploy.py controller=dannet.onnx                       # serve a machine
    python recipes/deploy.py controller=dannet.onnx mode=hil runtime.speedup=5
    python recipes/deploy.py controller=scripted mode=hil    # the scripted operator

Writes to the run directory: ``episodes/`` (the run as demonstration episodes),
``cycles.csv``, ``faults.csv``, ``summary.json``, ``layout.json``; with ``mode=hil`` also
``hil_episodes.json`` (the simulator's outcome of each episode).
"""

from __future__ import annotations

import json
import logging
from pathlib import Path

from pilerl.config import register_configs
from pilerl.deploy.config import DeployConfig
from pilerl.deploy.controllers import load_controller
from pilerl.deploy.hil import run_hil, runtime_kind, simulator_layout
from pilerl.deploy.runtime import ControlRuntime
from pilerl.io import write_text_atomic
from pilerl.policies.checkpoint import warn_if_other_control_rate
from pilerl.recipe import recipe

log = logging.getLogger(__name__)
register_configs()
HIL_KEYS = ("seed", "success", "fill_fraction", "steps", "late_commands")


@recipe("deploy", schema=DeployConfig, usage_errors=(ValueError, FileNotFoundError))
def main(config: DeployConfig) -> None:
    layout, control_hz = simulator_layout(config.env.simulator, config.env.make_kwargs())
    controller = load_controller(
        config.controller,
        sensors=layout.names,
        control_hz=control_hz,
        simulator=config.env.simulator,
    )
    if Path(config.controller).suffix in (".pt", ".onnx"):  # they know their training rate
        warn_if_other_control_rate(config.controller, control_hz)
    out_dir = Path(config.output_dir)
    settings = config.runtime_settings(control_hz)

    # --- serve a machine, or the simulator as the machine
    if config.mode == "hil":
        records, summary = run_hil(
            controller,
            config.bridge_settings(),
            settings,
            run_dir=out_dir,
            max_seconds=config.runtime.max_seconds,
        )
        rows = [{k: r[k] for k in HIL_KEYS} for r in records]
        write_text_atomic(out_dir / "hil_episodes.json", json.dumps(rows, indent=1))
        for row in rows:
            log.info("hil episode %s", row)
    else:
        kind = runtime_kind(controller.name)
        runtime = ControlRuntime(controller, layout, settings, run_dir=out_dir, runtime_kind=kind)
        log.info("serving %s on %s:%d", controller.name, *runtime.address)
        summary = runtime.run(
            max_seconds=config.runtime.max_seconds, episodes=config.runtime.episodes
        )
    log.info(
        "%d commands (%d neutral), %d deadline misses, faults %s, malformed %s, latency p99 %s ms",
        summary["commands"],
        summary["neutral_commands"],
        summary["deadline_misses"],
        summary["faults"],
        summary["malformed"],
        summary["latency"]["p99_ms"],
    )


if __name__ == "__main__":
    main()
