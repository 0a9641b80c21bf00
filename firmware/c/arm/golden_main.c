/* Cortex-M4F test image: the golden-vector check, printed through semihosting. */
#include "golden_check.h"
#include "semihost.h"

int main(void)
{
    return fogsf_golden_check(semihost_puts) == 0u ? 0 : 1;
}
