/* Cortex-M4F instruction-count probe: the fogsf_step calls of one sample (one per model of
 * the image, image_models.h) sit between two marker calls; QEMU's one-instruction-per-block
 * execution trace is counted between the markers (benchmarks/firmware_bench.py), which gives
 * exact, deterministic counts per sample. The models share one decimation (and shape).
 * Before the counted samples, whole decimation periods run uncounted until the run-time
 * check reads the floats of a table longer than the counted samples: then every counted
 * sample pays for a float of the check, its dearest case between model steps (a head word
 * or a table's start waits for a model step). */
#include "fogsf.h"
#include "image_models.h"
#include "semihost.h"

static const fogsf_model *const models[IMAGE_N_MODELS] = IMAGE_MODELS;
static fogsf_state states[IMAGE_N_MODELS];

typedef union {
    float f;
    uint32_t u;
} fogsf_f32;

__attribute__((noinline)) void fogsf_bench_begin(void)
{
    __asm__ volatile("" ::: "memory");
}

__attribute__((noinline)) void fogsf_bench_end(void)
{
    __asm__ volatile("" ::: "memory");
}

static float t_ramp = 20.0f;
static float g;

/* sample i's inputs: a 0.01 C a sample ramp; every 5th from 1 a NaN temperature, every 5th
 * from 2 one beyond t_max, every 7th from 3 a NaN gyro */
static void fogsf_sample_inputs(uint32_t i, float *t, float *gyro)
{
    fogsf_f32 nan;
    nan.u = 0x7fc00000u;
    t_ramp = t_ramp + 0.01f;
    *t = (i % 5u == 1u) ? nan.f : ((i % 5u == 2u) ? 500.0f : t_ramp);
    *gyro = (i % 7u == 3u) ? nan.f : 10.0f;
}

/* floats of the current table the check has still to read */
static uint32_t check_floats_left(const fogsf_state *st)
{
    return (st->crc_at != NULL) ? (uint32_t)(st->crc_end - st->crc_at) : 0u;
}

int main(void)
{
    fogsf_output out;
    uint32_t i, a, period, flags = 0u;
    float t = 20.0f;
    const uint32_t d = models[0]->decimation;
    for (a = 0; a < IMAGE_N_MODELS; ++a) {
        flags |= fogsf_init(models[a], &states[a], sizeof states[a]);
    }
    for (period = 0u; (period < 400u) && (check_floats_left(&states[0]) <= 2u * d + 1u);
         ++period) {
        for (i = 0; i < d; ++i) {
            fogsf_sample_inputs(i, &t, &g); /* the ramp: no stuck thermometer */
            for (a = 0; a < IMAGE_N_MODELS; ++a) {
                fogsf_step(models[a], &states[a], t, g, &out);
                flags |= out.flags & FOGSF_FLAG_MODEL_CHANGED;
            }
        }
    }
    t_ramp = 20.0f; /* the counted samples on the ramp as from the start */
    /* a ramp with every front-end path planted: NaN and beyond-range temperatures, a NaN
     * gyro (the worst sample is taken over all of them) */
    for (i = 0; i < 2u * models[0]->decimation + 1u; ++i) {
        fogsf_sample_inputs(i, &t, &g);
        fogsf_bench_begin();
        for (a = 0; a < IMAGE_N_MODELS; ++a) {
            fogsf_step(models[a], &states[a], t, g, &out);
            flags |= out.flags;
        }
        fogsf_bench_end();
    }
    semihost_puts((flags & (FOGSF_FLAG_MODEL_INVALID | FOGSF_FLAG_MODEL_CHANGED)) == 0u
                      ? "bench done\n"
                      : "bench flags\n");
    return 0;
}
