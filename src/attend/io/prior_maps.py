"""Prior maps of a search: where people are more likely to be, as a picture or a table.

A prior map is a grid of relative likelihoods w >= 0 over the search area (only ratios count:
P(a person's centre in cell c) is proportional to w_c). Row 0 is the area's north edge and
column 0 its west edge, as one looks at a map or a picture. Files:

- CSV: one row of comma-separated numbers per map row, no header;
- PNG (or any picture Pillow reads): the grey level of each pixel (colour pictures are turned
  to grey: 0.299 R + 0.587 G + 0.114 B), so a white region is 255 times as likely as a grey
  level of 1 and a black one is excluded.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from attend._validation import AttendInputError

#: File endings read as pictures (everything else is read as CSV).
PICTURE_SUFFIXES = (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp", ".gif")


def read_prior_map(path: str | Path) -> np.ndarray:
    """The relative likelihoods (rows, cols) of a prior-map file, row 0 north, column 0 west.

    path: a CSV table or a picture (module docstring). Raises AttendInputError naming the file
    for a missing or unreadable file, text where a number belongs, ragged rows, NaN, inf,
    negative values, or a map that is zero everywhere."""
    path = Path(path)
    if not path.is_file():
        raise AttendInputError(f"{path}: prior map not found (expected a CSV table or a PNG picture)")
    if path.suffix.lower() in PICTURE_SUFFIXES:
        weights = _read_picture(path)
    else:
        weights = _read_table(path)
    return validate_prior_map(weights, str(path))


def validate_prior_map(weights, field: str) -> np.ndarray:
    """``weights`` as a float (rows, cols) array of relative likelihoods, checked: two
    dimensions, at least one cell, finite, >= 0, not zero everywhere. field: named in errors."""
    array = np.asarray(weights, dtype=float) if not isinstance(weights, np.ndarray) else weights.astype(float)
    if array.ndim != 2 or array.size == 0:
        raise AttendInputError(f"{field}: expected a 2-D map of relative likelihoods, got shape {array.shape}")
    bad = ~np.isfinite(array)
    if bad.any():
        row, col = np.argwhere(bad)[0]
        raise AttendInputError(f"{field}: row {row + 1}, column {col + 1}: expected a finite number, got {array[row, col]}")
    if (array < 0).any():
        row, col = np.argwhere(array < 0)[0]
        raise AttendInputError(f"{field}: row {row + 1}, column {col + 1}: expected a relative likelihood >= 0, "
                               f"got {array[row, col]:g}")
    if not (array > 0).any():
        raise AttendInputError(f"{field}: the prior map is zero everywhere; expected some cells > 0")
    return array


def _read_table(path: Path) -> np.ndarray:
    try:
        text = path.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError:
        raise AttendInputError(f"{path}: not a text file; expected a CSV table of numbers or a PNG picture") from None
    rows = [line for line in text.splitlines() if line.strip()]
    if not rows:
        raise AttendInputError(f"{path}: empty; expected one row of comma-separated numbers per map row")
    table = []
    for i, line in enumerate(rows, start=1):
        cells = line.split(",")
        values = []
        for j, cell in enumerate(cells, start=1):
            try:
                values.append(float(cell))
            except ValueError:
                raise AttendInputError(f"{path}: line {i}, column {j}: expected a number, got {cell.strip()!r}") from None
        if table and len(values) != len(table[0]):
            raise AttendInputError(f"{path}: line {i}: expected {len(table[0])} numbers like line 1, got {len(values)}")
        table.append(values)
    return np.array(table)


def _read_picture(path: Path) -> np.ndarray:
    from PIL import Image, UnidentifiedImageError

    try:
        with Image.open(path) as picture:
            grey = picture.convert("L")
            return np.asarray(grey, dtype=float)
    except (UnidentifiedImageError, OSError) as error:
        raise AttendInputError(f"{path}: not a picture Pillow can read ({error}); expected a PNG") from None


def resample_to_grid(weights: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """The map ``weights`` (row 0 north) on a grid of ``shape`` = (ny, nx) cells with row 0
    south (attend's maps: y grows with the row), by the nearest map cell to each grid cell's
    centre."""
    ny, nx = shape
    rows, cols = weights.shape
    row_of_y = np.minimum(((np.arange(ny) + 0.5) * rows / ny).astype(int), rows - 1)
    col_of_x = np.minimum(((np.arange(nx) + 0.5) * cols / nx).astype(int), cols - 1)
    return weights[::-1][row_of_y][:, col_of_x]
