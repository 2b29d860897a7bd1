"""Unknown inputs at the exact posterior (issue 29): the oracle (exact_oracle.oracle_posterior) holds
on ill-conditioned models, the Kalman smoother reaches it, and the float64 dense exact_posterior
warns where its own conditioning spoils it. Figures on the whole bank:
benchmarks/bench_unknown_inputs.py."""

from fractions import Fraction

import numpy as np
import pytest

import attend
from attend.perception.kalman import KalmanEstimator
from attend.perception.references import double_double as dd
from attend.perception.references import exact_posterior
from attend.perception.references.exact import ConditioningWarning
from attend.perception.references.exact_oracle import correlation_root, oracle_posterior

# --- double-double arithmetic against exact rational arithmetic -----------------------------------


def _exact(value: dd.DD) -> np.ndarray:
    return np.vectorize(lambda hi, lo: Fraction(hi) + Fraction(lo), otypes=[object])(value.hi, value.lo)


def test_double_double_products_and_factor_are_exact_to_31_digits():
    rng = np.random.default_rng(0)
    a = rng.normal(size=(6, 9)) * np.exp(rng.uniform(-20, 20, size=(1, 9)))
    product = dd.matmul(dd.dd(a), dd.dd(a.T), symmetric=True)
    exact = np.array([[sum(Fraction(a[i, k]) * Fraction(a[j, k]) for k in range(9)) for j in range(6)]
                      for i in range(6)], dtype=object)
    scale = np.array([[float(sum(abs(Fraction(a[i, k]) * Fraction(a[j, k])) for k in range(9))) for j in range(6)]
                      for i in range(6)])
    assert np.max(np.abs((_exact(product) - exact).astype(float)) / scale) < 1e-30
    L = dd.cholesky(product)
    rebuilt = dd.matmul(L, L.T)
    assert np.max(np.abs((_exact(rebuilt) - _exact(product)).astype(float)) / scale) < 1e-29
    b = dd.dd(rng.normal(size=6))
    x = dd.solve_upper_transposed(L, dd.solve_lower(L, b))
    residual = (_exact(dd.matvec(product, x)) - _exact(b)).astype(float)
    assert np.max(np.abs(residual)) < 1e-28 * np.max(scale) * np.max(np.abs(x.value()))


# --- the oracle --------------------------------------------------------------------------------


def chain_case(seed=0, N=70, input_ratio=10.0, input_log_std=5.0, sensor_std=2e-3):
    """A double integrator (position measured to sensor_std) driven by an unknown input with a broad
    smooth prior (std e^input_log_std, width input_ratio samples), x[0] unknown with a broad
    prior: the covariance form's condition number is ~1e15 or more."""
    A = np.array([[0.0, 1.0], [0.0, -0.2]])
    system = attend.LinearSystem(A, np.array([[0.0], [1.0]]), np.array([[1.0, 0.0]]))
    dt = 0.1
    rng = np.random.default_rng(seed)
    su = np.exp(input_log_std)
    u = su * correlation_root(N, dt, input_ratio * dt) @ rng.standard_normal((N, 1))
    x0 = rng.normal(size=2)
    log = attend.simulate(system, u, dt, process_kernel_width=dt, sensor_kernel_width=dt, process_std=[0.01, 0.05],
                          measurement_std=sensor_std, initial_state=x0, seed=seed)
    model = dict(process_kernel_width=dt, sensor_kernel_width=dt, input_kernel_width=input_ratio * dt,
                 process_std=[0.01, 0.05], measurement_std=sensor_std, input_prior_mean=0.0, input_prior_std=su,
                 initial_mean=np.zeros(2), initial_std=50.0)
    return system, dt, log, u, model


def test_the_oracles_two_computations_agree_on_an_ill_conditioned_model():
    system, dt, log, _, model = chain_case()
    oracle = oracle_posterior(system, dt, log.outputs, **model)
    agreement = oracle.agreement
    assert agreement.condition > 1e13  # the covariance form's cond(G G'), rows scaled: float64 would lose it all
    assert agreement.mean_in_std < 1e-6  # square-root float64 vs covariance form in double-double
    assert agreement.std_relative < 1e-8


def test_the_oracle_is_exact_posteriors_model_where_that_is_well_conditioned():
    """White noises, moderate prior: the library's dense covariance form is exact to rounding there,
    so the two must agree to ~1e-10: the oracle conditions on the same model."""
    rng = np.random.default_rng(3)
    A = rng.normal(size=(3, 3)) / np.sqrt(3)
    A -= (np.linalg.eigvals(A).real.max() + 0.3) * np.eye(3)
    system = attend.LinearSystem(A, rng.normal(size=(3, 2)), rng.normal(size=(2, 3)))
    dt, N = 0.1, 50
    log = attend.simulate(system, np.zeros((N, 2)), dt, kernel_width=0.0, process_std=0.3, measurement_std=0.2, seed=1)
    model = dict(process_kernel_width=0.0, sensor_kernel_width=0.0, input_kernel_width=0.2, process_std=0.3,
                 measurement_std=0.2, input_prior_mean=0.1, input_prior_std=[1.0, 2.0], initial_std=1.5)
    oracle = oracle_posterior(system, dt, log.outputs, **model)
    dense = exact_posterior(system, dt, log.outputs, None, jitter=0.0, **model)
    np.testing.assert_allclose(dense.states, oracle.states, atol=1e-10 * np.abs(oracle.states).max())
    np.testing.assert_allclose(dense.inputs, oracle.inputs, atol=1e-10 * np.abs(oracle.inputs).max())
    np.testing.assert_allclose(dense.state_std, oracle.state_std, rtol=1e-9)
    np.testing.assert_allclose(dense.input_std, oracle.input_std, rtol=1e-9)


# --- the Kalman smoother against the oracle -------------------------------------------------------

SMOOTHER_CASES = [  # (seed, input width / dt, log input prior std, sensor std)
    (1, 0.25, 5.0, 2e-3),
    (2, 2.0, 4.0, 1e-3),
    (3, 10.0, 5.0, 2e-3),
]


@pytest.mark.parametrize("seed, input_ratio, input_log_std, sensor_std", SMOOTHER_CASES)
def test_the_smoother_reaches_the_oracle(seed, input_ratio, input_log_std, sensor_std):
    """Tolerance: the oracle certifies its own mean to agreement.mean_in_std (asserted <= 1e-6 std
    here; ~ sqrt(cond) eps at cond(G G') ~ 1e15). The smoother departs from the model as stated by
    its approximations: the noise models' white floors (1e-8 of the process and sensor noises'
    variance, <= 1e-10 of the inputs' prior: <= 1e-3 std on these cases, up to 1.1 std on the
    bench's smooth-noise cases, SSE within 0.2 %) and, against the oracle given those same floors,
    the spectral-factor fit (autocorrelation to 1e-5) and the steady gain (1e-6 relative): measured
    <= 3e-3 std over the bench's 39 cases. So: within 1e-2 std of the floored oracle, within 0.1
    std of the stated one, SSE within 1 %, std within 3 % (below)."""
    system, dt, log, u, model = chain_case(seed, input_ratio=input_ratio, input_log_std=input_log_std,
                                           sensor_std=sensor_std)
    estimator = KalmanEstimator(system, dt, sensor_precision=sensor_std**-2, process_precision=np.diag([1e4, 400.0]),
                                kernel_width=dt, known_inputs=False, input_prior_precision=model["input_prior_std"]**-2,
                                input_kernel_width=model["input_kernel_width"], initial_state=np.zeros(2),
                                initial_state_std=50.0)
    floors = estimator.noise_floors
    oracle = oracle_posterior(system, dt, log.outputs, **model)
    floored = oracle_posterior(system, dt, log.outputs, check=False, **model,
                               white_floor=(floors["process"], floors["sensor"], floors["input"]))
    assert oracle.agreement.mean_in_std < 1e-6
    assert floors["input"] <= 1e-10  # the inputs' prior keeps (nearly) no white part
    ours = estimator.estimate(log.outputs, np.zeros((log.outputs.shape[0], 1)))
    for reference, tolerance in ((floored, 1e-2), (oracle, 0.1)):
        assert np.max(np.abs(ours.states - reference.states) / reference.state_std) < tolerance
        assert np.max(np.abs(ours.inputs - reference.inputs) / reference.input_std) < tolerance
    def sse(estimate):
        return np.sum((estimate.states - log.states) ** 2), np.sum((estimate.inputs - u) ** 2)

    np.testing.assert_allclose(sse(ours), sse(oracle), rtol=0.01)
    # The std: near the start of the smoothest, broadest case (seed 3: x0 std 50 against sensor std
    # 0.002, so the first updates subtract nearly equal covariances, cancelling ~ (50 / 0.002)^2 ~ 6e8
    # per step) the smoother's covariance carries rounding of up to ~1 % relative, and how much
    # depends on the BLAS kernels: 0.15 % with the default OpenBLAS kernels, 1.02 % with PRESCOTT
    # on one thread and no AVX-512 (the second run of .ci/run). The oracle's std does not move
    # (float64 and double-double agree to 3.5e-9). Bound: 3 %, 3x the worst measured.
    np.testing.assert_allclose(ours.state_std, oracle.state_std, rtol=0.03)
    np.testing.assert_allclose(ours.input_std, oracle.input_std, rtol=0.03)


# --- the float64 dense posterior knows when it is off ---------------------------------------------


def test_exact_posterior_warns_when_its_jitter_moves_the_mean():
    system, dt, log, _, model = chain_case(4, N=120, input_ratio=10.0, input_log_std=4.0)
    oracle = oracle_posterior(system, dt, log.outputs, check=False, **model)
    with pytest.warns(ConditioningWarning, match="jitter"):
        dense = exact_posterior(system, dt, log.outputs, None, **model)
    off = np.max(np.abs(dense.states - oracle.states) / oracle.state_std)
    assert off > 0.1  # the warning is not idle: the dense mean is off the posterior
    assert dense.accuracy.jitter_shift > 0.1


def test_exact_posterior_is_silent_where_it_is_accurate():
    system, dt, log, _, model = chain_case(5, N=60, input_ratio=1.0, input_log_std=0.0, sensor_std=0.1)
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error", ConditioningWarning)
        dense = exact_posterior(system, dt, log.outputs, None, **model)
    assert dense.accuracy.jitter_shift < 1e-3
