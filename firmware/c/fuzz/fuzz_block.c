/*
 * libFuzzer harness of the calibration block loader (clang -fsanitize=fuzzer,address,undefined):
 * the first byte picks how the rest is given to fogsf_model_from_block:
 *   bit 0 clear  as it is (most inputs stop at a structural check or a CRC);
 *   bit 0 set    resealed first: the payload CRC and then the header CRC recomputed where
 *                the header's lengths allow, so mutations of sizes, offsets, lengths and
 *                weights reach the checks after the CRCs and the model itself;
 *   bit 1 set    the block one byte past an aligned start (MISALIGNED unless refused before).
 * The block sits in a heap buffer that ends exactly where it does, so ASan stops any read
 * past n. A block the loader accepts must be one fogsf_init accepts, and fogsf_step on it
 * must keep the totality contract (finite output, known flags) over 64 samples (huge
 * temperatures, and rates beyond a rate part's full scale of the seeds); a violation
 * aborts, which libFuzzer reports as a crash. "fuzz blocks: N (accepted A)" at exit.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fogsf_block.h"
#include "fuzz_common.h"

static unsigned long long inputs;
static unsigned long long accepted;
static fogsf_block_model bm;
static fogsf_state st;

static void report(void)
{
    fprintf(stderr, "fuzz blocks: %llu (accepted %llu)\n", inputs, accepted);
}

static uint32_t rd32(const uint8_t *p)
{
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) |
           ((uint32_t)p[3] << 24);
}

static void wr32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
    p[2] = (uint8_t)(v >> 16);
    p[3] = (uint8_t)(v >> 24);
}

static uint32_t crc32_of(const uint8_t *p, size_t n)
{
    uint32_t crc = 0xffffffffu;
    size_t i;
    int bit;
    for (i = 0; i < n; ++i) {
        crc ^= p[i];
        for (bit = 0; bit < 8; ++bit) {
            crc = (crc & 1u) ? (crc >> 1) ^ 0xedb88320u : crc >> 1;
        }
    }
    return ~crc;
}

/* the CRCs made good where the header's lengths lie within n */
static void reseal(uint8_t *b, size_t n)
{
    uint32_t header, total;
    if (n < FOGSF_BLOCK_HEAD_BYTES + 4u) {
        return;
    }
    header = rd32(b + 12);
    total = rd32(b + 8);
    if (header < FOGSF_BLOCK_HEAD_BYTES + 4u || header > n) {
        return;
    }
    if (total >= header && total <= n) {
        wr32(b + 20, crc32_of(b + header, total - header));
    }
    wr32(b + header - 4, crc32_of(b, header - 4));
}

static int finite_f(float v)
{
    return v - v == 0.0f;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    uint8_t mode;
    size_t n, shift;
    uint8_t *mem;
    fogsf_block_status status;
    if (size < 1) {
        return 0;
    }
    mode = data[0];
    n = size - 1;
    shift = (mode & 2u) ? 1u : 0u;
    /* the block ends where the buffer does: a read past n is an ASan finding */
    mem = malloc(n + shift + ((n + shift) == 0u ? 1u : 0u));
    if (mem == NULL) {
        return 0;
    }
    {
        uint8_t *blk = mem + shift;
        memcpy(blk, data + 1, n);
        if (mode & 1u) {
            reseal(blk, n);
        }
        status = fogsf_model_from_block(blk, n, &bm);
        ++inputs;
        if ((unsigned)status > (unsigned)FOGSF_BLOCK_MODEL_REFUSED) {
            abort();
        }
        if (status == FOGSF_BLOCK_OK) {
            int i;
            ++accepted;
            if (fogsf_init(&bm.model, &st, sizeof st) != 0u) {
                abort(); /* accepted by the loader, refused by the kernel */
            }
            for (i = 0; i < 64; ++i) {
                fogsf_output o;
                const float t = (i & 8) ? 1.0e30f : -40.0f + 2.5f * (float)i;
                const float g = (i & 4) ? -300.0f : 10.0f;
                fogsf_step(&bm.model, &st, t, g, &o);
                if (!finite_f(o.corrected_dps) || (o.flags & ~FOGSF_FLAGS_ALL) != 0u) {
                    abort();
                }
            }
        } else if (bm.model.format_version != 0u) {
            abort(); /* a refused block must leave a zeroed model */
        }
    }
    free(mem);
    return 0;
}
