"""The parsed model file (:class:`ModelFile`, one :class:`InputSpec` per input). The estimator it
describes is built by :mod:`attend.perception.file_estimators`."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from attend._validation import AttendInputError
from attend.models.linear import LinearSystem
from attend.models.nonlinear import NonlinearSystem

if TYPE_CHECKING:  # only named in annotations
    from attend.io.bags import BagLayout
    from attend.models.noise_model import NoiseModel


@dataclass(frozen=True)
class InputSpec:
    """One input: measured in ``column`` (known) or estimated with a Gaussian prior.

    name: the input's name (a column of B, in order); column: the CSV column holding its
    measurement, or None for an unknown input; prior_mean: eta, the prior mean of an unknown
    input [input unit]; prior_precision: P_v [1/input unit^2] of an unknown input;
    operating_point: the linearisation point subtracted from the measured column [input unit].
    """

    name: str
    column: str | None
    prior_mean: float = 0.0
    prior_precision: float = 1.0
    operating_point: float = 0.0

    @property
    def known(self) -> bool:
        """True when the input is measured (read from a CSV column)."""
        return self.column is not None


@dataclass(frozen=True)
class ModelFile:
    """A parsed model file: the system, its CSV mapping and the observer settings.

    system: the model ([model]: A, B, C, or f and g of a Python file); dt: the sample time the
    file asks for [s] (None: the log's); output_columns: the CSV column of each output (m,);
    inputs: one :class:`InputSpec` per input (r,); kernel_width: s [s], the Gaussian kernel width
    of both noises (0: white); embedding_order: p, an int or "auto"; input_order: d;
    sensor_precision: Pi_z [1/output unit^2] and process_precision: Pi_w, each a scalar, a
    per-row list or a matrix; precision_convention: "size" (SPM) or "max" (Meera);
    known_input_precision: prior precision [1/input unit^2] DEM gives measured inputs when some
    are unknown; time_column: the CSV column of time stamps [s]; learning: the [learning]
    section as a dict (None: absent); path: the model file (errors name it); method: "kalman",
    "dem" or (nonlinear) "ukf"; process_kernel_width: s_w [s], sensor_kernel_width: s_z [s] and
    input_kernel_width: s_u [s], each overriding kernel_width for w, z and the unknown inputs'
    prior (None: not given); initial_state: prior mean of x[0] (n,) (None: a broad prior);
    initial_state_std: its std [state unit], scalar or (n,); python_path: the resolved Python
    file of a nonlinear model ("" for a linear one); integration: DEM's one-sample step, "attend"
    or "spm" (spm_DEM's conventions, docs/spm.md); edges: DEM's windows at the ends of the log,
    "order0" or "clamp" (SPM's); dem_states: nonlinear DEM's "sample" (D-step) or "path" (one
    trajectory, a smoother; :mod:`attend.perception.nonlinear.path`); dem_backend: nonlinear DEM's
    "numpy" or "jax" (:mod:`attend.perception.nonlinear.jax_backend`); dem_motion: nonlinear DEM's
    generalised motion, "linearized" (SPM's) or "path" (f~ along the path, keeping its curvature);
    None: the default of each use (estimate: "linearized"; identify's learn_path: "path");
    bag_layout: how a ROS bag or MCAP file becomes the log ([log] rate_hz, grid_topic, resample,
    stamps, max_gap and [log.columns], :class:`attend.io.bags.BagLayout`; None: the file has no
    [log.columns], CSV logs only).
    """

    system: LinearSystem
    dt: float | None
    output_columns: tuple[str, ...]
    inputs: tuple[InputSpec, ...]
    kernel_width: float | None
    embedding_order: int | str
    input_order: int
    sensor_precision: object
    process_precision: object
    precision_convention: str
    known_input_precision: float
    time_column: str
    learning: dict = None
    path: str = ""
    method: str = "kalman"
    process_kernel_width: float | None = None
    sensor_kernel_width: float | None = None
    input_kernel_width: float | None = None
    initial_state: tuple | None = None
    initial_state_std: object = None
    python_path: str = ""  # the Python file of a nonlinear model ([model] python), resolved
    integration: str = "attend"
    edges: str = "order0"
    dem_states: str = "sample"
    dem_backend: str = "numpy"
    dem_motion: str | None = None
    bag_layout: BagLayout | None = None

    @property
    def nonlinear(self) -> bool:
        """True for a model given by f and g in a Python file ([model] python)."""
        return isinstance(self.system, NonlinearSystem)

    @property
    def noise(self) -> NoiseModel:
        """The file's noise as one :class:`attend.models.NoiseModel` (its sensor_precision,
        process_precision, and process_kernel_width / sensor_kernel_width where given, kernel_width
        otherwise), the value every estimator and simulator takes as ``noise=``; a setting the
        model cannot take raises an AttendInputError naming the file."""
        from attend.models.noise_model import NoiseModel

        try:
            return NoiseModel(process_precision=self.process_precision, sensor_precision=self.sensor_precision,
                              kernel_width=self.kernel_width, process_kernel_width=self.process_kernel_width,
                              sensor_kernel_width=self.sensor_kernel_width)
        except AttendInputError as error:
            raise AttendInputError(f"{self.path}: [observer] {error}") from None

    @property
    def learning_order(self) -> int:
        """The file's embedding order, or 6 (the largest that "auto" picks) when it says "auto"."""
        return 6 if self.embedding_order == "auto" else int(self.embedding_order)
