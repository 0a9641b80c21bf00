"""One feature spec fitted: the least-squares polynomials (poly, polyrate) here, the nets
(mlp, the LSTMs) by `training.net.spec_nets`; and the effective node(s) a spec of T_eff reads,
identified from the training logs."""

from __future__ import annotations

from collections.abc import Callable

from fogsf.logs.chamber_log import ChamberLog
from fogsf.models.features import FeatureSpec, front_end_for
from fogsf.models.structures.lag_bank import BankFit
from fogsf.models.structures.least_squares import (
    fit_linear,
    profile_effective_node,
    profile_two_nodes,
)
from fogsf.models.structures.physics_nodes import NodeFit
from fogsf.training.fitted_model import Fitted
from fogsf.training.inputs import TrainingInputs, training_inputs
from fogsf.training.net.config import LSTMConfig
from fogsf.training.options import TrainOptions


def fit_with_spec(opts: TrainOptions, logs: list[ChamberLog], spec: FeatureSpec,
                  lstm_cfg: LSTMConfig | None,
                  head_fn: Callable[[TrainingInputs], BankFit | NodeFit] | None = None
                  ) -> Fitted:
    """`opts.model` on `spec`'s features of `logs`; `head_fn` gives the least-squares part the
    LSTM's head carries (features then in one physical unit, not standardised)."""
    ti = training_inputs(opts, logs, spec, physical=head_fn is not None)
    norm = ti.norm
    kind = opts.model
    if kind in ("poly", "polyrate"):
        lf = fit_linear(ti.data, ti.z, opts.poly_degree, with_rate=kind == "polyrate")
        return Fitted(kind, spec, ti.fe, lambda d: lf.predict(norm.apply(d.s)), lf.params,
                      4 * lf.params, {"degree": opts.poly_degree,
                                      "coef": lf.coef.tolist(),
                                      "feat_w": norm.feat_w.tolist(),
                                      "feat_b": norm.feat_b.tolist()})
    # torch: loaded for the nets only (poly, polyrate and `fogsf train --help` go without)
    from fogsf.training.net import spec_nets

    if kind == "mlp":
        return spec_nets.fit_mlp(opts, spec, ti)
    assert lstm_cfg is not None
    head = head_fn(ti) if head_fn is not None else None
    return spec_nets.fit_lstm(opts, spec, ti, lstm_cfg, head)


def identify_node(opts: TrainOptions, logs: list[ChamberLog]) -> tuple[float, float]:
    """(tau_s, w) of one effective node T_eff, profiled over a grid on the training logs."""
    fe = front_end_for(logs, opts.model_step_s, ())
    node, _ = profile_effective_node(logs, fe, opts.latitude_deg)
    return node


def identify_two_nodes(opts: TrainOptions, logs: list[ChamberLog]
                       ) -> list[tuple[float, float]]:
    """Two effective nodes' (tau_s, w), profiled on the training logs."""
    fe = front_end_for(logs, opts.model_step_s, ())
    nodes, _ = profile_two_nodes(logs, fe, opts.latitude_deg)
    return nodes
