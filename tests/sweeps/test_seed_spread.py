"""The sweep summary gives each group's seed spread beside its pooled success."""

from __future__ import annotations

from test_sweeps import fake_job

from pilerl.sweeps import summarize_sweep


def test_the_seed_spread_is_the_lowest_and_highest_seeds_own_rate(tmp_path):
    for seed, successes in ((0, 2), (1, 8), (2, 5)):
        metrics = {"winter_success_rate": successes / 10, "winter_successes": successes}
        fake_job(
            tmp_path, seed, ["policy=dannet", f"seed={seed}"], metrics | {"winter_episodes": 10}
        )
    (row,) = summarize_sweep(tmp_path, plot_metric="winter_success_rate")
    assert row["n_jobs"] == 3 and row["winter_pooled_success_rate"] == 0.5  # 15 of 30
    assert (row["winter_seed_min"], row["winter_seed_max"]) == (0.2, 0.8)
    header = (tmp_path / "sweep_summary.md").read_text().splitlines()[2]
    assert header.endswith("| winter_seed_min | winter_seed_max |")
