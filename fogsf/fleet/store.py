"""The fleet store: the units of one design, in an SQLite file or a PostgreSQL database.

    store = open_store("line.fleet")                 # SQLite, created on first use
    store = open_store("line.fleet", "read")         # must exist and be a fleet; read-only
    store = open_store("postgresql://host/fleet")    # a server several chambers share
    store.add(record)                                # one transaction
    store.units(); store.unit("SN042"); store.remove("SN042")

Every add and remove is one transaction: a process killed in the middle of one leaves the
database as it was before it (SQLite: write-ahead log; a second writer waits for the first,
BEGIN IMMEDIATE and a busy timeout). User strings (serial numbers, paths) reach SQL only as
parameters. The schema is versioned (table `schema_version`; `fleet.schema`): `MIGRATIONS[i]`
takes a database from version i to i + 1, run in order, in one transaction, when a store is
opened. Every add and remove also bumps the fleet's state (`schema.bump_state`, in its
transaction): what is cached from the units is keyed by it.
"""

from __future__ import annotations

import json
import sqlite3
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from fogsf.errors import UserError
from fogsf.fleet.faults import _db_errors, sqlite_begin_waiting
from fogsf.fleet.names import check_unit_name, masked, shown
from fogsf.fleet.records import LOG_COLUMNS, LogRecord, UnitRecord, structure_of
from fogsf.fleet.schema import MIGRATIONS, SCHEMA_VERSION, bump_state, keep

BUSY_TIMEOUT_S = 60.0
PG_PREFIXES = ("postgresql://", "postgres://")
# a cached result is written only if the fleet's lock is had within this (else it is not
# kept: the next command computes it again; a command never waits on its cache)
QUIET_WAIT_S = 2.0
MIGRATION_LOCK = 0x0F05F1EE7  # PostgreSQL advisory lock key of the fleet's migrations
# How a command opens a fleet: "read" (list, check, report, the prior: read-only, the fleet
# must exist), "write" (remove, recording a unit trained under the prior: must exist),
# "create" (add, add-many: a new fleet where nothing is, an existing fleet, nothing else).
MODES = ("read", "write", "create")
Guard = Callable[["FleetStore"], None]  # last in an add's transaction; raises to refuse


def _dumps(x: Any) -> str:
    return json.dumps(x, sort_keys=True, allow_nan=True)


class FleetStore:
    """A fleet's database (subclasses: SQLite, PostgreSQL). SQL is written with `?`
    placeholders; values only ever as parameters."""

    location: str
    now_sql: str  # the database's clock in SQL, seconds since 1970 (leases' heartbeats)

    def execute(self, sql: str, params: tuple = ()) -> Any:
        raise NotImplementedError

    def _begin(self) -> None:
        raise NotImplementedError

    def close(self) -> None:
        raise NotImplementedError

    def __enter__(self) -> FleetStore:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    @contextmanager
    def transaction(self) -> Iterator[None]:
        """One write transaction: COMMIT at the end, ROLLBACK on any error."""
        self._begin()
        try:
            yield
        except BaseException:
            self.execute("ROLLBACK")
            raise
        self.execute("COMMIT")

    @contextmanager
    def snapshot(self) -> Iterator[None]:
        """Reads that see one state of the fleet (its state counter, its units and what is
        cached for them), whatever commits meanwhile."""
        self.execute(self.snapshot_sql)
        try:
            yield
        finally:
            self.execute("COMMIT")

    snapshot_sql = "BEGIN"

    def _begin_quietly(self) -> None:
        """BEGIN for a write that may be skipped: a lock held 2 s refuses it (raises)."""
        raise NotImplementedError

    # --- schema ----------------------------------------------------------------------------

    def _lock_version(self) -> None:
        """First in a migration's transaction: hold off other migrations (SQLite's BEGIN
        IMMEDIATE does)."""

    def _current_version(self) -> int | None:
        """The schema version, read without a transaction (None: no schema_version yet)."""
        return self.schema_version() if self._table_exists("schema_version") else None

    def _table_exists(self, name: str) -> bool:
        raise NotImplementedError

    def schema_version(self) -> int:
        rows = self.execute("SELECT version FROM schema_version").fetchall()
        return int(rows[0][0]) if rows else 0

    def migrate(self, upto: int = SCHEMA_VERSION) -> None:
        """Bring the schema forward to version `upto`, one migration after another, in one
        transaction; refuse a database a newer fogsf wrote."""
        now = self._current_version()
        if now == upto:  # nothing to do: no write lock taken
            return
        if now is not None and now > SCHEMA_VERSION:  # refused before any write
            raise UserError(f"{self.location}: fleet schema version {now} is newer than "
                            f"this fogsf's ({SCHEMA_VERSION}): upgrade fogsf")
        with self.transaction():
            self._lock_version()
            self.execute("CREATE TABLE IF NOT EXISTS schema_version (version INTEGER NOT NULL)")
            have = self.schema_version()
            if have == 0 and now is not None and self._table_exists("units"):
                raise UserError(f"{self.location}: the fleet's schema_version row is "
                                "missing (a damaged fleet: restore it from a backup)")
            if have > SCHEMA_VERSION:
                raise UserError(f"{self.location}: fleet schema version {have} is newer than "
                                f"this fogsf's ({SCHEMA_VERSION}): upgrade fogsf")
            if have == 0:
                self.execute("INSERT INTO schema_version (version) VALUES (0)")
            for v in range(have, upto):
                MIGRATIONS[v](self)
                self.execute("UPDATE schema_version SET version = ?", (v + 1,))

    # --- units -----------------------------------------------------------------------------

    def has(self, sn: str) -> bool:
        return bool(self.execute("SELECT 1 FROM units WHERE sn = ?", (sn,)).fetchall())

    def add(self, record: UnitRecord, replace: bool = False, guard: Guard | None = None) -> None:
        """Record a unit (one transaction); a unit of that serial number already there is
        refused, or replaced when `replace`; `guard(self)` runs last before COMMIT and
        refuses the unit by raising (a batch's lease, `fleet.lease.check_batch`)."""
        check_unit_name(record.unit)  # the last guard: no command records a bad name
        with self.transaction():
            if self.has(record.unit):
                if not replace:
                    raise UserError(f"unit {shown(record.unit)} is already in {self.location} "
                                    "(--replace to record it again, or `fogsf fleet remove`)")
                self._delete(record.unit)
            self.execute(
                "INSERT INTO units (sn, model_id, model_dir, fitted_with, figures, "
                "interval_json, summary, fogsf_version, created_utc, structure) "
                "VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
                (record.unit, record.model_id, record.model_dir, _dumps(record.fitted_with),
                 _dumps(record.figures),
                 None if record.interval is None else _dumps(record.interval),
                 _dumps(record.summary), record.fogsf_version, record.created_utc,
                 structure_of(record)))
            for i, lg in enumerate(record.logs):
                self.execute(
                    f"INSERT INTO logs (sn, idx, {LOG_COLUMNS}) "
                    "VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)", (record.unit, i, *lg.row()))
            bump_state(self)
            if guard is not None:  # last: a batch killed while the unit was written refuses it
                guard(self)

    def _delete(self, sn: str) -> None:
        self.execute("DELETE FROM logs WHERE sn = ?", (sn,))
        self.execute("DELETE FROM units WHERE sn = ?", (sn,))

    def remove(self, sn: str) -> None:
        """Remove a unit and its logs (one transaction)."""
        check_unit_name(sn)  # a name no command may record is named in no lookup either
        with self.transaction():
            if not self.has(sn):
                raise UserError(f"no unit {shown(sn)} in {self.location}")
            self._delete(sn)
            bump_state(self)

    def unit(self, sn: str) -> UnitRecord:
        found = self._read("WHERE sn = ?", (sn,))
        if not found:
            raise UserError(f"no unit {shown(sn)} in {self.location}")
        return found[0]

    def units(self) -> list[UnitRecord]:
        """Every unit, by serial number."""
        return self._read("", ())

    def _read(self, where: str, params: tuple) -> list[UnitRecord]:
        rows = self.execute(
            "SELECT sn, model_id, model_dir, fitted_with, figures, interval_json, summary, "
            f"fogsf_version, created_utc FROM units {where}", params).fetchall()
        rows = sorted(rows, key=lambda r: r[0])  # by code point, whatever the collation
        logs: dict[str, list[LogRecord]] = {r[0]: [] for r in rows}
        for lg in self.execute(f"SELECT sn, {LOG_COLUMNS} FROM logs ORDER BY idx").fetchall():
            if lg[0] in logs:
                logs[lg[0]].append(LogRecord.from_row(lg[1:]))
        return [UnitRecord(unit=r[0], logs=logs[r[0]], model_id=r[1], model_dir=r[2],
                           fitted_with=json.loads(r[3]), figures=json.loads(r[4]),
                           interval=None if r[5] is None else json.loads(r[5]),
                           summary=json.loads(r[6]), fogsf_version=r[7], created_utc=r[8])
                for r in rows]


def _check_file(p: Path, mode: str) -> None:
    """Refuse what is no fleet file before anything opens it: a folder, a missing file for
    a read or write (a typo says so), a missing folder."""
    if p.exists() and not p.is_file():
        raise UserError(f"fleet {p} is not a file (give an SQLite file or a "
                        "postgresql:// URL)")
    if mode != "create" and not p.exists():  # a read never creates
        raise UserError(f"{p}: no such fleet database (`fogsf fleet add` creates one)")
    if not p.parent.is_dir():
        raise UserError(f"fleet {p}: folder {p.parent} does not exist")


class SQLiteStore(FleetStore):
    """A fleet in one SQLite file (write-ahead log, writers queue on a busy timeout)."""
    now_sql = "((julianday('now') - 2440587.5) * 86400.0)"

    def __init__(self, path: str | Path, mode: str = "create") -> None:
        p = Path(path)
        self.location = str(p)
        _check_file(p, mode)
        # SQLite's own open modes: ro cannot write, rw cannot create, rwc may create.
        uri = f"{p.resolve().as_uri()}?mode={dict(read='ro', write='rw').get(mode, 'rwc')}"
        try:
            self.db = sqlite3.connect(uri, uri=True, timeout=BUSY_TIMEOUT_S,
                                      isolation_level=None)
            tables = {r[0] for r in self.db.execute(
                "SELECT name FROM sqlite_master WHERE type = 'table'").fetchall()}
        except sqlite3.DatabaseError as e:
            raise UserError(f"fleet {p} is not a fleet database (SQLite: {e})") from None
        # A file another program wrote is never written into: only an empty file or a fleet.
        if "schema_version" not in tables and (tables or mode != "create"):
            self.db.close()
            raise UserError(f"{p} is not a fleet database (an SQLite file without the "
                            "fleet's tables)" + ("" if mode != "create" else
                                                 ": give a new file"))
        if mode != "read":
            self.db.execute("PRAGMA journal_mode=WAL")
        self.db.execute("PRAGMA foreign_keys=ON")
        self.db.execute(f"PRAGMA busy_timeout={int(BUSY_TIMEOUT_S * 1000)}")

    def execute(self, sql: str, params: tuple = ()) -> Any:
        return self.db.execute(sql, params)

    def _table_exists(self, name: str) -> bool:
        return bool(self.execute("SELECT 1 FROM sqlite_master WHERE type = 'table' AND "
                                 "name = ?", (name,)).fetchall())

    def _begin(self) -> None:  # the write lock now (no upgrade deadlock later), waits said
        sqlite_begin_waiting(self.db, self.location, BUSY_TIMEOUT_S)

    def _begin_quietly(self) -> None:
        self.db.execute(f"PRAGMA busy_timeout={int(QUIET_WAIT_S * 1000)}")
        self.db.execute("BEGIN IMMEDIATE")

    def close(self) -> None:
        self.db.close()


class PostgresStore(FleetStore):
    """A fleet in a PostgreSQL database (psycopg 3), for several chambers at once."""
    now_sql = "CAST(EXTRACT(EPOCH FROM clock_timestamp()) AS DOUBLE PRECISION)"

    def __init__(self, url: str, mode: str = "create") -> None:
        try:
            import psycopg
        except ImportError:
            raise UserError("a postgresql:// fleet needs psycopg: pip install 'psycopg[binary]'"
                            ) from None
        self.location = masked(url)
        try:
            self.db = psycopg.connect(url, autocommit=True, connect_timeout=20)
        except psycopg.OperationalError as e:
            first = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
            raise UserError(f"cannot connect to fleet {self.location}: {first}") from None
        if mode != "create" and self._current_version() is None:
            self.db.close()
            raise UserError(f"{self.location} holds no fleet (`fogsf fleet add` creates one)")

    def read_only(self) -> None:
        """Every later transaction of this session read-only (the server refuses writes)."""
        self.db.execute("SET SESSION CHARACTERISTICS AS TRANSACTION READ ONLY")

    def execute(self, sql: str, params: tuple = ()) -> Any:
        return self.db.execute(sql.replace("?", "%s"), params)

    def _begin(self) -> None:
        self.db.execute("BEGIN")

    snapshot_sql = "BEGIN ISOLATION LEVEL REPEATABLE READ"

    def _begin_quietly(self) -> None:
        self.db.execute("BEGIN")
        self.db.execute(f"SET LOCAL lock_timeout = '{int(QUIET_WAIT_S * 1000)}ms'")

    def _lock_version(self) -> None:  # one migration at a time, even before the table exists
        self.db.execute("SELECT pg_advisory_xact_lock(%s)", (MIGRATION_LOCK,))

    def _table_exists(self, name: str) -> bool:
        return self.execute("SELECT to_regclass(?)", (name,)).fetchall()[0][0] is not None

    def add(self, record: UnitRecord, replace: bool = False, guard: Guard | None = None) -> None:
        import psycopg

        try:
            super().add(record, replace, guard)
        except psycopg.IntegrityError:  # another add of that unit committed first
            raise UserError(f"unit {shown(record.unit)} was added to {self.location} by another "
                            "process meanwhile (--replace to record it again)") from None

    def has(self, sn: str) -> bool:  # a unit's row locked until the transaction ends
        return bool(self.execute("SELECT 1 FROM units WHERE sn = ? FOR UPDATE",
                                 (sn,)).fetchall())

    def close(self) -> None:
        self.db.close()


def open_store(url_or_path: str, mode: str = "create") -> FleetStore:
    """The fleet at `url_or_path`: an SQLite file or a postgresql:// URL, opened as `mode`
    says (MODES); its schema brought to the current version (a read of an older fleet
    migrates it first, through a connection that may write)."""
    if mode not in MODES:
        raise ValueError(f"mode {mode!r} not in {MODES}")
    text = str(url_or_path)

    def connect(m: str) -> FleetStore:
        return PostgresStore(text, m) if text.startswith(PG_PREFIXES) else SQLiteStore(text, m)

    store = connect(mode)
    try:
        if mode == "read" and (store._current_version() or 0) < SCHEMA_VERSION:
            store.close()
            store = connect("write")
        store.migrate()
        if mode == "read" and isinstance(store, PostgresStore):
            store.read_only()
    except BaseException:
        store.close()
        raise
    return store


def fleet_exists(url_or_path: str) -> bool:
    """Whether a fleet (or another program's database) is at `url_or_path`, nothing created:
    `add` checks its unit against an existing fleet before training and creates a fleet only
    to record a unit, so a refused add leaves no empty fleet. A missing folder or a folder
    given for the file is refused here, before any training."""
    text = str(url_or_path)
    if text.startswith(PG_PREFIXES):
        store = PostgresStore(text, "create")  # connects only: creation is migrate's
        try:
            return store._current_version() is not None
        finally:
            store.close()
    p = Path(text)
    _check_file(p, "create")
    if not p.exists() or p.stat().st_size == 0:
        return False
    try:  # an SQLite file without tables is as empty as an empty file
        db = sqlite3.connect(f"{p.resolve().as_uri()}?mode=ro", uri=True)
        try:
            return bool(db.execute("SELECT 1 FROM sqlite_master").fetchall())
        finally:
            db.close()
    except sqlite3.DatabaseError:  # not SQLite: open_store refuses it in its words
        return True


def keep_quietly(url_or_path: str, kind: str, key: str, state: int, value: str) -> bool:
    """Keep a result computed from the fleet at `state` in its cache (`schema.keep`), in one
    transaction of a connection of its own (the command read the fleet read-only). A fleet
    that cannot be written now (a read-only file or role, a lock held past QUIET_WAIT_S, a
    fault) keeps nothing and says nothing: the cache only saves time. True when kept."""
    try:
        with open_store(url_or_path, "write") as store:
            store._begin_quietly()
            try:
                keep(store, kind, key, state, value)
            except BaseException:
                store.execute("ROLLBACK")
                raise
            store.execute("COMMIT")
        return True
    except (UserError, *_db_errors()):  # type: ignore[misc]  # a tuple of classes
        return False
