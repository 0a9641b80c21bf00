"""GSA fitness evaluations through executors: inline, local processes, a Dask cluster.

The same seed must give the same run whichever executor evaluated the agents.
"""

from __future__ import annotations

import os
from functools import partial

import pytest

from fogsf.errors import UserError
from fogsf.gsa.executors import dask_executor, default_workers, open_executor
from fogsf.gsa.optimizer import Param, minimize
from fogsf.gsa.testfunctions import shifted_sphere

SPACE = [Param("a", -2, 2), Param("n", 1, 30, "int"), Param("lr", 1e-4, 1e-1, "log-real")]
FITNESS = partial(shifted_sphere, target={"a": 0.7, "n": 11, "lr": 0.02})
SEED = 424242


def _run(executor, **kw):
    return minimize(FITNESS, SPACE, n_agents=10, n_iters=12, seed=SEED, executor=executor,
                    progress=False, **kw)


@pytest.fixture(scope="module")
def inline():
    return _run(None)


def _same(a, b) -> None:
    assert a.best_params == b.best_params
    assert a.best_fitness == b.best_fitness
    assert a.best_curve == b.best_curve and a.mean_curve == b.mean_curve
    assert a.n_evals == b.n_evals


def test_inline_run_finds_the_target(inline) -> None:
    assert inline.best_params["n"] == 11
    assert inline.best_fitness < inline.best_curve[0]


def test_local_processes_give_the_inline_result(inline) -> None:
    with open_executor(workers=2) as ex:
        assert ex is not None
        res = _run(ex)
    assert res.settings["executor"] == "ProcessPoolExecutor"
    _same(res, inline)


def test_default_executor_opens_local_processes(inline) -> None:
    res = _run("local", n_workers=2)
    assert res.settings["executor"] == "ProcessPoolExecutor"
    _same(res, inline)
    assert _run("local", n_workers=1).settings["executor"] == "inline"


def test_dask_local_cluster_gives_the_inline_result(inline) -> None:
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False,
                                  dashboard_address=None) as cluster:
        with dask_executor(cluster.scheduler_address) as ex:   # what --dask ADDRESS does
            res = _run(ex)
        assert res.settings["executor"] == "ClientExecutor"
        _same(res, inline)
        with open_executor(workers=1, dask=cluster.scheduler_address) as ex:
            assert type(ex).__name__ == "ClientExecutor"        # --dask wins over --workers


def test_fitness_errors_reach_the_caller() -> None:
    with open_executor(workers=2) as ex, pytest.raises(ZeroDivisionError):
        minimize(_boom, SPACE, n_agents=4, n_iters=2, seed=1, executor=ex, progress=False)


def _boom(params: dict) -> float:
    return 1.0 / 0.0


def test_unpicklable_fitness_is_refused_before_any_work() -> None:
    with open_executor(workers=2) as ex, pytest.raises(TypeError, match="not picklable"):
        minimize(lambda p: 0.0, SPACE, n_agents=4, n_iters=2, seed=1, executor=ex,
                 progress=False)


@pytest.mark.slow
def test_unreachable_scheduler_is_a_clear_user_error() -> None:
    with pytest.raises(UserError, match="cannot reach the Dask scheduler"):
        with dask_executor("tcp://127.0.0.1:9", timeout_s=1.0):
            pass


def test_workers_below_one_refused() -> None:
    with pytest.raises(UserError, match="at least 1"):
        with open_executor(workers=0):
            pass


def _threads(_: object) -> str:
    return os.environ.get("OMP_NUM_THREADS", "")


def test_local_workers_share_the_cores() -> None:
    with open_executor(workers=2) as ex:
        got = set(ex.map(_threads, range(4)))
    assert got == {str(max(1, default_workers() // 2))}
