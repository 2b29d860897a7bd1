"""attend.action.mission.ground: routes inside the area (shortest routes against SciPy's
Dijkstra, route lengths against the routes' legs)."""

from __future__ import annotations

import numpy as np
import pytest

from attend.action.mission import Mission
from attend.action.mission.errors import MissionInputError
from attend.action.mission.examples import write_example_mission
from attend.action.mission.ground import shortest_routes


def test_shortest_routes_equal_scipys_dijkstra():
    """Random dense graphs (some edges missing, some nodes unreachable): the distances equal
    scipy.sparse.csgraph.dijkstra's (sums of the same edge lengths: to a few ulp), and following
    ``previous`` from any reachable node adds up to its distance."""
    from scipy.sparse.csgraph import csgraph_from_dense, dijkstra

    rng = np.random.default_rng(3)
    for _ in range(40):
        k = int(rng.integers(1, 60))
        lengths = rng.uniform(0.1, 100.0, (k, k))
        lengths = np.minimum(lengths, lengths.T)
        lengths[rng.random((k, k)) < rng.uniform(0.0, 0.9)] = np.inf
        lengths = np.minimum(lengths, lengths.T)
        np.fill_diagonal(lengths, np.inf)
        source = int(rng.integers(k))
        distance, previous = shortest_routes(lengths, source)
        expected = dijkstra(csgraph_from_dense(lengths, null_value=np.inf), indices=source)
        np.testing.assert_allclose(distance, expected, rtol=1e-12)
        assert previous[source] == -1
        for node in np.flatnonzero(np.isfinite(distance)):
            total, here = 0.0, node
            while here != source:
                total += lengths[previous[here], here]
                here = previous[here]
            assert total == pytest.approx(distance[node], rel=1e-12)
        assert np.all(previous[~np.isfinite(distance)] == -1)


def test_route_length_is_the_length_of_the_route(tmp_path):
    """SearchGround.route_length_m (the first corner's leg plus that corner's graph distance to
    the goal, kept per goal) equals the summed legs of SearchGround.route from points inside and
    outside the area, on random areas with a hole and a no-fly zone; a goal that cannot be
    reached raises the same error as route."""
    rng = np.random.default_rng(7)
    detoured = 0
    for case in range(6):
        path = write_example_mission(tmp_path / f"case{case}", seed=40 + case, size_m=float(rng.uniform(200, 900)),
                                     n_uavs=1, flight_time_s=300.0, home_outside=bool(case % 2))
        mission = Mission.from_file(path)
        ground, home = mission.ground, np.asarray(mission.homes_m[0], dtype=float)
        x0, x1, y0, y1 = ground.grid.extent_m
        for _ in range(40):
            start = np.array([rng.uniform(x0, x1), rng.uniform(y0, y1)])
            end = ground.entry_point(*home)
            try:
                route = np.vstack([start[None], ground.route(start, end), home[None]])
            except MissionInputError:
                with pytest.raises(MissionInputError):
                    ground.route_length_m(start, home, leave_area=True)
                continue
            detoured += len(route) > 3 + (not ground.inside(*start))
            expected = float(np.sum(np.hypot(*np.diff(route, axis=0).T)))
            assert ground.route_length_m(start, home, leave_area=True) == pytest.approx(expected, rel=1e-12)
    assert detoured >= 10  # routes around a hole or a no-fly zone were compared, not only straight lines
