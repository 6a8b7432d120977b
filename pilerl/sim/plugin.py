"""What a simulator plugin declares so that pilerl can find and build it by name."""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass, fields

_GYM_ID = re.compile(r"^[\w.-]+/[\w.-]+-v\d+$")
_ENTRY_POINT = re.compile(r"^[\w.]+:[\w]+$")


@dataclass(frozen=True)
class SimulatorPlugin:
    """A simulator, as seen by pilerl's core.

    Attributes:
        name: registry name (``pile_loader``), what configs say.
        gym_id: Gymnasium id it is registered under, ``namespace/Name-vN``.
        entry_point: ``module:Class`` of the ``gymnasium.Env``; imported only on make.
        description: one line for listings.
    """

    name: str
    gym_id: str
    entry_point: str
    description: str = ""

    def __post_init__(self) -> None:
        if not _GYM_ID.match(self.gym_id):
            raise ValueError(
                f"SimulatorPlugin({self.name!r}).gym_id: expected "
                f"'namespace/Name-vN', got {self.gym_id!r}"
            )
        if not _ENTRY_POINT.match(self.entry_point):
            raise ValueError(
                f"SimulatorPlugin({self.name!r}).entry_point: expected "
                f"'module:Class', got {self.entry_point!r}"
            )

    @classmethod
    def from_declaration(cls, declaration: object, *, where: str) -> SimulatorPlugin:
        """Validate a plugin's ``PLUGIN`` mapping; errors name the entry point and field."""
        if isinstance(declaration, cls):
            return declaration
        if not isinstance(declaration, Mapping):
            raise TypeError(f"{where}: PLUGIN must be a mapping, got {type(declaration).__name__}")
        known = {f.name for f in fields(cls)}
        missing = {"name", "gym_id", "entry_point"} - set(declaration)
        unknown = set(declaration) - known
        if missing or unknown:
            raise ValueError(
                f"{where}: PLUGIN missing fields {sorted(missing)}, "
                f"unknown fields {sorted(unknown)}; expected {sorted(known)}"
            )
        return cls(**declaration)
