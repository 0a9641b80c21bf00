/*
 * Host driver of the block loader for the sanitizer build (tests/test_block_corrupt.py):
 * `block_main SHIFT FILE...` reads each file into a heap buffer that ends exactly at the
 * block's last byte, the block SHIFT bytes past malloc's (16-aligned) start, so ASan stops
 * any read past the block, and prints one line a file: the loader's status; for an accepted
 * block also what fogsf_init returned and the bits of 200 samples' outputs, XOR-folded (the
 * model runs).
 */
#include "fogsf_block.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static fogsf_block_model bm;
static fogsf_state st;

static unsigned long bits_of(float v)
{
    uint32_t u;
    memcpy(&u, &v, sizeof u);
    return (unsigned long)u;
}

int main(int argc, char **argv)
{
    int i;
    long shift;
    if (argc < 3) {
        fprintf(stderr, "usage: block_main SHIFT FILE...\n");
        return 2;
    }
    shift = strtol(argv[1], NULL, 10);
    for (i = 2; i < argc; ++i) {
        FILE *f = fopen(argv[i], "rb");
        long n = -1;
        unsigned char *mem = NULL;
        fogsf_block_status status;
        if (f != NULL && fseek(f, 0, SEEK_END) == 0) {
            n = ftell(f);
        }
        if (n >= 0 && fseek(f, 0, SEEK_SET) == 0) {
            mem = malloc((size_t)(n + shift) + (n + shift == 0 ? 1u : 0u));
        }
        if (mem == NULL || fread(mem + shift, 1, (size_t)n, f) != (size_t)n) {
            fprintf(stderr, "%s: cannot read\n", argv[i]);
            return 2;
        }
        fclose(f);
        status = fogsf_model_from_block(mem + shift, (size_t)n, &bm);
        printf("%s %d", argv[i], (int)status);
        if (status == FOGSF_BLOCK_OK) {
            unsigned long fold = 0;
            int j;
            uint32_t init = fogsf_init(&bm.model, &st, sizeof st);
            for (j = 0; j < 200; ++j) {
                fogsf_output o;
                fogsf_step(&bm.model, &st, 20.0f + 0.05f * (float)j, 10.0f, &o);
                fold ^= bits_of(o.corrected_dps) ^ bits_of(o.sf_ppm) ^ bits_of(o.bias_dph) ^
                        (unsigned long)o.flags;
            }
            printf(" init %u fold %08lx", (unsigned)init, fold);
        }
        printf("\n");
        free(mem);
    }
    return 0;
}
