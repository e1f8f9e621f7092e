/* test_between.c: the voxels a bounce fills from their gathered neighbours
 * instead of gathering (light/between.c).
 *
 * test_mean: the agreement rule on hand-made faces (a spread within 20% of
 * the mean, or 5% of the voxel's brightest face on a dark face; never NaN).
 * test_plan_cells: on a lit plane's finest level, every voxel whose
 * in-plane cells are not both even is planned, from exactly the cells one
 * step along its odd axes, unless one of those lies outside the window;
 * no other voxel is.
 * test_fill_fields: a linear field over the plane is filled exactly (the
 * mean of symmetric neighbours is the field at the voxel); a step in it
 * sends the voxels whose neighbours straddle the step to be gathered, and
 * fills every other one exactly. */
#include "test_util.h"
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include "cascade/cascade_internal.h"
#include "gi/gi.h"
#include "light/light.h"

static void set_faces(float f[GI_VOX_FACES][3], float v) {
  for (int i = 0; i < GI_VOX_FACES; i++)
    for (int k = 0; k < 3; k++) f[i][k] = v;
}

static void test_mean(void **state) {
  (void)state;
  float a[GI_VOX_FACES][3], b[GI_VOX_FACES][3], c[GI_VOX_FACES][3], d[GI_VOX_FACES][3], out[GI_VOX_FACES][3];
  const float(*v[4])[3] = {(const float(*)[3])a, (const float(*)[3])b, (const float(*)[3])c,
                           (const float(*)[3])d};
  set_faces(a, 1.0f), set_faces(b, 1.1f), set_faces(c, 0.9f), set_faces(d, 1.0f);
  assert_int_equal(gi__between_mean(v, out), 1);
  for (int f = 0; f < GI_VOX_FACES; f++)
    for (int k = 0; k < 3; k++) assert_true(fabsf(out[f][k] - 1.0f) < 1e-6f);
  /* One neighbour 0.225 from the mean of 1.075: more than 20%. */
  set_faces(b, 1.3f), set_faces(c, 1.0f);
  out[0][0] = -7;
  assert_int_equal(gi__between_mean(v, out), 0);
  assert_true(out[0][0] == -7); /* untouched */
  /* A dark face beside a bright one: 0.01 apart on a voxel whose brightest face is 1. */
  set_faces(b, 1.0f);
  a[3][1] = 0.0f, b[3][1] = 0.02f, c[3][1] = 0.01f, d[3][1] = 0.01f;
  assert_int_equal(gi__between_mean(v, out), 1);
  assert_true(fabsf(out[3][1] - 0.01f) < 1e-7f);
  /* The same spread on a voxel that is dark all over disagrees. */
  set_faces(a, 0.01f), set_faces(b, 0.01f), set_faces(c, 0.01f), set_faces(d, 0.01f);
  a[3][1] = 0.0f, b[3][1] = 0.02f;
  assert_int_equal(gi__between_mean(v, out), 0);
  /* A NaN never agrees. */
  set_faces(a, 1.0f), set_faces(b, 1.0f), set_faces(c, 1.0f), set_faces(d, 1.0f);
  c[5][2] = NAN;
  assert_int_equal(gi__between_mean(v, out), 0);
}

/* A bake of the sunlit plane y = 0 around the origin (level 0 is all
 * plane) and level 0's plan. */
static gi_cascade *plane_plan(gi_scene **s, gi_between **plan) {
  *s = tu_sunlit_plane(0.5, 1.0, 100);
  gi_quality q = {0};
  q.levels = 3;
  q.res = 16;
  q.voxel0 = 1.0;
  q.threads = 2;
  gi_cascade *c = NULL;
  gi_error_info err = {0};
  assert_int_equal(gi_cascade_bake(*s, (const double[3]){0.3, 2.0, 0.3}, &q, &c, NULL, &err), GI_OK);
  *plan = NULL;
  assert_int_equal(gi__between_plan(c, 0, plan), GI_OK);
  return c;
}

static void cell_of(const gi_cascade *c, int d, int32_t occ, int64_t cell[3]) {
  gi__slot_cell(&c->lv[d], c->R, c->lv[d].occ[occ], cell);
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
  assert_true(planned > (int)L->num_occ / 2); /* three in four, less the border */
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
    uint32_t n = gi__between_fill(c, 0, plan, E, redo);
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
      cmocka_unit_test(test_plan_cells),
      cmocka_unit_test(test_fill_fields),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
