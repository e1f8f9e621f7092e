/* ref_lights.c: the reference's next-event estimation, apart from the
 * bake's light sampler (scene/lights.c) so that neither can hide a bug of
 * the other.
 *
 * The radiometry is the scene's: a sun gives irradiance `color` to a
 * surface facing it; a point light `color / r^2`; a spot the same times a
 * smoothstep from its outer cone (0) to its inner cone (1); a sky is
 * radiance `color` over the upper hemisphere about the scene's up axis;
 * emissive triangles emit their material's radiance from the side their
 * winding normal faces only, or from both when the material is two-sided.
 * Sun, point and spot are evaluated exactly.
 * Emitters are sampled by area: a triangle picked, then a uniform point on
 * it by folding the unit square. The sky has no light sample: callers meet
 * it with their own cosine or mixture directions.
 *
 * Picking. A city has thousands of small emitters; picked by power alone
 * (a table built here, weight area times mean emission) a street-level
 * point spends nearly all its samples on windows across town, hidden or
 * far, and the few near ones it draws carry the light: noise. So by
 * default the pick walks the scene's light tree (scene/light_tree.c), by
 * power over distance squared and orientation seen from the shading point.
 * That is the one piece of sampling shared with the bake; it cannot bias
 * the reference unseen because only its probabilities matter (the
 * estimate divides by exactly the probability the walk took, and the MIS
 * weight of an emitter met by a BSDF ray asks the tree for the same
 * point's probability), and test_reference checks that those
 * probabilities sum to 1, match the walk's frequencies, and that both
 * pickers agree with each other and with closed forms.
 *
 * Light tracing (ref_lt, used by reference.c): the pick weights of point
 * and spot lights seen from a point and the area pdf of a light-traced
 * surface point, which both of its MIS strategies must compute alike. */
#include <stdlib.h>
#include <string.h>
#include "reference/ref_internal.h"
#include "scene/lights.h"

/* Lights closer than this (squared, local units) are skipped: 1 / r^2 blows up. */
#define MIN_LIGHT_DIST2 1e-12f

static void tri_corners(const gi_scene *s, uint32_t tri, const float *P[3]) {
  for (int c = 0; c < 3; c++) P[c] = &s->vertices[3 * s->indices[3 * tri + c]];
}

/* Winding normal times twice the area. */
static void tri_normal2(const float *P[3], float n[3]) {
  float e1[3], e2[3];
  for (int k = 0; k < 3; k++) e1[k] = P[1][k] - P[0][k], e2[k] = P[2][k] - P[0][k];
  gi__cross(e1, e2, n);
}

static int emissive(const float e[3]) { return e[0] > 0 || e[1] > 0 || e[2] > 0; }

/* Twice the area of triangle tri. */
static float tri_area2(const gi_scene *s, uint32_t tri) {
  const float *P[3];
  float ng[3];
  tri_corners(s, tri, P);
  tri_normal2(P, ng);
  return gi__len(ng);
}

/* The power table: entries q of L->em get cdf and pick from area times
 * mean emission; 0 when every emitter is degenerate (nothing to pick). */
static int power_table(ref_lights *L) {
  const gi_scene *s = L->s;
  double sum = 0;
  for (uint32_t q = 0; q < L->num_emitters; q++) {
    const float *e = s->materials[s->tri_material[L->em[q].tri]].emission;
    sum += (double)L->em[q].area * (e[0] + e[1] + e[2]) / 3;
    L->em[q].cdf = sum;
  }
  if (!(sum > 0)) return 0;
  double prev = 0;
  for (uint32_t q = 0; q < L->num_emitters; q++) {
    L->em[q].pick = (float)((L->em[q].cdf - prev) / sum);
    prev = L->em[q].cdf;
    L->em[q].cdf /= sum;
  }
  L->em[L->num_emitters - 1].cdf = 1.0;
  return 1;
}

/* The tree picks scene emitter slots: they must be this table's entries. */
static int slots_match(const ref_lights *L) {
  const gi_scene *s = L->s;
  if (s->num_emitters != L->num_emitters || !s->ltree) return 0;
  for (uint32_t q = 0; q < L->num_emitters; q++)
    if (s->emitter_tri[q] != L->em[q].tri) return 0;
  return 1;
}

gi_result gi__ref_lights_init(ref_lights *L, const gi_scene *s, int pick, int lights, gi_error_info *err) {
  memset(L, 0, sizeof *L);
  L->s = s;
  L->by_tree = pick == GI_REF_PICK_TREE;
  float ext = 0;
  for (int a = 0; a < 3; a++) ext = fmaxf(ext, s->hi[a] - s->lo[a]);
  /* Float positions near ext carry ~1e-7 ext of error: offsets scale with it. */
  L->eps = 2e-5f * ext + 1e-6f;
  L->extent = ext;
  L->up[s->up == GI_UP_Z ? 2 : 1] = 1;
  L->lights = lights ? lights : GI_REF_LIGHTS_ALL;
  for (uint32_t i = 0; i < s->num_lights && ref_light_on(L, GI_FX_SKY); i++)
    if (s->lights[i].type == GI_LIGHT_SKY) {
      L->has_sky = 1;
      for (int k = 0; k < 3; k++) L->sky[k] += s->lights[i].color[k];
    }
  uint32_t n = 0;
  for (uint32_t t = 0; t < s->num_triangles; t++) n += emissive(s->materials[s->tri_material[t]].emission);
  if (!n || !ref_light_on(L, GI_FX_EMISSIVE)) return GI_OK; /* no table: nothing sampled, nothing hit (emitted) */
  L->em = gi__malloc((size_t)n * sizeof *L->em);
  if (!L->em) return gi__fail(err, GI_ERR_NOMEM, "reference: out of memory for %u emissive triangles", n);
  for (uint32_t t = 0, q = 0; t < s->num_triangles; t++) {
    if (!emissive(s->materials[s->tri_material[t]].emission)) continue;
    L->em[q].tri = t;
    L->em[q++].area = 0.5f * tri_area2(s, t);
  }
  L->num_emitters = n;
  if (!power_table(L)) { /* only degenerate emitters: nothing can be sampled or hit */
    gi__ref_lights_free(L);
    return GI_OK;
  }
  if (L->by_tree && !slots_match(L)) {
    gi__ref_lights_free(L);
    return gi__fail(err, GI_ERR_INTERNAL, "reference: the scene's %u emitter slots are not its %u emissive triangles",
                    s->num_emitters, n);
  }
  return GI_OK;
}

void gi__ref_lights_free(ref_lights *L) {
  gi__free(L->em);
  L->em = NULL;
  L->num_emitters = 0;
}

int gi__ref_delta_light(const ref_lights *L, const gi_light *l, const float x[3], float w[3], float *dist, float E[3]) {
  if (!ref_light_on(L, l->type == GI_LIGHT_SUN ? GI_FX_SUN : GI_FX_LOCAL)) return 0;
  if (l->type == GI_LIGHT_SUN) {
    for (int k = 0; k < 3; k++) w[k] = -l->direction[k], E[k] = l->color[k];
    *dist = INFINITY;
    return 1;
  }
  if (l->type != GI_LIGHT_POINT && l->type != GI_LIGHT_SPOT) return 0;
  const gi_scene *s = L->s;
  double d[3], r2 = 0;
  for (int k = 0; k < 3; k++) d[k] = (l->position[k] - s->origin[k]) - x[k], r2 += d[k] * d[k];
  if (!(r2 > MIN_LIGHT_DIST2)) return 0;
  double r = sqrt(r2);
  for (int k = 0; k < 3; k++) w[k] = (float)(d[k] / r);
  double f = 1;
  if (l->type == GI_LIGHT_SPOT) {
    /* Cosine between the spot's axis and the way from the light to x. */
    double c = -(w[0] * (double)l->direction[0] + w[1] * (double)l->direction[1] + w[2] * (double)l->direction[2]);
    if (c <= l->cos_outer) return 0;
    if (c < l->cos_inner) {
      double u = (c - l->cos_outer) / (l->cos_inner - l->cos_outer);
      f = u * u * (3 - 2 * u);
    }
  }
  for (int k = 0; k < 3; k++) E[k] = (float)(f * l->color[k] / r2);
  *dist = (float)r;
  return 1;
}

/* Index of the first table entry whose cdf exceeds u. */
static uint32_t power_pick(const ref_lights *L, double u) {
  uint32_t lo = 0, hi = L->num_emitters - 1;
  while (lo < hi) {
    uint32_t mid = lo + (hi - lo) / 2;
    if (L->em[mid].cdf > u) hi = mid;
    else lo = mid + 1;
  }
  return lo;
}

uint32_t gi__ref_emitter_pick(const ref_lights *L, const float x[3], double u, double *prob) {
  if (!L->by_tree) {
    uint32_t q = power_pick(L, u);
    *prob = L->em[q].pick;
    return q;
  }
  float pr, u_rest;
  uint32_t q = gi__light_tree_pick(L->s, x, u, &pr, &u_rest);
  *prob = pr;
  return q;
}

double gi__ref_emitter_pick_prob(const ref_lights *L, const float x[3], uint32_t q) {
  return L->by_tree ? gi__light_tree_prob(L->s, x, q) : L->em[q].pick;
}

int gi__ref_emitter_sample(const ref_lights *L, const float x[3], ref_rng *r, float w[3], float *dist, float *pdf,
                       float Le[3]) {
  if (!L->num_emitters) return 0;
  const gi_scene *s = L->s;
  double prob;
  const ref_emitter *e = &L->em[gi__ref_emitter_pick(L, x, ref_u01d(r), &prob)];
  float u = ref_u01(r), v = ref_u01(r);
  if (u + v > 1) u = 1 - u, v = 1 - v; /* fold the square onto the triangle */
  const float *P[3];
  float ng[3], d[3];
  tri_corners(s, e->tri, P);
  tri_normal2(P, ng);
  for (int k = 0; k < 3; k++) d[k] = P[0][k] + u * (P[1][k] - P[0][k]) + v * (P[2][k] - P[0][k]) - x[k];
  float r2 = gi__dot(d, d), ln = gi__len(ng);
  if (!(r2 > 0) || !(ln > 0) || !(prob > 0) || !(e->area > 0)) return 0;
  float rr = sqrtf(r2);
  for (int k = 0; k < 3; k++) w[k] = d[k] / rr;
  float cos_e = gi__emitter_cos(s, e->tri, -gi__dot(ng, w) / ln);
  if (!(cos_e > 0)) return 0; /* the back of a one-sided emitter */
  *dist = rr;
  *pdf = (float)(prob / e->area) * r2 / cos_e;
  memcpy(Le, s->materials[s->tri_material[e->tri]].emission, sizeof(float[3]));
  return 1;
}

float gi__ref_emitter_pdf(const ref_lights *L, const float x[3], uint32_t tri, float t, float cos_e) {
  if (!L->num_emitters || !(cos_e > 0)) return 0;
  uint32_t lo = 0, hi = L->num_emitters;
  while (lo < hi) {
    uint32_t mid = lo + (hi - lo) / 2;
    if (L->em[mid].tri < tri) lo = mid + 1;
    else hi = mid;
  }
  if (lo >= L->num_emitters || L->em[lo].tri != tri || !(L->em[lo].area > 0)) return 0;
  return (float)(gi__ref_emitter_pick_prob(L, x, lo) / L->em[lo].area) * t * t / cos_e;
}

void gi__ref_batch_flush(ref_batch *b, const ref_lights *L, float E[3], float sh[9][3]) {
  gi__occluded(L->s, b->n, b->org, b->dir, b->tn, b->tf, b->vis);
  for (int i = 0; i < b->n; i++) {
    if (!b->vis[i]) continue;
    float f = 1;
    if (sh) {
      gi__ref_sh_add(sh, &b->dir[3 * i], b->V[i], 1.f);
      f = fmaxf(0.f, gi__dot(L->up, &b->dir[3 * i]));
    }
    for (int k = 0; k < 3; k++) E[k] += f * b->V[i][k];
  }
  b->n = 0;
}

void gi__ref_batch_add(ref_batch *b, const ref_lights *L, const float o[3], const float w[3], float tnear, float tfar,
                   const float V[3], float E[3], float sh[9][3]) {
  if (b->n == REF_BATCH) gi__ref_batch_flush(b, L, E, sh);
  int i = b->n++;
  memcpy(&b->org[3 * i], o, sizeof(float[3]));
  memcpy(&b->dir[3 * i], w, sizeof(float[3]));
  memcpy(b->V[i], V, sizeof(float[3]));
  b->tn[i] = tnear, b->tf[i] = tfar;
}

/* Queues the shadow ray from o (x lifted off its surface) to the light
 * point x + dist w: aimed from o at that point and stopped short of it.
 * Aimed along w from o instead, it would pass the light's plane by up to
 * the lift (1 cm in a 600 m city) and hit the emitter it aims at, losing
 * every nearby emitter's light sample. */
static void shadow_to(ref_batch *b, const ref_lights *L, const float o[3], const float x[3], const float w[3],
                      float dist, const float V[3], float E[3]) {
  if (isinf(dist)) {
    gi__ref_batch_add(b, L, o, w, 0, INFINITY, V, E, NULL);
    return;
  }
  float d[3];
  for (int k = 0; k < 3; k++) d[k] = x[k] + dist * w[k] - o[k];
  float l = gi__len(d);
  if (!(l > 0)) return;
  for (int k = 0; k < 3; k++) d[k] /= l;
  gi__ref_batch_add(b, L, o, d, 0, l * REF_SHADOW_SHORTEN, V, E, NULL);
}

/* A light's light-tracing weight lum(I) / d^2 stops growing closer to
 * the point than this fraction of the scene's extent. */
#define LT_NEAR_FRACTION 1e-3f

double gi__ref_lt_weight(const ref_lights *L, const gi_light *l, const float p[3]) {
  if ((l->type != GI_LIGHT_POINT && l->type != GI_LIGHT_SPOT) || !ref_light_on(L, GI_FX_LOCAL)) return 0;
  double d2 = 0, lum = 0.2126 * l->color[0] + 0.7152 * l->color[1] + 0.0722 * l->color[2];
  for (int k = 0; k < 3; k++) {
    double v = (l->position[k] - L->s->origin[k]) - p[k];
    d2 += v * v;
  }
  double near = LT_NEAR_FRACTION * L->extent;
  return lum > 0 ? lum / fmax(d2, near * near) : 0;
}

double gi__ref_lt_total(const ref_lights *L, const float p[3]) {
  double t = 0;
  for (uint32_t i = 0; i < L->s->num_lights; i++) t += gi__ref_lt_weight(L, &L->s->lights[i], p);
  return t;
}

double gi__ref_lt_pdf(const ref_lights *L, const ref_lt *lt, const gi_light *l, float c, float dist) {
  if (!(lt->total > 0)) return 0;
  double pick = gi__ref_lt_weight(L, l, lt->p) / lt->total;
  return pick * c / (4 * GI_PI * (double)dist * dist);
}

/* Balance-heuristic weight of a point or spot light's term at the first
 * vertex x (side n) of lt's probe path, against light tracing. */
static float lt_weight_at(const ref_lights *L, const ref_lt *lt, const gi_light *l, const float x[3],
                          const float n[3], float c, float dist) {
  double plt = gi__ref_lt_pdf(L, lt, l, c, dist);
  if (!(plt > 0)) return 1;
  float v[3];
  for (int k = 0; k < 3; k++) v[k] = lt->p[k] - x[k];
  double d2 = gi__dot(v, v), cy = fabs((double)gi__dot(n, v)) / sqrt(d2);
  double ppp = lt->pb * cy / d2; /* the path direction's pdf in area measure at x */
  return (float)(ppp / (ppp + plt));
}

void gi__ref_direct(const ref_lights *L, const float x[3], const float n[3], ref_rng *r, float E[3], const ref_lt *lt) {
  const gi_scene *s = L->s;
  float o[3], w[3], dist, V[3];
  ref_batch b;
  b.n = 0;
  for (int k = 0; k < 3; k++) o[k] = x[k] + L->eps * n[k];
  for (uint32_t i = 0; i < s->num_lights; i++) {
    if (!gi__ref_delta_light(L, &s->lights[i], x, w, &dist, V)) continue;
    float c = gi__dot(n, w);
    if (!(c > 0)) continue;
    float f = lt && !isinf(dist) ? lt_weight_at(L, lt, &s->lights[i], x, n, c, dist) : 1.f;
    for (int k = 0; k < 3; k++) V[k] *= c * f;
    shadow_to(&b, L, o, x, w, dist, V, E);
  }
  float pdf, Le[3];
  if (gi__ref_emitter_sample(L, x, r, w, &dist, &pdf, Le)) {
    float c = gi__dot(n, w);
    /* Balance heuristic: Le c / pdf * pdf / (pdf + c / pi). */
    for (int k = 0; k < 3; k++) V[k] = Le[k] * c / (pdf + c / (float)GI_PI);
    if (c > 0) shadow_to(&b, L, o, x, w, dist, V, E);
  }
  gi__ref_batch_flush(&b, L, E, NULL);
}
