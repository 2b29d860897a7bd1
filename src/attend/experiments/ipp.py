"""Experiment "ipp": informative path planning for UAV search and rescue (paper Sec. 4.3, Figs. 6-9).

Seeded trials per planner (25 in full mode, as in ICRA'19) with a 150 s budget (planners: precision
gain, adaptive, expected free energy, expected free energy in two phases - search at 14 m, then
confirmation of detections at 8 m - cover then confirm, lawnmower at 10 m, random): RSE, trace(P)
and people found vs flight time, time to find all 7 people, false alarms and planner time per
replan; paired differences against the lawnmower and random baselines; and one false-positive
episode (Fig. 9: people in the lower half, a false 2 x 3-cell detection injected in the first
image) showing the false detection resolved by revisits. Published anchors: initial trace(P) 387,
initial RSE 7.69; adaptive < lawnmower at 10 m < random in final RSE (ICRA'19).

``run`` computes (the curves and the Fig. 9 maps go to ``result.tables``), ``plot`` draws from
the result alone, ``claims`` weighs the measurements against the paper.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from attend._threads import with_single_blas_thread
from attend.action.camera import Camera
from attend.action.episode import EpisodeLog, fly
from attend.action.field import make_field
from attend.action.flight import FlightModel
from attend.action.planners import ALTITUDE_LAYERS_M, PlanningSetup, make_planner
from attend.action.plots import METRIC_LABELS, draw_map_snapshots, map_snapshots
from attend.experiments._result import Claim, ExperimentResult
from attend.plotting import new_figure

PLANNER_NAMES = ("precision_gain", "adaptive", "efe", "efe_confirm", "cover_confirm", "lawnmower", "random")
INFORMATIVE = ("precision_gain", "adaptive", "efe", "efe_confirm", "cover_confirm")
BASELINES = ("lawnmower", "random")
BUDGET_S = 150.0
#: (trials per planner, CMA-ES evaluations per replan) in quick and full mode
QUICK_TRIALS, QUICK_CMA_EVALUATIONS = 2, 12
FULL_TRIALS, FULL_CMA_EVALUATIONS = 25, 24
#: Fig. 9: the field seed (people in the lower half) and the map snapshot times [s]
FALSE_POSITIVE_SEED = 3
FALSE_POSITIVE_SNAPSHOTS_S = (0.0, 7.0, 40.0, 100.0, BUDGET_S)
#: Flight times [s] at which the curves are sampled (step-interpolated after the last image)
CURVE_TIMES_S = np.linspace(0, BUDGET_S, 151)
CURVE_METRICS = ("rse", "trace", "people_found")
#: Decimals kept of the Fig. 9 maps in the JSON (drawing only)
MAP_DECIMALS = 4
#: Published anchors (ICRA'19, spec action.md)
PUBLISHED_INITIAL_TRACE = 387.0
PUBLISHED_INITIAL_RSE = 7.69

CAPTIONS = {
    "ipp_curves.png": (
        "Map quality against flight time for each planner (mean over the seeded trials, band +- one "
        "standard deviation): root squared error of the occupancy map against the ground truth (left), "
        "total map variance trace(P) (middle) and people found, all cells of a person above 0.5 (right). "
        "Lower RSE and trace(P) and more people found sooner are better; the lawnmower at 10 m and "
        "random waypoints are the baselines."
    ),
    "ipp_false_positive.png": (
        "Fig. 9 episode (expected free energy planner, people only in the lower half, a false 2 x 3-cell "
        "detection injected in the first image): ground truth, then the occupancy mean (top, with the "
        "image positions so far) and variance (bottom) at 0, 7, 40, 100 and 150 s. The false blob first "
        "looks like a person and fades as the UAV looks again."
    ),
}


@with_single_blas_thread
def _one_trial(job: tuple[str, int, float, int]) -> EpisodeLog:
    """One mission (a worker's task): planner name, seed, budget [s], CMA-ES evaluations."""
    name, seed, budget_s, cma_evaluations = job
    if name == "false_positive_episode":
        return false_positive_episode(seed=seed, budget_s=budget_s, cma_evaluations=cma_evaluations)[1]
    field = make_field(seed)
    setup = PlanningSetup(field, cma_evaluations=cma_evaluations)
    return fly(field, make_planner(name, setup, seed), budget_s, seed, keep_maps=False)


def run_trials(
    planners=PLANNER_NAMES, trials: int = FULL_TRIALS, budget_s: float = BUDGET_S,
    cma_evaluations: int = FULL_CMA_EVALUATIONS, progress: bool = False, first_seed: int = 0, workers: int = 1,
    with_false_positive_episode: bool = False,
) -> dict[str, list[EpisodeLog]]:
    """``trials`` seeded missions per planner (seed k: same field and detector noise for every
    planner), each with one BLAS thread.

    planners: planner names; trials: missions per planner; budget_s: flight budget [s];
    cma_evaluations: CMA-ES evaluations per replan; progress: a tqdm bar over the missions;
    first_seed: seed of the first trial; workers: > 1 runs the missions in that many processes
    (results identical); with_false_positive_episode: also run the Fig. 9 episode in the same pool
    (key "false_positive_episode"). Returns planner name -> logs in seed order."""
    jobs = [(name, seed, budget_s, cma_evaluations) for seed in range(first_seed, first_seed + trials) for name in planners]
    if with_false_positive_episode:
        jobs.insert(0, ("false_positive_episode", FALSE_POSITIVE_SEED, budget_s, cma_evaluations))

    def shown(results):
        if not progress:
            return results
        from tqdm import tqdm

        return tqdm(results, total=len(jobs), desc="ipp trials", unit="episode")

    if workers > 1:
        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor

        with ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("spawn")) as pool:
            done = list(shown(pool.map(_one_trial, jobs)))
    else:
        done = [_one_trial(job) for job in shown(jobs)]
    logs: dict[str, list[EpisodeLog]] = {name: [] for name in planners}
    for (name, _, _, _), log in zip(jobs, done):
        logs.setdefault(name, []).append(log)
    return logs


def false_positive_episode(
    planner: str = "efe", seed: int = FALSE_POSITIVE_SEED, budget_s: float = BUDGET_S,
    cma_evaluations: int = FULL_CMA_EVALUATIONS,
):
    """Fig. 9: people in the lower half, one false blob injected in the first image. Returns
    (field, log).

    planner: planner name; seed: field, detector and planner seed; budget_s: flight budget [s];
    cma_evaluations: CMA-ES evaluations per replan."""
    field = make_field(seed, people_region="lower_half")
    setup = PlanningSetup(field, cma_evaluations=cma_evaluations)
    return field, fly(field, make_planner(planner, setup, seed), budget_s, seed, inject_false_detection_images=(0,))


def run(quick: bool = True, progress: bool = True) -> ExperimentResult:
    """Run the experiment: computes only, everything the figures need in ``result.tables``.

    quick: 2 trials per planner and CMA-ES with 12 evaluations (full: 25 trials, 24 evaluations);
    progress: a tqdm bar over the missions.
    Trials run in up to 2 worker processes."""
    import os

    trials = QUICK_TRIALS if quick else FULL_TRIALS
    cma_evaluations = QUICK_CMA_EVALUATIONS if quick else FULL_CMA_EVALUATIONS
    start = time.perf_counter()
    workers = max(1, min(2, os.cpu_count() or 1))
    logs = run_trials(trials=trials, cma_evaluations=cma_evaluations, progress=progress, workers=workers,
                      with_false_positive_episode=True)
    fp_log = logs.pop("false_positive_episode")[0]
    fp_field = make_field(FALSE_POSITIVE_SEED, people_region="lower_half")
    flight = FlightModel()
    result = ExperimentResult(
        "ipp",
        settings={
            "quick": quick, "trials_per_planner": trials, "budget_s": BUDGET_S, "planners": list(PLANNER_NAMES),
            "cma_evaluations": cma_evaluations, "grid": "40 x 40 cells of 0.75 m", "image_rate_hz": flight.image_rate_hz,
            "speed_m_s": flight.speed_m_s, "workers": workers, "acceleration_m_s2": flight.acceleration_m_s2,
            "altitude_layers_m": list(ALTITUDE_LAYERS_M),
        },
    )
    first = logs[PLANNER_NAMES[0]]
    result.add("initial_trace_P", np.mean([log.series("trace")[0] for log in first]), "1", published=PUBLISHED_INITIAL_TRACE)
    result.add("initial_RSE", np.mean([log.series("rse")[0] for log in first]), "1", published=PUBLISHED_INITIAL_RSE)
    final = {name: summarise(runs) for name, runs in logs.items()}
    _add_planner_metrics(result, final)
    _add_false_positive_metrics(result, fp_field, fp_log)
    result.add("wall_time", time.perf_counter() - start, "s")
    result.tables = {
        "curves": curve_table(logs),
        "false_positive_maps": map_snapshots(fp_field, fp_log, FALSE_POSITIVE_SNAPSHOTS_S, decimals=MAP_DECIMALS),
    }
    return result


def _add_planner_metrics(result: ExperimentResult, final: dict[str, dict[str, np.ndarray]]) -> None:
    """Per planner: final RSE, trace(P), people found, time to find all, false alarms, planner
    time; per informative planner: paired differences against each baseline."""
    def spread(values: np.ndarray) -> float:
        return values.std(ddof=1) if len(values) > 1 else 0.0

    for name, values in final.items():
        result.add(f"{name}_final_RSE_mean", values["rse"].mean(), "1")
        result.add(f"{name}_final_RSE_std", spread(values["rse"]), "1")
        result.add(f"{name}_final_trace_mean", values["trace"].mean(), "1")
        result.add(f"{name}_final_trace_std", spread(values["trace"]), "1")
        result.add(f"{name}_people_found_mean", values["found"].mean(), "people")
        result.add(f"{name}_all_found_fraction", np.mean(np.isfinite(values["time_to_all"])), "1")
        result.add(f"{name}_all_found_fraction_person_mean_criterion", np.mean(np.isfinite(values["time_to_all_person_mean"])), "1")
        finite = values["time_to_all"][np.isfinite(values["time_to_all"])]
        result.add(f"{name}_time_to_find_all_median", np.median(finite) if len(finite) else np.inf, "s")
        result.add(f"{name}_false_alarm_cells_mean", values["false_cells"].mean(), "cells")
        result.add(f"{name}_false_alarm_objects_mean", values["false_objects"].mean(), "objects")
        result.add(f"{name}_planner_time_median", values["planner_median"], "s")
    for name in INFORMATIVE:
        for baseline in BASELINES:
            for key, label in (("rse", "RSE"), ("trace", "trace")):
                diff = final[name][key] - final[baseline][key]
                result.add(f"{name}_minus_{baseline}_{label}_mean", diff.mean(), "1")
                result.add(f"{name}_minus_{baseline}_{label}_std", spread(diff), "1")


def _add_false_positive_metrics(result: ExperimentResult, field, log: EpisodeLog) -> None:
    """Fig. 9: the injected blob's map mean (peak, final), how often it was looked at again, and
    the episode's final false alarms and people found."""
    blob = log.clutter_cells[0]
    blob_mean = np.array([m[blob].mean() for m in log.means]) if len(blob) else np.zeros(1)
    revisits = sum(bool(np.isin(blob, img_cells).any()) for img_cells in _observed_cells(field, log)[1:])
    result.add("fp_episode_blob_peak_mean", blob_mean.max(), "1")
    result.add("fp_episode_blob_final_mean", blob_mean[-1], "1")
    result.add("fp_episode_blob_revisits", revisits, "images")
    result.add("fp_episode_final_false_alarm_objects", log.series("false_alarm_objects")[-1], "objects")
    result.add("fp_episode_people_found", log.series("people_found")[-1], "people")


def _observed_cells(field, log: EpisodeLog) -> list[np.ndarray]:
    camera = Camera()
    return [np.zeros(0, int)] + [np.flatnonzero(camera.visible_cells(np.asarray(p)[None], field.grid, field.obstacles)[0])
                                 for p in log.poses_m]


def summarise(runs: list[EpisodeLog]) -> dict[str, np.ndarray]:
    """Final values of each mission of one planner: RSE, trace(P), people found, time to find
    all (two criteria, inf if never), false-alarm cells and objects, median planner time [s].

    runs: the planner's mission logs."""
    return {
        "rse": np.array([r.series("rse")[-1] for r in runs]),
        "trace": np.array([r.series("trace")[-1] for r in runs]),
        "found": np.array([r.series("people_found")[-1] for r in runs]),
        "time_to_all": np.array([r.time_to_find_all_s() for r in runs]),
        "time_to_all_person_mean": np.array([r.time_to_find_all_s("people_found_person_mean") for r in runs]),
        "false_cells": np.array([r.series("false_alarm_cells")[-1] for r in runs]),
        "false_objects": np.array([r.series("false_alarm_objects")[-1] for r in runs]),
        "planner_median": float(np.median(np.concatenate([r.planner_times_s for r in runs]))),
    }


def curve_table(logs: dict[str, list[EpisodeLog]]) -> dict:
    """{"time_s": CURVE_TIMES_S, planner: {metric: {"mean": ..., "std": ...}}} of RSE, trace(P)
    and people found over flight time (population std over the trials).

    logs: planner name -> mission logs."""
    table: dict = {"time_s": CURVE_TIMES_S.tolist()}
    for name, runs in logs.items():
        table[name] = {}
        for key in CURVE_METRICS:
            curves = np.array([r.value_at(key, CURVE_TIMES_S) for r in runs])
            table[name][key] = {"mean": curves.mean(axis=0).tolist(), "std": curves.std(axis=0).tolist()}
    return table


def plot(result: ExperimentResult, out_dir) -> list[str]:
    """Curves vs flight time (mean +- std per planner) and the false-positive episode maps, from
    ``result.tables`` alone.

    result: the experiment's result (as run, or rebuilt from its JSON); out_dir: where the PNG
    files go (created). Returns their paths."""
    out = Path(out_dir)
    curves = result.tables["curves"]
    times = np.asarray(curves["time_s"])
    fig, axes = new_figure(out, (14, 3.8), 1, 3, layout="constrained")
    labels = dict(METRIC_LABELS)
    for name, series in curves.items():
        if name == "time_s":
            continue
        for ax, key in zip(axes, CURVE_METRICS):
            mean, std = np.asarray(series[key]["mean"]), np.asarray(series[key]["std"])
            ax.plot(times, mean, label=name)
            ax.fill_between(times, mean - std, mean + std, alpha=0.15)
    for ax, key in zip(axes, CURVE_METRICS):
        ax.set_xlabel("flight time [s]")
        ax.set_ylabel(labels[key])
    axes[0].legend(fontsize=8)
    curves_path = out / "ipp_curves.png"
    fig.savefig(curves_path, dpi=110)
    fp_path = draw_map_snapshots(result.tables["false_positive_maps"], out / "ipp_false_positive.png")
    return [str(curves_path), str(fp_path)]


def claims(result: ExperimentResult) -> list[Claim]:
    """The paper's claims this experiment tests, from the metrics alone.

    result: the experiment's result."""
    value = lambda name: result.metric(name).value  # noqa: E731
    trials = result.settings.get("trials_per_planner", "?")
    out = []
    trace0, rse0 = value("initial_trace_P"), value("initial_RSE")
    out.append(Claim(
        "The GP prior (Matern-3/2, l = 3.67 cells, s2 = 1.82, r0 = 2.01) starts at trace(P) ~ 387 on the 40 x 40 grid.",
        f"initial trace(P) {trace0:.1f}",
        "reproduced" if abs(trace0 / PUBLISHED_INITIAL_TRACE - 1) < 0.01 else "differs",
        f"{PUBLISHED_INITIAL_TRACE:g}",
    ))
    out.append(Claim(
        "The 0.1 prior starts at RSE 7.69 (54 person cells).",
        f"initial RSE {rse0:.2f}, mean over the fields of {trials} seeds (it depends on each field's person cells)",
        "reproduced" if abs(rse0 / PUBLISHED_INITIAL_RSE - 1) < 0.01 else "differs",
        f"{PUBLISHED_INITIAL_RSE:g}",
    ))
    rse = {name: value(f"{name}_final_RSE_mean") for name in ("adaptive", "lawnmower", "random")}
    out.append(Claim(
        "After 150 s the adaptive planner's map error is below the lawnmower's at 10 m, which is below random's (ICRA'19).",
        f"final RSE adaptive {rse['adaptive']:.2f}, lawnmower {rse['lawnmower']:.2f}, random {rse['random']:.2f} "
        f"({trials} trials each)",
        "reproduced" if rse["adaptive"] < rse["lawnmower"] < rse["random"] else "does not hold",
        "adaptive < lawnmower < random in RSE (25 trials)",
    ))
    traces = {name: value(f"{name}_final_trace_mean") for name in ("precision_gain", "efe", "lawnmower")}
    out.append(Claim(
        "Planning for precision gain leaves less map uncertainty trace(P) than lawnmower coverage after the same "
        "150 s of flight.",
        f"final trace(P) precision gain {traces['precision_gain']:.1f}, expected free energy {traces['efe']:.1f}, "
        f"lawnmower {traces['lawnmower']:.1f}",
        "reproduced" if traces["precision_gain"] < traces["lawnmower"] and traces["efe"] < traces["lawnmower"] else "does not hold",
        "final trace 46.78 (CMA-ES) vs 165.12 (lawnmower), IROS'17 on Gaussian random fields, 200 s",
    ))
    found = {name: value(f"{name}_all_found_fraction") for name in ("efe_confirm", "cover_confirm", "lawnmower")}
    out.append(Claim(
        "Confirming detections finds every person more often than lawnmower coverage (attend's own test).",
        f"share of trials with all 7 found in 150 s: cover-confirm {found['cover_confirm']:.0%}, "
        f"EFE search-confirm {found['efe_confirm']:.0%}, lawnmower {found['lawnmower']:.0%}",
        "reproduced" if found["cover_confirm"] > found["lawnmower"] else "does not hold",
    ))
    peak, final_mean = value("fp_episode_blob_peak_mean"), value("fp_episode_blob_final_mean")
    false_objects = value("fp_episode_final_false_alarm_objects")
    resolved = peak > 0.5 and final_mean < 0.5 and false_objects == 0
    out.append(Claim(
        "An early false detection is resolved by looking again (Fig. 9).",
        f"false blob mean peaks at {peak:.2f}, ends at {final_mean:.2f} after {value('fp_episode_blob_revisits'):.0f} "
        f"revisits; {false_objects:.0f} false objects at the end",
        "reproduced" if resolved else "does not hold",
        "all 7 people found in the photo-realistic run despite early false positives",
    ))
    return out
