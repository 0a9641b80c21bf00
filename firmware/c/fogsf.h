/*
 * fogsf: thermal scale-factor (SF) compensation of a fiber-optic gyro, one call per sample.
 * The public API of the C99 kernel.
 *
 * Streaming contract: docs/stream-contract.md (FOGSF_CONTRACT_VERSION); firmware use:
 * docs/firmware.md.
 * The model is data (CMSIS-NN style): `fogsf export --name NAME` writes NAME.h and NAME.c, whose
 * `const fogsf_model NAME` holds the sizes, front-end constants and pointers to `static const`
 * weights. Any number of models link into one image; every call takes the model by pointer.
 *
 * Statefulness: all state lives in a fogsf_state the caller owns (static, stack or a struct
 * of its own), one per gyro. fogsf_init() or fogsf_reset() starts a log; every fogsf_step()
 * consumes one sample in order, always with the same model. fogsf_state is sized for the
 * largest model of the image by FOGSF_MAX_LAYERS, FOGSF_MAX_HIDDEN, FOGSF_MAX_FEATURES,
 * FOGSF_MAX_FILTERS, FOGSF_MAX_PLAYS and FOGSF_MAX_RATE_ROWS (defaults below; the CMake
 * function fogsf_add_model raises them to the largest model added; NAME.c refuses to compile
 * when its model does not fit).
 * The kernel never allocates, never recurses, holds no state in globals, and calls no libm:
 * its exp/sigmoid/tanh are its own float32 code, so host and Cortex-M4F give the same bits.
 *
 * Totality: fogsf_step() cannot fail. A NaN/Inf temperature reuses the last good one, a
 * temperature outside the trained range is clamped, a stuck thermometer is flagged, a
 * non-finite gyro gives corrected = 0.0f, a model that does not fit the state (or a NULL
 * one) gives corrected = 0.0 and FOGSF_FLAG_MODEL_INVALID; until the first plausible
 * temperature the lag filters wait (FOGSF_FLAG_TEMP_UNPRIMED); a model changed after init
 * holds the last verified correction (FOGSF_FLAG_MODEL_CHANGED); a NULL pointer or a state
 * of another size is refused (FOGSF_FLAG_CALL_INVALID). The output is always finite and the
 * flags say why.
 */
#ifndef FOGSF_H
#define FOGSF_H

#include <stddef.h>
#include <stdint.h>

/* State capacity: the largest model stepped with a fogsf_state (override with -D). */
#ifndef FOGSF_MAX_LAYERS
#define FOGSF_MAX_LAYERS 1
#endif
#ifndef FOGSF_MAX_HIDDEN
#define FOGSF_MAX_HIDDEN 16
#endif
#ifndef FOGSF_MAX_FEATURES
#define FOGSF_MAX_FEATURES 4
#endif
#ifndef FOGSF_MAX_FILTERS
#define FOGSF_MAX_FILTERS 4
#endif
#ifndef FOGSF_MAX_PLAYS
#define FOGSF_MAX_PLAYS 1
#endif
/* the held coefficients of the rate part: R of a model, at most FOGSF_RATE_ROWS_LIMIT; 0 (the
 * default) builds the kernel without the rate part (no state, code or time for it; a model
 * with one is refused) */
#ifndef FOGSF_MAX_RATE_ROWS
#define FOGSF_MAX_RATE_ROWS 0
#endif

/* The rate part's bounds (docs/stream-contract.md, "Optional rate part"): R terms (|x| and
 * x^2 .. x^R), Q coefficients a term (a polynomial of degree Q-1 in temperature). */
#define FOGSF_RATE_ROWS_LIMIT 9u
#define FOGSF_RATE_COEFS_LIMIT 3u

/* Bounded, even time (define to 1 for the kernel's sources, all alike): the model step is
 * spread over the D samples up to the next one (its front at the step's sample, then one LSTM
 * unit a sample, then the head, then the bias head), its outputs held from the next step's
 * sample on (D samples later than by default, the same bits: docs/stream-contract.md,
 * "Even time"), and fogsf_expf / fogsf_tanhf run one path for every input. */
#ifndef FOGSF_EVEN_TIME
#define FOGSF_EVEN_TIME 0
#endif

/* 1: fogsf_init runs fogsf_selftest on the caller's state first and refuses the model when
 * the build's arithmetic gives other bits (a flag no macro announces: firmware/c/MISRA.md,
 * Dir 1.1); it costs the self-test's flash and its run time at every init. */
#ifndef FOGSF_SELFTEST_AT_INIT
#define FOGSF_SELFTEST_AT_INIT 0
#endif

/* A first temperature is plausible when finite, within [FOGSF_TEMP_PLAUSIBLE_MIN_C,
 * FOGSF_TEMP_PLAUSIBLE_MAX_C] (the range of common board sensors: DS18B20, LM75) and not
 * FOGSF_TEMP_POWER_ON_C (a DS18B20 reads 85 C until its first conversion; define it outside
 * the range to drop that test). The reference (docs/stream-contract.md) uses these values. */
#ifndef FOGSF_TEMP_PLAUSIBLE_MIN_C
#define FOGSF_TEMP_PLAUSIBLE_MIN_C (-55.0f)
#endif
#ifndef FOGSF_TEMP_PLAUSIBLE_MAX_C
#define FOGSF_TEMP_PLAUSIBLE_MAX_C 125.0f
#endif
#ifndef FOGSF_TEMP_POWER_ON_C
#define FOGSF_TEMP_POWER_ON_C 85.0f
#endif

#ifdef __cplusplus
extern "C" {
#endif

/* Status flags of one sample (bits may combine). */
#define FOGSF_FLAG_TEMP_INVALID 1u /* temperature NaN/Inf: last good value (or t_ref) used */
#define FOGSF_FLAG_TEMP_CLAMPED 2u /* temperature outside [t_min, t_max]: clamped */
#define FOGSF_FLAG_TEMP_STUCK 4u   /* raw temperature unchanged for >= stuck_samples */
#define FOGSF_FLAG_GYRO_INVALID 8u /* gyro (or corrected value) not finite: corrected = 0.0 */
#define FOGSF_FLAG_SF_CLAMPED 16u  /* model output NaN or beyond +-FOGSF_SF_LIMIT_PPM */
#define FOGSF_FLAG_MODEL_INVALID 32u /* model NULL or larger than FOGSF_MAX_*: corrected = 0 */
#define FOGSF_FLAG_BIAS_CLAMPED 64u /* bias head output NaN or beyond +-FOGSF_BIAS_LIMIT_DPH */
#define FOGSF_FLAG_TEMP_UNPRIMED 128u /* no plausible temperature since reset: the gyro as it
                                        is (sf 0, bias 0), the filters wait for one */
#define FOGSF_FLAG_MODEL_CHANGED 256u /* the model's sizes or tables changed since init: the
                                        last verified correction held until a reset */
#define FOGSF_FLAG_CALL_INVALID 512u /* a NULL pointer, or a state of another size: nothing
                                       read or written (corrected 0) */
#define FOGSF_FLAG_SELFTEST_FAILED 1024u /* fogsf_init only (FOGSF_SELFTEST_AT_INIT): the
                                           build's arithmetic failed the self-test */
#define FOGSF_FLAG_RATE_CLAMPED 2048u /* |corrected| beyond the rate part's full scale: the
                                        rate correction at the edge (x = +-1) used */
#define FOGSF_FLAGS_ALL 3071u /* every flag a sample's flags can hold (not SELFTEST_FAILED) */

#define FOGSF_SF_LIMIT_PPM 1.0e5f
#define FOGSF_BIAS_LIMIT_DPH 3.6e4f /* 10 deg/s: a bias beyond it is a broken model */

/* The bias head of a model (deg/h), a polynomial of the same features z:
 * bias = b + sum w[i] z_i + sum quad_w[i] z_i^2 + sum cube_w[i] z_i^3 (float32, index order);
 * corrected = (gyro - bias / 3600) / (1 + sf_ppm * 1e-6), in float32 (fogsf_output). */
typedef struct fogsf_bias_head {
    const float *w;               /* [F] */
    const float *quad_w;          /* [F] */
    const float *cube_w;          /* [F] */
    float b;                      /* deg/h */
} fogsf_bias_head;

/* P play (backlash) operators run after the lag filters at every model step:
 * x_j = 0 + v_j0 Tm + v_j1 y_1 + ... + v_jK y_K (float32, index order), then
 * p_j = min(max(p_j, x_j - h_j), x_j + h_j) (x - h and x + h in float32, then the two
 * compares), p_j primed with the first sample's temperature; s gains p_j - t_ref after the
 * filters, so feat_w is [F][1+K+P]. */
typedef struct fogsf_plays {
    uint32_t n_plays;             /* P >= 1 */
    const float *half_c;          /* [P] half widths h_j (C), finite, >= 0 */
    const float *source_w;        /* [P][1+K] source weights v over [Tm, y_1..y_K], finite */
} fogsf_plays;

/* A model, read-only (generated by `fogsf export --name NAME`; never written by the kernel).
 * Arrays are float32, row-major, in the layout of docs/stream-contract.md. The optional parts
 * are reached through their own pointers (NULL when absent), never by casting the model to a
 * larger struct, so no field value can make the kernel read past this struct. */
typedef struct fogsf_model {
    const char *model_id;         /* 16 hex digits, the artifact's id */
    uint32_t format_version;      /* FOGSF_FORMAT_VERSION: this struct's layout */
    uint32_t n_filters;           /* K lag filters */
    uint32_t n_features;          /* F features */
    uint32_t layers;              /* L LSTM layers */
    uint32_t hidden;              /* H units per layer */
    uint32_t decimation;          /* D samples per model step (>= 1) */
    uint32_t stuck_samples;       /* stuck-thermometer threshold, 0 = off */
    float sample_dt_s;            /* sample period the model was exported for */
    float t_ref_c, t_min_c, t_max_c;
    const float *filter_alpha;    /* [K] */
    const float *feat_w;          /* [F][1+K+P] ([F] with feat_diag) */
    const float *feat_b;          /* [F] */
    const float *const *lstm_w;   /* [L] -> [4H][n_in], gate order i, o, f, c */
    const float *const *lstm_r;   /* [L] -> [4H][H] */
    const float *const *lstm_b;   /* [L] -> [8H] = [Wb; Rb] */
    const float *head_w;          /* [H] */
    const float *skip_w;          /* [F] */
    const float *quad_w;          /* [F][F] ([F] with quad_diag), NULL without the poly head */
    const float *cube_w;          /* [F], NULL without the polynomial head */
    float head_b, out_scale, out_offset;
    uint32_t lstm_inputs;         /* N: LSTM layer 0 reads z[0:N], W is [4H][N]; 0 = all F */
    uint32_t quad_diag;           /* 1: quad_w is the diagonal [F] of the quadratic; 0: [F][F] */
    uint32_t feat_diag;           /* 1: F == 1+K+P and feat_w is the diagonal [F]:
                                     z_i = feat_b[i] + feat_w[i] * s_i; 0: [F][1+K+P] */
    const fogsf_bias_head *bias;  /* the bias head, NULL without one */
    const fogsf_plays *plays;     /* the play operators, NULL without them */
    uint32_t crc32_sizes;         /* CRC-32 of the sizes and scalars (fogsf_model_crc32) */
    uint32_t crc32;               /* CRC-32 of the sizes, scalars and every table */
    /* the rate part, only with format_version FOGSF_FORMAT_VERSION_RATE (NULL and 0
     * without it): per sample, after the SF and bias, x = corrected * rate_inv_fs clamped
     * to [-1, 1], corrected -= a_0 |x| + a_1 x^2 + ... + a_(R-1) x^R, each a_r a polynomial
     * of degree Q-1 in s0 = Tm - t_ref held from the model step (docs/stream-contract.md) */
    const float *rate_w;          /* [R][Q]: row r's coefficients of s0^0 .. s0^(Q-1) */
    uint32_t rate_rows;           /* R, 1 .. FOGSF_RATE_ROWS_LIMIT */
    uint32_t rate_coefs;          /* Q, 1 .. FOGSF_RATE_COEFS_LIMIT */
    float rate_inv_fs;            /* 1 / full scale (deg/s), float32, finite and > 0 */
} fogsf_model;

/* format_version of a fogsf_model laid out as above (explicit pointers to the bias head and
 * the plays, the two CRCs) without a rate part (its rate fields NULL and 0), and of one with
 * it; fogsf_model_check refuses every other value, so a kernel from before the rate part
 * refuses a model that has one rather than run it without. */
#define FOGSF_FORMAT_VERSION 6u
#define FOGSF_FORMAT_VERSION_RATE 7u

/* The streaming contract this kernel computes (docs/stream-contract.md): 2 = "fogsf-stream-2",
 * the per-sample correction in float32 (float gyro in and corrected rate out); 1 corrected in
 * double. The model tables (FOGSF_FORMAT_VERSION) are the same for both. */
#define FOGSF_CONTRACT_VERSION 2u

/* fogsf_model has feat_diag (NAME.c of a model with it checks, so that a kernel from before
 * it cannot read its [F] feat_w as [F][1+K+P]) */
#define FOGSF_FEAT_DIAG 1

/* Caller-owned state, sized for the largest model (FOGSF_MAX_*). Treat as opaque. */
typedef struct fogsf_state {
    const fogsf_model *model;                    /* the model fogsf_init/reset accepted
                                                    (fogsf_model_check), NULL if refused */
    float h[FOGSF_MAX_LAYERS][FOGSF_MAX_HIDDEN]; /* LSTM hidden state per layer */
    float c[FOGSF_MAX_LAYERS][FOGSF_MAX_HIDDEN]; /* LSTM cell state per layer */
#if FOGSF_EVEN_TIME
    /* what a step's parts pass on from sample to sample; the default build runs a step whole
     * on one sample and keeps them on its stack (one copy, not one a state) */
    float h_prev[FOGSF_MAX_HIDDEN];              /* one LSTM layer's previous h */
    float z[FOGSF_MAX_FEATURES];                 /* features of the step under way */
#endif
    float y[FOGSF_MAX_FILTERS];                  /* first-order lag filters of the temperature */
    float p[FOGSF_MAX_PLAYS];                    /* play operators' outputs */
    float acc;                                   /* sum of Tc since the last model step */
    float t_last_good;                           /* last sanitised finite temperature */
    float sf_ppm;                                /* output of the latest model step, held */
    float bias_dph;                              /* its bias (0 without a bias head), held */
    float bias_dps;                              /* bias_dph / 3600 (float32), held */
    float sf_k;                                  /* s / (1 + s), s = sf_ppm * 1e-6, held */
    uint32_t sf_flags;                           /* FOGSF_FLAG_SF/BIAS_CLAMPED of that step */
#if FOGSF_EVEN_TIME
    float sf_next, k_next, bias_next, bias_dps_next; /* the step being computed: held */
    uint32_t flags_next;                         /* from its publication on (the default
                                                    build writes the held ones at once) */
#endif
    uint32_t part;                               /* FOGSF_EVEN_TIME: its next part, 0 none */
    uint32_t raw_prev_bits;                      /* previous raw temperature, bitwise */
    uint32_t stuck_run;                          /* repeats of it (saturates at the threshold) */
    uint32_t n_acc;                              /* samples in acc */
    uint32_t started;                            /* 0 until the first plausible temperature
                                                    since reset (it primes the filters) */
    /* run-time integrity: what init recorded, the CRC pass under way (half a float a
     * sample), the held outputs at the start of the last verified pass and of this one */
    uint32_t model_crc;                          /* the model's crc32 at init */
    uint32_t sizes_a, sizes_b;                   /* its sizes at init, packed */
    const float *crc_at, *crc_end;               /* the next float of the pass, the end of
                                                    its table */
    uint32_t crc_seg;                            /* the pass's next head word or table;
                                                    bit 16: the float's high half next */
    uint32_t crc_reg;                            /* the pass's CRC register */
    uint32_t fault;                              /* FOGSF_FLAG_MODEL_CHANGED once a check
                                                    failed, until a reset */
    float good_sf, good_bias;                    /* verified held outputs */
    float cand_sf, cand_bias;                    /* held at this pass's start */
    uint32_t snap_flags;                         /* their sf_flags: good | cand << 16 */
#if FOGSF_MAX_RATE_ROWS > 0
    /* the rate part: the held a_r (+0 from R on), the step's (even-time build), the
     * verified and candidate ones; R | Q << 8 and 1/FS as init recorded them (0 without the
     * part); rate_on nonzero once primed with a rate part */
    uint32_t sizes_c;
    float rate_a[FOGSF_MAX_RATE_ROWS];
#if FOGSF_EVEN_TIME
    float rate_next[FOGSF_MAX_RATE_ROWS];
#endif
    float good_rate[FOGSF_MAX_RATE_ROWS];
    float cand_rate[FOGSF_MAX_RATE_ROWS];
    float rate_inv_fs;
    uint32_t rate_on;
#endif
} fogsf_state;

/* What one sample gives. */
typedef struct fogsf_output {
    float corrected_dps;  /* (gyro - bias_dph / 3600) / (1 + sf_ppm * 1e-6): the rate with the
                             nominal SF restored and the bias taken off, float32: d = gyro -
                             b, b = bias_dph / 3600, then d - d * k, k = s / (1 + s),
                             s = sf_ppm * 1e-6 (b and k once per model step); with a rate
                             part, less its rate error at that rate */
    float sf_ppm;         /* predicted SF error vs nominal, ppm (held between model steps) */
    uint32_t flags;       /* FOGSF_FLAG_* */
    float bias_dph;       /* predicted bias, deg/h (held; 0 without a bias head) */
} fogsf_output;

/* 0 when m is a whole model of this kernel's format (FOGSF_FORMAT_VERSION, or
 * FOGSF_FORMAT_VERSION_RATE with a rate part), fits fogsf_state (FOGSF_MAX_*), is complete
 * (lstm_inputs <= F, quad_diag 0 or 1 and only with the polynomial head, feat_diag 0 or 1
 * and only with F == 1+K+P, the bias head's and the plays' arrays present, half widths and
 * source weights finite; the rate part's rate_w present with 1 <= R <= FOGSF_MAX_RATE_ROWS,
 * 1 <= Q <= FOGSF_RATE_COEFS_LIMIT, its weights finite and rate_inv_fs finite and > 0, or
 * all its fields NULL and 0 in format FOGSF_FORMAT_VERSION) and its tables are intact
 * (crc32_sizes, then crc32: fogsf_model_crc32), else FOGSF_FLAG_MODEL_INVALID (a NULL m
 * too). Reads every table once (about 5 instructions a byte): fogsf_init calls it. After
 * init fogsf_step checks at every sample that the state was started with m, and on every
 * sample that reads the model's arrays for a model step (or, with FOGSF_EVEN_TIME, a part
 * of one) the sizes and pointers, the sizes against those init recorded; and it re-reads
 * half a float of the model's tables a sample into a CRC, so the whole model is compared
 * with the crc32 init recorded at least every fogsf_check_period(m) samples
 * (FOGSF_FLAG_MODEL_CHANGED). */
uint32_t fogsf_model_check(const fogsf_model *m);

/* The CRC-32 (IEEE 802.3, reflected, as zlib.crc32) of m's sizes and scalars
 * (sizes_only != 0: what crc32_sizes holds), or of those and then every table in the order
 * of the struct (what crc32 holds); every value is taken as its 32 bits, least significant
 * byte first. m must have passed the size checks of fogsf_model_check: the table lengths come
 * from its sizes (a NULL m: 0). */
uint32_t fogsf_model_crc32(const fogsf_model *m, uint32_t sizes_only);

/* The most samples one run-time check of m takes (a pass): fogsf_step reads half a float of
 * the tables a sample; a head word, the start of a table and the pass's compare each wait
 * for a sample that reads the arrays anyway (a model step's; with FOGSF_EVEN_TIME a part's):
 * (21 + T + 1) D + 2 (the floats of m's tables), T = 12 + 3 L table slots (with a rate
 * part 24 head slots and T = 13 + 3 L: its three scalars and rate_w). A model changed
 * after init is flagged within two passes. 0 for a model fogsf_model_check refuses. */
uint32_t fogsf_check_period(const fogsf_model *m);

/* Power-on check of the arithmetic this build gives: runs the kernel's activations and a
 * built-in 1x1 model (one filter, one play, polynomial and bias heads, bad inputs planted)
 * through fogsf_step on *scratch, and compares every output bit for bit with the values the
 * numpy reference gives (generated into fogsf_selftest.c). 0 when all match, else the OR of
 * FOGSF_SELFTEST_*: a compiler flag or a toolchain broke the float32 order (FMA contraction,
 * fast math, a wrong soft-float library); it also checks the IEEE rules the kernel's NaN,
 * signed-zero and division code relies on, each on its own probe. state_size is sizeof(fogsf_state) as the caller
 * compiled it (another size, or a NULL scratch: the model part fails, nothing is written).
 * *scratch is overwritten: fogsf_init it afterwards. */
uint32_t fogsf_selftest(fogsf_state *scratch, size_t state_size);

#define FOGSF_SELFTEST_ACTIVATIONS 1u /* fogsf_expf / sigmoidf / tanhf gave other bits */
#define FOGSF_SELFTEST_MODEL 2u       /* the built-in model's outputs differ */
#define FOGSF_SELFTEST_CHECK 4u       /* fogsf_model_check refused the built-in model */
#define FOGSF_SELFTEST_FLOAT_RULES 8u /* an IEEE rule the kernel relies on broken: a NaN
                                         compared equal or ordered, -0 + 0 not +0, x / c
                                         not correctly rounded, (a + b) - b reassociated, or
                                         Inf compared as finite (clang's -fno-honor-nans,
                                         -fno-signed-zeros, -freciprocal-math,
                                         -fassociative-math, -fno-honor-infinities, which
                                         no macro announces) */

/* Start a log: zero LSTM state, the filters primed by the first plausible temperature.
 * state_size is sizeof(fogsf_state) as the caller compiled it: a NULL st or another size (a
 * kernel built with other FOGSF_MAX_*) returns FOGSF_FLAG_CALL_INVALID and writes nothing.
 * Else returns fogsf_model_check(m) and records the model (its crc32 and sizes) for the
 * run-time checks of fogsf_step; a model it refuses is never stepped: every fogsf_step with
 * this state gives corrected 0 and FOGSF_FLAG_MODEL_INVALID until a reset with a model it
 * accepts. fogsf_init is fogsf_reset, with FOGSF_SELFTEST_AT_INIT 1 after fogsf_selftest on
 * st (a failure: FOGSF_FLAG_SELFTEST_FAILED | FOGSF_FLAG_MODEL_INVALID, the model refused). */
uint32_t fogsf_init(const fogsf_model *m, fogsf_state *st, size_t state_size);
uint32_t fogsf_reset(const fogsf_model *m, fogsf_state *st, size_t state_size);

/* One sample: board temperature (C) and raw gyro output (deg/s, nominal SF), both float32
 * (the correction is float32: a float32 rate carries 2^-24 = 0.06 ppm of itself, far below
 * any SF figure; docs/stream-contract.md, "Precisions"), with the model
 * st was started with (another model, or one refused at reset: corrected 0, MODEL_INVALID).
 * A NULL m or st: corrected 0, MODEL_INVALID | CALL_INVALID; a NULL out: nothing done. */
void fogsf_step(const fogsf_model *m, fogsf_state *st, float temp_c, float gyro_dps,
                fogsf_output *out);

/* A whole log from the current state, sample by sample through fogsf_step(); any output
 * pointer may be NULL. Returns the OR of all flags (n > 0 with a NULL input array or a NULL
 * st: FOGSF_FLAG_CALL_INVALID, nothing stepped or written). */
uint32_t fogsf_run(const fogsf_model *m, fogsf_state *st, const float *temp_c,
                   const float *gyro_dps, size_t n, float *corrected_dps, float *sf_ppm,
                   uint32_t *flags);

/* fogsf_run with the held bias (deg/h) per sample too (bias_dph may be NULL). */
uint32_t fogsf_run_bias(const fogsf_model *m, fogsf_state *st, const float *temp_c,
                        const float *gyro_dps, size_t n, float *corrected_dps,
                        float *sf_ppm, float *bias_dph, uint32_t *flags);

/* sizeof(fogsf_state), for bindings that check the layout they loaded. */
size_t fogsf_state_size(void);

/* --- building blocks, model-independent (runtime sizes) ----------------------------- */

/* One step of an ONNX LSTM cell (gate order i, o, f, c; ONNX equations with default
 * activations): W [4H][n_in] and R [4H][H] row-major, B [8H] = [Wb; Rb] or NULL, P [3H] =
 * peepholes (i, o, f) or NULL. Updates h[H] and c[H] in place; h_prev [H] is scratch.
 * x must not overlap h. Pre-activations accumulate Wb+Rb, then W.x, then R.h, in index order. */
void fogsf_lstm_cell(size_t n_in, size_t hidden, const float *w, const float *r,
                     const float *b, const float *p, const float *x, float *h, float *c,
                     float *h_prev);

/* Unit j of fogsf_lstm_cell (the same arguments): its c[j] and h[j], from h_prev [H], which
 * unit 0 first fills with h. fogsf_lstm_cell is this for j = 0 .. H-1 in order. It checks
 * nothing (the model step's innermost call): its arrays non-NULL and j < hidden are the
 * caller's; fogsf_lstm_cell refuses NULL arrays. */
void fogsf_lstm_unit(size_t n_in, size_t hidden, const float *w, const float *r,
                     const float *b, const float *p, const float *x, float *h, float *c,
                     float *h_prev, size_t j);

/* The kernel's float32 activations (no libm): within 1.2e-7 of the exact functions. */
float fogsf_expf(float x);
float fogsf_sigmoidf(float x);
float fogsf_tanhf(float x);

#ifdef __cplusplus
}
#endif

#endif /* FOGSF_H */
