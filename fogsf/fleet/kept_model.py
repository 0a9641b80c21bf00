"""A unit recorded from the model folder its training kept (`fogsf fleet add --model-dir
DIR`), without training again: the folder `fleet add --out` or `fogsf train --prior --unit` keeps
when the database write fails, or one `fogsf train --out` wrote.

The record is built as `fleet add` builds it from a fitted model (`records.unit_record`,
`plateau_unit.plateau_record`), from the folder's files instead: metrics.json (figures,
interval), train_info.json (the structure) and the firmware artifact (stream.json and
stream_weights.npz), whose float32 reference (`models.reference.run_steps` on the artifact's
own front end) gives the per-sample prediction the response and the SF curve read. That is
the kernel's prediction, not the torch net's the training scored: they agree within 0.01 ppm
(tests/test_train.py), so the response and the SF curve may differ from those of the add
that trained the model by that much; every other field is the same to the bit. A plateau
model is scored by the reference in both, so its record is the same to the bit.

`fleet add --out DIR` writes KEPT_FILE beside the model: the logs (their SHA-256) and the
options it was trained with; `--model-dir DIR` refuses other logs or options. A folder
without it (`fogsf train`'s) is checked against what metrics.json holds of its logs
(how many, a test log or not, the training logs' ramps or plateaus) and its kind and seed.
"""

from __future__ import annotations

import json
import os
import shlex
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from fogsf.errors import UserError
from fogsf.fleet.names import masked
from fogsf.fleet.plateau_unit import PLATEAU, plateau_record
from fogsf.fleet.records import UnitRecord, after_blocks, file_sha256, unit_record
from fogsf.logs.chamber_log import ChamberLog
from fogsf.logs.plateau_table import PlateauTable
from fogsf.logs.read.sampling import common_rate
from fogsf.models.features import FeatureSpec, SeqData
from fogsf.models.reference import run_steps
from fogsf.models.stream import StreamModel
from fogsf.models.stream_format import METRICS_FILE
from fogsf.training.fitted_model import Fitted
from fogsf.training.interval.transfer import ramp_segments
from fogsf.training.metrics_file import from_json
from fogsf.training.rate.plateau_train import rows_of
from fogsf.training.results import PlateauMetrics

KEPT_FILE = "fleet_unit.json"
KEPT_FORMAT = "fogsf-fleet-unit-1"
INFO_FILE = "train_info.json"
NO_ARTIFACT = ("poly", "polyrate", "mlp")  # models `fogsf train` writes no stream.json for


def write_kept(out: Path, record: UnitRecord) -> bool:
    """KEPT_FILE in `out`: the logs and options `record`'s model was trained with; False
    when it cannot be written (the disk full): the retry then checks what metrics.json
    holds (a model fitted under a prior cannot be retried), and the record is not held up."""
    content = {"format": KEPT_FORMAT, "unit": record.unit, "model_id": record.model_id,
               "logs": [asdict(lg) for lg in record.logs],
               "options": record.fitted_with.get("options", {})}
    tmp = out / f".{KEPT_FILE}.tmp"
    try:
        tmp.write_text(json.dumps(content, indent=2, default=str) + "\n", encoding="utf-8")
        os.replace(tmp, out / KEPT_FILE)
    except OSError:
        tmp.unlink(missing_ok=True)
        return False
    return True


def retry_command(argv: list[str], drop: tuple[str, ...], out: str) -> str:
    """`fogsf fleet add ARGV --model-dir OUT`: the add that records the model a training
    kept in OUT; ARGV the fleet, the unit, the logs and options as given, less every option
    of `drop` (a prior, a lease, the folder trained into: each takes a value), however
    given (`--opt value`, `--opt=value`, a prefix argparse took, more than once)."""
    for opt in drop:
        while at := _given(argv, opt):
            argv = argv[:at[0]] + argv[at[0] + at[1]:]
    # a fleet URL without its password: the add reads it from PGPASSWORD or ~/.pgpass
    return shlex.join(["fogsf", "fleet", "add", *(masked(a, drop=True) for a in argv),
                       "--model-dir", out])


def _given(argv: list[str], opt: str) -> tuple[int, int] | None:
    """Where `opt` first stands in argv with its value (index, tokens)."""
    for i, a in enumerate(argv):
        name, eq, _ = a.partition("=")
        if len(name) > 3 and name.startswith("--") and opt.startswith(name):
            return (i, 1) if eq else (i, min(2, len(argv) - i))
    return None


@dataclass
class KeptModel:
    """A model folder read and checked: metrics.json's content, train_info.json's ({} for
    a plateau model), the artifact and KEPT_FILE's content (None without one)."""

    folder: Path
    metrics: dict[str, Any]
    info: dict[str, Any]
    stream: StreamModel
    kept: dict[str, Any] | None

    @property
    def where(self) -> str:
        return f"--model-dir {self.folder}"


def _json(path: Path, where: str) -> dict[str, Any]:
    if not path.is_file():
        raise UserError(f"{where}: no {path.name}: not a complete fogsf model folder (fogsf "
                        "train --out and fogsf fleet add --out write one)")
    try:
        content = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError) as e:
        raise UserError(f"{where}: {path.name} cannot be read: {str(e).splitlines()[0]}"
                        ) from None
    if not isinstance(content, dict):
        raise UserError(f"{where}: {path.name} holds no JSON object")
    return content


def read_kept(folder: str | Path, plateau_logs: bool) -> KeptModel:
    """The model folder `folder`, refused in one line when it is missing, incomplete, not
    a fogsf model, a model with nothing to predict from, or of the other kind of logs than
    those given (`plateau_logs`: plateau tables)."""
    d = Path(folder)
    where = f"--model-dir {d}"
    if not d.is_dir():
        raise UserError(f"{where}: no such folder (the model folder a training kept)")
    metrics = _json(d / METRICS_FILE, where)
    kind = metrics.get("model")
    if not isinstance(kind, str):
        raise UserError(f"{where}: {METRICS_FILE} is not one fogsf train writes (no model "
                        "kind)")
    if metrics.get("bias_only"):
        raise UserError(f"{where}: a bias-only model (stationary logs) has no SF response "
                        "to record")
    if kind in NO_ARTIFACT:
        raise UserError(f"{where}: a '{kind}' model keeps no firmware artifact to predict "
                        "from; record it by training again (fleet add without --model-dir)")
    if not isinstance(metrics.get("model_id"), str):
        raise UserError(f"{where}: {METRICS_FILE} is not one fogsf train writes (no model id)")
    if (kind == PLATEAU) != plateau_logs:
        given = "plateau tables" if plateau_logs else "sample logs"
        raise UserError(f"{where} holds a {'plateau' if kind == PLATEAU else kind} model "
                        f"and the logs given are {given}")
    try:  # every key the record reads: an incomplete metrics.json is refused here
        from_json(metrics)
    except (KeyError, TypeError, ValueError) as e:
        raise UserError(f"{where}: {METRICS_FILE} is incomplete ({type(e).__name__}: "
                        f"{e})") from None
    info = {} if kind == PLATEAU else _json(d / INFO_FILE, where)
    stream = StreamModel.load(d)  # its own one-line refusals, naming the file
    if stream.model_id != metrics["model_id"]:
        raise UserError(f"{where}: the artifact is model {stream.model_id}, {METRICS_FILE} "
                        f"describes {metrics['model_id']}: parts of two trainings")
    kept = _json(d / KEPT_FILE, where) if (d / KEPT_FILE).is_file() else None
    if kept is not None and kept.get("format") != KEPT_FORMAT:
        raise UserError(f"{where}: {KEPT_FILE} is not one fogsf fleet add writes")
    if kept is not None and kept.get("model_id") != metrics["model_id"]:
        kept = None  # it names another training's logs (a later one wrote the folder)
    if metrics.get("prior") and "prior" not in ((kept or {}).get("options") or {}):
        raise UserError(f"{where}: trained under the design's prior without --unit, or its "
                        f"{KEPT_FILE} is missing (fogsf train --prior); fleet add records a "
                        "unit trained alone, or one `train --prior --unit` kept")
    return KeptModel(d, metrics, info, stream, kept)


def _check_logs(m: KeptModel, given: list[tuple[str, str]], counts: tuple[int, bool]) -> bool:
    """Refuse logs given ((role, path) each) other than those KEPT_FILE names (by SHA-256)
    or, without it, other in number than metrics.json's (`counts`: training logs, a test
    log or not). True when KEPT_FILE checked them (nothing left to check)."""
    if m.kept is not None:
        had = [(lg.get("role"), lg.get("sha256"), lg.get("path")) for lg in m.kept["logs"]]
        for (role, path), (r, sha, was) in zip(given, had, strict=False):
            mine = file_sha256(path) if Path(path).is_file() else ""
            if role != r or mine != sha:
                raise UserError(f"{m.where} was trained on {was} ({r}), not on {path}: give "
                                "the logs it was trained on")
        if len(given) == len(had) and all(sha for _, sha, _ in had):
            return True  # a folder log (a bag) has no hash: its ramps are checked below
        counts = (sum(r == "train" for r, _, _ in had), any(r == "test" for r, _, _ in had))
    n_train = sum(role == "train" for role, _ in given)
    test = any(role == "test" for role, _ in given)
    if (n_train, test) != counts:
        raise UserError(f"{m.where} was trained on {counts[0]} training log(s) "
                        f"{'and' if counts[1] else 'without'} a test log; {n_train} given "
                        f"{'with' if test else 'without'} one")
    return False


def _check_options(m: KeptModel, options: dict[str, Any]) -> None:
    """Refuse training options given other than those the model was trained with (all of
    them from KEPT_FILE; without it, the model kind and seed metrics.json records)."""
    ours = json.loads(json.dumps(options, default=str))
    if m.kept is not None:  # the prior a unit was fitted under is not an option of add's
        theirs = {k: v for k, v in (m.kept.get("options") or {}).items() if k != "prior"}
    else:
        theirs = {k: m.metrics[k] for k in ("model", "seed") if k in m.metrics and k in ours}
        ours = {k: v for k, v in ours.items() if k in theirs}
    for k in sorted(set(theirs) | set(ours)):
        if theirs.get(k) != ours.get(k):
            raise UserError(f"{m.where} was trained with {k} = {theirs.get(k)!r}, the options "
                            f"given say {ours.get(k)!r}: give the options it was trained with")


def _fitted(m: KeptModel) -> Fitted:
    """The artifact as a fitted model: its per-step prediction the float32 reference's on
    its own front end; the spec's rows are its feature map (normalisation folded in)."""
    sm = m.stream

    def predict_steps(d: SeqData) -> np.ndarray:
        return run_steps(sm, d.s).sf_ppm.astype(np.float64)

    w = np.asarray(sm.weights["feat_w"], np.float64)
    rows = np.diag(w) if sm.feat_diag else w
    spec = FeatureSpec(tuple(float(t) for t in sm.filter_tau_s),
                       tuple(tuple(float(v) for v in r) for r in rows),
                       tuple(str(n) for n in m.metrics.get("features") or ()),
                       tuple((tuple(float(v) for v in src), float(wd))
                             for src, wd in zip(sm.play_source_w, sm.play_width_c,
                                                strict=True)))
    return Fitted(str(m.metrics["model"]), spec, sm.front_end, predict_steps, sm.params,
                  4 * sm.params, m.info, stream_model=sm)


def kept_record(unit: str, train_logs: list[ChamberLog], test_log: ChamberLog | None,
                m: KeptModel, options: dict[str, Any]) -> UnitRecord:
    """The record `fleet add` writes of a unit whose model on sample logs is `m`
    (`read_kept`; `options`: the training options as data, as fleet add records them)."""
    given = [("train", str(lg.path)) for lg in train_logs]
    given += [("test", str(test_log.path))] if test_log is not None else []
    if not _check_logs(m, given, (len(after_blocks(m.metrics["train"])), "test" in m.metrics)):
        ramps = [[asdict(s) for s in ramp_segments(lg)] for lg in common_rate(train_logs)]
        if ramps != m.metrics["train_ramp_segments"]:
            raise UserError(f"{m.where} was trained on logs with other ramps than those "
                            "given: give the logs it was trained on")
    _check_options(m, options)
    if m.kept is not None and "prior" in (m.kept.get("options") or {}):
        options = {**options, "prior": m.kept["options"]["prior"]}  # as train --prior --unit
    return unit_record(unit, train_logs, test_log, m.metrics, _fitted(m), m.folder, options)


def kept_plateau_record(unit: str, train: list[PlateauTable], test: PlateauTable | None,
                        m: KeptModel, options: dict[str, Any]) -> UnitRecord:
    """The record `fleet add` writes of a unit whose plateau model is `m` (`read_kept`)."""
    metrics = from_json(m.metrics)
    assert isinstance(metrics, PlateauMetrics)  # read_kept: the kind is plateau
    given = [("train", str(t.path)) for t in train]
    given += [("test", str(test.path))] if test is not None else []
    if not _check_logs(m, given, (len(metrics.train), metrics.test is not None)):
        lat, cos = options.get("latitude_deg"), float(options.get("axis_cosine", 1.0))
        if [len(rows_of([t], lat, cos)) for t in train] != [s.plateaus for s in metrics.train]:
            raise UserError(f"{m.where} was trained on tables with other plateaus than "
                            "those given: give the tables it was trained on")
    _check_options(m, options)
    return plateau_record(unit, train, test, m.stream, metrics, m.folder, options)
