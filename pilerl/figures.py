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


def legend_outside(ax, **kwargs):
    """A legend to the right of ``ax``, outside the plotted area, so it never covers data.

    ``save_figure``'s tight layout makes room for it.
    """
    kwargs.setdefault("fontsize", 7)
    return ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0, **kwargs)
