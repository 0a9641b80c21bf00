/*
 * The fixed-size model path of the kernel: front end (sanitise, clamp, stuck detection,
 * block means, lag filters), model step (features, LSTM layers, head) and the per-sample
 * correction, exactly in the float32 order of docs/stream-contract.md.
 */
#define FOGSF_MODEL_WEIGHTS /* this translation unit holds the weights */
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

void fogsf_reset(fogsf_state *st)
{
    int l, j;
    for (l = 0; l < FOGSF_LAYERS; ++l) {
        for (j = 0; j < FOGSF_HIDDEN; ++j) {
            st->h[l][j] = 0.0f;
            st->c[l][j] = 0.0f;
        }
    }
    for (j = 0; j < FOGSF_HIDDEN; ++j) {
        st->h_prev[j] = 0.0f;
    }
    for (j = 0; j < FOGSF_N_FEATURES; ++j) {
        st->z[j] = 0.0f;
    }
    for (j = 0; j < FOGSF_N_FILTERS_ALLOC; ++j) {
        st->y[j] = 0.0f;
    }
    st->acc = 0.0f;
    st->t_last_good = FOGSF_T_REF_C;
    st->sf_ppm = 0.0f;
    st->sf_flags = 0u;
    st->raw_prev_bits = 0u;
    st->stuck_run = 0u;
    st->n_acc = 0u;
    st->started = 0u;
}

void fogsf_init(fogsf_state *st)
{
    fogsf_reset(st);
}

/* Contract step 4: one model step on the block-mean temperature tm. */
static void model_step(fogsf_state *st, float tm)
{
    float s[FOGSF_N_INPUTS];
    float y, sf, mag;
    const float *x = st->z;
    size_t n_in = FOGSF_N_FEATURES;
    int k, f, l, j;

    for (k = 0; k < FOGSF_N_FILTERS; ++k) {
        st->y[k] = st->y[k] + fogsf_filter_alpha[k] * (tm - st->y[k]);
    }
    s[0] = tm - FOGSF_T_REF_C;
    for (k = 0; k < FOGSF_N_FILTERS; ++k) {
        s[1 + k] = st->y[k] - FOGSF_T_REF_C;
    }
    for (f = 0; f < FOGSF_N_FEATURES; ++f) {
        float acc = fogsf_feat_b[f];
        for (j = 0; j < FOGSF_N_INPUTS; ++j) {
            acc = acc + fogsf_feat_w[f * FOGSF_N_INPUTS + j] * s[j];
        }
        st->z[f] = acc;
    }
    for (l = 0; l < FOGSF_LAYERS; ++l) {
        fogsf_lstm_cell(n_in, FOGSF_HIDDEN, fogsf_lstm_w[l], fogsf_lstm_r[l], fogsf_lstm_b[l],
                        NULL, x, st->h[l], st->c[l], st->h_prev);
        x = st->h[l];
        n_in = FOGSF_HIDDEN;
    }
    y = fogsf_head_b;
    for (j = 0; j < FOGSF_HIDDEN; ++j) {
        y = y + fogsf_head_w[j] * st->h[FOGSF_LAYERS - 1][j];
    }
    for (j = 0; j < FOGSF_N_FEATURES; ++j) {
        y = y + fogsf_skip_w[j] * st->z[j];
    }
    sf = y * fogsf_out_scale + fogsf_out_offset;
    mag = sf < 0.0f ? -sf : sf;
    st->sf_flags = 0u;
    if (!(mag <= FOGSF_SF_LIMIT_PPM)) { /* a broken model, or NaN: never pass it on */
        sf = sf > 0.0f ? FOGSF_SF_LIMIT_PPM : (sf < 0.0f ? -FOGSF_SF_LIMIT_PPM : 0.0f);
        st->sf_flags = FOGSF_FLAG_SF_CLAMPED;
    }
    st->sf_ppm = sf;
}

void fogsf_step(fogsf_state *st, float temp_c, double gyro_dps, fogsf_output *out)
{
    uint32_t flags = 0u;
    const uint32_t bits = float_bits(temp_c);
    float tc;
    double corrected;

    /* 1. temperature: stuck run on the raw bits, then sanitise and clamp */
    if (st->started != 0u && bits == st->raw_prev_bits) {
#if FOGSF_STUCK_SAMPLES > 0
        if (st->stuck_run < FOGSF_STUCK_SAMPLES) {
            st->stuck_run += 1u;
        }
#endif
    } else {
        st->stuck_run = 0u;
    }
    st->raw_prev_bits = bits;
#if FOGSF_STUCK_SAMPLES > 0
    if (st->stuck_run >= FOGSF_STUCK_SAMPLES) {
        flags |= FOGSF_FLAG_TEMP_STUCK;
    }
#endif
    if (!float_finite(temp_c)) {
        tc = st->t_last_good;
        flags |= FOGSF_FLAG_TEMP_INVALID;
    } else {
        tc = temp_c;
        if (tc < FOGSF_T_MIN_C) {
            tc = FOGSF_T_MIN_C;
            flags |= FOGSF_FLAG_TEMP_CLAMPED;
        } else if (tc > FOGSF_T_MAX_C) {
            tc = FOGSF_T_MAX_C;
            flags |= FOGSF_FLAG_TEMP_CLAMPED;
        }
        st->t_last_good = tc;
    }

    /* 2.-3. priming at the first sample, then one model step per FOGSF_DECIMATION samples */
    if (st->started == 0u) {
        int k;
        st->started = 1u;
        for (k = 0; k < FOGSF_N_FILTERS; ++k) {
            st->y[k] = tc;
        }
        model_step(st, tc);
    } else {
        st->acc = st->acc + tc;
        st->n_acc += 1u;
        if (st->n_acc == (uint32_t)FOGSF_DECIMATION) {
            const float tm = st->acc / (float)FOGSF_DECIMATION;
            st->acc = 0.0f;
            st->n_acc = 0u;
            model_step(st, tm);
        }
    }

    /* 5. the held SF error corrects this sample, in double */
    corrected = gyro_dps / (1.0 + (double)st->sf_ppm * 1e-6);
    if (!double_finite(gyro_dps) || !double_finite(corrected)) {
        corrected = 0.0;
        flags |= FOGSF_FLAG_GYRO_INVALID;
    }
    out->corrected_dps = corrected;
    out->sf_ppm = st->sf_ppm;
    out->flags = flags | st->sf_flags;
}

uint32_t fogsf_run(fogsf_state *st, const float *temp_c, const double *gyro_dps, size_t n,
                   double *corrected_dps, float *sf_ppm, uint32_t *flags)
{
    uint32_t all = 0u;
    size_t i;
    fogsf_output out;

    for (i = 0; i < n; ++i) {
        fogsf_step(st, temp_c[i], gyro_dps[i], &out);
        if (corrected_dps != NULL) {
            corrected_dps[i] = out.corrected_dps;
        }
        if (sf_ppm != NULL) {
            sf_ppm[i] = out.sf_ppm;
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

const char *fogsf_model_id(void)
{
    return FOGSF_MODEL_ID;
}
