/* Host driver of the golden-vector check (also built with -fsanitize=address,undefined). */
#include <stdio.h>

#include "golden_check.h"

static void put(const char *text)
{
    fputs(text, stdout);
}

int main(void)
{
    return fogsf_golden_check(put) == 0u ? 0 : 1;
}
