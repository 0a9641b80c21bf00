"""A model from plateau tables (docs/train.md, "Plateau tables"): the form `rate_choice` picks,
fitted by least squares on every plateau, written as a streaming artifact whose thermal
part is static (no filter: a plateau's mean temperature is all a table holds), the SF and
bias heads cubic in tau = (T - t_ref) / TEMP_SCALE_C, and the rate part on the thermally
corrected output.

The rate part reads c, not the raw output, so its terms are fitted on c: the fit alternates
FIXED_POINT_PASSES times between the heads (which give c) and the whole form on x = c / FS;
the heads move c by the SF offset (ppm to per mille), so the passes settle at once."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fogsf.logs.measure.table_figures import temperature_groups
from fogsf.models.stream import StreamModel
from fogsf.models.structures.rate_choice import FormChoice, RateRows, choose_form
from fogsf.models.structures.rate_forms import (
    TEMP_SCALE_C,
    RateForm,
    design,
    solve,
)

FIXED_POINT_PASSES = 3
HEAD_DEGREE = 3  # the heads' cubic in z
MODEL_STEP_S = 1.0  # firmware: the static heads step once a second
SAMPLE_DT_S = 0.01  # the artifact's nominal rate (100 Hz); `StreamModel.at_rate` re-rates it
RANGE_MARGIN = 1.0  # t_min/t_max: the training range widened by this part of its span
STUCK_S = 60.0
# the rate part's full scale over the largest training |rate|: the top plateaus' noise and
# SF stay inside it, so RATE_CLAMPED means a rate the tables never reached
FS_HEADROOM = 1.05


@dataclass(frozen=True)
class PlateauRows:
    """The measuring plateaus of one or more tables, stacked in time order: the mean output,
    the rate the gyro sensed (table + earth), the mean temperature."""

    gyro_dps: np.ndarray
    rate_dps: np.ndarray
    temp_c: np.ndarray

    def __len__(self) -> int:
        return int(self.gyro_dps.shape[0])

    @property
    def rates_measured(self) -> int:
        """How many distinct nonzero |rate| the rows hold, to 0.1 % of the largest (the
        earth rate on + and - plateaus is one |rate|)."""
        mag = np.abs(self.rate_dps) / np.max(np.abs(self.rate_dps))
        return int(np.unique(np.round(mag[mag > 1e-3], 3)).size)


@dataclass(frozen=True)
class PlateauFit:
    """The fitted model and what chose it."""

    model: StreamModel
    form: RateForm
    choice: FormChoice
    full_scale_dps: float
    linear_score_dph: float  # the best linear-SF form's held-out RMS
    rate_part_allowed: bool

    @property
    def heldout_dph(self) -> float:
        """The chosen form's held-out RMS (deg/h)."""
        return self.choice.score * self.full_scale_dps * 3600.0


def choice_rows(rows: PlateauRows, fs: float, t_ref: float) -> RateRows:
    return RateRows(rows.gyro_dps / fs, (rows.temp_c - t_ref) / TEMP_SCALE_C,
                    (rows.rate_dps - rows.gyro_dps) / fs,
                    temperature_groups(rows.temp_c), np.arange(len(rows)))


def _split(coef: np.ndarray, form: RateForm) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(beta0 [Q+1], beta1 [Q+1], rate [R, R_T+1]) of a form's coefficients (`design`'s
    column order); the rate rows as `rate_terms` orders them, zero where the form has no term."""
    q = form.temp_degree + 1
    b0, b1, rest = coef[:q], coef[q:2 * q], coef[2 * q:]
    rate = np.zeros((max(form.powers - 1, 0) + 1, form.rate_temp_degree + 1))
    held = ([0] if form.abs_term else []) + [p - 1 for p in form.power_list]
    rate[held] = rest.reshape(len(held), form.rate_temp_degree + 1)
    return b0, b1, rate


def _heads(b0: np.ndarray, b1: np.ndarray, fs: float, lo: float, hi: float, t_ref: float
           ) -> tuple[np.ndarray, np.ndarray]:
    """The SF (ppm) and bias (deg/h) heads' cubics in tau, fitted over [lo, hi] to what the
    form says: c = (g - b)(1 - k) = g (1 + beta1) + FS beta0, so k = -beta1 (sf = k/(1-k))
    and b = -FS beta0 / (1 + beta1)."""
    tau = (np.linspace(lo, hi, 401) - t_ref) / TEMP_SCALE_C
    p0 = np.polynomial.polynomial.polyval(tau, b0)
    p1 = np.polynomial.polynomial.polyval(tau, b1)
    sf_ppm = -p1 / (1.0 + p1) * 1e6
    bias_dph = -fs * p0 / (1.0 + p1) * 3600.0
    return (np.polynomial.polynomial.polyfit(tau, sf_ppm, HEAD_DEGREE),
            np.polynomial.polynomial.polyfit(tau, bias_dph, HEAD_DEGREE))


def _thermal_output(g: np.ndarray, tau: np.ndarray, sf_c: np.ndarray, bias_c: np.ndarray
                    ) -> np.ndarray:
    """c of the heads in float64: (g - b / 3600) / (1 + sf * 1e-6)."""
    sf = np.polynomial.polynomial.polyval(tau, sf_c)
    b = np.polynomial.polynomial.polyval(tau, bias_c)
    return (g - b / 3600.0) / (1.0 + sf * 1e-6)


def _fit_on_c(rows: PlateauRows, form: RateForm, fs: float, t_ref: float, lo: float, hi: float
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(sf cubic, bias cubic, rate [R, R_T+1] in FS units) with the rate terms on c."""
    g, w = rows.gyro_dps, rows.rate_dps
    tau = (rows.temp_c - t_ref) / TEMP_SCALE_C
    c = g.copy()
    for _ in range(FIXED_POINT_PASSES):
        a_lin = design(g / fs, tau, RateForm(1, False, form.temp_degree, 0))
        a_rate = design(c / fs, tau, form)[:, a_lin.shape[1]:]
        coef = solve(np.hstack([a_lin, a_rate]), (w - g) / fs)
        b0, b1, rate = _split(coef, form)
        sf_c, bias_c = _heads(b0, b1, fs, lo, hi, t_ref)
        c = _thermal_output(g, tau, sf_c, bias_c)
    return sf_c, bias_c, rate


def plateau_artifact(sf_c: np.ndarray, bias_c: np.ndarray, rate: np.ndarray | None, fs: float,
                     t_ref: float, lo: float, hi: float, extra: dict) -> StreamModel:
    """The streaming artifact: K = 0, F = 1 (z = (Tm - t_ref) / TEMP_SCALE_C, feat_diag), a
    1 x 1 LSTM with zero weights, the SF cubic in the polynomial head (diagonal), the bias
    head, and the rate part (rate_w in deg/s per s0^q) when `rate` is given."""
    f32 = np.float32
    weights = {k: np.zeros(s, f32) for k, s in (("lstm0_w", (4, 1)), ("lstm0_r", (4, 1)),
                                                ("lstm0_b", (8,)), ("head_w", (1,)),
                                                ("out_offset", (1,)))}
    weights.update({
        "filter_alpha": np.zeros(0, f32), "feat_w": np.array([1.0 / TEMP_SCALE_C], f32),
        "feat_b": np.zeros(1, f32), "out_scale": np.ones(1, f32),
        "head_b": np.array([sf_c[0]], f32), "skip_w": np.array([sf_c[1]], f32),
        "quad_w": np.array([sf_c[2]], f32), "cube_w": np.array([sf_c[3]], f32),
        "bias_b": np.array([bias_c[0]], f32), "bias_w": np.array([bias_c[1]], f32),
        "bias_quad_w": np.array([bias_c[2]], f32), "bias_cube_w": np.array([bias_c[3]], f32)})
    if rate is not None:  # a_r(s0) = -FS sum_q rate[r, q] (s0 / TEMP_SCALE_C)^q, in deg/s
        scale = TEMP_SCALE_C ** -np.arange(rate.shape[1], dtype=np.float64)
        weights["rate_w"] = (-fs * rate * scale).astype(f32)
    decimation = int(round(MODEL_STEP_S / SAMPLE_DT_S))
    model = StreamModel(model="plateau", decimation=decimation, t_ref_c=t_ref, t_min_c=lo,
                        t_max_c=hi, stuck_samples=int(STUCK_S / SAMPLE_DT_S), filter_tau_s=[],
                        n_features=1, layers=1, hidden=1, weights=weights,
                        sample_dt_s=SAMPLE_DT_S, poly_head=True, quad_diag=True,
                        bias_head=True, feat_diag=True,
                        rate_fs_dps=fs if rate is not None else 0.0, extra=extra)
    model.validate()
    return model


def fit_plateau_model(rows: PlateauRows, form: RateForm | None = None) -> PlateauFit:
    """The model of `rows`: `form` when given, else the one `choose_form` picks (rate terms
    only when the rows measure two |rates| or more)."""
    fs = float(np.ceil(FS_HEADROOM * np.max(np.abs(rows.rate_dps))))
    t_lo, t_hi = float(rows.temp_c.min()), float(rows.temp_c.max())
    t_ref = round(0.5 * (t_lo + t_hi), 1)
    margin = RANGE_MARGIN * (t_hi - t_lo)
    lo, hi = round(t_lo - margin, 1), round(t_hi + margin, 1)
    allowed = rows.rates_measured >= 2
    choice = choose_form(choice_rows(rows, fs, t_ref), allow_rate_part=allowed)
    linear = min(s for f, s in choice.scores.items() if not f.has_rate_part)
    pick = form or choice.form
    sf_c, bias_c, rate = _fit_on_c(rows, pick, fs, t_ref, lo, hi)
    extra = {"structure": "plateau", "rate_form": pick.describe()}
    model = plateau_artifact(sf_c, bias_c, rate if pick.has_rate_part else None, fs, t_ref,
                             lo, hi, extra)
    return PlateauFit(model, pick, choice, fs, linear * fs * 3600.0, allowed)

