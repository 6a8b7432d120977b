"""Issue #17 (1): CSV / TSV as data loggers write them."""

from __future__ import annotations

import math

import numpy as np
import pytest
from import_logs_helpers import (
    CONTROL_COLUMNS,
    RAW_COLUMNS,
    logger_mapping,
    logger_mapping_dict,
    scoop,
    to_raw,
    write_logger_csv,
)

from pilerl.data.importers import (
    LogImportError,
    MappingError,
    create_store,
    import_logs,
    load_mapping,
    read_all,
)

SENSOR_NAMES = list(RAW_COLUMNS)
CONTROL_NAMES = list(CONTROL_COLUMNS)


def assert_matches(episode, values, rows=slice(None)) -> None:
    """Imported episode == the scoop in pilerl units (6-decimal raw cells: 1e-5 slack)."""
    for name in SENSOR_NAMES:
        np.testing.assert_allclose(episode[name].numpy()[:, 0], values[name][rows], atol=1e-5)
    actions = np.stack([values[c][rows] for c in CONTROL_NAMES], axis=-1)
    np.testing.assert_allclose(episode["action"].numpy(), actions, atol=1e-6)


def test_units_row_decimal_comma_log_imports_in_pilerl_units(tmp_path):
    values = scoop(120)
    path = write_logger_csv(tmp_path / "log.csv", values)
    assert "Time;Boom angle" in path.read_text() and "ms;deg;deg;bar" in path.read_text()
    mapping = logger_mapping()
    store = create_store(tmp_path / "ds", mapping)
    (meta,) = import_logs(path, mapping, store)
    episode = store.load(0)
    assert_matches(episode, values)
    np.testing.assert_allclose(episode["time_s"].numpy(), values["time_s"], atol=1e-9)
    assert meta.rate_hz == pytest.approx(50.0)
    assert episode["boom_angle"].min().item() < math.radians(-33)  # the machine's range
    assert store.stats is not None and store.stats["n_samples"] == 120


@pytest.mark.parametrize(
    ("separator", "decimal", "units_row"), [("\t", ".", False), (",", ".", True), ("|", ",", True)]
)
def test_separators_decimal_marks_and_header_units_are_detected(
    tmp_path, separator, decimal, units_row
):
    values = scoop(40, seed=1)
    path = write_logger_csv(
        tmp_path / "log.csv",
        values,
        separator=separator,
        decimal=decimal,
        units_row=units_row,
        comments=False,
    )
    mapping_dict = logger_mapping_dict()
    mapping_dict["csv"]["units_row"] = units_row
    if not units_row:  # units in the header instead: "Boom angle [deg]"
        units = ["ms"] + [u for _, u in RAW_COLUMNS.values()] + ["%"] * 3 + ["degC"]
        lines = path.read_text().splitlines()
        names = lines[0].split(separator)
        lines[0] = separator.join(f"{n} [{u}]" for n, u in zip(names, units, strict=True))
        path.write_text("\n".join(lines) + "\n")
    episodes = read_all(path, load_mapping(mapping_dict))
    assert_matches(episodes[0].episode, values)
    assert any("separator" in note for note in episodes[0].notes)


def test_declared_separator_and_decimal_are_used(tmp_path):
    values = scoop(30)
    path = write_logger_csv(tmp_path / "log.csv", values)
    mapping_dict = logger_mapping_dict()
    mapping_dict["csv"].update(delimiter=";", decimal=",")
    assert_matches(read_all(path, load_mapping(mapping_dict))[0].episode, values)
    mapping_dict["csv"].update(decimal=".")
    with pytest.raises(
        LogImportError, match=r"column 'Time', row 1 .*non-numeric value '0,000000'"
    ):
        read_all(path, load_mapping(mapping_dict))


def test_a_units_row_not_declared_is_named_with_a_hint(tmp_path):
    path = write_logger_csv(tmp_path / "log.csv", scoop(10))
    mapping_dict = logger_mapping_dict()
    mapping_dict["csv"]["units_row"] = False
    with pytest.raises(LogImportError) as error:
        read_all(path, load_mapping(mapping_dict))
    message = str(error.value)
    assert "column 'Time', row 1 (1-based data row) at line 4: non-numeric value 'ms'" in message
    assert "set csv.units_row: true" in message


def test_unit_conversions_follow_the_declared_or_file_unit(tmp_path):
    values = scoop(20)
    path = write_logger_csv(tmp_path / "log.csv", values)
    mapping_dict = logger_mapping_dict()
    mapping_dict["sensors"]["drive_pressure"]["source_unit"] = "bar"  # agrees with the file
    assert_matches(read_all(path, load_mapping(mapping_dict))[0].episode, values)
    mapping_dict["sensors"]["drive_pressure"]["source_unit"] = "kPa"  # disagrees
    with pytest.raises(LogImportError, match=r"column 'p drive'.*'kPa' and the file's unit 'bar'"):
        read_all(path, load_mapping(mapping_dict))
    mapping_dict["sensors"]["drive_pressure"].update(source_unit="raw", scale=0.1)
    assert_matches(read_all(path, load_mapping(mapping_dict))[0].episode, values)
    text = path.read_text().replace("ms;deg;deg;bar", "ms;deg;deg;furlong", 1)
    path.write_text(text)
    with pytest.raises(LogImportError, match=r"column 'p drive'.*unknown unit 'furlong'"):
        read_all(path, load_mapping(logger_mapping_dict()))


def test_incompatible_units_are_refused_in_the_mapping():
    mapping_dict = logger_mapping_dict()
    mapping_dict["sensors"]["boom_angle"]["source_unit"] = "bar"
    with pytest.raises(MappingError, match=r"boom_angle\.source_unit: cannot convert 'bar'"):
        load_mapping(mapping_dict)
    mapping_dict = logger_mapping_dict(unit="ms", scale=0.001)
    with pytest.raises(MappingError, match=r"time: give unit or scale, not both"):
        load_mapping(mapping_dict)


def test_header_aliases_case_and_spacing(tmp_path):
    values = scoop(15)
    path = write_logger_csv(tmp_path / "log.csv", values)
    mapping_dict = logger_mapping_dict()
    mapping_dict["sensors"]["boom_angle"].update(
        column="th1", aliases=["Boom_Angle", "boom  ANGLE"]
    )
    mapping_dict["controls"]["boom"]["column"] = "JOY BOOM"
    (episode,) = read_all(path, load_mapping(mapping_dict))
    assert_matches(episode.episode, values)
    mapping_dict["sensors"]["boom_angle"]["aliases"] = []
    with pytest.raises(LogImportError, match=r"column 'boom_angle'|column 'th1'") as error:
        read_all(path, load_mapping(mapping_dict))
    assert "missing column" in str(error.value) and "Boom angle" in str(error.value)


def test_two_headers_matching_one_name_are_ambiguous(tmp_path):
    path = write_logger_csv(tmp_path / "log.csv", scoop(5))
    path.write_text(path.read_text().replace("Engine temp", "p Boom", 1))
    read_all(path, logger_mapping())  # the exact name wins
    mapping_dict = logger_mapping_dict()
    mapping_dict["sensors"]["boom_pressure"]["column"] = "P BOOM"
    with pytest.raises(LogImportError, match=r"ambiguous: columns \['p boom', 'p Boom'\]"):
        read_all(path, load_mapping(mapping_dict))


@pytest.mark.parametrize("unit", ["s", "ms", "iso"])
def test_time_in_seconds_milliseconds_or_iso_timestamps(tmp_path, unit):
    values = scoop(25, rate_hz=20.0)
    raw = to_raw(values)
    if unit == "s":
        times = [f"{t:.3f}" for t in values["time_s"] + 100.0]
    elif unit == "ms":
        times = [f"{t:.0f}" for t in raw["Time"]]
    else:
        base = np.datetime64("2025-02-11T10:15:03.000")
        times = [str(base + np.timedelta64(int(ms), "ms")) for ms in raw["Time"]]
    units = dict(
        [("Time", ""), *RAW_COLUMNS.values(), *((c, "%") for c in CONTROL_COLUMNS.values())]
    )
    columns = {
        "Time": times,
        **{f"{k} [{units[k]}]": [f"{v:.6f}" for v in col] for k, col in raw.items() if k != "Time"},
    }
    lines = [",".join(columns)] + [",".join(row) for row in zip(*columns.values(), strict=True)]
    path = tmp_path / "log.csv"
    path.write_text("\n".join(lines) + "\n")
    mapping_dict = logger_mapping_dict(**({} if unit == "iso" else {"unit": unit}))
    mapping_dict["csv"]["units_row"] = False
    (episode,) = read_all(path, load_mapping(mapping_dict))
    np.testing.assert_allclose(episode.episode["time_s"].numpy(), values["time_s"], atol=1e-6)
    assert episode.meta.rate_hz == pytest.approx(20.0)
    if unit == "iso":
        lines[5] = lines[5].replace("2025-02-11T", "2025-02-31T")
        path.write_text("\n".join(lines) + "\n")
        with pytest.raises(LogImportError, match=r"row 5 .*not an ISO 8601 timestamp"):
            read_all(path, load_mapping(mapping_dict))


def test_file_cut_mid_row_is_truncation_not_a_range_error(tmp_path):
    path = write_logger_csv(tmp_path / "log.csv", scoop(30))
    text = path.read_text()
    cut = text[: text.rindex(";", 0, len(text) - 40)]  # inside the last row, a few fields in
    path.write_text(cut)
    with pytest.raises(LogImportError, match="truncated file: the last row ends after") as error:
        read_all(path, logger_mapping())
    assert error.value.row == 30 and error.value.line == 34


def test_file_cut_inside_an_unmapped_trailing_column_is_truncation(tmp_path):
    path = write_logger_csv(tmp_path / "log.csv", scoop(30))
    path.write_text(path.read_text()[:-4])  # "81,5\n" -> "81"
    with pytest.raises(LogImportError, match="truncated file: the last row has no final newline"):
        read_all(path, logger_mapping())
    mapping_dict = logger_mapping_dict()
    mapping_dict["csv"]["final_newline"] = False  # a logger that writes none
    assert read_all(path, load_mapping(mapping_dict))[0].sampling.n_rows == 30


def test_short_row_in_the_middle_is_named(tmp_path):
    path = write_logger_csv(tmp_path / "log.csv", scoop(30))
    lines = path.read_text().splitlines()
    lines[10] = ";".join(lines[10].split(";")[:5])
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(
        LogImportError, match=r"row 7 \(1-based data row\) at line 11: row has 5 of 12"
    ):
        read_all(path, logger_mapping())


def test_mixed_decimal_marks_are_refused(tmp_path):
    path = write_logger_csv(tmp_path / "log.csv", scoop(10))
    lines = path.read_text().splitlines()
    lines[6] = lines[6].replace(",", ".")
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(LogImportError, match="cannot tell the decimal mark"):
        read_all(path, logger_mapping())


def drop_rows(path, rows: list[int]) -> None:
    """Delete data rows (0-based, after the units row) from a logger CSV."""
    lines = path.read_text().splitlines()
    first = next(i for i, line in enumerate(lines) if line.startswith("ms;")) + 1
    keep = [line for i, line in enumerate(lines) if i - first not in rows]
    path.write_text("\n".join(keep) + "\n")


def test_dropped_samples_and_jitter_are_measured_not_hidden(tmp_path):
    values = scoop(200)
    rng = np.random.default_rng(3)
    values["time_s"] = values["time_s"] + rng.uniform(-0.002, 0.002, 200)  # +-2 ms jitter
    path = write_logger_csv(tmp_path / "log.csv", values)
    drop_rows(path, [50, 51, 52, 120])
    (episode,) = read_all(path, logger_mapping(rate_hz=50.0))
    sampling = episode.sampling
    assert sampling.n_rows == 196
    assert [row for row, _ in sampling.gaps] == [51, 118]  # rows after the gaps (1-based)
    assert sampling.dropped == 4
    assert 0.0005 < sampling.jitter_s < 0.003
    np.testing.assert_allclose(
        episode.episode["time_s"].numpy()[50] - episode.episode["time_s"].numpy()[49],
        0.08,
        atol=0.005,
    )


def test_max_gap_refuses_dropped_samples_naming_the_row(tmp_path):
    path = write_logger_csv(tmp_path / "log.csv", scoop(100))
    drop_rows(path, [40, 41])
    with pytest.raises(LogImportError, match=r"column 'Time', row 41 .*gap of 0\.06 s"):
        read_all(path, logger_mapping(max_gap_s=0.05))


def test_resampling_happens_only_on_request(tmp_path):
    values = scoop(101)
    path = write_logger_csv(tmp_path / "log.csv", values)
    drop_rows(path, [30, 31, 32])
    (kept,) = read_all(path, logger_mapping())
    assert kept.episode.batch_size[0] == 98  # as logged
    (episode,) = read_all(path, logger_mapping(resample_hz=25.0))
    td = episode.episode
    assert td.batch_size[0] == 51 and episode.meta.rate_hz == 25.0
    np.testing.assert_allclose(td["time_s"].numpy(), np.arange(51) / 25.0, atol=1e-9)
    grid = np.arange(51) * 2  # 25 Hz rows of the 50 Hz scoop
    for name in SENSOR_NAMES:  # the slow sensors interpolate across the gap
        np.testing.assert_allclose(
            td[name].numpy()[:, 0], values[name][grid], atol=0.05 * np.ptp(values[name])
        )
    assert episode.sampling.resampled_hz == 25.0 and len(episode.sampling.gaps) == 1


def test_a_column_named_twice_in_the_header_is_refused(tmp_path):
    path = write_logger_csv(tmp_path / "log.csv", scoop(5))
    path.write_text(path.read_text().replace("Engine temp", "p boom", 1))
    with pytest.raises(LogImportError, match=r"column 'p boom': the header names 'p boom' twice"):
        read_all(path, logger_mapping())


def test_file_units_and_a_mapping_scale_do_not_convert_twice(tmp_path):
    values = scoop(10)
    path = write_logger_csv(tmp_path / "log.csv", values)
    old = logger_mapping_dict()
    old["sensors"]["drive_pressure"]["scale"] = 0.1  # written for a file without units
    with pytest.raises(
        LogImportError,
        match=r"column 'p drive': the file gives the unit 'bar' and the mapping a scale 0.1",
    ):
        read_all(path, load_mapping(old))
    old["sensors"]["drive_pressure"].update(source_unit="bar", scale=1.02)  # calibration
    (episode,) = read_all(path, load_mapping(old))
    np.testing.assert_allclose(
        episode.episode["drive_pressure"].numpy()[:, 0], values["drive_pressure"] * 1.02, rtol=1e-5
    )


def test_bracketed_words_that_are_not_units_stay_in_the_name(tmp_path):
    path = write_logger_csv(tmp_path / "log.csv", scoop(10))
    path.write_text(path.read_text().replace("p tele", "p tele (front)", 1))
    mapping_dict = logger_mapping_dict()
    mapping_dict["sensors"]["telescope_pressure"]["column"] = "p tele (front)"
    assert len(read_all(path, load_mapping(mapping_dict))) == 1


def test_a_declared_units_row_that_holds_numbers_is_named(tmp_path):
    path = write_logger_csv(tmp_path / "log.csv", scoop(10), units_row=False)
    with pytest.raises(LogImportError, match=r"line 4: csv.units_row is true, but the line"):
        read_all(path, logger_mapping())
