"""Shared runner of the nonlinear reproductions (lorenz, pendulum): one simulated log per seed,
DEM and the baselines on it, SSE per method, a figure of seed 0 and the SSE spread."""

from __future__ import annotations

import importlib
import time as clock
import warnings
from pathlib import Path

import numpy as np
from tqdm import tqdm

from attend.experiments._result import Claim, ExperimentResult
from attend.models.linear import ModelWarning
from attend.models.nonlinear import simulate_nonlinear
from attend.perception.nonlinear import NonlinearDEM
from attend.perception.nonlinear_smoothers import (
    coloured_unscented_smoother,
    extended_kalman,
    input_random_walk_variance,
    particle_smoother,
    unscented_kalman,
    white_noise_covariances,
)

METHODS = ("DEM", "DEM path", "EKF", "UKF", "UKF filter", "UKF lag", "coloured UKS", "particle")
#: the two DEM estimators: the D-step (sample mode, a filter) and path mode (a smoother)
DEM_MODES = ("DEM", "DEM path")
#: the UKF smoother's std: its white-noise model's covariance, and its error spread under the coloured noise
UKF_WHITE_STD, UKF_SPREAD = "UKF (white-noise std)", "UKF (error spread)"


def _setup(name: str, cfg: dict):
    """The system, the input series (or sample count) and the estimators' settings of ``name``."""
    module = importlib.import_module(f"attend.experiments.{name}")
    system = module.build_system(cfg)
    dt = cfg["dt"]
    n_samples = int(round(cfg["duration"] / dt))
    time = np.arange(n_samples) * dt
    u = module.true_input(time) if system.n_inputs else n_samples
    return system, u, time, n_samples


def _one_seed(name: str, cfg: dict, seed: int) -> dict:
    """Simulate seed ``seed`` and run every method: SSEs, runtimes, DEM coverage (and the log of
    seed 0 with all estimates, for the figure)."""
    system, u, time, n_samples = _setup(name, cfg)
    dt, s = cfg["dt"], cfg["kernel_width"]
    sw, sz = np.asarray(cfg["process_std"], float), np.asarray(cfg["measurement_std"], float)
    unknown = system.n_inputs > 0
    p = cfg["embedding_order"]
    trim = slice(p + 1, n_samples - p - 1)
    methods = tuple(cfg.get("methods", METHODS))
    input_width = cfg.get("input_kernel_width") or s  # the input prior's smoothness s_v (default: the noise's)
    dem = _dem(system, cfg)
    kalman = kalman_options(system, cfg)
    log = simulate_nonlinear(system, u, dt, kernel_width=s, process_std=sw, measurement_std=sz,
                             initial_state=cfg["initial_state"], seed=seed)
    estimates, runtime = {}, {}
    start = clock.perf_counter()
    estimates["DEM"] = dem.estimate(log.outputs)
    runtime["DEM"] = clock.perf_counter() - start
    if "DEM path" in methods:
        path = _dem(system, cfg, states="path")
        start = clock.perf_counter()
        estimates["DEM path"] = path.estimate(log.outputs)
        runtime["DEM path"] = clock.perf_counter() - start
    for method, function, smooth in (("EKF", extended_kalman, True), ("UKF", unscented_kalman, True),
                                     ("UKF filter", unscented_kalman, False), ("UKF lag", unscented_kalman, dem.delay)):
        if method in methods:
            start = clock.perf_counter()
            estimates[method] = function(system, dt, log.outputs, smooth=smooth, **kalman)
            runtime[method] = clock.perf_counter() - start
    coloured = dict(kernel_width=s, process_std=sw, measurement_std=sz,
                    input_prior_std=np.exp(-cfg["input_prior_log_precision"] / 2) if unknown else None,
                    initial_mean=cfg["initial_state"], initial_std=cfg["initial_std"], ar_order=cfg["ar_order"],
                    input_kernel_width=input_width if unknown else None)
    if "coloured UKS" in methods:
        start = clock.perf_counter()
        estimates["coloured UKS"] = coloured_unscented_smoother(system, dt, log.outputs, **coloured)
        runtime["coloured UKS"] = clock.perf_counter() - start
    if "particle" in methods:
        start = clock.perf_counter()
        estimates["particle"] = particle_smoother(system, dt, log.outputs, n_particles=cfg["particles"],
                                                  lag=cfg["particle_lag"], seed=seed, **coloured)
        runtime["particle"] = clock.perf_counter() - start
    out = dict(runtime=runtime, state_sse={}, input_sse={}, outputs=log.outputs, dem_states=estimates["DEM"].states)
    for method, estimate in estimates.items():
        out["state_sse"][method] = np.sum((estimate.states - log.states)[trim] ** 2)
        out["input_sse"][method] = np.sum((estimate.inputs - log.inputs)[trim] ** 2) if unknown else 0.0
    stds = {method: estimates[method] for method in DEM_MODES if method in estimates}
    if "UKF" in estimates:  # its own (white-noise) std, and its error spread under the coloured noise
        stds[UKF_WHITE_STD] = estimates["UKF"]
        stds[UKF_SPREAD] = unscented_kalman(system, dt, log.outputs, noise_kernel_width=s, seed=seed, input_prior=(
            1.0 / np.exp(cfg["input_prior_log_precision"]), input_width) if unknown else None, **kalman)
    out["coverage"] = {method: np.mean(np.abs(estimate.states - log.states)[trim] < 2 * estimate.state_std[trim])
                       for method, estimate in stds.items()}
    if seed == 0:
        out["example"] = dict(time=time, states=log.states, outputs=log.outputs, inputs=log.inputs,
                              **{f"{m}_states": e.states for m, e in estimates.items()},
                              **({f"{m}_inputs": e.inputs for m, e in estimates.items()} if unknown else {}))
    return out


def compare(name: str, cfg: dict, progress: bool) -> ExperimentResult:
    """Run DEM, EKF/UKF (input-augmented when the inputs are unknown), the coloured UKS and the
    particle smoother on ``cfg['seeds']`` simulated logs of experiment ``name`` (a module with
    build_system(cfg) and true_input(time)); SSE over samples p + 2 .. N - p - 2 (1-based).

    The estimators run their small matrices with one BLAS thread by themselves
    (:mod:`attend._threads`): no environment variable is needed.
    """
    seeds = range(cfg["seeds"])
    outs = [_one_seed(name, cfg, seed) for seed in tqdm(seeds, desc=f"{name} seeds", disable=not progress)]
    methods = tuple(cfg.get("methods", METHODS))
    state_sse = {m: np.array([o["state_sse"][m] for o in outs]) for m in methods}
    input_sse = {m: np.array([o["input_sse"][m] for o in outs]) for m in methods}
    runtime = {m: sum(o["runtime"][m] for o in outs) for m in methods}
    coverage = {m: [o["coverage"][m] for o in outs] for m in outs[0]["coverage"]}
    example = outs[0].get("example")
    system, _, _, n_samples = _setup(name, cfg)
    unknown = system.n_inputs > 0
    result = ExperimentResult(name, settings=cfg)
    for method in methods:
        result.add(f"{method} state SSE (median)", np.median(state_sse[method]), "state unit^2")
    if unknown:
        for method in methods:
            label = method if method in DEM_MODES + ("particle", "coloured UKS") else f"augmented {method}"
            result.add(f"{label} input SSE (median)", np.median(input_sse[method]), "input unit^2")
    for dem in (m for m in DEM_MODES if m in methods):
        for other in ("particle", "coloured UKS", "UKF", "UKF filter", "UKF lag"):
            if other in methods:
                result.add(f"{dem} / {other} state SSE (median ratio)",
                           np.median(state_sse[dem] / state_sse[other]), "1")
        if unknown and "UKF" in methods:
            result.add(f"{dem} / augmented UKF input SSE (median ratio)",
                       np.median(input_sse[dem] / input_sse["UKF"]), "1")
        result.add(f"{dem} |error| < 2 std (fraction of samples)", np.mean(coverage[dem]), "1")
    for label in (UKF_WHITE_STD, UKF_SPREAD):
        if label in coverage:
            result.add(f"{label} |error| < 2 std (fraction of samples)", np.mean(coverage[label]), "1")
    total = cfg["seeds"] * n_samples
    for method in methods:
        result.add(f"{method} speed", total / max(runtime[method], 1e-9), "samples/s")
    if "DEM" in methods:
        for metric, (value, unit) in _jax_speed(name, cfg, outs).items():
            result.add(metric, value, unit)
    # what the figure needs, kept in the JSON (the figure re-plots from it)
    result.tables = dict(state_sse={m: state_sse[m] for m in methods}, input_sse={m: input_sse[m] for m in methods},
                         example=example)
    result.notes.append("EKF/UKF assume white noise with the per-sample variance of the coloured noise (smoothers "
                        "unless 'filter'; 'lag': fixed-lag smoother with DEM's delay); the coloured UKS and the particle smoother model the coloured noise by "
                        "AR(%d) processes." % cfg["ar_order"])
    result.notes.append("UKF |error| < 2 std: with its white-noise model's own std, and with its error spread under "
                        "the coloured noise (noise_kernel_width; attend estimate's nonlinear default reports the latter).")
    return result


def _dem(system, cfg: dict, **options) -> NonlinearDEM:
    """The D-step of the reproduction's settings ``cfg`` for ``system`` (options: e.g. backend)."""
    unknown = system.n_inputs > 0
    prior_precision = np.exp(cfg["input_prior_log_precision"])
    return NonlinearDEM(system, cfg["dt"], kernel_width=cfg["kernel_width"],
                        sensor_precision=1.0 / np.asarray(cfg["measurement_std"], float)**2,
                        process_precision=1.0 / np.asarray(cfg["process_std"], float)**2,
                        input_prior_precision=prior_precision if unknown else None,
                        embedding_order=cfg["embedding_order"], input_order=cfg["input_order"],
                        input_kernel_width=(cfg.get("input_kernel_width") or cfg["kernel_width"]) if unknown else None,
                        **options)


def kalman_options(system, cfg: dict) -> dict:
    """The white-noise Kalman baselines' keywords for the reproduction's settings ``cfg``: Q, R of
    the noise integrated over a sample (white_noise_covariances), the prior on x[0], and for unknown
    inputs the random walk whose one-sample steps have the input prior's variance (the same prior
    information; a settings key input_random_walk_variance overrides it)."""
    dt, s = cfg["dt"], cfg["kernel_width"]
    Q, R = white_noise_covariances(system, dt, kernel_width=s, process_std=np.asarray(cfg["process_std"], float),
                                   measurement_std=np.asarray(cfg["measurement_std"], float))
    options = dict(process_covariance=Q, measurement_covariance=R, initial_mean=cfg["initial_state"],
                   initial_covariance=np.asarray(cfg["initial_std"], float) ** 2)
    if system.n_inputs:
        width = cfg.get("input_kernel_width") or s
        options["input_variance"] = cfg.get("input_random_walk_variance") or float(
            input_random_walk_variance(np.exp(cfg["input_prior_log_precision"]), kernel_width=width, dt=dt))
    return options


def _jax_speed(name: str, cfg: dict, outs: list) -> dict:
    """The D-step compiled with JAX (backend="jax", f and g in jax.numpy) on every seed's log:
    samples/s once compiled, the first call [s], and its largest difference from the NumPy D-step
    (relative to the states' scale); {} without JAX. outs: _one_seed's results (logs, D-step states)."""
    try:
        import jax  # noqa: F401
    except ImportError:
        return {}
    module = importlib.import_module(f"attend.experiments.{name}")
    compiled = _dem(module.build_jax_system(cfg), cfg, backend="jax")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ModelWarning)  # the NumPy run's warnings are reported there
        start = clock.perf_counter()
        compiled.estimate(outs[0]["outputs"])
        first_call = clock.perf_counter() - start
        start = clock.perf_counter()
        estimates = [compiled.estimate(out["outputs"]) for out in outs]
        elapsed = clock.perf_counter() - start
    difference = max(np.max(np.abs(estimate.states - out["dem_states"])) / np.max(np.abs(out["dem_states"]))
                     for estimate, out in zip(estimates, outs))
    samples = sum(len(out["outputs"]) for out in outs)
    return {"DEM (JAX) speed": (samples / max(elapsed, 1e-9), "samples/s"),
            "DEM (JAX) first call": (first_call, "s"),
            "DEM (JAX) / DEM largest state difference": (difference, "1")}


def run(module, quick: bool, progress: bool, seeds: int | None, quick_settings: dict) -> ExperimentResult:
    """The run() of a nonlinear reproduction ``module`` (its SETTINGS, build_system, true_input):
    ``seeds`` seeds (default 3 quick, 20 full), ``quick_settings`` replacing SETTINGS in the quick
    run; progress: a progress bar. Computes only (the module's plot draws the figure)."""
    cfg = dict(module.SETTINGS, seeds=seeds or (3 if quick else 20))
    if quick:
        cfg.update(quick_settings)
    return compare(module.__name__.rsplit(".", 1)[-1], cfg, progress)


#: particles from which the particle smoother is a converged reference (docs/nonlinear.md)
CONVERGED_PARTICLES = 100_000


def claims(result: ExperimentResult) -> list[Claim]:
    """The issue's targets for nonlinear DEM, for the D-step (sample mode) and for path mode, with
    the measured medians: state SSE <= 1.2x the posterior reference and <= the UKF smoother's
    (coloured noise, s/dt >= 2), the input SSE beside the augmented UKF smoother, and the D-step's
    speed. The reference is the particle smoother when it has CONVERGED_PARTICLES particles or
    more; with fewer (quick runs) it is not converged, and the better of it and the coloured UKS
    (the larger DEM ratio) stands in."""
    value = lambda name: result.metric(name).value  # noqa: E731
    cfg = result.settings
    setting = (f"{cfg['seeds']} seeds, {cfg['duration']:g} s at dt = {cfg['dt']} s, s/dt = "
               f"{cfg['kernel_width'] / cfg['dt']:.0f}")
    out = []
    for dem, title in (("DEM", "nonlinear DEM (D-step)"), ("DEM path", "nonlinear DEM in path mode")):
        if not _has(result, f"{dem} state SSE (median)"):
            continue
        ratio = value(f"{dem} / particle state SSE (median ratio)")
        reference = f"particle smoother, {cfg['particles']} particles"
        if cfg["particles"] < CONVERGED_PARTICLES and _has(result, f"{dem} / coloured UKS state SSE (median ratio)"):
            uks = value(f"{dem} / coloured UKS state SSE (median ratio)")
            reference = (f"{dem} / particle {ratio:.2f} with {cfg['particles']} particles (not converged), "
                         f"{dem} / coloured UKS {uks:.2f}: the larger counts")
            ratio = max(ratio, uks)
        estimate, ukf = value(f"{dem} state SSE (median)"), value("UKF state SSE (median)")
        out += [
            Claim(f"{title}'s state SSE is at most 1.2x the posterior reference's (median, coloured noise)",
                  f"median ratio {ratio:.2f} ({reference}; {setting})",
                  "reproduced" if ratio <= 1.2 else "does not hold"),
            Claim(f"{title}'s state SSE is at most the UKF smoother's (median, coloured noise)",
                  f"{dem} {estimate:.3g} vs UKF smoother {ukf:.3g} [state unit^2] ({setting})",
                  "reproduced" if estimate <= ukf else "does not hold"),
        ]
        if _has(result, f"{dem} input SSE (median)"):
            estimate_input, ukf_input = value(f"{dem} input SSE (median)"), value("augmented UKF input SSE (median)")
            out.append(Claim(f"{title}'s input SSE is at most the augmented UKF smoother's (median)",
                             f"{dem} {estimate_input:.3g} vs augmented UKF smoother {ukf_input:.3g} [(input unit)^2] "
                             f"({setting})", "reproduced" if estimate_input <= ukf_input else "does not hold"))
    out.append(Claim("nonlinear DEM (D-step) runs at >= 2e4 samples/s on one core",
                     f"{value('DEM speed'):.0f} samples/s (this run, on a possibly shared machine)",
                     "reproduced" if value("DEM speed") >= 2e4 else "does not hold"))
    if _has(result, "DEM (JAX) speed"):
        speed = value("DEM (JAX) speed")
        out.append(Claim("nonlinear DEM (D-step) compiled with JAX (backend='jax') runs at >= 2e4 samples/s on one core",
                         f"{speed:.0f} samples/s once compiled (first call {value('DEM (JAX) first call'):.1f} s; "
                         f"estimates equal to the NumPy D-step's to {value('DEM (JAX) / DEM largest state difference'):.0e} "
                         f"of their scale; this run, {setting})", "reproduced" if speed >= 2e4 else "does not hold"))
    return out


def _has(result: ExperimentResult, name: str) -> bool:
    return any(metric.name == name for metric in result.metrics)


def plot(result: ExperimentResult, out_dir, state_labels, input_label=None, sse_unit="state unit^2") -> list[str]:
    """NAME.png: seed-0 states (truth, DEM D-step and path mode, UKF, particle), input if estimated, SSE per method,
    from ``result.tables`` alone (as rebuilt from the JSON)."""
    from attend.plotting import figure

    data = {key: result.tables[key] for key in ("state_sse", "input_sse")}
    example = {key: np.asarray(value, dtype=float) for key, value in result.tables["example"].items()}
    n = example["states"].shape[1]
    unknown = input_label is not None
    panels = n + (1 if unknown else 0) + 1
    fig, axes = figure((4.2 * panels, 3.6), 1, panels)
    time = example["time"]
    for i in range(n):
        ax = axes[i]
        ax.plot(time, example["states"][:, i], "k", lw=2, label="true")
        ax.plot(time, example["DEM_states"][:, i], "C0", label="DEM (D-step)")
        if "DEM path_states" in example:
            ax.plot(time, example["DEM path_states"][:, i], "C4", lw=1.6, zorder=5, label="DEM path mode")
        if "UKF_states" in example:
            ax.plot(time, example["UKF_states"][:, i], "C1", lw=0.8, label="UKF smoother")
        if "coloured UKS_states" in example:
            ax.plot(time, example["coloured UKS_states"][:, i], "C3:", lw=0.8, label="coloured UKS")
        if "particle_states" in example:
            ax.plot(time, example["particle_states"][:, i], "C2--", lw=0.8, label="particle")
        ax.set_xlabel("time [s]")
        ax.set_ylabel(state_labels[i])
    axes[0].legend(fontsize=7)
    if unknown:
        ax = axes[n]
        ax.plot(time, example["inputs"][:, 0], "k", lw=2, label="true")
        ax.plot(time, example["DEM_inputs"][:, 0], "C0", label="DEM (D-step)")
        if "DEM path_inputs" in example:
            ax.plot(time, example["DEM path_inputs"][:, 0], "C4", lw=1.6, zorder=5, label="DEM path mode")
        if "UKF_inputs" in example:
            ax.plot(time, example["UKF_inputs"][:, 0], "C1", lw=0.8, label="augmented UKF")
        if "coloured UKS_inputs" in example:
            ax.plot(time, example["coloured UKS_inputs"][:, 0], "C3:", lw=0.8, label="coloured UKS")
        if "particle_inputs" in example:
            ax.plot(time, example["particle_inputs"][:, 0], "C2--", lw=0.8, label="particle")
        ax.set_xlabel("time [s]")
        ax.set_ylabel(input_label)
        ax.legend(fontsize=7)
    ax = axes[-1]
    names = list(data["state_sse"])
    ax.boxplot([data["state_sse"][m] for m in names])
    ax.set_xticks(range(1, len(names) + 1), [name.replace(" ", "\n") for name in names], fontsize=7)
    ax.set_yscale("log")
    ax.set_ylabel(f"state SSE per seed [{sse_unit}]")
    ax.set_title(f"{result.settings['seeds']} seeds")
    fig.tight_layout()
    path = Path(out_dir) / f"{result.experiment}.png"
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    return [path.name]
