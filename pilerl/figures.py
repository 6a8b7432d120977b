"""Saving matplotlib figures: headless backend, atomic write, figure closed afterwards."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # no display on the target machines
import matplotlib.pyplot as plt  # noqa: E402

from pilerl.io import atomic_path  # noqa: E402

DPI = 110


def save_figure(fig, path: str | Path) -> Path:
    """Lay out ``fig``, write it atomically to ``path`` (format from the suffix), close it."""
    fig.tight_layout()
    path = Path(path)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=DPI)
    plt.close(fig)
    return path
