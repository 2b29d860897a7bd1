"""Sample-by-sample DEM (:class:`OnlineDEM`): the batch observer's flow fed one sample at a time."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from attend._validation import AttendInputError, numeric_array, require_finite
from attend.perception.dem_flow import start_state
from attend.perception.sample_window import push_sample

if TYPE_CHECKING:
    from attend.perception.dem import DEMObserver


class OnlineDEM:
    """Sample-by-sample DEM: fixed-size state, output delayed by ``observer.delay`` samples.

    ``step(y, u)`` takes sample k (outputs, and the measured input or input prior) and returns
    (states, inputs) at sample k - delay once enough samples have arrived (None before).
    ``finish()`` returns the last ``delay`` estimates by repeating the final sample, as the
    batch mode does at the end of a log; batch and online results agree sample by sample.
    Memory does not grow with the length of the stream.
    """

    def __init__(self, observer: "DEMObserver"):
        self.observer = observer
        mats = observer.generalized_matrices()
        self._transition = mats["transition"]
        self._gain = mats["window_gain"]
        self._order0_gain = mats["order0_gain"]
        offsets = mats["offsets"]
        self._before = int(-offsets[0])
        self._window = len(offsets)
        self._width = observer.system.n_outputs + observer.system.n_inputs
        self._buffer = np.zeros((self._window, self._width))
        self._count = 0
        self._state: np.ndarray | None = None
        self._n = observer.system.n_states
        self._n_x = self._n * (observer.embedding_order + 1)
        self._r = observer.system.n_inputs
        self._order0 = observer.edges == "order0"

    def _advance(self, edge: bool) -> tuple[np.ndarray, np.ndarray]:
        if edge:
            data = self._buffer[self._before]
            drive = self._order0_gain @ data
        else:
            data = self._buffer.reshape(-1)
            drive = self._gain @ data
        if self._state is None:
            self._state = start_state(self.observer, self._buffer, self._before, edge)
        before = self._state
        self._state = self._transition @ self._state + drive
        reported = before if self.observer.integration == "spm" else self._state  # docs/spm.md
        states = reported[: self._n].copy()
        if self.observer.known_inputs:
            inputs = self._buffer[self._before, -self._r:].copy()
        else:
            inputs = reported[self._n_x: self._n_x + self._r].copy()
        return states, inputs

    def step(self, output, input_value=None):
        """Feed sample k (output: the outputs (m,); input_value: the input or input prior (r,),
        default 0); return (states, inputs) of sample k - delay, or None while the first window fills."""
        output = np.ravel(numeric_array(output, "step: output"))
        input_value = np.zeros(self._r) if input_value is None else np.ravel(numeric_array(input_value, "step: input_value"))
        sample = np.concatenate([output, input_value])
        if sample.shape[0] != self._width:
            raise AttendInputError(f"step: expected {self._width - self._r} outputs and {self._r} inputs")
        require_finite(sample, "step sample")
        self._count = push_sample(self._buffer, sample, self._count)
        lead = self._window - 1 - self._before  # future samples needed by the window
        if self._count <= lead:
            return None
        row = self._count - 1 - lead
        return self._advance(edge=self._order0 and row < self._before)

    def finish(self) -> list[tuple[np.ndarray, np.ndarray]]:
        """Flush the estimates still waiting for future samples (end samples repeated)."""
        lead = self._window - 1 - self._before
        out = []
        for _ in range(min(lead, self._count)):
            self._buffer[:-1] = self._buffer[1:].copy()
            out.append(self._advance(edge=self._order0))
        return out
