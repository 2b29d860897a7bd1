"""Run a sweep of independent, seeded tasks here or on a Dask cluster, with the same results.

A sweep is a list of *tasks*: picklable, self-contained descriptions of a piece of work (a dict
of settings, the seeds and the swept values of a chunk of runs) and a module-level function
that computes a task's result from the task alone. Every random thing a task needs is seeded
from the seeds it carries (no global RNG, no state shared between tasks), so where and in which
order the tasks run cannot change their results::

    from attend.sweep import run_tasks
    results = run_tasks(function, tasks)                             # here, in order
    results = run_tasks(function, tasks, cluster="tcp://host:8786")  # on a running cluster

Both return ``[function(task) for task in tasks]``, bit for bit the same arrays when the
workers run the same versions of attend and numpy as the client (checked: a mismatch warns).

Why Dask (``dask.distributed``) as the distributed engine, rather than Ray: it is pure Python
and light to install from PyPI (``pip install "dask[distributed]"``), whereas Ray is a large
binary wheel that is heavy for a 2-core CI runner and a laptop; a ``LocalCluster`` starts
in-process within a second, so the tests run a real scheduler and real worker processes;
and an existing cluster (``dask scheduler`` + ``dask worker``, dask-jobqueue on SLURM/PBS,
dask-kubernetes, Coiled) is reached by its scheduler address ``"tcp://host:8786"`` alone.
Dask is an optional dependency: it is imported only when a cluster is asked for.

Tasks should be chunks of runs that are still vectorised inside (e.g. a slice of a prior
precision x seed grid learned with one :func:`attend.perception.learning.learn_batch` call),
not single runs: the per-task overhead of a cluster is milliseconds, one learning run is too.
:func:`chunk_slices` cuts a run list into such chunks.
"""

from __future__ import annotations

import uuid
import warnings
from typing import Any, Callable, Iterable, Sequence, TypeVar

from attend._validation import AttendInputError

__all__ = ["run_tasks", "chunk_slices", "Cluster"]

T = TypeVar("T")
R = TypeVar("R")

#: A scheduler address such as ``"tcp://host:8786"`` or a ``distributed.Client``.
Cluster = Any

_INSTALL_HINT = 'install it with: pip install "dask[distributed]"'


def run_tasks(
    function: Callable[[T], R],
    tasks: Iterable[T],
    *,
    cluster: Cluster | None = None,
    progress: bool = True,
    desc: str = "sweep",
) -> list[R]:
    """Return ``[function(task) for task in tasks]``, computed here or on a Dask cluster.

    function: a module-level (picklable) function of one task; it must compute its result
        from the task alone (seeds inside the task), so results do not depend on where it runs.
    tasks: picklable task descriptions (e.g. dicts of settings, seeds and swept values).
    cluster: None (default) runs the tasks in order in this process; a scheduler address
        (``"tcp://host:8786"``, ``"tls://..."``, ``"inproc://..."``) connects a
        ``distributed.Client`` for this call and closes it after; a ``distributed.Client``
        is used as is (and left open). On a cluster the tasks are submitted with
        ``client.map`` and the results gathered in task order.
    progress: show a tqdm bar (per finished task).
    desc: the label of the bar and of the tasks on the Dask dashboard.

    A failing task raises its exception here (on a cluster, after cancelling the others).
    """
    tasks = list(tasks)
    if not callable(function):
        raise AttendInputError(f"function: expected a callable of one task, got {type(function).__name__}")
    if cluster is None:
        return _run_local(function, tasks, progress, desc)
    if isinstance(cluster, str):
        if "://" not in cluster:
            raise AttendInputError(
                f"cluster: expected a Dask scheduler address such as 'tcp://host:8786', got {cluster!r}"
            )
        distributed = _import_distributed(cluster)
        with distributed.Client(cluster) as client:
            return _run_on_client(client, function, tasks, progress, desc)
    distributed = _import_distributed(cluster)
    if not isinstance(cluster, distributed.Client):
        raise AttendInputError(
            "cluster: expected None, a scheduler address 'tcp://host:8786' or a distributed.Client, "
            f"got {type(cluster).__name__}"
        )
    return _run_on_client(cluster, function, tasks, progress, desc)


def chunk_slices(n_runs: int, runs_per_task: int) -> list[slice]:
    """Cut ``range(n_runs)`` into contiguous, near-equal slices of at most ``runs_per_task``.

    Every slice holds at least 2 runs when ``n_runs >= 2`` (so a batched learner never sees a
    batch of one, whose numpy reductions may take a different path: a last-bit difference).
    """
    if int(runs_per_task) != runs_per_task or runs_per_task < 1:
        raise AttendInputError(f"runs_per_task: expected a positive integer, got {runs_per_task!r}")
    if n_runs <= 0:
        return []
    n_tasks = -(-n_runs // int(runs_per_task))  # ceil
    n_tasks = max(1, min(n_tasks, n_runs // 2))
    bounds = [round(k * n_runs / n_tasks) for k in range(n_tasks + 1)]
    return [slice(lo, hi) for lo, hi in zip(bounds[:-1], bounds[1:])]


def _run_local(function, tasks: Sequence, progress: bool, desc: str) -> list:
    iterator = tasks
    if progress:
        from tqdm import tqdm

        iterator = tqdm(tasks, desc=desc, unit="task", leave=False)
    return [function(task) for task in iterator]


def _import_distributed(cluster):
    try:
        import distributed
    except ImportError:
        raise AttendInputError(
            f"cluster={cluster!r}: running a sweep on a cluster needs dask.distributed; {_INSTALL_HINT}"
        ) from None
    return distributed


def _run_on_client(client, function, tasks: Sequence, progress: bool, desc: str) -> list:
    import distributed

    if not tasks:
        return []
    _check_worker_versions(client)
    token = uuid.uuid4().hex[:8]
    keys = [f"{desc}-{token}-{i}" for i in range(len(tasks))]
    futures = client.map(function, tasks, key=keys, pure=False)
    try:
        if progress:
            from tqdm import tqdm

            with tqdm(total=len(futures), desc=desc, unit="task", leave=False) as bar:
                for future in distributed.as_completed(futures):
                    if future.status == "error":
                        future.result()  # raises the task's exception here
                    bar.update(1)
        return client.gather(futures)  # in task order, whatever the completion order
    except BaseException:
        client.cancel(futures)
        raise


def _versions() -> dict[str, str]:
    import numpy

    import attend

    return {"attend": attend.__version__, "numpy": numpy.__version__}


def _check_worker_versions(client) -> None:
    """Warn when a worker runs another attend or numpy than this process (results may differ)."""
    here = _versions()
    try:
        workers = client.run(_versions)
    except Exception as error:  # e.g. attend not importable on a worker
        warnings.warn(f"could not check the workers' attend/numpy versions: {error}", RuntimeWarning,
                      stacklevel=3)
        return
    for address, theirs in workers.items():
        if theirs != here:
            warnings.warn(
                f"worker {address} runs {theirs}, this process {here}: results may differ from a local run",
                RuntimeWarning, stacklevel=3,
            )
