"""One way to register a kind of thing by name (controllers, algorithms, loggers...).

A ``Registry`` is a read-only mapping ``name -> entry`` with a kind (``"controller"``);
asking for a name it does not hold raises ``UnknownNameError`` listing the known ones, and
``check`` turns the same into a config error naming the field::

    CONTROLLERS = Registry("controller", {"nnet": spec, ...})
    CONTROLLERS["nnet"]                      # the entry
    CONTROLLERS["mlp"]                       # UnknownNameError: unknown controller 'mlp';
                                             #   known controllers: ['nnet', ...]
    CONTROLLERS.check("policy.name", name)   # ValueError: policy.name: unknown 'mlp'; known: [...]

Simulators are the one kind found elsewhere: installed plugins declare them under an entry
point group (``pilerl.sim.registry``); their lookup fails the same way.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from typing import Generic, TypeVar

Entry = TypeVar("Entry")


class UnknownNameError(KeyError):
    """A name that is not registered; the message lists the known ones."""

    def __str__(self) -> str:  # KeyError would quote the whole message
        return str(self.args[0])


class Registry(Mapping[str, Entry], Generic[Entry]):
    """Named entries of one kind; an unknown name fails with the list of known ones.

    Args:
        kind: what the entries are, singular (``"controller"``): used in error messages.
        entries: the registered entries by name.
    """

    def __init__(self, kind: str, entries: Mapping[str, Entry]) -> None:
        self.kind = kind
        self._entries = dict(entries)

    def __getitem__(self, name: str) -> Entry:
        if name not in self._entries:
            raise UnknownNameError(
                f"unknown {self.kind} {name!r}; known {self.kind}s: {self.names()}"
            )
        return self._entries[name]

    def __contains__(self, name: object) -> bool:
        return name in self._entries

    def __iter__(self) -> Iterator[str]:
        return iter(self._entries)

    def __len__(self) -> int:
        return len(self._entries)

    def names(self) -> list[str]:
        """The registered names, in the order they were registered."""
        return list(self._entries)

    def check(self, where: str, name: str) -> None:
        """``ValueError`` naming the config field ``where`` unless ``name`` is registered."""
        if name not in self._entries:
            raise ValueError(f"{where}: unknown {name!r}; known: {self.names()}")

    def __repr__(self) -> str:
        return f"Registry({self.kind!r}, {self.names()})"
