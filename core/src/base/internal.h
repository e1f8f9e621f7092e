/* internal.h: helpers shared by the core's source files (not installed). */
#ifndef GI_INTERNAL_H
#define GI_INTERNAL_H

#include <math.h>
#include <stdarg.h>
#ifndef __cplusplus
#include <stdatomic.h>
#endif
#include <stddef.h>
#include <stdint.h>
#include "gi/gi_cancel.h"
#include "gi/gi_error.h"

/* Records code and a printf-style message in err (which may be NULL) and
 * returns code, so callers write `return gi__fail(err, GI_ERR_IO, ...)`. */
gi_result gi__fail(gi_error_info *err, gi_result code, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));

/* Every core allocation goes through these (base/alloc.c): malloc and
 * friends plus counters for the tests. Memory from them may be freed by
 * free(); memory the core hands to a caller who frees it with free() is
 * first passed to gi__alloc_release so the count stays balanced. Callers
 * treat NULL as GI_ERR_NOMEM. */
void *gi__malloc(size_t n);
void *gi__calloc(size_t n, size_t size);
void *gi__realloc(void *p, size_t n);
char *gi__strdup(const char *s);
void gi__free(void *p);
void gi__alloc_release(void *p);
/* Zeroed blocks for the cascade's textures, freed by gi__big_free with
 * the same n and size (never by free()). Blocks of 2 MB and more are
 * mapped on 2 MB boundaries and advised for transparent huge pages: on
 * the paravirtualised 2-core bench machine a 4 KB page's first touch
 * costs ~20 us of wall time (not counted as user or system time), so a
 * default cascade's 33 MB cost ~160 ms of faults; 17 huge pages ~7 ms.
 * Smaller blocks use gi__calloc (sanitizer builds map as well). */
void *gi__big_calloc(size_t n, size_t size);
/* A block for gi__big_free(p, bytes, 1): mapped and zeroed (*zeroed = 1)
 * where gi__big_calloc would map it, else uncleared heap memory the
 * caller clears (*zeroed = 0; the cascade clears it in slices between
 * checks of its cancel token). NULL when memory ran out. */
void *gi__big_malloc(size_t bytes, int *zeroed);
void gi__big_free(void *p, size_t n, size_t size);

/* Runs fn(ctx, begin, end, worker) over [0, n) in chunks of `grain` on up
 * to `threads` workers (0 = all cores). Blocks until all chunks are done.
 * fn must be safe to run concurrently on disjoint ranges. The calling
 * thread is always worker 0 and works until no chunk is left; the other
 * workers come from one persistent pool per process (cores - 1 threads,
 * started by the first call that can use them, joined at exit). Worker ids
 * lie in 0..gi__num_workers(threads)-1 and no two workers of one call hold
 * the same id at once, so per-worker scratch keyed by id needs no lock (an
 * id may pass from one pool thread to another between chunks; the hand-over
 * is ordered by the pool's lock).
 *
 * Sharing: calls may nest and may come from any number of application
 * threads at once. While k calls run on the pool, each may use at most
 * ceil(cores / k) workers, its caller included, and never more than
 * `threads` or its number of chunks; a pool thread leaves a call after a
 * chunk once the call holds more than its share, and joins whichever call
 * is below it. Calls that fit on their caller alone (threads = 1, one chunk)
 * do not count. Since the caller always works, a call finishes even when
 * every pool thread is busy elsewhere: no call ever waits for a free
 * thread, only for pool threads finishing one of its own chunks. */
typedef void (*gi__range_fn)(void *ctx, size_t begin, size_t end, int worker);
void gi__parallel_for(size_t n, size_t grain, int threads, gi__range_fn fn, void *ctx);
#ifndef __cplusplus /* the C++ shim has no workers; C11 atomics are C only */
/* As gi__parallel_for, but no further chunk starts once *stop is non-zero:
 * a worker that fails (workers return nothing) sets *stop, which lives in
 * its ctx, and the caller checks it after the loop. */
void gi__parallel_for_stop(size_t n, size_t grain, int threads, gi__range_fn fn, void *ctx, atomic_int *stop);
/* As gi__parallel_for_stop (stop may be NULL), and no chunk starts once the
 * cancel token (may be NULL) fired. Returns nonzero when the token stopped
 * the loop: some chunks did not run, so the caller's results are partial. */
int gi__parallel_for_cancel(size_t n, size_t grain, int threads, gi__range_fn fn, void *ctx, atomic_int *stop,
                            const gi_cancel *cancel);
#endif
/* GI_ERR_CANCELLED with a message naming the stage and why the token fired. */
gi_result gi__cancel_fail(const gi_cancel *c, gi_error_info *err, const char *stage);
/* Bound on the worker ids gi__parallel_for passes for `threads` (ids are
 * 0..N-1): the size of a per-worker scratch array. At most min(N, cores)
 * of them run at once. Never more than GI_MAX_WORKERS. */
#define GI_MAX_WORKERS 256
int gi__num_workers(int threads);

/* 1 when the hot loops take their x86-64-v3 build (base/cpu.c). */
int gi__cpu_v3(void);
/* Tests only: take the v3 build (when the CPU can) or the baseline one
 * from now on. Not while a bake runs. */
void gi__cpu_force(int v3);

/* Monotonic clock in milliseconds. */
double gi__now_ms(void);

/* Cells of size `cell` a viewpoint at local coordinate al (from the
 * scene's origin) may lie from it: cascades index cells in int64 and
 * place windows in double, so a cell index must stay an exact double.
 * Past this the voxel is too small for the distance (voxel 1e-300 from
 * a server's query wrapped the anchor to INT64_MIN). */
#define GI_MAX_CELL_INDEX 4503599627370496.0 /* 2^52 */
static inline int gi__cells_ok(double al, double cell) { return fabs(al / cell) < GI_MAX_CELL_INDEX; }

static inline int gi__finite3(const float v[3]) {
  return isfinite(v[0]) && isfinite(v[1]) && isfinite(v[2]);
}

/* pi in float, for the per-sample math of every stage. */
#define GI_PI_F 3.14159265358979f
#define GI_PI 3.14159265358979323846

/* A cone, a primary ray or a transmittance product counts as blocked once
 * its accumulated opacity reaches this: the rest would add under 1%. */
#define GI_OPAQUE_ALPHA 0.99f

/* Deterministic hash-based random numbers (splitmix64): samples depend on
 * what is sampled (a voxel's cell, a probe's position), never on thread
 * order. */
static inline uint64_t gi__mix64(uint64_t x) {
  x ^= x >> 30; x *= 0xbf58476d1ce4e5b9ULL;
  x ^= x >> 27; x *= 0x94d049bb133111ebULL;
  x ^= x >> 31;
  return x;
}
static inline float gi__u01(uint64_t *state) {
  *state += 0x9e3779b97f4a7c15ULL;
  return (float)(gi__mix64(*state) >> 40) * (1.0f / 16777216.0f);
}

/* The radical inverse of j in base 2 (van der Corput), in [0, 1). Paired
 * with a stratum (j + u) / m it makes m points stratified in two
 * dimensions (a jittered Hammersley set), where a second random number
 * would leave the second dimension plain Monte Carlo. */
static inline float gi__radical2(uint32_t j) {
  j = (j << 16) | (j >> 16);
  j = ((j & 0x00ff00ffu) << 8) | ((j & 0xff00ff00u) >> 8);
  j = ((j & 0x0f0f0f0fu) << 4) | ((j & 0xf0f0f0f0u) >> 4);
  j = ((j & 0x33333333u) << 2) | ((j & 0xccccccccu) >> 2);
  j = ((j & 0x55555555u) << 1) | ((j & 0xaaaaaaaau) >> 1);
  return (float)(j >> 8) * 0x1p-24f;
}
/* gi__radical2(j) shifted by rot in [0, 1), wrapped (a random shift
 * keeps the estimate unbiased). */
static inline float gi__radical2_rot(uint32_t j, float rot) {
  float r = gi__radical2(j) + rot;
  return r >= 1.f ? r - 1.f : r;
}

/* Branch-free min and max: without -ffinite-math-only, fminf and fmaxf
 * are library calls, and the hot loops need neither NaN rule. */
static inline float gi__minf(float a, float b) { return a < b ? a : b; }
static inline float gi__maxf(float a, float b) { return a > b ? a : b; }

/* exp(-x) for x >= 0 (0 beyond 87), relative error under 5e-6: 2^-k times
 * a degree-6 polynomial of the rest in [-ln2/2, ln2/2]. Once per cone
 * sample. */
static inline float gi__fast_exp_neg(float x) {
  if (!(x < 87.f)) return 0.f;
  float y = -x * 1.44269504f; /* log2(e) */
  float k = floorf(y + 0.5f);
  float f = (y - k) * 0.69314718f;
  float p = 1.f + f * (1.f + f * (0.5f + f * (0.16666667f + f * (0.041666668f + f * (0.0083333338f + f * 0.0013888889f)))));
  union { float f; uint32_t u; } v;
  v.u = (uint32_t)((int32_t)k + 127) << 23;
  return p * v.f;
}

static inline float gi__dot(const float a[3], const float b[3]) { return a[0]*b[0] + a[1]*b[1] + a[2]*b[2]; }
static inline void gi__cross(const float a[3], const float b[3], float o[3]) {
  o[0] = a[1]*b[2] - a[2]*b[1]; o[1] = a[2]*b[0] - a[0]*b[2]; o[2] = a[0]*b[1] - a[1]*b[0];
}
/* The same in double (world positions, before they are local). */
static inline void gi__cross_d(const double a[3], const double b[3], double o[3]) {
  o[0] = a[1]*b[2] - a[2]*b[1]; o[1] = a[2]*b[0] - a[0]*b[2]; o[2] = a[0]*b[1] - a[1]*b[0];
}
static inline float gi__len(const float a[3]) { return sqrtf(gi__dot(a, a)); }
static inline float gi__lum(const float c[3]) { return 0.2126f*c[0] + 0.7152f*c[1] + 0.0722f*c[2]; }

/* Orthonormal basis with unit n as the third axis (branchless, Duff et al. 2017). */
static inline void gi__basis(const float n[3], float t[3], float b[3]) {
  float sign = copysignf(1.0f, n[2]);
  float a = -1.0f / (sign + n[2]);
  float bb = n[0] * n[1] * a;
  t[0] = 1.0f + sign * n[0] * n[0] * a;
  t[1] = sign * bb;
  t[2] = -sign * n[0];
  b[0] = bb;
  b[1] = sign + n[1] * n[1] * a;
  b[2] = -n[1];
}

/* The cosine-weighted direction that u1, u2 in [0, 1) give about n (with
 * gi__basis's t, b) into w; returns its cosine to n. */
static inline float gi__cosine_dir(const float t[3], const float b[3], const float n[3], float u1, float u2,
                                   float w[3]) {
  float r = sqrtf(u1), phi = 2 * GI_PI_F * u2, z = sqrtf(fmaxf(0.f, 1 - u1));
  float x = r * cosf(phi), y = r * sinf(phi);
  for (int k = 0; k < 3; k++) w[k] = x * t[k] + y * b[k] + z * n[k];
  return z;
}

#endif
