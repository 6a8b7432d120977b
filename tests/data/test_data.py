"""Demonstration storage: schema, atomic store, recording, curation, replay buffers."""

from __future__ import annotations

import dataclasses
import json
import math
import multiprocessing

import numpy as np
import pytest
import torch
from tensordict import TensorDict

from pilerl.data import (
    EpisodeMeta,
    EpisodeStore,
    RecordingPlan,
    SchemaError,
    build_dataset,
    downsample_episode,
    make_episode,
    make_replay_buffer,
    record_demonstrations,
)
from pilerl.data.recorder import claim_plan, plan_description
from pilerl.sim import get_simulator, make_gym_env

SENSORS = {"boom_angle": "rad", "drive_pressure": "MPa"}
CONTROLS = ["boom", "bucket", "throttle"]


def synthetic_episode(n: int, *, start: float = 0.0, rate_hz: float = 100.0) -> TensorDict:
    rows = torch.arange(n, dtype=torch.float32) + start
    return make_episode(
        sensors={"boom_angle": rows / 100, "drive_pressure": rows},
        next_sensors={"boom_angle": (rows + 1) / 100, "drive_pressure": rows + 1},
        actions=torch.stack([torch.sin(rows), torch.cos(rows), rows * 0 + 0.5], -1),
        time_s=torch.arange(n, dtype=torch.float64) / rate_hz,
        rewards=torch.ones(n),
        terminated=True,
    )


def make_store(path, episodes) -> EpisodeStore:
    store = EpisodeStore.create(path, sensors=SENSORS, controls=CONTROLS)
    for td, success, rate in episodes:
        store.append(
            td,
            EpisodeMeta(
                rate_hz=rate,
                condition="summer",
                success=success,
                fill_fraction=0.8 if success else 0.2,
            ),
        )
    return store


def test_episode_round_trips_through_the_store(tmp_path):
    original = synthetic_episode(17)
    store = make_store(tmp_path / "ds", [(original, True, 100.0)])
    reopened = EpisodeStore.open(tmp_path / "ds")
    loaded = reopened.load(0)
    for key in original.keys(include_nested=True, leaves_only=True):
        if key != "episode":
            assert torch.equal(loaded[key], original[key]), key
    assert (loaded["episode"] == 0).all()
    meta = reopened.episodes[0]
    assert (meta.id, meta.n_samples, meta.success, meta.rate_hz) == (0, 17, True, 100.0)
    assert reopened.sensors == SENSORS and reopened.controls == CONTROLS
    assert len(store) == 1


@pytest.mark.parametrize(
    ("mutate", "message"),
    [
        (
            lambda td: td["drive_pressure"].__setitem__(3, float("nan")),
            "non-finite value in 'drive_pressure' at row 3",
        ),
        (lambda td: td["action"].__setitem__((5, 0), 1.5), "action outside \\[-1, 1\\] at row 5"),
        (lambda td: td["time_s"].__setitem__(4, 0.0), "time_s not strictly increasing at row 4"),
    ],
)
def test_bad_episodes_are_refused_and_nothing_is_written(tmp_path, mutate, message):
    store = make_store(tmp_path / "ds", [(synthetic_episode(8), True, 100.0)])
    bad = synthetic_episode(10)
    mutate(bad)
    index_before = (tmp_path / "ds" / "index.json").read_bytes()
    with pytest.raises(SchemaError, match=message):
        store.append(bad, EpisodeMeta(rate_hz=100.0))
    assert (tmp_path / "ds" / "index.json").read_bytes() == index_before
    assert len(list((tmp_path / "ds" / "episodes").iterdir())) == 1


def test_a_crash_mid_write_leaves_earlier_episodes_intact(tmp_path, monkeypatch):
    store = make_store(tmp_path / "ds", [(synthetic_episode(8), True, 100.0)])
    real_memmap = TensorDict.memmap_

    def crash_after_some_files(self, prefix=None, **kwargs):
        real_memmap(self.exclude("next"), prefix=prefix)  # part of the episode reaches disk
        raise KeyboardInterrupt("simulated crash")

    monkeypatch.setattr(TensorDict, "memmap_", crash_after_some_files)
    with pytest.raises(KeyboardInterrupt):
        store.append(synthetic_episode(9), EpisodeMeta(rate_hz=100.0))
    monkeypatch.setattr(TensorDict, "memmap_", real_memmap)

    reopened = EpisodeStore.open(tmp_path / "ds", writable=True)
    assert len(reopened) == 1
    assert reopened.load(0).batch_size == (8,)
    assert [p.name for p in (tmp_path / "ds" / "episodes").iterdir()] == ["ep_000000"]
    reopened.append(synthetic_episode(9), EpisodeMeta(rate_hz=100.0))  # and it goes on
    assert len(EpisodeStore.open(tmp_path / "ds")) == 2


def test_corrupt_or_foreign_datasets_fail_naming_the_file(tmp_path):
    make_store(tmp_path / "ds", [(synthetic_episode(8), True, 100.0)])
    index = tmp_path / "ds" / "index.json"
    data = json.loads(index.read_text())
    index.write_text(json.dumps({**data, "schema_version": 99}))
    with pytest.raises(SchemaError, match="index.json: schema_version 99"):
        EpisodeStore.open(tmp_path / "ds")
    index.write_text("{not json")
    with pytest.raises(SchemaError, match="index.json: corrupt index"):
        EpisodeStore.open(tmp_path / "ds")
    with pytest.raises(FileNotFoundError, match="not a pilerl dataset"):
        EpisodeStore.open(tmp_path / "nothing")


def test_missing_episode_files_fail_naming_the_episode(tmp_path):
    store = make_store(tmp_path / "ds", [(synthetic_episode(8), True, 100.0)])
    for f in (tmp_path / "ds" / "episodes" / "ep_000000").rglob("*.memmap"):
        f.unlink()
    with pytest.raises(SchemaError, match="ep_000000: cannot load episode"):
        store.load(0)


def test_downsampling_keeps_every_fth_row_exactly():
    episode = synthetic_episode(103)
    down = downsample_episode(episode, 25)
    assert down.batch_size == (5,)  # rows 0, 25, 50, 75, 100
    for k in range(5):
        for key in ("boom_angle", "drive_pressure", "action", "time_s"):
            assert torch.equal(down[key][k], episode[key][25 * k])
    # next = the following kept row's reading; the last keeps the episode's final next
    assert torch.equal(down["next", "drive_pressure"][1], episode["drive_pressure"][50])
    assert torch.equal(down["next", "drive_pressure"][4], episode["next", "drive_pressure"][-1])
    assert down["next", "reward"][0].item() == 25.0  # rewards of the skipped rows summed
    assert down["next", "done"].squeeze(-1).tolist() == [False] * 4 + [True]
    assert down["step"].tolist() == list(range(5))


def test_d_ii_keeps_successful_episodes_and_d_i_keeps_all(tmp_path):
    source = make_store(
        tmp_path / "raw",
        [
            (synthetic_episode(100), True, 500.0),
            (synthetic_episode(60), False, 500.0),
            (synthetic_episode(75), True, 500.0),
        ],
    )
    d_ii = build_dataset(
        source, tmp_path / "d_ii", successful_only=True, rate_hz=20.0, progress=False
    )
    d_i = build_dataset(
        source, tmp_path / "d_i", successful_only=False, rate_hz=None, progress=False
    )
    assert [m.operator["source_episode"] for m in d_ii.episodes] == [0, 2]
    assert [m.n_samples for m in d_ii.episodes] == [4, 3]  # ceil(100/25), ceil(75/25)
    assert all(m.rate_hz == 20.0 for m in d_ii.episodes)
    assert len(d_i) == 3 and d_i.n_samples == 235
    data = d_ii.to_tensordict()
    stats = d_ii.stats["sensors"]["drive_pressure"]
    assert stats["mean"] == pytest.approx(data["drive_pressure"].double().mean().item())
    assert stats["std"] == pytest.approx(data["drive_pressure"].double().std().item())
    assert EpisodeStore.open(tmp_path / "d_ii").stats == d_ii.stats  # stored with it
    with pytest.raises(ValueError, match="not a whole multiple of 30"):
        build_dataset(source, tmp_path / "bad", successful_only=False, rate_hz=30.0, progress=False)


def test_replay_buffer_samplers(tmp_path):
    store = make_store(
        tmp_path / "ds",
        [(synthetic_episode(40), True, 100.0), (synthetic_episode(40, start=1000), True, 100.0)],
    )
    data = store.to_tensordict()
    torch.manual_seed(0)
    uniform = make_replay_buffer(data, batch_size=32)
    assert uniform.sample().batch_size == (32,)
    epoch = make_replay_buffer(data, batch_size=20, sampler="without_replacement")
    seen = torch.cat([epoch.sample()["drive_pressure"].flatten() for _ in range(4)])
    assert sorted(seen.tolist()) == sorted(data["drive_pressure"].flatten().tolist())
    slices = make_replay_buffer(
        data,
        batch_size=32,
        sampler="slices",
        slice_len=8,
        storage="memmap",
        scratch_dir=tmp_path / "scratch",
    )
    batch = slices.sample().reshape(4, 8)
    for piece in batch.unbind(0):
        assert (piece["episode"] == piece["episode"][0]).all()  # one episode per slice
        assert (piece["step"].diff() == 1).all()  # contiguous
    with pytest.raises(ValueError, match="unknown sampler 'prioritised'"):
        make_replay_buffer(data, batch_size=8, sampler="prioritised")


def record(tmp_path, name, workers):
    plan = RecordingPlan(
        "pile_loader", {"condition": "summer", "control_hz": 20.0}, n_episodes=2, seed=3
    )
    env = make_gym_env("pile_loader").unwrapped  # the store declares the env's sensors
    store = EpisodeStore.create(
        tmp_path / name, sensors=env.sensor_units, controls=list(env.control_names)
    )
    record_demonstrations(store, plan, workers=workers, progress=False)
    return store


def test_recording_is_deterministic_and_independent_of_worker_count(tmp_path):
    serial, parallel = record(tmp_path, "a", workers=1), record(tmp_path, "b", workers=2)
    for i in range(2):
        a, b = serial.load(i), parallel.load(i)
        for key in a.keys(include_nested=True, leaves_only=True):
            assert torch.equal(a[key], b[key]), key
        assert serial.episodes[i].operator == parallel.episodes[i].operator
    assert serial.episodes[0].operator["style"] != serial.episodes[1].operator["style"]
    meta = serial.episodes[0]
    assert meta.condition == "summer" and meta.condition_params["ground"]["tyre_friction"] > 0
    assert not math.isnan(meta.fill_fraction)
    phases = serial.load(0)["phase"]
    assert phases[0] == 0 and (phases.diff() >= 0).all()  # approach -> fill -> finish


def test_recording_resumes_where_it_stopped(tmp_path):
    store = record(tmp_path, "a", workers=1)
    plan = RecordingPlan(
        "pile_loader", {"condition": "summer", "control_hz": 20.0}, n_episodes=3, seed=3
    )
    first_two = [store.load(i)["drive_pressure"].clone() for i in range(2)]
    new = record_demonstrations(store, plan, workers=1, progress=False)
    assert [m.id for m in new] == [2] and len(store) == 3
    assert all(torch.equal(store.load(i)["drive_pressure"], first_two[i]) for i in range(2))
    assert np.isfinite(store.load(2)["drive_pressure"].numpy()).all()


def test_extend_is_all_or_nothing(tmp_path, monkeypatch):
    store = make_store(tmp_path / "ds", [(synthetic_episode(8), True, 100.0)])
    real_memmap = TensorDict.memmap_
    calls = []

    def fail_on_second(self, prefix=None, **kwargs):
        calls.append(prefix)
        if len(calls) == 2:
            raise OSError("disk full")
        return real_memmap(self, prefix=prefix, **kwargs)

    monkeypatch.setattr(TensorDict, "memmap_", fail_on_second)
    batch = [(synthetic_episode(5), EpisodeMeta(rate_hz=100.0)) for _ in range(3)]
    with pytest.raises(OSError, match="disk full"):
        store.extend(batch)
    monkeypatch.setattr(TensorDict, "memmap_", real_memmap)
    assert len(EpisodeStore.open(tmp_path / "ds")) == 1 and len(store) == 1
    assert [p.name for p in (tmp_path / "ds" / "episodes").iterdir()] == ["ep_000000"]


def test_reopening_with_other_sensors_is_refused(tmp_path):
    make_store(tmp_path / "ds", [(synthetic_episode(8), True, 100.0)])
    with pytest.raises(SchemaError, match="existing dataset has sensors"):
        EpisodeStore.create(
            tmp_path / "ds", sensors={"boom_angle": "deg"}, controls=CONTROLS, exist_ok=True
        )


def test_resuming_a_recording_with_another_plan_is_refused(tmp_path):
    store = EpisodeStore.create(tmp_path / "demos", sensors=SENSORS, controls=CONTROLS)
    plan = RecordingPlan("pile_loader", {"condition": "summer", "control_hz": 20.0}, 3, seed=1)
    claim_plan(store, plan)
    claim_plan(EpisodeStore.open(tmp_path / "demos"), dataclasses.replace(plan, n_episodes=9))
    for changed in (
        dataclasses.replace(plan, env_kwargs={"condition": "winter_c", "control_hz": 20.0}),
        dataclasses.replace(plan, env_kwargs={"condition": "summer", "control_hz": 500.0}),
        dataclasses.replace(plan, seed=2),
        dataclasses.replace(plan, expert={"trigger_sensor": "telescope_pressure"}),
    ):
        with pytest.raises(SchemaError, match="was recorded with another plan"):
            claim_plan(EpisodeStore.open(tmp_path / "demos"), changed)
    assert EpisodeStore.open(tmp_path / "demos").index_entry("recording_plan")["seed"] == 1


def test_a_store_recorded_by_an_earlier_expert_is_not_resumed(tmp_path):
    """The pile loader's expert changed its default behaviour (expert_revision 1, session
    33): a store whose plan was written before revisions existed (revision 0) is refused;
    a simulator whose expert never changed (toy cart, revision 0) still resumes one."""
    assert get_simulator("pile_loader").expert_revision == 1
    for simulator, resumes in (("pile_loader", False), ("toy_cart", True)):
        store = EpisodeStore.create(tmp_path / simulator, sensors=SENSORS, controls=CONTROLS)
        plan = RecordingPlan(simulator, {"control_hz": 20.0}, n_episodes=3, seed=1)
        before_revisions = plan_description(plan)
        del before_revisions["expert_revision"]
        store.claim_index_entry("recording_plan", before_revisions)
        if resumes:
            claim_plan(EpisodeStore.open(tmp_path / simulator), plan)
        else:
            refused = (
                r"expert_revision': 0}, not {'expert_revision': 1}\) "
                r"\(the simulator's scripted expert has changed its default behaviour"
            )
            with pytest.raises(SchemaError, match=refused):
                claim_plan(EpisodeStore.open(tmp_path / simulator), plan)


def test_two_recorders_into_one_dataset_both_finish_without_duplicates(tmp_path):
    """Two processes record the same plan into one directory at once (issue 13)."""
    env = make_gym_env("pile_loader").unwrapped
    root = tmp_path / "demos"
    plan = RecordingPlan("pile_loader", {"control_hz": 20.0}, n_episodes=3, seed=4)
    EpisodeStore.create(root, sensors=env.sensor_units, controls=list(env.control_names))

    def record() -> None:
        store = EpisodeStore.open(root)
        record_demonstrations(store, plan, workers=1, progress=False)

    context = multiprocessing.get_context("fork")
    recorders = [context.Process(target=record) for _ in range(2)]
    for recorder in recorders:
        recorder.start()
    for recorder in recorders:
        recorder.join(timeout=300)
    assert [r.exitcode for r in recorders] == [0, 0]
    store = EpisodeStore.open(root)
    assert sorted(m.seed for m in store.episodes) == [plan.episode_seed(i) for i in range(3)]
    assert [m.id for m in store.episodes] == [0, 1, 2]
    assert all(store.load(i).batch_size[0] == m.n_samples for i, m in enumerate(store.episodes))
