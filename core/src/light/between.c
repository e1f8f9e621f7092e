/* between.c: the voxels a bounce fills from their neighbours instead of
 * gathering.
 *
 * On a plane of voxels that each hold one surface of the same orientation
 * (a floor, a wall, a street), a bounce gathers one voxel of each 2x2
 * block of the plane's two in-plane axes: the one whose cells along both
 * are even. The others are planned between gathered neighbours one cell
 * away: along the odd axis (two), or on both diagonals (four). Along an
 * edge, where two surfaces meet in a line of voxels (a facade on the
 * street), every other voxel is planned between its two neighbours on
 * the line. Once those are gathered, a planned voxel whose neighbours
 * agree (every side within AGREE of their mean) takes the mean; where
 * they do not (the light changes across the plane: the ground beside a
 * lit facade, a wall's dark inside near a corner that leaks) it is
 * gathered after all. A neighbour may hold more surfaces than the voxel
 * (the street's voxel at a facade's foot); corners (three surfaces) are
 * always gathered.
 *
 * Measured at default quality (2026-12-03, 2-core Xeon VM): cones per
 * bake -50% on the Cornell box, -21% in the city, -13% in Munich (its
 * buildings are off the grid's axes, its coarse voxels hold several
 * surfaces); probe indirect error 6.46 -> 6.03%, 9.66 -> 9.77%,
 * 7.93 -> 7.94%. Per face, the city's indirect light moved 0.3-2.6% (L1,
 * by level) from gathering every voxel; without the
 * agreement test 3.7-8.4%, and a street probe's light from the ground 4%
 * under a crossing's exact gathers (test_move's drive).
 *
 * The plan and the test depend only on the level's voxels and the
 * gathers, so a cold bake and the move's re-bake at one anchor fill and
 * gather the same voxels and give the same bits (bounce.c gathers the
 * voxels the test turns down: gi__bounce_between). */
#include <stdlib.h>
#include <string.h>
#include "base/internal.h"
#include "light/light.h"

/* A neighbour on the same plane: one group, the same orientation within
 * about 11 degrees, its surface within a quarter voxel of the plane. It
 * may lie a cell off along the plane's axis: a plane on a cell border
 * falls into either layer (the Cornell box's walls), a tilted one climbs
 * (its blocks, 17 degrees off the axes). */
#define PLANE_COS 0.98f
#define PLANE_OFFSET 0.25f
/* A plane's orientation must lie this close to one axis (45 degrees):
 * farther off, its in-plane neighbours climb more than a cell per cell. An
 * edge's line (where two groups meet) must lie within 18 degrees of one:
 * its neighbours are taken one cell along that axis, no layer off. */
#define AXIS_COS 0.7f
#define LINE_COS 0.95f
/* The neighbours agree when each side and channel lies within AGREE of
 * their mean, or of DARK of the brighter side where that is more (a dark
 * side's few percent of noise). */
#define AGREE 0.2f
#define DARK 0.05f

/* The group of h oriented as group i of g, or -1. */
static int match_group(const gi_vgeo *g, int i, const gi_vgeo *h) {
  for (int j = 0; j < h->groups; j++)
    if (gi__dot(h->u.fin.orient[j], g->u.fin.orient[i]) >= PLANE_COS) return j;
  return -1;
}

/* h holds g's surfaces: for each of g's groups one of its own, oriented
 * as it and lying on its plane. It may hold more: the street's voxel
 * beside a facade's foot holds the street too, and its street side is
 * read alone (gi__between_sides). */
static int same_surfaces(const gi_level *L, const gi_vgeo *g, uint32_t slot) {
  const gi_vgeo *h = gi__geo(L, slot);
  if (h->groups < g->groups) return 0;
  int used = 0;
  for (int i = 0; i < g->groups; i++) {
    int j = match_group(g, i, h);
    if (j < 0 || (used >> j & 1)) return 0;
    used |= 1 << j;
    const float *n = g->u.fin.orient[i];
    float off = 0;
    for (int k = 0; k < 3; k++) off += n[k] * (h->u.fin.gcen[j][k] - g->u.fin.gcen[i][k]);
    if (!(fabsf(off) <= PLANE_OFFSET * (float)L->s)) return 0;
  }
  return 1;
}

/* The axis v lies closest to, when within cos_min of it; else -1. */
static int near_axis(const float v[3], float cos_min) {
  int a = 0;
  for (int k = 1; k < 3; k++)
    if (fabsf(v[k]) > fabsf(v[a])) a = k;
  float l = gi__len(v);
  return l > 0 && fabsf(v[a]) >= cos_min * l ? a : -1;
}

/* A two-group voxel on an edge (a facade meeting the street): odd along
 * the edge's axis, between the cells one step along it that hold the same
 * two surfaces. A plane's voxel may take an edge voxel as a neighbour,
 * never a planned one: the edge's line is perpendicular to the plane's
 * orientation, so its axis is one of the plane's two in-plane axes
 * (within 18 and 45 degrees of them, the two cannot coincide), along
 * which the plane's neighbours are even. */
static int edge_slots(const gi_level *L, int R, const int32_t *own, const gi_vgeo *g, const int64_t cell[3],
                      uint32_t nb[4]) {
  float line[3];
  gi__cross(g->u.fin.orient[0], g->u.fin.orient[1], line);
  int a = near_axis(line, LINE_COS);
  if (a < 0 || !(cell[a] & 1)) return 0;
  for (int i = 0; i < 2; i++) {
    int64_t c[3] = {cell[0], cell[1], cell[2]};
    c[a] += i ? 1 : -1;
    if (c[a] < L->cell0[a] || c[a] >= L->cell0[a] + R) return 0;
    uint32_t s = gi__slot(c[0], c[1], c[2], R);
    if (own[s] < 0 || !same_surfaces(L, g, s)) return 0;
    nb[i] = nb[i + 2] = s;
  }
  return 1;
}

int gi__between_slots(const gi_level *L, int R, const int32_t *own, uint32_t slot, uint32_t nb[4]) {
  const gi_vgeo *g = gi__geo(L, slot);
  if (g->groups != 1 && g->groups != 2) return 0;
  int64_t cell[3];
  gi__slot_cell(L, R, slot, cell);
  if (g->groups == 2) return edge_slots(L, R, own, g, cell, nb);
  int a = near_axis(g->u.fin.orient[0], AXIS_COS);
  if (a < 0) return 0;
  int u = (a + 1) % 3, v = (a + 2) % 3;
  int odd_u = (int)(cell[u] & 1), odd_v = (int)(cell[v] & 1);
  if (!odd_u && !odd_v) return 0;
  static const int stay[1] = {0}, both[2] = {-1, 1};
  const int *du = odd_u ? both : stay, *dv = odd_v ? both : stay;
  int m = 0;
  /* Offsets -1 and +1 along each odd axis, 0 along an even one. */
  for (int i = 0; i < 1 + odd_u; i++)
    for (int j = 0; j < 1 + odd_v; j++) {
      int64_t c[3] = {cell[0], cell[1], cell[2]};
      c[u] += du[i], c[v] += dv[j];
      /* Outside the window: no neighbour (toroidal slots would wrap to the far side). */
      if (c[u] < L->cell0[u] || c[u] >= L->cell0[u] + R || c[v] < L->cell0[v] || c[v] >= L->cell0[v] + R) return 0;
      /* In the voxel's layer first, then the one below and the one above. */
      static const int layer[3] = {0, -1, 1};
      int found = 0;
      for (int t = 0; t < 3 && !found; t++) {
        int64_t ca = cell[a] + layer[t];
        if (ca < L->cell0[a] || ca >= L->cell0[a] + R) continue;
        c[a] = ca;
        uint32_t s = gi__slot(c[0], c[1], c[2], R);
        if (own[s] >= 0 && same_surfaces(L, g, s)) nb[m++] = s, found = 1;
      }
      if (!found) return 0;
    }
  if (m == 2) nb[2] = nb[0], nb[3] = nb[1];
  return 1;
}

typedef struct {
  const struct gi_cascade *c;
  const gi_level *L;
  const int32_t *occ_of; /* per slot: its occupied index, or -1 */
  gi_between *b;
} plan_ctx;

/* Each voxel's plan depends on the level's voxels alone: any order. */
static void plan_range(void *p, size_t lo, size_t hi, int worker) {
  (void)worker;
  const plan_ctx *x = p;
  for (size_t i = lo; i < hi; i++) {
    uint32_t nb[4];
    x->b[i].nb[0] = -1;
    if (gi__between_slots(x->L, x->c->R, x->occ_of, x->L->occ[i], nb))
      for (int k = 0; k < 4; k++) x->b[i].nb[k] = x->occ_of[nb[k]];
  }
}

gi_result gi__between_plan(const struct gi_cascade *c, int d, gi_between **out) {
  const gi_level *L = &c->lv[d];
  int R = c->R;
  size_t vox = (size_t)R * R * R;
  int32_t *occ_of = gi__malloc(vox * sizeof *occ_of);
  gi_between *b = gi__realloc(*out, ((size_t)L->num_occ + 1) * sizeof *b);
  if (b) *out = b;
  if (!occ_of || !b) {
    gi__free(occ_of);
    return GI_ERR_NOMEM;
  }
  for (size_t i = 0; i < vox; i++) occ_of[i] = -1;
  for (uint32_t i = 0; i < L->num_occ; i++) occ_of[L->occ[i]] = (int32_t)i;
  plan_ctx x = {.c = c, .L = L, .occ_of = occ_of, .b = b};
  gi__parallel_for(L->num_occ, 256, c->report.quality.threads, plan_range, &x);
  gi__free(occ_of);
  return GI_OK;
}

int gi__between_sides(const gi_vgeo *g, const gi_vgeo *h, const float E[GI_VOX_FACES][3],
                      float Es[2 * GI_VOX_GROUPS][3]) {
  if (h->groups < g->groups) return 0;
  for (int i = 0; i < g->groups; i++) {
    int j = match_group(g, i, h);
    if (j < 0) return 0;
    int a = near_axis(h->u.fin.orient[j], 0.f);
    /* The faces across the surface's major axis show its two sides, never the brighter instead. */
    int f0 = 2 * a, f1 = 2 * a + 1;
    if (h->face_side[f0] / 2 != j || h->face_side[f1] / 2 != j || h->face_side[f0] == h->face_side[f1] ||
        (h->brighter >> f0 & 1) || (h->brighter >> f1 & 1))
      return 0;
    memcpy(Es[2 * i + h->face_side[f0] % 2], E[f0], sizeof Es[0]);
    memcpy(Es[2 * i + h->face_side[f1] % 2], E[f1], sizeof Es[0]);
  }
  return 1;
}

int gi__between_mean(int sides, const float v[4][2 * GI_VOX_GROUPS][3], float out[2 * GI_VOX_GROUPS][3]) {
  float mean[2 * GI_VOX_GROUPS][3], top = 0;
  for (int sd = 0; sd < sides; sd++)
    for (int k = 0; k < 3; k++) {
      mean[sd][k] = 0.25f * ((v[0][sd][k] + v[1][sd][k]) + (v[2][sd][k] + v[3][sd][k]));
      top = gi__maxf(top, mean[sd][k]);
    }
  for (int sd = 0; sd < sides; sd++)
    for (int k = 0; k < 3; k++) {
      float room = gi__maxf(AGREE * mean[sd][k], DARK * top);
      for (int i = 0; i < 4; i++)
        if (!(fabsf(v[i][sd][k] - mean[sd][k]) <= room)) return 0;
    }
  memcpy(out, mean, (size_t)sides * sizeof mean[0]);
  return 1;
}

int gi__between_take(const gi_vgeo *g, const gi_vgeo *const h[4], const float (*const from[4])[3],
                     float E[GI_VOX_FACES][3]) {
  float v[4][2 * GI_VOX_GROUPS][3], mean[2 * GI_VOX_GROUPS][3];
  for (int k = 0; k < 4; k++)
    if (!gi__between_sides(g, h[k], from[k], v[k])) return 0;
  if (!gi__between_mean(2 * g->groups, (const float(*)[2 * GI_VOX_GROUPS][3])v, mean)) return 0;
  gi__face_light(g, (const float(*)[3])mean, E);
  return 1;
}

typedef struct {
  const gi_level *L;
  const gi_between *plan;
  gi_faces3 *E;
  uint32_t *turned; /* per voxel: 1 when its neighbours did not agree */
} fill_ctx;

/* A planned voxel reads its gathered neighbours' E only (a neighbour is
 * never planned itself: gi__between_plan), so the voxels fill in any order. */
static void fill_range(void *p, size_t b, size_t e, int worker) {
  (void)worker;
  const fill_ctx *x = p;
  const gi_level *L = x->L;
  for (size_t i = b; i < e; i++) {
    const int32_t *nb = x->plan[i].nb;
    x->turned[i] = 0;
    if (nb[0] < 0) continue;
    const gi_vgeo *h[4];
    const float(*from[4])[3];
    for (int k = 0; k < 4; k++) h[k] = gi__geo(L, L->occ[nb[k]]), from[k] = (const float(*)[3])x->E[nb[k]];
    x->turned[i] = !gi__between_take(gi__geo(L, L->occ[i]), h, from, x->E[i]);
  }
}

uint32_t gi__between_fill(const struct gi_cascade *c, int d, const gi_between *plan, gi_faces3 *E, uint32_t *redo,
                          int threads) {
  const gi_level *L = &c->lv[d];
  /* Each voxel's verdict in redo first, then the list in place (n <= i). */
  fill_ctx x = {.L = L, .plan = plan, .E = E, .turned = redo};
  gi__parallel_for(L->num_occ, 256, threads, fill_range, &x);
  uint32_t n = 0;
  for (uint32_t i = 0; i < L->num_occ; i++)
    if (redo[i]) redo[n++] = i;
  return n;
}
