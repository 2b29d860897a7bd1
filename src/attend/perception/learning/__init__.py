"""Learning: system identification, prior-precision modelling and noise-precision estimation.

Alternating D (states), E (parameters) and M (noise precisions) steps that maximise the free
energy of the paper's eq. 8 for an LTI model with **measured inputs** u::

    dx/dt = A x + B u + w,   y = C x + z,   Pi_z = exp(lambda_z) I_m,  Pi_w = exp(lambda_w) I_n.

Symbols (generalised coordinates, p + 1 orders, order-major; S = S_p the temporal precision):

    X_t = x~_t                     states at sample t (the D-step unknowns)
    e_y = y~ - C~ x~               sensory error,  precision Vy = kron(S, Pi_z)
    e_x = D x~ - A~ x~ - B~ u~     motion error,   precision W  = kron(S, Pi_w)
    theta = [vec(A); vec(B); vec(C)] (row-major), prior N(eta_theta, inv(P_theta)), P_theta diagonal
    lambda = [lambda_z; lambda_w],  prior N(eta_lambda, inv(P_lambda))

Mean-field Laplace posterior q(X_t) = N(mu_t, Sigma_X), q(theta) = N(theta, Sigma_theta),
q(lambda) = N(lambda, Sigma_lambda). The free energy maximised here is (constants dropped)::

    F = -1/2 sum_t E_q(X)[e_y' Vy e_y + e_x' W e_x]                    expected energy
        + n_t/2 (ln|Sigma_X| + dim X) + n_t/2 (ln|Vy| + ln|W|)          state / noise entropy
        - 1/2 e_theta' P_theta e_theta - 1/2 e_lambda' P_lambda e_lambda   priors
        + 1/2 ln|Sigma_theta P_theta| + 1/2 ln|Sigma_lambda P_lambda|       parameter entropy

with e_theta = theta - eta_theta, e_lambda = lambda - eta_lambda. At Sigma_X = inv(Pi_X) the
expectation equals the paper's sum of e' Pi e at the means plus n_t dim X, so F is eq. 8.

Because every error is linear in X for fixed theta and linear in theta for fixed X, the
expected energy is a quadratic in theta built from the S-weighted second moments

    K_ab = sum_t sum_ij S_ij E[a^(i) b^(j)']   (a, b among x, u, y, tau = x^(i+1))

that include the state uncertainty (E[x x'] = mu mu' + Sigma_X: the EM correction). With
phi = [x; u] and Theta = [A B]::

    H = blkdiag(Pi_w (x) K_phiphi, Pi_z (x) K_xx),  g = [vec(Pi_w K_tauphi); vec(Pi_z K_yx)]
    E-step objective  -1/2 theta' H theta + g' theta - 1/2 e_theta' P_theta e_theta
    posterior parameter precision  Pi_theta = H + P_theta = -d2F/dtheta2

Steps (each accepted only if F does not decrease; otherwise shrunk and retried):

* D-step: mu_t = inv(Pi_X) (C~' Vy y~_t + (D - A~)' W B~ u~_t), Sigma_X = inv(Pi_X),
  Pi_X = C~' Vy C~ + (D - A~)' W (D - A~)  (the exact per-sample maximiser; accepted with halving).
* E-step: theta <- theta* + expm(L J) (theta - theta*), J = -(H + P_theta),
  theta* = inv(H + P_theta)(g + P_theta eta_theta): the gradient flow of the quadratic
  integrated over the time L (``integration_time``, 10 as in Meera's code), i.e.
  theta += (expm(L J) - I) inv(J) dF/dtheta.
* M-step: dF/dlambda_z = -1/2 [exp(lambda_z) E_z + tr(Sigma_theta H_z)] + n_t m (p+1)/2
  - P_lambda (lambda_z - eta_lambda) (E_z the expected S-weighted sensory error, H_z the
  sensory part of H) and likewise for lambda_w; curvature the expected (Fisher) one
  -n_t/2 diag(m(p+1), n(p+1)) - P_lambda; step with integration time 4, clipped to +-2, up to 8
  inner iterations. The same curvature is the reported posterior precision Pi_lambda (it is
  -d2F/dlambda2 at the optimum) and enters the constant term 1/2 ln|Sigma_lambda P_lambda|.

Choices (where the published settings leave room): the D-step is the direct per-sample solve
(the fixed point of the DEM observer's flow), not the flow itself; inputs are embedded with
``input_order`` + 1 orders (default: as many as the states, the input being measured);
samples whose embedding window reaches past the log are left out of the sums
(``trim_edges``); entries with infinite prior precision are held fixed at their prior mean;
the noise log-precisions start at their prior mean (default 0, P_lambda = 1).

Numerics (the measurements behind each choice: docs/design.md, "Learning: design notes").
(1) Scaled generalised coordinates: order k is held as sigma^k d^k/dt^k, sigma = sqrt(2) s, so the
temporal precision is S's O(1) core (an exact reparameterisation, ``_prepare``). (2) Sample mode
marginalises the top-order motion error (x^(p+1) is not modelled): W keeps the precision
inv(V[:p, :p]) of orders 0..p-1 and counts p n dimensions, which keeps F bounded in lambda_w at
high sampling rates. (3) Over-relaxation: after each D-E-M sweep its total move in (theta, lambda)
is extended beta times (beta doubling on success, reset on failure), accepted only if F rises.
(4) Newton: once sweeps creep (gain < NEWTON_CREEP |F|), a Levenberg-Marquardt step on the
collapsed F*(theta, lambda) = max_q F, gradient by the envelope theorem, Hessian by differences;
accepted only if F rises.

Options: the fields of :class:`LearningSettings`, the one settings value :func:`identify` and
:func:`learn_batch` take (its docstring describes every field). ``top_order`` ("marginal" |
"truncate"): "truncate" is the paper's eq. 8 (x^(p+1) set to 0, all p + 1 orders of the motion
error carry precision); "marginal" is (2). ``overrelax``, ``newton`` and ``scaled`` switch (3),
(4) and (1). Defaults: top_order="marginal" in sample mode ("truncate" in path mode), overrelax
and scaled coordinates; newton on in :func:`identify` (and ``attend identify``), off in
:func:`learn_batch` (``newton=None``, the default, means the function's own).
``PAPER_LEARNER`` = LearningSettings(top_order="truncate", overrelax=False, newton=False,
scaled=False) is the learner as published; the paper reproductions pass it explicitly.
:func:`identify` warns (IdentifiabilityWarning) when an entry given a large ("known") prior precision ends more than
KNOWN_DISPLACED_STD prior std from its mean: the data then outweigh that prior, and freeing an
unobservable direction lets F grow without bound.

Path mode (``states="path"``; the default is "sample"). In eq. 8 every sample has its own
generalised states X_t and each window's error is counted at every sample its window covers
(p + 1 times). Path mode ties the states to one trajectory x (T samples, n each) and counts the
data once::

    X_t = G x_window(t),  G = kron(E, I_n)   (E: the embedding weights that also embed y)
    F = -1/(p+1) * 1/2 sum_t E_q[e_y' Vy e_y + e_x' W e_x] + 1/(p+1) * noise normalisation
        + 1/2 ln|Sigma_path| + n T_covered / 2 + (theta, lambda priors and entropies as above)

i.e. every precision exp(lambda) S is weighted by 1/(p+1). q(x) is Gaussian with precision
Pi_path = 1/(p+1) sum_t G' Pi_X G, block tridiagonal in blocks of p + 1 samples, so the D-step is
a batched block Cholesky solve and the state moments come from its selected inverse (O(T)).
Pi_path's condition number grows like dt^-2p, so path mode warns above p = 6.

All numerics are batched over a leading axis of independent runs (seeds, prior precisions,
noise levels) sharing one model structure: see :func:`learn_batch`.

Layout of this package (public names are re-exported here):
:mod:`.settings` :class:`LearningSettings`; :mod:`.problem` the embedded logs, the structure runs
share, Pi_X; :mod:`.path` path-mode block-tridiagonal algebra; :mod:`.free_energy` F and its
pieces; :mod:`.steps` the D, E and M steps (and the extra moves); :mod:`.batch` the batched loop
:func:`learn_batch`; :mod:`.identification` :func:`identify`. The N4SID and EM baselines and the
basis-invariant error metrics live with the other references (:mod:`attend.perception.references`); theta
<-> (A, B, C) is the model's (:mod:`attend.models.parameters`).
"""

from attend.constants import KNOWN_PRIOR_PRECISION
from attend.perception.learning.batch import BatchLearningResult, learn_batch
from attend.perception.learning.identification import KNOWN_DISPLACED_STD, IdentificationResult, identify
from attend.perception.learning.problem import IdentifiabilityWarning, LearningWarning
from attend.perception.learning.settings import PAPER_LEARNER, LearningSettings
from attend.perception.learning.steps import NEWTON_CREEP
from attend.perception.references import identification as _baselines
from attend.perception.references.identification import (  # re-exported: the baselines of identify
    continuous_from_discrete, eigenvalue_error, em_baseline, n4sid_baseline, transfer_function_error)

__all__ = [
    "PAPER_LEARNER",
    "LearningSettings",
    "IdentificationResult",
    "BatchLearningResult",
    "IdentifiabilityWarning",
    "LearningWarning",
    "identify",
    "learn_batch",
    *_baselines.__all__,
]
