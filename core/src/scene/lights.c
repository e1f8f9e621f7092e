/* lights.c: the light sampler shared by injection, probes and camera views.
 *
 * A point gets one sample per sun, point and spot light (a light cut's
 * samples when there are thousands: local_tree.c), stratified samples
 * over the sky's upper hemisphere and over emissive triangles picked by
 * power and distance (light_tree.c). Each sample carries what a surface facing it receives,
 * with solid-angle and pdf weights folded in, so callers only add up
 * visible samples (shadow.c decides visibility). Emitter samples also carry
 * their pdf for multiple importance sampling against the callers' own
 * cosine or sphere rays (gi__emitter_rays). */
#include <limits.h>
#include <stdlib.h>
#include <string.h>
#include "base/internal.h"
#include "scene/lights.h"

/* Picks per gi__light_tree_picks call (their u on the stack). */
#define GI_PICK_BATCH 64

/* The fractional golden ratio: the low-discrepancy step of sky azimuths. */
#define GI_GOLDEN 0.6180339887f

gi_light_plan gi__light_plan(const gi_bake_report *r, int samples) {
  gi_light_plan lp = {
      .sun = r->effects[GI_FX_SUN].ran,
      .local = r->effects[GI_FX_LOCAL].ran,
      .sky = r->effects[GI_FX_SKY].ran,
      .emissive = r->effects[GI_FX_EMISSIVE].ran,
      .sky_samples = samples,
      /* Every sample: with half of them for the emitters a grid shift's
       * jump at a fixed point grew 1.6-1.9x (docs/accuracy-notes.md). */
      .emit_samples = samples,
  };
  lp.local_cut = gi__local_cut_size(samples);
  return lp;
}

int gi__answer_sky(const gi_scene *s, const gi_bake_report *r) {
  if (r->effects[GI_FX_SKY].ran) return 1;
  if (r->quality.effects[GI_FX_SKY] == GI_FX_OFF) return 0;
  float sky[3];
  gi__sky_radiance(s, sky);
  return sky[0] > 0 || sky[1] > 0 || sky[2] > 0;
}

gi_light_plan gi__answer_light_plan(const gi_scene *s, const gi_bake_report *r, int samples) {
  gi_light_plan lp = gi__light_plan(r, samples);
  lp.sky = gi__answer_sky(s, r);
  /* The plan leaves emitters farther than half a cascade out of the
   * voxels; a point far from the viewpoint may sit right under one (a
   * probe inside the Cornell box, baked from its camera, read 0). */
  lp.emissive |= s->num_emitters > 0 && r->quality.effects[GI_FX_EMISSIVE] != GI_FX_OFF;
  return lp;
}

void gi__sky_radiance(const gi_scene *s, float out[3]) {
  out[0] = out[1] = out[2] = 0;
  for (uint32_t i = 0; i < s->num_lights; i++)
    if (s->lights[i].type == GI_LIGHT_SKY)
      for (int k = 0; k < 3; k++) out[k] += s->lights[i].color[k];
}

int gi__light_sample_cap(const gi_scene *s, const gi_light_plan *lp) {
  size_t n = 0;
  int cut = gi__local_by_cut(s, lp);
  for (uint32_t i = 0; i < s->num_lights; i++) {
    const gi_light *l = &s->lights[i];
    if (cut && (l->type == GI_LIGHT_POINT || l->type == GI_LIGHT_SPOT)) continue;
    n += l->type == GI_LIGHT_SKY ? (size_t)(lp->sky_samples > 0 ? lp->sky_samples : 0) : 1;
  }
  if (cut) n += (size_t)lp->local_cut;
  if (s->num_emitters > 0 && lp->emit_samples > 0) n += (size_t)lp->emit_samples;
  /* Beyond INT_MAX the buffer cannot be allocated anyway: the caller reports out of memory. */
  return n > INT_MAX ? INT_MAX : (int)(n ? n : 1);
}

/* m samples of one sky light over the upper hemisphere, stratified in
 * cos(theta) and azimuth, uniform pdf 1 / (2 pi); appended at out[n..max). */
static int sky_samples(const gi_light *l, int m, const float up[3], uint64_t *rng, gi_lsample *out, int n,
                       int max) {
  float t[3], b[3];
  gi__basis(up, t, b);
  float rot = gi__u01(rng);
  for (int j = 0; j < m && n < max; j++) {
    float ct = ((float)j + gi__u01(rng)) / (float)m;
    float st = sqrtf(fmaxf(0.f, 1 - ct * ct));
    float phi = 2 * GI_PI_F * ((float)j * GI_GOLDEN + rot);
    float cp = cosf(phi), sp = sinf(phi);
    gi_lsample *q = &out[n++];
    for (int k = 0; k < 3; k++) q->w[k] = st * cp * t[k] + st * sp * b[k] + ct * up[k];
    q->dist = INFINITY;
    for (int k = 0; k < 3; k++) q->V[k] = l->color[k] * 2 * GI_PI_F / (float)m;
    q->fx = GI_FX_SKY;
    q->mpl = 0;
  }
  return n;
}

/* The sample of emitter slot (picked with probability pt) that r1, r2
 * place on it, seen from p; V holds 1 / m of the estimate. */
static int emitter_point(const gi_scene *s, uint32_t slot, float pt, float r1, float r2, int m, const float p[3],
                         gi_lsample *q) {
  if (!(pt > 0)) return 0;
  const gi_emitter_geo *eg = &s->emitter_geo[slot];
  const float *A = eg->v[0], *B = eg->v[1], *C = eg->v[2];
  float sr = sqrtf(r1), ba = 1 - sr, bb = sr * (1 - r2), bc = sr * r2;
  float e1[3], e2[3], ng[3], y[3], v[3];
  for (int k = 0; k < 3; k++) {
    e1[k] = B[k] - A[k];
    e2[k] = C[k] - A[k];
    y[k] = ba * A[k] + bb * B[k] + bc * C[k];
    v[k] = y[k] - p[k];
  }
  gi__cross(e1, e2, ng);
  float area2 = gi__len(ng);
  if (!(area2 > 0)) return 0;
  float r2d = gi__dot(v, v);
  if (!(r2d > 0)) return 0;
  float r = sqrtf(r2d);
  for (int k = 0; k < 3; k++) q->w[k] = v[k] / r;
  /* An emitter faces its winding normal, or both ways when two-sided. */
  float cos_e = -gi__dot(ng, q->w) / area2;
  if (eg->two_sided) cos_e = fabsf(cos_e);
  if (!(cos_e > 0)) return 0;
  float area = 0.5f * area2;
  float pdf_area = pt / area;
  const float *Le = eg->Le;
  float k0 = cos_e / (r2d * pdf_area * (float)m);
  for (int k = 0; k < 3; k++) q->V[k] = Le[k] * k0;
  q->mpl = (float)m * pdf_area * r2d / cos_e;
  q->dist = r;
  q->fx = GI_FX_EMISSIVE;
  return 1;
}

/* Picks b..b+n-1 of m from p (n <= GI_PICK_BATCH) into out: stratum k
 * of u, drawn in order, walked down the tree together. */
static void picks_from(const gi_scene *s, const float p[3], int b, int n, int m, uint64_t *rng, gi_emitter_pick *out) {
  double u[GI_PICK_BATCH];
  for (int k = 0; k < n; k++) u[k] = ((double)(b + k) + gi__u01(rng)) / (double)m;
  gi__light_tree_picks(s, p, u, n, out);
}

int gi__emitter_picks(const gi_scene *s, const float c[3], int m, uint64_t *rng, gi_emitter_pick *out) {
  if (s->num_emitters == 0) return 0;
  for (int b = 0; b < m; b += GI_PICK_BATCH)
    picks_from(s, c, b, m - b < GI_PICK_BATCH ? m - b : GI_PICK_BATCH, m, rng, out + b);
  return 1;
}

int gi__emitter_sample_at(const gi_scene *s, const gi_emitter_pick *pk, float r2, const float p[3], gi_lsample *q) {
  return emitter_point(s, pk->slot, pk->prob, pk->u_rest, r2, 1, p, q);
}

int gi__light_samples(const gi_scene *s, const gi_light_plan *lp, const float p[3], uint64_t *rng,
                      gi_lsample *out, int max) {
  int n = 0, cut = gi__local_by_cut(s, lp);
  const float *up_axis = s->up == GI_UP_Z ? (const float[3]){0, 0, 1} : (const float[3]){0, 1, 0};
  /* With the cut, only the other lights one by one: a loop over all of
   * them was a quarter of a 16,384-lamp bake. */
  uint32_t count = cut ? s->num_other : s->num_lights;
  for (uint32_t i = 0; i < count && n < max; i++) {
    const gi_light *l = &s->lights[cut ? s->other_lights[i] : i];
    gi_lsample *o = &out[n];
    if (l->type == GI_LIGHT_SUN) {
      if (!lp->sun) continue;
      for (int k = 0; k < 3; k++) o->w[k] = -l->direction[k];
      o->dist = INFINITY;
      memcpy(o->V, l->color, sizeof o->V);
      o->fx = GI_FX_SUN;
      o->mpl = 0;
      n++;
    } else if (l->type == GI_LIGHT_POINT || l->type == GI_LIGHT_SPOT) {
      if (lp->local && !cut) n += gi__local_sample(s, l, p, o);
    } else if (l->type == GI_LIGHT_SKY && lp->sky && lp->sky_samples > 0) {
      n = sky_samples(l, lp->sky_samples, up_axis, rng, out, n, max);
    }
  }
  /* Many point and spot lights: the light cut's samples (local_tree.c). */
  if (cut) n += gi__local_cut_samples(s, p, lp->local_cut, rng, out + n, max - n);
  if (lp->emissive && s->num_emitters > 0) {
    /* Sample j of m: a triangle picked by the light tree (power and
     * distance, stratified in j), and a point on it. The pick's leftover u
     * places the point along the triangle and the radical inverse of j
     * across it, so strata that share a triangle spread over it instead of
     * landing at random (Cornell's direct error at the probes 0.72% from
     * 1.88%). */
    int m = lp->emit_samples;
    float rot2 = gi__u01(rng);
    gi_emitter_pick pk[GI_PICK_BATCH];
    for (int b = 0; b < m && n < max; b += GI_PICK_BATCH) {
      int c = m - b < GI_PICK_BATCH ? m - b : GI_PICK_BATCH;
      picks_from(s, p, b, c, m, rng, pk);
      for (int k = 0; k < c && n < max; k++)
        n += emitter_point(s, pk[k].slot, pk[k].prob, pk[k].u_rest, gi__radical2_rot((uint32_t)(b + k), rot2), m, p,
                           &out[n]);
    }
  }
  return n;
}

float gi__emitter_mpl(const gi_scene *s, const float p[3], uint32_t tri, float t, float cos_e, int m) {
  /* emitter_tri is ascending: binary search for the triangle's slot. */
  uint32_t lo = 0, hi = s->num_emitters;
  while (lo < hi) {
    uint32_t mid = (lo + hi) / 2;
    if (s->emitter_tri[mid] < tri) lo = mid + 1;
    else hi = mid;
  }
  if (lo >= s->num_emitters || s->emitter_tri[lo] != tri || !(cos_e > 0)) return 0;
  float pt = gi__light_tree_prob(s, p, lo);
  float ng[3];
  gi__tri_cross(s, tri, ng);
  float area = 0.5f * gi__len(ng);
  if (!(area > 0)) return 0;
  return (float)m * (pt / area) * t * t / cos_e;
}

int gi__emitter_hit(const gi_scene *s, uint32_t tri, const float w[3], float *cos_e) {
  const float *Le = s->materials[s->tri_material[tri]].emission;
  if (!(Le[0] > 0 || Le[1] > 0 || Le[2] > 0)) return 0;
  float ng[3];
  gi__tri_cross(s, tri, ng);
  float l = gi__len(ng);
  if (!(l > 0)) return 0;
  *cos_e = gi__emitter_cos(s, tri, -gi__dot(ng, w) / l);
  return *cos_e > 0;
}

void gi__emitter_rays(const gi_scene *s, const float p[3], int n, const float (*o)[3], const float (*w)[3],
                      const float *tnear, int m_light, const float *pb, int power, float (*out)[3], uint8_t *hit) {
  if (n <= 0) return;
  if (n > GI_EMIT_RAYS) n = GI_EMIT_RAYS;
  float tn[GI_EMIT_RAYS], th[GI_EMIT_RAYS], ce[GI_EMIT_RAYS];
  uint32_t tri[GI_EMIT_RAYS];
  /* A ray with no pdf finds nothing: a NaN start disables it. */
  for (int i = 0; i < n; i++) tn[i] = pb[i] > 0 ? tnear[i] : NAN;
  gi__emitter_find_n(s, n, o, w, tn, th, tri, hit);
  /* Anything in front of an emitter found, short of its own plane, blocks it. */
  float so[GI_EMIT_RAYS][3], sw[GI_EMIT_RAYS][3], stn[GI_EMIT_RAYS], stf[GI_EMIT_RAYS];
  uint8_t vis[GI_EMIT_RAYS];
  int who[GI_EMIT_RAYS], k = 0;
  for (int i = 0; i < n; i++) {
    if (hit[i] && !gi__emitter_hit(s, tri[i], w[i], &ce[i])) hit[i] = 0;
    if (!hit[i]) continue;
    float tf = th[i] * (1.f - GI_EMIT_SHADOW_SHORT);
    if (!(tf > tnear[i])) continue;
    memcpy(so[k], o[i], sizeof so[k]);
    memcpy(sw[k], w[i], sizeof sw[k]);
    stn[k] = tnear[i], stf[k] = tf, who[k++] = i;
  }
  gi__occluded(s, k, &so[0][0], &sw[0][0], stn, stf, vis);
  for (int j = 0; j < k; j++) hit[who[j]] = vis[j];
  for (int i = 0; i < n; i++) {
    if (!hit[i]) continue;
    float mpl = gi__emitter_mpl(s, p, tri[i], th[i], ce[i], m_light);
    const float *Le = s->materials[s->tri_material[tri[i]]].emission;
    if (power) {
      /* The light sample's weight with the roles swapped: one formula, finite whatever the pdfs. */
      float wb = gi__mis_light(pb[i], mpl, 1);
      for (int c = 0; c < 3; c++) out[i][c] = Le[c] * wb / pb[i];
    } else {
      for (int c = 0; c < 3; c++) out[i][c] = Le[c] / (mpl + pb[i]);
    }
  }
}

void gi__emitter_cosine_rays(const gi_scene *s, const float p[3], const float o[3], float tnear, const float n[3],
                             int mb, int m_light, uint64_t *rng, const float *rot, float E[3]) {
  float t[3], b[3];
  gi__basis(n, t, b);
  float w[GI_EMIT_RAYS][3], oo[GI_EMIT_RAYS][3], tn[GI_EMIT_RAYS], pb[GI_EMIT_RAYS], z[GI_EMIT_RAYS];
  float V[GI_EMIT_RAYS][3];
  uint8_t hit[GI_EMIT_RAYS];
  for (int j0 = 0; j0 < mb; j0 += GI_EMIT_RAYS) {
    int nb = mb - j0 < GI_EMIT_RAYS ? mb - j0 : GI_EMIT_RAYS;
    for (int i = 0; i < nb; i++) {
      int j = j0 + i;
      float u1 = ((float)j + gi__u01(rng)) / (float)mb;
      float u2 = rot ? gi__radical2_rot((uint32_t)j, *rot) : gi__u01(rng);
      z[i] = gi__cosine_dir(t, b, n, u1, u2, w[i]);
      memcpy(oo[i], o, sizeof oo[i]);
      tn[i] = tnear, pb[i] = (float)mb * z[i] / GI_PI_F;
    }
    gi__emitter_rays(s, p, nb, (const float(*)[3])oo, (const float(*)[3])w, tn, m_light, pb, 0, V, hit);
    /* In ray order, as one ray at a time added them. */
    for (int i = 0; i < nb; i++)
      if (hit[i])
        for (int k = 0; k < 3; k++) E[k] += V[i][k] * z[i];
  }
}
