"""Active vision on a rhythm (seed §2-3, Fig. 1; spec/rhythm.md use 3).

A foveated eye (acuity exp(-d^2 / (2 w^2)), w = 0.6 grid units, foveal precision rate
rho = 12 / (intensity^2 s)) views a 5 x 5 grid of hidden letters (E F T L O C, 5 x 5 glyphs).
Beliefs are exact categorical posteriors per location. The eye fixates while the precision
oscillator pi(t) = exp(sin(2 pi 4 Hz t)) is high and saccades in its troughs (a quarter of each
cycle; saccadic suppression: data taken while moving are weighted by 0.1 pi(t)).

Part 1, where to look (same rhythm for all policies; averaged over seeded scenes):
- epistemic: saccade to the maximum of the salience map S(f) = expected information gain of a
  fixation at f (no inhibition of return coded),
- static saliency: the most conspicuous location (centre-surround contrast of the true image),
  fixed over time, with the classical explicit inhibition of return (Itti & Koch) and without,
- random: a uniformly drawn other location.
Metrics: summed entropy [nats] and identification accuracy vs number of saccades, saccades to
90 % accuracy (mean curve), revisit rates.

Part 2, when to look (epistemic policy for all): the oscillator schedule vs fixed fixation
durations (the matched one has the oscillator's saccade rate and precision budget: perception
gain = mean of pi(t) over the oscillator's perception windows, act gain = mean of 0.1 pi(t) over
its troughs; the precision-driven scheduler uses the same two gains) vs the
precision-driven scheduler (move when the expected gain of staying drops below that of moving,
with and without the oscillator as a prior on timing). Metrics vs time [s].
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
from tqdm import tqdm

from attend.experiments._result import ExperimentResult
from attend.rhythm.oscillator import PrecisionOscillator
from attend.rhythm.scheduler import FixedDurationScheduler, OscillatorScheduler, PrecisionDrivenScheduler
from attend.rhythm.vision import (
    EpistemicPolicy,
    FoveatedEye,
    RandomPolicy,
    StaticSaliencyPolicy,
    random_scene,
    run_episode,
)

SETTINGS = dict(
    grid_rows=5, grid_cols=5, letters="EFTLOC", fovea_width=0.6, foveal_precision_rate=12.0,
    frequency=4.0, depth=1.0, action_fraction=0.25, saccadic_suppression=0.1, time_step=0.0125,
    accuracy_level=0.9,
)
QUICK = dict(scenes=16, saccades=20, monte_carlo_samples=16, timing_scenes=5, timing_duration=2.0)
FULL = dict(scenes=100, saccades=30, monte_carlo_samples=48, timing_scenes=40, timing_duration=3.0)

POLICY_NAMES = ("epistemic", "static saliency", "static saliency (no IOR)", "random")


def _policy(name: str):
    return {"epistemic": EpistemicPolicy, "random": RandomPolicy,
            "static saliency": lambda: StaticSaliencyPolicy(True),
            "static saliency (no IOR)": lambda: StaticSaliencyPolicy(False)}[name]()


def first_crossing(curve: np.ndarray, level: float, axis_values: np.ndarray) -> float:
    """First axis value at which ``curve`` >= ``level`` (NaN if never)."""
    hits = np.nonzero(curve >= level)[0]
    return float(axis_values[hits[0]]) if len(hits) else float("nan")


def revisit_rate(fixations: list[int], n_saccades: int | None = None) -> float:
    """Fraction of the first ``n_saccades`` saccades that land on a location fixated before."""
    last = len(fixations) if n_saccades is None else min(len(fixations), n_saccades + 1)
    landings = [fixations[i] in fixations[:i] for i in range(1, last)]
    return float(np.mean(landings)) if landings else float("nan")


def revisit_rate_while_uncertain(episode, entropy_level: float = 1.0) -> float:
    """Fraction of revisiting saccades among those made while the summed entropy exceeded
    ``entropy_level`` [nats] (after that the scene is resolved and no location has value)."""
    landings = [episode.fixations[i + 1] in episode.fixations[: i + 1]
                for i, record in enumerate(episode.saccades) if record.entropy > entropy_level]
    return float(np.mean(landings)) if landings else float("nan")


def run(quick: bool = True, out_dir=None, progress: bool = True, scenes: int | None = None) -> ExperimentResult:
    """Both parts; figures (PNG, GIF) go to ``out_dir`` when given."""
    cfg = dict(SETTINGS, **(QUICK if quick else FULL))
    if scenes is not None:
        cfg["scenes"] = scenes
        cfg["timing_scenes"] = max(2, min(cfg["timing_scenes"], scenes))
    result = ExperimentResult("vision", settings=dict(cfg, quick=quick))
    eye = FoveatedEye(cfg["fovea_width"], cfg["foveal_precision_rate"])
    oscillator = PrecisionOscillator(cfg["frequency"], cfg["depth"])
    rhythm = OscillatorScheduler(oscillator, cfg["time_step"], cfg["action_fraction"], cfg["saccadic_suppression"])
    perception_gain = rhythm.mean_perception_gain()
    # matched budget: the other schedulers' act-step gain s' g equals the oscillator's mean s pi(t)
    matched_suppression = rhythm.mean_action_gain() / perception_gain
    result.settings.update(matched_perception_gain=perception_gain, matched_saccadic_suppression=matched_suppression)
    fixation_duration = (1.0 - cfg["action_fraction"]) * oscillator.period
    action_duration = cfg["action_fraction"] * oscillator.period
    fixation_dose = perception_gain * fixation_duration
    n_locations = cfg["grid_rows"] * cfg["grid_cols"]
    saccade_axis = np.arange(cfg["saccades"] + 1)

    # Part 1: where to look --------------------------------------------------------------------
    curves = {name: dict(entropy=[], accuracy=[], revisit_all=[], revisit_first=[], revisit_uncertain=[])
              for name in POLICY_NAMES}
    example = {}
    jobs = [(name, seed) for seed in range(cfg["scenes"]) for name in POLICY_NAMES]
    for name, seed in tqdm(jobs, desc="vision: policies", disable=not progress):
        scene = random_scene(cfg["grid_rows"], cfg["grid_cols"], cfg["letters"], seed=seed)
        episode = run_episode(scene, eye, _policy(name), rhythm, fixation_dose, n_saccades=cfg["saccades"],
                              seed=seed, monte_carlo_samples=cfg["monte_carlo_samples"])
        c = curves[name]
        c["entropy"].append(episode.entropy)
        c["accuracy"].append(episode.accuracy)
        c["revisit_all"].append(revisit_rate(episode.fixations))
        c["revisit_first"].append(revisit_rate(episode.fixations, n_locations // 2))
        c["revisit_uncertain"].append(revisit_rate_while_uncertain(episode))
        if seed == 0:
            example[name] = (scene, episode)
    for name in POLICY_NAMES:
        c = curves[name]
        entropy, accuracy = np.array(c["entropy"]), np.array(c["accuracy"])
        mean_accuracy = accuracy.mean(axis=0)
        per_scene = [first_crossing(a, cfg["accuracy_level"], saccade_axis) for a in accuracy]
        key = name.replace(" ", "_").replace("(", "").replace(")", "")
        result.add(f"{key}: saccades to {cfg['accuracy_level']:.0%} accuracy (mean curve)",
                   first_crossing(mean_accuracy, cfg["accuracy_level"], saccade_axis), "saccades")
        result.add(f"{key}: median saccades to {cfg['accuracy_level']:.0%} accuracy per scene",
                   np.nanmedian(per_scene) if np.isfinite(per_scene).any() else float("nan"), "saccades")
        result.add(f"{key}: scenes never reaching {cfg['accuracy_level']:.0%}",
                   float(np.mean(~np.isfinite(per_scene))), "fraction")
        for n in (5, 10):
            result.add(f"{key}: accuracy after {n} saccades", mean_accuracy[n], "fraction")
            result.add(f"{key}: entropy after {n} saccades", entropy.mean(axis=0)[n], "nats")
        result.add(f"{key}: revisit rate, first {n_locations // 2} saccades", np.mean(c["revisit_first"]), "fraction")
        result.add(f"{key}: revisit rate, all {cfg['saccades']} saccades", np.mean(c["revisit_all"]), "fraction")
        result.add(f"{key}: revisit rate while summed entropy > 1 nat", np.nanmean(c["revisit_uncertain"]), "fraction")
        result.data[f"{key}_entropy"] = entropy
        result.data[f"{key}_accuracy"] = accuracy
    result.data["saccade_axis"] = saccade_axis

    # Part 2: when to look ---------------------------------------------------------------------
    n_steps = int(round(cfg["timing_duration"] / cfg["time_step"]))
    schedulers = {
        "oscillator (4 Hz)": rhythm,
        f"fixed {fixation_duration * 1e3:.0f} ms fixations (matched)": FixedDurationScheduler(
            fixation_duration, action_duration, cfg["time_step"], perception_gain, matched_suppression),
        "fixed 100 ms fixations": FixedDurationScheduler(
            0.1, action_duration, cfg["time_step"], perception_gain, matched_suppression),
        "fixed 400 ms fixations": FixedDurationScheduler(
            0.4, action_duration, cfg["time_step"], perception_gain, matched_suppression),
        "precision-driven, oscillator prior": PrecisionDrivenScheduler(
            oscillator, cfg["time_step"], action_duration, 1.0, matched_suppression, perception_gain),
        "precision-driven, no prior": PrecisionDrivenScheduler(
            oscillator, cfg["time_step"], action_duration, 0.0, matched_suppression, perception_gain),
    }
    time_axis = (np.arange(n_steps) + 1) * cfg["time_step"]
    timing = {}
    jobs = [(label, seed) for seed in range(cfg["timing_scenes"]) for label in schedulers]
    traces = {label: dict(entropy=[], accuracy=[], saccades=[]) for label in schedulers}
    for label, seed in tqdm(jobs, desc="vision: timing", disable=not progress):
        scene = random_scene(cfg["grid_rows"], cfg["grid_cols"], cfg["letters"], seed=1000 + seed)
        episode = run_episode(scene, eye, EpistemicPolicy(), schedulers[label], fixation_dose, n_steps=n_steps,
                              seed=1000 + seed, monte_carlo_samples=cfg["monte_carlo_samples"])
        traces[label]["entropy"].append(episode.entropy_trace)
        traces[label]["accuracy"].append(episode.accuracy_trace)
        traces[label]["saccades"].append(len(episode.saccades))
        if seed == 0:
            timing[label] = episode
    for label, t in traces.items():
        entropy, accuracy = np.array(t["entropy"]), np.array(t["accuracy"])
        for seconds in (0.5, 1.0):
            index = int(round(seconds / cfg["time_step"])) - 1
            result.add(f"timing {label}: entropy at {seconds:g} s", entropy.mean(axis=0)[index], "nats")
            result.add(f"timing {label}: accuracy at {seconds:g} s", accuracy.mean(axis=0)[index], "fraction")
        result.add(f"timing {label}: time to {cfg['accuracy_level']:.0%} accuracy (mean curve)",
                   first_crossing(accuracy.mean(axis=0), cfg["accuracy_level"], time_axis), "s")
        result.add(f"timing {label}: saccade rate", np.mean(t["saccades"]) / cfg["timing_duration"], "1/s")
        result.data[f"timing {label} entropy"] = entropy
        result.data[f"timing {label} accuracy"] = accuracy
    result.data["time_axis"] = time_axis

    if out_dir is not None:
        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        result.figures.extend(plot(result, example, timing, oscillator, out, cfg))
    return result


def plot(result: ExperimentResult, example: dict, timing: dict, oscillator: PrecisionOscillator,
         out: Path, cfg: dict) -> list[str]:
    """vision_scanpath.png (salience map per saccade), vision.png (curves), vision_scanpath.gif."""
    import matplotlib

    if os.environ.get("MPLBACKEND") is None:
        matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.animation import FuncAnimation, PillowWriter

    files = []
    scene, episode = example["epistemic"]
    rows, cols = scene.shape
    image = scene.image()
    side = int(round(np.sqrt(scene.patterns.shape[1]))) + 1
    extent = (-(side / 2) / side - 0.5 / side, (image.shape[1] - side / 2 - 0.5) / side,
              (image.shape[0] - side / 2 - 0.5) / side, -(side / 2) / side - 0.5 / side)
    locations = scene.locations
    shown = min(8, len(episode.saccades))

    def draw_panel(axis, index):
        record = episode.saccades[index]
        axis.imshow(image, cmap="Greys", extent=extent, interpolation="nearest", alpha=0.55)
        heat = axis.imshow(record.salience.reshape(rows, cols), cmap="magma", alpha=0.55,
                           extent=(-0.5, cols - 0.5, rows - 0.5, -0.5), interpolation="nearest")
        path = locations[episode.fixations[: index + 2]]
        axis.plot(path[:, 1], path[:, 0], "-o", color="tab:cyan", lw=1.5, ms=4)
        axis.plot(path[-1, 1], path[-1, 0], "*", color="lime", ms=14)
        axis.set_title(f"saccade {index + 1}: H = {record.entropy:.1f} nats", fontsize=8)
        axis.set_xticks([])
        axis.set_yticks([])
        return heat

    figure, axes = plt.subplots(2, 4, figsize=(12, 6.4))
    for index, axis in enumerate(axes.ravel()):
        if index < shown:
            heat = draw_panel(axis, index)
            figure.colorbar(heat, ax=axis, fraction=0.046, label="salience [nats]" if index % 4 == 3 else None)
        else:
            axis.axis("off")
    figure.suptitle("Epistemic scanpath on scene 0: salience map (expected information gain of each "
                    "fixation) before each saccade; star = chosen target")
    figure.tight_layout()
    path = out / "vision_scanpath.png"
    figure.savefig(path, dpi=110)
    plt.close(figure)
    files.append(str(path))

    figure, axis = plt.subplots(figsize=(4.5, 4.5))

    def frame(index):
        axis.clear()
        draw_panel(axis, index)

    animation = FuncAnimation(figure, frame, frames=len(episode.saccades), interval=600)
    path = out / "vision_scanpath.gif"
    animation.save(path, writer=PillowWriter(fps=2))
    plt.close(figure)
    files.append(str(path))

    figure, axes = plt.subplots(2, 3, figsize=(15, 8.5))
    saccade_axis = result.data["saccade_axis"]
    colours = dict(zip(POLICY_NAMES, ("tab:red", "tab:blue", "tab:gray", "tab:green")))
    for name in POLICY_NAMES:
        key = name.replace(" ", "_").replace("(", "").replace(")", "")
        for axis, quantity in zip(axes[0, :2], ("entropy", "accuracy")):
            values = result.data[f"{key}_{quantity}"]
            mean = values.mean(axis=0)
            se = values.std(axis=0) / np.sqrt(len(values))
            axis.plot(saccade_axis, mean, color=colours[name], label=name)
            axis.fill_between(saccade_axis, mean - se, mean + se, color=colours[name], alpha=0.2)
    axes[0, 0].set(xlabel="saccades", ylabel="remaining entropy [nats]", title="uncertainty left")
    axes[0, 1].axhline(cfg["accuracy_level"], color="k", ls=":", lw=1)
    axes[0, 1].set(xlabel="saccades", ylabel="identification accuracy", title="accuracy (mean ± SE)")
    axes[0, 0].legend(fontsize=8)
    rates = [[result.metric(f"{n.replace(' ', '_').replace('(', '').replace(')', '')}: revisit rate, {w}").value
              for n in POLICY_NAMES] for w in (f"first {rows * cols // 2} saccades", f"all {cfg['saccades']} saccades")]
    positions = np.arange(len(POLICY_NAMES))
    axes[0, 2].bar(positions - 0.2, rates[0], 0.4, label=f"first {rows * cols // 2} saccades")
    axes[0, 2].bar(positions + 0.2, rates[1], 0.4, label=f"all {cfg['saccades']} saccades")
    axes[0, 2].set_xticks(positions, [n.replace(" (", "\n(") for n in POLICY_NAMES], fontsize=8)
    axes[0, 2].set(ylabel="revisit rate", title="revisits (IOR coded only in static saliency)")
    axes[0, 2].legend(fontsize=8)

    time_axis = result.data["time_axis"]
    for label in timing:
        entropy = result.data[f"timing {label} entropy"].mean(axis=0)
        accuracy = result.data[f"timing {label} accuracy"].mean(axis=0)
        axes[1, 0].plot(time_axis, entropy, label=label)
        axes[1, 1].plot(time_axis, accuracy, label=label)
    axes[1, 0].set(xlabel="time [s]", ylabel="remaining entropy [nats]", title="when to look: entropy vs time",
                   yscale="log")
    axes[1, 1].axhline(cfg["accuracy_level"], color="k", ls=":", lw=1)
    axes[1, 1].set(xlabel="time [s]", ylabel="identification accuracy", title="when to look: accuracy vs time")
    axes[1, 0].legend(fontsize=7)
    window = min(1.0, time_axis[-1])
    t = np.linspace(0, window, 800)
    axes[1, 2].plot(t, oscillator.gain(t), color="k", lw=1, label="pi(t)")
    axes[1, 2].axhline(oscillator.threshold(cfg["action_fraction"]), color="k", ls=":", lw=1)
    for label, style in (("oscillator (4 Hz)", "tab:red"), ("precision-driven, oscillator prior", "tab:purple")):
        schedule = timing[label].schedule
        keep = schedule.time < window
        axes[1, 2].step(schedule.time[keep], schedule.precision_gain[keep], where="post", color=style,
                        alpha=0.8, label=f"{label}: step gain")
    axes[1, 2].set(xlabel="time [s]", ylabel="precision gain g", title="schedules (scene 1000)")
    axes[1, 2].legend(fontsize=7)
    figure.tight_layout()
    path = out / "vision.png"
    figure.savefig(path, dpi=110)
    plt.close(figure)
    files.append(str(path))
    return files
