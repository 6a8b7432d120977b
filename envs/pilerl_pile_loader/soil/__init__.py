"""Soil models, found by name. Add a model here to make it selectable with ``soil=<name>``."""

from __future__ import annotations

from .base import BucketGeometry, PileGeometry, SoilModel
from .heightfield import HeightfieldSoil
from .particles import ParticleSoil

SOIL_MODELS: dict[str, type[SoilModel]] = {
    HeightfieldSoil.name: HeightfieldSoil,
    ParticleSoil.name: ParticleSoil,
}


def get_soil_model(name: str) -> type[SoilModel]:
    """Look up a soil model class by name; unknown names list the known ones."""
    try:
        return SOIL_MODELS[name]
    except KeyError:
        raise ValueError(
            f"unknown soil model {name!r}; known soil models: {sorted(SOIL_MODELS)}"
        ) from None


__all__ = ["SOIL_MODELS", "BucketGeometry", "PileGeometry", "SoilModel", "get_soil_model"]
