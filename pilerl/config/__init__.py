"""Composition only: every room's typed settings registered in Hydra's ConfigStore.

Each room owns its settings (a dataclass checked in ``__post_init__``):
``pilerl.data.settings``, ``pilerl.policies.settings``, ``pilerl.evaluation.settings``,
``pilerl.training.settings``, ``pilerl.rl.config``, ``pilerl.deploy.config`` and
``pilerl.loggers``; the simulator's ``EnvConfig`` is in ``pilerl.sim.settings``. The YAML
files under conf/ extend the stored schemas, so a wrong type or an unknown key fails when
Hydra composes a config, and they state only what differs from the dataclasses' defaults.
``pipeline.py`` composes the main job's config. See docs/architecture.md."""

from __future__ import annotations

from pathlib import Path

CONF_ENV = Path(__file__).resolve().parents[2] / "conf" / "env"  # this checkout's env YAMLs


def register_configs() -> None:
    """Put every schema in Hydra's ConfigStore (idempotent): the recipes' primary schemas
    (``<recipe>_schema``) and each config group's (``<group>/<name>_schema``).

    The rooms are imported here, not at the top, so that importing this package stays cheap.
    """
    from hydra.core.config_store import ConfigStore

    from pilerl.data.settings import (
        BuildDatasetConfig,
        DatasetConfig,
        RecordConfig,
        TeleopConfig,
    )
    from pilerl.deploy.config import DeployConfig
    from pilerl.evaluation.settings import EvaluateConfig, ScoopConfig
    from pilerl.loggers import LoggerConfig
    from pilerl.policies.settings import PolicyConfig, SensorsConfig
    from pilerl.rl.config import ALGORITHMS, CurriculumConfig, FinetuneConfig
    from pilerl.sim.settings import register_env_configs
    from pilerl.training.settings import TrainBCConfig

    from .pipeline import PipelineConfig

    primary = {
        "scoop": ScoopConfig,
        "record": RecordConfig,
        "build_dataset": BuildDatasetConfig,
        "teleop": TeleopConfig,
        "train_bc": TrainBCConfig,
        "evaluate": EvaluateConfig,
        "finetune": FinetuneConfig,
        "pipeline": PipelineConfig,
        "deploy": DeployConfig,
    }
    groups = {
        "policy": {"policy": PolicyConfig},
        "sensors": {"sensors": SensorsConfig},
        "dataset": {"dataset": DatasetConfig},
        "logger": {"logger": LoggerConfig},
        "curriculum": {"curriculum": CurriculumConfig},
        "algorithm": dict(ALGORITHMS),  # one schema per registered learner
    }
    store = ConfigStore.instance()
    for recipe, schema in primary.items():
        store.store(name=f"{recipe}_schema", node=schema)
    for group, schemas in groups.items():
        for name, schema in schemas.items():
            store.store(group=group, name=f"{name}_schema", node=schema)
    # one ``env`` schema per installed simulator, from its declared options
    register_env_configs(yaml_names={p.stem for p in CONF_ENV.glob("*.yaml")})


__all__ = ["register_configs"]
