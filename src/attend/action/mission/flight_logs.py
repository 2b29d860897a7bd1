"""The mission's record: the images taken and the detections reported, read from CSV.

    images.csv       t_s,uav,lon,lat,alt_m,yaw_deg   one row per image: time since mission start [s],
                     the UAV's name, the camera's position [deg], altitude above home [m], heading
                     from north, clockwise [deg] (the across-track axis is perpendicular to it)
    detections.csv   t_s,uav,lon,lat,score           one row per detection on the ground; t_s and uav
                     those of its image; score in [0, 1], optional (may be empty)

Rows are checked: every column present, numbers finite, times >= 0 and increasing per UAV, known
UAV names, altitudes within the UAV's limits (1 m slack), every detection matched to an image.
A bad row is a :class:`MissionInputError` naming the file, the row (the header is row 1) and the
column.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from attend.action.mission.errors import MissionInputError

IMAGE_COLUMNS = ("t_s", "uav", "lon", "lat", "alt_m", "yaw_deg")
DETECTION_COLUMNS = ("t_s", "uav", "lon", "lat", "score")
#: Slack [m] on the altitude limits of a logged image.
ALTITUDE_SLACK_M = 1.0
#: Two times [s] closer than this are the same image.
TIME_MATCH_S = 1e-3


@dataclass(frozen=True)
class FlightLogs:
    """Images (n rows) and detections (k rows), as arrays.

    image_time_s, image_uav (index into the mission's UAVs), image_lon, image_lat, image_alt_m,
    image_yaw_deg: (n,); detection_image: (k,) the row index of each detection's image;
    detection_lon, detection_lat, detection_score (NaN where not given): (k,)."""

    image_time_s: np.ndarray
    image_uav: np.ndarray
    image_lon: np.ndarray
    image_lat: np.ndarray
    image_alt_m: np.ndarray
    image_yaw_deg: np.ndarray
    detection_image: np.ndarray
    detection_lon: np.ndarray
    detection_lat: np.ndarray
    detection_score: np.ndarray

    @property
    def n_images(self) -> int:
        return len(self.image_time_s)

    @classmethod
    def empty(cls) -> "FlightLogs":
        z = np.zeros(0)
        return cls(z, np.zeros(0, int), z, z, z, z, np.zeros(0, int), z, z, z)

    def subset(self, keep: np.ndarray) -> "FlightLogs":
        """The logs of the images where ``keep`` ((n,) bool) is True, with their detections
        (detection_image renumbered into the kept images)."""
        keep = np.asarray(keep, dtype=bool)
        renumber = np.full(len(keep), -1, dtype=int)
        renumber[keep] = np.arange(int(keep.sum()))
        kept = keep[self.detection_image]
        return FlightLogs(self.image_time_s[keep], self.image_uav[keep], self.image_lon[keep], self.image_lat[keep],
                          self.image_alt_m[keep], self.image_yaw_deg[keep], renumber[self.detection_image[kept]],
                          self.detection_lon[kept], self.detection_lat[kept], self.detection_score[kept])

    def fusion_order(self) -> np.ndarray:
        """Image rows in the order they are fused: by time, then by UAV index (stable)."""
        return np.lexsort((self.image_uav, self.image_time_s))


def read_flight_logs(images_path, detections_path, uav_names, altitude_limits_m) -> FlightLogs:
    """The checked logs (module docstring); images_path None: nothing flown yet (then
    detections_path must be None too); uav_names: the mission's UAV names, in order;
    altitude_limits_m: per UAV (min, max) [m]."""
    if images_path is None:
        if detections_path is not None:
            raise MissionInputError("detections given without images: expected --images too", file=detections_path)
        return FlightLogs.empty()
    index = {name: k for k, name in enumerate(uav_names)}
    rows = _rows(images_path, IMAGE_COLUMNS, IMAGE_COLUMNS)
    n = len(rows)
    time = np.empty(n)
    uav = np.empty(n, dtype=int)
    lon, lat, alt, yaw = np.empty(n), np.empty(n), np.empty(n), np.empty(n)
    last = {}
    for i, (row_number, row) in enumerate(rows):
        time[i] = _value(row, "t_s", images_path, row_number, low=0.0)
        uav[i] = _uav(row, index, images_path, row_number)
        lon[i] = _value(row, "lon", images_path, row_number, low=-180.0, high=180.0)
        lat[i] = _value(row, "lat", images_path, row_number, low=-90.0, high=90.0)
        alt[i] = _value(row, "alt_m", images_path, row_number)
        yaw[i] = _value(row, "yaw_deg", images_path, row_number)
        low, high = altitude_limits_m[uav[i]]
        if not low - ALTITUDE_SLACK_M <= alt[i] <= high + ALTITUDE_SLACK_M:
            raise MissionInputError(f"altitude {alt[i]:g} m outside the limits [{low:g}, {high:g}] m of "
                                    f"{uav_names[uav[i]]!r}", file=images_path, row=row_number, column="alt_m")
        previous = last.get(uav[i])
        if previous is not None and time[i] <= previous + TIME_MATCH_S:
            raise MissionInputError(f"time {time[i]:g} s is not after the previous image of {uav_names[uav[i]]!r} "
                                    f"({previous:g} s): expected each UAV's images in time order",
                                    file=images_path, row=row_number, column="t_s")
        last[uav[i]] = time[i]
    if detections_path is None:
        z = np.zeros(0)
        return FlightLogs(time, uav, lon, lat, alt, yaw, np.zeros(0, int), z, z, z)
    keys = {}
    for i in range(n):
        keys[(int(uav[i]), int(round(time[i] / TIME_MATCH_S)))] = i
    drows = _rows(detections_path, DETECTION_COLUMNS, DETECTION_COLUMNS[:4])
    k = len(drows)
    image = np.empty(k, dtype=int)
    dlon, dlat, score = np.empty(k), np.empty(k), np.full(k, np.nan)
    for j, (row_number, row) in enumerate(drows):
        t = _value(row, "t_s", detections_path, row_number, low=0.0)
        u = _uav(row, index, detections_path, row_number)
        match = keys.get((u, int(round(t / TIME_MATCH_S))))
        if match is None:
            raise MissionInputError(f"no image of {uav_names[u]!r} at t_s = {t:g} s in {Path(images_path).name}: "
                                    "expected each detection's t_s and uav to be those of its image",
                                    file=detections_path, row=row_number, column="t_s")
        image[j] = match
        dlon[j] = _value(row, "lon", detections_path, row_number, low=-180.0, high=180.0)
        dlat[j] = _value(row, "lat", detections_path, row_number, low=-90.0, high=90.0)
        text = (row.get("score") or "").strip()
        if text:
            score[j] = _value(row, "score", detections_path, row_number, low=0.0, high=1.0)
    return FlightLogs(time, uav, lon, lat, alt, yaw, image, dlon, dlat, score)


def _rows(path, columns, required) -> list[tuple[int, dict]]:
    path = Path(path)
    if not path.is_file():
        raise MissionInputError(f"not found (expected a CSV file with the columns {','.join(columns)})", file=path)
    try:
        with open(path, newline="", encoding="utf-8-sig") as handle:
            reader = csv.DictReader(handle)
            header = [name.strip() for name in (reader.fieldnames or [])]
            missing = [c for c in required if c not in header]
            if missing:
                raise MissionInputError(f"missing column(s) {', '.join(missing)}: expected the header "
                                        f"{','.join(columns)}", file=path, row=1, column=missing[0])
            reader.fieldnames = header
            out = []
            for number, row in enumerate(reader, start=2):
                if None in row:
                    raise MissionInputError(f"more fields than the {len(header)} columns of the header", file=path,
                                            row=number)
                if all(not (v or "").strip() for v in row.values()):
                    continue
                out.append((number, row))
            return out
    except UnicodeDecodeError:
        raise MissionInputError("not a text CSV file (expected UTF-8)", file=path) from None


def _value(row: dict, column: str, path, number: int, low: float | None = None, high: float | None = None) -> float:
    text = (row.get(column) or "").strip()
    try:
        value = float(text)
    except ValueError:
        raise MissionInputError(f"expected a number, got {text!r}", file=path, row=number, column=column) from None
    if not math.isfinite(value):
        raise MissionInputError(f"expected a finite number, got {text!r}", file=path, row=number, column=column)
    if low is not None and value < low:
        what = "a time >= 0 s" if column == "t_s" else f"a value >= {low:g}"
        raise MissionInputError(f"expected {what}, got {value:g}", file=path, row=number, column=column)
    if high is not None and value > high:
        raise MissionInputError(f"expected a value <= {high:g}, got {value:g}", file=path, row=number, column=column)
    return value


def _uav(row: dict, index: dict, path, number: int) -> int:
    name = (row.get("uav") or "").strip()
    if name not in index:
        raise MissionInputError(f"unknown UAV {name!r}: expected one of {', '.join(index)} (the mission's [[uav]] names)",
                                file=path, row=number, column="uav")
    return index[name]


def write_flight_logs(logs: FlightLogs, uav_names, images_path, detections_path) -> None:
    """Write ``logs`` as images.csv and detections.csv (module docstring); uav_names: the
    mission's UAV names by index; images_path, detections_path: the files to write."""
    with open(images_path, "w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(IMAGE_COLUMNS)
        for i in range(logs.n_images):
            writer.writerow([f"{logs.image_time_s[i]:.3f}", uav_names[logs.image_uav[i]], f"{logs.image_lon[i]:.9f}",
                             f"{logs.image_lat[i]:.9f}", f"{logs.image_alt_m[i]:.3f}", f"{logs.image_yaw_deg[i]:.2f}"])
    with open(detections_path, "w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(DETECTION_COLUMNS)
        for j in range(len(logs.detection_image)):
            i = logs.detection_image[j]
            score = "" if not np.isfinite(logs.detection_score[j]) else f"{logs.detection_score[j]:.3f}"
            writer.writerow([f"{logs.image_time_s[i]:.3f}", uav_names[logs.image_uav[i]], f"{logs.detection_lon[j]:.9f}",
                             f"{logs.detection_lat[j]:.9f}", score])
