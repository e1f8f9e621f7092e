/* reference.c: the Monte Carlo path tracer the cone tracer is measured against.
 *
 * DESIGN. Per probe sample: (1) next-event estimation at the probe with the
 * bake's own light sampler (gi__light_samples: one sky and one emitter
 * sample per light per vertex, every sun/point/spot), shadow rays through
 * Embree; (2) one path direction from a mixture of a cosine lobe around
 * up and a uniform sphere (pdf p(w) = cos+/(2 pi) + 1/(8 pi)): the lobe
 * keeps the up-facing irradiance low-noise, the sphere keeps the SH
 * projection's weight bounded (Y/p <= 8 pi Y). Where the path meets an
 * emitter's front the emission is direct light, MIS-weighted (balance
 * heuristic) against the area samples, exactly as the gather does. What the
 * first hit reflects toward the probe (both lobes) is the indirect part.
 *
 * Surfaces are two-sided (the voxel texture reflects on both sides too):
 * at each hit the normal is turned toward the arriving ray. The BRDF is
 * albedo/pi plus, on glossy materials only (roughness < 0.5 and
 * specular > 0, the cone tracer's rule), a glossy lobe: the physical
 * counterpart of the renderer's `specular * L_cone`. Its reflected
 * radiance is specular * E_p[L_in(w)] with p the normalised Phong lobe
 * (ns+1)/(2 pi) cos^ns(angle(w, r)) around the mirror direction r, of the
 * exponent the cone's aperture is derived from (gi__specular_tan: a =
 * roughness^2, ns = 2/a^2 - 2; a perfect mirror for a < 1e-4); directions below
 * the surface give 0, so the lobe reflects at most `specular`.
 *
 * Diffuse part: NEE + MIS (emitters against the cosine sample), path on
 * along the cosine sample with throughput times albedo. Sky and delta
 * lights reach it by NEE only. Glossy part: one exact sample of p, no
 * NEE; what it meets counts in full with no MIS weight (an emitter's
 * front, or the sky when it escapes above the horizon), since no light
 * sample ever draws from this lobe: nothing is counted twice. Delta lights
 * (sun, point, spot) are never met by a lobe sample, just as the cone,
 * which sees only voxel radiance, never sees them. (The cone sees the sky
 * through what it leaves unoccluded, but not emitters, which the voxel
 * texture does not hold. The reference keeps the physics; a comparison of
 * the specular parts must keep emitters out of the reflection.)
 * At the path's first vertex both lobes are followed (the path splits);
 * deeper, one lobe goes on, picked with probability spec / (spec + max
 * albedo) and divided by it. Russian roulette from rr_depth on keeps
 * unbounded depth unbiased. A diffuse material draws exactly the random
 * numbers it drew before the lobe existed, so diffuse scenes give
 * bit-identical answers.
 *
 * Samples run in chunks of CHUNK per probe; each chunk has its own seed
 * and sums, reduced in chunk order, so results do not depend on threads. */
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>
#include "answer/answer.h"
#include "base/internal.h"
#include "gi/gi_reference.h"
#include "gi/gi_render.h"
#include "scene/lights.h"

#define CHUNK 64
#define MAX_DEPTH_HARD 256 /* unbounded paths stop here; a^256 is nothing for any a < 0.97 */

typedef struct {
  double sum[3][3], sq[3][3]; /* [direct, indirect, total][rgb] */
  double sh[9][3];
} chunk_acc;

typedef struct {
  const gi_scene *s;
  const double *pts;
  gi_reference_opts o;
  int chunks;                 /* per probe */
  float eps;
  float up[3];
  float sky[3];               /* radiance of every sky light, summed: what an escaping lobe sample sees above the horizon */
  chunk_acc *acc;             /* n * chunks */
  atomic_int failed;          /* a worker ran out of memory */
} ref_ctx;

/* Every light kind, one sky and one emitter sample per path vertex. */
static const gi_light_plan ref_lp = {1, 1, 1, 1, 1, 1};

/* Offsets, up axis and sky radiance shared by probes and the view. */
static void ctx_setup(ref_ctx *rc, const gi_scene *s) {
  float ext = 0;
  for (int a = 0; a < 3; a++) ext = fmaxf(ext, s->hi[a] - s->lo[a]);
  /* Offsets scale with the scene: float positions near ext carry ~1e-7 ext of error. */
  rc->eps = 2e-5f * ext + 1e-6f;
  rc->up[0] = 0, rc->up[1] = s->up == GI_UP_Z ? 0.f : 1.f, rc->up[2] = s->up == GI_UP_Z ? 1.f : 0.f;
  gi__sky_radiance(s, rc->sky);
}

static void cosine_dir(const float n[3], uint64_t *rng, float w[3]) {
  float t[3], b[3];
  gi__basis(n, t, b);
  float u1 = gi__u01(rng), u2 = gi__u01(rng);
  float r = sqrtf(u1), phi = 2 * GI_PI_F * u2, z = sqrtf(fmaxf(0.f, 1 - u1));
  for (int k = 0; k < 3; k++) w[k] = r * cosf(phi) * t[k] + r * sinf(phi) * b[k] + z * n[k];
}

/* Direct irradiance at x on the side n: NEE over every light, MIS-weighted
 * for emitters against a cosine sample (pdf cos/pi, one sample). */
static void nee(const ref_ctx *rc, const float x[3], const float n[3], uint64_t *rng, gi_ray_scratch *sc,
                float E[3]) {
  gi_lsample *ls = sc->ls;
  float *org = sc->org, *dir = sc->dir, *tn = sc->tn, *tf = sc->tf;
  uint8_t *vis = sc->vis;
  int cap = sc->cap;
  int m = gi__light_samples(rc->s, &ref_lp, x, rng, ls, cap), k = 0;
  for (int i = 0; i < m; i++) {
    float c = gi__dot(n, ls[i].w);
    if (!(c > 0)) continue;
    for (int a = 0; a < 3; a++) org[3 * k + a] = x[a] + rc->eps * n[a], dir[3 * k + a] = ls[i].w[a];
    tn[k] = 0;
    tf[k] = isinf(ls[i].dist) ? INFINITY : ls[i].dist * 0.999f;
    ls[k] = ls[i];
    ls[k].dist = c; /* keep the cosine */
    k++;
  }
  gi__occluded(rc->s, k, org, dir, tn, tf, vis);
  for (int i = 0; i < k; i++) {
    if (!vis[i]) continue;
    float c = ls[i].dist;
    float f = ls[i].mpl > 0 ? ls[i].mpl / (ls[i].mpl + c / GI_PI_F) : 1.f;
    for (int a = 0; a < 3; a++) E[a] += f * ls[i].V[a] * c;
  }
}

/* Emitted radiance seen along w at a hit, MIS-weighted against light
 * sampling with one sample (pb = the direction's pdf). 0 when not an emitter's front. */
static int emitted(const gi_scene *s, uint32_t tri, const float ng[3], const float w[3], float t, float pb,
                   float out[3]) {
  const float *Le = s->materials[s->tri_material[tri]].emission;
  if (!(Le[0] > 0 || Le[1] > 0 || Le[2] > 0)) return 0;
  float cos_e = -gi__dot(ng, w);
  if (!(cos_e > 0)) return 0;
  float mpl = gi__emitter_mpl(s, tri, t, cos_e, 1);
  float f = pb / (pb + mpl);
  for (int k = 0; k < 3; k++) out[k] = f * Le[k];
  return 1;
}

/* Emitted radiance seen along w at a hit, without MIS weight (the glossy
 * lobe's sample, which light sampling never competes with). 0 when not an
 * emitter's front. */
static int emitted_full(const gi_scene *s, uint32_t tri, const float ng[3], const float w[3], float out[3]) {
  const float *Le = s->materials[s->tri_material[tri]].emission;
  if (!(Le[0] > 0 || Le[1] > 0 || Le[2] > 0) || !(-gi__dot(ng, w) > 0)) return 0;
  memcpy(out, Le, sizeof(float[3]));
  return 1;
}

/* The material's glossy lobe: exponent of the normalised Phong lobe the
 * cone tracer's aperture stands for (gi__specular_tan: a = roughness^2,
 * ns = 2 / a^2 - 2), or 0 when the material is not glossy (same rule as the
 * cone tracer and the effect plan: roughness < 0.5 and specular > 0).
 * INFINITY is a perfect mirror. */
static double glossy_exponent(const gi_material *m) {
  if (!(m->roughness < 0.5f && m->specular > 0)) return 0;
  double a = (double)m->roughness * m->roughness;
  return a < 1e-4 ? INFINITY : 2.0 / (a * a) - 2.0;
}

/* Samples w from p(w) = (ns+1)/(2 pi) cos^ns(angle(w, r)), exactly. */
static void phong_dir(const float r[3], double ns, uint64_t *rng, float w[3]) {
  float u1 = gi__u01(rng), u2 = gi__u01(rng);
  if (isinf(ns)) {
    memcpy(w, r, sizeof(float[3]));
    return;
  }
  float t[3], b[3];
  gi__basis(r, t, b);
  float ct = (float)pow(1.0 - (double)u1, 1.0 / (ns + 1.0)); /* 1 - u1 in (0, 1]: no 0^0 */
  float st = sqrtf(fmaxf(0.f, 1 - ct * ct)), phi = 2 * GI_PI_F * u2;
  for (int k = 0; k < 3; k++) w[k] = st * cosf(phi) * t[k] + st * sinf(phi) * b[k] + ct * r[k];
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
                           int depth0, int split0, uint64_t *rng, gi_ray_scratch *sc, float L[3], float Ls[3]) {
  const gi_scene *s = rc->s;
  float T[3] = {T0[0], T0[1], T0[2]};
  int maxd = rc->o.max_depth > 0 ? rc->o.max_depth : MAX_DEPTH_HARD;
  for (int depth = depth0;; depth++) {
    const gi_material *mat = &s->materials[s->tri_material[tri]];
    const float *a = mat->albedo;
    float n[3];
    float sg = gi__dot(ng, w) > 0 ? -1.f : 1.f;
    for (int k = 0; k < 3; k++) n[k] = sg * ng[k];
    float E[3] = {0, 0, 0};
    nee(rc, x, n, rng, sc, E);
    int last = depth >= maxd;
    /* The cosine sample: MIS partner of the emitter samples, and the next segment. */
    float wn[3], o[3], t, ngn[3];
    uint32_t trin;
    cosine_dir(n, rng, wn);
    for (int k = 0; k < 3; k++) o[k] = x[k] + rc->eps * n[k];
    int hit = (!last || s->num_emitters) && gi__intersect1(s, o, wn, 0, INFINITY, &t, &trin, ngn);
    float cn = gi__dot(n, wn);
    if (hit && cn > 0) {
      float Le[3];
      if (emitted(s, trin, ngn, wn, t, cn / GI_PI_F, Le))
        for (int k = 0; k < 3; k++) E[k] += GI_PI_F * Le[k]; /* Le cos / (cos / pi) */
    }
    for (int k = 0; k < 3; k++) L[k] += T[k] * a[k] * (1.f / GI_PI_F) * E[k];
    int dcont = !last && hit && cn > 0;
    /* The glossy lobe: one sample of p(w) around the mirror direction;
     * what it meets (an emitter's front, the sky above the horizon) counts
     * in full: no light sample ever draws from this lobe. */
    double ns = glossy_exponent(mat);
    int gcont = 0, split = split0 && depth == depth0;
    float wg[3], tg = 0, ngg[3], spec = mat->specular;
    uint32_t trig = 0;
    if (ns > 0) {
      float r[3], dn = gi__dot(w, n);
      for (int k = 0; k < 3; k++) r[k] = w[k] - 2 * dn * n[k];
      float lr = gi__len(r);
      for (int k = 0; k < 3; k++) r[k] /= lr;
      phong_dir(r, ns, rng, wg);
      float cg = gi__dot(n, wg);
      if (cg > 0) {
        float Lg[3] = {0, 0, 0};
        if (gi__intersect1(s, o, wg, 0, INFINITY, &tg, &trig, ngg)) {
          emitted_full(s, trig, ngg, wg, Lg);
          gcont = !last;
        } else if (gi__dot(rc->up, wg) > 0) {
          memcpy(Lg, rc->sky, sizeof Lg);
        }
        for (int k = 0; k < 3; k++) {
          float v = T[k] * spec * Lg[k];
          L[k] += v;
          if (split && Ls) Ls[k] += v;
        }
      }
    }
    if (split && gcont) {
      /* Follow the glossy lobe as its own path; the diffuse one goes on below. */
      float xg[3], Tg[3], Lg[3] = {0, 0, 0};
      for (int k = 0; k < 3; k++) xg[k] = o[k] + tg * wg[k], Tg[k] = T[k] * spec;
      reflected_from(rc, xg, wg, trig, ngg, Tg, depth + 1, 0, rng, sc, Lg, NULL); /* splits no further */
      for (int k = 0; k < 3; k++) {
        L[k] += Lg[k];
        if (Ls) Ls[k] += Lg[k];
      }
      gcont = 0;
    }
    if (!dcont && !gcont) break;
    /* One lobe goes on, picked in proportion to its reflectance; dividing
     * by the pick's probability keeps the sum of both unbiased. */
    float amax = fmaxf(a[0], fmaxf(a[1], a[2]));
    float pg = !gcont ? 0.f : !dcont ? 1.f : spec / (spec + amax);
    if (pg > 0 && (pg >= 1 || gi__u01(rng) < pg)) {
      for (int k = 0; k < 3; k++) T[k] *= spec / pg;
      for (int k = 0; k < 3; k++) x[k] = o[k] + tg * wg[k], w[k] = wg[k], ng[k] = ngg[k];
      tri = trig;
    } else {
      for (int k = 0; k < 3; k++) T[k] *= a[k] / (1.f - pg);
      for (int k = 0; k < 3; k++) x[k] = o[k] + t * wn[k], w[k] = wn[k], ng[k] = ngn[k];
      tri = trin;
    }
    if (depth >= rc->o.rr_depth) {
      float q = fminf(0.95f, fmaxf(T[0], fmaxf(T[1], T[2])));
      if (!(q > 0) || gi__u01(rng) >= q) break;
      for (int k = 0; k < 3; k++) T[k] /= q;
    }
  }
}

static void reflected(const ref_ctx *rc, float x[3], float w[3], uint32_t tri, float ng[3], uint64_t *rng,
                      gi_ray_scratch *sc, float L[3], float Ls[3]) {
  static const float one[3] = {1, 1, 1};
  reflected_from(rc, x, w, tri, ng, one, 1, 1, rng, sc, L, Ls);
}

static void ref_range(void *p, size_t b, size_t e, int worker) {
  ref_ctx *rc = p;
  const gi_scene *s = rc->s;
  gi_ray_scratch sc = {0};
  if (gi__scratch_alloc(&sc, gi__light_sample_cap(s, &ref_lp))) {
    atomic_store(&rc->failed, 1);
    goto out;
  }
  gi_lsample *ls = sc.ls;
  float *org = sc.org, *dir = sc.dir, *tn = sc.tn, *tf = sc.tf;
  uint8_t *vis = sc.vis;
  int cap = sc.cap;
  for (size_t task = b; task < e; task++) {
    size_t pi = task / (size_t)rc->chunks, ci = task % (size_t)rc->chunks;
    chunk_acc *A = &rc->acc[task];
    float p[3];
    uint64_t h = rc->o.seed;
    for (int k = 0; k < 3; k++) {
      p[k] = (float)(rc->pts[3 * pi + k] - s->origin[k]);
      uint32_t bits;
      memcpy(&bits, &p[k], 4);
      h = gi__mix64(h ^ bits);
    }
    uint64_t rng = gi__mix64(h ^ gi__mix64(ci + 0x5eedull));
    int first = (int)ci * CHUNK, count = rc->o.samples - first < CHUNK ? rc->o.samples - first : CHUNK;
    for (int j = 0; j < count; j++) {
      float Ed[3] = {0, 0, 0}, Ei[3] = {0, 0, 0};
      float shd[9][3] = {{0}}, shi[9][3] = {{0}};
      /* (1) NEE at the probe over the whole sphere. */
      {
        int m = gi__light_samples(s, &ref_lp, p, &rng, ls, cap);
        for (int i = 0; i < m; i++) {
          memcpy(&org[3 * i], p, sizeof(float[3]));
          memcpy(&dir[3 * i], ls[i].w, sizeof(float[3]));
          tn[i] = rc->eps;
          tf[i] = isinf(ls[i].dist) ? INFINITY : ls[i].dist * 0.999f;
        }
        gi__occluded(s, m, org, dir, tn, tf, vis);
        for (int i = 0; i < m; i++) {
          if (!vis[i]) continue;
          float cu = gi__dot(rc->up, ls[i].w);
          float pb = fmaxf(cu, 0.f) / (2 * GI_PI_F) + 1.f / (8 * GI_PI_F);
          float f = ls[i].mpl > 0 ? ls[i].mpl / (ls[i].mpl + pb) : 1.f;
          float V[3] = {f * ls[i].V[0], f * ls[i].V[1], f * ls[i].V[2]};
          gi__sh_add(shd, ls[i].w, V, 1.f);
          if (cu > 0)
            for (int k = 0; k < 3; k++) Ed[k] += V[k] * cu;
        }
      }
      /* (2) One path from the probe, direction from the mixture. */
      {
        float w[3];
        if (gi__u01(&rng) < 0.5f) cosine_dir(rc->up, &rng, w);
        else {
          float z = 1 - 2 * gi__u01(&rng), r = sqrtf(fmaxf(0.f, 1 - z * z)), phi = 2 * GI_PI_F * gi__u01(&rng);
          w[0] = r * cosf(phi), w[1] = r * sinf(phi), w[2] = z;
        }
        float cu = gi__dot(rc->up, w);
        float pb = fmaxf(cu, 0.f) / (2 * GI_PI_F) + 1.f / (8 * GI_PI_F);
        float t, ng[3];
        uint32_t tri;
        if (gi__intersect1(s, p, w, rc->eps, INFINITY, &t, &tri, ng)) {
          float Le[3], Lr[3] = {0, 0, 0};
          if (emitted(s, tri, ng, w, t, pb, Le)) {
            gi__sh_add(shd, w, Le, 1.f / pb);
            if (cu > 0)
              for (int k = 0; k < 3; k++) Ed[k] += Le[k] * cu / pb;
          }
          if (rc->o.max_depth >= 0) {
            float x[3] = {p[0] + t * w[0], p[1] + t * w[1], p[2] + t * w[2]};
            float wc[3] = {w[0], w[1], w[2]};
            reflected(rc, x, wc, tri, ng, &rng, &sc, Lr, NULL);
            gi__sh_add(shi, w, Lr, 1.f / pb);
            if (cu > 0)
              for (int k = 0; k < 3; k++) Ei[k] += Lr[k] * cu / pb;
          }
        }
      }
      for (int k = 0; k < 3; k++) {
        double v[3] = {Ed[k], Ei[k], (double)Ed[k] + Ei[k]};
        for (int q = 0; q < 3; q++) A->sum[q][k] += v[q], A->sq[q][k] += v[q] * v[q];
      }
      for (int i = 0; i < 9; i++)
        for (int k = 0; k < 3; k++) A->sh[i][k] += (double)shd[i][k] + shi[i][k];
    }
  }
out:
  gi__scratch_free(&sc);
}

gi_result gi_reference_irradiance(const gi_scene *s, const double *pts, size_t n, const gi_reference_opts *opts,
                                  gi_ref_probe *out, double *ms, gi_error_info *err) {
  if (!s || (n && (!pts || !out))) return gi__fail(err, GI_ERR_INVALID_ARG, "reference: missing arguments");
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
  for (size_t i = 0; i < 3 * n; i++)
    if (!isfinite(pts[i]))
      return gi__fail(err, GI_ERR_NONFINITE, "reference: point %zu has a non-finite coordinate", i / 3);
  double t0 = gi__now_ms();
  rc.chunks = (rc.o.samples + CHUNK - 1) / CHUNK;
  ctx_setup(&rc, s);
  size_t tasks = n * (size_t)rc.chunks;
  rc.acc = gi__calloc(tasks ? tasks : 1, sizeof *rc.acc);
  if (!rc.acc) return gi__fail(err, GI_ERR_NOMEM, "reference: out of memory for %zu sample chunks", tasks);
  atomic_init(&rc.failed, 0);
  gi__parallel_for_stop(tasks, 1, rc.o.threads, ref_range, &rc, &rc.failed);
  if (atomic_load(&rc.failed)) {
    gi__free(rc.acc);
    return gi__fail(err, GI_ERR_NOMEM, "reference: out of memory for the light-sample buffers");
  }
  gi_result res = GI_OK;
  for (size_t i = 0; i < n; i++) {
    chunk_acc T = {0};
    for (int c = 0; c < rc.chunks; c++) {
      const chunk_acc *A = &rc.acc[i * (size_t)rc.chunks + (size_t)c];
      for (int q = 0; q < 3; q++)
        for (int k = 0; k < 3; k++) T.sum[q][k] += A->sum[q][k], T.sq[q][k] += A->sq[q][k];
      for (int j = 0; j < 9; j++)
        for (int k = 0; k < 3; k++) T.sh[j][k] += A->sh[j][k];
    }
    gi_ref_probe *o = &out[i];
    memset(o, 0, sizeof *o);
    double N = rc.o.samples;
    o->samples = (uint32_t)rc.o.samples;
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
    gi__sh_radiance_to_irradiance(shr);
    memcpy(o->sh, shr, sizeof shr);
    for (int k = 0; k < 3; k++)
      if (!isfinite(o->irradiance[k]) || !isfinite(o->std_err[k])) res = GI_ERR_NONFINITE;
    for (int j = 0; j < 9; j++)
      for (int k = 0; k < 3; k++)
        if (!isfinite(o->sh[j][k])) res = GI_ERR_NONFINITE;
  }
  gi__free(rc.acc);
  if (ms) *ms = gi__now_ms() - t0;
  if (res != GI_OK) return gi__fail(err, res, "reference: a probe came out non-finite (scene values too large?)");
  return GI_OK;
}

/* ---- the path-traced camera view ------------------------------------ */

typedef struct {
  ref_ctx rc;
  const gi__cam *k;
  int spp;
  float *rgb, *spec;
} view_ctx;

static void view_rows(void *p, size_t b, size_t e, int worker) {
  view_ctx *vc = p;
  const ref_ctx *rc = &vc->rc;
  const gi_scene *s = rc->s;
  gi_ray_scratch sc = {0};
  if (gi__scratch_alloc(&sc, gi__light_sample_cap(s, &ref_lp))) {
    atomic_store(&vc->rc.failed, 1);
    return;
  }
  {
    for (size_t y = b; y < e; y++)
      for (int x = 0; x < vc->k->w; x++) {
        uint64_t rng = gi__mix64(rc->o.seed ^ gi__mix64((uint64_t)y << 32 | (uint32_t)x));
        double acc[3] = {0, 0, 0}, accs[3] = {0, 0, 0};
        for (int j = 0; j < vc->spp; j++) {
          float w[3], t, ng[3], L[3] = {0, 0, 0}, Ls[3] = {0, 0, 0};
          uint32_t tri;
          gi__cam_ray(vc->k, (float)x + gi__u01(&rng), (float)y + gi__u01(&rng), w);
          if (!gi__intersect1(s, vc->k->eye, w, 0, INFINITY, &t, &tri, ng)) {
            for (int a = 0; a < 3; a++) acc[a] += rc->sky[a];
            continue;
          }
          if (gi__dot(ng, w) < 0) /* an emitter seen from the front */
            for (int a = 0; a < 3; a++) L[a] += s->materials[s->tri_material[tri]].emission[a];
          float px[3] = {vc->k->eye[0] + t * w[0], vc->k->eye[1] + t * w[1], vc->k->eye[2] + t * w[2]};
          reflected(rc, px, w, tri, ng, &rng, &sc, L, Ls);
          for (int a = 0; a < 3; a++) acc[a] += L[a], accs[a] += Ls[a];
        }
        size_t i = 3 * (y * (size_t)vc->k->w + (size_t)x);
        for (int a = 0; a < 3; a++) vc->rgb[i + a] = (float)(acc[a] / vc->spp);
        if (vc->spec)
          for (int a = 0; a < 3; a++) vc->spec[i + a] = (float)(accs[a] / vc->spp);
      }
  }
  gi__scratch_free(&sc);
}

gi_result gi_reference_render_ex(const gi_scene *s, const gi_camera *cam, const gi_render_opts *opts, float *rgb,
                                 double *ms, gi_error_info *err) {
  gi_render_opts o = {0};
  if (opts) o = *opts;
  if (o.spp == 0) o.spp = 16;
  if (!s || !rgb) return gi__fail(err, GI_ERR_INVALID_ARG, "reference render: missing scene or image");
  if (o.spp < 1 || o.spp > (1 << 20))
    return gi__fail(err, GI_ERR_INVALID_ARG, "reference render: spp must be 1..1048576, got %d", o.spp);
  gi__cam k;
  gi_result r = gi__cam_setup(s, cam, &k, err);
  if (r != GI_OK) return r;
  double t0 = gi__now_ms();
  view_ctx vc = {.k = &k, .spp = o.spp, .rgb = rgb, .spec = o.specular};
  vc.rc.s = s;
  vc.rc.o.seed = o.seed ? o.seed : 1;
  vc.rc.o.rr_depth = 3;
  ctx_setup(&vc.rc, s);
  size_t np = (size_t)k.w * k.h * 3;
  memset(rgb, 0, np * sizeof(float));
  if (o.specular) memset(o.specular, 0, np * sizeof(float));
  atomic_init(&vc.rc.failed, 0);
  gi__parallel_for_stop((size_t)k.h, 1, o.threads, view_rows, &vc, &vc.rc.failed);
  if (atomic_load(&vc.rc.failed))
    return gi__fail(err, GI_ERR_NOMEM, "reference render: out of memory for the light-sample buffers");
  if (ms) *ms = gi__now_ms() - t0;
  for (size_t i = 0; i < np; i++)
    if (!isfinite(rgb[i]) || (o.specular && !isfinite(o.specular[i])))
      return gi__fail(err, GI_ERR_NONFINITE, "reference render: pixel %zu is not finite", i / 3);
  return GI_OK;
}

gi_result gi_reference_render(const gi_scene *s, const gi_camera *cam, int spp, uint64_t seed, int threads,
                              float *rgb, double *ms, gi_error_info *err) {
  if (spp == 0) /* the _ex default would hide a caller's missing count */
    return gi__fail(err, GI_ERR_INVALID_ARG, "reference render: spp must be 1..1048576, got %d", spp);
  gi_render_opts o = {.spp = spp, .seed = seed, .threads = threads};
  return gi_reference_render_ex(s, cam, &o, rgb, ms, err);
}
