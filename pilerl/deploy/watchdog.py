"""The safety watchdog: decides, from what arrived and when, whether the controller may act.

Once a fault is found the watchdog latches: every command is neutral (boom, bucket and
throttle 0) until an explicit re-arm. It does no I/O and reads no clock: the runtime
passes the times in, so its rules are tested with exact, simulated times.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import IntFlag

import numpy as np

NEUTRAL = np.zeros(3, dtype=np.float32)  # boom, bucket, throttle: valves closed, pump at zero


class Fault(IntFlag):
    """Why the controls are neutral (bits of a command packet's ``faults``)."""

    NONE = 0
    STALE = 1  # no fresh reading for longer than the allowed age, or a reading that old
    NON_FINITE = 2  # a reading is NaN or infinite
    OUT_OF_RANGE = 4  # a reading lies outside its sensor's declared range
    OUT_OF_ORDER = 8  # a sequence number lower than one already seen
    DUPLICATE = 16  # a sequence number seen already
    OVERRUN = 32  # inference took longer than its budget
    BAD_OUTPUT = 64  # the controller returned a non-finite control


def fault_names(faults: int) -> list[str]:
    return [f.name.lower() for f in Fault if f and faults & f]


@dataclass
class Watchdog:
    """Checks every sensor reading and the time since the last good one.

    Attributes:
        low, high: each sensor's declared range (layout order), in its unit.
        max_age_s: a reading older than this is stale [s]. Age is measured on the
            runtime's clock from arrival, plus any delay in transit beyond the smallest
            seen since arming (so two ends need not share a clock).
        latched: the faults that made the controls neutral (``Fault.NONE`` when armed).
    """

    low: np.ndarray
    high: np.ndarray
    max_age_s: float
    latched: Fault = Fault.NONE
    last_seq: int | None = None
    last_arrival_s: float | None = None
    _min_transit_s: float | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        if not self.max_age_s > 0:
            raise ValueError(f"Watchdog.max_age_s: must be > 0, got {self.max_age_s}")

    @property
    def armed(self) -> bool:
        return self.latched == Fault.NONE

    def check_reading(
        self, seq: int, values: np.ndarray, *, arrival_s: float, sent_s: float
    ) -> Fault:
        """Faults of one sensor packet (``Fault.NONE`` if it may be used).

        ``arrival_s`` is on the runtime's clock, ``sent_s`` the sender's stamp on its own.
        """
        faults = Fault.NONE
        if self.last_seq is not None:
            if seq == self.last_seq:
                faults |= Fault.DUPLICATE
            elif seq < self.last_seq:
                faults |= Fault.OUT_OF_ORDER
        if not np.isfinite(values).all():
            faults |= Fault.NON_FINITE
        elif ((values < self.low) | (values > self.high)).any():
            faults |= Fault.OUT_OF_RANGE
        transit = arrival_s - sent_s
        if self._min_transit_s is not None and transit - self._min_transit_s > self.max_age_s:
            faults |= Fault.STALE
        if not faults:
            self.last_seq = seq
            self.last_arrival_s = arrival_s
            if self._min_transit_s is None or transit < self._min_transit_s:
                self._min_transit_s = transit
        return faults

    def expected_arrival_s(self, sent_s: float) -> float | None:
        """When a packet stamped ``sent_s`` arrives without delay, on the runtime's clock."""
        return None if self._min_transit_s is None else sent_s + self._min_transit_s

    def stale_at(self) -> float | None:
        """When the last good reading becomes stale, on the runtime's clock [s]."""
        if self.last_arrival_s is None:
            return None
        return self.last_arrival_s + self.max_age_s

    def is_stale(self, now_s: float) -> bool:
        deadline = self.stale_at()
        return deadline is not None and now_s > deadline

    def latch(self, faults: Fault) -> None:
        self.latched |= faults

    def rearm(self) -> None:
        """Clear the latch and forget the stream: the next reading starts afresh."""
        self.latched = Fault.NONE
        self.last_seq = None
        self.last_arrival_s = None
        self._min_transit_s = None
