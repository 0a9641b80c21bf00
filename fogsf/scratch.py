"""Temporary folders: one folder a process, $TMPDIR/fogsf-<pid>-<start time>/, everything
temporary of that process inside it (the only way fogsf makes a temporary folder).

    path = process_dir()                    # created on first use, removed at exit
    with temp_dir("fleet-") as tmp: ...     # a folder inside it, removed after the block
    claim_tempdir()                         # the `fogsf` command: every tempfile call and
                                            # every child process's TMPDIR inside it too
    sweep()                                 # remove the folders of processes that are gone

A process killed with SIGKILL cannot remove its folder: the next fogsf command does
(`sweep`), when the folder's owner is gone. The owner is named by its pid and its start
time, so a pid the system gave to a new process since is not taken for the owner.
"""

from __future__ import annotations

import atexit
import os
import re
import shutil
import sys
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

PREFIX = "fogsf-"
OWNED = re.compile(r"^fogsf-(\d+)-(\d+)$")  # fogsf-<pid>-<start time>
_dir: Path | None = None
_base: Path | None = None  # where process folders are made (TMPDIR before claim_tempdir)


def start_time(pid: int) -> str | None:
    """A token of process `pid`'s start (Linux: clock ticks since boot, /proc/PID/stat);
    None when no such process runs (a zombie is gone). Elsewhere "0" for any live pid:
    a reused pid is then taken for its old owner (a folder kept, never one lost)."""
    try:
        text = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        if sys.platform.startswith("linux"):
            return None
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return None
        except OSError:  # another user's process: alive
            pass
        return "0"
    fields = text[text.rindex(")") + 2:].split()  # the name may hold spaces and ')'
    return None if fields[0] in ("Z", "X") else fields[19]


def alive(pid: int, start: str) -> bool:
    """Whether the process `pid` that started at `start` (`start_time`) still runs."""
    return start_time(pid) == start


def base_dir() -> Path:
    """The system's temporary folder as this process found it."""
    global _base
    if _base is None:
        _base = Path(tempfile.gettempdir())
    return _base


def process_dir() -> Path:
    """This process's folder (created on first use; removed at exit, normal or not
    by a signal Python handles)."""
    global _dir
    if _dir is None or not _dir.is_dir():
        path = base_dir() / f"{PREFIX}{os.getpid()}-{start_time(os.getpid())}"
        path.mkdir(mode=0o700, exist_ok=True)
        if _dir is None:
            atexit.register(remove_process_dir)
        _dir = path
    return _dir


def remove_process_dir() -> None:
    """Remove this process's folder now (at exit; a worker told its batch is gone)."""
    if _dir is not None and _dir.name == f"{PREFIX}{os.getpid()}-{start_time(os.getpid())}":
        shutil.rmtree(_dir, ignore_errors=True)  # a forked child shares _dir: never its own


@contextmanager
def temp_dir(prefix: str) -> Iterator[Path]:
    """A fresh folder inside this process's folder, removed after the block."""
    with tempfile.TemporaryDirectory(prefix=prefix, dir=process_dir()) as tmp:
        yield Path(tmp)


def claim_tempdir() -> Path:
    """Route every temporary file of this process and of its children here: libraries'
    tempfile calls (tempfile.tempdir) and child processes (TMPDIR, so their own process
    folders nest inside this one and go with it)."""
    path = process_dir()
    tempfile.tempdir = str(path)
    os.environ["TMPDIR"] = str(path)
    return path


def sweep(base: Path | None = None) -> list[Path]:
    """Remove the process folders in `base` (default: the system's temporary folder) whose
    owner is gone; folders of live processes, of other users and not named by an owner
    are left alone. Returns what was removed."""
    base = base_dir() if base is None else base
    gone: list[Path] = []
    try:
        entries = list(os.scandir(base))
    except OSError:
        return gone
    for e in entries:
        m = OWNED.match(e.name)
        try:
            mine = e.is_dir(follow_symlinks=False) and e.stat(
                follow_symlinks=False).st_uid == os.getuid()
        except OSError:
            continue
        if m and mine and not alive(int(m.group(1)), m.group(2)):
            shutil.rmtree(e.path, ignore_errors=True)
            gone.append(Path(e.path))
    return gone
