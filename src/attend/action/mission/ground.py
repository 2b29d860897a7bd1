"""The search area on the ground: a local east-north frame, the map grid over the area, and
routes that stay inside the area and out of the no-fly zones.

Frame. lon/lat (WGS84) <-> (x east, y north) [m] by the azimuthal equidistant projection centred
on the area's centroid (pyproj): distances from the centre are exact, and over 2 km the scale
error elsewhere is below 1e-7.

Grid. Square cells of the mission's side over the area's bounding box (plus one cell); a cell is
searchable when its centre lies in the area and outside every no-fly polygon (a no-fly zone is
not searched: people there are out of the mission's reach).

Routes. The UAV flies inside F = (area - no-fly) shrunk by ``margin_m``: every leg of a plan is
checked against F' = (area - no-fly) shrunk by margin / 2, and a route from s to g is the
straight leg if F' covers it, else the shortest path through the vertices of F (the visibility
graph, an edge being a segment F' covers; Dijkstra). A start outside F (a home outside the area)
first flies straight to its nearest point of F: that transit leg is the only one allowed
outside the area.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import shapely
import shapely.ops
from pyproj import CRS, Transformer

from attend.action.mission.errors import MissionInputError
from attend.action.probability_map import MapGrid

#: Largest distance [m] from a UAV's home to the area.
MAX_HOME_DISTANCE_M = 10_000.0
#: Least margin [m] kept inside the area's boundary and outside no-fly polygons.
MIN_MARGIN_M = 1.5


class LocalFrame:
    """Azimuthal equidistant east-north frame [m] centred on (lon0, lat0) [deg], WGS84."""

    def __init__(self, lon0: float, lat0: float) -> None:
        self.lon0, self.lat0 = float(lon0), float(lat0)
        self.crs = CRS.from_proj4(f"+proj=aeqd +lat_0={self.lat0!r} +lon_0={self.lon0!r} +x_0=0 +y_0=0 "
                                  "+datum=WGS84 +units=m +no_defs")
        self._forward = Transformer.from_crs("EPSG:4326", self.crs, always_xy=True)
        self._inverse = Transformer.from_crs(self.crs, "EPSG:4326", always_xy=True)

    def to_local(self, lon, lat) -> tuple[np.ndarray, np.ndarray]:
        """(x east, y north) [m] of lon, lat [deg] (arrays or scalars)."""
        x, y = self._forward.transform(np.asarray(lon, dtype=float), np.asarray(lat, dtype=float))
        return np.asarray(x, dtype=float), np.asarray(y, dtype=float)

    def to_lon_lat(self, x, y) -> tuple[np.ndarray, np.ndarray]:
        """(lon, lat) [deg] of x east, y north [m]."""
        lon, lat = self._inverse.transform(np.asarray(x, dtype=float), np.asarray(y, dtype=float))
        return np.asarray(lon, dtype=float), np.asarray(lat, dtype=float)

    def geometry_to_local(self, geometry):
        """A shapely geometry in lon/lat as the same geometry in (x, y) [m]."""
        return shapely.transform(geometry, lambda xy: np.column_stack(self.to_local(xy[:, 0], xy[:, 1])))

    def geometry_to_lon_lat(self, geometry):
        """A shapely geometry in (x, y) [m] as the same geometry in lon/lat."""
        return shapely.transform(geometry, lambda xy: np.column_stack(self.to_lon_lat(xy[:, 0], xy[:, 1])))


@dataclass
class SearchGround:
    """The area of one mission in the local frame (module docstring).

    frame: the :class:`LocalFrame`; area_m: the area polygon [m]; no_fly_m: the union of the
    no-fly polygons [m] (empty geometry if none); grid: the map grid; searchable: (ny, nx) bool;
    margin_m: the margin kept from the boundary and the no-fly zones [m]; in_area: (ny, nx)
    bool, the cells whose centres lie in the area (no-fly zones included)."""

    frame: LocalFrame
    area_m: object
    no_fly_m: object
    grid: MapGrid
    searchable: np.ndarray
    margin_m: float
    in_area: np.ndarray
    _free: object = field(init=False, repr=False)
    _allowed: object = field(init=False, repr=False)
    _nodes: np.ndarray = field(init=False, repr=False)
    _graph: np.ndarray = field(init=False, repr=False)
    _to_goal: dict = field(init=False, repr=False, default_factory=dict)

    def __post_init__(self) -> None:
        free = shapely.difference(self.area_m, self.no_fly_m) if not self.no_fly_m.is_empty else self.area_m
        inner = free.buffer(-self.margin_m, join_style="mitre")
        if inner.is_empty:
            raise MissionInputError(f"the area minus the no-fly zones, shrunk by the flight margin {self.margin_m:g} m, "
                                    "is empty: expected an area wide enough to fly in")
        self._free = inner.simplify(self.margin_m / 4, preserve_topology=True)
        self._allowed = free.buffer(-self.margin_m / 2, join_style="mitre")
        shapely.prepare(self._allowed)
        shapely.prepare(self._free)
        self._nodes = ring_vertices(self._free)
        self._graph = self._visibility(self._nodes)

    @classmethod
    def from_polygons(cls, boundary_lon_lat, exclusions_lon_lat, cell_size_m: float) -> "SearchGround":
        """The ground of an area given in lon/lat (shapely Polygon or MultiPolygon) minus the
        no-fly polygons, with square cells of ``cell_size_m`` [m]."""
        centroid = boundary_lon_lat.centroid
        frame = LocalFrame(centroid.x, centroid.y)
        area = frame.geometry_to_local(boundary_lon_lat)
        if not area.is_valid or area.is_empty or area.area <= 0:
            raise MissionInputError("the area has no surface once projected: expected a polygon in lon/lat degrees")
        exclusions = [frame.geometry_to_local(p) for p in exclusions_lon_lat]
        no_fly = shapely.union_all(exclusions) if exclusions else shapely.Polygon()
        x0, y0, x1, y1 = area.bounds
        s = float(cell_size_m)
        nx, ny = int(np.ceil((x1 - x0) / s)) + 2, int(np.ceil((y1 - y0) / s)) + 2
        if nx * ny > 16_000_000:
            raise MissionInputError(f"the area ({x1 - x0:.0f} m x {y1 - y0:.0f} m) at {s:g} m cells needs {nx * ny} cells; "
                                    "expected at most 16 million: raise cell_size_m")
        grid = MapGrid(nx, ny, s, (x0 - s, y0 - s))
        xx, yy = np.meshgrid(grid.centres_x, grid.centres_y)
        in_area = shapely.contains_xy(area, xx, yy)
        searchable = in_area.copy()
        if not no_fly.is_empty:
            searchable &= ~shapely.contains_xy(no_fly, xx, yy)
        if not searchable.any():
            raise MissionInputError(f"no cell of {s:g} m lies in the area outside the no-fly zones: expected a larger "
                                    "area or smaller cells")
        margin = max(MIN_MARGIN_M, 0.5 * s)
        return cls(frame, area, no_fly, grid, searchable, margin, in_area)

    @property
    def flyable(self):
        """F: the area minus the no-fly zones, shrunk by ``margin_m`` (module docstring)."""
        return self._free

    # ------------------------------------------------------------------------------------
    def inside(self, x, y) -> np.ndarray:
        """Whether points (x, y) [m] lie where the UAV may fly (F', module docstring)."""
        return shapely.contains_xy(self._allowed, np.asarray(x, float), np.asarray(y, float))

    def legs_allowed(self, starts: np.ndarray, ends: np.ndarray) -> np.ndarray:
        """(m,) bool: the straight legs starts[i] -> ends[i] ((m, >=2) [m]) lie in F'."""
        starts, ends = np.asarray(starts, float), np.asarray(ends, float)
        if len(starts) == 0:
            return np.zeros(0, dtype=bool)
        coords = np.stack([starts[:, :2], ends[:, :2]], axis=1)
        same = np.all(np.abs(coords[:, 0] - coords[:, 1]) < 1e-9, axis=1)
        coords[same, 1] += 1e-6
        return shapely.covers(self._allowed, shapely.linestrings(coords))

    def entry_point(self, x: float, y: float) -> np.ndarray:
        """The nearest point (x, y) [m] of F to (x, y) (itself when it lies in F')."""
        if self.inside(x, y):
            return np.array([x, y], dtype=float)
        point = shapely.ops.nearest_points(self._free, shapely.Point(x, y))[0]
        return np.array([point.x, point.y])

    def route(self, start_xy, goal_xy) -> np.ndarray:
        """Waypoints (j, 2) [m] after ``start_xy`` that end at ``goal_xy``, every leg in F'
        (a start outside first goes to its entry point). Raises MissionInputError when the
        goal cannot be reached inside the area (it lies outside it, or in another part of it)."""
        start, goal = np.asarray(start_xy, float)[:2], np.asarray(goal_xy, float)[:2]
        start, points = self._entered(start)
        if self.legs_allowed(start[None], goal[None])[0]:
            return np.array(points + [goal])
        path = self._graph_path(start, goal)
        if path is None:
            raise MissionInputError(f"no route inside the area from ({start[0]:.1f}, {start[1]:.1f}) m to "
                                    f"({goal[0]:.1f}, {goal[1]:.1f}) m east/north of its centre")
        return np.array(points + list(path))

    def route_length_m(self, start_xy, goal_xy, leave_area: bool = False) -> float:
        """Length [m] of the route from start_xy to goal_xy ((x, y) [m]); leave_area: the goal
        may lie outside the area (a home): route to its entry point, then straight to it."""
        start, goal = np.asarray(start_xy, float)[:2], np.asarray(goal_xy, float)[:2]
        end = self.entry_point(*goal) if leave_area else goal
        inside, _ = self._entered(start)
        length = float(np.hypot(*(goal - end))) + float(np.hypot(*(inside - start)))
        start = inside
        if self.legs_allowed(start[None], end[None])[0]:
            return length + float(np.hypot(*(end - start)))
        # the shortest route's first corner: min over the corners seen from start of the leg to it
        # plus the corner's graph distance to the goal (kept per goal: every call of a plan asks
        # for the same home)
        nodes = self._nodes
        to_goal = self._graph_distances_to(end)
        if len(nodes):
            seen = self.legs_allowed(np.broadcast_to(start, nodes.shape), nodes)
            first = np.where(seen, np.maximum(np.hypot(*(nodes - start).T), 1e-9) + to_goal, np.inf)
            if np.isfinite(first.min()):
                return length + float(first.min())
        raise MissionInputError(f"no route inside the area from ({start[0]:.1f}, {start[1]:.1f}) m to "
                                f"({end[0]:.1f}, {end[1]:.1f}) m east/north of its centre")

    def _entered(self, start: np.ndarray) -> tuple[np.ndarray, list]:
        """(where a route from ``start`` begins inside F', [that point] when start lies outside
        F' (the first waypoint), else [])."""
        if self.inside(*start):
            return start, []
        entry = self.entry_point(*start)
        return entry, [entry]

    def _graph_distances_to(self, goal: np.ndarray) -> np.ndarray:
        """(k,) [m] length of the shortest route from each corner of the graph to ``goal`` (inf:
        none), kept per goal."""
        key = (float(goal[0]), float(goal[1]))
        if key not in self._to_goal:
            lengths = self._graph_with((goal,))
            self._to_goal[key] = shortest_routes(lengths, len(self._nodes))[0][: len(self._nodes)]
        return self._to_goal[key]

    def _graph_with(self, points) -> np.ndarray:
        """The corners' visibility graph (k + j, k + j) [m] with ``points`` (j of (x, y)) appended:
        leg lengths (at least 1e-9 m) where the straight leg lies in F', inf where it does not."""
        nodes = self._nodes
        k = len(nodes)
        lengths = np.full((k + len(points), k + len(points)), np.inf)
        lengths[:k, :k] = self._graph
        if k:
            for index, point in enumerate(points, start=k):
                ok = self.legs_allowed(np.broadcast_to(point, nodes.shape), nodes)
                lengths[index, :k] = lengths[:k, index] = np.where(
                    ok, np.maximum(np.hypot(*(nodes - point).T), 1e-9), np.inf)
        return lengths

    def _graph_path(self, start: np.ndarray, goal: np.ndarray):
        k = len(self._nodes)
        if k == 0:
            return None
        distance, previous = shortest_routes(self._graph_with((start, goal)), k)
        if not np.isfinite(distance[k + 1]):
            return None
        path, node = [], k + 1
        all_nodes = np.vstack([self._nodes, start[None], goal[None]])
        while node != k:
            path.append(all_nodes[node])
            node = previous[node]
        return path[::-1]

    def _visibility(self, nodes: np.ndarray) -> np.ndarray:
        k = len(nodes)
        lengths = np.full((k, k), np.inf)
        if k < 2:
            return lengths
        i, j = np.triu_indices(k, 1)
        ok = self.legs_allowed(nodes[i], nodes[j])
        d = np.maximum(np.hypot(*(nodes[j] - nodes[i]).T), 1e-9)
        lengths[i[ok], j[ok]] = lengths[j[ok], i[ok]] = d[ok]
        return lengths


def shortest_routes(lengths: np.ndarray, source: int) -> tuple[np.ndarray, np.ndarray]:
    """Dijkstra's shortest routes on a dense graph: (distance (k,) [m] from ``source`` to each
    node, inf when unreachable; previous (k,) the node before each on its route, -1 for the source
    and unreachable nodes). lengths: (k, k) edge lengths >= 0, inf where there is no edge. O(k^2),
    written here because the graphs are small (a polygon's corners) and importing
    scipy.sparse.csgraph costs a third of a second of each ``attend plan`` call."""
    k = len(lengths)
    distance = np.full(k, np.inf)
    distance[source] = 0.0
    previous = np.full(k, -1, dtype=np.intp)
    done = np.zeros(k, dtype=bool)
    for _ in range(k):
        open_distance = np.where(done, np.inf, distance)
        node = int(np.argmin(open_distance))
        if not np.isfinite(open_distance[node]):
            break
        done[node] = True
        through = distance[node] + lengths[node]
        better = ~done & (through < distance)
        distance[better] = through[better]
        previous[better] = node
    return distance, previous


def ring_vertices(geometry) -> np.ndarray:
    """(k, 2) distinct ring vertices (exteriors and holes) of ``geometry``, a Polygon or MultiPolygon."""
    rings = []
    for polygon in getattr(geometry, "geoms", [geometry]):
        rings.append(np.asarray(polygon.exterior.coords)[:-1])
        rings.extend(np.asarray(hole.coords)[:-1] for hole in polygon.interiors)
    return np.vstack(rings) if rings else np.zeros((0, 2))


def check_home_distance(ground: SearchGround, home_xy, name: str, file) -> None:
    """MissionInputError when a home lies more than ``MAX_HOME_DISTANCE_M`` from the area.

    ground: the SearchGround; home_xy: the home (x, y) [m]; name: the UAV's name; file: the
    mission file (named in the error)."""
    distance = float(ground.area_m.distance(shapely.Point(*home_xy)))
    if distance > MAX_HOME_DISTANCE_M:
        raise MissionInputError(f"the home lies {distance / 1000:.1f} km from the area; expected at most "
                                f"{MAX_HOME_DISTANCE_M / 1000:g} km (a home in lon, lat order?)", file=file,
                                column=f"uav {name!r} home")
