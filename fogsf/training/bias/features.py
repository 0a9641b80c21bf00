"""The bias model's features z: what gives them for a log (`FeatureMap`: a front end and
z = feat_w s + feat_b, the kernel's order), the SF model's own z when its artifact has a
firmware form (`feature_map_of`), else the lag bank's, the `cubic`, `shupe` and `node`
structures' and the `lead` structure's on front ends of their own, and the SF model's z
followed by a bias structure's own features (`with_rows`)."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from fogsf.logs.chamber_log import ChamberLog
from fogsf.models.features import FeatureSpec, front_end_for, physical_normaliser
from fogsf.models.front_end import FrontEnd
from fogsf.models.reference import features as ref_features
from fogsf.models.step_inputs import frontend_s
from fogsf.models.stream import StreamModel
from fogsf.models.structures.lag_bank import bank_spec, n_curved
from fogsf.models.structures.physics_nodes import node_spec


@dataclass(frozen=True)
class FeatureMap:
    """What gives z for a log: the front end and z = feat_w s + feat_b (float32, the
    kernel's order)."""

    fe: FrontEnd
    feat_w: np.ndarray  # [F, 1+K] float32
    feat_b: np.ndarray  # [F] float32
    curved: int  # features (from the first) that carry squares and cubes
    names: tuple[str, ...] = ()  # the features' names, where known

    @property
    def weights(self) -> dict[str, np.ndarray]:  # what reference.features reads
        return {"feat_w": self.feat_w, "feat_b": self.feat_b}

    def z(self, log: ChamberLog) -> np.ndarray:
        """[n_steps, F] float32: the features of every model step of the log from reset."""
        s = frontend_s(log.temp_c, self.fe.at_rate(log.sample_dt_s))  # a block at a time
        return ref_features(self, s)  # type: ignore[arg-type]


def bank_curved(n_features: int, n_plays: int = 0) -> int:
    """Curved features for z of `n_features`: the bank's rule for the lag bank (its plays'
    features after it linear, as the SF model has them), all else."""
    return n_curved() if n_features - n_plays == bank_spec().n_features else n_features


def with_rows(fm: FeatureMap, own: FeatureMap) -> FeatureMap:
    """The SF model's features `fm` followed by `own`'s (a bias structure's, on filters of
    its own): the front end runs fm's filters, then own's, then fm's plays; fm's rows read
    none of own's filters and its plays none of them, so fm's z is unchanged."""
    k, k_own, p = fm.fe.filter_alpha.size, own.fe.filter_alpha.size, fm.fe.n_plays
    if own.fe.n_plays or own.fe.decimation != fm.fe.decimation:
        raise ValueError("the bias features' front end differs from the SF model's")
    rows_sf = np.insert(fm.feat_w, [1 + k] * k_own, 0.0, axis=1)
    rows_own = np.zeros((own.feat_w.shape[0], 1 + k + k_own + p), np.float32)
    rows_own[:, 0] = own.feat_w[:, 0]
    rows_own[:, 1 + k:1 + k + k_own] = own.feat_w[:, 1:]
    if len(fm.fe.filter_tau_s) != k:
        raise ValueError("the SF model's filters' time constants are unknown")
    fe = replace(fm.fe, filter_alpha=np.concatenate([fm.fe.filter_alpha, own.fe.filter_alpha]
                                                    ).astype(np.float32),
                 filter_tau_s=(*fm.fe.filter_tau_s, *own.fe.filter_tau_s),
                 play_source_w=tuple((*r[:1 + k], *([0.0] * k_own), *r[1 + k:])
                                     for r in fm.fe.play_source_w))
    return FeatureMap(fe, np.concatenate([rows_sf, rows_own]).astype(np.float32),
                      np.concatenate([fm.feat_b, own.feat_b]).astype(np.float32), fm.curved,
                      (*(fm.names or ("",) * fm.feat_w.shape[0]), *own.names))


def lead_feature_map(logs: list[ChamberLog], step_s: float, tau_c: float, w: float,
                     fast_s: float | None, with_t: bool = True) -> FeatureMap:
    """The lead structure's features on a front end of its own (one physical unit): T (if
    `with_t`), lag(T, fast_s) (if given) and the node w T + (1 - w) lag(T, tau_c), in
    that order."""
    taus = ((fast_s,) if fast_s is not None else ()) + (tau_c,)
    k = len(taus)
    rows: list[tuple[float, ...]] = []
    names: list[str] = []
    if with_t:
        rows.append((1.0,) + (0.0,) * k)
        names.append("T")
    if fast_s is not None:
        rows.append((0.0, 1.0) + (0.0,) * (k - 1))
        names.append(f"lag(T,{fast_s:.0f}s)")
    rows.append((w,) + (0.0,) * (k - 1) + (1.0 - w,))
    names.append(f"node(T,{tau_c:.0f}s,w={w:.3f})")
    spec = FeatureSpec(taus, tuple(rows), tuple(names))
    norm = physical_normaliser(spec)
    return FeatureMap(front_end_for(logs, step_s, taus), norm.feat_w, norm.feat_b,
                      len(rows), spec.names)


def node_feature_map(logs: list[ChamberLog], step_s: float,
                     taus_s: tuple[float, ...]) -> FeatureMap:
    """T and lags of T at `taus_s` (one physical unit) on a front end of their own: a
    bias-only model's features for the `cubic`, `shupe` and `node` structures."""
    norm = physical_normaliser(node_spec(taus_s))
    return FeatureMap(front_end_for(logs, step_s, taus_s), norm.feat_w, norm.feat_b,
                      1 + len(taus_s))


def bank_feature_map(logs: list[ChamberLog], step_s: float) -> FeatureMap:
    """The lag bank's z (T and its lags, one physical unit) with its own front end: the
    bias-only model's features, and the bias's for SF models without a firmware form."""
    spec = bank_spec()
    norm = physical_normaliser(spec)
    return FeatureMap(front_end_for(logs, step_s, spec.taus_s), norm.feat_w, norm.feat_b,
                      n_curved())


def feature_map_of(stream_model: StreamModel | None, logs: list[ChamberLog],
                   step_s: float) -> FeatureMap:
    """The SF model's own z when it has a firmware form (the bias head reads the same
    state), else the lag bank's."""
    if stream_model is None:
        return bank_feature_map(logs, step_s)
    w = stream_model.weights
    return FeatureMap(stream_model.front_end, w["feat_w"], w["feat_b"],
                      bank_curved(stream_model.n_features, stream_model.n_plays))
