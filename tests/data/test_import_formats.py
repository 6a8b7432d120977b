"""Issue #17 (2): message logs (MCAP, ROS 1 / ROS 2 bags, CAN with a DBC, MDF 4) behind
the same mapping and checks; the files are generated here with the same libraries."""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest
from import_logs_helpers import MACHINE_RANGES, UNITS

from pilerl.data.importers import (
    LogImportError,
    create_store,
    import_logs,
    load_mapping,
    quality_report,
    read_all,
)

RATE_HZ = 50.0
SENSOR_RATE_HZ = 100.0  # messages of the sensors; controls come at 20 Hz
CONTROL_RATE_HZ = 20.0
DURATION_S = 2.0
SIGNALS = {  # pilerl name -> (value function of time [s], in pilerl units)
    "boom_angle": lambda t: -0.6 + 0.5 * t,
    "bucket_angle": lambda t: 0.2 * np.sin(t),
    "drive_pressure": lambda t: 10.0 + 5.0 * t,
    "telescope_pressure": lambda t: 8.0 + t,
    "boom_pressure": lambda t: 12.0 + 2.0 * t,
    "bucket_pressure": lambda t: 9.0 + 0.5 * t,
    "pump_angle": lambda t: 0.1 * np.cos(t),
    "boom": lambda t: np.where(t > 1.0, 0.8, 0.0),
    "bucket": lambda t: np.where(t < 1.0, 0.5, 0.0),
    "throttle": lambda t: np.full_like(t, 0.6),
}
CONTROLS = ("boom", "bucket", "throttle")
T0 = 1_700_000_000.0  # message times are POSIX seconds


def message_times(name: str) -> np.ndarray:
    rate = CONTROL_RATE_HZ if name in CONTROLS else SENSOR_RATE_HZ
    return np.arange(int(DURATION_S * rate) + 1) / rate


def expected_on_grid(name: str, n: int) -> np.ndarray:
    """Sample-and-hold of the messages onto the 50 Hz grid starting at t = 0."""
    times = message_times(name)
    grid = np.arange(n) / RATE_HZ
    held = np.searchsorted(times, grid + 1e-9, side="right") - 1
    return SIGNALS[name](times[held])


def stream_mapping(column_of, units: dict[str, str] | None = None) -> dict:
    units = units or {}
    return {
        "sensors": {
            name: {
                "column": column_of(name),
                "unit": UNITS[name],
                "range": MACHINE_RANGES[name],
                **({"source_unit": units[name]} if name in units else {}),
            }
            for name in SIGNALS
            if name not in CONTROLS
        },
        "controls": {name: {"column": column_of(name)} for name in CONTROLS},
        "time": {"rate_hz": RATE_HZ},
        "metadata": {"condition": "site-b", "success": True},
    }


def assert_imported(path: Path, mapping: dict, tmp_path: Path, atol: float = 1e-6) -> None:
    mapping = load_mapping(mapping)
    store = create_store(tmp_path / "ds", mapping)
    (meta,) = import_logs(path, mapping, store)
    episode = store.load(0)
    n = int(DURATION_S * RATE_HZ) + 1
    assert meta.n_samples == n and meta.rate_hz == RATE_HZ
    np.testing.assert_allclose(episode["time_s"].numpy(), np.arange(n) / RATE_HZ, atol=1e-6)
    for name in SIGNALS:
        if name in CONTROLS:
            got = episode["action"].numpy()[:, CONTROLS.index(name)]
        else:
            got = episode[name].numpy()[:, 0]
        np.testing.assert_allclose(got, expected_on_grid(name, n), atol=atol, err_msg=name)
    assert store.stats is not None


# ------------------------------------------------------------------ MCAP (JSON messages)
def write_mcap(path: Path, silent: tuple[str, float, float] | None = None) -> Path:
    """MCAP with JSON messages; ``silent = (name, from_s, to_s)`` drops that signal's
    messages in the interval (a dropout)."""
    from mcap.writer import Writer

    with path.open("wb") as stream:
        writer = Writer(stream)
        writer.start()
        schema = writer.register_schema(
            name="Scalar",
            encoding="jsonschema",
            data=json.dumps(
                {"type": "object", "properties": {"value": {"type": "number"}}}
            ).encode(),
        )
        events = []
        for name in SIGNALS:
            channel = writer.register_channel(
                topic=f"/machine/{name}", message_encoding="json", schema_id=schema
            )
            for t in message_times(name):
                if silent and name == silent[0] and silent[1] < t < silent[2]:
                    continue
                value = float(SIGNALS[name](np.array(t)))
                events.append((t, channel, {"value": value, "status": {"ok": True}}))
        for t, channel, message in sorted(events, key=lambda e: e[0]):
            ns = int(round((T0 + t) * 1e9))
            writer.add_message(
                channel, log_time=ns, data=json.dumps(message).encode(), publish_time=ns
            )
        writer.finish()
    return path


def test_mcap_json_log_imports(tmp_path):
    path = write_mcap(tmp_path / "log.mcap")
    assert_imported(path, stream_mapping(lambda n: f"/machine/{n}.value"), tmp_path)


def test_a_signal_dropout_in_a_message_log_is_reported(tmp_path):
    path = write_mcap(tmp_path / "log.mcap", silent=("pump_angle", 0.5, 1.0))
    episodes = read_all(path, load_mapping(stream_mapping(lambda n: f"/machine/{n}.value")))
    assert episodes[0].signal_gaps["/machine/pump_angle.value"] == pytest.approx(0.5)
    report = quality_report(episodes, plots=False)
    assert report.warnings == [
        "episode_000000: no '/machine/pump_angle.value' message for 500 ms (held in between)"
    ]
    assert any("sampled at 50 Hz by holding the last message" in n for n in episodes[0].notes)


# ------------------------------------------------------------------ ROS 1 and ROS 2 bags
def write_bag(path: Path, version: int, storage: str = "sqlite3") -> Path:
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC if version == 1 else Stores.ROS2_HUMBLE)
    point = store.types["geometry_msgs/msg/PointStamped"]
    header = store.types["std_msgs/msg/Header"]
    stamp = store.types["builtin_interfaces/msg/Time"]
    if version == 1:
        from rosbags.rosbag1 import Writer

        writer = Writer(path)
    else:
        from rosbags.rosbag2 import StoragePlugin, Writer

        plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
        writer = Writer(path, version=9, storage_plugin=plugin)
    with writer:
        connections = {
            name: writer.add_connection(f"/{name}", point.__msgtype__, typestore=store)
            for name in SIGNALS
        }
        events = sorted((t, name) for name in SIGNALS for t in message_times(name))
        for t, name in events:
            sec = int(T0 + t)
            nanosec = int(round((T0 + t - sec) * 1e9))
            head = (
                header(seq=0, stamp=stamp(sec=sec, nanosec=nanosec), frame_id="base")
                if version == 1
                else header(stamp=stamp(sec=sec, nanosec=nanosec), frame_id="base")
            )
            value = float(SIGNALS[name](np.array(t)))
            message = point(
                header=head, point=store.types["geometry_msgs/msg/Point"](x=value, y=0.0, z=0.0)
            )
            data = (
                store.serialize_ros1(message, point.__msgtype__)
                if version == 1
                else store.serialize_cdr(message, point.__msgtype__)
            )
            # log time 5 ms after the stamp: the header stamp is what counts
            writer.write(connections[name], int(round((T0 + t + 0.005) * 1e9)), data)
    return path


@pytest.mark.parametrize("version", [1, 2])
def test_ros_bag_imports_at_header_stamps(tmp_path, version):
    path = write_bag(tmp_path / ("log.bag" if version == 1 else "bag"), version)
    assert_imported(path, stream_mapping(lambda n: f"/{n}.point.x"), tmp_path)


def test_ros2_bag_in_mcap_storage_imports_as_folder_and_as_file(tmp_path):
    folder = write_bag(tmp_path / "bag", 2, storage="mcap")
    mapping = stream_mapping(lambda n: f"/{n}.point.x")
    assert_imported(folder, mapping, tmp_path / "a")
    (file,) = folder.glob("*.mcap")
    assert_imported(file, mapping, tmp_path / "b")


# ------------------------------------------------------------------ CAN + DBC
DBC = """VERSION ""

NS_ :

BS_:

BU_: ECU

BO_ 256 Joints: 8 ECU
 SG_ BoomAngle : 0|16@1- (0.01,0) [-180|180] "deg" ECU
 SG_ BucketAngle : 16|16@1- (0.01,0) [-180|180] "deg" ECU
 SG_ PumpAngle : 32|16@1- (0.1,0) [-1000|1000] "mrad" ECU

BO_ 257 Pressures: 8 ECU
 SG_ DrivePressure : 0|16@1+ (0.01,0) [0|600] "bar" ECU
 SG_ TelescopePressure : 16|16@1+ (0.01,0) [0|600] "bar" ECU
 SG_ BoomPressure : 32|16@1+ (0.01,0) [0|600] "bar" ECU
 SG_ BucketPressure : 48|16@1+ (0.01,0) [0|600] "bar" ECU

BO_ 258 Operator: 8 ECU
 SG_ JoyBoom : 0|8@1- (1,0) [-100|100] "%" ECU
 SG_ JoyBucket : 8|8@1- (1,0) [-100|100] "%" ECU
 SG_ Pedal : 16|8@1+ (1,0) [0|100] "%" ECU
"""
CAN_SIGNALS = {
    "boom_angle": ("Joints", "BoomAngle", 180 / math.pi),
    "bucket_angle": ("Joints", "BucketAngle", 180 / math.pi),
    "pump_angle": ("Joints", "PumpAngle", 1000.0),
    "drive_pressure": ("Pressures", "DrivePressure", 10.0),
    "telescope_pressure": ("Pressures", "TelescopePressure", 10.0),
    "boom_pressure": ("Pressures", "BoomPressure", 10.0),
    "bucket_pressure": ("Pressures", "BucketPressure", 10.0),
    "boom": ("Operator", "JoyBoom", 100.0),
    "bucket": ("Operator", "JoyBucket", 100.0),
    "throttle": ("Operator", "Pedal", 100.0),
}
CAN_WRITERS = {".blf": "BLFWriter", ".asc": "ASCWriter", ".log": "CanutilsLogWriter"}


def write_can(path: Path, dbc: Path) -> Path:
    import can
    import cantools

    database = cantools.database.load_string(DBC)
    dbc.write_text(DBC)
    frames = []
    for message in database.messages:
        members = [n for n, (m, _, _) in CAN_SIGNALS.items() if m == message.name]
        rate = CONTROL_RATE_HZ if members[0] in CONTROLS else SENSOR_RATE_HZ
        for t in np.arange(int(DURATION_S * rate) + 1) / rate:
            data = {
                CAN_SIGNALS[n][1]: float(SIGNALS[n](np.array(t))) * CAN_SIGNALS[n][2]
                for n in members
            }
            frames.append((t, message.frame_id, message.encode(data)))
    frames.append((0.5, 0x7FF, bytes(8)))  # a frame the DBC does not know
    writer = getattr(can, CAN_WRITERS[path.suffix])(str(path))
    for t, frame_id, data in sorted(frames):
        writer.on_message_received(
            can.Message(timestamp=T0 + t, arbitration_id=frame_id, data=data, is_extended_id=False)
        )
    writer.stop()
    return path


@pytest.mark.parametrize("suffix", list(CAN_WRITERS))
def test_can_log_decoded_with_dbc_imports(tmp_path, suffix):
    dbc = tmp_path / "machine.dbc"
    path = write_can(tmp_path / f"log{suffix}", dbc)
    mapping = stream_mapping(lambda n: CAN_SIGNALS[n][1] if n != "boom" else "Operator.JoyBoom")
    mapping["can"] = {"dbc": str(dbc)}
    # DBC resolution (0.01 deg, 0.01 bar, 0.1 mrad, 1 %) bounds the error
    assert_imported(path, mapping, tmp_path, atol=2e-3)
    (episode,) = read_all(path, load_mapping(mapping))
    assert any("0x7ff (1)" in note for note in episode.notes)


def test_can_log_without_dbc_is_refused(tmp_path):
    path = write_can(tmp_path / "log.blf", tmp_path / "machine.dbc")
    mapping = stream_mapping(lambda n: CAN_SIGNALS[n][1])
    with pytest.raises(LogImportError, match="needs a DBC file: set can.dbc"):
        read_all(path, load_mapping(mapping))


# ------------------------------------------------------------------ MDF 4
def write_mdf(path: Path) -> Path:
    from asammdf import MDF, Signal

    mdf = MDF(version="4.10")
    for group in (("boom_angle", "bucket_angle", "pump_angle"), CONTROLS):
        times = message_times(group[0])
        mdf.append(
            [
                Signal(
                    samples=SIGNALS[n](times)
                    * (180 / math.pi if "angle" in n and n != "pump_angle" else 1.0),
                    timestamps=times,
                    name=f"MDF_{n}",
                    unit="deg"
                    if "angle" in n and n != "pump_angle"
                    else ("rad" if n == "pump_angle" else ""),
                )
                for n in group
            ]
        )
    times = message_times("drive_pressure")
    mdf.append(
        [
            Signal(samples=SIGNALS[n](times) * 10.0, timestamps=times, name=f"MDF_{n}", unit="bar")
            for n in ("drive_pressure", "telescope_pressure", "boom_pressure", "bucket_pressure")
        ]
    )
    mdf.save(path, overwrite=True)
    mdf.close()
    return path


def test_mdf4_measurement_imports_with_its_units(tmp_path):
    path = write_mdf(tmp_path / "log.mf4")
    assert_imported(path, stream_mapping(lambda n: f"MDF_{n}"), tmp_path, atol=1e-5)


# ------------------------------------------------------------------ shared checks
def test_message_logs_need_a_grid_rate(tmp_path):
    path = write_mcap(tmp_path / "log.mcap")
    mapping = stream_mapping(lambda n: f"/machine/{n}.value")
    mapping["time"] = {"column": "t", "rate_hz": RATE_HZ}
    with pytest.raises(LogImportError, match="leave time.column out of the mapping"):
        read_all(path, load_mapping(mapping))


def test_message_log_signal_missing_is_named(tmp_path):
    path = write_mcap(tmp_path / "log.mcap")
    mapping = stream_mapping(lambda n: f"/machine/{n}.value")
    mapping["sensors"]["pump_angle"]["column"] = "/machine/pump.value"
    with pytest.raises(LogImportError, match=r"column '/machine/pump.value': missing column"):
        read_all(path, load_mapping(mapping))


def test_message_log_out_of_range_reading_is_named(tmp_path):
    path = write_mcap(tmp_path / "log.mcap")
    mapping = stream_mapping(lambda n: f"/machine/{n}.value")
    mapping["sensors"]["boom_angle"]["range"] = [-0.5, 1.0]
    with pytest.raises(
        LogImportError, match=r"column '/machine/boom_angle.value', row 1 .*outside"
    ):
        read_all(path, load_mapping(mapping))


@pytest.mark.parametrize(
    ("suffix", "package"),
    [(".mcap", "mcap"), (".bag", "rosbags"), (".blf", "python-can"), (".mf4", "asammdf")],
)
def test_missing_optional_reader_says_what_to_install(tmp_path, monkeypatch, suffix, package):
    module = {"python-can": "can"}.get(package, package)
    monkeypatch.setitem(sys.modules, module, None)  # import fails as if not installed
    path = tmp_path / f"log{suffix}"
    path.write_bytes(b"not empty")
    mapping = stream_mapping(lambda n: n)
    mapping["can"] = {"dbc": str(tmp_path / "x.dbc")}
    with pytest.raises(
        LogImportError,
        match=rf"needs the optional package '{package}': pip install 'pilerl\[logs\]'",
    ):
        read_all(path, load_mapping(mapping))


@pytest.mark.parametrize("suffix", [".mcap", ".bag", ".blf", ".asc", ".mf4"])
def test_corrupt_message_logs_are_reported(tmp_path, suffix):
    path = tmp_path / f"log{suffix}"
    path.write_bytes(np.random.default_rng(0).bytes(3000))
    mapping = stream_mapping(lambda n: n)
    dbc = tmp_path / "machine.dbc"
    dbc.write_text(DBC)
    mapping["can"] = {"dbc": str(dbc)}
    with pytest.raises(LogImportError) as error:
        read_all(path, load_mapping(mapping))
    assert str(path) in str(error.value)
    assert "unreadable" in str(error.value) or "empty file" in str(error.value)
