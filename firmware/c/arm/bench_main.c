/* Cortex-M4F instruction-count probe: the fogsf_step calls of one sample (one per model of
 * the image, image_models.h) sit between two marker calls; QEMU's one-instruction-per-block
 * execution trace is counted between the markers (benchmarks/firmware_bench.py), which gives
 * exact, deterministic counts per sample. The models share one decimation. */
#include "fogsf.h"
#include "image_models.h"
#include "semihost.h"

static const fogsf_model *const models[IMAGE_N_MODELS] = IMAGE_MODELS;
static fogsf_state states[IMAGE_N_MODELS];

__attribute__((noinline)) void fogsf_bench_begin(void)
{
    __asm__ volatile("" ::: "memory");
}

__attribute__((noinline)) void fogsf_bench_end(void)
{
    __asm__ volatile("" ::: "memory");
}

int main(void)
{
    fogsf_output out;
    uint32_t i, a, flags = 0u;
    float t = 20.0f;
    for (a = 0; a < IMAGE_N_MODELS; ++a) {
        flags |= fogsf_init(models[a], &states[a]);
    }
    for (i = 0; i < 2u * models[0]->decimation + 1u; ++i) {
        fogsf_bench_begin();
        for (a = 0; a < IMAGE_N_MODELS; ++a) {
            fogsf_step(models[a], &states[a], t, 10.0, &out);
            flags |= out.flags;
        }
        fogsf_bench_end();
        t = t + 0.01f;
    }
    semihost_puts(flags == 0u ? "bench done\n" : "bench flags\n");
    return 0;
}
