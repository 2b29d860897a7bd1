"""The sweep task of Figs. 4 and 5 (and rhythm-learning): mass-spring-damper runs from the bank of
:mod:`attend.models.problems`, cut into self-contained, seeded tasks of one batched learn_batch call each
that run here or on a Dask cluster (:func:`attend.sweep.run_tasks`) with the same numbers."""

from __future__ import annotations

from dataclasses import replace
import numpy as np

from attend.constants import KNOWN_PRIOR_PRECISION
from attend.models.problems import MSD_FREE, msd_logs
from attend.perception.learning import PAPER_LEARNER, learn_batch
from attend.sweep import chunk_slices


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
    P = np.where(MSD_FREE[None], np.asarray(task["prior_precision"], dtype=float)[:, None], KNOWN_PRIOR_PRECISION)
    result = learn_batch(Y, U, cfg["dt"], n_states=2, kernel_width=cfg["kernel_width"],
                         prior_mean=np.asarray(task["prior_mean"], dtype=float), prior_precision=P,
                         settings=replace(PAPER_LEARNER, embedding_order=cfg["embedding_order"],
                                          max_iterations=cfg["iterations"]))
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
