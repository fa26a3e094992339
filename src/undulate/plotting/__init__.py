"""Figures from datasets: ``Dataset -> matplotlib Figure``; nothing here simulates.

Figures are built on :class:`matplotlib.figure.Figure` with the Agg canvas,
never through pyplot, so no global state or GUI backend is touched.
Import the submodule you need (``undulate.plotting.compatibility``); this
package imports no matplotlib by itself.
"""

from __future__ import annotations

import numpy as np

__all__ = ["new_figure", "phase_axis"]


def new_figure(width_in: float, height_in: float):
    """A Figure with an Agg canvas (no pyplot), ``width_in`` x ``height_in`` inches."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width_in, height_in), layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def phase_axis(axis) -> None:
    """Put ticks at multiples of pi/2 on a phase axis in rad (``ax.xaxis`` etc.)."""
    axis.set_ticks(np.pi * np.array([-1, -0.5, 0, 0.5, 1]),
                   [r"$-\pi$", r"$-\pi/2$", "0", r"$\pi/2$", r"$\pi$"])
