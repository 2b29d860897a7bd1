"""Active vision on a rhythm (paper Sec. 2-3, Fig. 1).

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

Part 2, when to look (epistemic policy for all): the rhythmic schedule vs fixed fixation
durations (the matched one has the oscillator's saccade rate and precision budget: perception
multiplier = mean of pi(t) over the oscillator's perception windows, act multiplier = mean of
0.1 pi(t) over its troughs; the precision-driven schedule uses the same two multipliers) vs the
precision-driven schedule (move when the expected information gain of staying drops below that
of moving, with and without the oscillator as a prior on timing). Metrics vs time [s].
Schedules: :mod:`attend.rhythm.schedule`, on the eye's clock by
:func:`attend.rhythm.fixations.fixation_policy`.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from tqdm import tqdm

from attend.experiments._result import Claim, ExperimentResult
from attend.rhythm.fixations import fixation_policy
from attend.rhythm.oscillator import PrecisionOscillator
from attend.rhythm.schedule import FixedSchedule, PrecisionDrivenSchedule, RhythmicSchedule
from attend.rhythm.vision import EpistemicPolicy, FoveatedEye, RandomPolicy, StaticSaliencyPolicy, look, random_scene

SETTINGS = dict(
    grid_rows=5, grid_cols=5, letters="EFTLOC", fovea_width=0.6, foveal_precision_rate=12.0,
    frequency=4.0, depth=1.0, action_fraction=0.25, saccadic_suppression=0.1, time_step=0.0125,
    accuracy_level=0.9,
)
QUICK = dict(scenes=16, saccades=20, monte_carlo_samples=16, timing_scenes=5, timing_duration=2.0)
FULL = dict(scenes=100, saccades=30, monte_carlo_samples=48, timing_scenes=40, timing_duration=3.0)

POLICY_NAMES = ("epistemic", "static saliency", "static saliency (no IOR)", "random")
#: the two schedules whose steps vision.png shows
SHOWN_SCHEDULES = ("oscillator (4 Hz)", "precision-driven, oscillator prior")


def _policy(name: str):
    return {"epistemic": EpistemicPolicy, "random": RandomPolicy,
            "static saliency": lambda: StaticSaliencyPolicy(True),
            "static saliency (no IOR)": lambda: StaticSaliencyPolicy(False)}[name]()


def _key(name: str) -> str:
    return name.replace(" ", "_").replace("(", "").replace(")", "")


def first_crossing(curve: np.ndarray, level: float, axis_values: np.ndarray) -> float:
    """First of ``axis_values`` at which ``curve`` >= ``level`` (NaN if never)."""
    hits = np.nonzero(curve >= level)[0]
    return float(axis_values[hits[0]]) if len(hits) else float("nan")


def revisit_rate(fixations: list[int], n_saccades: int | None = None) -> float:
    """Fraction of the first ``n_saccades`` saccades of the scanpath ``fixations`` (location
    indices) that land on a location fixated before."""
    last = len(fixations) if n_saccades is None else min(len(fixations), n_saccades + 1)
    landings = [fixations[i] in fixations[:i] for i in range(1, last)]
    return float(np.mean(landings)) if landings else float("nan")


def revisit_rate_while_uncertain(episode, entropy_level: float = 1.0) -> float:
    """Fraction of revisiting saccades of ``episode`` among those made while the summed entropy
    exceeded ``entropy_level`` [nats] (after that the scene is resolved and no location has value)."""
    landings = [episode.fixations[i + 1] in episode.fixations[: i + 1]
                for i, record in enumerate(episode.saccades) if record.entropy > entropy_level]
    return float(np.mean(landings)) if landings else float("nan")


def run(quick: bool = True, progress: bool = True, scenes: int | None = None) -> ExperimentResult:
    """Both parts (module docstring). quick: 16 scenes, 20 saccades (else 100, 30); scenes:
    override the number of scenes; progress: progress bars."""
    cfg = dict(SETTINGS, **(QUICK if quick else FULL))
    if scenes is not None:
        cfg["scenes"] = scenes
        cfg["timing_scenes"] = max(2, min(cfg["timing_scenes"], scenes))
    result = ExperimentResult("vision", settings=dict(cfg, quick=quick))
    eye = FoveatedEye(cfg["fovea_width"], cfg["foveal_precision_rate"])
    oscillator = PrecisionOscillator(cfg["frequency"], cfg["depth"])
    rhythm = fixation_policy(RhythmicSchedule(oscillator, cfg["action_fraction"]), cfg["time_step"],
                             cfg["saccadic_suppression"])
    perception = rhythm.mean_perception_multiplier()
    # matched budget: the other policies' act-step multiplier s' m equals the rhythm's mean s pi(t)
    suppression = rhythm.mean_action_multiplier() / perception
    result.settings.update(matched_perception_multiplier=perception, matched_saccadic_suppression=suppression)
    fixation_duration = (1.0 - cfg["action_fraction"]) * oscillator.period
    fixation_dose = perception * fixation_duration
    _where_to_look(result, cfg, eye, rhythm, fixation_dose, progress)
    _when_to_look(result, cfg, eye, _timing_policies(cfg, oscillator, rhythm, perception, suppression),
                  fixation_dose, progress)
    return result


def _where_to_look(result: ExperimentResult, cfg: dict, eye, rhythm, fixation_dose: float, progress: bool) -> None:
    """Part 1: every saccade policy on the same rhythm, over seeded scenes (metrics and tables)."""
    n_locations = cfg["grid_rows"] * cfg["grid_cols"]
    saccade_axis = np.arange(cfg["saccades"] + 1)
    curves = {name: dict(entropy=[], accuracy=[], revisit_all=[], revisit_first=[], revisit_uncertain=[])
              for name in POLICY_NAMES}
    jobs = [(name, seed) for seed in range(cfg["scenes"]) for name in POLICY_NAMES]
    for name, seed in tqdm(jobs, desc="vision: policies", disable=not progress):
        scene = random_scene(cfg["grid_rows"], cfg["grid_cols"], cfg["letters"], seed=seed)
        episode = look(scene, eye, _policy(name), rhythm, fixation_dose, n_saccades=cfg["saccades"],
                       seed=seed, monte_carlo_samples=cfg["monte_carlo_samples"])
        c = curves[name]
        c["entropy"].append(episode.entropy)
        c["accuracy"].append(episode.accuracy)
        c["revisit_all"].append(revisit_rate(episode.fixations))
        c["revisit_first"].append(revisit_rate(episode.fixations, n_locations // 2))
        c["revisit_uncertain"].append(revisit_rate_while_uncertain(episode))
        if seed == 0 and name == "epistemic":
            result.tables["scanpath"] = _scanpath_table(scene, episode)
    where = {}
    for name in POLICY_NAMES:
        entropy, accuracy = np.array(curves[name]["entropy"]), np.array(curves[name]["accuracy"])
        _add_where_metrics(result, cfg, name, curves[name], entropy, accuracy, saccade_axis, n_locations)
        where[name] = dict(entropy_mean=entropy.mean(axis=0), entropy_se=entropy.std(axis=0) / np.sqrt(len(entropy)),
                           accuracy_mean=accuracy.mean(axis=0),
                           accuracy_se=accuracy.std(axis=0) / np.sqrt(len(accuracy)))
        result.data[f"{_key(name)}_entropy"] = entropy
        result.data[f"{_key(name)}_accuracy"] = accuracy
    result.tables.update(saccade_axis=saccade_axis, where=where)


def _add_where_metrics(result, cfg, name, c, entropy, accuracy, saccade_axis, n_locations) -> None:
    mean_accuracy, level, key = accuracy.mean(axis=0), cfg["accuracy_level"], _key(name)
    per_scene = [first_crossing(a, level, saccade_axis) for a in accuracy]
    result.add(f"{key}: saccades to {level:.0%} accuracy (mean curve)",
               first_crossing(mean_accuracy, level, saccade_axis), "saccades")
    result.add(f"{key}: median saccades to {level:.0%} accuracy per scene",
               np.nanmedian(per_scene) if np.isfinite(per_scene).any() else float("nan"), "saccades")
    result.add(f"{key}: scenes never reaching {level:.0%}", float(np.mean(~np.isfinite(per_scene))), "fraction")
    for n in (5, 10):
        result.add(f"{key}: accuracy after {n} saccades", mean_accuracy[n], "fraction")
        result.add(f"{key}: entropy after {n} saccades", entropy.mean(axis=0)[n], "nats")
    result.add(f"{key}: revisit rate, first {n_locations // 2} saccades", np.mean(c["revisit_first"]), "fraction")
    result.add(f"{key}: revisit rate, all {cfg['saccades']} saccades", np.mean(c["revisit_all"]), "fraction")
    result.add(f"{key}: revisit rate while summed entropy > 1 nat", np.nanmean(c["revisit_uncertain"]), "fraction")


def _scanpath_table(scene, episode) -> dict:
    """What the scanpath figures need from one episode: the scene image, the locations, the
    fixations and, per saccade, the salience map and the entropy before it."""
    return dict(image=scene.image(), shape=list(scene.shape), side=int(round(np.sqrt(scene.patterns.shape[1]))) + 1,
                locations=scene.locations, fixations=list(episode.fixations),
                salience=[record.salience for record in episode.saccades],
                entropy=[record.entropy for record in episode.saccades])


def _timing_policies(cfg: dict, oscillator, rhythm, perception: float, suppression: float) -> dict:
    """Part 2's fixation policies, all with the rhythm's precision budget (module docstring)."""
    dt, q = cfg["time_step"], cfg["action_fraction"]
    fixation, saccade = (1.0 - q) * oscillator.period, q * oscillator.period

    def fixed(duration):
        return fixation_policy(FixedSchedule(duration, saccade, perception), dt, suppression)

    def precision_driven(weight):
        return fixation_policy(PrecisionDrivenSchedule(oscillator, weight, 1.0), dt, suppression, saccade_s=saccade,
                               perception_multiplier=perception)

    return {"oscillator (4 Hz)": rhythm, f"fixed {fixation * 1e3:.0f} ms fixations (matched)": fixed(fixation),
            "fixed 100 ms fixations": fixed(0.1), "fixed 400 ms fixations": fixed(0.4),
            "precision-driven, oscillator prior": precision_driven(1.0),
            "precision-driven, no prior": precision_driven(0.0)}


def _when_to_look(result: ExperimentResult, cfg: dict, eye, policies: dict, fixation_dose: float,
                  progress: bool) -> None:
    """Part 2: the epistemic policy timed by every fixation policy (metrics and tables)."""
    dt = cfg["time_step"]
    n_steps = int(round(cfg["timing_duration"] / dt))
    time_axis = (np.arange(n_steps) + 1) * dt
    traces = {label: dict(entropy=[], accuracy=[], saccades=[]) for label in policies}
    shown = {}
    jobs = [(label, seed) for seed in range(cfg["timing_scenes"]) for label in policies]
    for label, seed in tqdm(jobs, desc="vision: timing", disable=not progress):
        scene = random_scene(cfg["grid_rows"], cfg["grid_cols"], cfg["letters"], seed=1000 + seed)
        episode = look(scene, eye, EpistemicPolicy(), policies[label], fixation_dose, n_steps=n_steps,
                       seed=1000 + seed, monte_carlo_samples=cfg["monte_carlo_samples"])
        traces[label]["entropy"].append(episode.entropy_trace)
        traces[label]["accuracy"].append(episode.accuracy_trace)
        traces[label]["saccades"].append(len(episode.saccades))
        if seed == 0 and label in SHOWN_SCHEDULES:
            keep = episode.schedule.time < min(1.0, time_axis[-1])
            shown[label] = dict(time=episode.schedule.time[keep],
                                precision_multiplier=episode.schedule.precision_multiplier[keep])
    when = {}
    for label, t in traces.items():
        entropy, accuracy = np.array(t["entropy"]), np.array(t["accuracy"])
        for seconds in (0.5, 1.0):
            index = int(round(seconds / dt)) - 1
            result.add(f"timing {label}: entropy at {seconds:g} s", entropy.mean(axis=0)[index], "nats")
            result.add(f"timing {label}: accuracy at {seconds:g} s", accuracy.mean(axis=0)[index], "fraction")
        result.add(f"timing {label}: time to {cfg['accuracy_level']:.0%} accuracy (mean curve)",
                   first_crossing(accuracy.mean(axis=0), cfg["accuracy_level"], time_axis), "s")
        result.add(f"timing {label}: saccade rate", np.mean(t["saccades"]) / cfg["timing_duration"], "1/s")
        when[label] = dict(entropy_mean=entropy.mean(axis=0), accuracy_mean=accuracy.mean(axis=0))
        result.data[f"timing {label} entropy"] = entropy
        result.data[f"timing {label} accuracy"] = accuracy
    result.tables.update(time_axis=time_axis, when=when, shown_schedules=shown)


CAPTIONS = {
    "vision_scanpath.png": (
        "The epistemic scanpath on scene 0: before each of the first 8 saccades, the salience map "
        "(expected information gain of a fixation at each location, nats) over the hidden letters; "
        "cyan: the path so far; star: the chosen target. Resolved locations go dark, so the eye "
        "does not return to them although no inhibition of return is coded."),
    "vision_scanpath.gif": "The same scanpath as an animation, one frame per saccade.",
    "vision.png": (
        "Top, where to look (same 4 Hz rhythm for all): summed entropy and identification "
        "accuracy against the number of saccades (mean +- s.e. over scenes) for the epistemic, "
        "static-saliency (with and without inhibition of return) and random policies, and their "
        "revisit rates. Bottom, when to look (epistemic policy for all): entropy and accuracy "
        "against time for the rhythmic, fixed and precision-driven schedules at the same precision "
        "budget, and the precision multiplier of two schedules' steps over the first second with "
        "the oscillator pi(t) and its threshold (dotted)."),
}


def plot(result: ExperimentResult, out_dir) -> list[str]:
    """vision_scanpath.png, vision_scanpath.gif and vision.png from ``result.tables`` into
    ``out_dir`` (CAPTIONS); returns their paths."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    for name, fig in (("vision_scanpath.png", _plot_scanpath(result)), ("vision.png", _plot_curves(result))):
        fig.tight_layout()
        fig.savefig(out / name, dpi=110)
        paths.append(str(out / name))
    return [paths[0], str(_write_scanpath_gif(result, out)), paths[1]]


def _draw_saccade(axis, scanpath: dict, index: int):
    """One panel: the scene, the salience map before saccade ``index`` and the path so far."""
    rows, cols = scanpath["shape"]
    image, side = np.asarray(scanpath["image"], dtype=float), scanpath["side"]
    extent = (-(side / 2) / side - 0.5 / side, (image.shape[1] - side / 2 - 0.5) / side,
              (image.shape[0] - side / 2 - 0.5) / side, -(side / 2) / side - 0.5 / side)
    axis.imshow(image, cmap="Greys", extent=extent, interpolation="nearest", alpha=0.55)
    heat = axis.imshow(np.asarray(scanpath["salience"][index], dtype=float).reshape(rows, cols), cmap="magma",
                       alpha=0.55, extent=(-0.5, cols - 0.5, rows - 0.5, -0.5), interpolation="nearest")
    path = np.asarray(scanpath["locations"], dtype=float)[scanpath["fixations"][: index + 2]]
    axis.plot(path[:, 1], path[:, 0], "-o", color="tab:cyan", lw=1.5, ms=4)
    axis.plot(path[-1, 1], path[-1, 0], "*", color="lime", ms=14)
    axis.set_title(f"saccade {index + 1}: H = {scanpath['entropy'][index]:.1f} nats", fontsize=8)
    axis.set_xlabel("column [grid units]", fontsize=7)
    axis.set_ylabel("row [grid units]", fontsize=7)
    axis.set_xticks([])
    axis.set_yticks([])
    return heat


def _plot_scanpath(result: ExperimentResult):
    from attend.plotting import figure

    scanpath = result.tables["scanpath"]
    shown = min(8, len(scanpath["salience"]))
    fig, axes = figure((12, 6.4), 2, 4)
    for index, axis in enumerate(axes.ravel()):
        if index < shown:
            heat = _draw_saccade(axis, scanpath, index)
            fig.colorbar(heat, ax=axis, fraction=0.046, label="salience [nats]" if index % 4 == 3 else None)
        else:
            axis.axis("off")
    fig.suptitle("Epistemic scanpath on scene 0: salience map (expected information gain of each "
                 "fixation) before each saccade; star = chosen target")
    return fig


def _write_scanpath_gif(result: ExperimentResult, out: Path) -> Path:
    """One frame per saccade (Agg canvases), written as an animated GIF at 2 frames per second."""
    from PIL import Image

    from attend.plotting import figure

    scanpath = result.tables["scanpath"]
    frames = []
    for index in range(len(scanpath["salience"])):
        fig, axis = figure((4.5, 4.5))
        _draw_saccade(axis, scanpath, index)
        fig.canvas.draw()
        frames.append(Image.fromarray(np.asarray(fig.canvas.buffer_rgba())).convert("RGB"))
    path = out / "vision_scanpath.gif"
    frames[0].save(path, save_all=True, append_images=frames[1:], duration=500, loop=0)
    return path


def _plot_curves(result: ExperimentResult):
    from attend.plotting import figure

    fig, axes = figure((15, 8.5), 2, 3)
    _plot_where(axes[0], result)
    _plot_when(axes[1], result)
    return fig


def _plot_where(axes, result: ExperimentResult) -> None:
    cfg, where = result.settings, result.tables["where"]
    saccade_axis = np.asarray(result.tables["saccade_axis"], dtype=float)
    colours = dict(zip(POLICY_NAMES, ("tab:red", "tab:blue", "tab:gray", "tab:green")))
    for name in POLICY_NAMES:
        for axis, quantity in zip(axes[:2], ("entropy", "accuracy")):
            mean = np.asarray(where[name][f"{quantity}_mean"], dtype=float)
            se = np.asarray(where[name][f"{quantity}_se"], dtype=float)
            axis.plot(saccade_axis, mean, color=colours[name], label=name)
            axis.fill_between(saccade_axis, mean - se, mean + se, color=colours[name], alpha=0.2)
    axes[0].set(xlabel="saccades [count]", ylabel="remaining entropy [nats]", title="uncertainty left")
    axes[1].axhline(cfg["accuracy_level"], color="k", ls=":", lw=1)
    axes[1].set(xlabel="saccades [count]", ylabel="identification accuracy [fraction]",
                title="accuracy (mean ± SE)")
    axes[0].legend(fontsize=8)
    half = cfg["grid_rows"] * cfg["grid_cols"] // 2
    windows = (f"first {half} saccades", f"all {cfg['saccades']} saccades")
    rates = [[result.metric(f"{_key(n)}: revisit rate, {w}").value for n in POLICY_NAMES] for w in windows]
    positions = np.arange(len(POLICY_NAMES))
    axes[2].bar(positions - 0.2, rates[0], 0.4, label=windows[0])
    axes[2].bar(positions + 0.2, rates[1], 0.4, label=windows[1])
    axes[2].set_xticks(positions, [n.replace(" (", "\n(") for n in POLICY_NAMES], fontsize=8)
    axes[2].set(xlabel="saccade policy", ylabel="revisit rate [fraction of saccades]",
                title="revisits (IOR coded only in static saliency)")
    axes[2].legend(fontsize=8)


def _plot_when(axes, result: ExperimentResult) -> None:
    cfg, when = result.settings, result.tables["when"]
    time_axis = np.asarray(result.tables["time_axis"], dtype=float)
    for label, curves in when.items():
        axes[0].plot(time_axis, np.asarray(curves["entropy_mean"], dtype=float), label=label)
        axes[1].plot(time_axis, np.asarray(curves["accuracy_mean"], dtype=float), label=label)
    axes[0].set(xlabel="time [s]", ylabel="remaining entropy [nats]", title="when to look: entropy vs time",
                yscale="log")
    axes[1].axhline(cfg["accuracy_level"], color="k", ls=":", lw=1)
    axes[1].set(xlabel="time [s]", ylabel="identification accuracy [fraction]", title="when to look: accuracy vs time")
    axes[0].legend(fontsize=7)
    oscillator = PrecisionOscillator(cfg["frequency"], cfg["depth"])
    t = np.linspace(0, min(1.0, time_axis[-1]), 800)
    axes[2].plot(t, oscillator.multiplier(t), color="k", lw=1, label="pi(t)")
    axes[2].axhline(oscillator.threshold(cfg["action_fraction"]), color="k", ls=":", lw=1)
    for label, colour in zip(SHOWN_SCHEDULES, ("tab:red", "tab:purple")):
        steps = result.tables["shown_schedules"].get(label)
        if steps is not None:
            axes[2].step(steps["time"], steps["precision_multiplier"], where="post", color=colour, alpha=0.8,
                         label=f"{label}: step multiplier")
    axes[2].set(xlabel="time [s]", ylabel="precision multiplier [1]", title="schedules (scene 1000)")
    axes[2].legend(fontsize=7)


def claims(result: ExperimentResult) -> list[Claim]:
    """The paper's claims on active vision (§2-3, Fig. 1): epistemic
    salience finds the letters in fewer saccades than static saliency and random saccades;
    inhibition of return emerges without being coded; and timing saccades on the rhythm helps
    (against fixed fixations and the precision-driven rule at the same precision budget).
    result: the ExperimentResult of :func:`run`."""
    value = lambda name: result.metric(name).value  # noqa: E731
    level = f"{result.settings['accuracy_level']:.0%}"
    saccades = {n: value(f"{_key(n)}: saccades to {level} accuracy (mean curve)") for n in POLICY_NAMES}
    others = {n: v for n, v in saccades.items() if n != "epistemic"}
    fewer = all(not np.isfinite(v) or saccades["epistemic"] < v for v in others.values())
    claims_found = [Claim(
        f"Saccades to the most informative location (epistemic salience) reach {level} accuracy in fewer "
        "saccades than static saliency or random saccades",
        "saccades to " + level + " (mean curve): " + ", ".join(f"{n} {_text(v)}" for n, v in saccades.items()),
        "reproduced" if fewer else "does not hold")]
    uncertain = {n: value(f"{_key(n)}: revisit rate while summed entropy > 1 nat") for n in POLICY_NAMES}
    emerges = uncertain["epistemic"] < uncertain["random"] and uncertain["epistemic"] < uncertain["static saliency (no IOR)"]
    claims_found.append(Claim(
        "Inhibition of return emerges from epistemic salience without being coded",
        "revisit rate while the scene is unresolved: " + ", ".join(f"{n} {v:.2f}" for n, v in uncertain.items()),
        "reproduced" if emerges else "does not hold"))
    claims_found.append(_timing_claim(result, value))
    return claims_found


def _text(value: float) -> str:
    return f"{value:g}" if np.isfinite(value) else "never"


def _timing_claim(result: ExperimentResult, value) -> Claim:
    labels = list(result.tables["when"])
    entropy = {label: value(f"timing {label}: entropy at 1 s") for label in labels}
    rhythmic = min(entropy[label] for label in labels if label in SHOWN_SCHEDULES)
    others = min(entropy[label] for label in labels if label not in SHOWN_SCHEDULES)
    measured = ("summed entropy at 1 s [nats], mean over scenes: " + ", ".join(f"{k} {v:.1f}" for k, v in entropy.items())
                + f" ({result.settings.get('timing_scenes')} scenes)")
    return Claim("Timing saccades on the rhythm (or with the rhythm as a prior) leaves less uncertainty than "
                 "fixed fixations or precision dynamics alone, at the same precision budget", measured,
                 "reproduced" if rhythmic < others else "does not hold")
