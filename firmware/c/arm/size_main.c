/* Cortex-M4F size probe: the kernel as an application links it (one state, one step call
 * per sample), so arm-none-eabi-size reports what the kernel + model cost in flash and RAM. */
#include "fogsf.h"

static fogsf_state state;
volatile float probe_temp_c;
volatile double probe_gyro_dps;
volatile double probe_corrected_dps;
volatile uint32_t probe_samples;

int main(void)
{
    fogsf_output out;
    uint32_t i;
    fogsf_init(&state);
    for (i = 0; i < probe_samples; ++i) {
        fogsf_step(&state, probe_temp_c, probe_gyro_dps, &out);
        probe_corrected_dps = out.corrected_dps;
    }
    return 0;
}
