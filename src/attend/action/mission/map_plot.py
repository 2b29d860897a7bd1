"""map.png of ``attend plan``: P(person) over the area, the no-fly zones, the flown and planned
paths, the homes and the likely people, in metres east and north of the area's centre, with a
scale bar (on its own Agg canvas, no pyplot state)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.special import expit

from attend.action.search_plots import block_max
from attend.plotting import figure

_COLOURS = ["tab:orange", "tab:red", "tab:pink", "tab:brown", "white", "tab:cyan", "tab:olive", "tab:gray"]


def plot_mission_map(mission, plans, path, summary: dict | None = None) -> Path:
    """Draw the mission's map with ``plans`` to ``path`` (PNG); summary: the mission's
    :meth:`Mission.summary` (None: computed). Returns ``path``."""
    from matplotlib.colors import LogNorm

    ground = mission.ground
    grid = ground.grid
    fig, ax = figure((7.6, 7.0))
    x0, x1, y0, y1 = grid.extent_m
    shown = block_max(np.where(ground.searchable, expit(mission.belief.log_odds), np.nan))
    positive = shown[np.isfinite(shown) & (shown > 0)]
    floor = max(1e-6, float(positive.min())) if positive.size else 1e-6
    image = ax.imshow(np.clip(shown, floor, 1.0), origin="lower", extent=(x0, x1, y0, y1), cmap="viridis",
                      norm=LogNorm(vmin=floor, vmax=1.0), interpolation="nearest")
    from matplotlib.ticker import FuncFormatter, LogLocator

    bar = fig.colorbar(image, ax=ax, label="P(a person in the cell)", shrink=0.8)
    bar.ax.yaxis.set_major_locator(LogLocator(base=10.0))
    bar.ax.yaxis.set_major_formatter(FuncFormatter(lambda value, _: f"{value:.0e}".replace("e-0", "e-").replace("e+00", "")))
    bar.ax.yaxis.set_minor_formatter(FuncFormatter(lambda value, _: ""))  # plain text: no mathtext parser to load
    for polygon in getattr(ground.area_m, "geoms", [ground.area_m]):
        ax.plot(*np.asarray(polygon.exterior.coords).T, color="black", lw=1.0)
        for hole in polygon.interiors:
            ax.plot(*np.asarray(hole.coords).T, color="black", lw=0.8)
    if not ground.no_fly_m.is_empty:
        for polygon in getattr(ground.no_fly_m, "geoms", [ground.no_fly_m]):
            ax.fill(*np.asarray(polygon.exterior.coords).T, color="0.3", alpha=0.6, lw=0)
    for k, (uav, flown) in enumerate(zip(mission.config.uavs, mission.flown_paths_m())):
        colour = _COLOURS[k % len(_COLOURS)]
        ax.plot(flown[:, 0], flown[:, 1], "-", color=colour, lw=1.0, label=f"{uav.name} flown")
        route = np.vstack([plans[k].start[None, :3], plans[k].waypoints[:, :3]])
        ax.plot(route[:, 0], route[:, 1], "--", color=colour, lw=1.2, label=f"{uav.name} plan")
        ax.plot(*mission.homes_m[k], "^", color=colour, mec="black", ms=8)
    positions, masses, _, _ = mission.targets()
    if len(positions):
        ax.plot(positions[:, 0], positions[:, 1], "x", color="yellow", ms=9, mew=2, label="likely person")
    span = max(x1 - x0, y1 - y0)
    bar = float(10 ** np.floor(np.log10(span / 4)))
    bar *= 5 if span / 4 >= 5 * bar else (2 if span / 4 >= 2 * bar else 1)
    bx, by = x0 + 0.05 * (x1 - x0), y0 + 0.05 * (y1 - y0)
    ax.plot([bx, bx + bar], [by, by], color="white", lw=4, solid_capstyle="butt")
    ax.plot([bx, bx + bar], [by, by], color="black", lw=2, solid_capstyle="butt")
    ax.text(bx + bar / 2, by + 0.015 * (y1 - y0), f"{bar:g} m", ha="center", va="bottom", fontsize=8)
    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)
    ax.set_aspect("equal")
    ax.set_xlabel("east of the area's centre [m]")
    ax.set_ylabel("north of the area's centre [m]")
    summary = summary if summary is not None else mission.summary(plans)
    ax.set_title(f"{summary['targets']} likely people, P(all found) = {summary['p_all_found']:.2f}, "
                 f"{100 * summary['area_covered_fraction']:.0f} % of the area seen", fontsize=9)
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.09), ncol=3, fontsize=7, framealpha=0.7)
    fig.subplots_adjust(left=0.1, right=0.95, bottom=0.16, top=0.94)  # fixed: a tight layout costs 0.3 s
    fig.savefig(path, dpi=100)
    return Path(path)
