"""Downward camera and person detector with altitude-dependent errors.

Footprint of a nadir camera at altitude h with field of view (fov_x, fov_y), axes aligned with
the field (fixed yaw):  width_x = 2 h tan(fov_x / 2),  width_y = 2 h tan(fov_y / 2)
(8.3 m x 11.5 m at h = 10 m for 45 deg x 60 deg). A cell is observed when its centre lies in the
footprint and the line of sight from the camera to the cell centre misses every obstacle.

Measurement per observed cell i:  z_i = 1 if the detector fires on the cell, else 0.05,
with noise variance  sigma^2(h) = 1 - exp(-c h),  c = 0.05 / m  (0.39 at 10 m, 0.73 at 26 m).

Motion blur (optional, off by default): an image taken at ground speed v [m/s] and turn rate
omega [rad/s] is degraded by the factor

    q(v, omega) = 1 / (1 + b_v |v| + b_omega |omega|)   in (0, 1],  q = 1 when hovering,

b_v = ``motion_blur_per_speed`` [s/m], b_omega = ``motion_blur_per_turn_rate`` [s/rad]: the
detector's precision falls to q / sigma^2(h) (the noise variance it reports is sigma^2(h) / q)
and its true-positive rate falls towards the false-positive rate, fpr + q (tpr - fpr). The
camera is stabilised only when hovering. b_v = b_omega = 0 is the sharp camera, bit for bit.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from attend.action.errors import ActionInputError
from attend.action.field import Grid, Obstacle, SearchField

DETECTED_VALUE = 1.0
NOT_DETECTED_VALUE = 0.05


@dataclass(frozen=True)
class Camera:
    """Nadir camera: ``fov_x_deg`` x ``fov_y_deg`` full field of view in degrees (each in (0, 180))."""

    fov_x_deg: float = 45.0
    fov_y_deg: float = 60.0

    def __post_init__(self) -> None:
        for name in ("fov_x_deg", "fov_y_deg"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and np.isfinite(value) and 0 < value < 180):
                raise ActionInputError(f"{name}: expected a field of view in (0, 180) degrees, got {value!r}")

    def footprint_m(self, altitude_m: float | np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Footprint (width_x, width_y) in m: 2 h tan(fov / 2); altitude_m: h [m]."""
        h = np.asarray(altitude_m, dtype=float)
        return (
            2 * h * np.tan(np.radians(self.fov_x_deg) / 2),
            2 * h * np.tan(np.radians(self.fov_y_deg) / 2),
        )

    def visible_cells(self, poses_m: np.ndarray, grid: Grid, obstacles: Sequence[Obstacle] = ()) -> np.ndarray:
        """Boolean mask (k, n) of the cells each of k poses observes.

        poses_m: (k, 3) camera poses (x, y, z) [m]; grid: the map's grid; obstacles: boxes that
        hide the ground behind them."""
        poses = np.atleast_2d(np.asarray(poses_m, dtype=float))
        centres = grid.cell_centres()
        width_x, width_y = self.footprint_m(poses[:, 2])
        inside = (np.abs(centres[None, :, 0] - poses[:, None, 0]) <= width_x[:, None] / 2) & (
            np.abs(centres[None, :, 1] - poses[:, None, 1]) <= width_y[:, None] / 2
        )
        if obstacles:
            inside &= ~line_of_sight_blocked(poses, centres, obstacles, candidates=inside)
        return inside


def line_of_sight_blocked(
    poses_m: np.ndarray, ground_points_m: np.ndarray, obstacles: Sequence[Obstacle], candidates: np.ndarray | None = None
) -> np.ndarray:
    """(k, n) mask: the segment from pose k to ground point (x, y, 0) passes through a box
    (slab test; a point under a box counts as blocked).

    poses_m: (k, 3) camera poses (x, y, z) [m]; ground_points_m: (n, 2) ground points (x, y) [m];
    obstacles: the boxes; candidates: (k, n) mask of the pose-point pairs to test (the others
    count as not blocked; None: all pairs)."""
    poses = np.atleast_2d(poses_m)
    k, n = len(poses), len(ground_points_m)
    blocked = np.zeros((k, n), dtype=bool)
    rows, cols = np.nonzero(candidates) if candidates is not None else np.indices((k, n)).reshape(2, -1)
    if len(rows) == 0:
        return blocked
    start = poses[rows]
    end = np.column_stack([ground_points_m[cols], np.zeros(len(cols))])
    hit = np.zeros(len(rows), dtype=bool)
    for box in obstacles:
        hit |= segments_hit_box(start, end, box.bounds)
    blocked[rows, cols] = hit
    return blocked


def segments_hit_box(start: np.ndarray, end: np.ndarray, bounds: Sequence[float], margin_m: float = 0.0) -> np.ndarray:
    """Whether each segment start->end (arrays (m, 3) [m]) intersects the box (slab method): (m,) mask.

    bounds: the box (x_min, x_max, y_min, y_max, z_min, z_max) [m], e.g. :attr:`Obstacle.bounds`;
    margin_m: clearance [m] added on every side of the box."""
    x0, x1, y0, y1, z0, z1 = bounds
    low = np.array([x0 - margin_m, y0 - margin_m, z0 - margin_m])
    high = np.array([x1 + margin_m, y1 + margin_m, z1 + margin_m])
    direction = end - start
    t_enter = np.zeros(len(start))
    t_exit = np.ones(len(start))
    for axis in range(3):
        d = direction[:, axis]
        parallel = np.abs(d) < 1e-12
        with np.errstate(divide="ignore", invalid="ignore"):
            ta = (low[axis] - start[:, axis]) / d
            tb = (high[axis] - start[:, axis]) / d
        t_near = np.where(parallel, -np.inf, np.minimum(ta, tb))
        t_far = np.where(parallel, np.inf, np.maximum(ta, tb))
        outside_slab = parallel & ((start[:, axis] < low[axis]) | (start[:, axis] > high[axis]))
        t_enter = np.maximum(t_enter, t_near)
        t_exit = np.minimum(t_exit, t_far)
        t_exit = np.where(outside_slab, -np.inf, t_exit)
    return t_enter <= t_exit


def noise_variance(altitude_m: float | np.ndarray, rate_per_m: float = 0.05) -> np.ndarray:
    """Measurement noise variance sigma^2(h) = 1 - exp(-rate h) (dimensionless).

    altitude_m: h [m]; rate_per_m: rate [1/m]."""
    return 1.0 - np.exp(-rate_per_m * np.asarray(altitude_m, dtype=float))


@dataclass(frozen=True)
class Detector:
    """Per-cell person detector with altitude-dependent rates.

    True-positive rate, best at ``best_altitude_m`` and down to the false-positive rate at
    ``useless_altitude_m``:
        tpr(h) = fpr(h) + (tpr_max - fpr(h)) * q(h),
        q(h) = max(0, 1 - ((h - h_best) / (h_useless - h_best))^2)  for h >= h_best,
        q(h) = 1 - low_altitude_loss * ((h_best - h) / h_best)^2     for h <  h_best
    (people only partly in view from very low; tpr_max is ``max_true_positive_rate``). False-positive
    rate per cell (fpr_min, fpr_max: ``min_false_positive_rate``, ``max_false_positive_rate``)
        fpr(h) = fpr_min + (fpr_max - fpr_min) * clip((h - h_best) / (h_useless - h_best), 0, 1)^2.
    detection_unit "person" (default): each person in view is detected as a whole with
    probability tpr(h) * min(1, 2 * visible fraction of the person), and all its visible cells
    read 1 (a detector outputs boxes around people); "cell": each person cell fires alone with
    tpr(h). Other cells fire with fpr(h) each.
    Clutter: a Poisson number (mean ``clutter_rate_per_image``) of person-sized false blobs
    (2 x 3 cells) per image at random places in the footprint.
    Noise: sigma^2(h) = 1 - exp(-noise_rate_per_m h) (:func:`noise_variance`).
    Motion blur: ``motion_blur_per_speed`` b_v [s/m] and ``motion_blur_per_turn_rate`` b_omega
    [s/rad] (>= 0; module docstring): images taken while moving read with precision
    q / sigma^2(h) and true-positive rate fpr + q (tpr - fpr), q = 1 / (1 + b_v v + b_omega omega).
    """

    max_true_positive_rate: float = 0.95
    min_false_positive_rate: float = 0.002
    max_false_positive_rate: float = 0.04
    best_altitude_m: float = 10.0
    useless_altitude_m: float = 26.0
    low_altitude_loss: float = 0.5
    clutter_rate_per_image: float = 0.0
    noise_rate_per_m: float = 0.05
    detection_unit: str = "person"
    motion_blur_per_speed: float = 0.0
    motion_blur_per_turn_rate: float = 0.0

    def __post_init__(self) -> None:
        for name in ("motion_blur_per_speed", "motion_blur_per_turn_rate"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and np.isfinite(value) and value >= 0):
                raise ActionInputError(f"{name}: expected a blur coefficient >= 0 (s/m or s/rad), got {value!r}")
        if self.detection_unit not in ("person", "cell"):
            raise ActionInputError(f"detection_unit: expected 'person' or 'cell', got {self.detection_unit!r}")
        if not 0 < self.best_altitude_m < self.useless_altitude_m:
            raise ActionInputError(
                "best_altitude_m, useless_altitude_m: expected 0 < best < useless (m), "
                f"got {self.best_altitude_m!r}, {self.useless_altitude_m!r}"
            )
        if self.clutter_rate_per_image < 0:
            raise ActionInputError(f"clutter_rate_per_image: expected >= 0, got {self.clutter_rate_per_image!r}")

    def false_positive_rate(self, altitude_m: float | np.ndarray) -> np.ndarray:
        """fpr(h) per cell (class docstring); altitude_m: h [m]."""
        h = np.asarray(altitude_m, dtype=float)
        ramp = np.clip((h - self.best_altitude_m) / (self.useless_altitude_m - self.best_altitude_m), 0, 1)
        return self.min_false_positive_rate + (self.max_false_positive_rate - self.min_false_positive_rate) * ramp**2

    def true_positive_rate(self, altitude_m: float | np.ndarray) -> np.ndarray:
        """tpr(h) of a sharp image (class docstring); altitude_m: h [m]."""
        h = np.asarray(altitude_m, dtype=float)
        above = np.maximum(0.0, 1 - ((h - self.best_altitude_m) / (self.useless_altitude_m - self.best_altitude_m)) ** 2)
        below = 1 - self.low_altitude_loss * ((self.best_altitude_m - h) / self.best_altitude_m) ** 2
        quality = np.where(h >= self.best_altitude_m, above, np.clip(below, 0, 1))
        fpr = self.false_positive_rate(h)
        return fpr + (self.max_true_positive_rate - fpr) * quality

    def noise_variance(self, altitude_m: float | np.ndarray) -> np.ndarray:
        """sigma^2(h) = 1 - exp(-noise_rate_per_m h); altitude_m: h [m]."""
        return noise_variance(altitude_m, self.noise_rate_per_m)

    @property
    def blurs(self) -> bool:
        """Whether images taken while moving are degraded (a blur coefficient > 0)."""
        return self.motion_blur_per_speed > 0 or self.motion_blur_per_turn_rate > 0

    def blur_factor(self, speed_m_s: float | np.ndarray = 0.0, turn_rate_rad_s: float | np.ndarray = 0.0) -> np.ndarray:
        """q = 1 / (1 + b_v |v| + b_omega |omega|) in (0, 1] [dimensionless]; 1 when hovering.

        speed_m_s: v [m/s]; turn_rate_rad_s: omega [rad/s]."""
        v = np.abs(np.asarray(speed_m_s, dtype=float))
        w = np.abs(np.asarray(turn_rate_rad_s, dtype=float))
        return 1.0 / (1.0 + self.motion_blur_per_speed * v + self.motion_blur_per_turn_rate * w)

    def image_noise_variance(self, altitude_m, speed_m_s=0.0, turn_rate_rad_s=0.0) -> np.ndarray:
        """Noise variance of an image taken moving: sigma^2(h) / q(v, omega) (sigma^2(h) if sharp).

        altitude_m: h [m]; speed_m_s: v [m/s]; turn_rate_rad_s: omega [rad/s]."""
        if not self.blurs:
            return self.noise_variance(altitude_m)
        return self.noise_variance(altitude_m) / self.blur_factor(speed_m_s, turn_rate_rad_s)

    def image_true_positive_rate(self, altitude_m, speed_m_s=0.0, turn_rate_rad_s=0.0) -> np.ndarray:
        """True-positive rate of an image taken moving: fpr(h) + q (tpr(h) - fpr(h)).

        altitude_m: h [m]; speed_m_s: v [m/s]; turn_rate_rad_s: omega [rad/s]."""
        if not self.blurs:
            return self.true_positive_rate(altitude_m)
        fpr = self.false_positive_rate(altitude_m)
        return fpr + self.blur_factor(speed_m_s, turn_rate_rad_s) * (self.true_positive_rate(altitude_m) - fpr)


@dataclass(frozen=True)
class Image:
    """One processed image: pose_m (x, y, z) [m], time_s [s], observed cell indices ``cells``,
    ``measurements`` z, noise_variance sigma^2(h), and clutter_cells, the cells of injected or
    clutter false blobs (for logging)."""

    pose_m: np.ndarray
    time_s: float
    cells: np.ndarray
    measurements: np.ndarray
    noise_variance: float
    clutter_cells: np.ndarray


def take_image(
    field: SearchField,
    camera: Camera,
    detector: Detector,
    pose_m: Sequence[float],
    time_s: float,
    rng: np.random.Generator,
    inject_false_blob: bool = False,
    speed_m_s: float = 0.0,
    turn_rate_rad_s: float = 0.0,
) -> Image:
    """Simulate one image at ``pose_m``: per-cell detections with tpr(h) on person cells and
    fpr(h) elsewhere, plus clutter blobs (and one injected blob when asked). ``speed_m_s`` and
    ``turn_rate_rad_s``: the camera's motion when the image is taken (motion blur of a detector
    with blur coefficients; no effect on a sharp detector).

    field: the search field (truth, obstacles); camera, detector: the sensor models; pose_m:
    (x, y, z) [m]; time_s: mission time of the image [s]; rng: the random generator of the
    detector noise; inject_false_blob: add one false 2 x 3-cell blob."""
    pose = np.asarray(pose_m, dtype=float)
    visible = camera.visible_cells(pose[None], field.grid, field.obstacles)[0]
    cells = np.flatnonzero(visible)
    h = pose[2]
    detected = rng.random(len(cells)) < detector.false_positive_rate(h)
    tpr = detector.image_true_positive_rate(h, speed_m_s, turn_rate_rad_s)
    if detector.detection_unit == "cell":
        on_person = field.truth[cells] > 0.5
        detected[on_person] = rng.random(int(on_person.sum())) < tpr
    else:
        for person in field.person_cells:
            seen = np.isin(cells, person)
            fraction = seen.sum() / max(len(person), 1)
            if fraction == 0:
                continue
            detected[seen] = rng.random() < tpr * min(1.0, 2 * fraction)
    n_blobs = rng.poisson(detector.clutter_rate_per_image) if detector.clutter_rate_per_image > 0 else 0
    n_blobs += int(inject_false_blob)
    clutter = _false_blobs(field, cells, n_blobs, rng)
    detected |= np.isin(cells, clutter)
    z = np.where(detected, DETECTED_VALUE, NOT_DETECTED_VALUE)
    variance = detector.image_noise_variance(h, speed_m_s, turn_rate_rad_s)
    return Image(pose, float(time_s), cells, z, float(variance), clutter)


def _false_blobs(field: SearchField, cells: np.ndarray, n_blobs: int, rng: np.random.Generator) -> np.ndarray:
    """Cells of ``n_blobs`` 2 x 3-cell false blobs on visible, person-free cells."""
    if n_blobs == 0 or len(cells) == 0:
        return np.zeros(0, dtype=int)
    side = field.grid.cells_per_side
    truth = field.truth
    visible = np.zeros(field.grid.n_cells, dtype=bool)
    visible[cells] = True
    chosen: list[np.ndarray] = []
    for _ in range(n_blobs):
        for _attempt in range(50):
            anchor = rng.choice(cells)
            iy, ix = divmod(int(anchor), side)
            tall = rng.random() < 0.5
            dy, dx = (3, 2) if tall else (2, 3)
            if iy + dy > side or ix + dx > side:
                continue
            blob = np.array([(iy + a) * side + ix + b for a in range(dy) for b in range(dx)])
            if visible[blob].all() and truth[blob].max() == 0:
                chosen.append(blob)
                break
    return np.unique(np.concatenate(chosen)) if chosen else np.zeros(0, dtype=int)
