"""The floors of pilerl: every import points down (or sideways), and no module imports
itself back through others.

Imports are read with ``ast`` from every module under pilerl/, those inside functions
included (a lazy import is still an arrow). Each module sits on the floor of the longest
prefix listed in ``FLOORS``; a module may import from its own floor or any floor below.
docs/architecture.md explains the floors; ``python tests/config/test_layers.py`` prints the listing
(which room imports which).
"""

from __future__ import annotations

import ast
import sys
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
PACKAGE = ROOT / "pilerl"

# lowest first; a module's floor is that of the longest prefix naming it
FLOORS: list[tuple[str, tuple[str, ...]]] = [
    (
        "base",
        (
            "pilerl.checks",
            "pilerl.registry",
            "pilerl.io",
            "pilerl.runtime",
            "pilerl.figures",
            "pilerl.rendering",
            "pilerl.loggers",
            "pilerl.runs",
            "pilerl.layout",
            # done.json / metrics.json of a run directory: read by runs, written by recipes
            "pilerl.sweeps.completion",
        ),
    ),
    ("sim", ("pilerl", "pilerl.sim")),
    ("operators", ("pilerl.operators",)),
    ("data", ("pilerl.data",)),
    ("policies", ("pilerl.policies",)),
    ("evaluation", ("pilerl.evaluation",)),
    ("training", ("pilerl.training",)),
    ("sweeps", ("pilerl.sweeps",)),
    ("rl", ("pilerl.rl",)),
    ("reports", ("pilerl.reports",)),
    ("deploy", ("pilerl.deploy",)),
    ("config", ("pilerl.config", "pilerl.recipe")),
]
# arrows up that another change of issue #14 removes: (importer floor, imported floor) ->
# why. Each must still exist (a stale entry fails), so the list only shrinks.
PENDING_UPWARD: dict[tuple[str, str], str] = {}


def module_names() -> dict[str, Path]:
    """Dotted module name -> file, for every module under pilerl/."""
    modules = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = path.relative_to(ROOT).with_suffix("").parts
        if parts[-1] == "__init__":
            parts = parts[:-1]
        modules[".".join(parts)] = path
    return modules


def imports_of(name: str, path: Path, modules: dict[str, Path]) -> set[str]:
    """The pilerl modules ``name`` imports anywhere in its file (a ``from package import
    submodule`` counts as the submodule)."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found = set()
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                origin = ".".join([*base, *([node.module] if node.module else [])])
            else:
                origin = node.module or ""
            targets = [
                f"{origin}.{alias.name}" if f"{origin}.{alias.name}" in modules else origin
                for alias in node.names
            ]
        else:
            continue
        for target in targets:
            if target != "pilerl" and not target.startswith("pilerl."):
                continue
            while target not in modules:  # pilerl.x.y.Name -> pilerl.x.y
                target = target.rpartition(".")[0]
            if target != name:
                found.add(target)
    return found


def import_graph() -> dict[str, set[str]]:
    modules = module_names()
    return {name: imports_of(name, path, modules) for name, path in modules.items()}


def floor_of(module: str) -> int:
    best, floor = -1, None
    for level, (_, prefixes) in enumerate(FLOORS):
        for prefix in prefixes:
            if (module == prefix or module.startswith(prefix + ".")) and len(prefix) > best:
                best, floor = len(prefix), level
    assert floor is not None, f"{module}: on no floor; add it to FLOORS"
    return floor


def floor_name(module: str) -> str:
    return FLOORS[floor_of(module)][0]


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected groups of more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(node: str) -> None:
        index[node] = low[node] = len(index)
        stack.append(node)
        on_stack.add(node)
        for other in sorted(graph[node]):
            if other not in index:
                visit(other)
                low[node] = min(low[node], low[other])
            elif other in on_stack:
                low[node] = min(low[node], index[other])
        if low[node] == index[node]:
            group = []
            while True:
                member = stack.pop()
                on_stack.discard(member)
                group.append(member)
                if member == node:
                    break
            if len(group) > 1:
                found.append(sorted(group))

    limit = sys.getrecursionlimit()
    sys.setrecursionlimit(max(limit, 10 * len(graph)))
    try:
        for node in sorted(graph):
            if node not in index:
                visit(node)
    finally:
        sys.setrecursionlimit(limit)
    return found


def floor_listing(graph: dict[str, set[str]]) -> dict[str, set[str]]:
    """Floor -> the other floors its modules import."""
    listing: dict[str, set[str]] = defaultdict(set)
    for module, targets in graph.items():
        listing[floor_name(module)] |= {floor_name(t) for t in targets} - {floor_name(module)}
    return listing


# ---------------------------------------------------------------- tests


def test_every_module_is_on_a_floor_and_every_prefix_names_a_module():
    modules = module_names()
    for name in modules:
        floor_of(name)
    for _, prefixes in FLOORS:
        for prefix in prefixes:
            assert prefix in modules, f"FLOORS names {prefix!r}, which no longer exists"


def test_no_module_imports_itself_back():
    assert cycles(import_graph()) == []


def test_imports_point_down_or_sideways():
    upward = defaultdict(list)
    for module, targets in import_graph().items():
        for target in targets:
            if floor_of(target) > floor_of(module):
                upward[(floor_name(module), floor_name(target))].append(f"{module} -> {target}")
    unexpected = {k: v for k, v in upward.items() if k not in PENDING_UPWARD}
    assert not unexpected, f"imports up a floor: {unexpected}"
    stale = sorted(set(PENDING_UPWARD) - set(upward))
    assert not stale, f"PENDING_UPWARD lists {stale}, which no longer import up: remove them"


def test_the_config_circle_is_gone():
    """config/ composes the rooms; no room imports config/ ."""
    graph = import_graph()
    for module, targets in graph.items():
        if module.startswith("pilerl.config"):
            continue
        into_config = {t for t in targets if t.startswith("pilerl.config")}
        assert not into_config, f"{module} imports {into_config}"
    assert "pilerl.config" not in graph["pilerl.rl.config"]


def test_the_detector_sees_lazy_imports_and_circles():
    """The reader counts imports inside functions, and a circle is reported."""
    graph = import_graph()
    assert "pilerl.evaluation.evaluator" in graph["pilerl.evaluation.settings"]  # in plan()
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


if __name__ == "__main__":
    listing = floor_listing(import_graph())
    order = [name for name, _ in FLOORS]
    for floor in reversed(order):
        below = sorted(listing.get(floor, ()), key=order.index, reverse=True)
        print(f"{floor:>10} -> {', '.join(below) or '-'}")
