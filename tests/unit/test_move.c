/* test_move.c: moving a baked cascade (gi_cascade_move) against cold bakes.
 *
 * On the procedural city at small quality (4 levels of 16^3):
 *   walk: 200 seeded random moves, most by a few finest voxels, some far
 *     across the city (larger than the finer levels' extents: those levels
 *     are rebuilt). Every WALK_CHECK moves the geometry, opacity and direct
 *     light of every own voxel must equal a cold bake at that point bit for
 *     bit (the scroll rebuilds exactly the voxels that came into range).
 *     After the walk the viewer stands still until the refresh cycle closes
 *     (the re-bake's P slices at one anchor, gi_move.h);
 *     then every face of every voxel (unpacked texels: the two cascades may
 *     store them at different rad_scale) must equal the cold bake within
 *     1e-3 relative.
 *   deterministic: two cascades walked alike stay byte-identical.
 *   relit: moving out of a closed room turns the sky on (and back in off):
 *     every voxel is re-injected and matches a cold bake.
 *   cost: a move by one anchor cell voxelizes, injects and re-gathers far
 *     fewer voxels than the cold bake (counted, not timed).
 *   bounded: along a street walk and a drive no call re-gathers or
 *     voxelizes more than a quarter of a cold bake's voxels.
 *   refilter exact: the nested cells a move refilters are all that a full
 *     refilter would change.
 *   probe drift: the probe at the viewpoint along the walk and the drive
 *     stays within measured bounds of cold bakes at the same anchors.
 *   room fast walk: likewise through a compact room, crossing a cell at
 *     every call (the re-bake never closes).
 *   lamps: with 600 more street lamps (sampled through the light cut) the
 *     moved voxels still equal cold bakes, and the closed cycle too. */
#include "test_util.h"
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "base/alloc_test.h"
#include "base/internal.h"
#include "cascade/cascade_internal.h"
#include "gi/gi.h"
#include "gi/gi_move.h"
#include "light/light.h"
#include "scene/lights.h"
#include "test_levels.h"

#define WALK_MOVES 200
#define WALK_CHECK 25       /* moves between geometry checks against a cold bake */
#define FAR_SHARE 0.15      /* share of moves that jump across the city */
#define NEAR_VOXELS 3.0     /* a near move: up to this many finest voxels per horizontal axis */
#define FACE_REL_TOL 1e-3   /* the bound on every face */
/* Below about 2^-24 of the brightest texel a half float (stored relative to
 * rad_scale = brightest / 4096, subnormal under 2^-14) has no relative
 * precision left; differences under this share of the brightest are noise. */
#define FACE_ABS_FLOOR 1e-7
#define COST_SHARE 0.25     /* a one-cell move redoes at most this share of a cold bake's voxels */

static gi_scene *city(gi_city_params *cp) {
  gi_scene *s = NULL;
  gi_error_info err = {0};
  assert_int_equal(gi_city_build(cp, NULL, &s, &err), GI_OK);
  return s;
}

static const gi_quality SMALL = {.levels = 4, .res = 16, .light_samples = 4, .probe_samples = 16, .threads = 2};

static gi_cascade *bake(const gi_scene *s, const double at[3]) {
  gi_cascade *c = NULL;
  gi_error_info err = {0};
  assert_int_equal(gi_cascade_bake(s, at, &SMALL, &c, NULL, &err), GI_OK);
  return c;
}

/* Geometry, opacity and direct light of every own voxel, bit for bit. */
static void assert_same_geometry(const gi_cascade *m, const gi_cascade *b) {
  size_t vox = (size_t)m->R * m->R * m->R;
  for (int d = 0; d < m->n; d++) {
    const gi_level *A = &m->lv[d], *B = &b->lv[d];
    assert_memory_equal(A->cell0, B->cell0, sizeof A->cell0);
    assert_int_equal(A->num_occ, B->num_occ);
    assert_memory_equal(A->occ, B->occ, A->num_occ * sizeof *A->occ);
    assert_true(tl_same_entries(A, B, m->R, TL_GEO));
    assert_true(memcmp(A->busy, B->busy, vox) == 0);
    for (uint32_t i = 0; i < A->num_occ; i++) {
      uint32_t slot = A->occ[i];
      assert_memory_equal(gi__direct(A, slot), gi__direct(B, slot), sizeof(gi_faces3));
      for (int a = 0; a < 3; a++) {
        assert_int_equal(A->rad[slot].h[GI_VRAD_ALPHA + a], B->rad[slot].h[GI_VRAD_ALPHA + a]);
        assert_int_equal(A->rad[slot].h[GI_VRAD_TAU + a], B->rad[slot].h[GI_VRAD_TAU + a]);
      }
    }
  }
}

/* Faces at least this share of the brightest enter the drift figure. */
#define DRIFT_FLOOR 1e-3

static float brightest_face(const gi_cascade *b) {
  size_t vox = (size_t)b->R * b->R * b->R;
  float brightest = 0;
  for (int d = 0; d < b->n; d++)
    for (size_t i = 0; i < vox; i++) {
      gi_vrad_f f;
      gi__vrad_unpack(b, &b->lv[d].rad[i], &f);
      for (int k = 0; k < 18; k++) brightest = fmaxf(brightest, f.p[k / 3][k % 3]);
    }
  return brightest;
}

/* Every face of every voxel (both cascades' texels unpacked). With
 * `strict` each must agree within FACE_REL_TOL; either way the mean and
 * largest relative difference over faces above DRIFT_FLOOR of the
 * brightest go to mean/worst. */
static void compare_light(const gi_cascade *m, const gi_cascade *b, int strict, double *mean, double *worst) {
  size_t vox = (size_t)m->R * m->R * m->R;
  float brightest = brightest_face(b);
  if (strict)
    for (int d = 0; d < m->n; d++) assert_memory_equal(m->lv[d].cell0, b->lv[d].cell0, sizeof m->lv[d].cell0);
  *mean = *worst = 0;
  /* A viewpoint inside a solid sees no sun or sky (the effect plan): both dark. */
  if (brightest == 0) {
    assert_true(brightest_face(m) == 0);
    return;
  }
  double floor_abs = FACE_ABS_FLOOR * brightest, sum = 0;
  uint64_t faces = 0;
  *worst = 0;
  for (int d = 0; d < m->n; d++)
    for (size_t i = 0; i < vox; i++) {
      /* Cascades at other anchors share only the cells both windows hold
       * (a global cell has the same slot in both), own or nested in both. */
      int64_t cm[3], cb[3];
      gi__slot_cell(&m->lv[d], m->R, (uint32_t)i, cm);
      gi__slot_cell(&b->lv[d], b->R, (uint32_t)i, cb);
      if (memcmp(cm, cb, sizeof cm) != 0 ||
          gi__is_inner(&m->lv[d], cm[0], cm[1], cm[2]) != gi__is_inner(&b->lv[d], cb[0], cb[1], cb[2]))
        continue;
      gi_vrad_f x, y;
      gi__vrad_unpack(m, &m->lv[d].rad[i], &x);
      gi__vrad_unpack(b, &b->lv[d].rad[i], &y);
      for (int k = 0; k < 18; k++) {
        double u = x.p[k / 3][k % 3], v = y.p[k / 3][k % 3], diff = fabs(u - v);
        double big = fmax(fabs(u), fabs(v));
        if (strict && diff > FACE_REL_TOL * big + floor_abs)
          fail_msg("level %d slot %zu lane %d: move %.9g, bake %.9g (rel %.3g)", d, i, k, u, v, diff / big);
        if (big < DRIFT_FLOOR * brightest) continue;
        sum += diff / big;
        *worst = fmax(*worst, diff / big);
        faces++;
      }
      for (int a = 0; a < 3 && strict; a++) assert_true(x.alpha[a] == y.alpha[a] && x.tau[a] == y.tau[a]);
    }
  *mean = faces ? sum / (double)faces : 0;
}

/* The next viewpoint of the walk: near (a few finest voxels) or far. */
static void next_point(const gi_city_params *cp, double s0, uint64_t *rng, double at[3]) {
  if (gi__u01(rng) < FAR_SHARE) {
    at[0] = (gi__u01(rng) - 0.5) * 0.9 * cp->extent;
    at[2] = (gi__u01(rng) - 0.5) * 0.9 * cp->extent;
    at[1] = 1.7 + 20.0 * gi__u01(rng);
    return;
  }
  at[0] += (2.0 * gi__u01(rng) - 1.0) * NEAR_VOXELS * s0;
  at[2] += (2.0 * gi__u01(rng) - 1.0) * NEAR_VOXELS * s0;
  at[1] += (2.0 * gi__u01(rng) - 1.0) * s0;
  if (at[1] < 0.5) at[1] = 0.5;
}

/* A cascade whose cycle has closed (mi: its last move) against a cold
 * bake at the same anchor: geometry bit for bit, every face within
 * FACE_REL_TOL; frees both and the scene. */
static void assert_closed_equals_cold(const char *what, gi_cascade *c, gi_scene *s, const double at[3],
                                      const gi_move_info *mi) {
  assert_true(mi->cycle_closed);
  gi_cascade *b = bake(s, at);
  assert_same_geometry(c, b);
  double mean, worst;
  compare_light(c, b, 1, &mean, &worst);
  printf("%s: cycle closed: light against a cold bake: mean %.3g max %.3g relative (bound %.0e)\n", what, mean, worst,
         FACE_REL_TOL);
  gi_cascade_free(b);
  gi_cascade_free(c);
  gi_scene_release(s);
}

static void test_walk(void **state) {
  gi_city_params cp = {.seed = 3, .extent = 300};
  gi_scene *s = city(&cp);
  double at[3];
  gi_city_default_viewpoint(&cp, at);
  gi_cascade *c = bake(s, at);
  double s0 = c->s0;
  uint64_t rng = 0x5c2011;
  gi_error_info err = {0};
  int rebuilt = 0, closed = 0, relit = 0;
  for (int m = 1; m <= WALK_MOVES; m++) {
    double prev[3] = {at[0], at[1], at[2]};
    next_point(&cp, s0, &rng, at);
    gi_move_info mi;
    assert_int_equal(gi_cascade_move(c, at, NULL, &mi, &err), GI_OK);
    assert_true(mi.move == (uint64_t)m);
    for (int d = 0; d < c->n; d++) rebuilt += mi.rebuilt[d];
    closed += mi.cycle_closed;
    relit += mi.relit;
    if (m % WALK_CHECK == 0) {
      gi_cascade *b = bake(s, at);
      assert_same_geometry(c, b);
      /* Before the re-bake completes the light drifts (reported, not asserted). */
      /* Baseline: how far cold bakes at the previous and this point differ. */
      gi_cascade *p = bake(s, prev);
      double mean, worst, pmean, pworst;
      compare_light(c, b, 0, &mean, &worst);
      compare_light(p, b, 0, &pmean, &pworst);
      printf("move %3d (re-bake slice %d): light against a cold bake: mean %.4f max %.4f relative; "
             "cold bake one step back against it: mean %.4f max %.4f\n", m, mi.slice, mean, worst, pmean, pworst);
      gi_cascade_free(p);
      gi_cascade_free(b);
    }
  }
  printf("walk: %d level rebuilds, %d moves re-lit by a changed plan, %d cycles closed\n", rebuilt, relit, closed);
  assert_true(rebuilt > 0); /* the far jumps rebuilt some levels */
  assert_true(closed > 0);  /* ... and closed the cycle at once */
  /* Stand still until the cycle closes: one more call at the anchor the
   * walk ended on (the call that arrived does not count), then P calls. */
  gi_move_info mi = {0};
  assert_int_equal(gi_cascade_move(c, at, NULL, &mi, &err), GI_OK);
  for (uint64_t i = 1; i < gi_cascade_refresh_period(c, c->n - 1) && !mi.cycle_closed; i++)
    assert_int_equal(gi_cascade_move(c, at, NULL, &mi, &err), GI_OK);
  assert_closed_equals_cold("walk", c, s, at, &mi);
}

/* The walk's property on the shared scenes nobody here made: an emissive
 * Cornell box (millimetres), Munich from OpenStreetMap (z up, sun and sky)
 * and the Stanford bunny (a scan, default lights). SCENE_MOVES random moves
 * each, near (a few finest voxels across, one up or down) and far
 * (anywhere in the scene's bounds, inside solids too); geometry bit for bit
 * every SCENE_CHECK moves, then the closed cycle against a cold bake. */
#define SCENE_MOVES 40
#define SCENE_CHECK 10
typedef struct {
  const char *rel;
  gi_up_axis up;
  double at[3];
} walk_scene;

static void walk_one_scene(const walk_scene *ws) {
  const char *path = tu_scene_path(ws->rel);
  if (!path) return;
  gi_scene *s = NULL;
  gi_error_info err = {0};
  gi_scene_options so = {.up = ws->up, .default_lights = 1};
  assert_int_equal(gi_scene_load(path, &so, &s, &err), GI_OK);
  double lo[3], hi[3], at[3] = {ws->at[0], ws->at[1], ws->at[2]};
  gi_scene_bounds(s, lo, hi);
  gi_cascade *c = bake(s, at);
  uint64_t rng = 0x5ce9e5;
  int rebuilt = 0;
  for (int m = 1; m <= SCENE_MOVES; m++) {
    int far = gi__u01(&rng) < FAR_SHARE, up = ws->up == GI_UP_Z ? 2 : 1;
    for (int a = 0; a < 3; a++) {
      double near = (2.0 * gi__u01(&rng) - 1.0) * (a == up ? 1.0 : NEAR_VOXELS) * c->s0;
      at[a] = far ? lo[a] + gi__u01(&rng) * (hi[a] - lo[a]) : at[a] + near;
    }
    gi_move_info mi;
    assert_int_equal(gi_cascade_move(c, at, NULL, &mi, &err), GI_OK);
    for (int d = 0; d < c->n; d++) rebuilt += mi.rebuilt[d];
    if (m % SCENE_CHECK == 0) {
      gi_cascade *b = bake(s, at);
      assert_same_geometry(c, b);
      gi_cascade_free(b);
    }
  }
  printf("%s: %d moves, %d level rebuilds\n", ws->rel, SCENE_MOVES, rebuilt);
  /* Back beside the start, which is lit (a far point may lie in a solid). */
  for (int a = 0; a < 3; a++) at[a] = ws->at[a] + 0.5 * c->s0;
  gi_move_info mi = {0};
  assert_int_equal(gi_cascade_move(c, at, NULL, &mi, &err), GI_OK);
  for (uint64_t i = 1; i < gi_cascade_refresh_period(c, c->n - 1) && !mi.cycle_closed; i++)
    assert_int_equal(gi_cascade_move(c, at, NULL, &mi, &err), GI_OK);
  assert_true(brightest_face(c) > 0);
  assert_closed_equals_cold(ws->rel, c, s, at, &mi);
}

static void test_walk_scenes(void **state) {
  static const walk_scene scenes[] = {
      {"cornell-box/cornell-box.obj", GI_UP_Y, {278, 273, 279.6}},
      {"munich/munich.obj", GI_UP_Z, {0, 0, 2}},
      {"stanford-bunny/stanford-bunny.obj", GI_UP_Y, {0, 0.1, 0.1}},
  };
  for (size_t i = 0; i < sizeof scenes / sizeof scenes[0]; i++) walk_one_scene(&scenes[i]);
}

/* Three bounces, the third gathered with the wide cone set, and the
 * coarse levels the viewpoint barely sees with it from the first
 * (light/bounce.c): the re-bake must take the same set bounce by bounce
 * and level by level as the bake, so a closed cycle still equals a cold
 * bake. */
static void test_wide_bounce_cycle(void **state) {
  gi_city_params cp = {.seed = 3, .extent = 300};
  gi_scene *s = city(&cp);
  double at[3];
  gi_city_default_viewpoint(&cp, at);
  gi_quality q = SMALL;
  q.bounces = 3;
  gi_cascade *c = NULL, *b = NULL;
  gi_error_info err = {0};
  assert_int_equal(gi_cascade_bake(s, at, &q, &c, NULL, &err), GI_OK);
  assert_int_equal(gi_cascade_report(c)->bounces_run, 3);
  assert_true(!gi__bounce_wide(c, 1, 0) && gi__bounce_wide(c, 2, 0));
  int wl = gi_cascade_report(c)->wide_from_level;
  printf("levels %d-%d take the wide set from the first bounce\n", wl, c->n - 1);
  assert_true(wl > 0 && wl < c->n);
  assert_true(gi__bounce_wide(c, 0, wl) && !gi__bounce_wide(c, 0, wl - 1));
  /* A few finest voxels: level 0 scrolls, the re-bake restarts. */
  at[0] += 3 * c->s0;
  gi_move_info mi = {0};
  assert_int_equal(gi_cascade_move(c, at, NULL, &mi, &err), GI_OK);
  for (uint64_t i = 0; i <= gi_cascade_refresh_period(c, c->n - 1) && !mi.cycle_closed; i++)
    assert_int_equal(gi_cascade_move(c, at, NULL, &mi, &err), GI_OK);
  assert_true(mi.cycle_closed);
  assert_int_equal(gi_cascade_report(c)->bounces_run, 3);
  assert_int_equal(gi_cascade_bake(s, at, &q, &b, NULL, &err), GI_OK);
  assert_same_geometry(c, b);
  double mean, worst;
  compare_light(c, b, 1, &mean, &worst);
  printf("3 bounces, cycle closed: light against a cold bake: mean %.3g max %.3g relative (bound %.0e)\n", mean,
         worst, FACE_REL_TOL);
  gi_cascade_free(b);
  gi_cascade_free(c);
  gi_scene_release(s);
}

static uint64_t total(const uint64_t *v, int n) {
  uint64_t t = 0;
  for (int d = 0; d < n; d++) t += v[d];
  return t;
}

static void test_cost(void **state) {
  gi_city_params cp = {.seed = 3, .extent = 300};
  gi_scene *s = city(&cp);
  double at[3];
  gi_city_default_viewpoint(&cp, at);
  gi_cascade *c = bake(s, at);
  gi_bake_report cold = *gi_cascade_report(c);
  /* One anchor cell (2 finest voxels) along x: the first move, not a cycle's end. */
  at[0] += 2.0 * c->s0;
  gi_bake_report r;
  gi_move_info mi;
  gi_error_info err = {0};
  assert_int_equal(gi_cascade_move(c, at, &r, &mi, &err), GI_OK);
  assert_false(mi.cycle_closed);
  int n = c->n;
  uint64_t cv = total(cold.level_voxelized, n), mv = total(r.level_voxelized, n);
  uint64_t ci = total(cold.level_injected, n), minj = total(r.level_injected, n);
  uint64_t cb = total(cold.level_rebounced, n), mb = total(r.level_rebounced, n);
  printf("cold bake: voxelized %llu injected %llu rebounced %llu; move: %llu %llu %llu\n",
         (unsigned long long)cv, (unsigned long long)ci, (unsigned long long)cb, (unsigned long long)mv,
         (unsigned long long)minj, (unsigned long long)mb);
  printf("ms (figures only): cold voxelize %.2f inject %.2f filter %.2f bounce %.2f; move %.2f %.2f %.2f %.2f\n",
         cold.ms.voxelize, cold.ms.inject, cold.ms.filter, cold.ms.bounce, r.ms.voxelize, r.ms.inject, r.ms.filter,
         r.ms.bounce);
  for (int d = 0; d < n; d++)
    printf("  level %d: voxelized %llu injected %llu rebounced %llu\n", d, (unsigned long long)r.level_voxelized[d],
           (unsigned long long)r.level_injected[d], (unsigned long long)r.level_rebounced[d]);
  /* The cold bake counts every own voxel of every level. */
  assert_true(cv > 0 && ci > 0 && cb > 0);
  /* Level 0 scrolled by exactly 2 cells: a slab of 2 x R x R. */
  assert_true(r.level_voxelized[0] == 2ull * (uint64_t)c->R * (uint64_t)c->R);
  /* Level 0 gathered the slab's voxels and the kept ones within 3 cells
   * behind it (move.c, NEIGHBOUR_CELLS): every occupied voxel in the
   * window's last 5 columns along x, and none at the other face (the band
   * ends at the window's face; the level is toroidal, the band must not be). */
  const gi_level *L0 = &c->lv[0];
  uint64_t band = 0;
  for (uint32_t q = 0; q < L0->num_occ; q++) {
    int64_t cell[3];
    gi__slot_cell(L0, c->R, L0->occ[q], cell);
    band += cell[0] - L0->cell0[0] >= c->R - 5;
  }
  printf("level 0: %llu voxels in the slab and the band behind it, %llu gathered\n", (unsigned long long)band,
         (unsigned long long)r.level_rebounced[0]);
  assert_true(band > 0);
  assert_true(r.level_rebounced[0] == band);
  assert_true((double)mv < COST_SHARE * (double)cv);
  assert_true((double)minj < COST_SHARE * (double)ci);
  assert_true((double)mb < COST_SHARE * (double)cb);
  gi_cascade_free(c);
  gi_scene_release(s);
}

/* A street walk (1.4 m/s) and a drive (14 m/s) at 10 Hz along the street
 * through the city's central intersection (x grows, z fixed), centred on
 * it so that the drive (168 m) stays inside the 300 m city. */
#define STEP_HZ 10.0
#define WALK_SPEED 1.4
#define DRIVE_SPEED 14.0
#define PATH_STEPS 120

static void path_start(const gi_city_params *cp, double speed, double at[3]) {
  gi_city_default_viewpoint(cp, at);
  at[0] -= 0.5 * speed * PATH_STEPS / STEP_HZ;
}

/* Per-move work along a long walk and drive, counted: no call re-gathers
 * more than BOUND_SHARE of a cold bake's gathers (the bake's bounces times
 * its occupied voxels), nor voxelizes more than BOUND_SHARE of its voxels.
 * Measured: at most 29.0% (the drive) and 15.1% (at 16^3 a level's 2-cell
 * slab and the 3-cell band gathered with it are up to 8/16 of the level; a
 * re-bake slice is 1/8 of the bake's gathers); 20.5% with a 2-cell band. */
#define BOUND_SHARE 0.3
/* Nor traces more than this share of a cold bake's cone samples. Measured:
 * at most 31.5% (the drive: a crossing's gathers, near the window's faces,
 * take the diffuse set where the bake's third bounce takes the wide one;
 * 36.8% before the coarse levels took the wide set from the first bounce,
 * in the bake and the crossings alike; 33.1% before the new voxels' first
 * gather, move.c fresh_texture). */
#define SAMPLES_SHARE 0.4
static void test_bounded(void **state) {
  gi_city_params cp = {.seed = 3, .extent = 300};
  gi_scene *s = city(&cp);
  const double speeds[2] = {WALK_SPEED, DRIVE_SPEED};
  for (int v = 0; v < 2; v++) {
    double at[3];
    path_start(&cp, speeds[v], at);
    /* The reference is a bake that marches every bounce: a bake's later
     * bounces replay their first bounce's taps (light/bounce.c) and count
     * fewer samples for the same gathers, which no move replays. */
    gi__set_tape_budget(0);
    gi_cascade *c = bake(s, at);
    gi__set_tape_budget(GI_TAPE_MAX_BYTES);
    gi_bake_report cold = *gi_cascade_report(c);
    size_t fresh = gi_cascade_bytes(c);
    uint64_t cb = total(cold.level_rebounced, c->n), cv = total(cold.level_voxelized, c->n);
    uint64_t worst = 0, worst_v = 0, worst_s = 0, sum = 0;
    int slices = 0, crossings = 0;
    gi_error_info err = {0};
    for (int m = 0; m < PATH_STEPS; m++) {
      at[0] += speeds[v] / STEP_HZ;
      gi_bake_report r;
      gi_move_info mi;
      assert_int_equal(gi_cascade_move(c, at, &r, &mi, &err), GI_OK);
      /* The report's bytes are the cascade's as it now is (they stayed the bake's). */
      assert_int_equal(r.cascade_bytes, gi_cascade_bytes(c));
      assert_int_equal(gi_cascade_report(c)->cascade_bytes, gi_cascade_bytes(c));
      uint64_t g = total(r.level_rebounced, c->n), vx = total(r.level_voxelized, c->n);
      for (int d = 0; d < c->n; d++) assert_false(mi.rebuilt[d]);
      assert_false(mi.cycle_closed && mi.slice == 0);
      slices += mi.slice > 0;
      crossings += vx > 0;
      worst = g > worst ? g : worst;
      worst_v = vx > worst_v ? vx : worst_v;
      worst_s = r.cone_samples > worst_s ? r.cone_samples : worst_s;
      sum += g;
      assert_true((double)g <= BOUND_SHARE * (double)cb);
      assert_true((double)vx <= BOUND_SHARE * (double)cv);
      /* The work itself: every gather's cone samples (a crossing's first
       * gather of its new voxels included, which level_rebounced does not count). */
      assert_true((double)r.cone_samples <= SAMPLES_SHARE * (double)cold.cone_samples);
    }
    printf("%s: cold bake %llu cone samples; per move at most %llu (%.1f%%)\n", v ? "drive" : "walk",
           (unsigned long long)cold.cone_samples, (unsigned long long)worst_s,
           100.0 * (double)worst_s / (double)cold.cone_samples);
    printf("%s: cold bake %llu gathers, %llu voxels; per move at most %llu gathers (%.1f%%), mean %.1f (%.1f%%), "
           "at most %llu voxelized (%.1f%%); %d crossing moves, %d re-bake slices\n",
           v ? "drive" : "walk", (unsigned long long)cb, (unsigned long long)cv, (unsigned long long)worst,
           100.0 * (double)worst / (double)cb, (double)sum / PATH_STEPS, 100.0 * (double)sum / PATH_STEPS / (double)cb,
           (unsigned long long)worst_v, 100.0 * (double)worst_v / (double)cv, crossings, slices);
    /* The moves added their re-bake's buffers, and the whole stays within
     * what a holder reserves: the bake's bound plus the move's. */
    size_t grown = gi_cascade_bytes(c), est = gi_cascade_move_bytes_estimate(&c->report.quality);
    size_t baked = gi_cascade_bytes_estimate(&c->report.quality);
    printf("%s: baked cascade %zu bytes, moved %zu; bake estimate %zu + move estimate %zu\n", v ? "drive" : "walk",
           fresh, grown, baked, est);
    assert_true(grown > fresh && grown <= baked + est);
    gi_cascade_free(c);
  }
  gi_scene_release(s);
}

/* A viewer that keeps moving, DWELL calls per anchor, gets a re-bake cycle
 * of about DWELL - 1 slices (gi_move.h), which closes before its next
 * crossing and leaves the cascade equal to a cold bake there. One that
 * crosses on every call keeps the resting cycle (16 calls at 5 levels). */
#define DWELL 10
#define DWELL_ANCHORS 10
static const gi_quality MOVING = {.levels = 5, .res = 16, .light_samples = 4, .probe_samples = 16, .threads = 2};
static void test_moving_cycle(void **state) {
  gi_city_params cp = {.seed = 3, .extent = 300};
  gi_scene *s = city(&cp);
  double at[3];
  path_start(&cp, WALK_SPEED, at);
  gi_cascade *c = NULL, *b = NULL;
  gi_error_info err = {0};
  assert_int_equal(gi_cascade_bake(s, at, &MOVING, &c, NULL, &err), GI_OK);
  uint64_t rest = gi_cascade_refresh_period(c, 0), shortest = rest;
  assert_int_equal(rest, 1u << (MOVING.levels - 1));
  /* An anchor cell (two finest voxels) in DWELL calls. */
  double step = 2 * c->s0 / DWELL;
  int closed = 0;
  for (int m = 0; m < DWELL * DWELL_ANCHORS; m++) {
    at[0] += step;
    gi_move_info mi;
    assert_int_equal(gi_cascade_move(c, at, NULL, &mi, &err), GI_OK);
    uint64_t p = gi_cascade_refresh_period(c, 0);
    shortest = p < shortest ? p : shortest;
    if (!mi.cycle_closed) continue;
    closed++;
    assert_int_equal(gi_cascade_bake(s, at, &MOVING, &b, NULL, &err), GI_OK);
    double mean, worst;
    compare_light(c, b, 1, &mean, &worst);
    gi_cascade_free(b);
  }
  printf("moving %d calls per anchor: shortest cycle %llu calls (resting %llu), %d cycles closed over %d anchors\n",
         DWELL, (unsigned long long)shortest, (unsigned long long)rest, closed, DWELL_ANCHORS);
  assert_true(shortest < DWELL);
  /* The running mean settles after three anchors; the first is the bake's (measured: 8 of 10 closed). */
  assert_true(closed >= DWELL_ANCHORS - 5);
  /* Across an anchor cell on every call: back to the resting cycle. */
  for (int m = 0; m < DWELL; m++) {
    at[0] += 2.5 * c->s0;
    assert_int_equal(gi_cascade_move(c, at, NULL, NULL, &err), GI_OK);
  }
  assert_int_equal(gi_cascade_refresh_period(c, 0), rest);
  gi_cascade_free(c);
  gi_scene_release(s);
}

/* The probe at the viewpoint as the issue measures it: SH L00 and the
 * irradiance of the 6 axis directions, per channel (21 values). */
static void probe_figures(const gi_cascade *c, const double at[3], double v[21]) {
  gi_probe p;
  gi_error_info err = {0};
  assert_int_equal(gi_cascade_gather(c, at, 1, &p, NULL, &err), GI_OK);
  for (int k = 0; k < 3; k++) v[k] = p.sh[0][k];
  for (int f = 0; f < 6; f++) {
    float n[3] = {0, 0, 0}, o[3];
    n[f / 2] = f % 2 ? -1.f : 1.f;
    gi_sh_eval_irradiance(p.sh, n, o);
    for (int k = 0; k < 3; k++) v[3 + 3 * f + k] = o[k];
  }
}

/* Probe drift along the walk and the drive against cold bakes at the same
 * anchors: mean and largest relative difference of the 21 figures.
 * Measured on these paths (deterministic, both march kernels alike): walk
 * mean 0.0001, max 0.0044; drive mean 0.0020, max 0.0249 (0.0019 / 0.0300
 * while a crossing gathered from the whole texture, one order more than
 * the bake's, and the new voxels at their direct light; 0.0031 / 0.0391
 * with the order taken off but the new voxels not primed: move.c,
 * fresh_texture). The drive read
 * 0.0028 / 0.0677 while only the kept voxels within 2 cells of the new
 * slabs were re-gathered with it (move.c, NEIGHBOUR_CELLS): those 3 cells
 * behind still held what they gathered at the window's face. The bounds
 * leave 1.5x for other compilers (the walk's mean, 2x: it is tiny); the
 * scheme this replaced (whole levels re-gathered on a clock) measured 5x
 * the mean at default quality. By 13d9cdc the drive's max read 0.0347;
 * since the probes read a surface nearer than their first sample in one
 * sample (answer/gather.c) it reads 0.0379, the walk 0.0039: the figure is
 * E(-y), 0.2 against E(+y)'s 2, at steps 36-38, where the moved texture
 * differs from the cold one by 4% in the street under the probe and the
 * down cones now read it unblended. Bound 1.2x that.
 * The largest figure is one dim direction's noise, and the bounds fit this
 * seed: with the injection's seed changed (8 seeds, 5d6c999, 2026-12-08)
 * the same code read walk max 0.0037-0.0104 and drive 0.030-0.067, the
 * means 0.0001-0.0002 and 0.0018-0.0026. A change that only moves the
 * noise can cross the max bounds: read the means and other seeds first. */
static const double DRIFT_MEAN_BOUND[2] = {0.0004, 0.0029}, DRIFT_MAX_BOUND[2] = {0.0065, 0.045};
static void test_probe_drift(void **state) {
  gi_city_params cp = {.seed = 3, .extent = 300};
  gi_scene *s = city(&cp);
  const double speeds[2] = {WALK_SPEED, DRIVE_SPEED};
  for (int v = 0; v < 2; v++) {
    double at[3];
    path_start(&cp, speeds[v], at);
    gi_cascade *c = bake(s, at), *b = NULL;
    int64_t banchor[3] = {INT64_MIN, 0, 0};
    double sum = 0, worst = 0;
    int n = 0;
    gi_error_info err = {0};
    for (int m = 0; m < PATH_STEPS; m++) {
      at[0] += speeds[v] / STEP_HZ;
      assert_int_equal(gi_cascade_move(c, at, NULL, NULL, &err), GI_OK);
      int64_t an[3];
      assert_int_equal(gi_cascade_anchor(s, at, &c->report.quality, an, &err), GI_OK);
      if (memcmp(an, banchor, sizeof an) != 0) {
        gi_cascade_free(b);
        b = bake(s, at);
        memcpy(banchor, an, sizeof an);
      }
      double pm[21], pb[21];
      probe_figures(c, at, pm);
      probe_figures(b, at, pb);
      for (int i = 0; i < 21; i++) {
        double rel = fabs(pm[i] - pb[i]) / fmax(fabs(pb[i]), 1e-12);
        sum += rel;
        worst = fmax(worst, rel);
        n++;
      }
    }
    printf("%s: probe against cold bakes over %d steps: mean %.4f max %.4f relative (bounds %.4f, %.3f)\n",
           v ? "drive" : "walk", PATH_STEPS, sum / n, worst, DRIFT_MEAN_BOUND[v], DRIFT_MAX_BOUND[v]);
    assert_true(sum / n <= DRIFT_MEAN_BOUND[v]);
    assert_true(worst <= DRIFT_MAX_BOUND[v]);
    gi_cascade_free(b);
    gi_cascade_free(c);
  }
  gi_scene_release(s);
}

/* A fast walk through a compact scene: the lit room of test_render (4 x
 * 2.5 x 4, a point light inside) crossed at 0.05 a call (more than a
 * finest cell, 0.039), there and back, so the re-bake never closes. Every
 * ROOM_CHECK calls the probe (as test_probe_drift) against a cold bake at
 * the same point. The coarsest level (5 wide) holds the whole room
 * (cascade.c, cover_scene), so the walk does not scroll it. Measured:
 * mean 0.0028, max 0.0157 (the last check, back at the start); with every
 * level centred on the viewer the coarsest one cut the room and moved
 * with the walk, and its kept voxels held light gathered with other walls
 * in range: mean 0.0998, max 0.3680. Bounds 1.5x the measured figures. */
#define ROOM_STEPS 60
#define ROOM_CHECK 10
#define ROOM_MEAN_BOUND 0.0042
#define ROOM_MAX_BOUND 0.024
static void test_room_fast_walk(void **state) {
  gi_scene *s = tu_lit_room(0.6f);
  double at[3] = {0.1, 1.2, -1.5};
  gi_cascade *c = bake(s, at);
  double sum = 0, worst = 0;
  int n = 0;
  gi_error_info err = {0};
  for (int m = 1; m <= 2 * ROOM_STEPS; m++) {
    at[2] += m <= ROOM_STEPS ? 0.05 : -0.05;
    assert_int_equal(gi_cascade_move(c, at, NULL, NULL, &err), GI_OK);
    if (m % ROOM_CHECK) continue;
    gi_cascade *b = bake(s, at);
    double pm[21], pb[21];
    probe_figures(c, at, pm);
    probe_figures(b, at, pb);
    double step_worst = 0;
    for (int i = 0; i < 21; i++) {
      double rel = fabs(pm[i] - pb[i]) / fmax(fabs(pb[i]), 1e-12);
      sum += rel;
      step_worst = fmax(step_worst, rel);
      n++;
    }
    worst = fmax(worst, step_worst);
    printf("room walk: call %d at z = %.2f: largest relative difference %.4f\n", m, at[2], step_worst);
    gi_cascade_free(b);
  }
  printf("room walk: probe against cold bakes: mean %.4f max %.4f relative (bounds %.4f, %.3f)\n", sum / n, worst,
         ROOM_MEAN_BOUND, ROOM_MAX_BOUND);
  assert_true(sum / n <= ROOM_MEAN_BOUND);
  assert_true(worst <= ROOM_MAX_BOUND);
  gi_cascade_free(c);
  gi_scene_release(s);
}

/* Crossings right after a closed re-bake (each voxel's own last
 * increment known: move.c, keep_last, own_gain) in bakes with the bounce
 * tail: the lit room (its plan's tail, about 9x the last increment) and
 * the test city (3 bounces and the tail asked for). Each step moves one
 * anchor cell (2 finest voxels) and then rests until the re-bake closes;
 * the probe right after each crossing against a cold bake there.
 * Measured: room mean 0.0009, max 0.0104; city 0.0006 / 0.0038. While a
 * tail made the fresh gather read the whole texture (99fc4d8 to 3da0b34):
 * room 0.0010 / 0.0090, city 0.0007 / 0.0038: on cascades this small the
 * two forms agree, and the walk bench (600 m city, default quality) is
 * where they part (docs/experiments.md). Bounds 1.5x the measured figures.
 * As test_probe_drift's, they fit this seed: over 8 injection seeds the
 * city read max 0.0035-0.0196 and mean 0.0006-0.0010 (5d6c999). */
#define CLOSED_STEPS 12
static const double CLOSED_MEAN_BOUND[2] = {0.0014, 0.0009}, CLOSED_MAX_BOUND[2] = {0.016, 0.0057};
static void test_closed_crossings(void **state) {
  gi_city_params cp = {.seed = 3, .extent = 300};
  gi_scene *scenes[2] = {tu_lit_room(0.6f), city(&cp)};
  /* The room's plan adds the tail; the test city's asks for it. */
  gi_quality q[2] = {SMALL, SMALL};
  q[1].bounces = 3, q[1].bounce_tail = 1;
  for (int v = 0; v < 2; v++) {
    double at[3] = {0.1, 1.2, -1.5};
    if (v) gi_city_default_viewpoint(&cp, at);
    gi_cascade *c = NULL;
    gi_error_info err = {0};
    assert_int_equal(gi_cascade_bake(scenes[v], at, &q[v], &c, NULL, &err), GI_OK);
    assert_true(c->tail);
    double step = 2 * c->s0, sum = 0, worst = 0; /* an anchor cell: every step crosses */
    int n = 0;
    for (int m = 0; m <= CLOSED_STEPS; m++) {
      gi_move_info mi = {0};
      at[v ? 0 : 2] += step;
      assert_int_equal(gi_cascade_move(c, at, NULL, &mi, &err), GI_OK);
      /* The first crossing follows the cold bake: no re-bake has closed. */
      if (m) {
        gi_cascade *b = NULL;
        assert_int_equal(gi_cascade_bake(scenes[v], at, &q[v], &b, NULL, &err), GI_OK);
        double pm[21], pb[21];
        probe_figures(c, at, pm);
        probe_figures(b, at, pb);
        for (int i = 0; i < 21; i++) {
          double rel = fabs(pm[i] - pb[i]) / fmax(fabs(pb[i]), 1e-12);
          sum += rel, worst = fmax(worst, rel), n++;
        }
        gi_cascade_free(b);
      }
      for (int rest = 0; rest < 1024 && !mi.cycle_closed; rest++)
        assert_int_equal(gi_cascade_move(c, at, NULL, &mi, &err), GI_OK);
      assert_true(mi.cycle_closed);
    }
    printf("%s: crossings after a closed re-bake: probe against cold bakes: mean %.4f max %.4f relative "
           "(bounds %.4f, %.4f)\n", v ? "city" : "room", sum / n, worst, CLOSED_MEAN_BOUND[v], CLOSED_MAX_BOUND[v]);
    assert_true(sum / n <= CLOSED_MEAN_BOUND[v]);
    assert_true(worst <= CLOSED_MAX_BOUND[v]);
    gi_cascade_free(c);
    gi_scene_release(scenes[v]);
  }
}

/* A move refilters only the nested cells above what changed: after every
 * move of a drive and of a sideways walk, a full refilter changes no texel. */
#define REFILTER_MOVES 40
static void test_refilter_exact(void **state) {
  gi_city_params cp = {.seed = 3, .extent = 300};
  gi_scene *s = city(&cp);
  const double steps[2][3] = {{DRIVE_SPEED / STEP_HZ, 0, 0}, {0.3, 0.05, 0.9}};
  for (int v = 0; v < 2; v++) {
    double at[3];
    gi_city_default_viewpoint(&cp, at);
    gi_cascade *c = bake(s, at);
    size_t vox = (size_t)c->R * c->R * c->R;
    gi_vrad *before = gi__malloc(vox * sizeof *before);
    assert_non_null(before);
    gi_error_info err = {0};
    for (int m = 0; m < REFILTER_MOVES; m++) {
      for (int a = 0; a < 3; a++) at[a] += steps[v][a];
      assert_int_equal(gi_cascade_move(c, at, NULL, NULL, &err), GI_OK);
      for (int d = 1; d < c->n; d++) {
        memcpy(before, c->lv[d].rad, vox * sizeof *before);
        const int64_t *lo = c->lv[d].inner0, *hi = c->lv[d].inner1;
        assert_int_equal(gi__cascade_filter_box(c, 2, d, lo, hi), 0);
        assert_true(memcmp(before, c->lv[d].rad, vox * sizeof *before) == 0);
      }
    }
    gi__free(before);
    gi_cascade_free(c);
  }
  gi_scene_release(s);
}

/* Bad viewpoints are refused and leave the cascade as it was. */
static void test_bad_viewpoint(void **state) {
  gi_city_params cp = {.seed = 3, .extent = 300};
  gi_scene *s = city(&cp);
  double at[3];
  gi_city_default_viewpoint(&cp, at);
  gi_cascade *c = bake(s, at);
  gi_error_info err = {0};
  double nan_at[3] = {NAN, 0, 0}, far_at[3] = {2e9, 0, 0};
  assert_int_equal(gi_cascade_move(c, nan_at, NULL, NULL, &err), GI_ERR_NONFINITE);
  assert_int_equal(gi_cascade_move(c, far_at, NULL, NULL, &err), GI_ERR_INVALID_ARG);
  assert_int_equal(gi_cascade_move(NULL, at, NULL, NULL, &err), GI_ERR_INVALID_ARG);
  gi_cascade *b = bake(s, at);
  assert_same_geometry(c, b);
  gi_cascade_free(b);
  gi_cascade_free(c);
  gi_scene_release(s);
}

/* The city under 600 more street lamps, so injection samples its point
 * lights through the light cut (scene/local_tree.c): a cut's random picks
 * are seeded by the voxel's global cell like every other sample, so moved
 * voxels equal a cold bake's bit for bit, and the closed cycle equals a
 * cold bake within the walk's bound. */
#define LAMP_MOVES 24
static void test_lamps_move(void **state) {
  (void)state;
  gi_city_params cp = {.seed = 3, .extent = 300};
  gi_light lamps[600];
  uint64_t r = 77;
  memset(lamps, 0, sizeof lamps);
  for (int i = 0; i < 600; i++) {
    lamps[i].type = GI_LIGHT_POINT;
    lamps[i].position[0] = (gi__u01(&r) - 0.5) * 290;
    lamps[i].position[1] = 3 + 3 * gi__u01(&r);
    lamps[i].position[2] = (gi__u01(&r) - 0.5) * 290;
    for (int k = 0; k < 3; k++) lamps[i].color[k] = 20 + 80 * gi__u01(&r);
  }
  gi_scene_options o = {.lights = lamps, .num_lights = 600};
  gi_scene *s = NULL;
  gi_error_info err = {0};
  assert_int_equal(gi_city_build(&cp, &o, &s, &err), GI_OK);
  gi_light_plan lp = gi__light_plan(&(gi_bake_report){.effects[GI_FX_LOCAL].ran = 1}, SMALL.light_samples);
  assert_true(gi__local_by_cut(s, &lp));
  double at[3];
  gi_city_default_viewpoint(&cp, at);
  gi_cascade *c = bake(s, at);
  uint64_t rng = 0x1a3e;
  gi_move_info mi = {0};
  for (int m = 1; m <= LAMP_MOVES; m++) {
    next_point(&cp, c->s0, &rng, at);
    assert_int_equal(gi_cascade_move(c, at, NULL, &mi, &err), GI_OK);
    if (m % 8 == 0) {
      gi_cascade *b = bake(s, at);
      assert_same_geometry(c, b);
      gi_cascade_free(b);
    }
  }
  printf("lamps: last move: slice %d closed %d\n", mi.slice, mi.cycle_closed);
  /* Stand still until the cycle closes (at once when the last move closed it). */
  for (uint64_t i = 0; i < gi_cascade_refresh_period(c, c->n - 1) && !mi.cycle_closed; i++)
    assert_int_equal(gi_cascade_move(c, at, NULL, &mi, &err), GI_OK);
  assert_closed_equals_cold("lamps", c, s, at, &mi);
}

/* Two cascades walked along the same path hold the same bytes at every step
 * (also between cycle ends): the refresh runs on the move clock alone. */
#define DETERMINISM_MOVES 20
static void test_deterministic(void **state) {
  gi_city_params cp = {.seed = 3, .extent = 300};
  gi_scene *s = city(&cp);
  double at[3];
  gi_city_default_viewpoint(&cp, at);
  gi_cascade *a = bake(s, at), *b = bake(s, at);
  uint64_t rng = 0xd373;
  gi_error_info err = {0};
  size_t vox = (size_t)a->R * a->R * a->R;
  /* b moves with a token that never fires: the same bits as without one. */
  gi_cancel *never = gi_cancel_new();
  assert_non_null(never);
  for (int m = 0; m < DETERMINISM_MOVES; m++) {
    next_point(&cp, a->s0, &rng, at);
    assert_int_equal(gi_cascade_move(a, at, NULL, NULL, &err), GI_OK);
    assert_int_equal(gi_cascade_move_ex(b, at, never, NULL, NULL, &err), GI_OK);
    assert_true(a->rad_scale == b->rad_scale);
    for (int d = 0; d < a->n; d++) {
      assert_true(memcmp(a->lv[d].rad, b->lv[d].rad, vox * sizeof *a->lv[d].rad) == 0);
      assert_true(tl_same_entries(&a->lv[d], &b->lv[d], a->R, TL_SIDE));
    }
  }
  gi_cancel_free(never);
  gi_cascade_free(a);
  gi_cascade_free(b);
  gi_scene_release(s);
}

/* gi_cascade_move_prepare: each allocation's failure is GI_ERR_NOMEM with
 * the cascade as it was (no move state); once made, again is a no-op; and
 * a prepared cascade moves to the same bits as one that was not. */
static void test_prepare(void **state) {
  gi_city_params cp = {.seed = 3, .extent = 300};
  gi_scene *s = city(&cp);
  double at[3];
  gi_city_default_viewpoint(&cp, at);
  gi_cascade *a = bake(s, at), *b = bake(s, at);
  gi_error_info err = {0};
  assert_int_equal(gi_cascade_move_prepare(NULL, &err), GI_ERR_INVALID_ARG);
  long n = 0, live0 = gi__alloc_live();
  for (;; n++) {
    gi__alloc_fail_after(n);
    gi_result rc = gi_cascade_move_prepare(b, &err);
    int hit = !gi__alloc_fail_armed();
    gi__alloc_fail_after(-1);
    if (!hit) {
      assert_int_equal(rc, GI_OK);
      break;
    }
    assert_int_equal(rc, GI_ERR_NOMEM);
    assert_null(b->move_state);
    assert_int_equal(gi__alloc_live(), live0); /* nothing kept */
  }
  assert_true(n > 0);
  const void *made = b->move_state;
  assert_true(gi__move_state_bytes(b) > 0);
  assert_int_equal(gi_cascade_move_prepare(b, &err), GI_OK);
  assert_ptr_equal(b->move_state, made);
  uint64_t rng = 0x9e9a;
  size_t vox = (size_t)a->R * a->R * a->R;
  for (int m = 0; m < DETERMINISM_MOVES; m++) {
    next_point(&cp, a->s0, &rng, at);
    assert_int_equal(gi_cascade_move(a, at, NULL, NULL, &err), GI_OK);
    assert_int_equal(gi_cascade_move(b, at, NULL, NULL, &err), GI_OK);
    assert_true(a->rad_scale == b->rad_scale);
    for (int d = 0; d < a->n; d++) assert_true(memcmp(a->lv[d].rad, b->lv[d].rad, vox * sizeof *a->lv[d].rad) == 0);
  }
  gi_cascade_free(a);
  gi_cascade_free(b);
  gi_scene_release(s);
}

/* A move a client stopped: a far move (every level rebuilt, a cold bake's
 * work) with a fired token returns GI_ERR_CANCELLED, saying so; a small
 * one too. The cascade is then partial (placement at the new viewpoint,
 * some levels scrolled, the light stale): every call that reads it is
 * refused saying so (a gather and a retried move returned GI_OK with wrong
 * light, 0.17x a cold bake's indirect light, found by a helper session's
 * probes), gi_cascade_move_prepare too (it said GI_OK), covers answers 0,
 * the refresh period 0 and the view plan every effect off (they read the
 * torn placement, cycle and plan). The
 * next move re-bakes it whole: it then equals a cold bake at that
 * viewpoint (geometry bit for bit, every face within FACE_REL_TOL, the
 * probe equal) and moves on as any cascade; a re-bake cancelled in turn
 * leaves it partial again. */
static void test_cancelled_move(void **state) {
  gi_city_params cp = {.seed = 3, .extent = 300};
  gi_scene *s = city(&cp);
  double at[3];
  gi_city_default_viewpoint(&cp, at);
  gi_cancel *stop = gi_cancel_new();
  assert_non_null(stop);
  gi_cancel_set(stop);
  for (int far = 0; far < 2; far++) {
    gi_cascade *c = bake(s, at);
    assert_int_equal(gi_cascade_move_prepare(c, NULL), GI_OK);
    double to[3] = {at[0] + (far ? 120.0 : 2.5 * c->s0), at[1], at[2] + (far ? 90.0 : 0.0)};
    gi_error_info err = {0};
    gi_result rc = gi_cascade_move_ex(c, to, stop, NULL, NULL, &err);
    printf("cancelled %s move -> %s: %s\n", far ? "far" : "one-cell", gi_err_name(rc), err.msg);
    assert_int_equal(rc, GI_ERR_CANCELLED);
    assert_non_null(strstr(err.msg, "cancel"));
    gi_probe pr;
    float rgb[3 * 4];
    const double *pts = to;
    gi_camera cam = {{to[0], to[1], to[2]}, {to[0] + 1, to[1], to[2]}, {0, 1, 0}, 60, 2, 2};
    gi_error_info e2 = {0};
    assert_int_equal(gi_cascade_gather(c, pts, 1, &pr, NULL, &e2), GI_ERR_INVALID_ARG);
    assert_non_null(strstr(e2.msg, "gather: the cascade is partial"));
    assert_non_null(strstr(e2.msg, "move it again"));
    assert_int_equal(gi_cascade_render(c, &cam, 1, 1, rgb, NULL, &e2), GI_ERR_INVALID_ARG);
    float dir[2 * 1 * 3], ind[2 * 1 * 3];
    assert_int_equal(gi_cascade_panorama(c, to, 2, 1, dir, ind, NULL, &e2), GI_ERR_INVALID_ARG);
    assert_int_equal(gi_cascade_write_vdb(c, "unused.vdb", 0, &e2), GI_ERR_INVALID_ARG);
    e2.msg[0] = 0;
    rc = gi_cascade_move_prepare(c, &e2);
    printf("prepare after it -> %s: %s\n", gi_err_name(rc), e2.msg);
    assert_int_equal(rc, GI_ERR_INVALID_ARG);
    assert_non_null(strstr(e2.msg, "prepare: the cascade is partial"));
    assert_int_equal(gi_cascade_covers(c, to), 0);
    assert_int_equal(gi_cascade_covers(c, at), 0);
    assert_int_equal(gi_cascade_refresh_period(c, 0), 0);
    gi_effect fx[GI_FX_COUNT];
    gi_cascade_view_plan(c, fx);
    for (int i = 0; i < GI_FX_COUNT; i++) assert_false(fx[i].ran);
    assert_non_null(strstr(fx[GI_FX_BOUNCE].why, "partial"));
    /* A re-bake stopped in turn: still partial, still refused. */
    assert_int_equal(gi_cascade_move_ex(c, to, stop, NULL, NULL, &e2), GI_ERR_CANCELLED);
    assert_int_equal(gi_cascade_gather(c, pts, 1, &pr, NULL, &e2), GI_ERR_INVALID_ARG);
    /* Its levels were freed for the re-bake: it holds none now, and says so. */
    printf("after the stopped re-bake: %zu bytes held, report %llu\n", gi_cascade_bytes(c),
           (unsigned long long)gi_cascade_report(c)->cascade_bytes);
    assert_int_equal(gi_cascade_bytes(c), 0);
    assert_int_equal(gi_cascade_report(c)->cascade_bytes, 0);
    /* The next move re-bakes: a cold bake at that viewpoint. */
    double next[3] = {to[0] + 1.5 * c->s0, to[1], to[2]};
    gi_move_info mi;
    gi_bake_report r;
    rc = gi_cascade_move(c, next, &r, &mi, &e2);
    printf("move after it -> %s: %s\n", gi_err_name(rc), rc == GI_OK ? "" : e2.msg);
    assert_int_equal(rc, GI_OK);
    assert_true(mi.cycle_closed);
    assert_int_equal(mi.move, 3);
    for (int d = 0; d < c->n; d++) assert_true(mi.rebuilt[d] && mi.refreshed[d]);
    assert_int_equal(r.cascade_bytes, gi_cascade_bytes(c));
    gi_cascade *b = bake(s, next);
    assert_same_geometry(c, b);
    double mean, worst;
    compare_light(c, b, 1, &mean, &worst);
    gi_probe pm, pb;
    assert_int_equal(gi_cascade_gather(c, next, 1, &pm, NULL, &e2), GI_OK);
    assert_int_equal(gi_cascade_gather(b, next, 1, &pb, NULL, &e2), GI_OK);
    printf("re-baked: light against a cold bake: mean %.3g max %.3g; probe %.6g vs %.6g\n", mean, worst,
           pm.irradiance[1], pb.irradiance[1]);
    for (int k = 0; k < 3; k++)
      assert_true(fabsf(pm.irradiance[k] - pb.irradiance[k]) <= FACE_REL_TOL * pb.irradiance[k]);
    assert_true(gi_cascade_covers(c, next));
    /* And it moves on as a baked cascade does. */
    double on[3] = {next[0] + 2.5 * c->s0, next[1], next[2]};
    assert_int_equal(gi_cascade_move(c, on, NULL, &mi, &e2), GI_OK);
    assert_int_equal(gi_cascade_move_prepare(c, &e2), GI_OK);
    gi_cascade_free(b);
    gi_cascade_free(c);
  }
  gi_cancel_free(stop);
  gi_scene_release(s);
}

/* A move that ran out of memory part way is partial as a cancelled one:
 * refused, then re-baked by the next move (equal to a cold bake there). */
static void test_failed_move(void **state) {
  gi_city_params cp = {.seed = 3, .extent = 300};
  gi_scene *s = city(&cp);
  double at[3];
  gi_city_default_viewpoint(&cp, at);
  for (long n = 0; n < 12; n += 5) {
    gi_cascade *c = bake(s, at);
    assert_int_equal(gi_cascade_move_prepare(c, NULL), GI_OK);
    double to[3] = {at[0] + 2.5 * c->s0, at[1], at[2]};
    gi_error_info err = {0};
    gi__alloc_fail_after(n);
    gi_result rc = gi_cascade_move(c, to, NULL, NULL, &err);
    int hit = !gi__alloc_fail_armed();
    gi__alloc_fail_after(-1);
    printf("move failing allocation %ld -> %s: %s\n", n, gi_err_name(rc), err.msg);
    assert_true(hit);
    assert_int_equal(rc, GI_ERR_NOMEM);
    gi_probe pm, pb;
    assert_int_equal(gi_cascade_gather(c, to, 1, &pm, NULL, &err), GI_ERR_INVALID_ARG);
    assert_int_equal(gi_cascade_move_prepare(c, &err), GI_ERR_INVALID_ARG);
    gi_move_info mi;
    assert_int_equal(gi_cascade_move(c, to, NULL, &mi, &err), GI_OK);
    assert_true(mi.cycle_closed);
    gi_cascade *b = bake(s, to);
    assert_same_geometry(c, b);
    double mean, worst;
    compare_light(c, b, 1, &mean, &worst);
    assert_int_equal(gi_cascade_gather(c, to, 1, &pm, NULL, &err), GI_OK);
    assert_int_equal(gi_cascade_gather(b, to, 1, &pb, NULL, &err), GI_OK);
    assert_memory_equal(pm.irradiance, pb.irradiance, sizeof pm.irradiance);
    gi_cascade_free(b);
    gi_cascade_free(c);
  }
  gi_scene_release(s);
}

/* A closed room [0,4] x [0,3] x [0,4] (y up), lit by the sky and a point
 * light inside: from inside the plan skips the sky, from above the roof it
 * runs it, so moving in and out changes the lights of every voxel. */
static gi_scene *closed_room(void) {
  gi_mesh_builder *b = gi_mesh_builder_new();
  gi_material m = {.albedo = {0.6f, 0.6f, 0.6f}, .roughness = 1};
  uint32_t mat = gi_mesh_builder_add_material(b, &m);
  const double W = 4, H = 3;
  double f[4][3] = {{0, 0, 0}, {W, 0, 0}, {W, 0, W}, {0, 0, W}};
  gi_mesh_builder_add_quad(b, f[0], f[1], f[2], f[3], mat);
  for (int i = 0; i < 4; i++) {
    const double *p = f[i], *q = f[(i + 1) % 4];
    double top_p[3] = {p[0], H, p[2]}, top_q[3] = {q[0], H, q[2]};
    gi_mesh_builder_add_quad(b, p, q, top_q, top_p, mat);
  }
  double c[4][3] = {{0, H, 0}, {W, H, 0}, {W, H, W}, {0, H, W}};
  gi_mesh_builder_add_quad(b, c[0], c[1], c[2], c[3], mat);
  gi_light l[2] = {{.type = GI_LIGHT_SKY, .color = {1, 1, 1}},
                   {.type = GI_LIGHT_POINT, .color = {5, 5, 5}, .position = {1, 2, 1}}};
  gi_scene_options opt = {.up = GI_UP_Y, .lights = l, .num_lights = 2};
  gi_scene *s = NULL;
  gi_error_info err = {0};
  assert_int_equal(gi_scene_build(b, "closed room", &opt, &s, &err), GI_OK);
  gi_mesh_builder_free(b);
  return s;
}

/* A move that changes the effect plan's lights re-injects every voxel; the
 * geometry and direct light then equal a cold bake's, and after the cycle
 * closes so does every face. */
static void test_relit(void **state) {
  gi_scene *s = closed_room();
  gi_quality q = {.levels = 3, .res = 16, .voxel0 = 0.05, .light_samples = 8, .probe_samples = 16, .threads = 2};
  const double inside[3] = {2.03, 1.5, 2.03}, above[3] = {2.03, 4.5, 2.03};
  const double *path[2] = {above, inside};
  gi_cascade *c = NULL;
  gi_bake_report r;
  gi_error_info err = {0};
  assert_int_equal(gi_cascade_bake(s, inside, &q, &c, &r, &err), GI_OK);
  assert_false(r.effects[GI_FX_SKY].ran);
  for (int i = 0; i < 2; i++) {
    gi_move_info mi;
    assert_int_equal(gi_cascade_move(c, path[i], &r, &mi, &err), GI_OK);
    assert_true(mi.relit);
    /* Every voxel was re-lit: the move re-bakes at once. */
    assert_true(mi.cycle_closed);
    assert_int_equal(r.effects[GI_FX_SKY].ran, path[i] == above);
    gi_cascade *b = NULL;
    assert_int_equal(gi_cascade_bake(s, path[i], &q, &b, NULL, &err), GI_OK);
    assert_same_geometry(c, b);
    double mean, worst;
    compare_light(c, b, 1, &mean, &worst);
    gi_cascade_free(b);
  }
  gi_cascade_free(c);
  gi_scene_release(s);
}

/* A crossing keeps the bake's bounce count. In the closed white furnace
 * (test_furnace.c) with B = 2 explicit bounces a probe's indirect light is
 * exactly Le (a + a^2 + a^3). Moving 0.1 along x brings the wall at x = 1
 * into level 2's window: its voxels are new there, and they and their
 * neighbours are gathered. Gathered from the live texture, which holds
 * all three orders, they got a fourth (a^4 = 0.41 Le at a = 0.8): the
 * probe's indirect light read 3.20% over a cold bake at the same anchor
 * (measured with the fresh texture's order and prime switched off). The
 * fresh texture (move.c) takes the last bounce's order off: measured
 * +0.07%; the bound is 0.5%. */
static void test_crossing_orders(void **state) {
  const double a = 0.8, Le = 1.0;
  gi_scene *sc = tu_furnace_scene(1.0, a, Le);
  gi_quality q = {.levels = 4, .res = 32, .voxel0 = 1.25 / (32 * 4), .bounces = 2, .light_samples = 64,
                  .probe_samples = 8192, .seed = 1};
  double at[3] = {0.3, 0.5, 0.5}, to[3] = {0.4, 0.5, 0.5}, pt[3] = {0.43, 0.55, 0.47};
  gi_cascade *c = NULL, *cold = NULL;
  gi_error_info err = {0};
  assert_int_equal(gi_cascade_bake(sc, at, &q, &c, NULL, &err), GI_OK);
  assert_int_equal(gi_cascade_bake(sc, to, &q, &cold, NULL, &err), GI_OK);
  gi_move_info mi;
  assert_int_equal(gi_cascade_move(c, to, NULL, &mi, &err), GI_OK);
  assert_false(mi.cycle_closed);
  uint64_t gathered = total(c->report.level_rebounced, c->n);
  gi_probe pm, pc;
  assert_int_equal(gi_cascade_gather(c, pt, 1, &pm, NULL, &err), GI_OK);
  assert_int_equal(gi_cascade_gather(cold, pt, 1, &pc, NULL, &err), GI_OK);
  double im = 0, ic = 0;
  for (int k = 0; k < 3; k++) im += (pm.irradiance[k] - pm.direct[k]) / 3, ic += (pc.irradiance[k] - pc.direct[k]) / 3;
  double exact = GI_PI * Le * (a + a * a + a * a * a);
  printf("furnace crossing: %llu voxels gathered; indirect/pi moved %.5f, cold bake %.5f (%+.4f), exact %.5f\n",
         (unsigned long long)gathered, im / GI_PI, ic / GI_PI, (im - ic) / ic, exact / GI_PI);
  assert_true(gathered > 0);
  assert_true(fabs(ic - exact) <= 0.015 * exact); /* test_furnace's bound */
  assert_true(fabs(im - ic) <= 0.005 * ic);
  gi_cascade_free(c);
  gi_cascade_free(cold);
  gi_scene_release(sc);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_cost),
      cmocka_unit_test(test_bad_viewpoint),
      cmocka_unit_test(test_deterministic),
      cmocka_unit_test(test_prepare),
      cmocka_unit_test(test_cancelled_move),
      cmocka_unit_test(test_failed_move),
      cmocka_unit_test(test_relit),
      cmocka_unit_test(test_walk),
      cmocka_unit_test(test_walk_scenes),
      cmocka_unit_test(test_wide_bounce_cycle),
      cmocka_unit_test(test_bounded),
      cmocka_unit_test(test_refilter_exact),
      cmocka_unit_test(test_moving_cycle),
      cmocka_unit_test(test_probe_drift),
      cmocka_unit_test(test_room_fast_walk),
      cmocka_unit_test(test_closed_crossings),
      cmocka_unit_test(test_crossing_orders),
      cmocka_unit_test(test_lamps_move),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
