/* scene.c: the mesh builder and the immutable, reference-counted scene.
 *
 * Design: a gi_mesh_builder collects world positions in double, triangles and
 * materials in growable arrays; it never fails loudly on its own (add_* have
 * no result), so an allocation failure or an index overflow is remembered in
 * the builder and reported by gi_scene_build. Building classifies every
 * triangle in double precision (non-finite, degenerate or kept), chooses the
 * origin as the centre of the kept triangles' bounds, and stores only the
 * vertices the kept triangles use, as float relative to that origin; this
 * keeps sub-millimetre resolution for scenes far from the world origin.
 * Materials are sanitised (albedo clamped to [0,1], non-finite values to 0,
 * negative emission to 0), emissive triangles become a power-weighted CDF
 * for light sampling, and the Embree BVH is built last (bvh_embree.c). A
 * builder with no materials gets one default grey diffuse material, so a
 * quick test or generator need not define one. After gi_scene_build returns
 * the scene is read-only; only its reference count changes. */
#include <float.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "base/internal.h"
#include "scene/lights.h"
#include "scene/scene_internal.h"

struct gi_mesh_builder {
  double *v;          /* 3 per vertex */
  size_t nv, cap_v;
  uint32_t *tri;      /* 3 per triangle */
  uint32_t *mat;      /* 1 per triangle */
  size_t nt, cap_t, cap_mt;
  gi_material *mats;
  size_t nm, cap_m;
  float *uv2;         /* 2 per vertex up to cap_uv2/2: lightmap UVs, NaN when unset */
  size_t cap_uv2;
  float *col;         /* 3 per vertex up to cap_col/3: vertex colours, 1 when unset; NULL: none */
  size_t cap_col;
  uint64_t bad_col;   /* vertex colours given with a NaN or infinite channel (taken as white) */
  float *talb;        /* 3 per triangle up to cap_talb/3: albedo overrides, NaN when unset; NULL: none */
  size_t cap_talb;
  int oom;            /* an add_* ran out of memory */
  int overflow;       /* more than 2^32-1 vertices or materials */
  char bad[160];      /* the first call given a bad argument, for gi_scene_build's error; "" when none */
};

/* Grows *p (elements of size sz) so that it holds at least need elements. */
static int grow(void **p, size_t *cap, size_t need, size_t sz) {
  if (need <= *cap) return 1;
  size_t nc = *cap ? *cap : 64;
  while (nc < need) nc *= 2;
  if (nc > SIZE_MAX / sz) return 0;
  void *q = gi__realloc(*p, nc * sz);
  if (!q) return 0;
  *p = q;
  *cap = nc;
  return 1;
}

gi_mesh_builder *gi_mesh_builder_new(void) {
  return gi__calloc(1, sizeof(gi_mesh_builder));
}

void gi_mesh_builder_free(gi_mesh_builder *b) {
  if (!b) return;
  gi__free(b->v);
  gi__free(b->tri);
  gi__free(b->mat);
  gi__free(b->mats);
  gi__free(b->uv2);
  gi__free(b->col);
  gi__free(b->talb);
  gi__free(b);
}

/* Notes the first bad argument: the void add_* and set_* calls cannot
 * fail, so gi_scene_build reports it, naming the call. */
static void note_bad(gi_mesh_builder *b, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void note_bad(gi_mesh_builder *b, const char *fmt, ...) {
  if (b->bad[0]) return;
  va_list ap;
  va_start(ap, fmt);
  vsnprintf(b->bad, sizeof b->bad, fmt, ap);
  va_end(ap);
}

/* Item i's `width` floats of the per-item array *p (capacity *cap floats),
 * grown to `items` items with the new part set to `unset`; NULL (flagged
 * in b) when i is past the items or out of memory. The builder's optional
 * per-vertex and per-triangle attributes all live in such arrays. `call`
 * and `item` name them for the error. */
static float *item_slot(gi_mesh_builder *b, float **p, size_t *cap, size_t items, size_t i, int width, float unset,
                        const char *call, const char *item) {
  if (i >= items) {
    note_bad(b, "%s: %s %zu, but the builder has %zu", call, item, i, items);
    return NULL;
  }
  size_t old = *cap;
  if (!grow((void **)p, cap, (size_t)width * items, sizeof **p)) { b->oom = 1; return NULL; }
  for (size_t k = old; k < *cap; k++) (*p)[k] = unset;
  return *p + (size_t)width * i;
}

void gi_mesh_builder_set_vertex_color(gi_mesh_builder *b, uint32_t vertex, double r, double g, double bl) {
  float *c = item_slot(b, &b->col, &b->cap_col, b->nv, vertex, 3, 1.f,
                       "gi_mesh_builder_set_vertex_color", "vertex");
  const double v[3] = {r, g, bl};
  /* Not a colour: the vertex keeps its material's albedo, counted as a correction. */
  if (c && !(isfinite(r) && isfinite(g) && isfinite(bl))) b->bad_col++;
  for (int k = 0; c && k < 3; k++) c[k] = isfinite(v[k]) ? (float)v[k] : 1.f;
}

size_t gi_mesh_builder_num_triangles(const gi_mesh_builder *b) { return b ? b->nt : 0; }

void gi_mesh_builder_set_triangle_albedo(gi_mesh_builder *b, size_t tri, double r, double g, double bl) {
  float *a = item_slot(b, &b->talb, &b->cap_talb, b->nt, tri, 3, NAN,
                       "gi_mesh_builder_set_triangle_albedo", "triangle");
  const double v[3] = {r, g, bl};
  for (int k = 0; a && k < 3; k++) a[k] = isfinite(v[k]) ? (float)v[k] : NAN;
}

void gi_mesh_builder_set_lightmap_uv(gi_mesh_builder *b, uint32_t vertex, double u, double v) {
  float *t = item_slot(b, &b->uv2, &b->cap_uv2, b->nv, vertex, 2, NAN,
                       "gi_mesh_builder_set_lightmap_uv", "vertex");
  if (t) t[0] = (float)u, t[1] = (float)v;
}

uint32_t gi_mesh_builder_add_material(gi_mesh_builder *b, const gi_material *m) {
  if (!m) {
    note_bad(b, "gi_mesh_builder_add_material: m is NULL");
    return UINT32_MAX;
  }
  if (b->nm >= UINT32_MAX) { b->overflow = 1; return UINT32_MAX; }
  if (!grow((void **)&b->mats, &b->cap_m, b->nm + 1, sizeof *b->mats)) { b->oom = 1; return UINT32_MAX; }
  b->mats[b->nm] = *m;
  b->mats[b->nm].name[sizeof m->name - 1] = 0;
  return (uint32_t)b->nm++;
}

uint32_t gi_mesh_builder_add_vertex(gi_mesh_builder *b, double x, double y, double z) {
  if (!b) return UINT32_MAX;
  if (b->nv >= UINT32_MAX) { b->overflow = 1; return UINT32_MAX; }
  if (!grow((void **)&b->v, &b->cap_v, 3 * (b->nv + 1), sizeof *b->v)) { b->oom = 1; return UINT32_MAX; }
  double *p = b->v + 3 * b->nv;
  p[0] = x; p[1] = y; p[2] = z;
  return (uint32_t)b->nv++;
}

void gi_mesh_builder_add_triangle(gi_mesh_builder *b, uint32_t a, uint32_t c, uint32_t d, uint32_t material) {
  if (!grow((void **)&b->tri, &b->cap_t, 3 * (b->nt + 1), sizeof *b->tri) ||
      !grow((void **)&b->mat, &b->cap_mt, b->nt + 1, sizeof *b->mat)) {
    b->oom = 1;
    return;
  }
  uint32_t *t = b->tri + 3 * b->nt;
  t[0] = a; t[1] = c; t[2] = d;
  b->mat[b->nt++] = material;
}

void gi_mesh_builder_add_quad(gi_mesh_builder *b, const double a[3], const double bb[3],
                              const double c[3], const double d[3], uint32_t material) {
  uint32_t ia = gi_mesh_builder_add_vertex(b, a[0], a[1], a[2]);
  uint32_t ib = gi_mesh_builder_add_vertex(b, bb[0], bb[1], bb[2]);
  uint32_t ic = gi_mesh_builder_add_vertex(b, c[0], c[1], c[2]);
  uint32_t id = gi_mesh_builder_add_vertex(b, d[0], d[1], d[2]);
  gi_mesh_builder_add_triangle(b, ia, ib, ic, material);
  gi_mesh_builder_add_triangle(b, ia, ic, id, material);
}

void gi_mesh_builder_add_box(gi_mesh_builder *b, const double lo[3], const double hi[3], uint32_t material) {
  /* Corner k has x = hi when bit 0 is set, y with bit 1, z with bit 2. */
  uint32_t c[8];
  for (int k = 0; k < 8; k++)
    c[k] = gi_mesh_builder_add_vertex(b, (k & 1) ? hi[0] : lo[0], (k & 2) ? hi[1] : lo[1],
                                      (k & 4) ? hi[2] : lo[2]);
  /* Each face counter-clockwise seen from outside. */
  static const int face[6][4] = {
      {0, 4, 6, 2}, /* -x */
      {1, 3, 7, 5}, /* +x */
      {0, 1, 5, 4}, /* -y */
      {2, 6, 7, 3}, /* +y */
      {0, 2, 3, 1}, /* -z */
      {4, 5, 7, 6}, /* +z */
  };
  for (int f = 0; f < 6; f++) {
    gi_mesh_builder_add_triangle(b, c[face[f][0]], c[face[f][1]], c[face[f][2]], material);
    gi_mesh_builder_add_triangle(b, c[face[f][0]], c[face[f][2]], c[face[f][3]], material);
  }
}

/* --- scene ------------------------------------------------------------- */

static float luminance(const float c[3]) {
  return 0.2126f * c[0] + 0.7152f * c[1] + 0.0722f * c[2];
}

/* Clamps one material value into [lo, hi]; NaN/Inf become `bad`. Returns 1
 * when the value changed. */
static int clampf(float *x, float lo, float hi, float bad) {
  float v = *x;
  if (!isfinite(v)) { *x = bad; return 1; }
  if (v < lo) { *x = lo; return 1; }
  if (v > hi) { *x = hi; return 1; }
  return 0;
}

/* Sanitises m in place; returns 1 when the albedo, a negative emission or
 * any non-finite value had to be changed, which is what
 * stats.clamped_albedo counts (with the vertex colours that were not
 * numbers). *energy
 * receives the factor the albedo and the glossy lobe were scaled by so that
 * together they reflect at most what arrives (1: they did already). A
 * material of albedo 0.8 with a glossy lobe of 0.5 (a file's Kd 0.8, Ks 1,
 * Ns 8, or a builder's) reflected 130%: every bounce brighter than the
 * last and the plan's geometric tail negative. Scaling both keeps their
 * balance and is continuous at 1. */
static int sanitize_material(gi_material *m, float *energy) {
  int changed = 0;
  for (int k = 0; k < 3; k++) {
    changed |= clampf(&m->albedo[k], 0.f, 1.f, 0.f);
    if (!isfinite(m->emission[k])) { m->emission[k] = 0.f; changed = 1; }
    if (m->emission[k] < 0.f) { m->emission[k] = 0.f; changed = 1; }
  }
  /* A broken roughness is treated as fully diffuse: the safest reading. */
  if (!isfinite(m->roughness)) { m->roughness = 1.f; changed = 1; }
  clampf(&m->roughness, 0.f, 1.f, 1.f);
  if (!isfinite(m->specular)) { m->specular = 0.f; changed = 1; }
  clampf(&m->specular, 0.f, 1.f, 0.f);
  /* A tinted lobe: specular is its brightest channel (gi__gloss_rgb). */
  float tint = 0;
  for (int k = 0; k < 3; k++) {
    changed |= clampf(&m->specular_rgb[k], 0.f, 1.f, 0.f);
    tint = gi__maxf(tint, m->specular_rgb[k]);
  }
  if (tint > 0 && m->specular != tint) m->specular = tint;
  m->name[sizeof m->name - 1] = 0;
  float total = gi__maxf(m->albedo[0], gi__maxf(m->albedo[1], m->albedo[2])) + gi__gloss(m);
  *energy = total > 1.f ? 1.f / total : 1.f;
  if (total > 1.f) {
    for (int k = 0; k < 3; k++) m->albedo[k] *= *energy;
    m->specular *= *energy;
    changed = 1;
  }
  return changed;
}

static double tri_area2(const double *a, const double *b, const double *c, double *longest2) {
  double e1[3], e2[3], e3[3];
  for (int k = 0; k < 3; k++) { e1[k] = b[k] - a[k]; e2[k] = c[k] - a[k]; e3[k] = c[k] - b[k]; }
  double x = e1[1] * e2[2] - e1[2] * e2[1];
  double y = e1[2] * e2[0] - e1[0] * e2[2];
  double z = e1[0] * e2[1] - e1[1] * e2[0];
  double l1 = e1[0] * e1[0] + e1[1] * e1[1] + e1[2] * e1[2];
  double l2 = e2[0] * e2[0] + e2[1] * e2[1] + e2[2] * e2[2];
  double l3 = e3[0] * e3[0] + e3[1] * e3[1] + e3[2] * e3[2];
  double m = l1 > l2 ? l1 : l2;
  *longest2 = m > l3 ? m : l3;
  return sqrt(x * x + y * y + z * z); /* twice the area */
}

static int finite3d(const double *p) {
  return isfinite(p[0]) && isfinite(p[1]) && isfinite(p[2]);
}

/* Finite in float too: the scene's bounds and every stage after the load
 * hold positions as floats off an origin, so a corner past 3.4e38 (finite
 * in the file's double) made the bounds Inf and the default viewpoint NaN. */
static int float_finite3d(const double *p) {
  return finite3d(p) && fabs(p[0]) <= FLT_MAX && fabs(p[1]) <= FLT_MAX && fabs(p[2]) <= FLT_MAX;
}

/* Validates and copies one light; the message names the light by index. */
static gi_result check_light(gi_light *l, size_t i, gi_error_info *err) {
  if ((int)l->type < GI_LIGHT_SUN || (int)l->type > GI_LIGHT_SKY)
    return gi__fail(err, GI_ERR_INVALID_ARG, "light %zu: unknown type %d", i, (int)l->type);
  if (!gi__finite3(l->color))
    return gi__fail(err, GI_ERR_NONFINITE, "light %zu: colour is not finite", i);
  if (l->color[0] < 0 || l->color[1] < 0 || l->color[2] < 0)
    return gi__fail(err, GI_ERR_INVALID_ARG, "light %zu: colour is negative", i);
  for (int k = 0; k < 3; k++)
    if (l->color[k] > GI_MAX_LIGHT_VALUE)
      return gi__fail(err, GI_ERR_LIMIT, "light %zu: colour component %g exceeds %g (GI_MAX_LIGHT_VALUE)", i,
                      (double)l->color[k], (double)GI_MAX_LIGHT_VALUE);
  if ((l->type == GI_LIGHT_POINT || l->type == GI_LIGHT_SPOT) && !finite3d(l->position))
    return gi__fail(err, GI_ERR_NONFINITE, "light %zu: position is not finite", i);
  /* Positions become floats off the scene's origin: past float's range a
   * lamp's direction went NaN and every answer with it. */
  if ((l->type == GI_LIGHT_POINT || l->type == GI_LIGHT_SPOT) && !float_finite3d(l->position))
    return gi__fail(err, GI_ERR_INVALID_ARG, "light %zu: position (%g, %g, %g) is out of range: expected |x|, |y|, "
                    "|z| <= %g", i, l->position[0], l->position[1], l->position[2], (double)FLT_MAX);
  if (l->type == GI_LIGHT_SUN || l->type == GI_LIGHT_SPOT) {
    if (!gi__finite3(l->direction))
      return gi__fail(err, GI_ERR_NONFINITE, "light %zu: direction is not finite", i);
    double len = sqrt((double)l->direction[0] * l->direction[0] + (double)l->direction[1] * l->direction[1] +
                      (double)l->direction[2] * l->direction[2]);
    if (!(len > 1e-20))
      return gi__fail(err, GI_ERR_INVALID_ARG, "light %zu: direction has zero length", i);
    for (int k = 0; k < 3; k++) l->direction[k] = (float)(l->direction[k] / len);
  }
  if (l->type == GI_LIGHT_SPOT) {
    if (!isfinite(l->cos_inner) || !isfinite(l->cos_outer))
      return gi__fail(err, GI_ERR_NONFINITE, "light %zu: spot cone is not finite", i);
    clampf(&l->cos_inner, -1.f, 1.f, 1.f);
    clampf(&l->cos_outer, -1.f, 1.f, 1.f);
    /* The inner cone must lie inside the outer one (larger cosine). */
    if (l->cos_inner < l->cos_outer) { float t = l->cos_inner; l->cos_inner = l->cos_outer; l->cos_outer = t; }
  }
  return GI_OK;
}

enum { TRI_KEEP = 0, TRI_NONFINITE = 1, TRI_DEGENERATE = 2 };

/* Scratch of one build: per input triangle and vertex. */
typedef struct build_tmp {
  uint8_t *cls;      /* TRI_* per input triangle */
  float *energy;     /* per material: sanitize_material's factor, which its triangles' own albedos take too */
  uint32_t *remap;   /* input vertex -> kept vertex, UINT32_MAX when unused */
  double *area;      /* per input triangle, then compacted to kept triangles */
  size_t kept, kept_v;
} build_tmp;

/* Rejects builders and options that cannot make a scene, before any allocation. */
static gi_result check_input(const gi_mesh_builder *b, const gi_scene_options *opt, gi_error_info *err) {
  if (b->oom) return gi__fail(err, GI_ERR_NOMEM, "mesh builder ran out of memory while adding data");
  if (b->bad[0]) return gi__fail(err, GI_ERR_INVALID_ARG, "mesh builder: %s", b->bad);
  if (b->overflow) return gi__fail(err, GI_ERR_LIMIT, "mesh builder: more than 2^32-1 vertices or materials");
  if (b->nt > ((size_t)1 << 31))
    return gi__fail(err, GI_ERR_LIMIT, "scene has %zu triangles; the limit is 2^31", b->nt);
  if (opt->num_lights && !opt->lights)
    return gi__fail(err, GI_ERR_INVALID_ARG, "options: num_lights is %zu but lights is NULL", opt->num_lights);
  if (opt->scale != 0 && !isfinite(opt->scale)) return gi__fail(err, GI_ERR_NONFINITE, "options: scale is not finite");
  /* -1 inverted the scene through its origin and every normal with it: a
   * room lit by its ceiling came out dark, its inside reading as a solid. */
  if (opt->scale < 0)
    return gi__fail(err, GI_ERR_INVALID_ARG, "options: scale must be > 0 (0 = 1), got %g: a negative one turns "
                    "every surface inside out", opt->scale);
  if (opt->up != 0 && opt->up != GI_UP_Y && opt->up != GI_UP_Z)
    return gi__fail(err, GI_ERR_INVALID_ARG, "options: up axis %d is neither Y (1) nor Z (2)", (int)opt->up);
  size_t nm = b->nm ? b->nm : 1;
  for (size_t t = 0; t < b->nt; t++) {
    const uint32_t *ti = b->tri + 3 * t;
    if (ti[0] >= b->nv || ti[1] >= b->nv || ti[2] >= b->nv)
      return gi__fail(err, GI_ERR_INVALID_ARG, "triangle %zu uses vertex %u but the builder has %zu vertices", t,
                      ti[0] >= b->nv ? ti[0] : ti[1] >= b->nv ? ti[1] : ti[2], b->nv);
    if (b->mat[t] >= nm)
      return gi__fail(err, GI_ERR_INVALID_ARG, "triangle %zu uses material %u but the builder has %zu materials", t,
                      b->mat[t], b->nm);
  }
  return GI_OK;
}

static void grow_box(const double p[3], double lo[3], double hi[3]) {
  for (int k = 0; k < 3; k++) {
    if (p[k] < lo[k]) lo[k] = p[k];
    if (p[k] > hi[k]) hi[k] = p[k];
  }
}

/* Classifies triangles in double, on scaled positions: keeps finite ones
 * with area, numbers their vertices, and bounds what is kept in lo/hi. */
static void classify(const gi_mesh_builder *b, double scale, gi_scene *s, build_tmp *t, double lo[3], double hi[3]) {
  for (size_t i = 0; i < b->nv; i++) t->remap[i] = UINT32_MAX;
  for (size_t tr = 0; tr < b->nt; tr++) {
    const uint32_t *ti = b->tri + 3 * tr;
    double p[3][3];
    int fin = 1;
    for (int j = 0; j < 3; j++) {
      for (int k = 0; k < 3; k++) p[j][k] = b->v[3 * (size_t)ti[j] + k] * scale;
      fin &= float_finite3d(p[j]);
    }
    if (!fin) { t->cls[tr] = TRI_NONFINITE; s->stats.dropped_nonfinite++; continue; }
    double longest2, a2 = tri_area2(p[0], p[1], p[2], &longest2);
    /* Relative threshold: a sliver whose height is ~1e-12 of its length has no area worth tracing. */
    if (!(a2 > 2e-12 * longest2) || !isfinite(a2)) {
      t->cls[tr] = TRI_DEGENERATE; s->stats.dropped_degenerate++; continue;
    }
    t->cls[tr] = TRI_KEEP;
    t->area[tr] = 0.5 * a2;
    t->kept++;
    for (int j = 0; j < 3; j++) {
      if (t->remap[ti[j]] == UINT32_MAX) t->remap[ti[j]] = (uint32_t)t->kept_v++;
      grow_box(p[j], lo, hi);
    }
  }
  if (t->kept == 0) {
    /* Empty scene: the origin is the centre of whatever finite vertices exist, else 0. */
    for (size_t i = 0; i < b->nv; i++) {
      double p[3] = {b->v[3 * i] * scale, b->v[3 * i + 1] * scale, b->v[3 * i + 2] * scale};
      if (float_finite3d(p)) grow_box(p, lo, hi);
    }
  }
}

/* Stray triangles: at most STRAY_SHARE of them (at least one), none of
 * each within the rest's extent of the rest's box, when the whole bounds
 * span more than STRAY_RATIO times that extent. The rest is found from a
 * sample of at most STRAY_SAMPLE centroids: per axis the narrowest run of
 * sorted centroids that leaves out at most that share. */
#define STRAY_SHARE 0.01
#define STRAY_RATIO 100.0
#define STRAY_SAMPLE 65536

static int cmp_double(const void *a, const void *b) {
  double x = *(const double *)a, y = *(const double *)b;
  return x < y ? -1 : x > y;
}

/* Reorders a[0..n) so that a[k] holds the value a sort would put there,
 * none before it larger and none after it smaller (quickselect, the
 * middle of three as pivot; finite values). */
static void select_nth(double *a, size_t n, size_t k) {
  size_t lo = 0, hi = n - 1;
  while (hi > lo) {
    size_t mid = lo + (hi - lo) / 2;
    double x = a[lo], y = a[mid], z = a[hi];
    double pivot = x < y ? (y < z ? y : (x < z ? z : x)) : (x < z ? x : (y < z ? z : y));
    size_t i = lo, j = hi;
    while (i <= j) {
      while (a[i] < pivot) i++;
      while (a[j] > pivot) j--;
      if (i <= j) {
        double t = a[i];
        a[i] = a[j], a[j] = t;
        i++;
        if (j-- == 0) break;
      }
    }
    /* Now [lo, j] <= pivot <= [i, hi], and anything between equals it. */
    if (k <= j && j != SIZE_MAX) hi = j;
    else if (k >= i) lo = i;
    else return;
  }
}

/* Sorts the `head` smallest and the `head` largest values of a[0..n) into
 * place: bulk_box reads only those, and a full sort of the 65536-point
 * sample was a fifth of a city's load. */
static void sort_tails(double *a, size_t n, size_t head) {
  if (2 * head >= n) {
    qsort(a, n, sizeof *a, cmp_double);
    return;
  }
  select_nth(a, n, head - 1);
  qsort(a, head, sizeof *a, cmp_double);
  select_nth(a + head, n - head, n - 2 * head);
  qsort(a + n - head, head, sizeof *a, cmp_double);
}

static void centroid(const gi_mesh_builder *b, double scale, size_t tr, double c[3]) {
  const uint32_t *ti = b->tri + 3 * tr;
  for (int k = 0; k < 3; k++)
    c[k] = (b->v[3 * (size_t)ti[0] + k] + b->v[3 * (size_t)ti[1] + k] + b->v[3 * (size_t)ti[2] + k]) * scale / 3;
}

/* 1 when triangle v (world, double) meets the box [lo, hi]: no separating
 * axis among the box's three, the triangle's normal and their nine
 * cross products (a degenerate axis separates nothing). */
static int tri_meets_box(const double v[3][3], const double lo[3], const double hi[3]) {
  double p[3][3], h[3], e[3][3];
  for (int a = 0; a < 3; a++) {
    double c = 0.5 * (lo[a] + hi[a]);
    h[a] = 0.5 * (hi[a] - lo[a]);
    for (int j = 0; j < 3; j++) p[j][a] = v[j][a] - c;
  }
  for (int j = 0; j < 3; j++)
    for (int a = 0; a < 3; a++) e[j][a] = p[(j + 1) % 3][a] - p[j][a];
  double axes[13][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  gi__cross_d(e[0], e[1], axes[3]);
  for (int j = 0; j < 3; j++)
    for (int a = 0; a < 3; a++) {
      double u[3] = {0, 0, 0};
      u[a] = 1;
      gi__cross_d(e[j], u, axes[4 + 3 * j + a]);
    }
  for (int x = 0; x < 13; x++) {
    const double *w = axes[x];
    double r = h[0] * fabs(w[0]) + h[1] * fabs(w[1]) + h[2] * fabs(w[2]), mn = INFINITY, mx = -INFINITY;
    for (int j = 0; j < 3; j++) {
      double d = w[0] * p[j][0] + w[1] * p[j][1] + w[2] * p[j][2];
      mn = fmin(mn, d), mx = fmax(mx, d);
    }
    if (mn > r || mx < -r) return 0;
  }
  return 1;
}

/* The bulk box of the kept triangles: the whole bounds (lo, hi), unless a
 * few stray triangles lie far from the rest. Then the box is the rest's,
 * grown by its extent, and the strays are counted: a leftover triangle at
 * 0,0,0 beside a city in map coordinates put the origin halfway (float
 * steps of 0.25 m on the city) and the default voxel at 763 m (no
 * indirect light). GI_ERR_NOMEM without memory for the sample. */
static gi_result bulk_box(const gi_mesh_builder *b, double scale, gi_scene *s, const build_tmp *t, const double lo[3],
                          const double hi[3], gi_error_info *err) {
  memcpy(s->bulk_lo, lo, sizeof s->bulk_lo), memcpy(s->bulk_hi, hi, sizeof s->bulk_hi);
  size_t stride = t->kept > STRAY_SAMPLE ? (t->kept + STRAY_SAMPLE - 1) / STRAY_SAMPLE : 1, m = 0, k = 0;
  if (t->kept < 2) return GI_OK;
  double *c = gi__malloc(3 * (t->kept / stride + 1) * sizeof *c);
  if (!c) return gi__fail(err, GI_ERR_NOMEM, "out of memory building scene (finding stray triangles)");
  for (size_t tr = 0; tr < b->nt; tr++)
    if (t->cls[tr] == TRI_KEEP && k++ % stride == 0) {
      double p[3];
      centroid(b, scale, tr, p);
      for (int a = 0; a < 3; a++) c[a * (t->kept / stride + 1) + m] = p[a];
      m++;
    }
  double qlo[3], qhi[3], ext = 0, full = 0;
  size_t leave = (size_t)fmax(1.0, STRAY_SHARE * (double)m);
  for (int a = 0; a < 3; a++) {
    double *col = c + a * (t->kept / stride + 1);
    sort_tails(col, m, leave + 1);
    qlo[a] = col[0], qhi[a] = col[m - 1];
    for (size_t i = 0; i <= leave && i + m - leave - 1 < m; i++)
      if (col[i + m - 1 - leave] - col[i] < qhi[a] - qlo[a]) qlo[a] = col[i], qhi[a] = col[i + m - 1 - leave];
    ext = fmax(ext, qhi[a] - qlo[a]), full = fmax(full, hi[a] - lo[a]);
  }
  gi__free(c);
  if (!(ext > 0) || !(full > STRAY_RATIO * ext)) return GI_OK;
  double blo[3], bhi[3];
  for (int a = 0; a < 3; a++) blo[a] = qlo[a] - ext, bhi[a] = qhi[a] + ext;
  uint64_t far = 0;
  double nlo[3] = {INFINITY, INFINITY, INFINITY}, nhi[3] = {-INFINITY, -INFINITY, -INFINITY};
  /* A triangle is stray when none of it comes near the rest: a ground
   * quad of 200 m under a finely meshed 1 m model has its centroids far
   * out, yet the model stands on it (by centroids it was stray, and the
   * model baked without its ground: 0.6x the indirect light). */
  for (size_t tr = 0; tr < b->nt; tr++) {
    if (t->cls[tr] != TRI_KEEP) continue;
    double v[3][3];
    for (int j = 0; j < 3; j++)
      for (int a = 0; a < 3; a++) v[j][a] = b->v[3 * (size_t)b->tri[3 * tr + j] + a] * scale;
    if (!tri_meets_box((const double(*)[3])v, blo, bhi)) far++;
    else
      for (int j = 0; j < 3; j++) grow_box(v[j], nlo, nhi);
  }
  if (far == 0 || (double)far > fmax(1.0, STRAY_SHARE * (double)t->kept) || !(nlo[0] <= nhi[0])) return GI_OK;
  s->stats.far_triangles = far;
  memcpy(s->bulk_lo, nlo, sizeof nlo), memcpy(s->bulk_hi, nhi, sizeof nhi);
  return GI_OK;
}

/* Kept vertices relative to the origin, in float, and their local bounds. */
static gi_result copy_vertices(const gi_mesh_builder *b, double scale, gi_scene *s, const build_tmp *t,
                               gi_error_info *err) {
  /* 4 spare floats because Embree reads 16 bytes past the last vertex. */
  s->num_vertices = (uint32_t)t->kept_v;
  s->num_triangles = (uint32_t)t->kept;
  s->vertices = gi__calloc(3 * t->kept_v + 4, sizeof(float));
  s->indices = gi__malloc((t->kept ? t->kept : 1) * 3 * sizeof(uint32_t));
  s->tri_material = gi__malloc((t->kept ? t->kept : 1) * sizeof(uint32_t));
  if (!s->vertices || !s->indices || !s->tri_material)
    return gi__fail(err, GI_ERR_NOMEM, "out of memory building scene (%zu triangles)", t->kept);
  for (size_t i = 0; i < b->nv; i++) {
    if (t->remap[i] == UINT32_MAX) continue;
    float *q = s->vertices + 3 * (size_t)t->remap[i];
    for (int k = 0; k < 3; k++) q[k] = (float)(b->v[3 * i + k] * scale - s->origin[k]);
  }
  for (int k = 0; k < 3; k++) s->lo[k] = s->hi[k] = 0.f;
  if (t->kept) {
    for (int k = 0; k < 3; k++) { s->lo[k] = INFINITY; s->hi[k] = -INFINITY; }
    for (size_t i = 0; i < t->kept_v; i++)
      for (int k = 0; k < 3; k++) {
        float x = s->vertices[3 * i + k];
        if (x < s->lo[k]) s->lo[k] = x;
        if (x > s->hi[k]) s->hi[k] = x;
      }
  }
  return GI_OK;
}

/* The lightmap UVs of the kept vertices, kept only when every one has
 * finite UVs (a partial set cannot lay out a lightmap). */
static gi_result copy_uv2(const gi_mesh_builder *b, gi_scene *s, const build_tmp *t, gi_error_info *err) {
  if (!b->uv2 || !t->kept_v) return GI_OK;
  /* A set that misses some vertices (a mesh without TEXCOORD_1, a NaN) is
   * not a layout: it is dropped, and the count says why. */
  uint64_t missing = 0;
  for (size_t i = 0; i < b->nv; i++)
    missing += t->remap[i] != UINT32_MAX &&
               (2 * i + 1 >= b->cap_uv2 || !isfinite(b->uv2[2 * i]) || !isfinite(b->uv2[2 * i + 1]));
  if (missing) {
    s->stats.uv2_missing = missing;
    return GI_OK;
  }
  if (!(s->uv2 = gi__malloc(2 * t->kept_v * sizeof *s->uv2)))
    return gi__fail(err, GI_ERR_NOMEM, "out of memory for %zu lightmap UVs", t->kept_v);
  for (size_t i = 0; i < b->nv; i++)
    if (t->remap[i] != UINT32_MAX) memcpy(s->uv2 + 2 * (size_t)t->remap[i], b->uv2 + 2 * i, 2 * sizeof(float));
  return GI_OK;
}

/* The builder's materials (or one grey default), sanitized. */
static gi_result copy_materials(const gi_mesh_builder *b, gi_scene *s, build_tmp *t, gi_error_info *err) {
  size_t nm = b->nm ? b->nm : 1;
  s->num_materials = (uint32_t)nm;
  s->materials = gi__calloc(nm, sizeof *s->materials);
  t->energy = gi__malloc(nm * sizeof *t->energy);
  if (!s->materials || !t->energy) return gi__fail(err, GI_ERR_NOMEM, "out of memory copying materials");
  if (b->nm) {
    memcpy(s->materials, b->mats, nm * sizeof *s->materials);
  } else {
    gi_material *m = &s->materials[0];
    m->albedo[0] = m->albedo[1] = m->albedo[2] = 0.8f;
    m->roughness = 1.f;
    snprintf(m->name, sizeof m->name, "default");
  }
  for (size_t i = 0; i < nm; i++) {
    gi_material *m = &s->materials[i];
    s->stats.clamped_albedo += (uint64_t)sanitize_material(m, &t->energy[i]);
    for (int k = 0; k < 3; k++)
      if (m->emission[k] > GI_MAX_LIGHT_VALUE)
        return gi__fail(err, GI_ERR_LIMIT, "material %zu ('%s'): emission %g exceeds %g (GI_MAX_LIGHT_VALUE)", i,
                        m->name, (double)m->emission[k], (double)GI_MAX_LIGHT_VALUE);
  }
  s->stats.clamped_albedo += b->bad_col;
  s->stats.materials = (uint32_t)nm;
  return GI_OK;
}

static int emits(const float e[3]) { return e[0] > 0 || e[1] > 0 || e[2] > 0; }

/* A vertex's colour component k (white when never set). */
static float vertex_color(const gi_mesh_builder *b, uint32_t v, int k) {
  return 3 * (size_t)v + 2 < b->cap_col ? b->col[3 * (size_t)v + k] : 1.f;
}

/* Per kept triangle: its own albedo (else its material's) times its
 * corners' mean colour, in [0, 1], when the builder has either (else none
 * is kept). An own albedo takes its material's energy factor, and is held
 * so that its brightest channel plus the material's glossy lobe stay <= 1
 * (it may be brighter than its material's). */
static gi_result copy_tri_albedo(const gi_mesh_builder *b, gi_scene *s, const build_tmp *t, gi_error_info *err) {
  if ((!b->col && !b->talb) || !t->kept) return GI_OK;
  if (!(s->tri_albedo = gi__malloc(3 * t->kept * sizeof *s->tri_albedo)))
    return gi__fail(err, GI_ERR_NOMEM, "out of memory for the albedo of %zu triangles", t->kept);
  size_t j = 0;
  for (size_t tr = 0; tr < b->nt; tr++) {
    if (t->cls[tr] != TRI_KEEP) continue;
    const gi_material *mat = &s->materials[b->mat[tr]];
    float *out = &s->tri_albedo[3 * j++], mx = 0;
    for (int k = 0; k < 3; k++) {
      float c = (vertex_color(b, b->tri[3 * tr], k) + vertex_color(b, b->tri[3 * tr + 1], k) +
                 vertex_color(b, b->tri[3 * tr + 2], k)) / 3.f;
      float own = 3 * tr + k < b->cap_talb ? b->talb[3 * tr + k] : NAN;
      float a = isfinite(own) ? own * t->energy[b->mat[tr]] : mat->albedo[k];
      out[k] = gi__minf(gi__maxf(a * c, 0.f), 1.f);
      mx = gi__maxf(mx, out[k]);
    }
    float room = 1.f - gi__gloss(mat);
    if (mx > room)
      for (int k = 0; k < 3; k++) out[k] *= room / mx;
  }
  return GI_OK;
}

/* Kept triangles in input order, and the emitters among them with a cdf by
 * power (luminance times area) for light sampling. */
static gi_result copy_triangles(const gi_mesh_builder *b, gi_scene *s, build_tmp *t, gi_error_info *err) {
  size_t j = 0, ne = 0;
  for (size_t tr = 0; tr < b->nt; tr++) {
    if (t->cls[tr] != TRI_KEEP) continue;
    for (int k = 0; k < 3; k++) s->indices[3 * j + k] = t->remap[b->tri[3 * tr + k]];
    s->tri_material[j] = b->mat[tr];
    ne += emits(s->materials[b->mat[tr]].emission);
    t->area[j] = t->area[tr]; /* j <= tr: compacts areas in place for the emitter pass */
    j++;
  }
  s->stats.triangles = t->kept;
  if (!ne) return GI_OK;
  s->emitter_tri = gi__malloc(ne * sizeof *s->emitter_tri);
  float *power = gi__malloc(ne * sizeof *power);
  if (!s->emitter_tri || !power) {
    gi__free(power);
    return gi__fail(err, GI_ERR_NOMEM, "out of memory for emitters");
  }
  double asum = 0;
  size_t q = 0;
  for (size_t tr = 0; tr < t->kept; tr++) {
    const float *e = s->materials[s->tri_material[tr]].emission;
    if (!emits(e)) continue;
    s->emitter_tri[q] = (uint32_t)tr;
    asum += t->area[tr];
    /* A two-sided emitter sends its radiance out of both sides: twice the power. */
    power[q++] = luminance(e) * t->area[tr] * (s->materials[s->tri_material[tr]].two_sided ? 2.f : 1.f);
  }
  s->emitter_area_total = (float)asum;
  s->num_emitters = (uint32_t)ne;
  s->stats.emissive_triangles = (uint32_t)ne;
  gi_result rc = gi__light_tree_build(s, power, err);
  gi__free(power);
  return rc;
}

/* A sun down the up axis and a little sideways (so walls facing two ways
 * get some), and a sky. */
/* One sun for either up axis: north is +y with z up and -z with y up
 * (README), so z up's (0.4, 0.3, -1) is y up's (0.4, -1, -0.3). A y-up
 * copy of a z-up file was lit from the mirrored side (+z for -z): the
 * same street read its shadowed and its sunlit side swapped. */
static void default_lights(gi_scene *s, gi_light *sun, gi_light *sky) {
  double d[3] = {0.4, -1.0, -0.3};
  if (s->up == GI_UP_Z) { d[1] = 0.3; d[2] = -1.0; }
  double len = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
  sun->type = GI_LIGHT_SUN;
  sun->color[0] = 3.0f; sun->color[1] = 2.9f; sun->color[2] = 2.7f;
  for (int k = 0; k < 3; k++) { sun->direction[k] = (float)(d[k] / len); sun->position[k] = s->origin[k]; }
  sky->type = GI_LIGHT_SKY;
  sky->color[0] = 0.25f; sky->color[1] = 0.3f; sky->color[2] = 0.4f;
  for (int k = 0; k < 3; k++) sky->position[k] = s->origin[k];
  s->stats.default_lights_added = 1;
}

/* Lights: the caller's, then the defaults when asked and nothing lights the scene. */
static gi_result copy_lights(const gi_scene_options *opt, gi_scene *s, gi_error_info *err) {
  int add_defaults = opt->default_lights && opt->num_lights == 0 && s->num_emitters == 0;
  size_t nl = opt->num_lights + (add_defaults ? 2 : 0);
  if (nl) {
    s->lights = gi__calloc(nl, sizeof *s->lights);
    if (!s->lights) return gi__fail(err, GI_ERR_NOMEM, "out of memory for lights");
  }
  for (size_t i = 0; i < opt->num_lights; i++) {
    s->lights[i] = opt->lights[i];
    gi_result rc = check_light(&s->lights[i], i, err);
    if (rc != GI_OK) return rc;
  }
  if (add_defaults) default_lights(s, &s->lights[opt->num_lights], &s->lights[opt->num_lights + 1]);
  s->num_lights = (uint32_t)nl;
  s->stats.lights = (uint32_t)nl;
  return GI_OK;
}

gi_result gi_scene_build(const gi_mesh_builder *b, const char *name, const gi_scene_options *opt,
                         gi_scene **out, gi_error_info *err) {
  gi_scene_options defaults = {0};
  if (!out) return gi__fail(err, GI_ERR_INVALID_ARG, "gi_scene_build: out is NULL");
  *out = NULL;
  if (!b) return gi__fail(err, GI_ERR_INVALID_ARG, "gi_scene_build: builder is NULL");
  if (!opt) opt = &defaults;
  gi_result rc = check_input(b, opt, err);
  if (rc != GI_OK) return rc;
  double scale = opt->scale == 0 ? 1.0 : opt->scale;

  build_tmp t = {0};
  gi_scene *s = gi__calloc(1, sizeof *s);
  t.cls = gi__malloc(b->nt ? b->nt : 1);
  t.remap = gi__malloc((b->nv ? b->nv : 1) * sizeof *t.remap);
  t.area = gi__malloc((b->nt ? b->nt : 1) * sizeof *t.area);
  if (!s || !t.cls || !t.remap || !t.area) {
    rc = gi__fail(err, GI_ERR_NOMEM, "out of memory building scene");
    goto done;
  }
  atomic_init(&s->refcount, 1);
  snprintf(s->name, sizeof s->name, "%s", name ? name : "unnamed");
  s->up = opt->up ? opt->up : GI_UP_Y;
  s->stats.input_triangles = b->nt;

  double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  classify(b, scale, s, &t, lo, hi);
  if ((rc = bulk_box(b, scale, s, &t, lo, hi, err)) != GI_OK) goto done;
  /* The origin at the bulk's centre: float positions are finest where the scene is. */
  for (int k = 0; k < 3; k++) s->origin[k] = lo[k] <= hi[k] ? 0.5 * (s->bulk_lo[k] + s->bulk_hi[k]) : 0.0;
  if ((rc = copy_vertices(b, scale, s, &t, err)) != GI_OK || (rc = copy_uv2(b, s, &t, err)) != GI_OK ||
      (rc = copy_materials(b, s, &t, err)) != GI_OK ||
      (rc = copy_triangles(b, s, &t, err)) != GI_OK || (rc = copy_tri_albedo(b, s, &t, err)) != GI_OK ||
      (rc = copy_lights(opt, s, err)) != GI_OK ||
      (rc = gi__local_tree_build(s, err)) != GI_OK)
    goto done;
  if (t.kept) rc = gi__bvh_build(s, opt->threads, err);

done:
  gi__free(t.cls);
  gi__free(t.energy);
  gi__free(t.remap);
  gi__free(t.area);
  if (rc == GI_OK) {
    *out = s;
  } else if (s) {
    atomic_store(&s->refcount, 1);
    gi_scene_release(s);
  }
  return rc;
}

gi_scene *gi_scene_retain(gi_scene *s) {
  if (s) atomic_fetch_add_explicit(&s->refcount, 1, memory_order_relaxed);
  return s;
}

void gi_scene_release(gi_scene *s) {
  if (!s) return;
  if (atomic_fetch_sub_explicit(&s->refcount, 1, memory_order_acq_rel) != 1) return;
  gi__bvh_free(s);
  gi__free(s->vertices);
  gi__free(s->uv2);
  gi__free(s->indices);
  gi__free(s->tri_material);
  gi__free(s->tri_albedo);
  gi__free(s->materials);
  gi__free(s->lights);
  gi__free(s->local_tree);
  gi__free(s->other_lights);
  gi__free(s->emitter_tri);
  gi__free(s->emitter_leaf);
  gi__free(s->ltree);
  gi__free(s->lpair);
  gi__free(s->emitter_geo);
  gi__free(s);
}

/* The getters take a NULL scene as an empty one (zeros, NULL), as
 * gi_scene_origin does: a caller's failed load must not crash its report. */
void gi_scene_get_stats(const gi_scene *s, gi_scene_stats *out) {
  if (!out) return;
  if (!s) memset(out, 0, sizeof *out);
  else *out = s->stats;
}

void gi_scene_bounds(const gi_scene *s, double lo[3], double hi[3]) {
  for (int k = 0; k < 3; k++) {
    if (!s) {
      lo[k] = hi[k] = 0;
      continue;
    }
    lo[k] = s->origin[k] + (double)s->lo[k];
    hi[k] = s->origin[k] + (double)s->hi[k];
  }
}

void gi_scene_bulk_bounds(const gi_scene *s, double lo[3], double hi[3]) {
  if (!s || !s->stats.far_triangles) {
    gi_scene_bounds(s, lo, hi);
    return;
  }
  memcpy(lo, s->bulk_lo, sizeof s->bulk_lo), memcpy(hi, s->bulk_hi, sizeof s->bulk_hi);
}

int gi_scene_looks_z_up(const gi_scene *s) {
  if (!s || s->up == GI_UP_Z) return 0;
  double e[3];
  for (int k = 0; k < 3; k++) e[k] = (double)s->hi[k] - (double)s->lo[k];
  return e[2] > 0 && e[2] < 0.25 * e[0] && e[2] < 0.25 * e[1]; /* a plane alone may stand either way */
}

/* Direction i (0..25) of the 26 of a 3x3x3 block's neighbours: axes, face
 * and cube diagonals, unit length. */
#define NUM_DIR26 26
static void dir26(int i, float w[3]) {
  int j = i < 13 ? i : i + 1; /* skip the block's centre */
  int d[3] = {j % 3 - 1, (j / 3) % 3 - 1, j / 9 - 1};
  float l = sqrtf((float)(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]));
  for (int k = 0; k < 3; k++) w[k] = (float)d[k] / l;
}

double gi_scene_clearance(const gi_scene *s, const double p[3], double max) {
  if (!s || !p || !isfinite(p[0]) || !isfinite(p[1]) || !isfinite(p[2]) || !(max > 0)) return 0;
  float o[3];
  for (int k = 0; k < 3; k++) o[k] = (float)(p[k] - s->origin[k]);
  double best = max;
  for (int i = 0; i < NUM_DIR26; i++) {
    float w[3], t;
    dir26(i, w);
    if (gi__intersect1(s, o, w, 0, (float)best, &t, NULL, NULL) && t < best) best = t;
  }
  return best;
}

/* Of the 26 directions from world point p: how many first meet a
 * surface's back, and how many meet nothing. 0 for a non-finite p. */
static int dir26_hits(const gi_scene *s, const double p[3], int *back, int *open) {
  *back = *open = 0;
  if (!s || !p || !isfinite(p[0]) || !isfinite(p[1]) || !isfinite(p[2])) return 0;
  float o[3];
  for (int k = 0; k < 3; k++) o[k] = (float)(p[k] - s->origin[k]);
  for (int i = 0; i < NUM_DIR26; i++) {
    float w[3], t, ng[3];
    uint32_t tri;
    dir26(i, w);
    if (!gi__intersect1(s, o, w, 0, INFINITY, &t, &tri, ng)) (*open)++;
    else if (ng[0] * w[0] + ng[1] * w[1] + ng[2] * w[2] > 0) (*back)++;
  }
  return 1;
}

double gi_scene_backface_share(const gi_scene *s, const double p[3]) {
  int back, open;
  return dir26_hits(s, p, &back, &open) ? (double)back / NUM_DIR26 : 0;
}

double gi_scene_escape_share(const gi_scene *s, const double p[3]) {
  int back, open;
  return dir26_hits(s, p, &back, &open) ? (double)open / NUM_DIR26 : 1;
}

gi_up_axis gi_scene_up(const gi_scene *s) { return s ? s->up : GI_UP_Y; }
int gi_scene_has_lightmap_uv(const gi_scene *s) { return s && s->uv2 != NULL; }
const char *gi_scene_name(const gi_scene *s) { return s ? s->name : NULL; }
size_t gi_scene_num_lights(const gi_scene *s) { return s ? s->num_lights : 0; }
size_t gi_scene_num_materials(const gi_scene *s) { return s ? s->num_materials : 0; }

const gi_light *gi_scene_light(const gi_scene *s, size_t i) {
  return s && i < s->num_lights ? &s->lights[i] : NULL;
}

const gi_material *gi_scene_material(const gi_scene *s, size_t i) {
  return s && i < s->num_materials ? &s->materials[i] : NULL;
}
