"""Where fitness evaluations run: inline, local worker processes, or a Dask cluster.

All three look like a `concurrent.futures.Executor` (``None`` means inline). Use

    with open_executor(workers=2) as ex:                       # local processes
    with open_executor(workers=1) as ex:                       # inline (ex is None)
    with open_executor(dask="tcp://10.0.0.5:8786") as ex:      # a running Dask scheduler

and pass ``ex`` to `fogsf.gsa.optimizer.minimize`. Commands add the matching options with
`add_executor_options(parser)` (``--workers N``, ``--dask SCHEDULER_ADDRESS``) and open the
executor with `executor_from_args(args)`.

Local worker processes get cores // workers threads each for OpenMP/MKL/torch, so that
N workers do not each start one thread per core. They start with the ``forkserver`` method
(``spawn`` where that does not exist): forking a parent that already runs torch's thread
pools can deadlock. Functions sent to workers must therefore be picklable: a module-level
function, or a `functools.partial` of one with picklable arguments.
"""

from __future__ import annotations

import argparse
import multiprocessing
import os
import sys
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import Executor, ProcessPoolExecutor
from contextlib import AbstractContextManager, contextmanager
from typing import Any, Protocol, TypeVar

from fogsf.errors import UserError

T = TypeVar("T")


def default_workers() -> int:
    """Worker processes used when the user does not say: one per available core."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not Linux
        return max(1, os.cpu_count() or 1)


def _mp_context() -> multiprocessing.context.BaseContext:
    methods = multiprocessing.get_all_start_methods()
    return multiprocessing.get_context("forkserver" if "forkserver" in methods else "spawn")


def _limit_threads(threads: int) -> None:
    """Worker start-up: share the cores between workers instead of oversubscribing them."""
    for var in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
        os.environ[var] = str(threads)
    if "torch" in sys.modules:              # already imported (preloaded): tell it directly
        sys.modules["torch"].set_num_threads(threads)


@contextmanager
def open_executor(workers: int | None = None, dask: str | None = None
                  ) -> Iterator[Executor | None]:
    """Yield an executor and shut it down afterwards.

    ``dask`` (a scheduler address such as ``tcp://host:8786``) wins over ``workers``;
    otherwise ``workers`` local processes (default: one per core), and ``workers=1`` gives
    ``None``: run inline, in this process, with no pickling.
    """
    if dask:
        with dask_executor(dask) as ex:
            yield ex
        return
    n = default_workers() if workers is None else int(workers)
    if n < 1:
        raise UserError(f"--workers must be at least 1, got {n}")
    if n == 1:
        yield None
        return
    threads = max(1, default_workers() // n)
    ex = ProcessPoolExecutor(max_workers=n, mp_context=_mp_context(),
                             initializer=_limit_threads, initargs=(threads,))
    try:
        yield ex
    finally:
        ex.shutdown(wait=True, cancel_futures=True)


@contextmanager
def dask_executor(address: str, timeout_s: float = 30.0) -> Iterator[Executor]:
    """A `concurrent.futures` executor on the Dask cluster whose scheduler is at ``address``.

    Tasks are submitted with ``pure=False``: each evaluation runs, none is merged with
    another by Dask's hashing (the optimizer removes true duplicates itself).
    """
    try:
        from distributed import Client
    except ImportError as e:  # pragma: no cover - dev extra missing
        raise UserError("--dask needs the 'distributed' package: pip install distributed") \
            from e
    try:
        client = Client(address, timeout=timeout_s)
    except (OSError, TimeoutError) as e:
        raise UserError(f"cannot reach the Dask scheduler at {address!r} within "
                        f"{timeout_s:g} s: {e}") from e
    try:
        yield client.get_executor(pure=False)
    finally:
        client.close()


def add_executor_options(parser: argparse.ArgumentParser, what: str = "fitness evaluations"
                         ) -> None:
    """Add ``--workers`` and ``--dask`` to a command's parser; `what` is what they run in
    parallel (train: GSA's fitness evaluations; plan: the candidate programs' fits)."""
    g = parser.add_argument_group(f"parallel work ({what})")
    g.add_argument("--workers", type=int, default=None, metavar="N",
                   help=f"local worker processes for {what} "
                        f"(default: one per core, here {default_workers()}; 1 = inline)")
    g.add_argument("--dask", default=None, metavar="SCHEDULER_ADDRESS",
                   help=f"run {what} on a Dask distributed cluster instead, "
                        "e.g. tcp://10.0.0.5:8786 (start one with `dask scheduler` and "
                        "`dask worker ADDRESS`); workers need fogsf installed")


class ExecutorOptions(Protocol):
    """The options `add_executor_options` adds (parsed), or any options that have both."""

    workers: int | None
    dask: str | None


def executor_from_args(opts: ExecutorOptions) -> AbstractContextManager[Executor | None]:
    """`open_executor` from the options `add_executor_options` added."""
    return open_executor(workers=getattr(opts, "workers", None),
                         dask=getattr(opts, "dask", None))


def run_all(ex: Executor | None, fn: Callable[..., T], items: Sequence[Any], *args: Any,
            desc: str = "", unit: str = "it", progress: bool = True) -> list[T]:
    """fn(item, *args) for every item, inline (ex None) or on `ex`, with a progress bar;
    results in the order of `items`."""
    from concurrent.futures import as_completed

    from tqdm import tqdm

    bar = tqdm(total=len(items), desc=desc, unit=unit, disable=not progress)
    try:
        if ex is None:
            out = []
            for it in items:
                out.append(fn(it, *args))
                bar.update()
            return out
        futs = {ex.submit(fn, it, *args): i for i, it in enumerate(items)}
        res: list[Any] = [None] * len(items)
        for f in as_completed(futs):
            res[futs[f]] = f.result()
            bar.update()
        return res
    finally:
        bar.close()
