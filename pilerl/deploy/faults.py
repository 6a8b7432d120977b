"""Fault injection against the simulator: each scenario, its outcome, and the table.

A scenario runs one short episode through ``run_hil`` with one ``LinkFault`` (or a
controller that overruns its budget) from ``FAULT_STEP`` on, asks for a re-arm at
``REARM_STEP`` and checks, from what the simulated machine received:

- ``neutral``: a neutral command (state FAULTED) reached the machine after the fault;
  ``neutral_delay_s`` is its arrival minus the time the first faulty packet was due;
  the bound is one control period plus the watchdog age (wall clock, after speed-up);
- ``resumed``: the controller was back in charge after the re-arm;
- ``crashed``: the runtime or the bridge raised.

    python -m pilerl.deploy faults --cases 3
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

from pilerl.sim import DEFAULT_SIMULATOR

from .bridge import BridgeSettings
from .controllers import DeployedController, load_controller
from .hil import run_hil, simulator_layout
from .link import LinkFault
from .loop import RuntimeSettings
from .packets import ControllerState
from .watchdog import Fault

FAULT_STEP = 10
REARM_STEP = 30
EPISODE_STEPS = 45


@dataclass(frozen=True)
class FaultScenario:
    """A named fault; ``expect`` is the fault bit the watchdog must report (``None``: the
    fault is absorbed, e.g. one lost packet within the stale limit, and control goes on)."""

    name: str
    fault: LinkFault | None
    expect: Fault | None
    slow_at_call: int | None = None  # the controller overruns from this call on


def scenarios(age_s: float, period_s: float) -> list[FaultScenario]:
    """The scenarios for a stale limit ``age_s`` and control period ``period_s`` (machine
    time): bursts last twice the stale limit, single faults one packet."""
    burst = math.ceil(2 * age_s / period_s)
    return [
        FaultScenario("drop one packet", LinkFault("drop", FAULT_STEP), None),
        FaultScenario("drop a burst", LinkFault("drop", FAULT_STEP, burst), Fault.STALE),
        FaultScenario(
            "delay a burst",
            LinkFault("delay", FAULT_STEP, burst, delay_s=2 * age_s),
            Fault.STALE,
        ),
        FaultScenario("reorder two packets", LinkFault("reorder", FAULT_STEP), Fault.OUT_OF_ORDER),
        FaultScenario("duplicate a packet", LinkFault("duplicate", FAULT_STEP), Fault.DUPLICATE),
        FaultScenario("corrupt one packet", LinkFault("corrupt", FAULT_STEP), None),
        FaultScenario("corrupt a burst", LinkFault("corrupt", FAULT_STEP, burst), Fault.STALE),
        FaultScenario("garbage datagrams", LinkFault("garbage", FAULT_STEP, 20), None),
        FaultScenario("NaN reading", LinkFault("nan", FAULT_STEP), Fault.NON_FINITE),
        FaultScenario(
            "out-of-range reading", LinkFault("out_of_range", FAULT_STEP), Fault.OUT_OF_RANGE
        ),
        FaultScenario("kill the sensor stream", LinkFault("kill", FAULT_STEP), Fault.STALE),
        FaultScenario("inference overrun", None, Fault.OVERRUN, slow_at_call=FAULT_STEP + 1),
    ]


class OverrunningController:
    """Wraps a controller; call ``slow_at_call`` (1-based) sleeps ``sleep_s`` first, as a
    controller starved of its core for a moment would."""

    def __init__(self, controller: DeployedController, slow_at_call: int, sleep_s: float):
        self.controller, self.slow_at_call, self.sleep_s = controller, slow_at_call, sleep_s
        self.name, self.input_names = controller.name, controller.input_names
        self.calls = 0

    def act(self, readings):
        self.calls += 1
        if self.calls == self.slow_at_call:
            time.sleep(self.sleep_s)
        return self.controller.act(readings)


def run_scenario(
    scenario: FaultScenario,
    controller_path: str,
    *,
    env_kwargs: dict,
    seed: int,
    runtime: RuntimeSettings,
    simulator: str = DEFAULT_SIMULATOR,
) -> dict:
    """Run one scenario against ``simulator`` (its arguments ``env_kwargs``); returns its
    outcome (see the module docstring)."""
    layout, control_hz = simulator_layout(simulator, env_kwargs)
    controller = load_controller(controller_path, sensors=layout.names, control_hz=control_hz)
    if scenario.slow_at_call is not None:
        # + the runtime's warm-up calls, which come first
        from .runtime import WARM_UP_CALLS

        controller = OverrunningController(
            controller, scenario.slow_at_call + WARM_UP_CALLS, 2 * runtime.inference_budget_s
        )
    bridge = BridgeSettings(
        simulator=simulator,
        env_kwargs=env_kwargs,
        seeds=(seed,),
        speedup=runtime.speedup,
        max_steps=EPISODE_STEPS,
        rearm_at_step=None if scenario.name.startswith("kill") else REARM_STEP,
    )
    outcome = {"scenario": scenario.name, "seed": seed, "crashed": False, "error": ""}
    try:
        records, summary = run_hil(
            controller,
            bridge,
            runtime,
            fault=scenario.fault,
            max_seconds=30.0,
            max_idle_s=max(1.0, 20 * runtime.period_s),
        )
    except Exception as error:  # noqa: BLE001 - a crash is what this measures
        return outcome | {"crashed": True, "error": f"{type(error).__name__}: {error}"}
    record = records[0]
    if scenario.slow_at_call is not None:
        onset = record["sent_s"][FAULT_STEP]
    else:
        onset = record["fault_onset_s"]
    commands = record["commands"]
    neutral = [
        c for c in commands if c["state"] == ControllerState.FAULTED and c["arrival_s"] >= onset
    ]
    first = neutral[0] if neutral else None
    rearm_sent = record["sent_s"][REARM_STEP] if bridge.rearm_at_step is not None else math.inf
    resumed = any(
        c["state"] == ControllerState.ARMED and c["arrival_s"] > rearm_sent for c in commands
    )
    deadline = runtime.period_s + runtime.age_s
    faults = Fault(first["faults"]) if first else Fault.NONE
    return outcome | {
        "expect": scenario.expect.name.lower() if scenario.expect else "none",
        "neutral": first is not None,
        "reported": "+".join(f.name.lower() for f in Fault if f and faults & f) or "none",
        "neutral_delay_s": (first["arrival_s"] - onset) if first else math.nan,
        "deadline_s": deadline,
        "within_deadline": (
            first is not None
            and first["arrival_s"] - onset <= deadline
            and scenario.expect is not None
            and bool(faults & scenario.expect)
        ),
        "resumed": resumed,
        "malformed": sum(summary["malformed"].values()),
        "late_commands": record["late_commands"],
    }


def fault_table(
    controller_path: str,
    *,
    env_kwargs: dict,
    runtime: RuntimeSettings,
    cases: int = 1,
    only: list[str] | None = None,
    simulator: str = DEFAULT_SIMULATOR,
) -> list[dict]:
    """Every scenario ``cases`` times (seeds 0..cases-1) against ``simulator``; one outcome
    per run."""
    chosen = scenarios(runtime.max_sensor_age_s, 1 / runtime.control_hz)
    if only:
        chosen = [s for s in chosen if s.name in only]
    return [
        run_scenario(
            s,
            controller_path,
            env_kwargs=env_kwargs,
            seed=seed,
            runtime=runtime,
            simulator=simulator,
        )
        for s in chosen
        for seed in range(cases)
    ]


def format_table(outcomes: list[dict]) -> str:
    """fault | cases | expected | neutral within deadline | worst delay | resumed | crashes."""
    lines = [
        "| fault | cases | watchdog must report | neutral within deadline | worst delay / "
        "deadline [ms] | resumed after re-arm | crashes |",
        "|---|---|---|---|---|---|---|",
    ]
    for name in dict.fromkeys(o["scenario"] for o in outcomes):
        rows = [o for o in outcomes if o["scenario"] == name]
        ok = [o for o in rows if not o["crashed"]]
        expect = ok[0]["expect"] if ok else "?"
        if expect == "none":
            neutral = f"not needed ({sum(o['neutral'] for o in ok)} neutral)"
            delay = "-"
        else:
            neutral = f"{sum(o['within_deadline'] for o in ok)}/{len(rows)}"
            worst = max((o["neutral_delay_s"] for o in ok), default=math.nan)
            delay = f"{worst * 1e3:.1f} / {ok[0]['deadline_s'] * 1e3:.1f}" if ok else "-"
        resumed = "-" if name.startswith("kill") else f"{sum(o['resumed'] for o in ok)}/{len(rows)}"
        crashes = sum(o["crashed"] for o in rows)
        cells = [name, len(rows), expect, neutral, delay, resumed, crashes]
        lines.append("| " + " | ".join(str(c) for c in cells) + " |")
    return "\n".join(lines)
