"""Experiment "rhythm-ipp": when to stop flying and replan in UAV search (paper Sec. 4.4, Fig. 10).

The search-and-rescue mission of :mod:`attend.action` (40 x 40 map, 7 people, 150 s of flight,
``precision_gain`` planner with a 5-waypoint look-ahead) is flown under replan schedules
(:mod:`attend.rhythm.replanning`, policies built from :mod:`attend.rhythm.schedule`) at equal
total flight time:

* fixed budgets: replan after every segment ("segment"), or after 10, 20, 40 s of flight on
  each plan ("fixed_10s", ...);
* "oscillator": replan at each trough of a precision oscillator (f = 0.05 Hz, one trough every
  20 s: the rhythm alone);
* "precision": keep flying while the rest of the plan offers at least the gain rate a fresh plan
  is expected to offer (the last plan's rate scaled by the uncertainty left), the oscillator's
  phase tilting the decision towards its troughs (kappa = 0.5);
* "precision_no_prior": the same rule without the oscillator (kappa = 0).

Per policy and trial: RSE, trace(P), people found vs flight time, number of replans, planner
wall time and the schedule's own decision time. Trial k uses seed k for the field, the
detector noise and the planner, the same for every policy (paired differences). Each trial x
policy is one task of :func:`attend.sweep.run_tasks` (here or on a Dask cluster).

Quick mode: 8 trials, per-cell (diagonal) map covariance, CMA-ES with 6 evaluations per replan
(one generation). Full mode: 25 trials, full covariance, 24 evaluations.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from attend._validation import AttendInputError
from attend.action.camera import Camera, Detector
from attend.action.field import make_field
from attend.action.flight import FlightModel
from attend.action.planners import PlanningSetup, make_planner
from attend.experiments._result import Claim, ExperimentResult
from attend.rhythm.replanning import fly_scheduled_mission, make_replan_policy
from attend.sweep import run_tasks

SETTINGS = dict(
    budget_s=150.0, planner="precision_gain", lookahead_waypoints=5,
    policies=["segment", "fixed_10s", "fixed_20s", "fixed_40s", "oscillator", "precision", "precision_no_prior"],
    rhythmic_policy="precision",
    # the oscillator and the precision-driven rule (kappa = prior_weight, rho = tolerance)
    oscillator_frequency_hz=0.05, oscillator_phase_rad=0.0, prior_weight=0.5, tolerance=1.0,
    # sizes: quick / full
    quick_trials=8, full_trials=25, quick_cma_evaluations=6, full_cma_evaluations=24,
    quick_diagonal=True, full_diagonal=False, first_seed=0,
)

#: policies that are fixed budgets (the rhythmic policy is compared with the best of them)
FIXED_PREFIXES = ("segment", "fixed_")


def trial(task: dict) -> dict:
    """One mission of one policy (a sweep task): ``task`` holds ``policy``, ``seed`` and the
    settings (budget_s, planner, lookahead_waypoints, cma_evaluations, diagonal, oscillator and
    rule parameters). Returns the curves and costs as plain arrays."""
    s = task["settings"]
    seed = int(task["seed"])
    field = make_field(seed)
    setup = PlanningSetup(field, Camera(), Detector(), FlightModel(), lookahead_waypoints=s["lookahead_waypoints"],
                          cma_evaluations=s["cma_evaluations"])
    planner = make_planner(s["planner"], setup, seed)
    policy = make_replan_policy(task["policy"], s["oscillator_frequency_hz"], s["oscillator_phase_rad"],
                                s["prior_weight"], s["tolerance"])
    log = fly_scheduled_mission(field, planner, policy, s["budget_s"], seed, diagonal=s["diagonal"])
    return dict(
        policy=task["policy"], seed=seed, time_s=log.metric_times_s, rse=log.series("rse"), trace=log.series("trace"),
        people_found=log.series("people_found"), replan_times_s=np.array(log.replan_times_s),
        planner_times_s=np.array(log.planner_times_s), decision_times_s=np.array(log.decision_times_s),
        decisions=np.array(log.decisions, dtype=float).reshape(-1, 4),
    )


def _values_at(result: dict, key: str, times: np.ndarray) -> np.ndarray:
    index = np.searchsorted(result["time_s"], times, side="right") - 1
    return result[key][np.clip(index, 0, None)]


def _check(quick, trials, policies) -> tuple[int, list[str]]:
    if not isinstance(quick, (bool, np.bool_)):
        raise AttendInputError(f"quick: expected True or False, got {quick!r}")
    if trials is None:
        trials = SETTINGS["quick_trials"] if quick else SETTINGS["full_trials"]
    if isinstance(trials, bool) or not isinstance(trials, (int, np.integer)) or trials < 1:
        raise AttendInputError(f"trials: expected an integer >= 1, got {trials!r}")
    policies = list(SETTINGS["policies"] if policies is None else policies)
    if not policies:
        raise AttendInputError("policies: expected at least one policy name")
    for name in policies:
        make_replan_policy(name)  # raises AttendInputError naming "policy"
    return int(trials), policies


def run(quick: bool = True, progress: bool = True, cluster=None, trials: int | None = None,
        policies=None) -> ExperimentResult:
    """Fly every policy on the same seeded trials and compare them at equal flight time.

    quick: 8 trials, per-cell covariance, 6 CMA-ES evaluations per replan (< 90 s on 2 cores);
    otherwise 25 trials, full covariance, 24 evaluations. trials, policies: override the number
    of trials and the policy list (names as in SETTINGS["policies"]). progress: a progress bar;
    cluster: a Dask scheduler address or client (see attend.sweep.run_tasks)."""
    trials, policies = _check(quick, trials, policies)
    start = time.perf_counter()
    mode = "quick" if quick else "full"
    cfg = dict(SETTINGS, quick=bool(quick), trials=trials, policies=policies,
               cma_evaluations=SETTINGS[f"{mode}_cma_evaluations"], diagonal=SETTINGS[f"{mode}_diagonal"])
    seeds = list(range(cfg["first_seed"], cfg["first_seed"] + trials))
    tasks = [dict(policy=name, seed=seed, settings=cfg) for seed in seeds for name in policies]
    done = run_tasks(trial, tasks, cluster=cluster, progress=progress, desc="rhythm-ipp")
    runs = {name: [r for r in done if r["policy"] == name] for name in policies}

    result = ExperimentResult("rhythm-ipp", settings=cfg)
    grid_t = np.linspace(0.0, cfg["budget_s"], 151)
    summary = {name: _summary(rs, grid_t) for name, rs in runs.items()}
    for name, v in summary.items():
        _add_policy_metrics(result, name, v)
    comparison = _compare_with_best_fixed(result, summary, policies)
    result.add("wall_time", time.perf_counter() - start, "s")
    result.data = dict(runs=runs, summary=summary, comparison=comparison, grid_t=grid_t,
                       best_fixed=comparison and next(iter(comparison.values()))["best_fixed"])
    result.tables.update(_tables(runs, summary, grid_t, cfg))
    return result


def _summary(runs: list[dict], grid_t: np.ndarray) -> dict[str, np.ndarray]:
    summary = dict(
        rse=np.array([r["rse"][-1] for r in runs]),
        trace=np.array([r["trace"][-1] for r in runs]),
        found=np.array([r["people_found"][-1] for r in runs]),
        rse_time_average=np.array([_values_at(r, "rse", grid_t).mean() for r in runs]),
        replans=np.array([len(r["replan_times_s"]) for r in runs], dtype=float),
        planner_s=np.array([r["planner_times_s"].sum() for r in runs]),
        decision_s=np.array([r["decision_times_s"].sum() for r in runs]),
    )
    summary["compute_s"] = summary["planner_s"] + summary["decision_s"]
    return summary


def _std(values: np.ndarray) -> float:
    return float(np.std(values, ddof=1)) if len(values) > 1 else 0.0


def _add_policy_metrics(result: ExperimentResult, name: str, v: dict) -> None:
    result.add(f"{name}_final_RSE_mean", v["rse"].mean(), "1")
    result.add(f"{name}_final_RSE_std", _std(v["rse"]), "1")
    result.add(f"{name}_RSE_time_average_mean", v["rse_time_average"].mean(), "1")
    result.add(f"{name}_final_trace_mean", v["trace"].mean(), "1")
    result.add(f"{name}_people_found_mean", v["found"].mean(), "people")
    result.add(f"{name}_replans_mean", v["replans"].mean(), "plans")
    result.add(f"{name}_planner_time_mean", v["planner_s"].mean(), "s")
    result.add(f"{name}_decision_time_mean", v["decision_s"].mean(), "s")
    result.add(f"{name}_compute_time_mean", v["compute_s"].mean(), "s")


def _compare_with_best_fixed(result: ExperimentResult, summary: dict, policies: list[str]) -> dict:
    """Paired final-RSE differences of every non-fixed policy to the best fixed budget."""
    fixed = [n for n in policies if n.startswith(FIXED_PREFIXES)]
    comparison = {}
    if not fixed:
        return comparison
    best = min(fixed, key=lambda n: summary[n]["rse"].mean())
    result.notes.append(f"best fixed budget by mean final RSE: {best}")
    for name in policies:
        if name in fixed:
            continue
        diff = summary[name]["rse"] - summary[best]["rse"]
        sem = float(np.std(diff, ddof=1) / np.sqrt(len(diff))) if len(diff) > 1 else 0.0
        result.add(f"{name}_minus_best_fixed_final_RSE_mean", diff.mean(), "1")
        result.add(f"{name}_minus_best_fixed_final_RSE_sem", sem, "1")
        result.add(f"{name}_over_best_fixed_replans", summary[name]["replans"].mean() / summary[best]["replans"].mean(), "1")
        result.add(f"{name}_over_best_fixed_compute", summary[name]["compute_s"].mean() / summary[best]["compute_s"].mean(), "1")
        comparison[name] = dict(best_fixed=best, rse_difference=diff)
    return comparison


def _tables(runs: dict, summary: dict, grid_t: np.ndarray, cfg: dict) -> dict:
    """What the figures need: mean curves on ``grid_t``, per-trial costs, one mission's decisions."""
    curves = {name: {key: np.mean([_values_at(r, key, grid_t) for r in rs], axis=0)
                     for key in ("rse", "trace", "people_found")} for name, rs in runs.items()}
    costs = {name: {key: v[key] for key in ("rse", "replans", "compute_s", "decision_s")}
             for name, v in summary.items()}
    tables = dict(grid_t=grid_t, curves=curves, costs=costs)
    rhythmic = cfg.get("rhythmic_policy")
    if rhythmic in runs and len(runs[rhythmic][0]["decisions"]):
        first = runs[rhythmic][0]
        tables["decisions"] = dict(policy=rhythmic, seed=first["seed"], decisions=first["decisions"],
                                   replan_times_s=first["replan_times_s"])
    return tables


CAPTIONS = {
    "rhythm-ipp_curves.png": (
        "UAV search under replanning policies at equal flight time: RSE of the occupancy map, "
        "trace of its covariance and people found against flight time (mean over trials). Solid: "
        "fixed budgets; dashed: the rhythm (oscillator) and the precision-driven rules; thick: the "
        "rhythmic policy of the paper's proposal. If the rhythm helps, its dashed curves lie below "
        "(RSE, trace) or above (people) the solid ones."),
    "rhythm-ipp_cost.png": (
        "Per policy: final RSE, replans per mission and compute per mission (planner and the "
        "policy's own decisions, red), mean and std over trials. Fewer replans at equal RSE would be "
        "a saving of the rhythmic or precision-driven policies."),
    "rhythm-ipp_decisions.png": (
        "One precision-driven mission: the expected precision gain rate of the rest of the plan "
        "(stay) and of a fresh plan against flight time; black lines: replans; red bands: the "
        "oscillator's troughs, where the prior favours replanning."),
}


def plot(result: ExperimentResult, out_dir) -> list[str]:
    """rhythm-ipp_curves.png, rhythm-ipp_cost.png and (when a precision-driven mission made
    decisions) rhythm-ipp_decisions.png from ``result.tables`` into ``out_dir`` (CAPTIONS)."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    figures = {"rhythm-ipp_curves.png": _plot_curves(result), "rhythm-ipp_cost.png": _plot_costs(result)}
    if "decisions" in result.tables:
        figures["rhythm-ipp_decisions.png"] = _plot_decisions(result)
    paths = []
    for name, fig in figures.items():
        fig.tight_layout()
        fig.savefig(out / name, dpi=110)
        paths.append(str(out / name))
    return paths


def _plot_curves(result: ExperimentResult):
    from attend.plotting import figure

    curves, grid_t = result.tables["curves"], np.asarray(result.tables["grid_t"], dtype=float)
    fig, axes = figure((15, 4.2), 1, 3)
    for name, curve in curves.items():
        style = "-" if name.startswith(FIXED_PREFIXES) else "--"
        width = 2.2 if name == result.settings.get("rhythmic_policy") else 1.2
        for ax, key in zip(axes, ("rse", "trace", "people_found")):
            ax.plot(grid_t, np.asarray(curve[key], dtype=float), style, lw=width, label=name)
    trials = result.settings.get("trials")
    for ax, label, unit in zip(axes, ("RSE", "trace(P)", "people found"), ("[1]", "[1]", "[people]")):
        ax.set(xlabel="flight time [s]", ylabel=f"{label} {unit}", title=f"{label} (mean of {trials} trials)")
    axes[0].legend(fontsize=8)
    return fig


def _plot_costs(result: ExperimentResult):
    from attend.plotting import figure

    costs = result.tables["costs"]
    names = list(costs)
    fig, axes = figure((15, 4.0), 1, 3)
    x = np.arange(len(names))
    for ax, key, label in zip(axes, ("rse", "replans", "compute_s"),
                              ("final RSE [1]", "replans per mission [plans]", "compute per mission [s]")):
        values = [np.asarray(costs[n][key], dtype=float) for n in names]
        ax.bar(x, [v.mean() for v in values], yerr=[v.std() for v in values], color="0.7")
        if key == "compute_s":
            ax.bar(x, [np.mean(costs[n]["decision_s"]) for n in names], color="tab:red", label="decisions")
            ax.legend(fontsize=8)
        ax.set_xticks(x)
        ax.set_xticklabels(names, rotation=30, ha="right", fontsize=8)
        ax.set(xlabel="replanning policy", ylabel=label, title=label.split(" [")[0] + " (mean, std over trials)")
    return fig


def _plot_decisions(result: ExperimentResult):
    from attend.plotting import figure

    record = result.tables["decisions"]
    d = np.asarray(record["decisions"], dtype=float).reshape(-1, 4)
    fig, ax = figure((9, 3.6))
    ax.plot(d[:, 0], d[:, 1], "o-", label="stay: rest of the plan")
    ax.plot(d[:, 0], d[:, 2], "s--", label="fresh plan (estimate)")
    for t in record["replan_times_s"]:
        ax.axvline(t, color="k", lw=0.6, alpha=0.5)
    period = 1.0 / result.settings["oscillator_frequency_hz"]
    phase = result.settings["oscillator_phase_rad"]
    for t in np.arange(((-np.pi / 2 - phase) / (2 * np.pi)) % 1.0 * period, result.settings["budget_s"], period):
        ax.axvspan(t - 0.1 * period, t + 0.1 * period, color="tab:red", alpha=0.1)
    ax.set_xlabel("flight time [s] (black: replans; red: oscillator troughs)")
    ax.set_ylabel("expected trace(P) reduction per second [1/s]")
    ax.set_title(f"{record['policy']}: decisions of trial seed {record['seed']}")
    ax.legend(fontsize=8)
    return fig


def _verdict(mean: float, sem: float) -> str:
    """reproduced: lower final RSE than the best fixed budget by more than 2 standard errors;
    does not hold otherwise (no better, or not distinguishable at this number of trials)."""
    return "reproduced" if mean + 2 * sem < 0 else "does not hold"


def claims(result: ExperimentResult) -> list[Claim]:
    """The paper's claim (§4.4, Fig. 10, use 2): letting the rhythm, or precision dynamics with the
    rhythm as a prior, decide when to replan beats a flight-time budget per plan. result: the
    ExperimentResult of :func:`run`."""
    best = next((n[len("best fixed budget by mean final RSE: "):] for n in result.notes
                 if n.startswith("best fixed budget")), None)
    found = []
    wording = {"oscillator": "Replanning at the troughs of a rhythm",
               "precision": "Replanning when the precision dynamics say so, with the rhythm as a prior",
               "precision_no_prior": "Replanning when the precision dynamics say so (no rhythm)"}
    for name, text in wording.items():
        try:
            mean = result.metric(f"{name}_minus_best_fixed_final_RSE_mean").value
            sem = result.metric(f"{name}_minus_best_fixed_final_RSE_sem").value
            replans = result.metric(f"{name}_over_best_fixed_replans").value
        except KeyError:
            continue
        measured = (f"final RSE minus the best fixed budget ({best}): {mean:+.3f} +- {sem:.3f} (mean +- s.e.m. over "
                    f"{result.settings.get('trials')} paired trials); {replans:.2f} x its replans")
        found.append(Claim(f"{text} gives a lower final map error (RSE) than the best fixed flight budget per plan",
                           measured, _verdict(mean, sem)))
    return found
