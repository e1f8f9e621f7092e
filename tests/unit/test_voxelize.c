/* test_voxelize.c: exact voxelization counts, snapping and nesting.
 *
 * The cascade's grid is anchored at the scene's local origin (the centre of
 * its bounds), so a box of width 5 s centred anywhere has its faces at
 * +-2.5 s: half a voxel from every cell border, where occupancy is
 * unambiguous. Its surface covers cells -3..2 on each axis, so exactly
 * 6^3 - 4^3 = 152 voxels hold geometry at level 0; at level 1 (cells of
 * 2 s, filtered from level 0) cells -2..1, so 4^3 - 2^3 = 56. */
#include "test_util.h"
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include "gi/gi.h"
#include "cascade/cascade_internal.h"
#include "light/light.h"
#include "trace/trace.h"
#include "scene/lights.h"
#include "answer/answer.h"

static gi_scene *box_scene(double cx, double cy, double cz, double width, int copies, double spacing) {
  gi_mesh_builder *b = gi_mesh_builder_new();
  gi_material m = {.albedo = {0.5f, 0.5f, 0.5f}, .roughness = 1};
  uint32_t mat = gi_mesh_builder_add_material(b, &m);
  for (int i = 0; i < copies; i++) {
    double off = i * spacing;
    double lo[3] = {cx - width / 2 + off, cy - width / 2, cz - width / 2};
    double hi[3] = {cx + width / 2 + off, cy + width / 2, cz + width / 2};
    gi_mesh_builder_add_box(b, lo, hi, mat);
  }
  return tu_build(b, "boxes", NULL, 0);
}

static void test_exact_counts(void **state) {
  const double s0 = 0.25;
  const double centres[][3] = {{0, 0, 0}, {123.4, -7.9, 55.55}, {1e6 + 0.3, 2.0, -1e6}};
  for (size_t ci = 0; ci < 3; ci++) {
    const double *c = centres[ci];
    gi_scene *sc = box_scene(c[0], c[1], c[2], 5 * s0, 1, 0);
    gi_quality q = {.levels = 2, .res = 16, .voxel0 = s0, .bounces = -1, .light_samples = 1, .threads = 2};
    gi_cascade *cas = NULL;
    gi_bake_report rep;
    gi_error_info err = {0};
    double at[3] = {c[0] + 0.1 * s0, c[1] + 0.2 * s0, c[2] + 0.3 * s0};
    assert_int_equal(gi_cascade_bake(sc, at, &q, &cas, &rep, &err), GI_OK);
    printf("box at (%g,%g,%g): occupied L0=%llu L1=%llu, triangles visited %llu\n", c[0], c[1], c[2],
           (unsigned long long)rep.occupied[0], (unsigned long long)rep.occupied[1],
           (unsigned long long)rep.triangles_visited);
    assert_int_equal(rep.occupied[0], 152);
    assert_int_equal(rep.occupied[1], 56);
    /* Every face voxel got its share of area: the sum is the box's surface. */
    const gi_level *L = &cas->lv[0];
    double area = 0;
    int opaque_x = 0;
    for (size_t i = 0; i < 16 * 16 * 16; i++) {
      const gi_vgeo *g = gi__geo(L, (uint32_t)i);
      area += g->area;
      if (g->area > 0 && fabsf(g->normal[0]) > 0.999f) {
        /* A voxel cut by a full x-face: opaque along x, clear along y and z. */
        const gi_vrad *r = &L->rad[i];
        if (gi__vrad_alpha(r, 0) > 0.998f && gi__vrad_alpha(r, 1) == 0 && gi__vrad_alpha(r, 2) == 0) opaque_x++;
      }
    }
    assert_true(fabs(area - 6 * 25 * s0 * s0) < 1e-4 * 6 * 25 * s0 * s0);
    /* Two x-faces of 4x4 cells each that hold no other face (cells -2..1 in y and z). */
    assert_int_equal(opaque_x, 2 * 16);
    gi_cascade_free(cas);
    gi_scene_release(sc);
  }
}

static void test_snapping_and_nesting(void **state) {
  gi_scene *sc = box_scene(0, 0, 0, 10, 1, 0);
  gi_quality q = {.levels = 4, .res = 16, .voxel0 = 0.5, .bounces = -1, .light_samples = 1, .threads = 1};
  gi_bake_report ref;
  gi_cascade *cas = NULL;
  gi_error_info err = {0};
  /* Viewpoint in the middle of a 2-cell block: sub-voxel moves keep every level fixed. */
  double at0[3] = {1.1, 0.6, -0.9};
  assert_int_equal(gi_cascade_bake(sc, at0, &q, &cas, &ref, &err), GI_OK);
  gi_cascade_free(cas);
  srand(7);
  for (int trial = 0; trial < 20; trial++) {
    double at[3];
    for (int a = 0; a < 3; a++) at[a] = at0[a] + 0.09 * ((double)rand() / RAND_MAX - 0.5);
    gi_bake_report rep;
    assert_int_equal(gi_cascade_bake(sc, at, &q, &cas, &rep, &err), GI_OK);
    for (int d = 0; d < q.levels; d++) {
      for (int a = 0; a < 3; a++) assert_true(rep.level_origin[d][a] == ref.level_origin[d][a]);
      assert_int_equal(rep.occupied[d], ref.occupied[d]);
    }
    gi_cascade_free(cas);
  }
  /* Random viewpoints: each level starts on a cell border of the next and nests inside it. */
  for (int trial = 0; trial < 200; trial++) {
    double at[3];
    for (int a = 0; a < 3; a++) at[a] = 40.0 * ((double)rand() / RAND_MAX - 0.5);
    gi_bake_report rep;
    assert_int_equal(gi_cascade_bake(sc, at, &q, &cas, &rep, &err), GI_OK);
    for (int d = 0; d + 1 < q.levels; d++)
      for (int a = 0; a < 3; a++) {
        double o = rep.level_origin[d][a], O = rep.level_origin[d + 1][a], S = rep.voxel_size[d + 1];
        double k = (o - O) / S;
        assert_true(fabs(k - round(k)) < 1e-9);
        assert_true(o >= O && o + 16 * rep.voxel_size[d] <= O + 16 * S);
      }
    /* The viewpoint is inside the finest level, away from its border. */
    for (int a = 0; a < 3; a++) {
      assert_true(at[a] >= rep.level_origin[0][a] + 0.5 * 7 && at[a] <= rep.level_origin[0][a] + 0.5 * 9 + 0.5);
    }
    /* From inside the box (10 wide), levels 2 and 3 (32 and 64 wide) hold
     * all of it two cells clear of their faces (cascade.c, cover_scene).
     * Level 1 (16) does too unless holding level 0 (8, centred on the
     * viewpoint) stops it: then a face lies within one of its cells of
     * level 0's (levels start on even cells of their own). */
    int inside = 1;
    for (int a = 0; a < 3; a++) inside &= fabs(at[a]) < 5;
    for (int d = 1; d < q.levels && inside; d++)
      for (int a = 0; a < 3; a++) {
        double o = rep.level_origin[d][a], S = rep.voxel_size[d], e = 16 * S;
        double o0 = rep.level_origin[0][a], e0 = 16 * rep.voxel_size[0];
        int holds = o <= -5 - 2 * S && o + e >= 5 + 2 * S;
        assert_true(holds || (d == 1 && (fabs(o - o0) <= S || fabs(o + e - o0 - e0) <= S)));
      }
    gi_cascade_free(cas);
  }
  gi_scene_release(sc);
}

/* The orientation model (cascade_internal.h) on the box of test_exact_counts
 * lit by a sun from w = (0.6, 0.8, 0): a voxel on the box's +x/+y edge
 * holds two faces and shows the +x face through its x faces and the +y
 * face through its y faces, so each gets its own cosine (0.6, 0.8), where
 * one mean normal at 45 degrees would give both 0.99; a corner voxel holds
 * three groups; the box's inside receives nothing. */
static void test_orientation_groups(void **state) {
  const double s0 = 0.25;
  gi_mesh_builder *b = gi_mesh_builder_new();
  gi_material m = {.albedo = {0.5f, 0.5f, 0.5f}, .roughness = 1};
  uint32_t mat = gi_mesh_builder_add_material(b, &m);
  double lo[3] = {-2.5 * s0, -2.5 * s0, -2.5 * s0}, hi[3] = {2.5 * s0, 2.5 * s0, 2.5 * s0};
  gi_mesh_builder_add_box(b, lo, hi, mat);
  gi_light sun = {.type = GI_LIGHT_SUN, .color = {1, 1, 1}, .direction = {-0.6f, -0.8f, 0}};
  gi_scene_options opt = {.up = GI_UP_Y, .lights = &sun, .num_lights = 1};
  gi_scene *sc = NULL;
  gi_error_info err = {0};
  assert_int_equal(gi_scene_build(b, "box", &opt, &sc, &err), GI_OK);
  gi_mesh_builder_free(b);
  gi_quality q = {.levels = 1, .res = 16, .voxel0 = s0, .bounces = -1, .light_samples = 1, .threads = 2};
  gi_cascade *cas = NULL;
  gi_bake_report rep;
  double at[3] = {0.1 * s0, 0.2 * s0, 0.3 * s0};
  assert_int_equal(gi_cascade_bake(sc, at, &q, &cas, &rep, &err), GI_OK);
  const gi_level *L = &cas->lv[0];
  struct {
    int64_t cell[3];
    int groups;
    float px, nx, py, ny, pz;
  } want[] = {
      {{2, 0, 0}, 1, 0.6f, 0, 0, 0, 0},       /* the +x face alone */
      {{0, 2, -1}, 1, 0, 0, 0.8f, 0, 0},      /* the +y face alone */
      {{2, 2, 0}, 2, 0.6f, 0, 0.8f, 0, 0},    /* the +x/+y edge */
      {{2, 2, 2}, 3, 0.6f, 0, 0.8f, 0, 0},    /* the +x/+y/+z corner: +z is grazing */
      {{-3, 2, 0}, 2, 0, 0, 0.8f, 0, 0},      /* the -x/+y edge: -x faces away */
  };
  for (size_t i = 0; i < sizeof want / sizeof *want; i++) {
    const int64_t *c = want[i].cell;
    uint32_t slot = gi__slot(c[0], c[1], c[2], cas->R);
    const gi_vgeo *g = gi__geo(L, slot);
    const float *E[6];
    for (int f = 0; f < 6; f++) E[f] = gi__direct(L, slot)[f];
    printf("cell (%lld,%lld,%lld): %d groups, direct +x %.5f -x %.5f +y %.5f -y %.5f +z %.5f\n", (long long)c[0],
           (long long)c[1], (long long)c[2], g->groups, E[0][1], E[1][1], E[2][1], E[3][1], E[4][1]);
    assert_int_equal(g->groups, want[i].groups);
    const float expect[5] = {want[i].px, want[i].nx, want[i].py, want[i].ny, want[i].pz};
    for (int f = 0; f < 5; f++)
      if (g->proj[f / 2] > 0)
        for (int k = 0; k < 3; k++) assert_float_equal(E[f][k], expect[f], 1e-5);
  }
  gi_cascade_free(cas);
  gi_scene_release(sc);
}

static void test_query_visits_only_nearby(void **state) {
  /* 200 boxes 10 m apart along x; a one-level 16 x 0.25 m cascade sees one. */
  gi_scene *sc = box_scene(0, 0, 0, 1.25, 200, 10.0);
  gi_quality q = {.levels = 1, .res = 16, .voxel0 = 0.25, .bounces = -1, .light_samples = 1};
  gi_cascade *cas = NULL;
  gi_bake_report rep;
  gi_error_info err = {0};
  double at[3] = {500.0 + 0.1, 0.1, 0.1};
  assert_int_equal(gi_cascade_bake(sc, at, &q, &cas, &rep, &err), GI_OK);
  printf("200 boxes (2400 triangles): level 0 visited %llu triangles, %llu occupied\n",
         (unsigned long long)rep.triangles_visited, (unsigned long long)rep.occupied[0]);
  assert_int_equal(rep.triangles_visited, 12);
  assert_int_equal(rep.occupied[0], 152);
  gi_cascade_free(cas);
  gi_scene_release(sc);
}

/* A flat street of boxes with z up, on a ground plane: a coarse level's
 * geometry lies in one or two z-slabs, which the voxelizer splits into
 * y-bands and runs with every level's tasks in one loop. The occupied
 * voxels come out in the bake's (z, y, x) order from each window's first
 * cell, and the same on 1 and 2 threads, geometry included. */
static void test_order_and_threads(void **state) {
  gi_mesh_builder *b = gi_mesh_builder_new();
  gi_material m = {.albedo = {0.5f, 0.5f, 0.5f}, .roughness = 1};
  uint32_t mat = gi_mesh_builder_add_material(b, &m);
  double glo[3] = {-40, -40, -0.5}, ghi[3] = {40, 40, 0};
  gi_mesh_builder_add_box(b, glo, ghi, mat);
  for (int i = 0; i < 6; i++)
    for (int j = 0; j < 6; j++) {
      double lo[3] = {-30 + 10.0 * i, -30 + 10.0 * j, 0}, hi[3] = {lo[0] + 6, lo[1] + 4, 3 + (i * 7 + j * 3) % 11};
      gi_mesh_builder_add_box(b, lo, hi, mat);
    }
  gi_scene *sc = tu_build_up(b, "street", GI_UP_Z, NULL, 0);
  gi_error_info err = {0};
  gi_cascade *cas[2] = {NULL, NULL};
  for (int t = 0; t < 2; t++) {
    gi_quality q = {.levels = 4, .res = 16, .voxel0 = 0.6, .bounces = -1, .light_samples = 1, .threads = t + 1};
    const double at[3] = {1.3, 2.7, 1.5};
    assert_int_equal(gi_cascade_bake(sc, at, &q, &cas[t], NULL, &err), GI_OK);
  }
  int R = cas[0]->R;
  uint64_t total = 0;
  for (int d = 0; d < cas[0]->n; d++) {
    const gi_level *A = &cas[0]->lv[d], *B = &cas[1]->lv[d];
    assert_int_equal(A->num_occ, B->num_occ);
    int64_t prev = -1;
    for (uint32_t q = 0; q < A->num_occ; q++) {
      assert_int_equal(A->occ[q], B->occ[q]);
      const gi_vgeo *ga = gi__geo(A, A->occ[q]), *gb = gi__geo(B, B->occ[q]);
      assert_true(ga->area == gb->area && ga->centroid[0] == gb->centroid[0] && ga->groups == gb->groups);
      int64_t cell[3];
      gi__slot_cell(A, R, A->occ[q], cell);
      int64_t rank = ((cell[2] - A->cell0[2]) * R + (cell[1] - A->cell0[1])) * R + (cell[0] - A->cell0[0]);
      assert_true(rank > prev); /* z, then y, then x */
      prev = rank;
    }
    total += A->num_occ;
  }
  printf("street of 36 boxes, z up: %llu occupied voxels over %d levels, same order on 1 and 2 threads\n",
         (unsigned long long)total, cas[0]->n);
  assert_true(total > 1000);
  gi_cascade_free(cas[0]);
  gi_cascade_free(cas[1]);
  gi_scene_release(sc);
}

/* gi__voxel_clip_tri: a triangle inside the cell comes back as it is, in
 * its order, relative to the corner (vertices on the cell's faces count as
 * inside); one across a face is cut there, the new vertices exactly on
 * it; one whose centroid lies past the cell's upper faces is not its own. */
static void test_clip_tri(void **state) {
  (void)state;
  const int64_t cell[3] = {2, -2, 3};
  float poly[GI_CLIP_MAXV][3], corner[3];
  const float in[3][3] = {{1.25f, -0.75f, 1.5f}, {1.5f, -0.5f, 1.75f}, {1.0f, -1.0f, 1.5f}};
  assert_int_equal(gi__voxel_clip_tri(0.5, cell, in, poly, corner), 3);
  const float corner_want[3] = {1.0f, -1.0f, 1.5f};
  for (int a = 0; a < 3; a++) assert_true(corner[a] == corner_want[a]);
  for (int q = 0; q < 3; q++)
    for (int a = 0; a < 3; a++) assert_true(poly[q][a] == in[q][a] - corner_want[a]);
  /* Across x = 1.5 (the cell's upper x face): the part below it, a quad. */
  const float across[3][3] = {{1.25f, -0.75f, 1.5f}, {1.75f, -0.75f, 1.5f}, {1.25f, -0.75f, 2.0f}};
  int n = gi__voxel_clip_tri(0.5, cell, across, poly, corner);
  assert_int_equal(n, 4);
  const float want[4][3] = {{0.25f, 0.25f, 0}, {0.5f, 0.25f, 0}, {0.5f, 0.25f, 0.25f}, {0.25f, 0.25f, 0.5f}};
  for (int q = 0; q < 4; q++)
    for (int a = 0; a < 3; a++) assert_true(poly[q][a] == want[q][a]);
  /* Lying on the upper y face (y = -0.5): the cell above owns it. */
  const float top[3][3] = {{1.25f, -0.5f, 1.5f}, {1.5f, -0.5f, 1.75f}, {1.0f, -0.5f, 1.5f}};
  assert_int_equal(gi__voxel_clip_tri(0.5, cell, top, poly, corner), 0);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_exact_counts),
      cmocka_unit_test(test_clip_tri),
      cmocka_unit_test(test_snapping_and_nesting),
      cmocka_unit_test(test_query_visits_only_nearby),
      cmocka_unit_test(test_orientation_groups),
      cmocka_unit_test(test_order_and_threads),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
