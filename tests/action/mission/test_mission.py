"""attend.action.mission.mission: plans inside the area and within the flight time on random
areas, replay over split logs, the map from the logs, targets."""

from __future__ import annotations

import numpy as np
import pytest
import shapely

from attend.action.mission import Mission
from attend.action.mission.examples import write_example_mission
from attend.action.mission.errors import MissionInputError
from attend.action.mission.flight_logs import write_flight_logs
from attend.action.mission.mission import footprint_cells
from attend.action.mission.simulate import simulate_mission
from attend.action.probability_map import MapGrid

#: Slack [m] of the geometry checks: a leg may touch the boundary within this distance.
GEOMETRY_TOLERANCE_M = 1e-6


def _check_plans(mission: Mission, plans) -> list[str]:
    """Violations: a waypoint or leg outside the area or inside a no-fly polygon (after the
    transit leg of a UAV that starts outside the area), or a plan that ends too late to fly
    straight home within the flight time."""
    ground = mission.ground
    area = ground.area_m.buffer(GEOMETRY_TOLERANCE_M)
    no_fly = ground.no_fly_m.buffer(-GEOMETRY_TOLERANCE_M) if not ground.no_fly_m.is_empty else None
    bad = []
    for k, plan in enumerate(plans):
        if len(plan.waypoints) == 0:
            continue
        points = np.vstack([plan.start[None, :2], plan.waypoints[:, :2]])
        first = 0
        if not area.covers(shapely.Point(points[0])):
            first = 1  # the transit from a home outside the area to its entry point
        for a, b in zip(points[first:-1], points[first + 1:]):
            leg = shapely.LineString([a, b]) if np.hypot(*(b - a)) > 0 else shapely.Point(a)
            if not area.covers(leg):
                bad.append(f"uav {k}: leg {a} -> {b} leaves the area")
            if no_fly is not None and no_fly.intersects(leg):
                bad.append(f"uav {k}: leg {a} -> {b} enters a no-fly zone")
        speed = mission.config.uavs[k].speed_m_s
        straight_home = float(np.hypot(*(points[-1] - mission.homes_m[k]))) / speed
        if plan.waypoints[-1, 3] + straight_home > mission.config.flight_time_s + 1e-6:
            bad.append(f"uav {k}: plan ends at {plan.waypoints[-1, 3]:.1f} s, home at "
                       f"{plan.waypoints[-1, 3] + straight_home:.1f} s > {mission.config.flight_time_s} s")
        times = np.r_[plan.start[3], plan.waypoints[:, 3]]
        if np.any(np.diff(times) < -1e-9):
            bad.append(f"uav {k}: waypoint times go backwards")
    return bad


@pytest.mark.slow
def test_plans_stay_in_the_area_and_the_flight_time_on_random_areas(tmp_path):
    """50 random concave areas with a hole and a no-fly zone, 100 m - 2 km, 1-3 UAVs (homes
    inside, or outside the area), short and long flight times, both planners: no leg outside
    the area or in a no-fly zone, no plan past the flight time with the way home."""
    rng = np.random.default_rng(20261126)
    violations, plans_checked = [], 0
    for case in range(50):
        size = float(np.exp(rng.uniform(np.log(100), np.log(2000))))
        uavs = int(rng.integers(1, 4))
        flight = float(rng.choice([60.0, 240.0, 900.0]))
        path = write_example_mission(tmp_path / f"case{case}", seed=case, size_m=size, n_uavs=uavs,
                                     flight_time_s=flight, cell_size_m=max(1.0, size / 200),
                                     home_outside=bool(case % 5 == 4))
        mission = Mission.from_file(path)
        for planner in ("efe", "lawnmower") if case % 3 == 0 else ("efe",):
            plans = mission.plan(planner, horizon_s=90.0)
            plans_checked += len(plans)
            violations += [f"case {case} ({size:.0f} m, {planner}): {v}" for v in _check_plans(mission, plans)]
    assert plans_checked >= 90
    assert violations == []


def test_plans_after_flying_part_of_the_mission_stay_inside(tmp_path):
    """Mid-mission (logs flown by the simulator, 2 UAVs): the next plans still stay inside and
    end in time, and start where each UAV's last image was."""
    path = write_example_mission(tmp_path, seed=7, size_m=300.0, n_uavs=2, flight_time_s=200.0, cell_size_m=2.0)
    mission = Mission.from_file(path)
    simulate_mission(mission, seed=1, replan_s=30.0)
    for elapsed in (60.0, 150.0, 190.0):
        keep = mission.logs.image_time_s <= elapsed
        partial = mission.logs.subset(keep)
        mission.set_logs(partial)
        plans = mission.plan()
        assert _check_plans(mission, plans) == []
        for k, plan in enumerate(plans):
            pose, t = mission.uav_state(k)
            np.testing.assert_allclose(plan.start[:3], pose)
            assert plan.start[3] == t
            if len(plan.waypoints):
                assert plan.waypoints[0, 3] > t


def test_appending_images_gives_the_map_of_a_rebuild(tmp_path):
    """Fusing the images in three batches as they come equals rebuilding from all of them
    (same updates in the same order: equal to the last bit)."""
    path = write_example_mission(tmp_path, seed=2, size_m=250.0, n_uavs=2, flight_time_s=150.0, cell_size_m=2.0)
    mission = Mission.from_file(path)
    simulate_mission(mission, seed=4, replan_s=50.0)  # fuses batch by batch
    incremental = mission.belief.log_odds.copy()
    mission.set_logs(mission.logs)
    np.testing.assert_array_equal(mission.belief.log_odds, incremental)


def test_found_checks_time_the_finds_without_changing_the_flight(tmp_path):
    """Looking at the targets every 10 s instead of at each 30 s replan leaves the flight, its
    logs and the final map as they were (the same images fused in the same order), and finds
    each person no later, and no earlier than one check step before."""
    path = write_example_mission(tmp_path, seed=7, size_m=300.0, n_uavs=2, people=4, flight_time_s=200.0)
    coarse_mission, fine_mission = Mission.from_file(path), Mission.from_file(path)
    coarse = simulate_mission(coarse_mission, seed=7, planner="efe", found_check_s=30.0)
    fine = simulate_mission(fine_mission, seed=7, planner="efe", found_check_s=10.0)
    a, b = coarse_mission.logs, fine_mission.logs  # rows in the order they were appended
    order_a, order_b = a.fusion_order(), b.fusion_order()
    for column in ("image_time_s", "image_uav", "image_lon", "image_lat", "image_alt_m"):
        np.testing.assert_array_equal(getattr(a, column)[order_a], getattr(b, column)[order_b])
    np.testing.assert_array_equal(np.sort(a.detection_lon), np.sort(b.detection_lon))
    np.testing.assert_array_equal(coarse_mission.belief.log_odds, fine_mission.belief.log_odds)
    assert np.isfinite(coarse.found_times_s).sum() >= 1
    np.testing.assert_array_equal(np.isfinite(coarse.found_times_s), np.isfinite(fine.found_times_s))
    found = np.isfinite(coarse.found_times_s)
    assert np.all(fine.found_times_s[found] <= coarse.found_times_s[found])
    assert np.all(fine.found_times_s[found] > coarse.found_times_s[found] - 30.0)
    assert np.any(fine.found_times_s[found] < coarse.found_times_s[found])  # the finer clock is used
    with pytest.raises(MissionInputError, match="found_check_s"):
        simulate_mission(Mission.from_file(path), seed=7, found_check_s=0.0)


def test_replay_split_over_calls_gives_the_same_targets_and_plan(tmp_path):
    """The same logs given to `attend plan` whole, or growing over 3 or 10 calls into one
    folder, end with byte-identical plan.csv and targets.csv."""
    from attend.cli import main

    path = write_example_mission(tmp_path / "m", seed=11, size_m=250.0, n_uavs=2, flight_time_s=180.0,
                                 cell_size_m=2.0)
    mission = Mission.from_file(path)
    simulate_mission(mission, seed=3, replan_s=30.0)
    names = [u.name for u in mission.config.uavs]
    times = np.sort(mission.logs.image_time_s)
    times = times[times <= 120.0]  # the logs of the first 120 s of 180: a plan is left to compare
    finals = {}
    for calls in (1, 3, 10):
        out = tmp_path / f"out{calls}"
        for c in range(1, calls + 1):
            cut = times[int(np.ceil(c / calls * len(times))) - 1]
            part = mission.logs.subset(mission.logs.image_time_s <= cut)
            images, detections = tmp_path / f"images{calls}.csv", tmp_path / f"detections{calls}.csv"
            write_flight_logs(part, names, images, detections)
            assert main(["plan", str(path), "--out", str(out), "--images", str(images), "--detections",
                         str(detections), "--no-plot"]) == 0
        finals[calls] = ((out / "plan.csv").read_bytes(), (out / "targets.csv").read_bytes())
    assert finals[1] == finals[3] == finals[10]
    assert len(finals[1][0].splitlines()) > 1


def test_lawnmower_with_more_uavs_than_strips_keeps_the_spare_uav_home(tmp_path):
    """A 150 m area swept at 60 m by three UAVs has strips for two: the third gets an empty
    plan (it stays home) instead of an error, and the other two still sweep and find people."""
    import dataclasses

    from attend.action.mission.lawnmower import lawnmower_patterns

    path = write_example_mission(tmp_path, seed=3, size_m=150.0, n_uavs=3, people=3, flight_time_s=120.0)
    mission = Mission.from_file(path)
    mission.config = dataclasses.replace(mission.config, lawnmower_altitude_m=60.0)
    lengths = [len(p) for p in lawnmower_patterns(mission)]
    assert sorted(lengths)[0] == 1 and sorted(lengths)[1] > 1  # the case under test: one UAV without a strip
    plans = mission.plan("lawnmower")
    assert [len(p.waypoints) == 0 for p in plans] == [n == 1 for n in lengths]
    result = simulate_mission(mission, seed=3, planner="lawnmower")
    assert np.isfinite(result.found_times_s).any()


def test_footprint_rotates_with_the_heading():
    """Heading north: the across-track side lies along x (east); heading east: along y. A
    60 x 45 degree camera at 20 m sees 2 h tan(30) = 23.1 m across and 2 h tan(22.5) = 16.6 m
    along."""
    grid = MapGrid(200, 200, 0.25, (-25.0, -25.0))
    h = 20.0
    across, along = 2 * h * np.tan(np.radians(30)), 2 * h * np.tan(np.radians(22.5))
    for yaw, (wx, wy) in ((0.0, (across, along)), (90.0, (along, across)), (180.0, (across, along))):
        window, visible = footprint_cells(grid, 0.0, 0.0, h, yaw, (60.0, 45.0))
        cx, cy = grid.window_centres(window)
        xx, yy = np.meshgrid(cx, cy)
        assert np.ptp(xx[visible]) == pytest.approx(wx, abs=2 * grid.cell_size_m)
        assert np.ptp(yy[visible]) == pytest.approx(wy, abs=2 * grid.cell_size_m)
    # at 45 degrees the footprint is the rotated rectangle: its area is unchanged
    _, visible = footprint_cells(grid, 0.0, 0.0, h, 45.0, (60.0, 45.0))
    assert visible.sum() * grid.cell_area_m2 == pytest.approx(across * along, rel=0.03)


def test_targets_sit_on_the_people_the_simulator_placed(tmp_path):
    """A simulated mission on a 200 m area: every person has a target within the found radius,
    and every target is a person (a regression check of the closed loop on one seed)."""
    path = write_example_mission(tmp_path, seed=5, size_m=200.0, n_uavs=1, people=3, flight_time_s=300.0,
                                 cell_size_m=2.0)
    mission = Mission.from_file(path)
    result = simulate_mission(mission, seed=5)
    assert np.all(np.isfinite(result.found_times_s))
    assert result.false_targets == 0
    positions, masses, counts, _ = mission.targets()
    assert np.all((masses >= 0.5) & (masses <= 1.0))
    assert np.all(np.diff(masses) <= 0)
    assert np.all(counts >= 1)


def test_prior_map_from_csv_and_geotiff_puts_the_mass_where_the_weights_are(tmp_path):
    """A prior of weight 1 on the east half of the area and 0 on the west half, as CSV points
    and as the GeoTIFF attend writes: the prior's mass lies in the east half, and both files
    give the same map (the GeoTIFF is read back through its own CRS)."""
    from attend.action.mission.plan_files import write_geotiff
    from attend.action.mission.prior_files import read_prior_weights

    path = write_example_mission(tmp_path, seed=8, size_m=200.0, cell_size_m=2.0)
    mission = Mission.from_file(path)
    ground = mission.ground
    xx, yy = np.meshgrid(ground.grid.centres_x, ground.grid.centres_y)
    east = (xx > 0).astype(float)
    lon, lat = ground.frame.to_lon_lat(xx.ravel(), yy.ravel())
    rows = ["lon,lat,weight"] + [f"{a:.9f},{b:.9f},{w:g}" for a, b, w in zip(lon, lat, east.ravel())]
    (tmp_path / "prior.csv").write_text("\n".join(rows) + "\n")
    from_csv = read_prior_weights(tmp_path / "prior.csv", ground)
    np.testing.assert_array_equal(from_csv, east)
    write_geotiff(tmp_path / "prior.tif", east, ground.grid.origin_m, ground.grid.cell_size_m, ground.frame.crs.to_wkt())
    from_tif = read_prior_weights(tmp_path / "prior.tif", ground)
    np.testing.assert_array_equal(from_tif, east)
    text = path.read_text().replace("[search]", '[search]\nprior_map = "prior.csv"')
    path.write_text(text)
    prior = Mission.from_file(path).prior.probability
    assert prior[xx < 0].sum() < 1e-9 * prior.sum()
    assert prior.sum() == pytest.approx(5.0, rel=1e-9)


def test_at_least_is_the_poisson_binomial_tail():
    """P(at least n of 6 independent events) against the sum over all 2^6 outcomes."""
    import itertools

    from attend.action.mission.mission import at_least

    rng = np.random.default_rng(1)
    q = rng.random(6)
    for n in range(8):
        brute = sum(np.prod([q[i] if bit else 1 - q[i] for i, bit in enumerate(bits)])
                    for bits in itertools.product([0, 1], repeat=6) if sum(bits) >= n)
        assert at_least(q, n) == pytest.approx(brute, abs=1e-14)
