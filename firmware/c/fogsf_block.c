/*
 * The calibration block loader (fogsf_block.h): a unit's model as data in flash, its tables
 * used where they lie. Every header word is read byte by byte (little-endian whatever the
 * core), every offset and length is checked against n and the sizes before a table is read,
 * and then the CRCs; the model it fills is the one the generated C would give, so
 * fogsf_init and fogsf_step run it the same way.
 */
#include "fogsf_fp.h" /* first: the floating-point build checks */
#include "fogsf_block.h"

#include <stdbool.h>

/* byte offsets of the header's words (fogsf_block.h, "Layout") */
#define AT_MAGIC 0u
#define AT_VERSION 4u
#define AT_TOTAL 8u
#define AT_HEADER 12u
#define AT_TABLES 16u
#define AT_PAYLOAD_CRC 20u
#define AT_FORMAT 24u
#define AT_K 28u
#define AT_F 32u
#define AT_L 36u
#define AT_H 40u
#define AT_D 44u
#define AT_STUCK 48u
#define AT_N 52u
#define AT_QUAD_DIAG 56u
#define AT_FEAT_DIAG 60u
#define AT_P 64u
#define AT_DT 68u
#define AT_T_REF 72u
#define AT_T_MIN 76u
#define AT_T_MAX 80u
#define AT_HEAD_B 84u
#define AT_OUT_SCALE 88u
#define AT_OUT_OFFSET 92u
#define AT_BIAS_B 96u
#define AT_CRC_SIZES 100u
#define AT_CRC 104u
#define HEADER_MIN 112u /* the header without a directory: its words and its CRC */
#define RATE_HEAD_LEN 12u /* the rate part's R, Q and 1/FS bits (slot RATE_HEAD) */

/* what a slot must hold for the block's sizes */
#define NEED_NONE 0u /* absent (offset 0, length 0) */
#define NEED_ONE 1u  /* present, of the length the sizes give */
#define NEED_MAY 2u  /* an optional part: present with that length, or absent */
#define NEED_ANY 3u  /* not read by the loader (the meta table): any length */

/* the header's words the checks and the model need */
typedef struct block_head {
    uint32_t total;
    uint32_t header;
    uint32_t tables;
    uint32_t format;
    uint32_t k, f, l, h, d, n_in, quad_diag, feat_diag, p;
    uint32_t rate_rows;  /* R from slot RATE_HEAD; 0 until check_rate_head passes */
    uint32_t rate_coefs; /* Q, likewise */
} block_head;

/* word `at` of blk, least significant byte first (blk[at .. at+4) checked by the caller) */
static uint32_t rd32(const uint8_t *blk, uint32_t at)
{
    return (uint32_t)blk[at] | ((uint32_t)blk[at + 1u] << 8u) |
           ((uint32_t)blk[at + 2u] << 16u) | ((uint32_t)blk[at + 3u] << 24u);
}

static float rdf(const uint8_t *blk, uint32_t at)
{
    fogsf_f32_bits b;
    b.u = rd32(blk, at);
    return b.f;
}

/* CRC-32 (IEEE 802.3, reflected, as zlib.crc32) of blk[from .. to), a bit at a time: no
 * table in flash for a check that runs once at power-on */
static uint32_t crc32_of(const uint8_t *blk, uint32_t from, uint32_t to)
{
    uint32_t crc = 0xffffffffu;
    uint32_t i;
    uint32_t bit;
    for (i = from; i < to; ++i) {
        crc ^= (uint32_t)blk[i];
        for (bit = 0u; bit < 8u; ++bit) {
            if ((crc & 1u) != 0u) {
                crc = (crc >> 1u) ^ 0xedb88320u;
            } else {
                crc >>= 1u;
            }
        }
    }
    return crc ^ 0xffffffffu;
}

static uint32_t entry_offset(const uint8_t *blk, uint32_t t)
{
    return rd32(blk, FOGSF_BLOCK_HEAD_BYTES + (8u * t));
}

static uint32_t entry_length(const uint8_t *blk, uint32_t t)
{
    return rd32(blk, FOGSF_BLOCK_HEAD_BYTES + (8u * t) + 4u);
}

/* The header's own fields: its length, version and lengths against n first (they bound
 * every later read), then the model's format and sizes. */
static fogsf_block_status check_head(const uint8_t *blk, size_t n, block_head *hd)
{
    fogsf_block_status st = FOGSF_BLOCK_OK;
    if (n < (size_t)HEADER_MIN) {
        st = FOGSF_BLOCK_TRUNCATED;
    } else if (rd32(blk, AT_MAGIC) != FOGSF_BLOCK_MAGIC) {
        st = FOGSF_BLOCK_BAD_MAGIC;
    } else if (rd32(blk, AT_VERSION) != FOGSF_BLOCK_VERSION) {
        st = FOGSF_BLOCK_BAD_VERSION;
    } else {
        hd->total = rd32(blk, AT_TOTAL);
        hd->header = rd32(blk, AT_HEADER);
        hd->tables = rd32(blk, AT_TABLES);
        if ((hd->tables > FOGSF_BLOCK_MAX_TABLES) ||
            (hd->header != (HEADER_MIN + (8u * hd->tables)))) {
            st = FOGSF_BLOCK_BAD_LENGTH;
        } else if ((size_t)hd->header > n) {
            st = FOGSF_BLOCK_TRUNCATED;
        } else if ((hd->total < hd->header) || ((hd->total & 3u) != 0u)) {
            st = FOGSF_BLOCK_BAD_LENGTH;
        } else if ((size_t)hd->total > n) {
            st = FOGSF_BLOCK_TRUNCATED;
        } else {
            st = FOGSF_BLOCK_OK;
        }
    }
    if (st == FOGSF_BLOCK_OK) {
        hd->k = rd32(blk, AT_K);
        hd->f = rd32(blk, AT_F);
        hd->l = rd32(blk, AT_L);
        hd->h = rd32(blk, AT_H);
        hd->d = rd32(blk, AT_D);
        hd->n_in = rd32(blk, AT_N);
        hd->quad_diag = rd32(blk, AT_QUAD_DIAG);
        hd->feat_diag = rd32(blk, AT_FEAT_DIAG);
        hd->p = rd32(blk, AT_P);
        hd->format = rd32(blk, AT_FORMAT);
        if ((hd->format != FOGSF_FORMAT_VERSION) &&
            (hd->format != FOGSF_FORMAT_VERSION_RATE)) {
            st = FOGSF_BLOCK_MODEL_VERSION;
        } else if ((hd->k > (uint32_t)FOGSF_MAX_FILTERS) ||
                   (hd->f > (uint32_t)FOGSF_MAX_FEATURES) ||
                   (hd->l > (uint32_t)FOGSF_MAX_LAYERS) ||
                   (hd->h > (uint32_t)FOGSF_MAX_HIDDEN) || (hd->p > (uint32_t)FOGSF_MAX_PLAYS)) {
            st = FOGSF_BLOCK_TOO_LARGE;
        } else if ((hd->f < 1u) || (hd->l < 1u) || (hd->h < 1u) || (hd->d < 1u) ||
                   (hd->n_in > hd->f) || (hd->quad_diag > 1u) || (hd->feat_diag > 1u) ||
                   ((hd->feat_diag != 0u) && (hd->f != (1u + hd->k + hd->p)))) {
            st = FOGSF_BLOCK_BAD_SIZES;
        } else {
            st = FOGSF_BLOCK_OK;
        }
    }
    return st;
}

/* What slot t must hold for the sizes of hd (NEED_*), and its length in bytes (*len); the
 * sizes are bounded by FOGSF_MAX_* (check_head), so no product overflows. */
static uint32_t slot_need(const block_head *hd, uint32_t t, uint32_t *len)
{
    const uint32_t k = hd->k;
    const uint32_t f = hd->f;
    const uint32_t h = hd->h;
    const uint32_t n_in = (hd->n_in != 0u) ? hd->n_in : f;
    uint32_t rate_need = NEED_NONE; /* the rate part's two slots: only with format 7 */
    uint32_t need = NEED_ONE;
    uint32_t floats = f;
    if (hd->format == FOGSF_FORMAT_VERSION_RATE) {
        rate_need = NEED_ONE;
    }
    switch (t) {
    case FOGSF_BLOCK_T_MODEL_ID:
        floats = 0u;
        break;
    case FOGSF_BLOCK_T_FILTER_ALPHA:
        floats = k;
        if (k == 0u) {
            need = NEED_NONE;
        }
        break;
    case FOGSF_BLOCK_T_FEAT_W:
        floats = (hd->feat_diag != 0u) ? f : (f * (1u + k + hd->p));
        break;
    case FOGSF_BLOCK_T_LSTM_W:
        floats = (4u * h * n_in) + ((hd->l - 1u) * 4u * h * h);
        break;
    case FOGSF_BLOCK_T_LSTM_R:
        floats = hd->l * 4u * h * h;
        break;
    case FOGSF_BLOCK_T_LSTM_B:
        floats = hd->l * 8u * h;
        break;
    case FOGSF_BLOCK_T_HEAD_W:
        floats = h;
        break;
    case FOGSF_BLOCK_T_QUAD_W:
        floats = (hd->quad_diag != 0u) ? f : (f * f);
        need = NEED_MAY;
        break;
    case FOGSF_BLOCK_T_CUBE_W:
    case FOGSF_BLOCK_T_BIAS_W:
    case FOGSF_BLOCK_T_BIAS_QUAD_W:
    case FOGSF_BLOCK_T_BIAS_CUBE_W:
        need = NEED_MAY;
        break;
    case FOGSF_BLOCK_T_PLAY_HALF_C:
        floats = hd->p;
        if (hd->p == 0u) {
            need = NEED_NONE;
        }
        break;
    case FOGSF_BLOCK_T_PLAY_SOURCE_W:
        floats = hd->p * (1u + k);
        if (hd->p == 0u) {
            need = NEED_NONE;
        }
        break;
    case FOGSF_BLOCK_T_META:
        need = NEED_ANY;
        break;
    case FOGSF_BLOCK_T_RATE_HEAD:
        floats = RATE_HEAD_LEN / 4u;
        need = rate_need;
        break;
    case FOGSF_BLOCK_T_RATE_W:
        /* R, Q as checked from slot RATE_HEAD (before this slot: bounded products) */
        floats = hd->rate_rows * hd->rate_coefs;
        need = rate_need;
        break;
    case FOGSF_BLOCK_T_FEAT_B:
    case FOGSF_BLOCK_T_SKIP_W:
        break; /* [F] */
    default:
        need = NEED_NONE; /* a slot this loader does not know */
        break;
    }
    *len = (t == FOGSF_BLOCK_T_MODEL_ID) ? 17u : (4u * floats);
    return need;
}

/* The rate part's R and Q from slot RATE_HEAD, whose place and length check_tables has
 * checked: R within the state (FOGSF_MAX_RATE_ROWS, 0 in a build without the part) and Q
 * within the format, before slot RATE_W's length is computed from them. */
static fogsf_block_status check_rate_head(const uint8_t *blk, block_head *hd)
{
    fogsf_block_status st = FOGSF_BLOCK_OK;
    const uint32_t off = entry_offset(blk, FOGSF_BLOCK_T_RATE_HEAD);
    const uint32_t r = rd32(blk, off);
    const uint32_t q = rd32(blk, off + 4u);
    if (r > (uint32_t)FOGSF_MAX_RATE_ROWS) {
        st = FOGSF_BLOCK_TOO_LARGE;
    } else if ((r < 1u) || (q < 1u) || (q > FOGSF_RATE_COEFS_LIMIT)) {
        st = FOGSF_BLOCK_BAD_SIZES;
    } else {
        hd->rate_rows = r;
        hd->rate_coefs = q;
    }
    return st;
}

/* Every table against the header: inside [header, total), 4-aligned, of the length the
 * sizes give, present where they need it, no two sharing a byte. Reads the directory, and
 * the rate part's R and Q once their slot has passed (check_rate_head). */
static fogsf_block_status check_tables(const uint8_t *blk, block_head *hd)
{
    fogsf_block_status st = FOGSF_BLOCK_OK;
    uint32_t t;
    uint32_t u;
    for (t = 0u; (t < hd->tables) && (st == FOGSF_BLOCK_OK); ++t) {
        const uint32_t off = entry_offset(blk, t);
        const uint32_t len = entry_length(blk, t);
        uint32_t want = 0u;
        const uint32_t need = slot_need(hd, t, &want);
        if ((off == 0u) && (len != 0u)) {
            st = FOGSF_BLOCK_OFFSET_RANGE;
        } else if (off == 0u) {
            if (need == NEED_ONE) {
                st = FOGSF_BLOCK_TABLE_MISSING;
            }
        } else if ((off < hd->header) || (off > hd->total) || (len > (hd->total - off))) {
            st = FOGSF_BLOCK_OFFSET_RANGE;
        } else if ((off & 3u) != 0u) {
            st = FOGSF_BLOCK_MISALIGNED;
        } else if (t >= FOGSF_BLOCK_N_TABLES) {
            st = FOGSF_BLOCK_UNKNOWN_TABLE;
        } else if ((need != NEED_ANY) && (len != ((need == NEED_NONE) ? 0u : want))) {
            st = FOGSF_BLOCK_TABLE_LENGTH;
        } else if ((t == FOGSF_BLOCK_T_RATE_HEAD) && (need == NEED_ONE)) {
            st = check_rate_head(blk, hd);
        } else {
            st = FOGSF_BLOCK_OK;
        }
    }
    /* a directory shorter than this loader's slots: the slots it lacks are absent */
    for (t = hd->tables; (t < FOGSF_BLOCK_N_TABLES) && (st == FOGSF_BLOCK_OK); ++t) {
        uint32_t want = 0u;
        if (slot_need(hd, t, &want) == NEED_ONE) {
            st = FOGSF_BLOCK_TABLE_MISSING;
        }
    }
    if (st == FOGSF_BLOCK_OK) {
        /* the optional parts whole or absent: quad with cube (and with quad_diag), the bias
         * head's three together */
        const bool quad = (hd->tables > FOGSF_BLOCK_T_QUAD_W) &&
                          (entry_offset(blk, FOGSF_BLOCK_T_QUAD_W) != 0u);
        const bool cube = (hd->tables > FOGSF_BLOCK_T_CUBE_W) &&
                          (entry_offset(blk, FOGSF_BLOCK_T_CUBE_W) != 0u);
        uint32_t bias = 0u;
        for (t = FOGSF_BLOCK_T_BIAS_W; (t <= FOGSF_BLOCK_T_BIAS_CUBE_W) && (t < hd->tables);
             ++t) {
            bias += (entry_offset(blk, t) != 0u) ? 1u : 0u;
        }
        if ((quad != cube) || ((hd->quad_diag != 0u) && (!quad)) ||
            ((bias != 0u) && (bias != 3u))) {
            st = FOGSF_BLOCK_TABLE_MISSING;
        }
    }
    for (t = 0u; (t < hd->tables) && (st == FOGSF_BLOCK_OK); ++t) {
        const uint32_t a0 = entry_offset(blk, t);
        const uint32_t a1 = a0 + entry_length(blk, t); /* <= total: checked above */
        for (u = t + 1u; (u < hd->tables) && (st == FOGSF_BLOCK_OK); ++u) {
            const uint32_t b0 = entry_offset(blk, u);
            const uint32_t b1 = b0 + entry_length(blk, u);
            if ((a0 != 0u) && (b0 != 0u) && (a0 < b1) && (b0 < a1)) {
                st = FOGSF_BLOCK_OVERLAP;
            }
        }
    }
    return st;
}

/* the model id: 16 lowercase hex digits and a NUL */
static fogsf_block_status check_id(const uint8_t *id)
{
    fogsf_block_status st = (id[16] == 0u) ? FOGSF_BLOCK_OK : FOGSF_BLOCK_MODEL_ID;
    uint32_t i;
    for (i = 0u; i < 16u; ++i) {
        const uint8_t c = id[i];
        if (!(((c >= 0x30u) && (c <= 0x39u)) || ((c >= 0x61u) && (c <= 0x66u)))) {
            st = FOGSF_BLOCK_MODEL_ID;
        }
    }
    return st;
}

/* the float32 table of slot t where it lies in the block (NULL when absent); the block is
 * 4-aligned and so is the offset (check_tables) */
static const float *floats_at(const uint8_t *blk, const block_head *hd, uint32_t t)
{
    const float *tab = NULL;
    if (t < hd->tables) {
        const uint32_t off = entry_offset(blk, t);
        if (off != 0u) {
            const void *at = &blk[off];
            tab = (const float *)at;
        }
    }
    return tab;
}

/* *out from a block every check passed */
static void fill(const uint8_t *blk, const block_head *hd, fogsf_block_model *out)
{
    fogsf_model *m = &out->model;
    const float *w = floats_at(blk, hd, FOGSF_BLOCK_T_LSTM_W);
    const float *r = floats_at(blk, hd, FOGSF_BLOCK_T_LSTM_R);
    const float *b = floats_at(blk, hd, FOGSF_BLOCK_T_LSTM_B);
    const uint32_t n_in = (hd->n_in != 0u) ? hd->n_in : hd->f;
    const void *id = &blk[entry_offset(blk, FOGSF_BLOCK_T_MODEL_ID)];
    uint32_t l;
    m->model_id = (const char *)id;
    m->format_version = hd->format;
    m->n_filters = hd->k;
    m->n_features = hd->f;
    m->layers = hd->l;
    m->hidden = hd->h;
    m->decimation = hd->d;
    m->stuck_samples = rd32(blk, AT_STUCK);
    m->sample_dt_s = rdf(blk, AT_DT);
    m->t_ref_c = rdf(blk, AT_T_REF);
    m->t_min_c = rdf(blk, AT_T_MIN);
    m->t_max_c = rdf(blk, AT_T_MAX);
    m->filter_alpha = floats_at(blk, hd, FOGSF_BLOCK_T_FILTER_ALPHA);
    m->feat_w = floats_at(blk, hd, FOGSF_BLOCK_T_FEAT_W);
    m->feat_b = floats_at(blk, hd, FOGSF_BLOCK_T_FEAT_B);
    for (l = 0u; l < hd->l; ++l) {
        /* layer 0 reads N features, the others H */
        const uint32_t w_at =
            (l == 0u) ? 0u : ((4u * hd->h * n_in) + ((l - 1u) * 4u * hd->h * hd->h));
        out->lstm_w[l] = &w[w_at];
        out->lstm_r[l] = &r[l * 4u * hd->h * hd->h];
        out->lstm_b[l] = &b[l * 8u * hd->h];
    }
    m->lstm_w = out->lstm_w;
    m->lstm_r = out->lstm_r;
    m->lstm_b = out->lstm_b;
    m->head_w = floats_at(blk, hd, FOGSF_BLOCK_T_HEAD_W);
    m->skip_w = floats_at(blk, hd, FOGSF_BLOCK_T_SKIP_W);
    m->quad_w = floats_at(blk, hd, FOGSF_BLOCK_T_QUAD_W);
    m->cube_w = floats_at(blk, hd, FOGSF_BLOCK_T_CUBE_W);
    m->head_b = rdf(blk, AT_HEAD_B);
    m->out_scale = rdf(blk, AT_OUT_SCALE);
    m->out_offset = rdf(blk, AT_OUT_OFFSET);
    m->lstm_inputs = hd->n_in;
    m->quad_diag = hd->quad_diag;
    m->feat_diag = hd->feat_diag;
    out->bias.w = floats_at(blk, hd, FOGSF_BLOCK_T_BIAS_W);
    out->bias.quad_w = floats_at(blk, hd, FOGSF_BLOCK_T_BIAS_QUAD_W);
    out->bias.cube_w = floats_at(blk, hd, FOGSF_BLOCK_T_BIAS_CUBE_W);
    out->bias.b = rdf(blk, AT_BIAS_B);
    m->bias = (out->bias.w != NULL) ? &out->bias : NULL;
    out->plays.n_plays = hd->p;
    out->plays.half_c = floats_at(blk, hd, FOGSF_BLOCK_T_PLAY_HALF_C);
    out->plays.source_w = floats_at(blk, hd, FOGSF_BLOCK_T_PLAY_SOURCE_W);
    m->plays = (hd->p > 0u) ? &out->plays : NULL;
    m->crc32_sizes = rd32(blk, AT_CRC_SIZES);
    m->crc32 = rd32(blk, AT_CRC);
    if (hd->format == FOGSF_FORMAT_VERSION_RATE) {
        const uint32_t rate_at = entry_offset(blk, FOGSF_BLOCK_T_RATE_HEAD);
        m->rate_w = floats_at(blk, hd, FOGSF_BLOCK_T_RATE_W);
        m->rate_rows = hd->rate_rows;
        m->rate_coefs = hd->rate_coefs;
        m->rate_inv_fs = rdf(blk, rate_at + 8u);
    }
}

fogsf_block_status fogsf_model_from_block(const uint8_t *blk, size_t n, fogsf_block_model *out)
{
    /* all zero: the fields this loader does not fill (a later optional part) stay absent */
    static const fogsf_block_model zero_model;
    fogsf_block_status st = FOGSF_BLOCK_OK;
    block_head hd = {0u, 0u, 0u, 0u, 0u, 0u, 0u, 0u, 0u, 0u, 0u, 0u, 0u, 0u, 0u};
    if (out != NULL) {
        *out = zero_model;
    }
    if ((blk == NULL) || (out == NULL)) {
        st = FOGSF_BLOCK_NULL;
    } else {
        st = check_head(blk, n, &hd);
    }
    /* copy-free float tables need a 4-aligned block (the offsets are checked below) */
    if ((st == FOGSF_BLOCK_OK) && (((uintptr_t)blk & 3u) != 0u)) {
        st = FOGSF_BLOCK_MISALIGNED;
    }
    if (st == FOGSF_BLOCK_OK) {
        st = check_tables(blk, &hd);
    }
    if ((st == FOGSF_BLOCK_OK) &&
        (crc32_of(blk, 0u, hd.header - 4u) != rd32(blk, hd.header - 4u))) {
        st = FOGSF_BLOCK_HEADER_CRC;
    }
    if ((st == FOGSF_BLOCK_OK) &&
        (crc32_of(blk, hd.header, hd.total) != rd32(blk, AT_PAYLOAD_CRC))) {
        st = FOGSF_BLOCK_PAYLOAD_CRC;
    }
    if (st == FOGSF_BLOCK_OK) {
        st = check_id(&blk[entry_offset(blk, FOGSF_BLOCK_T_MODEL_ID)]);
    }
    if (st == FOGSF_BLOCK_OK) {
        fill(blk, &hd, out);
        if (fogsf_model_check(&out->model) != 0u) {
            st = FOGSF_BLOCK_MODEL_REFUSED;
        }
    }
    if ((st != FOGSF_BLOCK_OK) && (out != NULL)) {
        *out = zero_model;
    }
    return st;
}
