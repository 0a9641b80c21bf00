/* Cortex-M4F size probe: the kernel as an application links it (one state per model, one
 * step call per model and sample), so arm-none-eabi-size reports what the kernel + models
 * cost in flash and RAM. image_models.h (generated) lists the models of the image. */
#include "fogsf.h"
#include "image_models.h"

static const fogsf_model *const models[IMAGE_N_MODELS] = IMAGE_MODELS;
static fogsf_state states[IMAGE_N_MODELS];
volatile float probe_temp_c;
volatile float probe_gyro_dps;
volatile float probe_corrected_dps;
volatile uint32_t probe_samples;
#if defined(FOGSF_BENCH_SELFTEST) /* the image with the power-on self-test linked */
volatile uint32_t probe_selftest;
#endif

int main(void)
{
    fogsf_output out;
    uint32_t i, a;
#if defined(FOGSF_BENCH_SELFTEST)
    probe_selftest = fogsf_selftest(&states[0], sizeof states[0]);
#endif
    for (a = 0; a < IMAGE_N_MODELS; ++a) {
        (void)fogsf_init(models[a], &states[a], sizeof states[a]);
    }
    for (i = 0; i < probe_samples; ++i) {
        for (a = 0; a < IMAGE_N_MODELS; ++a) {
            fogsf_step(models[a], &states[a], probe_temp_c, probe_gyro_dps, &out);
            probe_corrected_dps = out.corrected_dps;
        }
    }
    return 0;
}
