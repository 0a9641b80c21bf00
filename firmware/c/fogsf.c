/*
 * The fixed-size model path of the kernel: front end (sanitise, clamp, stuck detection,
 * block means, lag filters), model step (features, LSTM layers, head with the optional
 * polynomial terms) and the per-sample correction, exactly in the float32 order of
 * docs/stream-contract.md (with the optional narrowed LSTM input, diagonal quadratic and
 * diagonal feature map). Sizes and weights come from the model struct at run time; the
 * state arrays are sized by FOGSF_MAX_* (fogsf_model_check).
 */
#include "fogsf_fp.h" /* first: the floating-point build checks */
#include "fogsf.h"

#include <stdbool.h>

static uint32_t float_bits(float v)
{
    fogsf_f32_bits b;
    b.f = v;
    return b.u;
}

static bool float_finite(float v)
{
    return (float_bits(v) & 0x7f800000u) != 0x7f800000u;
}

static uint32_t n_plays_of(const fogsf_model *m)
{
    return m->plays != NULL ? m->plays->n_plays : 0u;
}

/* The sizes and pointers fogsf_step relies on: 0 when m can be stepped with a fogsf_state
 * without reading past an array of the state or through NULL. */
static uint32_t model_fits(const fogsf_model *m)
{
    uint32_t bad = 0u;
    if (m == NULL) {
        bad = FOGSF_FLAG_MODEL_INVALID;
    } else if ((m->format_version != FOGSF_FORMAT_VERSION) ||
               (m->n_filters > (uint32_t)FOGSF_MAX_FILTERS) ||
               (m->n_features > (uint32_t)FOGSF_MAX_FEATURES) || (m->n_features < 1u) ||
               (m->layers > (uint32_t)FOGSF_MAX_LAYERS) || (m->layers < 1u) ||
               (m->hidden > (uint32_t)FOGSF_MAX_HIDDEN) || (m->hidden < 1u) ||
               (m->decimation < 1u) || ((m->n_filters > 0u) && (m->filter_alpha == NULL)) ||
               (m->feat_w == NULL) || (m->feat_b == NULL) || (m->lstm_w == NULL) ||
               (m->lstm_r == NULL) || (m->lstm_b == NULL) || (m->head_w == NULL) ||
               (m->skip_w == NULL) || ((m->quad_w == NULL) != (m->cube_w == NULL)) ||
               (m->lstm_inputs > m->n_features) || (m->quad_diag > 1u) ||
               ((m->quad_diag != 0u) && (m->quad_w == NULL)) || (m->feat_diag > 1u)) {
        bad = FOGSF_FLAG_MODEL_INVALID;
    } else if ((m->plays != NULL) &&
               ((m->plays->n_plays < 1u) || (m->plays->n_plays > (uint32_t)FOGSF_MAX_PLAYS) ||
                (m->plays->half_c == NULL) || (m->plays->source_w == NULL))) {
        bad = FOGSF_FLAG_MODEL_INVALID;
    } else if ((m->bias != NULL) &&
               ((m->bias->w == NULL) || (m->bias->quad_w == NULL) ||
                (m->bias->cube_w == NULL))) {
        bad = FOGSF_FLAG_MODEL_INVALID;
    } else if ((m->feat_diag != 0u) && (m->n_features != (1u + m->n_filters + n_plays_of(m)))) {
        /* a diagonal feat_w maps s (1+K+P entries) onto F features one to one */
        bad = FOGSF_FLAG_MODEL_INVALID;
    } else {
        bad = 0u;
    }
    return bad;
}

/* The plays' half widths (finite, >= 0) and source weights (finite). */
static uint32_t plays_finite(const fogsf_plays *p, uint32_t n_filters)
{
    uint32_t bad = 0u;
    uint32_t j;
    uint32_t i;
    for (j = 0u; j < p->n_plays; ++j) {
        if ((!(p->half_c[j] >= 0.0f)) || (!float_finite(p->half_c[j]))) {
            bad = FOGSF_FLAG_MODEL_INVALID;
        }
        for (i = 0u; i <= n_filters; ++i) {
            if (!float_finite(p->source_w[(j * (n_filters + 1u)) + i])) {
                bad = FOGSF_FLAG_MODEL_INVALID;
            }
        }
    }
    return bad;
}

/* CRC-32 (reflected 0xEDB88320), four bits at a time: 16 words of table. */
static uint32_t crc_word(uint32_t crc, uint32_t v)
{
    static const uint32_t nibble[16] = {
        0x00000000u, 0x1db71064u, 0x3b6e20c8u, 0x26d930acu, 0x76dc4190u, 0x6b6b51f4u,
        0x4db26158u, 0x5005713cu, 0xedb88320u, 0xf00f9344u, 0xd6d6a3e8u, 0xcb61b38cu,
        0x9b64c2b0u, 0x86d3d2d4u, 0xa00ae278u, 0xbdbdf21cu};
    uint32_t c = crc;
    uint32_t k;
    for (k = 0u; k < 32u; k += 4u) { /* the word's bytes least significant first */
        c = (c >> 4u) ^ nibble[(c ^ (v >> k)) & 0xfu];
    }
    return c;
}

/* the most tables a model has: filter_alpha, feat_w, feat_b, W/R/B per layer, head_w,
 * skip_w, quad_w, cube_w, the bias head's three, the plays' two */
#define CRC_TABLES (3u + (3u * (uint32_t)FOGSF_MAX_LAYERS) + 9u)
#define CRC_HEAD_WORDS 21u

/* the CRC register over n words, each least significant byte first */
static uint32_t crc_words(uint32_t crc, const uint32_t *w, uint32_t n)
{
    uint32_t c = crc;
    uint32_t i;
    for (i = 0u; i < n; ++i) {
        c = crc_word(c, w[i]);
    }
    return c;
}

uint32_t fogsf_model_crc32(const fogsf_model *m, uint32_t sizes_only)
{
    const uint32_t nk = m->n_filters;
    const uint32_t nf = m->n_features;
    const uint32_t nh = m->hidden;
    const uint32_t np = n_plays_of(m);
    const float *tab[CRC_TABLES];
    uint32_t len[CRC_TABLES];
    uint32_t head[CRC_HEAD_WORDS];
    uint32_t n_head = 20u;
    uint32_t n_tab = 0u;
    uint32_t c;
    uint32_t l;
    uint32_t t;
    head[0] = m->format_version;
    head[1] = nk;
    head[2] = nf;
    head[3] = m->layers;
    head[4] = nh;
    head[5] = m->decimation;
    head[6] = m->stuck_samples;
    head[7] = float_bits(m->sample_dt_s);
    head[8] = float_bits(m->t_ref_c);
    head[9] = float_bits(m->t_min_c);
    head[10] = float_bits(m->t_max_c);
    head[11] = float_bits(m->head_b);
    head[12] = float_bits(m->out_scale);
    head[13] = float_bits(m->out_offset);
    head[14] = m->lstm_inputs;
    head[15] = m->quad_diag;
    head[16] = m->feat_diag;
    head[17] = 0u; /* 1: the polynomial head */
    if (m->quad_w != NULL) {
        head[17] = 1u;
    }
    head[18] = 0u; /* 1: a bias head */
    if (m->bias != NULL) {
        head[18] = 1u;
    }
    head[19] = np;
    if (m->bias != NULL) {
        head[20] = float_bits(m->bias->b);
        n_head = 21u;
    }
    c = crc_words(0xffffffffu, head, n_head);
    if (sizes_only == 0u) {
        const uint32_t n_in0 = (m->lstm_inputs != 0u) ? m->lstm_inputs : nf;
        const uint32_t layers = (m->layers <= (uint32_t)FOGSF_MAX_LAYERS) ? m->layers : 0u;
        tab[0] = m->filter_alpha;
        len[0] = nk;
        tab[1] = m->feat_w;
        len[1] = (m->feat_diag != 0u) ? nf : (nf * (1u + nk + np));
        tab[2] = m->feat_b;
        len[2] = nf;
        n_tab = 3u;
        for (l = 0u; (l < layers) && (m->lstm_w != NULL) && (m->lstm_r != NULL) &&
                     (m->lstm_b != NULL); ++l) {
            tab[n_tab] = m->lstm_w[l];
            len[n_tab] = 4u * nh * ((l == 0u) ? n_in0 : nh);
            tab[n_tab + 1u] = m->lstm_r[l];
            len[n_tab + 1u] = 4u * nh * nh;
            tab[n_tab + 2u] = m->lstm_b[l];
            len[n_tab + 2u] = 8u * nh;
            n_tab += 3u;
        }
        tab[n_tab] = m->head_w;
        len[n_tab] = nh;
        tab[n_tab + 1u] = m->skip_w;
        len[n_tab + 1u] = nf;
        n_tab += 2u;
        if (m->quad_w != NULL) {
            tab[n_tab] = m->quad_w;
            len[n_tab] = (m->quad_diag != 0u) ? nf : (nf * nf);
            tab[n_tab + 1u] = m->cube_w;
            len[n_tab + 1u] = nf;
            n_tab += 2u;
        }
        if (m->bias != NULL) {
            tab[n_tab] = m->bias->w;
            tab[n_tab + 1u] = m->bias->quad_w;
            tab[n_tab + 2u] = m->bias->cube_w;
            len[n_tab] = nf;
            len[n_tab + 1u] = nf;
            len[n_tab + 2u] = nf;
            n_tab += 3u;
        }
        if (m->plays != NULL) {
            tab[n_tab] = m->plays->half_c;
            len[n_tab] = np;
            tab[n_tab + 1u] = m->plays->source_w;
            len[n_tab + 1u] = np * (1u + nk);
            n_tab += 2u;
        }
    }
    for (t = 0u; t < n_tab; ++t) { /* a NULL table adds nothing (the model is refused) */
        const float *a = tab[t];
        if (a != NULL) {
            uint32_t i;
            for (i = 0u; i < len[t]; ++i) {
                c = crc_word(c, float_bits(a[i]));
            }
        }
    }
    return c ^ 0xffffffffu;
}

uint32_t fogsf_model_check(const fogsf_model *m)
{
    uint32_t bad = model_fits(m);
    /* the sizes first: the tables' lengths come from them */
    if ((bad == 0u) && (fogsf_model_crc32(m, 1u) != m->crc32_sizes)) {
        bad = FOGSF_FLAG_MODEL_INVALID;
    }
    if ((bad == 0u) && (fogsf_model_crc32(m, 0u) != m->crc32)) {
        bad = FOGSF_FLAG_MODEL_INVALID;
    }
    if ((bad == 0u) && (m->plays != NULL)) {
        bad = plays_finite(m->plays, m->n_filters);
    }
    return bad;
}

uint32_t fogsf_reset(const fogsf_model *m, fogsf_state *st)
{
    uint32_t bad;
    uint32_t l;
    uint32_t j;
    for (l = 0u; l < (uint32_t)FOGSF_MAX_LAYERS; ++l) {
        for (j = 0u; j < (uint32_t)FOGSF_MAX_HIDDEN; ++j) {
            st->h[l][j] = 0.0f;
            st->c[l][j] = 0.0f;
        }
    }
    for (j = 0u; j < (uint32_t)FOGSF_MAX_HIDDEN; ++j) {
        st->h_prev[j] = 0.0f;
    }
    for (j = 0u; j < (uint32_t)FOGSF_MAX_FEATURES; ++j) {
        st->z[j] = 0.0f;
    }
    for (j = 0u; j < (uint32_t)FOGSF_MAX_FILTERS; ++j) {
        st->y[j] = 0.0f;
    }
    for (j = 0u; j < (uint32_t)FOGSF_MAX_PLAYS; ++j) {
        st->p[j] = 0.0f;
    }
    st->acc = 0.0f;
    st->t_last_good = (m != NULL) ? m->t_ref_c : 0.0f;
    st->sf_ppm = 0.0f;
    st->bias_dph = 0.0f;
    st->bias_dps = 0.0f;
    st->sf_k = 0.0f;
    st->sf_flags = 0u;
    st->sf_next = 0.0f;
    st->k_next = 0.0f;
    st->bias_next = 0.0f;
    st->bias_dps_next = 0.0f;
    st->flags_next = 0u;
    st->part = 0u;
    st->raw_prev_bits = 0u;
    st->stuck_run = 0u;
    st->n_acc = 0u;
    st->started = 0u;
    bad = fogsf_model_check(m);
    st->model = (bad == 0u) ? m : NULL;
    return bad;
}

uint32_t fogsf_init(const fogsf_model *m, fogsf_state *st)
{
    return fogsf_reset(m, st);
}

/* A model step (contract step 4) runs as parts, in this order: 0 the front (lag filters,
 * plays, features z), 1 .. L*H one LSTM unit each (layer by layer, unit by unit), then the
 * head (sf_ppm and k), then the bias head (bias_dph and b). Each part writes what the next
 * ones read, and the head and bias parts write the *_next fields, which publish() makes the
 * held outputs: so running the parts one after another at one sample, or one a sample, gives
 * the same bits. */
static uint32_t n_parts(const fogsf_model *m)
{
    return (m->layers * m->hidden) + 3u;
}

/* part 0 on the block-mean temperature tm */
static void part_front(const fogsf_model *m, fogsf_state *st, float tm)
{
    float s[1 + FOGSF_MAX_FILTERS + FOGSF_MAX_PLAYS];
    const fogsf_plays *pm = m->plays;
    const uint32_t nk = m->n_filters, nf = m->n_features, np = n_plays_of(m), ni = 1u + nk + np;
    uint32_t k, f, j;

    for (k = 0; k < nk; ++k) {
        st->y[k] = st->y[k] + m->filter_alpha[k] * (tm - st->y[k]);
    }
    s[0] = tm - m->t_ref_c;
    for (k = 0; k < nk; ++k) {
        s[1u + k] = st->y[k] - m->t_ref_c;
    }
    for (k = 0; k < np; ++k) { /* the play operators, after the filters */
        const float *v = pm->source_w + k * (nk + 1u);
        float xin = 0.0f, lo, hi;
        xin = xin + v[0] * tm;
        for (j = 0; j < nk; ++j) {
            xin = xin + v[1u + j] * st->y[j];
        }
        lo = xin - pm->half_c[k];
        hi = xin + pm->half_c[k];
        st->p[k] = st->p[k] < lo ? lo : (st->p[k] > hi ? hi : st->p[k]);
        s[1u + nk + k] = st->p[k] - m->t_ref_c;
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
}

/* LSTM unit u = l * H + j: unit j of layer l (its h_prev taken at the layer's first unit) */
static void part_unit(const fogsf_model *m, fogsf_state *st, uint32_t u)
{
    const uint32_t nh = m->hidden;
    const uint32_t l = u / nh;
    const uint32_t j = u - (l * nh);
    const float *x = st->z;
    size_t n_in = (m->lstm_inputs != 0u) ? m->lstm_inputs : m->n_features;
    if (l > 0u) {
        x = st->h[l - 1u];
        n_in = nh;
    }
    fogsf_lstm_unit(n_in, nh, m->lstm_w[l], m->lstm_r[l], m->lstm_b[l], NULL, x, st->h[l],
                    st->c[l], st->h_prev, j);
}

/* the head: sf_ppm (NaN or beyond +-FOGSF_SF_LIMIT_PPM clamped and flagged) and k */
static void part_head(const fogsf_model *m, fogsf_state *st)
{
    const uint32_t nf = m->n_features, nh = m->hidden;
    float y, sf, mag, s_rel;
    uint32_t i, j;

    y = m->head_b;
    for (j = 0; j < nh; ++j) {
        y = y + m->head_w[j] * st->h[m->layers - 1u][j];
    }
    for (j = 0; j < nf; ++j) {
        y = y + m->skip_w[j] * st->z[j];
    }
    if (m->quad_w != NULL) { /* polynomial head: the quadratic, then the cubic terms in z */
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
    st->flags_next = 0u;
    if (!(mag <= FOGSF_SF_LIMIT_PPM)) { /* a broken model, or NaN: never pass it on */
        sf = sf > 0.0f ? FOGSF_SF_LIMIT_PPM : (sf < 0.0f ? -FOGSF_SF_LIMIT_PPM : 0.0f);
        st->flags_next = FOGSF_FLAG_SF_CLAMPED;
    }
    st->sf_next = sf;
    /* the correction's factor, once per model step: k = s / (1 + s), s = sf * 1e-6, so that a
     * sample is corrected by d - d * k = d / (1 + s) with one rounding that matters */
    s_rel = sf * 1e-6f;
    st->k_next = s_rel / (1.0f + s_rel);
}

/* The bias head on the features z of this step (deg/h): the bias, then the squares, then
 * the cubes, index order; NaN or beyond +-FOGSF_BIAS_LIMIT_DPH is clamped and flagged. */
static void part_bias(const fogsf_model *m, fogsf_state *st)
{
    const fogsf_bias_head *b = m->bias;
    const uint32_t nf = m->n_features;
    float y, mag;
    uint32_t i;

    if (b != NULL) { /* without a bias head bias_dph stays 0 */
        y = b->b;
        for (i = 0; i < nf; ++i) {
            y = y + (b->w[i] * st->z[i]);
        }
        for (i = 0; i < nf; ++i) {
            y = y + (b->quad_w[i] * (st->z[i] * st->z[i]));
        }
        for (i = 0; i < nf; ++i) {
            y = y + (b->cube_w[i] * ((st->z[i] * st->z[i]) * st->z[i]));
        }
        mag = (y < 0.0f) ? -y : y;
        if (!(mag <= FOGSF_BIAS_LIMIT_DPH)) {
            y = (y > 0.0f) ? FOGSF_BIAS_LIMIT_DPH : ((y < 0.0f) ? -FOGSF_BIAS_LIMIT_DPH : 0.0f);
            st->flags_next |= FOGSF_FLAG_BIAS_CLAMPED;
        }
        st->bias_next = y;
        st->bias_dps_next = y / 3600.0f; /* once per model step, not per sample */
    }
}

/* part p of the model step (tm is read by part 0 only) */
static void run_part(const fogsf_model *m, fogsf_state *st, uint32_t p, float tm)
{
    const uint32_t units = m->layers * m->hidden;
    if (p == 0u) {
        part_front(m, st, tm);
    } else if (p <= units) {
        part_unit(m, st, p - 1u);
    } else if (p == (units + 1u)) {
        part_head(m, st);
    } else {
        part_bias(m, st);
    }
}

/* the step's outputs become the held ones */
static void publish(fogsf_state *st)
{
    st->sf_ppm = st->sf_next;
    st->sf_k = st->k_next;
    st->bias_dph = st->bias_next;
    st->bias_dps = st->bias_dps_next;
    st->sf_flags = st->flags_next;
}

/* A model step on the block mean tm at this sample. Default: all parts now, the outputs held
 * from this sample on (contract step 5). FOGSF_EVEN_TIME: the parts still pending from the
 * last step first (only when D < its parts), the last step's outputs published, then part 0
 * now and one part a sample after it (spread_part): the outputs held from the next step's
 * sample on, D samples later, with the same bits. */
static void model_step(const fogsf_model *m, fogsf_state *st, float tm)
{
#if FOGSF_EVEN_TIME
    while (st->part != 0u) {
        run_part(m, st, st->part, 0.0f);
        st->part = ((st->part + 1u) < n_parts(m)) ? (st->part + 1u) : 0u;
    }
    publish(st);
    run_part(m, st, 0u, tm);
    st->part = 1u;
#else
    uint32_t p;
    for (p = 0u; p < n_parts(m); ++p) {
        run_part(m, st, p, tm);
    }
    publish(st);
#endif
}

#if FOGSF_EVEN_TIME
/* one pending part of the step started at the last model step, if any */
static void spread_part(const fogsf_model *m, fogsf_state *st)
{
    if (st->part != 0u) {
        run_part(m, st, st->part, 0.0f);
        st->part = ((st->part + 1u) < n_parts(m)) ? (st->part + 1u) : 0u;
    }
}
#endif

/* true when this sample runs a model step or a part of one (the arrays are read by size) */
static bool runs_model(const fogsf_model *m, const fogsf_state *st)
{
    bool r = (st->started == 0u) || ((st->n_acc + 1u) >= m->decimation);
#if FOGSF_EVEN_TIME
    r = r || (st->part != 0u);
#endif
    return r;
}

/* One sample with a model that fits the state (contract steps 1-5). */
static void sample_step(const fogsf_model *m, fogsf_state *st, float temp_c, float gyro_dps,
                        fogsf_output *out)
{
    uint32_t flags = 0u;
    const uint32_t bits = float_bits(temp_c);
    float tc;
    float d;
    float corrected;

    /* 1. temperature: stuck run on the raw bits, then sanitise and clamp */
    if ((st->started != 0u) && (bits == st->raw_prev_bits)) {
        if (st->stuck_run < m->stuck_samples) {
            st->stuck_run += 1u;
        }
    } else {
        st->stuck_run = 0u;
    }
    st->raw_prev_bits = bits;
    if ((m->stuck_samples > 0u) && (st->stuck_run >= m->stuck_samples)) {
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
        } else {
            /* within [t_min, t_max]: as it is */
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
        } else {
            /* between model steps: with FOGSF_EVEN_TIME one part of the pending step */
#if FOGSF_EVEN_TIME
            spread_part(m, st);
#endif
        }
    }

    /* 5. the held bias and SF error correct this sample, float32: d = g - b / 3600, then
     * d - d * k (b / 3600 and k computed at the model step). A gyro that is NaN or Inf gives
     * a corrected value that is NaN or Inf (b and k are finite), so one test covers both. */
    d = gyro_dps - st->bias_dps;
    corrected = d - (d * st->sf_k);
    if (!float_finite(corrected)) {
        corrected = 0.0f;
        flags |= FOGSF_FLAG_GYRO_INVALID;
    }
    out->corrected_dps = corrected;
    out->sf_ppm = st->sf_ppm;
    out->bias_dph = st->bias_dph;
    out->flags = flags | st->sf_flags;
}

void fogsf_step(const fogsf_model *m, fogsf_state *st, float temp_c, float gyro_dps,
                fogsf_output *out)
{
    /* only the model the reset accepted (NULL when it refused one), its sizes and pointers
     * checked again on a sample that reads its arrays (one that runs a model step, or a part
     * of one), before anything of the state changes: never index past the state or through
     * NULL. The other samples read only scalars of the model and the state. */
    if ((m == NULL) || (m != st->model) || (runs_model(m, st) && (model_fits(m) != 0u))) {
        out->corrected_dps = 0.0f;
        out->sf_ppm = 0.0f;
        out->bias_dph = 0.0f;
        out->flags = FOGSF_FLAG_MODEL_INVALID;
    } else {
        sample_step(m, st, temp_c, gyro_dps, out);
    }
}

uint32_t fogsf_run(const fogsf_model *m, fogsf_state *st, const float *temp_c,
                   const float *gyro_dps, size_t n, float *corrected_dps, float *sf_ppm,
                   uint32_t *flags)
{
    return fogsf_run_bias(m, st, temp_c, gyro_dps, n, corrected_dps, sf_ppm, NULL, flags);
}

uint32_t fogsf_run_bias(const fogsf_model *m, fogsf_state *st, const float *temp_c,
                        const float *gyro_dps, size_t n, float *corrected_dps,
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
