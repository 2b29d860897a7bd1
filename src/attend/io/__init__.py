"""Model files (TOML) and logs (CSV) read and validated; estimates (CSV) and learned model files
(TOML) written. Reading and writing only: what `attend estimate` and `attend identify` run on the
files is :mod:`attend.workflows`.

Model file (all times in seconds)::

    [model]
    A = [[0, 1], [0, 0]]            # continuous-time state matrix [1/s]
    B = [[0], [0.37]]               # input matrix
    C = [[1, 0]]                    # output matrix
    states = ["phi", "phi_dot"]     # optional names (default x1, x2, ...)
    dt = 0.008333                   # optional; must match the log's sample time

    [outputs]
    columns = ["meas_phi"]          # CSV columns holding the outputs, one per row of C

    [[inputs]]                      # one table per column of B, in order
    name = "motor_1"
    column = "motor_1"              # known input: measured in this CSV column
    operating_point = 170.0         # optional: subtracted from the column (linearisation point)
    [[inputs]]
    name = "wind"
    prior_mean = 0.0                # unknown input: prior mean eta ...
    prior_precision = 1.0           # ... and prior precision P_v [1/unit^2]

    [observer]
    method = "kalman"               # "kalman" (default: coloured-noise Kalman smoother) or "dem"
    kernel_width = 0.006            # s, Gaussian noise kernel width of both noises (0: white)
    # process_kernel_width = 0.01   # s, or separately for w and z (each overrides kernel_width)
    # sensor_kernel_width = 0.0
    # input_kernel_width = 0.05     # s, smoothness of the unknown inputs' prior (default: process width)
    sensor_precision = 1.2e8        # Pi_z: scalar, per-output list, or matrix
    process_precision = [1e3, 1e2]  # Pi_w: scalar, per-state list, or matrix
    # initial_state = [0.0, 0.0]    # prior mean of x[0] (default: unknown, a broad prior) ...
    # initial_state_std = 0.1       # ... and its std (default 0 when initial_state is given)
    embedding_order = "auto"        # DEM only: p (default "auto": the largest stable, well-conditioned p <= 6)
    input_order = 2                 # DEM only: d
    precision_convention = "size"   # DEM only: "size" (SPM) or "max" (Meera)
    known_input_precision = 7.9e13  # DEM only: prior precision given to measured inputs when some
                                    # inputs are unknown (default exp(32))
    # integration = "spm"           # DEM only: "attend" (default) or "spm": spm_DEM's one-sample step
    # edges = "clamp"               # DEM only: "order0" (default) or "clamp" (SPM's; docs/spm.md)
    # states = "path"               # nonlinear DEM only: "sample" (default, the D-step) or "path"
                                    # (one trajectory for the whole log: a smoother; docs/nonlinear.md)
    # motion = "path"               # nonlinear DEM only: "linearized" (default, SPM's) or "path"
                                    # (f~ along the path; Lorenz path mode: ties the UKF smoother)

    [log]
    time_column = "t"               # CSV column with time stamps [s]: uniform, or with gaps and jitter
                                    # (`attend estimate`: docs/command-line.md, Gaps and jitter)

    [learning]                      # only for `attend identify` (all inputs measured)
    free = ["A[2,1]", "A[2,2]", "B[2,1]", "B[2,2]", "B[2,3]", "B[2,4]"]   # entries to learn (1-based)
    free_prior_precision = 1.0      # P_theta of the free entries (their prior means: [model])
    known_prior_precision = inf     # P_theta of the other entries: inf holds them fixed (exp(15) = 3.3e6: nearly)
    noise_prior_mean = [0.0, 0.0]   # eta_lambda of [lambda_z, lambda_w] (log-precisions)
    noise_prior_precision = 1.0     # P_lambda
    max_iterations = 50
    tolerance = 1e-3                # stop when an iteration raises F by less
    states = "sample"               # "sample" (paper's eq. 8) or "path" (one state path, data counted once)
    top_order = "marginal"          # top-order motion error: "marginal" (default) or "truncate" (eq. 8)

Nonlinear models: in [model], instead of A, B, C::

    python = "model.py"             # beside the model file: defines f(x, v) -> dx/dt and g(x, v) -> y
    n_states = 2                    # (or f(x, v, parameters), g(x, v, parameters) with a dict
    n_inputs = 1                    #  `parameters` in model.py; [model] parameters = {...} overrides it)
    n_outputs = 2
    parameters = { damping = 0.3 }  # optional
    vectorized = true               # optional: f and g take (n, K) columns, one point per column
                                    # (checked against single calls when the file is read)

[outputs], [[inputs]] (one per input of f and g; none when n_inputs = 0), [observer] (one
kernel_width; method "ukf", the default, or "dem") and [log] as above. Errors in f or g name the
Python file, the line and the function.

Log file: CSV with a header row; the time column, the output columns and the known-input
columns named in the model file (other columns are ignored).
"""

from attend.constants import KNOWN_INPUT_PRECISION  # noqa: F401 (importable from attend.io as before)
from attend.io.learned import write_learned_model, write_learned_nonlinear
from attend.io.logs import Log, read_log, write_estimates
from attend.io.model import InputSpec, ModelFile
from attend.io.model_file import NONLINEAR_KNOWN_INPUT_PRECISION, NONLINEAR_METHOD, read_model  # noqa: F401

__all__ = [
    "InputSpec", "Log", "ModelFile", "read_log", "read_model", "write_estimates", "write_learned_model",
    "write_learned_nonlinear",
]

for _name in __all__:  # their public home: the API reference and pickles name attend.io
    globals()[_name].__module__ = __name__
del _name
