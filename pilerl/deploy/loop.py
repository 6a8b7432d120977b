"""The control loop's rules, without sockets: what to send, when, and with which controls.

``ControlLoop`` is fed datagrams and wake-ups with the time they happened, and sends
command packets through a callable; ``pilerl.deploy.runtime`` wires it to UDP and a
clock. Kept apart so the timing rules are tested with exact, simulated times.

Timing. Commands go out on a fixed grid of one control period ``P``, locked to the
sensor stream: a fresh reading is acted on at once when it arrives within ``P/4`` of the
next grid time or later (the usual case when the machine samples at the control rate);
one that arrives earlier is held and acted on at the grid time (sample and hold, e.g.
20 Hz sensors under 3 Hz control). At most one command per period comes from data; a
grid time that passes without fresh data is a counted deadline miss. While a fault is
latched a neutral command goes out at once and then once per period.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from .controllers import DeployedController
from .packets import (
    ControllerState,
    PacketError,
    RearmPacket,
    SensorFlag,
    SensorLayout,
    SensorPacket,
    decode,
    encode_command,
)
from .watchdog import NEUTRAL, Fault, Watchdog, fault_names

EARLY_FRACTION = 0.25  # a reading this much of a period before its grid time is on time
CONTROL_HZ_CHOICES = (3.0, 20.0)  # the paper's command and sensor rates; others allowed


@dataclass(frozen=True)
class RuntimeSettings:
    """How the runtime runs (times are machine time; ``speedup`` divides them all).

    Attributes:
        control_hz: commands per second (the paper: 3 Hz on the machine; 20 Hz sensors).
        max_sensor_age_s: the watchdog's stale limit [s].
        max_inference_s: inference budget per command [s]; ``None`` = one control period.
        speedup: run this many times faster than real time (hardware-in-the-loop tests
            against a simulator running equally fast); 1 on a machine.
        host, port: where to listen for sensor and re-arm packets (loopback by default;
            port 0 = any free port). Commands go back to the sender of the sensors.
    """

    control_hz: float = 20.0
    max_sensor_age_s: float = 0.15
    max_inference_s: float | None = None
    speedup: float = 1.0
    host: str = "127.0.0.1"
    port: int = 0

    def __post_init__(self) -> None:
        for name in ("control_hz", "max_sensor_age_s", "speedup"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and 0 < value < float("inf")):
                raise ValueError(f"RuntimeSettings.{name}: must be finite and > 0, got {value}")
        if self.max_inference_s is not None and not self.max_inference_s > 0:
            raise ValueError(
                f"RuntimeSettings.max_inference_s: must be > 0 or None, got {self.max_inference_s}"
            )
        if not 0 <= self.port < 65536:
            raise ValueError(f"RuntimeSettings.port: must be in 0..65535, got {self.port}")

    @property
    def period_s(self) -> float:
        """Wall-clock control period [s]."""
        return 1.0 / (self.control_hz * self.speedup)

    @property
    def age_s(self) -> float:
        """Wall-clock stale limit [s]."""
        return self.max_sensor_age_s / self.speedup

    @property
    def inference_budget_s(self) -> float:
        """Wall-clock inference budget [s]."""
        budget = self.max_inference_s if self.max_inference_s is not None else 1 / self.control_hz
        return budget / self.speedup


@dataclass
class CycleRecord:
    """One command sent (what the episode log and ``cycles.csv`` keep)."""

    sent_s: float  # runtime clock [s]
    answered_seq: int  # -1: no reading answered (a repeated neutral command)
    arrival_s: float  # when the answered reading arrived [s] (NaN for repeats)
    inference_s: float  # NaN when the controller did not run
    faults: int
    controls: np.ndarray
    readings: np.ndarray | None  # the last good readings (layout order), if any

    @property
    def latency_s(self) -> float:
        return self.sent_s - self.arrival_s


@dataclass
class LoopCounters:
    """What the loop counted; written to ``summary.json``."""

    datagrams: int = 0
    readings: int = 0
    commands: int = 0
    neutral_commands: int = 0
    deadline_misses: int = 0
    superseded: int = 0  # fresh readings replaced before being acted on
    ignored_while_faulted: int = 0
    rearms: int = 0
    malformed: Counter = field(default_factory=Counter)
    faults: Counter = field(default_factory=Counter)


def check_inputs(controller: DeployedController, layout: SensorLayout) -> None:
    """Refuse a controller that reads a sensor the machine does not send."""
    missing = [n for n in controller.input_names if n not in layout.names]
    if missing:
        raise ValueError(
            f"controller {controller.name!r} reads sensors {missing} that the machine's "
            f"layout does not send; layout: {layout.names}"
        )


class ControlLoop:
    """See the module docstring.

    Args:
        controller: reads ``controller.input_names`` (a subset of the layout's sensors).
        layout: the sensors of a sensor packet, in order, with units and ranges.
        settings: rates, stale limit, inference budget.
        clock: seconds on the runtime's monotonic clock.
        send: ``send(datagram, address)``: one command to the machine's address.
        on_command, on_fault, on_reading: observers (the episode log).
    """

    def __init__(
        self,
        controller: DeployedController,
        layout: SensorLayout,
        settings: RuntimeSettings,
        *,
        clock: Callable[[], float],
        send: Callable[[bytes, object], None],
        on_command: Callable[[CycleRecord], None] | None = None,
        on_fault: Callable[[float, Fault, str], None] | None = None,
        on_reading: Callable[[SensorPacket, float], None] | None = None,
    ) -> None:
        check_inputs(controller, layout)
        self.controller, self.layout, self.settings = controller, layout, settings
        self.clock, self.send = clock, send
        self.on_command, self.on_fault, self.on_reading = on_command, on_fault, on_reading
        self.input_index = np.array([layout.names.index(n) for n in controller.input_names])
        self.layout_id = layout.layout_id
        self.watchdog = Watchdog(layout.low, layout.high, settings.age_s)
        self.counters = LoopCounters()
        self.period_s = settings.period_s
        self.pending: SensorPacket | None = None
        self._pending_arrival_s = float("nan")
        self.last_readings: np.ndarray | None = None
        self.next_due_s: float | None = None
        self.next_neutral_s: float | None = None
        self.machine_address: object | None = None  # sender of the last sensor packet
        self._command_seq = 0

    # ------------------------------------------------------------------ events
    @property
    def can_reply(self) -> bool:
        return self.machine_address is not None

    def on_datagram(self, data: bytes, now_s: float, sender: object = "machine") -> None:
        """Handle one datagram from ``sender`` (``now_s``: when it arrived)."""
        self.counters.datagrams += 1
        try:
            packet = decode(data, layout_id=self.layout_id, n_sensors=len(self.layout.names))
        except PacketError as error:
            self.counters.malformed[error.reason] += 1
            return
        if isinstance(packet, RearmPacket):
            self.rearm(now_s)
        elif isinstance(packet, SensorPacket):
            self.machine_address = sender
            self._on_reading(packet, now_s)
        else:
            self.counters.malformed["kind"] += 1  # commands are ours to send, not receive

    def on_timer(self, now_s: float) -> None:
        """Act on whatever is due at ``now_s``: staleness, neutral repeats, a held reading."""
        if self.watchdog.armed and self.watchdog.is_stale(now_s):
            self._fault(now_s, Fault.STALE, f"no fresh reading for {self.settings.age_s:.3f} s")
        if not self.watchdog.armed:
            if self.can_reply and self.next_neutral_s is not None and now_s >= self.next_neutral_s:
                self._send_neutral(answered_seq=-1, arrival_s=float("nan"))
            return
        if self.pending is not None and now_s >= self._act_from():
            self._act()

    def next_wakeup(self) -> float | None:
        """The next time ``on_timer`` has something to do (``None``: only a datagram)."""
        times = []
        if self.watchdog.armed:
            stale = self.watchdog.stale_at()
            if stale is not None:
                times.append(stale + 1e-6)
            if self.pending is not None:
                times.append(self._act_from())
        elif self.can_reply and self.next_neutral_s is not None:
            times.append(self.next_neutral_s)
        return min(times) if times else None

    def rearm(self, now_s: float) -> None:
        """Resume control: clear the latched fault; the next fresh reading is acted on."""
        self.counters.rearms += 1
        if self.on_fault is not None:
            self.on_fault(now_s, Fault.NONE, "re-armed")
        self.watchdog.rearm()
        self.pending, self.next_due_s, self.next_neutral_s = None, None, None

    # ------------------------------------------------------------------ internals
    def _act_from(self) -> float:
        if self.next_due_s is None:
            return float("-inf")
        return self.next_due_s - EARLY_FRACTION * self.period_s

    def _on_reading(self, packet: SensorPacket, now_s: float) -> None:
        self.counters.readings += 1
        if not self.watchdog.armed:
            self.counters.ignored_while_faulted += 1
            if packet.flags & SensorFlag.EPISODE_END and self.on_reading is not None:
                self.on_reading(packet, now_s)
            return
        faults = self.watchdog.check_reading(
            packet.seq, packet.values, arrival_s=now_s, sent_s=packet.stamp_ns * 1e-9
        )
        if faults:
            self._fault(now_s, faults, f"sensor packet seq {packet.seq}", answered=packet.seq)
            return
        self.last_readings = packet.values
        if self.on_reading is not None:
            self.on_reading(packet, now_s)
        if packet.flags & (SensorFlag.EPISODE_START | SensorFlag.EPISODE_END):
            self.next_due_s = None  # a new episode: lock the grid to its first reading
            self.pending = None
        if packet.flags & SensorFlag.EPISODE_START and hasattr(self.controller, "reset"):
            self.controller.reset()  # a stateful controller starts its episode afresh
        if packet.flags & SensorFlag.EPISODE_END:
            return  # the reading after the last command: nothing to answer
        if self.pending is not None:
            self.counters.superseded += 1
        self.pending = packet
        self._pending_arrival_s = now_s
        if now_s >= self._act_from():
            self._act()

    def _act(self) -> None:
        packet, arrival_s = self.pending, self._pending_arrival_s
        self.pending = None
        start = self.clock()
        action = self.controller.act(packet.values[self.input_index])
        inference_s = self.clock() - start
        action = np.asarray(action, dtype=np.float32).reshape(-1)
        faults = Fault.NONE
        if inference_s > self.settings.inference_budget_s:
            faults |= Fault.OVERRUN
        if action.shape != (3,) or not np.isfinite(action).all():
            faults |= Fault.BAD_OUTPUT
        now_s = self.clock()
        expected = self.watchdog.expected_arrival_s(packet.stamp_ns * 1e-9)
        self._advance_grid(now_s, arrival_s if expected is None else min(expected, arrival_s))
        if faults:
            detail = f"inference {inference_s * 1e3:.2f} ms, output {action.tolist()}"
            self._fault(now_s, faults, detail, answered=packet.seq, arrival_s=arrival_s)
            return
        # the simulator's rule: finite controls are clipped to [-1, 1]
        self._send(np.clip(action, -1.0, 1.0), packet.seq, arrival_s, inference_s)

    def _advance_grid(self, now_s: float, reading_s: float) -> None:
        """Next grid time after acting at ``now_s`` on a reading that arrived, or would
        have without delay, at ``reading_s``. A grid lost by more than a period (a
        stall) is locked again to the reading, not to ``now_s``: the machine keeps its
        own pace, and a grid behind it would hold every later reading."""
        if self.next_due_s is None:
            self.next_due_s = reading_s + self.period_s
            return
        following = self.next_due_s + self.period_s
        if following <= now_s:
            self.counters.deadline_misses += int((now_s - self.next_due_s) // self.period_s)
            following = reading_s + self.period_s
        self.next_due_s = following

    def _fault(
        self,
        now_s: float,
        faults: Fault,
        detail: str,
        *,
        answered: int = -1,
        arrival_s: float = float("nan"),
    ) -> None:
        for name in fault_names(faults):
            self.counters.faults[name] += 1
        if faults & Fault.OVERRUN:
            self.counters.deadline_misses += 1
        self.watchdog.latch(faults)
        self.pending = None
        if self.on_fault is not None:
            self.on_fault(now_s, faults, detail)
        if self.can_reply:
            self._send_neutral(answered_seq=answered, arrival_s=arrival_s)

    def _send_neutral(self, *, answered_seq: int, arrival_s: float) -> None:
        self.counters.neutral_commands += 1
        self._send(NEUTRAL, answered_seq, arrival_s, float("nan"))
        self.next_neutral_s = self.clock() + self.period_s

    def _send(
        self, controls: np.ndarray, answered_seq: int, arrival_s: float, inference_s: float
    ) -> None:
        faults = int(self.watchdog.latched)
        state = ControllerState.ARMED if faults == 0 else ControllerState.FAULTED
        data = encode_command(
            self.layout_id,
            self._command_seq,
            int(self.clock() * 1e9),
            answered_seq=max(answered_seq, 0),
            faults=faults,
            state=state,
            controls=controls,
        )
        self.send(data, self.machine_address)
        sent_s = self.clock()
        self._command_seq += 1
        self.counters.commands += 1
        if self.on_command is not None:
            self.on_command(
                CycleRecord(
                    sent_s,
                    answered_seq,
                    arrival_s,
                    inference_s,
                    faults,
                    np.array(controls, dtype=np.float32),
                    self.last_readings,
                )
            )
