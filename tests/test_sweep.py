"""attend.sweep: tasks run here or on a real Dask cluster give the same results, in task order.

The cluster tests start a ``distributed.LocalCluster`` with 2 worker *processes* (one thread
each), so tasks and results really cross a process boundary (pickling, a fresh interpreter
with OMP_NUM_THREADS=1 set by the Dask nanny) and reach the scheduler by its "tcp://" address,
as on a remote cluster.
"""

from __future__ import annotations

import sys
import time

import numpy as np
import pytest

from attend import AttendInputError
from attend.experiments import fig4, fig5
from attend.sweep import chunk_slices, run_tasks

SMALL = dict(n_seeds=3, n_prior_precisions=4)  # a fig4-like sweep: 12 runs


def _square_plus(task):
    return task["x"] ** 2 + task["offset"]


# ---- local runs ---------------------------------------------------------------------------


def test_run_tasks_local_keeps_task_order():
    tasks = [dict(x=x, offset=k) for k, x in enumerate([5, -1, 3, 0, 2])]
    assert run_tasks(_square_plus, tasks, progress=False) == [25, 2, 11, 3, 8]
    assert run_tasks(_square_plus, iter(tasks), progress=True, desc="test") == [25, 2, 11, 3, 8]
    assert run_tasks(_square_plus, [], progress=False) == []


@pytest.mark.parametrize("n_runs, per_task", [(0, 4), (1, 4), (2, 1), (3, 1), (7, 3), (12, 4), (156, 64), (1250, 64)])
def test_chunk_slices_cover_the_runs_in_order_with_at_least_two_per_chunk(n_runs, per_task):
    slices = chunk_slices(n_runs, per_task)
    covered = [i for s in slices for i in range(n_runs)[s]]
    assert covered == list(range(n_runs))
    sizes = [s.stop - s.start for s in slices]
    if n_runs >= 2:
        assert min(sizes) >= 2
    assert max(sizes, default=0) <= max(per_task, 3 if n_runs >= 2 else 1)


def test_bad_arguments_name_the_field():
    with pytest.raises(AttendInputError, match="cluster"):
        run_tasks(_square_plus, [dict(x=1, offset=0)], cluster="localhost:8786", progress=False)
    with pytest.raises(AttendInputError, match="cluster"):
        run_tasks(_square_plus, [dict(x=1, offset=0)], cluster=8786, progress=False)
    with pytest.raises(AttendInputError, match="function"):
        run_tasks(None, [dict(x=1, offset=0)], progress=False)
    with pytest.raises(AttendInputError, match="runs_per_task"):
        chunk_slices(10, 0)


def test_missing_dask_says_how_to_install(monkeypatch):
    monkeypatch.setitem(sys.modules, "distributed", None)  # import distributed -> ImportError
    with pytest.raises(AttendInputError, match=r"pip install \"dask\[distributed\]\""):
        run_tasks(_square_plus, [dict(x=1, offset=0)], cluster="tcp://127.0.0.1:8786", progress=False)


def test_fig4_numbers_do_not_depend_on_how_the_sweep_is_cut():
    """One batched call over all runs (the pre-sweep fig4) == chunks of 2..5 runs."""
    whole = fig4.run(progress=False, runs_per_task=1000, **SMALL)
    chunked = fig4.run(progress=False, runs_per_task=4, **SMALL)
    assert np.array_equal(whole.data["sse"], chunked.data["sse"])
    assert [m.value for m in whole.metrics] == [m.value for m in chunked.metrics]


# ---- a real Dask cluster ----------------------------------------------------------------------


@pytest.fixture(scope="module")
def cluster():
    distributed = pytest.importorskip("distributed", reason="dask.distributed is not installed")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as local_cluster:
        yield local_cluster


def test_fig4_sweep_on_the_cluster_equals_the_local_run(cluster):
    local = fig4.run(progress=False, runs_per_task=4, **SMALL)
    remote = fig4.run(progress=True, runs_per_task=4, cluster=cluster.scheduler_address, **SMALL)
    assert np.array_equal(local.data["sse"], remote.data["sse"])
    assert np.array_equal(local.data["prior_sse"], remote.data["prior_sse"])
    assert [m.value for m in local.metrics] == [m.value for m in remote.metrics]


def test_fig5_tasks_on_a_client_equal_the_local_run(cluster):
    distributed = pytest.importorskip("distributed")
    kwargs = dict(progress=False, n_seeds=2, n_noise_levels=3, runs_per_task=4)
    local = fig5.run(**kwargs)
    with distributed.Client(cluster) as client:
        remote = fig5.run(cluster=client, **kwargs)
    assert np.array_equal(local.data["sse"], remote.data["sse"])
    assert np.array_equal(local.data["lambda_z"], remote.data["lambda_z"])


def test_cluster_results_come_back_in_task_order(cluster):
    def slow_identity(task):  # a local function: pickled by value, no test module on the workers
        time.sleep(task["delay"])
        return task["index"]

    # the first tasks finish last
    tasks = [dict(index=i, delay=0.05 * (5 - i)) for i in range(6)]
    assert run_tasks(slow_identity, tasks, cluster=cluster.scheduler_address, progress=True) == list(range(6))
    assert run_tasks(slow_identity, tasks, progress=False) == list(range(6))


def test_a_failing_task_raises_on_the_client(cluster):
    def fail_on_three(task):
        if task == 3:
            raise ValueError("task 3 failed")
        return task

    with pytest.raises(ValueError, match="task 3 failed"):
        run_tasks(fail_on_three, range(5), cluster=cluster.scheduler_address, progress=True)
    with pytest.raises(ValueError, match="task 3 failed"):
        run_tasks(fail_on_three, range(5), cluster=cluster.scheduler_address, progress=False)
