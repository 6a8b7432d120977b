"""Readers whose libraries are optional extras (``pip install 'pilerl[logs]'``)."""

from __future__ import annotations

import importlib
from pathlib import Path
from types import ModuleType

from ..errors import LogImportError

EXTRA = "logs"
PACKAGES = {  # module -> PyPI package
    "mcap": "mcap",
    "rosbags": "rosbags",
    "cantools": "cantools",
    "can": "python-can",
    "asammdf": "asammdf",
}


def require(module: str, path: Path, what: str) -> ModuleType:
    """Import ``module`` or raise a ``LogImportError`` saying which package to install."""
    try:
        return importlib.import_module(module)
    except ImportError:
        package = PACKAGES.get(module.split(".")[0], module)
        raise LogImportError(
            path,
            f"reading {what} needs the optional package {package!r}: "
            f"pip install 'pilerl[{EXTRA}]' (or pip install {package})",
        ) from None
