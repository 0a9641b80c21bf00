"""gsa-lstm: GSA searches the LSTM's batch size, layers, hidden units and learning rate
(Table 1's four) and, in the extended space, (tau, w) of T_eff; the fitness is the RMS on the
validation part of the training logs (never the test log). Torch at the top: the fitness
trains an LSTM in every agent (`training.sf.fit` loads this module for gsa-lstm only)."""

from __future__ import annotations

import functools
import time
from dataclasses import asdict
from typing import TypedDict

import numpy as np
import torch

from fogsf.gsa.executors import open_executor
from fogsf.gsa.optimizer import SHORT_BUDGET, Param, minimize
from fogsf.logs.chamber_log import ChamberLog
from fogsf.models.features import effective_node_features, front_end_for, step_targets
from fogsf.training.fitted_model import Fitted
from fogsf.training.inputs import training_inputs
from fogsf.training.net.config import lstm_config, lstm_defaults
from fogsf.training.net.loops import train_stream
from fogsf.training.options import TrainOptions
from fogsf.training.sf.feature_spec import fit_with_spec, identify_node


def gsa_space(kind: str) -> list[Param]:
    space = [Param("batch_size", 8, 64, "int"), Param("layers", 1, 3, "int"),
             Param("hidden", 4, 256, "int"), Param("lr", 1e-3, 5e-2, "log-real")]
    if kind == "extended":
        space += [Param("tau_s", 120.0, 7200.0, "log-real"),
                  Param("w", 0.0, 0.5, "real")]
    return space


class Payload(TypedDict):
    """What every fitness call is given (pickled to worker processes)."""

    opts: TrainOptions
    logs: list[ChamberLog]
    targets: list[np.ndarray]
    node: tuple[float, float] | None  # None: searched (the extended space)


def gsa_fitness(params: dict, payload: Payload) -> float:
    """Validation RMS (ppm) of an LSTM trained with `params` on the payload's logs."""
    torch.set_num_threads(1)
    opts: TrainOptions = payload["opts"]
    logs: list[ChamberLog] = payload["logs"]
    node = (params["tau_s"], params["w"]) if "tau_s" in params else payload["node"]
    assert node is not None  # searched when not given
    spec = effective_node_features(tuple(node))
    cfg = lstm_config(opts, layers=int(params["layers"]), hidden=int(params["hidden"]),
                      batch_size=int(params["batch_size"]), lr=float(params["lr"]),
                      iters=opts.gsa_fitness_iters,
                      eval_every=max(1, opts.gsa_fitness_iters // 4))
    ti = training_inputs(opts, logs, spec, payload["targets"])
    _, hist = train_stream(ti.data, ti.z, cfg, ti.offset, ti.scale, False)
    return float(hist.best_val_rms_ppm)


def fit_gsa(opts: TrainOptions, logs: list[ChamberLog]) -> Fitted:
    """The search, then the best agent's LSTM trained at the full budget."""
    fe = front_end_for(logs, opts.model_step_s, ())
    targets = [step_targets(lg, fe.at_rate(lg.sample_dt_s).decimation, opts.latitude_deg,
                            opts.settle_s) for lg in logs]
    payload: Payload = {"opts": opts, "logs": logs, "targets": targets,
                        "node": opts.node or (None if opts.gsa_space == "extended"
                                              else identify_node(opts, logs))}
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
    assert node is not None  # searched when not given
    final_node = (float(node[0]), float(node[1]))
    final = TrainOptions(**{**asdict(opts), "model": "gsa-lstm",
                            "layers": int(best["layers"]), "hidden": int(best["hidden"]),
                            "batch_size": int(best["batch_size"]), "lr": float(best["lr"]),
                            "node": final_node})
    final.iters = opts.iters or lstm_defaults("gsa-lstm")["iters"]
    spec = effective_node_features(final_node)
    fitted = fit_with_spec(final, logs, spec, lstm_config(final))
    fitted.info["gsa"] = {"best_params": best, "best_fitness_ppm": res.best_fitness,
                          "best_curve": list(res.best_curve),
                          "mean_curve": list(res.mean_curve), "agents": opts.gsa_agents,
                          "iters": opts.gsa_iters, "fitness_iters": opts.gsa_fitness_iters,
                          "constants": "paper" if opts.gsa_paper_constants else SHORT_BUDGET,
                          "search_seconds": search_s}
    fitted.info["gsa_result"] = res
    return fitted
