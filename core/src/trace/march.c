/* trace.c: the cone-tracing filter over the cascaded texture.
 *
 * A cone at distance t has diameter D = 2 t tan(aperture/2). The level to
 * sample follows directly from D (lod = log2(D / s0)) and from the sample's
 * position (the finest level whose window, less a one-voxel border for the
 * trilinear footprint, contains it): no tree is walked. Between two levels
 * the sample blends linearly by the fractional lod, so a cone's result
 * changes smoothly as the viewpoint or the cascade moves.
 *
 * A sample reads the three faces that face back toward the apex, weighted
 * by the squared components of the direction. Opacity comes from optical
 * depth: sigma = sum |w_a| tau_a / s, so a slab that is opaque along its
 * normal stays opaque at any angle, and a segment of length dt has opacity
 * 1 - exp(-sigma dt) (the step-length correction). Compositing is front to
 * back: c += (1 - a) a_s c_s, a += (1 - a) a_s, until a >= GI_OPAQUE_ALPHA
 * or the cone leaves the coarsest level; a cone stopped by opacity is
 * renormalised by a. Where a cone starts and which levels it may enter
 * near a surface is the gather's rule (trace/gather.c).
 * */
#include <string.h>
#include "base/internal.h"
#include "scene/lights.h"
#include "trace/trace.h"

int gi__finest_level_at(const struct gi_cascade *c, const float p[3]) {
  for (int d = 0; d < c->n; d++)
    if (gi__level_contains(&c->lv[d], p, 1.0f)) return d;
  return -1;
}

float gi__voxel_at(const struct gi_cascade *c, const float p[3]) {
  int d = gi__finest_level_at(c, p);
  return (float)(d >= 0 ? c->lv[d].s : c->s0);
}

static int sample_level_ax(const struct gi_cascade *c, int d, const float p[3], const float w[3], const float *axw,
                           float prem[3], float *wsum_alpha, float *sigma);

int gi__sample_level(const struct gi_cascade *c, int d, const float p[3], const float w[3],
                     float prem[3], float *wsum_alpha, float *sigma) {
  return sample_level_ax(c, d, p, w, NULL, prem, wsum_alpha, sigma);
}

/* gi__sample_level with each axis's share scaled by axw[a] (NULL: 1). */
static int sample_level_ax(const struct gi_cascade *c, int d, const float p[3], const float w[3], const float *axw,
                           float prem[3], float *wsum_alpha, float *sigma) {
  const gi_level *L = &c->lv[d];
  int R = c->R;
  float inv = (float)(1.0 / L->s);
  /* Wrap each axis once: toroidal slots of the two cells the footprint spans. */
  uint32_t off[3][2];
  float f[3];
  for (int a = 0; a < 3; a++) {
    float u = (p[a] - L->lo[a]) * inv - 0.5f;
    float fl = floorf(u);
    int i0 = (int)fl;
    if (i0 < 0) i0 = 0, fl = 0, u = fmaxf(u, 0.f);
    if (i0 > R - 2) i0 = R - 2, fl = (float)(R - 2), u = fminf(u, (float)(R - 1));
    f[a] = u - fl;
    int s0 = L->slot0[a] + i0;
    if (s0 >= R) s0 -= R;
    int s1 = s0 + 1 == R ? 0 : s0 + 1;
    uint32_t stride = a == 0 ? 1u : (a == 1 ? (uint32_t)R : (uint32_t)R * (uint32_t)R);
    off[a][0] = (uint32_t)s0 * stride;
    off[a][1] = (uint32_t)s1 * stride;
  }
  if (!L->busy[off[0][0] + off[1][0] + off[2][0]]) {
    prem[0] = prem[1] = prem[2] = 0;
    *wsum_alpha = 0;
    *sigma = 0;
    return 0;
  }
  int face[3];
  float w2[3], wa[3];
  for (int a = 0; a < 3; a++) {
    /* Light travelling toward the apex (-w) leaves through the face facing -w. */
    face[a] = 2 * a + (w[a] > 0 ? 1 : 0);
    w2[a] = w[a] * w[a] * (axw ? axw[a] : 1.f);
    wa[a] = fabsf(w[a]) * (axw ? axw[a] : 1.f);
  }
  float P[3] = {0, 0, 0}, wal = 0, tau = 0;
  for (int dz = 0; dz < 2; dz++) {
    float wz = dz ? f[2] : 1 - f[2];
    if (wz <= 0) continue;
    for (int dy = 0; dy < 2; dy++) {
      float wyz = wz * (dy ? f[1] : 1 - f[1]);
      if (wyz <= 0) continue;
      uint32_t row = off[2][dz] + off[1][dy];
      for (int dx = 0; dx < 2; dx++) {
        float wt = wyz * (dx ? f[0] : 1 - f[0]);
        if (wt <= 0) continue;
        const gi_vrad *r = &L->rad[row + off[0][dx]];
        for (int a = 0; a < 3; a++) {
          float k = wt * w2[a];
          const float *pf = r->p[face[a]];
          P[0] += k * pf[0];
          P[1] += k * pf[1];
          P[2] += k * pf[2];
          wal += k * r->alpha[a];
          tau += wt * wa[a] * r->tau[a];
        }
      }
    }
  }
  prem[0] = P[0];
  prem[1] = P[1];
  prem[2] = P[2];
  *wsum_alpha = wal;
  *sigma = tau * inv;
  return 1;
}

/* A sample's trilinear footprint reaches this many of its level's voxels. */
#define GI_TRILINEAR_REACH 1.5f
/* A sample whose weighted opacity is below this carries no usable radiance. */
#define GI_MIN_SAMPLE_WEIGHT 1e-8f
/* Floor of the height above the surface, so its log stays finite. */
#define GI_MIN_HEIGHT 1e-30f

/* h0 < 0: the apex is in free space (a probe). h0 >= 0: the apex is h0
 * above a surface and nw is the cosine between the cone and its normal;
 * then level d is reached (lod capped at log2(h / (K s0))) only where the
 * sample is at least K = GI_SURFACE_LOD_K voxels of level d above the
 * surface plane. A coarse voxel's trilinear footprint reaches about 1.5 of
 * its voxels from the sample, and the blend toward level d+1 starts at lod
 * d, hence K = 2 x 1.5. Any closer and the footprint holds the surface
 * itself, and with it the radiance the surface sends out of its *other*
 * side: behind a wall thinner than a voxel, the lit room's light (the leak
 * in test_hardcases: 9% before, under 1% after). */
/* The part of the ray o + t w inside each level's window shrunk by one
 * voxel, [in, out] (empty when in > out): a sample at t may read level d
 * when in[d] <= t <= out[d], the test gi__level_contains makes on the
 * point, done once per cone instead of once per sample. */
typedef struct {
  float in, out;
} gi_span;

static void level_spans(const struct gi_cascade *c, const float o[3], const float w[3], gi_span *sp) {
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

static inline int span_has(const gi_span *sp, float t) { return t >= sp->in && t <= sp->out; }

void gi__cone_march(const struct gi_cascade *c, const float o[3], const float w[3], float tan_half, float t0,
                    float step, float ao_lambda, float h0, const float *n, gi_cone_out *out) {
  float L[3] = {0, 0, 0}, a = 0, occ = 0;
  float nw = n && h0 >= 0 ? gi__dot(n, w) : 0.f;
  uint32_t samples = 0;
  float s0 = (float)c->s0, inv_s0 = 1.f / s0, inv_ks0 = 1.f / (GI_SURFACE_LOD_K * s0);
  gi_span sp[GI_MAX_LEVELS];
  level_spans(c, o, w, sp);
  float t = t0;
  for (int guard = 0; guard < GI_CONE_MAX_STEPS && a < GI_OPAQUE_ALPHA; guard++) {
    float D = gi__maxf(2.0f * t * tan_half, s0);
    float lod = gi__fast_log2(D * inv_s0);
    int near = 0;
    if (h0 >= 0) {
      float h = h0 + t * nw;
      float lh = gi__fast_log2(gi__maxf(h, GI_MIN_HEIGHT) * inv_ks0);
      near = lh < lod;
      lod = gi__minf(lod, lh);
      if (lod < 0) lod = 0;
    }
    int d0 = (int)lod;
    float frac = lod - (float)d0;
    /* A cone wider than the coarsest voxels keeps sampling the coarsest level. */
    if (d0 >= c->n - 1) d0 = c->n - 1, frac = 0;
    int d = d0;
    while (d < c->n && !span_has(&sp[d], t)) d++;
    if (d >= c->n) break;
    if (d > d0) frac = 0; /* pushed to a coarser level by position, not by size */
    float p[3] = {o[0] + t * w[0], o[1] + t * w[1], o[2] + t * w[2]};
    /* Pushed there near the surface it started from, the coarse trilinear
     * footprint (1.5 voxels) holds that surface itself, which reads as an
     * occluder: a grazing cone leaving the finer window turned black on
     * the glossy floor of test_specular. Such samples read only the axes
     * across the surface's normal (weights 1 - n_a^2): a floor's own
     * opacity and radiance lie along its normal, a wall standing on it
     * lies across. */
    float P[3], wal, sig;
    if (d > d0 && h0 >= 0 && h0 + t * nw < GI_TRILINEAR_REACH * (float)c->lv[d].s) {
      float axw[3] = {1 - n[0] * n[0], 1 - n[1] * n[1], 1 - n[2] * n[2]};
      sample_level_ax(c, d, p, w, axw, P, &wal, &sig);
    } else {
      gi__sample_level(c, d, p, w, P, &wal, &sig);
    }
    samples++;
    if (frac > 0 && d + 1 < c->n && span_has(&sp[d + 1], t)) {
      float P2[3], wal2, sig2;
      gi__sample_level(c, d + 1, p, w, P2, &wal2, &sig2);
      samples++;
      for (int k = 0; k < 3; k++) P[k] += frac * (P2[k] - P[k]);
      wal += frac * (wal2 - wal);
      sig += frac * (sig2 - sig);
    }
    /* Step a fraction of the sampled level's voxel: a longer step could jump a
     * wall, a shorter one only re-reads the same trilinear data. Where the
     * surface rule holds the cone on a level finer than its width, the
     * step stays short (GI_NEAR_SURFACE_STEP): that is where a wall behind
     * the surface must not be jumped. */
    float dt = (near ? gi__minf(step, GI_NEAR_SURFACE_STEP) : step) * (float)c->lv[d].s;
    float as = 1.0f - gi__fast_exp_neg(sig * dt);
    if (as > 0 && wal > GI_MIN_SAMPLE_WEIGHT) {
      float k = (1 - a) * as / wal;
      L[0] += k * P[0];
      L[1] += k * P[1];
      L[2] += k * P[2];
    }
    occ += (1 - occ) * as / (1.0f + ao_lambda * 0.5f * D);
    a += (1 - a) * as;
    t += dt;
  }
  /* A cone stopped by the opacity threshold assumes its last 1% looks like
   * the rest; without this a closed room loses 1% per bounce. */
  if (a >= GI_OPAQUE_ALPHA)
    for (int k = 0; k < 3; k++) L[k] /= a;
  memcpy(out->L, L, sizeof L);
  out->alpha = a;
  out->occlusion = occ;
  out->samples = samples;
}
