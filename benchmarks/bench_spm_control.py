"""attend's active-inference reproductions against SPM12's own runs (issue 28).

    PYTHONPATH=src python benchmarks/bench_spm_control.py               # compare with the stored SPM runs
    PYTHONPATH=src python benchmarks/bench_spm_control.py --diagnose    # + attend with more sensory orders, and SPM's
                                                                        # conventions switched back one at a time
                                                                        # (attenuation and reaching)

No Octave is needed: SPM's numbers are stored in benchmarks/spm/reference/ (README there). Two demos:

- attenuation (attend.control.attenuation, SPM's ALAP_demo_attenuation through spm_ALAP): per attenuation
  h = -4..6 the peak true force (the world's x) and the peak perceived self-generated force (the belief x1),
  "fixed reflex precision" variant (SPM's G.U = [1 0]). SPM was run with the demo's world noise
  (exp(8), rng('default') before each run; attenuation_spm.csv) and with a noiseless world
  (attenuation_noiseless_spm.csv). attend is run with its SETTINGS (its own noise, seed 0) and with matched
  settings: a noiseless world and the intention peaking at t = 15 s (SPM's bin 16 is t = 15 s, since SPM's
  bin 1 is the initial state at t = 0).
- reaching (attend.control.reaching, SPM's ADEM_reaching through spm_ADEM), "vision" variant: the finger's
  path and the joint angles per bin. Matched settings: a noiseless world (SPM's exp(16) world noise changes
  its path by < 1e-4) and the cue peaking at t = 31 s (SPM's bin 32).

Both demos are also run in their "SPM conventions" variants (attend.control.attenuation.SPM_CONVENTIONS and
attend.control.reaching.SPM_CONVENTIONS: SPM's step, every sensory order, the world's generalised response with the
action's motion as data, the intention or causes embedded per bin, integration="spm" with no motion error at the top
order, and the world integrated jointly with the agent, as spm_ALAP and spm_ADEM do; the attenuation's prior also
moves within the bin as spm_ALAP's does, and its beliefs are recorded before each step; the reaching adds spm_ADEM's
weak prior on the beliefs).

Targets: the curves within 5 %, attend >= 100x faster (CPU time of one run of the demo against the CPU
time of the spm_ALAP / spm_ADEM call, as the drivers record it). Conventions that differ: docs/spm.md.

Regenerating the references (needs GNU Octave and SPM12 r7771 outside the repository, see
benchmarks/spm/README.md), from the repository root:

    cd benchmarks/spm
    octave --no-gui --quiet --eval "spm_root='/work/spm12'; noise=1; run('run_attenuation.m')"
    octave --no-gui --quiet --eval "spm_root='/work/spm12'; noise=0; run('run_attenuation.m')"
    octave --no-gui --quiet --eval "spm_root='/work/spm12'; cued=1; noise=1; run('run_reaching.m')"
    octave --no-gui --quiet --eval "spm_root='/work/spm12'; cued=1; noise=0; run('run_reaching.m')"
    octave --no-gui --quiet --eval "spm_root='/work/spm12'; cued=0; noise=0; run('run_reaching.m')"
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

import numpy as np

REFERENCE = Path(__file__).resolve().parent / "spm" / "reference"
NOISELESS = 64.0  # world log-precision of a noiseless attend world (noise std exp(-32))


# ---------------------------------------------------------------------------------------------- references
def spm_attenuation(tag: str = "attenuation_noiseless") -> dict:
    """SPM's attenuation run ``tag``: h, peak true and perceived force, CPU seconds per run (arrays), the
    time courses per h ((32, 7): bin, true x, belief x1, x2, action, belief v1, v2) and the JSON record."""
    table = np.loadtxt(REFERENCE / f"{tag}_spm.csv", delimiter=",", ndmin=2)
    traces = {int(h): np.loadtxt(REFERENCE / f"{tag}_h{int(h)}_spm.csv", delimiter=",") for h in table[:, 0]}
    record = json.loads((REFERENCE / f"{tag}_spm.csv.json").read_text())
    return dict(h=table[:, 0], true=table[:, 1], perceived=table[:, 2], cpu=table[:, 3], traces=traces,
                record=record)


def spm_reaching(tag: str = "reaching_noiseless") -> dict:
    """SPM's reaching run ``tag``: per bin (128 rows) the true angles and velocities, finger, believed angles,
    believed finger, action, believed causes, and the JSON record."""
    data = np.loadtxt(REFERENCE / f"{tag}_spm.csv", delimiter=",")
    record = json.loads((REFERENCE / f"{tag}_spm.csv.json").read_text())
    return dict(bin=data[:, 0], states=data[:, 1:5], finger=data[:, 5:7], believed_angles=data[:, 7:9],
                believed_finger=data[:, 9:11], action=data[:, 11:13], causes=data[:, 13:16], record=record)


# ---------------------------------------------------------------------------------------------- attend runs
def attenuation_settings(matched: bool = True) -> dict:
    """attend.control.attenuation.SETTINGS, or (matched) with a noiseless world and the intention's peak at
    t = 15 s, SPM's bin 16."""
    from attend.control import attenuation

    cfg = dict(attenuation.SETTINGS)
    if matched:
        cfg.update(world_log_precision=NOISELESS, intention_peak_s=15.0)
    return cfg


def attenuation_controller(h: float, cfg: dict, sensory_orders="relative_degree"):
    """(world, controller) of attend's attenuation run ("fixed reflex precision", SPM's G.U) at h; with
    sensory_orders other than attend's default the controller is rebuilt with it (a diagnostic)."""
    from attend.control import ActiveInferenceController, attenuation

    world, controller = attenuation.build(h, "fixed reflex precision", cfg)
    if sensory_orders != "relative_degree":
        controller = ActiveInferenceController(
            controller.model, cfg["dt"], action_gain=cfg["action_gain"], n_actions=1, action_jacobian="process",
            action_precision=cfg["reflex_precision"], action_prior_precision=np.exp(cfg["action_prior_log_precision"]),
            sensory_orders=sensory_orders)
    return world, controller


#: the configuration that isolates the convention that differs: attend stepping once per SPM bin and
#: attending sensory orders 0..3 (SPM weights all of 0..4; attend's default, "relative_degree", only 0..1)
SPM_LIKE_ORDERS = 3


def spm_like_attenuation_settings() -> dict:
    """The matched settings (:func:`attenuation_settings`) at SPM's step, dt = 1 s (one sample per bin)."""
    return dict(attenuation_settings(True), dt=1.0)


def attend_attenuation(cfg: dict, sensory_orders="relative_degree") -> dict:
    """attend's curve: per h of cfg the peak true and perceived force, the CPU seconds of each run, and the
    time courses at SPM's bins (t = 0, 1, .. 31 s); a diverging run gives NaN."""
    from attend.control import ClosedLoopDivergence, run

    hs = cfg["attenuations"]
    true, perceived, cpu, traces = [], [], [], {}
    step = int(round(1.0 / cfg["dt"]))
    for h in hs:
        world, controller = attenuation_controller(h, cfg, sensory_orders)
        start = time.process_time()
        try:
            loop = run(world, controller, cfg["duration"], seed=cfg["seed"])
        except ClosedLoopDivergence:
            true.append(np.nan), perceived.append(np.nan), cpu.append(np.nan)
            continue
        cpu.append(time.process_time() - start)
        true.append(float(loop.states[:, 0].max()))
        perceived.append(float(loop.belief_states[:, 0].max()))
        traces[int(h)] = np.column_stack([loop.states[::step, 0], loop.belief_states[::step, :2]])
    return dict(h=np.asarray(hs, dtype=float), true=np.array(true), perceived=np.array(perceived),
                cpu=np.array(cpu), traces=traces)


def spm_conventions_settings() -> dict:
    """The matched settings (:func:`attenuation_settings`) with attend.control.attenuation.SPM_CONVENTIONS: one step
    per SPM bin, every sensory order, the world's generalised response (with the action's embedded motion) as data, the
    intention embedded per bin and moving within it as spm_ALAP's, spm_ALAP's D-step (``integration="spm"``, no motion
    error at the top order), the world integrated jointly with the agent, and the beliefs recorded before each step."""
    from attend.control import attenuation

    return dict(attenuation_settings(True), **attenuation.SPM_CONVENTIONS)


def attend_attenuation_spm_conventions(cfg: dict | None = None, alter=None) -> dict:
    """As :func:`attend_attenuation` for the "SPM conventions" variant (attend.control.attenuation.simulate); the traces
    per bin hold the true force, the perceived self-generated and external forces. alter: None, or a function
    (world, controller) -> (world, controller) applied to each run before it starts (a diagnostic)."""
    from attend.control import attenuation

    cfg = spm_conventions_settings() if cfg is None else cfg
    true, perceived, cpu, traces = [], [], [], {}
    for h in cfg["attenuations"]:
        start = time.process_time()
        world, controller = attenuation.build(h, "fixed reflex precision", cfg)
        if alter is not None:
            world, controller = alter(world, controller)
            controller.reset()
        run = attenuation._simulate_built(world, controller, cfg)
        cpu.append(time.process_time() - start)
        true.append(float(run["true_force"].max()))
        perceived.append(float(run["perceived_self"].max()))
        traces[int(h)] = np.column_stack([run["true_force"], run["perceived_self"], run["perceived_external"]])
    return dict(h=np.asarray(cfg["attenuations"], dtype=float), true=np.array(true), perceived=np.array(perceived),
                cpu=np.array(cpu), traces=traces)


def attenuation_figures(run: dict, spm: dict) -> dict:
    """The comparison's figures of one attend ``run`` (:func:`attend_attenuation_spm_conventions`) against SPM's ``spm``
    (:func:`spm_attenuation`): per h the ratios attend / SPM of the peak true and perceived force ("true",
    "perceived"), the worst |ratio - 1| of each and its h, and the trace gaps: the largest |attend - SPM| over the 32
    bins and all h of the true and the perceived force, each over SPM's peak at that h ("trace_true",
    "trace_perceived")."""
    true, perceived = run["true"] / spm["true"], run["perceived"] / spm["perceived"]
    hs = [int(h) for h in spm["h"]]
    trace_true = max(np.abs(run["traces"][h][:, 0] - spm["traces"][h][:, 1]).max() / spm["true"][i]
                     for i, h in enumerate(hs))
    trace_perceived = max(np.abs(run["traces"][h][:, 1] - spm["traces"][h][:, 2]).max() / spm["perceived"][i]
                          for i, h in enumerate(hs))
    return dict(true=true, perceived=perceived, worst_true=float(np.max(np.abs(true - 1))),
                worst_true_h=hs[int(np.argmax(np.abs(true - 1)))], worst_perceived=float(np.max(np.abs(perceived - 1))),
                worst_perceived_h=hs[int(np.argmax(np.abs(perceived - 1)))], trace_true=float(trace_true),
                trace_perceived=float(trace_perceived))


def _cause_prior_precision_by_size(world, controller):
    """integration="spm" without SPM's cause-prior precision: S(s) at d + 1 orders (attend's), not the top-left block
    of S(s) at p + 1 orders."""
    from attend.control._core import JointFlow
    from attend.models.generalized import smoothness_precision

    n, r, m, P, Q = controller._sizes
    controller._Pi_v = np.kron(smoothness_precision(Q, controller.model.kernel_width),
                               controller.model.cause_prior_precision)
    controller._joint = JointFlow(n, r, m, controller.n_actions, P, Q, controller._D, controller._Pi_x,
                                  controller._Pi_v, controller.action_gain, controller.action_prior_precision,
                                  controller.dt)
    controller._joint.top_motion_error = controller.top_motion_error
    return world, controller


def _data_held(world, controller):
    """integration="spm" without the data's and the prior's motion within the bin."""
    controller._moving_data = False
    return world, controller


#: spm_diff's step (one-sided differences): spm_ALAP takes the world's df/da and the precision's d log pi / d(x, v)
#: from it
SPM_DIFFERENCE_STEP = float(np.exp(-8))


def _one_sided_differences(world, controller):
    """The world's df/da = d tanh(a) / da and the precision's d pi / d(x1, v1) = pi d log pi / d(x1, v1) as spm_diff
    takes them in spm_ALAP, one-sided with step exp(-8), in place of attend's analytic ones (a diagnostic of the
    numerics, not a convention)."""
    import dataclasses
    import math

    step = SPM_DIFFERENCE_STEP
    model = controller.model

    def world_jacobians(x, a):
        return np.array([[-0.25]]), np.array([[(math.tanh(a[0] + step) - math.tanh(a[0])) / step]])

    def precision_gradient(x, v):  # pi depends on x1 + v1 only
        log_pi = math.log(float(model.sensor_precision(x, v)[0]))
        moved = np.array([float(x[0] + v[0]) + step, 0.0])
        slope = (math.log(float(model.sensor_precision(moved, np.zeros(2))[0])) - log_pi) / step
        out = np.zeros((2, 2))
        out[:, 0] = math.exp(log_pi) * slope
        return out, out.copy()

    controller.model = dataclasses.replace(model, sensor_precision_gradient=precision_gradient)
    return dataclasses.replace(world, jacobian_f=world_jacobians), controller


#: SPM's conventions of the attenuation demo, each switched back to attend's (bench --diagnose; tests): label ->
#: (the settings that differ from attenuation.SPM_CONVENTIONS, an alteration of each (world, controller) or None)
ATTENUATION_ABLATION = {
    "world stepped apart (action held)": (dict(joint_world=False), None),
    "action held in the world's response": (dict(action_motion=False), None),
    "prior moving with its folded motion": (dict(prior_own_motion=False), None),
    "motion error at the top order kept": (dict(top_motion_error=True), None),
    "beliefs recorded after the step": (dict(record_before_step=False), None),
    "spm_ADEM's weak prior on the beliefs added": (dict(belief_prior_log_precision=-8.0), None),
    "sensory orders 0..3 instead of 0..4": (dict(sensory_orders=3), None),
    "intention without its motion": (dict(embedded_intention=False), None),
    "cause prior precision S(s) at d + 1 orders": ({}, _cause_prior_precision_by_size),
    "data and prior held within the bin (world apart)": (dict(joint_world=False, prior_own_motion=False), _data_held),
    "integration='attend' (world apart)": (dict(integration="attend", joint_world=False, prior_own_motion=False), None),
    "data sampled and embedded causally": (dict(generalised_data=False), None),
    "data sampled and embedded causally, orders 0..3": (dict(generalised_data=False, sensory_orders=3), None),
    "SPM's one-sided differences (numerics)": ({}, _one_sided_differences),
}


def attenuation_ablation(spm: dict, labels=None) -> dict:
    """label -> :func:`attenuation_figures` of the "SPM conventions" variant with one of :data:`ATTENUATION_ABLATION`'s
    conventions switched back (labels: those, default all), or where a run diverged, the time [s] it did; spm:
    :func:`spm_attenuation`'s run."""
    import re
    import warnings

    from attend.control import ClosedLoopDivergence

    out = {}
    for label in ATTENUATION_ABLATION if labels is None else labels:
        change, alter = ATTENUATION_ABLATION[label]
        try:
            with np.errstate(all="ignore"), warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)
                run = attend_attenuation_spm_conventions(dict(spm_conventions_settings(), **change), alter)
            out[label] = attenuation_figures(run, spm)
        except ClosedLoopDivergence as error:
            found = re.search(r"at t = ([0-9.e+-]+) s", str(error))
            out[label] = float(found.group(1)) if found else float("nan")
    return out


def reaching_settings(matched: bool = True) -> dict:
    """attend.control.reaching.SETTINGS, or (matched) with a noiseless world and the cue's peak at t = 31 s,
    SPM's bin 32."""
    from attend.control import reaching

    cfg = dict(reaching.SETTINGS)
    if matched:
        cfg.update(world_log_precision=NOISELESS, cue_peak_s=31.0)
    return cfg


def attend_reaching(cfg: dict, cued: bool = True) -> dict:
    """attend's "vision" run: finger path, joint angles and belief at SPM's bins (t = 0 .. 127 s), the full
    finger path with its times, and the CPU seconds of the run."""
    from attend.control import reaching

    start = time.process_time()
    trace = reaching.simulate("vision", cued, cfg)
    cpu = time.process_time() - start
    step = int(round(1.0 / cfg["dt"]))
    bins = int(round(cfg["duration"]))
    return dict(finger=np.asarray(trace["finger"])[::step][:bins], angles=np.asarray(trace["angles"])[::step][:bins],
                time_s=np.asarray(trace["time_s"]), finger_full=np.asarray(trace["finger"]), cpu=cpu)


def reaching_spm_conventions_settings() -> dict:
    """The matched settings (:func:`reaching_settings`) with attend.control.reaching.SPM_CONVENTIONS: one step per SPM
    bin, every sensory order, the world's generalised response (with the action's embedded motion) as data, the seen
    causes embedded per bin, spm_ADEM's D-step (``integration="spm"``, no motion error at the top order, the weak
    prior on the beliefs) and the world integrated jointly with the agent; and SPM's start exactly, angles (pi/2,
    pi/2) (SETTINGS: 1.5708, 3.7e-6 rad off, which this comparison resolves)."""
    import math

    from attend.control import reaching

    return dict(reaching_settings(True), **reaching.SPM_CONVENTIONS, initial_angles=[math.pi / 2, math.pi / 2])


def reaching_figures(run: dict, spm: dict, target) -> dict:
    """The comparison's figures of one attend ``run`` (:func:`attend_reaching`) against SPM's ``spm``
    (:func:`spm_reaching`), both at SPM's 128 bins, ``target`` the target (2,): RMS and largest finger gap
    over the start-target distance ("scale"), the bin of the largest gap, the closest approach to the target and its
    bin (1-based, as SPM's), the distance at bins 64 and 128 (the drift back) and the largest joint-angle gap [rad]."""
    target = np.asarray(target, dtype=float)
    scale = float(np.linalg.norm(spm["finger"][0] - target))
    gap = path_gap(run["finger"], spm["finger"])
    distance = np.linalg.norm(run["finger"] - target, axis=1)
    return dict(scale=scale, rms=float(np.sqrt(np.mean(gap**2))) / scale, max=float(gap.max()) / scale,
                max_bin=int(gap.argmax()) + 1, closest=float(distance.min()), closest_bin=int(distance.argmin()) + 1,
                bin64=float(distance[63]), bin128=float(distance[-1]),
                angles=float(np.abs(run["angles"] - spm["states"][:, :2]).max()))


#: SPM's conventions of the reaching demo, each switched back to attend's (bench --diagnose; tests): label -> the
#: settings that differ from reaching.SPM_CONVENTIONS
REACHING_ABLATION = {
    "motion error at the top order kept": dict(top_motion_error=True),
    "world stepped apart (action held)": dict(joint_world=False),
    "action held in the world's response": dict(action_motion=False),
    "cue as a world state (not embedded)": dict(embedded_causes=False),
    "no prior on the beliefs (SPM's Pu)": dict(belief_prior_log_precision=None),
    "sensory orders 0..3 instead of 0..4": dict(sensory_orders=3),
    "orders up to the relative degree": dict(sensory_orders="relative_degree"),
    "integration='attend' (no joint world)": dict(integration="attend", joint_world=False),
    "data sampled and embedded causally": dict(generalised_data=False),
    "8 steps per bin (dt = 1/8 s)": dict(dt=0.125),
}


def reaching_ablation(spm: dict, target) -> dict:
    """label -> :func:`reaching_figures` of the "SPM conventions" variant with one of :data:`REACHING_ABLATION`'s
    conventions switched back, or where the loop diverged, the time [s] it did; spm: :func:`spm_reaching`'s run,
    target: the target (2,)."""
    import re
    import warnings

    from attend.control import ClosedLoopDivergence

    out = {}
    for label, change in REACHING_ABLATION.items():
        try:
            with np.errstate(all="ignore"), warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)
                run = attend_reaching(dict(reaching_spm_conventions_settings(), **change))
            out[label] = reaching_figures(run, spm, target)
        except ClosedLoopDivergence as error:
            found = re.search(r"at t = ([0-9.e+-]+) s", str(error))
            out[label] = float(found.group(1)) if found else float("nan")
    return out


def path_gap(attend_finger: np.ndarray, spm_finger: np.ndarray) -> np.ndarray:
    """|attend finger - SPM finger| per bin [arm length]."""
    return np.linalg.norm(attend_finger - spm_finger, axis=1)


def best_time_shift(run: dict, spm_finger: np.ndarray, shifts=np.arange(-1.0, 1.01, 0.125)) -> tuple[float, float]:
    """(shift [s], RMS gap [arm length]): the time shift of attend's path (attend at t = bin - 1 + shift)
    closest to SPM's, over the bins where it is defined."""
    best = (0.0, np.inf)
    for shift in shifts:
        at = np.arange(spm_finger.shape[0]) + shift
        keep = (at >= 0) & (at <= run["time_s"][-1])
        path = np.column_stack([np.interp(at[keep], run["time_s"], run["finger_full"][:, k]) for k in range(2)])
        rms = float(np.sqrt(np.mean(path_gap(path, spm_finger[keep]) ** 2)))
        if rms < best[1]:
            best = (float(shift), rms)
    return best


# ---------------------------------------------------------------------------------------------- report
def _attenuation_report(diagnose: bool) -> None:
    spm_noisy, spm = spm_attenuation("attenuation"), spm_attenuation("attenuation_noiseless")
    own, matched = attend_attenuation(attenuation_settings(False)), attend_attenuation(attenuation_settings(True))
    print("Sensory attenuation (fixed reflex precision = SPM's G.U): peak true / perceived force per h")
    print(f"{'h':>3} | {'SPM demo noise':>15} | {'attend SETTINGS':>15} | {'SPM noiseless':>15} | "
          f"{'attend matched':>15} | {'true ratio':>10} | {'perc. ratio':>11} | trace gap")
    for i, h in enumerate(spm["h"]):
        trace_gap = np.abs(matched["traces"][int(h)][:, 0] - spm["traces"][int(h)][:, 1]).max() / spm["true"][i]
        print(f"{h:3.0f} | {spm_noisy['true'][i]:6.3f} / {spm_noisy['perceived'][i]:6.3f} | "
              f"{own['true'][i]:6.3f} / {own['perceived'][i]:6.3f} | {spm['true'][i]:6.3f} / {spm['perceived'][i]:6.3f} | "
              f"{matched['true'][i]:6.3f} / {matched['perceived'][i]:6.3f} | {matched['true'][i] / spm['true'][i]:10.3f} | "
              f"{matched['perceived'][i] / spm['perceived'][i]:11.3f} | {trace_gap:8.3f}")
    worst = np.max(np.abs(matched["true"] / spm["true"] - 1))
    print(f"worst |attend / SPM - 1| of the true force (matched, noiseless): {worst:.3f} (target <= 0.05: "
          f"{'met' if worst <= 0.05 else 'NOT met'}); trace gap: max |x_attend - x_SPM| over bins / SPM's peak")
    spm_like = attend_attenuation(spm_like_attenuation_settings(), sensory_orders=SPM_LIKE_ORDERS)
    ratio = spm_like["true"] / spm["true"]
    print(f"attend at SPM's step (dt = 1 s) attending orders 0..{SPM_LIKE_ORDERS} (SPM: 0..4): true / SPM per h "
          + " ".join(f"{r:.3f}" for r in ratio) + f"; worst |ratio - 1| {np.max(np.abs(ratio - 1)):.3f}; perceived / SPM "
          + " ".join(f"{r:.3f}" for r in spm_like["perceived"] / spm["perceived"]))
    conventions = attend_attenuation_spm_conventions()
    fig = attenuation_figures(conventions, spm)
    worst_conventions = max(fig["worst_true"], fig["worst_perceived"])
    print("attend with SPM's conventions (attenuation.SPM_CONVENTIONS: dt = 1 s, orders 0..4, generalised data with the "
          "action's motion, embedded intention moving as SPM's, integration='spm' without the top order's motion "
          "error, world integrated jointly, beliefs recorded before the step): attend / SPM - 1 per h, true force "
          + " ".join(f"{r - 1:+.1e}" for r in fig["true"]) + "; perceived " + " ".join(f"{r - 1:+.1e}" for r in fig["perceived"]))
    print(f"  worst |attend / SPM - 1|: true {fig['worst_true']:.1e} (h = {fig['worst_true_h']}), perceived "
          f"{fig['worst_perceived']:.1e} (h = {fig['worst_perceived_h']}) (target <= 0.05: "
          f"{'met' if worst_conventions <= 0.05 else 'NOT met'}); trace gap (max over bins and h / SPM's peak): true "
          f"{fig['trace_true']:.1e}, perceived {fig['trace_perceived']:.1e}")
    if diagnose:
        _spm_conventions_ablation(spm)
        for dt, orders in ((attenuation_settings(True)["dt"], 3), (attenuation_settings(True)["dt"], "all"), (1.0, "all")):
            probe = attend_attenuation(dict(attenuation_settings(True), dt=dt), sensory_orders=orders)
            print(f"  diagnostic, attend with dt = {dt:g} s, sensory_orders={orders!r}: true / SPM per h "
                  + " ".join("diverged" if np.isnan(r) else f"{r:.3f}" for r in probe["true"] / spm["true"])
                  + "; perceived / SPM " + " ".join("diverged" if np.isnan(r) else f"{r:.3f}"
                                                    for r in probe["perceived"] / spm["perceived"]))
    per_run_spm = spm["record"]["cpu_seconds_per_run"]
    per_run_attend = float(np.nanmedian(own["cpu"]))
    print(f"speed: spm_ALAP {per_run_spm:.2f} s CPU per run (Octave {spm['record']['octave']}), attend "
          f"{per_run_attend:.3f} s (median of {len(own['cpu'])} runs, {attenuation_settings(False)['duration'] / attenuation_settings(False)['dt']:.0f} samples): "
          f"{per_run_spm / per_run_attend:.1f}x (target >= 100x); at SPM's step (32 samples) "
          f"{float(np.nanmedian(spm_like['cpu'])):.4f} s: {per_run_spm / float(np.nanmedian(spm_like['cpu'])):.0f}x; "
          f"with SPM's conventions (32 samples) {float(np.median(conventions['cpu'])):.4f} s: "
          f"{per_run_spm / float(np.median(conventions['cpu'])):.0f}x\n")


def _spm_conventions_ablation(spm: dict) -> None:
    """Each of SPM's conventions switched back to attend's, one at a time, in the "SPM conventions" variant: which
    source carries which part of the difference (:func:`attenuation_ablation`)."""
    print("diagnostic: attenuation with SPM's conventions, each switched back to attend's (figures against SPM's runs)")
    print(f"  {'switched back':50s} | worst true (h)  | worst perc. (h) | trace gap true, perceived")
    print(f"  {'none (SPM conventions)':50s} | " + _ablation_row(attenuation_figures(attend_attenuation_spm_conventions(),
                                                                                      spm)))
    for label, fig in attenuation_ablation(spm).items():
        if not isinstance(fig, dict):
            print(f"  {label:50s} | diverged at t = {fig:g} s")
            continue
        print(f"  {label:50s} | " + _ablation_row(fig))


def _ablation_row(fig: dict) -> str:
    return (f"{fig['worst_true']:7.1e} ({fig['worst_true_h']:2d}) | {fig['worst_perceived']:7.1e} "
            f"({fig['worst_perceived_h']:2d}) | {fig['trace_true']:7.1e}, {fig['trace_perceived']:7.1e}")


def _reaching_report(diagnose: bool) -> None:
    spm, spm_noisy = spm_reaching("reaching_noiseless"), spm_reaching("reaching")
    spm_still = spm_reaching("reaching_nocue_noiseless")
    cfg, conventions_cfg = reaching_settings(True), reaching_spm_conventions_settings()
    own, matched = attend_reaching(reaching_settings(False)), attend_reaching(cfg)
    still = attend_reaching(cfg, cued=False)
    conventions = attend_reaching(conventions_cfg)
    conventions_still = attend_reaching(conventions_cfg, cued=False)
    target = np.asarray(cfg["target"])
    scale = float(np.linalg.norm(spm["finger"][0] - target))  # the distance the finger travels
    print(f"Reaching (vision variant): finger path at SPM's 128 bins; scale = start-target distance {scale:.3f}")
    gap, gap_own = path_gap(matched["finger"], spm["finger"]), path_gap(own["finger"], spm_noisy["finger"])
    gap_conventions = path_gap(conventions["finger"], spm["finger"])
    rows = [
        ("max finger gap / scale", gap_own.max() / scale, gap.max() / scale, gap_conventions.max() / scale),
        ("RMS finger gap / scale", np.sqrt(np.mean(gap_own ** 2)) / scale, np.sqrt(np.mean(gap ** 2)) / scale,
         np.sqrt(np.mean(gap_conventions ** 2)) / scale),
        ("max joint-angle gap [rad]", np.abs(own["angles"] - spm_noisy["states"][:, :2]).max(),
         np.abs(matched["angles"] - spm["states"][:, :2]).max(),
         np.abs(conventions["angles"] - spm["states"][:, :2]).max()),
    ]
    print(f"{'figure':34s} | {'attend SETTINGS':>15} | {'attend matched':>14} | {'SPM conventions':>15}")
    for name, a, b, c in rows:
        print(f"{name:34s} | {a:15.4f} | {b:14.4f} | {c:15.2e}")
    print(f"{'figure':34s} | {'SPM':>8} | {'attend matched':>14} | ratio | {'SPM conventions':>15} | ratio")
    distances = [np.linalg.norm(run["finger"] - target, axis=1) for run in (spm, matched, conventions)]

    def excursion(run):
        return np.linalg.norm(run["finger"] - run["finger"][0], axis=1).max()

    for name, pick in [("closest finger-target distance", lambda d: d.min()),
                       ("distance at bin 32 (cue peak)", lambda d: d[31]),
                       ("distance at bin 64", lambda d: d[63]),
                       ("final distance (bin 128)", lambda d: d[-1])]:
        s, a, c = (float(pick(d)) for d in distances)
        print(f"{name:34s} | {s:8.4f} | {a:14.4f} | {a / s:.3f} | {c:15.6f} | {c / s:.4f}")
    s, a, c = (int(d.argmin()) + 1 for d in distances)
    print(f"{'bin of the closest approach':34s} | {s:8d} | {a:14d} |       | {c:15d} |")
    s, a, c = excursion(spm_still), excursion(still), excursion(conventions_still)
    print(f"{'no cue: largest excursion':34s} | {s:8.1e} | {a:14.1e} |       | {c:15.1e} |")
    shift, rms = best_time_shift(matched, spm["finger"])
    print(f"attend's matched path closest to SPM's when shifted by {shift:+.3f} s (RMS gap / scale {rms / scale:.4f})")
    if diagnose:
        print("diagnostic: reaching with SPM's conventions, each switched back to attend's (figures against SPM's run)")
        print(f"  {'switched back':40s} | RMS gap | max gap (bin)  | closest (bin) | bin 64 | bin 128")
        for label, fig in reaching_ablation(spm, target).items():
            if not isinstance(fig, dict):
                print(f"  {label:40s} | diverged at t = {fig:g} s")
                continue
            print(f"  {label:40s} | {fig['rms']:7.1e} | {fig['max']:6.1e} ({fig['max_bin']:3d}) | {fig['closest']:.4f} "
                  f"({fig['closest_bin']:3d}) | {fig['bin64']:.4f} | {fig['bin128']:.4f}")
    cpu_conventions = [conventions["cpu"], conventions_still["cpu"]]
    cpu_conventions += [attend_reaching(conventions_cfg)["cpu"] for _ in range(3)]
    per_run = float(np.median(cpu_conventions))
    spm_cpu = spm_noisy["record"]["cpu_seconds"]
    print(f"speed: spm_ADEM {spm_cpu:.2f} s CPU (128 bins, Octave {spm_noisy['record']['octave']}), attend "
          f"{own['cpu']:.3f} s (1024 samples): {spm_cpu / own['cpu']:.1f}x (target >= 100x); with SPM's conventions "
          f"(128 steps) {per_run:.3f} s (median of {len(cpu_conventions)} runs): {spm_cpu / per_run:.0f}x")


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--diagnose", action="store_true",
                        help="also run attend's attenuation with sensory_orders=3 and 'all' (SPM weights every order), and the "
                             "SPM-conventions variants (attenuation, reaching) with each convention switched back to attend's")
    args = parser.parse_args(argv)
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    _attenuation_report(args.diagnose)
    _reaching_report(args.diagnose)


if __name__ == "__main__":
    main()
