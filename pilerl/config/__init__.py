"""Structured (typed) configs behind the YAML under conf/; see schema.py."""

from .schema import EnvConfig, OperatorConfig, ScoopConfig, register_configs

__all__ = ["EnvConfig", "OperatorConfig", "ScoopConfig", "register_configs"]
