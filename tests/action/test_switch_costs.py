"""Costs of switching between action and perception in the UAV search: motion blur of images
taken while moving, planning latency spent hovering. Off by default: then the episode is the plain
one, bit for bit (both run here, in one process).

No end value of a whole mission is stored here: a mission is a chain of arg-max decisions over
candidate scores, and on another BLAS kernel a near tie falls the other way and the UAV flies
another path (seed 1 under OPENBLAS_CORETYPE=PRESCOTT: final RSE 3.91 against 3.74), so such a
number holds only on the machine that wrote it."""

import numpy as np
import pytest

from attend.action import ActionInputError, Camera, Detector, FlightModel, PlanningSetup, make_field, make_planner
from attend.rhythm.replanning import fly_scheduled_mission, make_replan_policy, path_gain


def _episode(policy, seed=1, detector=None, latency=None, cma=6, mode="hover"):
    field = make_field(seed)
    setup = PlanningSetup(field, Camera(), detector or Detector(), FlightModel(), lookahead_waypoints=5,
                          cma_evaluations=cma)
    planner = make_planner("precision_gain", setup, seed)
    kwargs = {} if latency is None else dict(planning_latency_s=latency, latency_mode=mode)
    return fly_scheduled_mission(field, planner, make_replan_policy(policy), 150.0, seed, diagonal=True, **kwargs)


@pytest.mark.parametrize("policy", ["segment", "fixed_20s", "precision", "oscillator"])
def test_zero_cost_limit_is_the_plain_episode_bit_for_bit(policy):
    plain = _episode(policy)
    zero = _episode(policy, detector=Detector(motion_blur_per_speed=0.0, motion_blur_per_turn_rate=0.0), latency=0.0)
    for key in ("rse", "trace", "people_found", "false_alarm_cells"):
        assert np.array_equal(plain.series(key), zero.series(key))
    assert plain.times_s == zero.times_s and plain.replan_times_s == zero.replan_times_s
    assert zero.hover_s == 0.0


def test_blur_lowers_detection_precision_monotonically_with_speed_and_turn_rate():
    sharp = Detector()
    blurred = Detector(motion_blur_per_speed=0.2, motion_blur_per_turn_rate=0.5)
    speeds = np.linspace(0.0, 5.0, 11)
    for h in (5.0, 10.0, 14.0):
        precision = 1.0 / blurred.image_noise_variance(h, speeds)
        tpr = blurred.image_true_positive_rate(h, speeds)
        assert np.all(np.diff(precision) < 0) and np.all(np.diff(tpr) < 0)
        assert precision[0] == pytest.approx(1.0 / sharp.noise_variance(h), rel=1e-15)  # hovering: sharp
        assert tpr[0] == pytest.approx(sharp.true_positive_rate(h), rel=1e-15)
        assert np.all(tpr > blurred.false_positive_rate(h))  # never worse than chance
        turning = 1.0 / blurred.image_noise_variance(h, 2.0, np.linspace(0, 2, 5))
        assert np.all(np.diff(turning) < 0)
    # stronger blur, lower precision at the same speed
    weak, strong = Detector(motion_blur_per_speed=0.1), Detector(motion_blur_per_speed=0.4)
    assert strong.image_noise_variance(10.0, 3.0) > weak.image_noise_variance(10.0, 3.0) > sharp.noise_variance(10.0)
    assert blurred.blur_factor(0.0, 0.0) == 1.0
    assert blurred.blur_factor(5.0) == pytest.approx(1.0 / 2.0)


def test_speed_profile_is_the_derivative_of_the_distance_flown():
    flight = FlightModel()
    for length in (2.0, 8.3, 30.0):  # triangle and trapezoid profiles
        total = float(flight.segment_duration(length))
        t = np.linspace(0.01, total - 0.01, 200)
        numeric = (flight.distance_after(t + 1e-6, length) - flight.distance_after(t - 1e-6, length)) / 2e-6
        assert np.allclose(flight.speed_after(t, length), numeric, atol=1e-4)
        assert flight.speed_after(0.0, length) == 0.0 and flight.speed_after(total, length) == 0.0
        assert flight.speed_after(total + 3.0, length) == 0.0  # hovering at the waypoint
        assert flight.speed_after(t, length).max() <= flight.speed_m_s + 1e-12


def test_blurred_images_are_worth_less_to_the_schedule():
    field = make_field(0)
    path = np.array([[10.0, 14.0, 8.0], [-12.0, -14.0, 8.0], [12.0, 14.0, 8.0]])  # long legs: images in flight
    gains = []
    for blur in (0.0, 0.1, 0.4):
        setup = PlanningSetup(field, Camera(), Detector(motion_blur_per_speed=blur), FlightModel(), cma_evaluations=0)
        planner = make_planner("precision_gain", setup, 0)
        from attend.action import OccupancyMap
        gains.append(path_gain(planner, OccupancyMap.prior(field.grid, diagonal=True), field.start_pose_m, path, 0.0, 150.0))
    assert gains[0][1] == gains[1][1] == gains[2][1]  # same flight time
    assert gains[0][0] > gains[1][0] > gains[2][0] > 0


def test_planning_latency_costs_flight_time():
    fast = _episode("continuous", seed=0, cma=0)
    slow = _episode("continuous", seed=0, latency=5.0, cma=0)
    assert slow.hover_s == pytest.approx(5.0 * slow.n_replans)
    flown = lambda log: float(np.sum(np.linalg.norm(np.diff(np.asarray(log.waypoints_m), axis=0), axis=1)))
    assert flown(slow) < flown(fast)
    # images come on the mission clock either way; those taken in the first hover are at the start pose
    assert len(slow.times_s) == len(fast.times_s)
    assert np.allclose(slow.poses_m[0], make_field(0).start_pose_m)


def test_bad_switch_costs_name_the_field():
    with pytest.raises(ActionInputError, match="motion_blur_per_speed"):
        Detector(motion_blur_per_speed=-0.1)
    with pytest.raises(ActionInputError, match="motion_blur_per_turn_rate"):
        Detector(motion_blur_per_turn_rate=float("nan"))
    with pytest.raises(ActionInputError, match="planning_latency_s"):
        _episode("segment", latency=-1.0, cma=0)


def test_latency_flown_on_the_old_plan():
    hover = _episode("fixed_10s", seed=0, latency=4.0, cma=0)
    flying = _episode("fixed_10s", seed=0, latency=4.0, cma=0, mode="fly")
    flown = lambda log: float(np.sum(np.linalg.norm(np.diff(np.asarray(log.waypoints_m), axis=0), axis=1)))
    assert flying.hover_s < hover.hover_s  # only at take-off (no old plan yet) or when a plan ran out
    assert flying.hover_s >= 4.0
    assert flown(flying) > flown(hover)
    assert flying.times_s[-1] <= 150.0 and len(flying.times_s) == len(hover.times_s)
    # a schedule that flies every plan to its end has no old plan to fly: the same as hovering
    a = _episode("continuous", seed=0, latency=4.0, cma=0)
    b = _episode("continuous", seed=0, latency=4.0, cma=0, mode="fly")
    assert np.array_equal(a.series("rse"), b.series("rse")) and a.hover_s == b.hover_s
    with pytest.raises(ActionInputError, match="latency_mode"):
        _episode("segment", latency=1.0, cma=0, mode="drift")
