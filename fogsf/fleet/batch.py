"""add-many's local workers: each unit a `fogsf fleet add` child process that dies with
its batch.

    run_local(argvs, workers, done)   # the batch: at most `workers` children at once
    watch_parent()                    # in a child: exit as soon as the batch is gone

A child dies with the batch's process however that ends (SIGKILL included): its stdin is a
pipe only the batch holds, so it reads EOF the moment the batch is gone; Linux also sends
it SIGTERM then (PR_SET_PDEATHSIG), and the parent's pid is checked twice a second besides.
A child that outlives the batch for a moment still records nothing: its unit's transaction
checks the batch's lease (`fleet.lease`).
"""

from __future__ import annotations

import ctypes
import io
import os
import select
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Sequence
from typing import cast

from fogsf.scratch import remove_process_dir

PARENT_ENV = "FOGSF_BATCH_PARENT"  # set for a child: the batch's pid
STOP_WAIT_S = 5.0  # children told to stop get this long, then SIGKILL
PR_SET_PDEATHSIG = 1


def _die(*_: object) -> None:
    """The batch is gone: this child's temporary folder removed, the process ended now
    (os._exit: no training, no transaction of it is finished)."""
    remove_process_dir()
    os._exit(128 + signal.SIGTERM)


def _parent_death_signal() -> None:
    """Linux: SIGTERM to this process when its parent ends."""
    if not sys.platform.startswith("linux"):
        return
    try:
        ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, int(signal.SIGTERM), 0, 0, 0)
    except (OSError, AttributeError):  # no prctl: the pipe and the pid check remain
        pass


def watch_parent() -> None:
    """In a child of `run_local`: end this process when the batch ends. Does nothing in
    a process the batch did not start (a Dask worker: the lease alone guards it)."""
    parent = os.environ.pop(PARENT_ENV, None)  # not inherited by this process's children
    if not parent or not parent.isdigit():
        return
    signal.signal(signal.SIGTERM, _die)
    _parent_death_signal()
    if os.getppid() != int(parent):  # gone before the signal was asked for
        _die()

    def watch() -> None:
        fd = sys.stdin.fileno()
        while True:
            ready, _, _ = select.select([fd], [], [], 0.5)
            if os.getppid() != int(parent) or (ready and not os.read(fd, 1)):
                _die()  # the parent changed, or the pipe closed: the batch is gone

    threading.Thread(target=watch, name="fogsf-batch-parent", daemon=True).start()


def _child_env(workers: int) -> dict[str, str]:
    """A child's environment: the batch's pid, and the cores shared between the children
    (N children each with one thread a core would oversubscribe them)."""
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        cores = os.cpu_count() or 1
    threads = str(max(1, cores // workers))
    env = dict(os.environ, **{PARENT_ENV: str(os.getpid())})
    env.update(OMP_NUM_THREADS=threads, MKL_NUM_THREADS=threads, OPENBLAS_NUM_THREADS=threads)
    return env


class _Child:
    """One running unit: its process and what it printed (read by a thread, so that a
    child never blocks on a full pipe)."""

    def __init__(self, index: int, argv: Sequence[str], env: dict[str, str]) -> None:
        self.index = index
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "fogsf", "fleet", "add", *argv], env=env,
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
        self.chunks: list[bytes] = []
        self.reader = threading.Thread(target=self._read, daemon=True)
        self.reader.start()

    def _read(self) -> None:
        out = cast(io.BufferedReader, self.proc.stdout)  # Popen's pipe: read1 is there
        assert out is not None
        for chunk in iter(lambda: out.read1(65536), b""):
            self.chunks.append(chunk)

    def output(self) -> str:
        self.reader.join()
        return b"".join(self.chunks).decode("utf-8", "replace")


def run_local(argvs: Sequence[Sequence[str]], workers: int,
              done: Callable[[int, int, str], None]) -> None:
    """`fogsf fleet add ARGV` for every ARGV in `argvs`, `workers` at once, each in a child
    process started from this (the main) thread, as PR_SET_PDEATHSIG ties a child to the
    thread that started it; `done(index, exit status, output)` as each ends. However this
    ends (an error, Ctrl-C), the children still running are stopped before it returns."""
    env = _child_env(workers)
    todo = list(range(len(argvs)))
    running: list[_Child] = []
    try:
        while todo or running:
            while todo and len(running) < workers:
                i = todo.pop(0)
                running.append(_Child(i, argvs[i], env))
            for c in [c for c in running if c.proc.poll() is not None]:
                running.remove(c)
                done(c.index, c.proc.returncode, c.output())
            time.sleep(0.05)
    finally:
        _stop(running)


def _stop(children: list[_Child]) -> None:
    """Tell the children the batch is gone (their pipe closed), then SIGKILL the ones
    left after STOP_WAIT_S."""
    for c in children:
        if c.proc.stdin is not None:
            c.proc.stdin.close()
    t_end = time.monotonic() + STOP_WAIT_S
    for c in children:
        try:
            c.proc.wait(max(0.0, t_end - time.monotonic()))
        except subprocess.TimeoutExpired:
            c.proc.kill()
            c.proc.wait()
