"""A new unit of the design trained under the prior the fleet database gives
(`fogsf train --prior FLEET [--unit SN]`), and recorded in it with --unit."""

from __future__ import annotations

from pathlib import Path

from fogsf.errors import UserError
from fogsf.fleet.faults import db_faults
from fogsf.fleet.names import check_unit_name, masked, shown
from fogsf.fleet.records import unit_record
from fogsf.fleet.store import open_store
from fogsf.logs.chamber_log import ChamberLog
from fogsf.prior.design_prior import DesignPrior
from fogsf.training.options import TrainOptions
from fogsf.training.with_prior import prior_from_summaries, train_with_prior


def prior_from_store(path: str) -> DesignPrior:
    """The design's prior from the fleet database at `path` (its units' summaries)."""

    with db_faults(masked(path)), open_store(path, "read") as store:  # never creates one
        units = store.units()
    return prior_from_summaries({u.unit: u.summary for u in units if u.summary})


def train_on_prior(fleet: str, unit: str | None, opts: TrainOptions,
                   train_logs: list[ChamberLog], test_log: ChamberLog | None, out: Path) -> dict:
    """`fogsf train --prior FLEET [--unit SN]`: the prior from FLEET, the unit trained under
    it into `out`, recorded in FLEET with --unit; metrics.json's content."""

    if unit is not None:
        check_unit_name(unit)  # before the fleet is read or the unit trained
    with db_faults(masked(fleet)), open_store(fleet, "read") as store:
        units = store.units()
        where = store.location  # the password masked
    if unit is not None and any(u.unit == unit for u in units):
        raise UserError(f"unit {shown(unit)} is already in {where} (`fogsf fleet remove` "
                        "it first)")
    summaries = {u.unit: u.summary for u in units if u.summary.get("series")}
    if len(summaries) < 2:
        raise UserError(f"the design's prior needs at least two units in {where} "
                        f"with their logs' summary, it has {len(summaries)} (fogsf fleet add)")
    prior = prior_from_summaries(summaries)
    metrics, fitted = train_with_prior(opts, train_logs, test_log, out, prior)
    if unit is not None:
        options = {k: v for k, v in vars(opts).items()
                   if k not in ("progress", "workers", "dask", "extra")}
        options["prior"] = {"fleet_units": prior.units, "used": metrics["prior"]["used"]}
        record = unit_record(unit, train_logs, test_log, metrics, fitted, out, options)
        try:
            with db_faults(masked(fleet)), open_store(fleet, "write") as store:
                store.add(record)
        except UserError as e:  # the model is written: say where, the training not lost
            raise UserError(f"{e}; the trained model is kept in {out}") from None
        metrics["prior"]["recorded"] = f"recorded unit {unit} in {store.location}"
    return metrics

