"""The control loop's rules on a simulated clock: rate, watchdog faults, neutral deadline,
latching and re-arm. Times are exact here, so the deadline is asserted exactly."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pilerl.deploy.loop import ControlLoop, RuntimeSettings
from pilerl.deploy.packets import (
    CommandPacket,
    ControllerState,
    SensorChannel,
    SensorFlag,
    SensorLayout,
    decode,
    encode_rearm,
    encode_sensors,
)
from pilerl.deploy.watchdog import Fault

LAYOUT = SensorLayout(
    (
        SensorChannel("angle", "rad", -1.0, 1.0),
        SensorChannel("pressure", "MPa", 0.0, 40.0),
        SensorChannel("unused", "MPa", 0.0, 40.0),
    )
)
READING = np.float32([0.2, 10.0, 5.0])
PERIOD = 0.05
AGE = 0.15


class Clock:
    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


class FixedController:
    """Returns ``action``; each call takes ``cost_s`` of the simulated clock."""

    name = "fixed"
    input_names = ["pressure", "angle"]

    def __init__(self, clock: Clock, action=(0.5, 2.0, -0.25), cost_s: float = 0.0):
        self.clock, self.action, self.cost_s = clock, np.float32(action), cost_s
        self.seen: list[np.ndarray] = []

    def act(self, readings):
        self.seen.append(np.array(readings))
        self.clock.now += self.cost_s
        return self.action


class Harness:
    """A loop with a simulated clock; ``sent`` holds (time, command) pairs."""

    def __init__(self, control_hz: float = 20.0, **controller) -> None:
        self.clock = Clock()
        self.controller = FixedController(self.clock, **controller)
        self.sent: list[tuple[float, CommandPacket]] = []
        self.loop = ControlLoop(
            self.controller,
            LAYOUT,
            RuntimeSettings(control_hz=control_hz, max_sensor_age_s=AGE),
            clock=self.clock,
            send=self._send,
        )
        self.seq = 0

    def _send(self, data: bytes, address) -> None:
        packet = decode(data, layout_id=LAYOUT.layout_id, n_sensors=3)
        self.sent.append((self.clock.now, packet))

    def advance(self, until: float) -> None:
        """Run the loop's timers up to ``until``."""
        while (wake := self.loop.next_wakeup()) is not None and wake <= until:
            self.clock.now = max(self.clock.now, wake)
            self.loop.on_timer(self.clock.now)
        self.clock.now = max(self.clock.now, until)

    def deliver(self, at: float, data: bytes) -> None:
        self.advance(at)
        self.loop.on_datagram(data, self.clock.now, sender="machine")

    def reading(self, at: float, values=READING, *, seq=None, stamp=None, flags=SensorFlag.NONE):
        seq = self.seq if seq is None else seq
        self.seq = max(self.seq, seq + 1)
        stamp_ns = int((at if stamp is None else stamp) * 1e9)
        data = encode_sensors(LAYOUT.layout_id, seq, stamp_ns, values, flags)
        self.deliver(at, data)

    def stream(self, start: float, stop: float, period: float = PERIOD) -> None:
        for k in range(round((stop - start) / period)):
            self.reading(start + k * period)

    def neutral(self, after: float = -1.0) -> list[tuple[float, CommandPacket]]:
        return [(t, c) for t, c in self.sent if c.state == ControllerState.FAULTED and t >= after]


def test_each_reading_is_answered_at_once_with_clipped_controls_from_its_sensors():
    h = Harness()
    h.stream(0.0, 1.0)
    assert len(h.sent) == 20
    assert [c.answered_seq for _, c in h.sent] == list(range(20))
    assert all(t == pytest.approx(k * PERIOD) for k, (t, _) in enumerate(h.sent))  # no delay
    np.testing.assert_array_equal(h.sent[0][1].controls, np.float32([0.5, 1.0, -0.25]))
    np.testing.assert_array_equal(h.controller.seen[0], np.float32([10.0, 0.2]))  # by name
    assert h.loop.counters.deadline_misses == 0 and not h.neutral()


def test_slow_control_under_fast_sensors_keeps_the_control_rate():
    h = Harness(control_hz=3.0)
    h.stream(0.0, 6.0)  # 20 Hz readings for 6 s
    times = [t for t, _ in h.sent]
    assert len(times) in (18, 19)  # 3 Hz
    assert min(np.diff(times)) >= 0.75 / 3.0 - 1e-9
    assert h.loop.counters.superseded > 0 and not h.neutral()


def _stream_then(h: Harness, fault_at: float) -> None:
    h.stream(0.0, fault_at)


@pytest.mark.parametrize(
    ("inject", "expected"),
    [
        (lambda h, t: h.reading(t, np.float32([np.nan, 1, 1])), Fault.NON_FINITE),
        (lambda h, t: h.reading(t, np.float32([0.2, 41.0, 1])), Fault.OUT_OF_RANGE),
        (lambda h, t: h.reading(t, np.float32([0.2, 1, -1.0])), Fault.OUT_OF_RANGE),
        (lambda h, t: h.reading(t, seq=h.seq - 1), Fault.DUPLICATE),
        (lambda h, t: h.reading(t, seq=h.seq - 3), Fault.OUT_OF_ORDER),
        (lambda h, t: h.reading(t, stamp=t - AGE - 0.01), Fault.STALE),  # delayed in transit
        (lambda h, t: h.advance(t + 1.0), Fault.STALE),  # the stream stops
    ],
)
def test_faults_command_neutral_within_one_period_plus_the_age_and_latch(inject, expected):
    h = Harness()
    onset = 1.0
    h.stream(0.0, onset)
    inject(h, onset)
    h.advance(onset + 1.0)
    neutral = h.neutral()
    assert neutral, "no neutral command"
    first_time, first = neutral[0]
    last_good = (onset - PERIOD) if expected == Fault.STALE else onset
    assert first_time - last_good <= PERIOD + AGE + 1e-9
    assert first.faults & expected
    np.testing.assert_array_equal(first.controls, np.zeros(3, np.float32))
    # latched: good readings are ignored, neutral goes out once per period
    window = h.clock.now + 0.01
    h.stream(window, window + 0.5)
    after = [c for t, c in h.sent if t > first_time]
    assert all(c.state == ControllerState.FAULTED for c in after)
    assert all(np.all(c.controls == 0) for c in after)
    assert len([t for t, _ in h.sent if t >= window]) == pytest.approx(0.5 / PERIOD, abs=1)


def test_overrun_and_bad_output_are_faults():
    h = Harness(cost_s=0.06)  # > one period of inference
    h.reading(0.0)
    (_, command) = h.sent[0]
    assert command.state == ControllerState.FAULTED and command.faults & Fault.OVERRUN
    h = Harness(action=(np.nan, 0.0, 0.0))
    h.reading(0.0)
    assert h.sent[0][1].faults & Fault.BAD_OUTPUT


def test_control_resumes_only_after_an_explicit_rearm():
    h = Harness()
    h.stream(0.0, 0.5)
    h.reading(0.5, np.float32([np.nan, 1, 1]))
    h.stream(0.55, 1.0)
    assert h.sent[-1][1].state == ControllerState.FAULTED
    h.deliver(1.0, encode_rearm(LAYOUT.layout_id, 0, 0))
    h.stream(1.0, 1.5)
    resumed = [c for t, c in h.sent if t >= 1.0]
    assert resumed and all(c.state == ControllerState.ARMED for c in resumed)
    assert h.loop.counters.rearms == 1
    assert h.loop.counters.faults == {"non_finite": 1}


def test_no_command_before_the_machine_is_heard_and_none_while_fresh_data_is_missing():
    h = Harness()
    h.advance(1.0)
    assert h.sent == []  # nobody to command yet, and nothing stale to report
    h.reading(1.0)
    h.advance(1.0 + AGE)  # within the age: no neutral, no new command
    assert len(h.sent) == 1


def test_episode_start_relocks_the_grid():
    h = Harness()
    h.stream(0.0, 0.5)
    h.reading(0.51, flags=SensorFlag.EPISODE_START)  # a new episode, off the old grid
    assert h.sent[-1][0] == pytest.approx(0.51)


@settings(max_examples=200, deadline=None)
@given(st.lists(st.binary(max_size=80), max_size=20))
def test_garbage_is_counted_and_never_reaches_the_controller(datagrams):
    h = Harness()
    for i, data in enumerate(datagrams):
        h.deliver(i * 0.001, data)
    assert h.controller.seen == []
    assert sum(h.loop.counters.malformed.values()) == len(datagrams)


def test_after_a_stall_the_grid_locks_again_to_the_machine_not_to_the_stall():
    h = Harness()
    h.stream(0.0, 1.0)
    h.reading(1.0 + 0.07, stamp=1.0)  # the runtime was stalled 70 ms (> one period)
    start = len(h.sent)
    for k in range(1, 10):
        h.reading(1.0 + k * PERIOD)
    times = [t for t, _ in h.sent[start:]]
    assert times[0] == pytest.approx(1.07)  # the reading that came during the stall
    assert times[1:] == pytest.approx([1.0 + k * PERIOD for k in range(2, 10)])  # on arrival
    assert h.loop.counters.deadline_misses == 1 and not h.neutral()
