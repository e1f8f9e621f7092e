/* test_ground.c: which surface street-level probe grids stand on, and which
 * covered probes count as inside a building (probe_grid.c), on scenes of a
 * few boxes: a closed ground slab, a street over a tunnel, a canopy in a
 * square walled in on every side, a footbridge over a street closed at
 * both ends. Every kept probe must be HEIGHT above the ground one walks on
 * (y = 0 in all of them). */
#define _POSIX_C_SOURCE 200809L
#include "test_util.h"
#include <math.h>
#include <stdio.h>
#include <string.h>
#include "gi/gi.h"

#define HEIGHT 2.0

static gi_mesh_builder *new_builder(uint32_t *mat) {
  gi_mesh_builder *b = gi_mesh_builder_new();
  gi_material m = {.albedo = {0.5f, 0.5f, 0.5f}, .roughness = 1};
  *mat = gi_mesh_builder_add_material(b, &m);
  return b;
}

static void box(gi_mesh_builder *b, uint32_t mat, double x0, double y0, double z0, double x1, double y1, double z1) {
  double lo[3] = {x0, y0, z0}, hi[3] = {x1, y1, z1};
  gi_mesh_builder_add_box(b, lo, hi, mat);
}

/* The plane y = h over [x0, x1] x [z0, z1], facing up (down when down). */
static void level_quad(gi_mesh_builder *b, uint32_t mat, double x0, double z0, double x1, double z1, double h,
                       int down) {
  double p0[3] = {x0, h, z0}, p1[3] = {x0, h, z1}, p2[3] = {x1, h, z1}, p3[3] = {x1, h, z0};
  if (down) gi_mesh_builder_add_quad(b, p3, p2, p1, p0, mat);
  else gi_mesh_builder_add_quad(b, p0, p1, p2, p3, mat);
}

static gi_probe_grid street_grid(gi_scene *s, double spacing, const double lo[3], const double hi[3]) {
  gi_grid_spec spec = {.spacing = spacing, .above_ground = HEIGHT, .have_region = 1};
  memcpy(spec.lo, lo, sizeof spec.lo), memcpy(spec.hi, hi, sizeof spec.hi);
  gi_probe_grid g;
  gi_error_info err = {0};
  assert_int_equal(gi_probe_grid_build(s, &spec, &g, &err), GI_OK);
  return g;
}

/* Counts the probes at y = HEIGHT that are kept. */
static size_t kept_at_height(const gi_probe_grid *g) {
  size_t n = 0;
  for (size_t i = 0; i < g->n; i++) n += g->state[i] == GI_GRID_VALID && fabs(g->pos[3 * i + 1] - HEIGHT) < 1e-3;
  return n;
}

/* The ground as a closed slab T thick (its top at y = 0) under a closed
 * building: the lowest surface was the slab's bottom, so every probe stood
 * at HEIGHT - T (1 m thick: all at y = 1; 3 m: at y = -1 inside the slab,
 * 384 of 400 dropped as inside). */
static void test_closed_ground_slab(void **state) {
  (void)state;
  const double thick[2] = {1, 3};
  for (int k = 0; k < 2; k++) {
    uint32_t mat;
    gi_mesh_builder *b = new_builder(&mat);
    box(b, mat, 0, -thick[k], 0, 100, 0, 100);
    box(b, mat, 20, 0, 20, 40, 10, 40);
    gi_scene *s = tu_build(b, "slab", NULL, 0);
    double lo[3] = {2.5, -thick[k] - 1, 2.5}, hi[3] = {97.5, 20, 97.5};
    gi_probe_grid g = street_grid(s, 5, lo, hi);
    assert_int_equal(g.n, 400);
    size_t bad = 0;
    for (size_t i = 0; i < g.n; i++) {
      double x = g.pos[3 * i], z = g.pos[3 * i + 2];
      int in = x > 20 && x < 40 && z > 20 && z < 40;
      bad += fabs(g.pos[3 * i + 1] - HEIGHT) > 1e-3 || g.state[i] != (in ? GI_GRID_INSIDE : GI_GRID_VALID);
    }
    printf("slab %g m thick: %zu kept, %zu inside, %zu at the wrong height or state; first probe at y = %g\n",
           thick[k], g.num_valid, g.num_inside, bad, g.pos[1]);
    assert_int_equal(bad, 0);
    assert_int_equal(g.num_inside, 16); /* x, z in {22.5 .. 37.5}: the building */
    assert_int_equal(g.num_valid, 384);
    gi_probe_grid_free(&g);
    gi_scene_release(s);
  }
}

/* A street (a plane at y = 0) over an open tunnel 10 m wide along x, its
 * floor at -8 and ceiling at -3 wound inward as a room: the columns over
 * the tunnel took its floor, probes at y = -6 inside it. */
static void test_street_over_tunnel(void **state) {
  (void)state;
  uint32_t mat;
  gi_mesh_builder *b = new_builder(&mat);
  level_quad(b, mat, 0, 0, 100, 100, 0, 0);
  level_quad(b, mat, 0, 45, 100, 55, -8, 0);
  level_quad(b, mat, 0, 45, 100, 55, -3, 1);
  double w0[3] = {0, -8, 45}, w1[3] = {100, -8, 45}, w2[3] = {100, -3, 45}, w3[3] = {0, -3, 45};
  gi_mesh_builder_add_quad(b, w0, w1, w2, w3, mat); /* faces +z, into the tunnel */
  double v0[3] = {0, -8, 55}, v1[3] = {0, -3, 55}, v2[3] = {100, -3, 55}, v3[3] = {100, -8, 55};
  gi_mesh_builder_add_quad(b, v0, v1, v2, v3, mat); /* faces -z */
  gi_scene *s = tu_build(b, "tunnel", NULL, 0);
  double lo[3] = {2.5, -10, 2.5}, hi[3] = {97.5, 5, 97.5};
  gi_probe_grid g = street_grid(s, 5, lo, hi);
  size_t over = 0, over_ok = 0;
  for (size_t i = 0; i < g.n; i++) {
    double z = g.pos[3 * i + 2];
    if (z > 45 && z < 55) over++, over_ok += g.state[i] == GI_GRID_VALID && fabs(g.pos[3 * i + 1] - HEIGHT) < 1e-3;
  }
  printf("street over a tunnel: %zu of %zu kept at y = %g; over the tunnel %zu of %zu\n", kept_at_height(&g), g.n,
         HEIGHT, over_ok, over);
  assert_int_equal(over, 40);
  assert_int_equal(over_ok, 40);
  assert_int_equal(kept_at_height(&g), 400);
  gi_probe_grid_free(&g);
  gi_scene_release(s);
}

/* A 20 x 20 m canopy 5 m up over the middle of a 200 m square walled in by
 * 15 m blocks 60 m off on every side, as a closed box on four pillars or
 * as a single sheet facing down: every horizontal ray from under it hits a
 * block, so all 25 probes under it were dropped as inside. (A sheet facing
 * up is a roof seen from inside: the probes under it stay dropped.) */
static void test_canopy_in_a_square(void **state) {
  (void)state;
  for (int kind = 0; kind < 2; kind++) {
    uint32_t mat;
    gi_mesh_builder *b = new_builder(&mat);
    level_quad(b, mat, 0, 0, 200, 200, 0, 0);
    if (kind == 0) {
      box(b, mat, 90, 5, 90, 110, 5.5, 110);
      for (int p = 0; p < 4; p++) {
        double x = p & 1 ? 109 : 90, z = p & 2 ? 109 : 90;
        box(b, mat, x, 0, z, x + 1, 5, z + 1);
      }
    } else {
      level_quad(b, mat, 90, 90, 110, 110, 5, 1);
    }
    box(b, mat, 20, 0, 20, 180, 15, 30);
    box(b, mat, 20, 0, 170, 180, 15, 180);
    box(b, mat, 20, 0, 30, 30, 15, 170);
    box(b, mat, 170, 0, 30, 180, 15, 170);
    gi_scene *s = tu_build(b, "plaza", NULL, 0);
    double lo[3] = {92, 0, 92}, hi[3] = {108, 20, 108};
    gi_probe_grid g = street_grid(s, 4, lo, hi);
    printf("canopy (%s): %zu of %zu kept at y = %g, %zu dropped as inside\n",
           kind == 0 ? "box on pillars" : "sheet facing down", kept_at_height(&g), g.n,
           HEIGHT, g.num_inside);
    assert_int_equal(g.n, 25);
    assert_int_equal(kept_at_height(&g), 25);
    gi_probe_grid_free(&g);
    gi_scene_release(s);
  }
}

/* A 20 m street between two rows of 20 m blocks, closed 160 m apart by a
 * block at each end, under a 10 m wide footbridge (deck 8..10 m up): the
 * probes under the deck were dropped (every ray met a facade). */
static void test_footbridge_over_street(void **state) {
  (void)state;
  uint32_t mat;
  gi_mesh_builder *b = new_builder(&mat);
  level_quad(b, mat, 0, 0, 200, 200, 0, 0);
  box(b, mat, 0, 0, 0, 200, 20, 90);
  box(b, mat, 0, 0, 110, 200, 20, 200);
  box(b, mat, 95, 8, 90, 105, 10, 110);
  box(b, mat, 0, 0, 90, 20, 20, 110);
  box(b, mat, 180, 0, 90, 200, 20, 110);
  gi_scene *s = tu_build(b, "bridge", NULL, 0);
  double lo[3] = {22, 0, 92}, hi[3] = {178, 30, 108};
  gi_probe_grid g = street_grid(s, 4, lo, hi);
  size_t under = 0, under_ok = 0;
  for (size_t i = 0; i < g.n; i++) {
    double x = g.pos[3 * i];
    if (x > 95 && x < 105) under++, under_ok += g.state[i] == GI_GRID_VALID && fabs(g.pos[3 * i + 1] - HEIGHT) < 1e-3;
  }
  printf("street under a footbridge: %zu of %zu kept at y = %g; under the deck %zu of %zu\n", kept_at_height(&g),
         g.n, HEIGHT, under_ok, under);
  assert_int_equal(g.n, 200);
  assert_int_equal(under, 10); /* x = 98, 102 */
  assert_int_equal(under_ok, 10);
  assert_int_equal(kept_at_height(&g), 200);
  gi_probe_grid_free(&g);
  gi_scene_release(s);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_closed_ground_slab),
      cmocka_unit_test(test_street_over_tunnel),
      cmocka_unit_test(test_canopy_in_a_square),
      cmocka_unit_test(test_footbridge_over_street),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
