"""The SF part of `fogsf train`: `opts.model` fitted to the training logs. For lag-lstm the
structure first (chosen by the logs, `training.structure.choice`, or given), then whether a
hysteresis play joins it (`training.structure.hysteresis`), then the least-squares part and the
LSTM on what it leaves (`training.sf.feature_spec`)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict

from fogsf.errors import UserError
from fogsf.logs.chamber_log import ChamberLog
from fogsf.models.features import FeatureSpec, effective_node_features, make_features
from fogsf.models.structures.hysteresis import HystTerm, spec_with_play
from fogsf.models.structures.lag_bank import (
    BANK_LSTM_INPUTS,
    BankFit,
    bank_cross,
    bank_name,
    bank_penalty,
    bank_spec,
)
from fogsf.models.structures.physics_nodes import (
    NodeFit,
    fit_coefficients,
    identify_taus,
    node_spec,
)
from fogsf.training.bias.targets import measured_windows
from fogsf.training.fitted_model import Fitted
from fogsf.training.inputs import TrainingInputs, bank_data, fit_bank_head
from fogsf.training.net.config import lstm_config
from fogsf.training.options import TrainOptions, check_options
from fogsf.training.sf.feature_spec import fit_with_spec, identify_node, identify_two_nodes
from fogsf.training.structure import choice as sc
from fogsf.training.structure import heldout as sh
from fogsf.training.structure import hysteresis as hc
from fogsf.training.structure import penalty as sp


def fit_sf(opts: TrainOptions, train_logs: list[ChamberLog]) -> Fitted:
    """Train `opts.model` on `train_logs` (validation part held out inside them)."""
    check_options(opts, train_logs)
    kind = opts.model
    if kind in ("poly", "polyrate", "mlp", "lstm"):
        spec = make_features(rate_tau_s=None if kind == "poly" else opts.rate_tau_s)
        return fit_with_spec(opts, train_logs, spec, lstm_config(opts) if kind == "lstm"
                             else None)
    if kind == "lag-lstm":
        return _fit_lag_lstm(opts, train_logs)
    # torch: the search trains an LSTM per agent (gsa-lstm only)
    from fogsf.training.net.gsa_search import fit_gsa

    return fit_gsa(opts, train_logs)


def _fit_lag_lstm(opts: TrainOptions, train_logs: list[ChamberLog]) -> Fitted:
    choice = None
    if opts.structure == "auto" and opts.node is None and opts.nodes == 1:
        choice = sc.choose(train_logs, opts.model_step_s, opts.latitude_deg,
                           progress=opts.progress)
        structure, nodes = choice.structure()
        opts = TrainOptions(**{**asdict(opts), "structure": structure, "nodes": nodes})
    bank = opts.structure in ("bank", "auto") and opts.node is None and opts.nodes == 1
    if opts.structure != "physics" and not bank:
        return _fit_node(opts, train_logs)
    base = "bank" if bank else f"physics{opts.nodes}"
    # the check runs on the bank at BANK_LAMBDA (a loop's too): a lower penalty lets the
    # slow lags mimic a play inside the training program, which the held-out blocks
    # then cannot see
    hyst = hysteresis_choice(opts, train_logs, base)
    if choice is not None:
        name = choice.bank
    elif bank:  # the bank forced (`--structure bank`): its prior for these logs (no walk)
        name = bank_name(sp.bank_prior(train_logs, step_s=opts.model_step_s))
    else:  # physics nodes forced: no bank is fitted
        name = bank_name()
    if choice is not None and choice.penalty is not None and hyst["used"] and \
            bank_cross(name):
        name, choice.cross_left_out, choice.cross_with_term = _cross_beside_a_play(
            opts, train_logs, choice.penalty.plain, name)
    if opts.structure == "physics":
        fitted = _fit_physics(opts, train_logs, hyst["used"])
    else:  # the bank's name carries its penalty and cross terms (`choose`)
        fitted = _fit_bank(opts, train_logs, hyst["used"], name)
    if choice is not None:
        fitted.info["structure_choice"] = choice.as_dict()
    if "term" in fitted.info:
        hyst["term"] = fitted.info.pop("term")
    fitted.info["hysteresis_choice"] = hyst
    return fitted


def _cross_beside_a_play(opts: TrainOptions, logs: list[ChamberLog], plain: str, cross: str
                         ) -> tuple[str, str | None, dict | None]:
    """(the bank to train, why the cross terms are left out or None, the record of
    `structure.hysteresis.cross_with_term` or None) when the hysteresis
    term joins a bank the choice gave cross terms: left out beside a bias head too (three
    such models take 24 680 B of flash, over the M4F's 24 576: docs/firmware.md), or when,
    with the term in, they no longer predict the held-out parts better
    (`structure.hysteresis.cross_with_term`); then the bank the penalty walk reached without
    them."""
    why = f"; trained at {sp.bank_label(plain)}"
    if measures_bias(opts, logs):
        return plain, f"with a play and a bias head three models would not fit 24 KB{why}", None
    rec = hc.cross_with_term(logs, plain, cross, sh.choice_step_s(logs, opts.model_step_s),
                             opts.latitude_deg)
    if rec["kept"]:
        return cross, None, rec
    rms = rec["heldout_rms_ppm"]
    return plain, (f"with the hysteresis term they predicted {rec['wins']} of the "
                   f"{rec['parts']} held-out parts better (held-out RMS {rms[plain]:.1f} -> "
                   f"{rms[cross]:.1f} ppm){why}"), rec


def measures_bias(opts: TrainOptions, logs: list[ChamberLog]) -> bool:
    """Whether some training log measures the bias (the model will get a bias head)."""
    return any(measured_windows(lg, opts.window_s, opts.latitude_deg, opts.settle_s)
               is not None for lg in logs)


def _lstm_inputs(opts: TrainOptions, spec: FeatureSpec) -> int:
    n_in = BANK_LSTM_INPUTS if opts.lstm_inputs is None else opts.lstm_inputs
    if not 1 <= n_in <= spec.n_features:
        raise UserError(f"--lstm-inputs must lie in 1..{spec.n_features} (the model's "
                        f"features), got {n_in}")
    return n_in


def hysteresis_choice(opts: TrainOptions, logs: list[ChamberLog], base: str) -> dict:
    """Whether a play joins `base` (`structure.hysteresis.decide`'s record)."""
    # long logs are checked at the structure choice's coarser step (the term is then fitted
    # at the model step)
    return hc.decide(logs, base, sh.choice_step_s(logs, opts.model_step_s), opts.latitude_deg,
                     opts.hysteresis)


def _fit_physics(opts: TrainOptions, logs: list[ChamberLog], hysteresis: bool = False
                 ) -> Fitted:
    """Physics nodes: time constants identified by variable projection on every step of the
    training logs, the quadratic (with cross terms) held fixed in the head, the LSTM on what
    it leaves; with `hysteresis`, a play term too (`models.structures.hysteresis`)."""
    sd = sh.step_data(logs, opts.model_step_s, opts.latitude_deg)
    taus = identify_taus(sd.nodes, sd.y, opts.nodes)
    spec = node_spec(taus)

    def head_fn(ti: TrainingInputs) -> NodeFit:
        return fit_coefficients(*bank_data(ti), taus)

    if hysteresis:
        return _fit_with_term(opts, logs, f"physics{opts.nodes}", spec, sd)
    return fit_with_spec(opts, logs, spec,
                         lstm_config(opts, lstm_inputs=_lstm_inputs(opts, spec)),
                         head_fn=head_fn)


def fit_physics_head(opts: TrainOptions, logs: list[ChamberLog], taus_s: tuple[float, ...],
                     head_fn: Callable[[TrainingInputs], NodeFit],
                     term: HystTerm | None = None) -> Fitted:
    """lag-lstm on physics nodes at `taus_s` (and the play `term`, its feature last) with the
    head `head_fn` gives (fitted outside, e.g. under the design's prior,
    `training.with_prior`) and the LSTM on what it leaves."""
    spec = node_spec(taus_s) if term is None else spec_with_play(node_spec(taus_s), term)
    fitted = fit_with_spec(opts, logs, spec,
                           lstm_config(opts, lstm_inputs=_lstm_inputs(opts, spec)),
                           head_fn=head_fn)
    if term is not None:
        fitted.info["term"] = term.as_dict()
    return fitted


def _fit_bank(opts: TrainOptions, logs: list[ChamberLog], hysteresis: bool = False,
              name: str = "bank") -> Fitted:
    """The lag bank (ridge, its quadratic in the head: diagonal, or full with the cross terms)
    and the LSTM on what it leaves; with `hysteresis`, a play term too. `name` carries the
    penalty and the cross terms (`lag_bank.bank_name`)."""
    spec = bank_spec()
    if hysteresis:
        sd = sh.step_data(logs, opts.model_step_s, opts.latitude_deg)
        return _fit_with_term(opts, logs, name, spec, sd)
    lam, cross = bank_penalty(name), bank_cross(name)
    assert lam is not None
    # the bank's quadratic is diagonal (the head carries quad_w [F], not [F, F]) unless the
    # choice took its cross terms
    return fit_with_spec(opts, logs, spec,
                         lstm_config(opts, lstm_inputs=_lstm_inputs(opts, spec),
                                     quad_diag=not cross),
                         head_fn=lambda ti: fit_bank_head(ti, lam, cross))


def _fit_with_term(opts: TrainOptions, logs: list[ChamberLog], base: str, spec: FeatureSpec,
                   sd: sh.StepData) -> Fitted:
    """`base` (bank or physicsN with `spec`'s lags) with the play term chosen on every step
    of the training logs, its feature last, its coefficient unpenalised, in the head."""
    term = hc.final_term(base, sd, spec.taus_s)
    full = spec_with_play(spec, term)

    def head_fn(ti: TrainingInputs) -> BankFit | NodeFit:
        return hc.head_fit(base, *bank_data(ti), spec.taus_s)

    fitted = fit_with_spec(opts, logs, full,
                           lstm_config(opts, lstm_inputs=_lstm_inputs(opts, full),
                                       quad_diag=bank_penalty(base) is not None
                                       and not bank_cross(base)),
                           head_fn=head_fn)
    fitted.info["term"] = term.as_dict()
    return fitted


def _fit_node(opts: TrainOptions, train_logs: list[ChamberLog]) -> Fitted:
    if opts.nodes == 2:  # a quadratic form of two nodes, as the physics has it
        spec = effective_node_features(*identify_two_nodes(opts, train_logs))
        return fit_with_spec(opts, train_logs, spec, lstm_config(opts, cubes=False))
    tau, w = opts.node or identify_node(opts, train_logs)
    spec = effective_node_features((tau, w))
    return fit_with_spec(opts, train_logs, spec, lstm_config(opts))
