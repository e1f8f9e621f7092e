/* move/move.c: scrolling a baked cascade to a new viewpoint (gi_move.h).
 *
 * Levels are stored toroidally (cascade_internal.h), so re-placing a level
 * moves no memory: a cell that stays in the window keeps its slot and its
 * data. Only cells that are new to the window, or that the finer level's
 * region used to cover (they held filtered data), are cleared, voxelized
 * and injected. Voxelization goes through the bake's own per-cell code
 * (gi__voxel_add_tri, gi__voxel_finalize) over the triangles of each
 * stale box in index order, and injection seeds by global cell, so a
 * rebuilt voxel is bit-identical to the bake's.
 *
 * Indirect light (see gi_move.h): the scene is static, so kept voxels
 * keep their light; the new voxels and their neighbours are gathered once
 * from a copy of the live texture without the last bounce's order
 * (fresh_texture). Exactness comes from a re-bake that runs the
 * bake's own bounces (k bounces and the tail, from direct light) against a
 * second texture, one slice per call that keeps the anchor, and swaps it
 * in when done. Measured at default quality on the city (street walk at
 * 1.4 m/s, 10 Hz): the clocked scheme this replaced (whole levels
 * re-gathered every 2^d moves, a cold bake's bounces every 2^(n-1)) kept
 * the probe within 0.41% mean / 1.26% max of cold bakes; this one 0.08% /
 * 0.52%, since a repeated gather drifts toward the infinite-bounce answer
 * rather than the bake's. Everything runs on the call count, never on
 * timing, so a walk is reproducible. A scrolling move filters twice, but
 * only the nested cells above what changed (the whole regions when the
 * texels' scale changed): skipping the filter before the gather (coarse
 * cells just nested keep their own light) nearly tripled the largest probe
 * error on a drive. */
#include <limits.h>
#include <stdlib.h>
#include <string.h>
#include "base/internal.h"
#include "cascade/cascade_internal.h"
#include "gi/gi_move.h"
#include "light/light.h"
#include "plan.h"

/* Cell states during a move, kept in the level's busy array (scratch until
 * gi__cascade_mark_busy rebuilds it at the end of the move). */
enum { CELL_KEEP = 0, CELL_STALE = 1, CELL_VOXELIZED = 2, CELL_NEAR = 3 };

/* A scroll slab per axis and the old nested region. */
#define MAX_BOXES 4
/* Own voxels within this many cells of a rebuilt cell are re-gathered with
 * it. A voxel a few cells from a window's face sends most of its cones out
 * of the window into the coarser level, so what the voxels behind a new
 * slab gathered at the face no longer holds (8 s of the drive at 14 m/s,
 * with 2: level 2's kept voxels 1-3 cells behind the new slabs 5-54% off a
 * cold bake's, under 4% further in). Measured over the 60 s drive against
 * 2: probe drift max 2.03% -> 1.68%, largest jump at a grid shift 2.29% ->
 * 1.48%, for 1.4x the gathers per crossing (4: 1.31% and 1.55% for 1.8x). */
#define NEIGHBOUR_CELLS 3
/* The re-bake runs in 2^(n-1) slices (32 at the default 6 levels: each
 * about 3% of a bake's gathers), never fewer than this. */
#define MIN_SLICES 4
/* A viewer that keeps moving gets a shorter cycle, so the re-bake closes
 * before the next crossing (otherwise it restarts at every crossing and
 * the kept voxels' light drifts from the bake's as the windows scroll:
 * 0.06% after the first crossing of a 1.4 m/s walk, 2.8% after 45; with
 * it, 54 of the walk's 57 anchors close, for 2.5x the CPU per call, 24 ->
 * 59 ms). Never fewer slices than this: one call does at most 1/8 of a
 * bake's gathers; a viewer crossing faster than that keeps the resting
 * cycle. Such a viewer (a drive) never closes one: its kept voxels keep
 * what they gathered nearer a window's face, where a cold bake's cones
 * leave for the coarser level (docs/experiments.md, "Why the drive
 * drifts"). */
#define FAST_MIN_SLICES 8
/* Weight of the newest dwell (calls spent at one anchor) in its running mean. */
#define DWELL_WEIGHT 0.5

typedef struct {
  int64_t lo[3], hi[3]; /* global cells [lo, hi) of one level */
} cell_box;

#define FOR_BOX(b, i, j, k)                            \
  for (int64_t k = (b)->lo[2]; k < (b)->hi[2]; k++)    \
    for (int64_t j = (b)->lo[1]; j < (b)->hi[1]; j++)  \
      for (int64_t i = (b)->lo[0]; i < (b)->hi[0]; i++)

/* The re-bake's slices for a viewer that stays put: 2^(n-1), at least MIN_SLICES. */
static uint64_t resting_period(const struct gi_cascade *c) {
  uint64_t p = 1ull << (c->n - 1);
  return p < MIN_SLICES ? MIN_SLICES : p;
}

static int in_window(const gi_level *L, int R, int64_t i, int64_t j, int64_t k) {
  int64_t p[3] = {i, j, k};
  for (int a = 0; a < 3; a++)
    if (p[a] < L->cell0[a] || p[a] >= L->cell0[a] + R) return 0;
  return 1;
}

/* Boxes of the new window that may hold stale cells. */
static int stale_boxes(const gi_level *old, const gi_level *L, int R, int rebuild, cell_box *b) {
  int n = 0;
  cell_box win;
  for (int a = 0; a < 3; a++) win.lo[a] = L->cell0[a], win.hi[a] = L->cell0[a] + R;
  if (rebuild) {
    b[n++] = win;
    return n;
  }
  for (int a = 0; a < 3; a++) {
    int64_t delta = L->cell0[a] - old->cell0[a];
    if (delta == 0) continue;
    cell_box s = win;
    if (delta > 0) s.lo[a] = old->cell0[a] + R;
    else s.hi[a] = old->cell0[a];
    b[n++] = s;
  }
  if (old->has_inner) {
    cell_box s;
    int empty = 0;
    for (int a = 0; a < 3; a++) {
      s.lo[a] = old->inner0[a] > win.lo[a] ? old->inner0[a] : win.lo[a];
      s.hi[a] = old->inner1[a] < win.hi[a] ? old->inner1[a] : win.hi[a];
      empty |= s.lo[a] >= s.hi[a];
    }
    if (!empty) b[n++] = s;
  }
  return n;
}

/* Marks and clears the own cells of the new window that were not own cells
 * of the old one; returns how many. */
static uint64_t mark_stale(const gi_level *old, gi_level *L, int R, int rebuild, const cell_box *b, int nb) {
  uint64_t count = 0;
  memset(L->busy, CELL_KEEP, (size_t)R * R * R);
  for (int q = 0; q < nb; q++)
    FOR_BOX(&b[q], i, j, k) {
      if (gi__is_inner(L, i, j, k)) continue;
      if (!rebuild && in_window(old, R, i, j, k) && !gi__is_inner(old, i, j, k)) continue;
      uint32_t slot = gi__slot(i, j, k, R);
      if (L->busy[slot] == CELL_STALE) continue;
      L->busy[slot] = CELL_STALE;
      gi__level_release(L, slot);
      memset(&L->rad[slot], 0, sizeof *L->rad);
      count++;
    }
  return count;
}

/* Voxelizes the stale cells of one box: every triangle the BVH finds over
 * them, in index order (the bake's accumulation order per cell). */
static gi_result voxelize_box(struct gi_cascade *c, int d, const cell_box *in, uint32_t **tris, size_t *cap,
                              uint64_t *visited, gi_error_info *err) {
  gi_level *L = &c->lv[d];
  const gi_scene *s = c->scene;
  int R = c->R;
  size_t nt = 0;
  /* The old nested region is a box every move; usually nothing in it is
   * stale, or a slab at one side (what the finer level left): the query
   * takes the stale cells' bounds only. Over the whole region it returned
   * 72,000 of the city's triangles for a level-5 slab of 16 x 16 x 1 cells
   * (5 ms of query and sort on the walk's slowest updates). */
  cell_box sb, *b = &sb;
  for (int a = 0; a < 3; a++) sb.lo[a] = in->hi[a], sb.hi[a] = in->lo[a];
  FOR_BOX(in, i, j, k) {
    if (L->busy[gi__slot(i, j, k, R)] != CELL_STALE) continue;
    int64_t cl[3] = {i, j, k};
    for (int a = 0; a < 3; a++) {
      if (cl[a] < sb.lo[a]) sb.lo[a] = cl[a];
      if (cl[a] + 1 > sb.hi[a]) sb.hi[a] = cl[a] + 1;
    }
  }
  if (sb.lo[0] >= sb.hi[0]) return GI_OK;
  if (s->rtc) {
    float lo[3], hi[3];
    for (int a = 0; a < 3; a++) {
      lo[a] = (float)(b->lo[a] * L->s);
      hi[a] = (float)(b->hi[a] * L->s);
    }
    gi_result rc = gi__query_box(s, lo, hi, tris, &nt, cap);
    if (rc != GI_OK) return gi__fail(err, rc, "move: BVH query failed");
    gi__order_tris(s, *tris, &nt);
  }
  *visited += nt;
  for (size_t q = 0; q < nt; q++) {
    uint32_t t = (*tris)[q];
    const uint32_t *ix = &s->indices[3 * t];
    float tv[3][3];
    for (int v = 0; v < 3; v++) memcpy(tv[v], &s->vertices[3 * ix[v]], sizeof(float[3]));
    cell_box tb;
    for (int a = 0; a < 3; a++) {
      float tlo = gi__minf(tv[0][a], gi__minf(tv[1][a], tv[2][a]));
      float thi = gi__maxf(tv[0][a], gi__maxf(tv[1][a], tv[2][a]));
      tb.lo[a] = (int64_t)floor((double)tlo / L->s);
      tb.hi[a] = (int64_t)floor((double)thi / L->s) + 1;
      if (tb.lo[a] < b->lo[a]) tb.lo[a] = b->lo[a];
      if (tb.hi[a] > b->hi[a]) tb.hi[a] = b->hi[a];
    }
    gi_material tm;
    const gi_material *mat = gi__tri_material(s, t, &tm);
    FOR_BOX(&tb, i, j, k) {
      uint32_t slot = gi__slot(i, j, k, R);
      if (L->busy[slot] != CELL_STALE) continue;
      if (L->vix[slot] == 0) {
        /* The cell's sums get an entry at its first piece (a cell no
         * piece reaches stays empty). */
        if (gi__level_free_entries(L) == 0) {
          gi_result rc = gi__level_reserve(c, d, L->cap + 1, 1, err);
          if (rc != GI_OK) return rc;
        }
        gi__level_take(L, slot);
      }
      int64_t cell[3] = {i, j, k};
      gi__voxel_add_tri(gi__geo(L, slot), L->s, cell, (const float(*)[3])tv, mat);
    }
  }
  /* A cell in two boxes is complete after the first. */
  FOR_BOX(b, i, j, k) {
    uint32_t slot = gi__slot(i, j, k, R);
    if (L->busy[slot] == CELL_STALE) L->busy[slot] = CELL_VOXELIZED;
  }
  return GI_OK;
}

/* One pass of the dilation: in[] grown by `n` cells along window axis a
 * (no wrap: the window ends at its faces). Lines are R cells; a running
 * count of set cells in [x - n, x + n] makes the pass linear in R^3. */
static void dilate_axis(const uint8_t *in, uint8_t *out, int R, int a, int n) {
  size_t st = a == 0 ? 1 : (a == 1 ? (size_t)R : (size_t)R * R);
  for (int v = 0; v < R; v++)
    for (int u = 0; u < R; u++) {
      /* The line's first cell: the other two axes at (u, v). */
      size_t base = a == 0 ? (size_t)R * (u + (size_t)R * v)
                           : (a == 1 ? u + (size_t)R * R * v : u + (size_t)R * v);
      int count = 0;
      for (int x = 0; x < n && x < R; x++) count += in[base + x * st];
      for (int x = 0; x < R; x++) {
        if (x + n < R) count += in[base + (x + n) * st];
        if (x - n - 1 >= 0) count -= in[base + (x - n - 1) * st];
        out[base + x * st] = count > 0;
      }
    }
}

/* Marks the kept cells within NEIGHBOUR_CELLS of a rebuilt cell (in each
 * axis: a cube) CELL_NEAR: a separable dilation over the window in window
 * order, three passes of R^3. The cube per rebuilt cell it replaces cost
 * (2n+1)^3 each: the drive's first 8 s, moves 30.9 -> 27.6 ms at n = 2
 * and 37.7 -> 31.8 ms at n = 3 (medians of 3). `tmp` holds 2 R^3 bytes. */
static void mark_near(gi_level *L, int R, uint8_t *tmp) {
  size_t vox = (size_t)R * R * R, w = 0;
  uint8_t *a = tmp, *b = tmp + vox;
  for (int64_t k = L->cell0[2]; k < L->cell0[2] + R; k++)
    for (int64_t j = L->cell0[1]; j < L->cell0[1] + R; j++)
      for (int64_t i = L->cell0[0]; i < L->cell0[0] + R; i++) a[w++] = L->busy[gi__slot(i, j, k, R)] == CELL_VOXELIZED;
  dilate_axis(a, b, R, 0, NEIGHBOUR_CELLS);
  dilate_axis(b, a, R, 1, NEIGHBOUR_CELLS);
  dilate_axis(a, b, R, 2, NEIGHBOUR_CELLS);
  w = 0;
  for (int64_t k = L->cell0[2]; k < L->cell0[2] + R; k++)
    for (int64_t j = L->cell0[1]; j < L->cell0[1] + R; j++)
      for (int64_t i = L->cell0[0]; i < L->cell0[0] + R; i++) {
        uint8_t *c = &L->busy[gi__slot(i, j, k, R)];
        if (b[w++] && *c == CELL_KEEP) *c = CELL_NEAR;
      }
}

/* Finalizes the voxelized cells and rebuilds the occupied list in the
 * bake's order. Lists in `fresh` the rebuilt occupied voxels and the kept
 * ones next to them (they need a new gather); returns how many, and in
 * *nnew how many of them (the first) were rebuilt. */
static uint32_t finish_level(struct gi_cascade *c, gi_level *L, uint32_t *fresh, uint32_t *nnew, uint8_t *tmp) {
  int R = c->R;
  uint32_t nf = 0;
  int any_voxelized = 0;
  L->num_occ = 0;
  L->num_geo = 0;
  for (int64_t k = L->cell0[2]; k < L->cell0[2] + R; k++)
    for (int64_t j = L->cell0[1]; j < L->cell0[1] + R; j++)
      for (int64_t i = L->cell0[0]; i < L->cell0[0] + R; i++) {
        if (gi__is_inner(L, i, j, k)) continue;
        uint32_t slot = gi__slot(i, j, k, R);
        if (L->busy[slot] == CELL_VOXELIZED) {
          any_voxelized = 1;
          if (L->vix[slot] == 0) continue;
          int64_t cell[3] = {i, j, k};
          if (!gi__voxel_finalize(L, gi__geo(L, slot), slot, cell)) {
            gi__level_release(L, slot);
            continue;
          }
        } else if (L->vix[slot] == 0) {
          continue;
        }
        L->occ[L->num_occ++] = slot;
        L->num_geo++;
      }
  /* Rebuilt voxels first (they need direct light), then their neighbours. */
  for (uint32_t q = 0; q < L->num_occ; q++)
    if (L->busy[L->occ[q]] == CELL_VOXELIZED) fresh[nf++] = L->occ[q];
  uint32_t nf_rebuilt = nf;
  *nnew = nf_rebuilt;
  if (!any_voxelized) return nf;
  mark_near(L, R, tmp);
  for (uint32_t q = 0; q < L->num_occ; q++)
    if (L->busy[L->occ[q]] == CELL_NEAR) fresh[nf++] = L->occ[q];
  return nf;
}

/* The levels' voxelization, one level per task: levels share no cells,
 * entries or triangles, and the BVH queries are thread-safe. Serial, a
 * move where levels 3-5 scrolled together spent 20 ms here, 9 of them on
 * level 5 (a coarse slab's query visits most of the city). */
typedef struct {
  struct gi_cascade *c;
  cell_box (*boxes)[MAX_BOXES];
  const int *nboxes;
  uint32_t **fresh, *nfresh, *nnew;
  uint64_t visited[GI_MAX_LEVELS];
  gi_result rc[GI_MAX_LEVELS];
  gi_error_info err[GI_MAX_LEVELS];
  /* Per worker, kept across its levels: the triangle list and the
   * neighbours' mask (2 R^3 bytes: 33 MB at R 256, written whole per level). */
  struct {
    uint32_t *tris;
    size_t cap;
    uint8_t *tmp;
  } w[GI_MAX_WORKERS];
} scroll_ctx;

static void voxelize_levels(void *p, size_t b, size_t e, int worker) {
  scroll_ctx *x = p;
  struct gi_cascade *c = x->c;
  int R = c->R;
  if (!x->w[worker].tmp) x->w[worker].tmp = gi__malloc(2 * (size_t)R * R * R);
  uint8_t *tmp = x->w[worker].tmp;
  for (size_t i = b; i < e; i++) {
    /* Coarsest first: its slabs hold the most triangles, so it should not start last. */
    size_t d = (size_t)c->n - 1 - i;
    gi_result rc = tmp ? GI_OK : gi__fail(&x->err[d], GI_ERR_NOMEM, "move: out of memory for the neighbours' mask");
    for (int q = 0; q < x->nboxes[d] && rc == GI_OK; q++)
      rc = voxelize_box(c, (int)d, &x->boxes[d][q], &x->w[worker].tris, &x->w[worker].cap, &x->visited[d],
                        &x->err[d]);
    if (rc == GI_OK) x->nfresh[d] = finish_level(c, &c->lv[d], x->fresh[d], &x->nnew[d], tmp);
    x->rc[d] = rc;
  }
}

/* Scrolls every level and rebuilds the geometry of its stale cells. */
static gi_result scroll_levels(struct gi_cascade *c, const gi_level *old, uint32_t **fresh, uint32_t *nfresh,
                               uint32_t *nnew, cell_box (*boxes)[MAX_BOXES], int *nboxes, gi_move_info *mi,
                               gi_error_info *err) {
  int R = c->R;
  scroll_ctx *x = gi__calloc(1, sizeof *x);
  if (!x) return gi__fail(err, GI_ERR_NOMEM, "move: out of memory for the scroll");
  *x = (scroll_ctx){.c = c, .boxes = boxes, .nboxes = nboxes, .fresh = fresh, .nfresh = nfresh, .nnew = nnew};
  for (int d = 0; d < c->n; d++) {
    gi_level *L = &c->lv[d];
    int rebuild = 0;
    for (int a = 0; a < 3; a++) rebuild |= llabs(L->cell0[a] - old[d].cell0[a]) >= R;
    mi->rebuilt[d] = rebuild;
    nboxes[d] = stale_boxes(&old[d], L, R, rebuild, boxes[d]);
    c->report.level_voxelized[d] = mark_stale(&old[d], L, R, rebuild, boxes[d], nboxes[d]);
  }
  gi_result rc = GI_OK;
  if (gi__parallel_for_cancel((size_t)c->n, 1, c->report.quality.threads, voxelize_levels, x, NULL, c->cancel))
    rc = gi__cancel_fail(c->cancel, err, "move voxelize");
  for (int d = 0; d < c->n && rc == GI_OK; d++) {
    gi_level *L = &c->lv[d];
    c->report.triangles_visited += x->visited[d];
    if ((rc = x->rc[d]) != GI_OK) *err = x->err[d];
    /* The nested cells above the finer level, which is final now. */
    if (rc == GI_OK) rc = gi__nested_entries(c, d, err);
    c->report.voxel_size[d] = L->s;
    for (int a = 0; a < 3; a++)
      c->report.level_origin[d][a] = (double)L->cell0[a] * L->s + c->scene->origin[a];
  }
  for (int w = 0; w < gi__num_workers(c->report.quality.threads); w++) gi__free(x->w[w].tris), gi__free(x->w[w].tmp);
  gi__free(x);
  return rc;
}

/* The effect plan at the new placement; *relit when its lights changed. */
static gi_result replan(struct gi_cascade *c, gi_quality *q, int *tail, int *relit, gi_error_info *err) {
  static const int lights[] = {GI_FX_SUN, GI_FX_LOCAL, GI_FX_SKY, GI_FX_EMISSIVE};
  int before[GI_FX_COUNT];
  for (int i = 0; i < GI_FX_COUNT; i++) before[i] = c->report.effects[i].ran;
  *q = c->plan_q;
  gi_result rc = gi__plan_effects(c, q, c->auto_bounces, &c->report, tail, err);
  if (rc != GI_OK) return rc;
  q->ao = c->report.effects[GI_FX_AO].ran;
  c->report.quality = *q;
  *relit = 0;
  for (size_t i = 0; i < sizeof lights / sizeof lights[0]; i++)
    *relit |= before[lights[i]] != c->report.effects[lights[i]].ran;
  return GI_OK;
}

/* The re-bake: the bake's bounce schedule (gi__bounce) at the current
 * anchor, run against its own texture so answers keep reading the live one,
 * and cut into gi_cascade_refresh_period slices of equal gather counts. */
typedef struct gi_move_state {
  gi_vrad *rad[GI_MAX_LEVELS];    /* the re-bake's texture (R^3, toroidal like the live one) */
  gi_faces3 *side[GI_MAX_LEVELS]; /* the level's cap entries (gi__level_reserve keeps them equal) */
  /* Per live entry (cap, like side): what the last bounce added to its
   * light before the tail (D_k), for the fresh texture (fresh_texture).
   * Set for every own voxel when a re-bake closes; a crossing's gathered
   * voxels then get the last bounce's share of their new light. Valid
   * while have_last. */
  gi_faces3 *last[GI_MAX_LEVELS];
  int have_last;
  void *block;     /* rad of every level, one gi__big_calloc block (see struct gi_cascade) */
  size_t block_bytes;
  gi_faces3 *E[GI_MAX_LEVELS]; /* this bounce's gathers, per occupied voxel */
  gi_hfaces *H[GI_MAX_LEVELS]; /* the last bounce's hit shares, per occupied voxel (the tail's ratio) */
  uint32_t ecap[GI_MAX_LEVELS];   /* entries E[d] and H[d] hold */
  gi_between *plan[GI_MAX_LEVELS]; /* the voxels filled from their neighbours (the bake's plan at this anchor) */
  uint32_t plan_len[GI_MAX_LEVELS]; /* entries plan[d] holds */
  float rad_scale;
  int slice;       /* slices run at this anchor */
  int closed;      /* 1: the live cascade equals a cold bake at this anchor */
  int bounces, tail;
  double S[2][3];  /* the tail's area-weighted sums of the last two increments (as gi__bounce) */
  uint64_t period; /* slices of the cycle under way (0: the resting period) */
  uint64_t calls;  /* calls at the current anchor, the one that arrived included */
  double dwell;    /* running mean of calls per anchor while moving (0: none measured yet) */
  int arrived;     /* 1 once a move arrived at an anchor (the bake's own anchor's dwell is unknown) */
} gi_move_state;

/* P, read by the move itself too (while the cascade is torn). */
static uint64_t refresh_period(const struct gi_cascade *c) {
  const struct gi_move_state *m = c->move_state;
  return m && m->period ? m->period : resting_period(c);
}

uint64_t gi_cascade_refresh_period(const gi_cascade *c, int level) {
  /* A partial cascade's cycle was restarted part way: no period to tell. */
  if (!c || c->torn || level < 0 || level >= c->n) return 0;
  return refresh_period(c);
}

void gi__move_state_free(struct gi_move_state *m) {
  if (!m) return;
  gi__big_free(m->block, m->block_bytes, 1);
  for (int d = 0; d < GI_MAX_LEVELS; d++)
    gi__free(m->E[d]), gi__free(m->H[d]), gi__free(m->side[d]), gi__free(m->last[d]), gi__free(m->plan[d]);
  gi__free(m);
}

/* The re-bake's side and last arrays of level d at `entries` (the level's
 * cap: both side arrays always hold cap entries, so the swap keeps every
 * level whole). */
static gi_result move_state_reserve(struct gi_move_state *m, int d, uint32_t entries) {
  gi_faces3 *p = gi__realloc(m->side[d], (size_t)entries * sizeof *p);
  if (!p) return GI_ERR_NOMEM;
  m->side[d] = p;
  if (!(p = gi__realloc(m->last[d], (size_t)entries * sizeof *p))) return GI_ERR_NOMEM;
  m->last[d] = p;
  return GI_OK;
}

size_t gi__move_state_bytes(const struct gi_cascade *c) {
  const gi_move_state *m = c ? c->move_state : NULL;
  if (!m) return 0;
  size_t vox = (size_t)c->R * c->R * c->R, bytes = sizeof *m;
  for (int d = 0; d < c->n; d++)
    bytes += vox * sizeof *m->rad[d] +
             c->lv[d].cap * (sizeof *m->side[d] + sizeof *m->last[d] + sizeof *c->lv[d].shift) +
             m->ecap[d] * (sizeof *m->E[d] + sizeof *m->H[d]) + m->plan_len[d] * sizeof *m->plan[d];
  return bytes;
}

size_t gi_cascade_move_bytes_estimate(const gi_quality *q) {
  /* Out of range, as gi_cascade_bytes_estimate: the product would wrap. */
  if (!q || q->levels <= 0 || q->res <= 0 || q->levels > GI_MAX_LEVELS || q->res > GI_MAX_RES) return 0;
  gi_move_state *m = NULL;
  /* At most every voxel holds geometry: one side, last, E, H, plan and shift entry each. */
  size_t per_voxel = sizeof *m->rad[0] + sizeof *m->side[0] + sizeof *m->last[0] + sizeof *m->E[0] +
                     sizeof *m->H[0] + sizeof *m->plan[0] + sizeof(gi_shift6);
  return sizeof *m + (size_t)q->levels * (size_t)q->res * (size_t)q->res * (size_t)q->res * per_voxel;
}

/* Level L's apex shifts, kept per entry from now on (gi_shift6), all
 * still to be found: the bake's were its own. */
static gi_result shift_alloc(gi_level *L) {
  if (L->shift) return GI_OK;
  /* A level with no entry yet gets one slot: gi__level_reserve grows what exists. */
  if (!(L->shift = gi__malloc((size_t)(L->cap ? L->cap : 1) * sizeof *L->shift))) return GI_ERR_NOMEM;
  for (uint32_t e = 0; e < L->cap; e++) L->shift[e].v[0][0] = NAN;
  return GI_OK;
}

/* A freshly baked cascade is its anchor's bake: the state starts closed. */
static gi_result move_state(struct gi_cascade *c, gi_error_info *err) {
  if (c->move_state) return GI_OK;
  gi_move_state *m = gi__calloc(1, sizeof *m);
  size_t vox = (size_t)c->R * c->R * c->R;
  size_t per_level = vox * sizeof *m->rad[0];
  char *b = NULL;
  if (m) m->block_bytes = (size_t)c->n * per_level;
  if (m && (b = m->block = gi__big_calloc(m->block_bytes, 1)))
    for (int d = 0; d < c->n; d++) {
      m->rad[d] = (gi_vrad *)b, b += vox * sizeof *m->rad[d];
      if (move_state_reserve(m, d, c->lv[d].cap) != GI_OK || shift_alloc(&c->lv[d]) != GI_OK) b = NULL;
      if (!b) break;
    }
  if (!b) {
    gi__move_state_free(m);
    for (int d = 0; d < c->n; d++) gi__free(c->lv[d].shift), c->lv[d].shift = NULL;
    return gi__fail(err, GI_ERR_NOMEM, "move: out of memory for the re-bake's texture");
  }
  /* Touched now (it starts as the live texture): left to the first
   * crossing, its page faults made that move 15-20 ms slower than the
   * same scroll later (Munich, 6 levels of 32^3: 12 MB). */
  for (int d = 0; d < c->n; d++) memcpy(m->rad[d], c->lv[d].rad, vox * sizeof *m->rad[d]);
  m->closed = 1;
  c->move_state = m;
  return GI_OK;
}

gi_result gi_cascade_move_prepare(gi_cascade *c, gi_error_info *err) {
  if (!c) return gi__fail(err, GI_ERR_INVALID_ARG, "move: no cascade");
  /* Its state exists but was left part way: the next move re-bakes instead. */
  if (gi__cascade_whole(c, "prepare", err) != GI_OK) return GI_ERR_INVALID_ARG;
  return move_state(c, err);
}

/* Exchanges the live texture and the re-bake's (pointers only). */
static void swap_texture(struct gi_cascade *c, gi_move_state *m) {
  for (int d = 0; d < c->n; d++) {
    gi_vrad *r = c->lv[d].rad;
    gi_faces3 *sd = c->lv[d].side;
    c->lv[d].rad = m->rad[d], m->rad[d] = r;
    c->lv[d].side = m->side[d], m->side[d] = sd;
  }
  float sc = c->rad_scale;
  c->rad_scale = m->rad_scale, m->rad_scale = sc;
}

typedef struct {
  const struct gi_cascade *c;
  int d;
  const uint32_t *slots;
  int wide;        /* the bounces' wide set (gi__bounce_wide) */
  const gi_between *plan; /* the slots' plan entries, or NULL: gather every one */
  gi_faces3 *E;
  gi_hfaces *H;    /* the slots' hit shares, or NULL */
  atomic_ullong samples, cones;
} gather_ctx;

static void gather_range(void *p, size_t b, size_t e, int worker) {
  gather_ctx *g = p;
  uint64_t samples = 0, cones = 0;
  const gi_between *plan = g->plan ? g->plan + b : NULL;
  samples += gi__gather_voxels(g->c, g->d, g->slots + b, e - b, g->wide, plan, g->E + b, g->H ? g->H + b : NULL,
                               &cones);
  atomic_fetch_add(&g->samples, samples);
  atomic_fetch_add(&g->cones, cones);
}

/* Gathers the n voxels slots[] of level d from the current texture into E
 * (and their hit shares into H, may be NULL) with the diffuse or the wide
 * set, except those plan (the slots' own entries, or NULL) fills from
 * their neighbours. The report counts the
 * cones and samples of every gather, the voxels (level_rebounced) once a move: the
 * new voxels' first gather (fresh_texture's prime) does not count them. */
static gi_result gather_list(struct gi_cascade *c, int threads, int d, const uint32_t *slots, uint32_t n, int wide,
                             const gi_between *plan, int count, gi_faces3 *E, gi_hfaces *H, gi_error_info *err) {
  gather_ctx g = {.c = c, .d = d, .slots = slots, .wide = wide, .plan = plan, .E = E, .H = H};
  atomic_init(&g.samples, 0);
  atomic_init(&g.cones, 0);
  int cancelled = gi__parallel_for_cancel(n, 16, threads, gather_range, &g, NULL, c->cancel);
  c->report.cone_samples += atomic_load(&g.samples);
  c->report.cones_traced += atomic_load(&g.cones);
  if (count) c->report.level_rebounced[d] += n;
  return cancelled ? gi__cancel_fail(c->cancel, err, "move gather") : GI_OK;
}

/* With a bounce tail the fresh gather takes D_k and the tail on it off
 * (1 + f times D_k) and puts the tail back on what it gathers: with each
 * voxel's own D_k once a re-bake closed (the 600 m city's walk, 12
 * sampled shifts: 1.09% -> 0.82% from cold bakes, against 0.94% between
 * cold bakes). Before, only the cascade's mean share is known, which
 * misses where a voxel's own differs (near a lamp the first orders are
 * most of its light) and the tail multiplies the miss by f: the lit
 * room's walk that never closes (f ~ 9) read 0.0062 mean from cold bakes
 * so, 0.0028 with the whole texture read, which holds every order (the
 * gather of it returns E_k + f D_k where the ratio is the tail's). */
static int whole_texture(const struct gi_cascade *c, const gi_move_state *m) {
  return !m->have_last && c->tail_gain[0] + c->tail_gain[1] + c->tail_gain[2] > 0;
}

/* The texture the fresh gather reads, in the re-bake's arrays (free at a
 * crossing: the cycle restarts): every own voxel's light without what the
 * last bounce (and the tail on it: whole_texture) added, shaded and
 * filtered. A bake's last gather reads
 * orders 0..k-1 and returns orders 1..k; a gather of the whole texture
 * returned one order more (on a 1.4 m/s walk through the city, 3 bounces:
 * the probe 0.13% further from a cold bake right after a crossing, in the
 * direction of the jump). Since a re-bake closed, each voxel's own last
 * increment (m->last); before, the last bounce's share of its indirect
 * light (c->last_share): 1.15% -> 1.05% with the share alone, 0.92% with
 * the voxels' own (cold bakes 1.02%) at the walk's worst shift. New
 * voxels hold their direct light and the same share of prime[d][q], a
 * first gather of theirs from the live texture (the bounces' wide set
 * where there is one: it feeds the later orders only); with their direct
 * light alone the voxels behind a new slab gathered too little from it
 * (the drive, a new slab at nearly every step: probe 0.46% / 1.98% mean /
 * max from cold bakes, 0.39% / 1.49% primed). Swaps the fresh texture in
 * (the caller swaps it out); nonzero when cancelled. */
static int fresh_texture(struct gi_cascade *c, gi_move_state *m, int threads, uint32_t **fresh,
                         const uint32_t *nnew, gi_faces3 *const *prime) {
  size_t vox = (size_t)c->R * c->R * c->R;
  float keep[3], drop[3];
  int whole = whole_texture(c, m);
  for (int k = 0; k < 3; k++) {
    drop[k] = 1 + c->tail_gain[k]; /* D_k and the tail on it */
    keep[k] = whole ? 1 : fmaxf(0.f, 1 - drop[k] * c->last_share[k]);
  }
  for (int d = 0; d < c->n; d++) {
    gi_level *L = &c->lv[d];
    memcpy(m->rad[d], L->rad, vox * sizeof *L->rad);
    /* New voxels' entries (last may be a released voxel's) are set below. */
    for (uint32_t i = 0; i < L->num_occ; i++) {
      uint32_t e = L->vix[L->occ[i]];
      for (int f = 0; f < GI_VOX_FACES; f++)
        for (int k = 0; k < 3; k++)
          m->side[d][e][f][k] = m->have_last ? L->side[e][f][k] - drop[k] * m->last[d][e][f][k]
                                             : L->direct[e][f][k] + keep[k] * (L->side[e][f][k] - L->direct[e][f][k]);
    }
    for (uint32_t q = 0; q < nnew[d]; q++) {
      uint32_t e = L->vix[fresh[d][q]];
      for (int f = 0; f < GI_VOX_FACES; f++)
        for (int k = 0; k < 3; k++) m->side[d][e][f][k] = L->direct[e][f][k] + keep[k] * prime[d][q][f][k];
    }
  }
  swap_texture(c, m);
  gi__shade_all(c);
  return gi__cascade_filter(c, threads);
}

/* gather_list over level d's voxels slots[0..n), but the voxels the bake
 * fills from their neighbours (light/between.c) take their neighbours'
 * mean here too: a listed neighbour's gather, or the indirect light the
 * others hold (side, the live side entries, less direct). A crossing's
 * gather matches the bake's planned voxels so (with every listed voxel
 * gathered, and before the agreement test, the drive's probe read 0.42% /
 * 12.8% mean / max from cold bakes), and saves what the bake saves. own:
 * R^3 scratch. */
static gi_result gather_planned(struct gi_cascade *c, int threads, int d, const uint32_t *slots, uint32_t n,
                                int wide, int count, const gi_faces3 *side, gi_faces3 *E, int32_t *own,
                                gi_error_info *err) {
  const gi_level *L = &c->lv[d];
  size_t vox = (size_t)c->R * c->R * c->R;
  gi_between *plan = gi__malloc(((size_t)n + 1) * sizeof *plan);
  if (!plan) return gi__fail(err, GI_ERR_NOMEM, "move: out of memory for the gather plan of level %d", d);
  for (size_t s = 0; s < vox; s++) own[s] = -1;
  for (uint32_t i = 0; i < L->num_occ; i++) own[L->occ[i]] = INT32_MAX;
  for (uint32_t q = 0; q < n; q++) own[slots[q]] = (int32_t)q;
  /* nb holds neighbour slots here (R^3 < 2^31), only nb[0] >= 0 is read by the gather. */
  for (uint32_t q = 0; q < n; q++) {
    uint32_t nb[4];
    plan[q].nb[0] = -1;
    if (gi__between_slots(L, c->R, own, slots[q], nb))
      for (int k = 0; k < 4; k++) plan[q].nb[k] = (int32_t)nb[k];
  }
  gi_result rc = gather_list(c, threads, d, slots, n, wide, plan, count, E, NULL, err);
  /* Planned voxels whose neighbours disagree are gathered after all: marked by nb[0] = -2 for the second list. */
  uint32_t redo = 0;
  for (uint32_t q = 0; q < n && rc == GI_OK; q++) {
    if (plan[q].nb[0] < 0) continue;
    const gi_vgeo *h[4];
    const float(*from[4])[3];
    float kept[4][GI_VOX_FACES][3];
    for (int k = 0; k < 4; k++) {
      uint32_t ns = (uint32_t)plan[q].nb[k];
      int32_t p = own[ns];
      h[k] = gi__geo(L, ns);
      from[k] = p == INT32_MAX ? (const float(*)[3])kept[k] : (const float(*)[3])E[p];
      if (p != INT32_MAX) continue;
      const float(*dir)[3] = gi__direct(L, ns);
      for (int f = 0; f < GI_VOX_FACES; f++)
        for (int ch = 0; ch < 3; ch++) kept[k][f][ch] = side[L->vix[ns]][f][ch] - dir[f][ch];
    }
    if (!gi__between_take(gi__geo(L, slots[q]), h, from, E[q])) plan[q].nb[0] = -2, redo++;
  }
  if (rc == GI_OK && redo) {
    /* The turned-down voxels: their slots, their places in the list, their gathers. */
    uint32_t *rs = gi__malloc((size_t)redo * sizeof *rs), *at = gi__malloc((size_t)redo * sizeof *at);
    gi_faces3 *got = gi__malloc((size_t)redo * sizeof *got);
    if (!rs || !at || !got) rc = gi__fail(err, GI_ERR_NOMEM, "move: out of memory for the gather of level %d", d);
    uint32_t j = 0;
    for (uint32_t q = 0; q < n && rc == GI_OK; q++)
      if (plan[q].nb[0] == -2) rs[j] = slots[q], at[j++] = q;
    if (rc == GI_OK) rc = gather_list(c, threads, d, rs, redo, wide, NULL, 0, got, NULL, err);
    for (j = 0; j < redo && rc == GI_OK; j++) memcpy(E[at[j]], got[j], sizeof got[j]);
    gi__free(rs), gi__free(at), gi__free(got);
  }
  gi__free(plan);
  return rc;
}

/* A kept voxel's own tail gain 1 + f D_k / E_k and share D_k / E_k,
 * from the light it holds (side, direct) and its last increment D_k
 * (last), rather than the cascade's mean (see whole_texture). Leaves g,
 * sh as they are where the voxel holds no light before its tail. */
static void own_gain(const struct gi_cascade *c, float (*side)[3], float (*direct)[3], float (*last)[3], float g[3],
                     float sh[3]) {
  for (int k = 0; k < 3; k++) {
    double ek = 0, dk = 0, f = c->tail_gain[k];
    for (int sd = 0; sd < GI_VOX_FACES; sd++) {
      ek += side[sd][k] - direct[sd][k] - f * last[sd][k];
      dk += last[sd][k];
    }
    if (!(ek > 0) || !(dk >= 0)) continue;
    g[k] = (float)(1 + f * dk / ek);
    sh[k] = (float)(dk / ek);
  }
}

/* The live update's light: one Jacobi gather of the new voxels and their
 * kept neighbours from the fresh texture. Kept voxels further away
 * keep their light: the scene is static, so the light they hold is still
 * the field the bake would find there (measured: re-gathering whole levels
 * drifts toward the infinite-bounce answer instead, 5x the probe error). */
static gi_result gather_fresh(struct gi_cascade *c, int threads, uint32_t **fresh, const uint32_t *nfresh,
                              const uint32_t *nnew, gi_error_info *err) {
  gi_faces3 *E[GI_MAX_LEVELS] = {0};
  gi_move_state *m = c->move_state;
  gi_result rc = GI_OK;
  int32_t *own = gi__malloc((size_t)c->R * c->R * c->R * sizeof *own);
  if (!own) rc = gi__fail(err, GI_ERR_NOMEM, "move: out of memory for the gather plan");
  for (int d = 0; d < c->n && rc == GI_OK; d++)
    if (!(E[d] = gi__malloc(((size_t)nfresh[d] + 1) * sizeof *E[d])))
      rc = gi__fail(err, GI_ERR_NOMEM, "move: out of memory for the gather of level %d", d);
  if (rc != GI_OK) goto done;
  /* The new voxels' first gather, from the live texture (see
   * fresh_texture), with the set the bounces take for the later orders. */
  for (int d = 0; d < c->n && rc == GI_OK; d++)
    rc = gather_planned(c, threads, d, fresh[d], nnew[d], gi__bounce_wide(c, INT_MAX, d), 0, c->lv[d].side, E[d],
                        own, err);
  if (rc == GI_OK) {
    if (fresh_texture(c, m, threads, fresh, nnew, E)) rc = gi__cancel_fail(c->cancel, err, "move filter");
    /* The fresh texture is swapped in: the live side entries are m's now.
     * Each level gathers with the set of the bake's first bounce. */
    for (int d = 0; d < c->n && rc == GI_OK; d++)
      rc = gather_planned(c, threads, d, fresh[d], nfresh[d], gi__bounce_wide(c, 0, d), 1, m->side[d], E[d], own,
                          err);
    swap_texture(c, m);
  }
  /* The gather returned orders 1..k+1 (E_k): the tail puts f D_k on it,
   * D_k = s_k E_k with s_k = s / (1 - f s) (s: last_share, a share of
   * the light with the tail), so the light is E_k / (1 - f s). */
  float gain[3], share[3];
  int whole = whole_texture(c, m);
  for (int k = 0; k < 3; k++) {
    float fs = whole ? 0 : c->tail_gain[k] * c->last_share[k];
    gain[k] = fs < 1 ? 1 / (1 - fs) : 1;
    share[k] = c->last_share[k] * gain[k];
  }
  for (int d = 0; d < c->n && rc == GI_OK; d++) {
    gi_level *L = &c->lv[d];
    for (uint32_t q = 0; q < nfresh[d]; q++) {
      uint32_t slot = fresh[d][q];
      float(*side)[3] = gi__side(L, slot), (*direct)[3] = gi__direct(L, slot);
      float(*last)[3] = m->last[d][L->vix[slot]];
      float g[3] = {gain[0], gain[1], gain[2]}, sh[3] = {share[0], share[1], share[2]};
      /* fresh[d]'s first nnew[d] are the new voxels: no D_k of their own. */
      if (m->have_last && q >= nnew[d]) own_gain(c, side, direct, last, g, sh);
      for (int sd = 0; sd < GI_VOX_FACES; sd++)
        for (int k = 0; k < 3; k++) {
          side[sd][k] = direct[sd][k] + g[k] * E[d][q][sd][k];
          last[sd][k] = sh[k] * E[d][q][sd][k];
        }
    }
  }
done:
  for (int d = 0; d < c->n; d++) gi__free(E[d]);
  gi__free(own);
  return rc;
}

/* Slice 0 of a re-bake: its texture from the live one (opacity lanes and
 * geometry are the anchor's already), every own voxel back to its direct
 * light, shaded and filtered: the bake's state before its first bounce. */
static gi_result rebake_start(struct gi_cascade *c, const gi_quality *q, int tail, gi_error_info *err) {
  gi_move_state *m = c->move_state;
  size_t vox = (size_t)c->R * c->R * c->R;
  for (int d = 0; d < c->n; d++) {
    gi_level *L = &c->lv[d];
    memcpy(m->rad[d], L->rad, vox * sizeof *L->rad);
    memset(m->side[d], 0, L->cap * sizeof *m->side[d]);
    for (uint32_t i = 0; i < L->num_occ; i++)
      memcpy(m->side[d][L->vix[L->occ[i]]], gi__direct(L, L->occ[i]), sizeof *L->side);
    if (m->ecap[d] < L->num_occ + 1) {
      gi__free(m->E[d]), gi__free(m->H[d]);
      m->ecap[d] = 0;
      m->E[d] = gi__malloc(((size_t)L->num_occ + 1) * sizeof *m->E[d]);
      m->H[d] = gi__malloc(((size_t)L->num_occ + 1) * sizeof *m->H[d]);
      if (!m->E[d] || !m->H[d]) return gi__fail(err, GI_ERR_NOMEM, "move: out of memory for the re-bake of level %d", d);
      m->ecap[d] = L->num_occ + 1;
    }
    /* Only the last bounce's gathers measure them (as gi__bounce). */
    memset(m->H[d], GI_HIT_UNKNOWN, ((size_t)L->num_occ + 1) * sizeof *m->H[d]);
    m->plan_len[d] = 0;
    if (gi__between_plan(c, d, &m->plan[d]) != GI_OK)
      return gi__fail(err, GI_ERR_NOMEM, "move: out of memory for the re-bake's plan of level %d", d);
    m->plan_len[d] = L->num_occ + 1;
  }
  m->bounces = c->report.effects[GI_FX_BOUNCE].ran ? q->bounces : 0;
  m->tail = tail;
  memset(m->S, 0, sizeof m->S);
  swap_texture(c, m);
  gi__shade_all(c);
  int cancelled = gi__cascade_filter(c, q->threads);
  swap_texture(c, m);
  return cancelled ? gi__cancel_fail(c->cancel, err, "re-bake filter") : GI_OK;
}

/* The hit shares the re-bake's tail takes (gi__bounce's rule: a tail
 * after two bounces or more), or NULL. */
static gi_hfaces *const *tail_H(const gi_move_state *m) { return m->tail && m->bounces >= 2 ? m->H : NULL; }

/* Ends bounce `it` of the re-bake on its (swapped-in) texture with the
 * bake's own bounce end (light/bounce.c), so the result is bit-identical
 * to the bake's; then refilters. Between bounces that texture holds the
 * last increment only (the live one stays whole). */
static int rebake_bounce_end(struct gi_cascade *c, gi_move_state *m, int it, int threads) {
  gi__bounce_end(c, m->E, tail_H(m), m->S, m->tail && it + 1 == m->bounces && it >= 1, it + 1 == m->bounces);
  return gi__cascade_filter(c, threads);
}

/* Gathers units [lo, hi) of the re-bake (unit u: bounce u / U, then the
 * levels' occupied voxels in order, U voxels per bounce) from its texture,
 * ending each bounce whose last unit falls in the range. */
static gi_result rebake_units(struct gi_cascade *c, gi_move_state *m, uint64_t lo, uint64_t hi, uint64_t U,
                              int threads, gi_error_info *err) {
  gi_result rc = GI_OK;
  swap_texture(c, m);
  while (lo < hi && rc == GI_OK) {
    int it = (int)(lo / U);
    uint64_t end = (uint64_t)(it + 1) * U < hi ? (uint64_t)(it + 1) * U : hi, base = (uint64_t)it * U;
    for (int d = 0; d < c->n && rc == GI_OK; base += c->lv[d].num_occ, d++) {
      uint64_t b = lo > base ? lo - base : 0, e = end - base;
      if (e > c->lv[d].num_occ) e = c->lv[d].num_occ;
      if (lo >= base + c->lv[d].num_occ || end <= base || b >= e) continue;
      gi_hfaces *H = tail_H(m) && it + 1 == m->bounces ? m->H[d] + b : NULL;
      rc = gather_list(c, threads, d, c->lv[d].occ + b, (uint32_t)(e - b), gi__bounce_wide(c, it, d),
                       m->plan[d] + b, 1, m->E[d] + b, H, err);
    }
    if (rc == GI_OK && end == (uint64_t)(it + 1) * U) {
      uint64_t samples = 0, cones = 0;
      rc = gi__bounce_between(c, m->plan, m->E, it, threads, &samples, &cones, err);
      c->report.cone_samples += samples;
      c->report.cones_traced += cones;
      if (rc == GI_OK && rebake_bounce_end(c, m, it, threads)) rc = gi__cancel_fail(c->cancel, err, "re-bake filter");
    }
    lo = end;
  }
  swap_texture(c, m);
  return rc;
}

/* At a re-bake's end: each own voxel's last increment (its last bounce's
 * gather, still in E, before the tail) by entry. */
static void keep_last(struct gi_cascade *c, gi_move_state *m) {
  m->have_last = m->bounces > 0 && c->last_share[0] + c->last_share[1] + c->last_share[2] > 0;
  for (int d = 0; d < c->n && m->have_last; d++) {
    const gi_level *L = &c->lv[d];
    for (uint32_t i = 0; i < L->num_occ; i++) memcpy(m->last[d][L->vix[L->occ[i]]], m->E[d][i], sizeof m->E[d][i]);
  }
}

/* Runs the next slice of the re-bake; the last one hands its texture to
 * the live cascade (a pointer swap), which then equals a cold bake. */
static gi_result rebake_slice(struct gi_cascade *c, const gi_quality *q, int tail, gi_move_info *mi,
                              gi_error_info *err) {
  gi_move_state *m = c->move_state;
  if (m->closed) return GI_OK;
  uint64_t P = refresh_period(c);
  gi_result rc = GI_OK;
  if (m->slice == 0 && (rc = rebake_start(c, q, tail, err)) != GI_OK) return rc;
  uint64_t U = 0;
  for (int d = 0; d < c->n; d++) U += c->lv[d].num_occ;
  uint64_t W = U * (uint64_t)m->bounces, s = (uint64_t)m->slice;
  if (W > 0 && (rc = rebake_units(c, m, s * W / P, (s + 1) * W / P, U, q->threads, err)) != GI_OK) return rc;
  mi->slice = ++m->slice;
  if ((uint64_t)m->slice < P) return GI_OK;
  swap_texture(c, m);
  m->closed = 1;
  keep_last(c, m);
  mi->cycle_closed = 1;
  for (int d = 0; d < c->n; d++) mi->refreshed[d] = 1;
  c->report.bounces_run = m->bounces;
  return GI_OK;
}

/* Direct light into the rebuilt voxels (every own voxel when relit). */
static gi_result inject_fresh(struct gi_cascade *c, const gi_quality *q, int relit, uint32_t **fresh,
                              const uint32_t *nnew, gi_error_info *err) {
  const uint32_t *slots[GI_MAX_LEVELS];
  uint32_t count[GI_MAX_LEVELS];
  for (int d = 0; d < c->n; d++) {
    gi_level *L = &c->lv[d];
    slots[d] = relit ? L->occ : fresh[d];
    count[d] = relit ? L->num_occ : nnew[d];
  }
  gi_result rc = gi__inject_levels(c, q, slots, count, err);
  if (rc != GI_OK) return rc;
  for (int d = 0; d < c->n; d++) c->report.level_injected[d] = count[d];
  gi__shade_all(c);
  return GI_OK;
}

static gi_result check_viewpoint(const gi_cascade *c, const double at[3], gi_error_info *err) {
  if (!c || !at) return gi__fail(err, GI_ERR_INVALID_ARG, "move: cascade and viewpoint are required");
  if (!isfinite(at[0]) || !isfinite(at[1]) || !isfinite(at[2]))
    return gi__fail(err, GI_ERR_NONFINITE, "move: viewpoint (%g, %g, %g) is not finite", at[0], at[1], at[2]);
  return gi__viewpoint_range(c->scene, at, c->s0, "move", err);
}

/* Counters describe this move only. */
static void reset_counters(gi_bake_report *r) {
  memset(&r->ms, 0, sizeof r->ms);
  r->triangles_visited = r->shadow_rays = r->cone_samples = r->cones_traced = 0;
  r->bounces_run = 0;
  memset(r->level_voxelized, 0, sizeof r->level_voxelized);
  memset(r->level_injected, 0, sizeof r->level_injected);
  memset(r->level_rebounced, 0, sizeof r->level_rebounced);
}

/* Boxes of changed cells per level: a level's own stale boxes grown by
 * `grow` cells, and the nested cells above every changed box of the finer
 * level (refiltered here, finer levels first). */
#define MAX_CHANGED (MAX_BOXES * GI_MAX_LEVELS)
static int refilter_changed(struct gi_cascade *c, int threads, cell_box (*own)[MAX_BOXES], const int *nown,
                            int grow) {
  cell_box ch[2][MAX_CHANGED];
  int nch[2] = {0, 0};
  for (int d = 0; d < c->n; d++) {
    cell_box *cur = ch[d & 1], *fine = ch[!(d & 1)];
    int n = 0;
    for (int q = 0; q < nown[d]; q++) {
      cur[n] = own[d][q];
      for (int a = 0; a < 3; a++) cur[n].lo[a] -= grow, cur[n].hi[a] += grow;
      n++;
    }
    for (int q = 0; d > 0 && q < nch[!(d & 1)]; q++) {
      cell_box p;
      for (int a = 0; a < 3; a++) {
        p.lo[a] = gi__floordiv(fine[q].lo[a], 2);
        p.hi[a] = gi__floordiv(fine[q].hi[a] - 1, 2) + 1;
      }
      if (gi__cascade_filter_box(c, threads, d, p.lo, p.hi)) return 1;
      cur[n++] = p;
    }
    nch[d & 1] = n;
  }
  return 0;
}

/* Refilters what changed, or every nested region when `all` (the texels'
 * scale changed, so every filtered texel is stale). */
static int refilter(struct gi_cascade *c, int threads, int all, cell_box (*own)[MAX_BOXES], const int *nown,
                    int grow) {
  return all ? gi__cascade_filter(c, threads) : refilter_changed(c, threads, own, nown, grow);
}

/* A new anchor restarts the re-bake. Its length follows how long the
 * viewer has been staying at each anchor: the largest slice count that
 * still closes the cycle within the mean dwell (the arriving call does not
 * count), not below FAST_MIN_SLICES (else the resting period: a cycle
 * that cannot close before the next crossing at 1/8 of a bake per call
 * is not worth its work), never above the resting period. */
static void start_cycle(struct gi_cascade *c) {
  gi_move_state *m = c->move_state;
  if (m->arrived)
    m->dwell = m->dwell > 0 ? DWELL_WEIGHT * (double)m->calls + (1 - DWELL_WEIGHT) * m->dwell : (double)m->calls;
  m->arrived = 1;
  m->calls = 1;
  uint64_t rest = resting_period(c), p = m->dwell > 1 ? (uint64_t)(m->dwell - 1) : 0;
  m->period = p >= FAST_MIN_SLICES && p < rest ? p : rest;
  m->slice = 0;
  m->closed = 0;
}

/* Scrolls to the new placement and updates the live light: voxelize and
 * inject the new voxels, gather them and their neighbours once. A move that
 * re-lit every voxel or rebuilt a level runs the whole re-bake at once (it
 * is a cold bake's work anyway); otherwise the re-bake restarts at slice 0
 * on the next call that keeps this anchor. */
static gi_result scroll_and_update(struct gi_cascade *c, const gi_level *old, gi_move_info *mi, double t[4],
                                   gi_error_info *err) {
  uint32_t *fresh[GI_MAX_LEVELS] = {0}, nfresh[GI_MAX_LEVELS] = {0}, nnew[GI_MAX_LEVELS] = {0};
  cell_box boxes[GI_MAX_LEVELS][MAX_BOXES];
  int nboxes[GI_MAX_LEVELS] = {0};
  size_t vox = (size_t)c->R * c->R * c->R;
  gi_result rc = GI_OK;
  for (int d = 0; d < c->n && rc == GI_OK; d++)
    if (!(fresh[d] = gi__malloc(vox * sizeof *fresh[d])))
      rc = gi__fail(err, GI_ERR_NOMEM, "move: out of memory for the new voxels' list");
  gi_quality q = c->report.quality;
  int tail = c->tail, rebuilt = 0;
  if (rc == GI_OK) rc = scroll_levels(c, old, fresh, nfresh, nnew, boxes, nboxes, mi, err);
  /* The levels' entries may have grown: the re-bake's side arrays with them. */
  for (int d = 0; d < c->n && rc == GI_OK; d++)
    if (move_state_reserve(c->move_state, d, c->lv[d].cap) != GI_OK)
      rc = gi__fail(err, GI_ERR_NOMEM, "move: out of memory for the re-bake's light of level %d", d);
  t[1] = gi__now_ms();
  if (rc == GI_OK) rc = replan(c, &q, &tail, &mi->relit, err);
  c->tail = tail;
  float scale = c->rad_scale;
  if (rc == GI_OK) rc = inject_fresh(c, &q, mi->relit, fresh, nnew, err);
  t[2] = gi__now_ms();
  for (int d = 0; d < c->n; d++) rebuilt |= mi->rebuilt[d];
  if (rc == GI_OK && refilter(c, q.threads, mi->relit || rebuilt || c->rad_scale != scale, boxes, nboxes, 0))
    rc = gi__cancel_fail(c->cancel, err, "move filter");
  if (rc == GI_OK) gi__cascade_mark_busy(c);
  t[3] = gi__now_ms();
  start_cycle(c);
  if (rc == GI_OK && (mi->relit || rebuilt)) {
    while (rc == GI_OK && !c->move_state->closed) rc = rebake_slice(c, &q, tail, mi, err);
  } else if (rc == GI_OK && c->report.effects[GI_FX_BOUNCE].ran) {
    rc = gather_fresh(c, q.threads, fresh, nfresh, nnew, err);
    scale = c->rad_scale;
    if (rc == GI_OK) gi__shade_all(c);
    if (rc == GI_OK && refilter(c, q.threads, c->rad_scale != scale, boxes, nboxes, NEIGHBOUR_CELLS))
      rc = gi__cancel_fail(c->cancel, err, "move filter");
    if (rc == GI_OK) c->report.bounces_run = 1;
  }
  for (int d = 0; d < c->n; d++) gi__free(fresh[d]);
  return rc;
}

gi_result gi_cascade_move(gi_cascade *c, const double at[3], gi_bake_report *report, gi_move_info *info,
                          gi_error_info *err) {
  return gi_cascade_move_ex(c, at, NULL, report, info, err);
}

static gi_result move_body(gi_cascade *c, const double at[3], gi_bake_report *report, gi_move_info *info,
                           gi_error_info *err);

/* A move after one that failed or was cancelled part way. That cascade's
 * placement is the stopped move's, some levels scrolled and others not,
 * its plan, light and refresh cycle left part way: nothing in it can be
 * reused, so it is baked afresh at `at` with its bake's own request (a
 * cold bake's work, as a move by every level's extent) and takes the new
 * cascade's insides. Its levels are freed first, so the re-bake does not
 * hold two cascades. A failed or cancelled re-bake leaves it partial. */
static gi_result rebake_torn(gi_cascade *c, const double at[3], gi_bake_report *report, gi_move_info *info,
                             gi_error_info *err) {
  gi_result rc = check_viewpoint(c, at, err);
  if (rc != GI_OK) return rc;
  uint64_t moves = ++c->moves;
  c->torn = GI_TORN_MOVING;
  gi__cascade_free_levels(c);
  gi__move_state_free(c->move_state);
  c->move_state = NULL;
  gi_cascade *f = NULL;
  rc = gi__cascade_bake_at(c->scene, at, c->req_default ? NULL : &c->req_q, c->cancel, NULL, 0, &f, NULL, err);
  if (rc != GI_OK) {
    c->torn = GI_TORN_LEFT;
    c->report.cascade_bytes = gi__cascade_held_bytes(c); /* its levels are gone */
    return rc;
  }
  struct gi_cascade left = *c;
  *c = *f;
  *f = left; /* the partial cascade's insides: no levels, no move state */
  gi__cascade_discard(f);
  c->moves = moves;
  /* What moves need, as a session's prepare made it; without memory the next move makes it. */
  (void)move_state(c, NULL);
  gi_move_info mi = {.move = moves, .cycle_closed = 1, .slice = (int)refresh_period(c)};
  for (int d = 0; d < c->n; d++) mi.rebuilt[d] = mi.refreshed[d] = 1;
  c->report.cascade_bytes = gi__cascade_held_bytes(c);
  if (report) *report = c->report;
  if (info) *info = mi;
  return GI_OK;
}

gi_result gi_cascade_move_ex(gi_cascade *c, const double at[3], const gi_cancel *cancel, gi_bake_report *report,
                             gi_move_info *info, gi_error_info *err) {
  if (!c) return gi__fail(err, GI_ERR_INVALID_ARG, "move: no cascade");
  /* Torn by a move under way (another thread's): refused. Torn by one that stopped: re-baked. */
  if (c->torn == GI_TORN_MOVING) return gi__cascade_whole(c, "move", err);
  /* The stages look at c->cancel, as they do during a bake. */
  c->cancel = cancel;
  gi_result rc = c->torn ? rebake_torn(c, at, report, info, err) : move_body(c, at, report, info, err);
  if (rc != GI_OK && c->torn) c->torn = GI_TORN_LEFT;
  c->cancel = NULL;
  return rc;
}

static gi_result move_body(gi_cascade *c, const double at[3], gi_bake_report *report, gi_move_info *info,
                           gi_error_info *err) {
  gi_result rc = check_viewpoint(c, at, err);
  if (rc != GI_OK || (rc = move_state(c, err)) != GI_OK) return rc;
  gi_move_info mi = {.move = ++c->moves};
  reset_counters(&c->report);
  gi_level old[GI_MAX_LEVELS];
  memcpy(old, c->lv, sizeof old);
  c->torn = GI_TORN_MOVING; /* until the move is whole */
  for (int a = 0; a < 3; a++) {
    c->at_world[a] = at[a];
    c->at[a] = (float)(at[a] - c->scene->origin[a]);
  }
  gi__cascade_place(c);
  /* Placement depends on the anchor alone: an unchanged one scrolled nothing. */
  int scrolled = 0;
  for (int d = 0; d < c->n; d++) scrolled |= memcmp(old[d].cell0, c->lv[d].cell0, sizeof old[d].cell0) != 0;
  double t[5];
  t[0] = t[1] = t[2] = t[3] = gi__now_ms();
  if (scrolled) rc = scroll_and_update(c, old, &mi, t, err);
  else {
    c->move_state->calls++;
    rc = rebake_slice(c, &c->report.quality, c->tail, &mi, err);
  }
  if (rc != GI_OK) return rc;
  t[4] = gi__now_ms();
  c->report.ms.voxelize = t[1] - t[0];
  c->report.ms.inject = t[2] - t[1];
  c->report.ms.filter = t[3] - t[2];
  c->report.ms.bounce = t[4] - t[3];
  if (scrolled) gi__cascade_count_occupied(c);
  /* A move grows the levels' arrays and keeps its own state: the report
   * said the first bake's bytes for ever (1.39 MB against 3.22 MB held). */
  c->report.cascade_bytes = gi__cascade_held_bytes(c);
  c->torn = 0;
  if (report) *report = c->report;
  if (info) *info = mi;
  return GI_OK;
}
