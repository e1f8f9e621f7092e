/* march_kernel.c: the cone march's inner loop, built twice.
 *
 * CMake compiles this file once for any x86-64 CPU (GI_MARCH_V3 unset)
 * and once with -march=x86-64-v3 (GI_MARCH_V3=1); march.c calls the one
 * base/cpu.c chose. The two differ only in how a texel's 24 half floats
 * become float (bit arithmetic, or F16C eight lanes at a time) and in the
 * compiler's use of AVX2 and FMA. See march.c for what the march does.
 * The baseline build also replays the scalar march's taps (trace.h:
 * gi_tap) in its arithmetic; the x86-64-v3 one's are march_simd.c's. */
#include <string.h>
#include "base/internal.h"
#include "trace/trace.h"
#include "trace/march_internal.h"
#if GI_MARCH_V3
#define GI_KERNEL(name) name##_v3
#else
#define GI_KERNEL(name) name##_base
#endif

/* A sample's radiance from its summed texels s: on axis a the face facing
 * -w (faces bit a: w_a > 0) weighted k[a], times rad_scale. The march
 * (sample_level_ax) and its replay (tap_sample) share it, so their sums
 * are one arithmetic. */
static inline void faces_radiance(const struct gi_cascade *c, const gi_lanes *s, int faces, const float k[3],
                                  float prem[3]) {
  float P[3] = {0, 0, 0};
  for (int a = 0; a < 3; a++) {
    int face = 2 * a + (faces >> a & 1);
    for (int ch = 0; ch < 3; ch++) P[ch] += k[a] * s->v[3 * face + ch];
  }
  for (int ch = 0; ch < 3; ch++) prem[ch] = P[ch] * c->rad_scale;
}

/* gi__sample_level with each axis's share scaled by axw[a] (NULL: 1).
 * When the sample's 2x2x2 block is empty, *clear (may be NULL) receives
 * how far along w the point may move and still read only that block:
 * every sample there reads zero, so the march may skip to its end. With
 * `far` (the cone's level can no longer change: on the coarsest level by
 * width, with the height above the surface not shrinking, so no sample
 * in the block reads another level) and the sample's whole busy4 block
 * empty, *clear reaches that block's end instead. */
static int sample_level_ax(const struct gi_cascade *c, int d, const float p[3], const float w[3], const float *axw,
                           int far, float prem[3], float *wsum_alpha, float *sigma, float *clear) {
  const gi_level *L = &c->lv[d];
  int R = c->R;
  float inv = (float)(1.0 / L->s);
  uint32_t off[3][2];
  float f[3], run = INFINITY, run4 = INFINITY;
  int b4[3];
  for (int a = 0; a < 3; a++) {
    int i0;
    if (gi__cell_axis(L, R, a, p[a], inv, &f[a], off[a], &i0)) run = run4 = 0;
    /* Inside the block while u stays in [fl, fl + 1]; inside the busy4
     * block while u stays in [4 b, 4 b + 4]: `more` whole cells further. */
    b4[a] = i0 / GI_EMPTY_BLOCK;
    int in4 = i0 - GI_EMPTY_BLOCK * b4[a];
    /* One cell's length along w, by the reciprocal as the eight-lane march
     * takes it (once per cone there, not a division per sample). */
    float along = w[a] != 0 ? (float)L->s * (1.f / fabsf(w[a])) : 0.f;
    if (w[a] > 0) {
      run = gi__minf(run, (1.f - f[a]) * along);
      run4 = gi__minf(run4, ((float)(GI_EMPTY_BLOCK - 1 - in4) + (1.f - f[a])) * along);
    } else if (w[a] < 0) {
      run = gi__minf(run, f[a] * along);
      run4 = gi__minf(run4, ((float)in4 + f[a]) * along);
    }
  }
  if (!L->busy[off[0][0] + off[1][0] + off[2][0]]) {
    prem[0] = prem[1] = prem[2] = 0;
    *wsum_alpha = 0;
    *sigma = 0;
    if (clear) {
      int nb = gi__busy4_side(R);
      *clear = far && !L->busy4[b4[0] + nb * (b4[1] + nb * b4[2])] ? run4 : run;
    }
    return 0;
  }
  if (clear) *clear = 0;
  const gi_vrad *r[8];
  float wt[8];
  gi__cell_corners(L, off, f, r, wt);
  gi_lanes s;
  gi__sum_texels(r, wt, &s);
  /* Light travelling toward the apex (-w) leaves through the face facing -w.
   * Each face counts by its projected area along w, |w_a| alpha_a, the
   * weights the optical depth sums too, so a sample's opacity times its
   * colour is the faces' light seen from w (test_cone's box voxel). Weights
   * w_a^2 over-weighted the face most aligned with w: a closed solid's lit
   * face read 1.2x from 15 degrees, and the city's street probes read its
   * indirect light at 15.6% error instead of 10.4%. */
  float k[3], wal = 0, tau = 0;
  for (int a = 0; a < 3; a++) k[a] = fabsf(w[a]) * (axw ? axw[a] : 1.f);
  faces_radiance(c, &s, (w[0] > 0) | (w[1] > 0) << 1 | (w[2] > 0) << 2, k, prem);
  for (int a = 0; a < 3; a++) {
    wal += k[a] * s.v[GI_VRAD_ALPHA + a];
    tau += k[a] * s.v[GI_VRAD_TAU + a];
  }
  *wsum_alpha = wal;
  *sigma = tau * inv;
  return 1;
}

int GI_KERNEL(gi__sample_level)(const struct gi_cascade *c, int d, const float p[3], const float w[3],
                                float prem[3], float *wsum_alpha, float *sigma) {
  return sample_level_ax(c, d, p, w, NULL, 0, prem, wsum_alpha, sigma, NULL);
}

/* h0 < 0: the apex is in free space (a probe). h0 >= 0: the apex is h0
 * above a surface and nw is the cosine between the cone and its normal;
 * then level d is reached (lod capped at log2(h / (K s0))) only where the
 * sample is at least K = GI_SURFACE_LOD_K voxels of level d above the
 * surface plane. A coarse voxel's trilinear footprint reaches about 1.5 of
 * its voxels from the sample; samples the rule places read that one level
 * (no blend toward d+1), so K = 1.5 plus half a voxel of margin for the
 * step. Any closer and the footprint holds the surface itself, and with it
 * the radiance the surface sends out of its *other* side: behind a wall
 * thinner than a voxel, the lit room's light (the leak in test_hardcases:
 * 9% before the rule, 0.8% with it; K = 1.75 lets the camera views leak
 * 1.9%, K = 3, the value while near samples still blended, reads the same
 * 0.8% with 13% more samples). */
/* The tap of one lit scalar march step (see gi_tap): level d at p with
 * each axis weighted |w_a| ax_a (ax NULL: 1), the step's weight kk, and
 * frac >= 0 when it blended level d + 1 in. busy: GI_TAP_BUSY and
 * GI_TAP_BUSY2 as its samples read. */
static void push_tap(gi_tap_rec *rec, uint16_t job, int d, const float p[3], const float w[3], const float *ax,
                     float kk, float frac, int busy) {
  gi_tap t;
  t.job = job;
  t.d = (uint8_t)d;
  t.flags = (uint8_t)((w[0] > 0) | (w[1] > 0) << 1 | (w[2] > 0) << 2 | busy | (frac >= 0 ? GI_TAP_BLEND : 0) |
                      (ax ? GI_TAP_KALT : 0));
  for (int a = 0; a < 3; a++) t.p[a] = p[a], t.k[a] = fabsf(w[a]) * (ax ? ax[a] : 1.f);
  t.kk = kk, t.frac = frac >= 0 ? frac : 0, t.alpha = 0;
  gi__tap_push(rec, &t);
}

static void march(const struct gi_cascade *c, const float o[3], const float w[3], float tan_half, float t0,
                  float step, float ao_lambda, float h0, const float *n, gi_cone_out *out, gi_tap_rec *rec,
                  uint16_t job) {
  float L[3] = {0, 0, 0}, a = 0, occ = 0;
  float nw = n && h0 >= 0 ? gi__dot(n, w) : 0.f;
  uint32_t samples = 0;
  float s0 = (float)c->s0, inv_s0 = 1.f / s0, inv_ks0 = 1.f / (GI_SURFACE_LOD_K * s0);
  gi_span sp[GI_MAX_LEVELS];
  gi__level_spans(c, o, w, sp);
  float t = t0;
  for (int guard = 0; guard < GI_CONE_MAX_STEPS && a < GI_OPAQUE_ALPHA; guard++) {
    float D = gi__maxf(2.0f * t * tan_half, s0);
    /* x = 2^lod: the cone's width in finest voxels, or near a surface the
     * height the surface rule allows, whichever is smaller. */
    float x = D * inv_s0;
    int near = 0;
    if (h0 >= 0) {
      float xh = gi__maxf(h0 + t * nw, GI_MIN_HEIGHT) * inv_ks0;
      near = xh < x;
      x = gi__minf(x, xh);
      if (x < 1.f) x = 1.f;
    }
    /* The level is x's binary exponent and the blend toward the next level
     * its mantissa less one: linear in the width within an octave, 0 at
     * the finer level's voxel and 1 at the coarser's, with no log. Where
     * the surface rule sets the level there is no blend: the next level
     * is the one whose footprint would reach back through the surface, and
     * reading it too cost a third of the bounce's samples for no measured
     * accuracy (test_accuracy and the thin-wall leak unchanged). */
    union { float f; uint32_t u; } xb = {x};
    int d0 = (int)(xb.u >> 23) - 127;
    xb.u = (xb.u & 0x007fffffu) | 0x3f800000u;
    float frac = near ? 0.f : xb.f - 1.f;
    /* A cone wider than the coarsest voxels keeps sampling the coarsest
     * level. There the surface rule no longer holds it finer than its
     * width (the height allows that level too): the full step, as in free
     * space. */
    if (d0 >= c->n - 1) d0 = c->n - 1, frac = 0, near = 0;
    int d = d0;
    while (d < c->n && !gi__span_has(&sp[d], t)) d++;
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
    float P[3], wal, sig, clear, clear2 = INFINITY;
    /* Coarsest by width, height not shrinking: the cone reads this level to its end. */
    int far = d0 == c->n - 1 && (h0 < 0 || nw >= 0);
    int across = d > d0 && h0 >= 0 && h0 + t * nw < GI_TRILINEAR_REACH * (float)c->lv[d].s;
    float axw[3] = {across ? 1 - n[0] * n[0] : 1, across ? 1 - n[1] * n[1] : 1, across ? 1 - n[2] * n[2] : 1};
    const float *ax = across ? axw : NULL;
    int busy = sample_level_ax(c, d, p, w, ax, far, P, &wal, &sig, &clear) ? GI_TAP_BUSY : 0;
    samples++;
    int two = frac > 0 && d + 1 < c->n && gi__span_has(&sp[d + 1], t);
    if (two) {
      float P2[3], wal2, sig2;
      busy |= sample_level_ax(c, d + 1, p, w, NULL, 0, P2, &wal2, &sig2, &clear2) ? GI_TAP_BUSY2 : 0;
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
    /* In empty blocks nothing is read until the nearer block's end: skip the
     * whole steps before it (landing just past the border put every wall's
     * first sample at one phase of its voxels: the a=0.99 furnace read darker). */
    float run = gi__minf(clear, clear2);
    if (run > dt) dt *= ceilf(run / dt);
    float as = 1.0f - gi__fast_exp_neg(sig * dt);
    if (as > 0 && wal > GI_MIN_SAMPLE_WEIGHT) {
      float k = (1 - a) * as / wal;
      L[0] += k * P[0];
      L[1] += k * P[1];
      L[2] += k * P[2];
      if (rec) push_tap(rec, job, d, p, w, ax, k, two ? frac : -1.f, busy);
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

void GI_KERNEL(gi__cone_march)(const struct gi_cascade *c, const float o[3], const float w[3], float tan_half, float t0,
                               float step, float ao_lambda, float h0, const float *n, gi_cone_out *out) {
  march(c, o, w, tan_half, t0, step, ao_lambda, h0, n, out, NULL, 0);
}

void GI_KERNEL(gi__cone_march_rec)(const struct gi_cascade *c, const float o[3], const float w[3], float tan_half,
                                   float t0, float step, float ao_lambda, float h0, const float *n, gi_cone_out *out,
                                   gi_tap_rec *rec, uint16_t job) {
  march(c, o, w, tan_half, t0, step, ao_lambda, h0, n, out, rec, job);
}

#if !GI_MARCH_V3
/* sample_level_ax's radiance for a tap's sample on level d at p, axes
 * weighted k, through the faces bits of `faces` (busy: else 0). */
static void tap_sample(const struct gi_cascade *c, int d, const float p[3], const float k[3], int faces, int busy,
                       float prem[3]) {
  prem[0] = prem[1] = prem[2] = 0;
  if (!busy) return;
  const gi_level *L = &c->lv[d];
  float inv = (float)(1.0 / L->s), f[3];
  uint32_t off[3][2];
  int i0;
  for (int a = 0; a < 3; a++) gi__cell_axis(L, c->R, a, p[a], inv, &f[a], off[a], &i0);
  const gi_vrad *r[8];
  float wt[8];
  gi__cell_corners(L, off, f, r, wt);
  gi_lanes s;
  gi__sum_texels(r, wt, &s);
  faces_radiance(c, &s, faces, k, prem);
}

/* The scalar march's arithmetic, step by step (march), from a packed tape. */
size_t GI_KERNEL(gi__replay_tape)(const struct gi_cascade *c, const gi_tape_unit *u, size_t units, float L[][3],
                                  uint16_t *job) {
  size_t cone = 0;
  for (size_t w = 0; w < units;) {
    const gi_tape_unit *h = &u[w];
    const float *k0, *k1;
    unsigned n = gi__tape_cone(u, &w, &k0, &k1);
    float acc[3] = {0, 0, 0};
    for (unsigned q = 0; q < n; q++) {
      const gi_tape_unit *x = &u[w++];
      const float *k = x->tap.flags & GI_TAP_KALT ? k1 : k0;
      float P[3], P2[3];
      tap_sample(c, x->tap.d, x->tap.p, k, x->tap.flags, x->tap.flags & GI_TAP_BUSY, P);
      if (x->tap.flags & GI_TAP_BLEND) {
        float frac = u[w++].f[0];
        tap_sample(c, x->tap.d + 1, x->tap.p, k, x->tap.flags, x->tap.flags & GI_TAP_BUSY2, P2);
        for (int ch = 0; ch < 3; ch++) P[ch] += frac * (P2[ch] - P[ch]);
      }
      float kk = x->tap.kk;
      acc[0] += kk * P[0];
      acc[1] += kk * P[1];
      acc[2] += kk * P[2];
    }
    float a = h->head.alpha;
    if (a >= GI_OPAQUE_ALPHA)
      for (int ch = 0; ch < 3; ch++) acc[ch] /= a;
    memcpy(L[cone], acc, sizeof acc);
    if (job) job[cone] = h->head.job;
    cone++;
  }
  return cone;
}
#endif
