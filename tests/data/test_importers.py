"""Machine-log import (CSV / Parquet / HDF5) and dataset export: round trips and rejections."""

from __future__ import annotations

import math
import tempfile
from pathlib import Path

import h5py
import numpy as np
import pandas as pd
import pytest
import torch
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from pilerl_pile_loader.sensors import CONTROL_NAMES, SENSORS

from pilerl.data.export import (
    export_episodes,
    import_export,
    mapping_for_export,
    read_sidecar,
    sidecar_path,
)
from pilerl.data.importers import (
    ControlSpec,
    LogImportError,
    LogMapping,
    MappingError,
    MetadataSpec,
    SensorSpec,
    TimeSpec,
    create_store,
    import_logs,
    import_to_dataset,
    load_mapping,
    mapping_from_dict,
    quality_dir,
    save_mapping,
)
from pilerl.data.schema import EpisodeMeta, SchemaError, make_episode
from pilerl.data.store import EpisodeStore

FORMATS = ("csv", "parquet", "h5")
HDF5_GROUP = "log"
PROPERTY_SETTINGS = settings(
    max_examples=30,
    derandomize=True,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow],
)

# Raw log units -> pilerl units: angles in degrees (boom angle with a zero offset),
# pressures in bar, pump angle in mrad; controls in percent, throttle as 0..1000 counts.
SENSOR_SCALES = {
    "boom_angle": (math.pi / 180, -0.05),
    "bucket_angle": (math.pi / 180, 0.0),
    "drive_pressure": (0.1, 0.0),
    "telescope_pressure": (0.1, 0.0),
    "boom_pressure": (0.1, 0.0),
    "bucket_pressure": (0.1, 0.0),
    "pump_angle": (0.001, 0.0),
}
CONTROL_SCALES = {"boom": (0.01, 0.0), "bucket": (0.01, 0.0), "throttle": (0.002, -1.0)}


def log_mapping(**overrides) -> LogMapping:
    """The mapping of the synthetic machine logs below (time in ms, episode column "run")."""
    fields = {
        "sensors": {
            s.name: SensorSpec(
                column=f"{s.name}_raw",
                unit=s.unit,
                range=[s.low, s.high],
                scale=SENSOR_SCALES[s.name][0],
                offset=SENSOR_SCALES[s.name][1],
            )
            for s in SENSORS
        },
        "controls": {
            c: ControlSpec(
                column=f"u_{c}_raw", scale=CONTROL_SCALES[c][0], offset=CONTROL_SCALES[c][1]
            )
            for c in CONTROL_NAMES
        },
        "time": TimeSpec(column="t_ms", scale=0.001),
        "episode_column": "run",
        "hdf5_group": HDF5_GROUP,
        "metadata": MetadataSpec(condition="site-a", operator_id="op7"),
    }
    return LogMapping(**{**fields, **overrides})


def sensor_column(name: str) -> str:
    return f"{name}_raw"


def control_column(name: str) -> str:
    return f"u_{name}_raw"


def check_order(mapping: LogMapping) -> list[str]:
    """Columns in the order the importer checks them (store order = mapping order here)."""
    return [
        mapping.time.column,
        *(s.column for s in mapping.sensors.values()),
        *(c.column for c in mapping.controls.values()),
    ]


def log_table(rng: np.random.Generator, lengths: list[int]) -> pd.DataFrame:
    """A well-formed raw log: one run per length, time in ms restarting at a random origin."""
    n = sum(lengths)
    data: dict[str, np.ndarray] = {"run": np.repeat(np.arange(1, len(lengths) + 1), lengths)}
    data["t_ms"] = np.concatenate(
        [rng.uniform(0, 1e6) + np.cumsum(rng.uniform(10.0, 100.0, size=k)) for k in lengths]
    )
    for s in SENSORS:
        scale, offset = SENSOR_SCALES[s.name]
        span = s.high - s.low
        value = rng.uniform(s.low + 0.01 * span, s.high - 0.01 * span, size=n)
        data[sensor_column(s.name)] = (value - offset) / scale
    for c in CONTROL_NAMES:
        scale, offset = CONTROL_SCALES[c]
        data[control_column(c)] = (rng.uniform(-0.99, 0.99, size=n) - offset) / scale
    return pd.DataFrame(data)


def write_log(table: pd.DataFrame, path: Path) -> Path:
    """Write ``table`` as CSV, Parquet or HDF5 (one dataset per column in ``HDF5_GROUP``)."""
    if path.suffix == ".csv":
        table.to_csv(path, index=False)
    elif path.suffix == ".parquet":
        table.to_parquet(path, index=False)
    else:
        with h5py.File(path, "w") as h5:
            group = h5.create_group(HDF5_GROUP)
            for column in table.columns:
                values = table[column].to_numpy()
                if values.dtype == object:  # text: variable-length UTF-8 strings
                    group.create_dataset(
                        column, data=[str(v) for v in values], dtype=h5py.string_dtype()
                    )
                else:
                    group.create_dataset(column, data=values)
    return path


def expected_values(table: pd.DataFrame, mapping: LogMapping) -> dict[str, np.ndarray]:
    out = {}
    for name, spec in mapping.sensors.items():
        out[name] = (table[spec.column].to_numpy() * spec.scale + spec.offset).astype(np.float32)
    return out


def expected_actions(table: pd.DataFrame, mapping: LogMapping) -> np.ndarray:
    cols = [table[c.column].to_numpy() * c.scale + c.offset for c in mapping.controls.values()]
    return np.stack(cols, axis=-1).astype(np.float32)


def store_state(store: EpisodeStore) -> tuple[int, bytes, list[str]]:
    root = store.root
    return (
        len(EpisodeStore.open(root)),
        (root / "index.json").read_bytes(),
        sorted(p.name for p in (root / "episodes").iterdir()),
    )


def assert_names(
    error: pytest.ExceptionInfo, path: Path, column: str | None, row: int | None
) -> None:
    """The message names the file, the column and the 1-based data row."""
    message = str(error.value)
    assert isinstance(error.value, SchemaError)
    assert str(path) in message
    if column is not None:
        assert f"column {column!r}" in message
        assert error.value.column == column
    if row is not None:
        assert f"row {row} (1-based data row)" in message
    assert error.value.row == row


@pytest.fixture
def mapping() -> LogMapping:
    return log_mapping()


@pytest.fixture
def table() -> pd.DataFrame:
    return log_table(np.random.default_rng(0), [6, 4, 5])


# ------------------------------------------------------------------ well-formed logs
@pytest.mark.parametrize("fmt", FORMATS)
def test_log_imports_as_episodes(tmp_path, mapping, table, fmt):
    path = write_log(table, tmp_path / f"log.{fmt}")
    store = create_store(tmp_path / "ds", mapping)
    metas = import_logs([path], mapping, store)

    assert [m.n_samples for m in metas] == [6, 4, 5]
    assert len(store) == 3
    sensors, actions = expected_values(table, mapping), expected_actions(table, mapping)
    start = 0
    for i, meta in enumerate(metas):
        td, n = store.load(i), meta.n_samples
        rows = slice(start, start + n)
        for name in mapping.sensors:
            np.testing.assert_array_equal(td[name].numpy()[:, 0], sensors[name][rows])
            nxt = td["next", name].numpy()[:, 0]
            np.testing.assert_array_equal(nxt[:-1], sensors[name][rows][1:])
            assert nxt[-1] == sensors[name][rows][-1]  # last row: its own reading
        np.testing.assert_allclose(td["action"].numpy(), actions[rows], atol=1e-6)
        t_ms = table["t_ms"].to_numpy()[rows]
        np.testing.assert_allclose(td["time_s"].numpy(), (t_ms - t_ms[0]) * 1e-3, atol=1e-9)
        assert td["next", "done"][:, 0].tolist() == [False] * (n - 1) + [True]
        assert td["next", "terminated"][-1].item() and not td["next", "truncated"].any()
        assert torch.isnan(td["next", "reward"]).all()
        assert td["episode"].unique().tolist() == [i]
        assert meta.source == f"import:{path}#episode={i + 1}"
        assert meta.condition == "site-a" and meta.operator == {"id": "op7", "kind": "human"}
        assert 10.0 <= meta.rate_hz <= 100.0
        start += n


def test_import_to_dataset_creates_then_appends_and_numbers_the_reports(tmp_path, table):
    path = write_log(table, tmp_path / "log.csv")
    store, episodes, metas = import_to_dataset([path], log_mapping(), tmp_path / "ds")
    assert len(store) == len(episodes) == len(metas) == 3
    assert quality_dir(tmp_path / "ds") == tmp_path / "ds" / "quality" / "import_000"
    store, _, metas = import_to_dataset([path], log_mapping(), tmp_path / "ds")
    assert len(EpisodeStore.open(tmp_path / "ds")) == 6 and [m.id for m in metas] == [3, 4, 5]
    assert quality_dir(tmp_path / "ds") == tmp_path / "ds" / "quality" / "import_001"
    (tmp_path / "junk").mkdir()
    (tmp_path / "junk" / "notes.txt").write_text("not a dataset")
    with pytest.raises(SchemaError, match="junk: not a usable pilerl dataset"):
        import_to_dataset([path], log_mapping(), tmp_path / "junk")


def test_hdf5_column_datasets_may_be_n_by_1(tmp_path, mapping, table):
    path = tmp_path / "log.h5"
    with h5py.File(path, "w") as h5:
        group = h5.create_group(HDF5_GROUP)
        for column in table.columns:
            group.create_dataset(column, data=table[column].to_numpy()[:, None])
    store = create_store(tmp_path / "ds", mapping)
    assert [m.n_samples for m in import_logs(path, mapping, store)] == [6, 4, 5]


def test_one_file_is_one_episode_without_episode_column(tmp_path, table):
    mapping = log_mapping(episode_column=None, time=TimeSpec(rate_hz=20.0))
    paths = [
        write_log(table.iloc[:7], tmp_path / "a.csv"),
        write_log(table.iloc[7:], tmp_path / "b.parquet"),
    ]
    store = create_store(tmp_path / "ds", mapping)
    metas = import_logs(paths, mapping, store)
    assert [m.n_samples for m in metas] == [7, 8]
    assert [m.source for m in metas] == [f"import:{p}" for p in paths]
    assert metas[0].rate_hz == 20.0
    np.testing.assert_allclose(store.load(1)["time_s"].numpy(), np.arange(8) / 20.0)


def test_metadata_columns_take_the_last_row(tmp_path, table):
    table = table.assign(fill=np.nan, ok="")
    table.loc[5, "fill"], table.loc[5, "ok"] = 0.62, "yes"  # run 1 ends at row index 5
    table.loc[9, "ok"] = "0"  # run 2
    mapping = log_mapping(metadata=MetadataSpec(fill_fraction_column="fill", success_column="ok"))
    store = create_store(tmp_path / "ds", mapping)
    metas = import_logs(write_log(table, tmp_path / "log.csv"), mapping, store)
    assert metas[0].fill_fraction == pytest.approx(0.62) and metas[0].success is True
    assert math.isnan(metas[1].fill_fraction) and metas[1].success is False
    assert math.isnan(metas[2].fill_fraction) and metas[2].success is None


# ------------------------------------------------------------------ export round trips
def sim_like_store(root: Path, rng: np.random.Generator) -> EpisodeStore:
    """A dataset as the recorder writes it: time from dt, real next readings, rewards."""
    store = EpisodeStore.create(
        root, sensors={s.name: s.unit for s in SENSORS}, controls=list(CONTROL_NAMES)
    )
    for k, n in enumerate([5, 3, 7]):
        sensors = {
            s.name: torch.tensor(rng.uniform(s.low, s.high, n + 1), dtype=torch.float32)
            for s in SENSORS
        }
        store.append(
            make_episode(
                sensors={k_: v[:-1] for k_, v in sensors.items()},
                next_sensors={k_: v[1:] for k_, v in sensors.items()},
                actions=torch.tensor(rng.uniform(-1, 1, (n, 3)), dtype=torch.float32),
                time_s=torch.arange(1, n + 1, dtype=torch.float64) * 0.05,
                rewards=torch.tensor(rng.normal(size=n)),
                truncated=True,
            ),
            meta_for(k),
        )
    return store


def meta_for(k: int) -> EpisodeMeta:
    return EpisodeMeta(
        rate_hz=20.0,
        source="sim",
        condition=["summer", "winter_c"][k % 2],
        seed=k,
        fill_fraction=0.1 * k,
        success=k == 2,
    )


def assert_same_samples(a: EpisodeStore, b: EpisodeStore, ids_a: list[int]) -> None:
    assert len(b) == len(ids_a)
    for j, i in enumerate(ids_a):
        ta, tb = a.load(i), b.load(j)
        assert ta.batch_size == tb.batch_size
        for key in [*a.sensors, "action", "time_s", "step"]:
            torch.testing.assert_close(tb[key], ta[key], rtol=0, atol=1e-6)


@pytest.mark.parametrize("suffix", [".csv", ".parquet"])
def test_export_then_import_gives_the_same_episodes(tmp_path, suffix):
    original = sim_like_store(tmp_path / "ds", np.random.default_rng(1))
    path = export_episodes(original, tmp_path / f"demos{suffix}")
    copy = EpisodeStore.create(
        tmp_path / "copy", sensors=original.sensors, controls=original.controls
    )
    metas = import_logs(path, mapping_for_export(original), copy)
    assert [m.n_samples for m in metas] == [5, 3, 7]
    assert_same_samples(original, copy, [0, 1, 2])


@pytest.mark.parametrize("suffix", [".csv", ".parquet"])
def test_chosen_episodes_export_and_restore_metadata(tmp_path, suffix):
    original = sim_like_store(tmp_path / "ds", np.random.default_rng(2))
    path = export_episodes(original, tmp_path / f"out{suffix}", episode_ids=[2, 0])
    frame = pd.read_csv(path) if suffix == ".csv" else pd.read_parquet(path)
    sensor_names = [s.name for s in SENSORS]
    assert list(frame.columns) == [
        "episode",
        "step",
        "time_s",
        *sensor_names,
        "u_boom",
        "u_bucket",
        "u_throttle",
        "reward",
        "done",
    ]
    assert frame["episode"].tolist() == [2] * 7 + [0] * 5
    assert frame["done"].sum() == 2
    np.testing.assert_allclose(
        frame["reward"],
        np.concatenate([original.load(i)["next", "reward"].numpy()[:, 0] for i in (2, 0)]),
        rtol=1e-6,
    )
    sidecar = read_sidecar(path)
    assert sidecar_path(path).name == f"out{suffix}.meta.json"
    assert [e["id"] for e in sidecar["episodes"]] == [2, 0]
    assert sidecar["sensors"] == original.sensors and sidecar["controls"] == original.controls

    copy = EpisodeStore.create(
        tmp_path / "copy", sensors=original.sensors, controls=original.controls
    )
    metas = import_export(path, copy)
    assert_same_samples(original, copy, [2, 0])
    assert [(m.condition, m.seed, m.source, m.success) for m in metas] == [
        ("summer", 2, "sim", True),
        ("summer", 0, "sim", False),
    ]
    assert metas[0].fill_fraction == pytest.approx(0.2)


# ------------------------------------------------------------------ mapping loader
MAPPING_YAML = """
sensors:
  boom_angle: {column: th1_deg, unit: rad, range: [-0.55, 1.05], scale: 0.0174533}
  drive_pressure: {column: p_drive_bar, unit: MPa, range: [0, 40], scale: 0.1}
controls:
  boom: {column: u_boom_pct, scale: 0.01}
time: {column: t_ms, scale: 0.001}
episode_column: run
metadata: {condition: gravel-dry, operator_id: 12, success_column: ok}
"""


def test_mapping_loads_from_yaml_and_saves_back(tmp_path):
    path = tmp_path / "mapping.yaml"
    path.write_text(MAPPING_YAML)
    mapping = load_mapping(path)
    assert mapping.sensors["drive_pressure"] == SensorSpec("p_drive_bar", "MPa", [0.0, 40.0], 0.1)
    assert mapping.time == TimeSpec(column="t_ms", scale=0.001)
    assert mapping.metadata.operator_id == "12" and mapping.metadata.success_column == "ok"
    assert load_mapping(save_mapping(mapping, tmp_path / "again.yaml")) == mapping
    assert load_mapping(save_mapping(log_mapping(), tmp_path / "std.yaml")) == log_mapping()


@pytest.mark.parametrize(
    ("change", "expected"),
    [
        (
            lambda d: d["sensors"]["boom_angle"].update(colum="x"),
            r"mapping\.sensors\.boom_angle: unknown field\(s\) \['colum'\]",
        ),
        (
            lambda d: d["sensors"]["boom_angle"].pop("range"),
            r"mapping\.sensors\.boom_angle: missing required field\(s\) \['range'\]",
        ),
        (lambda d: d.pop("controls"), r"mapping: missing required field\(s\) \['controls'\]"),
        (lambda d: d.update(extra=1), r"mapping: unknown field\(s\) \['extra'\]"),
        (lambda d: d["time"].update(scale="ms"), r"mapping\.time\.scale: expected float"),
        (
            lambda d: d["sensors"]["boom_angle"].update(range=[1, 0]),
            r"mapping\.sensors\.boom_angle\.range: expected \[low, high\]",
        ),
        (lambda d: d["controls"]["boom"].update(scale=0), r"mapping\.controls\.boom\.scale"),
        (lambda d: d.update(time={"scale": 1.0}), r"mapping\.time: give a time column or rate_hz"),
        (
            lambda d: d["metadata"].update(success=True),
            r"mapping\.metadata: give success or success_column",
        ),
    ],
)
def test_mapping_errors_name_the_field(change, expected):
    import yaml

    data = yaml.safe_load(MAPPING_YAML)
    change(data)
    with pytest.raises(MappingError, match=expected):
        mapping_from_dict(data)


@pytest.mark.parametrize(
    ("change", "expected"),
    [
        (
            lambda d: d["sensors"]["boom_angle"].update(range="wide"),
            r"mapping\.sensors\.boom_angle\.range: expected list\[float\], got 'wide'",
        ),
        (
            lambda d: d["time"].update(rate_hz="fast"),
            r"mapping\.time\.rate_hz: expected float or null, got 'fast'",
        ),
        (lambda d: d.update(sensors=None), r"mapping\.sensors: field 'sensors' is not Optional"),
    ],
)
def test_mapping_type_errors_name_the_field_and_the_type(change, expected):
    import yaml

    data = yaml.safe_load(MAPPING_YAML)
    change(data)
    with pytest.raises(MappingError, match=expected):
        mapping_from_dict(data)


def test_mapping_file_errors_name_the_file_and_the_field(tmp_path):
    path = tmp_path / "mapping.yaml"
    path.write_text(MAPPING_YAML.replace("scale: 0.01}", "scale: 0.01, gain: 2}"))
    with pytest.raises(MappingError) as error:
        load_mapping(path)
    assert str(error.value).startswith(f"{path}.controls.boom: unknown field(s) ['gain']")


def test_mapping_text_is_taken_as_written_not_as_an_interpolation():
    import yaml

    data = yaml.safe_load(MAPPING_YAML)
    data["sensors"]["boom_angle"]["column"] = "th1${deg}"
    data["metadata"]["operator_id"] = "a\\${b}"
    mapping = mapping_from_dict(data)
    assert mapping.sensors["boom_angle"].column == "th1${deg}"
    assert mapping.metadata.operator_id == "a\\${b}"


def test_a_loaded_mapping_is_the_callers_own():
    import yaml

    data = yaml.safe_load(MAPPING_YAML)
    first = mapping_from_dict(data)
    first.sensors["boom_angle"].unit = "deg"
    first.controls["boom"].aliases.append("u_boom")
    again = mapping_from_dict(data)
    assert again.sensors["boom_angle"].unit == "rad" and again.controls["boom"].aliases == []


def test_mapping_must_fit_the_store(tmp_path, mapping):
    store = create_store(tmp_path / "ds", mapping)
    wrong_unit = log_mapping()
    wrong_unit.sensors["drive_pressure"].unit = "bar"
    with pytest.raises(MappingError, match=r"sensors\.drive_pressure\.unit: 'bar'"):
        import_logs([], wrong_unit, store)
    fewer = log_mapping(controls={"boom": ControlSpec("u")})
    with pytest.raises(MappingError, match=r"missing \['bucket', 'throttle'\]"):
        import_logs([], fewer, store)


# ------------------------------------------------------------------ malformed logs
def corrupt(table: pd.DataFrame, column: str, row: int, value) -> pd.DataFrame:
    table = table.copy()
    if isinstance(value, str):  # a text column, as a logger writing text would make it
        table[column] = table[column].map(repr).astype(object)
    table.loc[row - 1, column] = value
    return table


def sensor_out_of_range(name: str) -> float:
    s = next(s for s in SENSORS if s.name == name)
    scale, offset = SENSOR_SCALES[name]
    return (s.high + 0.5 - offset) / scale


CASES = {
    "nan": (sensor_column("boom_pressure"), 4, np.nan, "missing value"),
    "inf": (sensor_column("pump_angle"), 9, np.inf, "non-finite value inf"),
    "minus_inf": (control_column("bucket"), 2, -np.inf, "non-finite value -inf"),
    "out_of_range": (
        sensor_column("drive_pressure"),
        7,
        sensor_out_of_range("drive_pressure"),
        "outside the physical range [0, 40] MPa",
    ),
    "control": (control_column("throttle"), 12, 1001.0, "control throttle = 1.002"),
    "time_back": ("t_ms", 3, -1.0, "time is not strictly increasing"),
}


@pytest.mark.parametrize("fmt", FORMATS)
@pytest.mark.parametrize("case", list(CASES))
def test_bad_values_are_rejected_naming_file_column_row(tmp_path, mapping, table, fmt, case):
    column, row, value, problem = CASES[case]
    path = write_log(corrupt(table, column, row, value), tmp_path / f"log.{fmt}")
    store = create_store(tmp_path / "ds", mapping)
    with pytest.raises(LogImportError) as error:
        import_logs([path], mapping, store)
    assert_names(error, path, column, row)
    assert problem in str(error.value)


@pytest.mark.parametrize("fmt", FORMATS)
def test_non_numeric_value_is_rejected(tmp_path, mapping, table, fmt):
    path = write_log(
        corrupt(table, sensor_column("bucket_angle"), 5, "12,5°"), tmp_path / f"log.{fmt}"
    )
    with pytest.raises(LogImportError, match="non-numeric value '12,5°'") as error:
        import_logs(path, mapping, create_store(tmp_path / "ds", mapping))
    assert_names(error, path, sensor_column("bucket_angle"), 5)


def test_repeated_time_is_rejected(tmp_path, mapping, table):
    table.loc[3, "t_ms"] = table.loc[2, "t_ms"]
    path = write_log(table, tmp_path / "log.csv")
    with pytest.raises(LogImportError, match="repeats") as error:
        import_logs(path, mapping, create_store(tmp_path / "ds", mapping))
    assert_names(error, path, "t_ms", 4)


@pytest.mark.parametrize("fmt", FORMATS)
def test_missing_column_is_rejected(tmp_path, mapping, table, fmt):
    path = write_log(table.drop(columns=[control_column("boom")]), tmp_path / f"log.{fmt}")
    with pytest.raises(LogImportError, match="missing column") as error:
        import_logs(path, mapping, create_store(tmp_path / "ds", mapping))
    assert_names(error, path, control_column("boom"), None)


def test_episode_rows_must_be_contiguous(tmp_path, mapping, table):
    table.loc[14, "run"] = 1
    path = write_log(table, tmp_path / "log.csv")
    with pytest.raises(LogImportError, match="episode '1' appears again") as error:
        import_logs(path, mapping, create_store(tmp_path / "ds", mapping))
    assert_names(error, path, "run", 15)


def test_short_hdf5_column_is_rejected(tmp_path, mapping, table):
    path = write_log(table, tmp_path / "log.h5")
    with h5py.File(path, "a") as h5:
        del h5[HDF5_GROUP]["t_ms"]
        h5[HDF5_GROUP].create_dataset("t_ms", data=table["t_ms"].to_numpy()[:10])
    with pytest.raises(LogImportError, match="the column has 10 rows") as error:
        import_logs(path, mapping, create_store(tmp_path / "ds", mapping))
    assert_names(error, path, "t_ms", 11)


def test_single_row_needs_a_rate(tmp_path, mapping, table):
    path = write_log(table.iloc[:1], tmp_path / "log.csv")
    with pytest.raises(LogImportError, match="set time.rate_hz"):
        import_logs(path, mapping, create_store(tmp_path / "ds", mapping))


def test_bad_success_value_is_rejected(tmp_path, table):
    mapping = log_mapping(metadata=MetadataSpec(success_column="ok"))
    path = write_log(table.assign(ok=["yes"] * 7 + ["maybe"] + ["no"] * 7), tmp_path / "log.csv")
    with pytest.raises(LogImportError, match="got 'maybe'") as error:
        import_logs(path, mapping, create_store(tmp_path / "ds", mapping))
    assert_names(error, path, "ok", 8)


def empty_files(tmp_path: Path, table: pd.DataFrame) -> list[tuple[Path, str]]:
    header_only = tmp_path / "header.csv"
    header_only.write_text(",".join(table.columns) + "\n")
    zero_rows = write_log(table.iloc[:0], tmp_path / "zero_rows.parquet")
    zero_h5 = write_log(table.iloc[:0], tmp_path / "zero_rows.h5")
    zero_bytes = [tmp_path / f"zero.{fmt}" for fmt in FORMATS]
    for p in zero_bytes:
        p.write_bytes(b"")
    return [
        (header_only, "no data rows"),
        (zero_rows, "no data rows"),
        (zero_h5, "no data rows"),
        *((p, "0 bytes") for p in zero_bytes),
    ]


def test_empty_files_are_rejected(tmp_path, mapping, table):
    store = create_store(tmp_path / "ds", mapping)
    for path, problem in empty_files(tmp_path, table):
        with pytest.raises(LogImportError, match=problem) as error:
            import_logs(path, mapping, store)
        assert_names(error, path, None, None)


def test_corrupt_files_are_rejected(tmp_path, mapping, table):
    parquet = write_log(table, tmp_path / "truncated.parquet")
    parquet.write_bytes(parquet.read_bytes()[: parquet.stat().st_size // 2])
    garbage_h5 = tmp_path / "garbage.h5"
    garbage_h5.write_bytes(np.random.default_rng(0).bytes(4096))
    ragged_csv = write_log(table, tmp_path / "ragged.csv")
    ragged_csv.write_text(ragged_csv.read_text() + "1,2,3," * 10 + "\n")
    binary_csv = tmp_path / "binary.csv"
    binary_csv.write_bytes(b"\xff\xfe\x00" * 100)
    no_group = write_log(table, tmp_path / "no_group.h5")
    with h5py.File(no_group, "a") as h5:
        h5.move(HDF5_GROUP, "other")
    unknown = write_log(table, tmp_path / "log.csv").rename(tmp_path / "log.txt")
    store = create_store(tmp_path / "ds", mapping)
    for path, problem in [
        (parquet, "unreadable Parquet"),
        (garbage_h5, "unreadable HDF5"),
        (ragged_csv, "unreadable CSV"),
        (binary_csv, "unreadable CSV"),
        (no_group, "no HDF5 group 'log'"),
        (unknown, "unknown log format"),
    ]:
        with pytest.raises(LogImportError, match=problem) as error:
            import_logs(path, mapping, store)
        assert str(path) in str(error.value)
    assert len(store) == 0


def test_a_bad_file_leaves_the_store_as_it_was(tmp_path, mapping, table):
    store = create_store(tmp_path / "ds", mapping)
    import_logs(write_log(table, tmp_path / "first.csv"), mapping, store)
    before = store_state(store)
    good = write_log(table, tmp_path / "good.parquet")
    bad = write_log(corrupt(table, "t_ms", 15, np.nan), tmp_path / "bad.h5")
    with pytest.raises(LogImportError) as error:
        import_logs([good, good, bad], mapping, store)
    assert_names(error, bad, "t_ms", 15)
    assert store_state(store) == before
    assert len(store) == 3


# ------------------------------------------------------------------ property-based
@st.composite
def raw_logs(draw) -> tuple[pd.DataFrame, str]:
    lengths = draw(st.lists(st.integers(2, 12), min_size=1, max_size=4))
    seed = draw(st.integers(0, 2**32 - 1))
    return log_table(np.random.default_rng(seed), lengths), draw(st.sampled_from(FORMATS))


def cells(table: pd.DataFrame, columns: list[str]):
    """Strategy: a non-empty set of (column, 0-based row) cells."""
    cell = st.tuples(st.sampled_from(columns), st.integers(0, len(table) - 1))
    return st.lists(cell, min_size=1, max_size=6, unique=True)


def first_bad(table: pd.DataFrame, mapping: LogMapping, bad: set[tuple[str, int]]):
    """(column, 1-based row) the importer must report: first column checked, first row."""
    for column in check_order(mapping):
        rows = sorted(r for c, r in bad if c == column)
        if rows:
            return column, rows[0] + 1
    raise AssertionError("no bad cell")


def rejected(table: pd.DataFrame, fmt: str, mapping: LogMapping) -> pytest.ExceptionInfo:
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        path = write_log(table, root / f"log.{fmt}")
        store = create_store(root / "ds", mapping)
        before = store_state(store)
        with pytest.raises(LogImportError) as error:
            import_logs(path, mapping, store)
        assert store_state(store) == before
        assert str(path) in str(error.value)
    return error


@PROPERTY_SETTINGS
@given(data=st.data(), log=raw_logs())
def test_property_non_finite_cells_are_reported_at_the_first(data, log):
    table, fmt = log
    mapping = log_mapping()
    bad = data.draw(cells(table, check_order(mapping)))
    for column, row in bad:
        table.loc[row, column] = data.draw(st.sampled_from([np.nan, np.inf, -np.inf]))
    error = rejected(table, fmt, mapping)
    column, row = first_bad(table, mapping, set(bad))
    assert (error.value.column, error.value.row) == (column, row)
    assert f"column {column!r}, row {row} (1-based data row)" in str(error.value)


@PROPERTY_SETTINGS
@given(data=st.data(), log=raw_logs())
def test_property_out_of_range_cells_are_reported_at_the_first(data, log):
    table, fmt = log
    mapping = log_mapping()
    columns = check_order(mapping)[1:]  # sensors and controls
    bad = data.draw(cells(table, columns))
    for column, row in bad:
        excess = data.draw(st.floats(0.01, 1e3)) * data.draw(st.sampled_from([-1, 1]))
        name = column.removesuffix("_raw").removeprefix("u_")
        if name in mapping.sensors:
            spec = mapping.sensors[name]
            value = (spec.range[1] + excess) if excess > 0 else (spec.range[0] + excess)
        else:
            spec = mapping.controls[name]
            value = math.copysign(1.0 + abs(excess), excess)
        table.loc[row, column] = (value - spec.offset) / spec.scale
    error = rejected(table, fmt, mapping)
    column, row = first_bad(table, mapping, set(bad))
    assert (error.value.column, error.value.row) == (column, row)
    assert "outside" in str(error.value)


@PROPERTY_SETTINGS
@given(data=st.data(), log=raw_logs())
def test_property_shuffled_time_is_reported_where_it_goes_back(data, log):
    table, fmt = log
    order = data.draw(st.permutations(range(len(table))))
    runs = table["run"].to_numpy()
    time = table["t_ms"].to_numpy()[list(order)]
    table["t_ms"] = time
    steps_back = [
        i for i in range(1, len(table)) if runs[i] == runs[i - 1] and time[i] <= time[i - 1]
    ]
    if not steps_back:  # the shuffle kept every run increasing: it must import
        with tempfile.TemporaryDirectory() as tmp:
            write_log(table, Path(tmp) / f"log.{fmt}")
            mapping = log_mapping()
            store = create_store(Path(tmp) / "ds", mapping)
            import_logs(Path(tmp) / f"log.{fmt}", mapping, store)
        return
    error = rejected(table, fmt, log_mapping())
    assert (error.value.column, error.value.row) == ("t_ms", steps_back[0] + 1)
    assert "time is not strictly increasing" in str(error.value)


@PROPERTY_SETTINGS
@given(log=raw_logs(), export_suffix=st.sampled_from([".csv", ".parquet"]))
def test_property_well_formed_logs_round_trip(log, export_suffix):
    table, fmt = log
    mapping = log_mapping()
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        store = create_store(root / "ds", mapping)
        metas = import_logs(write_log(table, root / f"log.{fmt}"), mapping, store)
        assert [m.n_samples for m in metas] == table.groupby("run").size().tolist()
        imported = store.to_tensordict()
        for name, values in expected_values(table, mapping).items():
            np.testing.assert_array_equal(imported[name].numpy()[:, 0], values)
        np.testing.assert_allclose(
            imported["action"].numpy(), expected_actions(table, mapping), atol=1e-6
        )
        path = export_episodes(store, root / f"out{export_suffix}")
        copy = EpisodeStore.create(root / "copy", sensors=store.sensors, controls=store.controls)
        import_logs(path, mapping_for_export(store), copy)
        assert_same_samples(store, copy, list(range(len(store))))
        for i in range(len(store)):
            torch.testing.assert_close(
                copy.load(i)["next"].to_tensordict(),
                store.load(i)["next"].to_tensordict(),
                equal_nan=True,
            )
