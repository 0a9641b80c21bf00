"""Whether the default's structure gets a hysteresis term, chosen by the training logs.

The term (`models.structures.hysteresis`: the play of T or of a mix of the structure's lags, its
coefficient free) is tried only when the training logs turn back in temperature (a play
needs a reversal to show: on a monotonic ramp it is an offset). Then the structure is
scored with and without it on held-out blocks of the training logs: HOLDOUT_BLOCK_S blocks
dealt in turn to HOLDOUT_FOLDS folds, each fold predicted by the structure fitted on the
others (`training.structure.heldout.heldout_score`; the term's source and width chosen on
the fitted blocks only), and the term is kept when it lowers the held-out RMS by more than
HYST_GAIN. Interleaved blocks test what the term adds where the rest of the log holds the
same temperatures; holding out whole ramp segments tests extrapolation instead, whose
errors drowned the term's gain on development gyros (docs/decisions.md). Gyros without
hysteresis keep their structure unless their own logs say otherwise.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from fogsf.logs.chamber_log import ChamberLog
from fogsf.models.structures.hysteresis import (
    HYST_GAIN,
    HystTerm,
    choose_term,
    ridge_fit_free,
    sources,
    term_column,
)
from fogsf.models.structures.lag_bank import (
    BankFit,
    bank_cross,
    bank_design,
    bank_penalty,
    head_terms,
    n_curved,
)
from fogsf.models.structures.least_squares import TAU_GRID_S
from fogsf.models.structures.node_fit import RidgeFit, discrete_lag, lag_alpha
from fogsf.models.structures.physics_nodes import (
    NODE_LAMBDA,
    NodeFit,
    NodeTemperatures,
    head_from_ridge,
    identify_taus,
    node_design,
)
from fogsf.sim.effects import play_operator
from fogsf.training.structure.heldout import (
    Predictor,
    StepData,
    heldout_folds,
    heldout_score,
    part_folds,
    pooled_rms,
    step_data,
)
from fogsf.training.structure.penalty import step_won

REVERSAL_C = 2.0  # a turn back by more than this (C, block means) makes the check run
HOLDOUT_BLOCK_S = 1800.0  # held-out blocks (development gyros, docs/decisions.md)
HOLDOUT_FOLDS = 3
MODES = ("auto", "on", "off")


def has_reversal(t_rel: list[np.ndarray], turn_c: float = REVERSAL_C) -> bool:
    """True when some log's temperature turns back by more than turn_c: a play of that
    width moves both ways."""
    for t in t_rel:
        dp = np.diff(play_operator(t, turn_c))
        if np.any(dp > 0) and np.any(dp < 0):
            return True
    return False


@dataclass
class Structure:
    """A structure's design as a function of the hysteresis column h (h at index `free`)."""

    taus_s: tuple[float, ...]
    lam: float
    free: int
    scale: float  # the target's scale in the fit (the bank fits y / std(y))
    design: Callable[[NodeTemperatures, np.ndarray], np.ndarray]


def structure(name: str, sd: StepData, rows: np.ndarray) -> Structure:
    """The bank (`bank`, `bank:LAM`, `bankx`..., `lag_bank.bank_name`) or `physicsN` (time
    constants identified on `rows`) with a column h."""
    lam = bank_penalty(name)
    if lam is not None:
        cross = bank_cross(name)

        def bank(nt: NodeTemperatures, h: np.ndarray) -> np.ndarray:
            return bank_design(np.column_stack([nt.z(TAU_GRID_S), h]), n_curved(), cross)

        return Structure(TAU_GRID_S, lam, len(TAU_GRID_S) + 1,
                         float(np.std(sd.y[rows])) or 1.0, bank)
    n_nodes = int(name.removeprefix("physics"))
    taus = identify_taus(sd.nodes, sd.y, n_nodes, rows)

    def nodes(nt: NodeTemperatures, h: np.ndarray) -> np.ndarray:
        return node_design(np.column_stack([nt.z(taus), h]), taus)

    return Structure(taus, NODE_LAMBDA, 1 + n_nodes, 1.0, nodes)


def source_temperatures(nt: NodeTemperatures, taus_s: tuple[float, ...]
                        ) -> dict[float, list[np.ndarray]]:
    """Per source (0: T, else a lag's time constant): its temperature per log (C, rel.)."""
    return {src: [t if src == 0 else discrete_lag(t, lag_alpha(src, nt.step_s))
                  for t in nt.t_rel] for src in sources(taus_s)}


def fit_with_term(name: str, sd: StepData, rows: np.ndarray,
                  term: HystTerm | None = None) -> tuple[Predictor, HystTerm, RidgeFit]:
    """Structure `name` with the hysteresis term, fitted on `rows` (the term chosen there
    unless given)."""
    st = structure(name, sd, rows)
    y = sd.y / st.scale
    src_x = source_temperatures(sd.nodes, st.taus_s)
    if term is None:
        term, fit = choose_term(lambda h: st.design(sd.nodes, h), y, rows, src_x, st.lam,
                                st.free)
    else:
        x = st.design(sd.nodes, term_column(src_x, term))
        fit = ridge_fit_free(x[rows], y[rows], st.lam, [st.free])
    chosen = term

    def predict(nt: NodeTemperatures) -> np.ndarray:
        xs = source_temperatures(nt, st.taus_s)
        return fit.predict(st.design(nt, term_column(xs, chosen))) * st.scale

    return predict, term, fit


def final_term(name: str, sd: StepData, taus_s: tuple[float, ...]) -> HystTerm:
    """The term (source mix over T and the structure's lags `taus_s`, width) of structure
    `name` fitted on every step of `sd`."""
    rows = np.arange(sd.y.size)
    if bank_penalty(name) is not None:
        st = structure(name, sd, rows)
    else:
        n_nodes = len(taus_s)

        def nodes(nt: NodeTemperatures, h: np.ndarray) -> np.ndarray:
            return node_design(np.column_stack([nt.z(taus_s), h]), taus_s)

        st = Structure(tuple(taus_s), NODE_LAMBDA, 1 + n_nodes, 1.0, nodes)
    src_x = source_temperatures(sd.nodes, st.taus_s)
    term, _ = choose_term(lambda h: st.design(sd.nodes, h), sd.y / st.scale, rows, src_x,
                          st.lam, st.free)
    return term


def decide(logs: list[ChamberLog], base: str, step_s: float,
           latitude_deg: float | None = None, mode: str = "auto") -> dict:
    """The record of the choice (metrics.json `hysteresis_choice`): `used`, and why."""
    if mode not in MODES:
        raise ValueError(f"hysteresis mode must be one of {', '.join(MODES)}")
    out: dict = {"mode": mode, "base": base, "gain": HYST_GAIN, "used": mode == "on"}
    if mode != "auto":
        return out
    sd = step_data(logs, step_s, latitude_deg)
    if not has_reversal(sd.t_rel):
        out["reason"] = "no reversal in the training logs"
        return out
    block = max(1, int(round(HOLDOUT_BLOCK_S / sd.fe.step_s)))
    sd.fold = (np.arange(sd.y.size) // block) % HOLDOUT_FOLDS
    without = heldout_score(base, sd)
    with_term = heldout_score(base, sd, fit=lambda s, r: fit_with_term(base, s, r)[0])
    out["heldout_rms_ppm"] = {"without": without, "with": with_term}
    out["folds"] = f"{HOLDOUT_FOLDS} folds of {HOLDOUT_BLOCK_S / 60:g} min blocks"
    out["used"] = bool(with_term < (1.0 - HYST_GAIN) * without)
    out["reason"] = (f"held-out RMS {with_term:.2f} ppm with the term, {without:.2f} without: "
                     + ("kept" if out["used"] else f"not {100 * HYST_GAIN:.0f} % better"))
    return out


def cross_with_term(logs: list[ChamberLog], plain: str, cross: str, step_s: float,
                    latitude_deg: float | None = None) -> dict:
    """The bank's cross terms judged again with the hysteresis term in the model: the choice
    took them (`training.structure.penalty.choose_penalty`) on held-out parts fitted
    without it, and beside a play they can mimic the same turning. Both banks (`plain`, the
    one the penalty walk reached, and `cross`) fitted with the term on the same held-out
    parts; the record, its "kept" true when the cross terms still make a step the rule
    takes (`training.structure.penalty.step_won`)."""
    sd = step_data(logs, step_s, latitude_deg)
    sd.fold = part_folds(sd)
    def fit_of(n: str) -> Callable[[StepData, np.ndarray], Predictor]:
        return lambda s, r: fit_with_term(n, s, r)[0]

    folds = {n: heldout_folds(n, sd, fit=fit_of(n)) for n in (plain, cross)}
    wins, kept = step_won(folds[cross], folds[plain])
    rms = {n: pooled_rms(f) for n, f in folds.items()}
    return {"kept": bool(kept), "wins": wins, "parts": sd.n_folds, "heldout_rms_ppm": rms}


def choice_line(d: dict) -> str:
    """What `fogsf train` prints about the hysteresis term."""
    term = f" {d['term']['form']}" if d.get("term") else ""
    if d["mode"] != "auto":
        return f"hysteresis term{term}: {'on' if d['used'] else 'off'} (--hysteresis {d['mode']})"
    return (f"hysteresis term{term}: {'used' if d['used'] else 'not used'} "
            f"({d.get('reason', '')})")


def bank_head(z: np.ndarray, fit: RidgeFit, lam: float, cross: bool = False) -> BankFit:
    """A ridge fit of bank_design(z, n_curved(), cross) (h the last feature, linear) with
    penalty `lam` as a BankFit."""
    lin, quad, cube = head_terms(fit.coef, z.shape[1], n_curved(), cross)
    return BankFit(fit.intercept, lin, quad, cube, lam, fit.dof)


def node_head(z: np.ndarray, fit: RidgeFit, taus_s: tuple[float, ...]) -> NodeFit:
    return head_from_ridge(fit, z.shape[1], taus_s, NODE_LAMBDA)


def head_fit(name: str, z: np.ndarray, y: np.ndarray, taus_s: tuple[float, ...]
             ) -> BankFit | NodeFit:
    """The structure's head over features z whose last is the hysteresis feature (from the
    front end), its coefficient unpenalised: what the firmware carries."""
    f = z.shape[1] - 1
    lam = bank_penalty(name)
    if lam is not None:
        cross = bank_cross(name)
        fit = ridge_fit_free(bank_design(z, n_curved(), cross), y, lam, [f])
        return bank_head(z, fit, lam, cross)
    fit = ridge_fit_free(node_design(z, taus_s), y, NODE_LAMBDA, [f])
    return node_head(z, fit, taus_s)
