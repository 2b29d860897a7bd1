"""The error raised for bad input to the action (search-and-rescue) part of attend."""

from __future__ import annotations

from attend._validation import AttendInputError


class ActionInputError(AttendInputError):
    """Bad input to a mission, field, camera or planner; the message names the field and the
    expected form (a ValueError subclass)."""
