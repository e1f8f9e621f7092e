/* march_internal.h: what the scalar march (march_kernel.c) and the
 * eight-lane march (march_simd.c) share: the level spans of a cone and
 * the trilinear sum of a sample's eight texels. Included by the kernel
 * files only; GI_MARCH_V3 says which build is being compiled. */
#ifndef GI_MARCH_INTERNAL_H
#define GI_MARCH_INTERNAL_H

#include <string.h>
#include "base/internal.h"
#include "trace/trace.h"
#if GI_MARCH_V3
#include <immintrin.h>
#endif

/* The part of the ray o + t w inside each level's window shrunk by one
 * voxel, [in, out] (empty when in > out): a sample at t may read level d
 * when in[d] <= t <= out[d], the test gi__level_contains makes on the
 * point, done once per cone instead of once per sample. */
typedef struct {
  float in, out;
} gi_span;

static inline void gi__level_spans(const struct gi_cascade *c, const float o[3], const float w[3], gi_span *sp) {
  for (int d = 0; d < c->n; d++) {
    const gi_level *L = &c->lv[d];
    float b = (float)L->s, tin = -INFINITY, tout = INFINITY;
    for (int a = 0; a < 3; a++) {
      float lo = L->lo[a] + b, hi = L->hi[a] - b;
      if (w[a] == 0.f) {
        if (!(o[a] >= lo && o[a] <= hi)) tin = INFINITY, tout = -INFINITY;
        continue;
      }
      float inv = 1.f / w[a], t0 = (lo - o[a]) * inv, t1 = (hi - o[a]) * inv;
      tin = gi__maxf(tin, gi__minf(t0, t1));
      tout = gi__minf(tout, gi__maxf(t0, t1));
    }
    sp[d].in = tin;
    sp[d].out = tout;
  }
}

static inline int gi__span_has(const gi_span *sp, float t) { return t >= sp->in && t <= sp->out; }

/* Axis a of the trilinear cell at coordinate x on level L (inv = 1 / s):
 * the fraction f toward its second cell, both cells' toroidal slots times
 * the axis's stride (off), and the first cell's index in the window, i0,
 * in [0, R - 2]. Returns 1 when x lay outside and was clamped to it. */
static inline int gi__cell_axis(const gi_level *L, int R, int a, float x, float inv, float *f, uint32_t off[2],
                                int *i0out) {
  float u = (x - L->lo[a]) * inv - 0.5f;
  float fl = floorf(u);
  int i0 = (int)fl, clamped = 0;
  if (i0 < 0) i0 = 0, fl = 0, u = gi__maxf(u, 0.f), clamped = 1;
  if (i0 > R - 2) i0 = R - 2, fl = (float)(R - 2), u = gi__minf(u, (float)(R - 1)), clamped = 1;
  *f = u - fl;
  /* Wrap once: the window's cells sit in toroidal slots. */
  int s0 = L->slot0[a] + i0;
  if (s0 >= R) s0 -= R;
  int s1 = s0 + 1 == R ? 0 : s0 + 1;
  uint32_t stride = a == 0 ? 1u : (a == 1 ? (uint32_t)R : (uint32_t)R * (uint32_t)R);
  off[0] = (uint32_t)s0 * stride;
  off[1] = (uint32_t)s1 * stride;
  *i0out = i0;
  return clamped;
}

/* The cell's eight texels (corner i = dx + 2 dy + 4 dz) and their weights. */
static inline void gi__cell_corners(const gi_level *L, const uint32_t off[3][2], const float f[3],
                                    const gi_vrad *r[8], float wt[8]) {
  for (int i = 0; i < 8; i++) {
    int dx = i & 1, dy = (i >> 1) & 1, dz = i >> 2;
    r[i] = &L->rad[off[2][dz] + off[1][dy] + off[0][dx]];
    wt[i] = (dx ? f[0] : 1 - f[0]) * (dy ? f[1] : 1 - f[1]) * (dz ? f[2] : 1 - f[2]);
  }
}

/* The trilinear sum of the 2x2x2 texels at a sample, all 24 lanes at
 * once: the per-cone choice of faces and axis weights is applied after
 * (reduce), so the eight texel reads are the same straight-line loads for
 * every cone. */
typedef struct {
  float v[GI_VRAD_LANES];
} gi_lanes;

#if GI_MARCH_V3
static inline void gi__sum_texels(const gi_vrad *const r[8], const float wt[8], gi_lanes *out) {
  __m256 a0 = _mm256_setzero_ps(), a1 = _mm256_setzero_ps(), a2 = _mm256_setzero_ps();
  for (int i = 0; i < 8; i++) {
    __m256 w = _mm256_set1_ps(wt[i]);
    const __m128i *h = (const __m128i *)r[i]->h;
    a0 = _mm256_fmadd_ps(w, _mm256_cvtph_ps(_mm_loadu_si128(h)), a0);
    a1 = _mm256_fmadd_ps(w, _mm256_cvtph_ps(_mm_loadu_si128(h + 1)), a1);
    a2 = _mm256_fmadd_ps(w, _mm256_cvtph_ps(_mm_loadu_si128(h + 2)), a2);
  }
  _mm256_storeu_ps(out->v, a0);
  _mm256_storeu_ps(out->v + 8, a1);
  _mm256_storeu_ps(out->v + 16, a2);
}
#else
static inline void gi__sum_texels(const gi_vrad *const r[8], const float wt[8], gi_lanes *out) {
  memset(out, 0, sizeof *out);
  for (int i = 0; i < 8; i++)
    for (int l = 0; l < GI_VRAD_LANES; l++) out->v[l] += wt[i] * gi__h2f(r[i]->h[l]);
}
#endif

/* A packed tape's next cone (trace.h: gi_tape_unit) from unit *w on: its
 * tap count, its axis weights k0 and its second ones k1 (k0 when it has
 * none); *w moves to its first tap. */
static inline unsigned gi__tape_cone(const gi_tape_unit *u, size_t *w, const float **k0, const float **k1) {
  const gi_tape_unit *h = &u[(*w)++];
  *k0 = *k1 = h->head.k;
  if (h->head.n & GI_TAPE_ALT) *k1 = u[(*w)++].f;
  return h->head.n & ~GI_TAPE_ALT;
}

/* A sample's trilinear footprint reaches this many of its level's voxels. */
#define GI_TRILINEAR_REACH 1.5f
/* A sample whose weighted opacity is below this carries no usable radiance. */
#define GI_MIN_SAMPLE_WEIGHT 1e-8f
/* Floor of the height above the surface, so its log stays finite. */
#define GI_MIN_HEIGHT 1e-30f

#endif
