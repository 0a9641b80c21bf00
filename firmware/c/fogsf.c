/*
 * The fixed-size model path of the kernel: front end (sanitise, clamp, stuck detection,
 * block means, lag filters), model step (features, LSTM layers, head with the optional
 * polynomial terms) and the per-sample correction, exactly in the float32 order of
 * docs/stream-contract.md (with the optional narrowed LSTM input, diagonal quadratic and
 * diagonal feature map). Sizes and weights come from the model struct at run time; the
 * state arrays are sized by FOGSF_MAX_* (fogsf_model_check).
 */
#include "fogsf.h"

typedef union {
    float f;
    uint32_t u;
} f32_bits;

static uint32_t float_bits(float v)
{
    f32_bits b;
    b.f = v;
    return b.u;
}

static int float_finite(float v)
{
    return (float_bits(v) & 0x7f800000u) != 0x7f800000u;
}

static int double_finite(double v)
{
    return v - v == 0.0; /* Inf - Inf and NaN - NaN are NaN */
}

/* The plays of m: its fogsf_play_model when m is the sf member of one's base, else NULL. */
static const fogsf_play_model *plays_of(const fogsf_model *m)
{
    return m->format_version == FOGSF_FORMAT_PLAYS ? (const fogsf_play_model *)(const void *)m
                                                   : NULL;
}

/* The bias head of m: its fogsf_bias_model when m is the sf member of one with a bias head
 * (format 4, or format 5 with the bias arrays set), else NULL. */
static const fogsf_bias_model *bias_of(const fogsf_model *m)
{
    const fogsf_bias_model *b;
    if (m->format_version != FOGSF_FORMAT_BIAS && m->format_version != FOGSF_FORMAT_PLAYS) {
        return NULL;
    }
    b = (const fogsf_bias_model *)(const void *)m;
    return m->format_version == FOGSF_FORMAT_PLAYS && b->bias_w == NULL ? NULL : b;
}

static uint32_t n_plays_of(const fogsf_model *m)
{
    const fogsf_play_model *p = plays_of(m);
    return p != NULL ? p->n_plays : 0u;
}

uint32_t fogsf_model_check(const fogsf_model *m)
{
    const fogsf_bias_model *b;
    const fogsf_play_model *p;
    uint32_t j;
    if (m == NULL || m->n_filters > FOGSF_MAX_FILTERS || m->n_features > FOGSF_MAX_FEATURES ||
        m->n_features < 1u || m->layers > FOGSF_MAX_LAYERS || m->layers < 1u ||
        m->hidden > FOGSF_MAX_HIDDEN || m->hidden < 1u || m->decimation < 1u ||
        (m->n_filters > 0u && m->filter_alpha == NULL) || m->feat_w == NULL ||
        m->feat_b == NULL || m->lstm_w == NULL || m->lstm_r == NULL || m->lstm_b == NULL ||
        m->head_w == NULL || m->skip_w == NULL || (m->quad_w == NULL) != (m->cube_w == NULL) ||
        m->lstm_inputs > m->n_features || m->quad_diag > 1u ||
        (m->quad_diag != 0u && m->quad_w == NULL) || m->feat_diag > 1u) {
        return FOGSF_FLAG_MODEL_INVALID;
    }
    p = plays_of(m);
    if (p != NULL) {
        if (p->n_plays < 1u || p->n_plays > FOGSF_MAX_PLAYS || p->play_half_c == NULL ||
            p->play_source_w == NULL || (p->base.bias_w == NULL) != (p->base.bias_quad_w == NULL) ||
            (p->base.bias_w == NULL) != (p->base.bias_cube_w == NULL)) {
            return FOGSF_FLAG_MODEL_INVALID;
        }
        for (j = 0; j < p->n_plays; ++j) {
            uint32_t i;
            if (!(p->play_half_c[j] >= 0.0f) || !float_finite(p->play_half_c[j])) {
                return FOGSF_FLAG_MODEL_INVALID;
            }
            for (i = 0; i <= m->n_filters; ++i) {
                if (!float_finite(p->play_source_w[j * (m->n_filters + 1u) + i])) {
                    return FOGSF_FLAG_MODEL_INVALID;
                }
            }
        }
    }
    b = bias_of(m);
    if (b != NULL && (b->bias_w == NULL || b->bias_quad_w == NULL || b->bias_cube_w == NULL)) {
        return FOGSF_FLAG_MODEL_INVALID;
    }
    /* a diagonal feat_w maps s (1+K+P entries, P checked above) onto F features one to one */
    if (m->feat_diag != 0u &&
        m->n_features != 1u + m->n_filters + (p != NULL ? p->n_plays : 0u)) {
        return FOGSF_FLAG_MODEL_INVALID;
    }
    return 0u;
}

uint32_t fogsf_reset(const fogsf_model *m, fogsf_state *st)
{
    int l, j;
    for (l = 0; l < FOGSF_MAX_LAYERS; ++l) {
        for (j = 0; j < FOGSF_MAX_HIDDEN; ++j) {
            st->h[l][j] = 0.0f;
            st->c[l][j] = 0.0f;
        }
    }
    for (j = 0; j < FOGSF_MAX_HIDDEN; ++j) {
        st->h_prev[j] = 0.0f;
    }
    for (j = 0; j < FOGSF_MAX_FEATURES; ++j) {
        st->z[j] = 0.0f;
    }
    for (j = 0; j < FOGSF_MAX_FILTERS; ++j) {
        st->y[j] = 0.0f;
    }
    for (j = 0; j < FOGSF_MAX_PLAYS; ++j) {
        st->p[j] = 0.0f;
    }
    st->acc = 0.0f;
    st->t_last_good = m != NULL ? m->t_ref_c : 0.0f;
    st->sf_ppm = 0.0f;
    st->bias_dph = 0.0f;
    st->bias_dps = 0.0;
    st->sf_flags = 0u;
    st->raw_prev_bits = 0u;
    st->stuck_run = 0u;
    st->n_acc = 0u;
    st->started = 0u;
    return fogsf_model_check(m);
}

uint32_t fogsf_init(const fogsf_model *m, fogsf_state *st)
{
    return fogsf_reset(m, st);
}

/* The bias head on the features z of this step (deg/h): the bias, then the squares, then
 * the cubes, index order; NaN or beyond +-FOGSF_BIAS_LIMIT_DPH is clamped and flagged. */
static void bias_step(const fogsf_model *m, fogsf_state *st)
{
    const fogsf_bias_model *b = bias_of(m);
    const uint32_t nf = m->n_features;
    float y, mag;
    uint32_t i;

    if (b == NULL) {
        return; /* bias_dph stays 0 */
    }
    y = b->bias_b;
    for (i = 0; i < nf; ++i) {
        y = y + b->bias_w[i] * st->z[i];
    }
    for (i = 0; i < nf; ++i) {
        y = y + b->bias_quad_w[i] * (st->z[i] * st->z[i]);
    }
    for (i = 0; i < nf; ++i) {
        y = y + b->bias_cube_w[i] * ((st->z[i] * st->z[i]) * st->z[i]);
    }
    mag = y < 0.0f ? -y : y;
    if (!(mag <= FOGSF_BIAS_LIMIT_DPH)) {
        y = y > 0.0f ? FOGSF_BIAS_LIMIT_DPH : (y < 0.0f ? -FOGSF_BIAS_LIMIT_DPH : 0.0f);
        st->sf_flags |= FOGSF_FLAG_BIAS_CLAMPED;
    }
    st->bias_dph = y;
    st->bias_dps = (double)y / 3600.0; /* once per model step, not per sample */
}

/* Contract step 4: one model step on the block-mean temperature tm. */
static void model_step(const fogsf_model *m, fogsf_state *st, float tm)
{
    float s[1 + FOGSF_MAX_FILTERS + FOGSF_MAX_PLAYS];
    float y, sf, mag;
    const float *x = st->z;
    const fogsf_play_model *pm = plays_of(m);
    const uint32_t nk = m->n_filters, nf = m->n_features, nh = m->hidden,
                   np = pm != NULL ? pm->n_plays : 0u, ni = 1u + nk + np;
    size_t n_in = m->lstm_inputs != 0u ? m->lstm_inputs : nf; /* layer 0 reads z[0:n_in] */
    uint32_t k, f, l, j;

    for (k = 0; k < nk; ++k) {
        st->y[k] = st->y[k] + m->filter_alpha[k] * (tm - st->y[k]);
    }
    s[0] = tm - m->t_ref_c;
    for (k = 0; k < nk; ++k) {
        s[1 + k] = st->y[k] - m->t_ref_c;
    }
    for (k = 0; k < np; ++k) { /* the play operators, after the filters */
        const float *v = pm->play_source_w + k * (nk + 1u);
        float xin = 0.0f, lo, hi;
        xin = xin + v[0] * tm;
        for (j = 0; j < nk; ++j) {
            xin = xin + v[1u + j] * st->y[j];
        }
        lo = xin - pm->play_half_c[k];
        hi = xin + pm->play_half_c[k];
        st->p[k] = st->p[k] < lo ? lo : (st->p[k] > hi ? hi : st->p[k]);
        s[1 + nk + k] = st->p[k] - m->t_ref_c;
    }
    if (m->feat_diag != 0u) { /* the diagonal only: feat_w [F], F == 1+K+P */
        for (f = 0; f < nf; ++f) {
            st->z[f] = m->feat_b[f] + m->feat_w[f] * s[f];
        }
    } else {
        for (f = 0; f < nf; ++f) {
            float acc = m->feat_b[f];
            for (j = 0; j < ni; ++j) {
                acc = acc + m->feat_w[f * ni + j] * s[j];
            }
            st->z[f] = acc;
        }
    }
    for (l = 0; l < m->layers; ++l) {
        fogsf_lstm_cell(n_in, nh, m->lstm_w[l], m->lstm_r[l], m->lstm_b[l], NULL, x, st->h[l],
                        st->c[l], st->h_prev);
        x = st->h[l];
        n_in = nh;
    }
    y = m->head_b;
    for (j = 0; j < nh; ++j) {
        y = y + m->head_w[j] * st->h[m->layers - 1u][j];
    }
    for (j = 0; j < nf; ++j) {
        y = y + m->skip_w[j] * st->z[j];
    }
    if (m->quad_w != NULL) { /* polynomial head: the quadratic, then the cubic terms in z */
        uint32_t i;
        if (m->quad_diag != 0u) { /* the diagonal only: quad_w [F] */
            for (i = 0; i < nf; ++i) {
                y = y + m->quad_w[i] * (st->z[i] * st->z[i]);
            }
        } else {
            for (i = 0; i < nf; ++i) {
                for (j = 0; j < nf; ++j) {
                    y = y + m->quad_w[i * nf + j] * (st->z[i] * st->z[j]);
                }
            }
        }
        for (i = 0; i < nf; ++i) {
            y = y + m->cube_w[i] * ((st->z[i] * st->z[i]) * st->z[i]);
        }
    }
    sf = y * m->out_scale + m->out_offset;
    mag = sf < 0.0f ? -sf : sf;
    st->sf_flags = 0u;
    if (!(mag <= FOGSF_SF_LIMIT_PPM)) { /* a broken model, or NaN: never pass it on */
        sf = sf > 0.0f ? FOGSF_SF_LIMIT_PPM : (sf < 0.0f ? -FOGSF_SF_LIMIT_PPM : 0.0f);
        st->sf_flags = FOGSF_FLAG_SF_CLAMPED;
    }
    st->sf_ppm = sf;
    bias_step(m, st);
}

void fogsf_step(const fogsf_model *m, fogsf_state *st, float temp_c, double gyro_dps,
                fogsf_output *out)
{
    uint32_t flags = 0u;
    const uint32_t bits = float_bits(temp_c);
    float tc;
    double corrected;

    if (fogsf_model_check(m) != 0u) { /* never index past the state or through NULL */
        out->corrected_dps = 0.0;
        out->sf_ppm = 0.0f;
        out->bias_dph = 0.0f;
        out->flags = FOGSF_FLAG_MODEL_INVALID;
        return;
    }

    /* 1. temperature: stuck run on the raw bits, then sanitise and clamp */
    if (st->started != 0u && bits == st->raw_prev_bits) {
        if (st->stuck_run < m->stuck_samples) {
            st->stuck_run += 1u;
        }
    } else {
        st->stuck_run = 0u;
    }
    st->raw_prev_bits = bits;
    if (m->stuck_samples > 0u && st->stuck_run >= m->stuck_samples) {
        flags |= FOGSF_FLAG_TEMP_STUCK;
    }
    if (!float_finite(temp_c)) {
        tc = st->t_last_good;
        flags |= FOGSF_FLAG_TEMP_INVALID;
    } else {
        tc = temp_c;
        if (tc < m->t_min_c) {
            tc = m->t_min_c;
            flags |= FOGSF_FLAG_TEMP_CLAMPED;
        } else if (tc > m->t_max_c) {
            tc = m->t_max_c;
            flags |= FOGSF_FLAG_TEMP_CLAMPED;
        }
        st->t_last_good = tc;
    }

    /* 2.-3. priming at the first sample, then one model step per m->decimation samples */
    if (st->started == 0u) {
        uint32_t k;
        st->started = 1u;
        for (k = 0; k < m->n_filters; ++k) {
            st->y[k] = tc;
        }
        for (k = 0; k < n_plays_of(m); ++k) {
            st->p[k] = tc;
        }
        model_step(m, st, tc);
    } else {
        st->acc = st->acc + tc;
        st->n_acc += 1u;
        if (st->n_acc >= m->decimation) {
            const float tm = st->acc / (float)m->decimation;
            st->acc = 0.0f;
            st->n_acc = 0u;
            model_step(m, st, tm);
        }
    }

    /* 5. the held bias and SF error correct this sample, in double; a bias of 0 (always,
     * without a bias head) is not subtracted: gyro / (1 + sf * 1e-6) as before, and no
     * soft-double work on a Cortex-M4F */
    corrected = st->bias_dph != 0.0f ? gyro_dps - st->bias_dps : gyro_dps;
    corrected = corrected / (1.0 + (double)st->sf_ppm * 1e-6);
    if (!double_finite(gyro_dps) || !double_finite(corrected)) {
        corrected = 0.0;
        flags |= FOGSF_FLAG_GYRO_INVALID;
    }
    out->corrected_dps = corrected;
    out->sf_ppm = st->sf_ppm;
    out->bias_dph = st->bias_dph;
    out->flags = flags | st->sf_flags;
}

uint32_t fogsf_run(const fogsf_model *m, fogsf_state *st, const float *temp_c,
                   const double *gyro_dps, size_t n, double *corrected_dps, float *sf_ppm,
                   uint32_t *flags)
{
    return fogsf_run_bias(m, st, temp_c, gyro_dps, n, corrected_dps, sf_ppm, NULL, flags);
}

uint32_t fogsf_run_bias(const fogsf_model *m, fogsf_state *st, const float *temp_c,
                        const double *gyro_dps, size_t n, double *corrected_dps,
                        float *sf_ppm, float *bias_dph, uint32_t *flags)
{
    uint32_t all = 0u;
    size_t i;
    fogsf_output out;

    for (i = 0; i < n; ++i) {
        fogsf_step(m, st, temp_c[i], gyro_dps[i], &out);
        if (corrected_dps != NULL) {
            corrected_dps[i] = out.corrected_dps;
        }
        if (sf_ppm != NULL) {
            sf_ppm[i] = out.sf_ppm;
        }
        if (bias_dph != NULL) {
            bias_dph[i] = out.bias_dph;
        }
        if (flags != NULL) {
            flags[i] = out.flags;
        }
        all |= out.flags;
    }
    return all;
}

size_t fogsf_state_size(void)
{
    return sizeof(fogsf_state);
}
