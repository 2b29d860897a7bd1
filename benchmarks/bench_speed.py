"""Speed and scaling of the DEM observer on one CPU core.

    python benchmarks/bench_speed.py [--quick]

Targets (perception issue): batch DEM >= 1,000,000 samples/s for the ACC 2020 setting (p = 6,
d = 2) after set-up; online step median <= 50 us; set-up ("compile") time reported separately;
time and memory vs log length (1e3 .. 1e7), state dimension (2 .. 64) and p (0 .. 12); online
memory must not grow with the log length. For scale: SPM12's spm_DEM in Octave handles ~90
samples/s on this problem.
"""

from __future__ import annotations

import os

for variable in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[variable] = "1"  # one core, before numpy loads BLAS

import argparse  # noqa: E402
import time  # noqa: E402
import tracemalloc  # noqa: E402
import warnings  # noqa: E402

import numpy as np  # noqa: E402

from attend import DEMObserver, LinearSystem, convolution_model  # noqa: E402
from attend.models.linear import ModelWarning  # noqa: E402

warnings.simplefilter("ignore", ModelWarning)  # NaN std / refusals are not what this measures


def acc_observer(embedding_order=6, input_order=2, system=None):
    # a speed benchmark: run every p of the sweep, also those the stability analysis would refuse
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ModelWarning)
        return DEMObserver(system or convolution_model(), 0.1, kernel_width=0.5, sensor_precision=np.exp(8),
                           process_precision=np.exp(8), input_prior_precision=np.exp(-8),
                           embedding_order=embedding_order, input_order=input_order, allow_unstable=True)


def random_stable_system(n_states, seed=0):
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((n_states, n_states)) / np.sqrt(n_states)
    A -= (np.max(np.linalg.eigvals(A).real) + 0.5) * np.eye(n_states)
    return LinearSystem(A, rng.standard_normal((n_states, 1)), rng.standard_normal((4, n_states)))


def best_of(function, repeats=3):
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        function()
        times.append(time.perf_counter() - start)
    return min(times)


def batch_rate(observer, n_samples, repeats=3):
    rng = np.random.default_rng(1)
    outputs = rng.standard_normal((n_samples, observer.system.n_outputs)) * 0.1
    prior = np.full((n_samples, observer.system.n_inputs), 0.5)
    seconds = best_of(lambda: observer.estimate(outputs, prior), repeats)
    return n_samples / seconds, seconds


def peak_memory(function):
    tracemalloc.start()
    function()
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    return peak


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true", help="smaller sizes (for a smoke run)")
    args = parser.parse_args()

    print("== set-up (the 'compile' step: S, the observer matrices and one expm)")
    setup = best_of(lambda: acc_observer(), 5)
    print(f"set-up of the ACC observer (p = 6, d = 2): {setup * 1e3:.2f} ms")

    print("\n== batch DEM, ACC 2020 setting (n = 2, m = 4, r = 1, p = 6, d = 2), one core")
    observer = acc_observer()
    n_samples = 200_000 if args.quick else 2_000_000
    rate, seconds = batch_rate(observer, n_samples)
    verdict = "PASS" if rate >= 1e6 else "MISS"
    print(f"{n_samples} samples in {seconds:.3f} s: {rate:,.0f} samples/s   target >= 1,000,000  [{verdict}]"
          f"   (SPM12 spm_DEM in Octave: ~90 samples/s)")

    print("\n== online DEM, one sample per call")
    online = observer.online()
    rng = np.random.default_rng(2)
    samples = rng.standard_normal((20_000, 4)) * 0.1
    durations = np.empty(len(samples))
    prior = np.array([0.5])
    for k, sample in enumerate(samples):
        start = time.perf_counter()
        online.step(sample, prior)
        durations[k] = time.perf_counter() - start
    median = np.median(durations[100:]) * 1e6
    print(f"median step {median:.1f} us, 99th percentile {np.percentile(durations[100:], 99) * 1e6:.1f} us"
          f"   target median <= 50 us  [{'PASS' if median <= 50 else 'MISS'}]")

    def stream(n):
        online = observer.online()
        for sample in samples[:n] if n <= len(samples) else np.resize(samples, (n, 4)):
            online.step(sample, prior)

    short, long = 2_000, 20_000
    memory_short, memory_long = peak_memory(lambda: stream(short)), peak_memory(lambda: stream(long))
    print(f"online peak memory: {memory_short / 1024:.1f} KiB for {short} samples, {memory_long / 1024:.1f} KiB "
          f"for {long} samples  [{'PASS' if memory_long <= 1.1 * memory_short + 4096 else 'MISS'}: does not grow]")

    print("\n== scaling with log length (ACC setting)")
    print(f"{'samples':>10} {'time [s]':>10} {'samples/s':>12} {'peak memory [MiB]':>18}")
    lengths = [10**3, 10**4, 10**5, 10**6] + ([] if args.quick else [10**7])
    for n in lengths:
        rate, seconds = batch_rate(observer, n, repeats=1 if n >= 10**6 else 3)
        outputs = np.zeros((n, 4))
        prior_n = np.full((n, 1), 0.5)
        memory = peak_memory(lambda: observer.estimate(outputs, prior_n)) if n <= 10**6 else float("nan")
        print(f"{n:>10} {seconds:>10.4f} {rate:>12,.0f} {memory / 2**20:>18.1f}")

    print("\n== scaling with state dimension (p = 6, d = 2, 4 outputs, 1 input, 100,000 samples)")
    print(f"{'n states':>9} {'dim X':>7} {'set-up [s]':>11} {'samples/s':>12}")
    for n_states in [2, 4, 8, 16, 32] + ([] if args.quick else [64]):
        system = random_stable_system(n_states)
        start = time.perf_counter()
        obs = acc_observer(system=system)
        built = time.perf_counter() - start
        n = 100_000 if n_states <= 16 else 20_000
        rate, _ = batch_rate(obs, n, repeats=1)
        print(f"{n_states:>9} {obs.n_state_coordinates + obs.n_input_coordinates:>7} {built:>11.3f} {rate:>12,.0f}")

    print("\n== scaling with embedding order p (ACC system, d = 2, 200,000 samples)")
    print(f"{'p':>3} {'set-up [ms]':>12} {'samples/s':>12}")
    for p in range(0, 13, 2):
        start = time.perf_counter()
        obs = acc_observer(embedding_order=p)
        built = time.perf_counter() - start
        rate, _ = batch_rate(obs, 200_000, repeats=2)
        print(f"{p:>3} {built * 1e3:>12.2f} {rate:>12,.0f}")


if __name__ == "__main__":
    main()
