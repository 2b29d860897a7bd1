"""The error raised for bad mission files and flight logs: it names the file, row and column."""

from __future__ import annotations

from pathlib import Path

from attend.action.errors import ActionInputError


class MissionInputError(ActionInputError):
    """Bad input to a field mission (``attend plan``): the message starts with the file and,
    where they apply, the row (1-based, the header being row 1 of a CSV file) and the column or
    key, then says what was expected.

    message: what is wrong and what was expected; file: the file it is in (None: not from a
    file); row: 1-based row or feature number; column: the column name or key."""

    def __init__(self, message: str, file: str | Path | None = None, row: int | None = None,
                 column: str | None = None) -> None:
        self.file = None if file is None else str(file)
        self.row = row
        self.column = column
        where = []
        if self.file is not None:
            where.append(self.file)
        if row is not None:
            where.append(f"row {row}")
        if column is not None:
            where.append(f"column {column!r}" if self.file and self.file.endswith(".csv") else f"{column}")
        prefix = ", ".join(where)
        super().__init__(f"{prefix}: {message}" if prefix else message)
