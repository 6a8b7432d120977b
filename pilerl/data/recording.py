"""The recording stage: scripted demonstrations into an episode store, resumably.

``recipes/record.py`` and the pipeline's demonstration step both call these; the
episodes themselves are recorded by ``pilerl.data.recorder``.
"""

from __future__ import annotations

from pathlib import Path

from pilerl.sim import get_simulator, make_gym_env

from .recorder import RecordingPlan, record_demonstrations
from .store import EpisodeStore


def open_demonstrations(
    out_dir: str | Path, plan: RecordingPlan, *, description: str
) -> EpisodeStore:
    """The store at ``out_dir`` for ``plan``'s episodes, created or reopened (to resume).

    The plan's env is built once first, so a bad simulator argument (unknown condition,
    impossible rate...) fails before anything is written; the sensor units and control
    names the simulator declares become the store's.
    """
    make_gym_env(plan.simulator, **plan.env_kwargs).close()
    plugin = get_simulator(plan.simulator)
    sensors, controls = plugin.sensor_units, list(plugin.controls)
    return EpisodeStore.create(
        out_dir, sensors=sensors, controls=controls, description=description, exist_ok=True
    )


def record(
    out_dir: str | Path, plan: RecordingPlan, *, workers: int, description: str
) -> EpisodeStore:
    """Record ``plan`` into the store at ``out_dir`` (episodes already there are kept)."""
    store = open_demonstrations(out_dir, plan, description=description)
    record_demonstrations(store, plan, workers=workers)
    return store


def recording_metrics(store: EpisodeStore) -> dict[str, float | int]:
    """Episodes, samples and success rate of a recorded store (the recipe's metrics)."""
    successes = sum(meta.success for meta in store.episodes)
    return {
        "episodes": len(store),
        "samples": store.n_samples,
        "success_rate": successes / len(store),
    }
