"""Run directories: skip a finished run only under the same settings and inputs."""

from __future__ import annotations

import json

import pytest

from pilerl.layout import RunLayout
from pilerl.runs import (
    RunMismatch,
    begin_run,
    fingerprint_path,
    finish_run,
    read_run_settings,
    resolve_checkpoint,
)

SETTINGS = {"policy": {"name": "nnetv2"}, "epochs": 3, "workers": 2, "output_dir": "x"}


def test_a_new_run_records_settings_and_provenance(tmp_path):
    assert begin_run(tmp_path, SETTINGS, control_hz=20.0) is False
    record = json.loads(RunLayout(tmp_path).run_record.read_text())
    assert record["settings"] == {"policy.name": "nnetv2", "epochs": 3}  # workers: not results
    provenance = record["provenance"]
    assert provenance["packages"]["torch"].startswith("2.13")
    assert provenance["control_hz"] == 20.0
    assert {"commit", "dirty"} <= set(provenance["git"])
    assert read_run_settings(tmp_path) == SETTINGS


def test_finished_run_is_skipped_only_with_the_same_settings(tmp_path):
    begin_run(tmp_path, SETTINGS)
    finish_run(tmp_path, {"loss": 0.1})
    assert begin_run(tmp_path, SETTINGS) is True
    assert begin_run(tmp_path, {**SETTINGS, "workers": 1}) is True  # how, not what
    with pytest.raises(RunMismatch, match=r"epochs: 3 -> 6"):
        begin_run(tmp_path, {**SETTINGS, "epochs": 6})
    with pytest.raises(RunMismatch, match=r"policy.name: 'nnetv2' -> 'dannet'"):
        begin_run(tmp_path, {**SETTINGS, "policy": {"name": "dannet"}})


def test_an_interrupted_run_refuses_another_config_and_resumes_the_same(tmp_path):
    begin_run(tmp_path, SETTINGS)  # started, never finished (a kill)
    with pytest.raises(RunMismatch, match="epochs"):
        begin_run(tmp_path, {**SETTINGS, "epochs": 4})
    assert begin_run(tmp_path, SETTINGS) is False  # the same config resumes


def test_a_growable_budget_continues_a_finished_run(tmp_path):
    settings = {"total_frames": 1000, "seed": 0}
    begin_run(tmp_path, settings, growable=["total_frames"])
    finish_run(tmp_path, {"frames": 1000})
    assert begin_run(tmp_path, settings, growable=["total_frames"]) is True
    assert (
        begin_run(tmp_path, {**settings, "total_frames": 2000}, growable=["total_frames"]) is False
    )
    with pytest.raises(RunMismatch, match="seed"):
        begin_run(tmp_path, {**settings, "seed": 1}, growable=["total_frames"])


def test_changed_input_data_is_refused(tmp_path):
    data = tmp_path / "data"
    data.mkdir()
    (data / "index.json").write_text('{"episodes": [1]}')
    run = tmp_path / "run"
    begin_run(run, SETTINGS, inputs={"train_data": data})
    finish_run(run, {"loss": 0.1})
    assert begin_run(run, SETTINGS, inputs={"train_data": data}) is True
    (data / "index.json").write_text('{"episodes": [1, 2]}')  # same path, other episodes
    with pytest.raises(RunMismatch, match=r"input train_data: .* \(content\)"):
        begin_run(run, SETTINGS, inputs={"train_data": data})


def test_a_finished_run_without_a_record_is_not_reused(tmp_path):
    finish_run(tmp_path, {"loss": 0.1})  # as an older pilerl left it
    with pytest.raises(RunMismatch, match="did not record its settings"):
        begin_run(tmp_path, SETTINGS)


def test_refusal_restores_the_hydra_files_of_the_recorded_run(tmp_path):
    hydra = tmp_path / ".hydra"
    hydra.mkdir()
    (hydra / "config.yaml").write_text("epochs: 3\n")
    begin_run(tmp_path, SETTINGS)
    (hydra / "config.yaml").write_text("epochs: 6\n")  # what Hydra writes before the recipe
    with pytest.raises(RunMismatch):
        begin_run(tmp_path, {**SETTINGS, "epochs": 6})
    assert (hydra / "config.yaml").read_text() == "epochs: 3\n"


def test_fingerprints_tell_content_apart(tmp_path):
    a, b = tmp_path / "a.pt", tmp_path / "b.pt"
    a.write_bytes(b"weights-1")
    b.write_bytes(b"weights-2")
    assert fingerprint_path(a) != fingerprint_path(b)
    b.write_bytes(b"weights-1")
    assert fingerprint_path(a) == fingerprint_path(b)
    with pytest.raises(FileNotFoundError, match="missing"):
        fingerprint_path(tmp_path / "missing")


def test_a_run_directory_as_checkpoint_finds_best_pt_or_says_what_it_expected(tmp_path):
    run = tmp_path / "run"
    run.mkdir()
    (run / "last.pt").write_bytes(b"")
    with pytest.raises(FileNotFoundError, match=r"without best\.pt.*holds last\.pt"):
        resolve_checkpoint(run)
    (run / "best.pt").write_bytes(b"")
    assert resolve_checkpoint(run) == run / "best.pt"
    assert resolve_checkpoint(run / "best.pt") == run / "best.pt"
    with pytest.raises(FileNotFoundError, match="no such checkpoint"):
        resolve_checkpoint(tmp_path / "nowhere.pt")


def test_checkpoints_carry_the_provenance_of_the_run_that_wrote_them(tmp_path, caplog):
    from pilerl.policies import make_actor, save_actor
    from pilerl.policies.checkpoint import read_provenance, warn_if_other_control_rate

    sensors = ["boom_angle", "bucket_angle", "drive_pressure", "telescope_pressure"]
    stats = {
        "sensors": {n: {"mean": 0.0, "std": 1.0, "min": -1.0, "max": 1.0} for n in sensors},
        "action": {"mean": [0.0] * 3, "std": [1.0] * 3, "min": [-1.0] * 3, "max": [1.0] * 3},
        "n_samples": 10,
    }
    data = tmp_path / "data"
    data.mkdir()
    (data / "index.json").write_text("{}")
    begin_run(tmp_path / "run", SETTINGS, inputs={"train_data": data}, control_hz=20.0)
    path = save_actor(tmp_path / "best.pt", make_actor("nnetv2", sensors=sensors, stats=stats))
    provenance = read_provenance(path)
    assert provenance["control_hz"] == 20.0
    assert provenance["inputs"]["train_data"] == fingerprint_path(data)
    assert provenance["packages"]["torchrl"] and "dirty" in provenance["git"]
    assert not warn_if_other_control_rate(path, 20.0)
    assert warn_if_other_control_rate(path, 3.0)
    assert "trained at 20 Hz but runs at 3 Hz" in caplog.text


def test_a_grown_curriculum_resumes_and_stays_unfinished_until_it_ends_again(tmp_path):
    growable = ["curriculum.stages.*.frames"]
    settings = {"curriculum": {"stages": [{"frames": 1000, "conditions": {"winter_c": 1.0}}]}}
    begin_run(tmp_path, settings, growable=growable)
    finish_run(tmp_path, {"frames": 1000})
    grown = {"curriculum": {"stages": [{"frames": 2000, "conditions": {"winter_c": 1.0}}]}}
    assert begin_run(tmp_path, grown, growable=growable) is False  # continue
    assert begin_run(tmp_path, grown, growable=growable) is False  # killed: still unfinished
    finish_run(tmp_path, {"frames": 2000})
    assert begin_run(tmp_path, grown, growable=growable) is True
    other = {"curriculum": {"stages": [{"frames": 2000, "conditions": {"summer": 1.0}}]}}
    with pytest.raises(RunMismatch, match=r"curriculum.stages.0.conditions.summer"):
        begin_run(tmp_path, other, growable=growable)


def test_collection_settings_count_and_evaluation_workers_do_not(tmp_path):
    settings = {"collection": {"workers": 1, "envs_per_worker": 8}, "evaluation": {"workers": 2}}
    begin_run(tmp_path, settings)
    finish_run(tmp_path, {"frames": 1})
    assert begin_run(tmp_path, {**settings, "evaluation": {"workers": 1}}) is True
    with pytest.raises(RunMismatch, match="collection.envs_per_worker: 8 -> 4"):
        begin_run(tmp_path, {**settings, "collection": {"workers": 1, "envs_per_worker": 4}})


def test_a_killed_run_record_write_leaves_nothing_behind(tmp_path):
    (tmp_path / ".run.abc123.json").write_text("{")  # what a kill mid-write leaves
    begin_run(tmp_path, SETTINGS)
    assert sorted(p.name for p in tmp_path.iterdir()) == [RunLayout.RUN_RECORD]
