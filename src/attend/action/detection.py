"""Person detector of the scalable search: detections are reported positions, with clutter.

An image taken at altitude h [m] and ground speed v [m/s] reports every person whose centre is
in view with probability

    pd(h, v) = pd_max * q(h) / (1 + b_v |v|),
    q(h) = max(0, 1 - ((h - h_best) / (h_useless - h_best))^2)          for h >= h_best,
    q(h) = clip(1 - low_altitude_loss * ((h_best - h) / h_best)^2, 0, 1)  for h <  h_best

(q as the true-positive shape of :class:`attend.action.camera.Detector`: 1 at h_best, 0 from
h_useless up, people only partly in view from very low), at the person's centre plus a
horizontal error N(0, sigma(h)^2 I) with

    sigma(h) = sigma_best * h / h_best   (the ground size of a pixel grows with h).

Clutter: a Poisson number of false detections per image, mean

    lambda(h) = lambda_best + (lambda_useless - lambda_best) * clip((h - h_best) / (h_useless - h_best), 0, 1)^2,

spread uniformly over the ground in view, i.e. a density kappa(h) = lambda(h) / A(h) per m^2 with
A(h) the camera footprint area; a cell of area a then holds at least one false detection with
probability 1 - exp(-kappa(h) a).
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from attend.action.camera import Camera
from attend.action.errors import ActionInputError

_PROBABILITY_FIELDS = ("max_detection_probability", "low_altitude_loss")
_RATE_FIELDS = ("false_detections_at_best", "false_detections_at_useless", "motion_blur_per_speed")


@dataclass(frozen=True)
class DetectionModel:
    """Altitude- and speed-dependent person detector (module docstring for the equations).

    max_detection_probability: pd_max in [0, 1]; best_altitude_m: h_best [m] where pd is
    highest; useless_altitude_m: h_useless [m] where pd reaches 0; low_altitude_loss: the loss
    of q at h = 0 in [0, 1]; false_detections_at_best, false_detections_at_useless: clutter
    lambda per image at h_best and h_useless (>= 0); position_error_at_best_m: sigma_best [m],
    the horizontal standard deviation of a reported position at h_best (> 0);
    motion_blur_per_speed: b_v [s/m] (>= 0).
    """

    max_detection_probability: float = 0.95
    best_altitude_m: float = 30.0
    useless_altitude_m: float = 100.0
    low_altitude_loss: float = 0.5
    false_detections_at_best: float = 0.05
    false_detections_at_useless: float = 2.0
    position_error_at_best_m: float = 0.5
    motion_blur_per_speed: float = 0.0

    def __post_init__(self) -> None:
        for item in fields(self):
            value = getattr(self, item.name)
            if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)):
                raise ActionInputError(f"{item.name}: expected a number, got {value!r}")
            if not np.isfinite(value):
                raise ActionInputError(f"{item.name}: expected a finite number, got {value!r}")
        for name in _PROBABILITY_FIELDS:
            value = getattr(self, name)
            if not 0 <= value <= 1:
                raise ActionInputError(f"{name}: expected a probability in [0, 1], got {value!r}")
        for name in _RATE_FIELDS:
            value = getattr(self, name)
            if value < 0:
                raise ActionInputError(f"{name}: expected a rate >= 0, got {value!r}")
        if not 0 < self.best_altitude_m:
            raise ActionInputError(f"best_altitude_m: expected an altitude > 0 m, got {self.best_altitude_m!r}")
        if not self.best_altitude_m < self.useless_altitude_m:
            raise ActionInputError(
                f"useless_altitude_m: expected an altitude above best_altitude_m={self.best_altitude_m!r} m, "
                f"got {self.useless_altitude_m!r}"
            )
        if not self.position_error_at_best_m > 0:
            raise ActionInputError(
                f"position_error_at_best_m: expected a standard deviation > 0 m, got {self.position_error_at_best_m!r}"
            )

    def altitude_quality(self, altitude_m) -> np.ndarray:
        """q(h) in [0, 1] (module docstring); altitude_m: h [m]."""
        h = np.asarray(altitude_m, dtype=float)
        span = self.useless_altitude_m - self.best_altitude_m
        above = np.maximum(0.0, 1.0 - ((h - self.best_altitude_m) / span) ** 2)
        below = np.clip(1.0 - self.low_altitude_loss * ((self.best_altitude_m - h) / self.best_altitude_m) ** 2, 0, 1)
        return np.where(h >= self.best_altitude_m, above, below)

    def detection_probability(self, altitude_m, speed_m_s=0.0) -> np.ndarray:
        """pd(h, v) = pd_max q(h) / (1 + b_v |v|): probability that a person in view is reported.

        altitude_m: h [m]; speed_m_s: ground speed v [m/s] when the image is taken."""
        blur = 1.0 + self.motion_blur_per_speed * np.abs(np.asarray(speed_m_s, dtype=float))
        return self.max_detection_probability * self.altitude_quality(altitude_m) / blur

    def false_detections_per_image(self, altitude_m) -> np.ndarray:
        """lambda(h) = lambda_best + (lambda_useless - lambda_best) clip((h - h_best) / (h_useless - h_best), 0, 1)^2,
        the mean number of clutter detections per image; altitude_m: h [m]."""
        h = np.asarray(altitude_m, dtype=float)
        ramp = np.clip((h - self.best_altitude_m) / (self.useless_altitude_m - self.best_altitude_m), 0, 1)
        return self.false_detections_at_best + (self.false_detections_at_useless - self.false_detections_at_best) * ramp**2

    def position_error_m(self, altitude_m) -> np.ndarray:
        """sigma(h) = sigma_best h / h_best [m], the horizontal standard deviation of a reported
        position (each axis); altitude_m: h [m]."""
        return self.position_error_at_best_m * np.asarray(altitude_m, dtype=float) / self.best_altitude_m

    def clutter_density_per_m2(self, altitude_m, camera: Camera) -> np.ndarray:
        """kappa(h) = lambda(h) / (w_x(h) w_y(h)) [1/m^2], clutter detections per m^2 of ground in
        view; altitude_m: h [m] (> 0); camera: gives the footprint w_x, w_y [m]."""
        width_x, width_y = camera.footprint_m(altitude_m)
        return self.false_detections_per_image(altitude_m) / (width_x * width_y)

    def false_alarm_probability_per_cell(self, altitude_m, camera: Camera, cell_area_m2: float) -> np.ndarray:
        """1 - exp(-kappa(h) a): probability that a cell of area a holds at least one clutter
        detection; altitude_m: h [m]; camera: the footprint; cell_area_m2: a [m^2]."""
        return -np.expm1(-self.clutter_density_per_m2(altitude_m, camera) * float(cell_area_m2))

    @classmethod
    def paper(cls) -> "DetectionModel":
        """The detector of the paper's 30 m field (:mod:`attend.action.field`, 0.75 m cells,
        flights between 2 and 26 m): h_best = 10 m, h_useless = 26 m, pd_max = 0.95, the same
        altitude shape as :class:`attend.action.camera.Detector`.

        Clutter: 0.1 false detections per image at 10 m (footprint 8.3 m x 11.5 m = 96 m^2, so
        about 1e-3 per m^2, 6e-4 per 0.75 m cell), rising to 1 per image at 26 m; the old
        per-cell detector fires on 0.2 % of the cells at 10 m, i.e. on about 0.4 of its 192 cells
        per image, most of which a person detector would not group into a person, hence a
        quarter of that. Position error: 0.4 m at 10 m (about half a cell: a person's centre is
        located to within its own width of 0.75 m), 1.0 m at 26 m.
        """
        return cls(
            max_detection_probability=0.95,
            best_altitude_m=10.0,
            useless_altitude_m=26.0,
            low_altitude_loss=0.5,
            false_detections_at_best=0.1,
            false_detections_at_useless=1.0,
            position_error_at_best_m=0.4,
            motion_blur_per_speed=0.0,
        )


@dataclass(frozen=True)
class DetectionTable(DetectionModel):
    """A team's own detector calibration, tabulated by altitude (the ``[detector]`` table of a
    mission file): pd(h) and lambda(h) linear in h between the tabulated altitudes and held at
    the end values beyond them; sigma(h) = ``position_std_m`` at every altitude; no motion blur.

    altitudes_m: h_1 < ... < h_k [m] (k >= 1, > 0); detection_probabilities: pd(h_i) in [0, 1];
    false_detections_per_image_at: lambda(h_i) >= 0, clutter detections per image;
    position_std_m: sigma > 0 [m], the error of a detection's ground position (each axis).
    The parametric fields of :class:`DetectionModel` are unused, except ``best_altitude_m``
    (set to the tabulated altitude of the largest pd) and ``useless_altitude_m`` (twice the
    highest tabulated altitude), which only bound a planner's default altitude layers."""

    altitudes_m: tuple = ()
    detection_probabilities: tuple = ()
    false_detections_per_image_at: tuple = ()
    position_std_m: float = 1.0

    def __post_init__(self) -> None:
        try:
            h = np.asarray(self.altitudes_m, dtype=float).reshape(-1)
            pd = np.asarray(self.detection_probabilities, dtype=float).reshape(-1)
            lam = np.asarray(self.false_detections_per_image_at, dtype=float).reshape(-1)
        except (TypeError, ValueError):
            raise ActionInputError("altitudes_m, detection_probabilities, false_detections_per_image_at: expected "
                                   "lists of numbers") from None
        if h.size == 0:
            raise ActionInputError("altitudes_m: expected at least one altitude in m")
        for name, values in (("detection_probabilities", pd), ("false_detections_per_image_at", lam)):
            if values.size != h.size:
                raise ActionInputError(f"{name}: expected one value per altitude ({h.size}), got {values.size}")
        for name, values in (("altitudes_m", h), ("detection_probabilities", pd), ("false_detections_per_image_at", lam)):
            if not np.all(np.isfinite(values)):
                raise ActionInputError(f"{name}: expected finite numbers, got {values.tolist()}")
        if np.any(h <= 0) or np.any(np.diff(h) <= 0):
            raise ActionInputError(f"altitudes_m: expected increasing altitudes > 0 m, got {h.tolist()}")
        if np.any((pd < 0) | (pd > 1)):
            raise ActionInputError(f"detection_probabilities: expected probabilities in [0, 1], got {pd.tolist()}")
        if not np.any(pd > 0):
            raise ActionInputError("detection_probabilities: expected pd > 0 at one altitude at least (a detector that "
                                   "never detects cannot search)")
        if np.any(lam < 0):
            raise ActionInputError(f"false_detections_per_image_at: expected rates >= 0 per image, got {lam.tolist()}")
        sigma = self.position_std_m
        if isinstance(sigma, (bool, np.bool_)) or not isinstance(sigma, (int, float, np.integer, np.floating)) \
                or not np.isfinite(sigma) or sigma <= 0:
            raise ActionInputError(f"position_std_m: expected a standard deviation > 0 m, got {sigma!r}")
        object.__setattr__(self, "altitudes_m", tuple(float(v) for v in h))
        object.__setattr__(self, "detection_probabilities", tuple(float(v) for v in pd))
        object.__setattr__(self, "false_detections_per_image_at", tuple(float(v) for v in lam))
        object.__setattr__(self, "position_std_m", float(sigma))
        object.__setattr__(self, "best_altitude_m", float(h[int(np.argmax(pd))]))
        object.__setattr__(self, "useless_altitude_m", float(2 * h[-1]))
        object.__setattr__(self, "motion_blur_per_speed", 0.0)

    def altitude_quality(self, altitude_m) -> np.ndarray:
        """pd(h) / max_i pd(h_i); altitude_m: h [m]."""
        return self.detection_probability(altitude_m) / max(self.detection_probabilities)

    def detection_probability(self, altitude_m, speed_m_s=0.0) -> np.ndarray:
        """pd(h), interpolated in the table (speed_m_s: unused, the calibration includes blur)."""
        h = np.asarray(altitude_m, dtype=float)
        return np.interp(h, self.altitudes_m, self.detection_probabilities) + 0.0 * np.asarray(speed_m_s, dtype=float)

    def false_detections_per_image(self, altitude_m) -> np.ndarray:
        """lambda(h), interpolated in the table; altitude_m: h [m]."""
        return np.interp(np.asarray(altitude_m, dtype=float), self.altitudes_m, self.false_detections_per_image_at)

    def position_error_m(self, altitude_m) -> np.ndarray:
        """sigma [m] at every altitude; altitude_m: h [m]."""
        return np.full(np.shape(altitude_m), self.position_std_m)
