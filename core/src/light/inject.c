/* inject.c: direct light into the voxels.
 *
 * Every occupied voxel gets the direct irradiance on both sides of each
 * of its orientation groups (cascade_internal.h) from every light, with visibility from Embree shadow rays issued
 * as one stream per voxel. Sun, point and spot lights take one ray each;
 * the sky and emissive surfaces are sampled (stratified, seeded by the
 * voxel's global cell so a bake is deterministic and a voxel's noise does
 * not change when the cascade scrolls). Outgoing radiance per face is then
 * albedo / pi * irradiance of the side that face shows, times the face's
 * covered fraction (gi__shade_voxels). */
#include <stdlib.h>
#include <string.h>
#include "base/internal.h"
#include "light/light.h"
#include "scene/lights.h"

/* One parallel loop over the listed voxels of every level (level d's are
 * [start[d], start[d + 1])): a loop per level waited for its slowest
 * chunk six times, and the Cornell box's coarse levels hold a few chunks
 * each. Each voxel's light depends on its cell alone, not on the order. */
typedef struct {
  struct gi_cascade *c;
  const gi_light_plan *lp;
  gi_light_plan lp_other; /* lp without the emitters (a voxel that spread them) */
  const uint32_t *const *slots; /* per level: the voxels to light (its occ list, or a move's new voxels) */
  size_t start[GI_MAX_LEVELS + 1];
  uint64_t seed;
  int cap;             /* light samples per voxel at most (gi__light_sample_cap) */
  atomic_ullong rays;
  atomic_int failed;   /* a worker ran out of memory */
} inject_ctx;

/* A point or spot light closer to a voxel's surfaces than NEAR_FIELD_REACH
 * patch radii lights the voxel piece by piece (near_field.c): 1/r^2 at
 * the centroid can miss most of what the patch receives (a lamp 0.1 m
 * under its housing), and misses it differently at each level. The patch
 * radius is that of a disc of the voxel's surface area, at most a face's:
 * more is several surfaces (a corner, a duplicated triangle), not a
 * larger patch. Farther, the centroid's value is within a few percent. */
#define NEAR_FIELD_REACH 4.0f
static float near_reach(const gi_vgeo *g, float voxel) {
  return NEAR_FIELD_REACH * sqrtf(gi__minf(g->area, voxel * voxel) / GI_PI_F);
}

/* Per-worker buffers of inject_range. */
typedef struct {
  gi_ray_scratch sc;
  gi_lsample *all;     /* the voxel's light samples, before each group's pick */
  int8_t *side;        /* per picked sample: the side it lights */
  float *cosw;         /* per picked sample: |cos| to the group's orientation */
  float *mis;          /* per picked sample: its MIS weight against emitter_rays */
  uint8_t *near;       /* per sample of `all`: the groups near_lights lit with it (bit h) */
  gi_near_scratch ns;  /* the voxel's triangles for near lights */
  int64_t cell[3];     /* the voxel's global cell, of size sz */
  double sz;
  uint64_t near_rays;  /* shadow rays the near lights traced */
  int oom;             /* the near-field query ran out of memory */
} inject_buf;

/* A point or spot light bringing less than this share of what all the
 * group's samples would bring unshadowed, plus what the group's sides
 * already took over its surface (the spread sun, sky and emitters, near
 * lights), plays Russian roulette for its shadow ray: kept with
 * probability share / ROULETTE_SHARE and scaled up by its inverse, so the
 * sum stays unbiased. In the city most of a voxel's rays went to street
 * lamps a hundred metres off; without the spread light in the total, a
 * coarse voxel traced them all again (448k of the city's 1.36M rays). The
 * added noise is at most sqrt(ROULETTE_SHARE) of that total per group. Sky,
 * sun and emitter samples are stratified or importance-sampled already
 * and each carry a fair share: they always trace. */
#define ROULETTE_SHARE 0.01f

/* Russian roulette on the weak local-light samples of ls[0..m) (see
 * ROULETTE_SHARE; base: the light the group has already); compacts the
 * survivors with their side, cosine and MIS weight, returns how many
 * remain. A sample that brings nothing is dropped. */
static inline float unshadowed(const gi_lsample *ls, const inject_buf *ib, int i) {
  return (ls[i].V[0] + ls[i].V[1] + ls[i].V[2]) * ib->cosw[i] * ib->mis[i];
}

static int roulette(gi_lsample *ls, inject_buf *ib, int m, float base, uint64_t *rng) {
  float total = base;
  for (int i = 0; i < m; i++) total += unshadowed(ls, ib, i);
  float cut = ROULETTE_SHARE * total;
  int kept = 0;
  for (int i = 0; i < m; i++) {
    float c = unshadowed(ls, ib, i);
    if (!(c > 0)) continue;
    if (c < cut && ls[i].fx == GI_FX_LOCAL) {
      float p = c / cut;
      if (gi__u01(rng) >= p) continue;
      for (int k = 0; k < 3; k++) ls[i].V[k] /= p;
    }
    ls[kept] = ls[i];
    ib->side[kept] = ib->side[i];
    ib->cosw[kept] = ib->cosw[i];
    ib->mis[kept] = ib->mis[i];
    kept++;
  }
  return kept;
}

/* The orientation group most nearly facing direction w (either side). */
static int facing_group(const gi_vgeo *g, const float w[3]) {
  int best = 0;
  float bc = -1;
  for (int h = 0; h < g->groups; h++) {
    float c = fabsf(gi__dot(g->u.fin.orient[h], w));
    if (c > bc) bc = c, best = h;
  }
  return best;
}

/* The voxel's samples `all` lit over its surface instead of at its
 * centroid, into Es (all groups at once): local lights within reach of
 * its surfaces piece by piece, and on a coarse level (d) the sun and the
 * sky from points spread over it (light.h). ib->near[i] says which groups sample
 * i lit, so light_group skips it there. */
static void near_lights(const gi_scene *s, const gi_vgeo *g, float voxel, int d, int n, inject_buf *ib,
                        uint64_t *rng, float Es[GI_VOX_FACES][3]) {
  float reach = near_reach(g, voxel);
  for (int i = 0; i < n; i++) {
    const gi_lsample *l = &ib->all[i];
    int r = 0, m = 1;
    if (l->fx == GI_FX_LOCAL && l->dist < reach) {
      r = gi__near_field(s, g, ib->sz, ib->cell, l, &ib->ns, Es, &ib->near_rays);
    } else if ((l->fx == GI_FX_SUN || l->fx == GI_FX_SKY) && d >= GI_SPREAD_FROM) {
      /* A sky's samples are one block (gi__light_samples): spread together. */
      if (l->fx == GI_FX_SKY)
        while (i + m < n && ib->all[i + m].fx == GI_FX_SKY) m++;
      r = gi__spread_light(s, g, ib->sz, ib->cell, l, m, rng, &ib->ns, Es, &ib->near_rays);
    }
    if (r < 0) ib->oom = 1;
    for (int k = 0; k < m; k++) ib->near[i + k] = (uint8_t)(r > 0 ? r : 0);
    i += m - 1;
  }
}

/* Direct light from the samples `all` on both sides of group h, through
 * shadow rays from each side's centroid; adds to Es per side, returns the rays. */
static uint64_t light_group(const inject_ctx *ic, const gi_vgeo *g, int h, float voxel, int n, inject_buf *ib,
                            uint64_t *rng, float Es[GI_VOX_FACES][3]) {
  const gi_scene *s = ic->c->scene;
  const float *o = g->u.fin.orient[h];
  gi_lsample *ls = ib->sc.ls;
  int m = 0;
  for (int i = 0; i < n; i++) {
    const gi_lsample *l = &ib->all[i];
    if (ib->near[i] >> h & 1) continue;
    float cn = gi__dot(o, l->w);
    if (cn == 0) continue;
    ls[m] = *l;
    ib->side[m] = (int8_t)(2 * h + (cn > 0 ? 0 : 1));
    ib->cosw[m] = fabsf(cn);
    m++;
  }
  int mb = ic->lp->emissive && s->num_emitters ? ic->lp->emit_samples : 0;
  /* Balance heuristic against the cosine samples of emitter_rays. */
  for (int i = 0; i < m; i++)
    ib->mis[i] = gi__mis_light(ls[i].mpl, (float)mb * ib->cosw[i] / GI_PI_F, 0);
  float base = 0;
  for (int k = 0; k < 3; k++) base += Es[2 * h][k] + Es[2 * h + 1][k];
  m = roulette(ls, ib, m, base, rng);
  /* Each ray leaves from the surfaces of the side that faces its light. */
  float pp[3], pn[3];
  gi__side_centroid(g, 2 * h, pp);
  gi__side_centroid(g, 2 * h + 1, pn);
  gi__shadow_rays_sided(s, pp, pn, o, voxel, ls, m, &ib->sc);
  uint8_t *vis = ib->sc.vis;
  /* A point light within the voxel lights the surfaces facing it
   * whatever the group's centroid sees: the centroid of a small closed
   * object (a lamp's housing) lies inside it, and its shadow ray meets the
   * object's own faces. Only the group that faces the light best: the
   * others' sides facing it are the object's inside (a housing's side
   * walls seen from a lamp under its floor), which the shadow rays from
   * their own surfaces decide. */
  for (int i = 0; i < m; i++)
    if (ls[i].fx == GI_FX_LOCAL && ls[i].dist < voxel && facing_group(g, ls[i].w) == h) vis[i] = 1;
  for (int i = 0; i < m; i++) {
    if (!vis[i]) continue;
    for (int k = 0; k < 3; k++) Es[ib->side[i]][k] += ib->mis[i] * ls[i].V[k] * ib->cosw[i];
  }
  return (uint64_t)m;
}

/* Cosine-weighted rays find emitters that are close and large, which
 * area sampling almost never picks (the furnace's edges): mb per side of
 * every group. Returns the rays. */
static uint64_t emitter_rays(const inject_ctx *ic, const gi_vgeo *g, float voxel, uint64_t *rng,
                             float Es[GI_VOX_FACES][3]) {
  const gi_scene *s = ic->c->scene;
  int mb = ic->lp->emissive && s->num_emitters ? ic->lp->emit_samples : 0;
  uint64_t rays = 0;
  for (int sd = 0; sd < 2 * g->groups && mb > 0; sd++) {
    float pc[3], n[3], o[3];
    gi__side_centroid(g, sd, pc);
    float sg = (sd & 1) ? -1.f : 1.f;
    for (int k = 0; k < 3; k++) n[k] = sg * g->u.fin.orient[sd / 2][k];
    /* These rays all leave on side n: the shadow rule's start for it. */
    float tn = gi__shadow_origin(pc, n, voxel, n, o);
    /* A side no emitter faces finds none: skip its rays, drawing their
     * numbers all the same so the next side's stay as they were. */
    if (!gi__light_tree_may_face(s, o, n)) {
      for (int j = 0; j < 2 * mb; j++) (void)gi__u01(rng);
      continue;
    }
    gi__emitter_cosine_rays(s, pc, o, tn, n, mb, ic->lp->emit_samples, rng, NULL, Es[sd]);
    rays += (uint64_t)mb;
  }
  return rays;
}

static void inject_range(void *p, size_t b, size_t e, int worker) {
  (void)worker;
  inject_ctx *ic = p;
  struct gi_cascade *c = ic->c;
  inject_buf ib = {.sc = {0}};
  ib.all = gi__malloc((size_t)ic->cap * sizeof *ib.all);
  ib.side = gi__malloc((size_t)ic->cap);
  ib.cosw = gi__malloc((size_t)ic->cap * sizeof(float));
  ib.mis = gi__malloc((size_t)ic->cap * sizeof(float));
  ib.near = gi__malloc((size_t)ic->cap);
  if (!ib.all || !ib.side || !ib.cosw || !ib.mis || !ib.near || gi__scratch_alloc(&ib.sc, ic->cap)) {
    atomic_store(&ic->failed, 1);
    goto out;
  }
  uint64_t rays = 0;
  int R = c->R, d = 0;
  for (size_t q = b; q < e; q++) {
    while (q >= ic->start[d + 1]) d++;
    gi_level *L = &c->lv[d];
    float voxel = (float)L->s;
    ib.sz = L->s;
    uint32_t slot = ic->slots[d][q - ic->start[d]];
    const gi_vgeo *g = gi__geo(L, slot);
    float Es[GI_VOX_FACES][3] = {{0}}; /* per side 2 g + s */
    /* Seed from the global cell: the same voxel gets the same samples wherever the window is. */
    int64_t *cell = ib.cell;
    gi__slot_cell(L, R, slot, cell);
    gi__near_reset(&ib.ns);
    uint64_t rng = gi__mix64(ic->seed ^ gi__mix64((uint64_t)cell[0] * 73856093ull ^ (uint64_t)cell[1] * 19349663ull ^
                                                    (uint64_t)cell[2] * 83492791ull ^ (uint64_t)d << 56));
    /* A coarse voxel with an emitter near takes the emitters' light over its
     * surface when it can (gi__spread_emitters); then its centroids sample
     * the other lights only. */
    const gi_light_plan *lp = ic->lp;
    int spread = 0;
    if (d >= GI_EMIT_SPREAD_FROM && lp->emissive && c->scene->num_emitters &&
        gi__light_tree_within(c->scene, g->centroid, GI_EMIT_SPREAD_REACH * voxel)) {
      float Ee[GI_VOX_FACES][3] = {{0}};
      int r = gi__spread_emitters(c->scene, g, ib.sz, cell, lp->emit_samples, &rng, &ib.ns, Ee, &ib.near_rays);
      if (r < 0) ib.oom = 1;
      spread = r > 0 && r == (1 << g->groups) - 1;
      if (spread)
        for (int f = 0; f < GI_VOX_FACES; f++)
          for (int k = 0; k < 3; k++) Es[f][k] += Ee[f][k];
    }
    int n = gi__light_samples(c->scene, spread ? &ic->lp_other : lp, g->centroid, &rng, ib.all, ic->cap);
    near_lights(c->scene, g, voxel, d, n, &ib, &rng, Es);
    for (int h = 0; h < g->groups; h++) rays += light_group(ic, g, h, voxel, n, &ib, &rng, Es);
    if (!spread) rays += emitter_rays(ic, g, voxel, &rng, Es);
    gi__face_light(g, (const float(*)[3])Es, gi__direct(L, slot));
    memcpy(gi__side(L, slot), gi__direct(L, slot), sizeof(gi_faces3));
  }
  atomic_fetch_add(&ic->rays, rays + ib.near_rays);
  if (ib.oom) atomic_store(&ic->failed, 1);
out:
  gi__near_free(&ib.ns);
  gi__scratch_free(&ib.sc);
  gi__free(ib.all);
  gi__free(ib.side);
  gi__free(ib.cosw);
  gi__free(ib.mis);
  gi__free(ib.near);
}

/* Radiance leaving through each face of an occupied voxel (reflection of
 * what the side it shows receives: side, or the irradiance given). A
 * glossy material's lobe reflects `gloss` of what arrives, around the
 * mirror direction (the reference's BRDF, reference.c); the texture keeps
 * one radiance per face, so it holds that light spread like the diffuse
 * part. Its energy reaches the gathers, its direction does not: without
 * it the city's glass walls reflected nothing of the lobe, and every
 * light's indirect light at the street read low (16.9% -> 15.6%). */
static inline void face_radiance(const gi_level *L, uint32_t slot, const float (*side)[3],
                                 float Lf[GI_VOX_FACES][3]) {
  const gi_vgeo *g = gi__geo(L, slot);
  if (!side) side = (const float(*)[3])gi__side(L, slot);
  for (int f = 0; f < GI_VOX_FACES; f++)
    for (int k = 0; k < 3; k++) Lf[f][k] = (g->albedo[k] + g->gloss[k]) * (1.0f / GI_PI_F) * side[f][k];
}

/* Occupied voxels [begin, end) of level d from `from` (per occupied voxel;
 * NULL: their side light). */
static void shade_range(struct gi_cascade *c, int d, uint32_t begin, uint32_t end, const gi_faces3 *from) {
  gi_level *L = &c->lv[d];
  float inv = 1.0f / c->rad_scale;
  for (uint32_t q = begin; q < end; q++) {
    uint32_t slot = L->occ[q];
    gi_vrad *r = &L->rad[slot];
    float Lf[GI_VOX_FACES][3];
    face_radiance(L, slot, from ? (const float(*)[3])from[q] : NULL, Lf);
    for (int f = 0; f < 6; f++) {
      float al = gi__vrad_alpha(r, f / 2) * inv;
      for (int k = 0; k < 3; k++) r->h[3 * f + k] = gi__f2h(al * Lf[f][k]);
    }
  }
}

void gi__shade_voxels(struct gi_cascade *c, int d, uint32_t begin, uint32_t end) {
  shade_range(c, d, begin, end, NULL);
}

/* shade_all's two passes, each one parallel loop over every level's own
 * voxels (level d's are [start[d], start[d + 1])): each worker keeps its
 * brightest face in peak[worker]. */
typedef struct {
  struct gi_cascade *c;
  gi_faces3 *const *from;
  size_t start[GI_MAX_LEVELS + 1];
  float peak[GI_MAX_WORKERS];
} shade_ctx;

static void peak_range(void *p, size_t b, size_t e, int worker) {
  shade_ctx *sc = p;
  float m = sc->peak[worker];
  int d = 0;
  for (size_t q = b; q < e; q++) {
    while (q >= sc->start[d + 1]) d++;
    const gi_level *L = &sc->c->lv[d];
    size_t i = q - sc->start[d];
    float Lf[GI_VOX_FACES][3];
    face_radiance(L, L->occ[i], sc->from ? (const float(*)[3])sc->from[d][i] : NULL, Lf);
    for (int f = 0; f < GI_VOX_FACES; f++)
      for (int k = 0; k < 3; k++) m = gi__maxf(m, Lf[f][k]);
  }
  sc->peak[worker] = m;
}

static void shade_all_range(void *p, size_t b, size_t e, int worker) {
  (void)worker;
  shade_ctx *sc = p;
  for (int d = 0; d < sc->c->n; d++) {
    size_t lo = b > sc->start[d] ? b : sc->start[d], hi = e < sc->start[d + 1] ? e : sc->start[d + 1];
    if (lo < hi)
      shade_range(sc->c, d, (uint32_t)(lo - sc->start[d]), (uint32_t)(hi - sc->start[d]), sc->from ? sc->from[d] : NULL);
  }
}

/* Every occupied voxel of every level, after choosing the texels' scale
 * for the brightest of them (filtering then rewrites the nested regions
 * at the same scale). Both passes run on the bake's threads: serial, they
 * were 2.1-2.4 ms of each move, twice, and of each bounce's end (the
 * city's 13.5k voxels). The maximum does not depend on the order. */
static void shade_all(struct gi_cascade *c, gi_faces3 *const from[]) {
  shade_ctx sc = {.c = c, .from = from};
  for (int d = 0; d < c->n; d++) sc.start[d + 1] = sc.start[d] + c->lv[d].num_occ;
  int threads = c->report.quality.threads, nw = gi__num_workers(threads);
  gi__parallel_for(sc.start[c->n], 256, threads, peak_range, &sc);
  float brightest = 0;
  for (int w = 0; w < nw; w++) brightest = gi__maxf(brightest, sc.peak[w]);
  gi__vrad_rescale(c, brightest);
  gi__parallel_for(sc.start[c->n], 256, threads, shade_all_range, &sc);
}

void gi__shade_all(struct gi_cascade *c) { shade_all(c, NULL); }

void gi__shade_all_from(struct gi_cascade *c, gi_faces3 *const from[]) { shade_all(c, from); }

gi_result gi__inject_levels(struct gi_cascade *c, const gi_quality *q, const uint32_t *const slots[],
                            const uint32_t count[], gi_error_info *err) {
  gi_light_plan lp = gi__light_plan(&c->report, q->light_samples);
  int cap = gi__light_sample_cap(c->scene, &lp);
  inject_ctx ic = {.c = c, .lp = &lp, .lp_other = lp, .slots = slots, .seed = q->seed, .cap = cap};
  ic.lp_other.emissive = 0;
  for (int d = 0; d < c->n; d++) ic.start[d + 1] = ic.start[d] + count[d];
  atomic_init(&ic.rays, 0);
  atomic_init(&ic.failed, 0);
  int cancelled = gi__parallel_for_cancel(ic.start[c->n], 32, q->threads, inject_range, &ic, &ic.failed, c->cancel);
  if (cancelled) return gi__cancel_fail(c->cancel, err, "inject");
  if (atomic_load(&ic.failed))
    return gi__fail(err, GI_ERR_NOMEM, "inject: out of memory for the light-sample buffers (%d samples)", cap);
  c->report.shadow_rays += atomic_load(&ic.rays);
  return GI_OK;
}

gi_result gi__inject(struct gi_cascade *c, const gi_quality *q, gi_error_info *err) {
  const uint32_t *slots[GI_MAX_LEVELS];
  uint32_t count[GI_MAX_LEVELS];
  for (int d = 0; d < c->n; d++) slots[d] = c->lv[d].occ, count[d] = c->lv[d].num_occ;
  gi_result rc = gi__inject_levels(c, q, slots, count, err);
  if (rc == GI_OK) gi__shade_all(c);
  return rc;
}
