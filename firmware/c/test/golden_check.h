/* Golden-vector check of the kernel, shared by the host driver and the Cortex-M4F image. */
#ifndef FOGSF_GOLDEN_CHECK_H
#define FOGSF_GOLDEN_CHECK_H

typedef void (*fogsf_puts_fn)(const char *text);

/* Runs the golden vectors twice (one fogsf_step per sample, then fogsf_run over the whole
 * log after a reset), compares every output bit for bit, prints a report through `out`
 * (ending in "PASS ..." or "FAIL ...") and returns the number of mismatches. */
unsigned long fogsf_golden_check(fogsf_puts_fn out);

#endif
