/* Cortex-M4F instruction-count probe: each fogsf_step call sits between two marker calls;
 * QEMU's one-instruction-per-block execution trace is counted between the markers
 * (benchmarks/firmware_bench.py), which gives exact, deterministic counts per sample. */
#include "fogsf.h"
#include "semihost.h"

static fogsf_state state;

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
    uint32_t i;
    float t = 20.0f;
    fogsf_init(&state);
    for (i = 0; i < 2u * (uint32_t)FOGSF_DECIMATION + 1u; ++i) {
        fogsf_bench_begin();
        fogsf_step(&state, t, 10.0, &out);
        fogsf_bench_end();
        t = t + 0.01f;
    }
    semihost_puts(out.flags == 0u ? "bench done\n" : "bench flags\n");
    return 0;
}
