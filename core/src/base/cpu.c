/* cpu.c: the choice between the march's baseline and x86-64-v3 builds.
 *
 * Decided once per process and cached: __builtin_cpu_supports reads
 * CPUID data the compiler's runtime gathered at start-up. */
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>
#include "base/internal.h"
#include "gi/gi_cpu.h"

/* 0: not decided yet, 1: baseline, 2: x86-64-v3. */
static atomic_int chosen;

int gi_cpu_has_v3(void) {
#if defined(__x86_64__) && defined(GI_HAVE_V3_BUILD)
  __builtin_cpu_init();
  return __builtin_cpu_supports("x86-64-v3") ? 1 : 0;
#else
  return 0;
#endif
}

int gi__cpu_v3(void) {
  int c = atomic_load_explicit(&chosen, memory_order_relaxed);
  if (c) return c == 2;
  const char *env = getenv("GI_CPU_PATH");
  int want_base = env && !strcmp(env, "baseline");
  c = !want_base && gi_cpu_has_v3() ? 2 : 1;
  atomic_store_explicit(&chosen, c, memory_order_relaxed);
  return c == 2;
}

const char *gi_cpu_path(void) { return gi__cpu_v3() ? "x86-64-v3" : "baseline"; }

void gi__cpu_force(int v3) { atomic_store_explicit(&chosen, v3 && gi_cpu_has_v3() ? 2 : 1, memory_order_relaxed); }
