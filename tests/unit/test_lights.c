/* test_lights.c: direct light at a probe against closed-form answers.
 *
 * A probe 1 m above a large ground plane, each light on its own:
 *   sun of irradiance E straight down      -> E(up) = E
 *   point of intensity I at height 5 m     -> E(up) = I / 4^2
 *   spot, same, aimed down (30 deg cone)   -> I / 16 below it, 0 at 37 deg off-axis
 *   sky of radiance L, open upper half     -> E(up) = pi L (Monte Carlo, 4096 rays)
 * Delta lights take one shadow ray, so their answers are exact to float. */
#include "test_util.h"
#include <math.h>
#include <stdio.h>
#include "gi/gi.h"
#include "scene/lights.h"

static void direct_at(const gi_light *l, const double pts[][3], int n, float out[][3]) {
  gi_mesh_builder *b = gi_mesh_builder_new();
  gi_material m = {.albedo = {0.5f, 0.5f, 0.5f}, .roughness = 1};
  uint32_t mat = gi_mesh_builder_add_material(b, &m);
  double A[3] = {-500, 0, -500}, B[3] = {-500, 0, 500}, C[3] = {500, 0, 500}, D[3] = {500, 0, -500};
  gi_mesh_builder_add_quad(b, A, B, C, D, mat);
  gi_scene_options opt = {.up = GI_UP_Y, .lights = l, .num_lights = 1};
  gi_scene *s = NULL;
  gi_error_info err = {0};
  assert_int_equal(gi_scene_build(b, "plane", &opt, &s, &err), GI_OK);
  gi_mesh_builder_free(b);
  gi_quality q = {.levels = 2, .res = 16, .voxel0 = 1, .bounces = -1, .probe_samples = 4096};
  gi_cascade *c = NULL;
  gi_bake_report rep;
  double at[3] = {0, 1, 0};
  assert_int_equal(gi_cascade_bake(s, at, &q, &c, &rep, &err), GI_OK);
  for (int i = 0; i < n; i++) {
    gi_probe p;
    assert_int_equal(gi_cascade_gather(c, pts[i], 1, &p, NULL, &err), GI_OK);
    for (int k = 0; k < 3; k++) out[i][k] = p.direct[k];
  }
  gi_cascade_free(c);
  gi_scene_release(s);
}

static void test_delta_lights(void **state) {
  const double below[1][3] = {{0, 1, 0}};
  float e[2][3];
  gi_light sun = {.type = GI_LIGHT_SUN, .color = {2, 3, 4}, .direction = {0, -1, 0}};
  direct_at(&sun, below, 1, e);
  printf("sun: %g %g %g (exact 2 3 4)\n", e[0][0], e[0][1], e[0][2]);
  assert_true(fabsf(e[0][0] - 2) < 1e-5f && fabsf(e[0][2] - 4) < 1e-5f);

  gi_light pt = {.type = GI_LIGHT_POINT, .color = {10, 10, 10}, .position = {0, 5, 0}};
  direct_at(&pt, below, 1, e);
  printf("point: %g (exact 0.625)\n", e[0][0]);
  assert_true(fabsf(e[0][0] - 0.625f) < 1e-5f);

  gi_light spot = {.type = GI_LIGHT_SPOT, .color = {10, 10, 10}, .position = {0, 5, 0},
                   .direction = {0, -1, 0}, .cos_inner = cosf(10 * (float)M_PI / 180),
                   .cos_outer = cosf(15 * (float)M_PI / 180)};
  const double two[2][3] = {{0, 1, 0}, {3, 1, 0}};
  direct_at(&spot, two, 2, e);
  printf("spot: below %g (exact 0.625), 37 deg off-axis %g (exact 0)\n", e[0][0], e[1][0]);
  assert_true(fabsf(e[0][0] - 0.625f) < 1e-5f);
  assert_true(e[1][0] == 0);
}

static void test_sky(void **state) {
  const double below[1][3] = {{0, 1, 0}};
  float e[1][3];
  gi_light sky = {.type = GI_LIGHT_SKY, .color = {1, 1, 1}};
  direct_at(&sky, below, 1, e);
  printf("sky: %g (exact pi = %g)\n", e[0][0], M_PI);
  assert_true(fabsf(e[0][0] - (float)M_PI) < 0.02f * (float)M_PI);
}

/* The shadow-ray rule (scene/shadow.c) on a floor at y = 0 under an
 * emitter 0.01 above it, facing down, with a local voxel of 0.1 (offset
 * 0.002). Each case is one ray whose answer is known exactly. */
static void test_shadow_rule(void **state) {
  gi_mesh_builder *b = gi_mesh_builder_new();
  gi_material m = {.albedo = {0.5f, 0.5f, 0.5f}, .roughness = 1};
  gi_material e = {.emission = {1, 1, 1}, .roughness = 1};
  uint32_t mf = gi_mesh_builder_add_material(b, &m), me = gi_mesh_builder_add_material(b, &e);
  double A[3] = {-5, 0, -5}, B[3] = {-5, 0, 5}, C[3] = {5, 0, 5}, D[3] = {5, 0, -5};
  gi_mesh_builder_add_quad(b, A, B, C, D, mf);
  double EA[3] = {-0.1, 0.01, -0.1}, EB[3] = {0.1, 0.01, -0.1}, EC[3] = {0.1, 0.01, 0.1}, ED[3] = {-0.1, 0.01, 0.1};
  gi_mesh_builder_add_quad(b, EA, EB, EC, ED, me);
  gi_scene_options opt = {.up = GI_UP_Y};
  gi_scene *s = NULL;
  gi_error_info err = {0};
  assert_int_equal(gi_scene_build(b, "shadow", &opt, &s, &err), GI_OK);
  gi_mesh_builder_free(b);
  gi_ray_scratch sc = {0};
  assert_int_equal(gi__scratch_alloc(&sc, 4), 0);
  const float up[3] = {0, 1, 0}, voxel = 0.1f;
  /* Shadow rays take the scene's local frame (world minus its origin). */
  const double *o = s->origin;
  float p[3] = {(float)(0.05 - o[0]), (float)(0 - o[1]), (float)(0.05 - o[2])};
  /* A point on the emitter straight above, 0.01 away: visible. Aimed along w
   * from the offset start, the segment would end 0.002 past the emitter and
   * be blocked by it. Then the sun from below: the ray starts on the floor's
   * lower side and escapes. */
  gi_lsample ls[2] = {{.w = {0, 1, 0}, .dist = 0.01f}, {.w = {0, -1, 0}, .dist = INFINITY}};
  gi__shadow_rays(s, p, up, voxel, ls, 2, &sc);
  assert_int_equal(sc.vis[0], 1);
  assert_int_equal(sc.vis[1], 1);
  /* A light beyond the emitter, 1 above: the emitter blocks it. */
  gi_lsample far = {.w = {0, 1, 0}, .dist = 1.0f};
  gi__shadow_rays(s, p, up, voxel, &far, 1, &sc);
  assert_int_equal(sc.vis[0], 0);
  /* A point in space (no normal) skips hits closer than the offset: 0.001
   * above the floor it sees the sun below through it, 0.005 above not. */
  gi_lsample down = {.w = {0, -1, 0}, .dist = INFINITY};
  float q[3] = {(float)(2 - o[0]), (float)(0.001 - o[1]), (float)(2 - o[2])};
  gi__shadow_rays(s, q, NULL, voxel, &down, 1, &sc);
  assert_int_equal(sc.vis[0], 1);
  q[1] = (float)(0.005 - o[1]);
  gi__shadow_rays(s, q, NULL, voxel, &down, 1, &sc);
  assert_int_equal(sc.vis[0], 0);
  printf("shadow rule: offset %g voxels, shortening %g\n", (double)GI_SHADOW_OFFSET_VOXELS, (double)GI_SHADOW_SHORTEN);
  gi__scratch_free(&sc);
  gi_scene_release(s);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_delta_lights),
      cmocka_unit_test(test_sky),
      cmocka_unit_test(test_shadow_rule),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
