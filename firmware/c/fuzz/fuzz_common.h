/*
 * What the two libFuzzer harnesses (fuzz_step.c, fuzz_block.c) share: libFuzzer's entry
 * points and an initializer that makes the harness's own report() print its counts at exit,
 * which fogsf.bindings.fuzz reads. Include it once, from the harness, before report().
 */
#ifndef FOGSF_FUZZ_COMMON_H
#define FOGSF_FUZZ_COMMON_H

#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>

static void report(void);

int LLVMFuzzerInitialize(int *argc, char ***argv);
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerInitialize(int *argc, char ***argv)
{
    (void)argc;
    (void)argv;
    atexit(report);
    return 0;
}

#endif
