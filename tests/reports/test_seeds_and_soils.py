"""Seeds as an axis of closed-loop results: exact tests, seed-aware claims, cross-soil tau."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest
import yaml

from pilerl.reports import paper_numbers
from pilerl.reports.comparisons import compare, threshold
from pilerl.reports.cross_soil import EVERY_CONDITION, controller_of, soil_agreement, soil_cells
from pilerl.reports.paper import build_report, check_claim
from pilerl.reports.results import Cell, closed_loop_cells, job_results
from pilerl.reports.stats import fisher_greater_p, kendall_tau_b, sign_flip_p, welch_less_p

# --- exact tests against hand-computed values ---------------------------------------------


def test_sign_flip_test_counts_every_sign_pattern():
    assert sign_flip_p([1, 1, 1]) == 1 / 8  # only all-positive reaches 3
    # sums of three +-1: 3, 1, -1, -3 with 1, 3, 3, 1 patterns; P(S >= 1) = 4/8
    assert sign_flip_p([1, 1, -1]) == 0.5
    assert sign_flip_p([0, 0, 1]) == 0.5  # ties carry no sign
    assert sign_flip_p([]) == 1.0 and sign_flip_p([0, 0]) == 1.0
    # McNemar exact: 10 discordant pairs all for A: 2^-10
    assert sign_flip_p([1] * 10 + [0] * 30) == 1 / 1024
    # magnitudes 2 and 1: sums 3, 1, -1, -3 one pattern each; observed 2 - 1 = 1
    assert sign_flip_p([2, -1]) == 0.5
    assert sign_flip_p([2, 1]) == 0.25


def test_fisher_exact_matches_the_hypergeometric_tail():
    # 8/10 vs 2/10: P(X >= 8), X ~ Hypergeometric(20, 10 successes, 10 drawn)
    expected = (45 * 45 + 10 * 10 + 1) / math.comb(20, 10)
    assert fisher_greater_p(8, 10, 2, 10) == pytest.approx(expected)
    assert fisher_greater_p(2, 10, 8, 10) > 0.99
    with pytest.raises(ValueError, match="11 successes of 10"):
        fisher_greater_p(11, 10, 0, 10)


def test_kendall_tau_b_by_hand_and_against_scipy():
    # 6 pairs, 5 concordant and 1 discordant (2 and 3 swapped): (5 - 1) / 6
    assert kendall_tau_b([1, 2, 3, 4], [1, 3, 2, 4]) == pytest.approx(4 / 6)
    # one tie in each: 4 concordant, 0 discordant, tau-b = 4 / sqrt(5 * 5)
    assert kendall_tau_b([1, 1, 2, 3], [1, 2, 2, 3]) == pytest.approx(0.8)
    assert kendall_tau_b([1, 2, 3], [3, 2, 1]) == pytest.approx(-1.0)
    assert math.isnan(kendall_tau_b([0.5, 0.5], [0.1, 0.2]))
    scipy_stats = pytest.importorskip("scipy.stats")
    x, y = [0.1, 0.4, 0.4, 0.9, 0.3, 0.0], [0.2, 0.5, 0.1, 0.9, 0.3, 0.3]
    assert kendall_tau_b(x, y) == pytest.approx(scipy_stats.kendalltau(x, y).statistic)
    with pytest.raises(ValueError, match="at least 2"):
        kendall_tau_b([1], [1])


def test_welch_by_hand_and_against_scipy():
    # equal spreads and sizes: t = -0.01 / sqrt(2 * 0.01**2 / 8) = -2, df = 14
    scipy_stats = pytest.importorskip("scipy.stats")
    assert welch_less_p(0.05, 0.01, 8, 0.06, 0.01, 8) == pytest.approx(scipy_stats.t.cdf(-2.0, 14))
    # unequal spreads and sizes: the Welch-Satterthwaite degrees of freedom
    expected = scipy_stats.ttest_ind_from_stats(
        0.018, 0.0015, 30, 0.0182, 0.0013, 12, equal_var=False, alternative="less"
    ).pvalue
    assert welch_less_p(0.018, 0.0015, 30, 0.0182, 0.0013, 12) == pytest.approx(expected)
    assert welch_less_p(0.06, 0.01, 8, 0.05, 0.01, 8) > 0.95  # the other way round
    assert welch_less_p(1.0, 0.0, 3, 2.0, 0.0, 3) == 0.0  # no spread at all
    with pytest.raises(ValueError, match="group a needs at least 2"):
        welch_less_p(0.05, 0.01, 1, 0.06, 0.01, 8)


# --- seed-aware claims ----------------------------------------------------------------------


def cell(per_seed_wins: dict[int, list[bool]], conditions=("winter_a",)) -> Cell:
    """A cell whose seeds each ran the same starts 0..n-1 in ``conditions``."""
    outcomes = {
        (seed, condition, start): ok
        for seed, wins in per_seed_wins.items()
        for condition in conditions
        for start, ok in enumerate(wins)
    }
    per_seed = {
        seed: (sum(wins) * len(conditions), len(wins) * len(conditions))
        for seed, wins in per_seed_wins.items()
    }
    return Cell(
        successes=sum(s for s, _ in per_seed.values()),
        episodes=sum(n for _, n in per_seed.values()),
        seeds=len(per_seed),
        per_seed=per_seed,
        outcomes=outcomes,
    )


def test_a_beats_b_is_a_paired_test_over_seeds_and_starts():
    a = cell({0: [True] * 10, 1: [True] * 10, 2: [True] * 5 + [False] * 5})
    b = cell({0: [False] * 10, 1: [True] * 10, 2: [False] * 10})
    test = compare(a, b)
    # discordant pairs: seed 0 all 10, seed 2 the first 5; all for A
    assert test.method == "paired" and test.pairs == 30
    assert (test.a_ahead, test.b_ahead) == (15, 0)
    assert test.p_value == 2**-15 and test.significant
    assert (test.seeds_ahead, test.seeds) == (2, 3)
    assert not compare(b, a).significant
    # the same rates on unpaired episodes: only seed 1 shares starts with b, all ties
    shifted = Cell(
        a.successes,
        a.episodes,
        3,
        per_seed=a.per_seed,
        outcomes={(seed + 10, c, start): ok for (seed, c, start), ok in a.outcomes.items()},
    )
    assert compare(shifted, b).method == "unpaired"


def test_a_small_paired_lead_is_not_enough():
    a = cell({0: [True, True, False, False], 1: [True, False, False, False]})
    b = cell({0: [False, True, False, False], 1: [False, False, False, False]})
    test = compare(a, b)
    assert (test.a_ahead, test.b_ahead) == (2, 0) and test.p_value == 0.25
    assert not test.significant  # 38% vs 13% on 8 starts: not shown


def test_summer_against_the_winter_days_pairs_each_start():
    summer = cell({0: [True] * 8}, conditions=("summer",))
    winter = cell({0: [False] * 8}, conditions=("winter_a", "winter_b", "winter_c", "winter_d"))
    test = compare(summer, winter)
    assert test.method == "paired" and test.pairs == 8 and test.p_value == 2**-8
    half = cell({0: [True, False] * 4}, conditions=("winter_a", "winter_b"))
    assert compare(summer, half).pairs == 8


def test_threshold_claims_need_the_interval_and_every_seed():
    low = cell({0: [False] * 40, 1: [False] * 40, 2: [False] * 38 + [True] * 2})
    assert threshold(low, below=0.2).holds
    # pooled 10/120 is low, but one seed reaches 25%: not every seed stays below 20%
    mixed = cell({0: [False] * 40, 1: [False] * 40, 2: [True] * 10 + [False] * 30})
    check = threshold(mixed, below=0.2)
    assert check.interval_side and check.seeds_against == 1 and not check.holds
    high = cell({0: [True] * 40, 1: [True] * 40, 2: [True] * 39 + [False]})
    assert threshold(high, at_least=0.8).holds
    few = cell({0: [True] * 5})  # 5/5: the interval reaches down to 57%
    assert not threshold(few, at_least=0.8).holds
    with pytest.raises(ValueError, match="exactly one"):
        threshold(few)


def test_claims_use_the_seed_aware_tests():
    key_a, key_b = ("dannet", "s_pt", "d_ii", "winter"), ("nnetv2", "s_pt", "d_ii", "winter")
    cells = {
        key_a: cell({s: [True] * 9 + [False] for s in range(3)}),
        key_b: cell({s: [False] * 9 + [True] for s in range(3)}),
    }
    claim = paper_numbers.Claim("DANNet beats NNetV2", higher=((key_a, key_b),))
    ((holds, evidence),) = check_claim(claim, cells)
    assert holds and "paired over 30 seeded starts" in evidence and "ahead on 3 of 3" in evidence
    below = paper_numbers.Claim("NNetV2 fails", each=(key_b,), below=0.2)
    ((holds, evidence),) = check_claim(below, cells)
    assert not holds and "interval not below 20%" in evidence


# --- sweeps with seeds on disk ------------------------------------------------------------


def seeded_job(
    root: Path,
    n: int,
    *,
    policy: str,
    seed: int,
    wins: dict[str, list[bool]],
    soil=None,
    checkpoint=None,
) -> Path:
    """A finished train_bc job (or, with ``soil``, an evaluate job) with episodes.csv."""
    job = root / str(n)
    evaluation = job if soil else job / "evaluation"
    (job / ".hydra").mkdir(parents=True)
    evaluation.mkdir(exist_ok=True)
    config = {
        "policy": {"name": policy},
        "train_data": "data/datasets/d_ii_summer",
        "seed": seed,
        "epochs": 150,
        "gradient_steps": 5000,
        "evaluation": {"episodes": 4, "conditions": list(wins), "seed": 1},
    }
    if soil:
        config = {"checkpoint": checkpoint, "name": None, "env": {"soil": soil}}
    hydra = {"hydra": {"runtime": {"choices": {"sensors": "s_pt", "policy": policy}}}}
    (job / ".hydra" / "config.yaml").write_text(yaml.safe_dump(config))
    (job / ".hydra" / "hydra.yaml").write_text(yaml.safe_dump(hydra))
    lines = ["controller,condition,episode,seed,success"]
    summary = {}
    for condition, outcomes in wins.items():
        lines += [f"{policy},{condition},{i},{1 + i},{ok}" for i, ok in enumerate(outcomes)]
        summary[condition] = {"successes": sum(outcomes), "episodes": len(outcomes)}
    winter = [c for c in wins if c.startswith("winter_")]
    if len(winter) > 1:
        summary["winter"] = {
            "successes": sum(sum(wins[c]) for c in winter),
            "episodes": sum(len(wins[c]) for c in winter),
        }
    (evaluation / "episodes.csv").write_text("\n".join(lines) + "\n")
    (evaluation / "summary.json").write_text(json.dumps(summary))
    return job


def test_cells_keep_each_seed_and_each_condition(tmp_path):
    sweep = tmp_path / "exp"
    for seed, a in enumerate(([True] * 4, [True, True, False, False], [False] * 4)):
        seeded_job(sweep, seed, policy="rf", seed=seed, wins={"winter_a": a, "winter_c": a})
    cells, finished, _ = closed_loop_cells(sweep)
    winter = cells[("rf", "s_pt", "d_ii", "winter")]
    assert (winter.successes, winter.episodes, winter.seeds) == (12, 24, 3)
    assert winter.seed_rates == {0: 1.0, 1: 0.5, 2: 0.0} and winter.seed_spread == (0.0, 1.0)
    assert len(winter.outcomes) == 24 and winter.outcomes[(1, "winter_c", 3)] is False
    assert cells[("rf", "s_pt", "d_ii", "winter_a")].episodes == 12
    # the same seed twice in one cell is refused, naming the jobs
    seeded_job(sweep, 3, policy="rf", seed=1, wins={"winter_a": [True]})
    with pytest.raises(ValueError, match="training seed 1 appears in several jobs"):
        closed_loop_cells(sweep)


def test_report_rows_show_the_seed_spread_and_every_condition(tmp_path):
    sweep = tmp_path / "exp3"
    wins = {
        "winter_a": [True] * 4,
        "winter_b": [True] * 4,
        "winter_c": [True] * 4,
        "winter_d": [True] * 4,
        "wet_clay": [False] * 4,
        "dry_sand": [True] * 4,
    }
    for seed in range(3):
        seeded_job(sweep, seed, policy="dannet", seed=seed, wins=wins)
    poor = dict.fromkeys(wins, [False] * 4) | {"winter_b": [True, False, False, False]}
    for seed in range(3):
        seeded_job(sweep, 3 + seed, policy="nnetv2", seed=seed, wins=poor)
    markdown, _ = build_report(out_dir=tmp_path / "report", exp3=sweep)
    text = markdown.read_text()
    # DANNet 48/48 in winter, NNetV2 3/48: the paper's 100% vs 0% with p_t on D_II
    assert "| 100% | 48/48 | 93%–100% | agrees | not recorded | yes | 100% (3 seeds) |" in text
    assert "| 6% | 3/48 | 2%–17% | sim higher | not recorded | yes | 6% (3 seeds) |" in text
    row = next(
        line for line in text.splitlines() if line.startswith("| NNetV2 | + p_t | D_II | 3 |")
    )
    # winter_a .. winter_d, wet_clay, dry_sand, winter pooled; [lowest-highest seed]
    assert row.endswith(
        "| 0% [0%–0%] | 25% [25%–25%] | 0% [0%–0%] | 0% [0%–0%] | 0% [0%–0%] | 0% [0%–0%] "
        "| 6% [6%–6%] |"
    )
    claim = next(line for line in text.splitlines() if "even on D_II" in line)
    assert "paired over 48 seeded starts × seeds (45 vs 0 better)" in claim
    assert "p=2.84e-14" in claim  # 2^-45
    assert "| holds in part |" in claim  # ANNet not run


def test_cross_soil_report_gives_tau_and_the_gap_per_controller(tmp_path):
    train = tmp_path / "train"
    rates = {"rf": (4, 3), "nnetv2": (2, 2), "dannet": (3, 4)}  # heightfield, particles wins
    n = 0
    for policy, (hf, pt) in rates.items():
        run = seeded_job(train, n, policy=policy, seed=0, wins={"summer": [True]})
        for soil, k in (("heightfield", hf), ("particles", pt)):
            wins = [True] * k + [False] * (4 - k)
            seeded_job(
                tmp_path / "soils",
                n,
                policy=policy,
                seed=0,
                soil=soil,
                checkpoint=str(run / "best.pt"),
                wins={"summer": wins, "wet_clay": wins},
            )
            n += 1
    cells = soil_cells(tmp_path / "soils")
    assert set(cells.by_soil) == {"heightfield", "particles"}
    agreement = soil_agreement(cells, ("heightfield", "particles"))
    assert agreement.test == EVERY_CONDITION
    assert [c[0] for c in agreement.controllers] == ["dannet", "nnetv2", "rf"]
    assert agreement.rates == [(0.75, 1.0), (0.5, 0.5), (1.0, 0.75)]
    assert agreement.tau == pytest.approx(1 / 3)  # 2 concordant, 1 discordant of 3
    assert agreement.gaps == [-0.25, 0.0, 0.25] and not agreement.meets_target
    markdown, _ = build_report(out_dir=tmp_path / "report", cross_soil=tmp_path / "soils")
    text = markdown.read_text()
    assert "| every condition | 3 | 0.33 | 25 points | no |" in text
    assert "| RF | + p_t | D_II | 100% | 75% | +25 points |" in text
    assert "Soil model `particles`:" in text and "| wet_clay |" in text


def soil_jobs(
    root: Path, n: int, *, policy: str, seed: int, wins: dict[str, dict[str, list[bool]]]
) -> list[Path]:
    """Training job ``n`` under ``root / "train"`` and, per soil of ``wins``, its evaluate
    job in that soil's own sweep ``root / soil`` (``wins[soil]``: condition -> outcomes)."""
    run = seeded_job(root / "train", n, policy=policy, seed=seed, wins={"summer": [True]})
    checkpoint = str(run / "best.pt")
    return [
        seeded_job(
            root / soil, n, policy=policy, seed=seed, soil=soil, checkpoint=checkpoint, wins=w
        )
        for soil, w in wins.items()
    ]


def outcomes(successes: int, episodes: int = 4) -> list[bool]:
    return [True] * successes + [False] * (episodes - successes)


def test_soils_in_separate_sweeps_pool_only_the_conditions_both_evaluated(tmp_path):
    # heightfield on summer and wet_clay, particles (slower) on summer only, each in its
    # own sweep: 'every condition' must compare summer with summer, not wet_clay too
    rates = {"rf": (4, 0, 3), "dannet": (1, 4, 2)}  # heightfield summer, wet_clay; particles
    for n, (policy, (hf_summer, hf_clay, pt_summer)) in enumerate(rates.items()):
        heightfield = {"summer": outcomes(hf_summer), "wet_clay": outcomes(hf_clay)}
        wins = {"heightfield": heightfield, "particles": {"summer": outcomes(pt_summer)}}
        soil_jobs(tmp_path, n, policy=policy, seed=0, wins=wins)
    cells = soil_cells([tmp_path / "heightfield", tmp_path / "particles"])
    assert cells.pooled_conditions == ("summer",) and len(cells.finished) == 4
    agreement = soil_agreement(cells, ("heightfield", "particles"))
    # pooled over summer only: rf 4/4 vs 3/4, dannet 1/4 vs 2/4; with wet_clay the
    # heightfield would rank dannet (5/8) above rf (4/8) and tau would flip sign
    assert agreement.rates == [(0.25, 0.5), (1.0, 0.75)]
    assert agreement.tau == pytest.approx(1.0)
    markdown, _ = build_report(
        out_dir=tmp_path / "report", cross_soil=[tmp_path / "heightfield", tmp_path / "particles"]
    )
    text = markdown.read_text()
    assert "'every condition' pools the conditions every job evaluated: summer." in text
    assert "| every condition | 2 | 1.00 | 25 points | no |" in text


def test_a_group_is_compared_across_soils_only_where_it_pools_the_same_conditions(tmp_path):
    # heightfield on winter A-D, particles on winter C alone: both have a 'winter' test
    # (particles' is winter C), which must not be compared; winter C itself is
    days = ("winter_a", "winter_b", "winter_c", "winter_d")
    for n, (policy, c_wins) in enumerate({"rf": 4, "dannet": 1}.items()):
        hf = {day: outcomes(c_wins) for day in days}
        hf["winter_a"] = outcomes(4 - c_wins)  # ranks A-D the other way
        wins = {"heightfield": hf, "particles": {"winter_c": hf["winter_c"]}}
        soil_jobs(tmp_path, n, policy=policy, seed=0, wins=wins)
    sweeps = [tmp_path / "heightfield", tmp_path / "particles"]
    cells = soil_cells(sweeps)
    pair = ("heightfield", "particles")
    assert cells.members["heightfield"]["winter"] == {days}
    assert cells.members["particles"]["winter"] == {("winter_c",)}
    assert soil_agreement(cells, pair, "winter_c").tau == pytest.approx(1.0)
    with pytest.raises(ValueError, match="test 'winter' pools other conditions on each soil"):
        soil_agreement(cells, pair, "winter")
    text = build_report(out_dir=tmp_path / "report", cross_soil=sweeps)[0].read_text()
    assert "| winter_c | 2 | 1.00 | 0 points | yes |" in text
    assert (
        "Not compared: test 'winter' pools other conditions on each soil (heightfield: "
        "winter_a, winter_b, winter_c, winter_d; particles: winter_c)" in text
    )
    assert "\n| winter | 2 |" not in text


def test_soils_without_a_shared_condition_are_reported_not_crashed(tmp_path):
    for n, policy in enumerate(("rf", "dannet")):
        wins = {"heightfield": {"summer": [True, False]}, "particles": {"winter_c": [True, False]}}
        soil_jobs(tmp_path, n, policy=policy, seed=0, wins=wins)
    sweeps = [tmp_path / "heightfield", tmp_path / "particles"]
    cells = soil_cells(sweeps)
    assert cells.pooled_conditions == ()
    assert not any(k[3] == EVERY_CONDITION for k in cells.by_soil["heightfield"])
    text = build_report(out_dir=tmp_path / "report", cross_soil=sweeps)[0].read_text()
    assert "every job evaluated: none (so no such column)." in text
    assert "Fewer than two controllers on both soils: no rank agreement." in text
    # a mistyped sweep directory is refused before anything is written
    with pytest.raises(FileNotFoundError, match="no_such_sweep: no such sweep directory"):
        build_report(out_dir=tmp_path / "fresh", cross_soil=[sweeps[0], tmp_path / "no_such_sweep"])
    assert not (tmp_path / "fresh").exists()


def test_mean_fill_ranks_controllers_where_success_ties(tmp_path):
    # particles: every controller fails (success tau undefined) but fills differ; the
    # fill tau compares the rankings the soils' fills give, episode-weighted over seeds
    fills = {"rf": ((0.9, 0.8), 0.30), "nnetv2": ((0.5, 0.5), 0.10), "dannet": ((0.7, 0.7), 0.20)}
    n = 0
    for policy, (hf_fills, pt_fill) in fills.items():
        for seed, hf_fill in enumerate(hf_fills):
            wins = {"heightfield": {"summer": [True] * 2}, "particles": {"summer": [False] * 2}}
            jobs = soil_jobs(tmp_path, n, policy=policy, seed=seed, wins=wins)
            for job, fill in zip(jobs, (hf_fill, pt_fill), strict=True):
                summary = json.loads((job / "summary.json").read_text())
                summary["summer"]["fill_mean"] = fill
                (job / "summary.json").write_text(json.dumps(summary))
            n += 1
    sweeps = [tmp_path / "heightfield", tmp_path / "particles"]
    agreement = soil_agreement(soil_cells(sweeps), ("heightfield", "particles"))
    assert math.isnan(agreement.tau)
    assert [c[0] for c in agreement.controllers] == ["dannet", "nnetv2", "rf"]
    assert agreement.fills == [(0.7, 0.2), (0.5, 0.1), (pytest.approx(0.85), 0.3)]
    assert agreement.fill_tau == pytest.approx(1.0)
    text = build_report(out_dir=tmp_path / "report", cross_soil=sweeps)[0].read_text()
    assert "| no (τ undefined) | 1.00 |" in text
    assert "| RF | + p_t | D_II | 100% | 0% | +100 points | 0.85 | 0.30 |" in text


def test_a_repeated_seed_is_refused_naming_the_cell_the_seed_and_the_jobs(tmp_path):
    # a sweep run twice into one tree: two finished jobs of DANNet seed 2, same outcomes
    sweep = tmp_path / "exp"
    for n in (0, 1):
        seeded_job(sweep, n, policy="dannet", seed=2, wins={"summer": [True, False]})
    with pytest.raises(ValueError) as refused:
        closed_loop_cells(sweep)
    message = str(refused.value)
    assert "cell dannet / s_pt / d_ii / summer" in message
    assert "training seed 2 appears in several jobs" in message
    assert str(sweep / "0") in message and str(sweep / "1") in message
    assert "remove or move the job that should not count" in message
    # the cross-soil pooling names the soil too
    for n in (0, 1):
        seeded_job(tmp_path / "soils", n, policy="rf", seed=0, soil="particles", wins={})
    for n in (0, 1):  # two evaluate jobs of one checkpoint on one soil
        job = tmp_path / "soils" / str(n)
        summary = {"summer": {"successes": 1, "episodes": 1}}
        (job / "summary.json").write_text(json.dumps(summary))
    with pytest.raises(ValueError, match="cell particles / scripted / summer: training seed 0"):
        soil_cells(tmp_path / "soils")


def test_cross_soil_tau_is_undefined_with_its_reason_when_every_controller_ties(tmp_path):
    train = tmp_path / "train"
    for n, policy in enumerate(("rf", "dannet")):  # both 4/4 on both soils: no ranking
        run = seeded_job(train, n, policy=policy, seed=0, wins={"summer": [True]})
        for k, soil in enumerate(("heightfield", "particles")):
            seeded_job(
                tmp_path / "soils",
                2 * n + k,
                policy=policy,
                seed=0,
                soil=soil,
                checkpoint=str(run / "best.pt"),
                wins={"summer": [True] * 4},
            )
    agreement = soil_agreement(soil_cells(tmp_path / "soils"), ("heightfield", "particles"))
    assert math.isnan(agreement.tau) and not agreement.meets_target
    reason = (
        "undefined: every controller has the same success on heightfield (100%) and "
        "particles (100%), so there is no ranking to compare"
    )
    assert agreement.tau_text == reason
    assert agreement.target_text == "no (τ undefined)"
    markdown, _ = build_report(out_dir=tmp_path / "report", cross_soil=tmp_path / "soils")
    text = markdown.read_text()
    assert f"| every condition | 2 | {reason} | 0 points | no (τ undefined) |" in text
    assert "nan" not in text.lower().replace("nnet", "")


# --- a tiny real sweep over seeds -----------------------------------------------------------


def test_a_real_sweep_over_seeds_pools_them_on_paired_starts(datasets, tmp_path):
    from test_training import train_bc_recipe

    from pilerl.policies import actor_policy, load_actor

    root, _, _ = datasets
    sweep = tmp_path / "sweep"
    result = train_bc_recipe(
        "--multirun",
        f"hydra.sweep.dir={sweep}",
        "seed=0,1",
        "policy=rf",
        "sensors=s",
        "evaluation.episodes=2",
        "evaluation.conditions=[summer,winter_c]",
        "evaluation.workers=1",
        "evaluation.videos=false",
        data_root=root,
    )
    assert result.returncode == 0, result.stderr[-2000:]
    cells, finished, _ = closed_loop_cells(sweep)
    assert sorted(job.seed for job in finished) == [0, 1]
    winter = cells[("rf", "s", "d_i", "winter")]
    assert winter.seeds == 2 and sorted(winter.per_seed) == [0, 1]
    # both seeds ran the same two seeded starts: the keys differ only in the training seed
    starts = {seed: {(c, s) for t, c, s in winter.outcomes if t == seed} for seed in (0, 1)}
    assert starts[0] == starts[1] and len(starts[0]) == 2
    # the training seed reaches the forest (sklearn's random state, not torch's)
    forests = [actor_policy(load_actor(job.path / "best.pt")) for job in finished]
    assert [f.config.options["seed"] for f in forests] == [job.seed for job in finished]
    first, second = (dict(f.named_buffers())["controller.threshold"] for f in forests)
    assert first.shape != second.shape or not bool((first == second).all())
    markdown, _ = build_report(out_dir=tmp_path / "report", exp1=sweep)
    assert "| RF | θ1, θ2, p_d | D_I | 2 |" in markdown.read_text()  # pooled over 2 seeds


def test_a_checkpoint_outside_a_train_bc_job_is_named_by_its_directory(tmp_path):
    finetuned = tmp_path / "finetune" / "dannet_rlpd"
    (finetuned / ".hydra").mkdir(parents=True)
    (finetuned / ".hydra" / "config.yaml").write_text(yaml.safe_dump({"algorithm": "ppo"}))
    assert controller_of(str(finetuned / "best.pt"), None) == (("dannet_rlpd", "", ""), 0)
    assert controller_of(str(tmp_path / "x.pt"), "mine") == (("mine", "", ""), 0)
    assert controller_of(None, None) == (("scripted", "", ""), 0)
    train = seeded_job(tmp_path / "train", 0, policy="annet", seed=2, wins={"summer": [True]})
    assert controller_of(str(train / "best.pt"), None) == (("annet", "s_pt", "d_ii"), 2)


def test_job_results_carry_the_mean_fill_only_where_it_is_a_finite_number(tmp_path):
    # one read of summary.json gives each test's successes and its mean fill; the
    # paper's single-winter alias takes its winter condition's fill with its successes
    job = tmp_path / "job"
    job.mkdir()
    row = {"successes": 1, "episodes": 2, "failure_modes": {}}
    summary = {
        "summer": {**row, "fill_mean": 0.62},
        "winter_c": {**row, "fill_mean": 0.31},
        "winter_a": {**row, "fill_mean": float("nan")},
        "winter_b": {**row, "fill_mean": True},
        "winter_d": dict(row),
        "winter": {**row, "fill_mean": 0.4},  # the pooled group, as evaluate writes it
    }
    (job / "summary.json").write_text(json.dumps(summary))
    results = job_results(job, {})
    fills = {test: result.fill_mean for test, result in results.items()}
    assert fills == {
        "summer": 0.62,
        "winter_c": 0.31,
        "winter_a": None,
        "winter_b": None,
        "winter_d": None,
        "winter": 0.4,
    }
    del summary["winter_a"], summary["winter_b"], summary["winter_d"], summary["winter"]
    (job / "summary.json").write_text(json.dumps(summary))
    assert job_results(job, {})["winter"].fill_mean == 0.31


def test_fine_tuned_controllers_are_their_cloned_seeds_fine_tuned(tmp_path):
    # a finetune run started from cloned seed k is DANNet + PPO seed k, beside the cloned
    # DANNet itself: three fine-tuned seeds pool into one cell, not a repeated seed 0
    for seed in range(3):
        cloned = seeded_job(tmp_path / "train", seed, policy="dannet", seed=seed, wins={})
        tuned = tmp_path / "finetune" / f"seed{seed}"
        (tuned / ".hydra").mkdir(parents=True)
        settings = {"checkpoint": str(cloned / "best.pt"), "algorithm": {"name": "ppo"}}
        (tuned / ".hydra" / "config.yaml").write_text(yaml.safe_dump(settings))
        for soil, rates in {"heightfield": (2, 4), "particles": (1, 3)}.items():
            for k, (checkpoint, successes) in enumerate(zip((cloned, tuned), rates, strict=True)):
                seeded_job(
                    tmp_path / soil,
                    2 * seed + k,
                    policy="dannet",
                    seed=seed,
                    soil=soil,
                    checkpoint=str(checkpoint / "best.pt"),
                    wins={"summer": outcomes(successes)},
                )
    cells = soil_cells([tmp_path / "heightfield", tmp_path / "particles"])
    tuned_cell = cells.by_soil["particles"][("dannet+ppo", "s_pt", "d_ii", "summer")]
    assert (tuned_cell.seeds, tuned_cell.successes, tuned_cell.episodes) == (3, 9, 12)
    text = build_report(
        out_dir=tmp_path / "report", cross_soil=[tmp_path / "heightfield", tmp_path / "particles"]
    )[0].read_text()
    assert "| DANNet + PPO | + p_t | D_II | 100% | 75% | +25 points |" in text
    assert "| DANNet | + p_t | D_II | 50% | 25% | +25 points |" in text
    # a fine-tuning run whose checkpoint does not resolve from here is named, not guessed
    moved = tmp_path / "finetune" / "moved"
    (moved / ".hydra").mkdir(parents=True)
    settings = {"checkpoint": "elsewhere/train/0/best.pt", "algorithm": {"name": "ppo"}}
    (moved / ".hydra" / "config.yaml").write_text(yaml.safe_dump(settings))
    with pytest.raises(ValueError, match="checkpoint elsewhere/train/0/best.pt does not exist"):
        controller_of(str(moved / "best.pt"), None)
