/*
 * Golden-vector check: the expected outputs (golden_vectors.h, written by fogsf/bindings/firmware.py
 * from the host build) are compared bit for bit: sf_ppm and the corrected rate as float32
 * bits, the flags exactly. Mismatches are printed with their index (first 10).
 */
#include "fogsf.h"
#include "golden_check.h"
#include "golden_vectors.h"

typedef union {
    float f;
    uint32_t u;
} f32_bits;

/* test-driver state and one chunk of buffers for fogsf_run (the kernel keeps no globals);
 * the inputs are read from the golden tables in flash, so the check fits a 16 KB RAM core */
#define GOLDEN_CHUNK 50u
static fogsf_state state;
static float temps[GOLDEN_CHUNK];
static float gyros[GOLDEN_CHUNK];
static float run_corrected[GOLDEN_CHUNK];
static float run_sf[GOLDEN_CHUNK];
static uint32_t run_flags[GOLDEN_CHUNK];

static float temp_of(unsigned long i)
{
    f32_bits t;
    t.u = golden_temp_bits[i];
    return t.f;
}

static float gyro_of(unsigned long i)
{
    f32_bits g;
    g.u = golden_gyro_bits[i];
    return g.f;
}

static void put_uint(fogsf_puts_fn out, unsigned long v)
{
    char buf[24];
    int i = 23;
    buf[i] = '\0';
    do {
        buf[--i] = (char)('0' + (int)(v % 10u));
        v /= 10u;
    } while (v != 0u && i > 0);
    out(buf + i);
}

static void put_hex(fogsf_puts_fn out, uint64_t v, int digits)
{
    static const char hex[] = "0123456789abcdef";
    char buf[20];
    int i;
    for (i = 0; i < digits; ++i) {
        buf[i] = hex[(v >> (4 * (digits - 1 - i))) & 0xfu];
    }
    buf[digits] = '\0';
    out(buf);
}

static int same_text(const char *a, const char *b)
{
    while (*a != '\0' && *a == *b) {
        ++a;
        ++b;
    }
    return *a == *b;
}

static unsigned long compare(fogsf_puts_fn out, const char *pass, unsigned long i, float sf,
                             float corrected, uint32_t flags, unsigned long bad)
{
    f32_bits s;
    f32_bits c;
    s.f = sf;
    c.f = corrected;
    if (s.u == golden_sf_bits[i] && c.u == golden_corrected_bits[i] &&
        flags == golden_flags[i]) {
        return bad;
    }
    if (bad < 10u) {
        out("mismatch ");
        out(pass);
        out(" sample ");
        put_uint(out, i);
        out(": sf 0x");
        put_hex(out, s.u, 8);
        out(" want 0x");
        put_hex(out, golden_sf_bits[i], 8);
        out(", corrected 0x");
        put_hex(out, c.u, 8);
        out(" want 0x");
        put_hex(out, golden_corrected_bits[i], 8);
        out(", flags ");
        put_uint(out, flags);
        out(" want ");
        put_uint(out, golden_flags[i]);
        out("\n");
    }
    return bad + 1u;
}

unsigned long fogsf_golden_check(fogsf_puts_fn out)
{
    unsigned long i, bad = 0u;
    fogsf_output o;

    out("fogsf golden vectors: model ");
    out(FOGSF_GOLDEN_MODEL->model_id);
    out(", ");
    put_uint(out, (unsigned long)FOGSF_GOLDEN_N);
    out(" samples, state ");
    put_uint(out, (unsigned long)fogsf_state_size());
    out(" bytes\n");
    if (!same_text(FOGSF_GOLDEN_MODEL->model_id, FOGSF_GOLDEN_MODEL_ID)) {
        out("FAIL: vectors are for model " FOGSF_GOLDEN_MODEL_ID "\n");
        return 1u;
    }
    /* the power-on self-test of this build (the flags it was compiled with) first */
    {
        const uint32_t st = fogsf_selftest(&state, sizeof state);
        out("selftest ");
        put_uint(out, (unsigned long)st);
        out(st == 0u ? " (the reference's bits)\n" : " (FAIL: this build's arithmetic differs)\n");
        bad += (st != 0u) ? 1u : 0u;
    }
    (void)fogsf_init(FOGSF_GOLDEN_MODEL, &state, sizeof state);
    for (i = 0; i < FOGSF_GOLDEN_N; ++i) {
        fogsf_step(FOGSF_GOLDEN_MODEL, &state, temp_of(i), gyro_of(i), &o);
        bad = compare(out, "step", i, o.sf_ppm, o.corrected_dps, o.flags, bad);
#ifdef FOGSF_GOLDEN_BIAS /* a model with a bias head: its bias bit for bit too */
        {
            f32_bits b;
            b.f = o.bias_dph;
            if (b.u != golden_bias_bits[i]) {
                if (bad < 10u) {
                    out("mismatch step sample ");
                    put_uint(out, i);
                    out(": bias 0x");
                    put_hex(out, b.u, 8);
                    out(" want 0x");
                    put_hex(out, golden_bias_bits[i], 8);
                    out("\n");
                }
                bad += 1u;
            }
        }
#endif
    }
    /* fogsf_run over the log in chunks, the state carried from one to the next */
    (void)fogsf_reset(FOGSF_GOLDEN_MODEL, &state, sizeof state);
    for (i = 0; i < FOGSF_GOLDEN_N; i += GOLDEN_CHUNK) {
        unsigned long j, n = FOGSF_GOLDEN_N - i < GOLDEN_CHUNK ? FOGSF_GOLDEN_N - i : GOLDEN_CHUNK;
        for (j = 0; j < n; ++j) {
            temps[j] = temp_of(i + j);
            gyros[j] = gyro_of(i + j);
        }
        (void)fogsf_run(FOGSF_GOLDEN_MODEL, &state, temps, gyros, n, run_corrected, run_sf,
                        run_flags);
        for (j = 0; j < n; ++j) {
            bad = compare(out, "run", i + j, run_sf[j], run_corrected[j], run_flags[j], bad);
        }
    }
    if (bad == 0u) {
        out("PASS: ");
        put_uint(out, 2u * (unsigned long)FOGSF_GOLDEN_N);
        out(" outputs bit-exact\n");
    } else {
        out("FAIL: ");
        put_uint(out, bad);
        out(" mismatching outputs\n");
    }
    return bad;
}
