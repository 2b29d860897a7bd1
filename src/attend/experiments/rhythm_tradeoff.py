"""Experiment "rhythm-tradeoff": where does a rhythm help when action and perception compete?

The paper (§4.4, Fig. 10) proposes that a rhythm, or precision dynamics with a rhythm as prior,
should decide when to stop acting and perceive, instead of a fixed budget. In today's settings
switching is free, so there is nothing for a schedule to trade off (docs/experiments/rhythm-ipp.md).
Here switching costs, with a knob for how much, and every schedule is tuned the same way.

**UAV search** (the mission of :mod:`attend.experiments.ipp`: 40 x 40 map, 7 people, 150 s of
battery, ``precision_gain`` planner, 5-waypoint look-ahead). Two costs (:mod:`attend.action`):
motion blur (images taken at speed v read with precision q / sigma^2(h), q = 1 / (1 + b v);
sharp when hovering) and planning latency L (each plan takes L s of on-board computing, spent
hovering, charged to the battery). Schedule families (:mod:`attend.rhythm.replanning`):

* ``fixed``: replan after a fixed flight time per plan, or after every segment (the robotics
  standard, swept);
* ``oscillator``: replan at the troughs of a precision oscillator (phase-locked alternation; its
  period swept);
* ``precision``: replan when the rest of the plan pays less than a fresh plan (net of the
  latency), with the oscillator phase as a prior on the timing (tolerance, weight, period swept);
* ``precision_no_prior``: the same rule without the oscillator (tolerance swept);
* ``continuous``: always moving, always sensing (fly every plan to its end; nothing to tune).

**Active vision** (the foveated eye of :mod:`attend.experiments.vision`, 5 x 5 letters): a
saccade of duration c suppresses sensing (gain 0.1) and costs time; fixation precision grows
with dwell time with diminishing returns (adaptation time tau_a); a precision-driven decision to
move takes ``vision_decision_time_s`` before the saccade can start (clock-driven schedules know
their saccade times in advance). Families (:mod:`attend.rhythm.fixations`): ``fixed`` dwell
(swept), ``oscillator`` at 3-8 Hz (the trough holds the saccade; precision multiplier
normalised to a mean of 1 while fixating), ``precision`` (with the oscillator prior) and
``precision_no_prior``. Every schedule perceives at mean multiplier 1 and acts at 0.1.

**Equal terms.** For each setting of the trade-off (blur x latency; saccade cost), every
family's parameters are tuned on the tuning seeds (100, 101, ...) with the same number of
evaluated settings per family (``continuous`` has one), by the mean objective (final RSE; the
time-averaged entropy of the scene [nats]). The tuned setting of each family then flies / looks
at the trial seeds (0, 1, ..., as in ``attend reproduce ipp``), untouched until then. Reported
per setting: the winner (lowest trial mean) and paired differences of every family to the tuned
fixed budget and to the winner, with 95 % t confidence intervals over the trial seeds.

Quick mode: 2 settings per task, 2 parameter settings per family, 2 tuning and 3 trial seeds
(< 60 s on 2 cores). Full mode: a 3 x 3 (blur x latency) grid and 4 saccade costs, 6 settings
per family, 8 tuning and 25 trial seeds; meant for a Dask cluster (``cluster=``), with the same
numbers as a local run.
"""

from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np

from attend._validation import AttendInputError
from attend.experiments._result import Claim, ExperimentResult
from attend.sweep import run_tasks

SETTINGS = dict(
    ipp_budget_s=150.0,
    ipp_planner="precision_gain",
    ipp_lookahead_waypoints=5,
    ipp_cma_evaluations=6,
    ipp_diagonal=True,
    ipp_blur_per_speed=[0.0, 0.15, 0.4],
    ipp_latency_s=[0.0, 3.0, 8.0],
    quick_ipp_blur_per_speed=[0.0, 0.4],
    quick_ipp_latency_s=[0.0, 8.0],
    vision_rows=5,
    vision_cols=5,
    vision_letters="EFTLOC",
    vision_fovea_width=0.6,
    vision_foveal_precision_rate=12.0,
    vision_adaptation_time_s=0.15,
    vision_time_step_s=0.0125,
    vision_duration_s=2.0,
    vision_saccadic_suppression=0.1,
    vision_decision_time_s=0.025,
    vision_oscillator_depth=1.0,
    vision_saccade_cost_s=[0.025, 0.05, 0.1, 0.15],
    quick_vision_saccade_cost_s=[0.05, 0.15],
    vision_monte_carlo_samples=16,
    quick_vision_monte_carlo_samples=8,
    quick_vision_duration_s=1.5,
    tuning_first_seed=100,
    quick_tuning_seeds=2,
    full_tuning_seeds=8,
    trial_first_seed=0,
    quick_trials=3,
    full_trials=25,
    quick_settings_per_family=2,
    full_settings_per_family=6,
    confidence=0.95,
)

#: Parameter settings per IPP family, in the order tried (quick mode: the first 2 of each list).
IPP_FAMILIES: dict[str, list[dict]] = {
    "fixed": [dict(budget="fixed_20s"), dict(budget="segment"), dict(budget="fixed_5s"), dict(budget="fixed_10s"),
              dict(budget="fixed_40s"), dict(budget="fixed_80s")],
    "oscillator": [dict(period_s=20.0), dict(period_s=40.0), dict(period_s=10.0), dict(period_s=15.0),
                   dict(period_s=30.0), dict(period_s=60.0)],
    "precision": [dict(tolerance=1.0, prior_weight=0.5, period_s=20.0), dict(tolerance=0.7, prior_weight=1.0, period_s=20.0),
                  dict(tolerance=1.0, prior_weight=1.0, period_s=40.0), dict(tolerance=0.7, prior_weight=0.5, period_s=40.0),
                  dict(tolerance=1.3, prior_weight=0.5, period_s=20.0), dict(tolerance=1.0, prior_weight=2.0, period_s=20.0)],
    "precision_no_prior": [dict(tolerance=1.0), dict(tolerance=0.7), dict(tolerance=0.5), dict(tolerance=0.85),
                           dict(tolerance=1.2), dict(tolerance=1.5)],
    "continuous": [dict()],
}

#: Parameter settings per vision family (quick mode: the first 2 of each list).
VISION_FAMILIES: dict[str, list[dict]] = {
    "fixed": [dict(dwell_s=0.1), dict(dwell_s=0.25), dict(dwell_s=0.05), dict(dwell_s=0.15), dict(dwell_s=0.2),
              dict(dwell_s=0.35)],
    "oscillator": [dict(frequency_hz=4.0), dict(frequency_hz=6.0), dict(frequency_hz=3.0), dict(frequency_hz=5.0),
                   dict(frequency_hz=7.0), dict(frequency_hz=8.0)],
    "precision": [dict(frequency_hz=4.0, prior_weight=1.5), dict(frequency_hz=6.0, prior_weight=0.5),
                  dict(frequency_hz=4.0, prior_weight=0.5), dict(frequency_hz=6.0, prior_weight=1.5),
                  dict(frequency_hz=8.0, prior_weight=0.5), dict(frequency_hz=8.0, prior_weight=1.5)],
    "precision_no_prior": [dict(fixation_s=0.1), dict(fixation_s=0.2), dict(fixation_s=0.05), dict(fixation_s=0.15),
                           dict(fixation_s=0.3), dict(fixation_s=0.45)],
}

#: families whose timing comes from the rhythm
RHYTHMIC = ("oscillator", "precision")


# ----------------------------------------------------------------------------------------------
# One episode (a sweep task)


def ipp_episode(task: dict) -> dict:
    """One mission: ``task`` holds ``blur`` [s/m], ``latency_s``, ``family``, ``params``, ``seed``
    and ``settings``. Returns final RSE, trace(P), people found, time to find all 7 (inf if
    never), false-alarm cells and objects, replans and hover time."""
    from attend.action import Camera, Detector, FlightModel, PlanningSetup, make_field, make_planner
    from attend.rhythm.replanning import fly_scheduled_mission, make_replan_policy

    s, p, seed = task["settings"], task["params"], int(task["seed"])
    field = make_field(seed)
    detector = Detector(motion_blur_per_speed=float(task["blur"]))
    setup = PlanningSetup(field, Camera(), detector, FlightModel(), lookahead_waypoints=s["ipp_lookahead_waypoints"],
                          cma_evaluations=s["ipp_cma_evaluations"])
    planner = make_planner(s["ipp_planner"], setup, seed)
    latency = float(task["latency_s"])
    family = task["family"]
    if family == "fixed":
        policy = make_replan_policy(p["budget"])
    elif family == "oscillator":
        policy = make_replan_policy("oscillator", 1.0 / p["period_s"])
    elif family == "precision":
        policy = make_replan_policy("precision", 1.0 / p["period_s"], 0.0, p["prior_weight"], p["tolerance"], latency)
    elif family == "precision_no_prior":
        policy = make_replan_policy("precision_no_prior", tolerance=p["tolerance"], switch_cost_s=latency)
    elif family == "continuous":
        policy = make_replan_policy("continuous")
    else:
        raise AttendInputError(f"family: unknown IPP schedule family {family!r}")
    log = fly_scheduled_mission(field, planner, policy, s["ipp_budget_s"], seed, diagonal=s["ipp_diagonal"],
                                planning_latency_s=latency)
    return dict(
        objective=float(log.series("rse")[-1]),
        rse=float(log.series("rse")[-1]), trace=float(log.series("trace")[-1]),
        people_found=float(log.series("people_found")[-1]), time_to_find_all_s=log.time_to_find_all_s(),
        false_alarm_cells=float(log.series("false_alarm_cells")[-1]),
        false_alarm_objects=float(log.series("false_alarm_objects")[-1]),
        replans=float(log.n_replans), hover_s=float(log.hover_s),
    )


def vision_episode(task: dict) -> dict:
    """One scene: ``task`` holds ``saccade_cost_s``, ``family``, ``params``, ``seed`` and
    ``settings``. Returns the time-averaged summed entropy [nats] (the objective), the final
    accuracy, the time to 90 % accuracy (inf if never) and the number of saccades; infeasible
    parameters (an oscillator period shorter than the saccade) give an infinite objective."""
    from attend.rhythm.vision import EpistemicPolicy, FoveatedEye, look, random_scene

    s, p, seed = task["settings"], task["params"], int(task["seed"])
    cost, dt, suppression = float(task["saccade_cost_s"]), s["vision_time_step_s"], s["vision_saccadic_suppression"]
    fixations = _vision_fixations(task["family"], p, cost, dt, suppression, s["vision_oscillator_depth"],
                                  s["vision_decision_time_s"])
    if fixations is None:
        return dict(objective=float("inf"), entropy=float("inf"), accuracy=float("nan"),
                    time_to_90_s=float("inf"), saccades=float("nan"), feasible=False)
    eye = FoveatedEye(s["vision_fovea_width"], s["vision_foveal_precision_rate"], s["vision_adaptation_time_s"])
    scene = random_scene(s["vision_rows"], s["vision_cols"], s["vision_letters"], seed=seed)
    n_steps = int(round(s["vision_duration_s"] / dt))
    nominal_dose = eye.dwell_dose(0.0, 0.2)  # where to look: every schedule plans a 200 ms fixation
    episode = look(scene, eye, EpistemicPolicy(), fixations, nominal_dose, n_steps=n_steps, seed=seed,
                          monte_carlo_samples=s["vision_monte_carlo_samples"])
    accuracy = episode.accuracy_trace
    hits = np.flatnonzero(accuracy >= 0.9)
    return dict(objective=float(episode.entropy_trace.mean()), entropy=float(episode.entropy_trace.mean()),
                accuracy=float(accuracy[-1]), time_to_90_s=float((hits[0] + 1) * dt) if len(hits) else float("inf"),
                saccades=float(len(episode.saccades)), feasible=True)


def _vision_fixations(family: str, p: dict, cost: float, dt: float, suppression: float, depth: float,
                      decision_time: float):
    """The fixation policy of a vision family with parameters ``p`` for saccades of ``cost`` s
    (None: infeasible, an oscillator period shorter than its saccade)."""
    from attend.rhythm.fixations import fixation_policy
    from attend.rhythm.oscillator import PrecisionOscillator
    from attend.rhythm.schedule import FixedSchedule, PrecisionDrivenSchedule, RhythmicSchedule

    if family == "fixed":
        return fixation_policy(FixedSchedule(p["dwell_s"], cost, 1.0), dt, suppression)
    if family == "oscillator":
        fraction = cost * p["frequency_hz"]
        if not 0 < fraction < 1:
            return None
        unit = RhythmicSchedule(PrecisionOscillator(p["frequency_hz"], depth), fraction)
        oscillator = PrecisionOscillator(p["frequency_hz"], depth, 1.0 / unit.mean_perception_multiplier())
        return fixation_policy(RhythmicSchedule(oscillator, fraction), dt, suppression)
    if family in ("precision", "precision_no_prior"):
        if family == "precision":
            oscillator, weight, horizon_s = PrecisionOscillator(p["frequency_hz"]), p["prior_weight"], 1.0 / p["frequency_hz"]
        else:
            oscillator, weight, horizon_s = PrecisionOscillator(4.0), 0.0, p["fixation_s"]
        horizon = max(1, int(round(cost / dt))) + max(1, int(round(horizon_s / dt)))
        return fixation_policy(PrecisionDrivenSchedule(oscillator, weight, 1.0), dt, suppression, saccade_s=cost,
                               perception_multiplier=1.0, horizon_steps=horizon, decision_time=decision_time)
    raise AttendInputError(f"family: unknown vision schedule family {family!r}")


def _episode(task: dict) -> dict:
    return ipp_episode(task) if task["domain"] == "ipp" else vision_episode(task)


# ----------------------------------------------------------------------------------------------
# Tuning and trials


def grid_points(cfg: dict) -> list[dict]:
    """The trade-off settings of the run: IPP (blur [s/m], latency [s]) pairs, then vision saccade
    costs [s], each numbered by ``index``. cfg: the run's configuration (:data:`SETTINGS` plus
    ``quick``, which picks the quick_ lists and only the two IPP corners)."""
    prefix = "quick_" if cfg["quick"] else ""
    points = [dict(domain="ipp", blur=float(b), latency_s=float(lat))
              for b in cfg[f"{prefix}ipp_blur_per_speed"] for lat in cfg[f"{prefix}ipp_latency_s"]]
    if cfg["quick"]:  # the two corners: the zero-cost limit and the strongest trade-off
        points = [points[0], points[-1]]
    points += [dict(domain="vision", saccade_cost_s=float(c)) for c in cfg[f"{prefix}vision_saccade_cost_s"]]
    return [dict(point, index=i) for i, point in enumerate(points)]


def tuning_seed_list(cfg: dict) -> list[int]:
    """Seeds 100, 101, ... on which every family is tuned. cfg: the run's configuration
    (``tuning_first_seed`` and the number ``tuning_seeds``)."""
    return list(range(cfg["tuning_first_seed"], cfg["tuning_first_seed"] + cfg["tuning_seeds"]))


def trial_seed_list(cfg: dict) -> list[int]:
    """Seeds 0, 1, ... of the comparison (those of ``attend reproduce ipp``). cfg: the run's
    configuration (``trial_first_seed`` and the number ``trials``)."""
    return list(range(cfg["trial_first_seed"], cfg["trial_first_seed"] + cfg["trials"]))


def _families(domain: str, per_family: int) -> dict[str, list[dict]]:
    families = IPP_FAMILIES if domain == "ipp" else VISION_FAMILIES
    return {name: grid[:per_family] for name, grid in families.items()}


def _task(point: dict, family: str, params: dict, seed: int, cfg: dict) -> dict:
    task = dict(point, family=family, params=params, seed=seed, settings=cfg)
    if point["domain"] == "vision" and cfg["quick"]:
        task["settings"] = dict(cfg, vision_monte_carlo_samples=cfg["quick_vision_monte_carlo_samples"],
                                vision_duration_s=cfg["quick_vision_duration_s"])
    return task


def paired_interval(differences: np.ndarray, confidence: float = 0.95) -> tuple[float, float, float]:
    """Mean and ``confidence`` t interval of paired differences (NaN interval for fewer than 2)."""
    from scipy.stats import t

    d = np.asarray(differences, dtype=float)
    mean = float(d.mean())
    if len(d) < 2 or not np.all(np.isfinite(d)):
        return mean, float("nan"), float("nan")
    half = float(t.ppf(0.5 + confidence / 2, len(d) - 1) * d.std(ddof=1) / math.sqrt(len(d)))
    return mean, mean - half, mean + half


def _check(quick, trials, tuning) -> None:
    if not isinstance(quick, (bool, np.bool_)):
        raise AttendInputError(f"quick: expected True or False, got {quick!r}")
    for name, value in (("trials", trials), ("tuning_seeds", tuning)):
        if value is not None and (isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 2):
            raise AttendInputError(f"{name}: expected an integer >= 2, got {value!r}")


def run(quick: bool = True, progress: bool = True, cluster=None, trials: int | None = None,
        tuning_seeds: int | None = None, settings_per_family: int | None = None,
        points: list[int] | None = None) -> ExperimentResult:
    """Tune every schedule family on the tuning seeds, then compare the tuned families on the
    trial seeds, at every setting of the trade-off (module docstring).

    quick: 2 + 2 settings, 2 parameter settings per family, 2 tuning / 3 trial seeds (< 60 s);
    otherwise the full grid, 6 per family, 8 tuning / 25 trial seeds. trials, tuning_seeds,
    settings_per_family, points (indices into the grid of the mode) override them. progress: a
    progress bar; cluster: a Dask scheduler address or client (see attend.sweep.run_tasks)."""
    _check(quick, trials, tuning_seeds)
    start = time.perf_counter()
    mode = "quick" if quick else "full"
    cfg = dict(SETTINGS, quick=bool(quick))
    cfg["trials"] = int(trials) if trials is not None else cfg[f"{mode}_trials"]
    cfg["tuning_seeds"] = int(tuning_seeds) if tuning_seeds is not None else cfg[f"{mode}_tuning_seeds"]
    per_family = settings_per_family if settings_per_family is not None else cfg[f"{mode}_settings_per_family"]
    cfg["settings_per_family"] = int(per_family)
    grid = grid_points(cfg)
    if points is not None:
        grid = [grid[i] for i in points]
    tune, trial = tuning_seed_list(cfg), trial_seed_list(cfg)
    if set(tune) & set(trial):
        raise AttendInputError(f"tuning and trial seeds overlap: {sorted(set(tune) & set(trial))}")
    cfg["ipp_families"] = {k: v for k, v in _families("ipp", per_family).items()}
    cfg["vision_families"] = {k: v for k, v in _families("vision", per_family).items()}
    tuning = _tune(grid, per_family, tune, cfg, cluster, progress)
    # the tuned setting of each family on the untouched trial seeds
    tasks = [_task(point, family, tuning["chosen"][(point["index"], family)], seed, cfg)
             for point in grid for family in _families(point["domain"], per_family) for seed in trial]
    trial_runs = run_tasks(_episode, tasks, cluster=cluster, progress=progress, desc="rhythm-tradeoff trials")

    result = ExperimentResult("rhythm-tradeoff", settings=cfg)
    table = [_compare(result, point, list(_families(point["domain"], per_family)), tuning,
                      [out for task, out in zip(tasks, trial_runs) if task["index"] == point["index"]],
                      [task for task in tasks if task["index"] == point["index"]], cfg["confidence"])
             for point in grid]
    result.add("tuning seeds", cfg["tuning_seeds"], "seeds")
    result.add("trial seeds", cfg["trials"], "seeds")
    result.add("evaluated settings per family", per_family, "settings")
    result.add("wall_time", time.perf_counter() - start, "s")
    result.settings["tuning_seed_list"] = tune
    result.settings["trial_seed_list"] = trial
    result.data = dict(table=table)
    result.tables["map"] = [{k: v for k, v in row.items() if k != "index"} for row in table]
    return result


def _tune(grid: list[dict], per_family: int, seeds: list[int], cfg: dict, cluster, progress: bool) -> dict:
    """Every parameter setting of every family on the tuning ``seeds``: the chosen setting (lowest
    mean objective), the number evaluated and the tuning means, per (point index, family)."""
    tasks = [_task(point, family, params, seed, cfg)
             for point in grid for family, params_list in _families(point["domain"], per_family).items()
             for params in params_list for seed in seeds]
    tuned_runs = run_tasks(_episode, tasks, cluster=cluster, progress=progress, desc="rhythm-tradeoff tuning")
    scores: dict[tuple, list[float]] = {}
    for task, out in zip(tasks, tuned_runs):
        scores.setdefault((task["index"], task["family"], repr(task["params"])), []).append(out["objective"])
    tuning = dict(chosen={}, evaluated={}, means={})
    for point in grid:
        for family, params_list in _families(point["domain"], per_family).items():
            means = [float(np.mean(scores[(point["index"], family, repr(p))])) for p in params_list]
            tuning["chosen"][(point["index"], family)] = params_list[int(np.argmin(means))]
            tuning["evaluated"][(point["index"], family)] = len(params_list)
            tuning["means"][(point["index"], family)] = means
    return tuning


def _compare(result: ExperimentResult, point: dict, families: list[str], tuning: dict, outs: list[dict],
             tasks: list[dict], confidence: float) -> dict:
    """The row of one trade-off setting: winner, tuned settings, paired differences (adds the
    metrics and a note to ``result``)."""
    runs = {f: [out for task, out in zip(tasks, outs) if task["family"] == f] for f in families}
    objective = {f: np.array([r["objective"] for r in runs[f]]) for f in families}
    means = {f: float(objective[f].mean()) for f in families}
    winner = min(families, key=lambda f: means[f])
    label = (f"ipp blur {point['blur']:g} s/m latency {point['latency_s']:g} s" if point["domain"] == "ipp"
             else f"vision saccade {point['saccade_cost_s'] * 1e3:g} ms")
    unit = "1" if point["domain"] == "ipp" else "nats"
    index = point["index"]
    row = dict(point, label=label, winner=winner, tuned={f: tuning["chosen"][(index, f)] for f in families},
               evaluated={f: tuning["evaluated"][(index, f)] for f in families},
               tuning_mean={f: tuning["means"][(index, f)] for f in families}, mean=means,
               versus_fixed={}, versus_winner={}, summary={})
    for f in families:
        row["versus_fixed"][f] = paired_interval(objective[f] - objective["fixed"], confidence)
        row["versus_winner"][f] = paired_interval(objective[f] - objective[winner], confidence)
        row["summary"][f] = _summary(point["domain"], runs[f])
        result.add(f"{label}: {f} mean objective", means[f], unit)
        if f != "fixed":
            mean, low, high = row["versus_fixed"][f]
            result.add(f"{label}: {f} minus tuned fixed", mean, unit)
            result.add(f"{label}: {f} minus tuned fixed, CI low", low, unit)
            result.add(f"{label}: {f} minus tuned fixed, CI high", high, unit)
    result.notes.append(f"{label}: winner {winner}; tuned " + ", ".join(
        f"{f} {_params_text(row['tuned'][f])}" for f in families))
    return row


def _summary(domain: str, runs: list[dict]) -> dict:
    if domain == "ipp":
        find = np.array([r["time_to_find_all_s"] for r in runs])
        return dict(final_rse=float(np.mean([r["rse"] for r in runs])), final_trace=float(np.mean([r["trace"] for r in runs])),
                    people_found=float(np.mean([r["people_found"] for r in runs])),
                    all_found_fraction=float(np.mean(np.isfinite(find))),
                    time_to_find_all_median_s=float(np.median(find)) if np.isfinite(np.median(find)) else None,
                    false_alarm_cells=float(np.mean([r["false_alarm_cells"] for r in runs])),
                    false_alarm_objects=float(np.mean([r["false_alarm_objects"] for r in runs])),
                    replans=float(np.mean([r["replans"] for r in runs])), hover_s=float(np.mean([r["hover_s"] for r in runs])))
    times = np.array([r["time_to_90_s"] for r in runs])
    return dict(time_averaged_entropy=float(np.mean([r["entropy"] for r in runs])),
                final_accuracy=float(np.mean([r["accuracy"] for r in runs])),
                reached_90_fraction=float(np.mean(np.isfinite(times))),
                time_to_90_median_s=float(np.median(times)) if np.isfinite(np.median(times)) else None,
                saccades=float(np.mean([r["saccades"] for r in runs])))


def _params_text(params: dict) -> str:
    return "(" + ", ".join(f"{k}={v}" for k, v in params.items()) + ")" if params else "()"


# ----------------------------------------------------------------------------------------------
# Figure


SHORT = {"oscillator": "osc", "precision": "prec", "precision_no_prior": "prec, no prior", "continuous": "cont"}
COLOURS = {"fixed": "tab:gray", "oscillator": "tab:red", "precision": "tab:purple", "precision_no_prior": "tab:blue",
           "continuous": "tab:green"}


def _interval(values) -> tuple[float, float, float]:
    """(mean, low, high) of a JSON row (None, from NaN, back to NaN)."""
    return tuple(float("nan") if v is None else float(v) for v in values)


CAPTIONS = {
    "rhythm-tradeoff.png": (
        "Where does a rhythm help when switching between acting and perceiving costs? Every "
        "schedule family tuned alike on tuning seeds, then compared on trial seeds. Left: UAV "
        "search over motion blur x planning latency; cell colour: the family with the lowest final "
        "map error (RSE); text: each rhythmic family minus the tuned fixed budget, mean [95 % CI] "
        "(*: the interval excludes 0). Middle (UAV) and right (active vision, against the saccade "
        "duration): every family minus the tuned fixed budget with 95 % intervals; below 0 the "
        "family beats the fixed budget."),
}


def plot(result: ExperimentResult, out_dir) -> list[str]:
    """rhythm-tradeoff.png from ``result.tables["map"]`` into ``out_dir`` (CAPTIONS)."""
    from attend.plotting import new_figure

    table = result.tables["map"]
    ipp = [row for row in table if row["domain"] == "ipp"]
    vision = [row for row in table if row["domain"] == "vision"]
    fig, axes = new_figure(out_dir, (17, 5.6), 1, 3, constrained_layout=True)
    _plot_map(axes[0], ipp, result.settings["trials"])
    for ax, rows, unit, title in ((axes[1], ipp, "final RSE [1]", "UAV search"),
                                  (axes[2], vision, "time-averaged entropy [nats]", "active vision")):
        _plot_differences(ax, rows, unit, title)
    path = Path(out_dir) / "rhythm-tradeoff.png"
    fig.savefig(path, dpi=110)
    return [str(path)]


def _plot_map(ax, ipp: list[dict], trials: int) -> None:
    from matplotlib.patches import Patch, Rectangle

    if not ipp:
        ax.axis("off")
        return
    blurs = sorted({row["blur"] for row in ipp})
    latencies = sorted({row["latency_s"] for row in ipp})
    for row in ipp:
        x, y = latencies.index(row["latency_s"]), blurs.index(row["blur"])
        ax.add_patch(Rectangle((x - 0.5, y - 0.5), 1, 1, color=COLOURS[row["winner"]], alpha=0.35))
        lines = [f"winner: {row['winner']}"]
        for f in RHYTHMIC + ("precision_no_prior",):
            mean, low, high = _interval(row["versus_fixed"][f])
            star = "*" if low > 0 or high < 0 else ""
            lines.append(f"{SHORT[f]}: {mean:+.2f} [{low:+.2f}, {high:+.2f}]{star}")
        ax.text(x, y, "\n".join(lines), ha="center", va="center", fontsize=7)
    ax.set_xlim(-0.5, len(latencies) - 0.5)
    ax.set_ylim(-0.5, len(blurs) - 0.5)
    ax.set_xticks(range(len(latencies)), [f"{v:g}" for v in latencies])
    ax.set_yticks(range(len(blurs)), [f"{v:g}" for v in blurs])
    ax.set_xlabel("planning latency L [s] (hover per plan)")
    ax.set_ylabel("motion blur b [s/m]  (precision x 1/(1 + b v))")
    ax.set_title(f"UAV search: winner by final RSE ({trials} trial seeds);\n"
                 "family minus tuned fixed budget, mean [95 % CI] (*: excludes 0)", fontsize=9)
    ax.legend(handles=[Patch(color=c, alpha=0.35, label=f) for f, c in COLOURS.items()], fontsize=7, loc="upper right",
              bbox_to_anchor=(1.0, -0.12), ncol=3)


def _plot_differences(ax, rows: list[dict], unit: str, title: str) -> None:
    if not rows:
        ax.axis("off")
        return
    families = [f for f in rows[0]["versus_fixed"] if f != "fixed"]
    x = np.arange(len(rows))
    for k, f in enumerate(families):
        stats = np.array([_interval(row["versus_fixed"][f]) for row in rows], dtype=float)
        offset = (k - (len(families) - 1) / 2) * 0.12
        ax.errorbar(x + offset, stats[:, 0], yerr=[stats[:, 0] - stats[:, 1], stats[:, 2] - stats[:, 0]], fmt="o",
                    color=COLOURS[f], label=f, capsize=3)
    ax.axhline(0, color="k", lw=0.8)
    ticks = [f"b {row['blur']:g}\nL {row['latency_s']:g}" if row["domain"] == "ipp"
             else f"{row['saccade_cost_s'] * 1e3:g} ms" for row in rows]
    ax.set_xticks(x, ticks, fontsize=7)
    ax.set_xlabel("blur b [s/m], latency L [s]" if rows[0]["domain"] == "ipp" else "saccade duration [ms]")
    ax.set_ylabel(f"{unit}: family minus tuned fixed")
    ax.set_title(f"{title}: family minus tuned fixed (< 0: better), 95 % CI", fontsize=9)
    ax.legend(fontsize=7)


def claims(result: ExperimentResult) -> list[Claim]:
    """The paper's claim (§4.4, Fig. 10) where switching costs: a rhythm (the oscillator, or the
    precision-driven rule with the rhythm as prior) beats a fixed budget tuned alike. One claim
    per domain; reproduced if some rhythmic family's 95 % interval lies below 0 at some setting,
    does not hold otherwise. result: the ExperimentResult of :func:`run`."""
    found = []
    for domain, what in (("ipp", "UAV search (final RSE)"), ("vision", "active vision (time-averaged entropy, nats)")):
        rows = [row for row in result.tables.get("map", []) if row["domain"] == domain]
        if not rows:
            continue
        parts, better = [], False
        for row in rows:
            for f in RHYTHMIC:
                mean, low, high = _interval(row["versus_fixed"][f])
                better = better or high < 0
                parts.append(f"{row['label']}, {f}: {mean:+.3f} [{low:+.3f}, {high:+.3f}]")
        measured = (f"family minus tuned fixed budget, mean [95 % CI] over {result.settings.get('trials')} trial "
                    "seeds: " + "; ".join(parts) + "; winners: " + ", ".join(row["winner"] for row in rows))
        found.append(Claim(f"In {what}, with switching costs, a rhythmic schedule tuned like the fixed budget "
                           "beats it", measured, "reproduced" if better else "does not hold"))
    return found
