/* cascade.c: placing and allocating the cascaded voxel texture.
 *
 * Placement snaps each level's window to twice its voxel size around the
 * viewpoint, so a viewpoint moving by less than a voxel leaves every grid
 * where it was, and level d's window starts on a cell border of level d+1. */
#include <stdlib.h>
#include <string.h>
#include "base/internal.h"
#include "cascade/cascade_internal.h"

/* Every dense array of every level lies in one zeroed block
 * (gi__big_calloc: huge pages, so first touches cost few faults), each
 * array starting on a cache line. The entries (geo, side, direct) are
 * each level's own allocations, sized to the voxels holding geometry. */
#define GI_ARRAY_ALIGN 64

/* Bytes cleared between two checks of the cancel token (~5 ms of first touches here). */
#define GI_CLEAR_SLICE ((size_t)1 << 20)

static size_t align_up(size_t n) { return (n + GI_ARRAY_ALIGN - 1) & ~(size_t)(GI_ARRAY_ALIGN - 1); }

/* Bytes of one level's arrays in the block. */
static size_t level_block_bytes(size_t vox, size_t blocks) {
  return align_up(vox * sizeof(gi_vrad)) + 2 * align_up(vox * sizeof(uint32_t)) + align_up(vox) + align_up(blocks);
}

gi_result gi__cascade_alloc(struct gi_cascade *c, gi_error_info *err) {
  size_t vox = (size_t)c->R * c->R * c->R, nb = (size_t)gi__busy4_side(c->R);
  c->rad_scale = 1.0f;
  if (gi_cancel_check(c->cancel) != GI_CANCEL_NONE) return gi__cancel_fail(c->cancel, err, "allocate");
  c->block_bytes = (size_t)c->n * level_block_bytes(vox, nb * nb * nb);
  int zeroed;
  char *b = c->block = gi__big_malloc(c->block_bytes, &zeroed);
  if (!b) return gi__fail(err, GI_ERR_NOMEM, "cascade: cannot allocate %d levels of %d^3 voxels", c->n, c->R);
  /* Heap memory (small blocks) is cleared in slices a fired token stops. */
  for (size_t at = 0; !zeroed && at < c->block_bytes; at += GI_CLEAR_SLICE) {
    if (gi_cancel_check(c->cancel) != GI_CANCEL_NONE) {
      gi__cascade_free_levels(c);
      return gi__cancel_fail(c->cancel, err, "allocate");
    }
    size_t n = c->block_bytes - at < GI_CLEAR_SLICE ? c->block_bytes - at : GI_CLEAR_SLICE;
    memset(b + at, 0, n);
  }
  for (int d = 0; d < c->n; d++) {
    gi_level *L = &c->lv[d];
    L->rad = (gi_vrad *)b, b += align_up(vox * sizeof *L->rad);
    L->vix = (uint32_t *)b, b += align_up(vox * sizeof *L->vix);
    L->occ = (uint32_t *)b, b += align_up(vox * sizeof *L->occ);
    L->busy = (uint8_t *)b, b += align_up(vox);
    L->busy4 = (uint8_t *)b, b += align_up(nb * nb * nb);
  }
  return GI_OK;
}

void gi__cascade_free_levels(struct gi_cascade *c) {
  gi__big_free(c->block, c->block_bytes, 1);
  c->block = NULL;
  c->block_bytes = 0;
  for (int d = 0; d < GI_MAX_LEVELS; d++) {
    gi_level *L = &c->lv[d];
    gi__free(L->geo), gi__free(L->side), gi__free(L->direct), gi__free(L->shift), gi__free(L->freed);
    L->geo = NULL, L->rad = NULL, L->side = NULL, L->direct = NULL, L->occ = NULL, L->busy = NULL, L->busy4 = NULL;
    L->shift = NULL;
    L->vix = NULL, L->freed = NULL;
    L->cap = L->used = L->num_freed = 0;
  }
}

void gi__cascade_discard(struct gi_cascade *c) {
  gi__cascade_free_levels(c);
  gi_scene_release(c->scene);
  gi__free(c);
}

/* Growth of a level's entries beyond what was asked: a move adds a few
 * hundred voxels at a time. */
#define GI_ENTRY_SLACK 256

static int grow(void **p, size_t n, size_t size) {
  void *q = gi__realloc(*p, n * size);
  if (!q) return 0;
  *p = q;
  return 1;
}

gi_result gi__level_reserve(struct gi_cascade *c, int d, uint32_t entries, int slack, gi_error_info *err) {
  gi_level *L = &c->lv[d];
  if (entries <= L->cap) return GI_OK;
  uint64_t most = (uint64_t)c->R * c->R * c->R + 1;
  uint64_t want = slack ? (uint64_t)entries + entries / 4 + GI_ENTRY_SLACK : entries;
  if (want > most) want = most;
  if (entries > want) return gi__fail(err, GI_ERR_INVALID_ARG, "cascade: %u entries asked of a level of %llu voxels",
                                      entries, (unsigned long long)most - 1);
  uint32_t n = (uint32_t)want, old = L->cap;
  if (gi_cancel_check(c->cancel) != GI_CANCEL_NONE) return gi__cancel_fail(c->cancel, err, "allocate");
  if (!grow((void **)&L->geo, n, sizeof *L->geo) || !grow((void **)&L->side, n, sizeof *L->side) ||
      !grow((void **)&L->direct, n, sizeof *L->direct) || !grow((void **)&L->freed, n, sizeof *L->freed) ||
      (L->shift && !grow((void **)&L->shift, n, sizeof *L->shift)))
    return gi__fail(err, GI_ERR_NOMEM, "cascade: cannot grow level %d to %u voxels holding geometry", d, n);
  L->cap = n;
  if (old == 0) {
    /* Entry 0: what an empty slot reads. */
    memset(&L->geo[0], 0, sizeof L->geo[0]);
    memset(L->side[0], 0, sizeof L->side[0]);
    memset(L->direct[0], 0, sizeof L->direct[0]);
    L->used = 1;
  }
  return GI_OK;
}

uint32_t gi__level_free_entries(const gi_level *L) { return L->cap - L->used + L->num_freed; }

uint32_t gi__level_claim(gi_level *L, uint32_t slot) {
  uint32_t e = L->num_freed > 0 ? L->freed[--L->num_freed] : L->used++;
  L->vix[slot] = e;
  return e;
}

void gi__level_clear(gi_level *L, uint32_t e) {
  memset(&L->geo[e], 0, sizeof L->geo[e]);
  memset(L->side[e], 0, sizeof L->side[e]);
  memset(L->direct[e], 0, sizeof L->direct[e]);
  if (L->shift) L->shift[e].v[0][0] = NAN; /* found at its first gather */
}

void gi__level_take(gi_level *L, uint32_t slot) { gi__level_clear(L, gi__level_claim(L, slot)); }

void gi__level_release(gi_level *L, uint32_t slot) {
  uint32_t e = L->vix[slot];
  if (e == 0) return;
  L->freed[L->num_freed++] = e;
  L->vix[slot] = 0;
}

size_t gi__entries_bytes(const struct gi_cascade *c) {
  size_t b = 0;
  for (int d = 0; d < c->n; d++) b += (size_t)c->lv[d].cap * GI_ENTRY_BYTES;
  return b;
}

/* The value in [lo, hi] nearest v (lo <= hi). */
static int64_t clamp_i64(int64_t v, int64_t lo, int64_t hi) {
  return v < lo ? lo : (v > hi ? hi : v);
}

/* Cells kept free between a held scene and its level's faces: a cone
 * samples a level only one voxel inside its window (trace/march.c), and
 * the trilinear footprint reaches one cell further. */
#define HOLD_MARGIN 2

/* Even cells: the nearest at or above x, at or below x. */
static int64_t even_up(int64_t x) { return gi__floordiv(x + 1, 2) * 2; }
static int64_t even_down(int64_t x) { return gi__floordiv(x, 2) * 2; }

/* A level above the finest covers as much of the scene as it can while
 * holding the finer level: one wide enough holds the whole scene along the
 * axis, a narrower one stays inside it. Centred on a viewer near one side
 * of a compact scene, the coarsest level left the other side out (the
 * Cornell box from z = 500: its back wall) and moved with the viewer, so a
 * walk re-voxelized and re-lit the far walls; the finer levels spent half
 * their cells outside the scene. blo/bhi: the scene's local bulk box. */
static int64_t cover_scene(const struct gi_cascade *c, int d, int a, int64_t cell0, const double blo[3],
                           const double bhi[3]) {
  int R = c->R;
  double s = c->lv[d].s, far = 0x1p52; /* viewpoints lie within 2^52 cells of the origin (gi__viewpoint_range) */
  if (d == 0 || !(blo[a] <= bhi[a])) return cell0;
  int64_t first = (int64_t)fmax(floor(blo[a] / s), -far), last = (int64_t)fmin(floor(bhi[a] / s), far);
  /* Holding the scene with its margins: cell0 in [lo, hi]; when that is
   * empty the level is narrower, and cell0 in [hi, lo] keeps it inside. */
  int64_t lo = last + HOLD_MARGIN + 1 - R, hi = first - HOLD_MARGIN, want_lo, want_hi;
  if (lo <= hi) want_lo = even_up(lo), want_hi = even_down(hi);
  else want_lo = even_up(hi), want_hi = even_down(lo);
  /* Within an even cell of fitting: the scene in the middle. */
  if (want_lo > want_hi) want_lo = want_hi = even_down(gi__floordiv(first + last + 1 - R, 2));
  /* cell0 of the finer level is even, so f0 is exact; the finer window is [f0, f0 + R/2). */
  int64_t f0 = c->lv[d - 1].cell0[a] / 2, nlo = even_up(f0 - R / 2), nhi = even_down(f0);
  return nlo <= nhi ? clamp_i64(clamp_i64(cell0, want_lo, want_hi), nlo, nhi) : cell0;
}

gi_result gi__cascade_whole(const struct gi_cascade *c, const char *what, gi_error_info *err) {
  if (!c->torn) return GI_OK;
  return gi__fail(err, GI_ERR_INVALID_ARG,
                  "%s: the cascade is partial: a move failed or was cancelled part way (move it again, which "
                  "bakes it afresh at the new viewpoint, or free it), "
                  "or a move is running in another thread (no call may read a cascade while it moves: gi_move.h)",
                  what);
}

void gi__cascade_place(struct gi_cascade *c) {
  int R = c->R;
  double at[3] = {(double)c->at[0], (double)c->at[1], (double)c->at[2]};
  /* The scene's bulk box, local (a cascade built without a scene has none: empty). */
  double blo[3] = {1, 1, 1}, bhi[3] = {0, 0, 0};
  if (c->scene) gi_scene_bulk_bounds(c->scene, blo, bhi);
  for (int a = 0; a < 3 && c->scene; a++) blo[a] -= c->scene->origin[a], bhi[a] -= c->scene->origin[a];
  for (int d = 0; d < c->n; d++) {
    gi_level *L = &c->lv[d];
    L->s = c->s0 * (double)(1ull << d);
    for (int a = 0; a < 3; a++) {
      int64_t centre = (int64_t)floor(at[a] / L->s);
      L->cell0[a] = cover_scene(c, d, a, gi__floordiv(centre - R / 2, 2) * 2, blo, bhi);
      L->slot0[a] = gi__wrap(L->cell0[a], R);
      L->lo[a] = (float)(L->cell0[a] * L->s);
      L->hi[a] = (float)((L->cell0[a] + R) * L->s);
    }
    L->has_inner = 0;
    if (d > 0) {
      const gi_level *F = &c->lv[d - 1];
      L->has_inner = 1;
      for (int a = 0; a < 3; a++) {
        /* cell0 of the finer level is even, so this division is exact. */
        int64_t i0 = F->cell0[a] / 2, i1 = i0 + R / 2;
        if (i0 < L->cell0[a]) i0 = L->cell0[a];
        if (i1 > L->cell0[a] + R) i1 = L->cell0[a] + R;
        L->inner0[a] = i0;
        L->inner1[a] = i1;
      }
    }
  }
}

int gi__level_contains(const gi_level *L, const float p[3], float border) {
  float b = border * (float)L->s;
  for (int a = 0; a < 3; a++)
    if (!(p[a] >= L->lo[a] + b && p[a] <= L->hi[a] - b)) return 0;
  return 1;
}
