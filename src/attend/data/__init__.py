"""Bundled demo data: one quadrotor flight in wind (roll axis) and its model file."""

from __future__ import annotations

from importlib import resources
from pathlib import Path


def demo_paths() -> tuple[Path, Path]:
    """(model TOML, log CSV) of the built-in demo: quadrotor roll, flight exp_21 with wind."""
    root = resources.files("attend.data")
    return Path(str(root / "quadrotor_roll.toml")), Path(str(root / "quadrotor_roll_wind.csv"))
