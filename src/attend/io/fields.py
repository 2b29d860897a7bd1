"""Field readers of the model file: text of a user's file, numbers, names and matrices, with the
file's key names in every error."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from attend._validation import AttendInputError, number, numeric_array, require_finite, require_moderate, unique_names


def _check_keys(table: dict, allowed: set[str], where: str, path: str) -> None:
    unknown = sorted(set(table) - allowed)
    if unknown:
        raise AttendInputError(
            f"{path}: unknown key{'s' if len(unknown) > 1 else ''} {', '.join(map(repr, unknown))} "
            f"in [{where}]; expected one of {', '.join(sorted(allowed))}"
        )


def _read_text(path: str | Path, what: str) -> str:
    """The text of a user's file (UTF-8, an optional BOM dropped); a missing file, a directory,
    a permission problem or binary content is an AttendInputError naming the file."""
    path = Path(path)
    try:
        raw = path.read_bytes()
    except FileNotFoundError:
        raise AttendInputError(f"{what}: {path} does not exist") from None
    except IsADirectoryError:
        raise AttendInputError(f"{what}: {path} is a directory; expected a file") from None
    except PermissionError:
        raise AttendInputError(f"{what}: {path} cannot be read (permission denied)") from None
    except OSError as error:
        raise AttendInputError(f"{what}: {path} cannot be read ({error.strerror or error})") from None
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as error:
        raise AttendInputError(
            f"{path}: expected a UTF-8 text {what}, found byte 0x{raw[error.start]:02x} at byte {error.start} "
            "(a binary file, or text in another encoding: save it as UTF-8)"
        ) from None
    if "\x00" in text:
        raise AttendInputError(f"{path}: expected a text {what}, found a NUL byte (a binary file?)")
    return text


def _matrix(value, field: str) -> np.ndarray:
    """A model-file matrix: numbers (no text), finite and within +-1e150."""
    array = numeric_array(value, field, "a matrix of numbers (a list of rows)")
    require_finite(array, field)
    require_moderate(array, field)
    return array


def _file_number(table: dict, key: str, field: str, default: float, *, minimum: float | None = None,
                 positive: bool = False, allow_inf: bool = False) -> float:
    """table[key] as a finite (or, with ``allow_inf``, infinite) number within +-1e150 and the bounds."""
    if key not in table:
        return default
    value = number(table[key], field)
    if math.isnan(value) or (math.isinf(value) and not (allow_inf and value > 0)):
        raise AttendInputError(f"{field}: expected a finite number, got {value}")
    if math.isfinite(value):
        require_moderate(np.array([value]), field)
    if positive and not value > 0:
        raise AttendInputError(f"{field}: expected a number > 0, got {value}")
    if minimum is not None and value < minimum:
        raise AttendInputError(f"{field}: expected a number >= {minimum:g}, got {value}")
    return value


def _text(value, field: str) -> str:
    if not isinstance(value, str) or not value.strip():
        raise AttendInputError(f"{field}: expected a non-empty text (in quotes), got {value!r}")
    return value


def _text_list(value, field: str, size: int | None = None, what: str = "names") -> tuple[str, ...]:
    if not isinstance(value, list):
        raise AttendInputError(f"{field}: expected a list of {what} in quotes, got {value!r}")
    names = unique_names(value, field)
    if size is not None and len(names) != size:
        raise AttendInputError(f"{field}: expected {size} {what}, got {len(names)}")
    return names

