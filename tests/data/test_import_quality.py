"""Issue #17 (3, 4): imported datasets are ready to train (statistics, provenance, the
machine's own ranges) and every import gets a data-quality report."""

from __future__ import annotations

import hashlib

import numpy as np
import pytest
import yaml
from import_logs_helpers import logger_mapping, logger_mapping_dict, scoop, write_logger_csv

from pilerl.data.curation import compute_stats
from pilerl.data.importers import (
    LogImportError,
    create_store,
    import_episodes,
    import_logs,
    load_mapping,
    machine_ranges,
    quality_report,
    read_all,
    read_provenance,
)
from pilerl.data.importers.__main__ import main
from pilerl.data.store import EpisodeStore

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
SIM_RANGES = {"boom_angle": (-0.55, 1.05), "bucket_pressure": (0.0, 40.0)}


def awkward_log(path, seed: int = 4):
    """400 rows at 50 Hz with +-3 ms jitter, 6 dropped rows, a frozen telescope pressure,
    a clipped bucket pressure, the boom below the simulator's range, one control at a time
    (throttle held)."""
    values = scoop(400, seed=seed)
    rng = np.random.default_rng(seed + 1)
    values["time_s"] = values["time_s"] + rng.uniform(-0.003, 0.003, 400)
    values["telescope_pressure"][150:300] = values["telescope_pressure"][150]
    values["bucket_pressure"] = np.minimum(values["bucket_pressure"], 17.5)
    write_logger_csv(path, values)
    lines = path.read_text().splitlines()
    del lines[100:106]
    path.write_text("\n".join(lines) + "\n")
    return path


def test_import_stores_statistics_and_provenance(tmp_path):
    mapping = logger_mapping()
    store = create_store(tmp_path / "ds", mapping)
    first = write_logger_csv(tmp_path / "a.csv", scoop(60, seed=1))
    import_logs(first, mapping, store)
    assert store.stats == compute_stats(store)  # what build_dataset stores
    second = write_logger_csv(tmp_path / "b.csv", scoop(40, seed=2))
    import_logs([second], mapping, store)
    reopened = EpisodeStore.open(tmp_path / "ds")
    assert reopened.stats == compute_stats(reopened) and reopened.stats["n_samples"] == 100
    records = read_provenance(tmp_path / "ds")
    assert [r["episodes"] for r in records] == [[0], [1]]
    (file,) = records[1]["files"]
    assert file["path"] == str(second.resolve()) and file["bytes"] == second.stat().st_size
    assert file["sha256"] == hashlib.sha256(second.read_bytes()).hexdigest()
    assert load_mapping(records[1]["mapping"]) == mapping
    assert records[1]["sensor_ranges"]["boom_angle"] == {"low": -0.7, "high": 1.2, "unit": "rad"}
    assert machine_ranges(tmp_path / "ds")["boom_angle"] == (-0.7, 1.2)


def test_data_are_checked_against_the_machines_ranges_not_the_simulators(tmp_path):
    values = scoop(50)
    assert values["boom_angle"].min() < SIM_RANGES["boom_angle"][0]  # -34 deg
    path = write_logger_csv(tmp_path / "log.csv", values)
    (episode,) = read_all(path, logger_mapping())
    assert episode.episode["boom_angle"].min() < -0.55
    narrow = logger_mapping_dict()
    narrow["sensors"]["drive_pressure"]["range"] = [0, 25]  # inside the simulator's [0, 40]
    with pytest.raises(
        LogImportError,
        match=r"column 'p drive', row \d+ .*outside the physical range \[0, 25\] MPa",
    ):
        read_all(path, load_mapping(narrow))


def test_quality_report_measures_an_awkward_log(tmp_path):
    path = awkward_log(tmp_path / "log.csv")
    mapping = logger_mapping(rate_hz=50.0)
    store = create_store(tmp_path / "ds", mapping)
    episodes, _ = import_episodes(path, mapping, store)
    report = quality_report(
        episodes,
        out_dir=tmp_path / "report",
        required_sensors=["boom_angle", "wheel_speed"],
        reference_ranges=SIM_RANGES,
        control_names=store.controls,
    )
    (q,) = report.episodes
    assert q.rows == 394 and q.dropped == 6 and [row for row, _ in q.gaps] == [97]
    assert 1.0 < q.jitter_ms < 3.5
    assert q.frozen["telescope_pressure"] == pytest.approx(3.0, abs=0.05)
    assert set(q.clipped) == {"bucket_pressure"} and q.clipped["bucket_pressure"] > 0.2
    assert set(q.out_of_reference) == {"boom_angle"}
    assert q.single_control_share == 1.0  # boom and bucket never together; throttle held
    text = report.markdown
    assert "the controller needs sensors ['wheel_speed']" in text
    assert "6 dropped sample(s); the longest is" in text
    assert "['throttle'] active almost throughout and not counted" in text
    assert "| site-a | 1 | 1 | 0 | 0 |" in text
    assert (tmp_path / "report" / "report.md").read_text() == text
    (plot,) = report.plots
    assert plot.name == "episode_000000.png" and plot.read_bytes()[:8] == PNG_MAGIC
    assert "![episode_000000](episode_000000.png)" in text


def test_clean_log_has_no_warnings_and_conditions_are_counted(tmp_path):
    clean = logger_mapping_dict(rate_hz=50.0)
    episodes = []
    for k, condition in enumerate(["dry", "dry", "wet"]):
        clean["metadata"]["condition"] = condition
        clean["metadata"]["success"] = k != 1
        path = write_logger_csv(tmp_path / f"log{k}.csv", scoop(80, seed=k))
        episodes += read_all(path, load_mapping(clean))
    report = quality_report(episodes, required_sensors=["boom_angle"], plots=False)
    assert report.warnings == [] and report.path is None
    assert "| dry | 2 | 1 | 1 | 0 |" in report.markdown
    assert "| wet | 1 | 1 | 0 | 0 |" in report.markdown


def test_command_line_writes_the_report_beside_the_dataset(tmp_path, capsys):
    path = awkward_log(tmp_path / "log.csv")
    mapping = tmp_path / "mapping.yaml"
    mapping.write_text(yaml.safe_dump(logger_mapping_dict(rate_hz=50.0)))
    main(
        [
            "--mapping",
            str(mapping),
            "--dataset",
            str(tmp_path / "ds"),
            "--controller-sensors",
            "boom_angle,wheel_speed",
            str(path),
        ]
    )
    out = capsys.readouterr().out
    assert "imported 1 episodes (394 samples); 1 in the dataset; statistics stored" in out
    assert "warning: the controller needs sensors ['wheel_speed']" in out
    report = tmp_path / "ds" / "quality" / "import_000"
    assert (report / "report.md").exists() and (report / "episode_000000.png").exists()
    assert EpisodeStore.open(tmp_path / "ds").stats["n_samples"] == 394
