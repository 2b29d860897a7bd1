"""Calibrates attend.perception.spread_check.SPREAD_LIMIT: how large the ratio of an estimate's RMS to
its reference (measured proxy or prior spread) gets on correct models, and what it is on
mis-specified ones.

Correct models: (1) the random bank of bench_bank.py (dense C: the prior spread is the reference),
estimated by the coloured-noise Kalman smoother with the true model and, where it runs, DEM
(embedding_order "auto"); (2) random mechanical systems [q; dq/dt] with positions measured (the
measured proxy y / c and its derivative are the references), same estimators. False alarms: cases
with any ratio above the limit.

Mis-specified: (a) outputs logged in degrees, model in radians (C 57x too small for the log) on
bank systems; (b) a position sensor whose noise std the model says is 100x smaller than it is, with an
unknown force of a far too wide prior (std 1e3 against a true 0.3): the velocity, weakly pinned by
the data, follows the noise's derivative.

The input-prior check (``--input-prior``, spread_check.input_prior_findings: an unknown input's
RMS about its prior mean over its prior std, t_j, against the (1 - INPUT_PRIOR_FALSE_RATE) quantile
of the prior's own RMS over the log): (0) that quantile against 200000 draws of the prior (the
bound a correct model's posterior mean stays under); false warnings on correct models with the
inputs drawn from their prior: (1) bench_unknown_inputs.py's model-right cases (case i < 400,
default_rng([29, i])), the smoother `attend estimate` builds; (2) bench_bank.py's unknown-input
cases (its seed, i < 60, and seed 0, i < 40; GP inputs from the prior, and pulses under a GP prior), the Kalman smoother with
the true widths and, where the widths are shared, DEM; (3) bench_unknown_inputs_misfit.py's bank
drawn with the file's model as the truth (default_rng([2903, i]), i < 120; inputs 1/2-4x the
process width, which the file does not state), through `attend estimate`'s default (the width and
lambda* chosen from the log); then the misfit bench's own cases (which it warns). ~30 minutes on one core.

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_spread_check.py [--cases 60]
    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_spread_check.py --input-prior [--cases 120]
"""

from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_bank import draw_case  # noqa: E402

from attend import LinearSystem  # noqa: E402
from attend._validation import AttendInputError  # noqa: E402
from attend.perception.dem import DEMObserver  # noqa: E402
from attend.perception.kalman import KalmanEstimator  # noqa: E402
from attend.perception.spread_check import (  # noqa: E402
    INPUT_PRIOR_FALSE_RATE, SPREAD_LIMIT, input_prior_limit, input_prior_ratios, spread_findings)
from attend.models.linear import ModelWarning, simulate  # noqa: E402


def mechanical_case(index: int):
    """[q; dq/dt] with M q'' = -K q - D q' + F u: positions measured, forces known or unknown."""
    rng = np.random.default_rng([29, index])
    k = int(rng.integers(1, 4))
    n, r = 2 * k, int(rng.integers(1, k + 1))
    Q = np.linalg.qr(rng.standard_normal((k, k)))[0]
    K = Q @ np.diag(10 ** rng.uniform(-1, 1, k)) @ Q.T
    D = Q @ np.diag(10 ** rng.uniform(-1.5, 0, k)) @ Q.T
    A = np.block([[np.zeros((k, k)), np.eye(k)], [-K, -D]])
    B = np.vstack([np.zeros((k, r)), rng.standard_normal((k, r))])
    C = np.hstack([np.eye(k), np.zeros((k, k))])
    dt = float(rng.choice([0.01, 0.02, 0.05]))
    N = int(rng.integers(300, 1200))
    width = float(rng.choice([0.0, 1.0, 2.0, 4.0])) * dt
    unknown = bool(index % 2)
    t = np.arange(N) * dt
    u = np.sin(2 * np.pi * rng.uniform(0.05, 1.0, r) * t[:, None] + rng.uniform(0, 6, r))
    system = LinearSystem(A, B, C)
    process_std = np.concatenate([np.full(k, 1e-3), np.full(k, 10 ** rng.uniform(-2, 0))])
    clean = simulate(system, u, dt, kernel_width=0.0, seed=0)
    sensor_std = max(np.sqrt(np.mean(clean.outputs**2)), 1e-3) * 10 ** rng.uniform(-3, -1)
    log = simulate(system, u, dt, kernel_width=width, process_std=process_std, measurement_std=sensor_std,
                   seed=index)
    return dict(system=system, dt=dt, width=width, outputs=log.outputs, inputs=u, unknown=unknown, states=log.states,
                process_precision=process_std**-2, sensor_precision=sensor_std**-2,
                input_precision=np.ones(r), input_width=max(width, 5 * dt))


def ratios(system, dt, outputs, states, inputs, *, process_precision, width, unknown, drive, input_precision,
           input_width):
    r = system.n_inputs
    return spread_findings(system, dt, outputs, states, inputs, process_precision=process_precision,
                           process_kernel_width=width, sensor_kernel_width=width,
                           unknown=np.full(r, unknown), drive=drive, input_prior_precision=input_precision,
                           input_kernel_width=input_width, ratios=True)


def run_estimators(case, dem: bool = True):
    """{name: (states, inputs)} of the Kalman smoother and DEM (auto) on one case."""
    system, dt, width = case["system"], case["dt"], case["width"]
    r = system.n_inputs
    unknown = case["unknown"]
    signal = case["drive"] if unknown else case["inputs"]
    out = {}
    kalman = KalmanEstimator(system, dt, sensor_precision=case["sensor_precision"],
                             process_precision=case["process_precision"], kernel_width=width, known_inputs=not unknown,
                             input_prior_precision=case["input_precision"] if unknown else None,
                             input_kernel_width=case["input_width"] if unknown else None)
    estimate = kalman.estimate(case["outputs"], signal)
    out["kalman"] = (estimate.states, estimate.inputs if unknown else case["inputs"])
    if dem and width > 0:
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", ModelWarning)
                observer = DEMObserver(system, dt, kernel_width=width, sensor_precision=case["sensor_precision"],
                                       process_precision=case["process_precision"],
                                       input_prior_precision=case["input_precision"] if unknown else None,
                                       known_inputs=not unknown,
                                       input_kernel_width=case["input_width"] if unknown else None)
                estimate = observer.estimate(case["outputs"], signal)
            out["dem"] = (estimate.states, estimate.inputs)
        except AttendInputError:
            pass
    _ = r
    return out


def bank_case(index: int):
    case = draw_case(index)
    unknown = not case.known
    r = case.system.n_inputs
    return dict(system=case.system, dt=case.dt, width=case.process_width, outputs=case.outputs, states=case.states,
                inputs=case.inputs, unknown=unknown, process_precision=case.process_std**-2,
                sensor_precision=case.sensor_std**-2,
                input_precision=case.input_prior_std**-2 if unknown else np.ones(r),
                input_width=case.input_width if unknown else case.process_width,
                drive=case.input_prior_mean if unknown else case.inputs, sensor_width=case.sensor_width)


def case_ratios(case, estimates):
    drive = case.get("drive")
    if drive is None:
        drive = np.zeros_like(case["inputs"]) if case["unknown"] else case["inputs"]
    found = {}
    for name, (states, inputs) in estimates.items():
        found[name] = ratios(case["system"], case["dt"], case["outputs"], states, inputs,
                             process_precision=case["process_precision"], width=case["width"],
                             unknown=case["unknown"], drive=drive, input_precision=case["input_precision"],
                             input_width=case["input_width"])
    return found


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", type=int, default=60)
    parser.add_argument("--input-prior", action="store_true", help="the input-prior check (module docstring)")
    args = parser.parse_args(argv)
    if args.input_prior:
        return input_prior_main(args.cases)
    worst, alarms, count, true_alarms, missed = [], 0, 0, 0, 0
    for family, make in (("bank", bank_case), ("mechanical", mechanical_case)):
        values = []
        for index in range(args.cases):
            case = make(index)
            if "drive" not in case:
                case["drive"] = np.zeros_like(case["inputs"]) if case["unknown"] else case["inputs"]
            try:
                estimates = run_estimators(case)
            except AttendInputError as error:  # the smoother refuses the case (not the check's business)
                print(f"  {family} #{index}: refused: {error}")
                continue
            truth = np.sqrt(np.mean(case["states"] ** 2, axis=0))
            for name, found in case_ratios(case, estimates).items():
                # wild: some state's estimate swings over 3x as much as the truth does
                wild = np.any(np.sqrt(np.mean(estimates[name][0] ** 2, axis=0)) > 3 * truth)
                top = float(np.nanmax(found, initial=0.0))
                fires = top > SPREAD_LIMIT
                values.append(top)
                alarms += fires and not wild
                true_alarms += fires and wild
                missed += wild and not fires
                count += 1
                worst.append((top, family, index, name, wild))
        values = np.array(values)
        print(f"{family:10s}: {len(values)} estimates, largest ratio per estimate: median {np.median(values):.2f}, "
              f"95 % {np.quantile(values, 0.95):.2f}, max {values.max():.2f}")
    worst.sort(reverse=True)
    calm = [v for v, *_, wild in worst if not wild]
    print(f"correct models, {count} estimates (Kalman smoother and DEM): SPREAD_LIMIT = {SPREAD_LIMIT:g}; "
          f"false alarms (fires, estimate not wild: RMS <= 3x the truth's) {alarms}, largest ratio of those "
          f"{max(calm, default=0):.2f}; true alarms (wild estimates flagged) {true_alarms}; wild, not flagged {missed}")
    print("  largest: " + ", ".join(f"{f} #{i} {n} {v:.2f}{' (wild)' if w else ''}" for v, f, i, n, w in worst[:4]))
    # mis-specified (a): outputs in degrees, model in radians
    fired = []
    for index in range(min(args.cases, 20)):
        case = bank_case(index)
        case["outputs"] = case["outputs"] * 180 / np.pi
        try:
            estimates = run_estimators(case, dem=False)
        except AttendInputError as error:
            print(f"  (a) bank #{index}: refused: {error}")
            continue
        fired.append(float(np.nanmax(case_ratios(case, estimates)["kalman"], initial=0.0)))
    fired = np.array(fired)
    print(f"mis-specified (a), outputs in degrees: fires on {np.sum(fired > SPREAD_LIMIT)} of {len(fired)}; "
          f"largest ratio median {np.median(fired):.1f}, min {fired.min():.1f}")
    # mis-specified (b): sensor std 100x too small, unknown force with a far too wide prior
    fired = []
    for index in range(1, 2 * min(args.cases, 20), 2):
        case = mechanical_case(index)
        case["sensor_precision"] = case["sensor_precision"] * 1e4
        case["input_precision"] = np.full(case["system"].n_inputs, 1e-6)
        case["drive"] = np.zeros_like(case["inputs"])
        try:
            estimates = run_estimators(case, dem=False)
        except AttendInputError:  # the smoother refuses: its predicted outputs' covariance is singular
            continue
        fired.append(float(np.nanmax(case_ratios(case, estimates)["kalman"], initial=0.0)))
    fired = np.array(fired)
    print(f"mis-specified (b), sensor std 100x too small + input prior std 1e3: fires on "
          f"{np.sum(fired > SPREAD_LIMIT)} of {len(fired)}; largest ratio median {np.median(fired):.1f}, "
          f"min {fired.min():.1f}")
    return 0


# --- the input-prior check ------------------------------------------------------------------------

def _tally(label: str, rows: list) -> None:
    """rows: (name, t (r,), limit) per estimate; prints the false warnings (t_j > limit)."""
    if not rows:
        print(f"{label}: no estimate", flush=True)
        return
    tops = np.array([float(np.max(t / limit)) for _, t, limit in rows])
    inputs = sum(len(t) for _, t, _ in rows)
    fired = [(name, t, limit) for name, t, limit in rows if np.any(t > limit)]
    print(f"{label}: {len(rows)} estimates, {inputs} unknown inputs; warned {len(fired)} "
          f"(largest t / limit {tops.max():.3f}, 95 % {np.quantile(tops, 0.95):.3f})"
          + "".join(f"\n    {name}: t {np.round(t, 3).tolist()}, limit {limit:.3f}" for name, t, limit in fired),
          flush=True)


def _limit_against_draws(draws: int = 200000) -> None:
    """(0): the share of the prior's own RMS over N samples above input_prior_limit."""
    from scipy.linalg import eigh

    rng = np.random.default_rng(1)
    worst = []
    for N in (60, 111, 300, 1000):
        for ratio in (0.25, 1.0, 2.0, 5.0, 10.0, 16.0):
            lags = np.arange(N)
            weights = np.clip(eigh(np.exp(-((lags[:, None] - lags[None, :]) ** 2) / (4 * ratio**2)),
                                   eigvals_only=True), 0, None) / N
            weights = weights[weights > 1e-12 * weights.max()]
            limit = input_prior_limit(N, 1.0, ratio)
            above = sum(int(np.sum((rng.standard_normal((20000, len(weights))) ** 2) @ weights > limit**2))
                        for _ in range(draws // 20000))
            worst.append((above / draws, N, ratio))
    rates = np.array([w[0] for w in worst])
    print(f"(0) limit against {draws} draws of the prior (N 60-1000, s_u / dt 0.25-16, 24 pairs): share above, "
          f"nominal {INPUT_PRIOR_FALSE_RATE:g}: median {np.median(rates):.2e}, max {rates.max():.2e} "
          f"(N {max(worst)[1]}, s_u / dt {max(worst)[2]:g})", flush=True)


def _unknown_inputs_cases(count: int) -> list:
    import bench_unknown_inputs as bu

    rows = []
    for index in range(count):
        if index % 4 == 3:  # the bench's misfit cases
            continue
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            case = bu.draw_case(index)
            try:
                estimate = bu.smoother(case).estimate(case.outputs, case.input_mean)
            except AttendInputError:
                continue
        est = case.input_std > 0
        t = input_prior_ratios(estimate.inputs[:, est], case.input_mean[:, est], case.input_std[est] ** -2.0)
        rows.append((case.name, t, input_prior_limit(len(case.outputs), case.dt, case.input_width)))
    return rows


def _bank_cases(seeds: int) -> tuple[list, list]:
    """(Kalman, DEM) rows on bench_bank's unknown-input cases (its seed, i < 60; seed 0, i < 40), the
    model as the log was drawn."""
    import bench_bank as bb

    kalman, dem = [], []
    for seed, count in ((bb.BANK_SEED, 60), (0, 40))[:seeds]:  # (draw_case([1, 23]) never returns)
        for index in [i for i in range(count) if i % 4 in (2, 3)]:
            case = bb.draw_case(index, seed=seed)
            n = case.system.n_states
            precision = case.input_prior_std**-2.0
            noises = dict(sensor_precision=case.sensor_std**-2, process_precision=case.process_std**-2)
            limit = input_prior_limit(len(case.outputs), case.dt, case.input_width)
            name = f"bank {seed}/{index} ({case.input_kind})"
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    estimate = KalmanEstimator(
                        case.system, case.dt, process_kernel_width=case.process_width,
                        sensor_kernel_width=case.sensor_width, known_inputs=False, input_prior_precision=precision,
                        input_kernel_width=case.input_width, initial_state=np.zeros(n),
                        initial_state_std=max(case.initial_std, 1e-9), **noises).estimate(case.outputs,
                                                                                            case.input_prior_mean)
                kalman.append((name, input_prior_ratios(estimate.inputs, case.input_prior_mean, precision), limit))
            except AttendInputError:
                continue
            if case.process_width > 0 and case.process_width == case.sensor_width:
                try:
                    with warnings.catch_warnings():
                        warnings.simplefilter("ignore")
                        estimate = DEMObserver(case.system, case.dt, kernel_width=case.process_width,
                                               known_inputs=False, input_prior_precision=precision,
                                               input_kernel_width=case.input_width, **noises
                                               ).estimate(case.outputs, case.input_prior_mean)
                    t = input_prior_ratios(estimate.inputs, case.input_prior_mean, precision)
                    if np.all(np.isfinite(t)):
                        dem.append((name, t, limit))
                except AttendInputError:
                    pass
    return kalman, dem


def _correct_file_case(index: int):
    """bench_unknown_inputs_misfit's bank case drawn with the file's own model (no perturbation, the
    stated noise stds), inputs from the prior at 1/2-4x the process width; default_rng([2903, index])."""
    import bench_unknown_inputs_misfit as bm

    rng = np.random.default_rng([2903, index])
    if index % 9 == 8:
        system, dt, N = bm.drone_like(), 0.04, 250
        process_std = np.array([0.08, 0.08, 0.1, 0.5, 0.5, 0.8, 0.2, 0.2, 0.3, 28.0, 20.0, 5.0])
        sensor_std = np.array([0.01, 0.01, 0.005, 7e-4, 7e-4, 1.5e-3])
        prior_std = np.full(4, np.exp(rng.uniform(1, 3)))
    else:
        if index % 6 == 5:
            system = bm.integrator_chain(2 + (index // 6) % 2, damping=0.2)
        else:
            n = int(rng.integers(2, 6))
            m = int(rng.integers(1, min(n, 3) + 1))
            system = bm.random_stable_system(rng, n, m, int(rng.integers(1, m + 1)))
        dt, N = 0.1, int(rng.integers(150, 401))
        process_std = 0.1 * 10 ** rng.uniform(-1, 1, size=system.n_states)
        sensor_std = 0.05 * 10 ** rng.uniform(-1, 1, size=system.n_outputs)
        prior_std = np.exp(rng.uniform(0, 3, size=system.n_inputs))
    s = bm.KERNEL_RATIOS[index % 3] * dt
    eta = rng.normal(size=system.n_inputs) * prior_std * 0.3
    u = bm.gp_inputs(rng, N, dt, s * float(rng.choice([0.5, 1.0, 2.0, 4.0])), eta, prior_std)
    log = bm.simulate(system, u, dt, kernel_width=s, process_std=process_std, measurement_std=sensor_std,
                      initial_state=rng.normal(size=system.n_states) * 0.5, seed=rng)
    start = dict(initial_state=np.zeros(system.n_states), initial_state_std=1.0) if index % 2 else {}
    return bm.Case(f"{'drone' if index % 9 == 8 else 'chain' if index % 6 == 5 else 'random'}{index}", system, dt, s,
                   1 / process_std**2, 1 / sensor_std**2, eta, 1 / prior_std**2, log.outputs, log.states, u, **start)


def _default_rows(cases) -> list:
    """Rows of `attend estimate`'s default (width and lambda* from the log) on misfit-bench cases."""
    import tempfile

    import bench_unknown_inputs_misfit as bm

    from attend import io

    rows = []
    with tempfile.TemporaryDirectory() as folder:
        for case in cases:
            model_path, log_path = bm.write_files(case, Path(folder))
            model = io.read_model(model_path)
            log = io.read_log(log_path, model.time_column)
            estimator, estimate, _ = bm.run_file(model, log)
            if estimate is None:
                continue
            choice = estimator.input_width_choice
            scale = choice.noise_scale if choice is not None else 1.0
            width = choice.width if choice is not None else estimator.input_kernel_width
            mean = np.tile(case.prior_mean, (len(estimate.inputs), 1))
            rows.append((f"{case.name} (lambda* {scale:.3g})",
                         input_prior_ratios(estimate.inputs, mean, case.prior_precision, scale),
                         input_prior_limit(len(estimate.inputs), case.dt, width)))
    return rows


def input_prior_main(cases: int) -> int:
    import bench_unknown_inputs_misfit as bm

    _limit_against_draws()
    _tally("(1) bench_unknown_inputs model-right cases, Kalman smoother", _unknown_inputs_cases(400))
    kalman, dem = _bank_cases(2)
    for label, rows in (("Kalman smoother", kalman), ("DEM", dem)):
        for kind, what in (("unknown-gp", "GP inputs from the prior"), ("unknown-pulses", "pulses (not the prior)")):
            _tally(f"(2) bench_bank {what}, {label}", [row for row in rows if kind in row[0]])
    _tally("(3) misfit bank with the file's model as the truth, attend estimate's default",
           _default_rows([_correct_file_case(i) for i in range(cases)]))
    misfit = [bm.bank_case(i) for i in range(36)]
    if (bm.DATA / f"{bm.FLIGHTS[0]}.csv").is_file():
        misfit += [bm.flight_case(f, full) for full in (False, True) for f in bm.FLIGHTS]
    _tally("bench_unknown_inputs_misfit's cases (models that do not fit), attend estimate's default",
           _default_rows(misfit))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
