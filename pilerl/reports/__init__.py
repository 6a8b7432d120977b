"""Reports a person reads: the paper's experiments in simulation (``paper``), built from
finished sweeps (``results``) as Markdown and HTML (``document``)."""

from .document import Report
from .paper import build_report
from .results import Cell, closed_loop_cells, offline_validation_curves

__all__ = ["Cell", "Report", "build_report", "closed_loop_cells", "offline_validation_curves"]
