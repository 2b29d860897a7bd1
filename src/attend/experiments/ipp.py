"""Experiment "ipp": informative path planning for UAV search and rescue (seed §4.3, Figs. 6-9).

Seeded trials per planner (25 in full mode, as in ICRA'19) with a 150 s budget (planners: precision
gain, adaptive, expected free energy, expected free energy in two phases - search at 14 m, then
confirmation of detections at 8 m - lawnmower at 10 m, random): RSE, trace(P) and
people found vs flight time, time to find all 7 people, false alarms and planner time per
replan; paired differences against the lawnmower at 10 m; and one false-positive episode (Fig. 9:
people in the lower half, a false 2 x 3-cell detection injected in the first image) showing the
false detection resolved by revisits. Published anchors: initial trace(P) 387, initial RSE 7.69.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from attend.action.camera import Camera, Detector
from attend.action.episode import EpisodeLog, run_episode
from attend.action.field import make_field
from attend.action.flight import FlightModel
from attend.action.planners import PlanningSetup, make_planner
from attend.experiments._result import ExperimentResult

PLANNER_NAMES = ("precision_gain", "adaptive", "efe", "efe_confirm", "cover_confirm", "lawnmower", "random")
INFORMATIVE = ("precision_gain", "adaptive", "efe", "efe_confirm", "cover_confirm")
BUDGET_S = 150.0
FALSE_POSITIVE_SEED = 3


def _one_trial(job: tuple[str, int, float, int]) -> EpisodeLog:
    name, seed, budget_s, cma_evaluations = job
    if name == "false_positive_episode":
        return false_positive_episode(seed=seed, budget_s=budget_s, cma_evaluations=cma_evaluations)[1]
    camera, detector, flight = Camera(), Detector(), FlightModel()
    field = make_field(seed)
    setup = PlanningSetup(field, camera, detector, flight, cma_evaluations=cma_evaluations)
    planner = make_planner(name, setup, seed)
    return run_episode(field, planner, camera, detector, flight, budget_s, seed, keep_maps=False)


def run_trials(
    planners=PLANNER_NAMES, trials: int = 25, budget_s: float = BUDGET_S, cma_evaluations: int = 24,
    progress: bool = False, first_seed: int = 0, workers: int = 1, with_false_positive_episode: bool = False,
) -> dict[str, list[EpisodeLog]]:
    """``trials`` seeded missions per planner (seed k: same field and detector noise for every
    planner); ``workers`` > 1 runs them in that many processes (results identical). With
    ``with_false_positive_episode`` the Fig. 9 episode runs in the same pool (key
    "false_positive_episode")."""
    jobs = [(name, seed, budget_s, cma_evaluations) for seed in range(first_seed, first_seed + trials) for name in planners]
    if with_false_positive_episode:
        jobs.insert(0, ("false_positive_episode", FALSE_POSITIVE_SEED, budget_s, cma_evaluations))
    if workers > 1:
        import multiprocessing
        import os
        from concurrent.futures import ProcessPoolExecutor

        # one BLAS thread per worker process (set before the spawned workers import numpy)
        saved = {key: os.environ.get(key) for key in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")}
        os.environ.update({key: "1" for key in saved})
        try:
            context = multiprocessing.get_context("spawn")
            with ProcessPoolExecutor(max_workers=workers, mp_context=context) as pool:
                results = pool.map(_one_trial, jobs)
                if progress:
                    from tqdm import tqdm

                    results = tqdm(results, total=len(jobs), desc="ipp trials", unit="episode")
                done = list(results)
        finally:
            for key, value in saved.items():
                if value is None:
                    os.environ.pop(key, None)
                else:
                    os.environ[key] = value
    else:
        iterator = jobs
        if progress:
            from tqdm import tqdm

            iterator = tqdm(jobs, desc="ipp trials", unit="episode")
        done = [_one_trial(job) for job in iterator]
    logs: dict[str, list[EpisodeLog]] = {name: [] for name in planners}
    for (name, _, _, _), log in zip(jobs, done):
        logs.setdefault(name, []).append(log)
    return logs


def false_positive_episode(
    planner: str = "efe", seed: int = FALSE_POSITIVE_SEED, budget_s: float = BUDGET_S, cma_evaluations: int = 24
):
    """Fig. 9: people in the lower half, one false blob injected in the first image."""
    camera, detector, flight = Camera(), Detector(), FlightModel()
    field = make_field(seed, people_region="lower_half")
    setup = PlanningSetup(field, camera, detector, flight, cma_evaluations=cma_evaluations)
    log = run_episode(field, make_planner(planner, setup, seed), camera, detector, flight, budget_s, seed,
                      inject_false_detection_images=(0,))
    return field, log


def run(quick: bool = True, out_dir=None, progress: bool = True) -> ExperimentResult:
    """Run the experiment (quick: 2 trials per planner and CMA-ES with 12 evaluations; full: 25
    trials and 24 evaluations). Trials run in up to 2 worker processes; figures and
    ``out_dir/ipp.json`` are written when ``out_dir`` is given."""
    trials = 2 if quick else 25
    cma_evaluations = 12 if quick else 24
    start = time.perf_counter()
    import os

    workers = max(1, min(2, os.cpu_count() or 1))
    logs = run_trials(trials=trials, cma_evaluations=cma_evaluations, progress=progress, workers=workers,
                      with_false_positive_episode=True)
    fp_log = logs.pop("false_positive_episode")[0]
    fp_field = make_field(FALSE_POSITIVE_SEED, people_region="lower_half")
    result = ExperimentResult(
        "ipp",
        settings={
            "quick": quick, "trials_per_planner": trials, "budget_s": BUDGET_S, "planners": list(PLANNER_NAMES),
            "cma_evaluations": cma_evaluations, "grid": "40 x 40 cells of 0.75 m", "image_rate_hz": 0.15,
            "speed_m_s": 5.0, "workers": workers, "acceleration_m_s2": 3.0, "altitude_layers_m": [5.0, 8.0, 11.0, 14.0],
        },
    )
    first = logs[PLANNER_NAMES[0]]
    result.add("initial_trace_P", np.mean([log.series("trace")[0] for log in first]), "1", published=387.0)
    result.add("initial_RSE", np.mean([log.series("rse")[0] for log in first]), "1", published=7.69)
    final = {name: summarise(runs) for name, runs in logs.items()}
    for name, values in final.items():
        result.add(f"{name}_final_RSE_mean", values["rse"].mean(), "1")
        result.add(f"{name}_final_RSE_std", values["rse"].std(ddof=1) if len(values["rse"]) > 1 else 0.0, "1")
        result.add(f"{name}_final_trace_mean", values["trace"].mean(), "1")
        result.add(f"{name}_final_trace_std", values["trace"].std(ddof=1) if len(values["trace"]) > 1 else 0.0, "1")
        result.add(f"{name}_people_found_mean", values["found"].mean(), "people")
        result.add(f"{name}_all_found_fraction", np.mean(np.isfinite(values["time_to_all"])), "1")
        result.add(f"{name}_all_found_fraction_person_mean_criterion", np.mean(np.isfinite(values["time_to_all_person_mean"])), "1")
        finite = values["time_to_all"][np.isfinite(values["time_to_all"])]
        result.add(f"{name}_time_to_find_all_median", np.median(finite) if len(finite) else np.inf, "s")
        result.add(f"{name}_false_alarm_cells_mean", values["false_cells"].mean(), "cells")
        result.add(f"{name}_false_alarm_objects_mean", values["false_objects"].mean(), "objects")
        result.add(f"{name}_planner_time_median", values["planner_median"], "s")
    for name in INFORMATIVE:
        for baseline in ("lawnmower", "random"):
            for key, label in (("rse", "RSE"), ("trace", "trace")):
                diff = final[name][key] - final[baseline][key]
                result.add(f"{name}_minus_{baseline}_{label}_mean", diff.mean(), "1")
                result.add(f"{name}_minus_{baseline}_{label}_std", diff.std(ddof=1) if len(diff) > 1 else 0.0, "1")
    blob = fp_log.clutter_cells[0]
    blob_mean = np.array([m[blob].mean() for m in fp_log.means]) if len(blob) else np.zeros(1)
    revisits = sum(bool(np.isin(blob, img_cells).any()) for img_cells in _observed_cells(fp_field, fp_log)[1:])
    result.add("fp_episode_blob_peak_mean", blob_mean.max(), "1")
    result.add("fp_episode_blob_final_mean", blob_mean[-1], "1")
    result.add("fp_episode_blob_revisits", revisits, "images")
    result.add("fp_episode_final_false_alarm_objects", fp_log.series("false_alarm_objects")[-1], "objects")
    result.add("fp_episode_people_found", fp_log.series("people_found")[-1], "people")
    result.add("wall_time", time.perf_counter() - start, "s")
    result.data = {"logs": logs, "fp_field": fp_field, "fp_log": fp_log, "blob_mean": blob_mean}
    if out_dir is not None:
        result.figures.extend(str(p) for p in plot(result, out_dir))
        result.write(out_dir)
    return result


def _observed_cells(field, log: EpisodeLog) -> list[np.ndarray]:
    camera = Camera()
    return [np.zeros(0, int)] + [np.flatnonzero(camera.visible_cells(np.asarray(p)[None], field.grid, field.obstacles)[0])
                                 for p in log.poses_m]


def summarise(runs: list[EpisodeLog]) -> dict[str, np.ndarray]:
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


def plot(result: ExperimentResult, out_dir) -> list[Path]:
    """Curves vs flight time (mean +- std per planner) and the false-positive episode maps."""
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    from attend.action.plots import plot_maps

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    logs = result.data["logs"]
    grid_t = np.linspace(0, BUDGET_S, 151)
    fig, axes = plt.subplots(1, 3, figsize=(14, 3.8), constrained_layout=True)
    for name, runs in logs.items():
        for ax, key in zip(axes, ("rse", "trace", "people_found")):
            curves = np.array([r.value_at(key, grid_t) for r in runs])
            mean, std = curves.mean(axis=0), curves.std(axis=0)
            ax.plot(grid_t, mean, label=name)
            ax.fill_between(grid_t, mean - std, mean + std, alpha=0.15)
    for ax, label in zip(axes, ("RSE", "trace(P)", "people found")):
        ax.set_xlabel("flight time [s]")
        ax.set_title(label)
    axes[0].legend(fontsize=8)
    curves_path = out / "ipp_curves.png"
    fig.savefig(curves_path, dpi=110)
    plt.close(fig)
    fp_path = plot_maps(result.data["fp_field"], result.data["fp_log"], [0, 7, 40, 100, BUDGET_S], out / "ipp_false_positive.png")
    return [curves_path, fp_path]
