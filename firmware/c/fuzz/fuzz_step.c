/*
 * libFuzzer harness of the fogsf kernel (clang -fsanitize=fuzzer,address,undefined):
 *   mode 0  the activations on arbitrary float bits: exp finite and >= 0, sigmoid in [0, 1],
 *           tanh in [-1, 1];
 *   mode 1  the generic LSTM cell with sizes, weights and inputs from the fuzz data;
 *   mode 2  fogsf_step with the generated model fuzz_model (fuzz_model.h) on adversarial
 *           samples: (temperature bits, gyro bits, repeats) records, so NaN, Inf, denormals,
 *           huge values and stuck thermometers (a record repeated up to 255 times) all occur
 *           (the gyro takes 8 bytes, of which the last 4 are its float32 bits: the records
 *           keep the layout of the corpus written when the gyro was a double);
 *   mode 3  fogsf_step with an adversarial model: sizes (sometimes too large for the state),
 *           lstm_inputs, quad_diag and feat_diag (sometimes invalid), sometimes a bias head
 *           (sometimes with a NULL array), sometimes plays, every weight from the fuzz data
 *           (NaN, Inf, huge), the CRCs mostly right (so the model runs) and sometimes wrong,
 *           the format version sometimes forged.
 * After every step the totality contract is checked (corrected finite, |sf| and |bias| <=
 * their limits, flags known, a model fogsf_init refused gives 0 and MODEL_INVALID); a
 * violation aborts, which libFuzzer reports as a crash.
 * The number of fogsf_step calls is printed at exit ("fuzz steps: N") for make fuzz.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fogsf.h"
#include "fuzz_model.h"
#include "fuzz_common.h"

static unsigned long long steps;

static void report(void)
{
    fprintf(stderr, "fuzz steps: %llu\n", steps);
}

static int finite_f(float v)
{
    return v - v == 0.0f;
}

/* reads little pieces of the input; past the end it reads zeros */
typedef struct {
    const uint8_t *p;
    size_t n, at;
} reader;

static uint8_t next_u8(reader *r)
{
    return r->at < r->n ? r->p[r->at++] : 0u;
}

static uint32_t next_u32(reader *r)
{
    uint32_t v = 0u;
    int i;
    for (i = 0; i < 4; ++i) {
        v |= (uint32_t)next_u8(r) << (8 * i);
    }
    return v;
}

static float next_f32(reader *r)
{
    uint32_t u = next_u32(r);
    float f;
    memcpy(&f, &u, sizeof f);
    return f;
}

/* the record's gyro: 8 bytes, the last 4 its float32 bits (every float, NaN, Inf and
 * denormals included, as likely as any other bits) */
static float next_gyro(reader *r)
{
    (void)next_u32(r);
    return next_f32(r);
}

static void check(uint32_t refused, const fogsf_output *out)
{
    const float sf = out->sf_ppm < 0.0f ? -out->sf_ppm : out->sf_ppm;
    const float b = out->bias_dph < 0.0f ? -out->bias_dph : out->bias_dph;
    ++steps;
    if (!finite_f(out->corrected_dps) || !finite_f(out->sf_ppm) || !(sf <= FOGSF_SF_LIMIT_PPM) ||
        !(b <= FOGSF_BIAS_LIMIT_DPH) || (out->flags & ~FOGSF_FLAGS_ALL) != 0u) {
        fprintf(stderr, "totality violated: corrected %g sf %g flags %u\n",
                (double)out->corrected_dps,
                (double)out->sf_ppm, (unsigned)out->flags);
        abort();
    }
    if (refused != 0u &&
        (out->corrected_dps != 0.0f || out->flags != FOGSF_FLAG_MODEL_INVALID)) {
        fprintf(stderr, "an invalid model must give 0 and MODEL_INVALID only (init refused it)\n");
        abort();
    }
}

static void run_samples(const fogsf_model *m, reader *r)
{
    fogsf_state st;
    fogsf_output out;
    const uint32_t refused = fogsf_init(m, &st, sizeof st);
    while (r->at < r->n) {
        const float t = next_f32(r);
        const float g = next_gyro(r);
        unsigned rep = next_u8(r);
        do {
            fogsf_step(m, &st, t, g, &out);
            check(refused, &out);
        } while (rep-- > 0u);
    }
}

static void fuzz_activations(reader *r)
{
    while (r->at < r->n) {
        const float x = next_f32(r);
        const float e = fogsf_expf(x), s = fogsf_sigmoidf(x), t = fogsf_tanhf(x);
        if (!finite_f(e) || !(e >= 0.0f) || !(s >= 0.0f && s <= 1.0f) ||
            !(t >= -1.0f && t <= 1.0f)) {
            fprintf(stderr, "activation out of range at x bits 0x%08x\n", (unsigned)r->at);
            abort();
        }
    }
}

#define CELL_MAX 6
static void fuzz_cell(reader *r)
{
    float w[4 * CELL_MAX * CELL_MAX], rr[4 * CELL_MAX * CELL_MAX], b[8 * CELL_MAX];
    float p[3 * CELL_MAX], x[CELL_MAX], h[CELL_MAX], c[CELL_MAX], scratch[CELL_MAX];
    const size_t n_in = 1u + next_u8(r) % CELL_MAX, hid = 1u + next_u8(r) % CELL_MAX;
    const uint8_t opts = next_u8(r);
    size_t i;
    for (i = 0; i < 4 * hid * n_in; ++i) {
        w[i] = next_f32(r);
    }
    for (i = 0; i < 4 * hid * hid; ++i) {
        rr[i] = next_f32(r);
    }
    for (i = 0; i < 8 * hid; ++i) {
        b[i] = next_f32(r);
    }
    for (i = 0; i < 3 * hid; ++i) {
        p[i] = next_f32(r);
    }
    for (i = 0; i < n_in; ++i) {
        x[i] = next_f32(r);
    }
    for (i = 0; i < hid; ++i) {
        h[i] = next_f32(r);
        c[i] = next_f32(r);
    }
    fogsf_lstm_cell(n_in, hid, w, rr, (opts & 1u) ? b : NULL, (opts & 2u) ? p : NULL, x, h, c,
                    scratch);
    for (i = 0; i < hid; ++i) { /* h = sigmoid * tanh: NaN only if the inputs carried one */
        if (finite_f(h[i]) && !(h[i] >= -1.0f && h[i] <= 1.0f)) {
            fprintf(stderr, "cell h out of [-1, 1]\n");
            abort();
        }
    }
}

/* an adversarial model: every array a window of weights taken from the input */
#define ADV_FLOATS 4096
static float adv[ADV_FLOATS];

static fogsf_bias_head adv_bias; /* the adversarial model's bias head */
static fogsf_plays adv_plays; /* the adversarial model's play operators */
static float adv_play_source_w[(FOGSF_MAX_PLAYS + 1) * (FOGSF_MAX_FILTERS + 2)];

static void fuzz_model_data(reader *r)
{
    fogsf_model m;
    uint8_t stuck_byte;
    uint32_t bias_mode;
    const float *lw[FOGSF_MAX_LAYERS + 1], *lr[FOGSF_MAX_LAYERS + 1], *lb[FOGSF_MAX_LAYERS + 1];
    size_t i;
    int l;
    uint8_t opts;
    memset(&m, 0, sizeof m);
    m.model_id = "adversarial";
    m.n_filters = next_u8(r) % (FOGSF_MAX_FILTERS + 2u);
    m.n_features = next_u8(r) % (FOGSF_MAX_FEATURES + 2u);
    m.layers = next_u8(r) % (FOGSF_MAX_LAYERS + 2u);
    m.hidden = next_u8(r) % (FOGSF_MAX_HIDDEN + 2u);
    m.decimation = next_u8(r) % 5u;
    stuck_byte = next_u8(r);
    m.stuck_samples = stuck_byte % 8u;
    bias_mode = (uint32_t)(stuck_byte >> 3) % 3u; /* 0 none, 1 a bias head, 2 one NULL array */
    m.sample_dt_s = next_f32(r);
    m.t_ref_c = next_f32(r);
    m.t_min_c = next_f32(r);
    m.t_max_c = next_f32(r);
    m.head_b = next_f32(r);
    m.out_scale = next_f32(r);
    m.out_offset = next_f32(r);
    for (i = 0; i < 64u; ++i) { /* the weights: 64 values from the input, then repeated */
        adv[i] = next_f32(r);
    }
    for (i = 64u; i < ADV_FLOATS; ++i) {
        adv[i] = adv[i % 64u];
    }
    for (l = 0; l < FOGSF_MAX_LAYERS + 1; ++l) {
        lw[l] = adv;
        lr[l] = adv + 1;
        lb[l] = adv + 2;
    }
    m.filter_alpha = adv + 3;
    m.feat_w = adv + 4;
    m.feat_b = adv + 5;
    m.lstm_w = lw;
    m.lstm_r = lr;
    m.lstm_b = lb;
    m.head_w = adv + 6;
    m.skip_w = adv + 7;
    opts = next_u8(r);
    if (opts & 1u) {
        m.quad_w = adv + 8;
        m.cube_w = adv + 9;
    }
    /* format 3, from the same byte (so the older corpus keeps its meaning: 0 and 0): the
       first layer's inputs (bits 1-3; 0 = all, beyond F invalid), the diagonal quadratic
       (bits 4-7 mod 3; 2 is invalid, so is 1 without the head) and the diagonal feature map
       (bits 4-7 div 3 mod 3, 0 for the values 0-2 the older corpus holds; 2 is invalid, so
       is 1 unless F == 1+K+P) */
    m.lstm_inputs = ((uint32_t)(opts >> 1) & 7u) % (FOGSF_MAX_FEATURES + 2u);
    m.quad_diag = (uint32_t)(opts >> 4) % 3u;
    m.feat_diag = ((uint32_t)(opts >> 4) / 3u) % 3u;
    m.format_version = FOGSF_FORMAT_VERSION;
    if ((stuck_byte >> 5) >= 6u) { /* play operators: 0..MAX+1 of them, source weights and
                                     half widths from the input (any float) */
        uint32_t j;
        adv_plays.n_plays = (uint32_t)stuck_byte % (FOGSF_MAX_PLAYS + 2u);
        for (j = 0; j < (FOGSF_MAX_PLAYS + 1u) * (FOGSF_MAX_FILTERS + 2u); ++j) {
            adv_play_source_w[j] = next_f32(r); /* any float, NaN and Inf too */
        }
        adv_plays.half_c = adv + 14;
        adv_plays.source_w = adv_play_source_w;
        m.plays = &adv_plays;
    }
    if (bias_mode != 0u) {
        adv_bias.w = adv + 10;
        adv_bias.quad_w = bias_mode == 2u ? NULL : adv + 11;
        adv_bias.cube_w = adv + 12;
        adv_bias.b = adv[13];
        m.bias = &adv_bias;
    }
    /* the CRCs as fogsf export writes them (every table is a window of adv, long enough for
       any size up to FOGSF_MAX_* + 1), unless the next byte says otherwise (mod 8): 1 a wrong
       sizes CRC, 2 a wrong tables CRC, 3 a forged format version */
    opts = next_u8(r);
    m.crc32_sizes = fogsf_model_crc32(&m, 1u) ^ ((opts % 8u) == 1u ? 1u : 0u);
    m.crc32 = fogsf_model_crc32(&m, 0u) ^ ((opts % 8u) == 2u ? 0x100u : 0u);
    if ((opts % 8u) == 3u) {
        m.format_version = 4u + (uint32_t)(opts >> 3) % 3u;
    }
    run_samples(&m, r);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    reader r;
    if (size < 1u) {
        return 0;
    }
    r.p = data;
    r.n = size;
    r.at = 1u;
    switch (data[0] % 4u) {
    case 0:
        fuzz_activations(&r);
        break;
    case 1:
        fuzz_cell(&r);
        break;
    case 2:
        run_samples(&fuzz_model, &r);
        break;
    default:
        fuzz_model_data(&r);
        break;
    }
    return 0;
}
