/* inject.c: direct light into the voxels, and the voxel-to-voxel bounces.
 *
 * Injection: every occupied voxel gets the direct irradiance on both sides
 * of its surface from every light, with visibility from Embree shadow rays
 * issued as one stream per voxel. Sun, point and spot lights take one ray
 * each; the sky and emissive surfaces are sampled (stratified, seeded by the
 * voxel's global cell so a bake is deterministic and a voxel's noise does
 * not change when the cascade scrolls). Outgoing radiance per face is then
 * albedo / pi * irradiance of the side facing that way, times the face's
 * covered fraction (gi__shade_voxels).
 *
 * Bounce: each occupied voxel gathers indirect irradiance on each side with
 * the diffuse cone set (weights sum to pi, see trace.c), starting one voxel
 * off the surface; all voxels gather from the previous bounce's texture
 * (Jacobi), then the texture is reshaded and the nested regions refiltered.
 * A closed furnace of albedo a and emission Le therefore reaches
 * Le (a + ... + a^(k+1)) reflected radiance after k bounces. When the
 * effect plan capped an automatic bounce count short of what the albedo
 * asks for, the last bounce also adds the geometric tail of the orders
 * left out (ratio measured from the last two bounces); an explicit bounce
 * count keeps the exact k-bounce sum above. */
#include <stdlib.h>
#include <string.h>
#include "cascade_internal.h"
#include "internal.h"

#define PI_F 3.14159265358979f
#define MAX_LS 1024

gi_light_plan gi__light_plan(const gi_bake_report *r, int samples) {
  gi_light_plan lp = {
      .sun = r->effects[GI_FX_SUN].ran,
      .local = r->effects[GI_FX_LOCAL].ran,
      .sky = r->effects[GI_FX_SKY].ran,
      .emissive = r->effects[GI_FX_EMISSIVE].ran,
      .sky_samples = samples,
      .emit_samples = samples,
  };
  return lp;
}

void gi__sky_radiance(const gi_scene *s, float out[3]) {
  out[0] = out[1] = out[2] = 0;
  for (uint32_t i = 0; i < s->num_lights; i++)
    if (s->lights[i].type == GI_LIGHT_SKY)
      for (int k = 0; k < 3; k++) out[k] += s->lights[i].color[k];
}

int gi__light_samples(const gi_scene *s, const gi_light_plan *lp, const float p[3], uint64_t *rng,
                      gi_lsample *out, int max) {
  int n = 0;
  const float *up_axis = s->up == GI_UP_Z ? (const float[3]){0, 0, 1} : (const float[3]){0, 1, 0};
  for (uint32_t i = 0; i < s->num_lights && n < max; i++) {
    const gi_light *l = &s->lights[i];
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
      if (!lp->local) continue;
      float v[3];
      for (int k = 0; k < 3; k++) v[k] = (float)(l->position[k] - s->origin[k]) - p[k];
      float r2 = gi__dot(v, v);
      if (!(r2 > 1e-12f)) continue;
      float r = sqrtf(r2);
      for (int k = 0; k < 3; k++) o->w[k] = v[k] / r;
      float f = 1.0f;
      if (l->type == GI_LIGHT_SPOT) {
        float c = -gi__dot(o->w, l->direction);
        if (c <= l->cos_outer) continue;
        if (c < l->cos_inner) {
          float t = (c - l->cos_outer) / fmaxf(l->cos_inner - l->cos_outer, 1e-6f);
          f = t * t * (3 - 2 * t);
        }
      }
      o->dist = r;
      for (int k = 0; k < 3; k++) o->V[k] = f * l->color[k] / r2;
      o->fx = GI_FX_LOCAL;
      o->mpl = 0;
      n++;
    } else if (l->type == GI_LIGHT_SKY && lp->sky && lp->sky_samples > 0) {
      /* Upper hemisphere, stratified in cos(theta) and azimuth, uniform pdf 1 / (2 pi). */
      int m = lp->sky_samples;
      float t[3], b[3];
      gi__basis(up_axis, t, b);
      float rot = gi__u01(rng);
      for (int j = 0; j < m && n < max; j++) {
        float ct = ((float)j + gi__u01(rng)) / (float)m;
        float st = sqrtf(fmaxf(0.f, 1 - ct * ct));
        float phi = 2 * PI_F * ((float)j * 0.6180339887f + rot);
        float cp = cosf(phi), sp = sinf(phi);
        gi_lsample *q = &out[n++];
        for (int k = 0; k < 3; k++) q->w[k] = st * cp * t[k] + st * sp * b[k] + ct * up_axis[k];
        q->dist = INFINITY;
        for (int k = 0; k < 3; k++) q->V[k] = l->color[k] * 2 * PI_F / (float)m;
        q->fx = GI_FX_SKY;
        q->mpl = 0;
      }
    }
  }
  if (lp->emissive && s->num_emitters > 0) {
    int m = lp->emit_samples;
    for (int j = 0; j < m && n < max; j++) {
      float u = ((float)j + gi__u01(rng)) / (float)m;
      /* Pick a triangle by power: binary search in the cdf. */
      uint32_t lo = 0, hi = s->num_emitters - 1;
      while (lo < hi) {
        uint32_t mid = (lo + hi) / 2;
        if (s->emitter_cdf[mid] < u) lo = mid + 1;
        else hi = mid;
      }
      float pt = s->emitter_cdf[lo] - (lo ? s->emitter_cdf[lo - 1] : 0.f);
      if (!(pt > 0)) continue;
      uint32_t tri = s->emitter_tri[lo];
      const uint32_t *ix = &s->indices[3 * tri];
      const float *A = &s->vertices[3 * ix[0]], *B = &s->vertices[3 * ix[1]], *C = &s->vertices[3 * ix[2]];
      float r1 = gi__u01(rng), r2 = gi__u01(rng);
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
      if (!(area2 > 0)) continue;
      float r2d = gi__dot(v, v);
      if (!(r2d > 0)) continue;
      float r = sqrtf(r2d);
      gi_lsample *q = &out[n];
      for (int k = 0; k < 3; k++) q->w[k] = v[k] / r;
      /* Emitters are one-sided, facing their winding normal. */
      float cos_e = -gi__dot(ng, q->w) / area2;
      if (cos_e <= 0) continue;
      float area = 0.5f * area2;
      float pdf_area = pt / area;
      const float *Le = s->materials[s->tri_material[tri]].emission;
      float k0 = cos_e / (r2d * pdf_area * (float)m);
      for (int k = 0; k < 3; k++) q->V[k] = Le[k] * k0;
      q->mpl = (float)m * pdf_area * r2d / cos_e;
      q->dist = r;
      q->fx = GI_FX_EMISSIVE;
      n++;
    }
  }
  return n;
}

int gi__scratch_alloc(gi_ray_scratch *sc, int cap) {
  size_t n = (size_t)(cap > 0 ? cap : 1);
  sc->cap = cap;
  sc->ls = malloc(n * sizeof *sc->ls);
  sc->org = malloc(n * 3 * sizeof(float));
  sc->dir = malloc(n * 3 * sizeof(float));
  sc->tn = malloc(n * sizeof(float));
  sc->tf = malloc(n * sizeof(float));
  sc->vis = malloc(n);
  if (sc->ls && sc->org && sc->dir && sc->tn && sc->tf && sc->vis) return 0;
  gi__scratch_free(sc);
  return -1;
}

void gi__scratch_free(gi_ray_scratch *sc) {
  free(sc->ls); free(sc->org); free(sc->dir); free(sc->tn); free(sc->tf); free(sc->vis);
  sc->ls = NULL, sc->org = sc->dir = sc->tn = sc->tf = NULL, sc->vis = NULL;
}

float gi__emitter_mpl(const gi_scene *s, uint32_t tri, float t, float cos_e, int m) {
  /* emitter_tri is ascending: binary search for the triangle's cdf slot. */
  uint32_t lo = 0, hi = s->num_emitters;
  while (lo < hi) {
    uint32_t mid = (lo + hi) / 2;
    if (s->emitter_tri[mid] < tri) lo = mid + 1;
    else hi = mid;
  }
  if (lo >= s->num_emitters || s->emitter_tri[lo] != tri || !(cos_e > 0)) return 0;
  float pt = s->emitter_cdf[lo] - (lo ? s->emitter_cdf[lo - 1] : 0.f);
  const uint32_t *ix = &s->indices[3 * tri];
  const float *A = &s->vertices[3 * ix[0]], *B = &s->vertices[3 * ix[1]], *C = &s->vertices[3 * ix[2]];
  float e1[3], e2[3], ng[3];
  for (int k = 0; k < 3; k++) e1[k] = B[k] - A[k], e2[k] = C[k] - A[k];
  gi__cross(e1, e2, ng);
  float area = 0.5f * gi__len(ng);
  if (!(area > 0)) return 0;
  return (float)m * (pt / area) * t * t / cos_e;
}

static int emitter_hit(const gi_scene *s, uint32_t tri, const float w[3], float *cos_e) {
  const float *Le = s->materials[s->tri_material[tri]].emission;
  if (!(Le[0] > 0 || Le[1] > 0 || Le[2] > 0)) return 0;
  const uint32_t *ix = &s->indices[3 * tri];
  const float *A = &s->vertices[3 * ix[0]], *B = &s->vertices[3 * ix[1]], *C = &s->vertices[3 * ix[2]];
  float e1[3], e2[3], ng[3];
  for (int k = 0; k < 3; k++) e1[k] = B[k] - A[k], e2[k] = C[k] - A[k];
  gi__cross(e1, e2, ng);
  float l = gi__len(ng);
  if (!(l > 0)) return 0;
  *cos_e = -gi__dot(ng, w) / l;
  return *cos_e > 0;
}

int gi__emitter_ray(const gi_scene *s, const float o[3], const float w[3], float tnear, int m_light,
                    float pb, float out[3]) {
  float th, ng[3], ce;
  uint32_t tri;
  if (!(pb > 0) || !gi__intersect1(s, o, w, tnear, INFINITY, &th, &tri, ng)) return 0;
  if (!emitter_hit(s, tri, w, &ce)) return 0;
  float mpl = gi__emitter_mpl(s, tri, th, ce, m_light);
  const float *Le = s->materials[s->tri_material[tri]].emission;
  for (int k = 0; k < 3; k++) out[k] = Le[k] / (mpl + pb);
  return 1;
}

typedef struct {
  struct gi_cascade *c;
  const gi_light_plan *lp;
  int d;
  uint64_t seed;
  atomic_ullong rays;
} inject_ctx;

static void inject_range(void *p, size_t b, size_t e, int worker) {
  inject_ctx *ic = p;
  struct gi_cascade *c = ic->c;
  gi_level *L = &c->lv[ic->d];
  const gi_scene *s = c->scene;
  gi_ray_scratch sc = {0};
  int8_t *side = malloc(MAX_LS);
  float *cosw = malloc(MAX_LS * sizeof(float));
  if (gi__scratch_alloc(&sc, MAX_LS) || !side || !cosw) goto out; /* voxels stay dark */
  gi_lsample *ls = sc.ls;
  float *org = sc.org, *dir = sc.dir, *tn = sc.tn, *tf = sc.tf;
  uint8_t *vis = sc.vis;
  uint64_t rays = 0;
  int R = c->R;
  for (size_t q = b; q < e; q++) {
    uint32_t slot = L->occ[q];
    const gi_vgeo *g = &L->geo[slot];
    float(*E)[3] = L->direct[slot];
    memset(E, 0, sizeof(float[2][3]));
    /* Seed from the global cell: the same voxel gets the same samples wherever the window is. */
    int64_t cell[3];
    gi__slot_cell(L, R, slot, cell);
    uint64_t rng = gi__mix64(ic->seed ^ gi__mix64((uint64_t)cell[0] * 73856093ull ^ (uint64_t)cell[1] * 19349663ull ^
                                                    (uint64_t)cell[2] * 83492791ull ^ (uint64_t)ic->d << 56));
    int n = gi__light_samples(s, ic->lp, g->centroid, &rng, ls, MAX_LS);
    float eps = (float)(0.02 * L->s);
    int m = 0;
    for (int i = 0; i < n; i++) {
      float cn = gi__dot(g->normal, ls[i].w);
      if (cn == 0) continue;
      int sd = cn > 0 ? 0 : 1;
      float sg = cn > 0 ? 1.f : -1.f;
      for (int k = 0; k < 3; k++) {
        org[3 * m + k] = g->centroid[k] + sg * eps * g->normal[k];
        dir[3 * m + k] = ls[i].w[k];
      }
      tn[m] = 0;
      tf[m] = isinf(ls[i].dist) ? INFINITY : ls[i].dist * 0.999f;
      side[m] = (int8_t)sd;
      cosw[m] = fabsf(cn);
      /* Keep the sample index in the V slot order: compact in place. */
      ls[m] = ls[i];
      m++;
    }
    gi__occluded(s, m, org, dir, tn, tf, vis);
    rays += (uint64_t)m;
    int mb = ic->lp->emissive && s->num_emitters ? ic->lp->emit_samples : 0;
    for (int i = 0; i < m; i++) {
      if (!vis[i]) continue;
      /* Balance heuristic against the cosine samples below. */
      float f = ls[i].mpl > 0 ? ls[i].mpl / (ls[i].mpl + (float)mb * cosw[i] / PI_F) : 1.f;
      for (int k = 0; k < 3; k++) E[side[i]][k] += f * ls[i].V[k] * cosw[i];
    }
    /* Cosine-weighted rays find emitters that are close and large, which
     * area sampling almost never picks (the furnace's edges). */
    for (int sd = 0; sd < 2 && mb > 0; sd++) {
      float n[3], t[3], bb[3], o[3];
      float sg = sd ? -1.f : 1.f;
      for (int k = 0; k < 3; k++) n[k] = sg * g->normal[k], o[k] = g->centroid[k] + eps * n[k];
      gi__basis(n, t, bb);
      for (int j = 0; j < mb; j++) {
        float u1 = ((float)j + gi__u01(&rng)) / (float)mb, u2 = gi__u01(&rng);
        float r = sqrtf(u1), phi = 2 * PI_F * u2;
        float x = r * cosf(phi), y = r * sinf(phi), z = sqrtf(fmaxf(0.f, 1 - u1));
        float w[3];
        for (int k = 0; k < 3; k++) w[k] = x * t[k] + y * bb[k] + z * n[k];
        rays++;
        float V[3];
        if (!gi__emitter_ray(s, o, w, 0, ic->lp->emit_samples, (float)mb * z / PI_F, V)) continue;
        for (int k = 0; k < 3; k++) E[sd][k] += V[k] * z;
      }
    }
    memcpy(L->side[slot], E, sizeof(float[2][3]));
  }
  atomic_fetch_add(&ic->rays, rays);
out:
  gi__scratch_free(&sc);
  free(side);
  free(cosw);
}

void gi__shade_voxels(struct gi_cascade *c, int d, uint32_t begin, uint32_t end) {
  gi_level *L = &c->lv[d];
  for (uint32_t q = begin; q < end; q++) {
    uint32_t slot = L->occ[q];
    const gi_vgeo *g = &L->geo[slot];
    gi_vrad *r = &L->rad[slot];
    float Ls[2][3];
    for (int sd = 0; sd < 2; sd++)
      for (int k = 0; k < 3; k++) Ls[sd][k] = g->albedo[k] * (1.0f / PI_F) * L->side[slot][sd][k];
    for (int f = 0; f < 6; f++) {
      int a = f / 2;
      float sf = (f & 1) ? -1.f : 1.f;
      int sd = sf * g->normal[a] >= 0 ? 0 : 1;
      for (int k = 0; k < 3; k++) r->p[f][k] = r->alpha[a] * Ls[sd][k];
    }
  }
}

static void shade_all(struct gi_cascade *c) {
  for (int d = 0; d < c->n; d++) gi__shade_voxels(c, d, 0, c->lv[d].num_occ);
}

gi_result gi__inject(struct gi_cascade *c, const gi_quality *q, gi_error_info *err) {
  gi_light_plan lp = gi__light_plan(&c->report, q->light_samples);
  for (int d = 0; d < c->n; d++) {
    inject_ctx ic = {.c = c, .lp = &lp, .d = d, .seed = q->seed};
    atomic_init(&ic.rays, 0);
    gi__parallel_for(c->lv[d].num_occ, 32, q->threads, inject_range, &ic);
    c->report.shadow_rays += atomic_load(&ic.rays);
  }
  shade_all(c);
  return GI_OK;
}

typedef struct {
  struct gi_cascade *c;
  const gi_quality *q;
  int d;
  float (*E)[2][3]; /* per occupied voxel */
  atomic_ullong samples;
} bounce_ctx;

static void bounce_range(void *p, size_t b, size_t e, int worker) {
  bounce_ctx *bc = p;
  struct gi_cascade *c = bc->c;
  const gi_level *L = &c->lv[bc->d];
  float off = (float)L->s;
  float lambda = bc->q->ao_lambda;
  uint64_t samples = 0;
  for (size_t q = b; q < e; q++) {
    uint32_t slot = L->occ[q];
    const gi_vgeo *g = &L->geo[slot];
    memset(bc->E[q], 0, sizeof(float[2][3]));
    if (g->albedo[0] <= 0 && g->albedo[1] <= 0 && g->albedo[2] <= 0) continue;
    for (int sd = 0; sd < 2; sd++) {
      float n[3], t[3], bb[3], o[3];
      float sg = sd ? -1.f : 1.f;
      for (int k = 0; k < 3; k++) {
        n[k] = sg * g->normal[k];
        o[k] = g->centroid[k] + off * n[k];
      }
      gi__basis(n, t, bb);
      for (int ci = 0; ci < c->num_cones; ci++) {
        const float *cd = c->cone_dir[ci];
        float w[3];
        for (int k = 0; k < 3; k++) w[k] = cd[0] * t[k] + cd[1] * bb[k] + cd[2] * n[k];
        gi_cone_out co;
        gi__cone_trace_surface(c, o, w, c->cone_tan, off, bc->q->step, lambda, off, n, &co);
        samples += co.samples;
        for (int k = 0; k < 3; k++) bc->E[q][sd][k] += c->cone_weight[ci] * co.L[k];
      }
    }
  }
  atomic_fetch_add(&bc->samples, samples);
}

gi_result gi__bounce(struct gi_cascade *c, const gi_quality *q, int bounces, int tail, gi_error_info *err) {
  float(*E[GI_MAX_LEVELS])[2][3] = {0};
  gi_result rc = GI_OK;
  /* Area-weighted sums of the gathered irradiance per bounce (both sides,
   * every level's own voxels), for the tail's ratio. */
  double S[3][3] = {{0}};
  for (int d = 0; d < c->n; d++) {
    E[d] = malloc(((size_t)c->lv[d].num_occ + 1) * sizeof *E[d]);
    if (!E[d]) {
      rc = gi__fail(err, GI_ERR_NOMEM, "bounce: out of memory");
      goto done;
    }
  }
  for (int it = 0; it < bounces; it++) {
    for (int d = 0; d < c->n; d++) {
      bounce_ctx bc = {.c = c, .q = q, .d = d, .E = E[d]};
      atomic_init(&bc.samples, 0);
      gi__parallel_for(c->lv[d].num_occ, 16, q->threads, bounce_range, &bc);
      c->report.cone_samples += atomic_load(&bc.samples);
    }
    int last = it + 1 == bounces;
    /* The tail: bounce k gathers E_k = E_1 + ... (orders 2..k+1 of the
     * light leaving the voxels); its increment D_k = E_k - E_(k-1) shrinks
     * by the room's mean reflection r = D_k / D_(k-1) (area-weighted over
     * every voxel, per channel; the dominant eigenvalue of the transport
     * once the first bounces have spread the light). The orders left out
     * add D_k (r + r^2 + ...) = D_k r / (1 - r), each voxel scaled by its
     * own last increment. r is capped at 0.95 (a furnace of albedo 0.99
     * would otherwise multiply its last increment by 99). */
    double f[3] = {0, 0, 0};
    for (int k = 0; k < 3; k++) S[0][k] = S[1][k], S[1][k] = S[2][k], S[2][k] = 0;
    for (int d = 0; d < c->n; d++) {
      const gi_level *L = &c->lv[d];
      for (uint32_t i = 0; i < L->num_occ; i++) {
        double a = L->geo[L->occ[i]].area;
        for (int sd = 0; sd < 2; sd++)
          for (int k = 0; k < 3; k++) S[2][k] += a * E[d][i][sd][k];
      }
    }
    if (tail && last && it >= 1)
      for (int k = 0; k < 3; k++) {
        double dk = S[2][k] - S[1][k], dk1 = S[1][k] - S[0][k];
        double r = dk1 > 0 && dk > 0 ? dk / dk1 : 0;
        if (r > 0.95) r = 0.95;
        f[k] = r / (1 - r);
      }
    for (int d = 0; d < c->n; d++) {
      gi_level *L = &c->lv[d];
      for (uint32_t i = 0; i < L->num_occ; i++) {
        uint32_t slot = L->occ[i];
        for (int sd = 0; sd < 2; sd++)
          for (int k = 0; k < 3; k++) {
            float e = E[d][i][sd][k];
            /* side - direct is still the previous bounce's E. */
            float inc = e - (L->side[slot][sd][k] - L->direct[slot][sd][k]);
            float t = (float)f[k] * inc;
            L->side[slot][sd][k] = L->direct[slot][sd][k] + e + (t > 0 ? t : 0);
          }
      }
    }
    shade_all(c);
    gi__cascade_filter(c, q->threads);
    c->report.bounces_run = it + 1;
  }
done:
  for (int d = 0; d < c->n; d++) free(E[d]);
  return rc;
}
