/* gi_cpu.h: which code path the core's hot loops take on this CPU.
 *
 * The cone march is built twice: for any x86-64 CPU, and for x86-64-v3
 * (AVX2, FMA, F16C: Haswell, Zen and later). The first call that needs it
 * picks the v3 path when the CPU has those features, unless the
 * environment variable GI_CPU_PATH is "baseline" (to compare the two).
 * Both paths give the same answers to float rounding (FMA contracts a few
 * products); the choice is fixed for the life of the process.
 * Thread-safety: both functions may be called from any thread. */
#ifndef GI_CPU_H
#define GI_CPU_H

#ifdef __cplusplus
extern "C" {
#endif

/* "x86-64-v3" or "baseline": the path this process runs. A static string. */
const char *gi_cpu_path(void);

/* 1 when this CPU could run the x86-64-v3 path (whatever GI_CPU_PATH says). */
int gi_cpu_has_v3(void);

#ifdef __cplusplus
}
#endif
#endif
