"""Nonlinear DEM against its references on the Lorenz and pendulum reproductions.

    PYTHONPATH=src python benchmarks/bench_nonlinear.py [--seeds 20] [--sweep-seeds 10] [--prior-seeds 20] [--parts 8]

Part 0 (speed): samples/s of nonlinear DEM's D-step (NumPy, and backend="jax" when JAX is installed,
with its first call's compilation time) on a 2 s and a 20 s Lorenz log, and of the UKF smoother on
the 2 s log, each in a fresh process: BLAS as it comes (threaded) without attend's limiter
(ATTEND_BLAS_THREADS=keep: the speed before the estimators limited their threads), with the
limiter (the default now: nothing set by the caller), with OPENBLAS_NUM_THREADS=1 set by the caller
before numpy is imported, and pinned to one core (taskset -c 0, where taskset exists).
Part 1 (the reproductions' settings, s/dt = 2, ``--seeds`` seeds each): state SSE of DEM (the D-step,
and path mode: states="path") over the
particle smoother (target: median ratio <= 1.2), over the UKF smoother (target: DEM <= UKF median
where s/dt >= 2), beside the coloured-noise UKS, the UKF filter and the fixed-lag UKF with DEM's
delay (the same data window as DEM); input SSE beside the
augmented UKF (pendulum); samples/s of each method.
Part 2 (``--sweep-seeds`` seeds): DEM / UKF smoother, filter and fixed-lag state SSE as s/dt
varies (1, 2, 4, 8), the noise levels fixed.
Part 3 (``--prior-seeds`` seeds): the pendulum's input prior smoothness: input SSE of DEM and the
augmented UKF smoother with the noise's s = 0.1 s (and the old fixed random-walk variance 0.5)
against the pushes' 0.7 s (the random walk matched to the prior).
Part 4 (``--conv-seeds`` seeds): is the particle reference converged? State (and input) SSE with
``--particles``/2 and ``--particles`` particles and an independent run at ``--particles``.
Part 5 (``--linear-seeds`` seeds): is DEM's gap to the posterior inherent? A linear model through the
nonlinear path (which equals the linear DEM observer to rounding, tests) against the exact posterior.
Part 6 (``--learn-seeds`` seeds): learn_path's parameter error bars against the seed-to-seed spread
(Lorenz rho; the pendulum's damping simulated 10x finer than sampled; the mass-spring-damper's
damping from the zero-order-hold simulator).
Part 7 (``--bank-cases`` cases): path mode on unseen systems, bench_bank.py's random LTI bank
(tiny cases with one kernel width, s/dt >= 1) written as f, g, with the exact posterior's prior on x[0],
against the exact posterior.
Part 8 (``--paired-seeds`` seeds): path mode against the UKF smoother, seed by seed, on the reproductions'
settings (``--fine`` K > 1: simulated K times finer, noise held over each fine step, every K-th sample
kept): state (and input) SSE with SPM's linearised motion and with motion="path", the per-seed ratio's
median with a bootstrap 95 % interval, the seeds on which path mode is better, paired Wilcoxon p.
Not part of the test run. No BLAS environment variable is needed (attend._threads).
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import time

import numpy as np

from attend.experiments import lorenz, pendulum
from attend.experiments import _nonlinear


def _verdict(ok: bool) -> str:
    return "meets target" if ok else "MISSES target"


def _best_rate(run, n_samples: int, repeats: int = 5) -> float:
    """Samples/s of the fastest of ``repeats`` calls of run() on n_samples samples."""
    best = np.inf
    for _ in range(repeats):
        start = time.perf_counter()
        run()
        best = min(best, time.perf_counter() - start)
    return n_samples / best


def _jax_speeds(cfg, logs) -> dict:
    """backend="jax" on the same logs, Lorenz written with jax.numpy: samples/s on the 2 s and 20 s
    logs (compiled; best of 5) and the first call's time (tracing and compilation) [s]; {} without JAX."""
    try:
        import jax  # noqa: F401
    except ImportError:
        return {}
    from attend.perception.nonlinear import NonlinearDEM

    dem = NonlinearDEM(lorenz.build_jax_system(cfg), cfg["dt"], kernel_width=cfg["kernel_width"], sensor_precision=1.0,
                       process_precision=1 / 400, embedding_order=6, backend="jax")
    start = time.perf_counter()
    dem.estimate(logs[0].outputs)
    compile_seconds = time.perf_counter() - start
    return dict(JAX=_best_rate(lambda: dem.estimate(logs[0].outputs), 200),
                JAX_20s=_best_rate(lambda: dem.estimate(logs[1].outputs), 2000), compile_s=compile_seconds)


def speed_worker() -> None:
    """Print 'key value' pairs: samples/s of DEM (NumPy, and JAX if installed) and of the UKF smoother
    on a 2 s Lorenz log and of DEM on a 20 s log (best of 5), the online step [us], JAX's first call [s]."""
    from attend.perception.nonlinear import NonlinearDEM
    from attend.models import simulate_nonlinear
    from attend.perception.nonlinear_smoothers import unscented_kalman, white_noise_covariances

    cfg = lorenz.SETTINGS
    system = lorenz.build_system(cfg)
    dt, s = cfg["dt"], cfg["kernel_width"]
    logs = [simulate_nonlinear(system, n_samples, dt, kernel_width=s, process_std=20.0, measurement_std=1.0,
                               initial_state=cfg["initial_state"], seed=0) for n_samples in (200, 2000)]
    log = logs[0]
    dem = NonlinearDEM(system, dt, kernel_width=s, sensor_precision=1.0, process_precision=1 / 400, embedding_order=6)
    Q, R = white_noise_covariances(system, dt, kernel_width=s, process_std=20.0, measurement_std=1.0)
    rates = dict(DEM=_best_rate(lambda: dem.estimate(log.outputs), 200),
                 DEM_20s=_best_rate(lambda: dem.estimate(logs[1].outputs), 2000),
                 UKF=_best_rate(lambda: unscented_kalman(system, dt, log.outputs, process_covariance=Q,
                                                         measurement_covariance=R, initial_mean=cfg["initial_state"],
                                                         initial_covariance=1.0), 200))
    online = dem.online()
    for y in log.outputs[:20]:  # fill the window (and the start)
        online.step(y)
    steps = log.outputs[20:]
    best = np.inf
    for _ in range(3):
        start = time.perf_counter()
        for y in steps:
            online.step(y)
        best = min(best, (time.perf_counter() - start) / len(steps))
    rates.update(online_us=1e6 * best, **_jax_speeds(cfg, logs))
    print(" ".join(f"{key} {value:.4g}" for key, value in rates.items()))


def part0() -> None:
    print(f"\n== speed (samples/s of the D-step on a 2 s / 20 s Lorenz log, n = 3, p = 6, best of 5, fresh process "
          f"each; {os.cpu_count()} cores; target >= 2e4 samples/s)")
    keys = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS", "ATTEND_BLAS_THREADS")
    base = {key: value for key, value in os.environ.items() if key not in keys}
    runs = [("before: threaded BLAS, no limiter (ATTEND_BLAS_THREADS=keep)", {"ATTEND_BLAS_THREADS": "keep"}, []),
            ("now: nothing set by the caller (attend limits its loops)", {}, []),
            ("caller sets OPENBLAS_NUM_THREADS=1", {"OPENBLAS_NUM_THREADS": "1"}, [])]
    if shutil.which("taskset"):
        runs.append(("pinned to one core (taskset -c 0)", {}, ["taskset", "-c", "0"]))
    for label, extra, prefix in runs:
        out = subprocess.run(prefix + [sys.executable, __file__, "--speed-worker"], env={**base, **extra},
                             capture_output=True, text=True, check=True).stdout.split()
        rate = dict(zip(out[::2], map(float, out[1::2])))
        jax = (f"   JAX {rate['JAX']:7.0f} / {rate['JAX_20s']:7.0f} ({_verdict(rate['JAX'] >= 2e4)}; first call "
               f"{rate['compile_s']:.1f} s)") if "JAX" in rate else "   JAX not installed"
        print(f"  {label:62s}\n    DEM NumPy {rate['DEM']:7.0f} / {rate['DEM_20s']:7.0f} ({_verdict(rate['DEM'] >= 2e4)})"
              f"{jax}\n    UKF smoother {rate['UKF']:6.0f}   online DEM step {rate['online_us']:5.0f} us (target <= 200)")


def part1(seeds: int, experiments=("lorenz", "pendulum")) -> None:
    for module in (m for m in (lorenz, pendulum) if m.__name__.rsplit(".", 1)[-1] in experiments):
        start = time.perf_counter()
        result = module.run(quick=False, seeds=seeds, progress=False)
        elapsed = time.perf_counter() - start
        cfg = result.settings
        value = lambda name: result.metric(name).value  # noqa: E731
        print(f"\n== {result.experiment}: {seeds} seeds, {cfg['duration']:.0f} s at dt = {cfg['dt']} s, "
              f"s = {cfg['kernel_width']} s (s/dt = {cfg['kernel_width'] / cfg['dt']:.0f}), "
              f"{cfg['particles']} particles ({elapsed:.0f} s)")
        for method in _nonlinear.METHODS:
            print(f"  {method:14s} state SSE median {value(f'{method} state SSE (median)'):10.3f}   "
                  f"{value(f'{method} speed'):8.0f} samples/s")
        for dem in _nonlinear.DEM_MODES:
            ratio = value(f"{dem} / particle state SSE (median ratio)")
            print(f"  {dem} / particle     state SSE median ratio {ratio:6.3f}   target <= 1.2    "
                  f"{_verdict(ratio <= 1.2)}")
            ratio = value(f"{dem} / UKF state SSE (median ratio)")
            mine, ukf = value(f"{dem} state SSE (median)"), value("UKF state SSE (median)")
            print(f"  {dem} / UKF smoother state SSE median ratio {ratio:6.3f}   target median <= UKF median "
                  f"({mine:.3f} vs {ukf:.3f})  {_verdict(mine <= ukf)}")
            for other in ("coloured UKS", "UKF filter", "UKF lag"):
                print(f"  {dem} / {other:12s} state SSE median ratio "
                      f"{value(f'{dem} / {other} state SSE (median ratio)'):6.3f}   (no target)")
        if module is pendulum:
            for method in ("DEM", "DEM path", "augmented UKF", "augmented UKF filter", "augmented UKF lag",
                           "coloured UKS", "particle"):
                print(f"  input SSE median {method:22s} {value(f'{method} input SSE (median)'):10.3f}")
            for dem in _nonlinear.DEM_MODES:
                print(f"  {dem} / augmented UKF input SSE median ratio "
                      f"{value(f'{dem} / augmented UKF input SSE (median ratio)'):6.3f}   (no target)")
        for dem in _nonlinear.DEM_MODES + (_nonlinear.UKF_WHITE_STD, _nonlinear.UKF_SPREAD):
            print(f"  {dem} |error| < 2 std: {value(f'{dem} |error| < 2 std (fraction of samples)'):.3f} of samples "
                  "(calibrated if in 0.93-0.97)")


def part2(seeds: int) -> None:
    print(f"\n== s/dt sweep ({seeds} seeds; DEM, UKF smoother, UKF filter, UKF fixed-lag with DEM's delay)")
    for module in (lorenz, pendulum):
        for ratio_s in (1, 2, 4, 8):
            cfg = dict(module.SETTINGS)
            cfg.update(kernel_width=ratio_s * cfg["dt"], seeds=seeds, methods=("DEM", "UKF", "UKF filter", "UKF lag"))
            result = _nonlinear.compare(module.__name__.rsplit(".", 1)[-1], cfg, False)
            smoother = result.metric("DEM / UKF state SSE (median ratio)").value
            dem, ukf = result.metric("DEM state SSE (median)").value, result.metric("UKF state SSE (median)").value
            filt = result.metric("DEM / UKF filter state SSE (median ratio)").value
            lag = result.metric("DEM / UKF lag state SSE (median ratio)").value
            target = "" if ratio_s < 2 else f"  target DEM <= UKF: {_verdict(dem <= ukf)}"
            print(f"  {result.experiment:8s} s/dt = {ratio_s}: DEM/UKF smoother {smoother:6.3f}  "
                  f"DEM/UKF filter {filt:6.3f}  DEM/UKF lag {lag:6.3f}{target}")


def part3(seeds: int) -> None:
    print(f"\n== pendulum input prior smoothness ({seeds} seeds, 20 s; input SSE median, (rad/s^2)^2; states in brackets)")
    cases = (("before: s_v = s = 0.1 s, UKF random walk 0.5 (fixed)", dict(input_kernel_width=None,
                                                                          input_random_walk_variance=0.5)),
             ("s_v = s = 0.1 s, UKF random walk matched to the prior", dict(input_kernel_width=None)),
             ("after: s_v = 0.7 s (the pushes), random walk matched", dict(input_kernel_width=0.7)))
    for label, change in cases:
        cfg = dict(pendulum.SETTINGS, seeds=seeds, methods=("DEM", "UKF", "UKF lag"), **change)
        result = _nonlinear.compare("pendulum", cfg, False)
        value = lambda name: result.metric(name).value  # noqa: E731
        print(f"  {label:55s} DEM {value('DEM input SSE (median)'):7.1f} ({value('DEM state SSE (median)'):5.2f})  "
              f"augmented UKF smoother {value('augmented UKF input SSE (median)'):7.1f} "
              f"({value('UKF state SSE (median)'):5.2f})  fixed-lag UKF {value('augmented UKF lag input SSE (median)'):7.1f}  "
              f"DEM/UKF {value('DEM / augmented UKF input SSE (median ratio)'):5.2f}")


def part4(seeds: int, particles: int) -> None:
    print(f"\n== convergence of the particle reference ({seeds} seeds, full settings): state SSE with P/2, P and an "
          f"independent run at P = {particles}")
    from attend.models import simulate_nonlinear
    from attend.perception.nonlinear_smoothers import particle_smoother

    for module in (lorenz, pendulum):
        cfg = dict(module.SETTINGS)
        system, u, _, n_samples = _nonlinear._setup(module.__name__.rsplit(".", 1)[-1], cfg)
        unknown = system.n_inputs > 0
        sw, sz = np.asarray(cfg["process_std"], float), np.asarray(cfg["measurement_std"], float)
        trim = slice(cfg["embedding_order"] + 1, n_samples - cfg["embedding_order"] - 1)
        noise = dict(kernel_width=cfg["kernel_width"], process_std=sw, measurement_std=sz,
                     input_prior_std=np.exp(-cfg["input_prior_log_precision"] / 2) if unknown else None,
                     initial_mean=cfg["initial_state"], initial_std=cfg["initial_std"], ar_order=cfg["ar_order"],
                     input_kernel_width=cfg.get("input_kernel_width") if unknown else None, lag=cfg["particle_lag"])
        changes, spreads = [], []
        for seed in range(seeds):
            log = simulate_nonlinear(system, u, cfg["dt"], kernel_width=cfg["kernel_width"], process_std=sw,
                                     measurement_std=sz, initial_state=cfg["initial_state"], seed=seed)
            sse = {}
            for label, count, draw in (("half", particles // 2, seed), ("full", particles, seed),
                                       ("independent", particles, seed + 10_000)):
                estimate = particle_smoother(system, cfg["dt"], log.outputs, n_particles=count, seed=draw, **noise)
                sse[label] = (np.sum((estimate.states - log.states)[trim] ** 2),
                              np.sum((estimate.inputs - log.inputs)[trim] ** 2) if unknown else 0.0)
            changes.append(sse["full"][0] / sse["half"][0] - 1)
            spreads.append(abs(sse["independent"][0] / sse["full"][0] - 1))
            inputs = (f"  input SSE {sse['half'][1]:.1f} / {sse['full'][1]:.1f} / {sse['independent'][1]:.1f}"
                      if unknown else "")
            print(f"  {module.__name__.rsplit('.', 1)[-1]:8s} seed {seed}: state SSE {sse['half'][0]:.3f} / "
                  f"{sse['full'][0]:.3f} / {sse['independent'][0]:.3f}{inputs}", flush=True)
        print(f"  {module.__name__.rsplit('.', 1)[-1]:8s} state SSE change P/2 -> P: median {np.median(changes):+.1%}"
              f" (max |.| {np.max(np.abs(changes)):.1%}); independent runs at P differ by median "
              f"{np.median(spreads):.1%} (max {np.max(spreads):.1%})")


def part5(seeds: int) -> None:
    print(f"\n== is DEM's gap inherent? a linear model (mass-spring-damper, dt = 0.1 s) through the nonlinear "
          f"path against the exact posterior ({seeds} seeds, median state SSE ratio over samples 9..192)")
    from attend.perception.references import exact_posterior
    from attend.perception.nonlinear import NonlinearDEM
    from attend.models import NonlinearSystem
    from attend.perception.nonlinear_smoothers import unscented_kalman, white_noise_covariances
    from attend.models.problems import mass_spring_damper
    from attend.models.linear import simulate

    linear = mass_spring_damper()
    A, B, C = linear.A, linear.B, linear.C
    system = NonlinearSystem(lambda x, v: A @ x + B @ v, lambda x, v: C @ x, 2, 1, C.shape[0])
    dt, sw, sz = 0.1, 0.3, 0.05
    for ratio in (1, 2, 4):
        s = ratio * dt
        rows = {"DEM p = 6": [], "DEM p = 10": [], "DEM path p = 6": [], "UKF smoother (white)": []}
        Q, R = white_noise_covariances(system, dt, kernel_width=s, process_std=sw, measurement_std=sz)
        for seed in range(seeds):
            u = np.zeros((200, 1))
            log = simulate(linear, u, dt, kernel_width=s, process_std=sw, measurement_std=sz, seed=seed,
                           initial_state=[0.5, 0.0])
            exact = exact_posterior(linear, dt, log.outputs, u, kernel_width=s, process_std=sw, measurement_std=sz,
                                    initial_mean=[0.5, 0.0], initial_std=1e-2)
            trim = slice(8, 192)
            reference = np.sum((exact.states - log.states)[trim] ** 2)
            for label, p in (("DEM p = 6", 6), ("DEM p = 10", 10)):
                dem = NonlinearDEM(system, dt, kernel_width=s, sensor_precision=1 / sz**2, process_precision=1 / sw**2,
                                   embedding_order=p, known_inputs=True)
                estimate = dem.estimate(log.outputs, u)
                rows[label].append(np.sum((estimate.states - log.states)[trim] ** 2) / reference)
            path = NonlinearDEM(system, dt, kernel_width=s, sensor_precision=1 / sz**2, process_precision=1 / sw**2,
                                embedding_order=6, known_inputs=True, states="path").estimate(log.outputs, u)
            rows["DEM path p = 6"].append(np.sum((path.states - log.states)[trim] ** 2) / reference)
            ukf = unscented_kalman(system, dt, log.outputs, u, process_covariance=Q, measurement_covariance=R,
                                   initial_mean=[0.5, 0.0], initial_covariance=1e-4)
            rows["UKF smoother (white)"].append(np.sum((ukf.states - log.states)[trim] ** 2) / reference)
        print(f"  s/dt = {ratio}: " + "   ".join(f"{label} / exact {np.median(v):5.2f}" for label, v in rows.items()),
              flush=True)


def _learning_case(name: str, seed: int):
    """(model, outputs, inputs, learn_path keywords, true theta, active mask) of a part-6 case."""
    from attend.perception.nonlinear import ParametrisedSystem
    from attend.models import simulate_nonlinear
    from attend.models.problems import mass_spring_damper
    from attend.models.linear import simulate

    if name == "lorenz rho":
        cfg = lorenz.SETTINGS
        f = lambda x, v, th: np.array([10 * (x[1] - x[0]), x[0] * (th[0] - x[2]) - x[1], x[0] * x[1] - 8 / 3 * x[2]])  # noqa: E731
        model = ParametrisedSystem(f, lambda x, v, th: np.asarray(x, float), 3, 0, 3)
        log = simulate_nonlinear(model.at([28.0]), 400, cfg["dt"], kernel_width=cfg["kernel_width"], process_std=20.0,
                                 measurement_std=1.0, initial_state=cfg["initial_state"], seed=seed)
        options = dict(kernel_width=cfg["kernel_width"], sensor_precision=1.0, process_precision=1 / 400,
                       prior_mean=[20.0], prior_precision=[0.0])
        return model, log.outputs, None, cfg["dt"], options, np.array([28.0])
    if name == "pendulum damping (10x finer simulation)":
        cfg = pendulum.SETTINGS
        f = lambda x, v, th: np.array([x[1], -9.81 * np.sin(x[0]) - th[0] * x[1] + v[0]])  # noqa: E731
        model = ParametrisedSystem(f, lambda x, v, th: np.array([np.sin(x[0]), np.cos(x[0])]), 2, 1, 2)
        fine, dt = 10, cfg["dt"]
        log = simulate_nonlinear(model.at([0.3]), np.zeros((400 * fine, 1)), dt / fine, kernel_width=cfg["kernel_width"],
                                 process_std=cfg["process_std"], measurement_std=cfg["measurement_std"],
                                 initial_state=[1.0, 0.0], seed=seed)
        sw = np.asarray(cfg["process_std"])
        options = dict(kernel_width=cfg["kernel_width"], sensor_precision=1 / cfg["measurement_std"] ** 2,
                       process_precision=1 / sw**2, prior_mean=[1.0], prior_precision=[0.0])
        return model, log.outputs[::fine], np.zeros((400, 1)), dt, options, np.array([0.3])
    linear = mass_spring_damper()
    A, B, C = linear.A, linear.B, linear.C

    def f(x, v, th):
        A_theta = A.copy()
        A_theta[1, 1] = th[0]
        return A_theta @ x + B @ v

    model = ParametrisedSystem(f, lambda x, v, th: C @ x, 2, 1, C.shape[0])
    u = np.repeat(np.random.default_rng(100 + seed).normal(size=(20, 1)), 10, axis=0)
    log = simulate(linear, u, 0.1, kernel_width=0.2, process_std=0.3, measurement_std=0.05, seed=seed,
                   initial_state=[0.5, 0.0])
    options = dict(kernel_width=0.2, sensor_precision=1 / 0.05**2, process_precision=1 / 0.3**2,
                   prior_mean=[0.5 * A[1, 1]], prior_precision=[0.0], motion="linearized")
    return model, log.outputs, u, 0.1, options, np.array([A[1, 1]])


def part6(seeds: int) -> None:
    print(f"\n== learn_path: are the parameters' error bars calibrated? ({seeds} seeds; z = (theta_hat - theta) / std, "
          "calibrated: mean z^2 near 1, within the chi-square range printed)")
    from scipy.stats import chi2

    from attend.perception.nonlinear import learn_path

    low, high = chi2.ppf([0.025, 0.975], seeds) / seeds
    for name in ("lorenz rho", "pendulum damping (10x finer simulation)", "mass-spring-damper damping (a/m, ZOH simulation)"):
        z, estimates, stds, start = [], [], [], time.perf_counter()
        for seed in range(seeds):
            model, outputs, inputs, dt, options, truth = _learning_case(name, seed)
            result = learn_path(model, outputs, inputs, dt, **options)
            estimates.append(result.parameters[0])
            stds.append(result.parameter_std[0])
            z.append((result.parameters[0] - truth[0]) / result.parameter_std[0])
        z = np.array(z)
        print(f"  {name:48s} truth {truth[0]:7.3f}  mean estimate {np.mean(estimates):7.3f}  seed spread "
              f"{np.std(estimates, ddof=1):.3f}  rms std {np.sqrt(np.mean(np.square(stds))):.3f}  mean z {np.mean(z):+.2f}  "
              f"mean z^2 {np.mean(z**2):.2f} (95 % range if calibrated: {low:.2f}-{high:.2f})  "
              f"{time.perf_counter() - start:.0f} s", flush=True)


def part7(cases: int) -> None:
    print(f"\n== path mode on unseen systems: the random bank of bench_bank.py (tiny cases, shared kernel width, "
          f"s/dt >= 1, known inputs or unknown GP inputs) written as f, g, against the exact posterior ({cases} cases)")
    sys.path.insert(0, os.path.dirname(__file__))
    import warnings

    import bench_bank

    from attend.models.generalized import smoothness_condition
    from attend.perception.dem import AUTO_MAX_CONDITION
    from attend.perception.nonlinear import NonlinearDEM
    from attend.models import NonlinearSystem

    rows, index = [], 0
    while len(rows) < cases and index < 40 * cases:
        case = bench_bank.draw_case(index, tiny=True)
        index += 1
        if not case.shared or case.process_width < case.dt or case.input_kind == "unknown-pulses":
            continue
        A, B, C = case.system.A, case.system.B, case.system.C
        system = NonlinearSystem(lambda x, v, A=A, B=B: A @ x + B @ v, lambda x, v, C=C: C @ x, A.shape[0], B.shape[1],
                                 C.shape[0])
        s = case.process_width
        p = next((p for p in range(6, 0, -1) if smoothness_condition(p + 1, s, case.dt) <= AUTO_MAX_CONDITION), 1)
        unknown = not case.known
        options = dict(embedding_order=p, known_inputs=not unknown, states="path")
        if unknown:
            options.update(input_prior_precision=1 / case.input_prior_std**2, input_kernel_width=case.input_width)
        exact, _ = bench_bank.exact(case, causal=False)
        start = time.perf_counter()
        try:
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                # the exact posterior's prior on x[0] (about 0; "known": std 0, given as 1e-6 (1 + 0))
                estimate = NonlinearDEM(system, case.dt, kernel_width=s, sensor_precision=1 / case.sensor_std**2,
                                        process_precision=1 / case.process_std**2, **options).estimate(case.outputs,
                                                            case.input_prior_mean if unknown else case.inputs,
                                                            initial_state=np.zeros(A.shape[0]),
                                                            initial_state_std=case.initial_std or 1e-6)
        except Exception as error:  # noqa: BLE001 - a refusal is a result of the bank
            print(f"  case {case.index:3d} {case.describe()}: {type(error).__name__}: {str(error)[:100]}")
            continue
        warned = any("far from DEM's generalised model" in str(w.message) for w in caught)
        seconds = time.perf_counter() - start
        n_samples = len(case.outputs)
        trim = slice(n_samples // 10, n_samples - n_samples // 10)
        ratio = np.sum((estimate.states - case.states)[trim] ** 2) / np.sum((exact.states - case.states)[trim] ** 2)
        inside = np.mean(np.abs(estimate.states - case.states)[trim] < 2 * estimate.state_std[trim])
        exact_inside = np.mean(np.abs(exact.states - case.states)[trim] < 2 * exact.state_std[trim])
        rows.append((ratio, inside, exact_inside, warned))
        print(f"  case {case.index:3d} {case.describe()} p={p}: path / exact state SSE {ratio:9.3f}, |error| < 2 std "
              f"{inside:.3f} (exact posterior {exact_inside:.3f}){' WARNED (misfit)' if warned else ''}, "
              f"{n_samples / seconds:5.0f} samples/s", flush=True)
    rows = np.array(rows, dtype=float)
    for label, chosen in (("all", np.ones(len(rows), bool)), ("not warned", rows[:, 3] == 0),
                          ("warned", rows[:, 3] == 1)):
        if chosen.any():
            part = rows[chosen]
            print(f"  {label:10s} {len(part):2d} cases: path / exact state SSE median {np.median(part[:, 0]):.3f}, "
                  f"90th percentile {np.percentile(part[:, 0], 90):.3f}, max {part[:, 0].max():.3g}; |error| < 2 std "
                  f"pooled {part[:, 1].mean():.3f} (exact posterior {part[:, 2].mean():.3f})")


def _paired_log(module, cfg: dict, seed: int, fine: int):
    """The reproduction's log of ``seed``, simulated ``fine`` times finer and sampled at cfg's dt."""
    from attend.models import simulate_nonlinear

    name = module.__name__.rsplit(".", 1)[-1]
    system, u, _, n_samples = _nonlinear._setup(name, cfg)
    dt = cfg["dt"]
    fine_u = module.true_input(np.arange((n_samples - 1) * fine + 1) * dt / fine) if system.n_inputs else \
        (n_samples - 1) * fine + 1
    log = simulate_nonlinear(system, fine_u, dt / fine, kernel_width=cfg["kernel_width"],
                             process_std=cfg["process_std"], measurement_std=cfg["measurement_std"],
                             initial_state=cfg["initial_state"], seed=seed, substeps=max(1, 10 // fine))
    return system, log.states[::fine], log.inputs[::fine], log.outputs[::fine]


def part8(seeds: int, fine: int) -> None:
    from scipy.stats import wilcoxon
    from attend.perception.nonlinear_smoothers import unscented_kalman

    print(f"\n== path mode against the UKF smoother, seed by seed ({seeds} seeds, simulated {fine}x finer than dt; "
          "per-seed SSE ratio: median [bootstrap 95 %], seeds where path mode is better, paired Wilcoxon p)")
    rng = np.random.default_rng(0)
    for module in (lorenz, pendulum):
        cfg = dict(module.SETTINGS)
        p = cfg["embedding_order"]
        sse = {key: [] for key in ("linearized", "path", "UKF")}
        for seed in range(seeds):
            system, states, inputs, outputs = _paired_log(module, cfg, seed, fine)
            trim = slice(p + 1, len(states) - p - 1)
            estimates = {motion: _nonlinear._dem(system, cfg, states="path", motion=motion).estimate(outputs)
                         for motion in ("linearized", "path")}
            estimates["UKF"] = unscented_kalman(system, cfg["dt"], outputs, **_nonlinear.kalman_options(system, cfg))
            for key, estimate in estimates.items():
                sse[key].append((np.sum((estimate.states - states)[trim] ** 2),
                                 np.sum((estimate.inputs - inputs)[trim] ** 2) if system.n_inputs else np.nan))
        ukf = np.array(sse["UKF"])
        print(f"  {module.__name__.rsplit('.', 1)[-1]}: UKF smoother state SSE median {np.median(ukf[:, 0]):.3f}")
        for motion in ("linearized", "path"):
            mine = np.array(sse[motion])
            for column, label in ((0, "states"), (1, "input")):
                if np.isnan(mine[:, column]).all():
                    continue
                ratio = mine[:, column] / ukf[:, column]
                draws = [np.median(ratio[rng.integers(0, seeds, seeds)]) for _ in range(2000)]
                low, high = np.percentile(draws, [2.5, 97.5])
                print(f"    motion={motion:10s} {label:6s} SSE median {np.median(mine[:, column]):9.3f} vs "
                      f"{np.median(ukf[:, column]):9.3f}; per-seed ratio {np.median(ratio):.4f} [{low:.4f}, {high:.4f}]"
                      f", better on {np.sum(ratio < 1)}/{seeds}, Wilcoxon p {wilcoxon(mine[:, column], ukf[:, column]).pvalue:.2g}",
                      flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--sweep-seeds", type=int, default=10)
    parser.add_argument("--prior-seeds", type=int, default=20)
    parser.add_argument("--experiments", default="lorenz,pendulum", help="part 1: which reproductions")
    parser.add_argument("--conv-seeds", type=int, default=4)
    parser.add_argument("--particles", type=int, default=100_000, help="P of the convergence check (part 4)")
    parser.add_argument("--linear-seeds", type=int, default=12)
    parser.add_argument("--parts", default="012345678", help="which parts to run (default: all)")
    parser.add_argument("--bank-cases", type=int, default=24, help="cases of part 7 (path mode on the random bank)")
    parser.add_argument("--learn-seeds", type=int, default=12, help="seeds of part 6 (learn_path calibration)")
    parser.add_argument("--paired-seeds", type=int, default=100, help="seeds of part 8 (path mode vs UKF smoother)")
    parser.add_argument("--fine", type=int, default=1, help="part 8: simulate this many times finer than dt")
    parser.add_argument("--speed-worker", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.speed_worker:
        speed_worker()
        return
    if "0" in args.parts:
        part0()
    if "1" in args.parts:
        part1(args.seeds, args.experiments.split(","))
    if "2" in args.parts and args.sweep_seeds > 0:
        part2(args.sweep_seeds)
    if "3" in args.parts and args.prior_seeds > 0:
        part3(args.prior_seeds)
    if "4" in args.parts and args.conv_seeds > 0:
        part4(args.conv_seeds, args.particles)
    if "5" in args.parts and args.linear_seeds > 0:
        part5(args.linear_seeds)
    if "6" in args.parts and args.learn_seeds > 0:
        part6(args.learn_seeds)
    if "7" in args.parts and args.bank_cases > 0:
        part7(args.bank_cases)
    if "8" in args.parts and args.paired_seeds > 0:
        part8(args.paired_seeds, args.fine)


if __name__ == "__main__":
    main()
