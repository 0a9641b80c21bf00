"""The fleet database's schema and what it keeps beside the units: the fleet's state and the
results computed from it.

`MIGRATIONS[i]` takes a database from version i to i + 1 (`FleetStore.migrate` runs them in
order, in one transaction). Version 4 adds:
- `fleet_state`, one row: a counter every add and remove of a unit bumps in its own
  transaction, so a state names one set of units exactly (a unit recorded again with
  --replace is a new state, whatever its model id);
- `fleet_cache`: results computed from the units (`fleet check`'s, the design's prior) by
  kind and key, with the state they were computed at. A result is read only at that state,
  and written only while the fleet is still at it (`keep`), so no command reads a result
  of units other than the fleet's. One row a kind and key: a new state's result replaces
  the old one (the table does not grow with the fleet's history).
"""

from __future__ import annotations

import json
from collections.abc import Callable
from typing import Any, Protocol


class FleetStore(Protocol):
    """What the schema needs of a store (`fleet.store.FleetStore`): SQL with `?`."""

    def execute(self, sql: str, params: tuple = ...) -> Any: ...


def _v1(db: FleetStore) -> None:
    """Version 1: units (the record's JSON parts as text) and their training logs."""
    db.execute("""CREATE TABLE units (
        sn TEXT PRIMARY KEY,
        model_id TEXT NOT NULL,
        model_dir TEXT NOT NULL,
        fitted_with TEXT NOT NULL,
        figures TEXT NOT NULL,
        interval_json TEXT,
        summary TEXT NOT NULL,
        fogsf_version TEXT NOT NULL,
        created_utc TEXT NOT NULL)""")
    db.execute("""CREATE TABLE logs (
        sn TEXT NOT NULL REFERENCES units(sn) ON DELETE CASCADE,
        idx INTEGER NOT NULL,
        path TEXT NOT NULL,
        sha256 TEXT NOT NULL,
        n_rows BIGINT NOT NULL,
        span_s DOUBLE PRECISION NOT NULL,
        sample_rate_hz DOUBLE PRECISION NOT NULL,
        ramp_rates TEXT NOT NULL,
        temp_min_c DOUBLE PRECISION,
        temp_max_c DOUBLE PRECISION,
        PRIMARY KEY (sn, idx))""")


def _v2(db: FleetStore) -> None:
    """Version 2: a log's role (train or test: version 1 kept training logs only), and the
    unit's structure as a column of its own (for queries by structure), filled from the
    summary of the units version 1 wrote."""
    db.execute("ALTER TABLE logs ADD COLUMN role TEXT NOT NULL DEFAULT 'train'")
    db.execute("ALTER TABLE units ADD COLUMN structure TEXT NOT NULL DEFAULT ''")
    for sn, summary in db.execute("SELECT sn, summary FROM units").fetchall():
        db.execute("UPDATE units SET structure = ? WHERE sn = ?",
                   (_structure_of(json.loads(summary)), sn))
    db.execute("CREATE INDEX units_structure ON units (structure)")


def _v3(db: FleetStore) -> None:
    """Version 3: the leases of running add-many batches (`fleet.lease`)."""
    db.execute("CREATE TABLE batches (id TEXT PRIMARY KEY, host TEXT NOT NULL, pid BIGINT "
               "NOT NULL, started TEXT NOT NULL, heartbeat DOUBLE PRECISION NOT NULL)")


def _v4(db: FleetStore) -> None:
    """Version 4: the fleet's state counter and the results cached at a state."""
    db.execute("CREATE TABLE fleet_state (version BIGINT NOT NULL)")
    db.execute("INSERT INTO fleet_state (version) VALUES (1)")
    db.execute("CREATE TABLE fleet_cache (kind TEXT NOT NULL, key TEXT NOT NULL, state BIGINT "
               "NOT NULL, value TEXT NOT NULL, PRIMARY KEY (kind, key))")


MIGRATIONS: list[Callable[[FleetStore], None]] = [_v1, _v2, _v3, _v4]
SCHEMA_VERSION = len(MIGRATIONS)


def _structure_of(summary: dict) -> str:
    """A version-1 unit's structure, from its summary."""
    s = summary.get("structure") or (summary.get("model") or {}).get("structure") or ""
    return s if isinstance(s, str) else json.dumps(s, sort_keys=True)


def bump_state(db: FleetStore) -> None:
    """Inside the transaction that adds or removes a unit: the fleet is at a new state."""
    db.execute("UPDATE fleet_state SET version = version + 1")


def state_of(db: FleetStore) -> int:
    """The fleet's state (read inside the snapshot the units are read in)."""
    return int(db.execute("SELECT version FROM fleet_state").fetchall()[0][0])


def cached(db: FleetStore, kind: str, key: str, state: int | None) -> str | None:
    """The result of `kind` and `key` computed at `state` (None: at any state, for what does
    not depend on the units); None when there is none."""
    rows = db.execute("SELECT value, state FROM fleet_cache WHERE kind = ? AND key = ?",
                      (kind, key)).fetchall()
    return str(rows[0][0]) if rows and state in (None, int(rows[0][1])) else None


def keep(db: FleetStore, kind: str, key: str, state: int, value: str) -> None:
    """Inside a write transaction: keep `value` as the result of `kind` and `key` at `state`,
    only if the fleet is still at that state (a unit added meanwhile: nothing kept)."""
    db.execute("INSERT INTO fleet_cache (kind, key, state, value) SELECT ?, ?, ?, ? "
               "WHERE (SELECT version FROM fleet_state) = ? ON CONFLICT (kind, key) "
               "DO UPDATE SET state = excluded.state, value = excluded.value",
               (kind, key, state, value, state))
