"""Paper Fig. 4: exploration vs exploitation in system identification, set by P_theta.

The mass-spring-damper's unknown entries theta3 = -k/m, theta4 = -b/m, theta6 = 1/m get prior
means drawn uniformly in [-2, 2] (one draw per seed, shared across prior precisions) and a prior
precision P_theta swept over 12 orders of magnitude (1e-4 .. 1e8); the known entries keep
exp(15). Learning (attend.perception.learning, D/E/M steps, noise precisions learned from
lambda = 0 with P_lambda = 1) runs batched over the (P_theta, seed) grid, cut into sweep tasks of
``RUNS_PER_TASK`` runs (one learn_batch call each) that run here or on a Dask cluster
(``run(cluster="tcp://host:8786")``, see attend.sweep) with the same numbers. The parameter SSE
sum_i (theta_i - theta_i,true)^2 over the three unknown entries is low for a low P_theta
(over-exposed: attention on the sensory data), rises through a balanced band, and saturates
at the error of the random prior for a high P_theta (biased: attention on the prior).

Settings (the seed does not give them; the ACC 2020 setting): dt = 0.1 s, 32 s,
u(t) = exp(-0.25 (t - 12)^2), kernel width s = 0.5 s, noise log-precision 8 on w and z,
embedding order p = 6, 30 iterations (quick: 12 seeds x 13 precisions; full: 50 x 25).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from attend.constants import KNOWN_PRIOR_PRECISION
from attend.experiments._msd_sweep import RUNS_PER_TASK, gather_runs, learn_msd_runs, msd_tasks, task_logs
from attend.experiments._result import Claim, ExperimentResult
from attend.models.parameters import parameter_vector
from attend.models.problems import MSD_FREE, mass_spring_damper, msd_random_priors
from attend.sweep import run_tasks

SETTINGS = dict(dt=0.1, duration=32.0, kernel_width=0.5, noise_log_precision=8.0, embedding_order=6,
                prior_range=[-2.0, 2.0], known_prior_precision=KNOWN_PRIOR_PRECISION, iterations=30)

#: the names attend.experiments.rhythm_learning imports from here (the bank now lives in
#: attend.models.problems and attend.experiments._msd_sweep)
FREE, KNOWN_PRECISION = MSD_FREE, KNOWN_PRIOR_PRECISION
__all__ = ["SETTINGS", "run", "plot", "claims", "CAPTIONS", "FREE", "KNOWN_PRECISION", "RUNS_PER_TASK", "task_logs"]


def run(quick: bool = True, progress: bool = True, *, cluster=None, n_seeds: int | None = None,
        n_prior_precisions: int | None = None, runs_per_task: int = RUNS_PER_TASK) -> ExperimentResult:
    """Median parameter SSE vs P_theta over seeds.

    The (P_theta, seed) grid is cut into tasks of ``runs_per_task`` runs, each learned with one
    batched call; ``cluster`` (None: here; ``"tcp://host:8786"`` or a ``distributed.Client``)
    says where they run (:func:`attend.sweep.run_tasks`): the numbers are the same either way.
    ``n_seeds`` and ``n_prior_precisions`` override the quick/full sizes (12 x 13 / 50 x 25); progress:
    a progress bar over tasks. ``result.tables`` holds the SSE grid (P_theta x seed), the prior's SSE
    per seed and seed 0's parameter histories at both ends of the sweep, all :func:`plot` needs.
    """
    default_seeds, default_prec = (12, 13) if quick else (50, 25)
    n_seeds = default_seeds if n_seeds is None else int(n_seeds)
    n_prec = default_prec if n_prior_precisions is None else int(n_prior_precisions)
    cfg = dict(SETTINGS, seeds=n_seeds, prior_precisions=np.logspace(-4, 8, n_prec).tolist())
    precisions = np.array(cfg["prior_precisions"])
    seeds = np.arange(n_seeds)
    theta_true = parameter_vector(mass_spring_damper())
    std = np.exp(-cfg["noise_log_precision"] / 2)
    eta = msd_random_priors(seeds)
    # runs ordered (precision, seed)
    idx_seed = np.tile(np.arange(n_seeds), n_prec)
    idx_prec = np.repeat(np.arange(n_prec), n_seeds)
    tasks = msd_tasks(dict(cfg, process_std=std), seeds[idx_seed], std, eta[idx_seed], precisions[idx_prec],
                      runs_per_task)
    runs = gather_runs(run_tasks(learn_msd_runs, tasks, cluster=cluster, progress=progress,
                                 desc=f"fig4 ({len(idx_seed)} runs, {len(tasks)} tasks)"))
    sse = np.sum((runs["parameters"][:, MSD_FREE] - theta_true[MSD_FREE]) ** 2, axis=1).reshape(n_prec, n_seeds)
    prior_sse = np.sum((eta[:, MSD_FREE] - theta_true[MSD_FREE]) ** 2, axis=1)
    median = np.median(sse, axis=1)

    out = ExperimentResult("fig4", settings=cfg)
    out.add("median_sse_lowest_prior_precision", median[0], "", None)
    out.add("median_sse_highest_prior_precision", median[-1], "", None)
    out.add("median_sse_of_the_random_prior", np.median(prior_sse), "", None)
    middle = int(np.argmin(np.abs(np.log10(precisions) - 4)))
    out.add("median_sse_prior_precision_1e4", median[middle], "", None)
    out.add("orders_of_magnitude_swept", np.log10(precisions[-1] / precisions[0]), "decades", None)
    out.data.update(prior_precision=precisions, sse=sse, prior_sse=prior_sse)
    history = runs["parameter_history"]
    out.tables = dict(
        sse=sse, prior_sse=prior_sse, theta_true=theta_true[MSD_FREE],
        # seed 0's parameter history at the lowest and the highest P_theta (panels a and c)
        extremes=[dict(prior_precision=precisions[which], parameters=history[np.flatnonzero(idx_prec == which)[0]]
                       [:, MSD_FREE]) for which in (0, n_prec - 1)])
    return out


CAPTIONS = {
    "fig4.png": (
        "Exploration vs exploitation set by the prior parameter precision P_theta (mass-spring-damper, "
        "theta3 = -k/m [1/s^2], theta4 = -b/m [1/s], theta6 = 1/m [1/kg] unknown, random prior means). "
        "(a) Over-exposed learner (lowest P_theta): the parameters leave their prior and reach the true "
        "values (dotted). (c) Biased learner (highest P_theta): they stay at the prior. (b) Parameter SSE "
        "vs P_theta (median and quartiles over seeds): low for a low P_theta, rising through a band and "
        "saturating at the error of the random prior."
    ),
}

_LABELS = ("theta3 = -k/m [1/s^2]", "theta4 = -b/m [1/s]", "theta6 = 1/m [1/kg]")


def claims(result: ExperimentResult) -> list[Claim]:
    """The Fig. 4 claims, judged on ``result``: a low P_theta (attention on the data) learns the
    parameters; a high one (attention on the prior) keeps the error of the prior."""
    low = result.metric("median_sse_lowest_prior_precision").value
    high = result.metric("median_sse_highest_prior_precision").value
    prior = result.metric("median_sse_of_the_random_prior").value
    return [
        Claim("A low prior parameter precision (over-exposed) learns the parameters; a high one (biased) "
              "stays at the prior (Fig. 4)",
              f"median parameter SSE {low:.3g} at the lowest P_theta vs {high:.3g} at the highest "
              f"(prior error {prior:.3g})",
              "reproduced" if low < 0.01 * high else "does not hold", "low -> high SSE (figure only)"),
        Claim("At the highest P_theta the learner keeps the error of its random prior",
              f"median SSE {high:.4g} vs prior {prior:.4g}",
              "reproduced" if abs(high - prior) <= 0.01 * prior else "differs", "saturates (figure only)"),
    ]


def plot(result: ExperimentResult, out_dir) -> list[str]:
    """fig4.png from ``result.tables`` alone: (a) and (c) seed 0's parameters per iteration at the
    lowest and highest P_theta, (b) SSE vs P_theta. out_dir: the folder (created). Returns the names."""
    from attend.plotting import new_figure

    tables = result.tables
    precisions = np.asarray(result.settings["prior_precisions"], dtype=float)
    sse = np.asarray(tables["sse"], dtype=float)
    theta_true = np.asarray(tables["theta_true"], dtype=float)
    fig, axes = new_figure(out_dir, (13, 4), 1, 3)
    for ax, extreme, title in ((axes[0], tables["extremes"][0], "a) over-exposed (lowest P_theta)"),
                               (axes[2], tables["extremes"][1], "c) biased (highest P_theta)")):
        history = np.asarray(extreme["parameters"], dtype=float)
        for j in range(3):
            line, = ax.plot(history[:, j], label=_LABELS[j])
            ax.axhline(theta_true[j], color=line.get_color(), ls=":", lw=1)
        ax.set_xlabel("iteration")
        ax.set_ylabel("parameter value [unit in legend]")
        ax.set_title(f"{title}: P_theta = {extreme['prior_precision']:.0e}")
        ax.legend(fontsize=7)
    ax = axes[1]
    q1, q2, q3 = np.percentile(sse, [25, 50, 75], axis=1)
    ax.fill_between(precisions, q1, q3, alpha=0.3, label="quartiles")
    ax.loglog(precisions, q2, "o-", label="median SSE")
    ax.set_xlabel("prior parameter precision P_theta [1/unit of theta^2]")
    ax.set_ylabel("parameter SSE [(1/s^2)^2 + (1/s)^2 + (1/kg)^2]")
    ax.set_title("b) SSE vs P_theta")
    ax.legend(fontsize=7)
    fig.tight_layout()
    path = Path(out_dir) / "fig4.png"
    fig.savefig(path, dpi=110)
    return [path.name]
