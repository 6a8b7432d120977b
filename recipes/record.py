"""Record scripted demonstrations into a dataset directory.

    python recipes/record.py                       # 72 summer demonstrations at 500 Hz
    python recipes/record.py n_episodes=4 record_hz=100 out_dir=/tmp/demos

An existing ``out_dir`` is resumed: episodes already recorded are kept and skipped. Its
``run.json`` records the recording plan; resuming with another plan (condition, rate,
seed, operator ...) is refused, naming what differs; only ``n_episodes`` may grow.
"""

from __future__ import annotations

import logging

from pilerl.config import register_configs
from pilerl.data import RecordingPlan, record_demonstrations
from pilerl.data.recording import open_demonstrations, recording_metrics
from pilerl.data.settings import RecordConfig
from pilerl.recipe import Run, recipe

log = logging.getLogger(__name__)
register_configs()


@recipe("record")
def main(config: RecordConfig, run: Run) -> dict[str, float]:
    plan = RecordingPlan(
        config.env.simulator,
        config.env.make_kwargs(control_hz=config.record_hz),
        n_episodes=config.n_episodes,
        seed=config.seed,
        expert=config.expert,
    )
    # --- the store (its env built first: a bad argument fails before anything is written)
    description = f"scripted demonstrations, {config.env.condition}, {config.record_hz} Hz"
    store = open_demonstrations(config.out_dir, plan, description=description)
    plan_settings = {k: v for k, v in run.settings.items() if k != "out_dir"}  # the store itself
    run.begin(run_dir=config.out_dir, settings=plan_settings, growable=["n_episodes"])

    # --- record (resumes)
    record_demonstrations(store, plan, workers=config.workers)
    metrics = recording_metrics(store)
    log.info("%s: %s", config.out_dir, metrics)
    return metrics


if __name__ == "__main__":
    main()
