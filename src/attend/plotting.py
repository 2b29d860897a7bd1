"""Plots shared by the CLI and the experiments (matplotlib, PNG files).

Every figure gets its own Agg canvas (no pyplot state), so nothing here selects matplotlib's
backend or opens a window: importing or plotting leaves the process's matplotlib configuration
as it was.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np


def figure(figsize: tuple[float, float], nrows: int = 1, ncols: int = 1, **subplot_options):
    """A figure with its own Agg canvas and an (nrows, ncols) grid of axes; ``subplot_options``
    (sharex, squeeze, ...) go to ``Figure.subplots``. Returns (figure, axes)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=figsize)
    FigureCanvasAgg(fig)
    return fig, fig.subplots(nrows, ncols, **subplot_options)


def new_figure(out_dir, figsize: tuple[float, float], nrows: int = 1, ncols: int = 1, **figure_options):
    """A figure (own Agg canvas, no pyplot state) with an (nrows, ncols) grid of axes; creates
    ``out_dir``. ``figure_options`` go to ``matplotlib.figure.Figure``. Returns (figure, axes) as
    ``Figure.subplots`` does."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    Path(out_dir).mkdir(parents=True, exist_ok=True)
    fig = Figure(figsize=figsize, **figure_options)
    FigureCanvasAgg(fig)
    return fig, fig.subplots(nrows, ncols)


def plot_estimates(path, time, system, estimate) -> Path:
    """One panel per state and input: estimate with a +-2 standard-deviation band."""
    names = list(system.state_names) + list(system.input_names)
    means = np.column_stack([estimate.states, estimate.inputs])
    stds = np.column_stack([estimate.state_std, estimate.input_std])
    fig, axes = figure((8, 1.8 * len(names)), len(names), 1, sharex=True, squeeze=False)
    for j, (axis, name) in enumerate(zip(axes[:, 0], names)):
        axis.plot(time, means[:, j], lw=1.0, label="DEM estimate")
        axis.fill_between(time, means[:, j] - 2 * stds[:, j], means[:, j] + 2 * stds[:, j], alpha=0.3, label="±2 std")
        axis.set_ylabel(name)
    axes[0, 0].legend(loc="upper right", fontsize=8)
    axes[-1, 0].set_xlabel("time [s]")
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    return path
