/* test_between.c: the voxels a bounce fills from their gathered neighbours
 * instead of gathering (light/between.c).
 *
 * test_mean: the agreement rule on hand-made sides (a spread within 20% of
 * the mean, or 5% of the brighter side on a dark side; never NaN).
 * test_sides: a voxel's sides read from the faces across each surface's
 * major axis, in the planned voxel's order of surfaces (a neighbour may
 * hold more surfaces than it), and faced back as a gather would.
 * test_plan_cells: on a lit plane's finest level, every voxel whose
 * in-plane cells are not both even is planned, from exactly the cells one
 * step along its odd axes, unless one of those lies outside the window;
 * no other voxel is.
 * test_plan_tilted: on a plane 10 degrees off the grid, neighbours a
 * layer up or down, on the plane.
 * test_plan_edge: a wall on a floor: the edge's voxels odd along it are
 * planned between their neighbours along it.
 * test_fill_fields: a linear field over the plane is filled exactly (the
 * mean of symmetric neighbours is the field at the voxel); a step in it
 * sends the voxels whose neighbours straddle the step to be gathered, and
 * fills every other one exactly. */
#include "test_util.h"
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "cascade/cascade_internal.h"
#include "gi/gi.h"
#include "light/light.h"

static void set_faces(float f[GI_VOX_FACES][3], float v) {
  for (int i = 0; i < GI_VOX_FACES; i++)
    for (int k = 0; k < 3; k++) f[i][k] = v;
}

/* Neighbour i's sides all at x[i]. */
static void set_sides(float v[4][2 * GI_VOX_GROUPS][3], const float x[4]) {
  for (int i = 0; i < 4; i++)
    for (int sd = 0; sd < 2 * GI_VOX_GROUPS; sd++)
      for (int k = 0; k < 3; k++) v[i][sd][k] = x[i];
}

typedef const float (*sides4)[2 * GI_VOX_GROUPS][3];

static void test_mean(void **state) {
  (void)state;
  float v[4][2 * GI_VOX_GROUPS][3], out[2 * GI_VOX_GROUPS][3];
  set_sides(v, (const float[4]){1.0f, 1.1f, 0.9f, 1.0f});
  assert_int_equal(gi__between_mean(2, (sides4)v, out), 1);
  for (int sd = 0; sd < 2; sd++)
    for (int k = 0; k < 3; k++) assert_true(fabsf(out[sd][k] - 1.0f) < 1e-6f);
  /* One neighbour 0.225 from the mean of 1.075: more than 20%. */
  set_sides(v, (const float[4]){1.0f, 1.3f, 1.0f, 1.0f});
  out[0][0] = -7;
  assert_int_equal(gi__between_mean(2, (sides4)v, out), 0);
  assert_true(out[0][0] == -7); /* untouched */
  /* A dark side beside a bright one: 0.01 apart where the bright side is 1. */
  set_sides(v, (const float[4]){1.0f, 1.0f, 1.0f, 1.0f});
  v[0][1][1] = 0.0f, v[1][1][1] = 0.02f, v[2][1][1] = 0.01f, v[3][1][1] = 0.01f;
  assert_int_equal(gi__between_mean(2, (sides4)v, out), 1);
  assert_true(fabsf(out[1][1] - 0.01f) < 1e-7f);
  /* The same spread on a voxel that is dark all over disagrees. */
  set_sides(v, (const float[4]){0.01f, 0.01f, 0.01f, 0.01f});
  v[0][1][1] = 0.0f, v[1][1][1] = 0.02f;
  assert_int_equal(gi__between_mean(2, (sides4)v, out), 0);
  /* A NaN never agrees. */
  set_sides(v, (const float[4]){1.0f, 1.0f, 1.0f, 1.0f});
  v[2][0][2] = NAN;
  assert_int_equal(gi__between_mean(2, (sides4)v, out), 0);
}

/* A voxel's sides from its faces: the faces across each group's major
 * axis, whatever its minor faces show, in the order of the planned voxel's
 * groups. */
static void test_sides(void **state) {
  (void)state;
  gi_vgeo g, h;
  memset(&g, 0, sizeof g);
  g.groups = 1;
  g.u.fin.orient[0][0] = 0.1f, g.u.fin.orient[0][1] = 0.995f; /* major axis y */
  for (int f = 0; f < GI_VOX_FACES; f++) g.face_side[f] = gi__face_side(g.u.fin.orient[0], 0, f);
  float E[GI_VOX_FACES][3], Es[2 * GI_VOX_GROUPS][3];
  for (int f = 0; f < GI_VOX_FACES; f++)
    for (int k = 0; k < 3; k++) E[f][k] = (float)(f + 1);
  assert_int_equal(gi__between_sides(&g, &g, E, Es), 1);
  assert_true(Es[0][0] == 3.0f && Es[1][2] == 4.0f); /* +y shows side 0, -y side 1 */
  /* Faced back through gi__face_light, the sides give every face what its side holds. */
  float back[GI_VOX_FACES][3];
  gi__face_light(&g, (const float(*)[3])Es, back);
  for (int f = 0; f < GI_VOX_FACES; f++) assert_true(back[f][0] == Es[g.face_side[f]][0]);
  /* A major face showing the brighter side instead: no sides. */
  g.brighter = 1u << 3;
  assert_int_equal(gi__between_sides(&g, &g, E, Es), 0);
  g.brighter = 0;
  /* An edge: a floor (group 0, y) and a wall (group 1, x); h lists them the other way round. */
  g.groups = 2;
  memset(g.u.fin.orient, 0, sizeof g.u.fin.orient);
  g.u.fin.orient[0][1] = 1, g.u.fin.orient[1][0] = 1;
  h = g;
  memcpy(h.u.fin.orient[0], g.u.fin.orient[1], sizeof h.u.fin.orient[0]);
  memcpy(h.u.fin.orient[1], g.u.fin.orient[0], sizeof h.u.fin.orient[1]);
  /* h's faces: x shows its group 0 (the wall), y its group 1 (the floor), z the floor's top. */
  const uint8_t hs[GI_VOX_FACES] = {0, 1, 2, 3, 2, 2};
  memcpy(h.face_side, hs, sizeof hs);
  assert_int_equal(gi__between_sides(&g, &h, E, Es), 1);
  assert_true(Es[0][0] == 3.0f && Es[1][0] == 4.0f); /* g's floor: h's y faces */
  assert_true(Es[2][0] == 1.0f && Es[3][0] == 2.0f); /* g's wall: h's x faces */
  /* A plane's voxel beside the edge: g holds the floor alone, h the floor and the wall. */
  gi_vgeo f = g;
  f.groups = 1;
  memset(Es, 0, sizeof Es);
  assert_int_equal(gi__between_sides(&f, &h, E, Es), 1);
  assert_true(Es[0][0] == 3.0f && Es[1][0] == 4.0f && Es[2][0] == 0.0f); /* the floor's sides only */
  /* The other way round, fewer surfaces than g's: no sides. */
  assert_int_equal(gi__between_sides(&h, &f, E, Es), 0);
  /* Groups that do not match g's: no sides. */
  h.u.fin.orient[0][0] = 0, h.u.fin.orient[0][2] = 1;
  assert_int_equal(gi__between_sides(&g, &h, E, Es), 0);
}

/* A bake of the sunlit plane y = 0 around the origin (level 0 is all
 * plane) and level 0's plan. */
/* A bake of s at `at` (3 levels of 16^3, finest voxel 1) and level 0's plan. */
static gi_cascade *bake_plan(gi_scene *s, const double at[3], gi_between **plan) {
  gi_quality q = {.levels = 3, .res = 16, .voxel0 = 1.0, .threads = 2};
  gi_cascade *c = NULL;
  gi_error_info err = {0};
  assert_int_equal(gi_cascade_bake(s, at, &q, &c, NULL, &err), GI_OK);
  *plan = NULL;
  assert_int_equal(gi__between_plan(c, 0, plan), GI_OK);
  return c;
}

static gi_cascade *plane_plan(gi_scene **s, gi_between **plan) {
  *s = tu_sunlit_plane(0.5, 1.0, 100);
  return bake_plan(*s, (const double[3]){0.3, 2.0, 0.3}, plan);
}

/* Grey quads (corners abcd each) under a white sky. */
static gi_scene *grey_quads(const char *name, const double (*q)[4][3], int n) {
  gi_mesh_builder *b = gi_mesh_builder_new();
  gi_material m = {.albedo = {0.5f, 0.5f, 0.5f}, .roughness = 1};
  uint32_t mat = gi_mesh_builder_add_material(b, &m);
  for (int i = 0; i < n; i++) gi_mesh_builder_add_quad(b, q[i][0], q[i][1], q[i][2], q[i][3], mat);
  gi_light sky = {.type = GI_LIGHT_SKY, .color = {1, 1, 1}};
  return tu_build(b, name, &sky, 1);
}

static void cell_of(const gi_cascade *c, int d, int32_t occ, int64_t cell[3]) {
  gi__slot_cell(&c->lv[d], c->R, c->lv[d].occ[occ], cell);
}

/* Every planned voxel's neighbours are gathered ones: the fill reads their
 * gathers, never another planned voxel's stale light. */
static void expect_gathered_neighbours(const gi_cascade *c, int d, const gi_between *plan) {
  for (uint32_t i = 0; i < c->lv[d].num_occ; i++)
    for (int k = 0; k < 4 && plan[i].nb[0] >= 0; k++) assert_true(plan[plan[i].nb[k]].nb[0] < 0);
}

static void test_plan_cells(void **state) {
  (void)state;
  gi_scene *s;
  gi_between *plan;
  gi_cascade *c = plane_plan(&s, &plan);
  const gi_level *L = &c->lv[0];
  int R = c->R, planned = 0, expected = 0;
  assert_true(L->num_occ >= (uint32_t)(R * R)); /* the plane crosses the whole window */
  for (uint32_t i = 0; i < L->num_occ; i++) {
    int64_t cell[3];
    cell_of(c, 0, (int32_t)i, cell);
    const gi_vgeo *g = gi__geo(L, L->occ[i]);
    assert_int_equal(g->groups, 1);
    assert_true(fabsf(g->u.fin.orient[0][1]) > 0.99f);
    /* The plane's in-plane axes are z (u) and x (v) for its axis y. */
    int odd_z = (int)(cell[2] & 1), odd_x = (int)(cell[0] & 1);
    /* A neighbour outside the window along an odd axis. */
    int border = (odd_x && (cell[0] == L->cell0[0] || cell[0] == L->cell0[0] + R - 1)) ||
                 (odd_z && (cell[2] == L->cell0[2] || cell[2] == L->cell0[2] + R - 1));
    int want = (odd_z || odd_x) && !border;
    expected += want;
    if (plan[i].nb[0] < 0) {
      assert_false(want);
      continue;
    }
    assert_true(want);
    planned++;
    /* Each neighbour one step along each odd axis, none along an even one, in the plane's layer. */
    int seen[2][2] = {{0, 0}, {0, 0}};
    for (int k = 0; k < 4; k++) {
      int64_t nc[3];
      cell_of(c, 0, plan[i].nb[k], nc);
      int64_t dx = nc[0] - cell[0], dy = nc[1] - cell[1], dz = nc[2] - cell[2];
      assert_true(dy == 0);
      assert_true(odd_x ? (dx == -1 || dx == 1) : dx == 0);
      assert_true(odd_z ? (dz == -1 || dz == 1) : dz == 0);
      assert_true((nc[0] & 1) == 0 && (nc[2] & 1) == 0); /* a gathered voxel */
      seen[dx > 0][dz > 0] = 1;
    }
    /* Both sides of every odd axis. */
    if (odd_x && odd_z) assert_int_equal(seen[0][0] + seen[0][1] + seen[1][0] + seen[1][1], 4);
    else assert_int_equal(seen[0][0] + seen[0][1] + seen[1][0] + seen[1][1], 2);
  }
  assert_int_equal(planned, expected);
  expect_gathered_neighbours(c, 0, plan);
  assert_true(planned > (int)L->num_occ / 2); /* three in four, less the border */
  gi__free(plan);
  gi_cascade_free(c);
  gi_scene_release(s);
}

/* A plane tilted 10 degrees about z climbs a cell every 5.7 along x: the
 * neighbours a voxel is planned from may lie a layer up or down, never
 * further, and always on the plane. */
static void test_plan_tilted(void **state) {
  (void)state;
  double t = tan(10 * M_PI / 180);
  const double quad[1][4][3] = {
      {{-100, -100 * t, -100}, {-100, -100 * t, 100}, {100, 100 * t, 100}, {100, 100 * t, -100}}};
  gi_scene *s = grey_quads("tilted", quad, 1);
  gi_between *plan;
  gi_cascade *c = bake_plan(s, (const double[3]){0.3, 2.0, 0.3}, &plan);
  const gi_level *L = &c->lv[0];
  int planned = 0, climbed = 0;
  for (uint32_t i = 0; i < L->num_occ; i++) {
    if (plan[i].nb[0] < 0) continue;
    planned++;
    int64_t cell[3];
    cell_of(c, 0, (int32_t)i, cell);
    const gi_vgeo *g = gi__geo(L, L->occ[i]);
    for (int k = 0; k < 4; k++) {
      int64_t nc[3];
      cell_of(c, 0, plan[i].nb[k], nc);
      assert_true(llabs(nc[1] - cell[1]) <= 1);
      climbed += nc[1] != cell[1];
      const gi_vgeo *h = gi__geo(L, L->occ[plan[i].nb[k]]);
      float off = 0;
      for (int a = 0; a < 3; a++) off += g->u.fin.orient[0][a] * (h->u.fin.gcen[0][a] - g->u.fin.gcen[0][a]);
      assert_true(fabsf(off) <= 0.25f * (float)L->s);
    }
  }
  printf("tilted plane: %d of %u voxels planned, %d neighbours a layer off\n", planned, L->num_occ, climbed);
  assert_true(planned > (int)L->num_occ / 3);
  assert_true(climbed > 0);
  expect_gathered_neighbours(c, 0, plan);
  gi__free(plan);
  gi_cascade_free(c);
  gi_scene_release(s);
}

/* A wall standing on the floor: the voxels holding both, odd along the
 * edge's axis (z), are planned between the edge voxels one cell along it;
 * no other two-group voxel is. */
static void test_plan_edge(void **state) {
  (void)state;
  const double quads[2][4][3] = {{{-100, 0, -100}, {-100, 0, 100}, {100, 0, 100}, {100, 0, -100}},
                                 {{0.4, 0, -100}, {0.4, 50, -100}, {0.4, 50, 100}, {0.4, 0, 100}}};
  gi_scene *s = grey_quads("edge", quads, 2);
  gi_between *plan;
  gi_cascade *c = bake_plan(s, (const double[3]){2.3, 2.0, 0.3}, &plan);
  const gi_level *L = &c->lv[0];
  int edges = 0, planned = 0;
  for (uint32_t i = 0; i < L->num_occ; i++) {
    if (gi__geo(L, L->occ[i])->groups != 2) continue;
    edges++;
    int64_t cell[3];
    cell_of(c, 0, (int32_t)i, cell);
    int inside = cell[2] > L->cell0[2] && cell[2] < L->cell0[2] + c->R - 1;
    assert_int_equal(plan[i].nb[0] >= 0, (int)(cell[2] & 1) && inside);
    if (plan[i].nb[0] < 0) continue;
    planned++;
    for (int k = 0; k < 4; k++) {
      int64_t nc[3];
      cell_of(c, 0, plan[i].nb[k], nc);
      assert_true(nc[0] == cell[0] && nc[1] == cell[1] && llabs(nc[2] - cell[2]) == 1);
    }
  }
  printf("edge: %d of %d two-group voxels planned\n", planned, edges);
  assert_true(edges >= c->R && planned >= edges / 2 - 2);
  /* The floor beside the edge takes only gathered edge voxels as neighbours. */
  expect_gathered_neighbours(c, 0, plan);
  gi__free(plan);
  gi_cascade_free(c);
  gi_scene_release(s);
}

/* field(cell): linear in x and z, or with a step at x = step_x when step. */
static float field(const int64_t cell[3], int step, int64_t step_x) {
  if (step) return cell[0] < step_x ? 1.0f : 2.0f;
  return 1.0f + 0.01f * (float)cell[0] + 0.02f * (float)cell[2];
}

static void test_fill_fields(void **state) {
  (void)state;
  gi_scene *s;
  gi_between *plan;
  gi_cascade *c = plane_plan(&s, &plan);
  const gi_level *L = &c->lv[0];
  gi_faces3 *E = malloc(L->num_occ * sizeof *E);
  uint32_t *redo = malloc(L->num_occ * sizeof *redo);
  assert_non_null(E);
  assert_non_null(redo);
  int64_t step_x = L->cell0[0] + c->R / 2;
  for (int step = 0; step < 2; step++) {
    for (uint32_t i = 0; i < L->num_occ; i++) {
      int64_t cell[3];
      cell_of(c, 0, (int32_t)i, cell);
      set_faces(E[i], plan[i].nb[0] < 0 ? field(cell, step, step_x) : -1.0f);
    }
    /* Two workers: the voxels fill in any order, the list comes out in order. */
    uint32_t n = gi__between_fill(c, 0, plan, E, redo, 2);
    for (uint32_t j = 1; j < n; j++) assert_true(redo[j - 1] < redo[j]);
    int listed = 0;
    for (uint32_t i = 0; i < L->num_occ; i++) {
      if (plan[i].nb[0] < 0) continue;
      int64_t cell[3];
      cell_of(c, 0, (int32_t)i, cell);
      /* An odd x's neighbours are x - 1 and x + 1. */
      int straddles = step && (cell[0] & 1) && (cell[0] == step_x - 1 || cell[0] == step_x);
      int in_redo = 0;
      for (uint32_t j = 0; j < n; j++) in_redo |= redo[j] == i;
      if (straddles) {
        assert_true(in_redo);
        assert_true(E[i][0][0] == -1.0f); /* left for the gather */
        listed++;
        continue;
      }
      assert_false(in_redo);
      float want = field(cell, step, step_x);
      for (int f = 0; f < GI_VOX_FACES; f++)
        for (int k = 0; k < 3; k++) assert_true(fabsf(E[i][f][k] - want) <= 1e-5f * want);
    }
    assert_int_equal((int)n, listed);
    if (step) assert_true(listed > 0);
    else assert_int_equal(listed, 0);
  }
  free(E);
  free(redo);
  gi__free(plan);
  gi_cascade_free(c);
  gi_scene_release(s);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_mean),
      cmocka_unit_test(test_sides),
      cmocka_unit_test(test_plan_cells),
      cmocka_unit_test(test_plan_tilted),
      cmocka_unit_test(test_plan_edge),
      cmocka_unit_test(test_fill_fields),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
