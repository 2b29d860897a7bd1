"""Active inference control vs a tuned PID and LQG on two plants (attend.control, issue 28).

    python benchmarks/bench_control.py                  # both plants (10-14 min): tune on 5 seeds, 150 runs, evaluate 20 seeds
    python benchmarks/bench_control.py --plant roll     # the quadrotor roll axis only (about 3 min)
    python benchmarks/bench_control.py --quick          # 3 tuning seeds, 50 runs, 8 evaluation seeds

Plant "msd": the paper's mass-spring-damper (m = 1.4 kg, k = 0.8 N/m, b = 0.4 N s/m) pushed by a force
a (saturating at +-20 N) and a coloured force disturbance (std 0.3 N, kernel width 0.3 s), its
position read by two sensors (each std 2 mm, kernel width 0.02 s), sampled at 100 Hz.
Tasks: a 1 m step (10 s) and tracking r(t) = 0.5 sin(t) m (10 s).

Plant "roll": the roll axis of the quadrotor of shared/data/quadrotor-wind (attend.control.roll): the
authors' double integrator phi'' = b u + d(t), b = 0.374838 rad/s^2 per unit of the differential motor
command u = m1 - m2 - m3 + m4 (saturating at +-100), d the wind's roll acceleration with std and kernel
width identified from the four wind flights (printed), two roll-angle sensors (each std 2 mrad, kernel
width 0.01 s; the motion capture's own noise, 0.09 mrad, would make sensing trivial), sampled at 120 Hz
as the logs. Tasks: a 0.2 rad step (4 s) and tracking r(t) = 0.1 sin(pi t) rad (4 s).

Controllers, each with 4 parameters tuned by the same protocol and budget (log-uniform random search
in a box, then Nelder-Mead from the best point) to minimise mean(ITAE step + ITAE tracking) + w_e
effort on tuning seeds 1000.. (never evaluated):
- PID on the mean of the two sensors (kp, ki, kd, derivative filter tau_d);
- LQG with integral action (python-control dlqr/dlqe): LQR weights q_pos, q_vel, q_int (R = 1) and the
  scale of the Kalman filter's process covariance; both sensors fused by the filter; when tracking, the
  reference trajectory (r, r') with its feedforward action (the plant's inverse on r) (the active
  inference agent gets r and r' through its prior; the PID gets r only);
- active inference (attend.control): the agent believes the controlled variable is drawn critically
  damped to the target, x'' = -w^2 (x - v1) - 2 w (x' - v2), with the reference (r, r') as prior on the
  causes; dy~/da from the nominal plant (Markov parameters), Pi_z from the sensor noise; tuned w, log
  Pi_w, log kappa, s.

Figures (each printed beside its target): ITAE, overshoot, settling time (2 %), effort on the nominal
plant (mean over evaluation seeds); ITAE under +-30 % error in each plant parameter (m, k, b; the roll
gain b) as a ratio to the nominal ITAE; step and tracking while sensor 2 degrades (noise x10 from the
middle of the run): active inference with online sensory-precision learning (relative and absolute
level) vs fixed precision, paired over seeds (mean difference, 95 % t-interval);
the controller's step time for a 4-state model (target <= 100 us).
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402

import numpy as np  # noqa: E402
from scipy.optimize import minimize  # noqa: E402
from scipy.stats import t as student_t  # noqa: E402

from attend.control import (  # noqa: E402
    ActiveInferenceController,
    ClosedLoopDivergence,
    GenerativeModel,
    GenerativeProcess,
    LQGController,
    PIDController,
    SensorPrecisionLearning,
    markov_parameters,
    run,
    step_metrics,
)
from attend.control.metrics import itae  # noqa: E402
from attend.control.roll import identify_roll_disturbance, roll_matrices  # noqa: E402

SETTINGS = dict(
    plant="msd", dt=0.01, duration=10.0, step=1.0, track_amplitude=0.5, track_rate=1.0, mass=1.4, stiffness=0.8,
    damping=0.4, sensor_std=0.002, sensor_kernel_width=0.02, force_std=0.3, force_kernel_width=0.3, action_limit=20.0,
    effort_weight=1e-3, model_errors=(0.7, 1.3), error_parameters=("mass", "stiffness", "damping"), degrade_at=5.0,
    degrade_factor=10.0, learning_time_constant=2.0, learning_orders="all",
    embedding_order=2, cause_prior_log_precision=8.0, embedding_window=None, settling_band=0.02,
)
#: the quadrotor roll axis (attend.control.roll); disturbance_std / _kernel_width are identified from the flights
ROLL_SETTINGS = dict(
    plant="roll", dt=1.0 / 120.0, duration=4.0, step=0.2, track_amplitude=0.1, track_rate=float(np.pi),
    gain=0.374838, roll_damping=0.0, sensor_std=0.002, sensor_kernel_width=0.01, disturbance_std=None,
    disturbance_kernel_width=None, action_limit=100.0, effort_weight=1e-5, model_errors=(0.7, 1.3),
    error_parameters=("gain",), degrade_at=2.0, degrade_factor=10.0, learning_time_constant=0.25,
    learning_orders="all", embedding_order=2, cause_prior_log_precision=8.0, embedding_window=12,
    settling_band=0.1,
)
C2 = np.array([[1.0, 0.0], [1.0, 0.0]])


def plant_matrices(cfg, **change):
    """(A, B) of the plant with the parameters in ``change`` replacing cfg's (a model error)."""
    p = {**cfg, **change}
    if cfg["plant"] == "roll":
        return roll_matrices(p["gain"], p["roll_damping"])
    A = np.array([[0.0, 1.0], [-p["stiffness"] / p["mass"], -p["damping"] / p["mass"]]])
    B = np.array([[0.0], [1.0 / p["mass"]]])
    return A, B


def world(cfg, degrade=False, **change):
    """The plant (possibly with model error ``change``, possibly with sensor 2 degrading)."""
    A, B = plant_matrices(cfg, **change)
    scale = None
    if degrade:
        at, factor = cfg["degrade_at"], cfg["degrade_factor"]
        scale = lambda t: np.array([1.0, factor if t >= at else 1.0])  # noqa: E731
    limit = cfg["action_limit"]
    if cfg["plant"] == "roll":
        std, width = cfg["disturbance_std"], cfg["disturbance_kernel_width"]
    else:
        std, width = cfg["force_std"] / change.get("mass", cfg["mass"]), cfg["force_kernel_width"]
    return GenerativeProcess.linear(
        A, B, C2, sensor_noise_std=cfg["sensor_std"], sensor_kernel_width=cfg["sensor_kernel_width"],
        process_noise_std=[0.0, std], process_kernel_width=width,
        action_limits=(-limit, limit), sensor_noise_scale=scale)


def disturbance_variance(cfg):
    """Variance of the process noise on the velocity per sample (the Kalman filter's model of it)."""
    if cfg["plant"] == "roll":
        return cfg["disturbance_std"] ** 2
    return (cfg["force_std"] / cfg["mass"]) ** 2


def reference(task, cfg):
    """r(t) and its generalised form [r, r'] for the task."""
    if task == "step":
        return (lambda t: cfg["step"]), (lambda t: np.array([cfg["step"], 0.0]))
    amp, rate = cfg["track_amplitude"], cfg["track_rate"]
    return (lambda t: amp * np.sin(rate * t)), (lambda t: np.array([amp * np.sin(rate * t), amp * rate * np.cos(rate * t)]))


# --- the three controllers, each from 4 numbers (log scale) ------------------------------------

def make_pid(theta, task, cfg):
    kp, ki, kd, tau = np.exp(theta)
    r, _ = reference(task, cfg)
    limit = cfg["action_limit"]
    return PIDController(kp, ki, kd, cfg["dt"], reference=r, n_outputs=2, output_weights=[0.5, 0.5],
                         derivative_filter=tau, action_limits=(-limit, limit))


def make_lqg(theta, task, cfg):
    q_pos, q_vel, q_int, w_scale = np.exp(theta)
    A, B = plant_matrices(cfg)
    from attend.systems import zero_order_hold

    _, Wd = zero_order_hold(A, np.eye(2), cfg["dt"])
    W = w_scale * Wd @ np.diag([0.0, disturbance_variance(cfg)]) @ Wd.T + 1e-12 * np.eye(2)
    r, _ = reference(task, cfg)
    limit = cfg["action_limit"]
    feedforward = None
    if task == "track":  # the reference's motion, as the active inference agent gets it through its prior
        amp, w = cfg["track_amplitude"], cfg["track_rate"]

        def feedforward(t):  # the nominal plant's inverse on r: B a = r'' - A [r; r'] (second row)
            pos, vel, acc = amp * np.sin(w * t), amp * w * np.cos(w * t), -amp * w**2 * np.sin(w * t)
            return np.array([pos, vel]), np.array([(acc - A[1] @ np.array([pos, vel])) / B[1, 0]])
    return LQGController(A, B, C2, cfg["dt"], reference=r, tracked=[[1.0, 0.0]], state_weight=[q_pos, q_vel],
                         integral_weight=q_int, action_weight=1.0, process_covariance=W,
                         sensor_covariance=cfg["sensor_std"] ** 2 * np.eye(2), action_limits=(-limit, limit),
                         reference_state=feedforward)


def make_aif(theta, task, cfg, learning=None):
    omega, process_precision, gain, kernel_width = np.exp(theta)
    # desired dynamics: x'' = -w^2 (x - v1) - 2 w (x' - v2), causes v = (target position, target velocity)
    A_m = np.array([[0.0, 1.0], [-omega**2, -2.0 * omega]])
    B_m = np.array([[0.0, 0.0], [omega**2, 2.0 * omega]])
    _, generalised = reference(task, cfg)
    amp, rate = cfg["track_amplitude"], cfg["track_rate"]
    if task == "step":
        prior = lambda t: np.array([cfg["step"], 0.0, 0.0, 0.0])  # noqa: E731  [v1, v2, v1', v2']
    else:
        prior = lambda t: np.array([amp * np.sin(rate * t), amp * rate * np.cos(rate * t),  # noqa: E731
                                    amp * rate * np.cos(rate * t), -amp * rate**2 * np.sin(rate * t)])
    model = GenerativeModel.linear(A_m, B_m, C2, sensor_precision=1.0 / cfg["sensor_std"] ** 2,
                                   process_precision=process_precision,
                                   cause_prior_precision=np.exp(cfg["cause_prior_log_precision"]),
                                   cause_prior=prior, kernel_width=kernel_width,
                                   embedding_order=cfg["embedding_order"], cause_order=1,
                                   initial_causes=prior(0.0)[:2])
    A, B = plant_matrices(cfg)
    G = markov_parameters(A, B, C2, np.zeros((2, 1)), cfg["embedding_order"] + 1)
    limit = cfg["action_limit"]
    return ActiveInferenceController(model, cfg["dt"], action_gain=gain, action_jacobian=G,
                                     action_limits=(-limit, limit), precision_learning=learning,
                                     embedding_window=cfg["embedding_window"])


MAKERS = {"PID": make_pid, "LQG": make_lqg, "active inference": make_aif}
#: tuning box per plant and controller, (low, high) of each parameter (searched on a log scale)
BOUNDS = {
    "msd": {
        "PID": [(1.0, 1e3), (0.1, 1e3), (0.1, 1e2), (1e-3, 1.0)],  # kp, ki, kd, tau_d [s]
        "LQG": [(1.0, 1e8), (1e-2, 1e4), (1.0, 1e10), (1e-3, 1e4)],  # q_pos, q_vel, q_int, Kalman process scale
        "active inference": [(0.5, 30.0), (1.0, 1e8), (1e-2, 1e4), (5e-3, 1.0)],  # w [rad/s], Pi_w, kappa, s [s]
    },
    "roll": {  # the action is in motor-command units (b = 0.37 rad/s^2 per unit)
        "PID": [(10.0, 1e4), (1.0, 1e5), (1.0, 1e3), (1e-3, 0.3)],
        "LQG": [(1e2, 1e10), (1e-1, 1e6), (1e2, 1e12), (1e-3, 1e4)],
        "active inference": [(2.0, 60.0), (1.0, 1e8), (1e-1, 1e7), (1e-3, 0.3)],
    },
}


def evaluate(controller, task, cfg, seed, plant=None):
    """(ITAE, overshoot, settling, effort) of one run; inf ITAE if the loop diverges."""
    r, _ = reference(task, cfg)
    try:
        loop = run(plant or world(cfg), controller, cfg["duration"], seed=seed, record_beliefs=False)
    except ClosedLoopDivergence:
        return np.inf, np.inf, np.inf, np.inf
    target = np.array([r(t) for t in loop.time])
    if task == "step":
        m = step_metrics(loop.time, loop.states[:, 0], target, loop.actions, band=cfg["settling_band"])
        return m.itae, m.overshoot, m.settling_time, m.effort
    effort = float(np.sum(loop.actions**2) * cfg["dt"])
    return itae(loop.time, loop.states[:, 0], target), np.nan, np.nan, effort


def objective(name, theta, cfg, seeds):
    total = 0.0
    for task in ("step", "track"):
        for seed in seeds:
            try:
                controller = MAKERS[name](theta, task, cfg)
            except Exception:  # an LQR/Kalman design that does not exist for these weights
                return 1e6
            value, _, _, effort = evaluate(controller, task, cfg, seed)
            if not np.isfinite(value):
                return 1e6
            total += value + cfg["effort_weight"] * effort
    return total / (2 * len(seeds))


def tune(name, cfg, seeds, evaluations):
    """The same protocol for every controller: 40 % of the budget on log-uniform random points in BOUNDS (seeded),
    the rest on Nelder-Mead from the best of them. Returns (theta, objective, runs)."""
    box = np.log(np.array(BOUNDS[cfg["plant"]][name]))
    rng = np.random.default_rng(7)
    search = int(0.4 * evaluations)
    points = box[:, 0] + (box[:, 1] - box[:, 0]) * rng.random((search, box.shape[0]))
    values = [objective(name, theta, cfg, seeds) for theta in points]
    start = points[int(np.argmin(values))]
    result = minimize(lambda th: objective(name, th, cfg, seeds), start, method="Nelder-Mead",
                      options=dict(maxfev=evaluations - search, xatol=1e-3, fatol=1e-5))
    best = (result.x, result.fun) if result.fun <= min(values) else (start, min(values))
    return best[0], best[1], search + result.nfev


def interval(differences):
    """Mean and 95 % t-interval of paired differences."""
    d = np.asarray(differences, dtype=float)
    half = student_t.ppf(0.975, d.size - 1) * d.std(ddof=1) / np.sqrt(d.size)
    return d.mean(), d.mean() - half, d.mean() + half


def step_time(cfg, repeats=3000):
    """Median wall time of ActiveInferenceController.step for a 4-state model (two masses in a chain), p = 4:
    linear with constant precision (cached transition); with precision learning; the same model written as
    nonlinear (analytic Jacobians), re-linearised every sample and with jacobian_tolerance = 0 (its Jacobians
    are constant, so the linearisation is reused exactly); and a truly nonlinear chain (cubic springs), re-linearised
    every sample and with jacobian_tolerance = 5e-2 (with the largest action difference that reuse causes)."""
    k1, k2, m1, m2, b = 1.0, 0.5, 1.0, 0.5, 0.3
    A = np.array([[0, 1, 0, 0], [-(k1 + k2) / m1, -b / m1, k2 / m1, 0], [0, 0, 0, 1], [k2 / m2, 0, -k2 / m2, -b / m2]])
    B = np.array([[0.0], [1.0 / m1], [0.0], [0.0]])
    C = np.array([[1.0, 0, 0, 0], [0, 0, 1.0, 0]])
    G = markov_parameters(A, B, C, np.zeros((2, 1)), 5)
    options = dict(sensor_precision=1e4, process_precision=1e2, cause_prior_precision=1e2, cause_prior=np.zeros(1),
                   kernel_width=0.05, embedding_order=4, cause_order=1)
    cubic = 4.0  # cubic spring force cubic * x^3 on the first mass (a hardening spring)

    def f_cubic(x, v):
        return A @ x + B @ v - np.array([0.0, cubic * x[0] ** 3 / m1, 0.0, 0.0])

    def jf_cubic(x, v):
        fx = A.copy()
        fx[1, 0] -= 3 * cubic * x[0] ** 2 / m1
        return fx, B

    linear = GenerativeModel.linear(A, B, C, **options)
    written = GenerativeModel(f=lambda x, v: A @ x + B @ v, g=lambda x, v: C @ x, n_states=4, n_causes=1, n_outputs=2,
                              jacobian_f=lambda x, v: (A, B), jacobian_g=lambda x, v: (C, np.zeros((2, 1))), **options)
    nonlinear = GenerativeModel(f=f_cubic, g=lambda x, v: C @ x, n_states=4, n_causes=1, n_outputs=2,
                                jacobian_f=jf_cubic, jacobian_g=lambda x, v: (C, np.zeros((2, 1))), **options)
    cases = {
        "linear, constant precision": (linear, dict()),
        "linear, with precision learning": (linear, dict(precision_learning=SensorPrecisionLearning())),
        "linear written as nonlinear, re-linearised each sample": (written, dict()),
        "linear written as nonlinear, jacobian_tolerance 0": (written, dict(jacobian_tolerance=0.0)),
        "nonlinear (cubic spring), re-linearised each sample": (nonlinear, dict()),
        "nonlinear (cubic spring), jacobian_tolerance 5e-2": (nonlinear, dict(jacobian_tolerance=5e-2)),
    }
    rng = np.random.default_rng(0)
    samples = 0.3 * np.sin(np.arange(repeats)[:, None] * 0.01 * np.array([1.0, 0.7])) \
        + 1e-3 * rng.standard_normal((repeats, 2))
    out, actions = {}, {}
    for label, (model, extra) in cases.items():
        controller = ActiveInferenceController(model, 0.01, action_gain=1.0, action_jacobian=G, **extra)
        times = np.empty(repeats)
        taken = np.empty(repeats)
        for i in range(repeats):
            started = time.perf_counter()
            taken[i] = controller.step(samples[i])[0]
            times[i] = time.perf_counter() - started
        out[label] = float(np.median(times[100:]))
        actions[label] = taken
    exact = actions["nonlinear (cubic spring), re-linearised each sample"]
    reused = actions["nonlinear (cubic spring), jacobian_tolerance 5e-2"]
    out["largest action difference from reuse (cubic spring), relative"] = float(
        np.abs(reused - exact).max() / np.abs(exact).max())
    return out


def compare(cfg, tune_seeds, eval_seeds, evaluations):
    """Tune the three controllers on ``cfg``'s plant and print every figure beside its target."""
    if cfg["plant"] == "roll":
        wind = identify_roll_disturbance()
        cfg["disturbance_std"], cfg["disturbance_kernel_width"] = wind.std, wind.kernel_width
        print(f"quadrotor roll axis, b = {cfg['gain']} rad/s^2 per command unit; wind roll acceleration identified from "
              f"the 4 wind flights (samples 400..1599): std {wind.std:.3f} rad/s^2, kernel width "
              f"{wind.kernel_width:.4f} s (white remainder {wind.white_std:.3f} rad/s^2, the differentiated rate noise)")
        for name, (std, width, white) in wind.per_flight.items():
            print(f"  {name}: std {std:.3f} rad/s^2, kernel width {width:.4f} s, white {white:.3f} rad/s^2")
    else:
        print("mass-spring-damper")
    print(f"dt = {cfg['dt']:.5g} s, {cfg['duration']} s per task; tuning seeds {list(tune_seeds)}, "
          f"{evaluations} evaluations each; evaluation seeds 0..{len(eval_seeds) - 1}")
    tuned = {}
    for name in MAKERS:
        t0 = time.perf_counter()
        theta, value, nfev = tune(name, cfg, tune_seeds, evaluations)
        tuned[name] = theta
        print(f"  tuned {name:17s} objective {value:.4f} ({nfev} runs of {2 * len(tune_seeds)} loops, "
              f"{time.perf_counter() - t0:.0f} s): exp(theta) = {np.round(np.exp(theta), 4).tolist()}")

    # nominal plant -----------------------------------------------------------------------------
    nominal = {}
    for name in MAKERS:
        for task in ("step", "track"):
            rows = [evaluate(MAKERS[name](tuned[name], task, cfg), task, cfg, seed) for seed in eval_seeds]
            nominal[name, task] = np.array(rows)
    print(f"\nnominal plant (mean over evaluation seeds; settling band {100 * cfg['settling_band']:g} % of the step)")
    print(f"  {'controller':17s} {'ITAE step':>10s} {'overshoot %':>11s} {'settling s':>10s} {'effort':>10s} "
          f"{'ITAE track':>10s} {'effort track':>12s}")
    for name in MAKERS:
        s, tr = nominal[name, "step"], nominal[name, "track"]
        print(f"  {name:17s} {s[:, 0].mean():10.4f} {s[:, 1].mean():11.2f} {s[:, 2].mean():10.2f} {s[:, 3].mean():10.1f} "
              f"{tr[:, 0].mean():10.4f} {tr[:, 3].mean():12.1f}")
    for task in ("step", "track"):
        aif, pid, lqg = (nominal[n, task][:, 0] for n in ("active inference", "PID", "LQG"))
        d_pid, d_lqg = interval(aif - pid), interval(aif - 1.2 * lqg)
        print(f"  {task} ITAE: active inference {aif.mean():.4f} vs PID {pid.mean():.4f} (target <= PID: "
              f"{'met' if aif.mean() <= pid.mean() else 'NOT met'}; paired difference {d_pid[0]:+.4f}, 95 % "
              f"[{d_pid[1]:+.4f}, {d_pid[2]:+.4f}]); vs 1.2 x LQG = {1.2 * lqg.mean():.4f} "
              f"({'met' if aif.mean() <= 1.2 * lqg.mean() else 'NOT met'}; paired difference {d_lqg[0]:+.4f}, 95 % "
              f"[{d_lqg[1]:+.4f}, {d_lqg[2]:+.4f}])")

    # model error -----------------------------------------------------------------------------------
    print("\nmodel error: ITAE on the perturbed plant / nominal ITAE (controllers designed on the nominal model)")
    cases = [(f"{which} x {factor}", {which: cfg[which] * factor}) for which in cfg["error_parameters"]
             for factor in cfg["model_errors"]]
    for task in ("step", "track"):
        print(f"  {task:6s} {'plant':11s} " + " ".join(f"{name:>17s}" for name in MAKERS))
        worst = {name: (0.0, "") for name in MAKERS}
        for label, change in cases:
            ratios = []
            for name in MAKERS:
                rows = [evaluate(MAKERS[name](tuned[name], task, cfg), task, cfg, seed, world(cfg, **change))[0]
                        for seed in eval_seeds]
                ratio = np.mean(rows) / nominal[name, task][:, 0].mean()
                worst[name] = max(worst[name], (ratio, label))
                ratios.append(ratio)
            print(f"  {task:6s} {label:11s} " + " ".join(f"{value:17.3f}" for value in ratios))
        print(f"  {task} worst ratio: " + ", ".join(f"{name} {value:.3f} ({label})" for name, (value, label)
                                                 in worst.items()) + " (reported beside LQG's and PID's; no target)")

    # degrading sensor ----------------------------------------------------------------------------
    print(f"\nsensor 2 degrades (noise x{cfg['degrade_factor']:g} from t = {cfg['degrade_at']:g} s); learning: time constant "
          f"{cfg['learning_time_constant']:g} s, orders '{cfg['learning_orders']}' (chosen on the tuning seeds)")
    degraded = world(cfg, degrade=True)
    theta = tuned["active inference"]
    variants = {"active inference, fixed precision": None}
    for level in ("relative", "absolute"):
        variants[f"active inference, learned ({level})"] = SensorPrecisionLearning(
            time_constant=cfg["learning_time_constant"], level=level, orders=cfg["learning_orders"])
    for task in ("step", "track"):
        results = {}
        for label, learning in variants.items():
            results[label] = np.array([evaluate(make_aif(theta, task, cfg, learning), task, cfg, seed, degraded)[0]
                                       for seed in eval_seeds])
        for label, make in (("PID", make_pid), ("LQG", make_lqg)):
            results[label] = np.array([evaluate(make(tuned[label], task, cfg), task, cfg, seed, degraded)[0]
                                       for seed in eval_seeds])
        print(f"  {task}: " + ", ".join(f"{label} {values.mean():.4f}" for label, values in results.items()))
        for level in ("relative", "absolute"):
            mean, low, high = interval(results[f"active inference, learned ({level})"]
                                       - results["active inference, fixed precision"])
            verdict = "met" if high < 0 else ("NOT met" if low > 0 else "not resolved (interval contains 0)")
            print(f"  {task}: learned ({level}) - fixed ITAE {mean:+.4f}, 95 % interval [{low:+.4f}, {high:+.4f}] over "
                  f"{len(eval_seeds)} paired seeds (target < 0: {verdict})")



def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--quick", action="store_true", help="3 tuning seeds, 50 evaluations, 8 evaluation seeds")
    parser.add_argument("--plant", choices=("msd", "roll", "both", "none"), default="both",
                        help="mass-spring-damper, quadrotor roll axis, both (default) or none (step times only)")
    args = parser.parse_args()
    warnings.simplefilter("ignore")
    tune_seeds = range(1000, 1003 if args.quick else 1005)
    eval_seeds = range(8 if args.quick else 20)
    evaluations = 50 if args.quick else 150
    started = time.perf_counter()
    plants = {"msd": SETTINGS, "roll": ROLL_SETTINGS}
    for name in {"both": ("msd", "roll"), "none": ()}.get(args.plant, (args.plant,)):
        print(f"\n=== plant {name} ===")
        compare(dict(plants[name]), tune_seeds, eval_seeds, evaluations)

    # step time ----------------------------------------------------------------------------------
    times = step_time(dict(SETTINGS))
    for label, value in times.items():
        if label.startswith("largest"):
            print(f"\n{label}: {value:.2e}", end="")
            continue
        print(f"\ncontroller step, 4 states, p = 4, {label}: {value * 1e6:.1f} us (target <= 100 us: "
              f"{'met' if value <= 1e-4 else 'NOT met'})", end="")
    print(f"\n\nwall time {time.perf_counter() - started:.0f} s")


if __name__ == "__main__":
    main()
