"""A new unit of the design trained under the prior the fleet database gives
(`fogsf train --prior FLEET [--unit SN]`), and recorded in it with --unit."""

from __future__ import annotations

import json
import sys
from pathlib import Path

from fogsf import __version__
from fogsf.errors import UserError
from fogsf.fleet.faults import db_faults
from fogsf.fleet.kept_model import KEPT_FILE, write_kept
from fogsf.fleet.names import check_unit_name, masked, shown
from fogsf.fleet.plateau_unit import PLATEAU
from fogsf.fleet.records import recorded_options, unit_record
from fogsf.fleet.schema import cached, state_of
from fogsf.fleet.store import keep_quietly, open_store
from fogsf.logs.chamber_log import ChamberLog
from fogsf.prior.design_prior import DesignPrior
from fogsf.training.bias.targets import check_mixed
from fogsf.training.options import TrainOptions
from fogsf.training.with_prior import prior_from_summaries, train_with_prior

# what a cached prior was learned by: a prior another fogsf, or another method, learned is
# not read (bump it when the prior's learning changes)
PRIOR_METHOD = 3


def design_prior(fleet: str, unit: str | None = None) -> DesignPrior:
    """The design's prior from the fleet database at `fleet` (its units' summaries): read
    from the fleet's cache when it holds the prior of the fleet's state, else learned and
    kept there (`fleet.schema`: every add and remove makes a new state). `unit`: refused if
    the fleet has it (`train --prior --unit SN` records it)."""

    key = f"fogsf {__version__}; method {PRIOR_METHOD}"
    with db_faults(masked(fleet)), open_store(fleet, "read") as store, store.snapshot():
        where = store.location  # the password masked
        if unit is not None and store.execute("SELECT 1 FROM units WHERE sn = ?",
                                              (unit,)).fetchall():  # no row lock: a read
            raise UserError(f"unit {shown(unit)} is already in {where} (`fogsf fleet "
                            "remove` it first)")
        state = state_of(store)
        hit = cached(store, "prior", key, state)
        units = store.units() if hit is None else []
        plateau = int(store.execute("SELECT count(*) FROM units WHERE structure = ?",
                                    (PLATEAU,)).fetchall()[0][0])
    # the prior is built on the units' SF responses over time: a plateau table has none
    left = (f"{plateau} plateau unit(s) left out (the design's prior is built on SF "
            "responses over time, which plateau tables do not give)" if plateau else "")
    summaries = {u.unit: u.summary for u in units if u.summary.get("series")}
    if hit is None and len(summaries) < 2:
        raise UserError(f"the design's prior needs at least two units in {where} "
                        f"with their logs' summary, it has {len(summaries)} (fogsf fleet add)"
                        + (f"; {left}" if left else ""))
    if left:
        print(f"fogsf: {where}: {left}", file=sys.stderr)
    if hit is not None:
        return DesignPrior.from_cache(json.loads(hit))
    prior = prior_from_summaries(summaries)
    keep_quietly(fleet, "prior", key, state, json.dumps(prior.to_cache()))
    return prior


def prior_from_store(path: str) -> DesignPrior:
    """The design's prior from the fleet database at `path` (`design_prior`)."""
    return design_prior(path)


def refuse_stationary(train_logs: list[ChamberLog]) -> None:
    """A unit's record is its SF response: stationary logs alone (a bias-only model) are
    refused before any training."""
    if check_mixed(train_logs):
        raise UserError(", ".join(lg.path for lg in train_logs) + ": stationary (the table "
                        "stopped throughout): such logs train a bias-only model, which a "
                        "fleet cannot record (a unit is its SF response); give logs with "
                        "the table turning, or train it alone with fogsf train")


def train_on_prior(fleet: str, unit: str | None, opts: TrainOptions,
                   train_logs: list[ChamberLog], test_log: ChamberLog | None, out: Path,
                   retry: str | None = None) -> dict:
    """`fogsf train --prior FLEET [--unit SN]`: the prior from FLEET, the unit trained under
    it into `out`, recorded in FLEET with --unit; metrics.json's content. `retry`: the add
    that records the kept model when the database write fails (`kept_model.retry_command`)."""

    if unit is not None:
        check_unit_name(unit)  # before the fleet is read or the unit trained
        refuse_stationary(train_logs)
    prior = design_prior(fleet, unit)
    metrics, fitted = train_with_prior(opts, train_logs, test_log, out, prior)
    if unit is not None:
        options = recorded_options(opts)
        options["prior"] = {"fleet_units": prior.units, "used": metrics["prior"]["used"]}
        record = unit_record(unit, train_logs, test_log, metrics, fitted, out, options)
        kept = write_kept(out, record)  # what the retry checks its logs and options against
        try:
            with db_faults(masked(fleet)), open_store(fleet, "write") as store:
                store.add(record)
        except UserError as e:  # the model is written: say where, the training not lost
            again = (f"; record it without training again: {retry}" if retry and kept else
                     f"; {out}/{KEPT_FILE} could not be written: train the unit again to "
                     "record it" if retry else "")
            raise UserError(f"{e}; the trained model is kept in {out}{again}") from None
        metrics["prior"]["recorded"] = f"recorded unit {unit} in {store.location}"
    return metrics

