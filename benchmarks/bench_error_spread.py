"""Is the unscented smoother's reported std calibrated under coloured noise? Its white-noise model's
own std against its error spread (``noise_kernel_width``), on model families not in the random bank.

    PYTHONPATH=src python benchmarks/bench_error_spread.py [--seeds 4]

Four systems nobody tuned for: a Duffing oscillator and a van der Pol oscillator (measured push,
position sensor), Lotka-Volterra (no input, log-abundance sensor) and a forced pendulum seen
through arctan(2 sin(angle)) and its rate; 400 samples each, coloured noise of kernel width
s = 2 and 4 samples (simulate_nonlinear: held over each sample), the true x[0] as the prior mean
(std 0.1). Printed: the fraction of state samples (10 .. N - 10) within 2 reported std of the
truth, over the seeds (calibrated: ~0.95). Not part of the test run.
"""

from __future__ import annotations

import argparse

import numpy as np

from attend.perception.nonlinear import NonlinearSystem, simulate_nonlinear
from attend.perception.nonlinear_baselines import unscented_kalman


def _systems() -> dict:
    """name -> (system, x[0], dt [s], process std (per state, per s), sensor std (per output))."""
    return {
        "Duffing": (NonlinearSystem(lambda x, v: np.array([x[1], -0.2 * x[1] - x[0] - x[0] ** 3 + v[0]]),
                                    lambda x, v: x[:1], 2, 1, 1), [1.0, 0.0], 0.05, [0.0, 0.5], [0.05]),
        "van der Pol": (NonlinearSystem(lambda x, v: np.array([x[1], 1.5 * (1 - x[0] ** 2) * x[1] - x[0] + v[0]]),
                                        lambda x, v: x[:1], 2, 1, 1), [2.0, 0.0], 0.05, [0.0, 0.5], [0.1]),
        "Lotka-Volterra, log sensor": (NonlinearSystem(
            lambda x, v: np.array([x[0] * (1.0 - 0.5 * x[1]), x[1] * (-0.75 + 0.25 * x[0])]),
            lambda x, v: np.log(np.abs(x) + 1e-3), 2, 0, 2), [2.0, 1.0], 0.05, [0.05, 0.05], [0.05, 0.05]),
        "forced pendulum, arctan sensor": (NonlinearSystem(
            lambda x, v: np.array([x[1], -9.81 * np.sin(x[0]) - 0.1 * x[1] + np.cos(x[0]) * v[0]]),
            lambda x, v: np.array([np.arctan(2 * np.sin(x[0])), x[1]]), 2, 1, 2), [0.8, 0.0], 0.02, [0.0, 0.3],
            [0.05, 0.2]),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=4)
    args = parser.parse_args()
    print(f"== |error| < 2 std of the unscented smoother ({args.seeds} seeds, 400 samples; calibrated: ~0.95)")
    n_samples = 400
    for name, (system, x0, dt, process_std, sensor_std) in _systems().items():
        for ratio in (2, 4):
            s, inside = ratio * dt, {"white": [], "spread": []}
            for seed in range(args.seeds):
                time = np.arange(n_samples) * dt
                u = (0.5 * np.sin(0.9 * time + seed))[:, None] if system.n_inputs else n_samples
                log = simulate_nonlinear(system, u, dt, kernel_width=s, process_std=process_std,
                                         measurement_std=sensor_std, initial_state=x0, seed=seed)
                options = dict(process_covariance=np.diag((np.asarray(process_std) * dt) ** 2 + 1e-12),
                               measurement_covariance=np.diag(np.square(sensor_std)), initial_mean=x0,
                               initial_covariance=0.01)
                inputs = log.inputs if system.n_inputs else None
                for label, extra in (("white", {}), ("spread", dict(noise_kernel_width=s, seed=seed))):
                    estimate = unscented_kalman(system, dt, log.outputs, inputs, **options, **extra)
                    inner = slice(10, n_samples - 10)
                    inside[label].append(np.mean(np.abs(estimate.states - log.states)[inner]
                                                 < 2 * estimate.state_std[inner]))
            print(f"  {name:32s} s/dt = {ratio}: white-noise std {np.mean(inside['white']):.3f}, error spread "
                  f"{np.mean(inside['spread']):.3f} (per seed {' '.join(f'{v:.2f}' for v in inside['spread'])})",
                  flush=True)


if __name__ == "__main__":
    main()
