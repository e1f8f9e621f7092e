/* filter.c: the nested regions of coarse levels, from their finer level.
 *
 * The region of level d that level d-1 covers is not voxel-lit on its own:
 * it is filtered from level d-1 by compositing along each axis, which keeps
 * a thin wall that is opaque at the fine level opaque at the coarse one. */
#include <stdlib.h>
#include <string.h>
#include "base/internal.h"
#include "cascade/cascade_internal.h"

static int in_inner(const gi_level *L, int64_t i, int64_t j, int64_t k) {
  return L->has_inner && i >= L->inner0[0] && i < L->inner1[0] && j >= L->inner0[1] &&
         j < L->inner1[1] && k >= L->inner0[2] && k < L->inner1[2];
}

typedef struct {
  struct gi_cascade *c;
  int d;
  int64_t lo[3], hi[3]; /* the cells of level d to filter (inside its nested region) */
  gi_vrad empty;        /* what an empty voxel's texel holds (empty_texel) */
} filter_ctx;

/* 1 when a child holds no surface and its texel is all zero bits. */
static int child_empty(const gi_level *F, uint32_t s) {
  if (F->vix[s] != 0) return 0;
  uint16_t any = 0;
  for (int i = 0; i < GI_VRAD_LANES; i++) any |= F->rad[s].h[i];
  return any == 0;
}

/* What filter_voxel writes for eight empty children (tau = -log(1) packs
 * as a negative zero): computed by the same expressions, so the shortcut
 * below writes the same bits. */
static void empty_texel(const struct gi_cascade *c, gi_vrad *r) {
  gi_vrad_f o;
  memset(&o, 0, sizeof o);
  double T = 0.25 * (4 * exp(-0.0 - 0.0));
  for (int a = 0; a < 3; a++) o.tau[a] = (float)-log(T), o.alpha[a] = (float)(1.0 - T);
  gi__vrad_pack(c, &o, r);
}

/* Most of a city's nested regions are air: eight empty children (slots
 * cs) give an empty voxel without the 192 half conversions and 48
 * exponentials of the general case (every bounce refilters every nested
 * region). Returns 1 when it wrote the voxel. */
static int filter_empty(const gi_vrad *empty_rad, const gi_level *F, gi_level *L, const uint32_t cs[8], uint32_t slot) {
  for (int i = 0; i < 8; i++)
    if (!child_empty(F, cs[i])) return 0;
  /* No child holds geometry, so neither does the voxel: it has no entry (gi__nested_entries). */
  L->rad[slot] = *empty_rad;
  return 1;
}

/* One coarse voxel from its 2x2x2 children. */
static void filter_voxel(const struct gi_cascade *c, const gi_vrad *empty_rad, const gi_level *F, gi_level *L,
                         int64_t ci, int64_t cj, int64_t ck) {
  int R = c->R;
  uint32_t cs[8]; /* child x + 2 y + 4 z */
  for (int i = 0; i < 8; i++) cs[i] = gi__slot(2 * ci + (i & 1), 2 * cj + (i >> 1 & 1), 2 * ck + (i >> 2), R);
  uint32_t slot = gi__slot(ci, cj, ck, R);
  if (filter_empty(empty_rad, F, L, cs, slot)) return;
  gi_vrad_f kr[2][2][2];
  const gi_vgeo *kg[2][2][2];
  const float(*ks[2][2][2])[3];
  for (int z = 0; z < 2; z++)
    for (int y = 0; y < 2; y++)
      for (int x = 0; x < 2; x++) {
        uint32_t s = cs[x + 2 * y + 4 * z];
        gi__vrad_unpack(c, &F->rad[s], &kr[z][y][x]);
        kg[z][y][x] = gi__geo(F, s);
        ks[z][y][x] = gi__side(F, s);
      }
  gi_vrad_f o, *out = &o;
  memset(out, 0, sizeof *out);
  for (int axis = 0; axis < 3; axis++) {
    double T = 0;
    float pp[3] = {0, 0, 0}, pn[3] = {0, 0, 0};
    for (int u = 0; u < 2; u++)
      for (int v = 0; v < 2; v++) {
        /* The column's two children along `axis`: lo (index 0) and hi (index 1). */
        const gi_vrad_f *ch[2];
        for (int t = 0; t < 2; t++) {
          int x = axis == 0 ? t : u, y = axis == 1 ? t : (axis == 0 ? u : v), z = axis == 2 ? t : v;
          ch[t] = &kr[z][y][x];
        }
        T += exp(-(double)ch[0]->tau[axis] - (double)ch[1]->tau[axis]);
        float tlo = expf(-ch[0]->tau[axis]), thi = expf(-ch[1]->tau[axis]);
        for (int k = 0; k < 3; k++) {
          /* Leaving through +axis the hi child is in front; through -axis the lo child. */
          pp[k] += ch[1]->p[2 * axis][k] + thi * ch[0]->p[2 * axis][k];
          pn[k] += ch[0]->p[2 * axis + 1][k] + tlo * ch[1]->p[2 * axis + 1][k];
        }
      }
    T *= 0.25;
    if (T < GI_MIN_TRANSMITTANCE) T = GI_MIN_TRANSMITTANCE;
    out->tau[axis] = (float)-log(T);
    out->alpha[axis] = (float)(1.0 - T);
    for (int k = 0; k < 3; k++) {
      out->p[2 * axis][k] = 0.25f * pp[k];
      out->p[2 * axis + 1][k] = 0.25f * pn[k];
    }
  }
  gi__vrad_pack(c, out, &L->rad[slot]);
  /* Geometry and face irradiance: area-weighted means, for inspection
   * (export); one orientation group, the children's mean normal. A voxel
   * without an entry has no child holding geometry. */
  if (L->vix[slot] == 0) return;
  gi_vgeo *g = gi__geo(L, slot);
  float(*side)[3] = gi__side(L, slot);
  memset(g, 0, sizeof *g);
  memset(side, 0, sizeof(gi_faces3));
  double area = 0;
  for (int z = 0; z < 2; z++)
    for (int y = 0; y < 2; y++)
      for (int x = 0; x < 2; x++) {
        const gi_vgeo *h = kg[z][y][x];
        if (h->area <= 0) continue;
        float a = h->area;
        area += a;
        float sgn = gi__dot(h->normal, g->normal) < 0 ? -1.f : 1.f;
        for (int k = 0; k < 3; k++) {
          g->albedo[k] += a * h->albedo[k];
          g->emission[k] += a * h->emission[k];
          g->normal[k] += sgn * a * h->normal[k];
          g->centroid[k] += a * h->centroid[k];
          g->proj[k] += h->proj[k];
        }
        for (int f = 0; f < GI_VOX_FACES; f++)
          for (int k = 0; k < 3; k++) side[f][k] += a * ks[z][y][x][f][k];
        for (int k = 0; k < 3; k++) g->gloss[k] += a * h->gloss[k];
      }
  if (area > 0) {
    float ia = (float)(1.0 / area);
    g->area = (float)area;
    for (int k = 0; k < 3; k++) {
      g->albedo[k] *= ia;
      g->emission[k] *= ia;
      g->centroid[k] *= ia;
    }
    for (int f = 0; f < GI_VOX_FACES; f++)
      for (int k = 0; k < 3; k++) side[f][k] *= ia;
    for (int k = 0; k < 3; k++) g->gloss[k] *= ia;
    float nl = gi__len(g->normal);
    if (nl > 0)
      for (int k = 0; k < 3; k++) g->normal[k] /= nl;
    g->groups = 1;
    memcpy(g->u.fin.orient[0], g->normal, sizeof g->normal);
    memcpy(g->u.fin.gcen[0], g->centroid, sizeof g->centroid);
    for (int f = 0; f < GI_VOX_FACES; f++) g->face_side[f] = gi__face_side(g->normal, 0, f);
  }
}

static void filter_range(void *p, size_t b, size_t e, int worker) {
  filter_ctx *fc = p;
  struct gi_cascade *c = fc->c;
  gi_level *L = &c->lv[fc->d];
  const gi_level *F = &c->lv[fc->d - 1];
  int64_t nx = fc->hi[0] - fc->lo[0], ny = fc->hi[1] - fc->lo[1];
  for (size_t idx = b; idx < e; idx++) {
    int64_t i = fc->lo[0] + (int64_t)idx % nx;
    int64_t j = fc->lo[1] + ((int64_t)idx / nx) % ny;
    int64_t k = fc->lo[2] + (int64_t)idx / (nx * ny);
    filter_voxel(c, &fc->empty, F, L, i, j, k);
  }
}

int gi__cascade_filter_box(struct gi_cascade *c, int threads, int d, const int64_t lo[3], const int64_t hi[3]) {
  gi_level *L = &c->lv[d];
  if (d < 1 || d >= c->n || !L->has_inner) return 0;
  filter_ctx fc = {.c = c, .d = d};
  empty_texel(c, &fc.empty);
  size_t count = 1;
  for (int a = 0; a < 3; a++) {
    fc.lo[a] = lo[a] > L->inner0[a] ? lo[a] : L->inner0[a];
    fc.hi[a] = hi[a] < L->inner1[a] ? hi[a] : L->inner1[a];
    int64_t w = fc.hi[a] - fc.lo[a];
    count *= (size_t)(w > 0 ? w : 0);
  }
  if (count == 0) return 0;
  return gi__parallel_for_cancel(count, 256, threads, filter_range, &fc, NULL, c->cancel);
}

int gi__cascade_filter(struct gi_cascade *c, int threads) {
  for (int d = 1; d < c->n; d++)
    if (gi__cascade_filter_box(c, threads, d, c->lv[d].inner0, c->lv[d].inner1)) return 1;
  return 0;
}

int gi__is_inner(const gi_level *L, int64_t i, int64_t j, int64_t k) { return in_inner(L, i, j, k); }

/* A trilinear sample reads the 2x2x2 block at its base cell; the mask lets
 * samples in empty space skip those eight reads. Opacity is fixed once the
 * levels are voxelized and filtered (bounces change only radiance). */
/* The bits of a half other than its sign. */
#define GI_HALF_MAGNITUDE 0x7fffu

static void mark_busy2(gi_level *L, int R) {
  memset(L->busy, 0, (size_t)R * R * R);
  for (int k = 0; k < R; k++)
    for (int j = 0; j < R; j++)
      for (int i = 0; i < R; i++) {
        const gi_vrad *r = &L->rad[(size_t)i + (size_t)R * ((size_t)j + (size_t)R * k)];
        /* Optical depth is never negative: a half other than +0 and -0 is a
         * positive one. (A filtered voxel over empty children holds
         * -log(1) = -0: read as busy, every nested region was.) */
        if (!((r->h[GI_VRAD_TAU] | r->h[GI_VRAD_TAU + 1] | r->h[GI_VRAD_TAU + 2]) & GI_HALF_MAGNITUDE)) continue;
        for (int dz = 0; dz < 2; dz++)
          for (int dy = 0; dy < 2; dy++)
            for (int dx = 0; dx < 2; dx++) {
              int bi = (i - dx + R) % R, bj = (j - dy + R) % R, bk = (k - dz + R) % R;
              L->busy[(size_t)bi + (size_t)R * ((size_t)bj + (size_t)R * bk)] = 1;
            }
      }
}

/* busy4 of a block: any busy base cell in it (window cells, wrapped to slots). */
static void mark_busy4(gi_level *L, int R) {
  int nb = gi__busy4_side(R);
  memset(L->busy4, 0, (size_t)nb * nb * nb);
  for (int k = 0; k < R; k++)
    for (int j = 0; j < R; j++) {
      int sk = (L->slot0[2] + k) % R, sj = (L->slot0[1] + j) % R;
      const uint8_t *row = &L->busy[(size_t)R * ((size_t)sj + (size_t)R * sk)];
      uint8_t *brow = &L->busy4[(size_t)nb * ((size_t)(j / GI_EMPTY_BLOCK) + (size_t)nb * (k / GI_EMPTY_BLOCK))];
      for (int i = 0; i < R; i++)
        if (row[(L->slot0[0] + i) % R]) brow[i / GI_EMPTY_BLOCK] = 1;
    }
}

static void busy_range(void *p, size_t b, size_t e, int worker) {
  (void)worker;
  struct gi_cascade *c = p;
  for (size_t d = b; d < e; d++) {
    mark_busy2(&c->lv[d], c->R);
    mark_busy4(&c->lv[d], c->R);
  }
}

/* A level's masks are its own: the levels side by side. */
void gi__cascade_mark_busy(struct gi_cascade *c) {
  gi__parallel_for((size_t)c->n, 1, c->report.quality.threads, busy_range, c);
}

void gi__cascade_count_occupied(struct gi_cascade *c) {
  size_t vox = (size_t)c->R * c->R * c->R;
  for (int d = 0; d < c->n; d++) {
    uint64_t occ = 0;
    for (size_t i = 0; i < vox; i++) occ += c->lv[d].vix[i] != 0;
    c->report.occupied[d] = occ;
  }
}
