"""The machine's side of the UDP link, with optional fault injection on the sensor stream.

``MachineLink`` sends sensor packets (and re-arm requests) to a runtime and receives its
commands. A ``LinkFault`` makes it drop, delay, reorder, duplicate, corrupt or stop the
sensor packets from a given step on, or send NaN, out-of-range or garbage data, so that
tests can check the runtime's watchdog against the simulator.
"""

from __future__ import annotations

import contextlib
import socket
import time
from dataclasses import dataclass

import numpy as np

from .packets import (
    CommandPacket,
    ControllerState,
    PacketError,
    SensorFlag,
    SensorLayout,
    decode,
    encode_rearm,
    encode_sensors,
)

FAULT_KINDS = (
    "drop",  # `count` packets are not sent
    "delay",  # `count` packets are sent `delay_s` late (machine time)
    "reorder",  # packets `at_step` and `at_step + 1` are sent swapped
    "duplicate",  # packet `at_step` is sent twice
    "corrupt",  # `count` packets have bytes flipped (the checksum no longer holds)
    "nan",  # packet `at_step` reads NaN on its first sensor
    "out_of_range",  # packet `at_step` reads 10 x the declared maximum on its first sensor
    "garbage",  # `count` random datagrams are sent besides packet `at_step`
    "kill",  # no sensor packet is sent from `at_step` on (the episode end included)
)


@dataclass(frozen=True)
class LinkFault:
    """One injected fault on the sensor stream (step = the machine's control step)."""

    kind: str
    at_step: int
    count: int = 1
    delay_s: float = 0.0

    def __post_init__(self) -> None:
        if self.kind not in FAULT_KINDS:
            raise ValueError(f"LinkFault.kind: unknown {self.kind!r}; known: {FAULT_KINDS}")
        if self.at_step < 0 or self.count < 1 or self.delay_s < 0:
            raise ValueError(f"LinkFault: at_step >= 0, count >= 1, delay_s >= 0; got {self}")

    def covers(self, step: int) -> bool:
        if self.kind == "kill":
            return step >= self.at_step
        if self.kind == "reorder":
            return step in (self.at_step, self.at_step + 1)
        if self.kind in ("duplicate", "nan", "out_of_range", "garbage"):
            return step == self.at_step
        return self.at_step <= step < self.at_step + self.count


@dataclass
class ReceivedCommand:
    arrival_s: float  # machine clock [s]
    packet: CommandPacket


class MachineLink:
    """A UDP socket on loopback talking to the runtime at ``runtime_address``.

    Args:
        layout: the sensor layout (its id goes into every packet).
        runtime_address: (host, port) of the runtime.
        fault: the fault to inject, if any.
        speedup: divides ``fault.delay_s`` (machine time) into wall-clock time.
        seed: seeds the corrupt / garbage bytes.
    """

    def __init__(
        self,
        layout: SensorLayout,
        runtime_address: tuple[str, int],
        *,
        fault: LinkFault | None = None,
        speedup: float = 1.0,
        host: str = "127.0.0.1",
        seed: int = 0,
    ) -> None:
        self.layout, self.layout_id = layout, layout.layout_id
        self.runtime_address = runtime_address
        self.fault, self.speedup = fault, speedup
        self.socket = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.socket.bind((host, 0))
        self.rng = np.random.default_rng(seed)
        self.seq = 0
        self._held: list[tuple[float, bytes]] = []  # (release time, datagram)
        self._reordered: bytes | None = None
        self.received: list[ReceivedCommand] = []
        self.fault_onset_s: float | None = None  # when the first faulty packet was due
        self.malformed_commands = 0

    # ------------------------------------------------------------------ sending
    def send_sensors(self, step: int, values: np.ndarray, flags: SensorFlag) -> int:
        """Send the readings of control step ``step``; returns the sequence number used."""
        seq = self.seq
        self.seq += 1
        now = time.monotonic()
        fault = self.fault if self.fault is not None and self.fault.covers(step) else None
        if fault is not None and self.fault_onset_s is None:
            self.fault_onset_s = now
        values = np.array(values, dtype=np.float32)
        if fault is not None and fault.kind == "nan":
            values[0] = np.nan
        if fault is not None and fault.kind == "out_of_range":
            values[0] = 10 * max(abs(self.layout.channels[0].high), 1.0)
        data = encode_sensors(self.layout_id, seq, time.monotonic_ns(), values, flags)
        kind = fault.kind if fault is not None else None
        if kind in ("drop", "kill"):
            return seq
        if kind == "delay":
            self._held.append((now + fault.delay_s / self.speedup, data))
            return seq
        if kind == "corrupt":
            corrupted = bytearray(data)
            for index in self.rng.choice(len(data), size=3, replace=False):
                corrupted[index] ^= int(self.rng.integers(1, 256))
            data = bytes(corrupted)
        if kind == "reorder":
            if step == fault.at_step:
                self._reordered = data
                return seq
            self._send(data)
            data, self._reordered = self._reordered, None
        if kind == "duplicate":
            self._send(data)
        if kind == "garbage":
            for _ in range(fault.count):
                size = int(self.rng.integers(0, 120))
                self._send(self.rng.integers(0, 256, size, dtype=np.uint8).tobytes())
        if data is not None:
            self._send(data)
        return seq

    def send_rearm(self) -> None:
        self._send(encode_rearm(self.layout_id, self.seq, time.monotonic_ns()))

    def _send(self, data: bytes) -> None:
        with contextlib.suppress(OSError):  # the runtime is gone: the machine carries on
            self.socket.sendto(data, self.runtime_address)

    def _release_held(self, now: float) -> None:
        due = [item for item in self._held if item[0] <= now]
        self._held = [item for item in self._held if item[0] > now]
        for _, data in due:
            self._send(data)

    # ------------------------------------------------------------------ receiving
    def receive_until(self, deadline_s: float, *, answered_seq: int | None = None) -> None:
        """Collect commands until ``deadline_s`` (machine clock), or until one answering
        ``answered_seq`` arrives; releases delayed packets on time meanwhile."""
        while True:
            now = time.monotonic()
            self._release_held(now)
            wake = min([deadline_s, *(t for t, _ in self._held)])
            if now >= deadline_s:
                return
            self.socket.settimeout(max(wake - now, 1e-6))
            try:
                data = self.socket.recv(2048)
            except (TimeoutError, BlockingIOError, ConnectionRefusedError):
                continue
            try:
                packet = decode(data, layout_id=self.layout_id, n_sensors=len(self.layout.names))
            except PacketError:
                self.malformed_commands += 1
                continue
            if not isinstance(packet, CommandPacket):
                self.malformed_commands += 1
                continue
            self.received.append(ReceivedCommand(time.monotonic(), packet))
            answers = packet.answered_seq == answered_seq
            if answered_seq is not None and (answers or packet.state == ControllerState.FAULTED):
                return  # the answer, or a neutral command: either way the step can go on

    def latest_command(self) -> CommandPacket | None:
        return self.received[-1].packet if self.received else None

    def close(self) -> None:
        self.socket.close()
