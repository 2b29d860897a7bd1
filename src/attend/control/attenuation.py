"""Sensory attenuation as attention: an intended force happens only if its sensed consequences are attended away from.

The idea of SPM's ALAP_demo_attenuation (Brown, Adams, Parees, Edwards, Friston 2013), rebuilt with
attend.control. The world: one force x pushed by the action, dx/dt = tanh(a) - x/4 + w, sensed twice
(proprioception and touch), y = [x; x] + z. The agent believes in a self-generated force x1 and an
external one x2, dx/dt = v - x/4, y = [x1; x1 + x2], and intends a force: the prior on v1 is a bump
eta1(t) = exp(-(t - 16)^2 / 16) (precision exp(6)), v2 (external) has prior 0 with precision 1.
Sensory precision depends on the agent's own intended movement (attention, like spm_ALAP's M.ph)::

    Pi_z(x, v) = exp(8 - h tanh(v1 + x1)) I_2          h: attenuation (log-precision), -4 .. 6

so h > 0 attends away from the sensations of a self-generated force. The intended force is the peak
of x1 under the prior alone (dx1/dt = eta1 - x1/4); the true force the peak of the world's x; the
perceived force the peak of the belief x1. Claim (Brown et al.): with strong attenuation the
movement happens (true >= 80 % of intended), without it it does not (<= 20 %).

Two reflex arcs are compared (attend.control's action law da/dt = -kappa (dy~/da)' Pi~ e_y):
"model precision" weights the sensory errors by the agent's own (attenuated) Pi_z(x, v); "fixed
reflex precision" by a fixed diag(1, 0) on proprioception (SPM's G.U), so attention acts only on
perception. Settings are SPM's where it states them (precisions, orders, s = 1/2, P_a = exp(-2));
time unit 1 s per SPM bin, sampled at dt = 1/8 s. :data:`SPM_CONVENTIONS` applied over the settings follows spm_ALAP's
own conventions instead (one step per bin, every sensory order, generalised data with the action's motion, the embedded
intention, SPM's D-step, the world integrated jointly with the agent, the states recorded before each step; run by
:func:`simulate`): then the peak forces are SPM's to 4e-5 (docs/spm.md).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from attend.experiments._result import Claim, ExperimentResult

SETTINGS = dict(
    dt=0.125, duration=32.0, attenuations=list(range(-4, 7)), kernel_width=0.5, embedding_order=4, cause_order=2,
    sensor_log_precision=8.0, model_process_log_precision=4.0, intention_log_precision=6.0,
    external_log_precision=0.0, world_log_precision=8.0, world_kernel_width=0.5, action_gain=1.0,
    action_prior_log_precision=-2.0, reflex_precision=[1.0, 0.0], intention_peak_s=16.0, intention_width_s=4.0,
    seed=0, strong_attenuation=6, no_attenuation=0, movement_threshold=0.8, stillness_threshold=0.2,
)

#: reflex variant -> action_precision (None: the model's Pi_z(x, v))
VARIANTS = {"model precision": None, "fixed reflex precision": "reflex_precision"}

#: SPM's conventions (spm_ALAP), to be applied over SETTINGS; run by :func:`simulate`:
#: - dt = 1 s: one step per SPM bin; sensory_orders="all": sensory precision on every order 0..p (kron(S, Pi_z), and
#:   kron(S, G.U) in the reflex);
#: - generalised_data: the data are the world's generalised response (spm_ADEM_diff), not embedded samples;
#:   action_motion: with the action's motion in it, a' .. a^(p) embedded from the actions so far by spm_DEM_embed's
#:   centred window (spm_ALAP's pu.a), so that x'' = f_x x' + f_a a', ...;
#: - embedded_intention: the intention sampled once per bin and embedded in generalised coordinates (centred window, as
#:   spm_DEM_embed), its errors counted at p + 1 orders with the causes' orders above d pinned at 0
#:   (:func:`embedded_intention`); prior_own_motion: within the bin the prior moves with its own orders 0..d (order d
#:   held) and the part folded in from the orders above d is held, as spm_ALAP moves qu.u(1:d) only;
#: - integration="spm" and top_motion_error=False: spm_ALAP's D-step (the data and the prior move within the bin, the
#:   causes' prior precision from S at p + 1 orders, no motion error at the top order p, as spm_DEM_eval);
#: - joint_world: the world is integrated jointly with the agent over the bin (its state and motion, the data it
#:   drives, the beliefs and the action in one local-linearisation step, so that the action moves the force within
#:   the bin), as spm_ALAP integrates [world; agent]; not the world stepped apart with the action held;
#: - record_before_step: the beliefs and the action are recorded at the start of each bin, before its step, as
#:   spm_ALAP saves Q(is) before the update (the world's force always is); this moves the traces, not the peaks.
#: spm_ALAP puts no prior on the beliefs (its M.xP, M.vP are empty: Pu = 0), so belief_prior_log_precision is unset.
SPM_CONVENTIONS = dict(dt=1.0, sensory_orders="all", integration="spm", generalised_data=True, embedded_intention=True,
                       action_motion=True, prior_own_motion=True, top_motion_error=False, joint_world=True,
                       record_before_step=True)


def intention(t, cfg=SETTINGS) -> float:
    """eta1(t) = exp(-(t - t0)^2 / w^2) [force unit / s]: the intended push (t [s]); cfg: the settings
    (t0 = intention_peak_s, w = intention_width_s)."""
    return float(np.exp(-((t - cfg["intention_peak_s"]) ** 2) / cfg["intention_width_s"] ** 2))


def intended_force(cfg=SETTINGS) -> float:
    """Peak of x1 under the prior alone, dx1/dt = eta1(t) - x1/4 (fine Euler steps of dt/100); cfg: the settings."""
    h = cfg["dt"] / 100
    x, peak = 0.0, 0.0
    for t in np.arange(0.0, cfg["duration"], h):
        x += h * (intention(t, cfg) - x / 4)
        peak = max(peak, x)
    return peak


def embedded_intention(cfg=SETTINGS, folded: bool = True):
    """eta~(t) of SPM's prior on the causes: the intention sampled at t_k = k dt, embedded in p + 1 orders by the
    centred window of spm_DEM_embed (the end samples repeated), and folded into the d + 1 orders the agent estimates.
    SPM's prior errors at orders d + 1..p (where v~ is 0) are e = -eta^(d+1..p); with S = S(s) at p + 1 orders,
    the gradient on the orders 0..d is that of a prior mean eta^(0..d) + inv(S_00) S_01 eta^(d+1..p) (S_00, S_01: the
    blocks of S on orders 0..d and d + 1..p). folded=False: the embedded orders 0..d alone, eta^(0..d), whose motion
    moves spm_ALAP's prior within a bin (the folded part is held). Returns a function t [s] -> ((d + 1) r,)
    order-major (cfg: the settings)."""
    from attend.models.generalized import embed, fold_orders

    P, Q, dt = cfg["embedding_order"] + 1, cfg["cause_order"] + 1, cfg["dt"]
    n_bins = int(round(cfg["duration"] / dt))
    samples = np.array([intention(k * dt, cfg) for k in range(n_bins)])
    generalised = embed(samples[:, None], P, dt)  # (n_bins, P)
    table = np.zeros((n_bins, Q, 2))
    own = generalised[:, :Q] if not folded else fold_orders(generalised[:, :, None], Q, cfg["kernel_width"])[:, :, 0]
    table[:, :, 0] = own

    def prior(t):
        return table[min(max(int(round(t / dt)), 0), n_bins - 1)].reshape(-1)

    return prior


def _precision_gradient(x, v, base: float, h: float) -> tuple[np.ndarray, np.ndarray]:
    """(dpi/dx (2, 2), dpi/dv (2, 2)) of pi = exp(base - h tanh(v1 + x1)) (1, 1): dpi/dx1 = dpi/dv1 = -h pi (1 - tanh^2)."""
    slope = math.tanh(float(v[0]) + float(x[0]))
    rate = -h * math.exp(base - h * slope) * (1.0 - slope * slope)
    dx = np.zeros((2, 2))
    dx[:, 0] = rate
    return dx, dx.copy()


def build(attenuation: float, variant: str = "model precision", cfg=SETTINGS):
    """(process, controller) of one run: attenuation h [log-precision], variant one of :data:`VARIANTS`,
    cfg the settings."""
    from attend.control import ActiveInferenceController, GenerativeModel, GenerativeProcess

    h = float(attenuation)
    base = cfg["sensor_log_precision"]
    mixing = np.array([[1.0, 0.0], [1.0, 1.0]])
    model = GenerativeModel(
        f=lambda x, v: v - x / 4, g=lambda x, v: mixing @ x, n_states=2, n_causes=2, n_outputs=2,
        sensor_precision=lambda x, v: np.exp(base - h * np.tanh(v[0] + x[0])) * np.ones(2),
        sensor_precision_gradient=lambda x, v: _precision_gradient(x, v, base, h),
        process_precision=np.exp(cfg["model_process_log_precision"]),
        cause_prior_precision=np.exp([cfg["intention_log_precision"], cfg["external_log_precision"]]),
        cause_prior=(embedded_intention(cfg) if cfg.get("embedded_intention", False)
                     else (lambda t: np.array([intention(t, cfg), 0.0]))), kernel_width=cfg["kernel_width"],
        embedding_order=cfg["embedding_order"], cause_order=cfg["cause_order"],
        jacobian_f=lambda x, v: (-np.eye(2) / 4, np.eye(2)), jacobian_g=lambda x, v: (mixing, np.zeros((2, 2))))
    noise = np.exp(-cfg["world_log_precision"] / 2)
    world = GenerativeProcess(
        f=lambda x, a: np.tanh(a) - x / 4, g=lambda x, a: np.array([x[0], x[0]]), n_states=1, n_actions=1,
        n_outputs=2, process_noise_std=noise, sensor_noise_std=noise, process_kernel_width=cfg["world_kernel_width"],
        sensor_kernel_width=cfg["world_kernel_width"],
        jacobian_f=lambda x, a: (np.array([[-0.25]]), np.array([[1.0 - np.tanh(a[0]) ** 2]])),
        jacobian_g=lambda x, a: (np.ones((2, 1)), np.zeros((2, 1))))
    key = VARIANTS[variant]
    controller = ActiveInferenceController(
        model, cfg["dt"], action_gain=cfg["action_gain"], n_actions=1, action_jacobian="process",
        action_precision=None if key is None else cfg[key],
        action_prior_precision=np.exp(cfg["action_prior_log_precision"]),
        sensory_orders=cfg.get("sensory_orders", "relative_degree"), integration=cfg.get("integration", "attend"),
        top_motion_error=cfg.get("top_motion_error", True),
        belief_prior_precision=(0.0 if cfg.get("belief_prior_log_precision") is None
                                else np.exp(cfg["belief_prior_log_precision"])))
    return world, controller


def simulate(attenuation: float, variant: str = "fixed reflex precision", cfg=SETTINGS) -> dict:
    """One run of :func:`build` (attenuation h, variant, cfg as there): time [s], the world's force x, the perceived
    self-generated and external forces (beliefs x1, x2), the believed causes and the action, per sample. With
    ``cfg["generalised_data"]`` (:data:`SPM_CONVENTIONS`) the agent is given the world's generalised response
    (:meth:`GenerativeProcess.generalised_output`, the sampled output at order 0) instead of embedding its samples;
    with ``cfg["action_motion"]`` that response carries the action's motion, embedded from the actions so far; with
    ``cfg["prior_own_motion"]`` the embedded intention moves within the bin with its own orders 0..d (the folded part
    held; ``prior_motion`` of :meth:`ActiveInferenceController.step_generalised`); with ``cfg["joint_world"]`` the
    world is integrated with the agent in its step (:meth:`GenerativeProcess.generalised_motion`, ``world_motion`` of
    :meth:`ActiveInferenceController.step_generalised`), not stepped apart with the action held. The world's force is
    recorded before each step; the beliefs and the action after it, or with ``cfg["record_before_step"]`` before it
    (SPM's bin k is then the state of all of them at t = (k - 1) dt)."""
    world, controller = build(attenuation, variant, cfg)
    return _simulate_built(world, controller, cfg)


def _simulate_built(world, controller, cfg) -> dict:
    """:func:`simulate` for a (world, controller) pair already built (the benchmark's diagnostics alter it)."""
    from attend.control import run as closed_loop, run_generalised

    if not cfg.get("generalised_data", False):
        loop = closed_loop(world, controller, cfg["duration"], seed=cfg["seed"])
        return dict(time_s=loop.time, true_force=loop.states[:, 0], perceived_self=loop.belief_states[:, 0],
                    perceived_external=loop.belief_states[:, 1], causes=loop.belief_causes, action=loop.actions[:, 0])
    own_motion = (embedded_intention(cfg, folded=False)
                  if cfg.get("embedded_intention", False) and cfg.get("prior_own_motion", False) else None)
    loop = run_generalised(world, controller, cfg["duration"], seed=cfg["seed"],
                           action_motion=cfg.get("action_motion", False), joint_world=cfg.get("joint_world", False),
                           prior_motion=own_motion)
    # SPM's record (record_before_step): everything at the start of the bin; else the beliefs after the step
    rows = slice(0, -1) if cfg.get("record_before_step", False) else slice(1, None)
    beliefs, causes = loop.belief_states[rows], loop.belief_causes[rows]
    return dict(time_s=loop.time, true_force=loop.states[:, 0], perceived_self=beliefs[:, 0],
                perceived_external=beliefs[:, 1], causes=causes, action=loop.actions[rows, 0])


def run(quick: bool = True, progress: bool = True) -> ExperimentResult:
    """True and perceived force per attenuation h, for both reflex variants.

    quick: unused (the experiment takes seconds); progress: a progress bar over the runs.
    ``result.tables`` holds per variant the forces per h and the traces of h = 0 and the strongest h."""
    from tqdm import tqdm

    from attend.control import run as closed_loop

    cfg = dict(SETTINGS)
    intended = intended_force(cfg)
    result = ExperimentResult("attenuation", settings=cfg)
    forces, traces = {}, {}
    jobs = [(variant, h) for variant in VARIANTS for h in cfg["attenuations"]]
    for variant, h in tqdm(jobs, desc="attenuation", disable=not progress):
        world, controller = build(h, variant, cfg)
        loop = closed_loop(world, controller, cfg["duration"], seed=cfg["seed"])
        true, perceived = float(loop.states[:, 0].max()), float(loop.belief_states[:, 0].max())
        row = forces.setdefault(variant, dict(attenuation=[], true_force=[], perceived_force=[], true_over_intended=[]))
        row["attenuation"].append(h)
        row["true_force"].append(true)
        row["perceived_force"].append(perceived)
        row["true_over_intended"].append(true / intended)
        if h in (cfg["no_attenuation"], cfg["strong_attenuation"]):
            traces.setdefault(variant, {})[str(h)] = dict(
                time_s=loop.time, true_force=loop.states[:, 0], perceived_self=loop.belief_states[:, 0],
                perceived_external=loop.belief_states[:, 1], action=loop.actions[:, 0],
                sensor_precision=loop.sensor_precision[:, 0])
        slug = "model" if VARIANTS[variant] is None else "fixed"
        result.add(f"true force, h = {h:g} ({slug} reflex precision)", true, "force unit")
        result.add(f"perceived force, h = {h:g} ({slug} reflex precision)", perceived, "force unit")
    result.add("intended force", intended, "force unit")
    for variant, row in forces.items():
        slug = "model" if VARIANTS[variant] is None else "fixed"
        by_h = dict(zip(row["attenuation"], row["true_over_intended"]))
        result.add(f"true / intended, strong attenuation ({slug} reflex precision)", by_h[cfg["strong_attenuation"]], "1")
        result.add(f"true / intended, no attenuation ({slug} reflex precision)", by_h[cfg["no_attenuation"]], "1")
    result.tables = dict(forces=forces, traces=traces, intended_force=intended)
    return result


CAPTIONS = {
    "attenuation.png": (
        "Sensory attenuation and action. (a) Peak true (solid) and perceived (dashed) force against the "
        "attenuation h of sensory log-precision during self-generated movement, for a reflex weighted by the "
        "agent's own precision (blue) and by a fixed proprioceptive precision as in SPM (orange); dotted lines: "
        "80 % and 20 % of the intended force. (b, c) Fixed reflex precision, h = 0 and h = 6: the world's force, "
        "the perceived self-generated and external forces, and the action over time. Look for whether movement "
        "needs attenuation (orange rising with h) and whether the agent's own precision in the reflex undoes it."
    ),
}


def claims(result: ExperimentResult) -> list[Claim]:
    """The attenuation claim per reflex variant, judged on ``result``: strong attenuation moves (>= 80 % of
    the intended force) and no attenuation does not (<= 20 %)."""
    cfg = result.settings
    out = []
    for variant, key in VARIANTS.items():
        slug = "model" if key is None else "fixed"
        strong = result.metric(f"true / intended, strong attenuation ({slug} reflex precision)").value
        none = result.metric(f"true / intended, no attenuation ({slug} reflex precision)").value
        moves, still = strong >= cfg["movement_threshold"], none <= cfg["stillness_threshold"]
        # the claim is about necessity: movement without attenuation refutes it; the right direction short of
        # the movement threshold differs in size
        verdict = "reproduced" if moves and still else ("differs" if still and strong > 2 * none else "does not hold")
        out.append(Claim(
            f"Movement needs sensory attenuation (reflex weighted by {variant}): with h = {cfg['strong_attenuation']} "
            f"the intended force happens, with h = {cfg['no_attenuation']} it does not",
            f"true / intended force {strong:.2f} at h = {cfg['strong_attenuation']} (target >= "
            f"{cfg['movement_threshold']:.2f}), {none:.2f} at h = {cfg['no_attenuation']} (target <= "
            f"{cfg['stillness_threshold']:.2f})", verdict,
            "movement only with attenuation (Brown et al. 2013, figure only)"))
    return out


def plot(result: ExperimentResult, out_dir) -> list[str]:
    """attenuation.png from ``result.tables``: forces vs h (both variants) and two traces, into the folder
    out_dir (created). Returns the names."""
    from attend.plotting import new_figure

    tables = result.tables
    intended = tables["intended_force"]
    fig, axes = new_figure(out_dir, (15, 4.2), 1, 3)
    for (variant, row), colour in zip(tables["forces"].items(), ("C0", "C1")):
        axes[0].plot(row["attenuation"], row["true_force"], "o-", color=colour, label=f"true ({variant})")
        axes[0].plot(row["attenuation"], row["perceived_force"], "s--", color=colour, label=f"perceived ({variant})")
    for fraction in (0.8, 0.2):
        axes[0].axhline(fraction * intended, color="k", ls=":", lw=1)
    axes[0].set_xlabel("attenuation h of sensory log-precision [log-precision]")
    axes[0].set_ylabel("peak force [force unit]")
    axes[0].set_title("(a) true and perceived force")
    axes[0].legend(fontsize=7)
    fixed = tables["traces"].get("fixed reflex precision", {})
    for axis, (h, trace), letter in zip(axes[1:], sorted(fixed.items(), key=lambda item: float(item[0])), "bc"):
        axis.plot(trace["time_s"], trace["true_force"], "k", lw=2, label="world force x")
        axis.plot(trace["time_s"], trace["perceived_self"], "C0--", label="perceived self-generated x1")
        axis.plot(trace["time_s"], trace["perceived_external"], "C2--", label="perceived external x2")
        axis.plot(trace["time_s"], trace["action"], "C3", label="action a")
        axis.set_xlabel("time [s]")
        axis.set_ylabel("force [force unit], action [action unit]")
        axis.set_title(f"({letter}) fixed reflex precision, h = {h}")
        axis.legend(fontsize=7)
    fig.tight_layout()
    path = Path(out_dir) / "attenuation.png"
    fig.savefig(path, dpi=110)
    return [path.name]
