/* test_anchor.c: equal anchors give bit-identical cascades.
 *
 * gi_cascade_anchor is the server's cache key: every viewpoint inside one
 * anchor cell (the 2 s0 cell that places level 0) must bake the same
 * cascade, bit for bit. For points spread over one cell (its eight corners
 * pulled in by a thousandth of the cell, its centre, and random points) the
 * test asserts equal anchors, then bakes each and compares the effect plan
 * (ran and why), the report's placement and counters, every level's
 * geometry, radiance, irradiance and direct arrays byte for byte, and a
 * probe gathered at one fixed point. Points just across each face of the
 * cell get another anchor.
 *   the procedural city: the sky test runs in a street between houses;
 *   a room with a small skylight right above the cell: before the plan's
 *     sky rays started at the snapped cell, some points of one cell saw the
 *     sky through it and others did not, so the plan (and the sky light
 *     injected) depended on the exact viewpoint. */
#include "test_util.h"
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "cascade/cascade_internal.h"
#include "gi/gi.h"
#include "gi/gi_city.h"
#include "test_levels.h"

#define NUM_RANDOM 4             /* random points per cell, besides corners and centre */
#define NUM_POINTS (8 + 1 + NUM_RANDOM)
#define CORNER_INSET 1e-3        /* corners pulled in by this fraction of the cell */
#define SKYLIGHT_SIDE 0.05       /* metres: small enough that sky visibility varies within a cell */

/* World bounds of anchor cell A along each axis: [lo, hi). */
static void cell_bounds(const gi_scene *s, const gi_quality *q, const int64_t A[3], double lo[3], double hi[3]) {
  double w = 2.0 * q->voxel0;
  for (int a = 0; a < 3; a++) {
    lo[a] = s->origin[a] + (double)A[a] * w;
    hi[a] = s->origin[a] + (double)(A[a] + 1) * w;
  }
}

/* NUM_POINTS points inside the anchor cell of `at`: corners pulled in,
 * the centre, then seeded random points. */
static void points_in_cell(const gi_scene *s, const gi_quality *q, const double at[3], double pts[NUM_POINTS][3],
                           int64_t A[3]) {
  gi_error_info err = {0};
  assert_int_equal(gi_cascade_anchor(s, at, q, A, &err), GI_OK);
  double lo[3], hi[3];
  cell_bounds(s, q, A, lo, hi);
  for (int i = 0; i < 8; i++)
    for (int a = 0; a < 3; a++) {
      double in = CORNER_INSET * (hi[a] - lo[a]);
      pts[i][a] = (i >> a) & 1 ? hi[a] - in : lo[a] + in;
    }
  for (int a = 0; a < 3; a++) pts[8][a] = 0.5 * (lo[a] + hi[a]);
  uint64_t rng = 0xa11c0de;
  for (int i = 9; i < NUM_POINTS; i++)
    for (int a = 0; a < 3; a++) {
      double u = 0.01 + 0.98 * gi__u01(&rng);
      pts[i][a] = lo[a] + u * (hi[a] - lo[a]);
    }
}

/* Points just across each face of the cell land in the neighbouring cell. */
static void assert_neighbours_differ(const gi_scene *s, const gi_quality *q, const int64_t A[3]) {
  double lo[3], hi[3];
  cell_bounds(s, q, A, lo, hi);
  gi_error_info err = {0};
  for (int a = 0; a < 3; a++)
    for (int side = 0; side < 2; side++) {
      double p[3], in = CORNER_INSET * (hi[a] - lo[a]);
      for (int k = 0; k < 3; k++) p[k] = 0.5 * (lo[k] + hi[k]);
      p[a] = side ? hi[a] + in : lo[a] - in;
      int64_t B[3];
      assert_int_equal(gi_cascade_anchor(s, p, q, B, &err), GI_OK);
      for (int k = 0; k < 3; k++) assert_true(B[k] == A[k] + (k == a ? (side ? 1 : -1) : 0));
    }
}

static void assert_same_report(const gi_bake_report *a, const gi_bake_report *b) {
  for (int i = 0; i < GI_FX_COUNT; i++) {
    assert_int_equal(a->effects[i].ran, b->effects[i].ran);
    assert_string_equal(a->effects[i].why, b->effects[i].why);
  }
  assert_int_equal(a->levels, b->levels);
  assert_memory_equal(a->voxel_size, b->voxel_size, sizeof a->voxel_size);
  assert_memory_equal(a->level_origin, b->level_origin, sizeof a->level_origin);
  assert_memory_equal(a->occupied, b->occupied, sizeof a->occupied);
  assert_true(a->triangles_visited == b->triangles_visited);
  assert_true(a->shadow_rays == b->shadow_rays);
  assert_true(a->cone_samples == b->cone_samples);
  assert_int_equal(a->bounces_run, b->bounces_run);
  assert_int_equal(a->glossy_triangles, b->glossy_triangles);
  assert_int_equal(a->quality.bounces, b->quality.bounces);
}

/* Every per-voxel array the stages fill, level by level, byte for byte. */
static void assert_same_levels(const gi_cascade *a, const gi_cascade *b) {
  assert_int_equal(a->n, b->n);
  assert_int_equal(a->R, b->R);
  size_t vox = (size_t)a->R * a->R * a->R;
  for (int d = 0; d < a->n; d++) {
    const gi_level *A = &a->lv[d], *B = &b->lv[d];
    assert_memory_equal(A->cell0, B->cell0, sizeof A->cell0);
    assert_true(tl_same_entries(A, B, a->R, TL_GEO | TL_SIDE | TL_DIRECT));
    assert_true(memcmp(A->rad, B->rad, vox * sizeof *A->rad) == 0);
    assert_true(memcmp(A->busy, B->busy, vox) == 0);
    assert_int_equal(A->num_occ, B->num_occ);
  }
}

/* Bakes at every point of at's anchor cell and compares each cascade with
 * the first; returns how many bakes ran the sky (for the caller's checks). */
static int assert_cell_bakes_identical(const gi_scene *s, const double at[3], const gi_quality *req,
                                       const double probe_at[3], const char *label) {
  gi_quality q;
  gi_error_info err = {0};
  assert_int_equal(gi_quality_resolve(s, req, &q, &err), GI_OK);
  double pts[NUM_POINTS][3];
  int64_t A[3];
  points_in_cell(s, &q, at, pts, A);
  assert_neighbours_differ(s, &q, A);
  gi_cascade *first = NULL;
  gi_probe p0;
  int sky = 0;
  for (int i = 0; i < NUM_POINTS; i++) {
    int64_t B[3];
    assert_int_equal(gi_cascade_anchor(s, pts[i], &q, B, &err), GI_OK);
    assert_memory_equal(A, B, sizeof A);
    gi_cascade *c = NULL;
    gi_result rc = gi_cascade_bake(s, pts[i], req, &c, NULL, &err);
    if (rc != GI_OK) fprintf(stderr, "bake: %s\n", err.msg);
    assert_int_equal(rc, GI_OK);
    gi_probe p;
    assert_int_equal(gi_cascade_gather(c, probe_at, 1, &p, NULL, &err), GI_OK);
    const gi_bake_report *r = gi_cascade_report(c);
    sky += r->effects[GI_FX_SKY].ran;
    if (i == 0) {
      printf("%s: anchor (%lld, %lld, %lld), sky %s (%s), probe irradiance %.6g\n", label, (long long)A[0],
             (long long)A[1], (long long)A[2], r->effects[GI_FX_SKY].ran ? "ran" : "skipped",
             r->effects[GI_FX_SKY].why, p.irradiance[1]);
      first = c;
      p0 = p;
      continue;
    }
    assert_same_report(gi_cascade_report(first), r);
    assert_same_levels(first, c);
    assert_memory_equal(&p0, &p, sizeof p);
    gi_cascade_free(c);
  }
  gi_cascade_free(first);
  return sky;
}

static void test_city_cell(void **state) {
  gi_city_params cp = {.seed = 3, .extent = 300};
  gi_scene *s = NULL;
  gi_error_info err = {0};
  assert_int_equal(gi_city_build(&cp, NULL, &s, &err), GI_OK);
  double at[3];
  gi_city_default_viewpoint(&cp, at);
  gi_quality q = {.levels = 3, .res = 16, .light_samples = 4, .probe_samples = 64, .threads = 2};
  int sky = assert_cell_bakes_identical(s, at, &q, at, "city");
  /* A street between houses sees the sky. */
  assert_int_equal(sky, NUM_POINTS);
  gi_scene_release(s);
}

/* A closed room [0,4] x [0,3] x [0,4] (y up) with a square skylight of side
 * `hole` in the ceiling, centred over (hx, hz), lit by the sky and a point
 * light in a corner (so the walls carry bounce light either way). */
static gi_scene *skylight_room(double hole, double hx, double hz) {
  gi_mesh_builder *b = gi_mesh_builder_new();
  gi_material m = {.albedo = {0.6f, 0.6f, 0.6f}, .roughness = 1};
  uint32_t mat = gi_mesh_builder_add_material(b, &m);
  const double W = 4, H = 3;
  double x0 = hx - hole / 2, x1 = hx + hole / 2, z0 = hz - hole / 2, z1 = hz + hole / 2;
  /* Floor and walls. */
  double f[4][3] = {{0, 0, 0}, {W, 0, 0}, {W, 0, W}, {0, 0, W}};
  gi_mesh_builder_add_quad(b, f[0], f[1], f[2], f[3], mat);
  for (int i = 0; i < 4; i++) {
    const double *p = f[i], *q = f[(i + 1) % 4];
    double top_p[3] = {p[0], H, p[2]}, top_q[3] = {q[0], H, q[2]};
    gi_mesh_builder_add_quad(b, p, q, top_q, top_p, mat);
  }
  /* The ceiling in four pieces around the hole. */
  const double piece[4][4] = {{0, 0, W, z0}, {0, z1, W, W}, {0, z0, x0, z1}, {x1, z0, W, z1}};
  for (int i = 0; i < 4; i++) {
    double a[3] = {piece[i][0], H, piece[i][1]}, bb[3] = {piece[i][2], H, piece[i][1]};
    double c[3] = {piece[i][2], H, piece[i][3]}, d[3] = {piece[i][0], H, piece[i][3]};
    gi_mesh_builder_add_quad(b, a, bb, c, d, mat);
  }
  gi_light l[2] = {{.type = GI_LIGHT_SKY, .color = {1, 1, 1}},
                   {.type = GI_LIGHT_POINT, .color = {5, 5, 5}, .position = {1, 2, 1}}};
  gi_scene_options opt = {.up = GI_UP_Y, .lights = l, .num_lights = 2};
  gi_scene *s = NULL;
  gi_error_info err = {0};
  assert_int_equal(gi_scene_build(b, "skylight", &opt, &s, &err), GI_OK);
  gi_mesh_builder_free(b);
  return s;
}

static void test_skylight_cell(void **state) {
  gi_quality q = {.levels = 3, .res = 16, .voxel0 = 0.05, .light_samples = 8, .probe_samples = 64, .threads = 2};
  const double at[3] = {2.03, 2.5, 2.03}, probe_at[3] = {2.2, 2.3, 1.9};
  /* A 5 cm skylight 0.5 m above the cell: with the sky rays starting at the
   * raw viewpoint, about half of the points of one cell saw it. */
  gi_scene *s = skylight_room(SKYLIGHT_SIDE, 2.0, 2.0);
  assert_cell_bakes_identical(s, at, &q, probe_at, "skylight room");
  gi_scene_release(s);
}

/* The plan still tells a closed room from an open one: the same room with
 * the skylight shut runs no sky, with a wide one it does. */
static void test_skylight_sensitivity(void **state) {
  gi_quality q = {.levels = 2, .res = 16, .voxel0 = 0.05, .light_samples = 8, .probe_samples = 64, .threads = 2};
  const double at[3] = {2.03, 2.5, 2.03};
  gi_scene *shut = skylight_room(0.0, 2.0, 2.0), *open = skylight_room(1.0, 2.0, 2.0);
  gi_effect fx[GI_FX_COUNT];
  gi_error_info err = {0};
  assert_int_equal(gi_effect_plan(shut, at, &q, fx, NULL, &err), GI_OK);
  printf("skylight shut: sky %s (%s)\n", fx[GI_FX_SKY].ran ? "ran" : "skipped", fx[GI_FX_SKY].why);
  assert_false(fx[GI_FX_SKY].ran);
  assert_int_equal(gi_effect_plan(open, at, &q, fx, NULL, &err), GI_OK);
  printf("skylight 1 m: sky %s (%s)\n", fx[GI_FX_SKY].ran ? "ran" : "skipped", fx[GI_FX_SKY].why);
  assert_true(fx[GI_FX_SKY].ran);
  gi_scene_release(shut);
  gi_scene_release(open);
}

/* The server admits a bake by gi_cascade_bytes_estimate before it runs: the
 * estimate is the most a baked cascade can hold, levels x res^3 x (the
 * dense arrays rad, vix, occ, busy and one entry of geo, side, direct and
 * freed), as if every voxel held geometry. A bake then holds the dense
 * arrays and exactly one entry per voxel holding geometry (own or nested)
 * plus each level's empty entry 0. */
static void test_bytes_estimate(void **state) {
  (void)state;
  gi_city_params cp = {.seed = 3, .extent = 300};
  gi_scene *s = NULL;
  gi_error_info err = {0};
  assert_int_equal(gi_city_build(&cp, NULL, &s, &err), GI_OK);
  double at[3];
  gi_city_default_viewpoint(&cp, at);
  const size_t dense = sizeof(gi_vrad) + 4 + 4 + 1;
  const size_t entry = sizeof(gi_vgeo) + 2 * sizeof(gi_faces3) + 4;
  const int shapes[][2] = {{2, 8}, {3, 16}, {4, 12}};
  for (size_t i = 0; i < sizeof shapes / sizeof shapes[0]; i++) {
    gi_quality req = {.levels = shapes[i][0], .res = shapes[i][1], .light_samples = 4, .probe_samples = 16,
                      .threads = 2},
               q;
    assert_int_equal(gi_quality_resolve(s, &req, &q, &err), GI_OK);
    size_t est = gi_cascade_bytes_estimate(&q);
    size_t vox = (size_t)q.res * q.res * q.res;
    size_t want_est = (size_t)q.levels * (vox * (dense + entry) + entry);
    gi_cascade *c = NULL;
    assert_int_equal(gi_cascade_bake(s, at, &req, &c, NULL, &err), GI_OK);
    const gi_bake_report *r = gi_cascade_report(c);
    size_t want = (size_t)q.levels * vox * dense, holding = 0;
    for (int d = 0; d < q.levels; d++) {
      want += (r->occupied[d] + 1) * entry;
      holding += r->occupied[d];
    }
    printf("levels %d res %d: estimate %zu bytes, baked %zu (%zu of %zu voxels hold geometry)\n", q.levels, q.res,
           est, gi_cascade_bytes(c), holding, q.levels * vox);
    assert_true(holding > 0 && holding < q.levels * vox);
    assert_true(est == want_est);
    assert_true(gi_cascade_bytes(c) == want);
    assert_true(est > gi_cascade_bytes(c));
    assert_true(r->cascade_bytes == gi_cascade_bytes(c));
    gi_cascade_free(c);
  }
  gi_quality unresolved = {0};
  assert_true(gi_cascade_bytes_estimate(&unresolved) == 0);
  assert_true(gi_cascade_bytes_estimate(NULL) == 0);
  gi_scene_release(s);
}

/* gi_cascade_cell_centre inverts gi_cascade_anchor: the centre of cell A
 * is origin + (A + 1/2) 2 s0, snaps back to A, and a cell too far for the
 * float snapping is refused rather than answered with another cell. */
static void test_cell_centre(void **state) {
  (void)state;
  gi_city_params cp = {.seed = 3, .extent = 300};
  gi_scene *s = NULL;
  gi_error_info err = {0};
  assert_int_equal(gi_city_build(&cp, NULL, &s, &err), GI_OK);
  gi_quality req = {.levels = 3, .res = 16}, q;
  assert_int_equal(gi_quality_resolve(s, &req, &q, &err), GI_OK);
  double org[3];
  gi_scene_origin(s, org);
  for (int a = 0; a < 3; a++) assert_true(org[a] == s->origin[a]);
  const int64_t cells[][3] = {{0, 0, 0}, {-1, -1, -1}, {2, -5, 7}, {-25, 3, 40}, {1000, -1000, 123}};
  for (size_t i = 0; i < sizeof cells / sizeof cells[0]; i++) {
    double c[3], lo[3], hi[3];
    int64_t back[3];
    assert_int_equal(gi_cascade_cell_centre(s, cells[i], &q, c, &err), GI_OK);
    cell_bounds(s, &q, cells[i], lo, hi);
    assert_int_equal(gi_cascade_anchor(s, c, &q, back, &err), GI_OK);
    for (int a = 0; a < 3; a++) {
      assert_true(c[a] == 0.5 * (lo[a] + hi[a]));
      assert_true(back[a] == cells[i][a]);
    }
  }
  const int64_t far[3] = {((int64_t)1 << 40) + 1, 0, 0}; /* float spacing there: many cells */
  double c[3];
  assert_int_equal(gi_cascade_cell_centre(s, far, &q, c, &err), GI_ERR_INVALID_ARG);
  assert_non_null(strstr(err.msg, "too far"));
  gi_quality unresolved = {0};
  assert_int_equal(gi_cascade_cell_centre(s, cells[0], &unresolved, c, &err), GI_ERR_INVALID_ARG);
  /* A voxel far too small for the viewpoint's distance: refused, where the
   * cell index wrapped to INT64_MIN (a server's 307 to a cell of no cascade). */
  gi_quality tiny_req = {.levels = 3, .res = 16, .voxel0 = 1e-300}, tiny;
  assert_int_equal(gi_quality_resolve(s, &tiny_req, &tiny, &err), GI_OK);
  const double at[3] = {org[0] + 50, org[1] + 2, org[2] - 30};
  int64_t cell[3];
  assert_int_equal(gi_cascade_anchor(s, at, &tiny, cell, &err), GI_ERR_INVALID_ARG);
  assert_non_null(strstr(err.msg, "voxel size 1e-300 is too small"));
  gi_cascade *cc = NULL;
  assert_int_equal(gi_cascade_bake(s, at, &tiny_req, &cc, NULL, &err), GI_ERR_INVALID_ARG);
  assert_null(cc);
  assert_non_null(strstr(err.msg, "voxel size 1e-300 is too small"));
  /* 2^50 voxels away is still addressed. */
  tiny_req.voxel0 = 30.0 / (double)(1ull << 51);
  assert_int_equal(gi_quality_resolve(s, &tiny_req, &tiny, &err), GI_OK);
  assert_int_equal(gi_cascade_anchor(s, at, &tiny, cell, &err), GI_OK);
  gi_scene_release(s);
}

/* gi_cascade_would_cover, asked before a bake, answers what
 * gi_cascade_covers answers after it, point by point, from viewpoints
 * in the middle, at the edges and corners and above the roofs of a city,
 * for points over a box half again as wide as the city. Only the finest
 * level is centred on the viewpoint; the coarser ones lean toward the
 * scene, so the points a reach measured from the viewpoint (as if every
 * level were centred) gets wrong must turn up both ways: covered beyond
 * that reach and uncovered within it. */
static void test_would_cover(void **state) {
  (void)state;
  gi_city_params cp = {.seed = 3, .extent = 300};
  gi_scene *s = NULL;
  gi_error_info err = {0};
  assert_int_equal(gi_city_build(&cp, NULL, &s, &err), GI_OK);
  double lo[3], hi[3];
  gi_scene_bounds(s, lo, hi);
  gi_quality req = {.levels = 3, .res = 16, .light_samples = 1, .probe_samples = 1, .bounces = -1, .threads = 2}, q;
  assert_int_equal(gi_quality_resolve(s, &req, &q, &err), GI_OK);
  const double views[][3] = {{0, 2, 0}, {140, 2, 0}, {-145, 2, -145}, {0, 60, 148}, {-100, 130, 30}, {149, 2, 149}};
  enum { NPTS = 400 };
  static double pts[NPTS][3];
  uint8_t before[NPTS];
  uint64_t rng = 0xc0ffee;
  int beyond_but_covered = 0, within_but_not = 0, covered_all = 0, outside_all = 0;
  double reach = (q.res / 2 - 2) * q.voxel0 * (double)(1ull << (q.levels - 1));
  for (size_t v = 0; v < sizeof views / sizeof views[0]; v++) {
    for (int i = 0; i < NPTS; i++)
      for (int a = 0; a < 3; a++) {
        double mid = 0.5 * (lo[a] + hi[a]), half = 0.75 * (hi[a] - lo[a]);
        pts[i][a] = mid + (2 * gi__u01(&rng) - 1) * half;
      }
    size_t held = 0;
    assert_int_equal(gi_cascade_would_cover(s, views[v], &q, &pts[0][0], NPTS, before, &held, &err), GI_OK);
    gi_cascade *c = NULL;
    assert_int_equal(gi_cascade_bake(s, views[v], &req, &c, NULL, &err), GI_OK);
    size_t count = 0;
    for (int i = 0; i < NPTS; i++) {
      int after = gi_cascade_covers(c, pts[i]);
      assert_int_equal(before[i], after);
      count += (size_t)after;
      double d = 0;
      for (int a = 0; a < 3; a++) d = fmax(d, fabs(pts[i][a] - views[v][a]));
      beyond_but_covered += after && d > reach;
      within_but_not += !after && d <= reach;
    }
    assert_true(held == count);
    covered_all += (int)count, outside_all += NPTS - (int)count;
    gi_cascade_free(c);
  }
  printf("would_cover: %d points covered, %d not; against a centred reach of %g: %d covered beyond it, %d not "
         "covered within it\n", covered_all, outside_all, reach, beyond_but_covered, within_but_not);
  assert_true(covered_all > 0 && outside_all > 0);
  assert_true(beyond_but_covered > 0 && within_but_not > 0);
  /* A non-finite point is not covered; a refused viewpoint or quality fails as the bake does. */
  double odd[2][3] = {{0, 2, 0}, {NAN, 2, 0}};
  assert_int_equal(gi_cascade_would_cover(s, views[0], &q, &odd[0][0], 2, before, NULL, &err), GI_OK);
  assert_true(before[0] == 1 && before[1] == 0);
  const double nan_at[3] = {NAN, 2, 0};
  assert_int_equal(gi_cascade_would_cover(s, nan_at, &q, &odd[0][0], 1, NULL, NULL, &err), GI_ERR_NONFINITE);
  gi_quality unresolved = {0};
  assert_int_equal(gi_cascade_would_cover(s, views[0], &unresolved, &odd[0][0], 1, NULL, NULL, &err),
                   GI_ERR_INVALID_ARG);
  assert_non_null(strstr(err.msg, "not a resolved quality"));
  gi_scene_release(s);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_city_cell),
      cmocka_unit_test(test_skylight_cell),
      cmocka_unit_test(test_skylight_sensitivity),
      cmocka_unit_test(test_bytes_estimate),
      cmocka_unit_test(test_cell_centre),
      cmocka_unit_test(test_would_cover),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
