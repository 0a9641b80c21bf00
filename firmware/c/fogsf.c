/*
 * The fixed-size model path of the kernel: front end (sanitise, clamp, stuck detection,
 * block means, lag filters), model step (features, LSTM layers, head with the optional
 * polynomial terms) and the per-sample correction, exactly in the float32 order of
 * docs/stream-contract.md (with the optional narrowed LSTM input, diagonal quadratic and
 * diagonal feature map, and the rate part). Sizes and weights come from the model struct at run time; the
 * state arrays are sized by FOGSF_MAX_* (fogsf_model_check). Around it, the guards of a
 * model in the field: the power-on rule (the filters wait for a plausible temperature), the
 * NULL and state-size checks, and the run-time integrity check (the sizes against init's
 * before the arrays are read, a CRC pass over the model half a float a sample).
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

#if FOGSF_MAX_RATE_ROWS > 0
static float bits_float(uint32_t u)
{
    fogsf_f32_bits b;
    b.u = u;
    return b.f;
}
#endif

static bool float_finite(float v)
{
    return (float_bits(v) & 0x7f800000u) != 0x7f800000u;
}

static uint32_t n_plays_of(const fogsf_model *m)
{
    return m->plays != NULL ? m->plays->n_plays : 0u;
}

#if (FOGSF_MAX_RATE_ROWS < 0) || (FOGSF_MAX_RATE_ROWS > 9)
#error "fogsf: FOGSF_MAX_RATE_ROWS must lie in 0 .. 9 (FOGSF_RATE_ROWS_LIMIT; 0: no rate part)"
#endif

/* The rate part's fields: those of a model with it (format FOGSF_FORMAT_VERSION_RATE), or
 * all NULL and 0 (FOGSF_FORMAT_VERSION), so a field value never reaches a loop unchecked. */
static bool rate_fits(const fogsf_model *m)
{
    bool ok;
    if (m->format_version == FOGSF_FORMAT_VERSION_RATE) {
#if FOGSF_MAX_RATE_ROWS == 0
        ok = false; /* a kernel built without the rate part */
#else
        ok = (m->rate_w != NULL) && (m->rate_rows >= 1u) &&
             (m->rate_rows <= (uint32_t)FOGSF_MAX_RATE_ROWS) && (m->rate_coefs >= 1u) &&
             (m->rate_coefs <= FOGSF_RATE_COEFS_LIMIT) && (m->rate_inv_fs > 0.0f) &&
             float_finite(m->rate_inv_fs);
#endif
    } else {
        ok = (m->rate_w == NULL) && (m->rate_rows == 0u) && (m->rate_coefs == 0u) &&
             (float_bits(m->rate_inv_fs) == 0u);
    }
    return ok;
}

/* R | Q << 8 of a model rate_fits accepts (0 without a rate part, and always in a kernel
 * built without it, which refuses a model with one: its rate code then folds away) */
static uint32_t sizes_c(const fogsf_model *m)
{
#if FOGSF_MAX_RATE_ROWS > 0
    return (m->rate_w != NULL) ? ((m->rate_rows & 0xffu) | ((m->rate_coefs & 0xffu) << 8u))
                               : 0u;
#else
    (void)m;
    return 0u;
#endif
}

/* sizes_c as init recorded it */
static uint32_t recorded_c(const fogsf_state *st)
{
#if FOGSF_MAX_RATE_ROWS > 0
    return st->sizes_c;
#else
    (void)st;
    return 0u;
#endif
}

/* The sizes and pointers fogsf_step relies on: 0 when m can be stepped with a fogsf_state
 * without reading past an array of the state or through NULL. */
static uint32_t model_fits(const fogsf_model *m)
{
    uint32_t bad = 0u;
    if (m == NULL) {
        bad = FOGSF_FLAG_MODEL_INVALID;
    } else if (((m->format_version != FOGSF_FORMAT_VERSION) &&
                (m->format_version != FOGSF_FORMAT_VERSION_RATE)) || !rate_fits(m) ||
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

/* The rate part's weights (finite: its coefficients are finite at any finite s0 short of
 * overflow, which the per-sample path catches as GYRO_INVALID) */
static uint32_t rate_finite(const fogsf_model *m)
{
    uint32_t bad = 0u;
    uint32_t i;
    for (i = 0u; i < (m->rate_rows * m->rate_coefs); ++i) {
        if (!float_finite(m->rate_w[i])) {
            bad = FOGSF_FLAG_MODEL_INVALID;
        }
    }
    return bad;
}

/* The sizes the table lengths come from, packed in two words (the state records them at
 * init; the run-time pass reads its table lengths from that record, never from the model):
 * a = K | F << 8 | N << 16 | P << 24 (N = lstm_inputs, 0 = all F), b = H | L << 16 |
 * (feat_diag | quad_diag << 1 | polynomial head << 2 | bias head << 3) << 24. A layer count
 * beyond FOGSF_MAX_LAYERS packs as 0 (no table is then read through lstm_w). */
#if (FOGSF_MAX_FILTERS > 255) || (FOGSF_MAX_FEATURES > 255) || (FOGSF_MAX_PLAYS > 255) || \
    (FOGSF_MAX_LAYERS > 255) || (FOGSF_MAX_HIDDEN > 65535)
#error "fogsf: FOGSF_MAX_FILTERS, _FEATURES, _PLAYS, _LAYERS above 255 or FOGSF_MAX_HIDDEN above 65535: the state records sizes in 8 and 16 bits"
#endif
static uint32_t sizes_a(const fogsf_model *m)
{
    return (m->n_filters & 0xffu) | ((m->n_features & 0xffu) << 8u) |
           ((m->lstm_inputs & 0xffu) << 16u) | ((n_plays_of(m) & 0xffu) << 24u);
}

static uint32_t sizes_b(const fogsf_model *m)
{
    const uint32_t layers = (m->layers <= (uint32_t)FOGSF_MAX_LAYERS) ? m->layers : 0u;
    uint32_t parts = 0u; /* set bit by bit: no narrow constant widened (Rule 10.6) */
    if (m->feat_diag != 0u) {
        parts |= 1u;
    }
    if (m->quad_diag != 0u) {
        parts |= 2u;
    }
    if (m->quad_w != NULL) {
        parts |= 4u;
    }
    if (m->bias != NULL) {
        parts |= 8u;
    }
    return (m->hidden & 0xffffu) | (layers << 16u) | (parts << 24u);
}

/* 0 when m still has the sizes the state recorded at init and fits the state (its pointers
 * present), else FOGSF_FLAG_MODEL_CHANGED: checked before a sample reads the model's arrays
 * for a model step, so no loop of the step runs to a size other than init's (model_fits
 * bounds every size by FOGSF_MAX_*, so the packed fields hold them whole) */
static uint32_t sizes_changed(const fogsf_model *m, const fogsf_state *st)
{
    const bool same = (model_fits(m) == 0u) && (sizes_a(m) == st->sizes_a) &&
                      (sizes_b(m) == st->sizes_b) && (sizes_c(m) == recorded_c(st));
    return same ? 0u : FOGSF_FLAG_MODEL_CHANGED;
}

/* CRC-32 (reflected 0xEDB88320) of the 16 bits h16, four bits at a time (16 words of table,
 * not 256: flash), least significant first */
static inline uint32_t crc_half(uint32_t crc, uint32_t h16)
{
    static const uint32_t nibble[16] = {
        0x00000000u, 0x1db71064u, 0x3b6e20c8u, 0x26d930acu, 0x76dc4190u, 0x6b6b51f4u,
        0x4db26158u, 0x5005713cu, 0xedb88320u, 0xf00f9344u, 0xd6d6a3e8u, 0xcb61b38cu,
        0x9b64c2b0u, 0x86d3d2d4u, 0xa00ae278u, 0xbdbdf21cu};
    uint32_t c = crc ^ h16;
    c = (c >> 4u) ^ nibble[c & 0xfu];
    c = (c >> 4u) ^ nibble[c & 0xfu];
    c = (c >> 4u) ^ nibble[c & 0xfu];
    c = (c >> 4u) ^ nibble[c & 0xfu];
    return c;
}

/* the word's bytes least significant first */
static uint32_t crc_word(uint32_t crc, uint32_t v)
{
    return crc_half(crc_half(crc, v & 0xffffu), v >> 16u);
}

/* The model's head words as the CRCs read them: sizes, scalars, which parts it has. Slot 20
 * holds bias_b with a bias head, slots 21 .. 23 R, Q and 1/FS with a rate part; a slot the
 * model lacks adds nothing, so a model without them has the CRCs it had before they existed */
#define HEAD_WORDS 21u /* the slots of every model */
#define RATE_HEAD_WORDS 3u /* the slots after them, of a model with a rate part */
#define SEG_HIGH 0x10000u /* in crc_seg: the high half of the float at crc_at is next */

static bool head_present(const fogsf_model *m, uint32_t i)
{
    return (i < (HEAD_WORDS - 1u)) || ((i == (HEAD_WORDS - 1u)) && (m->bias != NULL)) ||
           ((i >= HEAD_WORDS) && (i < (HEAD_WORDS + RATE_HEAD_WORDS)) && (sizes_c(m) != 0u));
}

/* head slots a pass walks: by the sizes init recorded (sizes_c: the rate part) */
static uint32_t head_slots(uint32_t c)
{
    return (c != 0u) ? (HEAD_WORDS + RATE_HEAD_WORDS) : HEAD_WORDS;
}

static uint32_t head_word(const fogsf_model *m, uint32_t i)
{
    uint32_t w;
    switch (i) {
    case 0u: w = m->format_version; break;
    case 1u: w = m->n_filters; break;
    case 2u: w = m->n_features; break;
    case 3u: w = m->layers; break;
    case 4u: w = m->hidden; break;
    case 5u: w = m->decimation; break;
    case 6u: w = m->stuck_samples; break;
    case 7u: w = float_bits(m->sample_dt_s); break;
    case 8u: w = float_bits(m->t_ref_c); break;
    case 9u: w = float_bits(m->t_min_c); break;
    case 10u: w = float_bits(m->t_max_c); break;
    case 11u: w = float_bits(m->head_b); break;
    case 12u: w = float_bits(m->out_scale); break;
    case 13u: w = float_bits(m->out_offset); break;
    case 14u: w = m->lstm_inputs; break;
    case 15u: w = m->quad_diag; break;
    case 16u: w = m->feat_diag; break;
    case 17u: w = (sizes_b(m) >> 26u) & 1u; break; /* 1: the polynomial head */
    case 18u: w = (sizes_b(m) >> 27u) & 1u; break; /* 1: a bias head */
    case 19u: w = n_plays_of(m); break;
    case 20u: w = (m->bias != NULL) ? float_bits(m->bias->b) : 0u; break;
    case 21u: w = m->rate_rows; break;
    case 22u: w = m->rate_coefs; break;
    default: w = float_bits(m->rate_inv_fs); break;
    }
    return w;
}

/* the tables in the CRC's order: filter_alpha, feat_w, feat_b, W/R/B per layer, head_w,
 * skip_w, quad_w, cube_w, the bias head's three, the plays' two (absent ones: length 0),
 * then rate_w when the sizes c say there is a rate part (a slot only then, so a model
 * without it is read as before it existed) */
static uint32_t n_tables(uint32_t b, uint32_t c)
{
    return 12u + (3u * ((b >> 16u) & 0xffu)) + ((c != 0u) ? 1u : 0u);
}

/* table t of m and its length *len by the packed sizes a, b, c (NULL and 0 for a table the
 * sizes say is absent, or that m no longer has) */
static const float *table_at(const fogsf_model *m, uint32_t a, uint32_t b, uint32_t c,
                             uint32_t t, uint32_t *len)
{
    const uint32_t k = a & 0xffu;
    const uint32_t f = (a >> 8u) & 0xffu;
    const uint32_t p = a >> 24u;
    const uint32_t h = b & 0xffffu;
    const uint32_t lstm_end = n_tables(b, 0u) - 9u;
    const float *tab = NULL;
    uint32_t n = f;
    if (t == 0u) {
        tab = m->filter_alpha;
        n = k;
    } else if (t == 1u) {
        tab = m->feat_w;
        n = (((b >> 24u) & 1u) != 0u) ? f : (f * (1u + k + p));
    } else if (t == 2u) {
        tab = m->feat_b;
    } else if (t < lstm_end) {
        const uint32_t l = (t - 3u) / 3u;
        const uint32_t g = (t - 3u) - (3u * l);
        const uint32_t n_in = ((a >> 16u) & 0xffu) != 0u ? ((a >> 16u) & 0xffu) : f;
        const float *const *rows = (g == 0u) ? m->lstm_w : ((g == 1u) ? m->lstm_r : m->lstm_b);
        tab = (rows != NULL) ? rows[l] : NULL;
        n = (g == 2u) ? (8u * h) : (4u * h * (((g == 0u) && (l == 0u)) ? n_in : h));
    } else {
        const fogsf_bias_head *bh = (((b >> 27u) & 1u) != 0u) ? m->bias : NULL;
        const fogsf_plays *pl = (p != 0u) ? m->plays : NULL;
        const float *poly_w = (((b >> 26u) & 1u) != 0u) ? m->quad_w : NULL;
        switch (t - lstm_end) { /* n stays F where not set */
        case 0u:
            tab = m->head_w;
            n = h;
            break;
        case 1u:
            tab = m->skip_w;
            break;
        case 2u:
            tab = poly_w;
            n = (((b >> 25u) & 1u) != 0u) ? f : (f * f);
            break;
        case 3u:
            tab = (poly_w != NULL) ? m->cube_w : NULL;
            break;
        case 4u:
            tab = (bh != NULL) ? bh->w : NULL;
            break;
        case 5u:
            tab = (bh != NULL) ? bh->quad_w : NULL;
            break;
        case 6u:
            tab = (bh != NULL) ? bh->cube_w : NULL;
            break;
        case 7u:
            tab = (pl != NULL) ? pl->half_c : NULL;
            n = p;
            break;
        case 8u:
            tab = (pl != NULL) ? pl->source_w : NULL;
            n = p * (1u + k);
            break;
        default: /* rate_w [R][Q] */
            tab = (c != 0u) ? m->rate_w : NULL;
            n = (c & 0xffu) * ((c >> 8u) & 0xffu);
            break;
        }
    }
    *len = (tab != NULL) ? n : 0u;
    return tab;
}

uint32_t fogsf_model_crc32(const fogsf_model *m, uint32_t sizes_only)
{
    uint32_t c = 0xffffffffu;
    if (m != NULL) {
        uint32_t i;
        for (i = 0u; i < (HEAD_WORDS + RATE_HEAD_WORDS); ++i) {
            if (head_present(m, i)) {
                c = crc_word(c, head_word(m, i));
            }
        }
        if (sizes_only == 0u) {
            const uint32_t a = sizes_a(m);
            const uint32_t b = sizes_b(m);
            const uint32_t rc = sizes_c(m);
            uint32_t t;
            for (t = 0u; t < n_tables(b, rc); ++t) { /* a NULL table adds nothing (refused) */
                uint32_t len = 0u;
                const float *tab = table_at(m, a, b, rc, t, &len);
                for (i = 0u; i < len; ++i) {
                    c = crc_word(c, float_bits(tab[i]));
                }
            }
        }
    }
    return (m != NULL) ? (c ^ 0xffffffffu) : 0u;
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
    if ((bad == 0u) && (sizes_c(m) != 0u)) {
        bad = rate_finite(m);
    }
    return bad;
}

uint32_t fogsf_check_period(const fogsf_model *m)
{
    uint32_t n = 0u;
    if (fogsf_model_check(m) == 0u) {
        const uint32_t a = sizes_a(m);
        const uint32_t b = sizes_b(m);
        const uint32_t c = sizes_c(m);
        uint32_t t;
        /* half a float a sample; each head word, table start and the compare on a sample
         * that reads the arrays, at most D samples after the one before */
        n = (head_slots(c) + n_tables(b, c) + 1u) * m->decimation;
        for (t = 0u; t < n_tables(b, c); ++t) {
            uint32_t len = 0u;
            (void)table_at(m, a, b, c, t, &len);
            n += 2u * len;
        }
    }
    return n;
}

/* k = s / (1 + s), s = sf * 1e-6, and the bias in deg/s: the correction's two factors, once
 * per model step (or when a fault restores verified outputs) */
static float k_of(float sf)
{
    const float s_rel = sf * 1e-6f;
    return s_rel / (1.0f + s_rel);
}

static float dps_of(float bias_dph)
{
    return bias_dph / 3600.0f;
}

/* A check failed: the held outputs become those verified last, until a reset */
static void set_fault(fogsf_state *st)
{
#if FOGSF_MAX_RATE_ROWS > 0
    uint32_t r;
    for (r = 0u; r < (uint32_t)FOGSF_MAX_RATE_ROWS; ++r) {
        st->rate_a[r] = st->good_rate[r];
    }
#endif
    st->fault = FOGSF_FLAG_MODEL_CHANGED;
    st->sf_ppm = st->good_sf;
    st->sf_k = k_of(st->good_sf);
    st->bias_dph = st->good_bias;
    st->bias_dps = dps_of(st->good_bias);
    st->sf_flags = st->snap_flags & 0xffffu;
    st->part = 0u;
}

/* The pass read every word: the model is as init recorded it, so the outputs held at the
 * pass's start came from intact tables (they become the verified ones), or it is not */
static void pass_end(fogsf_state *st)
{
    if ((st->crc_reg ^ 0xffffffffu) == st->model_crc) {
#if FOGSF_MAX_RATE_ROWS > 0
        uint32_t r;
        for (r = 0u; r < (uint32_t)FOGSF_MAX_RATE_ROWS; ++r) {
            st->good_rate[r] = st->cand_rate[r];
            st->cand_rate[r] = st->rate_a[r];
        }
#endif
        st->good_sf = st->cand_sf;
        st->good_bias = st->cand_bias;
        st->snap_flags = (st->snap_flags >> 16u) | (st->sf_flags << 16u);
        st->cand_sf = st->sf_ppm;
        st->cand_bias = st->bias_dph;
    } else {
        set_fault(st);
    }
    st->crc_reg = 0xffffffffu;
    st->crc_seg = 0u;
}

/* true on a sample that reads the model's arrays anyway: priming, a model step, with
 * FOGSF_EVEN_TIME a part of one */
static bool reads_arrays(const fogsf_model *m, const fogsf_state *st)
{
    bool r = (st->started == 0u) || ((st->n_acc + 1u) >= m->decimation);
#if FOGSF_EVEN_TIME
    r = r || (st->part != 0u);
#endif
    return r;
}

/* One slice of the run-time check: half a float of the table under way (every sample, about
 * 25 instructions on a Cortex-M4F), else, on a sample that reads the arrays anyway (so a
 * plain sample never pays more), one head word, or the start of the next table (its length
 * from the sizes init recorded: the pass never reads past a table whatever the model's sizes
 * say now), or the pass's end. Returns the state's fault flags after it. */
static uint32_t check_slice(const fogsf_model *m, fogsf_state *st)
{
    uint32_t fault = 0u;
    if (st->crc_at != st->crc_end) { /* half a float a sample: its low half, then its high */
        const uint32_t w = float_bits(st->crc_at[0]);
        if ((st->crc_seg & SEG_HIGH) == 0u) {
            st->crc_reg = crc_half(st->crc_reg, w & 0xffffu);
        } else {
            st->crc_reg = crc_half(st->crc_reg, w >> 16u);
            st->crc_at = &st->crc_at[1];
        }
        st->crc_seg ^= SEG_HIGH;
    } else if (!reads_arrays(m, st)) {
        /* the table is read: what comes next waits for such a sample */
    } else if (st->crc_seg < head_slots(recorded_c(st))) {
        if (head_present(m, st->crc_seg)) {
            st->crc_reg = crc_word(st->crc_reg, head_word(m, st->crc_seg));
        }
        st->crc_seg += 1u;
    } else if ((st->crc_seg - head_slots(recorded_c(st))) <
               n_tables(st->sizes_b, recorded_c(st))) {
        uint32_t len = 0u;
        const float *tab = table_at(m, st->sizes_a, st->sizes_b, recorded_c(st),
                                    st->crc_seg - head_slots(recorded_c(st)), &len);
        st->crc_at = tab;
        st->crc_end = (tab != NULL) ? &tab[len] : NULL;
        st->crc_seg += 1u;
    } else {
        pass_end(st);
        fault = st->fault;
    }
    return fault;
}

/* Zero the state and start it with m (fogsf_model_check): records its crc32 and sizes */
static uint32_t start(const fogsf_model *m, fogsf_state *st)
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
#if FOGSF_EVEN_TIME
    for (j = 0u; j < (uint32_t)FOGSF_MAX_HIDDEN; ++j) {
        st->h_prev[j] = 0.0f;
    }
    for (j = 0u; j < (uint32_t)FOGSF_MAX_FEATURES; ++j) {
        st->z[j] = 0.0f;
    }
#endif
    for (j = 0u; j < (uint32_t)FOGSF_MAX_FILTERS; ++j) {
        st->y[j] = 0.0f;
    }
    for (j = 0u; j < (uint32_t)FOGSF_MAX_PLAYS; ++j) {
        st->p[j] = 0.0f;
    }
#if FOGSF_MAX_RATE_ROWS > 0
    for (j = 0u; j < (uint32_t)FOGSF_MAX_RATE_ROWS; ++j) { /* +0 from R on: rate_corrected */
        st->rate_a[j] = 0.0f;
#if FOGSF_EVEN_TIME
        st->rate_next[j] = 0.0f;
#endif
        st->good_rate[j] = 0.0f;
        st->cand_rate[j] = 0.0f;
    }
    st->rate_inv_fs = 0.0f;
    st->rate_on = 0u;
    st->sizes_c = 0u;
#endif
    st->acc = 0.0f;
    st->t_last_good = (m != NULL) ? m->t_ref_c : 0.0f;
    st->sf_ppm = 0.0f;
    st->bias_dph = 0.0f;
    st->bias_dps = 0.0f;
    st->sf_k = 0.0f;
    st->sf_flags = 0u;
#if FOGSF_EVEN_TIME
    st->sf_next = 0.0f;
    st->k_next = 0.0f;
    st->bias_next = 0.0f;
    st->bias_dps_next = 0.0f;
    st->flags_next = 0u;
#endif
    st->part = 0u;
    st->raw_prev_bits = 0u;
    st->stuck_run = 0u;
    st->n_acc = 0u;
    st->started = 0u;
    st->model_crc = 0u;
    st->sizes_a = 0u;
    st->sizes_b = 0u;
    st->crc_at = NULL;
    st->crc_end = NULL;
    st->crc_seg = 0u;
    st->crc_reg = 0xffffffffu;
    st->fault = 0u;
    st->good_sf = 0.0f;
    st->good_bias = 0.0f;
    st->snap_flags = 0u;
    st->cand_sf = 0.0f;
    st->cand_bias = 0.0f;
    bad = fogsf_model_check(m);
    if (bad == 0u) { /* model_fits bounded the sizes: the packed record holds them whole */
        st->sizes_a = sizes_a(m);
        st->sizes_b = sizes_b(m);
#if FOGSF_MAX_RATE_ROWS > 0
        st->sizes_c = sizes_c(m);
        st->rate_inv_fs = m->rate_inv_fs; /* 0 without a rate part */
#endif
        st->model_crc = m->crc32;
    }
    st->model = (bad == 0u) ? m : NULL;
    return (bad == 0u) ? 0u : FOGSF_FLAG_MODEL_INVALID;
}

uint32_t fogsf_reset(const fogsf_model *m, fogsf_state *st, size_t state_size)
{
    /* the caller's state of this kernel's size, or nothing is written */
    return ((st != NULL) && (state_size == sizeof(fogsf_state))) ? start(m, st)
                                                                 : FOGSF_FLAG_CALL_INVALID;
}

uint32_t fogsf_init(const fogsf_model *m, fogsf_state *st, size_t state_size)
{
#if FOGSF_SELFTEST_AT_INIT
    /* the build's arithmetic first, on the caller's state (then reset): a build that gives
     * other bits than the reference never steps a model */
    uint32_t failed = 0u;
    uint32_t bad;
    if ((st != NULL) && (state_size == sizeof(fogsf_state))) {
        if (fogsf_selftest(st, state_size) != 0u) {
            failed = FOGSF_FLAG_SELFTEST_FAILED | FOGSF_FLAG_MODEL_INVALID;
        }
    }
    bad = fogsf_reset(m, st, state_size);
    if ((failed != 0u) && (st != NULL)) {
        st->model = NULL;
    }
    return bad | failed;
#else
    return fogsf_reset(m, st, state_size);
#endif
}

/* A model step (contract step 4) runs as parts, in this order: 0 the front (lag filters,
 * plays, features z), 1 .. L*H one LSTM unit each (layer by layer, unit by unit), then the
 * head (sf_ppm and k), then the bias head (bias_dph and b). Each part writes what the next
 * ones read. The even-time build's head and bias parts write the *_next fields, which
 * publish() makes the held outputs, so running the parts one a sample gives the bits of
 * running them at one sample, where the default build's write the held outputs at once. */
static uint32_t n_parts(const fogsf_model *m)
{
    return (m->layers * m->hidden) + 3u;
}

#if FOGSF_MAX_RATE_ROWS > 0
/* The rate part's coefficients of this step, float32: a_r = Horner over q = Q-1 .. 0 of
 * rate_w[r][q] in s0 = Tm - t_ref. They depend on s0 alone, so computing them with the
 * front (not after the bias, as the contract lists them) changes no bit. */
static void rate_coefficients(const fogsf_model *m, fogsf_state *st, float s0)
{
    const uint32_t nr = m->rate_rows, nq = m->rate_coefs;
#if FOGSF_EVEN_TIME
    float *out = st->rate_next;
#else
    float *out = st->rate_a; /* the whole step runs on this sample: held from it on */
#endif
    uint32_t r, q;
    if (m->rate_w != NULL) {
        for (r = 0u; r < nr; ++r) {
            const float *w = &m->rate_w[r * nq];
            float a = w[nq - 1u];
            for (q = nq - 1u; q > 0u; --q) {
                a = (a * s0) + w[q - 1u];
            }
            out[r] = a;
        }
    }
}
#endif

/* part 0 on the block-mean temperature tm */
static void part_front(const fogsf_model *m, fogsf_state *st, float tm, float *z)
{
    float s[1 + FOGSF_MAX_FILTERS + FOGSF_MAX_PLAYS];
    const fogsf_plays *pm = m->plays;
    const uint32_t nk = m->n_filters, nf = m->n_features, np = n_plays_of(m), ni = 1u + nk + np;
    uint32_t k, f, j;

    for (k = 0; k < nk; ++k) {
        st->y[k] = st->y[k] + m->filter_alpha[k] * (tm - st->y[k]);
    }
    s[0] = tm - m->t_ref_c;
#if FOGSF_MAX_RATE_ROWS > 0
    rate_coefficients(m, st, s[0]);
#endif
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
            z[f] = m->feat_b[f] + m->feat_w[f] * s[f];
        }
    } else {
        for (f = 0; f < nf; ++f) {
            float acc = m->feat_b[f];
            for (j = 0; j < ni; ++j) {
                acc = acc + m->feat_w[f * ni + j] * s[j];
            }
            z[f] = acc;
        }
    }
}

/* LSTM unit u = l * H + j: unit j of layer l (its h_prev taken at the layer's first unit) */
static void part_unit(const fogsf_model *m, fogsf_state *st, uint32_t u, float *h_prev,
                      const float *z)
{
    const uint32_t nh = m->hidden;
    const uint32_t l = u / nh;
    const uint32_t j = u - (l * nh);
    const float *x = z;
    size_t n_in = (m->lstm_inputs != 0u) ? m->lstm_inputs : m->n_features;
    if (l > 0u) {
        x = st->h[l - 1u];
        n_in = nh;
    }
    fogsf_lstm_unit(n_in, nh, m->lstm_w[l], m->lstm_r[l], m->lstm_b[l], NULL, x, st->h[l],
                    st->c[l], h_prev, j);
}

/* the head: sf_ppm (NaN or beyond +-FOGSF_SF_LIMIT_PPM clamped and flagged) and k */
static void part_head(const fogsf_model *m, fogsf_state *st, const float *z)
{
    const uint32_t nf = m->n_features, nh = m->hidden;
    float y, sf, mag;
    uint32_t i, j, flags;

    y = m->head_b;
    for (j = 0; j < nh; ++j) {
        y = y + m->head_w[j] * st->h[m->layers - 1u][j];
    }
    for (j = 0; j < nf; ++j) {
        y = y + m->skip_w[j] * z[j];
    }
    if (m->quad_w != NULL) { /* polynomial head: the quadratic, then the cubic terms in z */
        if (m->quad_diag != 0u) { /* the diagonal only: quad_w [F] */
            for (i = 0; i < nf; ++i) {
                y = y + m->quad_w[i] * (z[i] * z[i]);
            }
        } else {
            for (i = 0; i < nf; ++i) {
                for (j = 0; j < nf; ++j) {
                    y = y + m->quad_w[i * nf + j] * (z[i] * z[j]);
                }
            }
        }
        for (i = 0; i < nf; ++i) {
            y = y + m->cube_w[i] * ((z[i] * z[i]) * z[i]);
        }
    }
    sf = y * m->out_scale + m->out_offset;
    mag = sf < 0.0f ? -sf : sf;
    flags = 0u;
    if (!(mag <= FOGSF_SF_LIMIT_PPM)) { /* a broken model, or NaN: never pass it on */
        sf = sf > 0.0f ? FOGSF_SF_LIMIT_PPM : (sf < 0.0f ? -FOGSF_SF_LIMIT_PPM : 0.0f);
        flags = FOGSF_FLAG_SF_CLAMPED;
    }
    /* the correction's factor, once per model step: k = s / (1 + s), s = sf * 1e-6, so that a
     * sample is corrected by d - d * k = d / (1 + s) with one rounding that matters */
#if FOGSF_EVEN_TIME
    st->flags_next = flags;
    st->sf_next = sf;
    st->k_next = k_of(sf);
#else
    st->sf_flags = flags; /* the whole step runs on this sample: held from it on */
    st->sf_ppm = sf;
    st->sf_k = k_of(sf);
#endif
}

/* The bias head on the features z of this step (deg/h): the bias, then the squares, then
 * the cubes, index order; NaN or beyond +-FOGSF_BIAS_LIMIT_DPH is clamped and flagged. */
static void part_bias(const fogsf_model *m, fogsf_state *st, const float *z)
{
    const fogsf_bias_head *b = m->bias;
    const uint32_t nf = m->n_features;
    float y, mag;
    uint32_t i;

    if (b != NULL) { /* without a bias head bias_dph stays 0 */
        y = b->b;
        for (i = 0; i < nf; ++i) {
            y = y + (b->w[i] * z[i]);
        }
        for (i = 0; i < nf; ++i) {
            y = y + (b->quad_w[i] * (z[i] * z[i]));
        }
        for (i = 0; i < nf; ++i) {
            y = y + (b->cube_w[i] * ((z[i] * z[i]) * z[i]));
        }
        mag = (y < 0.0f) ? -y : y;
        if (!(mag <= FOGSF_BIAS_LIMIT_DPH)) {
            y = (y > 0.0f) ? FOGSF_BIAS_LIMIT_DPH : ((y < 0.0f) ? -FOGSF_BIAS_LIMIT_DPH : 0.0f);
#if FOGSF_EVEN_TIME
            st->flags_next |= FOGSF_FLAG_BIAS_CLAMPED;
#else
            st->sf_flags |= FOGSF_FLAG_BIAS_CLAMPED;
#endif
        }
#if FOGSF_EVEN_TIME
        st->bias_next = y;
        st->bias_dps_next = dps_of(y); /* once per model step, not per sample */
#else
        st->bias_dph = y;
        st->bias_dps = dps_of(y);
#endif
    }
}

/* part p of the model step (tm is read by part 0 only) */
static void run_part(const fogsf_model *m, fogsf_state *st, uint32_t p, float tm,
                     float *h_prev, float *z)
{
    const uint32_t units = m->layers * m->hidden;
    if (p == 0u) {
        part_front(m, st, tm, z);
    } else if (p <= units) {
        part_unit(m, st, p - 1u, h_prev, z);
    } else if (p == (units + 1u)) {
        part_head(m, st, z);
    } else {
        part_bias(m, st, z);
    }
}

#if FOGSF_EVEN_TIME
/* the step's outputs become the held ones */
static void publish(fogsf_state *st)
{
#if FOGSF_MAX_RATE_ROWS > 0
    uint32_t r;
    for (r = 0u; r < (uint32_t)FOGSF_MAX_RATE_ROWS; ++r) {
        st->rate_a[r] = st->rate_next[r];
    }
#endif
    st->sf_ppm = st->sf_next;
    st->sf_k = st->k_next;
    st->bias_dph = st->bias_next;
    st->bias_dps = st->bias_dps_next;
    st->sf_flags = st->flags_next;
}
#endif

/* A model step on the block mean tm at this sample. Default: all parts now, the outputs held
 * from this sample on (contract step 5). FOGSF_EVEN_TIME: the parts still pending from the
 * last step first (only when D < its parts), the last step's outputs published, then part 0
 * now and one part a sample after it (spread_part): the outputs held from the next step's
 * sample on, D samples later, with the same bits. */
static void model_step(const fogsf_model *m, fogsf_state *st, float tm)
{
#if FOGSF_EVEN_TIME
    while (st->part != 0u) {
        run_part(m, st, st->part, 0.0f, st->h_prev, st->z);
        st->part = ((st->part + 1u) < n_parts(m)) ? (st->part + 1u) : 0u;
    }
    publish(st);
    run_part(m, st, 0u, tm, st->h_prev, st->z);
    st->part = 1u;
#else
    /* the step's scratch on the stack, not in each state; its parts write the held outputs */
    float h_prev[FOGSF_MAX_HIDDEN];
    float z[FOGSF_MAX_FEATURES];
    uint32_t p;
    for (p = 0u; p < n_parts(m); ++p) {
        run_part(m, st, p, tm, h_prev, z);
    }
#endif
}

/* Before a sample reads the model's arrays (priming, a model step, a part of one): the sizes
 * and pointers still init's, so no loop runs past a table or the state. false (the fault
 * set, nothing read) when they are not. */
static bool arrays_usable(const fogsf_model *m, fogsf_state *st)
{
    const bool ok = sizes_changed(m, st) == 0u;
    if (!ok) {
        set_fault(st);
    }
    return ok;
}

#if FOGSF_EVEN_TIME
/* one pending part of the step started at the last model step, if any; false when the
 * model changed (arrays_usable) */
static bool spread_part(const fogsf_model *m, fogsf_state *st)
{
    bool ok = true;
    if (st->part != 0u) {
        ok = arrays_usable(m, st);
        if (ok) {
            run_part(m, st, st->part, 0.0f, st->h_prev, st->z);
            st->part = ((st->part + 1u) < n_parts(m)) ? (st->part + 1u) : 0u;
        }
    }
    return ok;
}
#endif

/* A first temperature the filters may be primed with: within [FOGSF_TEMP_PLAUSIBLE_MIN_C,
 * FOGSF_TEMP_PLAUSIBLE_MAX_C] (so finite) and not the sensor's power-on value. */
static bool temp_plausible(float t)
{
    const bool power_on = float_bits(t) == float_bits(FOGSF_TEMP_POWER_ON_C);
    return (t >= FOGSF_TEMP_PLAUSIBLE_MIN_C) && (t <= FOGSF_TEMP_PLAUSIBLE_MAX_C) && !power_on;
}

#if FOGSF_MAX_RATE_ROWS > 0
/* The rate part on a corrected rate c, float32 in the contract's order: x = c * (1/FS),
 * clamped to [-1, 1] (RATE_CLAMPED into *flags beyond); p = Horner of a_(R-1) .. a_1 in x, then
 * (p * x) * x; c - (p + a_0 |x|). The Horner runs over all FOGSF_MAX_RATE_ROWS held terms,
 * those from R on +0, so it is written out once per term (no loop bound read, compared and
 * branched on per sample): a leading +0 term gives p the value of the first real one but
 * for the sign of a zero, so c - e differs at most in the sign of a zero c - +-0, which
 * only a c of -0 shows; then x is -0 and (+0 * -0) + a is a, sign and all: the same bits as
 * the contract's loop from R-1 for every R. */
static float rate_corrected(const fogsf_state *st, float c, uint32_t *flags)
{
    const float *a = st->rate_a;
    float x = c * st->rate_inv_fs;
    float ax;
    float p;
    uint32_t xb = float_bits(x);
    uint32_t ab = xb & 0x7fffffffu; /* |x| by its bits: +0 for -0, as the contract's */
    if (ab > 0x3f800000u) { /* |x| > 1, or x NaN */
        ab = 0x3f800000u;   /* the calibrated full scale's edge, +-1 */
        xb = (xb & 0x80000000u) | ab;
        x = bits_float(xb);
        if (float_finite(c)) { /* a c not finite is GYRO_INVALID alone */
            *flags |= FOGSF_FLAG_RATE_CLAMPED;
        }
    }
    ax = bits_float(ab);
#if FOGSF_MAX_RATE_ROWS > 1
    p = a[FOGSF_MAX_RATE_ROWS - 1];
#if FOGSF_MAX_RATE_ROWS > 8
    p = (p * x) + a[7];
#endif
#if FOGSF_MAX_RATE_ROWS > 7
    p = (p * x) + a[6];
#endif
#if FOGSF_MAX_RATE_ROWS > 6
    p = (p * x) + a[5];
#endif
#if FOGSF_MAX_RATE_ROWS > 5
    p = (p * x) + a[4];
#endif
#if FOGSF_MAX_RATE_ROWS > 4
    p = (p * x) + a[3];
#endif
#if FOGSF_MAX_RATE_ROWS > 3
    p = (p * x) + a[2];
#endif
#if FOGSF_MAX_RATE_ROWS > 2
    p = (p * x) + a[1];
#endif
    p = (p * x) * x;
#else
    p = 0.0f; /* R = 1 */
#endif
    return c - (p + (a[0] * ax));
}
#endif

/* 5. the held bias and SF error correct this sample, float32: d = g - b / 3600, then d - d * k
 * (b / 3600 and k computed at the model step; both 0 before the first), then the rate part
 * once primed with one. A gyro that is NaN or Inf gives a corrected value that is NaN or Inf
 * (b, k and the rate part's terms are finite), so one test covers both, and covers a rate
 * correction that overflows (a broken model) too. */
static void correct(const fogsf_state *st, float gyro_dps, uint32_t flags, fogsf_output *out)
{
    const float d = gyro_dps - st->bias_dps;
    float corrected = d - (d * st->sf_k);
    uint32_t f = flags;
#if FOGSF_MAX_RATE_ROWS > 0
    if (st->rate_on != 0u) {
        corrected = rate_corrected(st, corrected, &f);
    }
#endif
    if (!float_finite(corrected)) {
        corrected = 0.0f;
        f |= FOGSF_FLAG_GYRO_INVALID;
    }
    out->corrected_dps = corrected;
    out->sf_ppm = st->sf_ppm;
    out->bias_dph = st->bias_dph;
    out->flags = f | st->sf_flags;
}

/* Contract steps 1-4 of one sample with a model that fits the state: its flags
 * (FOGSF_FLAG_MODEL_CHANGED alone when it found the model changed: nothing stepped). */
static uint32_t sample_front(const fogsf_model *m, fogsf_state *st, float temp_c)
{
    uint32_t flags = 0u;
    const uint32_t bits = float_bits(temp_c);
    float tc;

    /* 1. temperature: stuck run on the raw bits, then sanitise and clamp. A run of 0 is
     * never stuck (the threshold is 0, off, or >= 1), so only a repeat tests it: a changing
     * temperature, the common sample, skips the test */
    if ((st->started != 0u) && (bits == st->raw_prev_bits)) {
        if (st->stuck_run < m->stuck_samples) {
            st->stuck_run += 1u;
        }
        if ((m->stuck_samples > 0u) && (st->stuck_run >= m->stuck_samples)) {
            flags |= FOGSF_FLAG_TEMP_STUCK;
        }
    } else {
        st->stuck_run = 0u;
    }
    st->raw_prev_bits = bits;
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

    /* 2.-3. priming at the first (plausible) sample, then one model step per m->decimation
     * samples */
    if (st->started == 0u) {
        if (arrays_usable(m, st)) {
            uint32_t k;
            st->started = 1u;
#if FOGSF_MAX_RATE_ROWS > 0
            st->rate_on = st->sizes_c; /* nonzero with a part: from the first sample primed */
#endif
            for (k = 0; k < m->n_filters; ++k) {
                st->y[k] = tc;
            }
            for (k = 0; k < n_plays_of(m); ++k) {
                st->p[k] = tc;
            }
            model_step(m, st, tc);
        } else {
            flags = FOGSF_FLAG_MODEL_CHANGED;
        }
    } else {
        st->acc = st->acc + tc;
        st->n_acc += 1u;
        if (st->n_acc >= m->decimation) {
            const float tm = st->acc / (float)m->decimation;
            st->acc = 0.0f;
            st->n_acc = 0u;
            if (arrays_usable(m, st)) {
                model_step(m, st, tm);
            } else {
                flags = FOGSF_FLAG_MODEL_CHANGED;
            }
        } else {
            /* between model steps: with FOGSF_EVEN_TIME one part of the pending step */
#if FOGSF_EVEN_TIME
            if (!spread_part(m, st)) {
                flags = FOGSF_FLAG_MODEL_CHANGED;
            }
#endif
        }
    }
    return flags;
}

/* corrected 0 and the flags: the sample was not computed */
static void refuse(fogsf_output *out, uint32_t flags)
{
    out->corrected_dps = 0.0f;
    out->sf_ppm = 0.0f;
    out->bias_dph = 0.0f;
    out->flags = flags;
}

void fogsf_step(const fogsf_model *m, fogsf_state *st, float temp_c, float gyro_dps,
                fogsf_output *out)
{
    if (out == NULL) {
        /* nowhere to say anything: nothing is done */
    } else if ((m == NULL) || (st == NULL)) {
        refuse(out, FOGSF_FLAG_MODEL_INVALID | FOGSF_FLAG_CALL_INVALID);
    } else if (m != st->model) { /* only the model the reset accepted (NULL if it refused) */
        refuse(out, FOGSF_FLAG_MODEL_INVALID);
    } else {
        /* the run-time checks: half a float of the pass here, then the sizes and pointers,
         * against init's, before a sample reads the arrays (arrays_usable); the other
         * samples read only scalars of the model and the state */
        uint32_t flags = st->fault;
        if (flags == 0u) {
            flags = check_slice(m, st);
        }
        if (flags != 0u) {
            /* the verified correction held; the temperature unread */
        } else if ((st->started == 0u) && !temp_plausible(temp_c)) {
            /* power-on: no plausible temperature yet, nothing primed (sf 0, bias 0) */
            flags = FOGSF_FLAG_TEMP_UNPRIMED;
            if (!float_finite(temp_c)) {
                flags |= FOGSF_FLAG_TEMP_INVALID;
            }
        } else {
            flags = sample_front(m, st, temp_c);
        }
        correct(st, gyro_dps, flags, out);
    }
}

size_t fogsf_state_size(void)
{
    return sizeof(fogsf_state);
}
