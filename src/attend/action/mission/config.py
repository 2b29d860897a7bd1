"""The mission file of ``attend plan`` (TOML): the area, the search, the UAVs and the detector.

    [area]      boundary (GeoJSON, KML or QGroundControl .plan), exclude (no-fly files), cell_size_m
    [search]    people (expected number), flight_time_s (per UAV), prior_map (optional), seed
    [[uav]]     name, home [lon, lat], speed_m_s, altitude_m [min, max], camera_fov_deg
                [across-track, along-track], image_interval_s
    [detector]  altitude_m, detection_probability, false_detections_per_image (one per altitude),
                position_std_m

Paths are relative to the mission file. Every key is checked: an unknown key, a missing one, a
wrong type or a value out of range is a :class:`MissionInputError` naming the file and the key.
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass
from pathlib import Path

from attend.action.detection import DetectionTable
from attend.action.mission.errors import MissionInputError

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

_SECTIONS = {"area", "search", "uav", "detector", "planner"}
_AREA_KEYS = {"boundary", "exclude", "cell_size_m"}
_SEARCH_KEYS = {"people", "flight_time_s", "prior_map", "seed", "people_known"}
_UAV_KEYS = {"name", "home", "speed_m_s", "altitude_m", "camera_fov_deg", "image_interval_s"}
_DETECTOR_KEYS = {"altitude_m", "detection_probability", "false_detections_per_image", "position_std_m"}
_PLANNER_KEYS = {"name", "horizon_s", "min_separation_m", "lawnmower_altitude_m"}


@dataclass(frozen=True)
class UavConfig:
    """One UAV: name; home (lon, lat) [deg] of take-off and landing; speed_m_s [m/s];
    altitude_m (min, max) above home [m]; camera_fov_deg (across-track, along-track) full
    field of view [deg] of its nadir camera; image_interval_s [s] between images."""

    name: str
    home: tuple[float, float]
    speed_m_s: float
    altitude_m: tuple[float, float]
    camera_fov_deg: tuple[float, float]
    image_interval_s: float


@dataclass(frozen=True)
class MissionConfig:
    """A mission file, checked: boundary and exclude paths (absolute); cell_size_m [m]; people:
    expected number of people in the area; flight_time_s [s] per UAV, take-off to landing;
    prior_map: optional path of relative likelihoods (GeoTIFF, or CSV lon,lat,weight); uavs;
    detector: the team's :class:`DetectionTable`; planner: "efe" or "lawnmower"; horizon_s:
    how far ahead [s] a plan reaches (the autopilot returns home after it unless replanned);
    min_separation_m: distance [m] UAVs keep apart; lawnmower_altitude_m: the lawnmower's
    altitude [m] (None: chosen, :mod:`attend.action.mission.lawnmower`); seed: seeds the planner's random lattice
    rotation (a plan is a function of the mission file and the logs); path: the mission file;
    people_known: the number of people is exactly ``people`` (a whole number), not an expectation:
    P(all found) is then the probability that at least that many targets are people."""

    boundary: Path
    exclude: tuple[Path, ...]
    cell_size_m: float
    people: float
    flight_time_s: float
    prior_map: Path | None
    uavs: tuple[UavConfig, ...]
    detector: DetectionTable
    planner: str = "efe"
    horizon_s: float = 120.0
    min_separation_m: float = 10.0
    seed: int = 0
    path: Path | None = None
    lawnmower_altitude_m: float | None = None
    people_known: bool = False

    def uav_index(self, name: str) -> int:
        """Index of the UAV called ``name`` (KeyError if none)."""
        for k, uav in enumerate(self.uavs):
            if uav.name == name:
                return k
        raise KeyError(name)


def read_mission(path: str | Path) -> MissionConfig:
    """The checked mission file at ``path`` (module docstring for its tables and keys)."""
    path = Path(path)
    if not path.is_file():
        raise MissionInputError("mission file not found (expected a TOML file with [area], [search], [[uav]], "
                                "[detector])", file=path)
    try:
        raw = tomllib.loads(path.read_text(encoding="utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as error:
        raise MissionInputError(f"not valid TOML: {error}", file=path) from None
    return mission_from_dict(raw, path)


def mission_from_dict(raw: dict, path: str | Path) -> MissionConfig:
    """The checked mission from the parsed TOML tables ``raw``; relative file names are taken
    from the folder of ``path`` (which errors name)."""
    path = Path(path)
    base = path.parent
    _known(raw, _SECTIONS, path, "")
    for section in ("area", "search", "uav", "detector"):
        if section not in raw:
            raise MissionInputError(f"missing the [{section}] table" if section != "uav"
                                    else "missing the [[uav]] tables (one per UAV)", file=path)
    area = _table(raw, "area", path)
    _known(area, _AREA_KEYS, path, "area.")
    boundary = _file(base, _required(area, "boundary", path, "area."), path, "area.boundary")
    exclude_raw = area.get("exclude", [])
    if isinstance(exclude_raw, str):
        exclude_raw = [exclude_raw]
    if not isinstance(exclude_raw, list):
        raise MissionInputError(f"expected a list of file names, got {exclude_raw!r}", file=path, column="area.exclude")
    exclude = tuple(_file(base, item, path, f"area.exclude[{k}]") for k, item in enumerate(exclude_raw))
    cell = _number(_required(area, "cell_size_m", path, "area."), path, "area.cell_size_m", low=0.05, high=100.0)

    search = _table(raw, "search", path)
    _known(search, _SEARCH_KEYS, path, "search.")
    people = _number(_required(search, "people", path, "search."), path, "search.people", low=0.0, open_low=True)
    flight = _number(_required(search, "flight_time_s", path, "search."), path, "search.flight_time_s",
                     low=0.0, open_low=True, high=86400.0)
    prior = search.get("prior_map")
    prior_path = None if prior is None else _file(base, prior, path, "search.prior_map")
    known = search.get("people_known", False)
    if not isinstance(known, bool):
        raise MissionInputError(f"expected true or false, got {known!r}", file=path, column="search.people_known")
    if known and people != int(people):
        raise MissionInputError(f"people_known = true needs a whole number of people, got {people:g}", file=path,
                                column="search.people")
    seed = search.get("seed", 0)
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise MissionInputError(f"expected a whole number >= 0, got {seed!r}", file=path, column="search.seed")

    uav_tables = raw["uav"]
    if isinstance(uav_tables, dict):
        uav_tables = [uav_tables]
    if not isinstance(uav_tables, list) or not uav_tables:
        raise MissionInputError("expected one or more [[uav]] tables", file=path, column="uav")
    uavs = tuple(_uav(table, k, path) for k, table in enumerate(uav_tables))
    names = [u.name for u in uavs]
    for name in names:
        if names.count(name) > 1:
            raise MissionInputError(f"two UAVs are called {name!r}; expected distinct names", file=path,
                                    column="uav.name")

    detector_table = _table(raw, "detector", path)
    _known(detector_table, _DETECTOR_KEYS, path, "detector.")
    altitudes = _numbers(_required(detector_table, "altitude_m", path, "detector."), path, "detector.altitude_m")
    probabilities = _numbers(_required(detector_table, "detection_probability", path, "detector."), path,
                             "detector.detection_probability")
    false = _numbers(_required(detector_table, "false_detections_per_image", path, "detector."), path,
                     "detector.false_detections_per_image")
    sigma = _number(_required(detector_table, "position_std_m", path, "detector."), path, "detector.position_std_m",
                    low=0.0, open_low=True)
    try:
        detector = DetectionTable(altitudes_m=tuple(altitudes), detection_probabilities=tuple(probabilities),
                                  false_detections_per_image_at=tuple(false), position_std_m=sigma)
    except ValueError as error:
        raise MissionInputError(str(error), file=path, column="detector") from None

    planner_table = raw.get("planner", {})
    if not isinstance(planner_table, dict):
        raise MissionInputError("expected a table", file=path, column="planner")
    _known(planner_table, _PLANNER_KEYS, path, "planner.")
    planner = planner_table.get("name", "efe")
    if planner not in ("efe", "lawnmower"):
        raise MissionInputError(f"expected 'efe' or 'lawnmower', got {planner!r}", file=path, column="planner.name")
    horizon = _number(planner_table.get("horizon_s", 120.0), path, "planner.horizon_s", low=1.0)
    separation = _number(planner_table.get("min_separation_m", 10.0), path, "planner.min_separation_m", low=0.0)
    sweep = planner_table.get("lawnmower_altitude_m")
    if sweep is not None:
        sweep = _number(sweep, path, "planner.lawnmower_altitude_m", low=0.0, open_low=True)
        for k, uav in enumerate(uavs):
            if not uav.altitude_m[0] <= sweep <= uav.altitude_m[1]:
                raise MissionInputError(f"expected an altitude within every UAV's limits, {uav.name!r} flies "
                                        f"{uav.altitude_m[0]:g}-{uav.altitude_m[1]:g} m, got {sweep:g}", file=path,
                                        column="planner.lawnmower_altitude_m")
    return MissionConfig(boundary=boundary, exclude=exclude, cell_size_m=cell, people=people, flight_time_s=flight,
                         prior_map=prior_path, uavs=uavs, detector=detector, planner=planner, horizon_s=horizon,
                         min_separation_m=separation, seed=int(seed), path=path, lawnmower_altitude_m=sweep, people_known=known)


def _uav(table, k: int, path: Path) -> UavConfig:
    key = f"uav[{k}]."
    if not isinstance(table, dict):
        raise MissionInputError("expected a table", file=path, column=f"uav[{k}]")
    _known(table, _UAV_KEYS, path, key)
    name = _required(table, "name", path, key)
    if not isinstance(name, str) or not name.strip() or any(c in name for c in ',"\n\r'):
        raise MissionInputError(f"expected a non-empty name without commas or quotes, got {name!r}", file=path,
                                column=key + "name")
    home = _numbers(_required(table, "home", path, key), path, key + "home", length=2)
    if not (-180 <= home[0] <= 180 and -90 <= home[1] <= 90):
        raise MissionInputError(f"expected [lon, lat] in degrees (WGS84), got {home}", file=path, column=key + "home")
    speed = _number(_required(table, "speed_m_s", path, key), path, key + "speed_m_s", low=0.0, open_low=True,
                    high=100.0)
    altitude = _numbers(_required(table, "altitude_m", path, key), path, key + "altitude_m", length=2)
    if not 0 < altitude[0] <= altitude[1] <= 1000:
        raise MissionInputError(f"expected [min, max] with 0 < min <= max <= 1000 m above home, got {altitude}",
                                file=path, column=key + "altitude_m")
    fov = _numbers(_required(table, "camera_fov_deg", path, key), path, key + "camera_fov_deg", length=2)
    if not all(0 < v < 180 for v in fov):
        raise MissionInputError(f"expected [across-track, along-track] fields of view in (0, 180) degrees, got {fov}",
                                file=path, column=key + "camera_fov_deg")
    interval = _number(_required(table, "image_interval_s", path, key), path, key + "image_interval_s", low=0.0,
                       open_low=True, high=3600.0)
    return UavConfig(name=name.strip(), home=(home[0], home[1]), speed_m_s=speed, altitude_m=(altitude[0], altitude[1]),
                     camera_fov_deg=(fov[0], fov[1]), image_interval_s=interval)


def _table(raw: dict, name: str, path: Path) -> dict:
    table = raw[name]
    if not isinstance(table, dict):
        raise MissionInputError("expected a table", file=path, column=f"[{name}]")
    return table


def _known(table: dict, keys: set, path: Path, prefix: str) -> None:
    for key in table:
        if key not in keys:
            raise MissionInputError(f"unknown key (expected one of {', '.join(sorted(keys))})", file=path,
                                    column=prefix + key if prefix else f"[{key}]")


def _required(table: dict, key: str, path: Path, prefix: str):
    if key not in table:
        raise MissionInputError("missing", file=path, column=prefix + key)
    return table[key]


def _number(value, path: Path, key: str, low: float | None = None, high: float | None = None,
            open_low: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise MissionInputError(f"expected a finite number, got {value!r}", file=path, column=key)
    value = float(value)
    if low is not None and (value < low or (open_low and value == low)):
        raise MissionInputError(f"expected a number {'>' if open_low else '>='} {low:g}, got {value:g}", file=path,
                                column=key)
    if high is not None and value > high:
        raise MissionInputError(f"expected a number <= {high:g}, got {value:g}", file=path, column=key)
    return value


def _numbers(value, path: Path, key: str, length: int | None = None) -> list[float]:
    if not isinstance(value, list) or not value:
        raise MissionInputError(f"expected a list of numbers, got {value!r}", file=path, column=key)
    if length is not None and len(value) != length:
        raise MissionInputError(f"expected {length} numbers, got {len(value)}", file=path, column=key)
    return [_number(v, path, f"{key}[{k}]") for k, v in enumerate(value)]


def _file(base: Path, value, path: Path, key: str) -> Path:
    if not isinstance(value, str) or not value.strip():
        raise MissionInputError(f"expected a file name, got {value!r}", file=path, column=key)
    target = (base / value).resolve() if not Path(value).is_absolute() else Path(value)
    if not target.is_file():
        raise MissionInputError(f"file {value!r} not found (looked in {base})", file=path, column=key)
    return target
