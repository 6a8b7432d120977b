"""Structured (typed) configs behind the YAML under conf/; see schema.py."""

from .schema import (
    BuildDatasetConfig,
    DatasetConfig,
    EnvConfig,
    RecordConfig,
    ScoopConfig,
    TeleopConfig,
    register_configs,
)

__all__ = [
    "BuildDatasetConfig",
    "DatasetConfig",
    "EnvConfig",
    "RecordConfig",
    "ScoopConfig",
    "TeleopConfig",
    "register_configs",
]
