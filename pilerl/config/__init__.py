"""Structured (typed) configs behind the YAML under conf/; see schema.py."""

from .schema import (
    BuildDatasetConfig,
    DatasetConfig,
    EnvConfig,
    PolicyConfig,
    RecordConfig,
    ScoopConfig,
    SensorsConfig,
    TeleopConfig,
    TrainBCConfig,
    register_configs,
)

__all__ = [
    "PolicyConfig",
    "SensorsConfig",
    "TrainBCConfig",
    "BuildDatasetConfig",
    "DatasetConfig",
    "EnvConfig",
    "RecordConfig",
    "ScoopConfig",
    "TeleopConfig",
    "register_configs",
]
