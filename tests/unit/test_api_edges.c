/* test_api_edges.c: the public API called as a careless program would:
 * NULL where no NULL is allowed, sizes no memory holds, values out of
 * range. Each call must fail with a gi_result whose message names the
 * argument, never crash or answer quietly from garbage. Scenes are a small
 * room made in code, baked at the lowest quality. */
#include "test_util.h"
#include "base/alloc_test.h"
#include <limits.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "gi/gi.h"

static gi_scene *room(void) {
  gi_mesh_builder *b = gi_mesh_builder_new();
  gi_material m = {{0.7f, 0.7f, 0.7f}, {0}, 1, 0, "white", 0, {0}};
  uint32_t mi = gi_mesh_builder_add_material(b, &m);
  const double lo[3] = {-1, 0, -1}, hi[3] = {1, 2, 1};
  gi_mesh_builder_add_box(b, lo, hi, mi);
  gi_light l = {.type = GI_LIGHT_POINT, .color = {5, 5, 5}, .position = {0, 1.8, 0}};
  return tu_build(b, "room", &l, 1);
}

static const double AT[3] = {0, 0.5, 0};

static gi_quality low_quality(void) {
  gi_quality q = {.levels = 2, .res = 8, .threads = 2, .light_samples = 2, .probe_samples = 4, .bounces = 1};
  return q;
}

/* The message names the argument: `word` appears in it. */
static void assert_names(const gi_error_info *err, const char *word) {
  if (!strstr(err->msg, word)) fail_msg("message '%s' does not name '%s'", err->msg, word);
}

/* gi_cascade_bake wrote *out = NULL before any check: a NULL out crashed. */
static void test_bake_null_out(void **state) {
  (void)state;
  gi_scene *s = room();
  gi_quality q = low_quality();
  gi_error_info err = {0};
  assert_int_equal(gi_cascade_bake(s, AT, &q, NULL, NULL, &err), GI_ERR_INVALID_ARG);
  assert_names(&err, "out");
  gi_cascade *c = NULL;
  assert_int_equal(gi_cascade_bake(s, NULL, &q, &c, NULL, &err), GI_ERR_INVALID_ARG);
  assert_null(c);
  assert_names(&err, "viewpoint");
  gi_scene_release(s);
}

/* gi_cascade_anchor wrote through a NULL anchor, and called an infinite
 * voxel size a non-finite viewpoint. It also called a finite viewpoint past
 * float range (1e39) non-finite, and gave one past 1e9 an anchor where the
 * bake and a move refuse it (gi-walk replayed a path up to that point). */
static void test_anchor_args(void **state) {
  (void)state;
  gi_scene *s = room();
  gi_quality q;
  gi_error_info err = {0};
  assert_int_equal(gi_quality_resolve(s, NULL, &q, &err), GI_OK);
  assert_int_equal(gi_cascade_anchor(s, AT, &q, NULL, &err), GI_ERR_INVALID_ARG);
  assert_names(&err, "anchor is NULL");
  int64_t a[3];
  const double huge[3] = {0, 1e39, 0}, far[3] = {2e9, 0, 0}, nan_at[3] = {0, 0, NAN};
  assert_int_equal(gi_cascade_anchor(s, huge, &q, a, &err), GI_ERR_INVALID_ARG);
  assert_names(&err, "viewpoint is more than 1e9 units from the scene");
  gi_cascade *c = NULL;
  assert_int_equal(gi_cascade_bake(s, far, &q, &c, NULL, &err), GI_ERR_INVALID_ARG);
  assert_int_equal(gi_cascade_anchor(s, far, &q, a, &err), GI_ERR_INVALID_ARG);
  assert_names(&err, "viewpoint is more than 1e9 units from the scene");
  assert_int_equal(gi_cascade_anchor(s, nan_at, &q, a, &err), GI_ERR_NONFINITE);
  assert_names(&err, "is not finite");
  q.voxel0 = INFINITY;
  assert_int_equal(gi_cascade_anchor(s, AT, &q, a, &err), GI_ERR_INVALID_ARG);
  assert_names(&err, "voxel0");
  gi_scene_release(s);
}

/* n past what memory holds: 3 * n wrapped, so a gather checked a few
 * points and then gathered n probes from memory it does not own (and the
 * reference's n x chunks tasks wrapped too). */
static void test_huge_n(void **state) {
  (void)state;
  gi_scene *s = room();
  gi_quality q = low_quality();
  gi_cascade *c = NULL;
  gi_error_info err = {0};
  assert_int_equal(gi_cascade_bake(s, AT, &q, &c, NULL, &err), GI_OK);
  gi_probe p;
  size_t huge = SIZE_MAX / 3 + 2; /* 3 * huge wraps to 5 */
  assert_int_equal(gi_cascade_gather(c, AT, huge, &p, NULL, &err), GI_ERR_INVALID_ARG);
  assert_names(&err, "n = ");
  gi_ref_probe rp;
  gi_reference_opts o = {.samples = 4, .threads = 2};
  assert_int_equal(gi_reference_irradiance(s, AT, huge, &o, &rp, NULL, &err), GI_ERR_INVALID_ARG);
  assert_names(&err, "n = ");
  /* 2^50 probes: 3n does not wrap, n x chunks (2^18 chunks of 64 samples) does. */
  gi_reference_opts d = {.samples = 1 << 24, .threads = 2};
  assert_int_equal(gi_reference_irradiance(s, AT, (size_t)1 << 50, &d, &rp, NULL, &err), GI_ERR_INVALID_ARG);
  /* And a NULL array is named ("missing arguments" named none). */
  assert_int_equal(gi_cascade_gather(c, NULL, 1, &p, NULL, &err), GI_ERR_INVALID_ARG);
  assert_names(&err, "pts is NULL");
  assert_int_equal(gi_reference_irradiance(s, AT, 1, &o, NULL, NULL, &err), GI_ERR_INVALID_ARG);
  assert_names(&err, "out is NULL");
  gi_cascade_free(c);
  gi_scene_release(s);
}

/* The answer writers said "nothing to write" or "missing arguments" for
 * any NULL; a probe volume's counts passed when two were negative (their
 * product matched n) and reached the file writers. */
static void test_writer_args(void **state) {
  (void)state;
  gi_scene *s = room();
  gi_quality q = low_quality();
  gi_cascade *c = NULL;
  gi_error_info err = {0};
  assert_int_equal(gi_cascade_bake(s, AT, &q, &c, NULL, &err), GI_OK);
  const gi_bake_report *rep = gi_cascade_report(c);
  char path[512];
  snprintf(path, sizeof path, "%s/edges.exr", tu_tmpdir());
  gi_probe p;
  assert_int_equal(gi_cascade_gather(c, AT, 1, &p, NULL, &err), GI_OK);
  assert_int_equal(gi_probes_write_exr(path, &p, 1, s, AT, NULL, 0, &err), GI_ERR_INVALID_ARG);
  assert_names(&err, "rep is NULL");
  assert_int_equal(gi_probes_write_exr(path, &p, 0, s, AT, rep, 0, &err), GI_ERR_INVALID_ARG);
  assert_names(&err, "n is 0");
  float px[3 * 2 * 1] = {0};
  assert_int_equal(gi_cascade_panorama(c, AT, 2, 1, px, NULL, NULL, &err), GI_ERR_INVALID_ARG);
  assert_names(&err, "indirect is NULL");
  assert_int_equal(gi_panorama_write_exr(path, 2, 1, px, px, s, AT, NULL, 0, NULL, 0, &err), GI_ERR_INVALID_ARG);
  assert_names(&err, "rep is NULL");
  assert_int_equal(gi_panorama_write_exr(path, 0, 1, px, px, s, AT, rep, 0, NULL, 0, &err), GI_ERR_INVALID_ARG);
  assert_names(&err, "size 0x1");
  assert_int_equal(gi_cascade_write_vdb(c, NULL, 0, &err), GI_ERR_INVALID_ARG);
  assert_names(&err, "path is NULL");
  gi_camera cam = {{0, 1, 0.9}, {0, 1, 0}, {0, 1, 0}, 60, 2, 2};
  assert_int_equal(gi_cascade_render(c, &cam, 1, 2, NULL, NULL, &err), GI_ERR_INVALID_ARG);
  assert_names(&err, "rgb is NULL");

  gi_probe probes[2] = {p, p};
  double pos[6] = {0, 0.5, 0, 0.5, 0.5, 0};
  uint8_t valid[2] = {1, 1};
  gi_probe_volume v = {.counts = {-2, -1, 1}, .spacing = 0.5, .up_axis = 1, .n = 2, .pos = pos, .valid = valid,
                       .probes = probes};
  assert_int_equal(gi_probe_volume_write_exr(path, &v, NULL, 0, &err), GI_ERR_INVALID_ARG);
  assert_names(&err, "counts -2 x -1 x 1");
  snprintf(path, sizeof path, "%s/edges.vdb", tu_tmpdir());
  assert_int_equal(gi_probe_volume_write_vdb(path, &v, "edges", &err), GI_ERR_INVALID_ARG);
  assert_names(&err, "counts -2 x -1 x 1");
  v.counts[0] = 2, v.counts[1] = 1, v.probes = NULL;
  assert_int_equal(gi_probe_volume_write_vdb(path, &v, "edges", &err), GI_ERR_INVALID_ARG);
  assert_names(&err, "probes is NULL");
  gi_cascade_free(c);
  gi_scene_release(s);
}

/* A deadline is a double; a long long held it. A negative one (a budget
 * computed below zero) meant "no deadline" although it has passed, and one
 * past 2^63 us was converted with undefined behaviour (UBSan's
 * float-cast-overflow; it read as "none" by luck). */
static void test_cancel_deadline_range(void **state) {
  (void)state;
  gi_cancel *c = gi_cancel_new();
  assert_non_null(c);
  gi_cancel_set_deadline(c, -5);
  assert_int_equal(gi_cancel_check(c), GI_CANCEL_DEADLINE);
  gi_cancel_set_deadline(c, 0);
  assert_int_equal(gi_cancel_check(c), GI_CANCEL_NONE);
  gi_cancel_set_deadline(c, NAN);
  assert_int_equal(gi_cancel_check(c), GI_CANCEL_DEADLINE);
  gi_cancel_set_deadline(c, 1e300);
  assert_int_equal(gi_cancel_check(c), GI_CANCEL_NONE);
  gi_cancel_set_deadline(c, INFINITY);
  assert_int_equal(gi_cancel_check(c), GI_CANCEL_NONE);
  gi_cancel_set_deadline(c, gi_now_ms() - 1);
  assert_int_equal(gi_cancel_check(c), GI_CANCEL_DEADLINE);
  gi_cancel_free(c);
}

/* gi_quality.ao is a flag, but any value passed and counted as on: ao =
 * -1, "off" in the convention of specular and effects[], ran AO. */
static void test_quality_ao_flag(void **state) {
  (void)state;
  gi_scene *s = room();
  gi_error_info err = {0};
  gi_quality in = {.ao = -1}, q;
  assert_int_equal(gi_quality_resolve(s, &in, &q, &err), GI_ERR_INVALID_ARG);
  assert_names(&err, "ao must be 0 or 1, got -1");
  in.ao = 7;
  assert_int_equal(gi_quality_resolve(s, &in, &q, &err), GI_ERR_INVALID_ARG);
  in.ao = 1;
  assert_int_equal(gi_quality_resolve(s, &in, &q, &err), GI_OK);
  gi_scene_release(s);
}

/* The builder's void calls: a NULL material crashed add_material, and an
 * index past the vertices or triangles failed the build as "more than
 * 2^32-1 vertices or materials" (GI_ERR_LIMIT), naming neither the call
 * nor the index. */
static void test_builder_bad_calls(void **state) {
  (void)state;
  gi_error_info err = {0};
  gi_scene *s = NULL;
  gi_mesh_builder *b = gi_mesh_builder_new();
  assert_int_equal(gi_mesh_builder_add_material(b, NULL), UINT32_MAX);
  assert_int_equal(gi_scene_build(b, NULL, NULL, &s, &err), GI_ERR_INVALID_ARG);
  assert_null(s);
  assert_names(&err, "gi_mesh_builder_add_material: m is NULL");
  gi_mesh_builder_free(b);

  b = gi_mesh_builder_new();
  const double lo[3] = {0, 0, 0}, hi[3] = {1, 1, 1};
  gi_mesh_builder_add_box(b, lo, hi, 0);
  gi_mesh_builder_set_vertex_color(b, 8, 1, 0, 0); /* 8 vertices: 0..7 */
  gi_mesh_builder_set_triangle_albedo(b, 99, 1, 0, 0);
  assert_int_equal(gi_scene_build(b, NULL, NULL, &s, &err), GI_ERR_INVALID_ARG);
  assert_names(&err, "gi_mesh_builder_set_vertex_color: vertex 8, but the builder has 8");
  gi_mesh_builder_free(b);

  b = gi_mesh_builder_new();
  gi_mesh_builder_add_box(b, lo, hi, 0);
  gi_mesh_builder_set_lightmap_uv(b, UINT32_MAX, 0, 0);
  assert_int_equal(gi_scene_build(b, NULL, NULL, &s, &err), GI_ERR_INVALID_ARG);
  assert_names(&err, "gi_mesh_builder_set_lightmap_uv: vertex 4294967295");
  gi_mesh_builder_free(b);
}

/* The estimates multiply levels x res^3 x bytes in size_t: a quality that
 * was never resolved (res 2^20) wrapped into a few hundred bytes instead of
 * "0: unresolved". */
static void test_bytes_estimate_range(void **state) {
  (void)state;
  gi_quality q = {.levels = 12, .res = 1 << 20};
  assert_int_equal(gi_cascade_bytes_estimate(&q), 0);
  assert_int_equal(gi_cascade_move_bytes_estimate(&q), 0);
  q.res = 256, q.levels = 13;
  assert_int_equal(gi_cascade_bytes_estimate(&q), 0);
  assert_int_equal(gi_cascade_move_bytes_estimate(&q), 0);
  q.levels = 12;
  assert_true(gi_cascade_bytes_estimate(&q) > (size_t)12 * 256 * 256 * 256);
  assert_true(gi_cascade_move_bytes_estimate(&q) > (size_t)12 * 256 * 256 * 256);
}

/* The effect plan answered a non-finite viewpoint with GI_ERR_INVALID_ARG
 * where the bake it previews (and move, gather, panorama) answers
 * GI_ERR_NONFINITE; its NULL messages and the quality's named nothing. */
static void test_plan_viewpoint(void **state) {
  (void)state;
  gi_scene *s = room();
  gi_error_info err = {0};
  gi_effect fx[GI_FX_COUNT];
  const double bad[3] = {0, NAN, 0};
  gi_cascade *c = NULL;
  assert_int_equal(gi_cascade_bake(s, bad, NULL, &c, NULL, &err), GI_ERR_NONFINITE);
  assert_int_equal(gi_effect_plan(s, bad, NULL, fx, NULL, &err), GI_ERR_NONFINITE);
  assert_names(&err, "viewpoint");
  assert_int_equal(gi_effect_plan(s, AT, NULL, NULL, NULL, &err), GI_ERR_INVALID_ARG);
  assert_names(&err, "out is NULL");
  /* gi_effect_plan_for: its points may be NULL when n is 0 (as its header
   * and gi_cascade_bake_for's say; NULL with n > 0 is refused,
   * test_null_getters) or not finite (skipped); it is the plan
   * gi_effect_plan gives where the points add nothing. */
  const double pts[6] = {1, 1, 1, NAN, 0, 0};
  gi_effect with[GI_FX_COUNT];
  gi_quality qa, qb;
  assert_int_equal(gi_effect_plan_for(NULL, AT, pts, 2, NULL, fx, NULL, &err), GI_ERR_INVALID_ARG);
  assert_names(&err, "scene is NULL");
  assert_int_equal(gi_effect_plan_for(s, AT, NULL, 0, NULL, with, &qa, &err), GI_OK);
  assert_int_equal(gi_effect_plan_for(s, AT, pts, 2, NULL, with, &qa, &err), GI_OK);
  assert_int_equal(gi_effect_plan(s, AT, NULL, fx, &qb, &err), GI_OK);
  assert_int_equal(qa.bounces, qb.bounces);
  assert_int_equal(gi_effect_plan_for(s, bad, pts, 2, NULL, with, NULL, &err), GI_ERR_NONFINITE);
  gi_quality q;
  assert_int_equal(gi_quality_resolve(NULL, NULL, &q, &err), GI_ERR_INVALID_ARG);
  assert_names(&err, "scene is NULL");
  gi_scene_release(s);
}

/* A floor strip x in [-10, 10] under a point light; its lightmap covers
 * x in [0, 10] in tiles of 1, so the tiles run away from the scene origin
 * (x = 0). */
static gi_lightmap *strip_lightmap(gi_scene **s, double tile) {
  gi_mesh_builder *b = gi_mesh_builder_new();
  gi_material m = {{0.6f, 0.6f, 0.6f}, {0}, 1, 0, "floor", 0, {0}};
  uint32_t mi = gi_mesh_builder_add_material(b, &m);
  for (int i = -10; i < 10; i++) {
    const double a[3] = {i, 0, 1}, c[3] = {i + 1, 0, 1}, d[3] = {i + 1, 0, -1}, e[3] = {i, 0, -1};
    gi_mesh_builder_add_quad(b, a, c, d, e, mi);
  }
  gi_light l = {.type = GI_LIGHT_POINT, .color = {50, 50, 50}, .position = {5, 3, 0}};
  *s = tu_build(b, "strip", &l, 1);
  gi_lightmap_opts o = {.texel = 0.25, .atlas = 256, .tile = tile, .have_region = 1,
                        .region_lo = {0, -1, -2}, .region_hi = {10, 1, 2}};
  gi_lightmap *lm = NULL;
  gi_error_info err = {0};
  assert_int_equal(gi_lightmap_layout(*s, &o, &lm, &err), GI_OK);
  return lm;
}

static double atlas_sum(const gi_lightmap *lm) {
  double sum = 0;
  for (size_t a = 0; a < gi_lightmap_num_atlases(lm); a++) {
    gi_lightmap_atlas at;
    assert_int_equal(gi_lightmap_get_atlas(lm, a, &at), 0);
    for (size_t i = 0; i < 3 * (size_t)at.width * at.height; i++)
      sum += fabs(at.radiance[i]) + fabs(at.irradiance[i]) + fabs(at.direct[i]) + fabs(at.indirect[i]);
    for (size_t i = 0; i < (size_t)at.width * at.height; i++) sum += at.valid[i];
  }
  return sum;
}

/* gi_lightmap_bake cleared the atlases first, then baked tile by tile: a
 * bake whose tile count was refused wiped the previous bake, and one that
 * failed part way left the first tiles baked beside zeros. A refused bake
 * (here: tiles past x = 5 lie more than 2^52 voxels of 1.1e-15 from the
 * origin, and every tile leaves its texels outside so small a cascade)
 * now leaves the previous bake as it was; one that fails part way (an
 * allocation of a later tile's cascade) leaves zeros. */
static void test_lightmap_failed_bake(void **state) {
  (void)state;
  gi_scene *s = NULL;
  gi_lightmap *lm = strip_lightmap(&s, 1.0);
  /* A 4 m window for 1 m tiles: every texel inside its tile's cascade. */
  gi_quality q = {.levels = 1, .res = 8, .voxel0 = 0.5, .threads = 1, .light_samples = 2, .probe_samples = 4,
                  .bounces = -1};
  gi_error_info err = {0};
  long a0 = gi__alloc_attempts();
  gi_result rc = gi_lightmap_bake(lm, &q, NULL, NULL, &err);
  if (rc) printf("%s\n", err.msg);
  assert_int_equal(rc, GI_OK);
  long per_bake = gi__alloc_attempts() - a0;
  double baked = atlas_sum(lm);
  assert_true(baked > 0);
  gi_quality tiny = q;
  tiny.voxel0 = 5.0 / 4503599627370496.0; /* 5 / 2^52 */
  assert_int_not_equal(gi_lightmap_bake(lm, &tiny, NULL, NULL, &err), GI_OK);
  assert_true(atlas_sum(lm) == baked);
  gi__alloc_fail_after(per_bake * 3 / 4);
  rc = gi_lightmap_bake(lm, &q, NULL, NULL, &err);
  gi__alloc_fail_after(-1);
  printf("an allocation %ld of %ld failed: %s\n", per_bake * 3 / 4, per_bake, err.msg);
  assert_int_equal(rc, GI_ERR_NOMEM);
  assert_true(atlas_sum(lm) == 0);
  gi_lightmap_free(lm);
  gi_scene_release(s);

  /* Default tiles (tile = 0) follow the cascade: a voxel of 1e-6 cuts the
   * strip into 4096 x 1 x 4096 tiles, refused before anything changes. */
  lm = strip_lightmap(&s, 0);
  assert_int_equal(gi_lightmap_bake(lm, &q, NULL, NULL, &err), GI_OK);
  baked = atlas_sum(lm);
  assert_true(baked > 0);
  tiny.voxel0 = 1e-6;
  assert_int_equal(gi_lightmap_bake(lm, &tiny, NULL, NULL, &err), GI_ERR_LIMIT);
  assert_true(atlas_sum(lm) == baked);
  gi_lightmap_free(lm);
  gi_scene_release(s);
}

/* Grid points are float: a height above ground of 1e39, or a region of
 * +-1e300 (which overlaps the scene, so it passed), built "valid" probes
 * at +-Inf that every gather and writer then refused. */
static void test_grid_float_range(void **state) {
  (void)state;
  gi_scene *s = room();
  gi_error_info err = {0};
  gi_probe_grid g = {0};
  gi_grid_spec high = {.spacing = 0.5, .above_ground = 1e39};
  assert_int_equal(gi_probe_grid_build(s, &high, &g, &err), GI_ERR_INVALID_ARG);
  assert_names(&err, "beyond float range");
  assert_null(g.pos);
  assert_int_equal(g.n, 0);
  gi_grid_spec wide = {.spacing = 1e300, .have_region = 1, .lo = {-1e300, -1e300, -1e300}, .hi = {1e300, 1e300, 1e300}};
  assert_int_equal(gi_probe_grid_build(s, &wide, &g, &err), GI_ERR_INVALID_ARG);
  assert_names(&err, "beyond float range");
  high.above_ground = 1e30; /* far, but a float */
  assert_int_equal(gi_probe_grid_build(s, &high, &g, &err), GI_OK);
  assert_true(g.n > 0);
  gi_probe_grid_free(&g);
  gi_scene_release(s);
}

/* A reference probe at 1e39 (a finite double, an Inf float offset) traced
 * NaN paths and then failed as "a probe came out non-finite (scene values
 * too large?)", blaming the scene; the reference panorama already refused
 * an eye past 1e9 up front, naming it. */
static void test_reference_far_point(void **state) {
  (void)state;
  gi_scene *s = room();
  gi_error_info err = {0};
  gi_ref_probe rp;
  gi_reference_opts o = {.samples = 4, .threads = 2};
  const double far[3] = {0, 1e39, 0};
  assert_int_equal(gi_reference_irradiance(s, far, 1, &o, &rp, NULL, &err), GI_ERR_NONFINITE);
  assert_names(&err, "point 0 is 1e+39 units from the scene on axis y");
  assert_int_equal(gi_reference_irradiance(s, AT, 1, &o, &rp, NULL, &err), GI_OK);
  gi_scene_release(s);
}

/* The 1e9 limit holds on each axis of a viewpoint's offset from the scene's
 * origin (each local coordinate is a float: its precision, and the cell
 * index, depend on that axis alone), and the message says so: it said
 * "more than 1e9 units from the scene" of a point whose distance was never
 * checked ((0.9e9, 0.9e9, 0.9e9), 1.56e9 away, passes). 1e9 exactly
 * passes, 1e9 + 1 fails naming the axis, for the anchor (the bake's and a
 * move's rule), a view's eye (compared after rounding to float, it
 * accepted 1e9 + 32 where gi-bake refuses it) and a panorama. */
static void test_viewpoint_limit_per_axis(void **state) {
  (void)state;
  gi_scene *s = room();
  gi_quality q = low_quality(), rq;
  gi_error_info err = {0};
  assert_int_equal(gi_quality_resolve(s, &q, &rq, &err), GI_OK);
  double o[3];
  gi_scene_origin(s, o);
  int64_t a[3];
  for (int ax = 0; ax < 3; ax++)
    for (int sign = -1; sign <= 1; sign += 2) {
      double p[3] = {o[0], o[1], o[2]};
      p[ax] = o[ax] + sign * 1e9;
      assert_int_equal(gi_cascade_anchor(s, p, &rq, a, &err), GI_OK);
      p[ax] = o[ax] + sign * (1e9 + 1);
      err.msg[0] = 0;
      assert_int_equal(gi_cascade_anchor(s, p, &rq, a, &err), GI_ERR_INVALID_ARG);
      char want[64];
      snprintf(want, sizeof want, "from the scene's origin on axis %c", "xyz"[ax]);
      assert_names(&err, "anchor: viewpoint is more than 1e9 units");
      assert_names(&err, want);
    }
  const double diag[3] = {o[0] + 0.9e9, o[1] + 0.9e9, o[2] + 0.9e9};
  assert_int_equal(gi_cascade_anchor(s, diag, &rq, a, &err), GI_OK);
  gi_cascade *c = NULL;
  assert_int_equal(gi_cascade_bake(s, AT, &q, &c, NULL, &err), GI_OK);
  float rgb[2 * 2 * 3], dir[2 * 1 * 3], ind[2 * 1 * 3];
  gi_camera cam = {{o[0] + 1e9 + 1, o[1], o[2]}, {o[0], o[1], o[2]}, {0, 1, 0}, 60, 2, 2};
  err.msg[0] = 0;
  assert_int_equal(gi_cascade_render(c, &cam, 1, 1, rgb, NULL, &err), GI_ERR_INVALID_ARG);
  assert_names(&err, "camera: eye is more than 1e9 units from the scene's origin on axis x");
  const double far_z[3] = {o[0], o[1], o[2] - 1e9 - 1};
  err.msg[0] = 0;
  assert_int_equal(gi_cascade_panorama(c, far_z, 2, 1, dir, ind, NULL, &err), GI_ERR_INVALID_ARG);
  assert_names(&err, "panorama: viewpoint is more than 1e9 units from the scene's origin on axis z");
  gi_cascade_free(c);
  gi_scene_release(s);
}

/* gi_lightmap_atlas_path compared snprintf's length with (int)cap for a
 * single atlas: a cap past INT_MAX (a caller's "no limit") turned negative
 * and a path that fits came back -1 (the several-atlas branch was right). */
static void test_atlas_path_cap(void **state) {
  (void)state;
  gi_scene *s = room();
  gi_lightmap *lm = NULL;
  gi_lightmap_opts o = {.texel = 0.25, .atlas = 256};
  gi_error_info err = {0};
  assert_int_equal(gi_lightmap_layout(s, &o, &lm, &err), GI_OK);
  assert_int_equal(gi_lightmap_num_atlases(lm), 1);
  char buf[64];
  assert_int_equal(gi_lightmap_atlas_path(lm, "out.exr", 0, buf, sizeof buf), 0);
  assert_string_equal(buf, "out.exr");
  assert_int_equal(gi_lightmap_atlas_path(lm, "out.exr", 0, buf, (size_t)INT_MAX + 1), 0);
  assert_string_equal(buf, "out.exr");
  assert_int_equal(gi_lightmap_atlas_path(lm, "out.exr", 0, buf, 7), -1); /* no room for the NUL */
  gi_lightmap_free(lm);
  gi_scene_release(s);
}

/* gi_scene_options.scale = -1 was taken: positions were inverted through
 * the origin, and with them every triangle's facing, so a closed room lit
 * by its ceiling came out dark and read as the inside of a solid. */
static void test_negative_scale(void **state) {
  (void)state;
  gi_mesh_builder *b = gi_mesh_builder_new();
  const double lo[3] = {-1, 0, -1}, hi[3] = {1, 2, 1};
  gi_mesh_builder_add_box(b, lo, hi, 0);
  gi_scene_options o = {.scale = -1, .default_lights = 1};
  gi_scene *s = NULL;
  gi_error_info err = {0};
  assert_int_equal(gi_scene_build(b, NULL, &o, &s, &err), GI_ERR_INVALID_ARG);
  assert_null(s);
  assert_names(&err, "scale must be > 0");
  o.scale = 2;
  assert_int_equal(gi_scene_build(b, NULL, &o, &s, &err), GI_OK);
  gi_scene_release(s);
  gi_mesh_builder_free(b);
}

/* More NULL messages that named nothing ("camera: missing", "no scene or
 * spec", "missing lightmap or path", "missing scene or image"). */
static void test_more_null_names(void **state) {
  (void)state;
  gi_scene *s = room();
  gi_error_info err = {0};
  assert_int_equal(gi_camera_validate(NULL, &err), GI_ERR_INVALID_ARG);
  assert_names(&err, "cam is NULL");
  gi_probe_grid g;
  assert_int_equal(gi_probe_grid_build(s, NULL, &g, &err), GI_ERR_INVALID_ARG);
  assert_names(&err, "spec is NULL");
  gi_lightmap *lm = NULL;
  gi_lightmap_opts o = {.texel = 0.25, .atlas = 256};
  assert_int_equal(gi_lightmap_layout(s, &o, &lm, &err), GI_OK);
  assert_int_equal(gi_lightmap_write_exr(lm, "", 0, &err), GI_ERR_INVALID_ARG);
  assert_names(&err, "path is empty");
  gi_lightmap_free(lm);
  gi_camera cam = {{0, 1, 0.9}, {0, 1, 0}, {0, 1, 0}, 60, 2, 2};
  assert_int_equal(gi_reference_render(s, &cam, 1, 1, 2, NULL, NULL, &err), GI_ERR_INVALID_ARG);
  assert_names(&err, "rgb is NULL");
  assert_int_equal(gi_reference_panorama(NULL, AT, 2, 1, NULL, NULL, NULL, &err), GI_ERR_INVALID_ARG);
  assert_names(&err, "scene is NULL");
  gi_scene_release(s);
}

/* The VDB writer reads a street-level probe's height on up_axis: 9 (or
 * -1) read pos and wrote the voxel index out of bounds (ASan: a
 * stack-buffer-overflow in voxel_of), and a height 1e10 spacings up was
 * narrowed to an int index, wrapping to 1.4e9 with GI_OK. */
static void test_street_volume_axis(void **state) {
  (void)state;
  gi_probe probes[2];
  memset(probes, 0, sizeof probes);
  double pos[6] = {0, 1, 0, 1, 1, 0};
  uint8_t valid[2] = {1, 1};
  gi_probe_volume v = {.counts = {2, 1, 1}, .spacing = 1, .up_axis = 9, .street_level = 1, .n = 2, .pos = pos,
                       .valid = valid, .probes = probes};
  gi_error_info err = {0};
  char path[512];
  snprintf(path, sizeof path, "%s/street.vdb", tu_tmpdir());
  assert_int_equal(gi_probe_volume_write_vdb(path, &v, "street", &err), GI_ERR_INVALID_ARG);
  assert_names(&err, "up_axis must be 1 (y) or 2 (z)");
  v.up_axis = -1;
  assert_int_equal(gi_probe_volume_write_vdb(path, &v, "street", &err), GI_ERR_INVALID_ARG);
  v.up_axis = 1;
  pos[1] = 1e10f;
  assert_int_equal(gi_probe_volume_write_vdb(path, &v, "street", &err), GI_ERR_INVALID_ARG);
  assert_names(&err, "probe 0's height");
  pos[1] = 1;
  assert_int_equal(gi_probe_volume_write_vdb(path, &v, "street", &err), GI_OK);
}

/* The EXR writers' extra attributes: a NULL array with num_extra 2
 * crashed, extras past 16 were dropped with GI_OK, and one named gi.scene
 * replaced the scene's name in the file. */
static void test_exr_extras(void **state) {
  (void)state;
  gi_scene *s = room();
  gi_quality q = low_quality();
  gi_cascade *c = NULL;
  gi_error_info err = {0};
  assert_int_equal(gi_cascade_bake(s, AT, &q, &c, NULL, &err), GI_OK);
  gi_probe p;
  assert_int_equal(gi_cascade_gather(c, AT, 1, &p, NULL, &err), GI_OK);
  const gi_bake_report *rep = gi_cascade_report(c);
  char path[512];
  snprintf(path, sizeof path, "%s/extras.exr", tu_tmpdir());
  assert_int_equal(gi_probes_write_exr_ex(path, &p, 1, s, AT, rep, 0, NULL, 2, &err), GI_ERR_INVALID_ARG);
  assert_names(&err, "extra is NULL");
  gi_exr_extra ex[20];
  char names[20][16];
  for (int i = 0; i < 20; i++) {
    snprintf(names[i], sizeof names[i], "x.k%d", i);
    ex[i] = (gi_exr_extra){names[i], "v"};
  }
  assert_int_equal(gi_probes_write_exr_ex(path, &p, 1, s, AT, rep, 0, ex, 20, &err), GI_ERR_LIMIT);
  assert_names(&err, "20 extra attributes");
  assert_int_equal(gi_probes_write_exr_ex(path, &p, 1, s, AT, rep, 0, ex, 16, &err), GI_OK);
  gi_exr_file *f = NULL;
  assert_int_equal(gi_exr_read(path, &f, &err), GI_OK);
  for (int i = 0; i < 16; i++) assert_non_null(gi_exr_file_attr(f, names[i]));
  gi_exr_file_free(f);
  gi_exr_extra spoof = {"gi.scene", "spoof"};
  assert_int_equal(gi_probes_write_exr_ex(path, &p, 1, s, AT, rep, 0, &spoof, 1, &err), GI_ERR_INVALID_ARG);
  assert_names(&err, "'gi.scene') is one the writer sets");
  /* Named by the caller's own index (the writer's list put it at 6). */
  gi_exr_extra blank[2] = {{"x.ok", "v"}, {NULL, "v"}};
  assert_int_equal(gi_probes_write_exr_ex(path, &p, 1, s, AT, rep, 0, blank, 2, &err), GI_ERR_INVALID_ARG);
  assert_names(&err, "extra attribute 1 has an empty name or no value");
  float px[3 * 2] = {0};
  assert_int_equal(gi_panorama_write_exr(path, 2, 1, px, px, s, AT, rep, 0, ex, 17, &err), GI_ERR_LIMIT);
  gi_cascade_free(c);
  gi_scene_release(s);
}

/* The readers and builders of core/src/io: a NULL output or input crashed
 * (gi_points_read wrote *pts first, gi_camera_from_mitsuba opened NULL,
 * the VDB builder dereferenced it), and a grid kind past the enum was
 * loaded as the C++ enum before its check (UBSan). */
static void test_io_null_args(void **state) {
  (void)state;
  char path[512];
  snprintf(path, sizeof path, "%s/pts.txt", tu_tmpdir());
  FILE *f = fopen(path, "w");
  assert_non_null(f);
  fputs("1 2 3\n", f);
  fclose(f);
  gi_error_info err = {0};
  double *pts = NULL;
  size_t n = 0;
  assert_int_equal(gi_points_read(path, 10, NULL, &n, &err), GI_ERR_INVALID_ARG);
  assert_names(&err, "pts");
  assert_int_equal(gi_points_read(path, 10, &pts, NULL, &err), GI_ERR_INVALID_ARG);
  assert_names(&err, "n");
  assert_int_equal(gi_points_read(NULL, 10, &pts, &n, &err), GI_ERR_INVALID_ARG);
  assert_names(&err, "path");
  assert_null(pts);
  assert_int_equal(gi_points_read(path, 10, &pts, &n, &err), GI_OK);
  assert_int_equal(n, 1);
  free(pts);
  /* A NUL byte in a line hid the rest of it (a second point, dropped). */
  f = fopen(path, "wb");
  assert_non_null(f);
  fwrite("1 2 3\0 4 5 6\n7 8 9\n", 1, 20, f);
  fclose(f);
  pts = NULL;
  assert_int_equal(gi_points_read(path, 10, &pts, &n, &err), GI_ERR_FORMAT);
  assert_non_null(strstr(err.msg, "pts.txt:1: a NUL byte in the line"));
  assert_null(pts);
  gi_camera cam;
  assert_int_equal(gi_camera_from_mitsuba(NULL, &cam, &err), GI_ERR_INVALID_ARG);
  assert_names(&err, "path");
  assert_int_equal(gi_camera_from_mitsuba(path, NULL, &err), GI_ERR_INVALID_ARG);
  assert_names(&err, "cam");
  assert_int_equal(gi_vdb_mem_new(1, NULL, &err), GI_ERR_INVALID_ARG);
  assert_names(&err, "out");
  gi_vdb_mem *m = NULL;
  assert_int_equal(gi_vdb_mem_new(1, &m, &err), GI_OK);
  const float v[3] = {1, 2, 3};
  assert_int_equal(gi_vdb_mem_set(NULL, 0, 0, 0, v, &err), GI_ERR_INVALID_ARG);
  assert_names(&err, "m");
  assert_int_equal(gi_vdb_mem_set(m, 0, 0, 0, NULL, &err), GI_ERR_INVALID_ARG);
  assert_names(&err, "vals");
  assert_int_equal(gi_vdb_mem_set(m, 0, 0, 0, v, &err), GI_OK);
  size_t bytes = 1;
  uint64_t active = 1;
  gi_vdb_mem_usage(NULL, &bytes, &active);
  assert_true(bytes == 0 && active == 0);
  gi_vdb_mem_usage(m, NULL, &active);
  assert_int_equal(active, 1);
  gi_vdb_mem_free(m);
  /* A kind past the enum, as a careless caller's int: refused by name. */
  const float data[1] = {1};
  gi_vdb_grid g = {.name = "d", .dims = {1, 1, 1}, .data = data, .voxel_size = 1};
  int bad = 5;
  memcpy(&g.kind, &bad, sizeof bad);
  snprintf(path, sizeof path, "%s/k.vdb", tu_tmpdir());
  assert_int_equal(gi_vdb_write(path, &g, 1, NULL, 0, &err), GI_ERR_INVALID_ARG);
  assert_names(&err, "unknown kind 5");
}

/* The scene and cascade getters take NULL as an empty object (a helper
 * session's UBSan run: gi_scene_get_stats, _bounds, _bulk_bounds, _up,
 * _num_lights, _light, _num_materials, _material, gi_cascade_bytes and
 * gi_mesh_builder_add_vertex dereferenced it; gi_cascade_report and
 * gi_scene_name returned a pointer into nothing), and gi_cascade_bake_for
 * refuses NULL points with n > 0 as gi_cascade_would_cover does (it baked
 * and ignored n). */
static void test_null_getters(void **state) {
  (void)state;
  gi_scene_stats st;
  memset(&st, 0xff, sizeof st);
  gi_scene_get_stats(NULL, &st);
  assert_true(st.triangles == 0 && st.far_triangles == 0 && st.clamped_albedo == 0);
  gi_scene_get_stats(NULL, NULL);
  double lo[3] = {1, 1, 1}, hi[3] = {1, 1, 1};
  gi_scene_bounds(NULL, lo, hi);
  for (int k = 0; k < 3; k++) assert_true(lo[k] == 0 && hi[k] == 0);
  lo[0] = hi[0] = 5;
  gi_scene_bulk_bounds(NULL, lo, hi);
  assert_true(lo[0] == 0 && hi[0] == 0);
  assert_int_equal(gi_scene_up(NULL), GI_UP_Y);
  assert_null(gi_scene_name(NULL));
  assert_int_equal(gi_scene_num_lights(NULL), 0);
  assert_null(gi_scene_light(NULL, 0));
  assert_int_equal(gi_scene_num_materials(NULL), 0);
  assert_null(gi_scene_material(NULL, 0));
  assert_int_equal(gi_mesh_builder_add_vertex(NULL, 0, 0, 0), UINT32_MAX);
  assert_int_equal(gi_mesh_builder_num_triangles(NULL), 0);
  assert_int_equal(gi_cascade_bytes(NULL), 0);
  assert_null(gi_cascade_report(NULL));
  gi_scene *s = room();
  gi_quality q = {.levels = 2, .res = 8, .threads = 1};
  gi_cascade *c = (gi_cascade *)(uintptr_t)1;
  gi_error_info err = {0};
  assert_int_equal(gi_cascade_bake_for(s, AT, NULL, 3, &q, NULL, &c, NULL, &err), GI_ERR_INVALID_ARG);
  assert_null(c);
  assert_names(&err, "pts is NULL with n = 3");
  gi_effect fx[GI_FX_COUNT];
  assert_int_equal(gi_effect_plan_for(s, AT, NULL, 2, &q, fx, NULL, &err), GI_ERR_INVALID_ARG);
  assert_names(&err, "pts is NULL with n = 2");
  gi_scene_release(s);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_bake_null_out),
      cmocka_unit_test(test_anchor_args),
      cmocka_unit_test(test_viewpoint_limit_per_axis),
      cmocka_unit_test(test_huge_n),
      cmocka_unit_test(test_writer_args),
      cmocka_unit_test(test_cancel_deadline_range),
      cmocka_unit_test(test_quality_ao_flag),
      cmocka_unit_test(test_builder_bad_calls),
      cmocka_unit_test(test_bytes_estimate_range),
      cmocka_unit_test(test_plan_viewpoint),
      cmocka_unit_test(test_lightmap_failed_bake),
      cmocka_unit_test(test_grid_float_range),
      cmocka_unit_test(test_reference_far_point),
      cmocka_unit_test(test_atlas_path_cap),
      cmocka_unit_test(test_negative_scale),
      cmocka_unit_test(test_more_null_names),
      cmocka_unit_test(test_street_volume_axis),
      cmocka_unit_test(test_exr_extras),
      cmocka_unit_test(test_io_null_args),
      cmocka_unit_test(test_null_getters),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
