"""The sliding window of samples that online observers keep (fixed memory)."""

from __future__ import annotations

import numpy as np


def push_sample(buffer: np.ndarray, sample: np.ndarray, count: int) -> int:
    """Shift ``sample`` into the window ``buffer`` (rows oldest first) and return count + 1.

    buffer: (window, width) the last samples, changed in place; sample: (width,) the new one;
    count: samples pushed so far. The first sample fills the whole window: the samples before
    the log are its first one repeated, as in batch mode.
    """
    if count == 0:
        buffer[:] = sample
    else:
        buffer[:-1] = buffer[1:]
        buffer[-1] = sample
    return count + 1
