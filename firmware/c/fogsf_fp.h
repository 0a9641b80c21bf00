/*
 * The floating-point build the kernel's bits rest on, checked where the compiler can tell
 * (private to the kernel's sources; included first by each of them).
 *
 * The kernel reproduces the numpy reference bit for bit only when every float32 operation is
 * one IEEE 754 operation, rounded to nearest, in the order the source writes it
 * (docs/stream-contract.md). Flags that let the compiler reorder, fuse, replace a division by
 * a reciprocal, or assume no NaN/Inf break that silently. So, whatever flags the caller's
 * build passes (which flags each compiler announces: firmware/c/MISRA.md, Dir 1.1):
 * - a build that announces such a flag by a predefined macro stops here (#error);
 * - float expressions must be evaluated in float (FLT_EVAL_METHOD 0: no x87 excess precision);
 * - the rest is switched off in the kernel's own sources by pragmas: on clang,
 *   fp reassociate(off) and STDC FP_CONTRACT OFF, and on x86 float_control(precise, on) (no
 *   reciprocal, NaN/Inf or signed-zero assumptions); on gcc, which ignores those,
 *   optimize("fp-contract=off") (its GNU modes default to -ffp-contract=fast); elsewhere
 *   the standard STDC FP_CONTRACT OFF. What no macro announces and no pragma undoes
 *   (clang's -ffp-contract=fast on a target with FMA; -fno-honor-nans and
 *   -fno-honor-infinities everywhere; -freciprocal-math and -fno-signed-zeros on clang for
 *   ARM; a flush-to-zero mode) is left to fogsf_selftest(), whose float-rule probes fail on
 *   each of those flags (FOGSF_SELFTEST_FLOAT_RULES; FOGSF_SELFTEST_AT_INIT: fogsf_init
 *   refuses the model when it fails).
 */
#ifndef FOGSF_FP_H
#define FOGSF_FP_H

#include <float.h>
#include <stdint.h>

#if defined(__FAST_MATH__)
#error "fogsf: built with -ffast-math: the kernel's float32 order and NaN/Inf handling need IEEE arithmetic; drop the flag for fogsf's sources"
#endif
#if defined(__FINITE_MATH_ONLY__)
#if __FINITE_MATH_ONLY__ != 0
#error "fogsf: built with -ffinite-math-only: the kernel's NaN/Inf handling would be compiled away; drop the flag for fogsf's sources"
#endif
#endif
#if defined(__ASSOCIATIVE_MATH__) || defined(__RECIPROCAL_MATH__) || defined(__NO_SIGNED_ZEROS__)
#error "fogsf: built with -fassociative-math, -freciprocal-math or -fno-signed-zeros: the kernel's float32 order needs IEEE arithmetic"
#endif
#if !defined(FLT_EVAL_METHOD)
#error "fogsf: FLT_EVAL_METHOD undefined: the kernel needs float expressions evaluated in float"
#elif FLT_EVAL_METHOD != 0
#error "fogsf: FLT_EVAL_METHOD is not 0 (float evaluated in a wider type, e.g. x87): the bits would differ from the contract's float32 order; use SSE (-mfpmath=sse) or a float32 FPU"
#endif

#if defined(__clang__)
#if defined(__x86_64__) || defined(__i386__)
/* clang announces -freciprocal-math and -fno-signed-zeros by no macro: precise arithmetic
 * here whatever the command line says (clang 14 has this pragma on x86 only, and it does not
 * hold -fno-honor-nans/-infinities; fogsf_selftest catches the rest: MISRA.md, Dir 1.1) */
#pragma float_control(precise, on)
#endif
/* -fassociative-math (no macro either), then FMA contraction (clang's default fuses within a
 * statement) */
#pragma clang fp reassociate(off)
#pragma STDC FP_CONTRACT OFF
#elif defined(__GNUC__)
/* gcc ignores the STDC pragma and defaults to -ffp-contract=fast outside -std=c99: no FMA
 * contraction in the functions that follow, whatever -ffp-contract says */
#pragma GCC optimize("fp-contract=off")
#else
#pragma STDC FP_CONTRACT OFF
#endif

/* The IEEE 754 bits of a float32 (Dir 1.1: the kernel relies on IEEE 754 binary32; it holds
 * no double; firmware/c/MISRA.md, Rule 19.2). */
typedef union {
    float f;
    uint32_t u;
} fogsf_f32_bits;

#endif /* FOGSF_FP_H */
