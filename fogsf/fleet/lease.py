"""A batch's lease: the row of table `batches` an `add-many` holds while it runs, so that no
unit of a stopped batch is recorded.

    with BatchLease("line.fleet") as lease:       # the batch's process
        ... workers run `fogsf fleet add ... --batch lease.id`
    check_batch(store, batch_id)                  # in the worker's add transaction

The batch is running while its row is there and its process lives: on the batch's own
host that process is asked directly (its pid and start time), elsewhere (a Dask worker on
another machine) the row's heartbeat, written every HEARTBEAT_S by the database's clock,
must be under STALE_S old. The row goes when the batch ends; a killed batch leaves it, and
its units are refused from that moment on the same host, within STALE_S elsewhere.
"""

from __future__ import annotations

import os
import socket
import threading
import uuid
from pathlib import Path

from fogsf.errors import UserError
from fogsf.fleet.store import FleetStore, open_store
from fogsf.scratch import alive, start_time

HEARTBEAT_S = 2.0
STALE_S = 10.0  # a heartbeat older than this: the batch is gone (5 beats missed)
FORGET_S = 86400.0  # rows of killed batches older than this are removed by the next batch


def is_lease_id(text: str) -> bool:
    """A batch's lease id as `BatchLease` makes it (32 hex digits): anything else given as
    one names no batch."""
    return len(text) == 32 and all(c in "0123456789abcdef" for c in text)


def host_key() -> str:
    """This machine and pid namespace: where a pid names the same process."""
    try:
        boot = Path("/proc/sys/kernel/random/boot_id").read_text().strip()
        ns = os.stat("/proc/self/ns/pid").st_ino
    except OSError:
        boot, ns = "", 0
    return f"{socket.gethostname()}/{boot}/{ns}"


class BatchLease:
    """The lease of one batch on `fleet`: its row written on entry, a heartbeat thread,
    the row removed on exit (the batch stopped: no later unit of it is recorded)."""

    def __init__(self, fleet: str) -> None:
        self.fleet = fleet
        self.id = uuid.uuid4().hex
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def __enter__(self) -> BatchLease:
        with open_store(self.fleet, "create") as store, store.transaction():
            now = store.now_sql
            store.execute(f"DELETE FROM batches WHERE heartbeat < {now} - ?", (FORGET_S,))
            store.execute("INSERT INTO batches (id, host, pid, started, heartbeat) "
                          f"VALUES (?, ?, ?, ?, {now})",
                          (self.id, host_key(), os.getpid(), start_time(os.getpid()) or ""))
        self._thread = threading.Thread(target=self._beat, name="fogsf-batch-lease",
                                        daemon=True)
        self._thread.start()
        return self

    def _beat(self) -> None:
        store: FleetStore | None = None
        while not self._stop.wait(HEARTBEAT_S):
            try:  # a missed beat is retried; a batch whose beats all fail goes stale
                store = store or open_store(self.fleet, "write")
                store.execute(f"UPDATE batches SET heartbeat = {store.now_sql} WHERE id = ?",
                              (self.id,))  # autocommit: SQLite's busy timeout waits quietly
            except Exception:  # noqa: BLE001 - the beat's own thread: retried next time
                if store is not None:
                    store.close()
                store = None
        if store is not None:
            store.close()

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join()
        with open_store(self.fleet, "write") as store, store.transaction():
            store.execute("DELETE FROM batches WHERE id = ?", (self.id,))


def check_batch(store: FleetStore, batch_id: str) -> None:
    """Inside a unit's add transaction, last before COMMIT: refuse the unit (UserError,
    the transaction rolled back) unless its batch still runs."""
    rows = store.execute(f"SELECT host, pid, started, {store.now_sql} - heartbeat "
                         "FROM batches WHERE id = ?", (batch_id,)).fetchall()
    if not rows:
        raise UserError(f"batch {batch_id[:8]} was stopped: the unit is not recorded")
    host, pid, started, age = rows[0]
    running = (alive(int(pid), str(started)) if host == host_key()
               else float(age) < STALE_S)
    if not running:
        raise UserError(f"batch {batch_id[:8]} is gone (its add-many process died): "
                        "the unit is not recorded")
