/* test_cornell.c: the Cornell box (shared scene) bleeds colour the right way.
 *
 * The red wall is at x = 556 mm, the green one at x = 0. Indirect light
 * arriving at a probe 40 mm from the red wall, on the side facing it, must be
 * redder (higher R/G) than at the mirror probe by the green wall, and the
 * other way round for green. Skips loudly when ../shared/scenes is absent. */
#include "test_util.h"
#include <math.h>
#include <stdio.h>
#include "gi/gi.h"

static void ind_facing(const gi_probe *p, const float n[3], float out[3]) {
  float sh[9][3];
  for (int i = 0; i < 9; i++)
    for (int k = 0; k < 3; k++) sh[i][k] = p->sh[i][k] - p->sh_direct[i][k];
  gi_sh_eval_irradiance((const float(*)[3])sh, n, out);
}

static void test_cornell_bleeding(void **state) {
  TU_SKIP_IF_NO_SCENE(path, "cornell-box/cornell-box.obj");
  gi_scene *sc = NULL;
  gi_error_info err = {0};
  gi_scene_options opt = {.up = GI_UP_Y};
  assert_int_equal(gi_scene_load(path, &opt, &sc, &err), GI_OK);
  gi_quality q = {0};
  gi_cascade *c = NULL;
  gi_bake_report rep;
  double at[3] = {278, 273, 279.6};
  gi_result rc = gi_cascade_bake(sc, at, &q, &c, &rep, &err);
  if (rc) fprintf(stderr, "%s\n", err.msg);
  assert_int_equal(rc, GI_OK);
  printf("cornell: voxelize %.1f ms, inject %.1f ms, bounce %.1f ms, s0 %.3f mm, %llu shadow rays\n",
         rep.ms.voxelize, rep.ms.inject, rep.ms.bounce, rep.quality.voxel0,
         (unsigned long long)rep.shadow_rays);
  assert_true(rep.effects[GI_FX_EMISSIVE].ran);
  assert_false(rep.effects[GI_FX_SUN].ran);
  double pts[3][3] = {{516, 273, 279.6}, {40, 273, 279.6}, {278, 273, 279.6}};
  gi_probe pr[3];
  assert_int_equal(gi_cascade_gather(c, &pts[0][0], 3, pr, NULL, &err), GI_OK);
  for (int p = 0; p < 3; p++)
    for (int i = 0; i < 9; i++)
      for (int k = 0; k < 3; k++) assert_true(isfinite(pr[p].sh[i][k]));
  const float to_red[3] = {1, 0, 0}, to_green[3] = {-1, 0, 0};
  float r[3], g[3];
  ind_facing(&pr[0], to_red, r);
  ind_facing(&pr[1], to_green, g);
  printf("indirect facing the red wall:   (%.4f, %.4f, %.4f)  R/G %.3f\n", r[0], r[1], r[2], r[0] / r[1]);
  printf("indirect facing the green wall: (%.4f, %.4f, %.4f)  R/G %.3f\n", g[0], g[1], g[2], g[0] / g[1]);
  printf("centre probe: direct E(up) (%.4f, %.4f, %.4f), indirect (%.4f, %.4f, %.4f)\n", pr[2].direct[0],
         pr[2].direct[1], pr[2].direct[2], pr[2].indirect[0], pr[2].indirect[1], pr[2].indirect[2]);
  for (int k = 0; k < 3; k++) assert_true(r[k] > 0 && g[k] > 0);
  assert_true(r[0] / r[1] > 1.5f * (g[0] / g[1]));
  assert_true(g[1] / g[0] > 1.5f * (r[1] / r[0]));
  /* Direct light comes from above: a probe's upward irradiance exceeds its downward one. */
  float down[3] = {0, -1, 0}, e_down[3];
  gi_sh_eval_irradiance((const float(*)[3])pr[2].sh_direct, down, e_down);
  assert_true(pr[2].direct[0] > 5 * fmaxf(e_down[0], 0));
  gi_cascade_free(c);
  gi_scene_release(sc);
}

int main(void) {
  const struct CMUnitTest tests[] = {cmocka_unit_test(test_cornell_bleeding)};
  return cmocka_run_group_tests(tests, NULL, NULL);
}
