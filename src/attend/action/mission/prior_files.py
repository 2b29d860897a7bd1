"""The prior map of a mission (``[search] prior_map``): where people are more likely to be, as
relative likelihoods w >= 0 (only ratios count).

- CSV ``lon,lat,weight`` (header row, one point per row): every cell takes the weight of the
  nearest point (a point cloud or a regular grid of any spacing);
- GeoTIFF (``.tif``/``.tiff``, needs rasterio): every cell takes the value of the pixel under its
  centre (band 1, in the file's own CRS); cells off the raster or on nodata get 0.
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from attend.action.mission.errors import MissionInputError


def read_prior_weights(path, ground) -> np.ndarray:
    """Relative likelihoods (ny, nx) on ``ground``'s grid from the file at ``path`` (module docstring)."""
    path = Path(path)
    if path.suffix.lower() in (".tif", ".tiff"):
        weights = _from_geotiff(path, ground)
    else:
        weights = _from_csv(path, ground)
    if not np.any(weights[ground.searchable] > 0):
        raise MissionInputError("the prior map is 0 on every searchable cell: expected weights > 0 over the area",
                                file=path)
    return weights


def _cell_centres(ground) -> tuple[np.ndarray, np.ndarray]:
    xx, yy = np.meshgrid(ground.grid.centres_x, ground.grid.centres_y)
    return xx, yy


def _from_csv(path: Path, ground) -> np.ndarray:
    points, weights = [], []
    with open(path, newline="", encoding="utf-8-sig") as handle:
        reader = csv.DictReader(handle)
        header = [h.strip() for h in (reader.fieldnames or [])]
        missing = [c for c in ("lon", "lat", "weight") if c not in header]
        if missing:
            raise MissionInputError(f"missing column(s) {', '.join(missing)}: expected the header lon,lat,weight",
                                    file=path, row=1, column=missing[0])
        reader.fieldnames = header
        for number, row in enumerate(reader, start=2):
            values = []
            for column in ("lon", "lat", "weight"):
                text = (row.get(column) or "").strip()
                try:
                    value = float(text)
                except ValueError:
                    raise MissionInputError(f"expected a number, got {text!r}", file=path, row=number,
                                            column=column) from None
                if not math.isfinite(value):
                    raise MissionInputError(f"expected a finite number, got {text!r}", file=path, row=number,
                                            column=column)
                values.append(value)
            if not (-180 <= values[0] <= 180 and -90 <= values[1] <= 90):
                raise MissionInputError(f"expected lon, lat in degrees, got {values[0]:g}, {values[1]:g}", file=path,
                                        row=number, column="lon")
            if values[2] < 0:
                raise MissionInputError(f"expected a weight >= 0, got {values[2]:g}", file=path, row=number,
                                        column="weight")
            points.append(values[:2])
            weights.append(values[2])
    if not points:
        raise MissionInputError("no rows: expected one lon,lat,weight row per point", file=path)
    lon, lat = np.array(points).T
    x, y = ground.frame.to_local(lon, lat)
    xx, yy = _cell_centres(ground)
    _, nearest = cKDTree(np.column_stack([x, y])).query(np.column_stack([xx.ravel(), yy.ravel()]))
    return np.asarray(weights)[nearest].reshape(xx.shape)


def _from_geotiff(path: Path, ground) -> np.ndarray:
    try:
        import rasterio
        from pyproj import Transformer
    except ImportError:  # pragma: no cover - rasterio is in the test and geotiff extras
        raise MissionInputError('reading a GeoTIFF needs rasterio: pip install "attend[geotiff]"', file=path) from None
    try:
        with rasterio.open(path) as source:
            band = source.read(1, masked=True).astype(float).filled(0.0)
            crs, transform = source.crs, source.transform
    except rasterio.errors.RasterioError as error:
        raise MissionInputError(f"not a readable GeoTIFF: {error}", file=path) from None
    if crs is None:
        raise MissionInputError("the GeoTIFF has no CRS: expected a georeferenced raster", file=path)
    xx, yy = _cell_centres(ground)
    to_raster = Transformer.from_crs(ground.frame.crs, crs.to_wkt(), always_xy=True)
    rx, ry = to_raster.transform(xx.ravel(), yy.ravel())
    cols, rows = ~transform @ (np.asarray(rx), np.asarray(ry))
    rows, cols = np.floor(rows).astype(int), np.floor(cols).astype(int)
    inside = (rows >= 0) & (rows < band.shape[0]) & (cols >= 0) & (cols < band.shape[1])
    out = np.zeros(xx.size)
    out[inside] = band[rows[inside], cols[inside]]
    if not np.all(np.isfinite(out)) or np.any(out < 0):
        raise MissionInputError("expected finite weights >= 0 in band 1", file=path)
    return out.reshape(xx.shape)
