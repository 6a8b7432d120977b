"""The paper's Fig. 3 (controls vs a demonstration) and Fig. 5 (attention masks per phase)."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from pilerl_pile_loader.operator import PHASES as EXPERT_PHASES
from tensordict import TensorDict

from pilerl.data import EpisodeMeta, EpisodeStore, make_episode
from pilerl.evaluation.attention_masks import phase_masks, plot_attention_masks
from pilerl.evaluation.control_signals import (
    SCOOP_PHASES,
    compare_controls,
    plot_control_signals,
    run_open_loop,
    scoop_phases,
)
from pilerl.policies import INPUT_MASK_KEY, OUTPUT_MASK_KEY, make_actor
from pilerl.sim import get_simulator
from pilerl.training.bc import validation_loss

SENSORS = ["boom_angle", "bucket_angle", "drive_pressure", "telescope_pressure"]
UNITS = {name: "rad" if name.endswith("angle") else "MPa" for name in SENSORS}
CONTROLS = ["boom", "bucket", "throttle"]
OPERATOR_PHASES = get_simulator("pile_loader").expert_phases()  # what ``phase`` indexes
RATE_HZ = 20.0
MIN_FIGURE_BYTES = 10_000  # a blank 110-dpi PNG of these sizes is far smaller than a plot
STATS = {
    "n_samples": 100,
    "sensors": {
        "boom_angle": {"mean": -0.3, "std": 0.2},
        "bucket_angle": {"mean": 0.4, "std": 0.3},
        "drive_pressure": {"mean": 12.0, "std": 5.0},
        "telescope_pressure": {"mean": 1.5, "std": 0.7},
    },
    "action": {"mean": [0.0] * 3, "std": [0.5] * 3, "min": [-1.0] * 3, "max": [1.0] * 3},
}


def scoop_episode(operator_phases: list[int], *, seed: int) -> TensorDict:
    """A tiny scripted-looking episode at 20 Hz with the operator's phase per row."""
    n = len(operator_phases)
    generator = torch.Generator().manual_seed(seed)
    readings = {
        name: STATS["sensors"][name]["mean"]
        + STATS["sensors"][name]["std"] * torch.randn(n, generator=generator)
        for name in SENSORS
    }
    episode = make_episode(
        sensors=readings,
        next_sensors=readings,
        actions=torch.rand(n, 3, generator=generator) * 2 - 1,
        time_s=torch.arange(n, dtype=torch.float64) / RATE_HZ,
        terminated=True,
    )
    episode["phase"] = torch.tensor(operator_phases, dtype=torch.int64)
    return episode


def operator_phases(approach: int, fill: int, finish: int) -> list[int]:
    return [0] * approach + [1] * fill + [2] * finish


def dannet(seed: int):
    torch.manual_seed(seed)
    return make_actor("dannet", sensors=SENSORS, stats=STATS)


def nnetv2(seed: int):
    torch.manual_seed(seed)
    return make_actor("nnetv2", sensors=SENSORS, stats=STATS)


def test_scoop_phases_follow_the_operator_with_an_impact_window() -> None:
    assert OPERATOR_PHASES == EXPERT_PHASES == ("approach", "fill", "finish")  # as below
    episode = scoop_episode(operator_phases(3, 6, 2), seed=0)
    # 20 Hz: fill starts at 0.15 s; a 0.12 s window holds rows at +0, +0.05, +0.10 s
    phases = scoop_phases(episode, impact_window_s=0.12)
    names = [SCOOP_PHASES[p] for p in phases]
    assert names == ["approach"] * 3 + ["impact"] * 3 + ["filling"] * 3 + ["finished"] * 2
    default = [SCOOP_PHASES[p] for p in scoop_phases(episode)]  # 0.5 s: the whole fill
    assert default == ["approach"] * 3 + ["impact"] * 6 + ["finished"] * 2


def test_scoop_phases_need_the_operator_phase() -> None:
    episode = scoop_episode(operator_phases(2, 2, 1), seed=0)
    with pytest.raises(ValueError, match="demo 7: no per-row 'phase'"):
        scoop_phases(episode.exclude("phase"), where="demo 7")
    episode["phase"][3] = 5
    with pytest.raises(ValueError, match="'phase' is 5 at row 3"):
        scoop_phases(episode)


def test_an_actor_matches_the_demonstration_it_generated(tmp_path) -> None:
    teacher, other = dannet(seed=1), nnetv2(seed=2)
    episode = scoop_episode(operator_phases(10, 25, 5), seed=3)
    episode["action"] = run_open_loop(teacher, episode)["action"]
    store = EpisodeStore.create(tmp_path / "demos", sensors=UNITS, controls=CONTROLS)
    store.append(episode, EpisodeMeta(rate_hz=RATE_HZ))
    demonstration = store.load(0)
    teacher.train()  # dropout on: the comparison must still run in eval mode
    result = compare_controls(
        demonstration, {"teacher": teacher, "other": other}, controls=store.controls
    )
    assert teacher.training  # its mode is restored
    assert set(result.mse["teacher"]) == {*CONTROLS, "all"}
    assert all(value < 1e-10 for value in result.mse["teacher"].values())
    assert min(result.mse["other"][c] for c in CONTROLS) > 1e-3
    # "all" is exactly the behaviour-cloning validation loss on this episode
    assert result.mse["other"]["all"] == pytest.approx(
        validation_loss(other, demonstration.to_tensordict()), rel=1e-5
    )
    np.testing.assert_allclose(result.predictions["teacher"], result.demonstration, atol=1e-6)
    assert [SCOOP_PHASES[p] for p in result.phases[[0, 10, 20, 35]]] == [
        "approach",
        "impact",
        "filling",
        "finished",
    ]
    path = plot_control_signals(result, tmp_path / "fig3.png", title="demo 0")
    assert path.is_file() and path.stat().st_size > MIN_FIGURE_BYTES


def test_comparison_names_a_missing_sensor() -> None:
    episode = scoop_episode(operator_phases(2, 2, 1), seed=0).exclude("telescope_pressure")
    with pytest.raises(ValueError, match=r"demo 4: has no readings of \['telescope_pressure'\]"):
        compare_controls(episode, {"nnetv2": nnetv2(seed=0)}, where="demo 4")


def test_masks_averaged_per_phase_equal_hand_computed_means(tmp_path) -> None:
    actor = dannet(seed=4)
    episodes = [
        scoop_episode(operator_phases(4, 16, 3), seed=5),
        # never reaches finish; fill starts at 0.4 s, where 0.6 s - 0.4 s < 0.2 s in float64
        scoop_episode(operator_phases(8, 12, 0), seed=6),
    ]
    masks = phase_masks(actor, episodes, controls=CONTROLS, impact_window_s=0.2)

    # by hand: one row at a time, pooled over the episodes; impact = first 4 fill rows
    rows = {phase: [] for phase in SCOOP_PHASES}
    actor.eval()
    for episode in episodes:
        seen_fill = 0
        for row in range(episode.batch_size[0]):
            out = actor(episode[row].select(*SENSORS).to_tensordict())
            operator_phase = OPERATOR_PHASES[int(episode["phase"][row])]
            if operator_phase == "approach":
                phase = "approach"
            elif operator_phase == "finish":
                phase = "finished"
            else:
                phase = "impact" if seen_fill < 4 else "filling"
                seen_fill += 1
            rows[phase].append(
                torch.cat([out[INPUT_MASK_KEY], out[OUTPUT_MASK_KEY]]).detach().numpy()
            )
    expected_counts = {"approach": 12, "impact": 8, "filling": 20, "finished": 3}
    assert dict(zip(SCOOP_PHASES, masks.n_rows.tolist(), strict=True)) == expected_counts
    for p, phase in enumerate(SCOOP_PHASES):
        by_hand = np.mean(rows[phase], axis=0)
        np.testing.assert_allclose(masks.input_mask[p], by_hand[:4], atol=1e-6)
        np.testing.assert_allclose(masks.output_mask[p], by_hand[4:], atol=1e-6)
    table = masks.input_table()
    assert list(table) == list(SCOOP_PHASES) and list(table["impact"]) == SENSORS
    assert table["filling"]["drive_pressure"] == pytest.approx(masks.input_mask[2, 2])
    np.testing.assert_allclose(masks.input_mask.sum(1), 1.0, atol=1e-5)  # softmax weights
    assert "| finished | 3 |" in masks.to_markdown()

    path = plot_attention_masks(masks, tmp_path / "fig5.png", episode=1, title="synthetic")
    assert path.is_file() and path.stat().st_size > MIN_FIGURE_BYTES


def test_an_empty_phase_has_no_mean() -> None:
    masks = phase_masks(dannet(seed=0), [scoop_episode(operator_phases(5, 5, 0), seed=1)])
    assert masks.n_rows[SCOOP_PHASES.index("finished")] == 0
    assert np.isnan(masks.input_mask[SCOOP_PHASES.index("finished")]).all()
    assert not np.isnan(masks.input_mask[SCOOP_PHASES.index("approach")]).any()


def test_annet_has_an_input_mask_only_and_plots(tmp_path) -> None:
    torch.manual_seed(0)
    annet = make_actor("annet", sensors=SENSORS, stats=STATS)
    masks = phase_masks(annet, [scoop_episode(operator_phases(5, 12, 2), seed=1)])
    assert masks.output_mask is None and masks.output_table() is None
    assert masks.input_mask.shape == (len(SCOOP_PHASES), len(SENSORS))
    assert "m_u" not in masks.to_markdown()
    path = plot_attention_masks(masks, tmp_path / "fig5_annet.png")
    assert path.is_file() and path.stat().st_size > MIN_FIGURE_BYTES
    with pytest.raises(IndexError, match="episode 1 not in 0..0"):
        plot_attention_masks(masks, tmp_path / "none.png", episode=1)


def test_an_actor_without_attention_is_refused() -> None:
    episode = scoop_episode(operator_phases(2, 2, 1), seed=0)
    with pytest.raises(ValueError, match="the 'nnetv2' actor has no attention"):
        phase_masks(nnetv2(seed=0), [episode])
