"""Structured (typed) configs behind the YAML under conf/; see schema.py."""

from .schema import (
    BuildDatasetConfig,
    ClosedLoopConfig,
    DatasetConfig,
    EnvConfig,
    EvaluateConfig,
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
    "ClosedLoopConfig",
    "EvaluateConfig",
    "DatasetConfig",
    "EnvConfig",
    "RecordConfig",
    "ScoopConfig",
    "TeleopConfig",
    "register_configs",
]
