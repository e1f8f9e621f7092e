/* bounce.c: the voxel-to-voxel bounces.
 *
 * Each occupied voxel gathers indirect irradiance on each side of each of
 * its orientation groups (cascade_internal.h) with the diffuse cone set
 * (weights sum to pi, see trace/cones.c) by the gather's surface rule
 * (trace/gather.c: one voxel off the surface); all voxels
 * gather from the previous bounce's texture (Jacobi). Transport is linear,
 * so a bounce gathers only the light the previous one added (the direct
 * light for the first): between bounces the texture holds that increment,
 * shaded and filtered, and each voxel's side light sums the increments;
 * after the last bounce the texture is reshaded from the sum. From the
 * third bounce on the increment is small and smooth, and the gather takes
 * the wide set (gi__bounce_wide); so do, from the first, the coarse
 * levels the viewpoint barely sees (c->wide_level, plan.c). On a plane,
 * three voxels in four wait for their gathered neighbours and take their
 * mean where those agree,
 * and every other voxel along an edge (between.c: the Cornell box's bake
 * marches 50% fewer cones). A cone's march depends on the opacity alone,
 * which no bounce changes, so a set's first bounce records each voxel's
 * tape (its lit steps and their weights, trace.h: gi_tap) and the set's
 * later bounces replay it, reading those steps' texels again without
 * marching: the same bits (Munich: 14.7 M samples -> 9.5 M marched and
 * 2.1 M steps replayed; docs/accuracy-notes.md). A closed furnace of albedo a
 * and emission Le therefore reaches Le (a + ... + a^(k+1)) reflected
 * radiance after k bounces. When the effect plan capped an automatic
 * bounce count short of what the albedo asks for, the last bounce also
 * adds the geometric tail of the orders left out (ratio measured from the
 * last two bounces); an explicit bounce count keeps the exact k-bounce sum
 * above. */
#include <stdlib.h>
#include <string.h>
#include "base/internal.h"
#include "light/light.h"
#include "trace/trace.h"

/* A voxel's tape: the taps (trace.h) of its cones on its set's first
 * bounce, cone by cone in the set's order (job: the cone's bit), with
 * each cone's alpha, packed (gi_tape_unit); the set's later bounces
 * replay it instead of marching (gi__replay_tape: the lit steps' texels
 * only, the march's arithmetic, its bits). The units live in their
 * worker's tape_arena. */
typedef struct {
  gi_tape_unit *u;
  uint32_t n, taps;       /* units, and the taps they hold */
  uint8_t rec;            /* recorded (0: march) */
  float hs[GI_VOX_FACES]; /* each side's hit share (side_hits), for the tail's H */
} gi_tape;

/* One worker's tape memory: blocks cut from chunks of TAPE_CHUNK bytes
 * or more, mapped on huge pages (gi__big_malloc). A set's tapes go all at
 * once and the next set's reuse the chunks (arena_reset); the bake frees
 * them at its end. A block per batch from the heap cost Munich's
 * recording bounce a third of its time on one thread: fresh 4 KB pages
 * faulted in one by one (base/internal.h), and the frees gave them back. */
#define TAPE_CHUNK ((size_t)4 << 20)
typedef struct tape_chunk {
  struct tape_chunk *next;
  size_t bytes;
} tape_chunk;
typedef struct {
  tape_chunk *head, *cur; /* the chunks in the order taken, and the one being cut */
  char *at;               /* cur's free space */
  size_t left;
} tape_arena;

#define CHUNK_HEAD ((sizeof(tape_chunk) + 63) & ~(size_t)63)

static void arena_use(tape_arena *a, tape_chunk *ch) {
  a->cur = ch, a->at = (char *)ch + CHUNK_HEAD, a->left = ch->bytes - CHUNK_HEAD;
}

/* Room for n units from a, or NULL when memory ran out. */
static gi_tape_unit *arena_take(tape_arena *a, size_t n) {
  size_t bytes = n * sizeof(gi_tape_unit);
  while (bytes > a->left) {
    if (a->cur && a->cur->next) { /* a chunk the last set used */
      arena_use(a, a->cur->next);
      continue;
    }
    size_t want = CHUNK_HEAD + bytes > TAPE_CHUNK ? CHUNK_HEAD + bytes : TAPE_CHUNK;
    int zeroed;
    tape_chunk *ch = gi__big_malloc(want, &zeroed);
    if (!ch) return NULL;
    ch->next = NULL, ch->bytes = want;
    if (a->cur) a->cur->next = ch;
    else a->head = ch;
    arena_use(a, ch);
  }
  gi_tape_unit *u = (gi_tape_unit *)(void *)a->at;
  a->at += bytes, a->left -= bytes;
  return u;
}

/* Every block of a is free again; its chunks stay for the next set. */
static void arena_reset(tape_arena *a) {
  if (a->head) arena_use(a, a->head);
}

static void arena_free(tape_arena *a) {
  while (a->head) {
    tape_chunk *next = a->head->next;
    gi__big_free(a->head, a->head->bytes, 1);
    a->head = next;
  }
  a->cur = NULL, a->at = NULL, a->left = 0;
}

/* The tapes' memory, bounded per bake: past it voxels march again. arena
 * and rec: per worker id (gi__parallel_for), the tapes' memory and the
 * march's record, kept across a bounce's chunks (regrowing a record per
 * chunk of 16 voxels faulted its pages in again each time). A level's
 * tapes are of class 1 when it takes the wide set from the first bounce
 * (they serve every bounce), else of class 0 (freed when the level turns
 * to the wide set): each class has its own arenas. */
typedef struct {
  atomic_size_t bytes;  /* both classes' */
  atomic_size_t cls[2]; /* each class's */
  size_t max;
  tape_arena arena[2][GI_MAX_WORKERS];
  gi_tap_rec rec[GI_MAX_WORKERS];
} tape_budget;

/* One bounce over every level's own voxels as one parallel loop (level d's
 * are [start[d], start[d + 1])): a loop per level waited for its slowest
 * chunk six times a bounce. */
typedef struct {
  struct gi_cascade *c;
  size_t start[GI_MAX_LEVELS + 1];
  gi_faces3 **E;    /* per level, per occupied voxel */
  gi_hits *hit[GI_MAX_LEVELS]; /* per level, per occupied voxel: the cones of its set that met opacity on the set's
                                  first bounce */
  gi_between **plan; /* per level, per occupied voxel: filled from its neighbours instead (between.c) */
  uint8_t wide[GI_MAX_LEVELS];   /* per level: the wide set (gi__bounce_wide) */
  uint8_t first[GI_MAX_LEVELS];  /* per level: its set's first bounce, which fills hit */
  uint8_t record[GI_MAX_LEVELS]; /* per level: this bounce fills tape (the set's first, with a later bounce of it) */
  uint8_t cls[GI_MAX_LEVELS];    /* per level: its tapes' class (tape_budget) */
  gi_shift6 **shift; /* per level, per occupied voxel: each side's apex shift (gi__away_from_beside) */
  int shift_known;  /* shift holds it (after the first bounce) */
  gi_hfaces **H;    /* per level, per occupied voxel: each face's share of its cones that met a surface, or NULL */
  gi_tape **tape;   /* per level (NULL: none kept), per occupied voxel: its set's tapes */
  tape_budget *budget;
  atomic_ullong samples, cones, taps;
  atomic_ullong replay_ns; /* the replays' time, summed over workers */
  atomic_int oom;          /* a tape could not be allocated */
} bounce_ctx;

/* A side of a voxel holding several orientation groups starts half a
 * voxel off each of the voxel's other surfaces too, on the side of each where
 * its own surface lies: a floor meeting a wall at the voxel's border
 * would otherwise start its cones against the wall, whose trilinear
 * footprint then shows the far side of the wall (a closed box's sky-lit
 * outside, read from inside). */
#define AWAY_VOXELS 0.5f
static void away_from_groups(const struct gi_cascade *c, int d, const gi_vgeo *g, int sd, gi_gather_start *st) {
  float s = AWAY_VOXELS * (float)c->lv[d].s;
  for (int o = 0; o < g->groups; o++) {
    if (o == sd / 2) continue;
    const float *no = g->u.fin.orient[o];
    float rel[3];
    gi__side_centroid(g, sd, rel);
    for (int k = 0; k < 3; k++) rel[k] -= g->u.fin.gcen[o][k];
    float side = gi__dot(no, rel);
    if (side == 0) continue;
    float sg = side > 0 ? s : -s;
    for (int k = 0; k < 3; k++) st->o[k] += sg * no[k];
  }
}

/* Cones of several voxels' gathers marched as one batch: the SIMD march
 * drains its lanes at a batch's end, and one voxel's 32-96 cones left a
 * fifth of the lane-steps idle (79% busy on the city). */
#define BATCH_VOXELS 32
typedef struct {
  gi_cone_job jobs[GI_MARCH_BATCH_JOBS];
  gi_cone_out co[GI_MARCH_BATCH_JOBS];
  int16_t which[GI_MARCH_BATCH_JOBS]; /* bit side * set size + cone */
  int nj, nv;
  float step, ao_lambda; /* the gather's step rule: the quality's, every voxel's alike */
  uint8_t *next_H;       /* the next voxel batch_add takes: where its faces' hit shares go, or NULL */
  gi_tape *next_tape;    /* the same for its tape, when this batch records */
  int wide;              /* the set its voxels gather with */
  gi_tap_rec *rec;       /* the batch's taps while recording (the worker's, reused across batches) */
  tape_arena *arena;     /* where the worker's kept taps go (their class's) */
  int cls;               /* that class */
  tape_budget *budget;   /* NULL: no recording */
  int oom;               /* a tape could not be allocated */
  struct {
    int d, first, count; /* the voxel's level and its jobs [first, first + count) */
    uint32_t slot;
    float *E;            /* its gi_faces3 */
    gi_hits *hit;        /* may be NULL */
    uint8_t *H;          /* its gi_hfaces, may be NULL */
    gi_tape *tape;       /* where its taps go, or NULL */
  } v[BATCH_VOXELS];
} cone_batch;

/* The jobs of every side of every group of a voxel with the diffuse or
 * the wide set, only the cones in `want` (bit side * set size + cone;
 * cones past the mask always run), appended to cb; its E (and *hit, may
 * be NULL) is cleared now and filled by batch_finish. *hit receives the
 * cones that met any opacity. A cone that met none took no light and
 * never will: the texture's opacity stays as voxelized through every
 * bounce (shading rewrites radiance only), so the same steps see the
 * same empty space. E receives each face's side. */
static void batch_add(const struct gi_cascade *c, int d, uint32_t slot, int wide, const gi_hits *want, gi_faces3 E,
                      gi_hits *hit, gi_shift6 *shift, int shift_known, cone_batch *cb) {
  const gi_vgeo *g = gi__geo(&c->lv[d], slot);
  memset(E, 0, sizeof(gi_faces3));
  if (hit) memset(hit, 0, sizeof *hit);
  /* A side that reflects nothing (no albedo, no glossy lobe) needs no light. */
  if (g->groups == 0 ||
      (g->albedo[0] + g->gloss[0] <= 0 && g->albedo[1] + g->gloss[1] <= 0 && g->albedo[2] + g->gloss[2] <= 0))
    return;
  int nc = wide ? c->num_wide_cones : c->num_cones, ns = 2 * g->groups, first = cb->nj;
  gi_cone_job all[GI_MAX_CONES];
  gi_gather_start st = {0};
  for (int sd = 0; sd < ns; sd++) {
    float n[3];
    float sg = (sd & 1) ? -1.f : 1.f;
    for (int k = 0; k < 3; k++) n[k] = sg * g->u.fin.orient[sd / 2][k];
    /* A voxel is a surface at its own level's resolution (level d is
     * given, so the start always exists). */
    float pc[3];
    gi__side_centroid(g, sd, pc);
    gi__gather_start(c, pc, n, GI_GATHER_SURFACE, d, &st);
    if (ns > 2) away_from_groups(c, d, g, sd, &st);
    /* Off the other surfaces beside it too (trace.h). The shift depends on
     * the geometry alone: a bake's first bounce finds it, the later ones
     * reuse it, and a moving cascade keeps it per entry (gi_shift6). */
    float sh[3];
    if (shift && shift_known) memcpy(sh, shift->v[sd], sizeof sh);
    else gi__away_from_beside(c, d, n, st.o, sh);
    if (shift && !shift_known) memcpy(shift->v[sd], sh, sizeof sh);
    for (int k = 0; k < 3; k++) st.o[k] += sh[k];
    gi__hemisphere_jobs(c, wide, &st, n, all);
    for (int ci = 0; ci < nc; ci++) {
      int bit = sd * nc + ci;
      if (bit >= GI_HIT_BITS || !want || (want->w[bit / 64] >> (bit % 64) & 1))
        cb->which[cb->nj] = (int16_t)bit, cb->jobs[cb->nj++] = all[ci];
    }
  }
  cb->step = st.step, cb->ao_lambda = st.ao_lambda;
  cb->v[cb->nv].d = d, cb->v[cb->nv].slot = slot, cb->v[cb->nv].first = first, cb->v[cb->nv].count = cb->nj - first;
  cb->v[cb->nv].E = &E[0][0], cb->v[cb->nv].hit = hit, cb->v[cb->nv].H = cb->next_H;
  cb->v[cb->nv].tape = cb->next_tape;
  cb->nv++;
}

/* An empty batch for worker w of the wide set or not, recording into
 * budget (the worker's record and its tape arena of class cls) or not
 * (NULL). */
static void batch_start(cone_batch *cb, int wide, tape_budget *budget, int cls, int w) {
  cb->nj = cb->nv = 0;
  cb->wide = wide;
  cb->next_H = NULL;
  cb->next_tape = NULL;
  cb->budget = budget;
  cb->rec = budget ? &budget->rec[w] : NULL;
  cb->arena = budget ? &budget->arena[cls][w] : NULL;
  cb->cls = cls;
  cb->oom = 0;
}

/* Whether cb has room for one more voxel's cones. */
static int batch_room(const struct gi_cascade *c, int wide, const cone_batch *cb) {
  int nc = wide ? c->num_wide_cones : c->num_cones;
  return cb->nv < BATCH_VOXELS && cb->nj + GI_VOX_FACES * nc <= GI_MARCH_BATCH_JOBS;
}

/* Voxel v of cb's share of each side's cones that met a surface: the
 * cosine-weighted opacity its cones gathered over the set's whole weight
 * (pi). Cones the first-hit mask skipped met none and add 0. */
static void side_hits(const struct gi_cascade *c, int wide, const cone_batch *cb, int v, float hs[GI_VOX_FACES]) {
  int nc = wide ? c->num_wide_cones : c->num_cones;
  const float *weight = wide ? c->wide_weight : c->cone_weight;
  float all = 0;
  for (int ci = 0; ci < nc; ci++) all += weight[ci];
  for (int f = 0; f < GI_VOX_FACES; f++) hs[f] = 0;
  for (int j = cb->v[v].first; j < cb->v[v].first + cb->v[v].count; j++)
    hs[cb->which[j] / nc] += weight[cb->which[j] % nc] * fminf(fmaxf(cb->co[j].alpha, 0.f), 1.f);
  for (int f = 0; f < GI_VOX_FACES; f++) hs[f] = all > 0 ? fminf(hs[f] / all, 1.f) : 0.f;
}

/* Each face's hit share, for the side it shows (gi__face_side_of on its
 * sides' light Es). */
static void face_hits(const gi_vgeo *g, const float hs[GI_VOX_FACES], const float Es[][3], uint8_t *H) {
  for (int f = 0; f < GI_VOX_FACES; f++) H[f] = (uint8_t)lrintf(hs[gi__face_side_of(g, Es, f)] * GI_HIT_STEPS);
}

/* After cb's march recorded its taps (cb->rec, job order = the march's),
 * gives each voxel with a tape slot its taps, packed (gi__tape_pack): its
 * cones' in job order, each cone's in step order, with the cone's bit and
 * alpha. A batch whose taps did not fit (rec full, the budget spent)
 * records nothing: its voxels march again. Out of memory sets
 * cb->oom: the bake fails as it would anywhere else. */
static void keep_tapes(const struct gi_cascade *c, int wide, cone_batch *cb) {
  gi_tap_rec *r = cb->rec;
  gi_tape_plan pl;
  if (r->oom) cb->oom = 1;
  if (r->full) return;
  gi__tape_plan(r->t, r->n, cb->nj, &pl);
  size_t all = pl.start[cb->nj], bytes = all * sizeof(gi_tape_unit);
  if (atomic_fetch_add(&cb->budget->bytes, bytes) + bytes > cb->budget->max) {
    atomic_fetch_sub(&cb->budget->bytes, bytes);
    return;
  }
  gi_tape_unit *block = NULL;
  if (all > 0) {
    if (!(block = arena_take(cb->arena, all))) {
      atomic_fetch_sub(&cb->budget->bytes, bytes);
      cb->oom = 1;
      return;
    }
    gi__tape_pack(r->t, r->n, cb->nj, &pl, cb->which, cb->co, block);
  }
  atomic_fetch_add(&cb->budget->cls[cb->cls], bytes);
  for (int v = 0; v < cb->nv; v++) {
    gi_tape *tp = cb->v[v].tape;
    if (!tp) continue;
    int j0 = cb->v[v].first, j1 = j0 + cb->v[v].count;
    tp->u = block ? block + pl.start[j0] : NULL;
    tp->n = pl.start[j1] - pl.start[j0];
    tp->taps = 0;
    for (int j = j0; j < j1; j++) tp->taps += pl.taps[j];
    tp->rec = 1;
    side_hits(c, wide, cb, v, tp->hs);
  }
}

/* Marches cb's cones and folds each voxel's into its E (and hit); empties
 * cb. Returns the samples taken. */
static uint64_t batch_finish(const struct gi_cascade *c, int wide, cone_batch *cb, uint64_t *cones) {
  uint64_t samples = 0;
  if (cb->budget) cb->rec->n = 0, cb->rec->full = cb->rec->oom = 0;
  if (cb->nj > 0)
    gi__cone_march_jobs_rec(c, cb->jobs, cb->nj, wide ? c->wide_tan : c->cone_tan, cb->step, cb->ao_lambda, cb->co,
                            cb->budget ? cb->rec : NULL);
  int nc = wide ? c->num_wide_cones : c->num_cones;
  const float *weight = wide ? c->wide_weight : c->cone_weight;
  for (int v = 0; v < cb->nv; v++) {
    const gi_vgeo *g = gi__geo(&c->lv[cb->v[v].d], cb->v[v].slot);
    float Es[GI_VOX_FACES][3] = {{0}};
    gi_hits *hit = cb->v[v].hit;
    /* In the order of the full set, so skipped cones (exact zeros) leave E's bits as they were. */
    for (int j = cb->v[v].first; j < cb->v[v].first + cb->v[v].count; j++) {
      int sd = cb->which[j] / nc;
      float cw = weight[cb->which[j] % nc];
      for (int k = 0; k < 3; k++) Es[sd][k] += cw * cb->co[j].L[k];
      samples += cb->co[j].samples;
      if (hit && cb->co[j].alpha > 0 && cb->which[j] < GI_HIT_BITS)
        hit->w[cb->which[j] / 64] |= 1ull << (cb->which[j] % 64);
    }
    gi__face_light(g, (const float(*)[3])Es, (float(*)[3])cb->v[v].E);
    if (cb->v[v].H) {
      float hs[GI_VOX_FACES];
      side_hits(c, wide, cb, v, hs);
      face_hits(g, hs, (const float(*)[3])Es, cb->v[v].H);
    }
    *cones += (uint64_t)cb->v[v].count;
  }
  if (cb->budget && cb->nv > 0) keep_tapes(c, wide, cb);
  cb->nj = cb->nv = 0;
  return samples;
}

/* gi__gather_voxels, and with hit (the level's first-hit masks, voxel i's
 * at hit[at[i]]; NULL: none) on the set's first bounce (first) each
 * voxel's mask filled, on its later bounces the cones its mask says met
 * nothing skipped: they bring exact zeros, as in bounce_range. */
static uint64_t gather_masked(const struct gi_cascade *c, int d, const uint32_t *slots, size_t n, int wide,
                              const gi_between *plan, gi_faces3 *E, gi_hfaces *H, gi_hits *hit, const uint32_t *at,
                              int first, uint64_t *cones) {
  cone_batch cb;
  batch_start(&cb, wide, NULL, 0, 0);
  uint64_t samples = 0;
  const gi_level *L = &c->lv[d];
  for (size_t i = 0; i < n; i++) {
    if (plan && plan[i].nb[0] >= 0) continue;
    if (!batch_room(c, wide, &cb)) samples += batch_finish(c, wide, &cb, cones);
    cb.next_H = H ? H[i] : NULL;
    gi_shift6 *sh = L->shift ? &L->shift[L->vix[slots[i]]] : NULL;
    gi_hits *hm = hit ? &hit[at[i]] : NULL;
    batch_add(c, d, slots[i], wide, first ? NULL : hm, E[i], first ? hm : NULL, sh, sh && !isnan(sh->v[0][0]), &cb);
  }
  return samples + batch_finish(c, wide, &cb, cones);
}

uint64_t gi__gather_voxels(const struct gi_cascade *c, int d, const uint32_t *slots, size_t n, int wide,
                           const gi_between *plan, gi_faces3 *E, gi_hfaces *H, uint64_t *cones) {
  return gather_masked(c, d, slots, n, wide, plan, E, H, NULL, NULL, 0, cones);
}

/* The voxels between gathered neighbours that gi__between_fill turned
 * down, of one level: their slots, where their E goes, and their gathers. */
typedef struct {
  const struct gi_cascade *c;
  int d, wide, first;
  uint32_t *slots;
  const uint32_t *at; /* their indices in the level's occ list */
  gi_faces3 *E;
  gi_hits *hit;       /* the level's first-hit masks (gather_masked), or NULL */
  atomic_ullong samples, cones;
} redo_ctx;

static void redo_range(void *p, size_t b, size_t e, int worker) {
  (void)worker;
  redo_ctx *r = p;
  uint64_t cones = 0, samples = gather_masked(r->c, r->d, r->slots + b, e - b, r->wide, NULL, r->E + b, NULL, r->hit,
                                              r->at + b, r->first, &cones);
  atomic_fetch_add(&r->samples, samples);
  atomic_fetch_add(&r->cones, cones);
}

/* Whether bounce `it` is the first of level d's set. */
static int set_first(const struct gi_cascade *c, int it, int d) {
  return it == 0 || gi__bounce_wide(c, it, d) != gi__bounce_wide(c, it - 1, d);
}

/* gi__bounce_between with each set's first-hit masks (per set and level,
 * or NULL): the turned-down voxels' masks are filled on their set's first
 * bounce and skip cones on its later ones, as every other voxel's. Their
 * cones that meet nothing are most of their samples (a cone into the open
 * sky crosses every level). */
static gi_result between_masked(struct gi_cascade *c, gi_between *const plan[], gi_faces3 *const E[], int it,
                                int threads, gi_hits *(*hit)[GI_MAX_LEVELS], uint64_t *samples,
                                uint64_t *cones, gi_error_info *err) {
  for (int d = 0; d < c->n; d++) {
    const gi_level *L = &c->lv[d];
    int wide = gi__bounce_wide(c, it, d), first = set_first(c, it, d);
    uint32_t *at = gi__malloc(((size_t)L->num_occ + 1) * sizeof *at), n;
    if (!at) return gi__fail(err, GI_ERR_NOMEM, "bounce: out of memory for level %d's voxels between", d);
    if (!(n = gi__between_fill(c, d, plan[d], E[d], at, threads))) {
      gi__free(at);
      continue;
    }
    redo_ctx r = {.c = c, .d = d, .wide = wide, .first = first, .at = at, .hit = hit ? hit[wide][d] : NULL};
    r.slots = gi__malloc((size_t)n * sizeof *r.slots);
    r.E = gi__malloc((size_t)n * sizeof *r.E);
    if (!r.slots || !r.E) {
      gi__free(at), gi__free(r.slots), gi__free(r.E);
      return gi__fail(err, GI_ERR_NOMEM, "bounce: out of memory for level %d's voxels between", d);
    }
    for (uint32_t j = 0; j < n; j++) r.slots[j] = L->occ[at[j]];
    atomic_init(&r.samples, 0);
    atomic_init(&r.cones, 0);
    int cancelled = gi__parallel_for_cancel(n, 16, threads, redo_range, &r, NULL, c->cancel);
    for (uint32_t j = 0; j < n && !cancelled; j++) memcpy(E[d][at[j]], r.E[j], sizeof r.E[j]);
    *samples += atomic_load(&r.samples);
    *cones += atomic_load(&r.cones);
    gi__free(at), gi__free(r.slots), gi__free(r.E);
    if (cancelled) return gi__cancel_fail(c->cancel, err, "bounce");
  }
  return GI_OK;
}

gi_result gi__bounce_between(struct gi_cascade *c, gi_between *const plan[], gi_faces3 *const E[], int it,
                             int threads, uint64_t *samples, uint64_t *cones, gi_error_info *err) {
  return between_masked(c, plan, E, it, threads, NULL, samples, cones, err);
}

/* The first two bounces gather the direct light and the first bounce's,
 * which carry the sharp detail (shadow edges, the lit patch under a lamp);
 * from the third on the increment has spread through the room. Measured
 * at 3 bounces, 16 cones: bounce instructions -14% (Cornell), -12%
 * (Munich), -13% (city), probe indirect within 1.5% of the 16 cones
 * throughout; 6 wide cones instead of 8 moved Munich's probe 7%. */
#define WIDE_FROM 2

int gi__bounce_wide(const struct gi_cascade *c, int it, int d) {
  return (it >= WIDE_FROM || d >= c->wide_level) && c->num_wide_cones < c->num_cones;
}

/* The set's later bounce for voxel (d, i) from its tape: the light its
 * cones would gather from the texture as it is now, summed as
 * batch_finish sums them (cones with no tap bring exact zeros). */
static void replay_voxel(const bounce_ctx *bc, int d, size_t i, uint32_t slot) {
  const gi_tape *tp = &bc->tape[d][i];
  const gi_vgeo *g = gi__geo(&bc->c->lv[d], slot);
  int nc = bc->wide[d] ? bc->c->num_wide_cones : bc->c->num_cones;
  const float *weight = bc->wide[d] ? bc->c->wide_weight : bc->c->cone_weight;
  float Es[GI_VOX_FACES][3] = {{0}}, L[GI_VOX_FACES * GI_MAX_CONES][3];
  uint16_t job[GI_VOX_FACES * GI_MAX_CONES];
  size_t cones = gi__replay_tape(bc->c, tp->u, tp->n, L, job);
  for (size_t k = 0; k < cones; k++) {
    int sd = job[k] / nc;
    float cw = weight[job[k] % nc];
    for (int ch = 0; ch < 3; ch++) Es[sd][ch] += cw * L[k][ch];
  }
  gi__face_light(g, (const float(*)[3])Es, bc->E[d][i]);
  if (bc->H) face_hits(g, tp->hs, (const float(*)[3])Es, bc->H[d][i]);
}

static void bounce_range(void *p, size_t b, size_t e, int worker) {
  bounce_ctx *bc = p;
  const struct gi_cascade *c = bc->c;
  uint64_t samples = 0, cones = 0, taps = 0;
  /* The replays' time: a clock read where a run of replayed voxels starts
   * and ends (one per voxel cost 1% of the bounce). */
  double run0 = -1, replay_ms = 0;
  int d = 0, key = -1; /* the batch's set, recording and class, as one key */
  cone_batch cb;
  batch_start(&cb, 0, NULL, 0, worker);
  for (size_t q = b; q < e; q++) {
    while (q >= bc->start[d + 1]) d++;
    size_t i = q - bc->start[d];
    uint32_t slot = c->lv[d].occ[i];
    if (bc->plan[d][i].nb[0] >= 0) continue;
    if (bc->tape[d] && !bc->record[d] && bc->tape[d][i].rec) {
      if (run0 < 0) run0 = gi__now_ms();
      replay_voxel(bc, d, i, slot);
      taps += bc->tape[d][i].taps;
      continue;
    }
    if (run0 >= 0) replay_ms += gi__now_ms() - run0, run0 = -1;
    /* A batch marches one set and records into one class, or not at all. */
    int wide = bc->wide[d], k = wide | bc->record[d] << 1 | bc->cls[d] << 2;
    if (k != key) {
      samples += batch_finish(c, cb.wide, &cb, &cones);
      if (cb.oom) atomic_store(&bc->oom, 1);
      batch_start(&cb, wide, bc->record[d] ? bc->budget : NULL, bc->cls[d], worker);
      key = k;
    } else if (!batch_room(c, wide, &cb)) {
      samples += batch_finish(c, wide, &cb, &cones);
    }
    cb.next_H = bc->H ? bc->H[d][i] : NULL;
    cb.next_tape = bc->record[d] ? &bc->tape[d][i] : NULL;
    if (bc->first[d])
      batch_add(c, d, slot, wide, NULL, bc->E[d][i], &bc->hit[d][i], &bc->shift[d][i], bc->shift_known, &cb);
    else
      batch_add(c, d, slot, wide, &bc->hit[d][i], bc->E[d][i], NULL, &bc->shift[d][i], bc->shift_known, &cb);
  }
  if (run0 >= 0) replay_ms += gi__now_ms() - run0;
  samples += batch_finish(c, cb.wide, &cb, &cones);
  if (cb.oom) atomic_store(&bc->oom, 1);
  atomic_fetch_add(&bc->samples, samples);
  atomic_fetch_add(&bc->cones, cones);
  atomic_fetch_add(&bc->taps, taps);
  if (replay_ms > 0) atomic_fetch_add(&bc->replay_ns, (unsigned long long)(replay_ms * 1e6));
}

/* The class of level d's tapes (tape_budget). */
static int tape_class(const struct gi_cascade *c, int d) { return gi__bounce_wide(c, 0, d); }

/* Frees the tapes of every level of class cls (NULL entries skipped) and
 * sets them NULL; the workers' tape memory of that class is free for the
 * next set's (arena_reset). */
static void free_tapes(const struct gi_cascade *c, gi_tape *tape[], tape_budget *budget, int cls) {
  for (int d = 0; d < c->n; d++) {
    if (tape_class(c, d) != cls) continue;
    gi__free(tape[d]);
    tape[d] = NULL;
  }
  for (int w = 0; w < GI_MAX_WORKERS; w++) arena_reset(&budget->arena[cls][w]);
  atomic_fetch_sub(&budget->bytes, atomic_exchange(&budget->cls[cls], 0));
}

/* The tapes' budget per bake: GI_TAPE_MAX_BYTES, or what
 * gi__set_tape_budget set (tests: 0 records none, every bounce marches).
 * Past it a bake marches the voxels it could not record. */
static atomic_size_t tape_budget_set = GI_TAPE_MAX_BYTES;

void gi__set_tape_budget(size_t bytes) { atomic_store(&tape_budget_set, bytes); }

static size_t tape_max_bytes(void) { return atomic_load(&tape_budget_set); }

/* gi__bounce_end's sums run over END_BLOCKS blocks of voxels (every
 * level's in turn, the blocks as even as the count allows) on the bake's
 * threads: each block sums its voxels in order and the blocks' sums are
 * added in block order, so the result depends on the voxels alone, not
 * on the thread count. Serial, the bounce's end was 2% of the Cornell
 * box's instructions, most of what kept its two threads from 1.8x of one. */
#define END_BLOCKS 256

/* Per block: the tail's sums (s: area-weighted increment; num and den:
 * the energy ratio's) on the first pass, the light's whole indirect part
 * (last_bounce_share's) on the second. */
typedef struct {
  double s[3], num[3], den[3], all[3];
} end_sums;

typedef struct {
  struct gi_cascade *c;
  gi_faces3 *const *E;
  gi_hfaces *const *H; /* the hit shares for the energy ratio, or NULL */
  size_t start[GI_MAX_LEVELS + 1];
  size_t per;          /* voxels per block */
  int second, last;
  double f[3];         /* the tail's factor (second pass) */
  end_sums part[END_BLOCKS];
} end_ctx;

/* Block b of the first pass (the sums) or the second (side += D_k and
 * its tail; last: the indirect light's sum). */
static void end_block(end_ctx *x, size_t b) {
  const struct gi_cascade *c = x->c;
  end_sums *o = &x->part[b];
  size_t q0 = b * x->per, q1 = q0 + x->per < x->start[c->n] ? q0 + x->per : x->start[c->n];
  memset(o, 0, sizeof *o);
  int d = 0;
  for (size_t q = q0; q < q1; q++) {
    while (q >= x->start[d + 1]) d++;
    const gi_level *L = &c->lv[d];
    uint32_t i = (uint32_t)(q - x->start[d]), slot = L->occ[i];
    const gi_vgeo *g = gi__geo(L, slot);
    double a = g->area;
    const float(*inc)[3] = (const float(*)[3])x->E[d][i];
    if (!x->second) {
      int hits = x->H && x->H[d][i][0] != GI_HIT_UNKNOWN;
      for (int f = 0; f < GI_VOX_FACES; f++)
        for (int k = 0; k < 3; k++) {
          double e = a * inc[f][k];
          o->s[k] += e;
          if (hits) o->num[k] += e * (g->albedo[k] + g->gloss[k]) * x->H[d][i][f] / GI_HIT_STEPS, o->den[k] += e;
        }
      continue;
    }
    float(*side)[3] = gi__side(L, slot), (*direct)[3] = gi__direct(L, slot);
    for (int f = 0; f < GI_VOX_FACES; f++)
      for (int k = 0; k < 3; k++) {
        float t = (float)x->f[k] * inc[f][k];
        side[f][k] += inc[f][k] + (t > 0 ? t : 0);
        if (x->last) o->all[k] += a * (side[f][k] - direct[f][k]);
      }
  }
}

static void end_range(void *p, size_t b, size_t e, int worker) {
  (void)worker;
  for (size_t k = b; k < e; k++) end_block(p, k);
}

/* One pass over every block; *sum: the blocks' sums added in block order. */
static void end_pass(end_ctx *x, end_sums *sum) {
  gi__parallel_for(END_BLOCKS, 1, x->c->report.quality.threads, end_range, x);
  memset(sum, 0, sizeof *sum);
  for (int b = 0; b < END_BLOCKS; b++)
    for (int k = 0; k < 3; k++) {
      const end_sums *o = &x->part[b];
      sum->s[k] += o->s[k], sum->num[k] += o->num[k], sum->den[k] += o->den[k], sum->all[k] += o->all[k];
    }
}

/* c->last_share from the last bounce's area-weighted increment `last`
 * and the voxels' whole indirect light `all` (side already summed, with
 * the tail), and c->tail_gain from the tail's factor f. */
static void last_bounce_share(struct gi_cascade *c, const double last[3], const double all[3], const double f[3]) {
  for (int k = 0; k < 3; k++) {
    double r = all[k] > 0 && last[k] > 0 ? last[k] / all[k] : 0;
    c->last_share[k] = (float)(r < 1 ? r : 1);
    c->tail_gain[k] = (float)f[k];
  }
}

/* The end of one bounce, shared with the move's re-bake (move/move.c) so
 * both give the same bits: E holds the bounce's gather of the previous
 * increment, i.e. this bounce's increment D_k; rolls the tail's sums S
 * (area-weighted D of the last two bounces) and adds side += D_k (side =
 * direct + E_k, E_k = D_0 + ... + D_k: orders 2..k+1 of the light leaving
 * the voxels). Not last: the texture is shaded from D_k alone, for the
 * next bounce to gather. Last: + the tail when add_tail, and the texture
 * is shaded from side. The tail: D_k shrinks by the room's mean
 * reflection r = D_k / D_(k-1) (area-weighted over every
 * voxel, per channel; the dominant eigenvalue of the transport once the
 * first bounces have spread the light), or by the energy ratio of the
 * last gathers' hit shares H (below) where that is smaller: a
 * ratio above it is the gathers' own gain. (Where the measured ratio is
 * the smaller, open scenes, it stays: the shipped scenes' bias against
 * the path tracer rose 0.1-1.8 points with the energy ratio alone.) H may
 * be NULL (no tail, or fewer than two bounces). The orders left out add
 * D_k (r + r^2 + ...) = D_k r / (1 - r), each voxel scaled by its own last
 * increment. r is capped at GI_TAIL_RATIO_MAX. Last also records
 * c->last_share, which a move's fresh gather takes off (move.c).
 * The tail's ratio from energy (H given): the share of the last
 * increment the surfaces send on to other surfaces, sum a rho h D / sum
 * a D over every voxel whose hit shares H were measured (rho: the face
 * reflectance of the shading, h: the cosine-weighted share of its cones
 * that met a surface, D: its last increment, a: its area). Exact
 * transport returns no more than this; in a closed room it is rho itself,
 * where D_k / D_(k-1) read 1-2% more: the gathers start a voxel off their
 * surface and miss the strip of wall beside them, which a lamp lights
 * less than the middle, so the bounces gained light and the tail
 * multiplied the gain (x1.07 the exact mean at albedo 0.9, test_furnace).
 * 0 when nothing was measured. */
void gi__bounce_end(struct gi_cascade *c, gi_faces3 *const E[], gi_hfaces *const H[], double S[2][3], int add_tail,
                    int last) {
  end_ctx x = {.c = c, .E = E, .H = add_tail ? H : NULL, .last = last};
  for (int d = 0; d < c->n; d++) x.start[d + 1] = x.start[d] + c->lv[d].num_occ;
  x.per = (x.start[c->n] + END_BLOCKS - 1) / END_BLOCKS;
  end_sums sum;
  end_pass(&x, &sum);
  double f[3] = {0, 0, 0};
  for (int k = 0; k < 3; k++) S[0][k] = S[1][k], S[1][k] = sum.s[k];
  if (add_tail)
    for (int k = 0; k < 3; k++) {
      double dk = S[1][k], dk1 = S[0][k];
      double r = dk1 > 0 && dk > 0 ? dk / dk1 : 0;
      double re = x.H && sum.den[k] > 0 && sum.num[k] > 0 ? sum.num[k] / sum.den[k] : 0;
      if (re > 0 && re < r) r = re;
      if (r > GI_TAIL_RATIO_MAX) r = GI_TAIL_RATIO_MAX;
      f[k] = r / (1 - r);
    }
  x.second = 1;
  memcpy(x.f, f, sizeof f);
  end_pass(&x, &sum);
  if (last) last_bounce_share(c, S[1], sum.all, f);
  if (last) gi__shade_all(c);
  else gi__shade_all_from(c, E);
}

gi_result gi__bounce(struct gi_cascade *c, const gi_quality *q, int bounces, int tail, gi_error_info *err) {
  gi_faces3 *E[GI_MAX_LEVELS] = {0};
  /* Each set's own first-hit mask: the wide set's cones are not the diffuse set's. */
  gi_hits *hit[2][GI_MAX_LEVELS] = {{0}};
  gi_between *plan[GI_MAX_LEVELS] = {0};
  gi_shift6 *shift[GI_MAX_LEVELS] = {0};
  gi_hfaces *H[GI_MAX_LEVELS] = {0}; /* the last bounce's hit shares, for the tail (gi__bounce_end) */
  gi_tape *tape[GI_MAX_LEVELS] = {0}; /* each level's set's tapes, while a later bounce of the set replays them */
  tape_budget budget = {.max = tape_max_bytes()};
  atomic_init(&budget.bytes, 0);
  atomic_init(&budget.cls[0], 0);
  atomic_init(&budget.cls[1], 0);
  for (int w = 0; w < GI_MAX_WORKERS; w++) budget.rec[w].max = budget.max / sizeof(gi_tap);
  int want_H = tail && bounces >= 2;
  gi_result rc = GI_OK;
  /* Area-weighted sums of the increment per bounce (both sides,
   * every level's own voxels), for the tail's ratio. */
  double S[2][3] = {{0}};
  memset(c->last_share, 0, sizeof c->last_share);
  memset(c->tail_gain, 0, sizeof c->tail_gain);
  int any_wide = bounces > 0 && gi__bounce_wide(c, bounces - 1, c->n - 1);
  for (int d = 0; d < c->n; d++) {
    size_t n = (size_t)c->lv[d].num_occ + 1;
    E[d] = gi__malloc(n * sizeof *E[d]);
    hit[0][d] = gi__malloc(n * sizeof *hit[0][d]);
    if (any_wide) hit[1][d] = gi__malloc(n * sizeof *hit[1][d]);
    shift[d] = gi__malloc(n * sizeof *shift[d]);
    if (want_H && (H[d] = gi__malloc(n * sizeof *H[d])) != NULL)
      memset(H[d], GI_HIT_UNKNOWN, n * sizeof *H[d]); /* a voxel filled from its neighbours is not measured */
    if (!E[d] || !hit[0][d] || (any_wide && !hit[1][d]) || !shift[d] || (want_H && !H[d]) ||
        gi__between_plan(c, d, &plan[d]) != GI_OK) {
      rc = gi__fail(err, GI_ERR_NOMEM, "bounce: out of memory");
      goto done;
    }
    /* Every cone, until a voxel's gather on its set's first bounce says which met something. */
    memset(hit[0][d], 0xff, n * sizeof *hit[0][d]);
    if (any_wide) memset(hit[1][d], 0xff, n * sizeof *hit[1][d]);
  }
  for (int it = 0; it < bounces; it++) {
    bounce_ctx bc = {.c = c, .E = E, .plan = plan, .shift = shift, .shift_known = it > 0,
                     .H = want_H && it + 1 == bounces ? H : NULL, .tape = tape, .budget = &budget};
    for (int d = 0; d < c->n; d++) {
      int wide = gi__bounce_wide(c, it, d), first = set_first(c, it, d);
      /* A set's first bounce records its tapes when a later bounce takes the same set. */
      int record = first && budget.max > 0 && it + 1 < bounces && gi__bounce_wide(c, it + 1, d) == wide;
      bc.wide[d] = (uint8_t)wide, bc.first[d] = (uint8_t)first, bc.record[d] = (uint8_t)record;
      bc.cls[d] = (uint8_t)tape_class(c, d), bc.hit[d] = hit[wide][d];
      /* A level's set changes once at most, with every level of its class. */
      if (first && it > 0 && tape[d]) free_tapes(c, tape, &budget, bc.cls[d]);
    }
    for (int d = 0; d < c->n; d++)
      if (bc.record[d] && !(tape[d] = gi__calloc((size_t)c->lv[d].num_occ + 1, sizeof *tape[d]))) {
        rc = gi__fail(err, GI_ERR_NOMEM, "bounce: out of memory");
        goto done;
      }
    for (int d = 0; d < c->n; d++) bc.start[d + 1] = bc.start[d] + c->lv[d].num_occ;
    atomic_init(&bc.samples, 0);
    atomic_init(&bc.cones, 0);
    atomic_init(&bc.taps, 0);
    atomic_init(&bc.replay_ns, 0);
    atomic_init(&bc.oom, 0);
    int cancelled = gi__parallel_for_cancel(bc.start[c->n], 16, q->threads, bounce_range, &bc, NULL, c->cancel);
    c->report.cone_samples += atomic_load(&bc.samples);
    c->report.cones_traced += atomic_load(&bc.cones);
    c->report.taps_replayed += atomic_load(&bc.taps);
    c->report.replay_thread_ms += (double)atomic_load(&bc.replay_ns) * 1e-6;
    size_t kept = atomic_load(&budget.bytes);
    if (kept > c->report.tape_bytes) c->report.tape_bytes = kept;
    if (cancelled) {
      rc = gi__cancel_fail(c->cancel, err, "bounce");
      goto done;
    }
    if (atomic_load(&bc.oom)) {
      rc = gi__fail(err, GI_ERR_NOMEM, "bounce: out of memory for the replay tapes");
      goto done;
    }
    uint64_t samples = 0, cones = 0;
    rc = between_masked(c, plan, E, it, q->threads, hit, &samples, &cones, err);
    c->report.cone_samples += samples;
    c->report.cones_traced += cones;
    if (rc != GI_OK) goto done;
    gi__bounce_end(c, E, want_H ? H : NULL, S, tail && it + 1 == bounces && it >= 1, it + 1 == bounces);
    if (gi__cascade_filter(c, q->threads)) {
      rc = gi__cancel_fail(c->cancel, err, "bounce filter");
      goto done;
    }
    c->report.bounces_run = it + 1;
  }
done:
  for (int cls = 0; cls < 2; cls++) free_tapes(c, tape, &budget, cls);
  for (int w = 0; w < GI_MAX_WORKERS; w++)
    arena_free(&budget.arena[0][w]), arena_free(&budget.arena[1][w]), gi__free(budget.rec[w].t);
  for (int d = 0; d < c->n; d++)
    gi__free(E[d]), gi__free(hit[0][d]), gi__free(hit[1][d]), gi__free(plan[d]), gi__free(shift[d]), gi__free(H[d]);
  return rc;
}
