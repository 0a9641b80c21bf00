"""The folder `fogsf fleet report --out DIR` owns, and its atomic replacement.

DIR is written only when it does not exist, is empty, or holds a report fogsf wrote: the
marker file MARKER lists every file of that report, and DIR must hold nothing else (a
user's file put inside would be lost otherwise). Anything else (the database's folder, a
models folder) is refused and left untouched. The new report is written into a fresh
sibling folder, swapped in by two renames, and the old report removed file by file from
its own list: never a tree deleted by name.
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from collections.abc import Callable
from pathlib import Path

from fogsf.errors import UserError

MARKER = ".fogsf-report"


def _files(folder: Path) -> set[str]:
    """Every entry under `folder`, as paths relative to it (folders end with /)."""
    out: set[str] = set()
    for root, dirs, files in os.walk(folder):
        rel = Path(root).relative_to(folder)
        out.update(f"{(rel / d).as_posix()}/" for d in dirs)
        out.update((rel / f).as_posix() for f in files)
    return out


def _own_listing(out: Path) -> set[str] | None:
    """What the report in `out` wrote, from its marker; None when `out` is not a report
    fogsf wrote (no marker, or a marker that is not ours)."""
    try:
        listed = json.loads((out / MARKER).read_text(encoding="utf-8"))["files"]
    except (OSError, ValueError, KeyError, TypeError):
        return None
    return {str(f) for f in listed} if isinstance(listed, list) else None


def check_out_dir(out: Path) -> None:
    """Refuse `out` unless the report may write there (see the module's rule)."""
    if out.is_symlink() or (out.exists() and not out.is_dir()):
        raise UserError(f"--out {out} exists and is not a folder")
    if not out.exists():
        return
    have = _files(out)
    if not have:
        return
    own = _own_listing(out)
    if own is None:
        raise UserError(f"--out {out} is a folder the report did not write ({len(have)} "
                        "entries, no {MARKER} file): nothing written; give a new or "
                        "empty folder")
    foreign = sorted(have - own - {MARKER})
    if foreign:
        raise UserError(f"--out {out} holds files the report did not write ({foreign[0]}"
                        + (f" and {len(foreign) - 1} more" if len(foreign) > 1 else "")
                        + "): nothing written; move them or give another folder")


def _remove_listed(folder: Path, listed: set[str]) -> None:
    """Remove the files `listed` and then the emptied folders; anything else stays (and
    so does its folder)."""
    for rel in sorted(listed, key=len, reverse=True):  # files and subfolders before parents
        target = folder / rel
        try:
            target.rmdir() if rel.endswith("/") else target.unlink()
        except OSError:
            pass
    try:
        folder.rmdir()
    except OSError:
        pass


def write_owned(out: Path, write: Callable[[Path], None]) -> None:
    """`write(tmp)` fills a fresh folder beside `out`, which then replaces `out` whole
    (check_out_dir first: the swap assumes `out` is ours, empty or absent)."""
    check_out_dir(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(dir=out.parent, prefix=f".{out.name}.tmp-"))
    try:
        write(tmp)
        listing = sorted(_files(tmp))
        (tmp / MARKER).write_text(json.dumps({"fogsf_report": 1, "files": listing}, indent=1)
                                  + "\n", encoding="utf-8")
        os.chmod(tmp, 0o755)  # mkdtemp's 0700 would hide the report from the line
        check_out_dir(out)  # again: nothing may have moved in while the plots were drawn
        if out.exists() and _files(out):
            old = Path(tempfile.mkdtemp(dir=out.parent, prefix=f".{out.name}.old-"))
            os.replace(out, old)  # onto the empty folder mkdtemp made: ours alone
            os.replace(tmp, out)
            _remove_listed(old, (_own_listing(old) or set()) | {MARKER})
        else:
            os.replace(tmp, out)  # rename onto an empty folder or none
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)  # the folder mkdtemp made for this run
        raise
