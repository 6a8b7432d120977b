"""Reports a person reads. ``paper``: the paper's experiments in simulation (also the CLI
``python -m pilerl.reports.paper``), built from finished sweeps (``results``: cells pooled
over training seeds; ``comparisons``: the seed-aware tests behind the claims;
``cross_soil``: held-out conditions and two soil models' rank agreement) as Markdown and
HTML (``document``)."""

from .document import Report
from .results import Cell, closed_loop_cells, offline_validation_curves

__all__ = ["Cell", "Report", "closed_loop_cells", "offline_validation_curves"]
