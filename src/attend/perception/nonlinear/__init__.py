"""Nonlinear DEM: state and input estimation for dx/dt = f(x, v, theta) + w, y = g(x, v, theta) + z.

The generative model (:class:`attend.models.NonlinearSystem`) is the linear core's with f and g in place of
(A, B, C): w and z are coloured (white noise convolved with a Gaussian kernel of width s), with
spatial precisions Pi_w (``process_precision``) and Pi_z (``sensor_precision``); unknown inputs v
have a prior mean eta (the ``inputs`` argument of :meth:`NonlinearDEM.estimate`) and precision
P_v (``input_prior_precision``), all weighted over orders of motion by S(s).

D-step (spec nonlinear.md): at every sample, the Jacobians fx = df/dx, fv = df/dv, gx, gv at the
current expansion point (order 0 of the estimate) give the generalised predictions::

    g~ = [g(x, v); gx x' + gv v'; gx x'' + gv v''; ...]
    f~ = [f(x, v); fx x' + fv v'; ...]                       (Jacobians held fixed)

and the errors e_y = y~ - g~, e_x = D x~ - f~, e_v = v~ - eta~ with precisions
Vy = kron(S_p, Pi_z), W = kron(S_p, Pi_w), Vv = kron(S_d, P_v). With E = de/dX (Jacobians held
fixed) the free-energy gradient is dF/dX = -E' Pi~ e and its curvature -E' Pi~ E (Gauss-Newton:
second derivatives of f and g are left out, as in SPM). The generalised gradient flow
dX/dt = D X + dF/dX is integrated over one sample dt by its local linearisation (Ozaki)::

    X <- X + (expm(J dt) - I) inv(J) (D X + dF/dX),      J = D - E' Pi~ E,

with the data held at the sample's embedded values y~[k], eta~[k] over the step. For a linear f, g
this is exactly the zero-order-hold discretisation of attend's linear observer
(:class:`attend.perception.dem.DEMObserver`): the two agree to rounding.
``integration="spm"`` follows spm_DEM's D-step instead: the data ride along their generalised
motion (d/dt y~ = D y~) jointly with X over the step, row k is the state before the step with
sample k, and the top order's motion error is 0 (docs/spm.md: equal to SPM's outputs to rounding).

Learning (:mod:`.learning`): :func:`learn_nonlinear` alternates this model's D-step with an
E-step for theta and an M-step for the noise log-precisions (the linear learner's free energy).
:func:`learn_path` (:mod:`.path_learning`) learns theta with the whole trajectory in path mode
(unknown inputs included, noise precisions known) and gives error bars from the estimator's spread.

Units are attend's: seconds. f is a rate [state unit / s], kernel_width s is in seconds
(SPM works in bins: s_bins = s / dt).
"""

from attend._lazy import lazy_exports

#: public name -> the module that defines it, imported at the first use of the name (PEP 562). The
#: model itself (NonlinearSystem, simulate_nonlinear) is in :mod:`attend.models.nonlinear`.
_EXPORTS = {
    "NonlinearDEM": "attend.perception.nonlinear.dem",
    "NonlinearLearningResult": "attend.perception.nonlinear.learning",
    "ParametrisedSystem": "attend.perception.nonlinear.learning",
    "learn_nonlinear": "attend.perception.nonlinear.learning",
    "OnlineNonlinearDEM": "attend.perception.nonlinear.online",
    "PathLearningResult": "attend.perception.nonlinear.path_learning",
    "learn_path": "attend.perception.nonlinear.path_learning",
}

__all__ = [
    "NonlinearDEM",
    "OnlineNonlinearDEM",
    "ParametrisedSystem",
    "NonlinearLearningResult",
    "learn_nonlinear",
    "PathLearningResult",
    "learn_path",
]

__getattr__, __dir__ = lazy_exports("attend.perception.nonlinear", _EXPORTS, globals())
