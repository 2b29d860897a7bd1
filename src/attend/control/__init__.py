"""Active inference control: action from precision-weighted sensory prediction errors (issue 28).

A generative process (the world: its own f, g and noise, with the action a entering f) and a
generative model (the agent's f, g, with priors on causes as intentions or targets) are coupled
sample by sample. Perception is the D-step of DEM in generalised coordinates
(dX/dt = D X + dF/dX); action descends the precision-weighted sensory prediction error,

    da/dt = -kappa (dy~/da)' kron(S, Pi_z) (y~ - g~),

with dy~/da the process's Markov parameters [g_a; g_x f_a; g_x f_x f_a; ...] (SPM's convention).
Sensory precision Pi_z is constant, state-dependent (Pi_z(x, v), like spm_ALAP's M.ph: attention,
sensory attenuation), modulated by a rhythm (attend.rhythm) or learned online.

- :class:`GenerativeModel` (the agent), :class:`GenerativeProcess` (the world),
  :func:`markov_parameters` (dy~/da of a linear plant)
- :class:`ActiveInferenceController` (``step(y) -> a``), :class:`SensorPrecisionLearning`,
  :class:`StepInfo`
- :func:`run` (the closed loop) -> :class:`ClosedLoop`; :func:`run_generalised` (spm_ADEM's loop: the world's
  generalised response per bin) -> :class:`GeneralisedLoop`; :func:`closed_loop_spectral_radius`;
  :func:`linear_controller` (a linear agent as an LTI map y -> a, for loop analysis)
- baselines (:mod:`attend.control.baselines`): :class:`PIDController`, :class:`LQGController`;
  metrics (:mod:`attend.control.metrics`): :func:`step_metrics`, :class:`StepMetrics`
- errors: :class:`ClosedLoopDivergence` (an :class:`attend.AttendInputError`)
- the sensory-attenuation reproduction: :mod:`attend.control.attenuation` (run, plot, claims)
- the reaching reproduction (SPM's ADEM_reaching): :mod:`attend.control.reaching` (run, plot, claims)
- the quadrotor roll plant of the wind flights and its identified wind: :mod:`attend.control.roll`
- a two-link arm in the vertical plane (rigid-body dynamics, torque disturbances, angle sensors) and
  building blocks of its controllers: :mod:`attend.control.arm`
"""

from attend.control._checks import ClosedLoopDivergence
from attend.control.baselines import LQGController, PIDController
from attend.control.controller import ActiveInferenceController, SensorPrecisionLearning, StepInfo
from attend.control.loop import (ClosedLoop, GeneralisedLoop, closed_loop_spectral_radius, linear_controller, run,
                                 run_generalised)
from attend.control.metrics import StepMetrics, step_metrics
from attend.control.model import GenerativeModel
from attend.control.process import GenerativeProcess, markov_parameters

__all__ = [
    "ActiveInferenceController", "ClosedLoop", "ClosedLoopDivergence", "GeneralisedLoop", "GenerativeModel",
    "GenerativeProcess", "LQGController", "PIDController", "SensorPrecisionLearning", "StepInfo", "StepMetrics",
    "closed_loop_spectral_radius", "linear_controller", "markov_parameters", "run", "run_generalised", "step_metrics",
]
