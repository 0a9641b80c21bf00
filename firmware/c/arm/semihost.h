#ifndef FOGSF_SEMIHOST_H
#define FOGSF_SEMIHOST_H
void semihost_puts(const char *text);
void semihost_exit(int failed);
#endif
