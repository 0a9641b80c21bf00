/* Cortex-M test image of the calibration block: the unit's block lies at a flash address of
 * its own (section .fogsf_block, placed by the link: block_data.S), the image reads it with
 * fogsf_model_from_block and runs the golden vectors of the generated C model on it. */
#include "fogsf_block.h"
#include "golden_check.h"
#include "semihost.h"

extern const uint8_t fogsf_unit_block[];
extern const uint8_t fogsf_unit_block_end[];

fogsf_block_model golden_block; /* golden_vectors.h: FOGSF_GOLDEN_MODEL (&golden_block.model) */

static void put_hex32(uint32_t v)
{
    static const char hex[] = "0123456789abcdef";
    char buf[11];
    int i;
    buf[0] = '0';
    buf[1] = 'x';
    for (i = 0; i < 8; ++i) {
        buf[2 + i] = hex[(v >> (28 - 4 * i)) & 0xfu];
    }
    buf[10] = '\0';
    semihost_puts(buf);
}

int main(void)
{
    const size_t n = (size_t)(fogsf_unit_block_end - fogsf_unit_block);
    const fogsf_block_status status = fogsf_model_from_block(fogsf_unit_block, n, &golden_block);
    semihost_puts("block at ");
    put_hex32((uint32_t)(uintptr_t)fogsf_unit_block);
    semihost_puts(", length ");
    put_hex32((uint32_t)n);
    semihost_puts(status == FOGSF_BLOCK_OK ? ": loaded\n" : ": REFUSED\n");
    if (status != FOGSF_BLOCK_OK) {
        semihost_puts("FAIL: the block was refused\n");
        return 1;
    }
    return fogsf_golden_check(semihost_puts) == 0u ? 0 : 1;
}
