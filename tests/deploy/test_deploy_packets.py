"""The deployment wire format: round trips, sizes, and malformed datagrams refused cleanly."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pilerl.deploy.packets import (
    COMMAND_SIZE,
    PACKET_VERSION,
    REARM_SIZE,
    CommandPacket,
    ControllerState,
    PacketError,
    RearmPacket,
    SensorChannel,
    SensorFlag,
    SensorLayout,
    SensorPacket,
    decode,
    encode_command,
    encode_rearm,
    encode_sensors,
    sensor_packet_size,
)

LAYOUT = SensorLayout(
    tuple(SensorChannel(f"sensor_{i}", "MPa", -1.0 - i, 40.0 + i) for i in range(7))
)
LAYOUT_ID = LAYOUT.layout_id
N = len(LAYOUT.names)


def _decode(data: bytes):
    return decode(data, layout_id=LAYOUT_ID, n_sensors=N)


def test_sensor_packet_round_trips_and_is_small():
    values = np.arange(N, dtype=np.float32) * 1.5 - 2
    data = encode_sensors(LAYOUT_ID, 41, 123_456_789, values, SensorFlag.EPISODE_START)
    assert len(data) == sensor_packet_size(N) == 56
    packet = _decode(data)
    assert isinstance(packet, SensorPacket)
    assert (packet.seq, packet.stamp_ns) == (41, 123_456_789)
    assert packet.flags == SensorFlag.EPISODE_START
    np.testing.assert_array_equal(packet.values, values)


def test_command_and_rearm_packets_round_trip():
    data = encode_command(
        LAYOUT_ID,
        7,
        99,
        answered_seq=41,
        faults=8,
        state=ControllerState.FAULTED,
        controls=[0.25, -1.0, 0.5],
    )
    assert len(data) == COMMAND_SIZE == 48
    packet = _decode(data)
    assert isinstance(packet, CommandPacket)
    assert (packet.answered_seq, packet.faults, packet.state) == (41, 8, ControllerState.FAULTED)
    np.testing.assert_array_equal(packet.controls, np.float32([0.25, -1.0, 0.5]))
    rearm = encode_rearm(LAYOUT_ID, 3, 5)
    assert len(rearm) == REARM_SIZE == 28
    assert _decode(rearm) == RearmPacket(3, 5)


def test_layout_id_depends_on_names_units_and_ranges():
    renamed = SensorLayout((SensorChannel("other", "MPa", -1.0, 40.0), *LAYOUT.channels[1:]))
    new_unit = SensorLayout((SensorChannel("sensor_0", "bar", -1.0, 40.0), *LAYOUT.channels[1:]))
    assert len({LAYOUT_ID, renamed.layout_id, new_unit.layout_id}) == 3
    assert SensorLayout.from_json(LAYOUT.to_json()).layout_id == LAYOUT_ID


def _reseal(data: bytearray) -> bytes:
    import zlib

    data[-4:] = zlib.crc32(bytes(data[:-4])).to_bytes(4, "little")
    return bytes(data)


@pytest.mark.parametrize(
    ("mangle", "reason"),
    [
        (lambda d: d[:-1], "crc"),  # a cut datagram fails its checksum
        (lambda d: d[:10], "size"),
        (lambda d: b"XXXX" + d[4:], "magic"),
        (lambda d: _reseal(bytearray(d[:4] + bytes([PACKET_VERSION + 1]) + d[5:])), "version"),
        (lambda d: d[:-5] + bytes([d[-5] ^ 0xFF]) + d[-4:], "crc"),
        (lambda d: _reseal(bytearray(d[:5] + bytes([9]) + d[6:])), "kind"),
        (lambda d: _reseal(bytearray(d[:-4] + b"\0\0\0\0" + d[-4:])), "size"),
    ],
)
def test_malformed_packets_name_their_reason(mangle, reason):
    good = encode_sensors(LAYOUT_ID, 1, 2, np.zeros(N))
    with pytest.raises(PacketError) as caught:
        _decode(mangle(good))
    assert caught.value.reason == reason


def test_a_packet_for_another_layout_is_refused():
    other = SensorLayout(LAYOUT.channels[:3])
    data = encode_sensors(other.layout_id, 1, 2, np.zeros(3))
    with pytest.raises(PacketError, match="layout"):
        _decode(data)


@settings(max_examples=400, deadline=None)
@given(st.binary(max_size=200))
def test_decoder_never_raises_anything_but_packet_error(data):
    try:
        packet = _decode(data)
    except PacketError as error:
        assert error.reason
    else:  # only a checksummed datagram of our layout gets through
        assert isinstance(packet, SensorPacket | CommandPacket | RearmPacket)


@settings(max_examples=300, deadline=None)
@given(
    st.lists(st.floats(width=32, allow_nan=True, allow_infinity=True), min_size=N, max_size=N),
    st.integers(0, 2**32 - 1),
    st.integers(-(2**63), 2**63 - 1),
    st.sets(st.integers(0, 55), max_size=6),
)
def test_any_bit_flip_of_a_valid_packet_is_caught(values, seq, stamp, flipped):
    data = bytearray(encode_sensors(LAYOUT_ID, seq, stamp, values))
    for index in flipped:
        data[index] ^= 0x5A
    try:
        packet = _decode(bytes(data))
    except PacketError:
        assert flipped  # a changed packet is refused...
    else:
        assert not flipped  # ...and an unchanged one decodes to what was sent
        assert packet.seq == seq and packet.stamp_ns == stamp
        np.testing.assert_array_equal(packet.values, np.float32(values))
