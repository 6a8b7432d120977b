"""Structured (typed) configs behind the YAML under conf/; see schema.py."""

from .schema import (
    BuildDatasetConfig,
    ClosedLoopConfig,
    DatasetConfig,
    EnvConfig,
    EvaluateConfig,
    LoggerConfig,
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
    "LoggerConfig",
    "DatasetConfig",
    "EnvConfig",
    "RecordConfig",
    "ScoopConfig",
    "TeleopConfig",
    "register_configs",
]
