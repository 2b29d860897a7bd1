"""Reliability table of predicted probabilities against outcomes, shared by the search benchmarks.

For each bin [low, high) of the predicted probability q: the number of cases n, the mean of q
over them and the observed frequency f of the event, with its binomial standard error
sqrt(f (1 - f) / n). Calibrated predictions have mean q within about two standard errors of f.
"""

from __future__ import annotations

import numpy as np

EDGES = (0.0, 0.5, 0.9, 1.0001)


def print_calibration_bins(predicted, observed, what: str, cases: str, edges=EDGES) -> None:
    """Print one line per non-empty bin of ``predicted`` (probabilities) with the observed rate of
    ``observed`` (0/1); ``what`` names the probability, ``cases`` the unit counted."""
    predicted = np.asarray(predicted, dtype=float)
    observed = np.asarray(observed, dtype=float)
    for low, high in zip(edges[:-1], edges[1:]):
        inside = (predicted >= low) & (predicted < high)
        if inside.any():
            rate = observed[inside].mean()
            error = np.sqrt(max(rate * (1 - rate), 1e-12) / inside.sum())
            print(f"  {what} in [{low:.2f}, {min(high, 1.0):.2f}): {inside.sum():4d} {cases}, mean "
                  f"{predicted[inside].mean():.3f}, observed {rate:.3f} (standard error {error:.3f})")
