"""DetectionModel: closed forms of pd, clutter and position error, and bad input."""

import numpy as np
import pytest

from attend.action.camera import Camera, Detector
from attend.action.detection import DetectionModel
from attend.action.errors import ActionInputError


def test_detection_probability_closed_forms():
    model = DetectionModel(max_detection_probability=0.9, best_altitude_m=30.0, useless_altitude_m=100.0, low_altitude_loss=0.5)
    assert model.detection_probability(30.0) == pytest.approx(0.9)
    assert model.detection_probability(100.0) == pytest.approx(0.0)
    assert model.detection_probability(150.0) == pytest.approx(0.0)
    # halfway up: q = 1 - 0.5^2; halfway down: q = 1 - 0.5 * 0.5^2
    assert model.detection_probability(65.0) == pytest.approx(0.9 * 0.75)
    assert model.detection_probability(15.0) == pytest.approx(0.9 * (1 - 0.5 * 0.25))
    blurred = DetectionModel(motion_blur_per_speed=0.05)
    assert blurred.detection_probability(30.0, 10.0) == pytest.approx(0.95 / 1.5)
    assert blurred.detection_probability(30.0, -10.0) == pytest.approx(0.95 / 1.5)


def test_altitude_shape_is_the_old_detectors_true_positive_shape():
    heights = np.linspace(1, 130, 200)
    model = DetectionModel()
    reference = Detector(max_true_positive_rate=0.95, min_false_positive_rate=0.0, max_false_positive_rate=0.0,
                         best_altitude_m=30.0, useless_altitude_m=100.0, low_altitude_loss=0.5)
    np.testing.assert_allclose(model.detection_probability(heights), reference.true_positive_rate(heights), atol=1e-12)


def test_clutter_and_position_error_closed_forms():
    model = DetectionModel(false_detections_at_best=0.1, false_detections_at_useless=2.1, position_error_at_best_m=0.5)
    assert model.false_detections_per_image(10.0) == pytest.approx(0.1)
    assert model.false_detections_per_image(30.0) == pytest.approx(0.1)
    assert model.false_detections_per_image(65.0) == pytest.approx(0.1 + 2.0 / 4)
    assert model.false_detections_per_image(200.0) == pytest.approx(2.1)
    assert model.position_error_m(60.0) == pytest.approx(1.0)
    camera = Camera()
    wx, wy = 2 * 65 * np.tan(np.radians(22.5)), 2 * 65 * np.tan(np.radians(30))
    kappa = 0.6 / (wx * wy)
    assert model.clutter_density_per_m2(65.0, camera) == pytest.approx(kappa)
    assert model.false_alarm_probability_per_cell(65.0, camera, 2.0) == pytest.approx(1 - np.exp(-2 * kappa))


def test_false_alarm_probability_matches_poisson_frequency():
    model = DetectionModel(false_detections_at_best=3.0, false_detections_at_useless=6.0)
    camera = Camera()
    h = 30.0
    wx, wy = camera.footprint_m(h)
    rng = np.random.default_rng(0)
    area = 4.0  # a 2 m x 2 m cell at the footprint's corner
    trials = 20000
    counts = rng.poisson(model.false_detections_per_image(h), trials)
    hits = 0
    for n in counts:
        xy = rng.uniform(0, 1, (n, 2)) * [wx, wy]
        hits += bool(np.any((xy[:, 0] < 2) & (xy[:, 1] < 2)))
    expected = float(model.false_alarm_probability_per_cell(h, camera, area))
    assert hits / trials == pytest.approx(expected, abs=4 * np.sqrt(expected / trials))


def test_paper_model():
    model = DetectionModel.paper()
    assert (model.best_altitude_m, model.useless_altitude_m) == (10.0, 26.0)
    assert model.detection_probability(10.0) == pytest.approx(0.95)
    assert model.detection_probability(26.0) == pytest.approx(0.0)


@pytest.mark.parametrize(
    "field, value",
    [
        ("max_detection_probability", 1.2),
        ("max_detection_probability", -0.1),
        ("low_altitude_loss", 2.0),
        ("best_altitude_m", 0.0),
        ("useless_altitude_m", 20.0),
        ("false_detections_at_best", -1.0),
        ("false_detections_at_useless", np.inf),
        ("position_error_at_best_m", 0.0),
        ("motion_blur_per_speed", -0.5),
        ("max_detection_probability", "high"),
        ("best_altitude_m", np.nan),
    ],
)
def test_bad_fields_are_named(field, value):
    with pytest.raises(ActionInputError, match=field):
        DetectionModel(**{field: value})
