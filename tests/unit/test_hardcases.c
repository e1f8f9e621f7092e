/* test_hardcases.c: numerically hard cases (DESIGN section 7, issue 5).
 *
 * Each case prints its measured figure on a line starting "hardcase:" and
 * asserts finite output plus a numeric bound; each bound's comment gives
 * the value measured on the 2-core EPYC VM beside it. Scenes are made in
 * code and baked small (R = 16..32, 2..4 levels) to keep the file quick.
 * Lights are a point light (one deterministic shadow ray per voxel) unless
 * a case needs otherwise, so figures carry no Monte Carlo noise. */
#include "test_util.h"
#include <math.h>
#include <stdio.h>
#include <string.h>
#include <stdlib.h>
#include "gi/gi.h"

#define PI 3.14159265358979

static double mean3(const float v[3]) { return ((double)v[0] + v[1] + v[2]) / 3.0; }

static void assert_probe_finite(const gi_probe *p) {
  for (int i = 0; i < 9; i++)
    for (int k = 0; k < 3; k++) {
      assert_true(isfinite(p->sh[i][k]));
      assert_true(isfinite(p->sh_direct[i][k]));
    }
  for (int k = 0; k < 3; k++) {
    assert_true(isfinite(p->irradiance[k]));
    assert_true(isfinite(p->direct[k]));
    assert_true(isfinite(p->indirect[k]));
    assert_true(p->irradiance[k] >= 0);
  }
  assert_true(isfinite(p->ao));
}

static gi_scene *build(gi_mesh_builder *b, const char *name, const gi_light *lights, size_t nl) {
  gi_scene *s = NULL;
  gi_error_info err = {0};
  gi_scene_options opt = {.up = GI_UP_Y, .lights = lights, .num_lights = nl};
  gi_result rc = gi_scene_build(b, name, &opt, &s, &err);
  if (rc) fprintf(stderr, "%s: %s\n", name, err.msg);
  assert_int_equal(rc, GI_OK);
  gi_mesh_builder_free(b);
  return s;
}

/* Bakes around `at` and gathers n points; every probe must be finite. */
static void bake_gather_rep(const gi_scene *s, const double at[3], const gi_quality *q, const double *pts,
                            size_t n, gi_probe *out, gi_bake_report *rep) {
  gi_cascade *c = NULL;
  gi_error_info err = {0};
  gi_result rc = gi_cascade_bake(s, at, q, &c, rep, &err);
  if (rc) fprintf(stderr, "bake: %s\n", err.msg);
  assert_int_equal(rc, GI_OK);
  assert_int_equal(gi_cascade_gather(c, pts, n, out, NULL, &err), GI_OK);
  for (size_t i = 0; i < n; i++) assert_probe_finite(&out[i]);
  gi_cascade_free(c);
}

static void bake_gather(const gi_scene *s, const double at[3], const gi_quality *q, const double *pts, size_t n,
                        gi_probe *out) {
  bake_gather_rep(s, at, q, pts, n, out, NULL);
}

/* The mesh of a closed 4 x 3 x 4 room (material 0) with a red box in it
 * (material 1), moved by o. */
static gi_mesh_builder *room_mesh(const double o[3], float albedo, float box) {
  gi_mesh_builder *b = gi_mesh_builder_new();
  gi_material wall = {.albedo = {albedo, albedo, albedo}, .roughness = 1};
  gi_material red = {.albedo = {box, box / 7, box / 7}, .roughness = 1};
  uint32_t mw = gi_mesh_builder_add_material(b, &wall), mr = gi_mesh_builder_add_material(b, &red);
  double lo[3] = {o[0], o[1], o[2]}, hi[3] = {o[0] + 4, o[1] + 3, o[2] + 4};
  gi_mesh_builder_add_box(b, lo, hi, mw);
  double blo[3] = {o[0] + 2.3, o[1], o[2] + 1.1}, bhi[3] = {o[0] + 3.1, o[1] + 1.4, o[2] + 2.0};
  gi_mesh_builder_add_box(b, blo, bhi, mr);
  return b;
}

/* The room's point light. */
static gi_light room_light(const double o[3], float light) {
  return (gi_light){.type = GI_LIGHT_POINT, .color = {light, light, light},
                    .position = {o[0] + 1.3, o[1] + 2.6, o[2] + 1.7}};
}

/* The room with its box and light. */
static gi_scene *room_scene2(const double o[3], float albedo, float box, float light) {
  gi_light pl = room_light(o, light);
  return build(room_mesh(o, albedo, box), "room", &pl, 1);
}

static gi_scene *room_scene(const double o[3], float albedo, float light) {
  return room_scene2(o, albedo, 0.7f, light);
}

/* ---- a lamp panel under a ceiling ------------------------------------- */

/* A closed 4 x 3 x 4 m room of albedo 0.95 lit by a black 1 x 1 m
 * emissive panel (facing down) 1 cm under its ceiling: the panel and the
 * ceiling share their voxels, which reflect the mean of the two (0.475)
 * on their lower side, where the panel hides the ceiling and reflects
 * nothing. The room absorbs too little, each bounce's increment shrinks
 * too slowly, and the geometric tail, whose ratio came from the last two
 * increments, multiplied the excess (r 0.946: 17.5x). Quads as in an OBJ
 * of the room (its faces wound inward). */
static gi_scene *panel_room_scene(void) {
  gi_mesh_builder *b = gi_mesh_builder_new();
  gi_material wall = {.albedo = {0.95f, 0.95f, 0.95f}, .roughness = 1};
  gi_material lamp = {.emission = {10, 10, 10}, .roughness = 1};
  uint32_t mw = gi_mesh_builder_add_material(b, &wall), ml = gi_mesh_builder_add_material(b, &lamp);
  const double v[28][3] = {{0, 0, 0}, {0, 0, 4}, {4, 0, 4}, {4, 0, 0}, {0, 3, 0}, {4, 3, 0}, {4, 3, 4},
                           {0, 3, 4}, {0, 0, 0}, {0, 3, 0}, {0, 3, 4}, {0, 0, 4}, {4, 0, 0}, {4, 0, 4},
                           {4, 3, 4}, {4, 3, 0}, {0, 0, 0}, {4, 0, 0}, {4, 3, 0}, {0, 3, 0}, {0, 0, 4},
                           {0, 3, 4}, {4, 3, 4}, {4, 0, 4}, {1.5, 2.99, 1.5}, {2.5, 2.99, 1.5},
                           {2.5, 2.99, 2.5}, {1.5, 2.99, 2.5}};
  for (int i = 0; i < 7; i++)
    gi_mesh_builder_add_quad(b, v[4 * i], v[4 * i + 1], v[4 * i + 2], v[4 * i + 3], i < 6 ? mw : ml);
  return build(b, "panel-room", NULL, 0);
}

/* The panel room's indirect light 1 m up against the path tracer's, at
 * default quality (the ceiling's voxels are 0.16 m there). */
static void test_panel_under_ceiling(void **state) {
  gi_scene *s = panel_room_scene();
  enum { N = 5 };
  const double pts[3 * N] = {0.7, 1, 0.7, 2, 1, 2, 3.3, 1, 0.7, 0.7, 1, 3.3, 3.3, 1, 3.3}, at[3] = {2, 1.5, 2};
  gi_quality q = {.threads = 2};
  gi_probe pr[N];
  bake_gather(s, at, &q, pts, N, pr);
  gi_ref_probe ref[N];
  gi_reference_opts ro = {.samples = 8192, .threads = 2};
  gi_error_info err = {0};
  assert_int_equal(gi_reference_irradiance(s, pts, N, &ro, ref, NULL, &err), GI_OK);
  double cone = 0, pt = 0, se = 0;
  for (int i = 0; i < N; i++)
    cone += mean3(pr[i].indirect), pt += mean3(ref[i].indirect), se += mean3(ref[i].std_err_indirect);
  printf("hardcase: panel 1 cm under the ceiling: indirect %.4f, reference %.4f (se %.4f): ratio %.4f\n", cone / N,
         pt / N, se / N / sqrt(N), cone / pt);
  /* Measured ratio 1.259 with the tail's ratio from the increments, 1.087
   * with the energy ratio's cap (bounce.c). The panel 10 cm lower reads
   * about 1.07 on these points (the cone tracer's bias in a room this
   * bright; the panel's voxels then hold the ceiling alone). Bound 1.15. */
  assert_true(pt > 1);
  assert_true(cone / pt > 0.95 && cone / pt < 1.15);
  gi_scene_release(s);
}

/* ---- far from the origin ------------------------------------------------ */

static void test_far_origin(void **state) {
  /* Not round numbers: world coordinates then round differently from local ones. */
  const double offs[] = {0, 1e6 + 0.3217, 1e7 + 0.3217};
  gi_quality q = {.levels = 3, .res = 32, .voxel0 = 5.0 / 128, .bounces = 2, .light_samples = 4,
                  .probe_samples = 16, .threads = 2};
  gi_probe ref[3], pr[3];
  for (size_t i = 0; i < 3; i++) {
    /* Same offset on all three axes; points and viewpoint move with the scene. */
    double o[3] = {offs[i], -offs[i], offs[i]};
    gi_scene *s = room_scene(o, 0.6f, 10.f);
    double at[3] = {o[0] + 2, o[1] + 1.5, o[2] + 2};
    double pts[9] = {o[0] + 2, o[1] + 1.5, o[2] + 2, o[0] + 0.7, o[1] + 0.4, o[2] + 3.1,
                     o[0] + 3.5, o[1] + 2.2, o[2] + 0.6};
    bake_gather(s, at, &q, pts, 3, i ? pr : ref);
    gi_scene_release(s);
    if (!i) continue;
    double worst = 0;
    for (int p = 0; p < 3; p++)
      for (int k = 0; k < 3; k++) {
        double a = ref[p].irradiance[k], b = pr[p].irradiance[k];
        worst = fmax(worst, fabs(a - b) / fmax(fabs(a), 1e-6));
        for (int j = 0; j < 9; j++)
          worst = fmax(worst, fabs(ref[p].sh[j][k] - pr[p].sh[j][k]) / fmax(fabs(ref[p].sh[0][k]), 1e-6));
      }
    printf("hardcase: far origin %.4f: largest relative probe difference %.3g (irradiance %.5f vs %.5f)\n",
           offs[i], worst, mean3(pr[0].irradiance), mean3(ref[0].irradiance));
    /* Issue 5 asks for 1e-3. The scene keeps float positions relative to a
     * double origin and the cascade snaps relative to that origin, so the
     * pipeline sees the same local numbers: measured 0 at 1e6 and 1e7. */
    assert_true(worst <= 1e-3);
  }
}


/* The room in map coordinates, with one stray triangle left at 0,0,0 (an
 * exporter's leftover): before, the origin sat halfway (float steps of
 * 0.5 m on the room) and the default voxel followed 5e6 m of bounds, so
 * the room read no indirect light. The stray is counted, and the room
 * bakes as it does alone, at default voxel size. */
static void test_stray_triangle(void **state) {
  (void)state;
  const double o[3] = {500000.3217, 12.5, 5000000.3217};
  gi_quality q = {.levels = 3, .res = 16, .bounces = 1, .light_samples = 4, .probe_samples = 16, .threads = 2};
  double at[3] = {o[0] + 2, o[1] + 1.5, o[2] + 2};
  double pts[6] = {o[0] + 2, o[1] + 1.5, o[2] + 2, o[0] + 0.7, o[1] + 0.4, o[2] + 3.1};
  gi_probe alone[2], with[2];
  gi_scene *s = room_scene(o, 0.6f, 10.f);
  gi_scene_stats st;
  gi_scene_get_stats(s, &st);
  assert_int_equal(st.far_triangles, 0);
  double lo[3], hi[3], blo[3], bhi[3];
  gi_scene_bounds(s, lo, hi);
  bake_gather(s, at, &q, pts, 2, alone);
  gi_scene_release(s);

  gi_mesh_builder *b = room_mesh(o, 0.6f, 0.7f);
  uint32_t v0 = gi_mesh_builder_add_vertex(b, 0, 0, 0), v1 = gi_mesh_builder_add_vertex(b, 1, 0, 0),
           v2 = gi_mesh_builder_add_vertex(b, 0, 0, 1);
  gi_mesh_builder_add_triangle(b, v0, v2, v1, 0);
  gi_light pl = room_light(o, 10.f);
  s = build(b, "room+stray", &pl, 1);
  gi_scene_get_stats(s, &st);
  assert_int_equal(st.far_triangles, 1);
  gi_scene_bulk_bounds(s, blo, bhi);
  for (int k = 0; k < 3; k++) assert_true(blo[k] == lo[k] && bhi[k] == hi[k]);
  gi_scene_bounds(s, lo, hi);
  assert_true(fabs(lo[0]) < 1 && fabs(hi[2] - (o[2] + 4)) < 1); /* float steps there: the stray is far */
  bake_gather(s, at, &q, pts, 2, with);
  gi_scene_release(s);
  for (int p = 0; p < 2; p++) {
    printf("hardcase: stray triangle at 0,0,0: probe %d indirect %.5f (alone %.5f), direct %.5f (alone %.5f)\n", p,
           mean3(with[p].indirect), mean3(alone[p].indirect), mean3(with[p].direct), mean3(alone[p].direct));
    assert_true(mean3(alone[p].indirect) > 0.01);
    for (int k = 0; k < 3; k++) {
      assert_true(fabs(with[p].indirect[k] - alone[p].indirect[k]) <= 1e-3 * alone[p].indirect[k]);
      assert_true(fabs(with[p].direct[k] - alone[p].direct[k]) <= 1e-3 * fmax(alone[p].direct[k], 1e-3));
    }
  }
}

/* ---- walls thinner than a voxel ---------------------------------------- */

/* Two 2 x 2 x 2 rooms side by side along x, split by a wall of thickness
 * s0/10 centred at x = xw; a point light in the lit room (x < xw). The
 * exact answer in the dark room is 0: all of its light leaked. */
#define WALL_S0 0.04
static const gi_quality wall_q = {.levels = 3, .res = 32, .voxel0 = WALL_S0, .bounces = 2, .light_samples = 4,
                                  .probe_samples = 16, .threads = 2};

static gi_scene *wall_scene(double xw) {
  gi_mesh_builder *b = gi_mesh_builder_new();
  gi_material m = {.albedo = {0.7f, 0.7f, 0.7f}, .roughness = 1};
  uint32_t mat = gi_mesh_builder_add_material(b, &m);
  double lo[3] = {-2, 0, 0}, hi[3] = {2, 2, 2};
  gi_mesh_builder_add_box(b, lo, hi, mat);
  double t = WALL_S0 / 10;
  double wlo[3] = {xw - t / 2, 0, 0}, whi[3] = {xw + t / 2, 2, 2};
  gi_mesh_builder_add_box(b, wlo, whi, mat);
  gi_light pl = {.type = GI_LIGHT_POINT, .color = {20, 20, 20}, .position = {xw - 1.2, 1.6, 1.1}};
  return build(b, "thin-wall", &pl, 1);
}

static double wall_leak(double xw, double *lit_out) {
  gi_scene *s = wall_scene(xw);
  gi_quality q = wall_q;
  double at[3] = {xw, 1, 1};
  /* Probes mirrored about the wall, and one near it on each side. */
  double pts[12] = {xw - 1, 1, 1, xw + 1, 1, 1, xw - 0.2, 1, 1, xw + 0.2, 1, 1};
  gi_probe pr[4];
  bake_gather(s, at, &q, pts, 4, pr);
  gi_scene_release(s);
  /* L00 is proportional to the irradiance averaged over all normals. */
  double lit = mean3(pr[0].sh[0]), dark = mean3(pr[1].sh[0]);
  double lit_n = mean3(pr[2].sh[0]), dark_n = mean3(pr[3].sh[0]);
  /* No direct light reaches the dark room (shadow rays see the real wall). */
  assert_true(mean3(pr[1].direct) == 0);
  printf("hardcase: thin wall at x=%+.4f (s0=%.3g, thickness s0/10): lit %.5f dark %.5f leak %.4f;"
         " 0.2 from the wall: lit %.5f dark %.5f leak %.4f\n",
         xw, WALL_S0, lit, dark, dark / lit, lit_n, dark_n, dark_n / lit_n);
  if (lit_out) *lit_out = lit;
  return fmax(dark / lit, dark_n / lit_n);
}

static void test_thin_wall(void **state) {
  /* The scene's origin is x = 0, so 0 puts the wall on a cell border (its
   * two faces in two voxels), 0.5 s0 in the middle of a cell (both faces in
   * one voxel), 0.3 s0 off-centre. */
  const double xs[] = {0.0, 0.5 * WALL_S0, 0.3 * WALL_S0};
  double worst = 0;
  for (int i = 0; i < 3; i++) worst = fmax(worst, wall_leak(xs[i], NULL));
  printf("hardcase: thin wall: largest leak %.4f\n", worst);
  /* Measured 0.0906 before bounce cones kept coarse levels off their own
   * surface (trace.c, GI_SURFACE_LOD_K; 0.069 with K = 1.5, 0.024 with
   * K = 2), 0.0072 after (K = 3), worst 0.2 from a wall on a cell border.
   * Bound 0.015. */
  assert_true(worst < 0.015);
}

/* Probes closer to the thin wall than a voxel of their level, on both
 * sides: level 0's (the cascade at the wall) and level 2's (the cascade
 * 1.5 away, so the wall lies in its coarsest level only). The probe's
 * cones leaving the wall once read its far side, lit, through their
 * first samples' footprint (answer/gather.c, the nearest surface). */
static void test_thin_wall_near_probes(void **state) {
  gi_scene *s = wall_scene(0.0);
  gi_quality q = wall_q;
  const double off[3] = {0.25, 0.5, 1.0}; /* in voxels of the probe's level */
  double worst = 0;
  for (int far = 0; far < 2; far++) {
    double at[3] = {far ? -1.5 : 0.0, 1, 1}, s_d = far ? 4 * WALL_S0 : WALL_S0;
    for (int i = 0; i < 3; i++) {
      double pts[6] = {-off[i] * s_d, 1, 1, off[i] * s_d, 1, 1};
      gi_probe pr[2];
      bake_gather(s, at, &q, pts, 2, pr);
      double lit = mean3(pr[0].sh[0]), dark = mean3(pr[1].sh[0]);
      printf("hardcase: probes %.2f voxels of level %d from the thin wall: lit %.5f dark %.5f leak %.4f\n", off[i],
             far ? 2 : 0, lit, dark, dark / lit);
      assert_true(lit > 0);
      worst = fmax(worst, dark / lit);
    }
  }
  printf("hardcase: probes closer than a voxel to a thin wall: largest leak %.4f\n", worst);
  /* Measured 0.594 (0.25 voxels of level 0) and 0.546 (of level 2) before
   * the probes' nearest-surface rule, 0.024 after, worst at level 0 (a
   * probe 0.2 from the wall reads 0.005, test_thin_wall). Bound 0.035. */
  assert_true(worst < 0.035);
  gi_scene_release(s);
}

/* A probe in a gap one voxel wide between two thin walls splitting the
 * lit room from the dark one, 0.1 voxel from the dark side's wall: the
 * cones leaving that wall start half way across the gap, not 1.5 voxels
 * out, past the far wall, in the lit room. (A gap much narrower than a
 * voxel is past what the texture resolves: at 0.3 voxels the probe reads
 * a quarter of the lit room either way.) */
static void test_probe_in_gap(void **state) {
  gi_mesh_builder *b = gi_mesh_builder_new();
  gi_material m = {.albedo = {0.7f, 0.7f, 0.7f}, .roughness = 1};
  uint32_t mat = gi_mesh_builder_add_material(b, &m);
  const double lo[3] = {-2, 0, 0}, hi[3] = {2, 2, 2}, t = WALL_S0 / 10, xb = WALL_S0;
  gi_mesh_builder_add_box(b, lo, hi, mat);
  const double alo[3] = {-t / 2, 0, 0}, ahi[3] = {t / 2, 2, 2}, blo[3] = {xb - t / 2, 0, 0}, bhi[3] = {xb + t / 2, 2, 2};
  gi_mesh_builder_add_box(b, alo, ahi, mat);
  gi_mesh_builder_add_box(b, blo, bhi, mat);
  gi_light pl = {.type = GI_LIGHT_POINT, .color = {20, 20, 20}, .position = {1.2, 1.6, 1.1}};
  gi_scene *s = build(b, "gap", &pl, 1);
  gi_quality q = wall_q;
  const double at[3] = {0, 1, 1};
  /* In the gap, 0.1 voxel from wall A; and in the lit room for scale. */
  double pts[6] = {0.1 * WALL_S0, 1, 1, 1.0, 1, 1};
  gi_probe pr[2];
  bake_gather(s, at, &q, pts, 2, pr);
  double gap = mean3(pr[0].sh[0]), lit = mean3(pr[1].sh[0]);
  printf("hardcase: probe in a gap of a voxel between two thin walls: %.5f against the lit room's %.5f "
         "(leak %.4f)\n", gap, lit, gap / lit);
  assert_true(lit > 0);
  /* Measured 0.074 (0.111 with a gap of 1.3 voxels) while a leaving cone
   * was lifted 1.5 voxels whatever stood there, 0.022 with the lift held
   * to half the gap. Bound 0.04. */
  assert_true(gap / lit < 0.04);
  gi_scene_release(s);
}

/* A closed 6 x 3 x 5 m room of single-sided walls facing in, under a sun
 * and a sky: nothing reaches its inside (the exact answer there is 0). */
static gi_scene *sealed_room_scene(void) {
  gi_mesh_builder *b = gi_mesh_builder_new();
  gi_material m = {.albedo = {0.7f, 0.7f, 0.7f}, .roughness = 1};
  uint32_t mat = gi_mesh_builder_add_material(b, &m);
  const double X = 6, Y = 3, Z = 5;
  const double c[8][3] = {{0, 0, 0}, {X, 0, 0}, {X, Y, 0}, {0, Y, 0}, {0, 0, Z}, {X, 0, Z}, {X, Y, Z}, {0, Y, Z}};
  const int q[6][4] = {{0, 4, 5, 1}, {3, 2, 6, 7}, {0, 3, 7, 4}, {1, 5, 6, 2}, {0, 1, 2, 3}, {4, 7, 6, 5}};
  for (int i = 0; i < 6; i++) gi_mesh_builder_add_quad(b, c[q[i][0]], c[q[i][1]], c[q[i][2]], c[q[i][3]], mat);
  const gi_light l[2] = {{.type = GI_LIGHT_SUN, .color = {3, 3, 3}, .direction = {0.37f, -0.86f, 0.35f}},
                         {.type = GI_LIGHT_SKY, .color = {0.3f, 0.3f, 0.3f}}};
  return build(b, "sealed-room", l, 2);
}

/* Probes 5 and 10 cm from the sealed room's corner under its ceiling, at
 * default quality and at R 24 and 48 (where its walls fall elsewhere in
 * the coarse cells). Their cones leaving the walls and the ceiling read
 * the sunlit roof's top through the ceiling's coarse voxels, and the ones
 * meeting a wall at once read the roof's faces beside it: L00 1.09 and
 * 0.49 at R 32, 1.68 and 1.55 at R 24, where a probe 1 m above the roof
 * (the scale) reads 6.6-6.8. Now the probe's other near surfaces lift its
 * cones too, and a cone meeting a surface reads only that surface's face. */
static void test_sealed_room_corner(void **state) {
  gi_scene *s = sealed_room_scene();
  const double pts[9] = {0.05, 2.95, 0.05, 0.1, 2.9, 0.1, 3, 4, 2.5}, at[3] = {3, 1.2, 2.5};
  const int res[3] = {0, 24, 48};
  double worst = 0;
  for (int i = 0; i < 3; i++) {
    gi_quality q = {.res = res[i], .threads = 2};
    gi_probe pr[3];
    bake_gather(s, at, &q, pts, 3, pr);
    double out = mean3(pr[2].sh[0]);
    for (int k = 0; k < 2; k++) {
      double in = mean3(pr[k].sh[0]);
      printf("hardcase: sealed room, R %d, probe %.2f from its corner: L00 %.5f (1 m above the roof %.4f, leak %.4f)\n",
             res[i] ? res[i] : 32, pts[3 * k], in, out, in / out);
      assert_true(out > 1);
      worst = fmax(worst, in / out);
    }
  }
  printf("hardcase: sealed room's corner: largest leak %.4f\n", worst);
  /* Measured leak (L00 over the roof probe's) 0.160, 0.256 and 0.172 at R
   * 32, 24 and 48 before; 0.0017, 0.0145 and 0.0282 with the probes' rule
   * alone, 0, 0 and 0.0144 once the bounce's apexes moved off the surfaces
   * beside them too (test_sealed_room_inside). Bound 0.06. */
  assert_true(worst < 0.06);
  gi_scene_release(s);
}

/* The sealed room's inside, 1 m up, at R 24, 32 and 48: its voxels' first
 * bounce read the sunlit roof through the ceiling's coarse voxels (a wall's
 * side under the ceiling started its cones within one) and the light went
 * round the room. The sides' apexes now move off the surfaces beside them
 * too (bounce.c). */
static void test_sealed_room_inside(void **state) {
  gi_scene *s = sealed_room_scene();
  enum { N = 5 };
  const double pts[3 * (N + 1)] = {0.75, 1, 0.75, 3, 1, 2.5, 5.25, 1, 4.25, 1.75, 1, 3.75, 4.25, 1, 1.75, 3, 4, 2.5};
  const double at[3] = {3, 1.2, 2.5};
  const int res[3] = {24, 0, 48};
  double worst = 0;
  for (int i = 0; i < 3; i++) {
    gi_quality q = {.res = res[i], .threads = 2};
    gi_probe pr[N + 1];
    bake_gather(s, at, &q, pts, N + 1, pr);
    double out = mean3(pr[N].sh[0]), in = 0;
    for (int k = 0; k < N; k++) in = fmax(in, mean3(pr[k].sh[0]));
    printf("hardcase: sealed room, R %d, inside 1 m up: largest L00 %.5f (1 m above the roof %.4f, leak %.5f)\n",
           res[i] ? res[i] : 32, in, out, in / out);
    assert_true(out > 1);
    worst = fmax(worst, in / out);
  }
  printf("hardcase: sealed room's inside: largest leak %.5f\n", worst);
  /* Measured leak (largest L00 inside over the roof probe's) 0.00235, 0.00011
   * and 0.00109 at R 24, 32 and 48 before (L00 0.015 at R 24, where the
   * windowed room's reference reads 0.1-0.4 inside); 0, 0 and 0.00023
   * after. Bound 1e-3. */
  assert_true(worst < 1e-3);
  gi_scene_release(s);
}

/* Points a hair inside the sealed room, under its ceiling and beside a
 * wall (2e-3 to 0.019 of a voxel: nearer than the shadow rays' offset,
 * farther than the 1e-3 within which a point is on the surface, and taken
 * above a level one, as on the roof below),
 * get no sun and no sky: the surface between them and the light shadows
 * them. They read full sun through it (3.42 at 1 mm under a ceiling, 0
 * at 5 mm): a point in space ignored hits nearer than the offset. Just
 * above the roof, and on it, they read what a point a voxel up does. */
static void test_probe_under_ceiling(void **state) {
  gi_scene *s = sealed_room_scene();
  gi_quality q = {.threads = 2}, rq;
  gi_error_info err = {0};
  assert_int_equal(gi_quality_resolve(s, &q, &rq, &err), GI_OK);
  enum { N = 5 };
  const double d[N] = {2e-3, 5e-3, 1e-2, 1.5e-2, 1.9e-2}, s0 = rq.voxel0;
  double pts[3 * (3 * N + 2)];
  for (int i = 0; i < N; i++) {
    double *under = pts + 3 * i, *wall = pts + 3 * (N + i), *above = pts + 3 * (2 * N + i);
    under[0] = 2, under[1] = 3 - d[i] * s0, under[2] = 2;
    wall[0] = d[i] * s0, wall[1] = 1.5, wall[2] = 2.5;
    above[0] = 2, above[1] = 3 + d[i] * s0, above[2] = 2;
  }
  double *on = pts + 3 * 3 * N, *up = pts + 3 * (3 * N + 1);
  on[0] = 2, on[1] = 3, on[2] = 2;
  up[0] = 2, up[1] = 3 + s0, up[2] = 2;
  gi_probe pr[3 * N + 2];
  bake_gather(s, (const double[3]){3, 1.2, 2.5}, &q, pts, 3 * N + 2, pr);
  double lit = mean3(pr[3 * N + 1].direct);
  assert_true(lit > 1);
  for (int i = 0; i < N; i++) {
    double u = mean3(pr[i].direct), w = mean3(pr[N + i].direct), a = mean3(pr[2 * N + i].direct);
    printf("hardcase: %.4f voxels inside the ceiling: direct %.4f, inside the wall %.4f; above the roof %.4f "
           "(a voxel up %.4f)\n", d[i], u, w, a, lit);
    assert_true(u == 0 && w == 0);
    assert_true(fabs(a / lit - 1) < 0.02);
  }
  printf("hardcase: on the roof: direct %.4f\n", mean3(pr[3 * N].direct));
  assert_true(fabs(mean3(pr[3 * N].direct) / lit - 1) < 0.02);
  gi_scene_release(s);
}

/* A 20 x 20 m wall standing alone (one two-sided quad at x = 0) under a
 * sun that lights its -x side and a sky of radiance LONE_WALL_SKY. */
#define LONE_WALL_SKY 0.3f
static gi_scene *lone_wall_scene(void) {
  gi_mesh_builder *b = gi_mesh_builder_new();
  gi_material m = {.albedo = {0.6f, 0.6f, 0.6f}, .roughness = 1};
  uint32_t mat = gi_mesh_builder_add_material(b, &m);
  const double A[3] = {0, 0, -10}, B[3] = {0, 20, -10}, C[3] = {0, 20, 10}, D[3] = {0, 0, 10};
  gi_mesh_builder_add_quad(b, A, B, C, D, mat);
  const gi_light l[2] = {{.type = GI_LIGHT_SUN, .color = {3, 3, 3}, .direction = {0.37f, -0.86f, 0.35f}},
                         {.type = GI_LIGHT_SKY, .color = {LONE_WALL_SKY, LONE_WALL_SKY, LONE_WALL_SKY}}};
  return build(b, "lone-wall", l, 2);
}

/* The lone wall at default quality, and probes
 * 0.02-0.4 m from its shaded side, the nearest inside a voxel of their
 * level (0.195 m there): their indirect light is the shaded side's sky
 * light and nothing from the sunlit side. Against the path tracer. */
static void test_probes_beside_wall(void **state) {
  gi_scene *s = lone_wall_scene();
  enum { N = 5 };
  const double dist[N] = {0.02, 0.05, 0.1, 0.2, 0.4};
  double pts[3 * N];
  for (int i = 0; i < N; i++) pts[3 * i] = dist[i], pts[3 * i + 1] = 10, pts[3 * i + 2] = 0;
  const double at[3] = {2, 10, 0};
  gi_quality q = {.threads = 2};
  gi_probe pr[N];
  bake_gather(s, at, &q, pts, N, pr);
  gi_ref_probe ref[N];
  gi_reference_opts ro = {.samples = 4096, .seed = 3};
  gi_error_info err = {0};
  assert_int_equal(gi_reference_irradiance(s, pts, N, &ro, ref, NULL, &err), GI_OK);
  double worst = 0;
  for (int i = 0; i < N; i++) {
    double r = pr[i].indirect[0] / ref[i].indirect[0];
    printf("hardcase: probe %.2f m from a lone wall's shaded side: indirect %.4f, reference %.4f (+- %.4f), "
           "ratio %.2f\n", dist[i], pr[i].indirect[0], ref[i].indirect[0], ref[i].std_err_indirect[0], r);
    worst = fmax(worst, fabs(r - 1));
  }
  /* Measured ratios 3.0-3.2 at 0.02-0.1 m, 2.1 at 0.2 m and 1.5 at 0.4 m
   * while probes gathered as if nothing stood near them; 0.89-0.91 since
   * they take the nearest surface's rule (answer/gather.c). Bound: within
   * 30%. */
  printf("hardcase: probes beside a lone wall: largest indirect error %.2f\n", worst);
  assert_true(worst < 0.3);
  gi_scene_release(s);
}

/* A panorama from an eye 1 cm from the lone wall's shaded side, the cascade
 * baked there (its finest voxel 2.4 cm): the eye's nearest surface takes
 * the probes' rule. Mean relative error of the pixels' luminance against
 * the path tracer's panorama, sky pixels left out. */
static void test_panorama_beside_wall(void **state) {
  gi_scene *s = lone_wall_scene();
  enum { W = 64, H = 32 };
  const double at[3] = {0.01, 10, 0};
  gi_quality q = {.threads = 2};
  gi_cascade *c = NULL;
  gi_error_info err = {0};
  assert_int_equal(gi_cascade_bake(s, at, &q, &c, NULL, &err), GI_OK);
  static float dir[W * H * 3], ind[W * H * 3], ref[W * H * 3];
  assert_int_equal(gi_cascade_panorama(c, at, W, H, dir, ind, NULL, &err), GI_OK);
  gi_render_opts ro = {.spp = 1024, .seed = 5, .threads = 2};
  assert_int_equal(gi_reference_panorama(s, at, W, H, &ro, ref, NULL, &err), GI_OK);
  /* A pixel whose primary ray escaped shows the sky: left out. */
  static uint8_t sky[W * H];
  double mean = 0, e = 0;
  int kept = 0;
  for (int i = 0; i < W * H; i++) {
    sky[i] = dir[3 * i] == LONE_WALL_SKY && dir[3 * i + 1] == LONE_WALL_SKY && dir[3 * i + 2] == LONE_WALL_SKY;
    if (!sky[i]) mean += mean3(&ref[3 * i]), kept++;
  }
  assert_true(kept > 0);
  mean /= kept;
  for (int i = 0; i < W * H; i++) {
    if (sky[i]) continue;
    float x[3] = {dir[3 * i] + ind[3 * i], dir[3 * i + 1] + ind[3 * i + 1], dir[3 * i + 2] + ind[3 * i + 2]};
    e += fabs(mean3(x) - mean3(&ref[3 * i])) / fmax(mean3(&ref[3 * i]), 0.05 * mean);
  }
  e /= kept;
  printf("hardcase: panorama 1 cm from a lone wall: error %.4f over %d pixels\n", e, kept);
  /* Measured 0.209 while the eye's cones stepped past the wall and read
   * its sunlit side, 0.101 with the probes' rule. Bound 0.15. */
  assert_true(e < 0.15);
  gi_cascade_free(c);
  gi_scene_release(s);
}

/* The same rooms through the camera: a view of the wall and the floor at
 * its foot from each side, 0.6 from it. No light reaches the dark room, so
 * its mean over the lit room's is what leaked. */
#define WALL_PX 48
static double wall_view_leak(double xw) {
  gi_scene *s = wall_scene(xw);
  gi_quality q = wall_q;
  double at[3] = {xw, 1, 1};
  gi_cascade *c = NULL;
  gi_error_info err = {0};
  assert_int_equal(gi_cascade_bake(s, at, &q, &c, NULL, &err), GI_OK);
  static float img[WALL_PX * WALL_PX * 3];
  double mean[2];
  for (int side = 0; side < 2; side++) {
    double sg = side ? 1 : -1; /* 0: the lit room, 1: the dark one */
    gi_camera cam = {.eye = {xw + sg * 0.6, 1, 1}, .target = {xw, 0.6, 1}, .up = {0, 1, 0}, .fov_deg = 50,
                     .width = WALL_PX, .height = WALL_PX};
    assert_int_equal(gi_cascade_render(c, &cam, 16, 2, img, NULL, &err), GI_OK);
    mean[side] = 0;
    for (int i = 0; i < WALL_PX * WALL_PX * 3; i++) mean[side] += img[i] / (WALL_PX * WALL_PX * 3.0);
  }
  gi_cascade_free(c);
  gi_scene_release(s);
  printf("hardcase: thin wall at x=%+.4f, camera views: lit %.5f dark %.5f leak %.4f\n", xw, mean[0], mean[1],
         mean[1] / mean[0]);
  assert_true(mean[0] > 0);
  return mean[1] / mean[0];
}

static void test_thin_wall_view(void **state) {
  const double xs[] = {0.0, 0.5 * WALL_S0, 0.3 * WALL_S0};
  double worst = 0;
  for (int i = 0; i < 3; i++) worst = fmax(worst, wall_view_leak(xs[i]));
  printf("hardcase: thin wall, camera views: largest leak %.4f\n", worst);
  /* Measured 0.49 while camera views gathered by the free-space rule from
   * one voxel off the surface, 0.0089 with the bounce's surface rule
   * (trace/gather.c), worst on a cell border; 0.0125 at 067088e (every
   * pixel gathering its own), 0.0127 with the indirect mixed between
   * anchors (render.c). The probes' bound. */
  assert_true(worst < 0.015);
}


/* ---- viewpoint on cell and cascade borders ------------------------------ */

/* A client at fixed probe points while the cascade's viewpoint walks along
 * x in steps of s0/16 over [-2.5 s0, 2.5 s0] around the scene's local
 * origin: across level-0 cell borders (every s0), level-0 window snaps
 * (every 2 s0) and x = 0, where every level's window snaps at once (0 is a
 * multiple of 2 s_d for all d). Per step, the change of each probe's
 * irradiance (L00 and E(up), every channel) relative to its value. */
static void test_border_steps(void **state) {
  const double o[3] = {0, 0, 0};
  gi_scene *s = room_scene(o, 0.6f, 10.f); /* local origin = world (2, 1.5, 2) */
  const int R = 16, steps_per_voxel = 16;
  const double s0 = 0.08, span = 2.5;
  gi_quality q = {.levels = 3, .res = R, .voxel0 = s0, .bounces = 1, .light_samples = 4, .probe_samples = 16,
                  .threads = 2};
  /* Near the viewpoint, and 0.3, 0.5 and 0.6 of level 0's half-width away. */
  enum { NP = 4 };
  const double half = 0.5 * R * s0;
  const double probe[3 * NP] = {2.15, 1.7, 1.8, 2 + 0.6 * half, 1.5, 2, 2, 1.5 - 0.5 * half, 2.1,
                                2 - 0.3 * half, 1.5 + 0.3 * half, 2 - 0.9 * half};
  int n = (int)lround(2 * span * steps_per_voxel) + 1, snaps = 0;
  double prev[NP][6] = {{0}}, prev_origin[GI_MAX_LEVELS][3] = {{0}};
  double worst_snap = 0, worst_still = 0, sum = 0;
  for (int i = 0; i < n; i++) {
    double x = -span * s0 + i * s0 / steps_per_voxel;
    double at[3] = {2 + x, 1.5, 2};
    gi_probe pr[NP];
    gi_bake_report rep;
    bake_gather_rep(s, at, &q, probe, NP, pr, &rep);
    int snapped = i > 0 && memcmp(prev_origin, rep.level_origin, sizeof prev_origin) != 0;
    memcpy(prev_origin, rep.level_origin, sizeof prev_origin);
    snaps += snapped;
    for (int p = 0; p < NP; p++) {
      double cur[6] = {pr[p].sh[0][0], pr[p].sh[0][1], pr[p].sh[0][2],
                       pr[p].irradiance[0], pr[p].irradiance[1], pr[p].irradiance[2]};
      sum += mean3(pr[p].irradiance) / NP;
      if (i) {
        double step = 0;
        for (int k = 0; k < 6; k++) step = fmax(step, fabs(cur[k] - prev[p][k]) / fmax(fabs(prev[p][k]), 1e-9));
        if (snapped) worst_snap = fmax(worst_snap, step);
        else worst_still = fmax(worst_still, step);
      }
      memcpy(prev[p], cur, sizeof cur);
    }
  }
  gi_scene_release(s);
  printf("hardcase: border walk (3 x %d^3, s0 %.2f, %d steps of s0/%d): mean E %.4f; %d window snaps, largest "
         "per-step change %.4f at a snap, %.2g between snaps\n",
         R, s0, n - 1, steps_per_voxel, sum / n, snaps, worst_snap, worst_still);
  /* Windows snap at 2 s_d: x = -2, 0 (all levels) and +2 s0 (level 0). */
  assert_int_equal(snaps, 3);
  /* Between snaps the grids stay put and the gather is a pure function of
   * the texture and the point: exactly no change (measured 0). */
  assert_true(worst_still == 0);
  /* At a snap, coarse cells switch between filtered from the finer level
   * and voxelized and lit on their own, which do not agree exactly:
   * measured 0.054 (at x = 0, all levels snapping). Bound 0.08. */
  assert_true(worst_snap < 0.08);
}

/* ---- hostile geometry, materials and lights ------------------------------ */

static const gi_quality small_q = {.levels = 3, .res = 16, .voxel0 = 5.0 / 64, .bounces = 2, .light_samples = 4,
                                   .probe_samples = 16, .threads = 2};
static const double room_at[3] = {2, 1.5, 2};
static const double room_pts[6] = {2, 1.5, 2, 1.0, 2.5, 3.0};

static double max_rel_diff(const gi_probe *a, const gi_probe *b, int n) {
  double worst = 0;
  for (int p = 0; p < n; p++)
    for (int k = 0; k < 3; k++)
      worst = fmax(worst, fabs(a[p].irradiance[k] - b[p].irradiance[k]) / fmax(fabs(a[p].irradiance[k]), 1e-12));
  return worst;
}

/* The room with an enormous floor (1e6 across, 10 below the room: kept,
 * voxelized by every level it crosses, hidden from the probes by the closed
 * room); with `hostile`, also every wall twice and degenerate, sliver and
 * non-finite triangles, which must change nothing. */
static gi_scene *hostile_scene(int hostile) {
  gi_mesh_builder *b = gi_mesh_builder_new();
  gi_material wall = {.albedo = {0.6f, 0.6f, 0.6f}, .roughness = 1};
  gi_material red = {.albedo = {0.7f, 0.1f, 0.1f}, .roughness = 1};
  uint32_t mw = gi_mesh_builder_add_material(b, &wall), mr = gi_mesh_builder_add_material(b, &red);
  double lo[3] = {0, 0, 0}, hi[3] = {4, 3, 4};
  gi_mesh_builder_add_box(b, lo, hi, mw);
  double blo[3] = {2.3, 0, 1.1}, bhi[3] = {3.1, 1.4, 2.0};
  gi_mesh_builder_add_box(b, blo, bhi, mr);
  uint32_t e0 = gi_mesh_builder_add_vertex(b, -1e6, -10, -1e6), e1 = gi_mesh_builder_add_vertex(b, 1e6, -10, -1e6);
  uint32_t e2 = gi_mesh_builder_add_vertex(b, 0, -10, 1e6);
  gi_mesh_builder_add_triangle(b, e0, e1, e2, mw);
  if (hostile) {
    gi_mesh_builder_add_box(b, lo, hi, mw); /* every wall twice */
    uint32_t v0 = gi_mesh_builder_add_vertex(b, 1, 1, 1), v1 = gi_mesh_builder_add_vertex(b, 2, 1, 1);
    uint32_t v2 = gi_mesh_builder_add_vertex(b, 3, 1, 1); /* collinear with v0, v1 */
    gi_mesh_builder_add_triangle(b, v0, v0, v1, mw);      /* repeated vertex */
    gi_mesh_builder_add_triangle(b, v0, v1, v2, mw);      /* zero area */
    uint32_t s0 = gi_mesh_builder_add_vertex(b, 1, 2, 1), s1 = gi_mesh_builder_add_vertex(b, 3, 2, 1);
    uint32_t s2 = gi_mesh_builder_add_vertex(b, 2, 2 + 1e-13, 1); /* height 1e-13 over length 2 */
    gi_mesh_builder_add_triangle(b, s0, s1, s2, mw);
    uint32_t n0 = gi_mesh_builder_add_vertex(b, NAN, 1, 1), n1 = gi_mesh_builder_add_vertex(b, 1, INFINITY, 1);
    gi_mesh_builder_add_triangle(b, n0, v1, s0, mw);
    gi_mesh_builder_add_triangle(b, v0, n1, s1, mw);
  }
  gi_light pl = {.type = GI_LIGHT_POINT, .color = {10, 10, 10}, .position = {1.3, 2.6, 1.7}};
  return build(b, hostile ? "hostile" : "enormous", &pl, 1);
}

static void test_degenerate_triangles(void **state) {
  gi_scene *ref = hostile_scene(0), *s = hostile_scene(1);
  gi_scene_stats st;
  gi_scene_get_stats(s, &st);
  printf("hardcase: hostile triangles: %llu in, %llu kept, %llu degenerate, %llu non-finite dropped\n",
         (unsigned long long)st.input_triangles, (unsigned long long)st.triangles,
         (unsigned long long)st.dropped_degenerate, (unsigned long long)st.dropped_nonfinite);
  assert_int_equal(st.dropped_degenerate, 3);
  assert_int_equal(st.dropped_nonfinite, 2);
  assert_int_equal(st.triangles, 12 + 12 + 1 + 12);
  gi_probe a[2], b[2];
  gi_bake_report rep;
  bake_gather_rep(ref, room_at, &small_q, room_pts, 2, a, &rep);
  printf("hardcase: enormous triangle: %llu triangle/level pairs visited, probe E %.5f (finite)\n",
         (unsigned long long)rep.triangles_visited, mean3(a[0].irradiance));
  bake_gather(s, room_at, &small_q, room_pts, 2, b);
  double d = max_rel_diff(a, b, 2);
  printf("hardcase: duplicate, degenerate, sliver, non-finite triangles: largest relative probe difference %.3g\n", d);
  /* Duplicates double a voxel's projected area, but opacity saturates at
   * 0.999 either way and albedo is an area-weighted mean; the rest are
   * dropped. Measured 1.7e-4 (the duplicates' summation order). Bound 1e-3. */
  assert_true(d <= 1e-3);
  gi_scene_release(s);
  gi_scene_release(ref);
}

static void test_albedo_extremes(void **state) {
  const double o[3] = {0, 0, 0};
  const float albedo[] = {0.f, 1.f, 1.5f};
  gi_probe pr[3][2];
  for (int i = 0; i < 3; i++) {
    gi_scene *s = room_scene2(o, albedo[i], albedo[i], 10.f);
    gi_scene_stats st;
    gi_scene_get_stats(s, &st);
    bake_gather(s, room_at, &small_q, room_pts, 2, pr[i]);
    printf("hardcase: albedo %.1f: %llu material(s) clamped; probe E %.5f (direct %.5f, indirect %.5f)\n",
           albedo[i], (unsigned long long)st.clamped_albedo, mean3(pr[i][0].irradiance), mean3(pr[i][0].direct),
           mean3(pr[i][0].indirect));
    /* 1.5 is clamped (both materials: walls 1.5, box R 1.5) and counted. */
    assert_int_equal(st.clamped_albedo, i == 2 ? 2 : 0);
    gi_scene_release(s);
  }
  /* Albedo 0: nothing bounces, indirect light is exactly 0. */
  assert_true(mean3(pr[0][0].indirect) == 0 && mean3(pr[0][1].indirect) == 0);
  /* Albedo 1 in a closed room: finite (checked), and more light than at 0. */
  assert_true(mean3(pr[1][0].indirect) > 0);
  /* Albedo 1.5 on the walls is clamped to 1: the walls match the albedo-1
   * room; the box differs only in G and B (1.5/7 against 1/7). */
  for (int p = 0; p < 2; p++) assert_true(fabs(pr[2][p].irradiance[0] - pr[1][p].irradiance[0]) <=
                                          0.05 * pr[1][p].irradiance[0]);
}

static void test_light_extremes(void **state) {
  const double o[3] = {0, 0, 0};
  /* Up to the brightest light a scene takes (gi_scene.h). */
  /* 1e-36: the texels' scale went subnormal under 1.5e-35 and every
   * answer NaN (texel.c). */
  const float light[] = {1.f, 1e-6f, 1e6f, GI_MAX_LIGHT_VALUE, 1e-36f};
  gi_probe pr[5][2];
  double worst = 0;
  for (int i = 0; i < 5; i++) {
    gi_scene *s = room_scene(o, 0.6f, light[i]);
    bake_gather(s, room_at, &small_q, room_pts, 2, pr[i]);
    gi_scene_release(s);
    for (int p = 0; p < 2 && i; p++)
      for (int k = 0; k < 3; k++) {
        double want = (double)pr[0][p].irradiance[k] * light[i];
        worst = fmax(worst, fabs(pr[i][p].irradiance[k] - want) / want);
      }
    printf("hardcase: light %.0e: probe E %.6g\n", light[i], mean3(pr[i][0].irradiance));
  }
  printf("hardcase: lights 1e-6, 1e6, 1e20 and 1e-36: largest departure from linear scaling %.3g\n", worst);
  /* Light transport is linear; in float the pipeline is linear to rounding
   * (measured 4.9e-6 with the 1e20 light, 7.6e-8 up to 1e6). Bound 1e-4. */
  assert_true(worst <= 1e-4);
}

static void test_empty_and_outside(void **state) {
  /* Empty scene: no triangles, a sun. The probe sees the sun, nothing else. */
  gi_light sun = {.type = GI_LIGHT_SUN, .color = {3, 3, 3}, .direction = {0.6f, -0.8f, 0}};
  gi_scene *e = build(gi_mesh_builder_new(), "empty", &sun, 1);
  gi_probe pr[2];
  bake_gather(e, room_at, &small_q, room_pts, 2, pr);
  gi_scene_release(e);
  printf("hardcase: empty scene: E(up) %.6f (exact 2.4), indirect %.3g\n", mean3(pr[0].irradiance), mean3(pr[0].indirect));
  assert_true(fabs(mean3(pr[0].irradiance) - 3 * 0.8) <= 1e-5);
  assert_true(mean3(pr[0].indirect) == 0);

  /* The room with a sun, the cascade 1000 units away: no level holds any
   * geometry; the probe there gets the sun and nothing else. */
  const double o[3] = {0, 0, 0};
  gi_mesh_builder *b = gi_mesh_builder_new();
  gi_material m = {.albedo = {0.6f, 0.6f, 0.6f}, .roughness = 1};
  uint32_t mat = gi_mesh_builder_add_material(b, &m);
  double lo[3] = {o[0], o[1], o[2]}, hi[3] = {4, 3, 4};
  gi_mesh_builder_add_box(b, lo, hi, mat);
  gi_scene *s = build(b, "far-room", &sun, 1);
  double at[3] = {1000, 1.5, 2}, pts[6] = {1000, 1.5, 2, 1001, 2, 2};
  gi_bake_report rep;
  bake_gather_rep(s, at, &small_q, pts, 2, pr, &rep);
  gi_scene_release(s);
  uint64_t occ = 0;
  for (int d = 0; d < rep.levels; d++) occ += rep.occupied[d];
  printf("hardcase: scene outside every cascade: occupied voxels %llu, E(up) %.6f (exact 2.4), indirect %.3g\n",
         (unsigned long long)occ, mean3(pr[0].irradiance), mean3(pr[0].indirect));
  assert_int_equal(occ, 0);
  assert_true(fabs(mean3(pr[0].irradiance) - 2.4) <= 1e-5);
  assert_true(mean3(pr[0].indirect) == 0 && mean3(pr[1].indirect) == 0);

  /* A lamp panel (emitting 10 down) 1 m over a floor, the cascade 1000
   * units away: the plan leaves the emitter out of the voxels, but a probe
   * under it still reads its direct light, as a bake there does (it read
   * 0: a probe in the Cornell box baked from the box's camera). */
  b = gi_mesh_builder_new();
  mat = gi_mesh_builder_add_material(b, &m);
  gi_material lamp = {.albedo = {0, 0, 0}, .roughness = 1, .emission = {10, 10, 10}};
  uint32_t ml = gi_mesh_builder_add_material(b, &lamp);
  double f0[3] = {-2, 0, -2}, f1[3] = {-2, 0, 2}, f2[3] = {2, 0, 2}, f3[3] = {2, 0, -2};
  gi_mesh_builder_add_quad(b, f0, f1, f2, f3, mat);
  double l0[3] = {-0.5, 1, -0.5}, l1[3] = {0.5, 1, -0.5}, l2[3] = {0.5, 1, 0.5}, l3[3] = {-0.5, 1, 0.5};
  gi_mesh_builder_add_quad(b, l0, l1, l2, l3, ml);
  s = build(b, "far-lamp", NULL, 0);
  double under[3] = {0, 0.2, 0}, far_at[3] = {1000, 1, 0};
  gi_probe near_pr, far_pr;
  bake_gather_rep(s, under, &small_q, under, 1, &near_pr, &rep);
  assert_true(rep.effects[GI_FX_EMISSIVE].ran);
  bake_gather_rep(s, far_at, &small_q, under, 1, &far_pr, &rep);
  gi_scene_release(s);
  printf("hardcase: an emitter out of the cascade's reach (%s): probe under it, direct %.5f (baked there %.5f)\n",
         rep.effects[GI_FX_EMISSIVE].why, mean3(far_pr.direct), mean3(near_pr.direct));
  assert_false(rep.effects[GI_FX_EMISSIVE].ran);
  assert_true(mean3(near_pr.direct) > 1);
  for (int k = 0; k < 3; k++) assert_true(fabs(far_pr.direct[k] - near_pr.direct[k]) <= 1e-5 * near_pr.direct[k]);
}

/* gi_cascade_covers tells a point inside the cascade from one outside
 * every level, where the gather answers direct light only. */
static void test_covers(void **state) {
  const double o[3] = {0, 0, 0};
  gi_scene *s = room_scene(o, 0.6f, 10.f);
  gi_cascade *c = NULL;
  gi_error_info err = {0};
  assert_int_equal(gi_cascade_bake(s, room_at, &small_q, &c, NULL, &err), GI_OK);
  const double far[3] = {room_at[0] + 1e4, room_at[1], room_at[2]}, nan_pt[3] = {NAN, 0, 0};
  assert_int_equal(gi_cascade_covers(c, room_at), 1);
  assert_int_equal(gi_cascade_covers(c, far), 0);
  assert_int_equal(gi_cascade_covers(c, nan_pt), 0);
  assert_int_equal(gi_cascade_covers(NULL, room_at), 0);
  gi_probe p;
  assert_int_equal(gi_cascade_gather(c, far, 1, &p, NULL, &err), GI_OK);
  assert_true(p.indirect[0] == 0 && p.indirect[1] == 0 && p.indirect[2] == 0);
  gi_cascade_free(c);
  gi_scene_release(s);
}

/* ---- the furnace at albedo 0.99 ------------------------------------------ */

static void test_furnace_099(void **state) {
  const double a = 0.99, Le = 1.0;
  gi_scene *sc = tu_furnace_scene(1.0, a, Le);
  gi_quality q = {.levels = 3, .res = 32, .voxel0 = 1.25 / (32 * 4), .bounces = 8, .light_samples = 64,
                  .probe_samples = 8192, .threads = 2};
  double at[3] = {0.5, 0.5, 0.5}, pts[3] = {0.43, 0.55, 0.47};
  gi_probe pr;
  bake_gather(sc, at, &q, pts, 1, &pr);
  gi_scene_release(sc);
  /* k = 9 light bounces: Le (1 + a + ... + a^9); all bounces: Le / (1 - a) = 100. */
  double want = 0, p = 1;
  for (int i = 0; i <= 9; i++, p *= a) want += p;
  double direct = mean3(pr.direct) / PI, total = mean3(pr.irradiance) / PI;
  double ind = total - direct, want_ind = want - Le;
  printf("hardcase: furnace a=0.99, 8 bounces: indirect/pi %.5f (exact %.5f) rel.err %+.4f; total/pi %.5f "
         "(exact after 8 bounces %.5f, converged %.1f)\n",
         ind, want_ind, (ind - want_ind) / want_ind, total, want, Le / (1 - a));
  /* Direct: test_furnace's noise budget (4 sigma, 5.5%). Indirect: each
   * voxel bounce transfers about 0.5% too little in this closed cube, so
   * the relative error grows by a steady 0.30% per bounce (measured
   * -0.27%, -0.55%, -0.85% ... -2.34% for 1..8 bounces; test_furnace's
   * 1.5% covers its 3): stable, not diverging. Measured -2.34% at 8; bound
   * 3%, and the result must stay below the converged answer. */
  assert_true(fabs(direct - Le) <= 0.055 * Le);
  assert_true(total < Le / (1 - a));
  assert_true(fabs(ind - want_ind) <= 0.03 * want_ind);
}

/* Probes on the floor of a room lit by a lamp under its ceiling, and a
 * hair above it, the viewpoint among them, read the light a probe two
 * voxels up reads: irradiance is continuous as a point comes down to a
 * surface. They read 0.12x (on it: no near-surface rule, the upward
 * cones began in the floor's voxels and saw its underside) and 0.12-0.91x
 * (1e-4 to 0.6 voxels up: the ground rule kept their start unlifted). */
static void test_probe_on_floor(void **state) {
  (void)state;
  gi_mesh_builder *b = gi_mesh_builder_new();
  gi_material wall = {.albedo = {0.7f, 0.7f, 0.7f}, .roughness = 1};
  gi_material lamp = {.emission = {10, 10, 10}, .roughness = 1};
  uint32_t mw = gi_mesh_builder_add_material(b, &wall), ml = gi_mesh_builder_add_material(b, &lamp);
  /* A 4 m room wound inward (as an OBJ room is), the gi-bake default's s0. */
  double P[8][3];
  for (int i = 0; i < 8; i++) P[i][0] = (i & 1) ? 4 : 0, P[i][1] = (i & 2) ? 4 : 0, P[i][2] = (i & 4) ? 4 : 0;
  static const int qd[6][4] = {{0, 2, 6, 4}, {1, 5, 7, 3}, {0, 4, 5, 1}, {2, 3, 7, 6}, {0, 1, 3, 2}, {4, 6, 7, 5}};
  for (int f = 0; f < 6; f++) gi_mesh_builder_add_quad(b, P[qd[f][0]], P[qd[f][1]], P[qd[f][2]], P[qd[f][3]], mw);
  double A[3] = {1.5, 3.9, 1.5}, B[3] = {2.5, 3.9, 1.5}, C[3] = {2.5, 3.9, 2.5}, D[3] = {1.5, 3.9, 2.5};
  gi_mesh_builder_add_quad(b, A, B, C, D, ml); /* facing down */
  gi_scene *s = build(b, "lamp-room", NULL, 0);
  const double s0 = 5.0 / 1024;
  gi_quality q = {.levels = 6, .res = 32, .voxel0 = s0, .bounces = 1, .light_samples = 4, .probe_samples = 16,
                  .threads = 2};
  const double at[3] = {2, 0, 2}, ys[5] = {0, 1e-4 * s0, 0.2 * s0, 0.6 * s0, 2 * s0};
  double pts[15];
  for (int i = 0; i < 5; i++) pts[3 * i] = 2, pts[3 * i + 1] = ys[i], pts[3 * i + 2] = 2;
  gi_probe pr[5];
  bake_gather(s, at, &q, pts, 5, pr);
  gi_scene_release(s);
  double ref = mean3(pr[4].indirect), worst = 0;
  assert_true(ref > 0);
  for (int i = 0; i < 4; i++) {
    double r = mean3(pr[i].indirect) / ref;
    printf("hardcase: probe %.4g voxels above the floor: indirect %.5f, %.3fx the one 2 voxels up\n", ys[i] / s0,
           mean3(pr[i].indirect), r);
    worst = fmax(worst, fabs(r - 1));
  }
  /* Measured 0.0% off after the fix (all start a lifted voxel up); bound 5%. */
  assert_true(worst < 0.05);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_far_origin),
      cmocka_unit_test(test_stray_triangle),
      cmocka_unit_test(test_thin_wall),
      cmocka_unit_test(test_thin_wall_view),
      cmocka_unit_test(test_thin_wall_near_probes),
      cmocka_unit_test(test_probes_beside_wall),
      cmocka_unit_test(test_probe_in_gap),
      cmocka_unit_test(test_sealed_room_corner),
      cmocka_unit_test(test_sealed_room_inside),
      cmocka_unit_test(test_probe_under_ceiling),
      cmocka_unit_test(test_panorama_beside_wall),
      cmocka_unit_test(test_covers),
      cmocka_unit_test(test_border_steps),
      cmocka_unit_test(test_degenerate_triangles),
      cmocka_unit_test(test_albedo_extremes),
      cmocka_unit_test(test_light_extremes),
      cmocka_unit_test(test_empty_and_outside),
      cmocka_unit_test(test_furnace_099),
      cmocka_unit_test(test_probe_on_floor),
      cmocka_unit_test(test_panel_under_ceiling),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
