/*
 * fogsf: thermal scale-factor (SF) compensation of a fiber-optic gyro, one call per 10 Hz
 * sample. The public API of the C99 kernel.
 *
 * Streaming contract: docs/stream-contract.md ("fogsf-stream-1"). The model (sizes, front-end
 * constants, weights) comes from the generated header fogsf_model.h (`fogsf export`), found on
 * the include path; this header only needs its size macros.
 *
 * Statefulness: all state lives in a fogsf_state the caller owns (static, stack or a struct
 * of its own). fogsf_init() or fogsf_reset() starts a log; every fogsf_step() consumes one
 * sample in order. Several gyros need several states; the weights are shared read-only.
 * The kernel never allocates, never recurses, holds no state in globals, and calls no libm:
 * its exp/sigmoid/tanh are its own float32 code, so host and Cortex-M4F give the same bits.
 *
 * Totality: fogsf_step() cannot fail. A NaN/Inf temperature reuses the last good one, a
 * temperature outside the trained range is clamped, a stuck thermometer is flagged, a
 * non-finite gyro gives corrected = 0.0; the output is always finite and the flags say why.
 */
#ifndef FOGSF_H
#define FOGSF_H

#include <stddef.h>
#include <stdint.h>

#include "fogsf_model.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Status flags of one sample (bits may combine). */
#define FOGSF_FLAG_TEMP_INVALID 1u /* temperature NaN/Inf: last good value (or t_ref) used */
#define FOGSF_FLAG_TEMP_CLAMPED 2u /* temperature outside [t_min, t_max]: clamped */
#define FOGSF_FLAG_TEMP_STUCK 4u   /* raw temperature unchanged for >= FOGSF_STUCK_SAMPLES */
#define FOGSF_FLAG_GYRO_INVALID 8u /* gyro (or corrected value) not finite: corrected = 0.0 */
#define FOGSF_FLAG_SF_CLAMPED 16u  /* model output NaN or beyond +-FOGSF_SF_LIMIT_PPM */

#define FOGSF_SF_LIMIT_PPM 1.0e5f

/* Caller-owned state, sized by the model macros. Treat as opaque; fogsf_reset() sets it. */
typedef struct fogsf_state {
    float h[FOGSF_LAYERS][FOGSF_HIDDEN];  /* LSTM hidden state per layer */
    float c[FOGSF_LAYERS][FOGSF_HIDDEN];  /* LSTM cell state per layer */
    float h_prev[FOGSF_HIDDEN];           /* scratch of one LSTM layer update */
    float z[FOGSF_N_FEATURES];            /* features of the latest model step */
    float y[FOGSF_N_FILTERS_ALLOC];       /* first-order lag filters of the temperature */
    float acc;                            /* sum of Tc since the last model step */
    float t_last_good;                    /* last sanitised finite temperature */
    float sf_ppm;                         /* output of the latest model step, held */
    uint32_t sf_flags;                    /* FOGSF_FLAG_SF_CLAMPED of that step */
    uint32_t raw_prev_bits;               /* previous raw temperature, bitwise */
    uint32_t stuck_run;                   /* repeats of it (saturates at the threshold) */
    uint32_t n_acc;                       /* samples in acc */
    uint32_t started;                     /* 0 until the first sample since reset */
} fogsf_state;

/* What one sample gives. */
typedef struct fogsf_output {
    double corrected_dps; /* gyro / (1 + sf_ppm * 1e-6): rate with the nominal SF restored */
    float sf_ppm;         /* predicted SF error vs nominal, ppm (held between model steps) */
    uint32_t flags;       /* FOGSF_FLAG_* */
} fogsf_output;

/* Start a log: zero LSTM state, filters primed by the first sample. init == reset. */
void fogsf_init(fogsf_state *st);
void fogsf_reset(fogsf_state *st);

/* One 10 Hz sample: board temperature (C) and raw gyro output (deg/s, nominal SF). */
void fogsf_step(fogsf_state *st, float temp_c, double gyro_dps, fogsf_output *out);

/* A whole log from the current state, sample by sample through fogsf_step(); any output
 * pointer may be NULL. Returns the OR of all flags. */
uint32_t fogsf_run(fogsf_state *st, const float *temp_c, const double *gyro_dps, size_t n,
                   double *corrected_dps, float *sf_ppm, uint32_t *flags);

/* sizeof(fogsf_state) and the model id, for bindings that check what they loaded. */
size_t fogsf_state_size(void);
const char *fogsf_model_id(void);

/* --- building blocks, model-independent (runtime sizes) ----------------------------- */

/* One step of an ONNX LSTM cell (gate order i, o, f, c; ONNX equations with default
 * activations): W [4H][n_in] and R [4H][H] row-major, B [8H] = [Wb; Rb] or NULL, P [3H] =
 * peepholes (i, o, f) or NULL. Updates h[H] and c[H] in place; h_prev [H] is scratch.
 * x must not overlap h. Pre-activations accumulate Wb+Rb, then W.x, then R.h, in index order. */
void fogsf_lstm_cell(size_t n_in, size_t hidden, const float *w, const float *r,
                     const float *b, const float *p, const float *x, float *h, float *c,
                     float *h_prev);

/* The kernel's float32 activations (no libm): within 1.2e-7 of the exact functions. */
float fogsf_expf(float x);
float fogsf_sigmoidf(float x);
float fogsf_tanhf(float x);

#ifdef __cplusplus
}
#endif

#endif /* FOGSF_H */
