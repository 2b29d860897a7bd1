"""The DEM observer as a python-control system (`pip install control`).

- :func:`observer_to_statespace`: a DEM observer as a causal discrete-time ``control.StateSpace``.
  (The other way, a ``control.StateSpace`` as an attend model, is
  :func:`attend.models.from_statespace`.)

The observer's estimate of sample k needs the samples up to k + delay (its embedding window),
so as a causal system it runs ``delay`` samples behind: its state stacks the generalised
estimate X (dim X) and the last W - 1 raw samples [y; u] (W = window length); its input is the
newest sample [y; u][k]; its output is the order-0 estimates [x; v] at sample k - delay::

    X[k] = Phi X[k-1] + G window[k - delay]          (window = the W samples ending at k)
    out[k] = [x; v] of X[k]

This is the steady-state observer away from the ends of a log (no edge handling).
"""

from __future__ import annotations

import numpy as np

from attend._validation import AttendInputError
from attend.perception.dem import DEMObserver


def _control():
    try:
        import control
    except ImportError:  # pragma: no cover - exercised only without the optional dependency
        raise AttendInputError("python-control is not installed: pip install control") from None
    return control


def observer_to_statespace(observer: DEMObserver):
    """The DEM observer as a causal discrete-time control.StateSpace (dt = observer.dt).

    Inputs: [y (m); u or eta (r)] at sample k. Outputs: [x (n); v (r)] at sample k - delay
    (for known inputs the v outputs repeat the measured inputs). States: X, then the W - 1
    previous raw samples, oldest first. Only for ``integration="attend"`` (an SPM-convention
    observer reports the state before each step, which this form does not hold).
    """
    if getattr(observer, "integration", "attend") != "attend":
        raise AttendInputError(f"observer.integration: {observer.integration!r} cannot be exported; expected "
                               "'attend' (the SPM convention reports the state before each step)")
    control = _control()
    mats = observer.generalized_matrices()
    transition, gain = mats["transition"], mats["window_gain"]
    offsets = mats["offsets"]
    window = len(offsets)
    system = observer.system
    width = system.n_outputs + system.n_inputs
    size = transition.shape[0]
    buffer = (window - 1) * width
    # the window for the row emitted at k: samples k - W + 1 .. k, i.e. buffer (oldest first) + newest
    gain_buffer, gain_newest = gain[:, :buffer], gain[:, buffer:]
    A = np.zeros((size + buffer, size + buffer))
    B = np.zeros((size + buffer, width))
    A[:size, :size] = transition
    A[:size, size:] = gain_buffer
    B[:size, :] = gain_newest
    if buffer:
        A[size: size + buffer - width, size + width:] = np.eye(buffer - width)  # shift the buffer
        B[size + buffer - width:, :] = np.eye(width)  # newest sample enters last
    n, r = system.n_states, system.n_inputs
    n_x = n * (observer.embedding_order + 1)
    C = np.zeros((n + r, size + buffer))
    C[:n, :n] = np.eye(n)
    D = np.zeros((n + r, width))
    if not observer.known_inputs:
        C[n:, n_x: n_x + r] = np.eye(r)
    # read the state after this step's update: out[k] = C (A s[k] + B in[k])
    C, D = C @ A, C @ B
    if observer.known_inputs:
        # pass the measured input of the emitted row through. Before this step's update the
        # buffer holds samples k - W + 1 .. k - 1 (oldest first); the row's centre sits at window
        # position -offsets[0], which is the newest sample (a D term) when it is W - 1.
        position = -int(offsets[0])
        if position < window - 1:
            column = size + position * width + system.n_outputs
            C[n:, column: column + r] = np.eye(r)
        else:
            D[n:, system.n_outputs:] = np.eye(r)
    names_in = [*system.output_names, *system.input_names]
    names_out = [*system.state_names, *system.input_names]
    return control.ss(A, B, C, D, observer.dt, inputs=names_in, outputs=names_out, name="dem_observer")
