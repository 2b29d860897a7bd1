"""Plots shared by the CLI and the experiments (matplotlib, PNG files).

Every figure gets its own Agg canvas (no pyplot state), so nothing here selects matplotlib's
backend or opens a window: importing or plotting leaves the process's matplotlib configuration
as it was.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np


def figure(figsize: tuple[float, float], nrows: int = 1, ncols: int = 1, **subplot_options):
    """A figure of size ``figsize`` (inches) with its own Agg canvas and an (nrows, ncols) grid of axes; ``subplot_options``
    (sharex, squeeze, ...) go to ``Figure.subplots``. Returns (figure, axes)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=figsize)
    FigureCanvasAgg(fig)
    return fig, fig.subplots(nrows, ncols, **subplot_options)


def new_figure(out_dir, figsize: tuple[float, float], nrows: int = 1, ncols: int = 1, **figure_options):
    """A figure of size ``figsize`` (inches; own Agg canvas, no pyplot state) with an (nrows, ncols) grid of axes; creates
    ``out_dir``. ``figure_options`` go to ``matplotlib.figure.Figure``. Returns (figure, axes) as
    ``Figure.subplots`` does."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    Path(out_dir).mkdir(parents=True, exist_ok=True)
    fig = Figure(figsize=figsize, **figure_options)
    FigureCanvasAgg(fig)
    return fig, fig.subplots(nrows, ncols)


def plot_estimates(path, time, system, estimate, measured_inputs=(), units=None) -> Path:
    """One row per state and input: the estimate with its +-2 standard-deviation band (left) and
    the band's half-width 2 std on its own scale (right), so a band far narrower than the signal
    still shows.

    path: the PNG file (parent folders created); time (N,) [s]; system: gives the state and input
    names; estimate: ``states``, ``inputs`` (N, n) and ``state_std``, ``input_std``;
    measured_inputs: indices of the inputs that were measured, drawn as "measured" with no band;
    units: name -> unit for the axis labels (default: "units of the log"). Returns the path.
    """
    names = list(system.state_names) + list(system.input_names)
    means = np.column_stack([estimate.states, estimate.inputs])
    stds = np.column_stack([estimate.state_std, estimate.input_std])
    measured = {len(system.state_names) + int(j) for j in measured_inputs}
    units = units or {}
    fig, axes = figure((11, 1.9 * len(names)), len(names), 2, sharex=True, squeeze=False,
                       gridspec_kw={"width_ratios": (3, 1)})
    for j, name in enumerate(names):
        unit = units.get(name, "units of the log")
        value_axis, std_axis = axes[j]
        value_axis.set_ylabel(f"{name} [{unit}]", fontsize=8)
        if j in measured:
            value_axis.plot(time, means[:, j], "k", lw=1.0, label="measured input")
            value_axis.legend(loc="upper right", fontsize=7)
            std_axis.text(0.5, 0.5, "measured:\nno estimation band", ha="center", va="center",
                          transform=std_axis.transAxes, fontsize=8)
            std_axis.set_yticks([])
            continue
        lower, upper = means[:, j] - 2 * stds[:, j], means[:, j] + 2 * stds[:, j]
        value_axis.fill_between(time, lower, upper, color="C1", alpha=0.5, lw=0, label="+-2 std")
        value_axis.plot(time, means[:, j], "C0", lw=0.8, label="estimate")
        value_axis.legend(loc="upper right", fontsize=7)
        std_axis.plot(time, 2 * stds[:, j], "C1", lw=1.0)
        std_axis.set_ylabel(f"2 std [{unit}]", fontsize=8)
    axes[0, 0].set_title("estimate and +-2 std band")
    axes[0, 1].set_title("band half-width (own scale)")
    for axis in axes[-1]:
        axis.set_xlabel("time [s]")
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    return path
