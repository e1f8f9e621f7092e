/* mempolicy.c: how a one-shot tool's malloc keeps the memory it frees.
 *
 * A tool loads a scene, then bakes: the load's buffers (the importer's,
 * the mesh builder's) are freed before the bake's arrays are taken. By
 * default glibc hands blocks of 128 KB and more back to the kernel when
 * they are freed, so every later block of that size is fresh memory, and
 * fresh memory is what costs on a virtual machine: each 4 KB page's first
 * touch is a fault the host must back (about 3 ms per MB on the 2-vCPU
 * VM the benchmarks ran on, against 10 GB/s for a page already backed).
 * Keeping freed blocks in the heap lets the next ones reuse pages that are
 * already there. The process's peak is the same; it only stops giving
 * memory back in the middle of one run, which a tool that exits after its
 * run has no use for. gi-server does not call this: a long-lived process
 * should return what a large request freed. */
#include "toolargs.h"
#if defined(__GLIBC__)
#include <malloc.h>
#endif

/* Blocks below this come from the heap (glibc's largest mmap threshold on
 * 64-bit); larger ones are still mapped and returned on free. */
#define KEEP_BELOW ((int)(32 << 20))
/* The free memory at the heap's top that stays before glibc trims it. */
#define KEEP_TOP ((int)(256 << 20))
/* How far the heap grows at a time: one system call per 64 MB, not per block. */
#define GROW_BY ((int)(64 << 20))

void ta_memory_policy(void) {
#if defined(__GLIBC__)
  /* Advice only: a malloc that ignores these (a sanitizer's) keeps its own. */
  (void)mallopt(M_MMAP_THRESHOLD, KEEP_BELOW);
  (void)mallopt(M_TRIM_THRESHOLD, KEEP_TOP);
  (void)mallopt(M_TOP_PAD, GROW_BY);
#endif
}
