/* test_scene.c: the mesh builder, scene build, Embree queries and import. */
#include "test_util.h"
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "gi/gi_scene.h"
#include "scene_internal.h"

static gi_material grey(void) {
  gi_material m = {.albedo = {0.5f, 0.5f, 0.5f}, .roughness = 1.f};
  snprintf(m.name, sizeof m.name, "grey");
  return m;
}

static void test_builder_box(void **state) {
  gi_mesh_builder *b = gi_mesh_builder_new();
  gi_material m = grey();
  uint32_t mi = gi_mesh_builder_add_material(b, &m);
  double lo[3] = {-1, 2, 3}, hi[3] = {4, 5.5, 7};
  gi_mesh_builder_add_box(b, lo, hi, mi);
  gi_scene *s = NULL;
  gi_error_info err = {0};
  assert_int_equal(gi_scene_build(b, "box", NULL, &s, &err), GI_OK);
  gi_scene_stats st;
  gi_scene_get_stats(s, &st);
  assert_int_equal(st.triangles, 12);
  assert_int_equal(st.input_triangles, 12);
  assert_int_equal(st.dropped_degenerate, 0);
  assert_int_equal(st.materials, 1);
  assert_int_equal(st.lights, 0);
  double blo[3], bhi[3];
  gi_scene_bounds(s, blo, bhi);
  for (int k = 0; k < 3; k++) {
    assert_true(blo[k] == lo[k]);
    assert_true(bhi[k] == hi[k]);
  }
  assert_string_equal(gi_scene_name(s), "box");
  assert_int_equal(s->num_vertices, 8);
  gi_scene_release(s);
  gi_mesh_builder_free(b);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_builder_box),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
