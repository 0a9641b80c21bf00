/*
 * The floating-point build the kernel's bits rest on, checked where the compiler can tell
 * (private to the kernel's sources; included first by each of them).
 *
 * The kernel reproduces the numpy reference bit for bit only when every float32 operation is
 * one IEEE 754 operation, rounded to nearest, in the order the source writes it
 * (docs/stream-contract.md). Flags that let the compiler reorder, fuse, replace a division by
 * a reciprocal, or assume no NaN/Inf break that silently: -ffast-math failed 6426 of 12000
 * golden outputs on the host, -ffinite-math-only removed the NaN/Inf handling. So:
 * - a build that announces such a flag stops here (#error);
 * - float expressions must be evaluated in float (FLT_EVAL_METHOD 0: no x87 excess precision);
 * - contraction into FMA is switched off by `#pragma STDC FP_CONTRACT OFF` where the compiler
 *   honours it (clang and the compilers built on it), and by -ffp-contract=off everywhere
 *   (gcc ignores the pragma: the CMake library, the Makefile's builds and the bindings pass the
 *   flag). Contraction leaves no macro to test, so fogsf_selftest() catches it at power-on.
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
#pragma STDC FP_CONTRACT OFF
#endif

/* The IEEE 754 bits of a float32 (Dir 1.1: the kernel relies on IEEE 754 binary32; it holds
 * no double; firmware/c/MISRA.md, Rule 19.2). */
typedef union {
    float f;
    uint32_t u;
} fogsf_f32_bits;

#endif /* FOGSF_FP_H */
