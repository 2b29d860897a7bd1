"""map.png of ``attend plan``: P(person) over the area, the no-fly zones, the flown and planned
paths, the homes and the likely people, in metres east and north of the area's centre, with a
scale bar (on its own Agg canvas, no pyplot state)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from attend.action.log_odds import logistic

from attend.action.search_plots import block_max
from attend.plotting import figure

_COLOURS = ["tab:orange", "tab:red", "tab:pink", "tab:brown", "white", "tab:cyan", "tab:olive", "tab:gray"]


@dataclass
class MapPicture:
    """What map.png shows, as plain arrays (picklable, so another process can draw it).

    probability: P(person) per displayed block (NaN outside the searchable ground), row 0 south;
    extent_m: (x0, x1, y0, y1) [m]; area_rings / no_fly_rings: (n, 2) rings [m] of the area's
    boundaries and holes, and of the no-fly polygons; uav_names; flown / routes: per UAV (n, 2)
    [m] of the flown path and of the plan from its start; homes_m: (k, 2) [m]; targets_m: (t, 2)
    [m]; title: the line above the map."""

    probability: np.ndarray
    extent_m: tuple
    area_rings: list
    no_fly_rings: list
    uav_names: list
    flown: list
    routes: list
    homes_m: np.ndarray
    targets_m: np.ndarray
    title: str


def map_picture(mission, plans, summary: dict | None = None) -> MapPicture:
    """The :class:`MapPicture` of ``mission`` with ``plans``; summary: the mission's
    :meth:`Mission.summary` (None: computed)."""
    ground = mission.ground
    area_rings = []
    for polygon in getattr(ground.area_m, "geoms", [ground.area_m]):
        area_rings.append(np.asarray(polygon.exterior.coords))
        area_rings += [np.asarray(hole.coords) for hole in polygon.interiors]
    no_fly_rings = [] if ground.no_fly_m.is_empty else [
        np.asarray(polygon.exterior.coords) for polygon in getattr(ground.no_fly_m, "geoms", [ground.no_fly_m])]
    routes = [np.vstack([plan.start[None, :3], plan.waypoints[:, :3]])[:, :2] for plan in plans]
    summary = summary if summary is not None else mission.summary(plans)
    return MapPicture(
        probability=block_max(np.where(ground.searchable, logistic(mission.belief.log_odds), np.nan)),
        extent_m=tuple(float(v) for v in ground.grid.extent_m),
        area_rings=area_rings, no_fly_rings=no_fly_rings,
        uav_names=[uav.name for uav in mission.config.uavs],
        flown=[np.asarray(path)[:, :2] for path in mission.flown_paths_m()], routes=routes,
        homes_m=np.asarray(mission.homes_m, dtype=float).reshape(-1, 2),
        targets_m=np.asarray(mission.targets()[0], dtype=float).reshape(-1, 2),
        title=(f"{summary['targets']} likely people, P(all found) = {summary['p_all_found']:.2f}, "
               f"{100 * summary['area_covered_fraction']:.0f} % of the area seen"))


def plot_mission_map(mission, plans, path, summary: dict | None = None) -> Path:
    """Draw the mission's map with ``plans`` to ``path`` (PNG); summary: the mission's
    :meth:`Mission.summary` (None: computed). Returns ``path``."""
    return draw_map(map_picture(mission, plans, summary), path)


def draw_map(picture: MapPicture, path) -> Path:
    """Draw ``picture`` (a :class:`MapPicture`) to ``path`` (PNG). Returns ``path``."""
    from matplotlib.colors import LogNorm
    from matplotlib.ticker import FuncFormatter, LogLocator

    fig, ax = figure((7.6, 7.0))
    x0, x1, y0, y1 = picture.extent_m
    shown = picture.probability
    positive = shown[np.isfinite(shown) & (shown > 0)]
    floor = max(1e-6, float(positive.min())) if positive.size else 1e-6
    image = ax.imshow(np.clip(shown, floor, 1.0), origin="lower", extent=(x0, x1, y0, y1), cmap="viridis",
                      norm=LogNorm(vmin=floor, vmax=1.0), interpolation="nearest")
    bar = fig.colorbar(image, ax=ax, label="P(a person in the cell)", shrink=0.8)
    bar.ax.yaxis.set_major_locator(LogLocator(base=10.0))
    bar.ax.yaxis.set_major_formatter(FuncFormatter(lambda value, _: f"{value:.0e}".replace("e-0", "e-").replace("e+00", "")))
    bar.ax.yaxis.set_minor_formatter(FuncFormatter(lambda value, _: ""))  # plain text: no mathtext parser to load
    for ring in picture.area_rings:
        ax.plot(*ring.T, color="black", lw=1.0)
    for ring in picture.no_fly_rings:
        ax.fill(*ring.T, color="0.3", alpha=0.6, lw=0)
    for k, (name, flown, route) in enumerate(zip(picture.uav_names, picture.flown, picture.routes)):
        colour = _COLOURS[k % len(_COLOURS)]
        ax.plot(flown[:, 0], flown[:, 1], "-", color=colour, lw=1.0, label=f"{name} flown")
        ax.plot(route[:, 0], route[:, 1], "--", color=colour, lw=1.2, label=f"{name} plan")
        ax.plot(*picture.homes_m[k], "^", color=colour, mec="black", ms=8)
    if len(picture.targets_m):
        ax.plot(picture.targets_m[:, 0], picture.targets_m[:, 1], "x", color="yellow", ms=9, mew=2, label="likely person")
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
    ax.set_title(picture.title, fontsize=9)
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.09), ncol=3, fontsize=7, framealpha=0.7)
    fig.subplots_adjust(left=0.1, right=0.95, bottom=0.16, top=0.94)  # fixed: a tight layout costs 0.3 s
    fig.savefig(path, dpi=100)
    return Path(path)
