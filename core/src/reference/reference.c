/* reference.c: the Monte Carlo path tracer the cone tracer is measured against.
 *
 * INDEPENDENCE. The reference shares no sampling code with what it judges:
 * its own next-event estimation and emitter table (ref_lights.c), camera
 * (ref_camera.c), frames, random streams (PCG32) and SH projection
 * (ref_sampling.c). It reads the scene's data and asks the BVH
 * (gi__intersect1, gi__occluded) and, to pick emitters by distance, the
 * scene's light tree (gi__light_tree_pick / _prob: only probabilities,
 * checked by test_reference; see ref_lights.c). A sampling bug in the
 * bake's light sampler therefore cannot cancel out of the comparison.
 *
 * DESIGN. Per probe sample: (1) next-event estimation at the probe: every
 * sun, point and spot light exactly, one area sample of the emitters
 * (picked by power, distance and orientation from the probe, or by power
 * alone: opts.emitter_pick), shadow rays through Embree; (2) one path
 * direction from a mixture of a cosine lobe around up and a uniform sphere
 * (pdf p(w) = cos+/(2 pi) + 1/(8 pi)): the lobe keeps the up-facing
 * irradiance low-noise, the sphere keeps the SH projection's weight
 * bounded (Y/p <= 8 pi Y). Where the path meets an emitter's front the
 * emission is direct light, MIS-weighted (balance heuristic) against the
 * area sample; where it escapes above the horizon it sees the sky (direct
 * light too; the sky has no light sample).
 * What the first hit reflects toward the probe (both lobes) is the
 * indirect part. (3) Light tracing from point and spot lights (ref_lt):
 * a light picked by lum(I) / d^2 from the probe shoots a uniform
 * direction, and the surface it meets reflects toward the probe; it and
 * the path's first vertex share that light's once-reflected term by the
 * balance heuristic. Every diffuse path vertex does the same toward
 * itself, against its cosine sample. A street lamp's point light 10 cm
 * under its head makes a spot 10^4 times brighter than the street that
 * paths from a probe meet rarely (the city's indirect light at 4096 paths:
 * 16.7% relative standard error without it, 3.7% with it).
 *
 * Surfaces are two-sided (the voxel texture reflects on both sides too):
 * at each hit the normal is turned toward the arriving ray. The BRDF is
 * albedo/pi plus, on glossy materials only (roughness < 0.5 and
 * specular > 0, the cone tracer's rule), a glossy lobe: the physical
 * counterpart of the renderer's `specular * L_cone`. Its reflected
 * radiance is specular * E_p[L_in(w)] with p the normalised Phong lobe
 * (ns+1)/(2 pi) cos^ns(angle(w, r)) around the mirror direction r, of the
 * exponent the cone's aperture is derived from (a = roughness^2,
 * ns = 2/a^2 - 2; a perfect mirror for a < 1e-4); directions below the
 * surface give 0, so the lobe reflects at most `specular`.
 *
 * Diffuse part: sun, point, spot and one emitter sample (MIS against the
 * cosine sample), and the cosine sample itself: an emitter's front it
 * meets (MIS-weighted), the sky when it escapes above the horizon (in
 * full), and the path goes on along it with throughput times albedo.
 * Glossy part: one exact sample of p, no light sample; what it meets
 * counts in full with no MIS weight (an emitter's front, or the sky when
 * it escapes above the horizon), since no light sample ever draws from
 * this lobe: nothing is counted twice. Delta lights (sun, point, spot) are
 * never met by a lobe sample, just as the cone, which sees only voxel
 * radiance, never sees them. (The cone sees the sky through what it leaves
 * unoccluded, but not emitters, which the voxel texture does not hold. The
 * reference keeps the physics; a comparison of the specular parts must
 * keep emitters out of the reflection.)
 * At the path's first vertex both lobes are followed (the path splits);
 * deeper, one lobe goes on, picked with probability spec / (spec + max
 * albedo) and divided by it. Russian roulette from rr_depth on keeps
 * unbounded depth unbiased.
 *
 * Samples run in chunks of CHUNK per probe; each chunk has its own stream
 * and sums, reduced in chunk order, so results do not depend on threads. */
#include <stdlib.h>
#include <string.h>
#include "gi/gi_reference.h"
#include "gi/gi_render.h"
#include "reference/ref_internal.h"

#define CHUNK 64
#define MAX_DEPTH_HARD 256 /* unbounded paths stop here; a^256 is nothing for any a < 0.97 */
/* Russian roulette keeps a path with at most this probability. */
#define RR_MAX_KEEP 0.95f
/* Stream keys: probes and pixels draw from disjoint families of streams. */
#define KEY_PROBE 0x70726f6265ULL
#define KEY_PIXEL 0x706978656cULL

typedef struct {
  double sum[3][3], sq[3][3]; /* [direct, indirect, total][rgb] */
  double sh[9][3];
} chunk_acc;

typedef struct {
  const gi_scene *s;
  const double *pts;
  gi_reference_opts o;
  int chunks;                 /* per probe */
  ref_lights L;               /* up axis, sky, offsets and the emitter table */
  chunk_acc *acc;             /* n * chunks */
} ref_ctx;

/* Where a sampled direction leads: the ray's origin and direction and,
 * when it hits, distance, triangle and winding normal. */
typedef struct {
  float o[3], w[3], t, ng[3];
  uint32_t tri;
  int hit;
} seg;

/* Emitted radiance seen along w from x at a hit, MIS-weighted against one
 * emitter area sample from x (pb = the direction's own pdf; the light
 * strategy's pdf is the pick probability for x, as the sample's was).
 * 0 when not an emitter's front. */
static int emitted(const ref_lights *L, const float x[3], uint32_t tri, const float ng[3], const float w[3],
                   float t, float pb, float out[3]) {
  const float *Le = L->s->materials[L->s->tri_material[tri]].emission;
  float cos_e = gi__emitter_cos(L->s, tri, -gi__dot(ng, w));
  if (!ref_light_on(L, GI_FX_EMISSIVE) || !(Le[0] > 0 || Le[1] > 0 || Le[2] > 0) || !(cos_e > 0)) return 0;
  float f = pb / (pb + gi__ref_emitter_pdf(L, x, tri, t, cos_e));
  for (int k = 0; k < 3; k++) out[k] = f * Le[k];
  return 1;
}

/* Emitted radiance seen along w at a hit, without MIS weight (the glossy
 * lobe's sample, which light sampling never competes with). 0 when not an
 * emitter's front. */
static int emitted_full(const ref_lights *L, uint32_t tri, const float ng[3], const float w[3], float out[3]) {
  const float *Le = L->s->materials[L->s->tri_material[tri]].emission;
  if (!ref_light_on(L, GI_FX_EMISSIVE) || !(Le[0] > 0 || Le[1] > 0 || Le[2] > 0) || !(gi__emitter_cos(L->s, tri, -gi__dot(ng, w)) > 0))
    return 0;
  memcpy(out, Le, sizeof(float[3]));
  return 1;
}

/* Samples w from p(w) = (ns+1)/(2 pi) cos^ns(angle(w, r)), exactly. */
static void phong_dir(const float r[3], double ns, ref_rng *rng, float w[3]) {
  if (isinf(ns)) {
    memcpy(w, r, sizeof(float[3]));
    return;
  }
  float t[3], b[3];
  gi__ref_frame(r, t, b);
  /* Inverting the cdf 1 - cos^(ns+1); 1 - u in (0, 1]: no 0^0. */
  double ct = pow(1.0 - (double)ref_u01(rng), 1.0 / (ns + 1.0));
  float st = (float)sqrt(fmax(0.0, 1 - ct * ct)), phi = 2 * (float)GI_PI * ref_u01(rng);
  for (int k = 0; k < 3; k++) w[k] = st * cosf(phi) * t[k] + st * sinf(phi) * b[k] + (float)ct * r[k];
}

/* One sample of the light tracing strategy (ref_lt) toward x, a probe
 * (n NULL) or a surface point of side n: a point or spot light picked by
 * lum(I) / d^2 from x, a uniform direction from it, and the surface point
 * y it meets. Gives the unit direction wd from x toward y, the radiance Lr
 * y's diffuse lobe sends back along it, g = cos_y / |y - x|^2 and y's area
 * pdf plt; 0 when nothing comes (the ray escapes, x is behind y's lit
 * side or below n, or something is in between). */
static int lt_sample(const ref_ctx *rc, const float x[3], const float *n, const ref_lt *lt, ref_rng *rng,
                     float wd[3], float Lr[3], float *g, double *plt) {
  const ref_lights *L = &rc->L;
  const gi_scene *s = rc->s;
  double u = ref_u01d(rng) * lt->total, acc = 0;
  const gi_light *l = NULL;
  for (uint32_t i = 0; i < s->num_lights; i++) {
    double wl = gi__ref_lt_weight(L, &s->lights[i], x);
    if (!(wl > 0)) continue;
    l = &s->lights[i]; /* the last one with weight, should rounding leave u past the sum */
    if (u < (acc += wl)) break;
  }
  float lp[3], om[3], t, ng[3], y[3], wl[3], dist, E[3], v[3];
  uint32_t tri;
  if (!l) return 0;
  for (int k = 0; k < 3; k++) lp[k] = (float)(l->position[k] - s->origin[k]);
  gi__ref_sphere(rng, om);
  if (!gi__intersect1(s, lp, om, 0, INFINITY, &t, &tri, ng)) return 0;
  float ln = gi__len(ng), sg = gi__dot(ng, om) > 0 ? -1.f : 1.f;
  for (int k = 0; k < 3; k++) y[k] = lp[k] + t * om[k], ng[k] *= sg / ln; /* ng faces the light */
  for (int k = 0; k < 3; k++) v[k] = x[k] - y[k];
  float d = gi__len(v), cy = d > 0 ? gi__dot(ng, v) / d : 0.f;
  if (!(cy > 0) || !gi__ref_delta_light(L, l, y, wl, &dist, E)) return 0;
  for (int k = 0; k < 3; k++) wd[k] = -v[k] / d;
  float c = gi__dot(ng, wl);
  *plt = gi__ref_lt_pdf(L, lt, l, c, dist);
  if (!(c > 0) || !(*plt > 0) || (n && !(gi__dot(n, wd) > 0))) return 0;
  /* From a surface the ray starts lifted off it and aims at y (as gi__ref_direct's). */
  float o[3], dir[3], tn = n ? 0.f : L->eps, tf;
  for (int k = 0; k < 3; k++) o[k] = n ? x[k] + L->eps * n[k] : x[k], dir[k] = y[k] - o[k];
  float dl = gi__len(dir);
  if (!(dl > 0)) return 0;
  for (int k = 0; k < 3; k++) dir[k] /= dl;
  tf = dl * REF_SHADOW_SHORTEN;
  uint8_t vis = 0;
  gi__occluded(s, 1, o, dir, &tn, &tf, &vis);
  if (!vis) return 0;
  const float *a = gi__tri_albedo(s, tri);
  for (int k = 0; k < 3; k++) Lr[k] = a[k] / (float)GI_PI * E[k] * c;
  *g = cy / (d * d);
  return 1;
}

/* Light tracing toward a surface point x (side n): adds its balance-
 * weighted share of irradiance to E; the cosine sample is the other
 * strategy (area pdf cos_x / pi * g). */
static void surface_lt(const ref_ctx *rc, const float x[3], const float n[3], const ref_lt *lt, ref_rng *rng,
                       float E[3]) {
  float wd[3], Lr[3], g;
  double plt;
  if (!(lt->total > 0) || !lt_sample(rc, x, n, lt, rng, wd, Lr, &g, &plt)) return;
  float cx = gi__dot(n, wd);
  double f = cx * g / (plt + cx / GI_PI * g);
  for (int k = 0; k < 3; k++) E[k] += (float)(Lr[k] * f);
}

/* The diffuse lobe at x (side n): direct irradiance into E (lights, and
 * what the cosine sample d meets: an emitter's front, MIS-weighted, or the
 * sky above the horizon), and d itself, for the path to go on. At the
 * last vertex the sample is traced only when it can meet light. lt_in:
 * x was reached by the diffuse (or probe) sample of that point, whose
 * light tracing competes with x's point and spot terms; lt_here: light
 * tracing toward x itself (total 0 at the last vertex: that light is
 * reflected once more). */
static void diffuse_vertex(const ref_ctx *rc, const float x[3], const float n[3], int last, const ref_lt *lt_in,
                           const ref_lt *lt_here, ref_rng *rng, float E[3], seg *d) {
  const ref_lights *L = &rc->L;
  gi__ref_direct(L, x, n, rng, E, lt_in);
  surface_lt(rc, x, n, lt_here, rng, E);
  gi__ref_cosine(n, rng, d->w);
  for (int k = 0; k < 3; k++) d->o[k] = x[k] + L->eps * n[k];
  d->hit = 0;
  float cn = gi__dot(n, d->w);
  if (!(cn > 0) || (last && !L->num_emitters && !L->has_sky)) return;
  if (gi__intersect1(rc->s, d->o, d->w, 0, INFINITY, &d->t, &d->tri, d->ng)) {
    d->hit = 1;
    /* The light strategy's pdf is for the point as seen from x, not from
     * the lifted origin: the distance from x. */
    float y[3], Le[3];
    for (int k = 0; k < 3; k++) y[k] = d->o[k] + d->t * d->w[k] - x[k];
    if (emitted(L, x, d->tri, d->ng, d->w, gi__len(y), cn / (float)GI_PI, Le))
      for (int k = 0; k < 3; k++) E[k] += (float)GI_PI * Le[k]; /* Le cos / (cos / pi), times the MIS weight */
  } else if (L->has_sky && gi__dot(L->up, d->w) > 0) {
    for (int k = 0; k < 3; k++) E[k] += (float)GI_PI * L->sky[k];
  }
}

/* The glossy lobe at a surface (side n) hit along w: one sample g of the
 * lobe from o; Lg = what it meets (an emitter's front or the sky above the
 * horizon), in full. 0 when the sample points below the surface. */
static int glossy_vertex(const ref_ctx *rc, const float w[3], const float n[3], const float o[3], double ns,
                         ref_rng *rng, float Lg[3], seg *g) {
  float r[3], dn = gi__dot(w, n);
  for (int k = 0; k < 3; k++) r[k] = w[k] - 2 * dn * n[k];
  float lr = gi__len(r);
  for (int k = 0; k < 3; k++) r[k] /= lr, g->o[k] = o[k];
  phong_dir(r, ns, rng, g->w);
  g->hit = 0;
  if (!(gi__dot(n, g->w) > 0)) return 0;
  if (gi__intersect1(rc->s, g->o, g->w, 0, INFINITY, &g->t, &g->tri, g->ng)) {
    g->hit = 1;
    emitted_full(&rc->L, g->tri, g->ng, g->w, Lg);
  } else if (gi__dot(rc->L.up, g->w) > 0) {
    memcpy(Lg, rc->L.sky, sizeof(float[3]));
  }
  return 1;
}

/* What the glossy lobe (exponent ns, finite; mirror direction of w about
 * n) at x reflects of the sun, point and spot lights, without `specular`:
 * sum over the lights seen of E p(w_l) (p the lobe's density). A lobe
 * sample never meets a light of no area, so a glossy floor showed no
 * highlight of a lamp. Taken at a path's first vertex only (what the
 * camera or probe sees, directly or along a lobe): deeper, a diffuse
 * direction rarely lands in a sharp lobe and each that does carries the
 * lamp's whole peak, so the light a glossy floor throws on the walls (a
 * caustic) stays out, as the voxels, which hold a lobe as diffuse light,
 * leave it out too. */
static void glossy_delta(const ref_ctx *rc, const float x[3], const float w[3], const float n[3], double ns,
                         float Ld[3]) {
  const gi_scene *s = rc->s;
  float r[3], dn = gi__dot(w, n), o[3];
  for (int k = 0; k < 3; k++) r[k] = w[k] - 2 * dn * n[k], o[k] = x[k] + rc->L.eps * n[k];
  float lr = gi__len(r);
  for (int k = 0; k < 3; k++) r[k] /= lr;
  for (uint32_t i = 0; i < s->num_lights; i++) {
    float wl[3], dist, E[3];
    if (!gi__ref_delta_light(&rc->L, &s->lights[i], x, wl, &dist, E) || !(gi__dot(n, wl) > 0)) continue;
    float p = gi__phong_lobe(ns, gi__dot(r, wl));
    if (!(p > 0)) continue;
    float tn = 0, tf = isinf(dist) ? INFINITY : dist * REF_SHADOW_SHORTEN;
    uint8_t vis = 0;
    gi__occluded(s, 1, o, wl, &tn, &tf, &vis);
    if (vis)
      for (int k = 0; k < 3; k++) Ld[k] += E[k] * p;
  }
}

/* Radiance reflected toward the ray's origin by the surface hit at
 * x (ray direction w, triangle tri, winding normal ng), times T0: the
 * indirect part of one path, whose first vertex here is reflection number
 * depth0. With split0, at that first vertex the glossy lobe and the
 * diffuse lobe are both followed (the glossy one as a path that splits no
 * further, so a room of glossy walls cannot branch without bound); Ls (may
 * be NULL) receives the glossy lobe's share of L there, i.e. specular *
 * (radiance along the lobe sample). Deeper vertices pick one lobe at random. */
static void reflected_from(const ref_ctx *rc, float x[3], float w[3], uint32_t tri, float ng[3], const float T0[3],
                           int depth0, int split0, const ref_lt *lt, ref_rng *rng, float L[3], float Ls[3]) {
  const gi_scene *s = rc->s;
  float T[3] = {T0[0], T0[1], T0[2]};
  int maxd = rc->o.max_depth > 0 ? rc->o.max_depth : MAX_DEPTH_HARD;
  /* Light tracing toward this vertex (here) and toward the one the path
   * came from by its diffuse sample (prev, when it did). */
  float hx[3], px[3];
  ref_lt here = {.p = hx}, prev = {.p = px};
  for (int depth = depth0;; depth++) {
    const gi_material *mat = &s->materials[s->tri_material[tri]];
    const float *a = gi__tri_albedo(s, tri);
    float n[3], sg = gi__dot(ng, w) > 0 ? -1.f : 1.f;
    for (int k = 0; k < 3; k++) n[k] = sg * ng[k];
    int last = depth >= maxd;
    float E[3] = {0, 0, 0};
    seg d, g = {.hit = 0};
    memcpy(hx, x, sizeof hx);
    here.total = last || rc->o.no_light_tracing ? 0 : gi__ref_lt_total(&rc->L, x);
    diffuse_vertex(rc, x, n, last, lt, &here, rng, E, &d);
    for (int k = 0; k < 3; k++) L[k] += T[k] * a[k] * (1.f / (float)GI_PI) * E[k];
    int dcont = !last && d.hit;
    double ns = gi__gloss_exponent(mat);
    int gcont = 0, split = split0 && depth == depth0;
    /* The lobe per channel (a gold metal's colour); spec, its brightest, picks the lobe. */
    float spec = mat->specular, sr[3], Lg[3] = {0, 0, 0}, Ld[3] = {0, 0, 0};
    gi__gloss_rgb(mat, sr);
    if (depth == depth0 && ns > 0 && !isinf(ns)) {
      glossy_delta(rc, x, w, n, ns, Ld);
      for (int k = 0; k < 3; k++) {
        float v = T[k] * sr[k] * Ld[k];
        L[k] += v;
        if (split && Ls) Ls[k] += v;
      }
    }
    if (ns > 0 && glossy_vertex(rc, w, n, d.o, ns, rng, Lg, &g)) {
      gcont = !last && g.hit;
      for (int k = 0; k < 3; k++) {
        float v = T[k] * sr[k] * Lg[k];
        L[k] += v;
        if (split && Ls) Ls[k] += v;
      }
    }
    if (split && gcont) {
      /* Follow the glossy lobe as its own path; the diffuse one goes on below. */
      float xg[3], Tg[3], Lr[3] = {0, 0, 0};
      for (int k = 0; k < 3; k++) xg[k] = g.o[k] + g.t * g.w[k], Tg[k] = T[k] * sr[k];
      reflected_from(rc, xg, g.w, g.tri, g.ng, Tg, depth + 1, 0, NULL, rng, Lr, NULL); /* splits no further */
      for (int k = 0; k < 3; k++) {
        L[k] += Lr[k];
        if (Ls) Ls[k] += Lr[k];
      }
      gcont = 0;
    }
    if (!dcont && !gcont) break;
    /* One lobe goes on, picked in proportion to its reflectance; dividing
     * by the pick's probability keeps the sum of both unbiased. */
    float amax = fmaxf(a[0], fmaxf(a[1], a[2]));
    float pg = !gcont ? 0.f : !dcont ? 1.f : spec / (spec + amax);
    const seg *next = pg > 0 && (pg >= 1 || ref_u01(rng) < pg) ? &g : &d;
    lt = NULL;
    if (next == &d && here.total > 0) {
      memcpy(px, hx, sizeof px);
      prev.total = here.total, prev.pb = gi__dot(n, d.w) / (float)GI_PI;
      lt = &prev;
    }
    for (int k = 0; k < 3; k++) T[k] *= next == &g ? sr[k] / pg : a[k] / (1.f - pg);
    for (int k = 0; k < 3; k++) x[k] = next->o[k] + next->t * next->w[k], w[k] = next->w[k], ng[k] = next->ng[k];
    tri = next->tri;
    if (depth >= rc->o.rr_depth) {
      float q = fminf(RR_MAX_KEEP, fmaxf(T[0], fmaxf(T[1], T[2])));
      if (!(q > 0) || ref_u01(rng) >= q) break;
      for (int k = 0; k < 3; k++) T[k] /= q;
    }
  }
}

static void reflected(const ref_ctx *rc, float x[3], float w[3], uint32_t tri, float ng[3], const ref_lt *lt,
                      ref_rng *rng, float L[3], float Ls[3]) {
  static const float one[3] = {1, 1, 1};
  reflected_from(rc, x, w, tri, ng, one, 1, 1, lt, rng, L, Ls);
}

/* Pdf of the probe's path direction: the cosine lobe about up and the
 * uniform sphere, half and half. */
static float mixture_pdf(float cu) { return fmaxf(cu, 0.f) / (2 * (float)GI_PI) + 1.f / (8 * (float)GI_PI); }

/* Next-event estimation at the probe over the whole sphere: into the
 * direct SH, and into Ed for the up-facing surface. */
static void probe_direct(const ref_ctx *rc, const float p[3], ref_rng *rng, float sh[9][3], float Ed[3]) {
  const ref_lights *L = &rc->L;
  const gi_scene *s = rc->s;
  float w[3], dist, V[3];
  ref_batch b;
  b.n = 0;
  for (uint32_t i = 0; i < s->num_lights; i++)
    if (gi__ref_delta_light(L, &s->lights[i], p, w, &dist, V))
      gi__ref_batch_add(&b, L, p, w, L->eps, isinf(dist) ? INFINITY : dist * REF_SHADOW_SHORTEN, V, Ed, sh);
  float pl, Le[3];
  if (gi__ref_emitter_sample(L, p, rng, w, &dist, &pl, Le)) {
    /* Balance heuristic against the path direction: Le / pl * pl / (pl + pb). */
    float f = 1.f / (pl + mixture_pdf(gi__dot(L->up, w)));
    for (int k = 0; k < 3; k++) V[k] = Le[k] * f;
    gi__ref_batch_add(&b, L, p, w, L->eps, dist * REF_SHADOW_SHORTEN, V, Ed, sh);
  }
  gi__ref_batch_flush(&b, L, Ed, sh);
}

/* One path from the probe along a direction of the mixture: emitters and
 * the sky it meets are direct light, what its first hit reflects indirect. */
static void probe_path(const ref_ctx *rc, const float p[3], double lt_total, ref_rng *rng, float shd[9][3],
                       float shi[9][3], float Ed[3], float Ei[3]) {
  const ref_lights *L = &rc->L;
  float w[3];
  if (ref_u01(rng) < 0.5f) gi__ref_cosine(L->up, rng, w);
  else gi__ref_sphere(rng, w);
  float cu = gi__dot(L->up, w), pb = mixture_pdf(cu);
  float t, ng[3];
  uint32_t tri;
  if (!gi__intersect1(rc->s, p, w, L->eps, INFINITY, &t, &tri, ng)) {
    if (!L->has_sky || !(cu > 0)) return;
    gi__ref_sh_add(shd, w, L->sky, 1.f / pb);
    for (int k = 0; k < 3; k++) Ed[k] += L->sky[k] * cu / pb;
    return;
  }
  float Le[3], Lr[3] = {0, 0, 0};
  if (emitted(L, p, tri, ng, w, t, pb, Le)) {
    gi__ref_sh_add(shd, w, Le, 1.f / pb);
    if (cu > 0)
      for (int k = 0; k < 3; k++) Ed[k] += Le[k] * cu / pb;
  }
  if (rc->o.max_depth < 0) return;
  float x[3] = {p[0] + t * w[0], p[1] + t * w[1], p[2] + t * w[2]};
  float wc[3] = {w[0], w[1], w[2]};
  ref_lt lt = {.p = p, .pb = pb, .total = lt_total};
  reflected(rc, x, wc, tri, ng, &lt, rng, Lr, NULL);
  gi__ref_sh_add(shi, w, Lr, 1.f / pb);
  if (cu > 0)
    for (int k = 0; k < 3; k++) Ei[k] += Lr[k] * cu / pb;
}

/* Light tracing toward the probe (ref_lt): indirect light, the probe
 * path's mixture direction being the other strategy (area pdf pb g). */
static void probe_lt(const ref_ctx *rc, const float p[3], double total, ref_rng *rng, float shi[9][3],
                     float Ei[3]) {
  ref_lt lt = {.p = p, .total = total};
  float wd[3], Lr[3], g;
  double plt;
  if (!(total > 0) || rc->o.max_depth < 0 || !lt_sample(rc, p, NULL, &lt, rng, wd, Lr, &g, &plt)) return;
  float cu = gi__dot(rc->L.up, wd), f = (float)(g / (plt + mixture_pdf(cu) * g));
  gi__ref_sh_add(shi, wd, Lr, f);
  if (cu > 0)
    for (int k = 0; k < 3; k++) Ei[k] += Lr[k] * f * cu;
}

static void ref_range(void *p, size_t b, size_t e, int worker) {
  ref_ctx *rc = p;
  const gi_scene *s = rc->s;
  for (size_t task = b; task < e; task++) {
    size_t pi = task / (size_t)rc->chunks, ci = task % (size_t)rc->chunks;
    chunk_acc *A = &rc->acc[task];
    float pt[3];
    /* The stream depends on the seed, the probe's position and the chunk only. */
    uint64_t key = gi__ref_hash(rc->o.seed, KEY_PROBE);
    for (int k = 0; k < 3; k++) {
      pt[k] = (float)(rc->pts[3 * pi + k] - s->origin[k]);
      uint32_t bits;
      memcpy(&bits, &pt[k], 4);
      key = gi__ref_hash(key, bits);
    }
    ref_rng rng;
    gi__ref_rng_seed(&rng, gi__ref_hash(key, ci));
    double lt_total = rc->o.no_light_tracing ? 0 : gi__ref_lt_total(&rc->L, pt);
    int first = (int)ci * CHUNK, count = rc->o.samples - first < CHUNK ? rc->o.samples - first : CHUNK;
    for (int j = 0; j < count; j++) {
      float Ed[3] = {0, 0, 0}, Ei[3] = {0, 0, 0};
      float shd[9][3] = {{0}}, shi[9][3] = {{0}};
      probe_direct(rc, pt, &rng, shd, Ed);
      probe_path(rc, pt, lt_total, &rng, shd, shi, Ed, Ei);
      probe_lt(rc, pt, lt_total, &rng, shi, Ei);
      for (int k = 0; k < 3; k++) {
        double v[3] = {Ed[k], Ei[k], (double)Ed[k] + Ei[k]};
        for (int q = 0; q < 3; q++) A->sum[q][k] += v[q], A->sq[q][k] += v[q] * v[q];
      }
      for (int i = 0; i < 9; i++)
        for (int k = 0; k < 3; k++) A->sh[i][k] += (double)shd[i][k] + shi[i][k];
    }
  }
}

/* Reduces probe i's chunks, in chunk order, into o; 0 when not finite. */
static int finish_probe(const ref_ctx *rc, size_t i, gi_ref_probe *o) {
  chunk_acc T = {0};
  for (int c = 0; c < rc->chunks; c++) {
    const chunk_acc *A = &rc->acc[i * (size_t)rc->chunks + (size_t)c];
    for (int q = 0; q < 3; q++)
      for (int k = 0; k < 3; k++) T.sum[q][k] += A->sum[q][k], T.sq[q][k] += A->sq[q][k];
    for (int j = 0; j < 9; j++)
      for (int k = 0; k < 3; k++) T.sh[j][k] += A->sh[j][k];
  }
  memset(o, 0, sizeof *o);
  double N = rc->o.samples;
  o->samples = (uint32_t)rc->o.samples;
  float *mean[3] = {o->direct, o->indirect, o->irradiance};
  float *se[3] = {o->std_err_direct, o->std_err_indirect, o->std_err};
  for (int q = 0; q < 3; q++)
    for (int k = 0; k < 3; k++) {
      double m = T.sum[q][k] / N;
      double var = N > 1 ? fmax(0.0, (T.sq[q][k] - N * m * m) / (N - 1)) : 0.0;
      mean[q][k] = (float)m;
      se[q][k] = (float)sqrt(var / N);
    }
  float shr[9][3];
  for (int j = 0; j < 9; j++)
    for (int k = 0; k < 3; k++) shr[j][k] = (float)(T.sh[j][k] / N);
  gi__ref_sh_to_irradiance(shr);
  memcpy(o->sh, shr, sizeof shr);
  int ok = 1;
  for (int k = 0; k < 3; k++) ok &= isfinite(o->irradiance[k]) && isfinite(o->std_err[k]);
  for (int j = 0; j < 9; j++)
    for (int k = 0; k < 3; k++) ok &= isfinite(o->sh[j][k]);
  return ok;
}

gi_result gi_reference_irradiance(const gi_scene *s, const double *pts, size_t n, const gi_reference_opts *opts,
                                  gi_ref_probe *out, double *ms, gi_error_info *err) {
  if (!s || (n && (!pts || !out)))
    return gi__fail(err, GI_ERR_INVALID_ARG, "reference: %s is NULL", !s ? "scene" : !pts ? "pts" : "out");
  ref_ctx rc = {.s = s, .pts = pts};
  if (opts) rc.o = *opts;
  if (rc.o.samples == 0) rc.o.samples = 1024;
  if (rc.o.rr_depth == 0) rc.o.rr_depth = 3;
  if (rc.o.seed == 0) rc.o.seed = 1;
  if (rc.o.samples < 1 || rc.o.samples > (1 << 24))
    return gi__fail(err, GI_ERR_INVALID_ARG, "reference: samples must be 1..16777216, got %d", rc.o.samples);
  if (rc.o.max_depth < -1 || rc.o.max_depth > MAX_DEPTH_HARD)
    return gi__fail(err, GI_ERR_INVALID_ARG, "reference: max_depth must be -1..%d, got %d", MAX_DEPTH_HARD,
                    rc.o.max_depth);
  if (rc.o.rr_depth < 1)
    return gi__fail(err, GI_ERR_INVALID_ARG, "reference: rr_depth must be at least 1, got %d", rc.o.rr_depth);
  if (rc.o.no_light_tracing != 0 && rc.o.no_light_tracing != 1)
    return gi__fail(err, GI_ERR_INVALID_ARG, "reference: no_light_tracing must be 0 or 1, got %d",
                    rc.o.no_light_tracing);
  if (rc.o.lights & ~GI_REF_LIGHTS_ALL)
    return gi__fail(err, GI_ERR_INVALID_ARG,
                    "reference: lights must be a mask of 1 << GI_FX_SUN, _LOCAL, _SKY and _EMISSIVE (0 = all), got %#x",
                    (unsigned)rc.o.lights);
  if (rc.o.emitter_pick != GI_REF_PICK_TREE && rc.o.emitter_pick != GI_REF_PICK_POWER)
    return gi__fail(err, GI_ERR_INVALID_ARG, "reference: emitter_pick must be GI_REF_PICK_TREE or _POWER, got %d",
                    rc.o.emitter_pick);
  /* As a gather: past this no caller holds the arrays, and 3 * n and the
   * n x chunks tasks below would wrap. */
  if (n > SIZE_MAX / sizeof *out || n > SIZE_MAX / (size_t)((rc.o.samples + CHUNK - 1) / CHUNK))
    return gi__fail(err, GI_ERR_INVALID_ARG, "reference: n = %zu probes cannot fit in memory", n);
  for (size_t i = 0; i < 3 * n; i++) {
    if (!isfinite(pts[i]))
      return gi__fail(err, GI_ERR_NONFINITE, "reference: point %zu has a non-finite coordinate", i / 3);
    /* As the reference panorama's eye: a point at 1e39 failed after its
     * paths, blaming "scene values too large". */
    if (!(fabs(pts[i] - s->origin[i % 3]) <= REF_MAX_DIST))
      return gi__fail(err, GI_ERR_NONFINITE, "reference: point %zu is %g units from the scene on axis %c, past %g",
                      i / 3, fabs(pts[i] - s->origin[i % 3]), "xyz"[i % 3], REF_MAX_DIST);
  }
  double t0 = gi__now_ms();
  rc.chunks = (rc.o.samples + CHUNK - 1) / CHUNK;
  gi_result res = gi__ref_lights_init(&rc.L, s, rc.o.emitter_pick, rc.o.lights, err);
  if (res != GI_OK) return res;
  size_t tasks = n * (size_t)rc.chunks;
  rc.acc = gi__calloc(tasks ? tasks : 1, sizeof *rc.acc);
  if (!rc.acc) {
    gi__ref_lights_free(&rc.L);
    return gi__fail(err, GI_ERR_NOMEM, "reference: out of memory for %zu sample chunks", tasks);
  }
  gi__parallel_for(tasks, 1, rc.o.threads, ref_range, &rc);
  int ok = 1;
  for (size_t i = 0; i < n; i++) ok &= finish_probe(&rc, i, &out[i]);
  gi__free(rc.acc);
  gi__ref_lights_free(&rc.L);
  if (ms) *ms = gi__now_ms() - t0;
  if (!ok) return gi__fail(err, GI_ERR_NONFINITE, "reference: a probe came out non-finite (scene values too large?)");
  return GI_OK;
}

/* ---- the path-traced camera view ------------------------------------ */

typedef struct {
  ref_ctx rc;
  const ref_cam *k;
  int spp;
  float *rgb, *spec;
} view_ctx;

/* The camera's hit eye + t w, put back on its triangle's plane (unit
 * normal ng) in double: a camera 1e6 from the scene placed it up to 0.06
 * units off the surface, and the paths leaving it met the surface again
 * (the Cornell box's walls went black, 18494% error at 1e6). */
static void onto_plane(const gi_scene *s, uint32_t tri, const float ng[3], float p[3]) {
  const float *a = s->vertices + 3 * (size_t)s->indices[3 * (size_t)tri];
  double d = 0;
  for (int k = 0; k < 3; k++) d += ((double)p[k] - a[k]) * ng[k];
  for (int k = 0; k < 3; k++) p[k] = (float)((double)p[k] - d * ng[k]);
}

/* One pixel: spp paths through jittered points of its square. */
static void view_pixel(const view_ctx *vc, int x, int y) {
  const ref_ctx *rc = &vc->rc;
  const gi_scene *s = rc->s;
  const ref_cam *k = vc->k;
  ref_rng rng;
  gi__ref_rng_seed(&rng, gi__ref_hash(gi__ref_hash(gi__ref_hash(rc->o.seed, KEY_PIXEL), (uint64_t)y), (uint64_t)x));
  double acc[3] = {0, 0, 0}, accs[3] = {0, 0, 0};
  for (int j = 0; j < vc->spp; j++) {
    float w[3], t, ng[3], L[3] = {0, 0, 0}, Ls[3] = {0, 0, 0};
    uint32_t tri;
    float px = (float)x + ref_u01(&rng), py = (float)y + ref_u01(&rng);
    gi__ref_cam_dir(k, px, py, w);
    if (!gi__camera_hit(s, k->eye, w, &t, &tri, ng)) {
      /* The camera sees the sky itself, as the cone-traced view does. */
      for (int a = 0; a < 3; a++) acc[a] += rc->L.sky[a];
      continue;
    }
    if (gi__emitter_cos(s, tri, -gi__dot(ng, w)) > 0) /* an emitter seen from the front (or two-sided) */
      for (int a = 0; a < 3; a++) L[a] += s->materials[s->tri_material[tri]].emission[a];
    float p[3] = {k->eye[0] + t * w[0], k->eye[1] + t * w[1], k->eye[2] + t * w[2]};
    onto_plane(s, tri, ng, p);
    reflected(rc, p, w, tri, ng, NULL, &rng, L, Ls);
    for (int a = 0; a < 3; a++) acc[a] += L[a], accs[a] += Ls[a];
  }
  size_t i = 3 * (y * (size_t)k->w + (size_t)x);
  for (int a = 0; a < 3; a++) vc->rgb[i + a] = (float)(acc[a] / vc->spp);
  if (vc->spec)
    for (int a = 0; a < 3; a++) vc->spec[i + a] = (float)(accs[a] / vc->spp);
}

static void view_rows(void *p, size_t b, size_t e, int worker) {
  const view_ctx *vc = p;
  for (size_t y = b; y < e; y++)
    for (int x = 0; x < vc->k->w; x++) view_pixel(vc, x, (int)y);
}

/* Renders the prepared camera or panorama k with options o (spp checked). */
static gi_result render_view(const gi_scene *s, const ref_cam *k, const gi_render_opts *o, float *rgb, double *ms,
                             gi_error_info *err) {
  double t0 = gi__now_ms();
  view_ctx vc = {.k = k, .spp = o->spp, .rgb = rgb, .spec = o->specular};
  vc.rc.s = s;
  vc.rc.o.seed = o->seed ? o->seed : 1;
  vc.rc.o.rr_depth = 3;
  gi_result r = gi__ref_lights_init(&vc.rc.L, s, GI_REF_PICK_TREE, 0, err);
  if (r != GI_OK) return r;
  size_t np = (size_t)k->w * k->h * 3;
  memset(rgb, 0, np * sizeof(float));
  if (o->specular) memset(o->specular, 0, np * sizeof(float));
  gi__parallel_for((size_t)k->h, 1, o->threads, view_rows, &vc);
  gi__ref_lights_free(&vc.rc.L);
  if (ms) *ms = gi__now_ms() - t0;
  for (size_t i = 0; i < np; i++)
    if (!isfinite(rgb[i]) || (o->specular && !isfinite(o->specular[i])))
      return gi__fail(err, GI_ERR_NONFINITE, "reference render: pixel %zu is not finite", i / 3);
  return GI_OK;
}

/* Options with their defaults filled in; GI_OK when spp is in range. */
static gi_result view_opts(const gi_render_opts *opts, gi_render_opts *o, gi_error_info *err) {
  memset(o, 0, sizeof *o);
  if (opts) *o = *opts;
  if (o->spp == 0) o->spp = 16;
  if (o->spp < 1 || o->spp > (1 << 20))
    return gi__fail(err, GI_ERR_INVALID_ARG, "reference render: spp must be 1..1048576, got %d", o->spp);
  return GI_OK;
}

gi_result gi_reference_render_ex(const gi_scene *s, const gi_camera *cam, const gi_render_opts *opts, float *rgb,
                                 double *ms, gi_error_info *err) {
  gi_render_opts o;
  if (!s || !rgb) return gi__fail(err, GI_ERR_INVALID_ARG, "reference render: %s is NULL", !s ? "scene" : "rgb");
  gi_result r = view_opts(opts, &o, err);
  if (r != GI_OK) return r;
  ref_cam k;
  r = gi__ref_cam_init(&k, s, cam, err);
  if (r != GI_OK) return r;
  return render_view(s, &k, &o, rgb, ms, err);
}

gi_result gi_reference_panorama(const gi_scene *s, const double at[3], int w, int h, const gi_render_opts *opts,
                                float *rgb, double *ms, gi_error_info *err) {
  gi_render_opts o;
  if (!s || !rgb) return gi__fail(err, GI_ERR_INVALID_ARG, "reference panorama: %s is NULL", !s ? "scene" : "rgb");
  gi_result r = view_opts(opts, &o, err);
  if (r != GI_OK) return r;
  ref_cam k;
  r = gi__ref_pano_init(&k, s, at, w, h, err);
  if (r != GI_OK) return r;
  return render_view(s, &k, &o, rgb, ms, err);
}

gi_result gi_reference_render(const gi_scene *s, const gi_camera *cam, int spp, uint64_t seed, int threads,
                              float *rgb, double *ms, gi_error_info *err) {
  if (spp == 0) /* the _ex default would hide a caller's missing count */
    return gi__fail(err, GI_ERR_INVALID_ARG, "reference render: spp must be 1..1048576, got %d", spp);
  gi_render_opts o = {.spp = spp, .seed = seed, .threads = threads};
  return gi_reference_render_ex(s, cam, &o, rgb, ms, err);
}
