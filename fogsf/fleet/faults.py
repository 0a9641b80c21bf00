"""A fleet database's faults as one line and exit status 2, never a traceback.

Whatever SQLite or PostgreSQL raise (a lock held past the wait, a read-only file, a full
disk, corrupt pages, a dropped connection) reaches the user as "fleet LOCATION: what the
database said" (its first line: a server's detail and hints are not the user's business;
the location is the store's, its password masked)."""

from __future__ import annotations

import sqlite3
import sys
from collections.abc import Iterator
from contextlib import contextmanager

from fogsf.errors import UserError

SQLITE_BUSY_FIRST_S = 2.0  # a write lock is tried this long quietly, then the wait is said


def _db_errors() -> tuple[type[BaseException], ...]:
    """The exception classes of the database drivers at hand (psycopg only if loaded: a
    SQLite fleet must not import it)."""
    errors: list[type[BaseException]] = [sqlite3.Error]
    psycopg = sys.modules.get("psycopg")
    if psycopg is not None:
        errors.append(psycopg.Error)
    return tuple(errors)


def first_line(e: BaseException) -> str:
    text = str(e).strip()
    return text.splitlines()[0] if text else type(e).__name__


@contextmanager
def db_faults(location: str) -> Iterator[None]:
    """Turn a database driver's error raised inside into a UserError naming `location`."""
    try:
        yield
    except _db_errors() as e:
        hint = ""
        if isinstance(e, sqlite3.DatabaseError) and "malformed" in str(e):
            hint = " (the file is damaged: restore it from a backup)"
        raise UserError(f"fleet {location}: {first_line(e)}{hint}") from None


def sqlite_begin_waiting(db: sqlite3.Connection, location: str, wait_s: float) -> None:
    """BEGIN IMMEDIATE on `db`: tried quietly for SQLITE_BUSY_FIRST_S, then with a message
    on stderr up to `wait_s` in all (a chamber's operator sees why nothing happens), then a
    one-line refusal."""
    db.execute(f"PRAGMA busy_timeout={int(SQLITE_BUSY_FIRST_S * 1000)}")
    try:
        db.execute("BEGIN IMMEDIATE")
        return
    except sqlite3.OperationalError as e:
        if "locked" not in str(e) and "busy" not in str(e):
            raise
    print(f"fleet {location} is busy (another process is writing to it): waiting up to "
          f"{wait_s:.0f} s", file=sys.stderr, flush=True)
    db.execute(f"PRAGMA busy_timeout={int(max(wait_s - SQLITE_BUSY_FIRST_S, 0) * 1000)}")
    try:
        db.execute("BEGIN IMMEDIATE")
    except sqlite3.OperationalError as e:
        if "locked" not in str(e) and "busy" not in str(e):
            raise
        raise UserError(f"fleet {location} stayed locked by another process for "
                        f"{wait_s:.0f} s: nothing written; try again once it is done"
                        ) from None
