"""Figures of a search mission, each on its own Agg canvas (:mod:`attend.plotting`, no pyplot
state): ground truth, belief mean and variance maps at several times (seed Figs. 7-9), the 3-D
flight path, metrics over time, and an animated GIF of the mission."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Sequence

import numpy as np

from attend.action.episode import EpisodeLog
from attend.action.field import SearchField
from attend.plotting import new_figure


def snapshot_indices(log: EpisodeLog, times_s: Sequence[float]) -> list[int]:
    """Map entries (0 = prior) closest after each requested time.

    log: a mission's log; times_s: the requested mission times [s]."""
    metric_times = log.metric_times_s
    return [int(np.clip(np.searchsorted(metric_times, t, side="right") - 1, 0, len(metric_times) - 1)) for t in times_s]


def map_snapshots(field: SearchField, log: EpisodeLog, times_s: Sequence[float], decimals: int | None = None) -> dict[str, Any]:
    """Everything :func:`draw_map_snapshots` draws, as JSON-able lists: the field's side [m],
    grid shape, ground truth and obstacle boxes, and per snapshot the mission time [s], the map
    mean and variance and the image positions (x, y) [m] so far.

    field: the search field; log: the mission's log (with maps, ``keep_maps``); times_s: the
    snapshot times [s]; decimals: round the maps to this many decimals (None: as they are)."""
    def values(array: np.ndarray) -> list[float]:
        return (np.asarray(array) if decimals is None else np.round(array, decimals)).tolist()

    snapshots = []
    for index in snapshot_indices(log, times_s):
        poses = np.array(log.poses_m[:index]) if index else np.zeros((0, 3))
        snapshots.append({"time_s": float(log.metric_times_s[index]), "mean": values(log.means[index]),
                          "variance": values(log.variances[index]), "path_xy_m": poses[:, :2].tolist()})
    return {
        "size_m": float(field.grid.size_m), "shape": list(field.grid.shape), "truth": field.truth.astype(int).tolist(),
        "obstacles": [list(map(float, box.bounds)) for box in field.obstacles],
        "variance_max": float(np.max(log.variances[0])), "snapshots": snapshots,
    }


def _draw_boxes(ax, obstacles: Sequence[Sequence[float]]) -> None:
    from matplotlib.patches import Rectangle

    for x0, x1, y0, y1, _, _ in obstacles:
        ax.add_patch(Rectangle((x0, y0), x1 - x0, y1 - y0, fill=False, edgecolor="k", hatch="//", lw=1))


def _map_axes(ax, data: dict[str, Any], values, cmap: str, vmax: float, title: str):
    half = data["size_m"] / 2
    image = ax.imshow(np.reshape(values, data["shape"]), origin="lower", extent=[-half, half, -half, half], cmap=cmap,
                      vmin=0, vmax=vmax)
    ax.set_title(title)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    _draw_boxes(ax, data["obstacles"])
    return image


def draw_map_snapshots(data: dict[str, Any], path: Path) -> Path:
    """Ground truth, then belief mean (top) and variance (bottom) at each snapshot, from the
    output of :func:`map_snapshots`.

    data: the snapshots (:func:`map_snapshots`); path: the PNG written (returned)."""
    path = Path(path)
    columns = len(data["snapshots"]) + 1
    fig, axes = new_figure(path.parent, (3.1 * columns, 6.2), 2, columns, layout="constrained")
    _map_axes(axes[0, 0], data, data["truth"], "viridis", 1, "ground truth")
    axes[1, 0].axis("off")
    for c, snapshot in enumerate(data["snapshots"], start=1):
        t = snapshot["time_s"]
        im_mean = _map_axes(axes[0, c], data, snapshot["mean"], "viridis", 1, f"occupancy, t = {t:.0f} s")
        im_var = _map_axes(axes[1, c], data, snapshot["variance"], "magma", data["variance_max"], f"variance, t = {t:.0f} s")
        track = np.reshape(snapshot["path_xy_m"], (-1, 2))
        if len(track):
            axes[0, c].plot(track[:, 0], track[:, 1], "w.-", ms=3, lw=0.7)
    fig.colorbar(im_mean, ax=axes[0, -1], label="occupancy mean [probability]")
    fig.colorbar(im_var, ax=axes[1, -1], label="variance diag(P) [probability²]")
    fig.savefig(path, dpi=110)
    return path


def plot_maps(field: SearchField, log: EpisodeLog, times_s: Sequence[float], path: Path) -> Path:
    """Ground truth, then belief mean (top) and variance (bottom) at ``times_s``.

    field: the search field; log: the mission's log (with maps); times_s: snapshot times [s];
    path: the PNG written (returned)."""
    return draw_map_snapshots(map_snapshots(field, log, times_s), path)


def _extent(field: SearchField) -> list[float]:
    half = field.grid.size_m / 2
    return [-half, half, -half, half]


#: (metric, axis label with unit) of the per-image metrics drawn over flight time.
METRIC_LABELS = (("rse", "RSE [occupancy]"), ("trace", "trace(P) [occupancy²]"), ("people_found", "people found [count]"),
                 ("false_alarm_cells", "false-alarm cells [count]"))


def plot_path_3d(field: SearchField, log: EpisodeLog, path: Path) -> Path:
    """Flown waypoints and image poses in 3-D over the ground truth.

    field: the search field; log: the mission's log; path: the PNG written (returned)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig = Figure(figsize=(6.5, 5.5))
    FigureCanvasAgg(fig)
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
    return path


def plot_metrics(log: EpisodeLog, path: Path) -> Path:
    """RSE, trace(P), people found and false-alarm cells over flight time.

    log: the mission's log; path: the PNG written (returned)."""
    path = Path(path)
    t = log.metric_times_s
    fig, axes = new_figure(path.parent, (14, 3.2), 1, 4, layout="constrained")
    for ax, (key, label) in zip(axes, METRIC_LABELS):
        ax.step(t, log.series(key), where="post")
        ax.set_xlabel("flight time [s]")
        ax.set_ylabel(label)
    fig.savefig(path, dpi=110)
    return path


def write_gif(field: SearchField, log: EpisodeLog, path: Path, fps: float = 3.0) -> Path:
    """Animated GIF: one frame per image (belief mean with the path so far, variance).

    field: the search field; log: the mission's log (with maps); path: the GIF written
    (returned); fps: frames per second."""
    from matplotlib.animation import FuncAnimation, PillowWriter

    path = Path(path)
    shape = field.grid.shape
    fig, (ax_mean, ax_var) = new_figure(path.parent, (8, 4), 1, 2, layout="constrained")
    mean_image = ax_mean.imshow(log.means[0].reshape(shape), origin="lower", extent=_extent(field), cmap="viridis", vmin=0, vmax=1)
    var_image = ax_var.imshow(log.variances[0].reshape(shape), origin="lower", extent=_extent(field), cmap="magma", vmin=0,
                              vmax=float(np.max(log.variances[0])))
    (track,) = ax_mean.plot([], [], "w.-", ms=3, lw=0.8)
    (uav,) = ax_mean.plot([], [], "r^", ms=8)
    for ax in (ax_mean, ax_var):
        _draw_boxes(ax, [box.bounds for box in field.obstacles])
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
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
    return path
