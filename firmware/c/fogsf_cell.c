/*
 * Model-independent parts of the kernel: float32 activations, the generic LSTM cell, and the
 * whole-log calls fogsf_run / fogsf_run_bias. These loop over fogsf_step from here, not from
 * fogsf.c: a caller of fogsf_step in its own file lets GCC split it into an inlinable header
 * and a body, which costs the per-sample path a call and a second prologue.
 *
 * The activations are Cephes-style (range reduction + polynomial) in float32 only, written
 * so that every operation is a single IEEE float32 op: with -ffp-contract=off any IEEE
 * machine (x86-64 SSE, Cortex-M4F FPv4-SP) gives the same bits, and exp_f32, sigmoid_f32 and
 * tanh_f32 of fogsf/models/f32.py reproduce them op for op in numpy.
 */
#include "fogsf_fp.h" /* first: the floating-point build checks */
#include "fogsf.h"

#include <stdbool.h>

/* the parameters are named as in fogsf.h (Rule 8.3) and copied before they are clamped
 * (Rule 17.8) */
float fogsf_expf(float x)
{
    float xc = x;
    float t, tr, nf, r, z, p, e;
    int32_t n;
    fogsf_f32_bits scale;

    /* selects, not branches (one path for every input): NaN counts as -87, so exp stays
     * finite and the cast below defined */
    xc = (xc > -87.0f) ? xc : -87.0f;
    xc = (xc > 88.0f) ? 88.0f : xc;
    /* xc = n ln2 + r, |r| <= ln2/2, ln2 split in two so that n*ln2_hi is exact */
    t = xc * 1.44269502f;
    tr = t + ((t >= 0.0f) ? 0.5f : -0.5f); /* rounded in a variable: only it is cast (10.8) */
    n = (int32_t)tr;
    nf = (float)n;
    r = (xc - nf * 0.693359375f) - nf * -0.000212194442f;
    z = r * r;
    p = 0.000198756912f;
    p = p * r + 0.00139819994f;
    p = p * r + 0.00833345205f;
    p = p * r + 0.0416657962f;
    p = p * r + 0.166666657f;
    p = p * r + 0.5f;
    e = (p * z + r) + 1.0f;
    n = n + 127; /* the biased exponent of 2^n, n in [-126, 127]: 1 .. 254 */
    scale.u = (uint32_t)n << 23u;
    return e * scale.f;
}

float fogsf_sigmoidf(float x)
{
    return 1.0f / (1.0f + fogsf_expf(-x));
}

/* tanh of |x| > 0.625 (a = |x|, sign applied by the caller): 1 - 2 / (e^2a + 1) */
static float tanh_big(float a)
{
    return 1.0f - (2.0f / (fogsf_expf(a + a) + 1.0f));
}

/* tanh of |x| <= 0.625: x + x^3 P(x^2), the Cephes odd polynomial */
static float tanh_small(float x)
{
    const float z = x * x;
    float p = -0.00570498873f;
    p = (p * z) + 0.020639088f;
    p = (p * z) + -0.0537397154f;
    p = (p * z) + 0.133314416f;
    p = (p * z) + -0.333332807f;
    return ((p * z) * x) + x;
}

#if FOGSF_EVEN_TIME
/* a when c, else b, by the bits: both are computed, nothing branches on the value */
static float select_f(bool c, float a, float b)
{
    const uint32_t mask = c ? 0xffffffffu : 0u;
    fogsf_f32_bits ua;
    fogsf_f32_bits ub;
    ua.f = a;
    ub.f = b;
    ua.u = (ua.u & mask) | (ub.u & ~mask);
    return ua.f;
}

/* tanh with one path for every input: the exp form and the polynomial both computed, the
 * one the default build would take selected (the same bits) */
float fogsf_tanhf(float x)
{
    float xc = x;
    float a, big, small;

    xc = (xc >= -10.0f) ? xc : -10.0f; /* tanh(10) rounds to 1.0f; NaN counts as -10 */
    xc = (xc > 10.0f) ? 10.0f : xc;
    a = (xc < 0.0f) ? -xc : xc;
    big = tanh_big(a);
    big = select_f(xc < 0.0f, -big, big);
    small = tanh_small(xc);
    return select_f(a > 0.625f, big, small);
}
#else
float fogsf_tanhf(float x)
{
    float xc = x;
    float a, y;

    if (!(xc >= -10.0f)) { /* tanh(10) rounds to 1.0f; NaN counts as -10 */
        xc = -10.0f;
    }
    if (xc > 10.0f) {
        xc = 10.0f;
    }
    a = (xc < 0.0f) ? -xc : xc;
    if (a > 0.625f) {
        const float big = tanh_big(a);
        y = (xc < 0.0f) ? -big : big;
    } else {
        y = tanh_small(xc);
    }
    return y;
}
#endif

/* pre[g] += rows[g] . v for the four gate rows at once, each accumulated in index order (the
 * contract's order: four independent chains interleaved, so the bits are those of four
 * separate loops while an out-of-order CPU overlaps their latencies) */
static void dot4_from(float pre[4], const float *rows[4], const float *v, size_t n)
{
    float a0 = pre[0], a1 = pre[1], a2 = pre[2], a3 = pre[3];
    const float *r0 = rows[0], *r1 = rows[1], *r2 = rows[2], *r3 = rows[3];
    size_t k;
    for (k = 0; k < n; ++k) {
        const float vk = v[k];
        a0 = a0 + r0[k] * vk;
        a1 = a1 + r1[k] * vk;
        a2 = a2 + r2[k] * vk;
        a3 = a3 + r3[k] * vk;
    }
    pre[0] = a0;
    pre[1] = a1;
    pre[2] = a2;
    pre[3] = a3;
}

void fogsf_lstm_unit(size_t n_in, size_t hidden, const float *w, const float *r,
                     const float *b, const float *p, const float *x, float *h, float *c,
                     float *h_prev, size_t j)
{
    size_t gate;
    float pre[4];
    const float *rows[4];
    float gi, go, gf, gc, ci, cf, cn;

    if (j == 0u) { /* the layer's first unit: the previous h, which every unit reads */
        for (gate = 0u; gate < hidden; ++gate) {
            h_prev[gate] = h[gate];
        }
    }
    /* the unit's four gate rows (i, o, f, c) read only the previous h */
    for (gate = 0u; gate < 4u; ++gate) {
        const size_t row = (gate * hidden) + j;
        pre[gate] = (b != NULL) ? (b[row] + b[(4u * hidden) + row]) : 0.0f;
        rows[gate] = w + row * n_in;
    }
    dot4_from(pre, rows, x, n_in);
    for (gate = 0u; gate < 4u; ++gate) {
        rows[gate] = r + (((gate * hidden) + j) * hidden);
    }
    dot4_from(pre, rows, h_prev, hidden);
    gi = pre[0];
    go = pre[1];
    gf = pre[2];
    gc = pre[3];
    if (p != NULL) { /* peepholes see the previous cell state (i, f), the new one (o) */
        gi = gi + p[j] * c[j];
        gf = gf + (p[(2u * hidden) + j] * c[j]);
    }
    ci = fogsf_sigmoidf(gi) * fogsf_tanhf(gc);
    cf = fogsf_sigmoidf(gf) * c[j];
    cn = cf + ci;
    if (p != NULL) {
        go = go + p[hidden + j] * cn;
    }
    c[j] = cn;
    h[j] = fogsf_sigmoidf(go) * fogsf_tanhf(cn);
}

void fogsf_lstm_cell(size_t n_in, size_t hidden, const float *w, const float *r,
                     const float *b, const float *p, const float *x, float *h, float *c,
                     float *h_prev)
{
    size_t j;

    /* a NULL array: nothing is read or written (b and p may be NULL) */
    if ((w != NULL) && (r != NULL) && (x != NULL) && (h != NULL) && (c != NULL) &&
        (h_prev != NULL)) {
        for (j = 0; j < hidden; ++j) {
            fogsf_lstm_unit(n_in, hidden, w, r, b, p, x, h, c, h_prev, j);
        }
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

    if ((n > 0u) && ((temp_c == NULL) || (gyro_dps == NULL) || (st == NULL))) {
        all = FOGSF_FLAG_CALL_INVALID; /* nothing stepped or written */
    } else {
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
    }
    return all;
}
