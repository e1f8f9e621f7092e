/* test_street.c: street-level light, the cities' hard cases, against the
 * reference path tracer.
 *
 * (1) A street canyon between two closed buildings, the western facade in
 *     the sun: street probes 1.7 m up read the facades' light through
 *     coarse voxels whose footprint also holds the ground under the probe.
 *     The probe gather keeps the surface rule over the ground (see
 *     gi__gather_probe_hemispheres): mean ratio cone / reference 1.16,
 *     where reading the ground's underside as an occluder gave 0.76.
 * (2) A lamp 0.1 m under its housing: the housing reflects about a quarter
 *     of the lamp's light back down, the largest share of a lit street's
 *     indirect light. The housing's centroid lies inside it, so its shadow
 *     ray met its own faces and the housing stayed black (cone 0.000 against
 *     the reference's 6.75 under the lamp); averaging the irradiance over a
 *     disc of the voxel's area gave 0.41 of the reference; lighting the
 *     voxel's own pieces of triangle by their solid angle from the lamp
 *     (light/near_field.c) gives 0.86 there. Over five probes from under
 *     the lamp to 3.8 m aside the cones read 0.70 to 1.11 of the reference
 *     (mean 0.87): the coarse voxels spread the 0.5 m housing over 1-2 m,
 *     so the cone pointing at it reads part of its light and its
 *     neighbours the rest. Until the march weighted a voxel's faces by
 *     their projected area (test_cone's box voxel) tilted cones over-read
 *     the housing's lit underside, and the same probes read 0.85 to 1.29
 *     (mean 1.07).
 * (3) gi_scene_clearance, which keeps gi-accuracy's street probes out of
 *     walls, against distances known by construction.
 * (4) A wall hidden behind a sunlit facade, inside its building, in a
 *     synthetic canyon and on Munich's street past the Neues Rathaus. */
#include <math.h>
#include <stdio.h>
#include <string.h>
#include "gi/gi.h"
#include "test_util.h"

#define STREET_PROBES 7
#define REF_PATHS 16384

/* Two closed 20 m blocks either side of a 14 m street along z (x in -7..7),
 * a black street, the sun from the west-southwest 53 degrees up. */
static gi_scene *canyon_scene_hidden(const gi_light *light, double hidden) {
  gi_mesh_builder *b = gi_mesh_builder_new();
  gi_material wall = {{0.8f, 0.8f, 0.8f}, {0, 0, 0}, 1, 0, "wall", 0, {0}}, street = {{0, 0, 0}, {0, 0, 0}, 1, 0, "street", 0, {0}};
  uint32_t mw = gi_mesh_builder_add_material(b, &wall), ms = gi_mesh_builder_add_material(b, &street);
  double w0[3] = {-27, 0, -100}, w1[3] = {-7, 20, 100}, e0[3] = {7, 0, -100}, e1[3] = {27, 20, 100};
  gi_mesh_builder_add_box(b, w0, w1, mw);
  gi_mesh_builder_add_box(b, e0, e1, mw);
  const double g0[3] = {-7, 0, -100}, g1[3] = {-7, 0, 100}, g2[3] = {7, 0, 100}, g3[3] = {7, 0, -100};
  gi_mesh_builder_add_quad(b, g0, g1, g2, g3, ms);
  if (hidden > 0) {
    /* A second wall `hidden` behind the western facade, inside its block, facing the street too. */
    double x = -7 - hidden, h0[3] = {x, 0, -100}, h1[3] = {x, 20, -100}, h2[3] = {x, 20, 100}, h3[3] = {x, 0, 100};
    gi_mesh_builder_add_quad(b, h0, h1, h2, h3, mw);
  }
  gi_scene_options so = {.up = GI_UP_Y, .lights = light, .num_lights = 1};
  gi_scene *s = NULL;
  gi_error_info err = {0};
  gi_result rc = gi_scene_build(b, "canyon", &so, &s, &err);
  gi_mesh_builder_free(b);
  if (rc) fprintf(stderr, "canyon: %s\n", err.msg);
  assert_int_equal(rc, GI_OK);
  return s;
}

static gi_scene *canyon_scene(const gi_light *light) { return canyon_scene_hidden(light, 0); }

/* Mean over the probes of cone / reference indirect irradiance (green),
 * one voxel bounce's light (the reference limited to one reflection). */
static double street_ratio(gi_scene *s, const double *pts, int n, const char *what) {
  gi_ref_probe ref[STREET_PROBES];
  gi_probe pr[STREET_PROBES];
  gi_error_info err = {0};
  gi_reference_opts ro = {.samples = REF_PATHS, .max_depth = 1, .seed = 3};
  assert_int_equal(gi_reference_irradiance(s, pts, (size_t)n, &ro, ref, NULL, &err), GI_OK);
  gi_quality q = {.bounces = -1};
  double at[3] = {0.1, 1.7, 0.3};
  gi_cascade *c = NULL;
  assert_int_equal(gi_cascade_bake(s, at, &q, &c, NULL, &err), GI_OK);
  assert_int_equal(gi_cascade_gather(c, pts, (size_t)n, pr, NULL, &err), GI_OK);
  double sum = 0;
  for (int i = 0; i < n; i++) {
    assert_true(ref[i].indirect[1] > 0 && isfinite(pr[i].indirect[1]));
    double r = pr[i].indirect[1] / ref[i].indirect[1];
    printf("street %s: x %5.1f cone %.4f reference %.4f (+- %.4f) ratio %.3f\n", what, pts[3 * i], pr[i].indirect[1],
           ref[i].indirect[1], ref[i].std_err_indirect[1], r);
    sum += r;
  }
  gi_cascade_free(c);
  return sum / n;
}

static void street_points(double *pts) {
  for (int i = 0; i < STREET_PROBES; i++) pts[3 * i] = -6 + 2 * i, pts[3 * i + 1] = 1.7, pts[3 * i + 2] = 0.3;
}

static void test_canyon_sun(void **state) {
  (void)state;
  gi_light sun = {.type = GI_LIGHT_SUN, .color = {3, 3, 3}, .direction = {-0.6f, -0.8f, 0}};
  gi_scene *s = canyon_scene(&sun);
  double pts[3 * STREET_PROBES];
  street_points(pts);
  double r = street_ratio(s, pts, STREET_PROBES, "sun");
  printf("street canyon, sun: mean ratio cone / reference %.3f\n", r);
  /* Measured 1.157 (1.136 with the faces weighted by w_a^2, 0.756 before
   * the ground rule); the reference's own error is 1.2%, the rest is the
   * cones' coarse reading of a street whose light changes 2.4x across it. */
  assert_true(r >= 0.9 && r <= 1.2);
  gi_scene_release(s);
}

/* The sunlit facade with a second wall 0.2 m behind it, inside the block
 * and facing the street too (OpenStreetMap buildings often hold such a
 * wall: a building part drawn over another; Munich's Neues Rathaus has
 * one 0.55 m behind its front). The path tracer cannot see it; the cones
 * must not either. Measured mean ratio 0.582 against 1.157 without the
 * wall (0.901 with it 0.55 m behind): a coarse voxel holding both spread
 * the sun over both walls' area, half of it dark behind the facade, and
 * on the finest level light and cones started between the walls, behind
 * the outer one. Now a coarse voxel's sides count only the pieces no
 * other piece in the voxel hides (light/near_field.c, hidden_side), and
 * a side starts at its front-most piece (cascade/voxelize.c,
 * side_offsets): 1.162 (1.161 at 0.55 m). */
static void test_canyon_hidden_wall(void **state) {
  (void)state;
  gi_light sun = {.type = GI_LIGHT_SUN, .color = {3, 3, 3}, .direction = {-0.6f, -0.8f, 0}};
  gi_scene *s = canyon_scene(&sun), *h = canyon_scene_hidden(&sun, 0.2);
  double pts[3 * STREET_PROBES];
  street_points(pts);
  double r = street_ratio(s, pts, STREET_PROBES, "sun"), rh = street_ratio(h, pts, STREET_PROBES, "hidden wall");
  printf("street canyon, a wall hidden behind the sunlit facade: mean ratio %.3f (%.3f without it)\n", rh, r);
  assert_true(fabs(rh - r) <= 0.05);
  assert_true(rh >= 0.9 && rh <= 1.2);
  gi_scene_release(s);
  gi_scene_release(h);
}

/* Munich's street past the Neues Rathaus (OpenStreetMap, sun and sky):
 * eleven probes 1.7 m up along 70 m of it, baked at the middle one. The
 * Rathaus front there is two walls 0.55 m apart, both facing the street
 * (see test_canyon_hidden_wall): measured mean ratio cone / reference
 * 0.756 [0.550, 1.091] and indirect error 26.0% before, 0.994 [0.901,
 * 1.119] and 4.9% now. Bounds: the mean within 0.85..1.15, each probe
 * within 0.7..1.3. */
#define MUNICH_PROBES 11
static void test_munich_street(void **state) {
  (void)state;
  TU_SKIP_IF_NO_SCENE(path, "munich/munich.obj");
  gi_scene *s = NULL;
  gi_error_info err = {0};
  gi_scene_options so = {.up = GI_UP_Z, .default_lights = 1};
  assert_int_equal(gi_scene_load(path, &so, &s, &err), GI_OK);
  double pts[3 * MUNICH_PROBES];
  for (int i = 0; i < MUNICH_PROBES; i++) {
    /* Along the street's centre line, (-45.1, -2.7) to (-64.5, -69.9). */
    double t = (double)i / (MUNICH_PROBES - 1);
    pts[3 * i] = -45.105 + t * (-64.478 + 45.105), pts[3 * i + 1] = -2.656 + t * (-69.922 + 2.656);
    pts[3 * i + 2] = 1.7;
  }
  gi_ref_probe ref[MUNICH_PROBES];
  gi_reference_opts ro = {.samples = REF_PATHS, .seed = 3};
  assert_int_equal(gi_reference_irradiance(s, pts, MUNICH_PROBES, &ro, ref, NULL, &err), GI_OK);
  gi_quality q = {0};
  gi_cascade *c = NULL;
  gi_probe pr[MUNICH_PROBES];
  assert_int_equal(gi_cascade_bake(s, &pts[3 * (MUNICH_PROBES / 2)], &q, &c, NULL, &err), GI_OK);
  assert_int_equal(gi_cascade_gather(c, pts, MUNICH_PROBES, pr, NULL, &err), GI_OK);
  double mean = 0, mre = 0, lo = INFINITY, hi = 0;
  for (int i = 0; i < MUNICH_PROBES; i++) {
    double cone = 0, r = 0;
    for (int k = 0; k < 3; k++) cone += pr[i].indirect[k] / 3, r += ref[i].indirect[k] / 3;
    assert_true(r > 0 && isfinite(cone));
    printf("munich street: (%.1f, %.1f) cone %.4f reference %.4f ratio %.3f\n", pts[3 * i], pts[3 * i + 1], cone, r,
           cone / r);
    mean += cone / r / MUNICH_PROBES, mre += fabs(cone - r) / r / MUNICH_PROBES;
    lo = fmin(lo, cone / r), hi = fmax(hi, cone / r);
  }
  printf("munich street: mean ratio %.3f [%.3f, %.3f], indirect error %.1f%%\n", mean, lo, hi, 100 * mre);
  assert_true(mean >= 0.85 && mean <= 1.15);
  assert_true(lo >= 0.7 && hi <= 1.3);
  gi_cascade_free(c);
  gi_scene_release(s);
}

#define HOUSING_PROBES 5
static void test_lamp_housing(void **state) {
  (void)state;
  gi_light lamp = {.type = GI_LIGHT_POINT, .color = {120, 120, 120}, .position = {0, 5.9, 0}};
  gi_mesh_builder *b = gi_mesh_builder_new();
  gi_material white = {{0.8f, 0.8f, 0.8f}, {0, 0, 0}, 1, 0, "housing", 0, {0}}, dark = {{0.1f, 0.1f, 0.1f}, {0, 0, 0}, 1, 0, "ground", 0, {0}};
  uint32_t mw = gi_mesh_builder_add_material(b, &white), mg = gi_mesh_builder_add_material(b, &dark);
  double h0[3] = {-0.25, 6, -0.25}, h1[3] = {0.25, 6.5, 0.25}, g0[3] = {-20, -1, -20}, g1[3] = {20, 0, 20};
  gi_mesh_builder_add_box(b, h0, h1, mw);
  gi_mesh_builder_add_box(b, g0, g1, mg);
  gi_scene_options so = {.up = GI_UP_Y, .lights = &lamp, .num_lights = 1};
  gi_scene *s = NULL;
  gi_error_info err = {0};
  assert_int_equal(gi_scene_build(b, "lamp", &so, &s, &err), GI_OK);
  gi_mesh_builder_free(b);
  /* Under the lamp and aside from it, each probe with its own bake (the
   * cascade centred on it, as a server request would). */
  const double aside[HOUSING_PROBES] = {0.3, 1.0, 1.8, 2.6, 3.8};
  double mean = 0, lo = INFINITY, hi = 0;
  for (int i = 0; i < HOUSING_PROBES; i++) {
    double p[3] = {aside[i], 1.7, 0.2};
    gi_ref_probe ref;
    gi_reference_opts ro = {.samples = 1 << 16, .max_depth = 1, .seed = 3};
    assert_int_equal(gi_reference_irradiance(s, p, 1, &ro, &ref, NULL, &err), GI_OK);
    gi_quality q = {.bounces = -1, .voxel0 = 0.25};
    gi_cascade *c = NULL;
    gi_probe pr;
    assert_int_equal(gi_cascade_bake(s, p, &q, &c, NULL, &err), GI_OK);
    assert_int_equal(gi_cascade_gather(c, p, 1, &pr, NULL, &err), GI_OK);
    double r = pr.indirect[1] / ref.indirect[1];
    printf("lamp housing: indirect %.1f m aside, cone %.4f reference %.4f (+- %.4f) ratio %.3f\n", aside[i],
           pr.indirect[1], ref.indirect[1], ref.std_err_indirect[1], r);
    mean += r / HOUSING_PROBES, lo = fmin(lo, r), hi = fmax(hi, r);
    gi_cascade_free(c);
  }
  printf("lamp housing: mean ratio %.3f, %.3f to %.3f\n", mean, lo, hi);
  /* Measured 0.874, 0.701 to 1.108 (see the header). */
  assert_true(mean >= 0.8 && mean <= 1.2);
  assert_true(lo >= 0.65 && hi <= 1.2);
  gi_scene_release(s);
}

static void test_clearance(void **state) {
  (void)state;
  gi_light sun = {.type = GI_LIGHT_SUN, .color = {3, 3, 3}, .direction = {-0.6f, -0.8f, 0}};
  gi_scene *s = canyon_scene(&sun);
  /* 1.7 m over the street, 2 m from the western facade: the street is nearest. */
  double p[3] = {-5, 1.7, 0.3};
  assert_float_equal(gi_scene_clearance(s, p, 100), 1.7, 1e-4);
  /* In the facade's plane: no room. */
  double in_wall[3] = {-7, 5, 0.3};
  assert_true(gi_scene_clearance(s, in_wall, 100) < 1e-3);
  /* 40 m over the street's middle: straight down meets the street at 40,
   * the face diagonals down and sideways meet a roof at (+-20, 20): 20 sqrt 2. */
  double mid[3] = {0, 40, 0.3};
  assert_float_equal(gi_scene_clearance(s, mid, 100), 20.0 * sqrt(2.0), 1e-3);
  /* Capped at max; bad input gives 0. */
  double sky[3] = {0, 500, 0.3}, bad[3] = {NAN, 0, 0};
  assert_float_equal(gi_scene_clearance(s, sky, 10), 10, 0);
  assert_float_equal(gi_scene_clearance(s, bad, 10), 0, 0);
  assert_float_equal(gi_scene_clearance(s, p, 0), 0, 0);
  gi_scene_release(s);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_canyon_sun),
      cmocka_unit_test(test_canyon_hidden_wall),
      cmocka_unit_test(test_munich_street),
      cmocka_unit_test(test_lamp_housing),
      cmocka_unit_test(test_clearance),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
