/* uv.c: lightmap charts, each projected onto its plane.
 *
 * Design: the triangles whose centre lies in the region are taken in scene
 * order. Vertices are welded by exact position (a generator may repeat a
 * corner per quad), triangles sharing a welded edge are neighbours, and a
 * chart grows breadth-first from the lowest-numbered free triangle through
 * neighbours whose normal lies within GI_LM_CHART_COS of the seed's. So an
 * OSM wall is one chart and the layout depends on nothing but the scene
 * and the options. A chart is projected onto the plane of its area-weighted
 * normal, in a frame that keeps walls upright (v runs down the up axis)
 * and floors aligned with the world axes, at one texel per opts.texel. */
#include <stdlib.h>
#include <string.h>
#include "base/internal.h"
#include "lightmap/lightmap_internal.h"

typedef struct {
  uint64_t key;  /* welded vertex pair, smaller first */
  uint32_t tri;  /* index into the selection */
} edge;

static const float *vtx(const gi_scene *s, uint32_t tri, int j) { return s->vertices + 3 * (size_t)s->indices[3 * (size_t)tri + j]; }

static void tri_normal(const gi_scene *s, uint32_t tri, float n[3], float *area) {
  const float *a = vtx(s, tri, 0), *b = vtx(s, tri, 1), *c = vtx(s, tri, 2);
  float e1[3], e2[3];
  for (int k = 0; k < 3; k++) e1[k] = b[k] - a[k], e2[k] = c[k] - a[k];
  gi__cross(e1, e2, n);
  float l = gi__len(n);
  *area = 0.5f * l;
  for (int k = 0; k < 3; k++) n[k] = l > 0 ? n[k] / l : 0.f;
}

static int cmp_edge(const void *pa, const void *pb) {
  const edge *a = pa, *b = pb;
  if (a->key != b->key) return a->key < b->key ? -1 : 1;
  return a->tri < b->tri ? -1 : a->tri > b->tri;
}

/* canon[v] = the smallest vertex index at v's exact position. qsort has no
 * context argument (a file-level scene pointer would race between
 * threads), so a bottom-up merge sort orders the vertices by position. */
static gi_result weld(const gi_scene *s, uint32_t *canon, gi_error_info *err) {
  uint32_t nv = s->num_vertices;
  uint32_t *order = gi__malloc((nv ? nv : 1) * sizeof *order);
  if (!order) return gi__fail(err, GI_ERR_NOMEM, "lightmap: out of memory welding %u vertices", nv);
  for (uint32_t i = 0; i < nv; i++) order[i] = i;
  uint32_t *tmp = gi__malloc((nv ? nv : 1) * sizeof *tmp);
  if (!tmp) {
    gi__free(order);
    return gi__fail(err, GI_ERR_NOMEM, "lightmap: out of memory welding %u vertices", nv);
  }
  for (size_t width = 1; width < nv; width *= 2) {
    for (size_t lo = 0; lo < nv; lo += 2 * width) {
      size_t mid = lo + width < nv ? lo + width : nv, hi = lo + 2 * width < nv ? lo + 2 * width : nv;
      size_t i = lo, j = mid, k = lo;
      while (i < mid && j < hi) {
        const float *a = s->vertices + 3 * (size_t)order[i], *b = s->vertices + 3 * (size_t)order[j];
        int c = 0;
        for (int d = 0; d < 3 && !c; d++) c = a[d] < b[d] ? -1 : a[d] > b[d] ? 1 : 0;
        tmp[k++] = c <= 0 ? order[i++] : order[j++];
      }
      while (i < mid) tmp[k++] = order[i++];
      while (j < hi) tmp[k++] = order[j++];
    }
    memcpy(order, tmp, nv * sizeof *order);
  }
  /* Each run of equal positions takes its smallest index. */
  for (uint32_t r = 0; r < nv;) {
    uint32_t q = r + 1, least = order[r];
    while (q < nv && !memcmp(s->vertices + 3 * (size_t)order[q], s->vertices + 3 * (size_t)order[r], 3 * sizeof(float)))
      least = order[q] < least ? order[q] : least, q++;
    for (uint32_t i = r; i < q; i++) canon[order[i]] = least;
    r = q;
  }
  gi__free(order);
  gi__free(tmp);
  return GI_OK;
}

/* The selected triangles' neighbour lists (CSR: nb_start, nb). */
static gi_result neighbours(const gi_scene *s, const uint32_t *sel, size_t n, const uint32_t *canon,
                            uint32_t **nb_start, uint32_t **nb, gi_error_info *err) {
  edge *e = gi__malloc((n ? 3 * n : 1) * sizeof *e);
  uint32_t *cnt = gi__calloc(n + 1, sizeof *cnt);
  if (!e || !cnt) {
    gi__free(e);
    gi__free(cnt);
    return gi__fail(err, GI_ERR_NOMEM, "lightmap: out of memory for the edges of %zu triangles", n);
  }
  for (size_t i = 0; i < n; i++)
    for (int j = 0; j < 3; j++) {
      uint64_t a = canon[s->indices[3 * (size_t)sel[i] + j]], b = canon[s->indices[3 * (size_t)sel[i] + (j + 1) % 3]];
      e[3 * i + j].key = a < b ? a << 32 | b : b << 32 | a;
      e[3 * i + j].tri = (uint32_t)i;
    }
  qsort(e, 3 * n, sizeof *e, cmp_edge);
  /* Every pair within a run of equal keys is a neighbour pair. */
  size_t pairs = 0;
  for (size_t r = 0; r < 3 * n;) {
    size_t q = r;
    while (q < 3 * n && e[q].key == e[r].key) q++;
    for (size_t a = r; a < q; a++) cnt[e[a].tri] += (uint32_t)(q - r - 1), pairs += q - r - 1;
    r = q;
  }
  *nb_start = gi__malloc((n + 1) * sizeof **nb_start);
  *nb = gi__malloc((pairs ? pairs : 1) * sizeof **nb);
  if (!*nb_start || !*nb) {
    gi__free(e);
    gi__free(cnt);
    return gi__fail(err, GI_ERR_NOMEM, "lightmap: out of memory for %zu neighbour pairs", pairs);
  }
  (*nb_start)[0] = 0;
  for (size_t i = 0; i < n; i++) (*nb_start)[i + 1] = (*nb_start)[i] + cnt[i], cnt[i] = 0;
  for (size_t r = 0; r < 3 * n;) {
    size_t q = r;
    while (q < 3 * n && e[q].key == e[r].key) q++;
    for (size_t a = r; a < q; a++)
      for (size_t b = r; b < q; b++)
        if (a != b) (*nb)[(*nb_start)[e[a].tri] + cnt[e[a].tri]++] = e[b].tri;
    r = q;
  }
  gi__free(e);
  gi__free(cnt);
  return GI_OK;
}

/* The chart's projection frame: t x b = n, walls upright, floors on the world axes. */
static void chart_frame(const gi_scene *s, const float n[3], float t[3], float b[3]) {
  float up[3] = {0, s->up == GI_UP_Z ? 0.f : 1.f, s->up == GI_UP_Z ? 1.f : 0.f};
  /* Floors: v along the horizontal axis that is not x. */
  float side[3] = {0, s->up == GI_UP_Z ? -1.f : 0.f, s->up == GI_UP_Z ? 0.f : 1.f};
  const float *ref = fabsf(gi__dot(n, up)) > 0.7f ? side : up;
  float d = gi__dot(ref, n);
  for (int k = 0; k < 3; k++) b[k] = -(ref[k] - d * n[k]);
  float l = gi__len(b);
  for (int k = 0; k < 3; k++) b[k] /= l;
  gi__cross(b, n, t);
}

/* Projects chart c (its triangles lm->tri[first..]) and sizes it. */
static void project_chart(struct gi_lightmap *lm, gi_lm_chart *c) {
  const gi_scene *s = lm->scene;
  float n[3] = {0, 0, 0}, lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  for (size_t i = c->pub.first; i < c->pub.first + c->pub.count; i++) {
    float tn[3], a;
    tri_normal(s, lm->tri[i], tn, &a);
    for (int k = 0; k < 3; k++) n[k] += a * tn[k];
  }
  float l = gi__len(n);
  if (!(l > 0)) tri_normal(s, lm->tri[c->pub.first], n, &l);
  else for (int k = 0; k < 3; k++) n[k] /= l;
  memcpy(c->pub.normal, n, sizeof n);
  chart_frame(s, n, c->t, c->b);
  memcpy(c->o, vtx(s, lm->tri[c->pub.first], 0), sizeof c->o);
  float umin = INFINITY, vmin = INFINITY, umax = -INFINITY, vmax = -INFINITY, inv = (float)(1.0 / lm->opts.texel);
  for (size_t i = c->pub.first; i < c->pub.first + c->pub.count; i++)
    for (int j = 0; j < 3; j++) {
      const float *p = vtx(s, lm->tri[i], j);
      float d[3];
      for (int k = 0; k < 3; k++) d[k] = p[k] - c->o[k], lo[k] = fminf(lo[k], p[k]), hi[k] = fmaxf(hi[k], p[k]);
      float u = gi__dot(d, c->t) * inv, v = gi__dot(d, c->b) * inv;
      lm->uv[6 * i + 2 * j] = u, lm->uv[6 * i + 2 * j + 1] = v;
      umin = fminf(umin, u), vmin = fminf(vmin, v), umax = fmaxf(umax, u), vmax = fmaxf(vmax, v);
    }
  for (size_t i = 6 * c->pub.first; i < 6 * (c->pub.first + c->pub.count); i += 2)
    lm->uv[i] -= umin, lm->uv[i + 1] -= vmin;
  c->umin = umin, c->vmin = vmin;
  /* Texel j's centre sits at j: the content's edges fall on texel centres. */
  /* Clamped so a chart far too large for any atlas still has an int size (pack.c refuses it). */
  c->cw = (int)floorf(fminf(umax - umin, 4.f * GI_LIGHTMAP_MAX_ATLAS) + 0.5f) + 1;
  c->ch = (int)floorf(fminf(vmax - vmin, 4.f * GI_LIGHTMAP_MAX_ATLAS) + 0.5f) + 1;
  for (int k = 0; k < 3; k++) c->centre[k] = 0.5f * (lo[k] + hi[k]);
}

/* The region's triangles, in scene order. */
static gi_result select_tris(struct gi_lightmap *lm, uint32_t **sel, size_t *n, gi_error_info *err) {
  const gi_scene *s = lm->scene;
  *n = 0;
  *sel = gi__malloc((s->num_triangles ? s->num_triangles : 1) * sizeof **sel);
  if (!*sel) return gi__fail(err, GI_ERR_NOMEM, "lightmap: out of memory selecting triangles");
  for (uint32_t t = 0; t < s->num_triangles; t++) {
    int in = 1;
    for (int k = 0; k < 3; k++) {
      float c = (vtx(s, t, 0)[k] + vtx(s, t, 1)[k] + vtx(s, t, 2)[k]) / 3.f;
      in &= c >= lm->lo[k] && c <= lm->hi[k];
    }
    if (in) (*sel)[(*n)++] = t;
  }
  if (!*n) return gi__fail(err, GI_ERR_INVALID_ARG, "lightmap: region: no triangle of the scene has its centre in the region");
  return GI_OK;
}

/* Breadth-first charts over the neighbour lists; fills lm->tri chart by chart. */
static gi_result grow_charts(struct gi_lightmap *lm, const uint32_t *sel, size_t n, const uint32_t *nb_start,
                             const uint32_t *nb, gi_error_info *err) {
  int32_t *chart_of = gi__malloc(n * sizeof *chart_of);
  float *nrm = gi__malloc(3 * n * sizeof *nrm);
  lm->tri = gi__malloc(n * sizeof *lm->tri);
  lm->charts = gi__calloc(n, sizeof *lm->charts); /* at most one chart per triangle; trimmed below */
  if (!chart_of || !nrm || !lm->tri || !lm->charts) {
    gi__free(chart_of);
    gi__free(nrm);
    return gi__fail(err, GI_ERR_NOMEM, "lightmap: out of memory for the charts of %zu triangles", n);
  }
  for (size_t i = 0; i < n; i++) {
    float a;
    chart_of[i] = -1;
    tri_normal(lm->scene, sel[i], nrm + 3 * i, &a);
  }
  size_t out = 0, nc = 0;
  for (size_t seed = 0; seed < n; seed++) {
    if (chart_of[seed] >= 0) continue;
    gi_lm_chart *c = &lm->charts[nc];
    c->pub.first = out;
    size_t head = out;
    chart_of[seed] = (int32_t)nc;
    lm->tri[out++] = (uint32_t)seed; /* selection index for now */
    while (head < out) {
      uint32_t t = lm->tri[head++];
      for (uint32_t k = nb_start[t]; k < nb_start[t + 1]; k++) {
        uint32_t m = nb[k];
        if (chart_of[m] >= 0 || gi__dot(nrm + 3 * m, nrm + 3 * seed) < GI_LM_CHART_COS) continue;
        chart_of[m] = (int32_t)nc;
        lm->tri[out++] = m;
      }
    }
    c->pub.count = out - c->pub.first;
    nc++;
  }
  for (size_t i = 0; i < n; i++) lm->tri[i] = sel[lm->tri[i]];
  lm->num_tris = n;
  lm->num_charts = nc;
  gi__free(chart_of);
  gi__free(nrm);
  return GI_OK;
}

/* Share of the selected triangles' area whose UVs may have no area (float
 * rounding of a sliver) before the UV set counts as broken. */
#define UV_FLAT_SHARE 0.01
/* How far outside [0, 1] a UV may round (the file's float32, times the atlas). */
#define UV_SLACK 1e-4f

/* Share of the texels a UV set covers that a second triangle may claim too
 * (a mirrored or stacked island) before the set counts as broken: the bake
 * finds one triangle per texel, so the other surfaces would show its light. */
#define UV_OVERLAP_SHARE 0.01
/* A texel centre belongs to a triangle only this far (texels) inside its
 * row's span: neighbours across a shared edge never both take one. */
#define UV_INSET 0.01f

/* Row y's texels whose centres lie inside triangle u (texel units, 6
 * floats): [*x0, *x1], empty when *x0 > *x1. Each edge is evaluated from
 * its lower end, so two triangles sharing it meet at the same u. */
static void row_span(const float *u, int y, int N, int *x0, int *x1) {
  float vc = (float)y + 0.5f, lo = INFINITY, hi = -INFINITY;
  for (int e = 0; e < 3; e++) {
    const float *a = u + 2 * e, *b = u + 2 * ((e + 1) % 3);
    if (a[1] > b[1] || (a[1] == b[1] && a[0] > b[0])) {
      const float *t = a;
      a = b, b = t;
    }
    if (!(vc >= a[1] && vc <= b[1]) || a[1] == b[1]) continue;
    float x = a[0] + (vc - a[1]) * (b[0] - a[0]) / (b[1] - a[1]);
    lo = gi__minf(lo, x), hi = gi__maxf(hi, x);
  }
  *x0 = 1, *x1 = 0;
  if (!(lo + UV_INSET < hi - UV_INSET)) return;
  float a = ceilf(lo + UV_INSET - 0.5f), b = floorf(hi - UV_INSET - 0.5f);
  *x0 = a > 0 ? (int)a : 0;
  *x1 = b < (float)(N - 1) ? (int)b : N - 1;
}

/* Rows of triangle u that may hold texel centres, clamped to the atlas. */
static void tri_rows(const float *u, int N, int *y0, int *y1) {
  float lo = gi__minf(u[1], gi__minf(u[3], u[5])), hi = gi__maxf(u[1], gi__maxf(u[3], u[5]));
  float a = ceilf(lo - 0.5f), b = floorf(hi - 0.5f);
  *y0 = a > 0 ? (int)a : 0;
  *y1 = b < (float)(N - 1) ? (int)b : N - 1;
}

/* No texel may belong to two triangles of the scene's UV set beyond
 * UV_OVERLAP_SHARE of those it covers. Fails naming a pair and a texel. */
static gi_result check_uv_overlap(const struct gi_lightmap *lm, const uint32_t *sel, size_t n, const char *way,
                                  gi_error_info *err) {
  int N = lm->opts.atlas;
  /* Texels claimed once, and twice or more: each shared texel counts once
   * (counting every extra claim read 3700% for 38 triangles on one spot). */
  uint64_t *bits = gi__calloc(((size_t)N * N + 63) / 64, sizeof *bits);
  uint64_t *multi = bits ? gi__calloc(((size_t)N * N + 63) / 64, sizeof *multi) : NULL;
  if (!multi) {
    gi__free(bits);
    return gi__fail(err, GI_ERR_NOMEM, "lightmap: out of memory checking the UV set of a %d atlas", N);
  }
  size_t covered = 0, twice = 0, first = SIZE_MAX;
  int fx = 0, fy = 0;
  for (size_t i = 0; i < n; i++) {
    const float *u = &lm->uv[6 * i];
    int y0, y1, x0, x1;
    tri_rows(u, N, &y0, &y1);
    for (int y = y0; y <= y1; y++) {
      row_span(u, y, N, &x0, &x1);
      for (int x = x0; x <= x1; x++) {
        size_t t = (size_t)y * N + (size_t)x;
        if (bits[t / 64] >> (t % 64) & 1) {
          if (!twice) first = i, fx = x, fy = y;
          if (!(multi[t / 64] >> (t % 64) & 1)) multi[t / 64] |= 1ull << (t % 64), twice++;
        } else {
          bits[t / 64] |= 1ull << (t % 64), covered++;
        }
      }
    }
  }
  gi__free(bits);
  gi__free(multi);
  if (!(twice > UV_OVERLAP_SHARE * (double)covered)) return GI_OK;
  size_t other = 0; /* the earlier triangle that claimed the first shared texel */
  for (size_t j = 0; j < first; j++) {
    int x0, x1;
    row_span(&lm->uv[6 * j], fy, N, &x0, &x1);
    if (fx >= x0 && fx <= x1) {
      other = j;
      break;
    }
  }
  return gi__fail(err, GI_ERR_FORMAT,
                  "lightmap: the scene's own lightmap UVs (its second UV set) overlap: %.1f%% of the texels they "
                  "cover belong to two triangles or more (triangles %u and %u share texel %d, %d of the %d atlas), "
                  "and a texel holds one surface's light; %s", 100.0 * (double)twice / (double)covered, sel[other],
                  sel[first], fx, fy, N, way);
}

/* The scene's UV set must be a lightmap layout: inside [0, 1] (outside, the
 * texels fell off the atlas: a UV set moved by a whole tile baked nothing)
 * and with area (all UVs at one point gathered one texel for the whole
 * atlas), and without overlaps. Fails naming the first bad triangle and
 * the way out. */
static gi_result check_scene_uv(const struct gi_lightmap *lm, const uint32_t *sel, size_t n, double *surface,
                                double *texels, gi_error_info *err) {
  const gi_scene *s = lm->scene;
  float N = (float)lm->opts.atlas, lo = -UV_SLACK * N, hi = (1 + UV_SLACK) * N;
  size_t outside = 0, first = SIZE_MAX;
  int bad = 0; /* first's vertex outside */
  double area = 0, flat = 0, covered = 0;
  for (size_t i = 0; i < n; i++) {
    const float *u = &lm->uv[6 * i];
    int out = 0;
    for (int j = 0; j < 3; j++)
      if (!(u[2 * j] >= lo && u[2 * j] <= hi && u[2 * j + 1] >= lo && u[2 * j + 1] <= hi)) {
        if (!out && first == SIZE_MAX) first = i, bad = j;
        out = 1;
      }
    outside += (size_t)out;
    const uint32_t *ix = &s->indices[3 * (size_t)sel[i]];
    float e1[3], e2[3], x[3];
    for (int k = 0; k < 3; k++)
      e1[k] = s->vertices[3 * (size_t)ix[1] + k] - s->vertices[3 * (size_t)ix[0] + k],
      e2[k] = s->vertices[3 * (size_t)ix[2] + k] - s->vertices[3 * (size_t)ix[0] + k];
    gi__cross(e1, e2, x);
    double a = 0.5 * gi__len(x), uv_area = 0.5 * fabs((double)(u[2] - u[0]) * (u[5] - u[1]) - (double)(u[4] - u[0]) * (u[3] - u[1]));
    area += a, covered += uv_area;
    if (!(uv_area > 1e-6)) flat += a; /* under a millionth of a texel */
  }
  *surface = area, *texels = covered;
  const char *way = "fix the UV set, or make charts instead (gi-bake --own-charts, gi_lightmap_opts.scene_uv = -1)";
  if (outside)
    return gi__fail(err, GI_ERR_FORMAT,
                    "lightmap: the scene's own lightmap UVs (its second UV set) put %zu of %zu triangles outside [0, 1] "
                    "(triangle %u has %g, %g); %s", outside, n, sel[first], lm->uv[6 * first + 2 * bad] / N,
                    lm->uv[6 * first + 2 * bad + 1] / N, way);
  if (flat > UV_FLAT_SHARE * area)
    return gi__fail(err, GI_ERR_FORMAT,
                    "lightmap: the scene's own lightmap UVs (its second UV set) give %.1f%% of the surface no area on "
                    "the atlas; %s", 100 * flat / area, way);
  return check_uv_overlap(lm, sel, n, way, err);
}

/* The scene's own lightmap UVs: every selected triangle in one chart that
 * covers the whole atlas, in texel units (texel centres at j + 0.5), and
 * opts.texel the mean world side of their texels. */
static gi_result scene_chart(struct gi_lightmap *lm, uint32_t *sel, size_t n, gi_error_info *err) {
  const gi_scene *s = lm->scene;
  lm->charts = gi__calloc(1, sizeof *lm->charts);
  lm->uv = gi__malloc(6 * n * sizeof *lm->uv);
  if (!lm->charts || !lm->uv) return gi__fail(err, GI_ERR_NOMEM, "lightmap: out of memory for %zu triangles", n);
  float N = (float)lm->opts.atlas, lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  for (size_t i = 0; i < n; i++)
    for (int j = 0; j < 3; j++) {
      uint32_t v = s->indices[3 * (size_t)sel[i] + j];
      lm->uv[6 * i + 2 * j] = s->uv2[2 * (size_t)v] * N;
      lm->uv[6 * i + 2 * j + 1] = s->uv2[2 * (size_t)v + 1] * N;
      for (int k = 0; k < 3; k++) lo[k] = fminf(lo[k], s->vertices[3 * (size_t)v + k]), hi[k] = fmaxf(hi[k], s->vertices[3 * (size_t)v + k]);
    }
  double area, covered;
  gi_result rc = check_scene_uv(lm, sel, n, &area, &covered, err);
  if (rc != GI_OK) return rc;
  /* The texel the UVs give (the EXR's gi.texel, the tiles' margins): the
   * mean side, from the surface's area over the texels it covers. The
   * caller's texel, unused here, was written as if it had been. */
  lm->opts.texel = sqrt(area / covered);
  gi_lm_chart *c = &lm->charts[0];
  c->pub.count = n;
  c->cw = c->ch = lm->opts.atlas;
  for (int k = 0; k < 3; k++) c->centre[k] = 0.5f * (lo[k] + hi[k]);
  lm->tri = sel;
  lm->num_tris = n;
  lm->num_charts = 1;
  return GI_OK;
}

gi_result gi__lm_charts(struct gi_lightmap *lm, gi_error_info *err) {
  const gi_scene *s = lm->scene;
  uint32_t *sel = NULL, *canon = NULL, *nb_start = NULL, *nb = NULL;
  size_t n = 0;
  gi_result rc = select_tris(lm, &sel, &n, err);
  if (rc == GI_OK && lm->scene_uv) {
    rc = scene_chart(lm, sel, n, err);
    if (rc != GI_OK) gi__free(sel);
    return rc;
  }
  if (rc == GI_OK && !(canon = gi__malloc((s->num_vertices ? s->num_vertices : 1) * sizeof *canon)))
    rc = gi__fail(err, GI_ERR_NOMEM, "lightmap: out of memory welding vertices");
  if (rc == GI_OK) rc = weld(s, canon, err);
  if (rc == GI_OK) rc = neighbours(s, sel, n, canon, &nb_start, &nb, err);
  if (rc == GI_OK) rc = grow_charts(lm, sel, n, nb_start, nb, err);
  if (rc == GI_OK && !(lm->uv = gi__malloc(6 * n * sizeof *lm->uv)))
    rc = gi__fail(err, GI_ERR_NOMEM, "lightmap: out of memory for the UVs of %zu triangles", n);
  if (rc == GI_OK)
    for (size_t c = 0; c < lm->num_charts; c++) project_chart(lm, &lm->charts[c]);
  gi__free(sel);
  gi__free(canon);
  gi__free(nb_start);
  gi__free(nb);
  return rc;
}
