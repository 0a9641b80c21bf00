/*
 * imu3: three fiber-optic gyros (x, y, z), each compensated by its own fogsf model, in one
 * Cortex-M4F image. The inputs are a deterministic ramp (with NaN temperatures planted) that
 * tests/test_firmware_cmake.py rebuilds in numpy; every sample of every axis is printed as
 * "axis index sf_bits corrected_bits flags" (hex) through semihosting, then "imu3 done".
 */
#include "fogsf.h"
#include "imu_x.h"
#include "imu_y.h"
#include "imu_z.h"
#include "semihost.h"

#define IMU3_SAMPLES 1500u

static const fogsf_model *const models[3] = {&imu_x, &imu_y, &imu_z};
static fogsf_state states[3];

typedef union {
    float f;
    uint32_t u;
} f32_bits;

static void put_hex(char *p, uint64_t v, int digits)
{
    static const char hex[] = "0123456789abcdef";
    int i;
    for (i = 0; i < digits; ++i) {
        p[i] = hex[(v >> (4 * (digits - 1 - i))) & 0xfu];
    }
}

int main(void)
{
    char line[48];
    uint32_t i, a, bad = 0u;
    for (a = 0; a < 3u; ++a) {
        bad |= fogsf_init(models[a], &states[a], sizeof states[a]);
    }
    for (i = 0; i < IMU3_SAMPLES; ++i) {
        for (a = 0; a < 3u; ++a) {
            fogsf_output out;
            f32_bits t, s, c;
            t.f = (-40.0f + (float)i * 0.0625f) + (float)a * 0.5f;
            if (i % 331u == 17u + a) {
                t.u = 0x7fc00000u; /* a NaN temperature: the kernel must hold the last one */
            }
            fogsf_step(models[a], &states[a], t.f, 10.0f * (float)(a + 1u) + (float)i * 0.001f,
                       &out);
            s.f = out.sf_ppm;
            c.f = out.corrected_dps;
            line[0] = (char)('x' + a);
            line[1] = ' ';
            put_hex(line + 2, i, 4);
            line[6] = ' ';
            put_hex(line + 7, s.u, 8);
            line[15] = ' ';
            put_hex(line + 16, c.u, 8);
            line[24] = ' ';
            put_hex(line + 25, out.flags, 2);
            line[27] = '\n';
            line[28] = '\0';
            semihost_puts(line);
        }
    }
    semihost_puts(bad == 0u ? "imu3 done\n" : "imu3 FAIL: a model does not fit the state\n");
    return bad != 0u;
}
