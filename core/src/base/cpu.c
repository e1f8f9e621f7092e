/* cpu.c: the choice between the march's baseline and x86-64-v3 builds.
 *
 * Decided once per process and cached. The features are read from CPUID
 * directly rather than by __builtin_cpu_supports("x86-64-v3"): clang 14
 * (the fuzz build's compiler) does not know that name, and the level is
 * only a fixed list of features plus the OS saving the AVX registers. */
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#if defined(__x86_64__)
#include <cpuid.h>
#endif
#include "base/internal.h"
#include "gi/gi_cpu.h"

/* 0: not decided yet, 1: baseline, 2: x86-64-v3. */
static atomic_int chosen;

#if defined(__x86_64__) && defined(GI_HAVE_V3_BUILD)
/* x86-64-v3 (the psABI's levels): v2's CMPXCHG16B, LAHF/SAHF, POPCNT,
 * SSE3, SSSE3, SSE4.1, SSE4.2, then AVX, AVX2, BMI1, BMI2, F16C, FMA,
 * LZCNT, MOVBE, and XSAVE enabled by the OS for the XMM and YMM state. */
static int cpuid_has_v3(void) {
  unsigned a, b, c, d;
  if (!__get_cpuid(1, &a, &b, &c, &d)) return 0;
  /* SSE3, SSSE3, FMA, CX16, SSE4.1, SSE4.2, MOVBE, POPCNT, OSXSAVE, AVX, F16C */
  const unsigned need1 = 1u << 0 | 1u << 9 | 1u << 12 | 1u << 13 | 1u << 19 | 1u << 20 | 1u << 22 | 1u << 23 |
                         1u << 27 | 1u << 28 | 1u << 29;
  if ((c & need1) != need1) return 0;
  unsigned lo, hi;
  __asm__ volatile("xgetbv" : "=a"(lo), "=d"(hi) : "c"(0));
  if ((lo & 6u) != 6u) return 0; /* XMM and YMM state */
  if (__get_cpuid_max(0, NULL) < 7) return 0;
  __cpuid_count(7, 0, a, b, c, d);
  const unsigned need7 = 1u << 3 | 1u << 5 | 1u << 8; /* BMI1 AVX2 BMI2 */
  if ((b & need7) != need7) return 0;
  if (!__get_cpuid(0x80000001u, &a, &b, &c, &d)) return 0;
  const unsigned needx = 1u << 0 | 1u << 5; /* LAHF/SAHF, LZCNT */
  return (c & needx) == needx;
}
#endif

int gi_cpu_has_v3(void) {
#if defined(__x86_64__) && defined(GI_HAVE_V3_BUILD)
  return cpuid_has_v3();
#else
  return 0;
#endif
}

/* What GI_CPU_PATH asks for. Unset and "" are auto, as before the check. */
enum { WANT_AUTO, WANT_BASELINE, WANT_V3, WANT_BAD };

static int cpu_path_wanted(const char **value) {
  const char *env = getenv("GI_CPU_PATH");
  *value = env ? env : "";
  if (!env || !*env || !strcmp(env, "auto")) return WANT_AUTO;
  if (!strcmp(env, "baseline")) return WANT_BASELINE;
  if (!strcmp(env, "x86-64-v3")) return WANT_V3;
  return WANT_BAD;
}

int gi_cpu_path_check(char *why, size_t size) {
  const char *v;
  int want = cpu_path_wanted(&v);
  /* The value is quoted and cut short: it may be any bytes. */
  if (want == WANT_BAD)
    snprintf(why, size,
             "GI_CPU_PATH='%.64s' is not recognised: expected baseline, x86-64-v3 or auto "
             "(auto, the default when unset, takes %s on this CPU)",
             v, gi_cpu_has_v3() ? "x86-64-v3" : "baseline");
  else if (want == WANT_V3 && !gi_cpu_has_v3())
    snprintf(why, size,
             "GI_CPU_PATH=x86-64-v3, but this CPU or build cannot run that path (it needs AVX2, FMA, "
             "F16C and BMI2): use baseline or auto");
  else
    return 0;
  return -1;
}

int gi__cpu_v3(void) {
  int c = atomic_load_explicit(&chosen, memory_order_relaxed);
  if (c) return c == 2;
  const char *v;
  /* A value gi_cpu_path_check refuses takes the default: the tools exit on
   * it before any bake, and a library does not end its host. */
  int want_base = cpu_path_wanted(&v) == WANT_BASELINE;
  c = !want_base && gi_cpu_has_v3() ? 2 : 1;
  atomic_store_explicit(&chosen, c, memory_order_relaxed);
  return c == 2;
}

const char *gi_cpu_path(void) { return gi__cpu_v3() ? "x86-64-v3" : "baseline"; }

void gi__cpu_force(int v3) { atomic_store_explicit(&chosen, v3 && gi_cpu_has_v3() ? 2 : 1, memory_order_relaxed); }
