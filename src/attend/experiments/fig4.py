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

from attend.experiments._result import ExperimentResult
from attend.perception.learning import PAPER_LEARNER, learn_batch, parameter_vector
from attend.sweep import chunk_slices, run_tasks
from attend.systems import mass_spring_damper, simulate

#: theta3 = -k/m, theta4 = -b/m, theta6 = 1/m (1-based positions in theta = [vec A; vec B; vec C])
FREE = np.array([False, False, True, True, False, True, False, False])
PUBLISHED_THETA = {"theta3": -0.5714, "theta4": -0.2857, "theta6": 0.7143}
KNOWN_PRECISION = float(np.exp(15.0))

SETTINGS = dict(dt=0.1, duration=32.0, kernel_width=0.5, noise_log_precision=8.0, embedding_order=6,
                prior_range=[-2.0, 2.0], known_prior_precision=KNOWN_PRECISION, iterations=30)


def msd_logs(seeds, sensor_std, process_std, dt=0.1, duration=32.0, kernel_width=0.5):
    """Simulated mass-spring-damper logs: outputs (R, T, 1), inputs (R, T, 1), one run per
    (seed, sensor_std) pair of the broadcast arrays; u(t) = exp(-0.25 (t - 12)^2)."""
    system = mass_spring_damper()
    time = np.arange(int(round(duration / dt))) * dt
    u = np.exp(-0.25 * (time - 12.0) ** 2)[:, None]
    seeds, sensor_std = np.broadcast_arrays(np.asarray(seeds), np.asarray(sensor_std, dtype=float))
    outputs, inputs = [], []
    for seed, std in zip(seeds.ravel(), sensor_std.ravel()):  # simulation only; learning is batched
        log = simulate(system, u, dt, kernel_width=kernel_width, process_std=process_std,
                       measurement_std=std, seed=int(seed))
        outputs.append(log.outputs)
        inputs.append(log.inputs)
    return np.array(outputs), np.array(inputs)


def random_priors(seeds, rng_offset: int = 1000) -> np.ndarray:
    """Prior means (len(seeds), 8): the true theta with theta3, theta4, theta6 uniform in [-2, 2]."""
    theta = parameter_vector(mass_spring_damper())
    eta = np.tile(theta, (len(seeds), 1))
    for k, seed in enumerate(seeds):
        eta[k, FREE] = np.random.default_rng(rng_offset + int(seed)).uniform(-2.0, 2.0, FREE.sum())
    return eta


#: Runs per sweep task: each task is one learn_batch call over this many (seed, P_theta) runs
#: (at least 2: see attend.sweep.chunk_slices), enough to amortise the per-iteration overhead.
RUNS_PER_TASK = 64


def task_logs(task: dict) -> tuple[np.ndarray, np.ndarray]:
    """Outputs and inputs (R, T, 1) of a sweep task's runs, each distinct (seed, sensor_std)
    simulated once (settings: process_std, dt, duration, kernel_width)."""
    cfg = task["settings"]
    seeds = np.asarray(task["seed"], dtype=int)
    sensor_std = np.asarray(task["sensor_std"], dtype=float)
    pairs, which = np.unique(np.stack([seeds.astype(float), sensor_std], axis=1), axis=0, return_inverse=True)
    Y, U = msd_logs(pairs[:, 0].astype(int), pairs[:, 1], cfg["process_std"], cfg["dt"], cfg["duration"],
                    cfg["kernel_width"])
    which = np.asarray(which).ravel()
    return Y[which], U[which]


def learn_msd_runs(task: dict) -> dict:
    """Learn one chunk of mass-spring-damper runs: the sweep task of Figs. 4 and 5.

    ``task`` is self-contained and seeded: ``settings`` (dt, duration, kernel_width,
    embedding_order, iterations, process_std) and per-run arrays ``seed`` (simulation seed),
    ``sensor_std``, ``prior_mean`` eta_theta (R, 8) and ``prior_precision`` P_theta of the free
    entries (R,) (the known entries keep exp(15)). The logs are simulated here from the seeds
    (once per distinct (seed, sensor_std)) and all R runs are learned in one batched call, so
    the result does not depend on where the task runs or on how the sweep was cut into tasks.
    Returns per-run ``parameters`` (R, 8), ``log_precision`` (R, 2), ``iterations`` (R,) and
    ``parameter_history`` (R, iterations + 1, 8; NaN after a run's last iteration).
    """
    cfg = task["settings"]
    Y, U = task_logs(task)
    P = np.where(FREE[None], np.asarray(task["prior_precision"], dtype=float)[:, None], KNOWN_PRECISION)
    result = learn_batch(Y, U, cfg["dt"], n_states=2, kernel_width=cfg["kernel_width"],
                         prior_mean=np.asarray(task["prior_mean"], dtype=float), prior_precision=P,
                         embedding_order=cfg["embedding_order"], max_iterations=cfg["iterations"],
                         **PAPER_LEARNER)
    return dict(parameters=result.parameters, log_precision=result.log_precision,
                iterations=result.iterations, parameter_history=result.parameter_history)


def msd_tasks(settings: dict, seed, sensor_std, prior_mean, prior_precision,
              runs_per_task: int = RUNS_PER_TASK) -> list[dict]:
    """Cut a list of runs (per-run arrays, in sweep order) into :func:`learn_msd_runs` tasks."""
    keys = ("dt", "duration", "kernel_width", "embedding_order", "iterations", "process_std")
    shared = {k: settings[k] for k in keys}
    seed, sensor_std, prior_precision = (np.broadcast_to(np.asarray(a), (len(prior_mean),))
                                         for a in (seed, sensor_std, prior_precision))
    return [dict(settings=shared, seed=seed[s].copy(), sensor_std=sensor_std[s].copy(),
                 prior_mean=np.asarray(prior_mean)[s].copy(), prior_precision=prior_precision[s].copy())
            for s in chunk_slices(len(prior_mean), runs_per_task)]


def gather_runs(results: list[dict]) -> dict:
    """Concatenate :func:`learn_msd_runs` results in task order; histories NaN-padded to one length."""
    length = max(r["parameter_history"].shape[1] for r in results)
    history = [np.pad(r["parameter_history"], ((0, 0), (0, length - r["parameter_history"].shape[1]), (0, 0)),
                      constant_values=np.nan) for r in results]
    out = {k: np.concatenate([r[k] for r in results]) for k in ("parameters", "log_precision", "iterations")}
    out["parameter_history"] = np.concatenate(history)
    return out


def run(quick: bool = True, out_dir=None, progress: bool = True, *, cluster=None, n_seeds: int | None = None,
        n_prior_precisions: int | None = None, runs_per_task: int = RUNS_PER_TASK) -> ExperimentResult:
    """Median parameter SSE vs P_theta over seeds.

    The (P_theta, seed) grid is cut into tasks of ``runs_per_task`` runs, each learned with one
    batched call; ``cluster`` (None: here; ``"tcp://host:8786"`` or a ``distributed.Client``)
    says where they run (:func:`attend.sweep.run_tasks`): the numbers are the same either way.
    ``n_seeds`` and ``n_prior_precisions`` override the quick/full sizes (12 x 13 / 50 x 25).
    """
    default_seeds, default_prec = (12, 13) if quick else (50, 25)
    n_seeds = default_seeds if n_seeds is None else int(n_seeds)
    n_prec = default_prec if n_prior_precisions is None else int(n_prior_precisions)
    cfg = dict(SETTINGS, seeds=n_seeds, prior_precisions=np.logspace(-4, 8, n_prec).tolist())
    precisions = np.array(cfg["prior_precisions"])
    seeds = np.arange(n_seeds)
    theta_true = parameter_vector(mass_spring_damper())
    std = np.exp(-cfg["noise_log_precision"] / 2)
    eta = random_priors(seeds)
    # runs ordered (precision, seed)
    idx_seed = np.tile(np.arange(n_seeds), n_prec)
    idx_prec = np.repeat(np.arange(n_prec), n_seeds)
    tasks = msd_tasks(dict(cfg, process_std=std), seeds[idx_seed], std, eta[idx_seed], precisions[idx_prec],
                      runs_per_task)
    runs = gather_runs(run_tasks(learn_msd_runs, tasks, cluster=cluster, progress=progress,
                                 desc=f"fig4 ({len(idx_seed)} runs, {len(tasks)} tasks)"))
    sse = np.sum((runs["parameters"][:, FREE] - theta_true[FREE]) ** 2, axis=1).reshape(n_prec, n_seeds)
    prior_sse = np.sum((eta[:, FREE] - theta_true[FREE]) ** 2, axis=1)
    median = np.median(sse, axis=1)

    out = ExperimentResult("fig4", settings=cfg)
    out.add("median_sse_lowest_prior_precision", median[0], "", None)
    out.add("median_sse_highest_prior_precision", median[-1], "", None)
    out.add("median_sse_of_the_random_prior", np.median(prior_sse), "", None)
    middle = int(np.argmin(np.abs(np.log10(precisions) - 4)))
    out.add("median_sse_prior_precision_1e4", median[middle], "", None)
    out.add("orders_of_magnitude_swept", np.log10(precisions[-1] / precisions[0]), "decades", None)
    out.data.update(prior_precision=precisions, sse=sse, prior_sse=prior_sse)
    if out_dir is not None:
        out.figures.append(str(_plot(runs["parameter_history"], precisions, sse, theta_true, idx_prec, Path(out_dir))))
        out.write(out_dir)
    return out


def _plot(parameter_history, precisions, sse, theta_true, idx_prec, out_dir: Path) -> Path:
    from attend.plotting import new_figure

    fig, axes = new_figure(out_dir, (13, 4), 1, 3)
    labels = ["theta3 = -k/m", "theta4 = -b/m", "theta6 = 1/m"]
    for ax, which, title in ((axes[0], 0, "a) over-exposed (lowest P_theta)"),
                             (axes[2], len(precisions) - 1, "c) biased (highest P_theta)")):
        run = np.flatnonzero(idx_prec == which)[0]
        history = parameter_history[run][:, FREE]
        for j in range(3):
            line, = ax.plot(history[:, j], label=labels[j])
            ax.axhline(theta_true[FREE][j], color=line.get_color(), ls=":", lw=1)
        ax.set_xlabel("iteration")
        ax.set_ylabel("parameter")
        ax.set_title(f"{title}: P_theta = {precisions[which]:.0e}")
        ax.legend(fontsize=7)
    ax = axes[1]
    q1, q2, q3 = np.percentile(sse, [25, 50, 75], axis=1)
    ax.fill_between(precisions, q1, q3, alpha=0.3, label="quartiles")
    ax.loglog(precisions, q2, "o-", label="median SSE")
    ax.set_xlabel("prior parameter precision P_theta")
    ax.set_ylabel("parameter SSE")
    ax.set_title("b) SSE vs P_theta")
    ax.legend(fontsize=7)
    fig.tight_layout()
    path = out_dir / "fig4.png"
    fig.savefig(path, dpi=110)
    return path
