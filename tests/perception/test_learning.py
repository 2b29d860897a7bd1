"""Tests of attend.perception.learning: E/M-step derivatives against finite differences of the
free energy, monotone free energy, least-squares limit, recovery, bad input and divergence."""

import warnings
from dataclasses import replace

import numpy as np
import pytest

from attend._validation import AttendInputError
from attend.constants import KNOWN_INPUT_PRECISION, KNOWN_PRIOR_PRECISION
from attend.models.linear import simulate
from attend.models.parameters import parameter_names, parameter_vector, system_from_parameters
from attend.models.problems import identification_system, mass_spring_damper
from attend.perception import learning as L
from attend.perception.learning import free_energy as FE
from attend.perception.learning import path as PP
from attend.perception.learning import problem as PR

DT = 0.1
FREE_MSD = np.array([False, False, True, True, False, True, False, False])  # theta3, theta4, theta6


def _msd_log(seed=0, n=320, sigma=np.exp(-4)):
    system = mass_spring_damper()
    t = np.arange(n) * DT
    u = np.exp(-0.25 * (t - 12) ** 2)[:, None]
    return system, simulate(system, u, DT, kernel_width=0.5, process_std=sigma, measurement_std=sigma, seed=seed)


def _problem(seed=0, p=4, lam=(6.0, 5.0), states="sample"):
    """A small problem with q(X) from one D-step at a perturbed theta."""
    system, log = _msd_log(seed, n=120)
    theta_true = parameter_vector(system)
    P_theta = np.where(FREE_MSD, 0.5, 40.0)
    st, Y, U = PR._prepare(log.outputs[None], log.inputs[None], DT, 0.5, p, p, np.isfinite(P_theta), 2, True, "size",
                          states)
    rng = np.random.default_rng(seed)
    eta = theta_true + 0.3 * rng.standard_normal(8) * FREE_MSD
    theta = theta_true + 0.2 * rng.standard_normal(8)
    lam = np.array([lam])
    priors = PR._Priors(eta[None], P_theta[None], np.array([[1.0, 2.0]]), np.array([[1.0, 3.0]]),
                       0.5 * st.n_used * st.orders * np.array([st.m, st.n], dtype=float))
    mu = FE._d_step(theta[None], lam, Y, U, st)
    K_mean = FE._mean_moments(mu, Y, U, st)
    Sigma_X = PR._observer(theta[None], lam, st)[1]
    return st, Y, U, priors, mu, K_mean, Sigma_X, theta, lam


def _sqrt_psd(M):
    """R with R'R = M for a positive semi-definite M (the motion precision gives the top order none)."""
    w, V = np.linalg.eigh(0.5 * (M + M.T))
    return (V * np.sqrt(np.clip(w, 0, None))).T


def _F_fixed_q(st, priors, mu, K_mean, Sigma_X, theta, lam):
    """Free energy with q(X) = (mu, Sigma_X) held fixed."""
    return FE._evaluate(PR._State(mu, theta[None], lam), K_mean, priors, st, Sigma_X=Sigma_X).F[0]


@pytest.mark.parametrize("states", ["sample", "path"])
def test_e_step_gradient_and_hessian_match_finite_differences(states):
    st, Y, U, priors, mu, K_mean, Sigma_X, theta, lam = _problem(states=states)
    ev = FE._evaluate(PR._State(mu, theta[None], lam), K_mean, priors, st, Sigma_X=Sigma_X)
    target, J = FE._e_step_target(PR._State(mu, theta[None], lam), ev.K, priors, st)
    # the E-step objective is the quadratic with curvature J and maximiser target (all entries active)
    gradient = J[0] @ (theta - target[0])
    f = lambda th: _F_fixed_q(st, priors, mu, K_mean, Sigma_X, th, lam)
    h = 1e-4
    fd_grad = np.array([(f(theta + h * e) - f(theta - h * e)) / (2 * h) for e in np.eye(8)])
    scale = np.abs(fd_grad).max()
    np.testing.assert_allclose(gradient, fd_grad, rtol=1e-6, atol=1e-7 * scale)
    fd_hess = np.array([[(f(theta + h * a + h * b) - f(theta + h * a - h * b) - f(theta - h * a + h * b)
                          + f(theta - h * a - h * b)) / (4 * h * h) for b in np.eye(8)] for a in np.eye(8)])
    np.testing.assert_allclose(J[0], fd_hess, rtol=1e-4, atol=1e-5 * np.abs(J).max())
    # Pi_theta = -d2F/dtheta2
    np.testing.assert_allclose(ev.Pi_theta[0], -fd_hess, rtol=1e-4, atol=1e-5 * np.abs(J).max())


@pytest.mark.parametrize("states", ["sample", "path"])
def test_m_step_gradient_matches_finite_differences(states):
    st, Y, U, priors, mu, K_mean, Sigma_X, theta, lam = _problem(seed=1, states=states)
    ev = FE._evaluate(PR._State(mu, theta[None], lam), K_mean, priors, st, Sigma_X=Sigma_X)
    grad = FE._m_gradient(ev, PR._State(mu, theta[None], lam), priors, st)[0]
    h = 1e-5
    fd = [(_F_fixed_q(st, priors, mu, K_mean, Sigma_X, theta, lam + h * e[None])
           - _F_fixed_q(st, priors, mu, K_mean, Sigma_X, theta, lam - h * e[None])) / (2 * h) for e in np.eye(2)]
    np.testing.assert_allclose(grad, fd, rtol=1e-5)


def test_expected_energy_matches_dense_generalised_errors():
    """F's energy term equals sum_t e'Pi e at the means plus n_t tr(Pi_X Sigma_X), built densely."""
    st, Y, U, priors, mu, K_mean, Sigma_X, theta, lam = _problem(seed=2)
    P, n, m = st.orders, st.n, st.m
    ev = FE._evaluate(PR._State(mu, theta[None], lam), K_mean, priors, st, Sigma_X=Sigma_X)
    A, B, C = theta[:4].reshape(2, 2), theta[4:6].reshape(2, 1), theta[6:].reshape(1, 2)
    Ct, At, Bt = np.kron(np.eye(P), C), np.kron(np.eye(P), A), np.kron(np.eye(P), B)
    Dx = np.kron(np.eye(P, k=1), np.eye(n)) / st.time_scale  # order k held as sigma^k d^k/dt^k
    Vy, W = np.kron(st.S, np.exp(lam[0, 0]) * np.eye(m)), np.kron(st.S_motion, np.exp(lam[0, 1]) * np.eye(n))
    total = 0.0
    for t in np.flatnonzero(st.used):
        x, y, u = mu[0, t].ravel(), Y[0, t].ravel(), U[0, t].ravel()
        ey, ex = y - Ct @ x, (Dx - At) @ x - Bt @ u
        total += ey @ Vy @ ey + ex @ W @ ex
    Pi_X = Ct.T @ Vy @ Ct + (Dx - At).T @ W @ (Dx - At)
    total += st.n_used * np.trace(Pi_X @ Sigma_X[0])
    expected = np.exp(lam[0, 0]) * ev.Ez[0] + np.exp(lam[0, 1]) * ev.Ew[0]
    np.testing.assert_allclose(expected, total, rtol=1e-9)


def test_e_step_with_known_states_and_flat_prior_is_least_squares():
    """Sigma_X = 0, flat prior: theta* is the weighted least-squares fit of the generalised errors."""
    st, Y, U, priors, mu, K_mean, Sigma_X, theta, lam = _problem(seed=3)
    flat = PR._Priors(priors.eta_theta, np.zeros((1, 8)), priors.eta_lambda, priors.P_lambda, priors.fisher)
    K = K_mean  # no state uncertainty
    target, _ = FE._e_step_target(PR._State(mu, theta[None], lam), K, flat, st)
    P, n, m = st.orders, st.n, st.m
    rows, rhs = [], []
    wy = np.linalg.cholesky(np.kron(st.S, np.exp(lam[0, 0]) * np.eye(m))).T
    ww = _sqrt_psd(np.kron(st.S_motion, np.exp(lam[0, 1]) * np.eye(n)))
    for t in np.flatnonzero(st.used):
        x = mu[0, t]  # (P, n)
        u = U[0, t]  # (P, 1)
        tau = np.vstack([x[1:], np.zeros((1, n))]) / st.time_scale  # scaled coordinates
        # e_x = tau - A x - B u per order; e_y = y - C x per order (theta public order)
        Nx = np.zeros((P * n, 8))
        Ny = np.zeros((P * m, 8))
        for i in range(P):
            for a in range(n):
                Nx[i * n + a, a * n: a * n + n] = x[i]
                Nx[i * n + a, 4 + a] = u[i, 0]
            Ny[i, 6:8] = x[i]
        rows += [ww @ Nx, wy @ Ny]
        rhs += [ww @ tau.ravel(), wy @ Y[0, t].ravel()]
    lsq = np.linalg.lstsq(np.vstack(rows), np.concatenate(rhs), rcond=None)[0]
    np.testing.assert_allclose(target[0], lsq, rtol=1e-7, atol=1e-9)


def test_free_energy_never_decreases_and_parameters_are_recovered():
    system, log = _msd_log(seed=4)
    rng = np.random.default_rng(0)
    theta = parameter_vector(system)
    start = theta.copy()
    start[FREE_MSD] = rng.uniform(-2, 2, 3)
    prior = system_from_parameters(start, system)
    result = L.identify(prior, log.outputs, log.inputs, DT, kernel_width=0.5, free=FREE_MSD,
                        settings=L.LearningSettings(max_iterations=40))
    trace = result.settings["free_energy_trace"]
    assert np.all(np.diff(trace) >= 0)
    assert np.all(np.diff(result.free_energy) >= 0)
    assert result.steps_accepted["E"] > 0 and result.steps_accepted["M"] > 0
    rel = np.abs(result.parameters[FREE_MSD] - theta[FREE_MSD]) / np.abs(theta[FREE_MSD])
    assert np.all(rel < 0.25), rel
    assert abs(result.log_precision[0] - 8.0) < 0.5
    # posterior precision of the learned entries rose far above the prior precision 1
    assert np.all(np.diag(result.parameter_precision)[FREE_MSD] > 100)
    learned = result.system()
    np.testing.assert_allclose(learned.A.ravel()[[2, 3]], result.parameters[[2, 3]])


def test_batch_equals_single_runs():
    system, log0 = _msd_log(seed=5, n=200)
    _, log1 = _msd_log(seed=6, n=200)
    theta = parameter_vector(system)
    P = np.where(FREE_MSD, 1.0, KNOWN_PRIOR_PRECISION)
    eta = np.stack([theta + 0.5 * FREE_MSD, theta - 0.4 * FREE_MSD])
    kw = dict(n_states=2, kernel_width=0.5, prior_precision=P[None],
              settings=L.LearningSettings(max_iterations=8, embedding_order=4))
    batch = L.learn_batch(np.stack([log0.outputs, log1.outputs]), np.stack([log0.inputs, log1.inputs]), DT,
                          prior_mean=eta, **kw)
    for k, log in enumerate((log0, log1)):
        single = L.learn_batch(log.outputs[None], log.inputs[None], DT, prior_mean=eta[k:k + 1], **kw)
        np.testing.assert_allclose(batch.parameters[k], single.parameters[0], rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(batch.free_energy[k], single.free_energy[0][: batch.free_energy.shape[1]], rtol=1e-10)


def test_identification_system_learns_a_and_b():
    system = identification_system()
    t = np.arange(320) * DT
    u = np.exp(-0.25 * (t - 12) ** 2)[:, None]
    log = simulate(system, u, DT, kernel_width=0.5, process_std=np.exp(-4), measurement_std=np.exp(-4), seed=0)
    theta = parameter_vector(system)
    free = np.zeros(14, bool)
    free[:6] = True
    start = theta.copy()
    start[free] = np.random.default_rng(1).uniform(-2, 2, 6)
    result = L.identify(system_from_parameters(start, system), log.outputs, log.inputs, DT, kernel_width=0.5,
                        free=free, prior_precision=np.where(free, np.exp(6), KNOWN_INPUT_PRECISION),
                        settings=L.LearningSettings(noise_prior_precision=np.exp(3), max_iterations=20))
    assert np.abs(result.parameters[free] - theta[free]).max() < 0.1
    assert abs(result.log_precision[0] - 8.0) < 0.5


# --- bad input and failure -------------------------------------------------------------------

def test_free_entries_with_infinite_prior_precision_are_rejected():
    system, log = _msd_log(n=100)
    P = np.where(FREE_MSD, np.inf, 1.0)
    with pytest.raises(AttendInputError, match="infinite prior precision"):
        L.identify(system, log.outputs, log.inputs, DT, kernel_width=0.5, free=FREE_MSD, prior_precision=P)


def test_everything_fixed_is_rejected():
    system, log = _msd_log(n=100)
    with pytest.raises(AttendInputError, match="nothing to learn"):
        L.identify(system, log.outputs, log.inputs, DT, kernel_width=0.5, free=np.zeros(8, bool),
                   prior_precision=np.inf)


def test_log_without_excitation_is_rejected():
    system, _ = _msd_log(n=100)
    with pytest.raises(AttendInputError, match="no excitation"):
        L.identify(system, np.zeros((100, 1)), np.zeros((100, 1)), DT, kernel_width=0.5, free=FREE_MSD)


def test_zero_input_with_free_b_warns():
    system, log = _msd_log(n=100)
    with pytest.warns(L.IdentifiabilityWarning, match="inputs are identically zero"):
        L.identify(system, log.outputs, np.zeros((100, 1)), DT, kernel_width=0.5, free=FREE_MSD,
                   settings=L.LearningSettings(max_iterations=2))


def test_unidentifiable_model_warns():
    """A, B and C all free: a change of state basis leaves the input-output behaviour unchanged."""
    system, log = _msd_log(n=100)
    with pytest.warns(L.IdentifiabilityWarning, match="determines only"):
        L.identify(system, log.outputs, log.inputs, DT, kernel_width=0.5, free=np.ones(8, bool),
                   settings=L.LearningSettings(max_iterations=2))


@pytest.mark.parametrize("field, kwargs, match", [
    ("outputs", dict(outputs=np.zeros((100, 2))), "outputs: expected 1 columns"),
    ("inputs", dict(inputs=np.zeros((90, 1))), "inputs: expected shape"),
    ("outputs", dict(outputs=np.full((100, 1), np.nan)), "outputs: expected finite"),
    ("free", dict(free=["A[3,1]"]), "unknown parameter"),
    ("dt", dict(dt=-1.0), "dt"),
    ("noise_prior_precision", dict(settings=dict(noise_prior_precision=0.0)), "noise_prior_precision"),
    ("outputs", dict(outputs=np.ones((10, 1)), inputs=np.ones((10, 1))), "at least"),
    ("embedding_order", dict(settings=dict(embedding_order=0)), "embedding_order: expected p >= 1"),
    ("settings", dict(settings={"max_iterations": 5}, raw=True), "settings: expected a LearningSettings"),
])
def test_bad_input_names_the_field(field, kwargs, match):
    system, log = _msd_log(n=100)
    args = dict(outputs=log.outputs, inputs=log.inputs, dt=DT, free=FREE_MSD)
    args.update(kwargs)
    with pytest.raises(AttendInputError, match=match):
        if "settings" in args and not args.pop("raw", False):
            args["settings"] = L.LearningSettings(**args["settings"])
        L.identify(system, args.pop("outputs"), args.pop("inputs"), args.pop("dt"), kernel_width=0.5, **args)


def test_divergence_stops_with_a_message_and_the_last_accepted_estimate():
    system, log = _msd_log(n=100)
    huge = log.outputs * 1e160  # squares overflow: every step yields a non-finite free energy
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", L.IdentifiabilityWarning)
        with pytest.warns(L.LearningWarning, match=r"iteration \d+"):
            result = L.identify(system, huge, log.inputs, DT, kernel_width=0.5, free=FREE_MSD,
                                settings=L.LearningSettings(max_iterations=5))
    assert "step" in result.message
    assert np.all(np.isfinite(result.parameters))
    np.testing.assert_allclose(result.parameters, parameter_vector(system))


@pytest.mark.parametrize("p", [2, 3])
def test_path_posterior_matches_dense_gaussian(p):
    """Path mode: block-tridiagonal solve and selected inverse equal the dense Gaussian q(x)."""
    system, log = _msd_log(seed=3, n=60)
    theta = np.tile(parameter_vector(system), (2, 1))
    st, Y, U = PR._prepare(np.stack([log.outputs] * 2), np.stack([log.inputs] * 2), DT, 0.5, p, p,
                          np.ones(8, bool), 2, True, "size", "path")
    lam = np.array([[0.0, 0.0], [1.0, -1.0]])
    post = PP._path_posterior(theta, lam, Y, U, st)
    Pi_X, _, CtVy, MtWB = PR._observer(theta, lam, st, want_inverse=False)
    P, n, T = p + 1, 2, Y.shape[1]
    G = np.kron(st.E, np.eye(n))  # embedding weights in the scaled coordinates
    used = np.flatnonzero(st.used)
    starts = used - P // 2
    for r in range(2):
        Pi, b = np.zeros((T * n, T * n)), np.zeros(T * n)
        for t, s in zip(used, starts):
            window = slice(s * n, (s + P) * n)
            Pi[window, window] += G.T @ Pi_X[r] @ G
            b[window] += G.T @ (CtVy[r] @ Y[r, t].ravel() + MtWB[r] @ U[r, t].ravel())
        covered = np.zeros(T * n, bool)
        for s in starts:
            covered[s * n:(s + P) * n] = True
        Pi = Pi[np.ix_(covered, covered)]
        Sigma = np.linalg.inv(Pi)
        x = np.zeros(T * n)
        x[covered] = Sigma @ b[covered]
        full = np.zeros((T * n, T * n))
        full[np.ix_(covered, covered)] = Sigma
        entropy = -0.5 * np.linalg.slogdet(Pi)[1] + 0.5 * covered.sum()
        sigma_mean = np.mean([G @ full[s * n:(s + P) * n, s * n:(s + P) * n] @ G.T for s in starts], axis=0)
        means = np.array([(G @ x[s * n:(s + P) * n]).reshape(P, n) for s in starts])
        np.testing.assert_allclose(post.entropy[r], entropy, rtol=1e-9)
        np.testing.assert_allclose(post.sigma_mean[r], sigma_mean, rtol=1e-8, atol=1e-10 * np.abs(sigma_mean).max())
        np.testing.assert_allclose(post.mean[r][used], means, rtol=1e-8, atol=1e-10 * np.abs(means).max())


def test_path_mode_free_energy_rises_and_recovers_the_damping():
    """Path mode on the mass-spring-damper (8 seeds, random starts in [-2, 2]): F never decreases,
    lambda_z is learned, and the median relative error of theta3, theta4, theta6 is <= 6 %, the
    damping theta4 at most half of sample mode's (measured: 5 % vs 12.5 %)."""
    from attend.models.problems import msd_logs
    from attend.models.problems import msd_random_priors as random_priors

    theta = parameter_vector(mass_spring_damper())
    seeds = np.arange(8)
    Y, U = msd_logs(seeds, np.exp(-4.0), np.exp(-4.0))
    P = np.where(FREE_MSD, 1.0, L.KNOWN_PRIOR_PRECISION)[None].repeat(len(seeds), 0)
    errors = {}
    for states in ("sample", "path"):
        res = L.learn_batch(Y, U, DT, n_states=2, kernel_width=0.5, prior_mean=random_priors(seeds), prior_precision=P,
                            settings=L.LearningSettings(max_iterations=40, states=states))
        steps = np.diff(res.free_energy, axis=1)
        assert np.all(steps[np.isfinite(steps)] >= 0)
        errors[states] = np.median(np.abs(res.parameters[:, FREE_MSD] - theta[FREE_MSD]) / np.abs(theta[FREE_MSD]), axis=0)
    assert np.all(errors["path"] <= 0.06), errors
    # with the top-order motion error marginalised, sample mode no longer drives lambda_w up and its
    # damping error falls too (measured: path 5.2 %, sample 4.6 %; 12.5 % before): both are small
    assert np.all(errors["sample"] <= 0.06), errors
    assert np.all(np.abs(res.log_precision[:, 0] - 8.0) < 0.5)


def test_unknown_states_mode_is_rejected():
    system, log = _msd_log(seed=0, n=100)
    with pytest.raises(AttendInputError, match="states"):
        L.identify(system, log.outputs, log.inputs, DT, kernel_width=0.5, free=FREE_MSD,
                   settings=L.LearningSettings(states="window"))


def test_path_posterior_marks_only_the_failing_run():
    """A run whose Pi_path is not positive definite gets F = -inf; the other runs are unaffected."""
    system, log = _msd_log(seed=3, n=60)
    theta = np.tile(parameter_vector(system), (2, 1))
    st, Y, U = PR._prepare(np.stack([log.outputs] * 2), np.stack([log.inputs] * 2), DT, 0.5, 2, 2,
                          np.ones(8, bool), 2, True, "size", "path")
    lam = np.array([[0.0, 0.0], [0.0, 0.0]])
    alone = PP._path_posterior(theta[:1], lam[:1], Y[:1], U[:1], st)
    theta[1, 6:] = np.nan  # C of run 1 unusable: its precision is not finite
    both = PP._path_posterior(theta, lam, Y, U, st)
    assert both.entropy[1] == -np.inf and np.all(np.isnan(both.mean[1]))
    np.testing.assert_allclose(both.entropy[0], alone.entropy[0])
    np.testing.assert_allclose(both.mean[0], alone.mean[0])


def test_path_posterior_isolates_a_run_that_is_not_positive_definite(monkeypatch):
    system, log = _msd_log(seed=3, n=60)
    theta = np.tile(parameter_vector(system), (2, 1))
    st, Y, U = PR._prepare(np.stack([log.outputs] * 2), np.stack([log.inputs] * 2), DT, 0.5, 2, 2,
                          np.ones(8, bool), 2, True, "size", "path")
    lam = np.zeros((2, 2))
    alone = PP._path_posterior(theta[:1], lam[:1], Y[:1], U[:1], st)
    observer = PR._observer

    def flipped(*args, **kwargs):
        Pi_X, Sigma, CtVy, MtWB = observer(*args, **kwargs)
        Pi_X = Pi_X.copy()
        Pi_X[1] *= -1.0  # finite but negative definite: the batched Cholesky raises
        return Pi_X, Sigma, CtVy, MtWB

    monkeypatch.setattr(PP, "_observer", flipped)
    both = PP._path_posterior(theta, lam, Y, U, st)
    assert both.entropy[1] == -np.inf
    np.testing.assert_allclose(both.entropy[0], alone.entropy[0])
    np.testing.assert_allclose(both.mean[0], alone.mean[0])


def test_path_mode_warns_above_order_six():
    system, log = _msd_log(seed=0, n=100)
    with pytest.warns(L.LearningWarning, match="ill-conditioned"):
        L.learn_batch(log.outputs[None], log.inputs[None], DT, n_states=2, kernel_width=0.5,
                      prior_mean=parameter_vector(system)[None], prior_precision=np.where(FREE_MSD, 1.0, KNOWN_PRIOR_PRECISION)[None],
                      settings=L.LearningSettings(embedding_order=8, max_iterations=1, states="path"))


from conftest import QUADROTOR_DATA as QUADROTOR  # noqa: E402  (../shared beside the clone, or ATTEND_SHARED)


@pytest.mark.skipif(not QUADROTOR.exists(), reason="quadrotor flight data not available")
@pytest.mark.parametrize("flight", ["exp_21_WW_WM_1", "exp_24_WW_WM_0"])
def test_readme_learning_section_converges_on_real_flights(flight):
    """The README's [learning] example on 2 s ... 10 s slices of real 120 Hz flights (s = 0.006 s, p = 6):
    converges, F never decreases over accepted steps, lambda stays finite and moderate, and the
    learned model's estimates are finite (it used to diverge with lambda_w ~ 44)."""
    import sys

    sys.path.insert(0, str(__import__("pathlib").Path(__file__).parents[2] / "benchmarks"))
    from bench_identify_flights import DT, LEARNING, PRIOR, SETTINGS, load

    y, u, _ = load(QUADROTOR / f"{flight}.csv", 399, 1200)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", L.IdentifiabilityWarning)
        result = L.identify(PRIOR, y, u, DT, kernel_width=0.006, settings=SETTINGS, **LEARNING)
    assert result.converged, result.message
    trace = result.settings["free_energy_trace"]
    assert np.all(np.diff(trace) >= 0)
    assert np.all(np.isfinite(result.log_precision)) and np.all(np.abs(result.log_precision) < 25)
    assert np.all(np.isfinite(result.parameter_std[result.free]))
    from attend.perception.dem import DEMObserver

    # embedding_order "auto" as `attend estimate` uses: at p = 6 the DEM stability analysis (main) refuses this
    # slice for the PRIOR model too at the learned sensor precision (a start error would outlive the log)
    observer = DEMObserver(result.system(), DT, kernel_width=0.006, sensor_precision=result.sensor_precision,
                           process_precision=result.process_precision, input_prior_precision=None,
                           embedding_order="auto", input_order=2, known_inputs=True, precision_convention="max")
    assert np.all(np.isfinite(observer.estimate(y, u).states))


# --- top order, the published learner, whole flights ----------------------------------------------

def test_top_order_option_is_validated_and_reported():
    system, log = _msd_log(seed=0, n=120)
    kw = dict(n_states=2, kernel_width=0.5, prior_mean=parameter_vector(system)[None],
              prior_precision=np.where(FREE_MSD, 1.0, KNOWN_PRIOR_PRECISION)[None])
    with pytest.raises(AttendInputError, match="top_order"):
        L.learn_batch(log.outputs[None], log.inputs[None], DT, settings=L.LearningSettings(top_order="zero"), **kw)
    truncate = L.learn_batch(log.outputs[None], log.inputs[None], DT,
                             settings=L.LearningSettings(top_order="truncate", max_iterations=3), **kw)
    marginal = L.learn_batch(log.outputs[None], log.inputs[None], DT,
                             settings=L.LearningSettings(top_order="marginal", max_iterations=3), **kw)
    assert not np.allclose(truncate.free_energy[0, -1], marginal.free_energy[0, -1])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", L.IdentifiabilityWarning)
        result = L.identify(system, log.outputs, log.inputs, DT, kernel_width=0.5,
                            settings=L.LearningSettings(max_iterations=2))
        path = L.identify(system, log.outputs, log.inputs, DT, kernel_width=0.5,
                          settings=L.LearningSettings(max_iterations=2, states="path"))
    assert result.settings["top_order"] == "marginal" and path.settings["top_order"] == "truncate"


def _default_learner_theta3_seed0() -> float:
    """theta3 that today's default learner (not PAPER_LEARNER) learns from fig3's quick seed 0."""
    from attend.experiments import fig3

    cfg = dict(fig3.SETTINGS, iterations=40)
    std = np.exp(-cfg["noise_log_precision"] / 2)
    Y, U = fig3.msd_logs(np.arange(1), std, std, cfg["dt"], cfg["duration"], cfg["kernel_width"])
    P = np.where(fig3.MSD_FREE, cfg["free_prior_precision"], KNOWN_PRIOR_PRECISION)[None]
    settings = L.LearningSettings(noise_prior_mean=cfg["noise_prior_mean"], noise_prior_precision=cfg["noise_prior_precision"],
                                  embedding_order=cfg["embedding_order"], max_iterations=cfg["iterations"])
    result = L.learn_batch(Y, U, cfg["dt"], n_states=2, kernel_width=cfg["kernel_width"],
                           prior_mean=fig3.msd_random_priors(np.arange(1)), prior_precision=P, settings=settings,
                           progress=False)
    return float(result.parameters[0, 2])


def test_paper_reproduction_numbers_are_the_published_learners():
    """fig3 (quick) passes PAPER_LEARNER: its numbers are those of the learner before the top-order,
    over-relaxation, Newton and scaling changes (values from main before they were made)."""
    from attend.experiments import fig3

    assert L.PAPER_LEARNER == L.LearningSettings(top_order="truncate", overrelax=False, newton=False, scaled=False)
    got = {m.name: m.value for m in fig3.run(quick=True, progress=False).metrics}
    # Tolerances from the computation's conditioning, not from the digits one machine printed.
    # Seed 0 runs all 40 iterations; each E-step solves with a curvature whose condition number is
    # about posterior / prior precision of theta3 (1.5e9 / 1), so rounding that differs between
    # BLAS kernels and SIMD loops (eps = 2.2e-16) may move the results by eps * 1.5e9 = 3e-7
    # relative: compare at 1e-6 (seen across kernels: 2e-10 to 7e-8).
    expected = {"theta3_seed0": -0.5312380550798431, "theta4_seed0": -0.2138427184277307,
                "lambda_w_seed0": 15.890143322456774, "free_energy_rise_seed0": 10022.555505288108}
    for name, value in expected.items():
        assert got[name] == pytest.approx(value, rel=1e-6, abs=0), name
    # Path mode stops when an iteration raises F by less than 1e-3, so where it stops depends on
    # rounding (one seed stops at iteration 16 or 17 across kernels) and theta3 is fixed only to
    # that stopping rule (up to 3e-5 of 0.56): the median relative error is compared at 1e-3.
    assert got["theta3_median_relative_error_path_mode"] == pytest.approx(0.019351323261938055, abs=1e-3)
    # The tolerances still tell the learners apart: today's defaults learn another theta3.
    assert got["theta3_seed0"] != pytest.approx(_default_learner_theta3_seed0(), rel=1e-6)


BUNDLED = __import__("pathlib").Path(__file__).parents[2] / "src" / "attend" / "data" / "quadrotor_roll_wind.csv"


def _bundled_flight():
    table = np.genfromtxt(BUNDLED, delimiter=",", names=True)
    motors = np.column_stack([table[f"motor_{i}"] for i in range(1, 5)])
    return table["meas_phi"][:, None], motors - motors.mean(axis=0)


def test_readme_example_converges_on_the_whole_bundled_flight():
    """The README [learning] example (known entries held: inf) on all 3481 samples of the bundled flight
    converges in sample mode (it hit the 50-iteration cap with known_prior_precision = 3.3e6)."""
    import sys

    sys.path.insert(0, str(__import__("pathlib").Path(__file__).parents[2] / "benchmarks"))
    from bench_identify_flights import DT as DT_FLIGHT, LEARNING, PRIOR, SETTINGS

    y, u = _bundled_flight()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", L.IdentifiabilityWarning)
        result = L.identify(PRIOR, y, u, DT_FLIGHT, kernel_width=0.006, settings=SETTINGS, **LEARNING)
    assert result.converged and result.iterations < 50, result.message
    assert np.all(np.diff(result.settings["free_energy_trace"]) >= 0)
    known = ~result.free
    assert np.array_equal(result.parameters[known], result.prior_mean[known])


def test_drifting_known_entries_are_named():
    """Known entries (finite known_prior_precision) that end many prior std from their means are named, and
    an unconverged run says to hold them (on the whole bundled flight with exp(15) and B[2,1] the only free
    input gain, C[1,2] and A[1,2] drifted 43 and 21 prior std towards a (C, A) with an unobservable mode,
    where F is unbounded). Here the run starts displaced (C[1,2] = 0.02, 36 prior std) and stops after 2."""
    import sys

    sys.path.insert(0, str(__import__("pathlib").Path(__file__).parents[2] / "benchmarks"))
    from bench_identify_flights import DT as DT_FLIGHT, LEARNING, PRIOR, SETTINGS

    y, u = _bundled_flight()
    start = parameter_vector(PRIOR)
    start[parameter_names(PRIOR).index("C[1,2]")] = 0.02
    with pytest.warns(L.IdentifiabilityWarning, match=r"known entries moved .*C\[1,2\]"):
        result = L.identify(PRIOR, y, u, DT_FLIGHT, kernel_width=0.006, initial=start,
                            settings=replace(SETTINGS, max_iterations=2),
                            **dict(LEARNING, known_prior_precision=3.3e6))
    assert not result.converged and "known_prior_precision = inf" in result.message


def test_identify_accepts_a_python_control_statespace():
    """The prior system may be a python-control StateSpace (converted with from_statespace)."""
    control = pytest.importorskip("control")
    from attend import LearningSettings, identify, mass_spring_damper, simulate

    system = mass_spring_damper()
    t = np.arange(200) * 0.1
    u = np.exp(-0.25 * (t - 8) ** 2)[:, None]
    log = simulate(system, u, 0.1, kernel_width=0.5, process_std=np.exp(-4), measurement_std=np.exp(-4), seed=0)
    options = dict(kernel_width=0.5, free=["A[2,1]"], settings=LearningSettings(max_iterations=3))
    from_statespace = identify(control.ss(system.A, system.B, system.C, 0), log.outputs, u, 0.1, **options)
    direct = identify(system, log.outputs, u, 0.1, **options)
    np.testing.assert_allclose(from_statespace.system().A, direct.system().A)
