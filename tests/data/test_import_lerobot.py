"""Issue #17 (6): LeRobot dataset layout (v3.0) export and import; the export is read the
way TorchRL 0.14's LeRobot reader reads a snapshot."""

from __future__ import annotations

import json
import math

import numpy as np
import pyarrow.parquet as pq
import pytest
import torch
from pilerl_pile_loader.sensors import CONTROL_NAMES, SENSORS

from pilerl.data.lerobot import (
    LeRobotFormatError,
    export_lerobot,
    import_lerobot,
    import_lerobot_dataset,
    main,
    read_lerobot,
)
from pilerl.data.schema import EpisodeMeta, make_episode
from pilerl.data.store import EpisodeStore


def sim_store(root, rates=(20.0, 20.0, 20.0)) -> EpisodeStore:
    rng = np.random.default_rng(0)
    store = EpisodeStore.create(
        root, sensors={s.name: s.unit for s in SENSORS}, controls=list(CONTROL_NAMES)
    )
    for k, (n, rate) in enumerate(zip([6, 4, 5], rates, strict=True)):
        readings = {
            s.name: torch.tensor(rng.uniform(s.low, s.high, n + 1), dtype=torch.float32)
            for s in SENSORS
        }
        store.append(
            make_episode(
                sensors={name: v[:-1] for name, v in readings.items()},
                next_sensors={name: v[1:] for name, v in readings.items()},
                actions=torch.tensor(rng.uniform(-1, 1, (n, 3)), dtype=torch.float32),
                time_s=torch.arange(n, dtype=torch.float64) / rate,
                rewards=torch.tensor(rng.normal(size=n)),
                terminated=k != 1,
                truncated=k == 1,
            ),
            EpisodeMeta(
                rate_hz=rate,
                condition=["summer", "winter_c"][k % 2],
                seed=k,
                success=k == 2,
                fill_fraction=0.3 * k,
            ),
        )
    return store


def test_export_has_the_lerobot_v3_layout(tmp_path):
    store = sim_store(tmp_path / "ds")
    out = export_lerobot(store, tmp_path / "lerobot")
    info = json.loads((out / "meta" / "info.json").read_text())
    assert info["codebase_version"] == "v3.0" and info["fps"] == 20.0
    assert info["total_episodes"] == 3 and info["total_frames"] == 15
    assert info["features"]["observation.state"]["names"] == [s.name for s in SENSORS]
    frames = pq.read_table(out / "data" / "chunk-000" / "file-000.parquet")
    assert frames.column("index").to_pylist() == list(range(15))
    assert frames.column("episode_index").to_pylist() == [0] * 6 + [1] * 4 + [2] * 5
    episodes = pq.read_table(
        out / "meta" / "episodes" / "chunk-000" / "file-000.parquet"
    ).to_pylist()
    assert [(e["length"], e["dataset_from_index"], e["dataset_to_index"]) for e in episodes] == [
        (6, 0, 6),
        (4, 6, 10),
        (5, 10, 15),
    ]
    assert pq.read_table(out / "meta" / "tasks.parquet").to_pylist() == [
        {"task_index": 0, "task": "summer"},
        {"task_index": 1, "task": "winter_c"},
    ]
    stats = json.loads((out / "meta" / "stats.json").read_text())
    state = store.to_tensordict()
    np.testing.assert_allclose(
        stats["observation.state"]["max"], [state[s.name].max().item() for s in SENSORS], rtol=1e-6
    )


def test_torchrl_lerobot_reader_reads_the_export(tmp_path):
    from torchrl.data.datasets.lerobot import (
        LeRobotExperienceReplay,
        _LeRobotSnapshot,
        lerobot_columns_to_tensordict,
    )

    store = sim_store(tmp_path / "ds")
    out = export_lerobot(store, tmp_path / "lerobot")
    # TorchRL's snapshot reader, pointed at the folder instead of a hub download
    snapshot = _LeRobotSnapshot.__new__(_LeRobotSnapshot)
    snapshot.root = out
    snapshot.info = json.loads((out / "meta" / "info.json").read_text())
    episodes, tasks = snapshot._load_episodes(), snapshot._load_tasks()
    assert [e["episode_index"] for e in episodes] == [0, 1, 2] and tasks == {
        0: "summer",
        1: "winter_c",
    }
    # its frames: every data parquet, as `datasets.load_dataset("parquet")` yields them
    table = pq.read_table(sorted((out / "data").rglob("*.parquet"))[0])
    columns = {}
    for name in table.column_names:
        values = table.column(name).to_pylist()
        columns[name] = torch.tensor(values)
    columns["task"] = [tasks[int(i)] for i in columns["task_index"]]
    td = lerobot_columns_to_tensordict(columns)
    expected = store.to_tensordict()
    state = torch.cat([expected[s.name] for s in SENSORS], dim=1)
    torch.testing.assert_close(td["observation", "state"], state)
    torch.testing.assert_close(td["action"], expected["action"])
    assert td["next", "done"].shape == (15, 1) and td["next", "done"].sum() == 3
    assert td.get("language_instruction").tolist()[6] == "winter_c"
    buffer = LeRobotExperienceReplay.from_columns(columns, batch_size=4)
    assert buffer.sample()["observation", "state"].shape == (4, 7)


def test_export_imports_back_with_its_metadata(tmp_path):
    store = sim_store(tmp_path / "ds")
    out = export_lerobot(store, tmp_path / "lerobot", episode_ids=[2, 0])
    copy = EpisodeStore.create(tmp_path / "copy", sensors=store.sensors, controls=store.controls)
    metas = import_lerobot(out, copy)
    assert [(m.condition, m.seed, m.success) for m in metas] == [
        ("summer", 2, True),
        ("summer", 0, False),
    ]
    assert metas[0].fill_fraction == pytest.approx(0.6)
    for j, i in enumerate([2, 0]):
        a, b = store.load(i), copy.load(j)
        for key in [*store.sensors, "action", "time_s", ("next", "reward"), ("next", "done")]:
            torch.testing.assert_close(b[key], a[key], atol=1e-6, rtol=0, check_dtype=False)
    assert copy.stats is not None and copy.stats["n_samples"] == 11


def test_episodes_at_different_rates_are_refused(tmp_path):
    store = sim_store(tmp_path / "ds", rates=(20.0, 10.0, 20.0))
    with pytest.raises(ValueError, match=r"one fps: curate to one rate first"):
        export_lerobot(store, tmp_path / "lerobot")
    assert not (tmp_path / "lerobot").exists()
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".lerobot")]


def test_foreign_lerobot_folder_needs_units_and_takes_tasks_as_conditions(tmp_path):
    out = export_lerobot(sim_store(tmp_path / "ds"), tmp_path / "lerobot")
    info = json.loads((out / "meta" / "info.json").read_text())
    del info["pilerl"]
    info["features"]["observation.state"]["names"] = {
        "motors": info["features"]["observation.state"]["names"]
    }
    (out / "meta" / "info.json").write_text(json.dumps(info))
    table = pq.read_table(out / "meta" / "episodes" / "chunk-000" / "file-000.parquet").drop(
        ["pilerl_meta"]
    )
    pq.write_table(table, out / "meta" / "episodes" / "chunk-000" / "file-000.parquet")
    with pytest.raises(LeRobotFormatError, match=r"no unit for observation.state components"):
        read_lerobot(out)
    sensors, controls, episodes = read_lerobot(out, sensor_units={s.name: s.unit for s in SENSORS})
    assert controls == list(CONTROL_NAMES)
    assert [m.condition for _, m in episodes] == ["summer", "winter_c", "summer"]
    assert [m.rate_hz for _, m in episodes] == [20.0] * 3 and math.isnan(
        episodes[0][1].fill_fraction
    )


def test_command_line_round_trip_and_bad_folder(tmp_path, capsys):
    sim_store(tmp_path / "ds")
    main(["export", str(tmp_path / "ds"), str(tmp_path / "lerobot")])
    main(["import", str(tmp_path / "lerobot"), str(tmp_path / "copy")])
    assert len(EpisodeStore.open(tmp_path / "copy")) == 3
    (tmp_path / "bad" / "meta").mkdir(parents=True)
    (tmp_path / "bad" / "meta" / "info.json").write_text('{"codebase_version": "v1.6", "fps": 10}')
    with pytest.raises(SystemExit, match=r"codebase_version 'v1.6'"):
        main(["import", str(tmp_path / "bad"), str(tmp_path / "never")])
    assert not (tmp_path / "never").exists()


def test_import_into_a_new_dataset_and_refusal_of_another_layout(tmp_path):
    out = export_lerobot(sim_store(tmp_path / "ds"), tmp_path / "lerobot")
    store, metas = import_lerobot_dataset(out, tmp_path / "new")
    assert len(metas) == 3 and len(EpisodeStore.open(tmp_path / "new")) == 3
    assert store.stats is not None and store.stats["n_samples"] == 15
    EpisodeStore.create(tmp_path / "other", sensors={"boom_angle": "rad"}, controls=["boom"])
    with pytest.raises(ValueError, match="existing dataset has sensors"):
        import_lerobot_dataset(out, tmp_path / "other")
    assert len(EpisodeStore.open(tmp_path / "other")) == 0
