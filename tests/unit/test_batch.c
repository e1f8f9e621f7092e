/* test_batch.c: batch probe grids (gi_batch.h): where street-level probes
 * go, checked against the geometry that decides it, and the probe EXR and
 * VDB read back value by value.
 *
 * The street scene is a 100 x 100 m ground (Y up) with two closed
 * buildings and an open roof plate (an arcade) over a street: probes
 * inside the buildings must be dropped, probes under the plate kept, every
 * kept probe 2 m above the ground (not above a roof or the plate). */
#define _POSIX_C_SOURCE 200809L
#include "test_util.h"
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "gi/gi.h"

#define SPACING 5.0
#define HEIGHT 2.0

/* Footprints (x0, z0, x1, z1) and heights of the closed buildings. */
static const double kBuildings[2][5] = {{12, 12, 28, 28, 20}, {61, 52, 79, 88, 10}};
/* The open roof plate: x in [41, 49], all z, at y = 6. */
static const double kPlate[3] = {41, 49, 6};

static gi_scene *street_scene(void) {
  gi_mesh_builder *b = gi_mesh_builder_new();
  gi_material m = {.albedo = {0.5f, 0.5f, 0.5f}, .roughness = 1};
  uint32_t mat = gi_mesh_builder_add_material(b, &m);
  /* The ground overhangs the grid so no column sits on its edge. */
  double g0[3] = {-1, 0, -1}, g1[3] = {-1, 0, 101}, g2[3] = {101, 0, 101}, g3[3] = {101, 0, -1};
  gi_mesh_builder_add_quad(b, g0, g1, g2, g3, mat);
  for (int i = 0; i < 2; i++) {
    const double *k = kBuildings[i];
    double lo[3] = {k[0], 0, k[1]}, hi[3] = {k[2], k[4], k[3]};
    gi_mesh_builder_add_box(b, lo, hi, mat);
  }
  double p0[3] = {kPlate[0], kPlate[2], 0}, p1[3] = {kPlate[0], kPlate[2], 100}, p2[3] = {kPlate[1], kPlate[2], 100},
         p3[3] = {kPlate[1], kPlate[2], 0};
  gi_mesh_builder_add_quad(b, p3, p2, p1, p0, mat);
  gi_scene_options so = {.up = GI_UP_Y, .threads = 1};
  gi_scene *s = NULL;
  gi_error_info err = {0};
  assert_int_equal(gi_scene_build(b, "street", &so, &s, &err), GI_OK);
  gi_mesh_builder_free(b);
  return s;
}

/* A closed 4 x 2 x 2 room moved by off on every axis. */
static gi_scene *room_at(double off) {
  gi_mesh_builder *b = gi_mesh_builder_new();
  gi_material m = {.albedo = {0.8f, 0.8f, 0.8f}, .roughness = 1};
  uint32_t mat = gi_mesh_builder_add_material(b, &m);
  double lo[3] = {off, off, off}, hi[3] = {off + 4, off + 2, off + 2};
  gi_mesh_builder_add_box(b, lo, hi, mat);
  gi_scene_options so = {.up = GI_UP_Y, .threads = 1};
  gi_scene *s = NULL;
  gi_error_info err = {0};
  assert_int_equal(gi_scene_build(b, "room", &so, &s, &err), GI_OK);
  gi_mesh_builder_free(b);
  return s;
}

/* A grid 1e7 from the origin, 0.25 apart, and 1e6 away, 0.02 apart: the
 * same points relative to the scene as at the origin. Positions were
 * float, 1 unit coarse at 1e7: 45 distinct points of 1377, each baked
 * where its neighbours were (1261 probes more than 1% off). Both the lattice
 * and street-level columns. */
static void test_grid_far_from_origin(void **state) {
  (void)state;
  const double offs[2] = {1e7, 1e6}, steps[2] = {0.25, 0.02};
  for (int k = 0; k < 2; k++)
    for (int street = 0; street < 2; street++) {
      gi_probe_grid g[2];
      for (int f = 0; f < 2; f++) {
        double o = f ? offs[k] : 0;
        gi_scene *s = room_at(o);
        /* The whole room at 1e7 (17 x 9 x 9), a corner of it at 1e6. */
        gi_grid_spec spec = {.spacing = steps[k], .have_region = 1, .above_ground = street ? 0.5 : 0,
                             .lo = {o + (k ? 0.9 : 0), o + (k ? 0.1 : 0), o + (k ? 0.9 : 0)},
                             .hi = {o + (k ? 1.1 : 4), o + (k ? 1.0 : 2), o + (k ? 1.0 : 2)}};
        gi_error_info err = {0};
        assert_int_equal(gi_probe_grid_build(s, &spec, &g[f], &err), GI_OK);
        gi_scene_release(s);
      }
      assert_int_equal(g[0].n, g[1].n);
      assert_int_equal(g[0].num_valid, g[1].num_valid);
      double worst = 0;
      for (size_t i = 0; i < 3 * g[0].n; i++) worst = fmax(worst, fabs((g[1].pos[i] - offs[k]) - g[0].pos[i]));
      printf("grid %g apart %g from the origin%s: %zu points, largest shift from the origin's %.3g\n", steps[k],
             offs[k], street ? ", street level" : "", g[0].n, worst);
      assert_true(worst < 1e-6);
      for (int f = 0; f < 2; f++) gi_probe_grid_free(&g[f]);
    }
}

static int in_building(double x, double z) {
  for (int i = 0; i < 2; i++)
    if (x > kBuildings[i][0] && x < kBuildings[i][2] && z > kBuildings[i][1] && z < kBuildings[i][3]) return 1;
  return 0;
}

static void test_street_level_against_geometry(void **state) {
  (void)state;
  gi_scene *s = street_scene();
  gi_grid_spec spec = {.spacing = SPACING, .above_ground = HEIGHT, .have_region = 1, .lo = {0, 0, 0}, .hi = {100, 30, 100}};
  gi_probe_grid g;
  gi_error_info err = {0};
  assert_int_equal(gi_probe_grid_build(s, &spec, &g, &err), GI_OK);
  assert_int_equal(g.counts[0], 21);
  assert_int_equal(g.counts[1], 1);
  assert_int_equal(g.counts[2], 21);
  assert_int_equal(g.up_axis, 1);
  size_t inside = 0, under_plate = 0;
  for (size_t i = 0; i < g.n; i++) {
    double x = g.pos[3 * i], y = g.pos[3 * i + 1], z = g.pos[3 * i + 2];
    assert_float_equal(x, SPACING * (double)(i % 21), 1e-4);
    assert_float_equal(z, SPACING * (double)(i / 21), 1e-4);
    /* Every column has ground, so the probe is 2 m above it, never above a roof or the plate. */
    assert_float_equal(y, HEIGHT, 1e-3);
    int expect_inside = in_building(x, z);
    assert_int_equal(g.state[i], expect_inside ? GI_GRID_INSIDE : GI_GRID_VALID);
    inside += (size_t)expect_inside;
    under_plate += x > kPlate[0] && x < kPlate[1];
  }
  /* Building A covers x,z in {15,20,25}^2, B x in {65,70,75} by z in {55..85}: 9 + 21. */
  assert_int_equal(inside, 30);
  assert_int_equal(g.num_inside, 30);
  assert_int_equal(g.num_valid, g.n - 30);
  assert_int_equal(g.num_no_ground, 0);
  assert_int_equal(under_plate, 21); /* x = 45: kept although covered */
  gi_probe_grid_free(&g);
  gi_scene_release(s);
}

/* A grid over the scene's bounds puts its last row and column on the
 * ground's outer edge; Embree counts a ray along a boundary edge on one
 * side only, so those columns all read "no ground" (21 of 121 here). */
static void test_street_level_on_the_bounds(void **state) {
  (void)state;
  /* A 200 m ground in 4 x 4 quads, wound as an exporter wrote one (a, d, c, b). */
  gi_mesh_builder *b = gi_mesh_builder_new();
  gi_material m = {.albedo = {0.5f, 0.5f, 0.5f}, .roughness = 1};
  uint32_t mat = gi_mesh_builder_add_material(b, &m);
  for (int i = 0; i < 4; i++)
    for (int j = 0; j < 4; j++) {
      double x0 = -100 + 50 * i, x1 = x0 + 50, z0 = -100 + 50 * j, z1 = z0 + 50;
      double qa[3] = {x0, 0, z0}, qb[3] = {x1, 0, z0}, qc[3] = {x1, 0, z1}, qd[3] = {x0, 0, z1};
      gi_mesh_builder_add_quad(b, qa, qd, qc, qb, mat);
    }
  gi_scene_options so = {.up = GI_UP_Y, .threads = 1};
  gi_scene *s = NULL;
  gi_error_info e0 = {0};
  assert_int_equal(gi_scene_build(b, "ground", &so, &s, &e0), GI_OK);
  gi_mesh_builder_free(b);
  gi_grid_spec spec = {.spacing = 20, .above_ground = HEIGHT};
  gi_probe_grid g;
  gi_error_info err = {0};
  assert_int_equal(gi_probe_grid_build(s, &spec, &g, &err), GI_OK);
  assert_int_equal(g.counts[0], 11);
  assert_int_equal(g.counts[2], 11);
  printf("plane's bounds, 11 x 11 columns: %zu valid, %zu without ground\n", g.num_valid, g.num_no_ground);
  assert_int_equal(g.num_no_ground, 0);
  assert_int_equal(g.num_valid, 121);
  for (size_t i = 0; i < g.n; i++) assert_float_equal(g.pos[3 * i + 1], HEIGHT, 1e-4);
  gi_probe_grid_free(&g);
  gi_scene_release(s);
}

static void test_lattice_and_bad_specs(void **state) {
  (void)state;
  gi_scene *s = street_scene();
  gi_probe_grid g;
  gi_error_info err = {0};
  gi_grid_spec spec = {.spacing = 10, .have_region = 1, .lo = {0, 0, 0}, .hi = {20, 5, 30}};
  assert_int_equal(gi_probe_grid_build(s, &spec, &g, &err), GI_OK);
  assert_int_equal(g.counts[0], 3);
  assert_int_equal(g.counts[1], 1);
  assert_int_equal(g.counts[2], 4);
  assert_int_equal(g.num_valid, 12);
  /* Point 5 = (x 2, y 0, z 1) in x-fastest order. */
  assert_float_equal(g.pos[3 * 5], 20, 0);
  assert_float_equal(g.pos[3 * 5 + 2], 10, 0);
  gi_probe_grid_free(&g);

  spec.spacing = 0;
  assert_int_equal(gi_probe_grid_build(s, &spec, &g, &err), GI_ERR_INVALID_ARG);
  spec.spacing = NAN;
  assert_int_equal(gi_probe_grid_build(s, &spec, &g, &err), GI_ERR_INVALID_ARG);
  spec.spacing = 1e-4; /* 2e5 x 5e4 x 3e5 points */
  assert_int_equal(gi_probe_grid_build(s, &spec, &g, &err), GI_ERR_LIMIT);
  spec.spacing = 10;
  double far_lo[3] = {500, 0, 0}, far_hi[3] = {600, 10, 10};
  memcpy(spec.lo, far_lo, sizeof far_lo), memcpy(spec.hi, far_hi, sizeof far_hi);
  assert_int_equal(gi_probe_grid_build(s, &spec, &g, &err), GI_ERR_INVALID_ARG);
  assert_non_null(strstr(err.msg, "beside the scene bounds"));
  assert_null(g.pos);
  /* Wholly above the bounds (probes over the roofs): taken; it was refused
   * while a box reaching 1 cm into the bounds baked the same probes. */
  double lo[3], hi[3];
  gi_scene_bounds(s, lo, hi);
  double up_lo[3] = {lo[0], hi[1] + 5, lo[2]}, up_hi[3] = {lo[0] + 20, hi[1] + 15, lo[2] + 20};
  memcpy(spec.lo, up_lo, sizeof up_lo), memcpy(spec.hi, up_hi, sizeof up_hi);
  assert_int_equal(gi_probe_grid_build(s, &spec, &g, &err), GI_OK);
  printf("region above the bounds: %d x %d x %d points\n", g.counts[0], g.counts[1], g.counts[2]);
  assert_true(g.n > 0 && g.pos[1] >= hi[1] + 5);
  gi_probe_grid_free(&g);
  gi_scene_release(s);
}

/* A small street-level volume with made-up answers. */
#define VX 4
#define VZ 3
static double vpos[3 * VX * VZ];
static uint8_t vvalid[VX * VZ];
static gi_probe vprobes[VX * VZ];

static gi_probe_volume make_volume(void) {
  gi_probe_volume v = {.counts = {VX, 1, VZ}, .origin = {100, 0, -20}, .spacing = 2, .up_axis = 1,
                       .street_level = 1, .n = VX * VZ, .pos = vpos, .valid = vvalid, .probes = vprobes};
  for (int i = 0; i < VX * VZ; i++) {
    vpos[3 * i] = (double)(100 + 2 * (i % VX));
    vpos[3 * i + 1] = (double)(0.5 + 2.0 * (i % 3)); /* voxel rows 0, 1, 2 (0.25, 1.25, 2.25 rounded) */
    vpos[3 * i + 2] = (double)(-20 + 2 * (i / VX));
    vvalid[i] = i != 5;
    for (int c = 0; c < 9; c++)
      for (int k = 0; k < 3; k++) vprobes[i].sh[c][k] = (float)(i + 0.01 * c + 0.001 * k);
    for (int k = 0; k < 3; k++) vprobes[i].irradiance[k] = (float)(10 * i + k);
  }
  return v;
}

static void test_volume_vdb_read_back(void **state) {
  (void)state;
  gi_probe_volume v = make_volume();
  char path[512], path2[512];
  snprintf(path, sizeof path, "%s/probes.vdb", tu_tmpdir());
  snprintf(path2, sizeof path2, "%s/probes2.vdb", tu_tmpdir());
  gi_error_info err = {0};
  assert_int_equal(gi_probe_volume_write_vdb(path, &v, "0123456789abcdef", &err), GI_OK);
  gi_vdb_grid_info info[16];
  size_t n = 0;
  assert_int_equal(gi_vdb_read_info(path, info, 16, &n, &err), GI_OK);
  assert_int_equal(n, 11);
  assert_string_equal(info[0].name, "sh_L00");
  assert_string_equal(info[8].name, "sh_L22");
  assert_string_equal(info[9].name, "irradiance");
  for (size_t g = 0; g < n; g++) {
    assert_int_equal(info[g].active_voxels, VX * VZ - 1);
    assert_float_equal(info[g].voxel_size, 2, 1e-12);
    /* Voxel (0,0,0)'s centre is the grid origin. */
    assert_float_equal(info[g].index_to_world[0], 100, 1e-9);
    assert_float_equal(info[g].index_to_world[2], -20, 1e-9);
  }
  for (int i = 0; i < VX * VZ; i++) {
    int vi = i % VX, vk = i / VX, vj = (int)lround((vpos[3 * i + 1] - 0.0) / 2.0);
    float val[3];
    assert_int_equal(gi_vdb_read_value(path, "sh_L21", vi, vj, vk, val, &err), GI_OK);
    for (int k = 0; k < 3; k++) assert_float_equal(val[k], i == 5 ? 0.f : vprobes[i].sh[7][k], 0);
    assert_int_equal(gi_vdb_read_value(path, "P", vi, vj, vk, val, &err), GI_OK);
    if (i != 5) assert_float_equal(val[1], vpos[3 * i + 1], 0);
  }
  char meta[64];
  assert_int_equal(gi_vdb_read_meta(path, NULL, "gi.bake_hash", meta, sizeof meta, &err), GI_OK);
  assert_string_equal(meta, "0123456789abcdef");
  /* Same inputs, same id: same bytes (the file UUID is derived, not random). */
  assert_int_equal(gi_probe_volume_write_vdb(path2, &v, "0123456789abcdef", &err), GI_OK);
  char cmd[1200];
  snprintf(cmd, sizeof cmd, "cmp -s '%s' '%s'", path, path2);
  assert_int_equal(system(cmd), 0);
}

static void test_volume_exr_read_back(void **state) {
  (void)state;
  gi_probe_volume v = make_volume();
  char path[512];
  snprintf(path, sizeof path, "%s/probes.exr", tu_tmpdir());
  gi_exr_attr attrs[] = {{"gi.kind", "probe-grid"}};
  gi_error_info err = {0};
  assert_int_equal(gi_probe_volume_write_exr(path, &v, attrs, 1, &err), GI_OK);
  gi_exr_file *f = NULL;
  assert_int_equal(gi_exr_read(path, &f, &err), GI_OK);
  assert_int_equal(gi_exr_file_width(f), VX);
  assert_int_equal(gi_exr_file_height(f), VZ);
  const float *py = gi_exr_file_channel(f, "P.Y"), *valid = gi_exr_file_channel(f, "valid.Y");
  const float *sh = gi_exr_file_channel(f, "sh.L2-1.G"), *r = gi_exr_file_channel(f, "R");
  assert_non_null(py), assert_non_null(valid), assert_non_null(sh), assert_non_null(r);
  assert_null(gi_exr_file_channel(f, "ao.Y"));
  for (int i = 0; i < VX * VZ; i++) {
    assert_float_equal(py[i], vpos[3 * i + 1], 0);
    assert_float_equal(valid[i], i == 5 ? 0.f : 1.f, 0);
    assert_float_equal(sh[i], i == 5 ? 0.f : vprobes[i].sh[5][1], 0);
    assert_float_equal(r[i], i == 5 ? 0.f : vprobes[i].irradiance[0], 0);
  }
  assert_string_equal(gi_exr_file_attr(f, "gi.kind"), "probe-grid");
  gi_exr_file_free(f);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_grid_far_from_origin),
      cmocka_unit_test(test_street_level_against_geometry),
      cmocka_unit_test(test_street_level_on_the_bounds),
      cmocka_unit_test(test_lattice_and_bad_specs),
      cmocka_unit_test(test_volume_vdb_read_back),
      cmocka_unit_test(test_volume_exr_read_back),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
