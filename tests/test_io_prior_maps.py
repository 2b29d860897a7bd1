"""attend.io.prior_maps: prior maps of a search from CSV tables and pictures, row 0 north."""

import numpy as np
import pytest

from attend._validation import AttendInputError
from attend.io.prior_maps import read_prior_map, resample_to_grid


def test_csv_and_png_read_as_relative_likelihoods(tmp_path):
    table = np.array([[0, 1, 2], [3, 4, 5]], dtype=float)
    (tmp_path / "map.csv").write_text("\n".join(",".join(f"{v:g}" for v in row) for row in table) + "\n")
    np.testing.assert_array_equal(read_prior_map(tmp_path / "map.csv"), table)
    from PIL import Image

    grey = np.array([[0, 128, 255], [10, 20, 30]], dtype=np.uint8)
    Image.fromarray(grey, mode="L").save(tmp_path / "map.png")
    np.testing.assert_array_equal(read_prior_map(tmp_path / "map.png"), grey.astype(float))


def test_resampling_puts_row_0_north_and_keeps_nearest_values():
    north_high = np.array([[9.0, 9.0], [1.0, 1.0]])  # row 0 north
    grid = resample_to_grid(north_high, (4, 6))       # attend's maps: row 0 south
    assert grid.shape == (4, 6)
    np.testing.assert_array_equal(grid[:2], 1.0)
    np.testing.assert_array_equal(grid[2:], 9.0)
    west_east = np.array([[1.0, 2.0, 3.0]])
    np.testing.assert_array_equal(resample_to_grid(west_east, (1, 3)), [[1.0, 2.0, 3.0]])


@pytest.mark.parametrize("text, expected", [
    ("1,2\n3,-1\n", "row 2, column 2: expected a relative likelihood >= 0"),
    ("1,2\n3,nan\n", "row 2, column 2: expected a finite number"),
    ("1,2\n3,inf\n", "row 2, column 2: expected a finite number"),
    ("0,0\n0,0\n", "zero everywhere"),
    ("1,2\n3\n", "line 2: expected 2 numbers like line 1, got 1"),
    ("1,x\n", "line 1, column 2: expected a number, got 'x'"),
    ("\n\n", "empty"),
])
def test_bad_prior_maps_are_one_line_errors_naming_the_file(tmp_path, text, expected):
    path = tmp_path / "bad.csv"
    path.write_text(text)
    with pytest.raises(AttendInputError, match="bad.csv") as error:
        read_prior_map(path)
    assert expected in str(error.value)


def test_missing_and_unreadable_files(tmp_path):
    with pytest.raises(AttendInputError, match="not found"):
        read_prior_map(tmp_path / "none.csv")
    (tmp_path / "broken.png").write_bytes(b"not a picture")
    with pytest.raises(AttendInputError, match="broken.png: not a picture"):
        read_prior_map(tmp_path / "broken.png")
