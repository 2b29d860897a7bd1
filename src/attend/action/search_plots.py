"""Figures of a search on the probability map, each on its own Agg canvas (no pyplot state): the
final map of P(person) with the paths, people and targets; people found, P(all found) and the
expected number of people against time."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from attend.plotting import figure

if TYPE_CHECKING:  # only named in annotations: attend plan's map.png needs block_max alone
    from attend.action.search_mission import SearchLog
    from attend.action.world import SearchWorld

#: Largest map side [cells] drawn as it is; larger maps are shown by block maxima.
DRAWN_CELLS = 800


def plot_search_map(world: SearchWorld, log: SearchLog, path: Path) -> Path:
    """The final P(person) per cell (log colour scale), buildings, the flown paths (one colour per
    UAV), the people (truth, circles) and the reported targets (crosses). Returns ``path``."""
    from matplotlib.colors import LogNorm

    fig, ax = figure((7.2, 7.0))
    x0, x1, y0, y1 = world.grid.extent_m
    probability = log.final_map.probability if log.final_map is not None else np.zeros(world.grid.shape)
    shown = block_max(np.where(world.searchable, probability, np.nan))
    floor = max(1e-6, float(np.nanmin(shown[shown > 0])) if np.any(shown > 0) else 1e-6)
    image = ax.imshow(np.clip(shown, floor, 1.0), origin="lower", extent=(x0, x1, y0, y1), cmap="viridis",
                      norm=LogNorm(vmin=floor, vmax=1.0), interpolation="nearest")
    fig.colorbar(image, ax=ax, label="P(a person's centre in the cell)")
    for box in world.buildings:
        bx0, bx1, by0, by1, _, height = box.bounds
        ax.fill([bx0, bx1, bx1, bx0], [by0, by0, by1, by1], color="0.35", alpha=0.8, lw=0)
    colours = ["tab:orange", "tab:red", "tab:pink", "tab:brown", "white", "tab:cyan", "tab:olive", "tab:gray"]
    for k, points in enumerate(log.paths_m):
        points = np.asarray(points)
        ax.plot(points[:, 0], points[:, 1], "-", color=colours[k % len(colours)], lw=1.2, label=f"UAV {k + 1} path")
    people = np.asarray(world.people_m)
    found = np.isfinite(log.person_found_times_s) if len(log.person_found_times_s) else np.zeros(len(people), bool)
    ax.plot(people[found, 0], people[found, 1], "o", mfc="none", mec="white", ms=9, label="person, found")
    ax.plot(people[~found, 0], people[~found, 1], "o", mfc="none", mec="red", ms=9, label="person, not found")
    if log.final_map is not None:
        targets, _ = log.final_map.targets()
        if len(targets):
            ax.plot(targets[:, 0], targets[:, 1], "x", color="yellow", ms=8, label="reported target")
    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)
    ax.set_xlabel("x (east) [m]")
    ax.set_ylabel("y (north) [m]")
    summary = f"{len(log.found_times_s)}/{log.people_total} found, {log.false_targets} false targets"
    ax.set_title(f"Probability map after {log.budget_s:.0f} s: {summary}")
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.1), ncol=3, fontsize=7, framealpha=0.7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    return Path(path)


def plot_found_over_time(log: SearchLog, path: Path) -> Path:
    """People found (steps) and the map's expected number of people against mission time, and
    P(all found) on a second axis. Returns ``path``."""
    fig, ax = figure((7.2, 4.0))
    times = np.concatenate([[0.0], np.asarray(log.times_s)])
    found = np.concatenate([[0], np.asarray(log.people_found)])
    ax.step(times, found, where="post", color="tab:blue", label="people found")
    if log.expected_people:
        ax.plot(times[1:], log.expected_people, color="tab:green", lw=1, label="expected people in the map (sum p)")
    ax.axhline(log.people_total, color="0.5", ls=":", lw=1, label="people in the area")
    ax.set_xlabel("mission time [s]")
    ax.set_ylabel("people")
    ax.set_xlim(0, log.budget_s)
    right = ax.twinx()
    if log.p_all_found:
        right.plot(times[1:], log.p_all_found, color="tab:purple", lw=1, label="P(all found)")
    right.set_ylim(0, 1.02)
    right.set_ylabel("P(all found)")
    lines = ax.get_legend_handles_labels()[0] + right.get_legend_handles_labels()[0]
    labels = ax.get_legend_handles_labels()[1] + right.get_legend_handles_labels()[1]
    ax.legend(lines, labels, loc="upper left", fontsize=8)
    ax.set_title("Search progress")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    return Path(path)


def block_max(values: np.ndarray) -> np.ndarray:
    """The map reduced by block maxima to at most DRAWN_CELLS per side (NaN blocks stay NaN)."""
    ny, nx = values.shape
    block = max(1, int(np.ceil(max(ny, nx) / DRAWN_CELLS)))
    if block == 1:
        return values
    pad_y, pad_x = (-ny) % block, (-nx) % block
    padded = np.pad(values, ((0, pad_y), (0, pad_x)), constant_values=np.nan)
    blocks = padded.reshape(padded.shape[0] // block, block, padded.shape[1] // block, block)
    with np.errstate(all="ignore"):
        import warnings

        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            return np.nanmax(blocks, axis=(1, 3))
