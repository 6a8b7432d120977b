"""Reports a person reads. ``paper``: the paper's experiments in simulation (also the CLI
``python -m pilerl.reports.paper``), built from finished sweeps (``results``) as Markdown
and HTML (``document``)."""

from .document import Report
from .results import Cell, closed_loop_cells, offline_validation_curves

__all__ = ["Cell", "Report", "closed_loop_cells", "offline_validation_curves"]
