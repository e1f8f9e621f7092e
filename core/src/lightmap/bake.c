/* bake.c: gi_lightmap_bake, every texel's irradiance from a cascade.
 *
 * Design. The region is cut into a grid of tiles no wider than opts.tile
 * (default: 0.8 of the coarsest cascade level, smaller until every tile's
 * cascade, as the bake places it, holds its texels: place_tiles);
 * each texel belongs to the tile holding its anchor (the first point of its
 * footprint on its chart), and each tile with texels is one cascade bake,
 * gathered, then freed: memory stays one cascade. (By its chart's centre, a
 * ground plane's texels all went to the middle tile, and those far from it
 * read the coarse levels there.) A texel takes supersample^2 points of its footprint; each point
 * finds its triangle through the chart's bins (or the nearest point of the
 * nearest triangle within half a texel, so texels straddling a chart's
 * edge see the surface, not what lies beyond it), is tested for lying
 * inside geometry (most of a few hemisphere rays hit back faces), and is
 * gathered by the surface rule (answer/surface.c). The texel keeps the
 * mean of its valid points on its centre's side of any geometry crossing
 * its footprint (a wall thinner than a texel standing on it). Every point's random stream comes from the
 * seed and its atlas position, so the result does not depend on tiles or
 * threads. Afterwards, invalid texels and gutters are filled layer by
 * layer from their already-filled neighbours in the same chart. */
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "answer/answer.h"
#include "base/internal.h"
#include "gi/gi_cascade.h"
#include "lightmap/lightmap_internal.h"
#include "plan.h"
#include "scene/lights.h"
#include "trace/trace.h"

/* Default tile side as a fraction of the coarsest level's side. */
#define GI_LM_TILE_FRACTION 0.8
/* A default tile whose cascade leaves texels outside shrinks by this
 * factor, at most this many times. */
#define GI_LM_SHRINK 0.75
#define GI_LM_SHRINK_TRIES 12
/* The most tiles one bake takes: each is a cascade bake. */
#define GI_LM_MAX_TILES (1 << 20)
/* A footprint point farther than this (texels) from its chart is not on it. */
#define GI_LM_EDGE_REACH 0.5f
/* How far such a point moves toward its triangle's centre (a fraction of the way). */
#define GI_LM_INSET 0.01f
/* Rays that decide whether a point lies inside geometry, and the share of
 * back-face hits above which it does. */
#define GI_LM_INSIDE_RAYS 12
#define GI_LM_INSIDE_SHARE 0.5f
/* A texel's points reach each other along its surface unless a triangle
 * crosses the path between them; triangles this near parallel to the
 * surface are its own facets (twice the chart angle, GI_LM_CHART_COS),
 * passed at most this many times, each time resuming this share of the
 * path further. */
#define GI_LM_SAME_SURFACE_COS (2 * GI_LM_CHART_COS * GI_LM_CHART_COS - 1)
#define GI_LM_REACH_PASSES 4
#define GI_LM_REACH_EPS 1e-4f

/* A texel of a tile's list: its chart, and its place in the chart's rectangle. */
#define GI_LM_TEXEL(chart, dx, dy) ((uint64_t)(chart) << 32 | (uint64_t)(dy) << 16 | (uint64_t)(dx))

typedef struct {
  const gi_lightmap *lm;
  const struct gi_cascade *c;
  const uint64_t *texels;      /* GI_LM_TEXEL entries */
  int samples, cap;
  const gi_cancel *cancel;     /* checked per texel too (tile_texels) */
  atomic_int failed;
  atomic_size_t reached;       /* every texel a chunk started lies below it */
} tile_ctx;

/* Nearest point of 2D triangle (a, b, c) to p as barycentrics; returns the squared distance. */
static float nearest_bary(const float *uv, const float p[2], float bary[3]) {
  const float *a = uv, *b = uv + 2, *c = uv + 4;
  float e0[2] = {b[0] - a[0], b[1] - a[1]}, e1[2] = {c[0] - a[0], c[1] - a[1]}, d[2] = {p[0] - a[0], p[1] - a[1]};
  float den = e0[0] * e1[1] - e0[1] * e1[0];
  float v = (d[0] * e1[1] - d[1] * e1[0]) / den, w = (e0[0] * d[1] - e0[1] * d[0]) / den;
  if (v >= 0 && w >= 0 && v + w <= 1) {
    bary[0] = 1 - v - w, bary[1] = v, bary[2] = w;
    return 0;
  }
  /* Outside: the nearest of the three edges. */
  float best = INFINITY;
  const float *P[3] = {a, b, c};
  for (int i = 0; i < 3; i++) {
    const float *s = P[i], *e = P[(i + 1) % 3];
    float se[2] = {e[0] - s[0], e[1] - s[1]}, sp[2] = {p[0] - s[0], p[1] - s[1]};
    float l2 = se[0] * se[0] + se[1] * se[1];
    float t = l2 > 0 ? fminf(1.f, fmaxf(0.f, (sp[0] * se[0] + sp[1] * se[1]) / l2)) : 0.f;
    float dx = sp[0] - t * se[0], dy = sp[1] - t * se[1], d2 = dx * dx + dy * dy;
    if (d2 < best) {
      best = d2;
      bary[0] = bary[1] = bary[2] = 0;
      bary[i] = 1 - t, bary[(i + 1) % 3] = t;
    }
  }
  return best;
}

/* The lightmap triangle under atlas point p of chart c, else the nearest
 * within reach (*outside = 1; its point pulled a little inside, so it is
 * not on the edge a neighbouring wall starts from); -1 if none. */
static long find_tri(const gi_lightmap *lm, const gi_lm_chart *c, const float p[2], float bary[3], int *outside) {
  int bx = (int)((p[0] - (float)c->pub.x) / GI_LM_BIN), by = (int)((p[1] - (float)c->pub.y) / GI_LM_BIN);
  if (bx < 0 || by < 0 || bx >= c->bins_x || by >= c->bins_y) return -1;
  size_t b = (size_t)by * c->bins_x + bx;
  long best = -1;
  float bd = GI_LM_EDGE_REACH * GI_LM_EDGE_REACH, tb[3];
  for (uint32_t k = c->bin_start[b]; k < c->bin_start[b + 1]; k++) {
    uint32_t t = c->bin_tri[k];
    float d2 = nearest_bary(lm->uv + 6 * (size_t)t, p, tb);
    if (d2 <= bd) {
      bd = d2, best = (long)t;
      memcpy(bary, tb, sizeof tb);
      if (d2 == 0) break;
    }
  }
  *outside = bd > 0;
  if (best >= 0 && *outside)
    for (int j = 0; j < 3; j++) bary[j] = (1 - GI_LM_INSET) * bary[j] + GI_LM_INSET / 3;
  return best;
}

/* The texel's footprint point p (its sub-point `sub`, row-major). */
static void sub_point(int x, int y, int ss, int sub, float p[2]) {
  p[0] = (float)x + ((float)(sub % ss) + 0.5f) / (float)ss;
  p[1] = (float)y + ((float)(sub / ss) + 0.5f) / (float)ss;
}

/* The chart's surface point under atlas point p: its triangle and local
 * position. pass 0 takes points inside the chart's triangles only, pass 1
 * the nearest edge points too; 0 when p is on neither. */
static int chart_point(const gi_lightmap *lm, const gi_lm_chart *c, const float p[2], int pass, uint32_t *tri,
                       float X[3]) {
  const gi_scene *s = lm->scene;
  float bary[3] = {0, 0, 0};
  int outside;
  long t = find_tri(lm, c, p, bary, &outside);
  if (t < 0 || (outside && pass == 0)) return 0;
  *tri = lm->tri[t];
  for (int k = 0; k < 3; k++) X[k] = 0;
  for (int j = 0; j < 3; j++)
    for (int k = 0; k < 3; k++) X[k] += bary[j] * s->vertices[3 * (size_t)s->indices[3 * (size_t)*tri + j] + k];
  return 1;
}

/* The texel's anchor: the first of its footprint points on the chart, in
 * bake_texel's order (pass 0's first, else pass 1's); 0 when it has none
 * (a gutter). Local coordinates. */
static int texel_anchor_tri(const gi_lightmap *lm, const gi_lm_chart *c, int x, int y, float X[3], uint32_t *tri) {
  int ss = lm->opts.supersample;
  for (int pass = 0; pass < 2; pass++)
    for (int sub = 0; sub < ss * ss; sub++) {
      float p[2];
      sub_point(x, y, ss, sub, p);
      if (chart_point(lm, c, p, pass, tri, X)) return 1;
    }
  return 0;
}

static int texel_anchor(const gi_lightmap *lm, const gi_lm_chart *c, int x, int y, float X[3]) {
  uint32_t tri;
  return texel_anchor_tri(lm, c, x, y, X, &tri);
}

/* Up to TILE_HINTS of a tile's texels, evenly spread over its list, as
 * the plan's answer points (cascade_internal.h): anchor and its triangle's
 * unit normal. Returns how many. */
#define TILE_HINTS 32
static int tile_hints(const gi_lightmap *lm, const uint64_t *texels, size_t nj, float out[TILE_HINTS][6]) {
  int n = 0;
  size_t want = nj < TILE_HINTS ? nj : TILE_HINTS;
  for (size_t i = 0; i < want; i++) {
    uint64_t t = texels[i * nj / want];
    const gi_lm_chart *c = &lm->charts[t >> 32];
    uint32_t tri;
    if (!texel_anchor_tri(lm, c, c->pub.x + (int)(t & 0xffff), c->pub.y + (int)(t >> 16 & 0xffff), out[n], &tri))
      continue;
    const uint32_t *ix = &lm->scene->indices[3 * (size_t)tri];
    const float *A = &lm->scene->vertices[3 * ix[0]], *B = &lm->scene->vertices[3 * ix[1]];
    const float *C = &lm->scene->vertices[3 * ix[2]];
    float e1[3], e2[3], nrm[3];
    for (int k = 0; k < 3; k++) e1[k] = B[k] - A[k], e2[k] = C[k] - A[k];
    gi__cross(e1, e2, nrm);
    float len = gi__len(nrm);
    if (!(len > 0)) continue;
    for (int k = 0; k < 3; k++) out[n][3 + k] = nrm[k] / len;
    n++;
  }
  return n;
}

/* Back-face share of a few rays over the hemisphere of n from x, and whether any front face was hit. */
static float backface_share(const gi_scene *s, const float x[3], const float n[3], float reach, int *front) {
  float t[3], b[3];
  gi__basis(n, t, b);
  int back = 0;
  *front = 0;
  for (int i = 0; i < GI_LM_INSIDE_RAYS; i++) {
    /* A fixed spiral of directions: deterministic, spread over the hemisphere. */
    float z = 1.f - ((float)i + 0.5f) / GI_LM_INSIDE_RAYS, r = sqrtf(fmaxf(0.f, 1 - z * z));
    float phi = 2.39996323f * (float)i, w[3], o[3], th, ng[3];
    for (int k = 0; k < 3; k++) w[k] = r * cosf(phi) * t[k] + r * sinf(phi) * b[k] + z * n[k];
    float tn = gi__shadow_origin(x, n, reach, w, o);
    uint32_t tri;
    if (!gi__intersect1(s, o, w, tn, INFINITY, &th, &tri, ng)) continue;
    if (gi__dot(ng, w) > 0) back++;
    else *front = 1;
  }
  return (float)back / GI_LM_INSIDE_RAYS;
}

/* The side of triangle tri to gather at x: its winding normal, the other
 * side when that one is inside geometry but the other sees front faces
 * (a surface wound the wrong way), else 0 (the point is inside). */
static int surface_side(const gi_scene *s, uint32_t tri, const float x[3], float reach, float n[3]) {
  const float *v0 = s->vertices + 3 * (size_t)s->indices[3 * (size_t)tri];
  const float *v1 = s->vertices + 3 * (size_t)s->indices[3 * (size_t)tri + 1];
  const float *v2 = s->vertices + 3 * (size_t)s->indices[3 * (size_t)tri + 2];
  float e1[3], e2[3];
  for (int k = 0; k < 3; k++) e1[k] = v1[k] - v0[k], e2[k] = v2[k] - v0[k];
  gi__cross(e1, e2, n);
  float l = gi__len(n);
  for (int k = 0; k < 3; k++) n[k] /= l;
  int front;
  if (backface_share(s, x, n, reach, &front) <= GI_LM_INSIDE_SHARE) return 1;
  float m[3] = {-n[0], -n[1], -n[2]};
  if (backface_share(s, x, m, reach, &front) <= GI_LM_INSIDE_SHARE && front) {
    memcpy(n, m, sizeof m);
    return 1;
  }
  return 0;
}

/* Whether geometry lies between surface points a and b (unit normals na,
 * nb): the straight path between them lifted by `lift` along their
 * normals meets a triangle. Hits on triangles within twice the chart
 * angle of na (either side) are the surface itself (the chord across a
 * convex fold of a chart dips under the lift) and are passed. */
static int surface_blocked(const gi_scene *s, const float a[3], const float na[3], const float b[3],
                           const float nb[3], float lift) {
  float o[3], e[3], w[3];
  for (int k = 0; k < 3; k++) o[k] = a[k] + lift * na[k], e[k] = b[k] + lift * nb[k] - o[k];
  float len = gi__len(e), t0 = 0;
  if (!(len > 0)) return 0;
  for (int k = 0; k < 3; k++) w[k] = e[k] / len;
  for (int i = 0; i < GI_LM_REACH_PASSES; i++) {
    float th, ng[3];
    uint32_t t;
    if (!gi__intersect1(s, o, w, t0, len, &th, &t, ng)) return 0;
    if (fabsf(gi__dot(ng, na)) < GI_LM_SAME_SURFACE_COS) return 1;
    t0 = th + GI_LM_REACH_EPS * len;
  }
  return 1;
}

/* Of a texel's valid points pt[0..nv) (triangles tri), keeps one group
 * of points that reach each other along the surface (surface_blocked; a
 * group is the points its first reaches): when geometry crosses the
 * footprint, the group its centre reaches most of, or the largest (the
 * first on a tie) when the centre lies inside geometry or reaches none.
 * A wall thinner than half a texel standing on a floor left points on
 * both sides valid, and the texel beside a dark room read half the lit
 * side's light. Moves the kept points to the front, in order; returns
 * how many. */
static int reachable_points(const gi_lightmap *lm, const gi_lm_chart *c, int x, int y, float reach,
                            gi_surface_pt *pt, uint32_t *tri, int nv) {
  enum { MAXP = GI_LIGHTMAP_MAX_SUPERSAMPLE * GI_LIGHTMAP_MAX_SUPERSAMPLE };
  const gi_scene *s = lm->scene;
  float lift = gi__shadow_offset(reach);
  int group[MAXP], size[MAXP] = {0}, seen[MAXP] = {0}, ng = 0, keep = 0;
  for (int v = 0; v < nv; v++) group[v] = -1;
  for (int v = 0; v < nv; v++) {
    if (group[v] >= 0) continue;
    group[v] = ng, size[ng] = 1;
    for (int u = v + 1; u < nv; u++)
      if (group[u] < 0 && !surface_blocked(s, pt[v].x, pt[v].n, pt[u].x, pt[u].n, lift)) group[u] = ng, size[ng]++;
    ng++;
  }
  if (ng <= 1) return nv;
  float ctr[2] = {(float)x + 0.5f, (float)y + 0.5f}, X[3], n[3];
  uint32_t ct;
  if ((chart_point(lm, c, ctr, 0, &ct, X) || chart_point(lm, c, ctr, 1, &ct, X)) && surface_side(s, ct, X, reach, n))
    for (int v = 0; v < nv; v++) seen[group[v]] += !surface_blocked(s, X, n, pt[v].x, pt[v].n, lift);
  for (int k = 1; k < ng; k++)
    if (seen[k] > seen[keep] || (seen[k] == seen[keep] && size[k] > size[keep])) keep = k;
  int k = 0;
  for (int v = 0; v < nv; v++)
    if (group[v] == keep) pt[k] = pt[v], tri[k] = tri[v], k++;
  return k;
}

/* One texel: the mean over the valid points of its footprint that lie on
 * the chart and on its centre's side of any geometry crossing it
 * (reachable_points); a texel the chart only grazes takes the nearest
 * edge points. */
static void bake_texel(tile_ctx *g, const gi_lm_chart *c, gi_lm_atlas *a, int atlas, int x, int y,
                       gi_ray_scratch *sc) {
  const gi_scene *s = g->lm->scene;
  int ss = g->lm->opts.supersample, nv = 0;
  float acc[5][3] = {{0}}; /* radiance, direct, indirect, point, normal */
  float reach = -1; /* the voxel at the texel's anchor (texel_anchor), its first point on the chart */
  uint64_t seed = gi__mix64(g->c->report.quality.seed ^
                            ((uint64_t)atlas << 48 | (uint64_t)(uint32_t)y << 24 | (uint32_t)x));
  /* The footprint's valid points first, then their light in one call:
   * their gathers march together. */
  gi_surface_pt pt[GI_LIGHTMAP_MAX_SUPERSAMPLE * GI_LIGHTMAP_MAX_SUPERSAMPLE];
  uint32_t tri[GI_LIGHTMAP_MAX_SUPERSAMPLE * GI_LIGHTMAP_MAX_SUPERSAMPLE];
  for (int pass = 0; pass < 2 && !nv; pass++)
    for (int sub = 0; sub < ss * ss; sub++) {
      float p[2];
      sub_point(x, y, ss, sub, p);
      if (!chart_point(g->lm, c, p, pass, &tri[nv], pt[nv].x)) continue;
      if (reach < 0) reach = gi__voxel_at(g->c, pt[nv].x);
      /* Not inside geometry: from the side that is not (surface_side). */
      if (!surface_side(s, tri[nv], pt[nv].x, reach, pt[nv].n)) continue;
      pt[nv++].seed = gi__mix64(seed + (uint64_t)sub);
    }
  nv = reachable_points(g->lm, c, x, y, reach, pt, tri, nv);
  float E[GI_LIGHTMAP_MAX_SUPERSAMPLE * GI_LIGHTMAP_MAX_SUPERSAMPLE][3];
  float I[GI_LIGHTMAP_MAX_SUPERSAMPLE * GI_LIGHTMAP_MAX_SUPERSAMPLE][3];
  gi__surface_irradiance(g->c, pt, (size_t)nv, g->samples, sc, E, I);
  for (int v = 0; v < nv; v++) {
    const float *alb = gi__tri_albedo(s, tri[v]);
    for (int k = 0; k < 3; k++) {
      acc[0][k] += alb[k] * (E[v][k] + I[v][k]) / GI_PI_F;
      acc[1][k] += E[v][k], acc[2][k] += I[v][k], acc[3][k] += pt[v].x[k], acc[4][k] += pt[v].n[k];
    }
  }
  if (!nv) return;
  size_t i = (size_t)y * a->w + x;
  float nl = gi__len(acc[4]);
  for (int k = 0; k < 3; k++) {
    a->radiance[3 * i + k] = acc[0][k] / (float)nv;
    a->direct[3 * i + k] = acc[1][k] / (float)nv;
    a->indirect[3 * i + k] = acc[2][k] / (float)nv;
    a->irradiance[3 * i + k] = a->direct[3 * i + k] + a->indirect[3 * i + k];
    a->point[3 * i + k] = acc[3][k] / (float)nv;
    a->normal[3 * i + k] = nl > 0 ? acc[4][k] / nl : 0.f;
  }
  a->valid[i] = 1.f;
}

static void tile_texels(void *p, size_t b, size_t e, int worker) {
  (void)worker;
  tile_ctx *g = p;
  gi_ray_scratch sc = {0};
  /* Chunks start in order: a cancelled bake wrote below the highest end. */
  size_t seen = atomic_load(&g->reached);
  while (seen < e && !atomic_compare_exchange_weak(&g->reached, &seen, e)) {
  }
  if (gi__scratch_alloc(&sc, g->cap)) {
    atomic_store(&g->failed, 1);
    return;
  }
  for (size_t j = b; j < e; j++) {
    /* A chunk of 64 texels at supersample 8 is 4096 gathers: checked
     * between chunks only, a cancelled bake ran on for 100-300 ms (a
     * helper session's probes; 5 s under ASan on a loaded machine). */
    if (gi_cancel_check(g->cancel)) break;
    uint64_t t = g->texels[j];
    const gi_lm_chart *c = &g->lm->charts[t >> 32];
    gi_lm_atlas *a = &g->lm->atlases[c->pub.atlas];
    bake_texel(g, c, a, c->pub.atlas, c->pub.x + (int)(t & 0xffff), c->pub.y + (int)(t >> 16 & 0xffff), &sc);
  }
  gi__scratch_free(&sc);
}

/* The tile grid: tiles of `size` from the region's corner lm->lo, nreg
 * of them over the region, and whole tiles beyond it where texels lie more
 * than half a tile past it (a triangle whose centre is in the region may
 * reach far out: in its edge tile those texels lay outside every level of
 * the tile's cascade). Tile index i along an axis is grid cell first + i. */
typedef struct {
  int nt[3], nreg[3], first[3];
  double size[3];
} lm_grid;

/* The grid cell holding p along axis k: within half a tile past the
 * region, the region's edge tile. */
static int64_t grid_cell(const gi_lightmap *lm, const lm_grid *g, const float p[3], int k) {
  if (!(g->size[k] > 0)) return 0;
  double v = floor(((double)p[k] - lm->lo[k]) / g->size[k]);
  if (v < 0 && (double)p[k] >= lm->lo[k] - 0.5 * g->size[k]) v = 0;
  if (v > g->nreg[k] - 1 && (double)p[k] <= lm->hi[k] + 0.5 * g->size[k]) v = g->nreg[k] - 1;
  /* Anchors lie on the scene's triangles, so within float range: clamp only for safety. */
  return (int64_t)fmax(fmin(v, 1e9), -1e9);
}

/* Texels between two looks at the cancel token in the loops over every
 * texel (a mask: every 65536). */
#define CANCEL_EVERY 0xffff

/* The grid for tiles of side at most `side` over the region and the
 * anchors anc[0..total) (3 floats each, NaN: none). 0 when its tiles number
 * more than max (g->nt then says how many along each axis), -1 when the
 * cancel token fired. */
static int grid_make(const gi_lightmap *lm, double side, const float *anc, size_t total, size_t max,
                     const gi_cancel *cancel, lm_grid *g) {
  int64_t lo[3] = {0, 0, 0}, hi[3];
  for (int k = 0; k < 3; k++) {
    double ext = (double)lm->hi[k] - lm->lo[k];
    double n = ceil(ext / side);
    g->nreg[k] = n < 1 ? 1 : n > 4096 ? 4096 : (int)n;
    g->size[k] = ext / g->nreg[k];
    hi[k] = g->nreg[k] - 1;
  }
  for (size_t i = 0; i < total; i++) {
    const float *p = anc + 3 * i;
    if (!(i & CANCEL_EVERY) && gi_cancel_check(cancel)) return -1;
    if (isnan(p[0])) continue;
    for (int k = 0; k < 3; k++) {
      int64_t v = grid_cell(lm, g, p, k);
      if (v < lo[k]) lo[k] = v;
      if (v > hi[k]) hi[k] = v;
    }
  }
  uint64_t count = 1;
  for (int k = 0; k < 3; k++) {
    uint64_t n = (uint64_t)(hi[k] - lo[k] + 1);
    g->first[k] = (int)lo[k];
    g->nt[k] = n > (uint64_t)INT32_MAX ? INT32_MAX : (int)n;
    count = count > max ? count : count * n;
  }
  return count <= max;
}

static int tile_of(const gi_lightmap *lm, const lm_grid *g, const float p[3]) {
  int id[3];
  for (int k = 0; k < 3; k++) {
    int64_t v = grid_cell(lm, g, p, k) - g->first[k];
    id[k] = v < 0 ? 0 : v >= g->nt[k] ? g->nt[k] - 1 : (int)v;
  }
  return (id[2] * g->nt[1] + id[1]) * g->nt[0] + id[0];
}

/* Tile t's centre (world). */
static void tile_centre(const gi_lightmap *lm, const lm_grid *g, size_t t, double at[3]) {
  size_t id[3] = {t % (size_t)g->nt[0], t / (size_t)g->nt[0] % (size_t)g->nt[1], t / ((size_t)g->nt[0] * g->nt[1])};
  for (int k = 0; k < 3; k++)
    at[k] = lm->scene->origin[k] + lm->lo[k] + ((double)g->first[k] + (double)id[k] + 0.5) * g->size[k];
}

/* One tile: bake its cascade, gather its texels, free the cascade. */
static gi_result bake_tile(gi_lightmap *lm, const gi_quality *q, const gi_cancel *cancel, const uint64_t *texels,
                           size_t nj, const double at[3], size_t *reached, gi_lightmap_report *rep,
                           gi_error_info *err) {
  gi_cascade *c = NULL;
  gi_result rc = GI_OK;
  double t0 = gi__now_ms();
  gi_bake_report br;
  float hints[TILE_HINTS][6];
  int nh = tile_hints(lm, texels, nj, hints);
  if ((rc = gi__cascade_bake_at(lm->scene, at, q, cancel, &hints[0][0], nh, &c, &br, err)) != GI_OK) goto done;
  double t1 = gi__now_ms();
  const gi_quality *rq = &br.quality;
  int ss = lm->opts.supersample;
  /* The probe's light-sample budget, shared by the texel's footprint points. */
  int samples = rq->probe_samples / (ss * ss);
  tile_ctx g = {.lm = lm, .c = c, .texels = texels, .samples = samples < 1 ? 1 : samples, .cancel = cancel};
  gi_light_plan lp = gi__answer_light_plan(lm->scene, &br, g.samples);
  g.cap = gi__light_sample_cap(lm->scene, &lp);
  atomic_init(&g.failed, 0);
  atomic_init(&g.reached, 0);
  lm->written = 1;
  int stopped = gi__parallel_for_cancel(nj, 64, rq->threads, tile_texels, &g, &g.failed, cancel);
  *reached = atomic_load(&g.reached);
  if (stopped) {
    rc = gi__cancel_fail(cancel, err, "lightmap");
    goto done;
  }
  if (atomic_load(&g.failed)) {
    rc = gi__fail(err, GI_ERR_NOMEM, "lightmap: out of memory for the light-sample buffers (%d samples)", g.cap);
    goto done;
  }
  rep->cascade_ms += t1 - t0;
  rep->gather_ms += gi__now_ms() - t1;
  rep->ms.plan += br.ms.plan;
  rep->ms.voxelize += br.ms.voxelize;
  rep->ms.inject += br.ms.inject;
  rep->ms.filter += br.ms.filter;
  rep->ms.bounce += br.ms.bounce;
  for (int i = 0; i < GI_FX_COUNT; i++) {
    if (rep->tiles == 0 || (br.effects[i].ran && !rep->effect_tiles[i])) rep->effects[i] = br.effects[i];
    rep->effect_tiles[i] += br.effects[i].ran != 0;
  }
  rep->tiles++;
done:
  gi_cascade_free(c);
  return rc;
}

/* Every chart texel's anchor (NaN: none), charts in parallel;
 * anc[3 * (base[i] + dy * w + dx)] for chart i's rectangle. */
typedef struct {
  const gi_lightmap *lm;
  const size_t *base;
  float *anc;
  const gi_cancel *cancel; /* checked per row: one ground chart holds 10^5-10^6 texels */
} anchor_ctx;

static void anchor_charts(void *p, size_t b, size_t e, int worker) {
  (void)worker;
  anchor_ctx *x = p;
  for (size_t i = b; i < e; i++) {
    const gi_lm_chart *c = &x->lm->charts[i];
    float *X = x->anc + 3 * x->base[i];
    for (int dy = 0; dy < c->pub.h; dy++) {
      if (gi_cancel_check(x->cancel)) return; /* the caller sees the token and drops every anchor */
      for (int dx = 0; dx < c->pub.w; dx++, X += 3)
        if (!texel_anchor(x->lm, c, c->pub.x + dx, c->pub.y + dy, X)) X[0] = NAN;
    }
  }
}

/* The anchors of every chart texel (anchor_charts), found once whatever
 * the tiles: *base[i] is chart i's first texel, *total their count. */
static gi_result texel_anchors(const gi_lightmap *lm, int threads, const gi_cancel *cancel, size_t **base,
                               float **anc, size_t *total, gi_error_info *err) {
  size_t n = 0;
  *anc = NULL;
  if (!(*base = gi__malloc((lm->num_charts + 1) * sizeof **base)))
    return gi__fail(err, GI_ERR_NOMEM, "lightmap: out of memory for %zu charts", lm->num_charts);
  for (size_t i = 0; i < lm->num_charts; i++) (*base)[i] = n, n += (size_t)lm->charts[i].pub.w * lm->charts[i].pub.h;
  *total = n;
  if (!(*anc = gi__malloc((n ? n : 1) * 3 * sizeof **anc)))
    return gi__fail(err, GI_ERR_NOMEM, "lightmap: out of memory for the anchors of %zu texels", n);
  anchor_ctx ax = {.lm = lm, .base = *base, .anc = *anc, .cancel = cancel};
  if (gi__parallel_for_cancel(lm->num_charts, 1, threads, anchor_charts, &ax, NULL, cancel) ||
      gi_cancel_check(cancel))
    return gi__cancel_fail(cancel, err, "lightmap texel anchors");
  return GI_OK;
}

/* The texels of each tile of g, [start[t], start[t + 1]) of list
 * (counting sort: chart order, then row-major, inside a tile), and the box
 * of their anchors, box[t] = lo[3], hi[3] (local; empty for a tile without). */
static gi_result texels_by_tile(const gi_lightmap *lm, const lm_grid *g, const size_t *base, const float *anc,
                                size_t total, const gi_cancel *cancel, size_t **start, uint64_t **list,
                                float (**box)[6], gi_error_info *err) {
  size_t ntiles = (size_t)g->nt[0] * g->nt[1] * g->nt[2], listed = 0;
  *start = gi__calloc(ntiles + 1, sizeof **start);
  *box = gi__malloc((ntiles ? ntiles : 1) * sizeof **box);
  int32_t *tid = gi__malloc((total ? total : 1) * sizeof *tid);
  if (!*start || !*box || !tid) {
    gi__free(tid);
    return gi__fail(err, GI_ERR_NOMEM, "lightmap: out of memory for the tiles of %zu texels", total);
  }
  for (size_t t = 0; t < ntiles; t++)
    for (int k = 0; k < 3; k++) (*box)[t][k] = INFINITY, (*box)[t][3 + k] = -INFINITY;
  for (size_t k = 0; k < total; k++) {
    if (!(k & CANCEL_EVERY) && gi_cancel_check(cancel)) {
      gi__free(tid);
      return gi__cancel_fail(cancel, err, "lightmap tiles");
    }
    tid[k] = isnan(anc[3 * k]) ? -1 : tile_of(lm, g, anc + 3 * k);
    if (tid[k] >= 0) (*start)[tid[k] + 1]++, listed++;
  }
  for (size_t t = 0; t < ntiles; t++) (*start)[t + 1] += (*start)[t];
  *list = gi__malloc((listed ? listed : 1) * sizeof **list);
  size_t *fill = gi__calloc(ntiles ? ntiles : 1, sizeof *fill);
  if (!*list || !fill) {
    gi__free(tid), gi__free(fill);
    return gi__fail(err, GI_ERR_NOMEM, "lightmap: out of memory for the tiles of %zu texels", listed);
  }
  for (size_t i = 0; i < lm->num_charts; i++) {
    const gi_lm_chart *c = &lm->charts[i];
    for (int dy = 0; dy < c->pub.h; dy++)
      for (int dx = 0; dx < c->pub.w; dx++) {
        size_t k = base[i] + (size_t)dy * c->pub.w + dx;
        int32_t t = tid[k];
        if (t < 0) continue;
        (*list)[(*start)[t] + fill[t]++] = GI_LM_TEXEL(i, dx, dy);
        for (int a = 0; a < 3; a++)
          (*box)[t][a] = fminf((*box)[t][a], anc[3 * k + a]), (*box)[t][3 + a] = fmaxf((*box)[t][3 + a], anc[3 * k + a]);
      }
  }
  gi__free(tid), gi__free(fill);
  return GI_OK;
}

/* Fills texel i from the filled 8-neighbours of the same chart (stamp < layer); 0 when none. */
static int fill_from_neighbours(gi_lm_atlas *a, size_t i, const int *stamp, int layer) {
  int x = (int)(i % (size_t)a->w), y = (int)(i / (size_t)a->w), n = 0;
  float acc[4][3] = {{0}};
  for (int dy = -1; dy <= 1; dy++)
    for (int dx = -1; dx <= 1; dx++) {
      int u = x + dx, v = y + dy;
      if ((!dx && !dy) || u < 0 || v < 0 || u >= a->w || v >= a->h) continue;
      size_t j = (size_t)v * a->w + u;
      if (a->chart[j] != a->chart[i] || stamp[j] < 0 || stamp[j] >= layer) continue; /* unfilled or this layer */
      for (int k = 0; k < 3; k++)
        acc[0][k] += a->radiance[3 * j + k], acc[1][k] += a->direct[3 * j + k], acc[2][k] += a->indirect[3 * j + k];
      n++;
    }
  if (!n) return 0;
  for (int k = 0; k < 3; k++) {
    a->radiance[3 * i + k] = acc[0][k] / (float)n;
    a->direct[3 * i + k] = acc[1][k] / (float)n;
    a->indirect[3 * i + k] = acc[2][k] / (float)n;
    a->irradiance[3 * i + k] = a->direct[3 * i + k] + a->indirect[3 * i + k];
  }
  return 1;
}

/* Appends to next the unstamped, unqueued texels of i's chart around i. */
static void queue_neighbours(const gi_lm_atlas *a, size_t i, int *stamp, size_t *next, size_t *nn) {
  int x = (int)(i % (size_t)a->w), y = (int)(i / (size_t)a->w);
  for (int dy = -1; dy <= 1; dy++)
    for (int dx = -1; dx <= 1; dx++) {
      int u = x + dx, v = y + dy;
      if (u < 0 || v < 0 || u >= a->w || v >= a->h) continue;
      size_t j = (size_t)v * a->w + u;
      if (stamp[j] != -1 || a->chart[j] != a->chart[i]) continue;
      stamp[j] = -2; /* queued */
      next[(*nn)++] = j;
    }
}

/* Layer by layer (a breadth-first front, so every texel is visited a
 * bounded number of times), each chart texel without a value of its own
 * takes the mean of its neighbours filled in earlier layers (the valid
 * texels are layer 0): invalid interiors and gutters grow in from the surface. */
static gi_result fill_atlas(gi_lm_atlas *a, uint64_t *filled, gi_error_info *err) {
  size_t n = (size_t)a->w * a->h, nf = 0, nn = 0;
  int *stamp = gi__malloc(n * sizeof *stamp);
  size_t *front = gi__malloc(n * sizeof *front), *next = gi__malloc(n * sizeof *next);
  if (!stamp || !front || !next) {
    gi__free(stamp);
    gi__free(front);
    gi__free(next);
    return gi__fail(err, GI_ERR_NOMEM, "lightmap: out of memory filling a %d x %d atlas", a->w, a->h);
  }
  for (size_t i = 0; i < n; i++) stamp[i] = a->valid[i] > 0 ? 0 : -1;
  for (size_t i = 0; i < n; i++)
    if (stamp[i] == 0) queue_neighbours(a, i, stamp, front, &nf);
  for (int layer = 1; nf; layer++) {
    for (size_t k = 0; k < nf; k++)
      if (fill_from_neighbours(a, front[k], stamp, layer)) (*filled)++;
    for (size_t k = 0; k < nf; k++) stamp[front[k]] = layer;
    nn = 0;
    for (size_t k = 0; k < nf; k++) queue_neighbours(a, front[k], stamp, next, &nn);
    size_t *t = front;
    front = next, next = t, nf = nn;
  }
  gi__free(stamp);
  gi__free(front);
  gi__free(next);
  return GI_OK;
}

/* Every atlas's gathered arrays to zero: unbaked. Only when a bake wrote
 * them (lm->written): a 4096^2 atlas is 1.25 GiB, and zeroing the fresh
 * layout's atlases held a cancelled bake 0.5 s before its first tile and
 * again after. In place: callers may hold the arrays across bakes. */
static void clear_atlases(gi_lightmap *lm) {
  if (!lm->written) return;
  for (size_t a = 0; a < lm->num_atlases; a++) {
    gi_lm_atlas *A = &lm->atlases[a];
    size_t n = (size_t)A->w * A->h;
    float *rgb[] = {A->radiance, A->irradiance, A->direct, A->indirect, A->point, A->normal};
    for (size_t i = 0; i < sizeof rgb / sizeof rgb[0]; i++) memset(rgb[i], 0, 3 * n * sizeof(float));
    memset(A->valid, 0, n * sizeof(float));
  }
  lm->written = 0;
}

/* Zeroes the listed texels (GI_LM_TEXEL entries) of the atlases: what the
 * tiles of a failed bake wrote, before the fill reached the gutters. Only
 * up to where the failed tile's chunks reached (tile_ctx.reached): zeroing
 * its whole list wrote pages nothing had touched, and a cancelled 4096^2
 * lightmap answered its deadline 231 ms late for 907,082 texels. */
static void clear_texels(gi_lightmap *lm, const uint64_t *texels, size_t n) {
  for (size_t j = 0; j < n; j++) {
    const gi_lm_chart *c = &lm->charts[texels[j] >> 32];
    gi_lm_atlas *A = &lm->atlases[c->pub.atlas];
    size_t i = (size_t)(c->pub.y + (int)(texels[j] >> 16 & 0xffff)) * A->w + c->pub.x + (int)(texels[j] & 0xffff);
    float *rgb[] = {A->radiance, A->irradiance, A->direct, A->indirect, A->point, A->normal};
    for (size_t r = 0; r < sizeof rgb / sizeof rgb[0]; r++) memset(rgb[r] + 3 * i, 0, 3 * sizeof(float));
    A->valid[i] = 0;
  }
  lm->written = 0;
}

/* How far a texel's footprint points may lie from its anchor, in texels
 * (its own square, and the half texel a point may snap to its chart). */
#define GI_LM_FOOTPRINT_TEXELS 2.0

/* *in = 1 when the cascade baked at `at` holds box b (lo[3], hi[3],
 * local) with `margin` around it, within the scene's bounds (gathered
 * points lie on its triangles), inside its coarsest level less the
 * one-voxel border gi_cascade_covers keeps (finer levels lie inside it). */
static gi_result cascade_holds(const gi_lightmap *lm, const gi_quality *rq, const double at[3], const float b[6],
                               double margin, int *in, gi_error_info *err) {
  struct gi_cascade *c;
  gi_result rc = gi__cascade_placed(lm->scene, at, rq, "lightmap", &c, err);
  if (rc != GI_OK) return rc;
  const gi_level *L = &c->lv[c->n - 1];
  *in = 1;
  for (int k = 0; k < 3; k++) {
    double lo = fmax(b[k] - margin, lm->scene->lo[k]), hi = fmin(b[3 + k] + margin, lm->scene->hi[k]);
    *in &= lo >= (double)L->lo[k] + L->s && hi <= (double)L->hi[k] - L->s;
  }
  gi__free(c);
  return GI_OK;
}

/* The viewpoint of each tile holding texels (tat[t], world): its centre,
 * or, when its cascade there would leave some of its texels outside every
 * level (their indirect light would read 0), the centre of its texels'
 * box. *held = 1 when every tile's cascade holds its texels, else 0 and
 * *bad says which tile does not. At res 8 the default tile, 0.8 of the
 * coarsest level, reached past its border: 84% of the Cornell box's
 * texels read no indirect light. */
static gi_result place_tiles(const gi_lightmap *lm, const gi_quality *rq, const gi_cancel *cancel, const lm_grid *g,
                             const size_t *start, const float (*box)[6], double (*tat)[3], int *held, size_t *bad,
                             gi_error_info *err) {
  double margin = GI_LM_FOOTPRINT_TEXELS * lm->opts.texel;
  size_t ntiles = (size_t)g->nt[0] * g->nt[1] * g->nt[2];
  *held = 1;
  for (size_t t = 0; t < ntiles; t++) {
    if (start[t] == start[t + 1]) continue;
    if (gi_cancel_check(cancel)) return gi__cancel_fail(cancel, err, "lightmap tiles");
    int in;
    tile_centre(lm, g, t, tat[t]);
    gi_result rc = cascade_holds(lm, rq, tat[t], box[t], margin, &in, err);
    if (rc == GI_OK && !in) {
      /* Its texels off its centre (past the region, within half a tile). */
      for (int k = 0; k < 3; k++) tat[t][k] = lm->scene->origin[k] + 0.5 * ((double)box[t][k] + box[t][3 + k]);
      rc = cascade_holds(lm, rq, tat[t], box[t], margin, &in, err);
    }
    if (rc != GI_OK) return rc;
    if (!in) {
      *held = 0, *bad = t;
      return GI_OK;
    }
  }
  return GI_OK;
}

/* The tiles' texels (start, list) and viewpoints (tat) for quality rq:
 * the default side shrinks until every tile's cascade holds its texels; a
 * side the caller chose that does not is refused (as is a grid of more
 * than GI_LM_MAX_TILES), nothing changed. */
typedef struct {
  lm_grid g;
  size_t *start;
  uint64_t *list;
  float (*box)[6];
  double (*tat)[3];
} lm_tiling;

static void tiling_free(lm_tiling *T) {
  gi__free(T->start), gi__free(T->list), gi__free(T->box), gi__free(T->tat);
  T->start = NULL, T->list = NULL, T->box = NULL, T->tat = NULL;
}

static gi_result plan_tiling(const gi_lightmap *lm, const gi_quality *rq, const gi_cancel *cancel, const size_t *base,
                             const float *anc, size_t total, lm_tiling *T, gi_error_info *err) {
  double side = lm->opts.tile > 0 ? lm->opts.tile
                                  : GI_LM_TILE_FRACTION * rq->res * rq->voxel0 * (double)(1u << (rq->levels - 1));
  for (int tries = 0;; tries++) {
    /* Each tile is a cascade bake: past this many the request is a mistake (and tile ids stay ints). */
    /* "raise tile" said to a caller who gave none (the default shrank) was no help. */
    int fits = grid_make(lm, side, anc, total, GI_LM_MAX_TILES, cancel, &T->g);
    if (fits < 0) return gi__cancel_fail(cancel, err, "lightmap tiles");
    if (!fits)
      return gi__fail(err, GI_ERR_LIMIT, "lightmap: tiles of side %g cut the region and its texels into %d x %d x %d "
                      "tiles, more than %d cascade bakes: %s", side, T->g.nt[0], T->g.nt[1], T->g.nt[2],
                      GI_LM_MAX_TILES, lm->opts.tile > 0 ? "raise tile" :
                      "the default tile shrank to fit its cascade; use a larger voxel, more levels or a smaller region");
    size_t ntiles = (size_t)T->g.nt[0] * T->g.nt[1] * T->g.nt[2], bad = 0;
    gi_result rc = texels_by_tile(lm, &T->g, base, anc, total, cancel, &T->start, &T->list, &T->box, err);
    if (rc != GI_OK) return rc;
    if (!(T->tat = gi__malloc((ntiles ? ntiles : 1) * sizeof *T->tat)))
      return gi__fail(err, GI_ERR_NOMEM, "lightmap: out of memory for %zu tiles", ntiles);
    int held = 0;
    rc = place_tiles(lm, rq, cancel, &T->g, T->start, (const float(*)[6])T->box, T->tat, &held, &bad, err);
    if (rc != GI_OK || held) return rc;
    if (lm->opts.tile > 0 || tries >= GI_LM_SHRINK_TRIES) {
      const double *o = lm->scene->origin;
      const float *b = T->box[bad];
      return gi__fail(err, GI_ERR_INVALID_ARG, "lightmap: texels of the tile of side %g at (%g, %g, %g) .. (%g, %g, "
                      "%g) lie outside its cascade (%d levels of %d voxels, the finest %g): their indirect light would "
                      "be 0; %s", side, b[0] + o[0], b[1] + o[1], b[2] + o[2], b[3] + o[0], b[4] + o[1], b[5] + o[2],
                      rq->levels, rq->res, rq->voxel0,
                      lm->opts.tile > 0 ? "use a smaller tile (the default shrinks until it fits) or more levels"
                                        : "use more levels or a larger res");
    }
    tiling_free(T);
    side *= GI_LM_SHRINK;
  }
}

/* One bounce count for every tile: each tile's cascade plans its own
 * (the brightest level's albedo round the tile), so a room's tiles took 4
 * bounces and the tail and the ground's beside them 2, and the light
 * stepped at their border. Left to the plan (q's bounces automatic), the
 * tiles share the most any of them plans and the tail if any adds it; an
 * explicit count is every tile's already. *tq: q with that count; *shared
 * 1 when it was chosen here. */
static gi_result shared_bounces(const gi_lightmap *lm, const gi_quality *q, const gi_cancel *cancel, const lm_tiling *T,
                                gi_quality *tq, int *shared, gi_error_info *err) {
  gi_quality z = {0};
  *tq = q ? *q : z;
  *shared = 0;
  if (tq->bounces != 0) return GI_OK;
  int most = 0, tail = 0;
  for (size_t t = 0; t < (size_t)T->g.nt[0] * T->g.nt[1] * T->g.nt[2]; t++) {
    if (T->start[t] == T->start[t + 1]) continue;
    if (gi_cancel_check(cancel)) return gi__cancel_fail(cancel, err, "lightmap effect plan");
    gi_effect fx[GI_FX_COUNT];
    gi_quality r;
    float hints[TILE_HINTS][6]; /* as bake_tile gives its bake: the same sky test */
    int nh = tile_hints(lm, T->list + T->start[t], T->start[t + 1] - T->start[t], hints);
    gi_result rc = gi__effect_plan_for(lm->scene, T->tat[t], q, &hints[0][0], nh, fx, &r, err);
    if (rc != GI_OK) return rc;
    if (!fx[GI_FX_BOUNCE].ran) continue;
    most = r.bounces > most ? r.bounces : most;
    tail |= r.bounce_tail;
  }
  tq->bounces = most > 0 ? most : -1;
  tq->bounce_tail = tail;
  *shared = 1;
  return GI_OK;
}

gi_result gi_lightmap_bake(gi_lightmap *lm, const gi_quality *q, const gi_cancel *cancel,
                           gi_lightmap_report *report, gi_error_info *err) {
  if (!lm) return gi__fail(err, GI_ERR_INVALID_ARG, "lightmap: lightmap is NULL");
  double t0 = gi__now_ms();
  gi_lightmap_report rep = {.triangles = lm->num_tris, .charts = lm->num_charts, .atlases = lm->num_atlases,
                            .layout_ms = lm->layout_ms};
  gi_quality rq;
  gi_result rc = gi_quality_resolve(lm->scene, q, &rq, err);
  if (rc != GI_OK) return rc;
  lm_tiling T = {0};
  size_t *base = NULL, total = 0;
  float *anc = NULL;
  int cleared = 0;
  /* Refused requests leave a baked lightmap as it was; from the first
   * tile's bake on, a failed one (cancelled, or a tile whose cascade
   * fails) clears the atlases at `done`: tiles baked before the failure
   * beside zeros were not a lightmap. */
  double ts = gi__now_ms();
  rc = texel_anchors(lm, rq.threads, cancel, &base, &anc, &total, err);
  if (rc == GI_OK) rc = plan_tiling(lm, &rq, cancel, base, anc, total, &T, err);
  rep.sort_ms = gi__now_ms() - ts;
  gi_quality tq;
  int shared = 0;
  if (rc == GI_OK) rc = shared_bounces(lm, q, cancel, &T, &tq, &shared, err);
  if (rc != GI_OK) goto done;
  clear_atlases(lm), cleared = 1;
  size_t reached = 0; /* T.list[0, reached): the texels the tiles so far may have written */
  for (size_t t = 0; t < (size_t)T.g.nt[0] * T.g.nt[1] * T.g.nt[2] && rc == GI_OK; t++)
    if (T.start[t] != T.start[t + 1]) {
      size_t got = 0;
      rc = bake_tile(lm, &tq, cancel, T.list + T.start[t], T.start[t + 1] - T.start[t], T.tat[t], &got, &rep, err);
      reached = T.start[t] + got;
    }
  if (rc != GI_OK) {
    if (lm->written) clear_texels(lm, T.list, reached);
    goto done;
  }
  if (shared && rep.effect_tiles[GI_FX_BOUNCE])
    snprintf(rep.effects[GI_FX_BOUNCE].why, sizeof rep.effects[GI_FX_BOUNCE].why,
             "%d bounces%s in every tile: the most any tile's plan chose (one count: no step at their borders)",
             tq.bounces, tq.bounce_tail ? " and the geometric tail" : "");
  double tf = gi__now_ms();
  for (size_t a = 0; a < lm->num_atlases && rc == GI_OK; a++) {
    const gi_lm_atlas *A = &lm->atlases[a];
    for (size_t i = 0; i < (size_t)A->w * A->h; i++) {
      rep.texels += A->chart[i] >= 0;
      rep.texels_valid += A->valid[i] > 0;
    }
    rc = fill_atlas(&lm->atlases[a], &rep.texels_filled, err);
  }
  rep.fill_ms = gi__now_ms() - tf;
  /* Filling finishes what the gathers left: one stage, as in a probe answer. */
  rep.ms.gather = rep.gather_ms + rep.fill_ms;
done:
  tiling_free(&T);
  gi__free(base);
  gi__free(anc);
  if (rc != GI_OK && cleared) clear_atlases(lm);
  rep.bake_ms = gi__now_ms() - t0;
  if (report) *report = rep;
  return rc;
}
