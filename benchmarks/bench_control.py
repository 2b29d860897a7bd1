"""Active inference control vs a tuned PID and LQG on three plants (attend.control, issue 28).

    python benchmarks/bench_control.py                  # all three plants: tune on 5 seeds, 150 runs, evaluate 20 seeds
    python benchmarks/bench_control.py --plant both     # the mass-spring-damper and the roll axis
    python benchmarks/bench_control.py --plant roll     # the quadrotor roll axis only (408 s on 2 shared cores)
    python benchmarks/bench_control.py --plant arm      # the two-link arm only (892 s on 2 shared cores)
    python benchmarks/bench_control.py --quick          # 3 tuning seeds, 50 runs, 8 evaluation seeds
    python benchmarks/bench_control.py --plots DIR      # where the arm's response plots go (default results/control)
    python benchmarks/bench_control.py --loop-shape     # the loop analyses at the documented tuned points (--plant)
    python benchmarks/bench_control.py --restarts 3     # tune 3 times (random-search seeds 7, 8, 9), keep the best

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

Plant "arm": a two-link arm in the vertical plane (attend.control.arm: M(q) q'' + C q' + g(q) = tau + tau_d - B q';
links 0.5 / 0.4 m, 2.0 / 1.2 kg, uniform rods, viscous friction 0.1 / 0.05 N m s/rad), torques saturating at 30 / 10 N m,
a coloured torque disturbance on each joint (std 0.5 / 0.2 N m, kernel width 0.1 s), two angle sensors per joint (each
std 2 mrad, kernel width 0.01 s), 100 Hz. Tasks: a step from hanging (-pi/2, 0) to (-0.6, 0.8) rad and tracking
(-0.8, 1.0) + (0.4 sin 1.5 t, 0.3 sin 2 t) rad (4 s each). All three controllers add the gravity torque of the
nominal model (PID: at the measured angles; LQG: its operating point's torque and, tracking, the inverse dynamics of
the reference; active inference: at its believed angles). PID per joint with gains per unit of the joint's inertia
M_ii at the target; LQG on the arm linearised at rest at the target (tracking: at the reference's centre);
active inference with dy~/da of the torque held over one sample (about (M^-1 dt^2/2, M^-1 dt, M^-1), M(q) of the
nominal model at the believed angles; attending orders 0..2) and the reference's (r, r', r'') as prior on its
causes. Figures are medians over seeds; model error: masses and inertias x 0.7 / x 1.3, a payload
(link 2 x 1.3), friction x 1.3, and every inertial parameter and friction drawn in [0.7, 1.3] per seed; the
degrading sensor is sensor 2 of both joints, and precision learning shares each joint's total between its sensors.

Controllers, each with 4 parameters tuned by the same protocol and budget (log-uniform random search
in a box, seeded 7, then Nelder-Mead from the best point) to minimise mean(ITAE step + ITAE tracking) + w_e
effort on tuning seeds 1000.. (never evaluated); --restarts K runs the protocol K times (random-search seeds
7..7+K-1, the budget each) and keeps the point of least objective on the tuning seeds, for every controller:
- PID on the mean of the two sensors (kp, ki, kd, derivative filter tau_d);
- LQG with integral action (python-control dlqr/dlqe): LQR weights q_pos, q_vel, q_int (R = 1) and the
  scale of the Kalman filter's process covariance; both sensors fused by the filter; when tracking, the
  reference trajectory (r, r') with its feedforward action (the plant's inverse on r) (the active
  inference agent gets r and r' through its prior; the PID gets r only);
- active inference (attend.control): the agent believes the controlled variable is drawn critically
  damped to the target, x'' = -w^2 (x - v1) - 2 w (x' - v2) + v3, with the reference (r, r', r'') as prior
  on the causes; dy~/da from the nominal plant (the Markov parameters of the action held over one sample,
  (b dt^2/2, b dt, b) for phi'' = b u, attending orders 0..2; on the roll axis and the mass-spring-damper the
  data and the prior move with their generalised motion within each sample, data_motion="generalised"; the
  mass-spring-damper's agent before 2026-11-27 had the instantaneous dy~/da, (r, r') and held data,
  MSD_BEFORE), Pi_z from the sensor noise, the prior on the causes at precision exp(8) (on the roll axis and
  the arm 1 / sensor_std^2, the precision of one sensor); tuned w, log Pi_w, log kappa, s.
Then each controller is tuned further for the least mean ITAE at a common effort (Nelder-Mead, 60 % of the budget,
from its tuned point; mean effort per task at most the lower of the tuned PID's and LQG's on the tuning seeds): the
"effort-matched" rows, a diagnostic beside the targets (ITAE + w_e effort makes each baseline the least-ITAE design
at its own effort, and the agent settles at less effort).

Figures (each printed beside its target): ITAE, overshoot, settling time (2 %), effort on the nominal
plant (mean over evaluation seeds); ITAE under +-30 % error in each plant parameter (m, k, b; the roll
gain b) as a ratio to the nominal ITAE; step and tracking while sensor 2 degrades (noise x10 from the
middle of the run): active inference with online sensory-precision learning (relative and absolute
level) vs fixed precision, paired over seeds (mean difference, 95 % t-interval);
the controller's step time for a 4-state model and for the arm's agent (arm_step_time; median and mean, each
target <= 100 us: the mean carries the refreshes of dy~/da, each an exact transition of the 26-state joint flow).
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402
from pathlib import Path  # noqa: E402

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
from attend.control import arm  # noqa: E402
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
    learning_orders="all", embedding_order=2, cause_prior_log_precision="sensor", embedding_window=None,
    settling_band=0.1, action_hold=True, sensory_orders=2, reference_acceleration=True, data_motion="generalised",
)
#: The roll axis takes dy~/da of the action held over one sample, (b dt^2/2, b dt, b) per sensor, attending orders 0..2
#: (exact backward differences, 3 samples). Chosen on tuning seeds 1000-1001 (grid over w, Pi_w, kappa, s): objective
#: 0.064 with 3 samples, 0.090 with 6; with the instantaneous (0, 0, b): 0.13 at best (3 or 6 samples), 0.23 with 12.
#: The roll agent's causes include the reference's acceleration, x'' = r'' - w^2 (x - r) - 2 w (x' - r') (LQG feeds
#: forward the reference's inverse dynamics): objective on seeds 1000-1004 at the tuned point 0.0559 against 0.0597.
#: data_motion "generalised" (y~ and eta~ move by D within the sample instead of being held; a held belief ends each
#: step a sample behind the data): tuned objective on seeds 1000-1004 0.0515 against 0.0523 held. On the arm it did
#: worse (0.114 against 0.108), so the arm and msd keep "held".
#: cause_prior_log_precision "sensor": the roll agent holds its intention (the causes' prior) as precisely as one
#: sensor reports the roll, P_v = 1 / sensor_std^2 (log 12.43), instead of exp(8). At exp(8) the belief about the
#: target yields to the wind (it moves by 0.30-0.77 rad per rad of roll at 1-10 rad/s), and the reflex's loop gain there
#: is half the PID's. At the least steady-state error for the baselines' rms action (--loop-shape, docs/control.md) the
#: agent gives 3.79 mrad at exp(8), 2.91 at exp(12) (PID 2.91, LQG 2.89). Tuned objective on seeds 1000-1004: 0.0513
#: against 0.0515.
#: The same rule on the mass-spring-damper did worse by the protocol (tuned objective on seeds 1000-1004 0.474 against
#: 0.188 at exp(8); with the reference's acceleration as a cause as well, 0.275 (0.461 at exp(8))), so msd keeps exp(8):
#: a stiff intention without r'' lags the sine (tracking ITAE 0.171 against 0.073 at the exp(8)-tuned point), and
#: with r'' it buys step ITAE (0.144 against 0.171) with effort (147 against 112, at w_e = 1e-3). docs/control.md.
#: Since 2026-11-27 msd uses the roll's agent (intention kept at exp(8)): dy~/da of the force held over one sample,
#: attending orders 0..2, the reference's acceleration as a cause and the data moving within the sample. Tuned by the
#: protocol on seeds 1000-1004 the objective is 0.178 against 0.188 with the instantaneous dy~/da, (r, r') and held
#: data (0.179 with held data); the random search seeded 8 or 9 lands at the same point (0.178), where the old
#: agent's reached 0.193, 1.38 and 1.10 (seeds 8, 9, 10). Its grid over seeds 1000-1001 (0.37 with the held column
#: alone) had not tried it with r''. With P_v = 1 / sensor_std^2 as well (the whole roll agent) the objective was
#: 0.1835, so exp(8) stays. docs/control.md.
SETTINGS.update(action_hold=True, sensory_orders=2, reference_acceleration=True, data_motion="generalised")
#: the mass-spring-damper agent before 2026-11-27 (instantaneous dy~/da, (r, r') as causes, held data), for the
#: loop analysis of its documented tuned points
MSD_BEFORE = dict(action_hold=False, sensory_orders="relative_degree", reference_acceleration=False, data_motion="held")
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
    from attend.models.linear import zero_order_hold

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


def cause_log_precision(cfg):
    """log P_v of the agent's intention: a number, or "sensor" for the log-precision of one sensor, -2 log sensor_std."""
    value = cfg["cause_prior_log_precision"]
    return -2.0 * np.log(cfg["sensor_std"]) if value == "sensor" else float(value)


def make_aif(theta, task, cfg, learning=None):
    omega, process_precision, gain, kernel_width = np.exp(theta)
    # desired dynamics: x'' = -w^2 (x - v1) - 2 w (x' - v2) [+ v3], causes v = (target position, target velocity
    # [, target acceleration when cfg["reference_acceleration"]])
    with_acceleration = cfg["reference_acceleration"]
    A_m = np.array([[0.0, 1.0], [-omega**2, -2.0 * omega]])
    B_m = np.array([[0.0, 0.0, 0.0], [omega**2, 2.0 * omega, 1.0]])[:, : 3 if with_acceleration else 2]
    amp, rate = cfg["track_amplitude"], cfg["track_rate"]
    r_size = 3 if with_acceleration else 2

    def prior(t):  # eta~ = [v; v'], v = (r, r'[, r''])
        if task == "step":
            r = np.array([cfg["step"], 0.0, 0.0, 0.0])  # r, r', r'', r'''
        else:
            r = amp * rate ** np.arange(4) * np.array([np.sin(rate * t), np.cos(rate * t), -np.sin(rate * t),
                                                         -np.cos(rate * t)])
        return np.concatenate([r[:r_size], r[1:r_size + 1]])
    model = GenerativeModel.linear(A_m, B_m, C2, sensor_precision=1.0 / cfg["sensor_std"] ** 2,
                                   process_precision=process_precision,
                                   cause_prior_precision=np.exp(cause_log_precision(cfg)),
                                   cause_prior=prior, kernel_width=kernel_width,
                                   embedding_order=cfg["embedding_order"], cause_order=1,
                                   initial_causes=prior(0.0)[:r_size])
    A, B = plant_matrices(cfg)
    # dy~/da: instantaneous (Markov parameters) or of the action held over one sample (cfg["action_hold"])
    G = markov_parameters(A, B, C2, np.zeros((2, 1)), cfg["embedding_order"] + 1,
                          hold=cfg["dt"] if cfg["action_hold"] else 0.0)
    limit = cfg["action_limit"]
    return ActiveInferenceController(model, cfg["dt"], action_gain=gain, action_jacobian=G,
                                     action_limits=(-limit, limit), precision_learning=learning,
                                     embedding_window=cfg["embedding_window"], sensory_orders=cfg["sensory_orders"],
                                     data_motion=cfg.get("data_motion", "held"))


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
    if cfg["plant"] == "arm":
        return evaluate_arm(controller, task, cfg, seed, plant)
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


def objective(name, theta, cfg, seeds, effort_caps=None):
    """mean(ITAE + w_e effort) over both tasks and ``seeds``; with ``effort_caps`` {task: cap}, mean ITAE plus, per
    task, the relative excess of the mean effort over its cap, max(0, effort / cap - 1) (an effort-matched tuning: the
    least ITAE at no more effort than the cap)."""
    total, excess = 0.0, 0.0
    for task in ("step", "track"):
        efforts = []
        for seed in seeds:
            try:
                controller = makers(cfg)[name](theta, task, cfg)
            except Exception:  # an LQR/Kalman design that does not exist for these weights
                return 1e6
            value, _, _, effort = evaluate(controller, task, cfg, seed)
            if not np.isfinite(value):
                return 1e6
            efforts.append(effort)
            total += value + (0.0 if effort_caps else cfg["effort_weight"] * effort)
        if effort_caps:
            excess += max(0.0, np.mean(efforts) / effort_caps[task] - 1.0)
    return total / (2 * len(seeds)) + excess


def tune(name, cfg, seeds, evaluations, effort_caps=None, restarts=1):
    """The same protocol for every controller: 40 % of the ``evaluations`` budget on log-uniform random points in
    BOUNDS (seeded), the rest on Nelder-Mead from the best of them, minimising :func:`objective` on ``seeds`` (the
    tuning seeds; ``effort_caps``: see :func:`objective`). ``restarts`` K runs both phases K times, the random search
    seeded 7, 8, ..., 7 + K - 1 and each restart with the whole budget ``evaluations``, and keeps the point of least
    objective on ``seeds`` (the earliest restart on a tie; K = 1 is the protocol with seed 7 alone). Returns (theta,
    objective, runs, restart_objectives): runs summed over the restarts, restart_objectives the objective each
    restart reached."""
    box = np.log(np.array(BOUNDS[cfg["plant"]][name]))
    search = int(0.4 * evaluations)
    best, runs, restart_objectives = None, 0, []
    for search_seed in range(7, 7 + restarts):
        rng = np.random.default_rng(search_seed)
        points = box[:, 0] + (box[:, 1] - box[:, 0]) * rng.random((search, box.shape[0]))
        values = [objective(name, theta, cfg, seeds, effort_caps) for theta in points]
        start = points[int(np.argmin(values))]
        result = minimize(lambda th: objective(name, th, cfg, seeds, effort_caps), start, method="Nelder-Mead",
                          options=dict(maxfev=evaluations - search, xatol=1e-3, fatol=1e-5))
        found = (result.x, result.fun) if result.fun <= min(values) else (start, min(values))
        runs += search + result.nfev
        restart_objectives.append(found[1])
        if best is None or found[1] < best[1]:
            best = found
    return best[0], best[1], runs, restart_objectives


THREE = ("active inference", "PID", "LQG")  # the agent first, then the baselines it is compared with


def restart_note(restart_objectives):
    """The objective each restart of :func:`tune` reached, as a line to print ("" for a single restart)."""
    if len(restart_objectives) == 1:
        return ""
    return "\n    restarts (random-search seed: objective) " + ", ".join(
        f"{7 + i}: {value:.4f}" for i, value in enumerate(restart_objectives))


def restart_label(restarts):
    """How the tuning was restarted, for the header ("" for a single restart, the protocol with seed 7)."""
    if restarts == 1:
        return ""
    return f" x {restarts} restarts (random-search seeds 7..{6 + restarts}, the least tuning objective kept)"


def matched(name):
    """The label of ``name`` tuned on ITAE under the common effort caps (:func:`tune_effort_matched`)."""
    return f"{'AI' if name == 'active inference' else name}, effort-matched"


def tune_effort_matched(cfg, seeds, evaluations, tuned, average=np.mean):
    """Each controller tuned further, on the least mean ITAE at no more effort, per task, than the lower of the tuned
    PID's and LQG's average effort on the tuning ``seeds`` (average: np.mean, or np.median on the arm): Nelder-Mead
    (the protocol's second phase, 60 % of the budget) from its tuned point, keeping that point if it is better. The
    objective ITAE + w_e effort makes each baseline the least-ITAE design at its own effort (w_e is the Lagrange
    multiplier of that effort); the agent on it settles at less effort (docs/control.md), so its ITAE alone is
    compared here at a common effort. It has no random phase: with restarts (:func:`tune`) it starts from the point
    the restarts kept. Returns ({name: theta}, {name: objective}, caps)."""
    caps = {}
    for task in ("step", "track"):
        caps[task] = min(average([evaluate(makers(cfg)[name](tuned[name], task, cfg), task, cfg, seed)[3]
                                  for seed in seeds]) for name in ("PID", "LQG"))
    thetas, values = {}, {}
    for name in makers(cfg):
        start = tuned[name]
        value = objective(name, start, cfg, seeds, caps)
        result = minimize(lambda th: objective(name, th, cfg, seeds, caps), start, method="Nelder-Mead",
                          options=dict(maxfev=evaluations - int(0.4 * evaluations), xatol=1e-3, fatol=1e-5))
        thetas[matched(name)], values[matched(name)] = (result.x, result.fun) if result.fun < value else (start, value)
    return thetas, values, caps


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
        "linear, constant precision, data_motion 'generalised'": (linear, dict(data_motion="generalised")),
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


def compare(cfg, tune_seeds, eval_seeds, evaluations, restarts=1):
    """Tune the three controllers on ``cfg``'s plant (on ``tune_seeds``, ``evaluations`` runs per restart, ``restarts``
    restarts: see :func:`tune`) and print every figure beside its target over ``eval_seeds``."""
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
          f"{evaluations} evaluations each{restart_label(restarts)}; evaluation seeds 0..{len(eval_seeds) - 1}")
    tuned = {}
    for name in MAKERS:
        t0 = time.perf_counter()
        theta, value, nfev, restart_objectives = tune(name, cfg, tune_seeds, evaluations, restarts=restarts)
        tuned[name] = theta
        print(f"  tuned {name:17s} objective {value:.4f} ({nfev} runs of {2 * len(tune_seeds)} loops, "
              f"{time.perf_counter() - t0:.0f} s): exp(theta) = {np.round(np.exp(theta), 4).tolist()}"
              + restart_note(restart_objectives))
    every = {**MAKERS, **{matched(name): MAKERS[name] for name in MAKERS}}
    t0 = time.perf_counter()
    thetas, values, caps = tune_effort_matched(cfg, tune_seeds, evaluations, tuned)
    tuned.update(thetas)
    print(f"  effort-matched (Nelder-Mead from each tuned point on mean ITAE, mean effort per task <= the lower "
          f"baseline's on the tuning seeds: step {caps['step']:.1f}, track {caps['track']:.1f}; "
          f"{time.perf_counter() - t0:.0f} s):")
    for name, theta in thetas.items():
        print(f"    {name:22s} objective {values[name]:.4f}: exp(theta) = {np.round(np.exp(theta), 4).tolist()}")

    # nominal plant -----------------------------------------------------------------------------
    nominal = {}
    for name in every:
        for task in ("step", "track"):
            rows = [evaluate(every[name](tuned[name], task, cfg), task, cfg, seed) for seed in eval_seeds]
            nominal[name, task] = np.array(rows)
    print(f"\nnominal plant (mean over evaluation seeds; settling band {100 * cfg['settling_band']:g} % of the step)")
    print(f"  {'controller':22s} {'ITAE step':>10s} {'overshoot %':>11s} {'settling s':>10s} {'effort':>10s} "
          f"{'ITAE track':>10s} {'effort track':>12s}")
    for name in every:
        s, tr = nominal[name, "step"], nominal[name, "track"]
        print(f"  {name:22s} {s[:, 0].mean():10.4f} {s[:, 1].mean():11.2f} {s[:, 2].mean():10.2f} "
              f"{s[:, 3].mean():10.1f} {tr[:, 0].mean():10.4f} {tr[:, 3].mean():12.1f}")
    for names, task in [(n, t) for n in (THREE, tuple(map(matched, THREE))) for t in ("step", "track")]:
        agent = names[0]
        aif, pid, lqg = (nominal[n, task][:, 0] for n in names)
        d_pid, d_lqg = interval(aif - pid), interval(aif - 1.2 * lqg)
        print(f"  {task} ITAE: {agent} {aif.mean():.4f} vs {names[1]} {pid.mean():.4f} (target <= PID: "
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



# --- the two-link arm (attend.control.arm) ------------------------------------------------------------

#: the two-link arm in the vertical plane: nominal parameters ArmParameters() (links 0.5 / 0.4 m, 2.0 / 1.2 kg).
#: Chosen on the tuning seeds (1000-1002, 50 runs each, --quick): the agent's causes include the reference's
#: acceleration (reference_acceleration, objective 0.146 against 0.179 without); exact backward differences for the
#: embedding (embedding_window None; 6 samples: 0.87, 12 samples: 1.95).
#: dy~/da of the torque held over one sample (ArmActionJacobian(hold=dt), about (M^-1 dt^2/2, M^-1 dt, M^-1)), attending
#: orders 0..2: tuned objective on seeds 1000-1004 0.108 against 0.141 for the instantaneous column's tuned agent.
#: cause_prior_log_precision "sensor" (the roll axis's rule, P_v = 1 / sensor_std^2): at exp(8) the believed target
#: yields to the data (--loop-shape --plant arm: 0.43-1.20 rad per rad of joint angle at 1-10 rad/s; on the step it
#: starts 0.50 rad short at 0.05 s, seed 1000), so the agent starts slowly. Tuned objective on seeds 1000-1004 0.1001
#: against 0.108 at exp(8) (log P_v 12: 0.0999, 13: 0.1008).
ARM_SETTINGS = dict(
    plant="arm", dt=0.01, duration=4.0, start=(-np.pi / 2, 0.0), target=(-0.6, 0.8), track_centre=(-0.8, 1.0),
    track_amplitude=(0.4, 0.3), track_rate=(1.5, 2.0), torque_noise_std=(0.5, 0.2), torque_kernel_width=0.1,
    sensor_std=0.002, sensor_kernel_width=0.01, torque_limits=(30.0, 10.0), effort_weight=1e-4, degrade_at=2.0,
    degrade_factor=10.0, learning_time_constants=(0.25, 0.5, 1.0), learning_orders=("value", "all"),
    embedding_order=2, cause_prior_log_precision="sensor", embedding_window=None, settling_band=0.02,
    jacobian_tolerance=0.02, substeps=2, random_error=0.3, reference_acceleration=True, action_hold=True,
    sensory_orders=2,
    model_errors=(("masses, inertias x 0.7", dict(link_masses=0.7, link_inertias=0.7)),
                  ("masses, inertias x 1.3", dict(link_masses=1.3, link_inertias=1.3)),
                  ("payload: link 2 x 1.3", dict(link_masses=(1.0, 1.3), link_inertias=(1.0, 1.3))),
                  ("friction x 1.3", dict(joint_friction=1.3))),
)
#: the parameters drawn independently in [1 - e, 1 + e] per evaluation seed for the "random +-30 %" case
ARM_RANDOM_FIELDS = ("link_masses", "com_distances", "link_inertias", "joint_friction")


def arm_reference(task, cfg):
    """(r(t) -> (2,), trajectory t -> (r, r', r'')) [rad, rad/s, rad/s^2] of the task."""
    if task == "step":
        target = np.asarray(cfg["target"], dtype=float)
        return (lambda t: target), (lambda t: (target, np.zeros(2), np.zeros(2)))
    centre, amp, rate = (np.asarray(cfg[k], dtype=float) for k in ("track_centre", "track_amplitude", "track_rate"))
    speed, curvature = amp * rate, -amp * rate**2

    def trajectory(t):
        sine = np.sin(rate * t)
        return centre + amp * sine, speed * np.cos(rate * t), curvature * sine
    return (lambda t: centre + amp * np.sin(rate * t)), trajectory


def arm_start(task, cfg):
    """The arm's angles at t = 0 (at rest): hanging for the step, the centre of the reference for tracking."""
    return np.asarray(cfg["start"] if task == "step" else cfg["track_centre"], dtype=float)


def arm_world(cfg, task, degrade=False, params=None):
    """The arm plant for ``task`` (true parameters ``params``, default nominal), sensor 2 of both joints degrading."""
    scale = None
    if degrade:
        at, factor = cfg["degrade_at"], cfg["degrade_factor"]
        scale = lambda t: np.array([1.0, 1.0, factor, factor]) if t >= at else 1.0  # noqa: E731
    return arm.arm_plant(params or arm.ArmParameters(), initial_angles=arm_start(task, cfg),
                         torque_noise_std=cfg["torque_noise_std"], torque_kernel_width=cfg["torque_kernel_width"],
                         sensor_std=cfg["sensor_std"], sensor_kernel_width=cfg["sensor_kernel_width"],
                         torque_limits=cfg["torque_limits"], sensor_noise_scale=scale, substeps=cfg["substeps"])


def arm_operating_angles(task, cfg):
    """The pose the model-based designs are made at: the target (step) or the reference's centre (tracking)."""
    return np.asarray(cfg["target"] if task == "step" else cfg["track_centre"], dtype=float)


def make_arm_pid(theta, task, cfg):
    """PID per joint with gravity feed-forward; gains per unit of the joint's inertia M_ii at the operating pose."""
    kp, ki, kd, tau = np.exp(theta)
    model = arm.ArmParameters()
    inertia = np.diag(arm.mass_matrix(model, arm_operating_angles(task, cfg)))
    gains = np.column_stack([inertia * kp, inertia * ki, inertia * kd, [tau, tau]])
    r, _ = arm_reference(task, cfg)
    return arm.joint_pid(model, cfg["dt"], gains=gains, reference=r, torque_limits=cfg["torque_limits"])


def make_arm_lqg(theta, task, cfg):
    """LQG on the nominal arm linearised at the operating pose; tracking: the reference and its inverse dynamics."""
    q_pos, q_vel, q_int, w_scale = np.exp(theta)
    model = arm.ArmParameters()
    q_o = arm_operating_angles(task, cfg)
    A, B, _ = arm.linearise(model, q_o)
    from attend.models.linear import zero_order_hold

    _, Wd = zero_order_hold(A, np.eye(4), cfg["dt"])
    Minv = np.linalg.inv(arm.mass_matrix(model, q_o))
    accel = Minv @ np.diag(np.square(cfg["torque_noise_std"])) @ Minv.T  # torque noise as acceleration noise
    W = w_scale * Wd @ np.block([[np.zeros((2, 2)), np.zeros((2, 2))], [np.zeros((2, 2)), accel]]) @ Wd.T \
        + 1e-12 * np.eye(4)
    r, trajectory = arm_reference(task, cfg)
    return arm.ArmLQG(model, cfg["dt"], operating_angles=q_o, reference=r,
                      reference_trajectory=trajectory if task == "track" else None,
                      initial_angles=arm_start(task, cfg), state_weight=[q_pos, q_pos, q_vel, q_vel],
                      integral_weight=q_int, action_weight=1.0, process_covariance=W,
                      sensor_covariance=cfg["sensor_std"] ** 2 * np.eye(4), torque_limits=cfg["torque_limits"])


def arm_action_jacobian(cfg):
    """dy~/da of the agent: the nominal arm at the believed pose (held over dt with cfg["action_hold"])."""
    return arm.ArmActionJacobian(arm.ArmParameters(), cfg["embedding_order"], tolerance=cfg["jacobian_tolerance"],
                                 hold=cfg["dt"] if cfg["action_hold"] else 0.0)


def make_arm_aif(theta, task, cfg, learning=None, feedforward=True, action_jacobian=None):
    """Active inference: each joint believed drawn critically damped to the reference (r, r') (prior on the causes);
    dy~/da from the nominal arm at the believed pose (``action_jacobian``: default :func:`arm_action_jacobian`); plus
    the nominal gravity torque at the believed pose."""
    omega, process_precision, gain, kernel_width = np.exp(theta)
    _, trajectory = arm_reference(task, cfg)

    with_acceleration = cfg["reference_acceleration"]

    squared_rate = -np.asarray(cfg["track_rate"]) ** 2
    held = np.concatenate([trajectory(0.0)[0], np.zeros(10 if with_acceleration else 6)])

    def prior(t):  # eta~ = [v; v'], v = (r, r') or (r, r', r''), v' its derivative
        if task == "step":  # the target, at rest
            return held.copy()
        q, w, acc = trajectory(t)
        if not with_acceleration:
            return np.concatenate([q, w, w, acc])
        return np.concatenate([q, w, acc, w, acc, squared_rate * w])
    model = arm.critically_damped_model(
        omega, sensor_std=cfg["sensor_std"], process_precision=process_precision, kernel_width=kernel_width,
        cause_prior=prior, cause_prior_precision=np.exp(cause_log_precision(cfg)),
        embedding_order=cfg["embedding_order"], initial_angles=arm_start(task, cfg),
        reference_acceleration=with_acceleration)
    nominal = arm.ArmParameters()
    limit = np.asarray(cfg["torque_limits"])
    controller = ActiveInferenceController(
        model, cfg["dt"], action_gain=gain, n_actions=2,
        action_jacobian=arm_action_jacobian(cfg) if action_jacobian is None else action_jacobian,
        action_limits=(-limit, limit), precision_learning=learning, embedding_window=cfg["embedding_window"],
        sensory_orders=cfg["sensory_orders"], data_motion=cfg.get("data_motion", "held"))
    return arm.GravityFeedforward(controller, nominal, "believed") if feedforward else controller


#: the agent's tuned point in docs/control.md (intention at 1 / sensor_std^2: w 14.9 rad/s, Pi_w 1.33e7, kappa 64.7,
#: s 22.2 ms; at exp(8) it was w 11.5 rad/s, Pi_w 2.1e6, kappa 533, s 12.2 ms), for its step time
ARM_TIMING_THETA = np.log([14.9, 1.33e7, 64.7, 0.0222])


def arm_step_time(cfg, theta=ARM_TIMING_THETA, runs=5, warm_up=20):
    """{task: (median, mean) wall time [s] of the arm agent's step, refreshes of dy~/da per run}: the outputs of seed
    0's closed loop are replayed through ``runs`` fresh agents (the same beliefs and actions as in the loop), each
    step timed alone (GravityFeedforward(ActiveInferenceController).step), the first ``warm_up`` steps of each run
    left out."""
    out = {}
    for task in ("step", "track"):
        outputs = arm_run(make_arm_aif(theta, task, cfg), task, cfg, 0).outputs
        times = []
        for _ in range(runs):
            jacobian = arm_action_jacobian(cfg)
            agent = make_arm_aif(theta, task, cfg, action_jacobian=jacobian)
            taken = np.empty(len(outputs))
            for i, y in enumerate(outputs):
                started = time.perf_counter()
                agent.step(y)
                taken[i] = time.perf_counter() - started
            times.append(taken[warm_up:])
        times = np.concatenate(times)
        out[task] = (float(np.median(times)), float(np.mean(times)), jacobian.refreshes)
    return out


ARM_MAKERS = {"PID": make_arm_pid, "LQG": make_arm_lqg, "active inference": make_arm_aif}
BOUNDS["arm"] = {  # PID gains per unit of joint inertia [1/s^2, 1/s^3, 1/s], tau_d [s]; LQR weights (R = I, N m)
    "PID": [(1.0, 1e5), (0.1, 1e6), (0.1, 1e3), (1e-3, 0.3)],
    "LQG": [(1.0, 1e8), (1e-2, 1e5), (1.0, 1e10), (1e-3, 1e4)],
    "active inference": [(0.5, 40.0), (1.0, 1e8), (1e-1, 1e7), (1e-3, 0.3)],
}


def makers(cfg):
    """The three controllers' constructors for ``cfg``'s plant."""
    return ARM_MAKERS if cfg["plant"] == "arm" else MAKERS


def arm_run(controller, task, cfg, seed, plant=None):
    """One closed loop on the arm (None if it diverged)."""
    try:
        return run(plant or arm_world(cfg, task), controller, cfg["duration"], seed=seed, record_beliefs=False)
    except ClosedLoopDivergence:
        return None


def arm_metrics(loop, task, cfg):
    """(ITAE summed over the joints, overshoot (largest joint) [%], settling (slowest joint) [s], effort) of a run."""
    r, _ = arm_reference(task, cfg)
    target = np.array([r(t) for t in loop.time])
    effort = float(np.sum(loop.actions**2) * cfg["dt"])
    if task == "track":
        return sum(itae(loop.time, loop.states[:, i], target[:, i]) for i in range(2)), np.nan, np.nan, effort
    joints = [step_metrics(loop.time, loop.states[:, i], target[:, i], loop.actions, band=cfg["settling_band"])
              for i in range(2)]
    return (sum(m.itae for m in joints), max(m.overshoot for m in joints), max(m.settling_time for m in joints),
            effort)


def evaluate_arm(controller, task, cfg, seed, plant=None):
    """(ITAE, overshoot, settling, effort) of one run on the arm; inf if the loop diverges."""
    loop = arm_run(controller, task, cfg, seed, plant)
    return (np.inf,) * 4 if loop is None else arm_metrics(loop, task, cfg)


def random_arm(cfg, seed):
    """The arm with each of ARM_RANDOM_FIELDS (per link) drawn in [1 - e, 1 + e] x nominal (e = random_error)."""
    rng = np.random.default_rng(10_000 + seed)
    e = cfg["random_error"]
    return arm.ArmParameters().scaled(**{name: rng.uniform(1 - e, 1 + e, 2) for name in ARM_RANDOM_FIELDS})


def median_row(rows):
    return np.median(np.asarray(rows, dtype=float), axis=0)


def plot_arm(cfg, tuned, out_dir, learning):
    """arm_responses.png: seed 0's joint angles and torques of the three controllers (step, tracking, sensor 2
    degrading during the step with fixed and learned precision) into ``out_dir``."""
    from attend.plotting import new_figure

    fig, axes = new_figure(out_dir, (13, 9), 3, 3)
    colours = {"PID": "C0", "LQG": "C1", "active inference": "C3"}
    for row, (task, degrade) in enumerate((("step", False), ("track", False), ("step", True))):
        r, _ = arm_reference(task, cfg)
        variants = {name: ARM_MAKERS[name](tuned[name], task, cfg) for name in ARM_MAKERS}
        if degrade:
            variants["active inference, learned"] = make_arm_aif(tuned["active inference"], task, cfg, learning)
        for label, controller in variants.items():
            loop = arm_run(controller, task, cfg, 0, arm_world(cfg, task, degrade))
            if loop is None:
                continue
            style = dict(color=colours.get(label, "C2"), lw=1.2, ls="--" if "learned" in label else "-")
            for joint in range(2):
                axes[row, joint].plot(loop.time, loop.states[:, joint], label=label, **style)
            axes[row, 2].plot(loop.time, loop.actions[:, 0], **style)
            axes[row, 2].plot(loop.time, loop.actions[:, 1], alpha=0.5, **style)
        target = np.array([r(t) for t in loop.time])
        for joint in range(2):
            axes[row, joint].plot(loop.time, target[:, joint], "k:", lw=1, label="reference")
            axes[row, joint].set_ylabel(f"q{joint + 1} [rad]")
        axes[row, 2].set_ylabel("torque [N m] (q1 solid, q2 faint)")
        title = {0: "step", 1: "tracking", 2: f"step, sensor 2 noise x{cfg['degrade_factor']:g} from "
                 f"{cfg['degrade_at']:g} s"}[row]
        axes[row, 0].set_title(title, loc="left", fontsize=10)
        if degrade:
            for axis in axes[row]:
                axis.axvline(cfg["degrade_at"], color="0.6", lw=0.8)
    axes[0, 0].legend(fontsize=8)
    axes[2, 0].legend(fontsize=8)
    for axis in axes[-1]:
        axis.set_xlabel("time [s]")
    fig.tight_layout()
    path = Path(out_dir) / "arm_responses.png"
    fig.savefig(path, dpi=100)
    return path


def compare_arm(cfg, tune_seeds, eval_seeds, evaluations, out_dir, restarts=1):
    """Tune the three controllers on the arm (on ``tune_seeds``, ``evaluations`` runs per restart, ``restarts``
    restarts: see :func:`tune`) and print every figure beside its target (medians over ``eval_seeds``; response
    plots in ``out_dir`` unless None)."""
    params = arm.ArmParameters()
    print(f"two-link arm in the vertical plane: masses {params.link_masses} kg, lengths {params.link_lengths} m, "
          f"centres of mass {params.com_distances} m, inertias {tuple(round(i, 4) for i in params.link_inertias)} "
          f"kg m^2, friction {params.joint_friction} N m s/rad; torque limits {cfg['torque_limits']} N m; torque "
          f"disturbance std {cfg['torque_noise_std']} N m (kernel width {cfg['torque_kernel_width']} s); 2 angle "
          f"sensors per joint, std {cfg['sensor_std'] * 1e3:g} mrad (kernel width {cfg['sensor_kernel_width']} s)")
    print(f"step {np.round(cfg['start'], 3).tolist()} -> {list(cfg['target'])} rad; tracking "
          f"{list(cfg['track_centre'])} + {list(cfg['track_amplitude'])} sin({list(cfg['track_rate'])} t) rad; "
          f"dt = {cfg['dt']:g} s, {cfg['duration']} s per task; tuning seeds {list(tune_seeds)}, {evaluations} "
          f"evaluations each{restart_label(restarts)}; evaluation seeds 0..{len(eval_seeds) - 1}; figures are medians "
          f"over the evaluation seeds")
    tuned = {}
    for name in ARM_MAKERS:
        t0 = time.perf_counter()
        theta, value, nfev, restart_objectives = tune(name, cfg, tune_seeds, evaluations, restarts=restarts)
        tuned[name] = theta
        print(f"  tuned {name:17s} objective {value:.4f} ({nfev} runs of {2 * len(tune_seeds)} loops, "
              f"{time.perf_counter() - t0:.0f} s): exp(theta) = {np.round(np.exp(theta), 4).tolist()}"
              + restart_note(restart_objectives))
    every = {**ARM_MAKERS, **{matched(name): ARM_MAKERS[name] for name in ARM_MAKERS}}
    t0 = time.perf_counter()
    thetas, values, caps = tune_effort_matched(cfg, tune_seeds, evaluations, tuned, np.median)
    tuned.update(thetas)
    print(f"  effort-matched (Nelder-Mead from each tuned point on mean ITAE, median effort per task <= the lower "
          f"baseline's on the tuning seeds: step {caps['step']:.1f}, track {caps['track']:.1f}; "
          f"{time.perf_counter() - t0:.0f} s):")
    for name, theta in thetas.items():
        print(f"    {name:22s} objective {values[name]:.4f}: exp(theta) = {np.round(np.exp(theta), 4).tolist()}")

    # nominal plant ---------------------------------------------------------------------------------
    nominal, step_seconds = {}, {}
    for name in every:
        for task in ("step", "track"):
            rows = []
            for seed in eval_seeds:
                loop = arm_run(every[name](tuned[name], task, cfg), task, cfg, seed)
                rows.append((np.inf,) * 4 if loop is None else arm_metrics(loop, task, cfg))
                if loop is not None:
                    step_seconds.setdefault(name, []).append(np.median(loop.step_seconds))
            nominal[name, task] = np.array(rows)
    print(f"\nnominal arm (median over {len(eval_seeds)} evaluation seeds; ITAE summed over both joints; overshoot of "
          f"the larger joint; settling band {100 * cfg['settling_band']:g} % of each joint's step, the slower joint)")
    print(f"  {'controller':22s} {'ITAE step':>10s} {'overshoot %':>11s} {'settling s':>10s} {'effort':>10s} "
          f"{'ITAE track':>10s} {'effort track':>12s} {'step us':>8s}")
    for name in every:
        s, tr = median_row(nominal[name, "step"]), median_row(nominal[name, "track"])
        print(f"  {name:22s} {s[0]:10.4f} {s[1]:11.2f} {s[2]:10.2f} {s[3]:10.1f} {tr[0]:10.4f} {tr[3]:12.1f} "
              f"{np.median(step_seconds.get(name, [np.nan])) * 1e6:8.1f}")
    for names, task in [(n, t) for n in (THREE, tuple(map(matched, THREE))) for t in ("step", "track")]:
        agent = names[0]
        aif, pid, lqg = (nominal[n, task][:, 0] for n in names)
        d_pid, d_lqg = interval(aif - pid), interval(aif - 1.2 * lqg)
        m_aif, m_pid, m_lqg = np.median(aif), np.median(pid), np.median(lqg)
        print(f"  {task} ITAE: {agent} {m_aif:.4f} vs {names[1]} {m_pid:.4f} (target <= PID: "
              f"{'met' if m_aif <= m_pid else 'NOT met'}; paired mean difference {d_pid[0]:+.4f}, 95 % "
              f"[{d_pid[1]:+.4f}, {d_pid[2]:+.4f}]); vs 1.2 x LQG = {1.2 * m_lqg:.4f} "
              f"({'met' if m_aif <= 1.2 * m_lqg else 'NOT met'}; paired mean difference {d_lqg[0]:+.4f}, 95 % "
              f"[{d_lqg[1]:+.4f}, {d_lqg[2]:+.4f}])")

    # model error -----------------------------------------------------------------------------------
    e = cfg["random_error"]
    print(f"\nmodel error: median ITAE on the changed arm / median nominal ITAE (every controller's model, dy~/da and "
          f"gravity feed-forward stay nominal); 'random +-{100 * e:g} %': {', '.join(ARM_RANDOM_FIELDS)} of each link "
          f"drawn in [{1 - e:g}, {1 + e:g}] x nominal, one arm per evaluation seed")
    cases = [(label, lambda seed, change=change: params.scaled(**change)) for label, change in cfg["model_errors"]]
    cases.append((f"random +-{100 * e:g} %", lambda seed: random_arm(cfg, seed)))
    for task in ("step", "track"):
        print(f"  {task:6s} {'arm':24s} " + " ".join(f"{name:>17s}" for name in ARM_MAKERS))
        worst = {name: (0.0, "") for name in ARM_MAKERS}
        for label, true_arm in cases:
            ratios = []
            for name in ARM_MAKERS:
                rows = [evaluate_arm(ARM_MAKERS[name](tuned[name], task, cfg), task, cfg, seed,
                                     arm_world(cfg, task, params=true_arm(seed)))[0] for seed in eval_seeds]
                ratio = np.median(rows) / np.median(nominal[name, task][:, 0])
                worst[name] = max(worst[name], (ratio, label))
                ratios.append(ratio)
            print(f"  {task:6s} {label:24s} " + " ".join(f"{value:17.3f}" for value in ratios))
        print(f"  {task} worst ratio: " + ", ".join(f"{name} {value:.3f} ({label})" for name, (value, label)
                                                 in worst.items()) + " (reported beside LQG's and PID's; no target)")

    # degrading sensor ------------------------------------------------------------------------------
    theta = tuned["active inference"]
    choices = [(tc, orders) for tc in cfg["learning_time_constants"] for orders in cfg["learning_orders"]]

    def learned_objective(learning):
        return np.mean([evaluate_arm(make_arm_aif(theta, task, cfg, learning), task, cfg, seed,
                                     arm_world(cfg, task, degrade=True))[0]
                        for task in ("step", "track") for seed in tune_seeds])
    groups = (0, 1, 0, 1)  # the relative level shares precision among each joint's sensors
    scores = {(tc, orders): learned_objective(SensorPrecisionLearning(time_constant=tc, level="relative", orders=orders,
                                                                      groups=groups))
              for tc, orders in choices}
    tc, orders = min(scores, key=scores.get)
    print(f"\nsensor 2 of both joints degrades (noise x{cfg['degrade_factor']:g} from t = {cfg['degrade_at']:g} s); "
          f"learning: time constant {tc:g} s, orders '{orders}' (chosen on the tuning seeds from "
          + ", ".join(f"{c[0]:g} s/{c[1]}: {v:.4f}" for c, v in scores.items()) + ")")
    variants = {"active inference, fixed precision": None}
    for level in ("relative", "absolute"):
        variants[f"active inference, learned ({level})"] = SensorPrecisionLearning(time_constant=tc, level=level,
                                                                                   orders=orders, groups=groups)
    for task in ("step", "track"):
        degraded = arm_world(cfg, task, degrade=True)
        results = {}
        for label, learning in variants.items():
            results[label] = np.array([evaluate_arm(make_arm_aif(theta, task, cfg, learning), task, cfg, seed,
                                                    degraded)[0] for seed in eval_seeds])
        for label in ("PID", "LQG"):
            results[label] = np.array([evaluate_arm(ARM_MAKERS[label](tuned[label], task, cfg), task, cfg, seed,
                                                    degraded)[0] for seed in eval_seeds])
        print(f"  {task} median ITAE: " + ", ".join(f"{label} {np.median(v):.4f}" for label, v in results.items()))
        for level in ("relative", "absolute"):
            diff = results[f"active inference, learned ({level})"] - results["active inference, fixed precision"]
            mean, low, high = interval(diff)
            verdict = "met" if high < 0 else ("NOT met" if low > 0 else "not resolved (interval contains 0)")
            print(f"  {task}: learned ({level}) - fixed ITAE: mean {mean:+.4f}, 95 % interval [{low:+.4f}, {high:+.4f}], "
                  f"median {np.median(diff):+.4f} over {len(eval_seeds)} paired seeds (target < 0: {verdict})")
    if out_dir is not None:
        path = plot_arm(cfg, tuned, out_dir, SensorPrecisionLearning(time_constant=tc, level="relative", orders=orders,
                                                                     groups=groups))
        print(f"\nresponses (seed 0) plotted in {path}")
    return tuned


#: the roll axis's tuned points (exp(theta) as the benchmark prints them) that --loop-shape analyses: the baselines,
#: the agent tuned with its intention at exp(8) (before) and at the sensors' precision (after), docs/control.md
LOOP_SHAPE_POINTS = {
    "PID": ("PID", [2248.6225, 49574.0211, 104.4275, 0.001], {}),
    "LQG": ("LQG", [12589.9686, 26.1237, 2713573985.9346, 32042.6154], {}),
    "AI, intention exp(8)": ("active inference", [12.3, 4.1e8, 5.2e4, 0.0060], dict(cause_prior_log_precision=8.0)),
    "AI, intention 1/sigma^2": ("active inference", [17.35941, 587.74831, 9365.84893, 0.01232], {}),
}


def controller_map(name, controller):
    """(A, B, C, D) of a tuned controller as a linear map y[k] -> a[k] (no saturation, reference 0):
    q[k+1] = A q + B y, a = C q + D y. The agent's from attend.control.linear_controller; the PID's and LQG's
    from their gains (baselines.py's update equations)."""
    from attend.control import linear_controller

    dt = controller.dt
    if name == "active inference":
        return linear_controller(controller)
    if name == "PID":
        kp, ki, kd, tau = controller.kp, controller.ki, controller.kd, controller.derivative_filter
        w, g = controller.output_weights.reshape(1, -1), 1.0 / (tau + dt)
        A = np.array([[1.0, 0.0, 0.0], [0.0, tau * g, kd * g], [0.0, 0.0, 0.0]])  # integral, derivative, last input
        B = np.vstack([-ki * dt * w, -kd * g * w, w])
        return A, B, np.array([[1.0, tau * g, kd * g]]), -(kp + ki * dt + kd * g) * w
    Ad, Bd, C, L, Kx, Ki, H = (controller._Ad, controller._Bd, controller._C, controller._L, controller._Kx,
                               controller._Ki, controller._H)
    n, p = Ad.shape[0], H.shape[0]
    M = np.eye(n) - L @ C  # x^[k|k] = M x^[k|k-1] + L y; q = [x^[k|k-1], xi]
    Cq, Dq = np.hstack([-Kx @ M, -Ki]), -Kx @ L
    A = np.vstack([np.hstack([Ad @ M, np.zeros((n, p))]) + Bd @ Cq, np.hstack([-dt * H @ M, np.eye(p)])])
    return A, np.vstack([Ad @ L + Bd @ Dq, -dt * H @ L]), Cq, Dq


def loop_shape(cfg, points=None, n_frequencies=6000):
    """Print the roll axis's loops at the tuned ``points`` (LOOP_SHAPE_POINTS): each controller as a linear map
    (controller_map) closed around the sampled plant, the wind (the identified Gaussian-kernel spectrum) and the sensor
    noise as inputs. Per frequency band, the steady-state variance of the roll they cause ((1/pi) int |H|^2 Phi dtheta
    over the band); crossover, phase margin, max |S|, |K| at 1 and 5 rad/s, rms action; for the agent, how far its
    belief about the target (v1) moves per unit of roll in the wind's band."""
    from attend.models.linear import zero_order_hold
    from attend.models.noise import gaussian_kernel

    wind = identify_roll_disturbance()
    cfg = dict(cfg, disturbance_std=wind.std, disturbance_kernel_width=wind.kernel_width)
    dt = cfg["dt"]
    A, B = plant_matrices(cfg)
    Ad, drive = zero_order_hold(A, np.hstack([B, np.eye(2)]), dt)
    Bd, Wd = drive[:, :1], drive[:, 2:3]  # the wind drives the rate
    theta = np.linspace(1e-4, np.pi, n_frequencies)
    omega, z = theta / dt, np.exp(1j * theta)

    def spectrum(width, std):  # of std * (kernel * white) / |kernel|, per rad/sample
        h = gaussian_kernel(dt, width)
        return std**2 * np.abs(np.exp(-1j * np.outer(theta, np.arange(h.size))) @ h) ** 2 / np.sum(h**2)
    Phi_d = spectrum(cfg["disturbance_kernel_width"], cfg["disturbance_std"])
    Phi_n = spectrum(cfg["sensor_kernel_width"], cfg["sensor_std"])
    bands = [0, 2, 5, 10, 20, 40, 80, 400]
    rows = {}
    for label, (name, values, change) in (points or LOOP_SHAPE_POINTS).items():
        controller = makers(cfg)[name](np.log(values), "step", {**cfg, **change})
        Ac, Bc, Cc, Dc = controller_map(name, controller)
        nq = Ac.shape[0]
        Acl = np.block([[Ad + Bd @ Dc @ C2, Bd @ Cc], [Bc @ C2, Ac]])  # [x; q], inputs [d, n1, n2]
        Bcl = np.block([[Wd, Bd @ Dc], [np.zeros((nq, 1)), Bc]])
        Ca, Da = np.hstack([Dc @ C2, Cc]), np.hstack([np.zeros((1, 1)), Dc])
        I = np.eye(Acl.shape[0])
        X = np.array([np.linalg.solve(zi * I - Acl, Bcl) for zi in z])  # (F, states, inputs)
        phi, act = X[:, 0, :], np.einsum("j,fji->fi", Ca[0], X) + Da[0]
        K = np.array([(Cc @ np.linalg.solve(zi * np.eye(nq) - Ac, Bc) + Dc).sum() for zi in z])
        P = np.array([np.linalg.solve(zi * np.eye(2) - Ad, Bd)[0, 0] for zi in z])
        loop = -K * P
        dth = theta[1] - theta[0]
        wind_density = np.abs(phi[:, 0]) ** 2 * Phi_d / np.pi
        noise_density = (np.abs(phi[:, 1]) ** 2 + np.abs(phi[:, 2]) ** 2) * Phi_n / np.pi
        action = (np.abs(act[:, 0]) ** 2 * Phi_d + (np.abs(act[:, 1]) ** 2 + np.abs(act[:, 2]) ** 2) * Phi_n) / np.pi
        cross = int(np.argmax(np.abs(loop) < 1))
        at = lambda w: int(np.argmin(np.abs(omega - w)))  # noqa: E731
        extra = ""
        if name == "active inference":  # v1, the believed target: after the plant's x, the window and x~ in [x; q]
            model = controller.model
            size_x, size_v = (model.embedding_order + 1) * model.n_states, (model.cause_order + 1) * model.n_causes
            v1 = 2 + (nq - size_x - size_v - controller.n_actions) + size_x
            extra = "; target belief moves per unit roll: " + ", ".join(
                f"{abs(X[at(w), v1, 0] / phi[at(w), 0]):.2f} at {w:g}" for w in (1, 5, 10)) + " rad/s"
        rows[label] = [np.sum(d[(omega >= lo) & (omega < hi)]) * dth * 1e6 for lo, hi in zip(bands[:-1], bands[1:])
                       for d in (wind_density, noise_density)]
        wind_var, noise_var = wind_density.sum() * dth, noise_density.sum() * dth
        print(f"  {label:24s} rms roll {1e3 * np.sqrt(wind_var + noise_var):.2f} mrad "
              f"(wind {1e3 * np.sqrt(wind_var):.2f}, noise {1e3 * np.sqrt(noise_var):.2f})"
              f", rms action {np.sqrt(action.sum() * dth):.1f}; crossover {omega[cross]:.1f} rad/s, phase margin "
              f"{180 + np.degrees(np.angle(loop[cross])):.1f} deg, max |S| {np.abs(1 / (1 + loop)).max():.2f}; |K| "
              f"{abs(K[at(1)]):.0f} at 1 rad/s, {abs(K[at(5)]):.0f} at 5 rad/s{extra}")
    print("  variance of the roll per band [mrad^2], wind / sensor noise:")
    print(f"    {'band [rad/s]':12s} " + " ".join(f"{label:>24s}" for label in rows))
    for i, (lo, hi) in enumerate(zip(bands[:-1], bands[1:])):
        print(f"    {f'{lo}-{hi}':12s} " + " ".join(f"{r[2 * i]:11.3f} / {r[2 * i + 1]:10.3f}" for r in rows.values()))


#: the mass-spring-damper's and the arm's tuned points (exp(theta) as the benchmark prints them, docs/control.md) for
#: --loop-shape: the baselines, the agent tuned with its intention at exp(8), the same point with P_v = 1 / sensor_std^2
#: (the structure alone), and the agent retuned at 1 / sensor_std^2; on the mass-spring-damper those three with its
#: agent before 2026-11-27 (MSD_BEFORE), and its agent since (held dy~/da, r'' a cause, moving data; exp(8)) as tuned
MSD_LOOP_SHAPE_POINTS = {
    "PID": ("PID", [216.0, 1638.0, 25.8, 0.025], {}),
    "LQG": ("LQG", [222.0, 455.0, 4.1e5, 995.0], {}),
    "AI, exp(8)": ("active inference", [10.6, 8.6e4, 2.7e5, 0.0037],
                   dict(MSD_BEFORE, cause_prior_log_precision=8.0)),
    "AI, exp(8) pt, 1/s^2": ("active inference", [10.6, 8.6e4, 2.7e5, 0.0037],
                             dict(MSD_BEFORE, cause_prior_log_precision="sensor")),
    "AI, 1/s^2 (retuned)": ("active inference", [12.765, 4410.77, 1534.11, 0.015597],
                            dict(MSD_BEFORE, cause_prior_log_precision="sensor")),
    "AI, held dy~/da, r''": ("active inference", [5.8418, 6.049e8, 148.6287, 0.0224], {}),
}
ARM_LOOP_SHAPE_POINTS = {
    "PID": ("PID", [641.0, 5529.0, 37.1, 0.0015], {}),
    "LQG": ("LQG", [295.0, 0.86, 5.8e6, 736.0], {}),
    "AI, exp(8)": ("active inference", [11.5, 2.1e6, 533.0, 0.0122], dict(cause_prior_log_precision=8.0)),
    "AI, exp(8) pt, 1/s^2": ("active inference", [11.5, 2.1e6, 533.0, 0.0122],
                             dict(cause_prior_log_precision="sensor")),
    "AI, 1/s^2 (retuned)": ("active inference", [14.8981, 1.32524e7, 64.7288, 0.022179],
                            dict(cause_prior_log_precision="sensor")),
}


def plant_loop_maps(cfg, name, controller):
    """(Ad, Bd, Wd, disturbance std per channel, kernel width, joints, (A, B, C, D) of the controller with the
    gravity feed-forward linearised, [rows of q holding the believed target's angles] or None) of the
    mass-spring-damper or the arm (linearised at rest at the step's target), for :func:`plant_loop_shape`."""
    from attend.control import linear_controller
    from attend.models.linear import zero_order_hold

    dt = cfg["dt"]
    if cfg["plant"] != "arm":
        A, B = plant_matrices(cfg)
        Ad, drive = zero_order_hold(A, np.hstack([B, np.eye(2)]), dt)
        Bd, Wd = drive[:, :1], drive[:, 2:3]
        std, width = np.array([cfg["force_std"] / cfg["mass"]]), cfg["force_kernel_width"]
        Ac, Bc, Cc, Dc = controller_map(name, controller)
        v1 = None
        if name == "active inference":
            model = controller.model
            size_x = (model.embedding_order + 1) * model.n_states
            v1 = [Ac.shape[0] - controller.n_actions - (model.cause_order + 1) * model.n_causes]  # after x~
            assert size_x + (model.cause_order + 1) * model.n_causes + controller.n_actions <= Ac.shape[0]
        return Ad, Bd, Wd, std, width, [0], (Ac, Bc, Cc, Dc), v1
    params = arm.ArmParameters()
    q_o = np.asarray(cfg["target"], dtype=float)
    A, B, _ = arm.linearise(params, q_o)
    Ad, Bd = zero_order_hold(A, B, dt)
    h = 1e-6  # dg/dq at the target, for the feed-forward at the measured (PID) or believed (agent) angles
    Gq = np.column_stack([(arm.gravity_torque(params, q_o + h * e) - arm.gravity_torque(params, q_o - h * e)) / (2 * h)
                          for e in np.eye(2)])
    v1 = None
    if name == "PID":
        maps = [controller_map("PID", joint) for joint in controller.joints]
        sizes = [m[0].shape[0] for m in maps]
        Ac = np.zeros((sum(sizes), sum(sizes)))
        Ac[: sizes[0], : sizes[0]], Ac[sizes[0]:, sizes[0]:] = maps[0][0], maps[1][0]
        Bc = np.vstack([m[1] for m in maps])
        Cc = np.zeros((2, sum(sizes)))
        Cc[0, : sizes[0]], Cc[1, sizes[0]:] = maps[0][2][0], maps[1][2][0]
        mean = np.zeros((2, 4))
        mean[0, 0::2] = mean[1, 1::2] = 0.5
        Dc = np.vstack([maps[0][3], maps[1][3]]) + Gq @ mean
    elif name == "LQG":
        Ac, Bc, Cc, Dc = controller_map("LQG", controller.lqg)
    else:
        agent = controller.controller
        Ac, Bc, Cc, Dc = linear_controller(agent)
        angles = [Ac.shape[0] - agent._Z.size + i for i in range(2)]  # the believed angles: x~'s first rows in Z
        Cc, Dc = Cc + Gq @ Ac[angles], Dc + Gq @ Bc[angles]  # g^ at the beliefs after the step
        model = agent.model
        v1 = [Ac.shape[0] - agent._Z.size + (model.embedding_order + 1) * model.n_states + i for i in range(2)]
    return Ad, Bd, Bd, np.asarray(cfg["torque_noise_std"], dtype=float), cfg["torque_kernel_width"], [0, 1], \
        (Ac, Bc, Cc, Dc), v1


def plant_loop_shape(cfg, points, n_frequencies=3000, bands=(0, 0.5, 1, 2, 5, 10, 20, 40, 80, 400)):
    """:func:`loop_shape` for the mass-spring-damper and the arm (linearised at rest at the step's target, torque
    disturbance on each joint, every controller with its gravity feed-forward linearised): per controlled angle the
    steady-state variance per band (disturbance / sensor noise), the loop gain |K| (angle -> own torque, summed over
    the joint's sensors) at 1 and 5 rad/s, crossover and phase margin of the joint's own loop, rms action, and for the
    agent how far its believed target moves per unit of the angle."""
    from attend.models.noise import gaussian_kernel

    dt = cfg["dt"]
    theta = np.linspace(1e-4, np.pi, n_frequencies)
    omega, z = theta / dt, np.exp(1j * theta)
    dth = theta[1] - theta[0]

    def shape(width):
        h = gaussian_kernel(dt, width)
        return np.abs(np.exp(-1j * np.outer(theta, np.arange(h.size))) @ h) ** 2 / np.sum(h**2)
    at = lambda w: int(np.argmin(np.abs(omega - w)))  # noqa: E731
    rows = {}
    for label, (name, values, change) in points.items():
        run_cfg = {**cfg, **change}
        controller = makers(cfg)[name](np.log(values), "step", run_cfg) if cfg["plant"] != "arm" or \
            name != "active inference" else make_arm_aif(
                np.log(values), "step", run_cfg,
                action_jacobian=arm_action_jacobian(run_cfg)(np.concatenate([cfg["target"], [0.0, 0.0]]), None, None))
        Ad, Bd, Wd, std, width, joints, (Ac, Bc, Cc, Dc), v1 = plant_loop_maps(cfg, name, controller)
        C = C2 if cfg["plant"] != "arm" else arm.sensor_matrix(2)
        n, nq, kd, m = Ad.shape[0], Ac.shape[0], Wd.shape[1], C.shape[0]
        Phi_d = std[None, :] ** 2 * shape(width)[:, None]
        Phi_n = cfg["sensor_std"] ** 2 * shape(cfg["sensor_kernel_width"])
        Acl = np.block([[Ad + Bd @ Dc @ C, Bd @ Cc], [Bc @ C, Ac]])
        Bcl = np.block([[Wd, Bd @ Dc], [np.zeros((nq, kd)), Bc]])
        Ca, Da = np.hstack([Dc @ C, Cc]), np.hstack([np.zeros((Dc.shape[0], kd)), Dc])
        I = np.eye(n + nq)
        X = np.array([np.linalg.solve(zi * I - Acl, Bcl) for zi in z])  # (F, states, inputs)
        act = np.einsum("aj,fji->fai", Ca, X) + Da[None]
        K = np.array([Cc @ np.linalg.solve(zi * np.eye(nq) - Ac, Bc) + Dc for zi in z])  # (F, actions, sensors)
        P = np.array([np.linalg.solve(zi * np.eye(n) - Ad, Bd) for zi in z])  # (F, states, actions)
        action_var = sum((np.abs(act[:, :, c]) ** 2 * Phi_d[:, [c]]).sum() for c in range(kd)) \
            + sum((np.abs(act[:, :, kd + s]) ** 2 * Phi_n[:, None]).sum() for s in range(m))
        rows[label] = []
        for j in joints:
            own = C[:, j] > 0  # the joint's sensors
            K_j = K[:, j, own].sum(axis=1)
            loop = -K_j * P[:, j, j]
            wind = (np.abs(X[:, j, :kd]) ** 2 * Phi_d).sum(axis=1) / np.pi
            noise = (np.abs(X[:, j, kd:]) ** 2).sum(axis=1) * Phi_n / np.pi
            rows[label].append([np.sum(d[(omega >= lo) & (omega < hi)]) * dth * 1e6
                                for lo, hi in zip(bands[:-1], bands[1:]) for d in (wind, noise)])
            cross = int(np.argmax(np.abs(loop) < 1))
            extra = ""
            if v1 is not None:
                unit = "angle" if cfg["plant"] == "arm" else "position"
                extra = f"; target belief moves per unit {unit}: " + ", ".join(
                    f"{abs(X[at(w), n + v1[j], j] / X[at(w), j, j]):.2f} at {w:g}" for w in (1, 5, 10)) + " rad/s"
            print(f"  {label:22s} {'joint ' + str(j + 1) if cfg['plant'] == 'arm' else 'position'}: rms "
                  f"{1e3 * np.sqrt((wind.sum() + noise.sum()) * dth):.2f} {'mrad' if cfg['plant'] == 'arm' else 'mm'} "
                  f"(disturbance {1e3 * np.sqrt(wind.sum() * dth):.2f}, "
                  f"noise {1e3 * np.sqrt(noise.sum() * dth):.2f}); crossover {omega[cross]:.1f} rad/s, phase margin "
                  f"{180 + np.degrees(np.angle(loop[cross])):.1f} deg, max |S| {np.abs(1 / (1 + loop)).max():.2f}; "
                  f"|K| {abs(K_j[at(1)]):.1f} at 1, {abs(K_j[at(5)]):.1f} at 5 rad/s{extra}")
        print(f"  {label:22s} rms action {np.sqrt(action_var * dth / np.pi):.2f}")
    unit = "mrad^2" if cfg["plant"] == "arm" else "mm^2"
    for i, j in enumerate(joints):
        print(f"  variance of {'joint ' + str(j + 1) if cfg['plant'] == 'arm' else 'the position'} per band [{unit}], "
              f"disturbance / sensor noise:")
        print(f"    {'band [rad/s]':12s} " + " ".join(f"{label:>24s}" for label in rows))
        for b, (lo, hi) in enumerate(zip(bands[:-1], bands[1:])):
            print(f"    {f'{lo}-{hi}':12s} " + " ".join(f"{r[i][2 * b]:11.4f} / {r[i][2 * b + 1]:10.4f}"
                                                       for r in rows.values()))


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--quick", action="store_true", help="3 tuning seeds, 50 evaluations, 8 evaluation seeds")
    parser.add_argument("--plant", choices=("msd", "roll", "arm", "both", "all", "none"), default="all",
                        help="mass-spring-damper, quadrotor roll axis, two-link arm, both (msd and roll), all (default: "
                             "the three) or none (step times only)")
    parser.add_argument("--loop-shape", action="store_true",
                        help="only the loop analysis at the documented tuned points of the plants chosen by "
                             "--plant (roll, msd, arm; a few seconds each)")
    parser.add_argument("--plots", default="results/control", metavar="DIR",
                        help="folder for the response plots (default: %(default)s); 'none': no plots")
    parser.add_argument("--restarts", type=int, default=1, metavar="K",
                        help="run the tuning (random search, then Nelder-Mead; the budget each) K times with "
                             "random-search seeds 7..7+K-1 and keep the least tuning objective, for every controller "
                             "(default: %(default)s, seed 7 alone)")
    parser.add_argument("--effort-weight", type=float, default=None, metavar="W",
                        help="the tuning objective's weight on effort, mean ITAE + W effort, for every controller "
                             "(a diagnostic: the default is each plant's, 1e-3 msd, 1e-5 roll, 1e-4 arm)")
    args = parser.parse_args()
    if args.restarts < 1:
        parser.error("--restarts must be at least 1")
    if args.effort_weight is not None and not (np.isfinite(args.effort_weight) and args.effort_weight >= 0):
        parser.error("--effort-weight must be a finite number >= 0")
    weight = {} if args.effort_weight is None else {"effort_weight": args.effort_weight}
    out_dir = None if args.plots == "none" else args.plots
    warnings.simplefilter("ignore")
    if args.loop_shape:
        chosen = {"both": ("msd", "roll"), "all": ("msd", "roll", "arm"), "none": ()}.get(args.plant, (args.plant,))
        if "roll" in chosen:
            print("quadrotor roll axis: the tuned controllers as linear maps, closed around the sampled plant "
                  "(steady state)")
            loop_shape(dict(ROLL_SETTINGS))
        if "msd" in chosen:
            print("\nmass-spring-damper: the tuned controllers as linear maps, closed around the sampled plant "
                  "(steady state)")
            plant_loop_shape(dict(SETTINGS), MSD_LOOP_SHAPE_POINTS)
        if "arm" in chosen:
            print("\ntwo-link arm, linearised at rest at the step's target, each controller with its gravity "
                  "feed-forward linearised (the agent's dy~/da fixed there): closed loop, steady state")
            plant_loop_shape(dict(ARM_SETTINGS), ARM_LOOP_SHAPE_POINTS)
        return
    tune_seeds = range(1000, 1003 if args.quick else 1005)
    eval_seeds = range(8 if args.quick else 20)
    evaluations = 50 if args.quick else 150
    started = time.perf_counter()
    plants = {"msd": SETTINGS, "roll": ROLL_SETTINGS}
    for name in {"both": ("msd", "roll"), "all": ("msd", "roll", "arm"), "none": ()}.get(args.plant, (args.plant,)):
        print(f"\n=== plant {name} ===")
        if name == "arm":
            compare_arm(dict(ARM_SETTINGS, **weight), tune_seeds, eval_seeds, evaluations, out_dir, args.restarts)
        else:
            compare(dict(plants[name], **weight), tune_seeds, eval_seeds, evaluations, args.restarts)

    # step time ----------------------------------------------------------------------------------
    times = step_time(dict(SETTINGS))
    for label, value in times.items():
        if label.startswith("largest"):
            print(f"\n{label}: {value:.2e}", end="")
            continue
        print(f"\ncontroller step, 4 states, p = 4, {label}: {value * 1e6:.1f} us (target <= 100 us: "
              f"{'met' if value <= 1e-4 else 'NOT met'})", end="")
    for task, (median, mean, refreshes) in arm_step_time(dict(ARM_SETTINGS)).items():
        print(f"\ncontroller step, two-link arm (4 states, 6 causes, p = 2, dy~/da held over dt, refreshed on "
              f"{refreshes} of {round(ARM_SETTINGS['duration'] / ARM_SETTINGS['dt'])} samples), {task}: median "
              f"{median * 1e6:.1f} us (target <= 100 us: {'met' if median <= 1e-4 else 'NOT met'}), mean "
              f"{mean * 1e6:.1f} us (target <= 100 us: {'met' if mean <= 1e-4 else 'NOT met'})", end="")
    print(f"\n\nwall time {time.perf_counter() - started:.0f} s")


if __name__ == "__main__":
    main()
