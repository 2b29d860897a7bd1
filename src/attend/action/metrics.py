"""Map-quality metrics logged at every image.

RSE = sqrt(sum_i (mean_i - truth_i)^2)   (7.69 for the 0.1 prior with 54 person cells of 1600)
RMSE per cell = RSE / sqrt(n)
trace(P) = sum_i var_i;  trace of interest = sum of var_i over cells with mean_i + sigma_i >= 0.4
people found = people all of whose cells have mean > 0.5 (the spec's criterion);
people found (person mean) = people whose cells' average mean > 0.5 (a looser diagnostic)
false-alarm cells = cells with mean > 0.5 and no person;  false-alarm objects = connected
groups of cells with mean > 0.5 that contain no person cell.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np
import scipy.ndimage

#: A person counts as found when every one of its cells has map mean above this.
FOUND_THRESHOLD = 0.5
INTEREST_THRESHOLD = 0.4


def root_squared_error(mean: np.ndarray, truth: np.ndarray) -> float:
    """RSE = sqrt(sum (mean - truth)^2)."""
    return float(np.sqrt(np.sum((mean - truth) ** 2)))


def map_metrics(
    mean: np.ndarray, variance: np.ndarray, truth: np.ndarray, person_cells: Sequence[np.ndarray], shape: tuple[int, int]
) -> dict[str, float]:
    """All per-image metrics of one belief against the ground truth (module docstring).

    mean, variance: the map's mean and per-cell variance (n,); truth: occupancy 0/1 (n,);
    person_cells: the cell indices of each person; shape: the grid's (ny, nx)."""
    rse = root_squared_error(mean, truth)
    interest = mean + np.sqrt(np.maximum(variance, 0)) >= INTEREST_THRESHOLD
    above = mean > FOUND_THRESHOLD
    found = sum(bool(np.all(above[cells])) for cells in person_cells if len(cells))
    found_on_average = sum(bool(np.mean(mean[cells]) > FOUND_THRESHOLD) for cells in person_cells if len(cells))
    false_cells = above & (truth < 0.5)
    labels, n_groups = scipy.ndimage.label(above.reshape(shape))
    flat_labels = labels.ravel()
    with_person = set(np.unique(flat_labels[(truth > 0.5) & above]).tolist())
    false_objects = sum(1 for g in range(1, n_groups + 1) if g not in with_person)
    return {
        "rse": rse,
        "rmse": rse / np.sqrt(len(mean)),
        "trace": float(np.sum(variance)),
        "trace_interest": float(np.sum(variance[interest])),
        "people_found": float(found),
        "people_found_person_mean": float(found_on_average),
        "false_alarm_cells": float(np.sum(false_cells)),
        "false_alarm_objects": float(false_objects),
    }
