"""Field, camera, detector and flight model: closed forms, properties and bad input."""

import numpy as np
import pytest

from attend.action.camera import Camera, Detector, noise_variance, take_image
from attend.action.errors import ActionInputError
from attend.action.field import Grid, Obstacle, Person, SearchField, make_field, person_cell_indices
from attend.action.flight import FlightModel, path_collides
from attend.action.planners import PlanningSetup


def test_footprint_8_3_by_11_5_at_10m():
    wx, wy = Camera().footprint_m(10.0)
    assert wx == pytest.approx(8.28, abs=0.01)
    assert wy == pytest.approx(11.55, abs=0.01)


def test_noise_variance_values():
    assert noise_variance(10.0) == pytest.approx(0.393, abs=1e-3)
    assert noise_variance(26.0) == pytest.approx(0.727, abs=1e-3)


def test_detector_best_near_10m_and_useless_at_26m():
    det = Detector()
    heights = np.linspace(2, 26, 49)
    tpr = det.true_positive_rate(heights)
    assert heights[np.argmax(tpr)] == pytest.approx(10.0)
    assert det.true_positive_rate(26.0) == pytest.approx(det.false_positive_rate(26.0))
    assert np.all(np.diff(det.false_positive_rate(heights)) >= 0)


def test_visible_cells_match_footprint_and_obstacles_hide_ground():
    grid = Grid()
    cam = Camera()
    mask = cam.visible_cells(np.array([[0.0, 0.0, 10.0]]), grid)[0]
    # cell centres at +-0.375, +-1.125, ... within +-4.14 m (x) and +-5.77 m (y): 12 x 16
    assert mask.sum() == 12 * 16
    box = Obstacle(0.0, 0.0, 4.0, 4.0, 13.0)
    hidden = cam.visible_cells(np.array([[0.0, 0.0, 20.0]]), grid, [box])[0]
    under = SearchField(grid, (), (box,)).obstacle_cells()
    assert not np.any(hidden & under)


def test_people_cells_and_region():
    field = make_field(3, people_region="lower_half")
    assert len(field.people) == 7
    assert all(p.y_m < 0 for p in field.people)
    counts = [len(c) for c in field.person_cells]
    assert all(5 <= c <= 12 for c in counts)
    # a person aligned with the grid: x exactly one column, y from row 10 to 12.67 -> 3 cells
    grid = Grid()
    person = Person(-15 + 0.375 + 0.75 * 10, -15 + 0.75 * 10 + 1.0, np.pi / 2)
    cells = person_cell_indices(person, grid)
    np.testing.assert_array_equal(cells, [10 * 40 + 10, 11 * 40 + 10, 12 * 40 + 10])


def test_false_blob_injection_is_detected_on_empty_cells():
    field = make_field(0)
    rng = np.random.default_rng(1)
    det = Detector(min_false_positive_rate=0.0, max_false_positive_rate=0.0)
    image = take_image(field, Camera(), det, (0.0, 0.0, 10.0), 0.0, rng, inject_false_blob=True)
    assert len(image.clutter_cells) == 6
    assert np.all(field.truth[image.clutter_cells] == 0)
    detected = image.cells[image.measurements == 1.0]
    assert set(image.clutter_cells) <= set(detected)


def test_trapezoid_timing():
    flight = FlightModel(speed_m_s=5.0, acceleration_m_s2=3.0)
    # long segment: d / v + v / a
    assert flight.segment_duration(30.0) == pytest.approx(30 / 5 + 5 / 3)
    # short segment (triangle): 2 sqrt(d / a)
    assert flight.segment_duration(3.0) == pytest.approx(2 * np.sqrt(1.0))
    t = flight.segment_duration(30.0)
    assert flight.distance_after(t, 30.0) == pytest.approx(30.0)
    assert flight.distance_after(t / 2, 30.0) == pytest.approx(15.0)


def test_images_every_period_along_path():
    flight = FlightModel(speed_m_s=5.0, acceleration_m_s2=3.0, image_rate_hz=0.15)
    poses, times, valid, duration, next_after = flight.segment_images(
        np.array([[-14.0, 0, 10]]), np.array([[14.0, 0, 10]]), np.array([0.0]), np.array([100.0])
    )
    assert valid[0].sum() == 2  # 7.27 s flight: images at 0 and 6.67 s
    np.testing.assert_allclose(times[0, :2], [0.0, 1 / 0.15])
    assert next_after[0] == pytest.approx(2 / 0.15 - duration[0])


def test_image_due_at_departure_belongs_to_the_start():
    # 10 m takes 3.67 s < one period: image at the start (t = 0), then hover at the goal for the
    # image one period later, so the goal is imaged too (the first segment of every episode)
    flight = FlightModel(speed_m_s=5.0, acceleration_m_s2=3.0, image_rate_hz=0.15)
    poses, times, valid, duration, next_after = flight.segment_images(
        np.array([[0.0, 0, 10]]), np.array([[10.0, 0, 10]]), np.array([0.0]), np.array([100.0])
    )
    assert valid[0].sum() == 2
    np.testing.assert_allclose(times[0, :2], [0.0, 1 / 0.15])
    np.testing.assert_allclose(poses[0, 1], [10.0, 0, 10])
    assert duration[0] == pytest.approx(1 / 0.15) and next_after[0] == pytest.approx(1 / 0.15)
    # staying put with an image due now: one image, no wait
    _, _, valid, duration, _ = flight.segment_images(
        np.array([[0.0, 0, 10]]), np.array([[0.0, 0, 10]]), np.array([0.0]), np.array([100.0]))
    assert valid[0].sum() == 1 and duration[0] == 0.0


def test_collision_check():
    box = Obstacle(0.0, 0.0, 4.0, 4.0, 13.0)
    paths = np.array([[[-10, 0, 10], [10, 0, 10]], [[-10, 0, 20], [10, 0, 20]], [[-10, 8, 10], [10, 8, 10]]], float)
    np.testing.assert_array_equal(path_collides(paths, [box]), [True, False, False])


@pytest.mark.parametrize(
    "make, field_name",
    [
        (lambda: make_field(0, start_pose_m=(40.0, 0.0, 7.0)), "start_pose_m"),
        (lambda: make_field(0, start_pose_m=(0.0, 0.0, 40.0)), "start_pose_m"),
        (lambda: make_field(0, obstacles=[Obstacle(14.0, 0.0)]), "obstacles[0]"),
        (lambda: make_field(0, altitude_limits_m=(26.0, 2.0)), "altitude_limits_m"),
        (lambda: Camera(fov_x_deg=180.0), "fov_x_deg"),
        (lambda: Camera(fov_y_deg=0.0), "fov_y_deg"),
        (lambda: Camera(fov_y_deg=-10.0), "fov_y_deg"),
        (lambda: FlightModel(speed_m_s=0.0), "speed_m_s"),
        (lambda: make_field(0, people_region="left"), "people_region"),
        (lambda: PlanningSetup(make_field(0), altitude_layers_m=(5.0, 30.0)), "altitude_layers_m"),
    ],
)
def test_bad_input_names_the_field(make, field_name):
    with pytest.raises(ActionInputError, match=field_name.replace("[", r"\[").replace("]", r"\]")) as info:
        make()
    assert isinstance(info.value, ValueError)
    assert "expected" in str(info.value)
