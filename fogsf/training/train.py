"""`fogsf train`: fit a compensation model on training logs, score it on a test log.

Models (all causal, all from the board thermometer and time only):
- `poly`: polynomial in T (the industry's first try);
- `polyrate`: polynomial in T with a filtered dT/dt (the industry standard);
- `mlp`: the paper's MLP baseline on (T, filtered dT/dt);
- `lstm`: the paper's LSTM on (T, filtered dT/dt), Table 1 defaults (2 x 200, batch 32,
  lr 0.02, Adam);
- `lag-lstm` (the default): the physics part fitted by least squares and carried exactly in
  the polynomial head, a 1 x 16 LSTM learning what it leaves. Its structure is chosen by
  the training logs (`structure="auto"`, `training.structure_choice`: held-out prediction
  of their parts among physics nodes with 1-3 nodes and the lag bank), or given: physics nodes
  (`models.physics_nodes`: T and N first-order lags of it with identified time constants,
  a quadratic with cross terms), the lag bank (`models.lag_bank`: T and its lags at 11 time
  constants, ridge with a prior that logs of many held-out parts may lower; in the head's
  diagonal quadratic, or the full one with the cross terms those logs may add) or, with
  `structure="node"`, one or two effective sensing temperatures
  T_eff = w T + (1 - w) lag(T, tau), (tau, w) profiled over a grid; the LSTM reads the
  first BANK_LSTM_INPUTS features (T). A hysteresis (play) term joins the bank or the
  physics nodes when logs that turn back in temperature ask for it
  (`training.hysteresis_choice`; `hysteresis="on"` / `"off"` to force it);
- `gsa-lstm`: GSA searches batch size, layers, hidden units and learning rate (Table 1's
  four) and (tau, w) of T_eff; fitness is the error on the validation part of the training
  logs, never the test log.

The LSTM models run at the model rate (one step per D samples, state carried) and are
written in the firmware artifact format (stream.json + stream_weights.npz) for `fogsf export`.
"""

from __future__ import annotations

import functools
import json
import math
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from fogsf.errors import UserError
from fogsf.logs.chamber_log import ChamberLog
from fogsf.logs.columns import Column, held
from fogsf.logs.metrics import log_metrics, reference_sf_of_logs
from fogsf.logs.plateaus import SETTLE_S
from fogsf.models.features import (
    FeatureSpec,
    Normaliser,
    SeqData,
    effective_node_features,
    fit_normaliser,
    front_end_for,
    make_features,
    physical_normaliser,
    prepare,
    step_targets,
)
from fogsf.models.lag_bank import (
    BANK_LAMBDA,
    BANK_LSTM_INPUTS,
    BankFit,
    bank_cross,
    bank_name,
    bank_penalty,
    bank_spec,
    fit_bank,
    n_curved,
)
from fogsf.models.physics_nodes import NodeFit
from fogsf.models.reference import expand
from fogsf.models.stream import (
    FrontEnd,
    StreamModel,
    decimation_for,
    diagonal_features,
    pure_play_rows,
)
from fogsf.training.options import TrainOptions
from fogsf.training.transfer import ramp_segments, training_ramp_rates
from fogsf.training.transfer_interval import rate_transfer

if TYPE_CHECKING:  # training.fit imports torch; commands import this module at start-up
    from fogsf.training.fit import LSTMConfig

MODELS = ("poly", "polyrate", "mlp", "lstm", "lag-lstm", "gsa-lstm")
DEFAULT_MODEL = "lag-lstm"  # what `fogsf train` fits without --model
# lag-lstm: chosen by the training logs, physics nodes, the lag bank, one / two effective nodes
STRUCTURES = ("auto", "physics", "bank", "node")
EXPORTABLE = ("lstm", "lag-lstm", "gsa-lstm")


def lstm_defaults(model: str) -> dict:
    if model == "lstm":  # the paper's Table 1
        return {"layers": 2, "hidden": 200, "batch_size": 32, "lr": 0.02, "iters": 300}
    # lag-lstm, gsa-lstm: the physics least-squares polynomial of T_eff carried exactly in
    # the head, the LSTM learns the residual
    return {"layers": 1, "hidden": 16, "batch_size": 32, "lr": 0.01, "iters": 400,
            "poly_head": True}


@dataclass
class Fitted:
    """A trained model: per-step predictions (ppm vs nominal) and what to save."""

    kind: str
    spec: FeatureSpec
    fe: FrontEnd
    predict_steps: Callable[[SeqData], np.ndarray]
    params: int
    weights_bytes: int
    info: dict
    stream_model: StreamModel | None = None  # the firmware artifact (exportable models)
    torch_state: dict | None = None


def _check(opts: TrainOptions, train_logs: list[ChamberLog]) -> None:
    if opts.model not in MODELS:
        raise UserError(f"unknown model {opts.model!r}; choose one of {', '.join(MODELS)}")
    if not train_logs:
        raise UserError("give at least one training log (--train)")
    if opts.nodes not in ((1, 2, 3) if opts.structure == "physics" else (1, 2)):
        raise UserError("--nodes must be 1 or 2 (1-3 with --structure physics)")
    if opts.structure not in STRUCTURES:
        raise UserError(f"--structure must be one of {', '.join(STRUCTURES)}")
    if opts.hysteresis not in ("auto", "on", "off"):
        raise UserError("--hysteresis must be one of auto, on, off")
    if opts.node is not None and opts.nodes != 1:
        raise UserError("--node gives one effective node; drop it or use --nodes 1")
    if opts.lstm_inputs is not None and not (opts.model == "lag-lstm"
                                             and opts.structure != "node"):
        raise UserError("--lstm-inputs narrows the LSTM of the lag bank or the physics "
                        "nodes: it needs --model lag-lstm without --structure node")
    if not (math.isfinite(opts.model_step_s) and opts.model_step_s > 0):
        raise UserError(f"--model-step-s must be > 0, got {opts.model_step_s!r}")
    lo, hi = opts.val_chunk
    if not 0.0 <= lo < hi <= 1.0 or hi - lo > 0.5:
        raise UserError("--val-chunk LO:HI must satisfy 0 <= LO < HI <= 1, at most half")


def _lstm_config(opts: TrainOptions, **over: object) -> LSTMConfig:
    from fogsf.training.fit import LSTMConfig

    d = lstm_defaults(opts.model)
    for k in ("layers", "hidden", "batch_size", "lr", "iters"):
        if getattr(opts, k) is not None:
            d[k] = getattr(opts, k)
    if opts.lstm_window is not None:
        d["window"] = opts.lstm_window
    d.update(over)
    return LSTMConfig(seed=opts.seed, **d)


def fit_model(opts: TrainOptions, train_logs: list[ChamberLog]) -> Fitted:
    """Train `opts.model` on `train_logs` (validation part held out inside them)."""
    _check(opts, train_logs)
    kind = opts.model
    if kind in ("poly", "polyrate", "mlp", "lstm"):
        spec = make_features(rate_tau_s=None if kind == "poly" else opts.rate_tau_s)
        return _fit_with_spec(opts, train_logs, spec, _lstm_config(opts) if kind == "lstm"
                              else None)
    if kind == "lag-lstm":
        choice = None
        if opts.structure == "auto" and opts.node is None and opts.nodes == 1:
            from fogsf.training.structure_choice import choose

            choice = choose(train_logs, opts.model_step_s, opts.latitude_deg,
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
        hyst = _hysteresis_choice(opts, train_logs, base)
        if choice is not None:
            name = choice.bank
        elif bank:  # the bank forced (`--structure bank`): its prior for these logs (no walk)
            from fogsf.training.structure_choice import bank_prior

            name = bank_name(bank_prior(train_logs, step_s=opts.model_step_s))
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
    return _fit_gsa(opts, train_logs)


def _cross_beside_a_play(opts: TrainOptions, logs: list[ChamberLog], plain: str, cross: str
                         ) -> tuple[str, str | None, dict | None]:
    """(the bank to train, why the cross terms are left out or None, the record of
    `hysteresis_choice.cross_with_term` or None) when the hysteresis
    term joins a bank the choice gave cross terms: left out beside a bias head too (three
    such models take 24 680 B of flash, over the M4F's 24 576: docs/firmware.md), or when,
    with the term in, they no longer predict the held-out parts better
    (`hysteresis_choice.cross_with_term`); then the bank the penalty walk reached without
    them."""
    from fogsf.training.hysteresis_choice import cross_with_term
    from fogsf.training.structure_choice import bank_label, choice_step_s

    why = f"; trained at {bank_label(plain)}"
    if _measures_bias(opts, logs):
        return plain, f"with a play and a bias head three models would not fit 24 KB{why}", None
    rec = cross_with_term(logs, plain, cross, choice_step_s(logs, opts.model_step_s),
                          opts.latitude_deg)
    if rec["kept"]:
        return cross, None, rec
    rms = rec["heldout_rms_ppm"]
    return plain, (f"with the hysteresis term they predicted {rec['wins']} of the "
                   f"{rec['parts']} held-out parts better (held-out RMS {rms[plain]:.1f} -> "
                   f"{rms[cross]:.1f} ppm){why}"), rec


def _measures_bias(opts: TrainOptions, logs: list[ChamberLog]) -> bool:
    """Whether some training log measures the bias (the model will get a bias head)."""
    from fogsf.training.bias_model import measured_windows

    return any(measured_windows(lg, opts.window_s, opts.latitude_deg, opts.settle_s)
               is not None for lg in logs)


def _lstm_inputs(opts: TrainOptions, spec: FeatureSpec) -> int:
    n_in = BANK_LSTM_INPUTS if opts.lstm_inputs is None else opts.lstm_inputs
    if not 1 <= n_in <= spec.n_features:
        raise UserError(f"--lstm-inputs must lie in 1..{spec.n_features} (the model's "
                        f"features), got {n_in}")
    return n_in


def _hysteresis_choice(opts: TrainOptions, logs: list[ChamberLog], base: str) -> dict:
    from fogsf.training.hysteresis_choice import decide
    from fogsf.training.structure_choice import choice_step_s

    # long logs are checked at the structure choice's coarser step (the term is then fitted
    # at the model step)
    return decide(logs, base, choice_step_s(logs, opts.model_step_s), opts.latitude_deg,
                  opts.hysteresis)


def _fit_physics(opts: TrainOptions, logs: list[ChamberLog], hysteresis: bool = False
                 ) -> Fitted:
    """Physics nodes: time constants identified by variable projection on every step of the
    training logs, the quadratic (with cross terms) held fixed in the head, the LSTM on what
    it leaves; with `hysteresis`, a play term too (`models.hysteresis`)."""
    from fogsf.models.physics_nodes import fit_coefficients, identify_taus, node_spec
    from fogsf.training.structure_choice import step_data

    sd = step_data(logs, opts.model_step_s, opts.latitude_deg)
    taus = identify_taus(sd.nodes, sd.y, opts.nodes)
    spec = node_spec(taus)

    def head_fn(ti: TrainingInputs) -> NodeFit:
        return fit_coefficients(*bank_data(ti), taus)

    if hysteresis:
        return _fit_with_term(opts, logs, f"physics{opts.nodes}", spec, sd)
    return _fit_with_spec(opts, logs, spec,
                          _lstm_config(opts, lstm_inputs=_lstm_inputs(opts, spec)),
                          head_fn=head_fn)


def _fit_bank(opts: TrainOptions, logs: list[ChamberLog], hysteresis: bool = False,
              name: str = "bank") -> Fitted:
    """The lag bank (ridge, its quadratic in the head: diagonal, or full with the cross terms)
    and the LSTM on what it leaves; with `hysteresis`, a play term too. `name` carries the
    penalty and the cross terms (`lag_bank.bank_name`)."""
    spec = bank_spec()
    if hysteresis:
        from fogsf.training.structure_choice import step_data

        sd = step_data(logs, opts.model_step_s, opts.latitude_deg)
        return _fit_with_term(opts, logs, name, spec, sd)
    lam, cross = bank_penalty(name), bank_cross(name)
    assert lam is not None
    # the bank's quadratic is diagonal (the head carries quad_w [F], not [F, F]) unless the
    # choice took its cross terms
    return _fit_with_spec(opts, logs, spec,
                          _lstm_config(opts, lstm_inputs=_lstm_inputs(opts, spec),
                                       quad_diag=not cross),
                          head_fn=lambda ti: _fit_bank_head(ti, lam, cross))


def _fit_with_term(opts: TrainOptions, logs: list[ChamberLog], base: str, spec: FeatureSpec,
                   sd: object) -> Fitted:
    """`base` (bank or physicsN with `spec`'s lags) with the play term chosen on every step
    of the training logs, its feature last, its coefficient unpenalised, in the head."""
    from fogsf.models.hysteresis import spec_with_play
    from fogsf.training.hysteresis_choice import final_term, head_fit

    term = final_term(base, sd, spec.taus_s)
    full = spec_with_play(spec, term)

    def head_fn(ti: TrainingInputs) -> BankFit | NodeFit:
        return head_fit(base, *bank_data(ti), spec.taus_s)

    fitted = _fit_with_spec(opts, logs, full,
                            _lstm_config(opts, lstm_inputs=_lstm_inputs(opts, full),
                                         quad_diag=bank_penalty(base) is not None
                                         and not bank_cross(base)),
                            head_fn=head_fn)
    fitted.info["term"] = term.as_dict()
    return fitted


def _fit_node(opts: TrainOptions, train_logs: list[ChamberLog]) -> Fitted:
    if opts.nodes == 2:  # a quadratic form of two nodes, as the physics has it
        spec = effective_node_features(*_identify_two_nodes(opts, train_logs))
        return _fit_with_spec(opts, train_logs, spec, _lstm_config(opts, cubes=False))
    tau, w = opts.node or _identify_node(opts, train_logs)
    spec = effective_node_features((tau, w))
    return _fit_with_spec(opts, train_logs, spec, _lstm_config(opts))


def _identify_node(opts: TrainOptions, logs: list[ChamberLog]) -> tuple[float, float]:
    from fogsf.models.least_squares import profile_effective_node

    fe = front_end_for(logs, opts.model_step_s, ())
    node, _ = profile_effective_node(logs, fe, opts.latitude_deg)
    return node


def _identify_two_nodes(opts: TrainOptions, logs: list[ChamberLog]
                        ) -> list[tuple[float, float]]:
    from fogsf.models.least_squares import profile_two_nodes

    fe = front_end_for(logs, opts.model_step_s, ())
    nodes, _ = profile_two_nodes(logs, fe, opts.latitude_deg)
    return nodes


@dataclass
class TrainingInputs:
    """The logs at the model rate, their normalised features and the output scaling."""

    fe: FrontEnd
    data: list[SeqData]
    norm: Normaliser
    z: list[np.ndarray]
    offset: float
    scale: float


def training_inputs(opts: TrainOptions, logs: list[ChamberLog], spec: FeatureSpec,
                    targets: list[np.ndarray] | None = None,
                    physical: bool = False) -> TrainingInputs:
    """physical: features in one physical unit (`physical_normaliser`), not standardised."""
    fe = front_end_for(logs, opts.model_step_s, spec.taus_s, plays=spec.plays)
    ts = targets if targets is not None else [None] * len(logs)
    data = [prepare(lg, fe, opts.val_chunk, opts.latitude_deg, t, opts.window_s, opts.settle_s)
            for lg, t in zip(logs, ts, strict=True)]
    norm = physical_normaliser(spec) if physical else fit_normaliser(spec, data)
    y = np.concatenate([d.target_ppm[d.train_mask] for d in data])
    return TrainingInputs(fe, data, norm, [norm.apply(d.s) for d in data],
                          float(y.mean()), float(y.std() or 1.0))


def _fit_bank_head(ti: TrainingInputs, lam: float = BANK_LAMBDA, cross: bool = False
                   ) -> BankFit:
    """The lag bank (with its cross terms if `cross`) fitted by ridge (penalty `lam`) to the
    normalised targets of every step of the training logs (the validation part too: it only
    picks the LSTM's iteration, and the bank needs every transient the logs hold)."""
    return fit_bank(*bank_data(ti), lam, curved=n_curved(), cross=cross)


def bank_data(ti: TrainingInputs) -> tuple[np.ndarray, np.ndarray]:
    """(z, y): the normalised features and targets of every measured step of the training
    logs, what the lag bank is fitted to."""
    z = np.concatenate([z[d.measured] for z, d in zip(ti.z, ti.data, strict=True)])
    y = np.concatenate([(d.target_ppm[d.measured] - ti.offset) / ti.scale for d in ti.data])
    return z, y


def bank_compensation(logs: list[ChamberLog], opts: TrainOptions | None = None
                      ) -> Callable[[ChamberLog], np.ndarray]:
    """The lag bank at its prior for `logs` (least squares; the default model's fixed part
    wherever the logs hold fewer than PENALTY_MIN_FOLDS held-out parts,
    `training.structure_choice.bank_prior`) trained on `logs`: a function giving a log's SF
    error prediction (ppm vs nominal) per sample, held over each model step as the kernel
    holds it. Fast (no LSTM), for benches and the planner."""
    from fogsf.training.structure_choice import bank_prior

    ti = training_inputs(opts or TrainOptions(model="lag-lstm"), logs, bank_spec(),
                         physical=True)
    bank = _fit_bank_head(ti, bank_prior(logs, step_s=ti.fe.step_s))

    def predict(log: ChamberLog) -> np.ndarray:
        d = prepare(log, ti.fe, None, None)
        steps = bank.predict(ti.norm.apply(d.s)) * ti.scale + ti.offset
        return expand(steps, len(log), d.decimation)

    return predict


def _fit_with_spec(opts: TrainOptions, logs: list[ChamberLog], spec: FeatureSpec,
                   lstm_cfg: LSTMConfig | None,
                   head_fn: Callable[[TrainingInputs], BankFit | NodeFit] | None = None
                   ) -> Fitted:
    ti = training_inputs(opts, logs, spec, physical=head_fn is not None)
    fe, data, norm, z, offset, scale = ti.fe, ti.data, ti.norm, ti.z, ti.offset, ti.scale
    kind = opts.model
    if kind in ("poly", "polyrate"):
        from fogsf.models.least_squares import fit_linear

        lf = fit_linear(data, z, opts.poly_degree, with_rate=kind == "polyrate")
        return Fitted(kind, spec, fe, lambda d: lf.predict(norm.apply(d.s)), lf.params,
                      4 * lf.params, {"degree": opts.poly_degree,
                                      "coef": lf.coef.tolist(),
                                      "feat_w": norm.feat_w.tolist(),
                                      "feat_b": norm.feat_b.tolist()})
    import torch

    from fogsf.models.nets import count_params, to_stream_model
    from fogsf.training.fit import MLPConfig, predict_stream, train_mlp, train_stream

    if kind == "mlp":
        net, hist = train_mlp(data, z, MLPConfig(seed=opts.seed), offset, scale,
                              opts.progress)

        def predict(d: SeqData) -> np.ndarray:
            with torch.no_grad():
                out = net(torch.from_numpy(norm.apply(d.s))).numpy().astype(np.float64)
            return out * scale + offset

        n = count_params(net)
        return Fitted(kind, spec, fe, predict, n, 4 * n, {"history": hist.as_dict()},
                      torch_state=net.state_dict())
    head = head_fn(ti) if head_fn is not None else None
    net, hist = train_stream(data, z, lstm_cfg, offset, scale, opts.progress, head)
    info: dict = {"history": hist.as_dict(), "hyper": asdict(lstm_cfg)}
    structure = None
    if isinstance(head, NodeFit):
        structure = "physics-nodes"
        info["physics_nodes"] = {"taus_s": list(head.taus_s), "ridge_lambda": head.lam,
                                 "dof": head.dof}
    elif head is not None:
        structure = "lag-bank"
        info["lag_bank"] = {"ridge_lambda": head.lam, "dof": head.dof,
                            "cross_terms": bool(head.quad.ndim == 2)}
    sm = to_stream_model(net, kind, spec, norm, fe, offset, scale,
                         extra={"hyper": asdict(lstm_cfg),
                                **({"structure": structure} if structure else {})})
    n = sm.params  # the artifact's count, as `fogsf export` prints it (filter alphas and the
    # polynomial head included; the torch net holds the LSTM and linear head only)
    return Fitted(kind, spec, fe, lambda d: predict_stream(net, norm.apply(d.s)) * scale
                  + offset, n, 4 * n, info, stream_model=sm, torch_state=net.state_dict())


# --- GSA --------------------------------------------------------------------------------

def gsa_space(kind: str):
    from fogsf.gsa.optimizer import Param

    space = [Param("batch_size", 8, 64, "int"), Param("layers", 1, 3, "int"),
             Param("hidden", 4, 256, "int"), Param("lr", 1e-3, 5e-2, "log-real")]
    if kind == "extended":
        space += [Param("tau_s", 120.0, 7200.0, "log-real"),
                  Param("w", 0.0, 0.5, "real")]
    return space


def gsa_fitness(params: dict, payload: dict) -> float:
    """Validation RMS (ppm) of an LSTM trained with `params` on the payload's logs."""
    import torch

    torch.set_num_threads(1)
    opts: TrainOptions = payload["opts"]
    logs: list[ChamberLog] = payload["logs"]
    node = (params["tau_s"], params["w"]) if "tau_s" in params else payload["node"]
    spec = effective_node_features(tuple(node))
    cfg = _lstm_config(opts, layers=int(params["layers"]), hidden=int(params["hidden"]),
                       batch_size=int(params["batch_size"]), lr=float(params["lr"]),
                       iters=opts.gsa_fitness_iters,
                       eval_every=max(1, opts.gsa_fitness_iters // 4))
    ti = training_inputs(opts, logs, spec, payload["targets"])
    from fogsf.training.fit import train_stream

    _, hist = train_stream(ti.data, ti.z, cfg, ti.offset, ti.scale, False)
    return float(hist.best_val_rms_ppm)


def _fit_gsa(opts: TrainOptions, logs: list[ChamberLog]) -> Fitted:
    from fogsf.gsa.executors import open_executor
    from fogsf.gsa.optimizer import SHORT_BUDGET, minimize

    fe = front_end_for(logs, opts.model_step_s, ())
    targets = [step_targets(lg, fe.at_rate(lg.sample_dt_s).decimation, opts.latitude_deg,
                            opts.settle_s) for lg in logs]
    payload = {"opts": opts, "logs": logs, "targets": targets,
               "node": opts.node or (None if opts.gsa_space == "extended"
                                     else _identify_node(opts, logs))}
    fn = functools.partial(gsa_fitness, payload=payload)
    space = gsa_space(opts.gsa_space)
    t0 = time.perf_counter()
    with open_executor(workers=opts.workers, dask=opts.dask) as ex:
        res = minimize(fn, space, n_agents=opts.gsa_agents, n_iters=opts.gsa_iters,
                       seed=opts.seed, executor=ex, progress=opts.progress,
                       **({} if opts.gsa_paper_constants else SHORT_BUDGET))
    search_s = time.perf_counter() - t0
    best = res.best_params
    node = (best["tau_s"], best["w"]) if "tau_s" in best else payload["node"]
    final = TrainOptions(**{**asdict(opts), "model": "gsa-lstm",
                            "layers": int(best["layers"]), "hidden": int(best["hidden"]),
                            "batch_size": int(best["batch_size"]), "lr": float(best["lr"]),
                            "node": (float(node[0]), float(node[1]))})
    final.iters = opts.iters or lstm_defaults("gsa-lstm")["iters"]
    spec = effective_node_features(final.node)
    fitted = _fit_with_spec(final, logs, spec, _lstm_config(final))
    fitted.info["gsa"] = {"best_params": best, "best_fitness_ppm": res.best_fitness,
                          "best_curve": list(res.best_curve),
                          "mean_curve": list(res.mean_curve), "agents": opts.gsa_agents,
                          "iters": opts.gsa_iters, "fitness_iters": opts.gsa_fitness_iters,
                          "constants": "paper" if opts.gsa_paper_constants else SHORT_BUDGET,
                          "search_seconds": search_s}
    fitted.info["gsa_result"] = res
    return fitted


# --- scoring and saving -----------------------------------------------------------------

def per_sample_prediction(fitted: Fitted, log: ChamberLog, latitude_deg: float | None
                          ) -> np.ndarray:
    d = prepare(log, fitted.fe, None, latitude_deg)
    # a log on disk: the prediction made a block at a time too
    return held(fitted.predict_steps(d), log.time_s, d.decimation)


def score(fitted: Fitted, logs: list[ChamberLog], ref: float, window_s: float,
          latitude_deg: float | None, settle_s: float = SETTLE_S) -> dict:
    """Before/after metrics over `logs` (their windows pooled)."""
    if len(logs) != 1:
        return {f"log{i}": score(fitted, [lg], ref, window_s, latitude_deg, settle_s)
                for i, lg in enumerate(logs)}
    lg = logs[0]
    pred = per_sample_prediction(fitted, lg, latitude_deg)
    return {"before": log_metrics(lg, window_s, ref=ref, latitude_deg=latitude_deg,
                                  settle_s=settle_s),
            "after": log_metrics(lg, window_s, latitude_deg=latitude_deg,
                                 correction_ppm=pred, settle_s=settle_s)}


def run_training(opts: TrainOptions, train_logs: list[ChamberLog],
                 test_log: ChamberLog | None, out_dir: Path) -> tuple[dict, Fitted]:
    """Train, score, and write the model directory; returns metrics.json's content and the
    fitted model."""
    from fogsf.logs.sampling import common_rate
    from fogsf.training import bias_model as bm

    train_logs = common_rate(train_logs)  # other rates, jitter, drops: on one grid of time
    for lg in [*train_logs, *([test_log] if test_log is not None else [])]:
        decimation_for(opts.model_step_s, lg.sample_dt_s, lg.path)  # before the fit, not after
    if bm.check_mixed(train_logs):  # stationary logs alone: a bias-only model
        from fogsf.training.bias_only import train_bias_only

        return train_bias_only(opts, train_logs, test_log, out_dir)  # type: ignore[return-value]
    t0 = time.perf_counter()
    fitted = fit_model(opts, train_logs)
    shared = (None if fitted.stream_model is None else  # the bias head reads the SF's z
              bm.feature_map_of(fitted.stream_model, train_logs, opts.model_step_s))
    sf_seen: dict[int, Column] = {}

    def sf_of(log: ChamberLog) -> Column:  # the SF model's, off the pairs' plateaus
        if id(log) not in sf_seen:  # once a log: the fit and the scores read it
            sf_seen[id(log)] = per_sample_prediction(fitted, log, opts.latitude_deg)
        return sf_seen[id(log)]

    bias = bm.fit_bias(shared, train_logs, opts.window_s, opts.latitude_deg, opts.settle_s,
                       opts.model_step_s, sf_of=sf_of,
                       full_quad=fitted.info.get("lag_bank", {}).get("cross_terms", False))
    if bias is not None and fitted.stream_model is not None:  # one step corrects both
        fitted.stream_model = bm.with_bias_head(fitted.stream_model, bias)
    if fitted.stream_model is not None:  # a diagonal feature map as its diagonal
        fitted.stream_model = diagonal_features(pure_play_rows(fitted.stream_model))
        fitted.params, fitted.weights_bytes = (fitted.stream_model.params,
                                               4 * fitted.stream_model.params)
    train_s = time.perf_counter() - t0
    ref = opts.ref_sf if opts.ref_sf is not None else reference_sf_of_logs(
        train_logs, opts.window_s, opts.latitude_deg, settle_s=opts.settle_s)
    metrics: dict = {"model": fitted.kind, "window_s": opts.window_s,
                     "settle_s": opts.settle_s}
    if test_log is not None:
        test = score(fitted, [test_log], ref, opts.window_s, opts.latitude_deg, opts.settle_s)
        metrics["noise_floor_ppm"] = test["before"]["noise_floor_ppm"]
        metrics["test"] = test
    if test_log is not None and opts.transfer_check:
        metrics["rate_transfer"] = rate_transfer(
            train_logs, test_log, opts.latitude_deg,
            per_sample_prediction(fitted, test_log, opts.latitude_deg),
            step_s=fitted.fe.step_s, window_s=opts.window_s, settle_s=opts.settle_s).as_dict()
    metrics["train"] = score(fitted, train_logs, ref, opts.window_s, opts.latitude_deg,
                             opts.settle_s)
    # every ramp of every training log, read per segment (up and down, several rates a log)
    metrics["train_ramp_rates_c_per_min"] = training_ramp_rates(train_logs)
    metrics["train_ramp_segments"] = [[asdict(sg) for sg in ramp_segments(lg)]
                                      for lg in train_logs]
    if bias is not None:  # the logs measure the bias: its model and before/after (deg/h)
        metrics["bias"] = bm.score_logs(bias, train_logs, test_log, opts.window_s,
                                        opts.latitude_deg, opts.settle_s, sf_of)
    if "noise_floor_ppm" not in metrics:
        first = metrics["train"] if "after" in metrics["train"] else metrics["train"]["log0"]
        metrics["noise_floor_ppm"] = first["before"]["noise_floor_ppm"]
    features, taus = list(fitted.spec.names), list(fitted.spec.taus_s)
    if bias is not None and fitted.stream_model is not None and bias.n_shared:
        # the bias head's own features and filters, after the SF model's (`lead`)
        features += list(bias.fm.names[bias.n_shared:])
        taus += list(bias.fm.fe.filter_tau_s[len(taus):])
    metrics.update({
        "params": fitted.params,
        "weights_bytes": fitted.weights_bytes,
        "features": features,
        "filter_tau_s": taus,
        "decimation": fitted.fe.decimation,
        "model_step_s": fitted.fe.step_s,
        "sample_rate_hz": 1.0 / fitted.fe.sample_dt_s,
        "ref_sf_ratio": ref,
        "exportable": fitted.stream_model is not None,
        "train_seconds": train_s,
        "seed": opts.seed,
        "val_chunk": list(opts.val_chunk),
    })
    if "structure_choice" in fitted.info:
        metrics["structure_choice"] = fitted.info["structure_choice"]
    if "hysteresis_choice" in fitted.info:
        metrics["hysteresis_choice"] = fitted.info["hysteresis_choice"]
    if fitted.stream_model is not None:
        metrics["model_id"] = fitted.stream_model.model_id
        hist = fitted.info.get("history", {})
        # best_iter 0: no training step beat the least-squares start on the validation part,
        # so the model is that start (its LSTM contributes nothing learned)
        metrics["kept_least_squares_start"] = bool(hist.get("best_iter", 1) == 0)
    save(fitted, metrics, out_dir)
    return metrics, fitted


def save(fitted: Fitted, metrics: dict, out_dir: Path) -> None:
    out_dir.mkdir(parents=True, exist_ok=True)
    info = {k: v for k, v in fitted.info.items() if k != "gsa_result"}
    (out_dir / "metrics.json").write_text(json.dumps(metrics, indent=2) + "\n")
    (out_dir / "train_info.json").write_text(json.dumps(
        {"model": fitted.kind, "features": metrics["features"],
         "filter_tau_s": metrics["filter_tau_s"], **info}, indent=2, default=_json) + "\n")
    if fitted.stream_model is not None:
        fitted.stream_model.save(out_dir)
    if fitted.torch_state is not None:
        import torch

        torch.save(fitted.torch_state, out_dir / "model.pt")
    res = fitted.info.get("gsa_result")
    if res is not None:
        res.save_json(out_dir / "gsa_fitness.json")
        res.plot(out_dir / "gsa_fitness.png")


def _json(o: object) -> object:
    if isinstance(o, np.generic):
        return o.item()
    raise TypeError(type(o).__name__)
