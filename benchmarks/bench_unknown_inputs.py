"""Unknown inputs at the exact posterior (issue 29, item 1): the default Kalman smoother against an
oracle that is shown to hold on every case.

    PYTHONPATH=src python benchmarks/bench_unknown_inputs.py [--quick] [--cases 36] [--verbose] [--json OUT]

The oracle: :func:`attend.perception.references.exact_oracle.oracle_posterior`, the dense Gaussian
posterior of states and inputs under the model the smoother is given (the inputs' Gaussian-process
prior with its mean, std and kernel width, rho(tau) = exp(-tau^2 / (4 s_u^2)) sampled at the lags;
simulate()'s kernels for w and z; the same x[0] prior), computed twice: a square-root form in
float64 and the covariance form in double-double (~32 digits). Their agreement is printed for
every case (``agree``: the largest mean difference in units of the posterior std, the largest
relative std difference); a case counts only when both are below 1e-3.

The bank (fixed; case i drawn with numpy's default_rng([29, i])): windows of 60-80 samples;
random stable systems (n 2-5 states, m 1-3 outputs, 1-3 inputs, all unknown or some measured)
and integrator chains (a double and a triple integrator with light damping); the inputs' prior
kernel width s_u / dt cycling over 0.25, 0.5, 1, 2, 4, 10 and its std over e^0, e^2, e^4, e^5;
process and sensor widths s / dt in {0, 0.5, 1, 2}; per-channel noise stds spread over 3 decades
(10^U(-1.5, 1.5) around each noise's level); x[0] known, unknown with a stated prior (std 1), or
unknown under the smoother's default (diffuse: 100 x the scale of the first sample seen through
C, :class:`attend.perception.kalman.KalmanEstimator`; the oracle is given the same std). Every
fourth case is a log the model fits poorly: simulated from a perturbed system (A and B moved by
15-20 %, noise stds off by 2-5x, inputs 3x rougher or smoother than the prior). Model-right
logs are drawn from the model itself: the inputs from the same square root of rho the oracle
uses, w and z by attend.simulate. Plus three cases shaped like the AR.Drone 2 flight of issue
29, built synthetically (12 states: position, velocity, attitude, body rates; 6 outputs:
position and attitude; 4 unknown inputs: thrust and three torques; 25 Hz; all kernel widths
0.04 s = 1 sample; process stds 0.08-28 per state; sensor stds 7e-4 - 1e-2; input prior std e^4;
x[0] known, diffuse, and a perturbed system), window 60 samples, and once over 200 samples (x[0]
diffuse: the window of issue 29's comparison; its double-double check takes a few minutes).

Figures (each beside its target): state SSE and input SSE against the true trajectories, the
smoother's over the oracle's (median <= 1.02, worst <= 1.05); the smoother's mean from the
oracle's in units of the oracle's std (largest over samples and channels); calibration: the
share of |error| < 1.96 std of the smoother's 95 % intervals, pooled over the model-right cases
(93-97 %). Beside them, attend's float64 dense exact_posterior (the library's covariance form,
Cholesky jitter 1e-12) measured against the same oracle. ~4 minutes on one core (--quick: 12
cases, ~1 minute).
"""

from __future__ import annotations

import os

for _variable in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")  # one core, before numpy loads BLAS

import argparse  # noqa: E402
import json  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402
from dataclasses import dataclass, field  # noqa: E402

import numpy as np  # noqa: E402

from attend._validation import AttendInputError  # noqa: E402
from attend.models.linear import LinearSystem, ModelWarning, simulate  # noqa: E402
from attend.perception.kalman import KalmanEstimator  # noqa: E402
from attend.perception.references import exact_posterior  # noqa: E402
from attend.perception.references.exact import ConditioningWarning  # noqa: E402
from attend.perception.references.exact_oracle import correlation_root, oracle_posterior  # noqa: E402

SSE_MEDIAN, SSE_WORST = 1.02, 1.05
CALIBRATION = (0.93, 0.97)
ORACLE_TOLERANCE = 1e-3
FLOOR_CHECK = 0.01   # smoother's mean farther than this (in oracle std) from the oracle's: ask the floored oracle
DENSE_OFF = 0.1      # exact_posterior's mean farther than this (in oracle std): "off the posterior"
INPUT_RATIOS = (0.25, 0.5, 1.0, 2.0, 4.0, 10.0)
INPUT_LOG_STDS = (0.0, 2.0, 4.0, 5.0)
NOISE_RATIOS = (0.0, 0.5, 1.0, 2.0, 3.0)
X0_KINDS = ("known", "prior", "diffuse")


@dataclass
class Case:
    """One log and the model the estimators are given."""

    name: str
    system: LinearSystem          # the model
    dt: float
    process_width: float
    sensor_width: float
    input_width: float
    process_std: np.ndarray
    sensor_std: np.ndarray
    input_std: np.ndarray         # prior std per input (0 for measured inputs)
    input_mean: np.ndarray        # (N, r): prior mean, or the measured values
    x0_kind: str
    x0_mean: np.ndarray
    x0_std: np.ndarray | None     # None: the smoother's diffuse default
    outputs: np.ndarray
    states: np.ndarray            # the truth
    inputs: np.ndarray
    model_right: bool
    notes: dict = field(default_factory=dict)


def random_stable_system(rng, n, m, r) -> LinearSystem:
    """A stable, observable random system (real parts of the eigenvalues in -0.8 .. -0.05 1/s)."""
    while True:
        A = rng.normal(size=(n, n)) / np.sqrt(n)
        A -= (np.linalg.eigvals(A).real.max() + rng.uniform(0.05, 0.8)) * np.eye(n)
        B, C = rng.normal(size=(n, r)), rng.normal(size=(m, n))
        O = np.vstack([C @ np.linalg.matrix_power(A, k) for k in range(n)])
        if np.linalg.matrix_rank(O) == n:
            return LinearSystem(A, B, C)


def integrator_chain(order: int, damping: float) -> LinearSystem:
    """x1' = x2, ..., x_order' = u - damping x_order; y = x1 (position) and, for order 3, x2."""
    A = np.diag(np.ones(order - 1), 1)
    A[-1, -1] = -damping
    B = np.zeros((order, 1))
    B[-1, 0] = 1.0
    C = np.eye(order)[: 1 if order == 2 else 2]
    return LinearSystem(A, B, C)


def drone_like() -> LinearSystem:
    """A hover linearisation shaped like the AR.Drone 2 model of issue 29 (synthetic numbers):
    states p (3), v (3), attitude (roll, pitch, yaw), body rates; inputs thrust and three torques
    (scaled); outputs position and attitude."""
    g = 9.81
    A = np.zeros((12, 12))
    A[0:3, 3:6] = np.eye(3)
    A[3:6, 3:6] = -0.3 * np.eye(3)
    A[3, 7], A[4, 6] = g, -g
    A[6:9, 9:12] = np.eye(3)
    A[9:12, 9:12] = -0.5 * np.eye(3)
    B = np.zeros((12, 4))
    B[5, 0], B[9, 1], B[10, 2], B[11, 3] = 0.05, 0.3, 0.3, 0.1
    C = np.zeros((6, 12))
    C[0:3, 0:3] = np.eye(3)
    C[3:6, 6:9] = np.eye(3)
    names = dict(state_names=("x", "y", "z", "vx", "vy", "vz", "roll", "pitch", "yaw", "p", "q", "r"),
                 input_names=("thrust", "torque_roll", "torque_pitch", "torque_yaw"))
    return LinearSystem(A, B, C, **names)


def diffuse_std(system: LinearSystem, y0: np.ndarray, sensor_std: np.ndarray) -> float:
    """The smoother's default prior std of every x[0] entry when no initial_state is given:
    100 x the larger of the state's scale seen through C in the first sample and the sensor
    noise's (the rule of KalmanEstimator's diffuse start, restated here for the oracle)."""
    inverse = np.linalg.pinv(system.C)
    seen = inverse @ y0
    noise = np.sqrt(np.mean(np.diag(inverse @ np.diag(sensor_std**2) @ inverse.T)))
    return 100 * max(float(np.sqrt(np.mean(seen**2))), float(noise), 1e-12)


def perturbed(system: LinearSystem, rng, size: float = 0.15) -> LinearSystem:
    """A and B moved by ~size relative (entrywise, scaled by each matrix's norm), kept stable
    when the nominal A is."""
    scale_A = np.linalg.norm(system.A) / np.sqrt(system.A.size)
    for _ in range(100):
        A = system.A + size * scale_A * rng.normal(size=system.A.shape) * (system.A != 0)
        if not system.is_stable() or np.max(np.linalg.eigvals(A).real) < 0:
            break
    B = system.B * (1 + 1.3 * size * rng.normal(size=system.B.shape))
    return LinearSystem(A, B, system.C, state_names=system.state_names, input_names=system.input_names)


def gp_inputs(rng, N, dt, width, mean, std) -> np.ndarray:
    """(N, r) draws of the inputs' prior: mean + std * root(rho) e (the oracle's square root)."""
    root = correlation_root(N, dt, width)
    return mean + (root @ rng.standard_normal((N, std.size))) * std


def draw_case(index: int) -> Case:
    """Case ``index`` of the bank (see the module docstring); default_rng([29, index])."""
    rng = np.random.default_rng([29, index])
    kind = "chain" if index % 6 == 5 else "random"
    if kind == "chain":
        system = integrator_chain(2 + (index // 6) % 2, damping=0.2)
    else:
        n = int(rng.integers(2, 6))
        system = random_stable_system(rng, n, int(rng.integers(1, min(n, 3) + 1)), int(rng.integers(1, 4)))
    n, m, r = system.n_states, system.n_outputs, system.n_inputs
    dt = 0.1
    N = int(rng.integers(60, min(240, 480 // m) + 1))
    input_ratio = INPUT_RATIOS[index % len(INPUT_RATIOS)]
    log_std = INPUT_LOG_STDS[(index // len(INPUT_RATIOS) + index) % len(INPUT_LOG_STDS)]
    process_ratio, sensor_ratio = rng.choice(NOISE_RATIOS), rng.choice(NOISE_RATIOS)
    process_std = 0.1 * 10 ** rng.uniform(-1.5, 1.5, size=n)
    sensor_std = 0.05 * 10 ** rng.uniform(-1.5, 1.5, size=m)
    measured = np.zeros(r, dtype=bool)
    if r > 1 and index % 5 == 2:
        measured[0] = True  # one input measured, the others estimated
    input_std = np.where(measured, 0.0, np.exp(log_std))
    x0_kind = X0_KINDS[index % 3]
    misfit = index % 4 == 3
    case = _simulate_case(f"{kind}{index}", system, rng, dt, N, process_ratio * dt, sensor_ratio * dt,
                          input_ratio * dt, process_std, sensor_std, input_std, measured, x0_kind, misfit, x0_scale=1.0)
    if x0_kind == "diffuse":
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", ModelWarning)
                smoother(case)
        except AttendInputError:  # states unobservable with the inputs unknown: a diffuse x[0] is refused
            case.x0_kind, case.x0_std = "prior*", np.full(n, 1.0)
    return case


DRONE_VARIANTS = ("known", "diffuse", "misfit", "long")


def drone_case(variant: str) -> Case:
    """The AR.Drone-like cases: variant "known" (x[0] given), "diffuse", "misfit" (60 samples), "long"
    (diffuse, 200 samples: the window length of issue 29's comparison)."""
    rng = np.random.default_rng([29, 1000, DRONE_VARIANTS.index(variant)])
    system = drone_like()
    dt = s = 0.04
    process_std = np.array([0.08, 0.08, 0.1, 0.5, 0.5, 0.8, 0.2, 0.2, 0.3, 28.0, 20.0, 5.0])
    sensor_std = np.array([0.01, 0.01, 0.005, 7e-4, 7e-4, 1.5e-3])
    input_std = np.full(4, np.exp(4.0))
    x0_kind = "known" if variant == "known" else "diffuse"
    N = 200 if variant == "long" else 60
    return _simulate_case(f"drone-{variant}", system, rng, dt, N, s, s, s, process_std, sensor_std, input_std,
                          np.zeros(4, dtype=bool), x0_kind, variant == "misfit", x0_scale=0.5)


def _simulate_case(name, system, rng, dt, N, s_w, s_z, s_u, sw, sz, su, measured, x0_kind, misfit, x0_scale) -> Case:
    r = system.n_inputs
    eta = rng.normal(size=r) * np.where(measured, 0.0, su) * 0.3  # a prior mean off zero
    truth_system, true_sw, true_sz, true_width = system, sw, sz, s_u
    notes = {}
    if misfit:
        truth_system = perturbed(system, rng)
        factors = np.exp(rng.uniform(np.log(2), np.log(5), size=2)) ** rng.choice([-1, 1], size=2)
        true_sw, true_sz = sw * factors[0], sz * factors[1]
        true_width = s_u * (3.0 if rng.uniform() < 0.5 else 1 / 3)
        notes = dict(noise_factors=factors.round(2).tolist(), input_width_factor=round(true_width / s_u, 3))
    prior_std = np.where(measured, 1.0, su)
    u = gp_inputs(rng, N, dt, true_width, eta, prior_std)
    u_mean = np.where(measured[None, :], u, eta[None, :])
    x0 = rng.normal(size=system.n_states) * x0_scale
    log = simulate(truth_system, u, dt, process_kernel_width=s_w, sensor_kernel_width=s_z, process_std=true_sw,
                   measurement_std=true_sz, initial_state=x0, seed=rng)
    if x0_kind == "known":
        x0_mean, x0_std = x0, np.zeros(system.n_states)
    elif x0_kind == "prior":
        x0_mean, x0_std = np.zeros(system.n_states), np.full(system.n_states, x0_scale)
    else:
        x0_mean, x0_std = np.zeros(system.n_states), None
    return Case(name, system, dt, s_w, s_z, s_u, sw, sz, su, u_mean, x0_kind, x0_mean, x0_std, log.outputs,
                log.states, u, not misfit, notes)


def smoother(case: Case) -> KalmanEstimator:
    """The estimator `attend estimate` builds for this model file (io.model.ModelFile.kalman)."""
    estimated = case.input_std > 0
    prior = np.where(estimated, case.input_std, 1.0) ** -2.0
    given = {} if case.x0_std is None else dict(initial_state=case.x0_mean, initial_state_std=case.x0_std)
    return KalmanEstimator(case.system, case.dt, sensor_precision=np.diag(case.sensor_std**-2.0),
                           process_precision=np.diag(case.process_std**-2.0),
                           process_kernel_width=case.process_width, sensor_kernel_width=case.sensor_width,
                           input_prior_precision=np.diag(prior), input_kernel_width=case.input_width,
                           known_inputs=(~estimated).tolist(), **given)


def model_arguments(case: Case) -> dict:
    """The model as exact_posterior / oracle_posterior take it."""
    x0_std = case.x0_std if case.x0_std is not None else \
        np.full(case.system.n_states, diffuse_std(case.system, case.outputs[0], case.sensor_std))
    return dict(process_kernel_width=case.process_width, sensor_kernel_width=case.sensor_width,
                input_kernel_width=case.input_width, process_std=case.process_std, measurement_std=case.sensor_std,
                input_prior_mean=case.input_mean, input_prior_std=case.input_std, initial_mean=case.x0_mean,
                initial_std=x0_std)


def _in_std(difference, std) -> float:
    """max |difference| / std over the entries with std > 0 (a known x[0] has std 0)."""
    spread = std > 1e-12 * max(float(np.max(std)), 1e-300)
    return float(np.max(np.abs(difference[spread]) / std[spread])) if spread.any() else 0.0


def _distance(estimate, oracle, estimated) -> tuple[float, float]:
    """max |mean - oracle mean| / oracle std over states, and over the estimated inputs."""
    return (_in_std(estimate.states - oracle.states, oracle.state_std),
            _in_std((estimate.inputs - oracle.inputs)[:, estimated], oracle.input_std[:, estimated]))


def _median_ratio(numerator, denominator) -> float:
    spread = denominator > 1e-12 * max(float(np.max(denominator)), 1e-300)
    return float(np.median(numerator[spread] / denominator[spread]))


def run_case(case: Case) -> dict:
    estimated = case.input_std > 0
    arguments = model_arguments(case)
    start = time.perf_counter()
    oracle = oracle_posterior(case.system, case.dt, case.outputs, **arguments)
    oracle_time = time.perf_counter() - start
    start = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ModelWarning)
        estimator = smoother(case)
        ours = estimator.estimate(case.outputs, case.input_mean)
    smoother_time = time.perf_counter() - start
    if caught:
        case.notes["warnings"] = [str(w.message).split(";")[0] for w in caught]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ConditioningWarning)
        try:
            dense = exact_posterior(case.system, case.dt, case.outputs, None, **arguments)
        except Exception as error:  # noqa: BLE001 - reported, not raised
            dense = None
            dense_error = str(error).splitlines()[0]
    dense_warned = any(issubclass(w.category, ConditioningWarning) for w in caught)
    sse = {}
    for label, estimate in (("oracle", oracle), ("smoother", ours), ("dense", dense)):
        if estimate is not None:
            sse[label] = (float(np.sum((estimate.states - case.states) ** 2)),
                          float(np.sum((estimate.inputs - case.inputs)[:, estimated] ** 2)))
    inside = lambda estimate, truth, std: (np.abs(estimate - truth) < 1.96 * std)  # noqa: E731
    result = dict(
        name=case.name, n=case.system.n_states, m=case.system.n_outputs, r=case.system.n_inputs,
        estimated=int(estimated.sum()), N=case.outputs.shape[0], input_ratio=case.input_width / case.dt,
        input_log_std=float(np.log(case.input_std[estimated].max())), process_ratio=case.process_width / case.dt,
        sensor_ratio=case.sensor_width / case.dt, x0=case.x0_kind, model_right=case.model_right, notes=case.notes,
        agree_mean=oracle.agreement.mean_in_std, agree_std=oracle.agreement.std_relative,
        condition=oracle.agreement.condition, oracle_time=oracle_time, smoother_time=smoother_time,
        state_ratio=sse["smoother"][0] / sse["oracle"][0], input_ratio_sse=sse["smoother"][1] / sse["oracle"][1],
        distance=_distance(ours, oracle, estimated),
        std_ratio=(_median_ratio(ours.state_std, oracle.state_std),
                   _median_ratio(ours.input_std[:, estimated], oracle.input_std[:, estimated])),
        inside=[int(inside(ours.states, case.states, ours.state_std).sum()),
                int(inside(ours.inputs, case.inputs, ours.input_std)[:, estimated].sum()),
                int(case.states.size), int(case.inputs[:, estimated].size)],
        oracle_inside=[int(inside(oracle.states, case.states, oracle.state_std).sum()),
                       int(inside(oracle.inputs, case.inputs, oracle.input_std)[:, estimated].sum())],
    )
    floors = estimator.noise_floors
    result["input_floor"] = floors["input"]
    if max(result["distance"]) > FLOOR_CHECK:  # how much of the gap is the smoother's white floors
        floored = oracle_posterior(case.system, case.dt, case.outputs, check=False, **arguments,
                                   white_floor=(floors["process"], floors["sensor"], floors["input"]))
        result["floor_distance"] = _distance(ours, floored, estimated)
        result["floor_effect"] = _distance(floored, oracle, estimated)
    if dense is not None:
        result["dense_distance"] = _distance(dense, oracle, estimated)
        result["dense_ratio"] = (sse["dense"][0] / sse["oracle"][0], sse["dense"][1] / sse["oracle"][1])
        result["dense_warned"] = dense_warned
        result["dense_jitter_shift"] = dense.accuracy.jitter_shift
    else:
        result["dense_error"] = dense_error
    return result


def _line(result: dict) -> str:
    dense = result.get("dense_distance")
    dense_text = (f"dense {dense[0]:8.2g} {dense[1]:8.2g}{' W' if result['dense_warned'] else '  '}" if dense
                  else f"dense failed: {result['dense_error'][:40]}")
    return (f"{result['name']:>14} n{result['n']} m{result['m']} r{result['estimated']}/{result['r']} "
            f"su/dt {result['input_ratio']:5.2f} e^{result['input_log_std']:.0f} x0 {result['x0']:7} "
            f"{'right' if result['model_right'] else 'MISFIT'}  agree {result['agree_mean']:.1e} "
            f"{result['agree_std']:.1e} cond {result['condition']:.0e} | SSE x {result['state_ratio']:.4f} "
            f"u {result['input_ratio_sse']:.4f} | dist x {result['distance'][0]:.2g} u {result['distance'][1]:.2g} "
            f"| std x {result['std_ratio'][0]:.3f} u {result['std_ratio'][1]:.3f} | {dense_text} "
            f"| {result['oracle_time']:.1f} s" + (f" | floor: smoother {result['floor_distance'][0]:.2g} "
                                                  f"{result['floor_distance'][1]:.2g}, floor's effect "
                                                  f"{result['floor_effect'][0]:.2g} {result['floor_effect'][1]:.2g}"
                                                  if "floor_distance" in result else ""))


def summarise(results: list[dict]) -> None:
    held = [r for r in results if r["agree_mean"] <= ORACLE_TOLERANCE and r["agree_std"] <= ORACLE_TOLERANCE]
    print(f"\noracle holds (both computations within {ORACLE_TOLERANCE:g}) on {len(held)} of {len(results)} cases; "
          f"worst agreement: mean {max(r['agree_mean'] for r in results):.1e} std, "
          f"std {max(r['agree_std'] for r in results):.1e} (relative); cond(G G') up to "
          f"{max(r['condition'] for r in results):.0e}")
    for label, key in (("state SSE", "state_ratio"), ("input SSE", "input_ratio_sse")):
        values = np.array([r[key] for r in held])
        print(f"smoother / oracle {label}: median {np.median(values):.4f} (target <= {SSE_MEDIAN}), worst "
              f"{values.max():.4f} (target <= {SSE_WORST}) [{values.min():.4f} best] over {len(values)} cases")
    for part, index in (("states", 0), ("inputs", 1)):
        values = np.array([r["distance"][index] for r in held])
        print(f"smoother's mean from the oracle's, {part}: median {np.median(values):.2g} std, "
              f"worst {values.max():.2g} std")
    right = [r for r in held if r["model_right"]]
    counts = np.sum([r["inside"] for r in right], axis=0)
    oracle_counts = np.sum([r["oracle_inside"] for r in right], axis=0)
    print(f"calibration of the smoother's 95 % intervals ({len(right)} model-right cases): states "
          f"{counts[0] / counts[2]:.1%}, inputs {counts[1] / counts[3]:.1%} (target {CALIBRATION[0]:.0%}-"
          f"{CALIBRATION[1]:.0%}); the oracle's: {oracle_counts[0] / counts[2]:.1%}, "
          f"{oracle_counts[1] / counts[3]:.1%}")
    floored = [r for r in held if "floor_distance" in r]
    if floored:
        worst = max(floored, key=lambda r: max(r["floor_distance"]))
        print(f"cases with the smoother > {FLOOR_CHECK} std from the oracle: {len(floored)} "
              f"{[r['name'] for r in floored]}; against the oracle given the smoother's white floors (1e-8 of the "
              f"process and sensor noises, {sorted({r['input_floor'] for r in held})} of the inputs' prior) the worst "
              f"of them is {max(worst['floor_distance']):.2g} std ({worst['name']})")
    dense = [r for r in held if "dense_distance" in r]
    failed = [r for r in held if "dense_error" in r]
    if dense:
        worst = max(dense, key=lambda r: max(r["dense_distance"]))
        off = [r["name"] for r in dense if max(r["dense_distance"]) > DENSE_OFF]
        warned = [r["name"] for r in dense if r["dense_warned"]]
        print(f"attend's float64 exact_posterior against the oracle: mean off by > {DENSE_OFF} std on {len(off)} of "
              f"{len(dense)} cases {off}; worst {worst['name']}: {max(worst['dense_distance']):.2g} std, SSE x "
              f"{worst['dense_ratio'][0]:.3f} (states) {worst['dense_ratio'][1]:.3f} (inputs) of the oracle's; refused "
              f"on {len(failed)} {[r['name'] for r in failed]}; ConditioningWarning on {len(warned)} {warned} "
              f"(off and not warned: {sorted(set(off) - set(warned))})")


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="12 random cases and one AR.Drone-like case")
    parser.add_argument("--cases", type=int, default=36, help="random/chain cases (default 36)")
    parser.add_argument("--only", type=str, default=None, help="comma-separated case indices (debugging)")
    parser.add_argument("--no-drone", action="store_true", help="skip the AR.Drone-like cases")
    parser.add_argument("--verbose", action="store_true", help="one line per case")
    parser.add_argument("--json", type=str, default=None, help="write every case's figures to this file")
    args = parser.parse_args(argv)
    count = 12 if args.quick else args.cases
    indices = [int(i) for i in args.only.split(",")] if args.only else list(range(count))
    cases = [lambda i=i: draw_case(i) for i in indices]
    if not args.no_drone and not args.only:
        variants = ("known",) if args.quick else DRONE_VARIANTS
        cases += [lambda v=v: drone_case(v) for v in variants]
    start = time.perf_counter()
    results = []
    for make in cases:
        result = run_case(make())
        results.append(result)
        if args.verbose:
            print(_line(result), flush=True)
    summarise(results)
    print(f"total {time.perf_counter() - start:.0f} s")
    if args.json:
        with open(args.json, "w") as handle:
            json.dump(results, handle, indent=1, default=float)


if __name__ == "__main__":
    main()
