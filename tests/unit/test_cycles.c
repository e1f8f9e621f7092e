/* test_cycles.c: gi-accuracy's Blender Cycles comparison
 * (tools/gi-accuracy/cycles.c) on a view whose answer is known, so a
 * Cycles figure in the report compares the same scene, camera, lights and
 * units as ours.
 *
 * A ground plane (Z up) in two halves, albedo 0.2 for x < 0 and 0.8 for
 * x > 0, under a sun 30 degrees from the zenith and a black sky: every
 * pixel shows exactly a E cos30 / pi in both renderers (the sun sampled
 * as a delta light, every bounce escaping into the black sky). The camera
 * looks north from the south, so x < 0 is the left half of the image; the
 * seam x = 0 falls on the border between the two middle columns, so no
 * pixel mixes the halves. Cycles at 16 samples must match our path tracer
 * and the exact values (a mirrored or misoriented picture, a sun pointing
 * the wrong way or in other units would not). Skips loudly without
 * blender on PATH. */
#include "test_util.h"
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "acc.h"
#include "gi/gi.h"

enum { W = 48, H = 32 };

static const char *const obj_text =
    "mtllib halves.mtl\n"
    "v -500 -500 0\nv 0 -500 0\nv 0 500 0\nv -500 500 0\nv 500 -500 0\nv 500 500 0\n"
    "usemtl dark\nf 1 2 3 4\nusemtl bright\nf 2 5 6 3\n";
static const char *const mtl_text = "newmtl dark\nKd 0.2 0.2 0.2\nnewmtl bright\nKd 0.8 0.8 0.8\n";

static void test_cycles_halves(void **state) {
  if (!acc_have_blender()) {
    printf("SKIP: blender is not on PATH\n");
    skip();
  }
  tu_write_file("halves.mtl", mtl_text, strlen(mtl_text));
  const char *obj = tu_write_file("halves.obj", obj_text, strlen(obj_text));
  const double E = 3, c30 = sqrt(3.0) / 2;
  gi_light sun = {.type = GI_LIGHT_SUN, .color = {E, E, E}, .direction = {0.5f, 0, (float)-c30}};
  gi_scene_options so = {.up = GI_UP_Z, .lights = &sun, .num_lights = 1};
  gi_scene *s = NULL;
  gi_error_info err = {0};
  assert_int_equal(gi_scene_load(obj, &so, &s, &err), GI_OK);
  gi_camera cam = {.eye = {0, -20, 15}, .target = {0, 0, 0}, .up = {0, 0, 1}, .fov_deg = 60, .width = W, .height = H};
  static float ref[W * H * 3], cyc[W * H * 3];
  assert_int_equal(gi_reference_render(s, &cam, 16, 1, 2, ref, NULL, &err), GI_OK);
  double ms = 0;
  assert_int_equal(acc_cycles_image(obj, tu_tmpdir(), s, &cam, 16, cyc, &ms), 1);
  const double dark = 0.2 * E * c30 / M_PI, bright = 0.8 * E * c30 / M_PI;
  static unsigned char mask[W * H];
  memset(mask, 1, sizeof mask);
  double mre = acc_image_mre(cyc, ref, mask, W * H, 0);
  printf("Cycles %.1f ms; MRE against ours %.2g; pixel (5, 20) %.4f / %.4f (exact %.4f), (40, 20) %.4f / %.4f "
         "(exact %.4f)\n", ms, mre, cyc[3 * (20 * W + 5)], ref[3 * (20 * W + 5)], dark, cyc[3 * (20 * W + 40)],
         ref[3 * (20 * W + 40)], bright);
  assert_true(ms > 0);
  for (int y = 0; y < H; y++)
    for (int x = 0; x < W; x++) {
      double want = x < W / 2 ? dark : bright;
      for (int k = 0; k < 3; k++) {
        assert_true(fabs(ref[3 * (y * W + x) + k] - want) < 1e-4 * want);
        assert_true(fabs(cyc[3 * (y * W + x) + k] - want) < 1e-2 * want);
      }
    }
  assert_true(mre < 1e-2);
  gi_scene_release(s);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_cycles_halves),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
