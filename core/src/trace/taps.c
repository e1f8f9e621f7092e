/* taps.c: the growth of a march's tap record (trace.h: gi_tap_rec), and
 * the packing of kept tapes (gi_tape_unit). Its own file: both builds of
 * the march call it, and march.c calls them. */
#include <string.h>
#include "base/internal.h"
#include "trace/trace.h"

int gi__tap_grow(gi_tap_rec *r) {
  if (r->full) return 0;
  size_t cap = r->cap ? 2 * r->cap : 1024;
  if (cap > r->max) cap = r->max;
  gi_tap *t = cap > r->cap ? gi__realloc(r->t, cap * sizeof *t) : NULL;
  if (!t) {
    /* Past max is the caller's budget; a failed realloc is out of memory. */
    r->oom = cap > r->cap;
    r->full = 1;
    return 0;
  }
  r->t = t, r->cap = cap;
  return 1;
}

void gi__tape_plan(const gi_tap *t, size_t n, int nj, gi_tape_plan *pl) {
  for (int j = 0; j < nj; j++) pl->start[j] = pl->taps[j] = 0, pl->k0[j] = pl->k1[j] = -1;
  for (size_t i = 0; i < n; i++) {
    int j = t[i].job;
    pl->taps[j]++;
    pl->start[j] += 1 + ((t[i].flags & GI_TAP_BLEND) != 0);
    if (t[i].flags & GI_TAP_KALT) pl->k1[j] = (int32_t)i;
    else pl->k0[j] = (int32_t)i;
  }
  /* Each cone's units (a head, its second k, its taps) into offsets. */
  uint32_t at = 0;
  for (int j = 0; j < nj; j++) {
    uint32_t u = pl->taps[j] ? 1 + (pl->k1[j] >= 0) + pl->start[j] : 0;
    pl->start[j] = at;
    at += u;
  }
  pl->start[nj] = at;
}

void gi__tape_pack(const gi_tap *t, size_t n, int nj, const gi_tape_plan *pl, const int16_t *id,
                   const gi_cone_out *co, gi_tape_unit *u) {
  uint32_t pos[GI_MARCH_BATCH_JOBS];
  for (int j = 0; j < nj; j++) {
    pos[j] = pl->start[j];
    if (!pl->taps[j]) continue;
    gi_tape_unit *h = &u[pos[j]++];
    int alt = pl->k1[j] >= 0;
    h->head.job = (uint16_t)id[j];
    h->head.n = (uint16_t)(pl->taps[j] | (alt ? GI_TAPE_ALT : 0));
    h->head.alpha = co[j].alpha;
    /* A cone whose every step read across the normal has no first k: any will do. */
    memcpy(h->head.k, t[pl->k0[j] >= 0 ? pl->k0[j] : pl->k1[j]].k, sizeof h->head.k);
    if (alt) {
      memset(&u[pos[j]], 0, sizeof u[pos[j]]);
      memcpy(u[pos[j]++].f, t[pl->k1[j]].k, 3 * sizeof(float));
    }
  }
  /* A tap's p and kk, then d and flags (and its job, unused), as two moves. */
  for (size_t i = 0; i < n; i++) {
    int j = t[i].job;
    gi_tape_unit *x = &u[pos[j]++];
    memcpy(x, &t[i], 16);
    memcpy(&x->tap.d, &t[i].d, 4);
    if (t[i].flags & GI_TAP_BLEND) {
      memset(&u[pos[j]], 0, sizeof u[pos[j]]);
      u[pos[j]++].f[0] = t[i].frac;
    }
  }
}
