"""The estimator a model file describes (``[observer]`` of an ``attend estimate`` model file): the
coloured-noise Kalman smoother, the DEM observer, or for a nonlinear model (``[model] python``) a
:class:`NonlinearFileEstimator` (the unscented Kalman smoother, or nonlinear DEM). The model file
itself is read and checked by :mod:`attend.io.model`."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from attend._validation import AttendInputError, precision_matrix

if TYPE_CHECKING:  # imported where it is built: a nonlinear model file loads no linear DEM
    from attend.io.model import ModelFile
    from attend.models.nonlinear import NonlinearSystem
    from attend.perception.dem import DEMObserver


def file_estimator(model: ModelFile, dt: float, outputs=None, signals=None, time=None):
    """The estimator the model file describes (``[observer] method``), for logs sampled every ``dt``
    s: :func:`file_nonlinear_estimator` for a nonlinear model, else :func:`file_kalman_estimator`
    or :func:`file_dem_observer`. model: the parsed :class:`attend.io.model.ModelFile`; outputs
    (N, m), signals (N, r) and time (N,) [s]: the log the estimator will run on (optional), from
    which the Kalman smoother chooses the unknown inputs' prior width when the file gives none."""
    if model.nonlinear:
        return file_nonlinear_estimator(model, dt)
    if model.method == "kalman":
        return file_kalman_estimator(model, dt, outputs, signals, time)
    return file_dem_observer(model, dt)


def file_nonlinear_order(model: ModelFile, dt: float) -> int:
    """The DEM embedding order of a nonlinear model: the file's, or under "auto" the largest
    p <= 6 whose S(s) stays well conditioned (cond <= 1e8 in sample units; the stability check
    of the linear "auto" needs A, B, C). model: the parsed model file; dt: the log's sample time [s]."""
    from attend.models.generalized import smoothness_condition
    from attend.perception.dem import AUTO_MAX_CONDITION, AUTO_MAX_ORDER

    if model.embedding_order != "auto":
        return int(model.embedding_order)
    try:
        for p in range(AUTO_MAX_ORDER, 0, -1):
            if smoothness_condition(p + 1, model.kernel_width, dt) <= AUTO_MAX_CONDITION:
                return p
    except AttendInputError as error:
        raise AttendInputError(f"{model.path}: [observer] embedding_order = \"auto\": {error}") from None
    return 0


def file_nonlinear_estimator(model: ModelFile, dt: float) -> NonlinearFileEstimator:
    """The estimator of a nonlinear model file ``model`` (see :class:`NonlinearFileEstimator`), for
    logs sampled every ``dt`` s."""
    estimator = NonlinearFileEstimator(model, dt, model.method, file_nonlinear_order(model, dt),
                                       model.embedding_order == "auto")
    try:
        estimator.dem()  # the settings are checked here, whichever method runs
    except AttendInputError as error:
        raise AttendInputError(f"{model.path}: [observer] {error}") from None
    return estimator


def file_kalman_estimator(model: ModelFile, dt: float, outputs=None, signals=None, time=None):
    """The coloured-noise Kalman smoother of the model file ``model``, for logs sampled every ``dt``
    s: measured inputs drive the model, the others are estimated.

    When some inputs are unknown, the file gives no ``input_kernel_width`` and the log is passed
    (outputs (N, m), NaN where missing; signals (N, r): the measured inputs and the unknown ones'
    prior means; time (N,) [s] or None), the inputs' prior width is the maximum of the log's
    likelihood over a grid (:func:`attend.perception.input_width.choose_input_width`), recorded in
    the estimator's ``input_width_choice``; a flat likelihood keeps the process width with a
    ModelWarning naming input_kernel_width, and innovations 10x off the model's prediction (in
    std) are a ModelWarning naming the precisions. The white part of the process and sensor noise is
    raised from its numerical floor where the log supports it
    (:func:`attend.perception.input_width.choose_white_floor`; not on jittered time stamps), and the
    width chosen again under it.
    Without the log: the process width."""
    from attend.perception.kalman import KalmanEstimator

    known = [spec.known for spec in model.inputs]
    prior = None if all(known) else np.array([1.0 if s.known else s.prior_precision for s in model.inputs])
    settings = dict(noise=model.noise, input_prior_precision=prior,
                    known_inputs=known if model.inputs else True, initial_state=model.initial_state,
                    initial_state_std=model.initial_state_std)
    try:
        estimator = KalmanEstimator(model.system, dt, input_kernel_width=model.input_kernel_width, **settings)
        if all(known) or model.input_kernel_width is not None or outputs is None:
            return estimator
        return _with_chosen_input_width(estimator, settings, outputs, signals, time, model.path)
    except AttendInputError as error:
        raise AttendInputError(f"{model.path}: [observer] {error}") from None


def _with_chosen_input_width(estimator, settings: dict, outputs, signals, time, path: str):
    """The Kalman smoother of ``settings`` at the input width of largest likelihood on the log, with the
    white part of its noise raised where the log supports it (``estimator``: the one at the process width,
    which is also the fallback; path: the model file, named in the warnings)."""
    import warnings

    from attend.models.linear import ModelWarning
    from attend.models.sample_times import sample_grid
    from attend.perception.input_width import (WhiteFloorChoice, choose_input_width, choose_white_floor,
                                               innovation_terms_on, profiled_log_likelihood)

    def build(width, floor=estimator.noise_white_floor):
        same_width = np.isclose(width, estimator.input_kernel_width, rtol=1e-12, atol=0.0)
        if same_width and floor == estimator.noise_white_floor:
            return estimator
        with warnings.catch_warnings():  # the observability note was given once, by ``estimator``
            warnings.simplefilter("ignore", ModelWarning)
            return type(estimator)(estimator.system, estimator.dt, input_kernel_width=width, noise_white_floor=floor,
                                   **settings)

    def width_at(floor):
        return choose_input_width(lambda width: innovation_terms_on(build(width, floor), outputs, signals, time),
                                  estimator.dt, estimator.input_kernel_width)

    def score(width, floor):
        return profiled_log_likelihood(innovation_terms_on(build(width, floor), outputs, signals, time))[0]

    floor = estimator.noise_white_floor
    stated = width_at(floor)
    used = np.isclose(stated.widths, stated.width, rtol=1e-9, atol=0.0)
    value = float(stated.log_likelihoods[used][0]) if used.any() else score(stated.width, floor)
    if time is not None and not sample_grid(time, estimator.dt).uniform:  # jittered steps keep the floor 1e-8
        floors = WhiteFloorChoice(floor, np.array([floor]), np.array([value]))
    else:
        floors = choose_white_floor(lambda candidate: score(stated.width, candidate), floor, value)
    # the width again, under the noise the log supports; the misfit is judged on the model as stated
    choice = (width_at(floors.floor) if floors.raised else stated)._replace(white_floor=floors)
    _warn(path, choice.warning(), stated.misfit())  # a flat likelihood; a model far from the log
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ModelWarning)
        return type(estimator)(estimator.system, estimator.dt, input_kernel_width=choice.width,
                               noise_white_floor=floors.floor, input_width_choice=choice, **settings)


def _warn(path, *messages) -> None:
    """A ModelWarning "path: message" for each message that is not None (the width choice's warnings)."""
    import warnings

    from attend.models.linear import ModelWarning

    for message in messages:
        if message:
            warnings.warn(f"{path}: {message}", ModelWarning, stacklevel=5)


def file_dem_observer(model: ModelFile, dt: float) -> DEMObserver:
    """The DEM observer the model file ``model`` describes, for logs sampled every ``dt`` seconds.

    All inputs measured: the known-input observer. Otherwise inputs are unknowns; measured
    ones get their measurement as prior mean with precision ``known_input_precision``.
    """
    from attend.perception.dem import DEMObserver

    all_known = all(spec.known for spec in model.inputs)
    prior = None if all_known else np.array(
        [model.known_input_precision if s.known else s.prior_precision for s in model.inputs]
    )
    try:
        return DEMObserver(model.system, dt, noise=model.noise, input_prior_precision=prior,
                           embedding_order=model.embedding_order, input_order=model.input_order,
                           known_inputs=all_known, precision_convention=model.precision_convention,
                           input_kernel_width=model.input_kernel_width,
                           initial_state=None if model.initial_state is None else np.array(model.initial_state),
                           integration=model.integration, edges=model.edges)
    except AttendInputError as error:
        raise AttendInputError(f"{model.path}: [observer] {error}") from None


@dataclass(frozen=True)
class NonlinearFileEstimator:
    """The estimator of a nonlinear model file ([model] python), for logs sampled every ``dt`` s.

    method "ukf": the unscented Kalman (RTS) smoother on a white-noise model with the coloured
    noises' per-sample variance (Q = dt^2 inv(Pi_w), R = inv(Pi_z)); unknown inputs ride in the
    state as random walks whose one-sample increments have the variance of their prior's
    (:func:`attend.perception.nonlinear_smoothers.input_random_walk_variance`), started at the prior mean; measured inputs drive f and g.
    Without [observer] initial_state the smoother starts from the best start of a global search over
    x[0] (:mod:`attend.perception.nonlinear.start_search`; an error naming initial_state where two
    starts fit the log about equally well and lead to different estimates; :meth:`_start`). method "dem": :class:`attend.perception.nonlinear.NonlinearDEM` (measured inputs,
    when some are unknown, get their measurement as prior mean with precision known_input_precision).

    model: the parsed :class:`ModelFile`; dt: sample time [s]; method: "ukf" or "dem";
    embedding_order: p, resolved to an int (:func:`file_nonlinear_order`); automatic_order:
    True when the file said "auto" and p was chosen here; choices: what was chosen from the last log
    (the unknown inputs' width: :attr:`input_width_choice`), filled by :meth:`estimate`.
    """

    model: ModelFile
    dt: float
    method: str
    embedding_order: int
    automatic_order: bool
    choices: dict = field(default_factory=dict, repr=False, compare=False)

    @property
    def system(self) -> NonlinearSystem:
        return self.model.system

    @property
    def known(self) -> np.ndarray:
        return np.array([spec.known for spec in self.model.inputs], dtype=bool)

    def dem(self):
        """The NonlinearDEM of the file's settings."""
        from attend.perception.nonlinear import NonlinearDEM

        model, known = self.model, self.known
        all_known = bool(known.all())
        prior = None if all_known else np.array(
            [model.known_input_precision if spec.known else spec.prior_precision for spec in model.inputs])
        return NonlinearDEM(self.system, self.dt, kernel_width=model.kernel_width,
                            sensor_precision=model.sensor_precision, process_precision=model.process_precision,
                            input_prior_precision=prior, embedding_order=self.embedding_order,
                            input_order=model.input_order, known_inputs=all_known,
                            precision_convention=model.precision_convention,
                            input_kernel_width=model.input_kernel_width, integration=model.integration,
                            edges=model.edges, states=model.dem_states, backend=model.dem_backend,
                            motion=model.dem_motion or "linearized")

    @property
    def input_kernel_width(self) -> float:
        """s_v [s]: the file's input_kernel_width, else the width chosen from the last log (method "ukf",
        :attr:`input_width_choice`), else the kernel width."""
        choice = self.input_width_choice
        return self.model.input_kernel_width or (choice.width if choice is not None else self.model.kernel_width)

    @property
    def input_width_choice(self):
        """How method "ukf" chose the unknown inputs' width on the last log (an
        :class:`attend.perception.input_width.InputWidthChoice`), or None (given, or not estimated yet)."""
        return self.choices.get("input_width")

    def estimate(self, outputs, signals, steps=None):
        """Estimates on outputs (N, m), an :class:`attend.perception.estimate.Estimate` (method "nonlinear
        dem" or "unscented kalman smoother"); signals (N, r): measured inputs (operating point
        removed) or the prior means of the unknown ones; steps: (N - 1,) the steps' lengths [s] of a
        log whose stamps jitter (method "ukf": each step integrated over its own length), None: dt."""
        model = self.model
        self.choices.pop("input_width", None)  # a choice belongs to one log
        initial = None if model.initial_state is None else np.array(model.initial_state)
        if self.method == "dem":
            if steps is not None:
                raise AttendInputError('steps: method "dem" needs samples every dt (a uniform embedding)')
            dem = self.dem()
            return dem.estimate(outputs, signals, initial_state=initial,
                                initial_state_std=_path_prior_std(model) if dem.states == "path" else None)
        from attend.perception.nonlinear_smoothers import unscented_kalman

        r = self.system.n_inputs
        known = self.known
        unknown = bool(r) and not known.all()
        if unknown:
            bad = [spec.name for spec in model.inputs if not spec.known and not spec.prior_precision > 0]
            if bad:
                raise AttendInputError(f"[[inputs]] {', '.join(map(repr, bad))} prior_precision: method \"ukf\" "
                                       "needs a prior precision > 0 (it sets the random walk of the input)")
        # the unknown inputs' prior precisions (1 in the places of the measured ones, which are masked)
        precisions = np.array([1.0 if spec.known else spec.prior_precision for spec in model.inputs]) if unknown \
            else None
        input_mean = signals[0] if unknown else None
        width = self.input_kernel_width
        options = self._ukf_options(width, precisions, input_mean, steps)
        inputs = (signals if known.any() else None) if unknown else (signals if r else None)
        mean, std, substeps = self._start(outputs, signals, initial, inputs, options)
        covariance = np.diag(np.asarray(std, dtype=float) ** 2)
        if unknown and model.input_kernel_width is None:  # the width from the log, as the linear default
            width = self._chosen_input_width(outputs, inputs, mean, covariance, substeps, precisions, input_mean,
                                             steps)
            options = self._ukf_options(width, precisions, input_mean, steps)
        # the std: the smoother's error spread under the file's coloured noise, its exact covariance
        # through the smoother's linearisation (error_spread.smoother_error_covariance: no draws)
        prior = (1.0 / precisions, width) if unknown else None
        from attend.perception.estimate import as_estimate

        return as_estimate(unscented_kalman(self.system, self.dt, outputs, inputs, initial_mean=mean,
                                            initial_covariance=covariance, substeps=substeps, noise_kernel_width=model.kernel_width,
                                            input_prior=prior, spread_draws=None, **options),
                           "unscented kalman smoother")

    def _ukf_options(self, width, precisions, input_mean, steps=None) -> dict:
        """The unscented smoother's noise options of the file (:func:`attend.perception.nonlinear_smoothers.
        white_noise_options`) with the unknown inputs' random walk at width s_v = ``width`` [s]; precisions: the
        inputs' prior precisions (None: no unknown input); input_mean: their prior mean at the first sample;
        steps: the steps' lengths of a jittered log (None: dt)."""
        from attend.perception.nonlinear_smoothers import white_noise_options

        model, system = self.model, self.system
        return dict(step_lengths=steps) | white_noise_options(
            self.dt, process_precision=precision_matrix(model.process_precision, system.n_states, "process_precision"),
            sensor_precision=precision_matrix(model.sensor_precision, system.n_outputs, "sensor_precision"),
            input_prior_precision=precisions, input_kernel_width=width, known_inputs=self.known,
            input_mean=input_mean, who='method "ukf"')

    def _chosen_input_width(self, outputs, inputs, mean, covariance, substeps, precisions, input_mean,
                            steps=None) -> float:
        """s_v [s], the unknown inputs' width of largest likelihood on the log:
        :func:`attend.perception.input_width.choose_input_width` over the unscented filter's prediction-error
        decomposition from the start found (:func:`attend.perception.nonlinear_smoothers.unscented_innovation_terms`),
        the noise level profiled; the random walk's steps follow the width. A flat likelihood keeps the kernel
        width with a warning naming input_kernel_width, as for linear models. steps: as
        :meth:`estimate`."""
        from attend.perception.input_width import choose_input_width
        from attend.perception.nonlinear_smoothers import unscented_innovation_terms

        model = self.model
        choice = choose_input_width(
            lambda width: unscented_innovation_terms(self.system, self.dt, outputs, inputs, initial_mean=mean,
                                                     initial_covariance=covariance, substeps=substeps,
                                                     **self._ukf_options(width, precisions, input_mean, steps)),
            self.dt, model.kernel_width, smallest=model.kernel_width)
        self.choices["input_width"] = choice
        _warn(model.path, choice.warning(), choice.misfit())
        return choice.width

    def _start(self, outputs, signals, initial, inputs, options):
        """(x[0], its std, RK4 sub-steps) of the smoother. With the file's initial_state: it and
        initial_state_std. Without: the best start of a global search over x[0]
        (:func:`attend.perception.nonlinear.start_search.search_start`) under a Gaussian prior about
        DEM's start as wide as its states' spread where DEM's D-step follows the whole log
        (:func:`attend.perception.nonlinear.path_starts.initial_state_prior`), else a Student t (one
        degree of freedom) about 0 with scale the file's initial_state_std or 1; DEM's start, where
        DEM gives one, is also one of the search's starts. An
        :class:`~attend.perception.nonlinear.start_search.AmbiguousStartError` where two starts fit
        the log about equally well and lead to different estimates; a ModelWarning naming
        initial_state where the best start's estimate does not follow the log. Sub-steps:
        :func:`attend.perception.nonlinear.path_starts.smoother_substeps` on DEM's D-step (10 where
        it fails), then, without initial_state, ``rk4_substeps`` along the chosen start's estimate.
        initial: the file's initial_state or None; inputs, options: the smoother's (measured inputs,
        white-noise model)."""
        import warnings

        from attend.models.linear import ModelWarning
        from attend.perception.nonlinear.path_starts import d_step_basis, initial_state_prior, smoother_substeps
        from attend.perception.nonlinear.start_search import MISFIT_LIMIT, AmbiguousStartError, search_start
        from attend.perception.nonlinear_smoothers.kalman import rk4_substeps

        dem, n = self.dem(), self.system.n_states
        dem_start, dem_followed = None, False
        substeps = 10
        try:
            with warnings.catch_warnings():  # of the D-step, which only helps start the smoother here
                warnings.simplefilter("ignore", ModelWarning)
                checked = dem.checked_signals(_interpolated(outputs), signals)
                basis = d_step_basis(dem, checked, dem.dstep_estimate(checked, True, None, check=False))
                substeps = smoother_substeps(dem, basis)
                if initial is None:
                    dem_start, dem_followed = initial_state_prior(dem, checked, basis), basis[1]
        except np.linalg.LinAlgError:  # the D-step failed numerically: the search goes without its hint
            pass
        except AttendInputError as error:
            if self.model.python_path and str(error).startswith(self.model.python_path):
                raise
        if initial is not None:
            given = self.model.initial_state_std
            return initial, np.broadcast_to(np.asarray(0.0 if given is None else given, dtype=float), (n,)), substeps
        centre, scale, dof = None, self.model.initial_state_std, 1.0
        if scale is None and dem_followed:  # DEM's D-step follows the whole log: its start and states' spread
            (centre, scale), dof = dem_start, np.inf
        search = search_start(self.system, self.dt, outputs, inputs, substeps=substeps, prior_mean=centre,
                              prior_scale=None if scale is None else np.asarray(scale, dtype=float), prior_dof=dof,
                              extra_starts=() if dem_start is None else (dem_start,), **options)
        if search.ambiguous:
            raise AmbiguousStartError(search.message)
        best = search.modes[0]
        if best.misfit > MISFIT_LIMIT:
            warnings.warn(f"{self.model.path}: [observer] {search.misfit_message}", ModelWarning, stacklevel=2)
        with np.errstate(all="ignore"):
            substeps = rk4_substeps(self.system, self.dt, best.states, signals)
        return search.mean, search.std, substeps


def _interpolated(outputs) -> np.ndarray:
    """outputs (N, m) with each missing value (NaN) interpolated linearly between the measured ones of
    its column (held at the ends): what DEM's D-step, which needs every sample, reads where it only
    helps the unscented smoother start (the smoother itself skips the missing values). A column
    without any measured value stays NaN (the D-step then refuses the log and the start search
    goes without it)."""
    outputs = np.asarray(outputs, dtype=float)
    missing = np.isnan(outputs)
    if not missing.any():
        return outputs
    filled = outputs.copy()
    samples = np.arange(len(outputs))
    for j in np.flatnonzero(missing.any(axis=0) & ~missing.all(axis=0)):
        known = ~missing[:, j]
        filled[missing[:, j], j] = np.interp(samples[missing[:, j]], samples[known], outputs[known, j])
    return filled


def _path_prior_std(model) -> np.ndarray | None:
    """[observer] initial_state_std for DEM's path mode: None without initial_state; a std of 0
    (x[0] known: the file's default when initial_state is given) becomes 1e-6 (1 + |x[0]|)."""
    if model.initial_state is None:
        return None
    mean = np.asarray(model.initial_state, dtype=float)
    std = np.broadcast_to(np.asarray(0.0 if model.initial_state_std is None else model.initial_state_std,
                                     dtype=float), mean.shape)
    return np.where(std > 0, std, 1e-6 * (1.0 + np.abs(mean)))
