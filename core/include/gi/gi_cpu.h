/* gi_cpu.h: which code path the core's hot loops take on this CPU.
 *
 * The cone march is built twice: for any x86-64 CPU, and for x86-64-v3
 * (AVX2, FMA, F16C: Haswell, Zen and later). The first call that needs it
 * picks the v3 path when the CPU has those features, unless the
 * environment variable GI_CPU_PATH says otherwise (to compare the two):
 * "baseline", "x86-64-v3" or "auto" (the default; unset or "" too).
 * Both paths give the same answers to float rounding (FMA contracts a few
 * products); the choice is fixed for the life of the process.
 * Thread-safety: these functions may be called from any thread. */
#ifndef GI_CPU_H
#define GI_CPU_H

#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

/* "x86-64-v3" or "baseline": the path this process runs. A static string. */
const char *gi_cpu_path(void);

/* 0 when GI_CPU_PATH is unset, empty, or a path this process can run;
 * else -1 and one line in why (naming the variable, its value and the
 * accepted values). A value it refuses leaves the path to auto: the gi-*
 * programs call this first and exit 2, so a typo never passes for a
 * forced path. */
int gi_cpu_path_check(char *why, size_t size);

/* 1 when this CPU could run the x86-64-v3 path (whatever GI_CPU_PATH says). */
int gi_cpu_has_v3(void);

#ifdef __cplusplus
}
#endif
#endif
