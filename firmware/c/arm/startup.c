/*
 * Minimal bare-metal start-up for QEMU's Cortex-M boards (mps2-an386 Cortex-M4F, mps2-an385
 * Cortex-M3, microbit Cortex-M0): vector table, .data/.bss set-up, FPU enable (hard-float
 * builds), and ARM semihosting (SYS_WRITE0 to print, SYS_EXIT to stop QEMU with
 * a status). No newlib start-up: its rdimon crt0 is not needed for a test that only prints.
 */
#include <stddef.h>
#include <stdint.h>

#include "semihost.h"

extern uint32_t _sidata, _sdata, _edata, _sbss, _ebss, _estack;
extern int main(void);

void reset_handler(void);
void fault_handler(void);

static int semihost_call(int op, const void *arg)
{
    register int r0 __asm__("r0") = op;
    register const void *r1 __asm__("r1") = arg;
    __asm__ volatile("bkpt 0xAB" : "+r"(r0) : "r"(r1) : "memory");
    return r0;
}

void semihost_puts(const char *text)
{
    (void)semihost_call(0x04, text); /* SYS_WRITE0 */
}

void semihost_exit(int failed)
{
    /* SYS_EXIT: ADP_Stopped_ApplicationExit -> QEMU exits 0, RunTimeErrorUnknown -> 1 */
    (void)semihost_call(0x18, (const void *)(uintptr_t)(failed ? 0x20023u : 0x20026u));
    for (;;) {
    }
}

void fault_handler(void)
{
    semihost_puts("FAIL: fault\n");
    semihost_exit(1);
}

void reset_handler(void)
{
    uint32_t *src = &_sidata;
    uint32_t *dst;
    for (dst = &_sdata; dst < &_edata; ++dst) {
        *dst = *src++;
    }
    for (dst = &_sbss; dst < &_ebss; ++dst) {
        *dst = 0u;
    }
#if defined(__ARM_FP)
    /* CPACR: full access to CP10/CP11 (the FPU) before any float instruction */
    *(volatile uint32_t *)0xE000ED88u |= 0xFu << 20;
    __asm__ volatile("dsb\n\tisb" ::: "memory");
#endif
    semihost_exit(main() != 0);
}

__attribute__((section(".isr_vector"), used)) void (*const vector_table[16])(void) = {
    (void (*)(void))(uintptr_t)&_estack, reset_handler, fault_handler, fault_handler,
    fault_handler, fault_handler, fault_handler, 0, 0, 0, 0, fault_handler, fault_handler, 0,
    fault_handler, fault_handler,
};

/* gcc may turn loops into these calls; there is no libc here */
void *memset(void *s, int c, size_t n)
{
    unsigned char *p = s;
    while (n-- > 0u) {
        *p++ = (unsigned char)c;
    }
    return s;
}

void *memcpy(void *d, const void *s, size_t n)
{
    unsigned char *dp = d;
    const unsigned char *sp = s;
    while (n-- > 0u) {
        *dp++ = *sp++;
    }
    return d;
}

/* clang calls the ARM run-time ABI's forms (newlib has them; this image links no libc) */
void __aeabi_memclr(void *s, size_t n);
void __aeabi_memclr4(void *s, size_t n);
void __aeabi_memclr8(void *s, size_t n);
void __aeabi_memset(void *s, size_t n, int c);
void __aeabi_memset4(void *s, size_t n, int c);
void __aeabi_memcpy(void *d, const void *s, size_t n);
void __aeabi_memcpy4(void *d, const void *s, size_t n);

void __aeabi_memclr(void *s, size_t n)
{
    (void)memset(s, 0, n);
}

void __aeabi_memclr4(void *s, size_t n)
{
    (void)memset(s, 0, n);
}

void __aeabi_memclr8(void *s, size_t n)
{
    (void)memset(s, 0, n);
}

void __aeabi_memset(void *s, size_t n, int c)
{
    (void)memset(s, c, n);
}

void __aeabi_memset4(void *s, size_t n, int c)
{
    (void)memset(s, c, n);
}

void __aeabi_memcpy(void *d, const void *s, size_t n)
{
    (void)memcpy(d, s, n);
}

void __aeabi_memcpy4(void *d, const void *s, size_t n)
{
    (void)memcpy(d, s, n);
}
