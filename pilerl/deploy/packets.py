"""The deployment wire format (version 1): small binary UDP packets, little-endian.

Every packet is a 24-byte header, a body that depends on its kind, and a CRC-32 of
everything before it (4 bytes, ``zlib.crc32``):

| offset | field | type | meaning |
|---|---|---|---|
| 0 | ``magic`` | 4 bytes | ``b"PLRL"`` |
| 4 | ``version`` | u8 | ``PACKET_VERSION`` (1) |
| 5 | ``kind`` | u8 | 1 sensors, 2 command, 3 re-arm |
| 6 | ``flags`` | u16 | sensors: ``EPISODE_START`` / ``EPISODE_END`` / ``TERMINATED`` |
| 8 | ``layout_id`` | u32 | CRC-32 of the sensor layout (names, units, ranges) |
| 12 | ``seq`` | u32 | sender's sequence number, +1 per packet it sends |
| 16 | ``stamp_ns`` | i64 | sender's monotonic clock when the packet was made [ns] |

Bodies:

- sensors (machine -> runtime): one float32 per sensor of the layout, in layout order
  (physical units, e.g. rad and MPa). 7 sensors: 56 bytes in all.
- command (runtime -> machine): ``answered_seq`` u32 (the sensor packet acted on),
  ``faults`` u16 (``pilerl.deploy.watchdog.Fault`` bits, 0 = none), ``state`` u8
  (1 armed, 2 faulted: neutral until re-armed), one pad byte, then float32
  boom, bucket, throttle in [-1, 1]. 48 bytes.
- re-arm (operator -> runtime): no body. 28 bytes.

A packet of the wrong size, magic, version, kind, CRC or layout is a ``PacketError``
whose ``reason`` the runtime counts; it never reaches the controller.
"""

from __future__ import annotations

import json
import math
import struct
import zlib
from collections.abc import Mapping
from dataclasses import dataclass
from enum import IntEnum, IntFlag

import numpy as np

MAGIC = b"PLRL"
PACKET_VERSION = 1
HEADER = struct.Struct("<4sBBHIIq")
CRC = struct.Struct("<I")
COMMAND_BODY = struct.Struct("<IHBx3f")
N_CONTROLS = 3  # boom, bucket, throttle
U32 = 2**32


class PacketKind(IntEnum):
    SENSORS = 1
    COMMAND = 2
    REARM = 3


class SensorFlag(IntFlag):
    """Flags of a sensor packet: episode bookkeeping for logging (not safety)."""

    NONE = 0
    EPISODE_START = 1  # first reading of an episode
    EPISODE_END = 2  # the reading after the last command: no command is wanted
    TERMINATED = 4  # with EPISODE_END: the task ended (not a time limit)


class ControllerState(IntEnum):
    ARMED = 1
    FAULTED = 2


class PacketError(ValueError):
    """A datagram that is not a valid packet; ``reason`` is a short counter name."""

    def __init__(self, reason: str, detail: str) -> None:
        super().__init__(f"{reason}: {detail}")
        self.reason = reason


@dataclass(frozen=True)
class SensorChannel:
    """One sensor of the layout: name, unit and declared range (low, high)."""

    name: str
    unit: str
    low: float
    high: float


@dataclass(frozen=True)
class SensorLayout:
    """The machine's sensors in packet order, as the simulator plugin declares them."""

    channels: tuple[SensorChannel, ...]

    def __post_init__(self) -> None:
        names = self.names
        if not names or len(set(names)) != len(names):
            raise ValueError(f"SensorLayout: need distinct sensor names, got {names}")
        for c in self.channels:
            if not (math.isfinite(c.low) and math.isfinite(c.high) and c.low < c.high):
                raise ValueError(f"SensorLayout: sensor {c.name!r} has range {c.low}..{c.high}")

    @property
    def names(self) -> list[str]:
        return [c.name for c in self.channels]

    @property
    def units(self) -> dict[str, str]:
        return {c.name: c.unit for c in self.channels}

    @property
    def low(self) -> np.ndarray:
        return np.array([c.low for c in self.channels], dtype=np.float32)

    @property
    def high(self) -> np.ndarray:
        return np.array([c.high for c in self.channels], dtype=np.float32)

    @property
    def layout_id(self) -> int:
        """CRC-32 of the layout's JSON: both ends must agree on it."""
        return zlib.crc32(json.dumps(self.to_json(), sort_keys=True).encode())

    def to_json(self) -> list[dict]:
        return [
            {"name": c.name, "unit": c.unit, "low": float(c.low), "high": float(c.high)}
            for c in self.channels
        ]

    @classmethod
    def from_json(cls, data: list[dict]) -> SensorLayout:
        return cls(tuple(SensorChannel(**entry) for entry in data))

    @classmethod
    def from_env(cls, env, units: Mapping[str, str]) -> SensorLayout:
        """From a simulator env: its ``Dict`` observation space (order, ranges) and the
        sensor ``units`` its plugin declares (``SimulatorPlugin.sensor_units``)."""
        base = env.unwrapped
        channels = []
        for name, space in base.observation_space.spaces.items():
            channels.append(
                SensorChannel(
                    name, units.get(name, ""), float(space.low.min()), float(space.high.max())
                )
            )
        return cls(tuple(channels))


@dataclass(frozen=True)
class SensorPacket:
    seq: int
    stamp_ns: int
    values: np.ndarray  # float32 [n_sensors], layout order
    flags: SensorFlag = SensorFlag.NONE


@dataclass(frozen=True)
class CommandPacket:
    seq: int
    stamp_ns: int
    answered_seq: int
    faults: int
    state: ControllerState
    controls: np.ndarray  # float32 [3]: boom, bucket, throttle


@dataclass(frozen=True)
class RearmPacket:
    seq: int
    stamp_ns: int


Packet = SensorPacket | CommandPacket | RearmPacket


def _seal(header_and_body: bytes) -> bytes:
    return header_and_body + CRC.pack(zlib.crc32(header_and_body))


def _header(kind: PacketKind, flags: int, layout_id: int, seq: int, stamp_ns: int) -> bytes:
    return HEADER.pack(MAGIC, PACKET_VERSION, kind, flags, layout_id, seq % U32, stamp_ns)


def encode_sensors(
    layout_id: int, seq: int, stamp_ns: int, values, flags: SensorFlag = SensorFlag.NONE
) -> bytes:
    body = np.asarray(values, dtype="<f4").tobytes()
    return _seal(_header(PacketKind.SENSORS, int(flags), layout_id, seq, stamp_ns) + body)


def encode_command(
    layout_id: int,
    seq: int,
    stamp_ns: int,
    *,
    answered_seq: int,
    faults: int,
    state: ControllerState,
    controls,
) -> bytes:
    boom, bucket, throttle = (float(v) for v in controls)
    body = COMMAND_BODY.pack(answered_seq % U32, faults, state, boom, bucket, throttle)
    return _seal(_header(PacketKind.COMMAND, 0, layout_id, seq, stamp_ns) + body)


def encode_rearm(layout_id: int, seq: int, stamp_ns: int) -> bytes:
    return _seal(_header(PacketKind.REARM, 0, layout_id, seq, stamp_ns))


def sensor_packet_size(n_sensors: int) -> int:
    return HEADER.size + 4 * n_sensors + CRC.size


COMMAND_SIZE = HEADER.size + COMMAND_BODY.size + CRC.size
REARM_SIZE = HEADER.size + CRC.size


def decode(data: bytes, *, layout_id: int, n_sensors: int) -> Packet:
    """Parse one datagram; raises ``PacketError`` (never anything else) if it is not valid."""
    if len(data) < HEADER.size + CRC.size:
        raise PacketError("size", f"{len(data)} bytes is shorter than a header and CRC")
    magic, version, kind, flags, layout, seq, stamp_ns = HEADER.unpack_from(data)
    if magic != MAGIC:
        raise PacketError("magic", f"magic {magic!r}, expected {MAGIC!r}")
    if version != PACKET_VERSION:
        raise PacketError("version", f"version {version}, this runtime speaks {PACKET_VERSION}")
    (crc,) = CRC.unpack_from(data, len(data) - CRC.size)
    if crc != zlib.crc32(data[: -CRC.size]):
        raise PacketError("crc", "checksum mismatch")
    if layout != layout_id:
        raise PacketError("layout", f"layout id {layout:#010x}, expected {layout_id:#010x}")
    if kind == PacketKind.SENSORS:
        expected = sensor_packet_size(n_sensors)
        if len(data) != expected:
            raise PacketError("size", f"sensor packet of {len(data)} bytes, expected {expected}")
        if flags & ~int(SensorFlag(7)):
            raise PacketError("flags", f"unknown sensor flags {flags:#06x}")
        values = np.frombuffer(data, dtype="<f4", count=n_sensors, offset=HEADER.size)
        return SensorPacket(seq, stamp_ns, values.astype(np.float32), SensorFlag(flags))
    if kind == PacketKind.COMMAND:
        if len(data) != COMMAND_SIZE:
            raise PacketError("size", f"command packet of {len(data)} bytes, not {COMMAND_SIZE}")
        answered, faults, state, *controls = COMMAND_BODY.unpack_from(data, HEADER.size)
        if state not in (ControllerState.ARMED, ControllerState.FAULTED):
            raise PacketError("state", f"unknown controller state {state}")
        return CommandPacket(
            seq,
            stamp_ns,
            answered,
            faults,
            ControllerState(state),
            np.asarray(controls, dtype=np.float32),
        )
    if kind == PacketKind.REARM:
        if len(data) != REARM_SIZE:
            raise PacketError("size", f"re-arm packet of {len(data)} bytes, not {REARM_SIZE}")
        return RearmPacket(seq, stamp_ns)
    raise PacketError("kind", f"unknown packet kind {kind}")
