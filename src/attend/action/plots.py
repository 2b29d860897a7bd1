"""Figures of a search mission (matplotlib, Agg backend chosen by the caller's entry point):
ground truth, belief mean and variance maps at several times (seed Figs. 7-9), the 3-D flight
path, metrics over time, and an animated GIF of the mission."""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

import numpy as np

from attend.action.episode import EpisodeLog
from attend.action.field import SearchField


def _pyplot():
    import matplotlib

    if matplotlib.get_backend().lower() not in ("agg", "pdf", "svg", "png"):
        matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    return plt


def _extent(field: SearchField) -> list[float]:
    half = field.grid.size_m / 2
    return [-half, half, -half, half]


def _draw_obstacles(ax, field: SearchField) -> None:
    from matplotlib.patches import Rectangle

    for box in field.obstacles:
        x0, x1, y0, y1, _, _ = box.bounds
        ax.add_patch(Rectangle((x0, y0), x1 - x0, y1 - y0, fill=False, edgecolor="k", hatch="//", lw=1))


def snapshot_indices(log: EpisodeLog, times_s: Sequence[float]) -> list[int]:
    """Map entries (0 = prior) closest after each requested time."""
    metric_times = log.metric_times_s
    return [int(np.clip(np.searchsorted(metric_times, t, side="right") - 1, 0, len(metric_times) - 1)) for t in times_s]


def plot_maps(field: SearchField, log: EpisodeLog, times_s: Sequence[float], path: Path) -> Path:
    """Ground truth, then belief mean (top) and variance (bottom) at ``times_s``."""
    plt = _pyplot()
    indices = snapshot_indices(log, times_s)
    columns = len(indices) + 1
    fig, axes = plt.subplots(2, columns, figsize=(3.1 * columns, 6.2), constrained_layout=True)
    shape = field.grid.shape
    axes[0, 0].imshow(field.truth.reshape(shape), origin="lower", extent=_extent(field), cmap="viridis", vmin=0, vmax=1)
    axes[0, 0].set_title("ground truth")
    _draw_obstacles(axes[0, 0], field)
    axes[1, 0].axis("off")
    vmax_var = float(np.max(log.variances[0]))
    for c, index in enumerate(indices, start=1):
        t = log.metric_times_s[index]
        im_mean = axes[0, c].imshow(log.means[index].reshape(shape), origin="lower", extent=_extent(field), cmap="viridis", vmin=0, vmax=1)
        axes[0, c].set_title(f"occupancy, t = {t:.0f} s")
        im_var = axes[1, c].imshow(log.variances[index].reshape(shape), origin="lower", extent=_extent(field), cmap="magma", vmin=0, vmax=vmax_var)
        axes[1, c].set_title(f"variance, t = {t:.0f} s")
        poses = np.array(log.poses_m[:index]) if index else np.zeros((0, 3))
        if len(poses):
            axes[0, c].plot(poses[:, 0], poses[:, 1], "w.-", ms=3, lw=0.7)
        for r in (0, 1):
            _draw_obstacles(axes[r, c], field)
    fig.colorbar(im_mean, ax=axes[0, -1], label="occupancy mean")
    fig.colorbar(im_var, ax=axes[1, -1], label="variance diag(P)")
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def plot_path_3d(field: SearchField, log: EpisodeLog, path: Path) -> Path:
    """Flown waypoints and image poses in 3-D over the ground truth."""
    plt = _pyplot()
    fig = plt.figure(figsize=(6.5, 5.5))
    ax = fig.add_subplot(projection="3d")
    waypoints = np.array(log.waypoints_m)
    images = np.array(log.poses_m) if log.poses_m else np.zeros((0, 3))
    ax.plot(waypoints[:, 0], waypoints[:, 1], waypoints[:, 2], "-", color="tab:blue", lw=1.2, label="flight path")
    if len(images):
        ax.scatter(images[:, 0], images[:, 1], images[:, 2], color="tab:orange", s=12, label="images")
    centres = field.grid.cell_centres()
    people = field.truth > 0.5
    ax.scatter(centres[people, 0], centres[people, 1], 0, color="tab:red", s=4, label="people")
    for box in field.obstacles:
        x0, x1, y0, y1, _, z1 = box.bounds
        ax.bar3d(x0, y0, 0, x1 - x0, y1 - y0, z1, color="grey", alpha=0.35)
    half = field.grid.size_m / 2
    ax.set_xlim(-half, half)
    ax.set_ylim(-half, half)
    ax.set_zlim(0, field.altitude_limits_m[1])
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_zlabel("altitude [m]")
    ax.set_title(f"{log.planner}: flight path")
    ax.legend(loc="upper left", fontsize=8)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def plot_metrics(log: EpisodeLog, path: Path) -> Path:
    """RSE, trace(P), people found and false-alarm cells over flight time."""
    plt = _pyplot()
    t = log.metric_times_s
    fig, axes = plt.subplots(1, 4, figsize=(14, 3.2), constrained_layout=True)
    for ax, (key, label) in zip(
        axes, [("rse", "RSE"), ("trace", "trace(P)"), ("people_found", "people found"), ("false_alarm_cells", "false-alarm cells")]
    ):
        ax.step(t, log.series(key), where="post")
        ax.set_xlabel("flight time [s]")
        ax.set_title(label)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def write_gif(field: SearchField, log: EpisodeLog, path: Path, fps: float = 3.0) -> Path:
    """Animated GIF: one frame per image (belief mean with the path so far, variance)."""
    plt = _pyplot()
    from matplotlib.animation import FuncAnimation, PillowWriter

    shape = field.grid.shape
    fig, (ax_mean, ax_var) = plt.subplots(1, 2, figsize=(8, 4), constrained_layout=True)
    mean_image = ax_mean.imshow(log.means[0].reshape(shape), origin="lower", extent=_extent(field), cmap="viridis", vmin=0, vmax=1)
    var_image = ax_var.imshow(log.variances[0].reshape(shape), origin="lower", extent=_extent(field), cmap="magma", vmin=0,
                              vmax=float(np.max(log.variances[0])))
    (track,) = ax_mean.plot([], [], "w.-", ms=3, lw=0.8)
    (uav,) = ax_mean.plot([], [], "r^", ms=8)
    for ax in (ax_mean, ax_var):
        _draw_obstacles(ax, field)
    title = fig.suptitle("")
    poses = np.array(log.poses_m) if log.poses_m else np.zeros((0, 3))

    def frame(i: int):
        mean_image.set_data(log.means[i].reshape(shape))
        var_image.set_data(log.variances[i].reshape(shape))
        if i > 0:
            track.set_data(poses[:i, 0], poses[:i, 1])
            uav.set_data([poses[i - 1, 0]], [poses[i - 1, 1]])
        found = log.series("people_found")[i]
        title.set_text(
            f"{log.planner}  t = {log.metric_times_s[i]:.0f} s  found {found:.0f}/{log.people_total}  "
            f"trace(P) = {log.series('trace')[i]:.0f}"
        )
        return mean_image, var_image, track, uav, title

    animation = FuncAnimation(fig, frame, frames=len(log.means), blit=False)
    animation.save(str(path), writer=PillowWriter(fps=fps))
    plt.close(fig)
    return path
