"""One registration mechanism: every kind chosen by name fails alike on an unknown name."""

from __future__ import annotations

import pytest

from pilerl.loggers import LOGGERS
from pilerl.policies.registry import CONTROLLERS
from pilerl.registry import Registry, UnknownNameError
from pilerl.rl.config import ALGORITHMS, LearnerConfig

REGISTRIES = {"controller": CONTROLLERS, "algorithm": ALGORITHMS, "logger": LOGGERS}


@pytest.mark.parametrize("kind", sorted(REGISTRIES))
def test_an_unknown_name_fails_with_the_known_ones(kind):
    registry = REGISTRIES[kind]
    assert registry.kind == kind and len(registry) >= 2
    with pytest.raises(UnknownNameError) as error:
        registry["no_such_name"]
    assert f"unknown {kind} 'no_such_name'" in str(error.value)
    assert all(repr(name) in str(error.value) for name in registry)
    with pytest.raises(ValueError, match=rf"^{kind}\.name: unknown 'no_such_name'; known: \["):
        registry.check(f"{kind}.name", "no_such_name")
    for name in registry:
        registry.check(f"{kind}.name", name)  # the known ones pass


def test_every_algorithm_names_itself():
    for name, settings in ALGORITHMS.items():
        assert issubclass(settings, LearnerConfig) and settings().name == name


def test_a_registry_keeps_its_order_and_is_read_only():
    registry = Registry("colour", {"red": 1, "blue": 2})
    assert registry.names() == ["red", "blue"] and registry["blue"] == 2
    assert "red" in registry and "green" not in registry
    with pytest.raises(TypeError):
        registry["green"] = 3  # type: ignore[index]
