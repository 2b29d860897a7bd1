"""attend's DEM against SPM's spm_DEM on the same data (issue 15: agree within 5 % SSE).

    PYTHONPATH=src python benchmarks/bench_spm.py [--decompose] [--sweep 20]   # against the stored SPM outputs
    PYTHONPATH=src python benchmarks/bench_spm.py --export        # rewrite the data SPM is run on

Two cases, 5 seeds each, data simulated by attend and stored in benchmarks/spm/reference/:
- lorenz: the Lorenz reproduction's settings (attend.experiments.lorenz: dt = 0.01 s, s = 0.02 s
  = 2 bins, sigma_w = 20, sigma_z = 1, p = 6), 400 samples; lorenz_seed<k>_data.csv holds
  y1..y3 then the true x1..x3; attend's NonlinearDEM against spm_DEM (run_lorenz.m).
- convolution: SPM's own linear convolution model (attend.models.problems.convolution_model, one bin =
  dt = 1 s, s = 0.5, Pi_z = Pi_w = exp(8), P_v = exp(-8), p = d = 6), 64 samples, input a
  Gaussian bump at t = 12; convolution_seed<k>_data.csv holds y1..y4, x1, x2, u; attend's linear
  DEMObserver against spm_DEM (run_convolution.m).
spm_DEM runs only its D-step (fixed parameters and precisions); its estimates are stored as
<case>_seed<k>_spm.csv and its run time as <case>_seed<k>_spm.csv.json (README there: how, with
which SPM and Octave). This script needs no Octave: it runs attend on the stored data and prints,
per seed, the SSE of SPM and attend against the truth, their ratio (target: within 5 %) and the
SSE between the two estimates, for attend's own integration and for integration="spm" (spm_DEM's
D-step, which matches SPM to rounding), over samples p + 2 .. N - p - 1 (1-based; the reproductions' trim).
``--decompose`` attributes the differences to SPM's integration conventions with
:func:`spm_style_flow`, a Python re-derivation of spm_DEM's D-step; ``--sweep N`` compares the
two integrations on N fresh seeds per case with it. Conventions: docs/spm.md.
"""

from __future__ import annotations

import argparse
import json
import time
import warnings
from pathlib import Path

import numpy as np
from scipy.linalg import expm

from attend.experiments import lorenz
from attend.models.generalized import embed, shift_operator, smoothness_precision
from attend.perception.dem import DEMObserver
from attend.perception.nonlinear import NonlinearDEM
from attend.models import NonlinearSystem, simulate_nonlinear
from attend.models.problems import convolution_model
from attend.models.linear import simulate

REFERENCE = Path(__file__).resolve().parent / "spm" / "reference"
SEEDS = range(5)
EMBEDDING_ORDER = 6
LORENZ_SAMPLES = 400
CONVOLUTION = dict(dt=1.0, samples=64, kernel_width=0.5, log_precision=8.0, prior_log_precision=-8.0)


def convolution_input(time_points: np.ndarray) -> np.ndarray:
    """u(t) = exp(-(t - 12)^2 / 4): the Gaussian bump of SPM's convolution demo, (N, 1)."""
    return np.exp(-0.25 * (time_points - 12.0) ** 2)[:, None]


def simulated_data(case: str, seed: int) -> np.ndarray:
    """One data set of ``case`` ("lorenz" or "convolution") as stored: outputs, true states (and
    the true input), one row per sample."""
    if case == "lorenz":
        cfg = lorenz.SETTINGS
        log = simulate_nonlinear(lorenz.build_system(cfg), LORENZ_SAMPLES, cfg["dt"], kernel_width=cfg["kernel_width"],
                                 process_std=cfg["process_std"], measurement_std=cfg["measurement_std"],
                                 initial_state=cfg["initial_state"], seed=seed)
        return np.hstack([log.outputs, log.states])
    c = CONVOLUTION
    u = convolution_input(np.arange(c["samples"]) * c["dt"])
    std = np.exp(-c["log_precision"] / 2)
    log = simulate(convolution_model(), u, c["dt"], kernel_width=c["kernel_width"], process_std=std,
                   measurement_std=std, seed=seed)
    return np.hstack([log.outputs, log.states, log.inputs])


def export() -> None:
    """Write <case>_seed<k>_data.csv for both cases (columns: outputs, true states, true input)."""
    REFERENCE.mkdir(parents=True, exist_ok=True)
    for case in ("lorenz", "convolution"):
        for seed in SEEDS:
            np.savetxt(REFERENCE / f"{case}_seed{seed}_data.csv", simulated_data(case, seed), delimiter=",", fmt="%.17g")
    print(f"wrote {2 * len(SEEDS)} data files to {REFERENCE}")


def lorenz_estimator(integration: str = "attend") -> NonlinearDEM:
    """attend's NonlinearDEM on SPM's conventions (docs/spm.md): s/dt = 2 bins, p = 6, the true
    precisions, the flow in sample units with one D-step per bin, repeated end samples;
    integration: "attend" (data held, row k after the step) or "spm" (spm_DEM's D-step)."""
    cfg = lorenz.SETTINGS
    return NonlinearDEM(lorenz.build_system(cfg), cfg["dt"], kernel_width=cfg["kernel_width"],
                        sensor_precision=1.0 / cfg["measurement_std"] ** 2,
                        process_precision=1.0 / cfg["process_std"] ** 2, embedding_order=EMBEDDING_ORDER,
                        flow_time="samples", substeps=1, motion="linearized", edges="clamp", integration=integration)


def convolution_estimator(integration: str = "attend") -> DEMObserver:
    """attend's linear DEMObserver on SPM's convolution settings (p = d = 6, start at x = 0);
    integration: "attend" or "spm" as in :func:`lorenz_estimator`."""
    c = CONVOLUTION
    return DEMObserver(convolution_model(), c["dt"], kernel_width=c["kernel_width"],
                       sensor_precision=np.exp(c["log_precision"]), process_precision=np.exp(c["log_precision"]),
                       input_prior_precision=np.exp(c["prior_log_precision"]), embedding_order=EMBEDDING_ORDER,
                       input_order=EMBEDDING_ORDER, edges="clamp", initial_state=np.zeros(2), allow_unstable=True,
                       integration=integration)


def spm_style_flow(system: NonlinearSystem, outputs, dt: float, kernel_width: float, sensor_precision: float,
                   process_precision: float, start, embedding_order: int = EMBEDDING_ORDER,
                   input_prior_precision: float = 0.0, input_order: int | None = None, *, move_data: bool = True,
                   top_error_zero: bool = True, report_before_step: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """spm_DEM's D-step re-derived in Python: a diagnostic that reproduces the stored SPM outputs,
    each flag switching one SPM convention to attend's. Returns the order-0 estimates of the
    states (N, n) and of the unknown inputs (N, r) (input prior mean 0).

    system: f, g (attend's units); outputs: (N, m); dt: sample time [s]; kernel_width: s [s];
    sensor_precision, process_precision, input_prior_precision: Pi_z, Pi_w, P_v (scalars times I);
    start: order-0 states of the first bin (SPM's M(1).x); embedding_order: E.n; input_order:
    E.d <= E.n (default E.n): v has E.d + 1 orders, the higher ones pinned at 0 in the errors.
    Units are SPM's bins: x^(i) per bin^i, f_bin = dt f, Pi_w,bin = Pi_w / dt^2, s_bin = s / dt.
    Per bin k, with u = [x~; v~] and y~ the clamped embedding of y at k:
    e_y^(i) = y^(i) - g^(i), e_v^(i) = v^(i), e_x^(i) = x^(i+1) - f^(i) (order 0: g(x, v), f(x, v);
    order i: gx x^(i) + gv v^(i), fx x^(i) + fv v^(i)), the top order's e_x set to 0
    (``top_error_zero``, SPM; attend keeps -f^(p)); precisions kron(S(s_bin), Pi).
    ``move_data`` (SPM): the data ride along the flow, d/dt [u; y~] = [D u + dF/du; D y~], the
    pair integrated over one bin by the exponential of its Jacobian [[D - E'Pi E, -E'Pi dE/dy~],
    [0, D]]; attend holds y~ at the bin's value (d/dt u = D u + dF/du only).
    ``report_before_step`` (SPM stores qU(k) before the update at bin k): row k is the state
    reached from bin k - 1; attend reports the state after the update with bin k's data.
    """
    n, r, m, orders = system.n_states, system.n_inputs, system.n_outputs, embedding_order + 1
    v_orders = orders if input_order is None else min(input_order, embedding_order) + 1
    S = smoothness_precision(orders, kernel_width / dt)
    blocks = [np.kron(S, sensor_precision * np.eye(m)), np.kron(S, input_prior_precision * np.eye(r)),
              np.kron(S, process_precision / dt**2 * np.eye(n))]
    size = orders * (m + r + n)
    Pi = np.zeros((size, size))
    offset = 0
    for block in blocks:
        Pi[offset: offset + len(block), offset: offset + len(block)] = block
        offset += len(block)
    I = np.eye(orders)
    D_u = np.zeros((orders * n + v_orders * r,) * 2)
    D_u[: orders * n, : orders * n] = shift_operator(orders, n)
    D_u[orders * n:, orders * n:] = shift_operator(v_orders, r)
    I_v = np.eye(orders, v_orders)
    Dy = shift_operator(orders, m)
    embedded = embed(np.asarray(outputs, float), orders, 1.0, edges="clamp")
    dE_dy = np.zeros((size, orders * m))
    dE_dy[: orders * m] = np.eye(orders * m)
    u = np.zeros(orders * n + v_orders * r)
    u[:n] = start
    states, inputs = [], []
    for y_tilde in embedded:
        x, v = u[: orders * n].reshape(orders, n), np.zeros((orders, r))
        v[:v_orders] = u[orders * n:].reshape(v_orders, r)
        fx, fv, gx, gv = system.jacobians(x[0], v[0])
        fx, fv = dt * fx, dt * fv
        f_tilde, g_tilde = x @ fx.T + v @ fv.T, x @ gx.T + v @ gv.T
        f_tilde[0], g_tilde[0] = dt * system.flow(x[0], v[0]), system.observe(x[0], v[0])
        e_x = np.vstack([x[1:], np.zeros((1, n))]) - f_tilde
        if top_error_zero:
            e_x[-1] = 0.0
        error = np.concatenate([y_tilde - g_tilde.ravel(), v.ravel(), e_x.ravel()])
        dE_du = np.block([[-np.kron(I, gx), -np.kron(I_v, gv)],
                          [np.zeros((orders * r, orders * n)), np.kron(I_v, np.eye(r))],
                          [shift_operator(orders, n) - np.kron(I, fx), -np.kron(I_v, fv)]])
        gradient = -dE_du.T @ Pi @ error
        jacobian = -dE_du.T @ Pi @ dE_du + D_u
        if report_before_step:
            states.append(x[0].copy())
            inputs.append(v[0].copy())
        flow = gradient + D_u @ u
        if move_data:
            flow = np.concatenate([flow, Dy @ y_tilde])
            jacobian = np.block([[jacobian, -dE_du.T @ Pi @ dE_dy], [np.zeros((orders * m, len(u))), Dy]])
        augmented = np.zeros((len(flow) + 1,) * 2)
        augmented[1:, 0], augmented[1:, 1:] = flow, jacobian
        u = u + expm(augmented)[1:, 0][: len(u)]
        if not report_before_step:
            states.append(u[:n].copy())
            inputs.append(u[orders * n: orders * n + r].copy())
    return np.array(states), np.array(inputs).reshape(len(states), r)


def sse(estimate: np.ndarray, truth: np.ndarray) -> float:
    """Sum of squared errors over samples p + 2 .. N - p - 1 (1-based)."""
    trim = slice(EMBEDDING_ORDER + 1, len(truth) - EMBEDDING_ORDER - 1)
    return float(np.sum((np.asarray(estimate) - np.asarray(truth))[trim] ** 2))


def _load(case: str, seed: int):
    """(data, spm, meta) of one stored run, or None when SPM's output is missing."""
    spm_path = REFERENCE / f"{case}_seed{seed}_spm.csv"
    if not spm_path.exists():
        return None
    data = np.loadtxt(REFERENCE / f"{case}_seed{seed}_data.csv", delimiter=",")
    meta = json.loads((REFERENCE / f"{case}_seed{seed}_spm.csv.json").read_text())
    return data, np.loadtxt(spm_path, delimiter=","), meta


def _run_attend(case: str, data: np.ndarray, integration: str = "attend"):
    """attend's estimates (states, inputs or None) and its CPU seconds on one stored data set;
    integration: "attend" (attend's default) or "spm" (spm_DEM's D-step)."""
    start = time.process_time()
    if case == "lorenz":
        states, inputs = lorenz_estimator(integration).estimate(data[:, :3], initial_state=data[0, :3]).states, None
    else:
        with warnings.catch_warnings():  # p = d = 6 is outside attend's stable orders here (ModelWarning)
            warnings.simplefilter("ignore")
            estimate = convolution_estimator(integration).estimate(data[:, :4])
        states, inputs = estimate.states, estimate.inputs
    return states, inputs, time.process_time() - start


def compare(case: str, integration: str = "attend") -> list[float]:
    """Print, per seed, SPM's and attend's SSE against the truth, their ratio and the SSE between
    them (states, and the input for the convolution model); return the ratios. integration:
    attend's "attend" (default) or "spm" (spm_DEM's D-step, docs/spm.md)."""
    columns = {"lorenz": (slice(0, 3), slice(3, 6), None), "convolution": (slice(0, 4), slice(4, 6), slice(6, 7))}
    _, x_cols, u_cols = columns[case]
    width = x_cols.stop - x_cols.start
    print(f"\n== {case}, attend integration={integration!r}: SSE against the truth (samples p + 2 .. N - p - 1)")
    header = f"{'seed':>4} {'spm_DEM x':>10} {'attend x':>10} {'ratio':>7} {'SSE(att-SPM)':>12}"
    if u_cols:
        header += f" {'spm_DEM u':>10} {'attend u':>10} {'ratio':>7} {'SSE(att-SPM)':>12}"
    print(header)
    ratios, spm_rate, attend_rate = [], [], []
    digits = 4 if integration == "attend" else 8
    for seed in SEEDS:
        loaded = _load(case, seed)
        if loaded is None:
            print(f"{seed:4d} no SPM output: run benchmarks/spm/run_all.sh")
            continue
        data, spm, meta = loaded
        states, inputs, seconds = _run_attend(case, data, integration)
        spm_rate.append(meta["samples_per_second"])
        attend_rate.append(len(data) / seconds)
        truth, spm_x = data[:, x_cols], spm[:, :width]
        row = f"{seed:4d} {sse(spm_x, truth):10.4g} {sse(states, truth):10.4g} "
        ratios.append(sse(states, truth) / sse(spm_x, truth))
        row += f"{ratios[-1]:7.{digits}f} {sse(states, spm_x):12.4g}"
        if u_cols:
            spm_u, true_u = spm[:, width:], data[:, u_cols]
            ratios.append(sse(inputs, true_u) / sse(spm_u, true_u))
            row += f" {sse(spm_u, true_u):10.4g} {sse(inputs, true_u):10.4g} {ratios[-1]:7.{digits}f} " \
                   f"{sse(inputs, spm_u):12.4g}"
        print(row)
    if ratios:
        worst = max(abs(r - 1) for r in ratios)
        print(f"median attend/SPM SSE ratio {np.median(ratios):.{digits}f}, worst |ratio - 1| = {worst:.2g}: "
              f"{'within' if worst <= 0.05 else 'NOT within'} 5 %")
        print(f"speed (samples per CPU second, median): spm_DEM in Octave {np.median(spm_rate):.1f}, "
              f"attend {np.median(attend_rate):.0f} ({np.median(attend_rate) / np.median(spm_rate):.0f}x)")
    return ratios


VARIANTS = {
    "SPM's conventions": dict(),
    "top e_x kept (attend)": dict(top_error_zero=False),
    "data held (attend)": dict(move_data=False),
    "reported after step (attend)": dict(report_before_step=False),
    "all three attend's": dict(move_data=False, top_error_zero=False, report_before_step=False),
}


def convolution_as_nonlinear() -> NonlinearSystem:
    """The convolution model as a NonlinearSystem (f = A x + B v, g = C x) for spm_style_flow."""
    linear = convolution_model()
    A, B, C = (np.asarray(matrix, float) for matrix in (linear.A, linear.B, linear.C))
    return NonlinearSystem(lambda x, v: A @ x + B @ v, lambda x, v: C @ x, 2, 1, 4,
                           jacobian_f=lambda x, v: (A, B), jacobian_g=lambda x, v: (C, np.zeros((4, 1))))


def _flow_settings(case: str, data: np.ndarray):
    """(system, outputs, positional arguments of spm_style_flow after outputs) of a stored case."""
    if case == "lorenz":
        cfg = lorenz.SETTINGS
        return lorenz.build_system(cfg), data[:, :3], (cfg["dt"], cfg["kernel_width"], 1.0 / cfg["measurement_std"] ** 2,
                                                       1.0 / cfg["process_std"] ** 2, data[0, :3])
    c = CONVOLUTION
    return convolution_as_nonlinear(), data[:, :4], (c["dt"], c["kernel_width"], np.exp(c["log_precision"]),
                                                     np.exp(c["log_precision"]), np.zeros(2), EMBEDDING_ORDER,
                                                     np.exp(c["prior_log_precision"]))


def decompose() -> None:
    """Where attend and SPM differ: spm_style_flow with SPM's conventions, and with each switched
    to attend's; state (and input) SSE of each against the truth, the stored SPM output and attend."""
    print("\n== decomposition (spm_style_flow: Python re-derivation of spm_DEM's D-step; x: states, u: input)")
    print(f"{'case':>11} {'seed':>4} {'variant':30s} {'x SSE':>8} {'x vs SPM':>9} {'x vs attend':>11} "
          f"{'u SSE':>8} {'u vs SPM':>9} {'u vs attend':>11}")
    for case in ("lorenz", "convolution"):
        for seed in SEEDS:
            loaded = _load(case, seed)
            if loaded is None:
                continue
            data, spm, _ = loaded
            system, outputs, arguments = _flow_settings(case, data)
            n = system.n_states
            truth_x, truth_u = data[:, system.n_outputs: system.n_outputs + n], data[:, system.n_outputs + n:]
            ours_x, ours_u, _ = _run_attend(case, data)
            for label, flags in VARIANTS.items():
                flow_x, flow_u = spm_style_flow(system, outputs, *arguments, **flags)
                row = f"{case:>11} {seed:4d} {label:30s} {sse(flow_x, truth_x):8.4g} {sse(flow_x, spm[:, :n]):9.2g} " \
                      f"{sse(flow_x, ours_x):11.2g}"
                if system.n_inputs:
                    row += f" {sse(flow_u, truth_u):8.4g} {sse(flow_u, spm[:, n:]):9.2g} {sse(flow_u, ours_u):11.2g}"
                print(row)


def check_input_order() -> None:
    """SPM with E.d = 2 < E.n = 6 and a strong input prior (P_v = 1; convolution seed 0, stored as
    convolution_d2_seed0_spm.csv): spm_style_flow reproduces it, and with attend's conventions it
    reproduces attend's DEMObserver with precision_convention="max" (not "size")."""
    spm_path = REFERENCE / "convolution_d2_seed0_spm.csv"
    if not spm_path.exists():
        return
    spm = np.loadtxt(spm_path, delimiter=",")
    data = np.loadtxt(REFERENCE / "convolution_seed0_data.csv", delimiter=",")
    c, outputs = CONVOLUTION, data[:, :4]
    arguments = (c["dt"], c["kernel_width"], np.exp(c["log_precision"]), np.exp(c["log_precision"]), np.zeros(2),
                 EMBEDDING_ORDER, 1.0)
    system = convolution_as_nonlinear()
    flow_x, flow_u = spm_style_flow(system, outputs, *arguments, input_order=2)
    print("\n== E.d = 2 < E.n = 6, P_v = 1 (convolution seed 0; SSE over all samples)")
    print(f"spm_style_flow (SPM's conventions) vs spm_DEM: x {np.sum((flow_x - spm[:, :2]) ** 2):.2g}, "
          f"u {np.sum((flow_u - spm[:, 2:]) ** 2):.2g}")
    flow_x, flow_u = spm_style_flow(system, outputs, *arguments, input_order=2, move_data=False,
                                    top_error_zero=False, report_before_step=False)
    for convention in ("max", "size"):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            estimate = DEMObserver(convolution_model(), c["dt"], kernel_width=c["kernel_width"],
                                   sensor_precision=np.exp(c["log_precision"]),
                                   process_precision=np.exp(c["log_precision"]), input_prior_precision=1.0,
                                   embedding_order=EMBEDDING_ORDER, input_order=2, edges="clamp",
                                   initial_state=np.zeros(2), allow_unstable=True,
                                   precision_convention=convention).estimate(outputs)
        print(f"spm_style_flow (attend's conventions) vs DEMObserver(precision_convention={convention!r}): "
              f"x {np.sum((flow_x - estimate.states) ** 2):.2g}, u {np.sum((flow_u - estimate.inputs) ** 2):.2g}")


def sweep(seeds: int) -> None:
    """Which integration is more accurate, on ``seeds`` fresh data sets per case (no Octave:
    spm_style_flow with SPM's conventions stands for spm_DEM, which it reproduces): the median
    and range of attend's SSE over SPM's, states and input."""
    print(f"\n== {seeds} seeds per case: attend SSE / SPM-convention SSE (spm_style_flow)")
    for case in ("lorenz", "convolution"):
        state_ratio, input_ratio = [], []
        for seed in range(seeds):
            data = simulated_data(case, seed)
            system, outputs, arguments = _flow_settings(case, data)
            n, m = system.n_states, system.n_outputs
            spm_x, spm_u = spm_style_flow(system, outputs, *arguments)
            ours_x, ours_u, _ = _run_attend(case, data)
            state_ratio.append(sse(ours_x, data[:, m: m + n]) / sse(spm_x, data[:, m: m + n]))
            if system.n_inputs:
                input_ratio.append(sse(ours_u, data[:, m + n:]) / sse(spm_u, data[:, m + n:]))
        for label, ratios in (("states", state_ratio), ("input", input_ratio)):
            if ratios:
                print(f"{case:>11} {label:6s} median {np.median(ratios):.3f}  range {min(ratios):.3f}-{max(ratios):.3f}  "
                      f"attend better on {sum(r < 1 for r in ratios)} of {len(ratios)}")


def main() -> None:
    """Command line: --export rewrites the data; otherwise compare with the stored SPM outputs."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--export", action="store_true", help="write the simulated data SPM is run on")
    parser.add_argument("--decompose", action="store_true",
                        help="also attribute the differences to SPM's conventions (spm_style_flow)")
    parser.add_argument("--sweep", type=int, default=0, metavar="SEEDS",
                        help="also compare the two integrations on this many fresh seeds (no Octave needed)")
    args = parser.parse_args()
    if args.export:
        export()
        return
    for case in ("lorenz", "convolution"):
        for integration in ("attend", "spm"):
            compare(case, integration)
    if args.decompose:
        decompose()
        check_input_order()
    if args.sweep:
        sweep(args.sweep)


if __name__ == "__main__":
    main()
