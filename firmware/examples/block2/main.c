/*
 * block2: two gyros (a, b), each compensated by the model of its calibration block, read in
 * place from its flash sector at power-on; the image holds no model, so one image serves every
 * unit. A block the loader refuses is reported with its reason code and the image stops
 * ("block2 FAIL a 3": gyro a, bad magic). The inputs are a deterministic ramp (NaN
 * temperatures planted) that tests/test_block_firmware.py rebuilds in numpy; every sample of
 * each gyro is printed as "gyro index sf_bits corrected_bits bias_bits flags" (hex) through
 * semihosting, then "block2 done".
 */
#include "fogsf_block.h"
#include "semihost.h"

#define BLOCK2_SAMPLES 1200u

static fogsf_block_model models[2]; /* they point into the sectors: kept in place */
static fogsf_state states[2];

typedef union {
    float f;
    uint32_t u;
} f32_bits;

static void put_hex(char *p, uint32_t v, int digits)
{
    static const char hex[] = "0123456789abcdef";
    int i;
    for (i = 0; i < digits; ++i) {
        p[i] = hex[(v >> (4 * (digits - 1 - i))) & 0xfu];
    }
}

int main(void)
{
    static const uintptr_t sectors[2] = {BLOCK2_SECTOR_A, BLOCK2_SECTOR_B};
    char line[48];
    uint32_t i, g;
    for (g = 0; g < 2u; ++g) {
        const fogsf_block_status st = fogsf_model_from_block((const uint8_t *)sectors[g],
                                                             BLOCK2_SECTOR_BYTES, &models[g]);
        if (st != FOGSF_BLOCK_OK || fogsf_init(&models[g].model, &states[g],
                                               sizeof states[g]) != 0u) {
            char msg[] = "block2 FAIL a 00\n";
            msg[12] = (char)('a' + g);
            put_hex(msg + 14, (uint32_t)st, 2);
            semihost_puts(msg);
            return 1;
        }
        semihost_puts(g == 0u ? "gyro a: model " : "gyro b: model ");
        semihost_puts(models[g].model.model_id);
        semihost_puts("\n");
    }
    for (i = 0; i < BLOCK2_SAMPLES; ++i) {
        for (g = 0; g < 2u; ++g) {
            fogsf_output out;
            f32_bits t, s, c, b;
            t.f = (-30.0f + (float)i * 0.0625f) + (float)g * 0.25f;
            if (i % 257u == 11u + g) {
                t.u = 0x7fc00000u; /* a NaN temperature: the kernel holds the last one */
            }
            fogsf_step(&models[g].model, &states[g], t.f, 20.0f + (float)i * 0.002f, &out);
            s.f = out.sf_ppm;
            c.f = out.corrected_dps;
            b.f = out.bias_dph;
            line[0] = (char)('a' + g);
            line[1] = ' ';
            put_hex(line + 2, i, 4);
            line[6] = ' ';
            put_hex(line + 7, s.u, 8);
            line[15] = ' ';
            put_hex(line + 16, c.u, 8);
            line[24] = ' ';
            put_hex(line + 25, b.u, 8);
            line[33] = ' ';
            put_hex(line + 34, out.flags, 3);
            line[37] = '\n';
            line[38] = '\0';
            semihost_puts(line);
        }
    }
    semihost_puts("block2 done\n");
    return 0;
}
