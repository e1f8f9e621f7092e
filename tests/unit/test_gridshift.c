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
 * Every shift is asserted, the coarse ones too: 16 shifts here (one of
 * them moves level 3), worst 1.03% (bound 2%). The jump was the data of a
 * level filtered from a finer one whose border cells turn from own voxels
 * into filtered ones (placement alone moves the probe by 0.02% at most):
 * with one mean normal per voxel a coarse own voxel and the filter of its
 * children differed up to 10x at corners, 6.6% at step 211 of the x walk
 * (levels 0-3 moved). With orientation groups (cascade_internal.h) that
 * step jumps 0.22%. Beside a street lamp a shift still jumped 11.3%: the
 * housing's coarse own voxel read the lamp at its centroid, its children
 * at theirs, and the two differed by half (64.6 against 99.1). Since each
 * voxel's pieces of triangle take the lamp's light by their solid angle
 * (light/near_field.c) the lamp walk below jumps 1.03%. */
#include "test_util.h"
#include <math.h>
#include <stdio.h>
#include <string.h>
#include "gi/gi.h"

#define STEPS_PER_VOXEL 16
#define SHIFT_JUMP 0.02     /* the bound, at every shift */
#define LAMP_WALK_DX 26.6 /* from the default viewpoint (2.1, 1.7, 1.4) to x 28.7 */
#define LAMP_WALK_DZ 0.7
#define COARSE_LEVEL 3      /* a shift that moves this level or a coarser one moves a coarse window */

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

/* Walks `cells` anchor cells from the default viewpoint moved by (dx, 0, dz)
 * along axis; returns the worst jump at any shift, counting the shifts and
 * those that moved a coarse window. */
static double walk(const gi_scene *s, int axis, double dx, double dz, int cells, int *shifts, int *coarse) {
  gi_city_params cp = {0};
  double at0[3];
  gi_city_default_viewpoint(&cp, at0);
  at0[0] += dx, at0[2] += dz;
  gi_quality q = {.threads = 2}, rq;
  gi_error_info err = {0};
  assert_int_equal(gi_quality_resolve(s, &q, &rq, &err), GI_OK);
  double s0 = rq.voxel0, worst = 0;
  gi_cascade *c = NULL;
  int64_t cur[3] = {0, 0, 0};
  for (int i = 0; i <= cells * 2 * STEPS_PER_VOXEL; i++) {
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
      printf("gridshift: axis %d from (%+.0f, %+.0f), step %d: levels 0..%d moved, jump %.2f%%\n", axis, dx, dz, i,
             top, 100 * j);
      worst = fmax(worst, j), ++*shifts;
      *coarse += top >= COARSE_LEVEL;
    }
    gi_cascade_free(c);
    c = n;
    memcpy(cur, an, sizeof an);
  }
  gi_cascade_free(c);
  return worst;
}

static void test_shift_jump(void **state) {
  gi_city_params cp = {0};
  gi_scene *s = NULL;
  gi_error_info err = {0};
  assert_int_equal(gi_city_build(&cp, NULL, &s, &err), GI_OK);
  int shifts = 0, coarse = 0;
  double worst = fmax(walk(s, 0, 0, 0, 10, &shifts, &coarse), walk(s, 2, 7, 3, 4, &shifts, &coarse));
  /* Along the street past two lamps 23.4 m apart, one at each end of the
   * finest window (x 18.3 and 41.7): its shift near x 30.7 turns one
   * housing from an own voxel of level 1 into a filtered one and the other
   * back (gi-walk's worst step). */
  worst = fmax(worst, walk(s, 0, LAMP_WALK_DX, LAMP_WALK_DZ, 2, &shifts, &coarse));
  printf("gridshift: %d shifts (%d moving a coarse window), worst jump %.2f%% (bound %.0f%%)\n", shifts, coarse,
         100 * worst, 100 * SHIFT_JUMP);
  assert_true(shifts >= 12 && coarse >= 1);
  assert_true(worst <= SHIFT_JUMP);
  gi_scene_release(s);
}

int main(void) {
  const struct CMUnitTest tests[] = {cmocka_unit_test(test_shift_jump)};
  return cmocka_run_group_tests(tests, NULL, NULL);
}
