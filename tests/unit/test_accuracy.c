/* test_accuracy.c: the quick accuracy sweep on the Cornell box.
 *
 * The cone tracer and the path tracer are compared with a path-traced
 * reference (65536 paths per probe, unbounded depth) at the Cornell box
 * probes gi-accuracy uses (a 3x3x3 grid inside the box, minus the points
 * inside the blocks). Error must fall as quality rises, for both methods,
 * and the default quality must stay under a bound. The bounds are the
 * measured values plus a margin, measured on a 2-core AMD EPYC VM; the
 * bakes are deterministic, so a change in them is a change in the code,
 * not noise (the reference's own noise is printed: ~0.8% on indirect).
 * The reference's noise does move the MREs, though: at 16384 paths the
 * default-vs-high ordering of indirect MRE (0.7 points apart) flipped for
 * 1 reference seed in 6, with either path tracer; at 65536 it held for all.
 * Skips loudly when ../shared/scenes is absent. */
#include "test_util.h"
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "gi/gi.h"
#include "metrics.h"

#define MAXP 27

typedef struct {
  gi_scene *s;
  double at[3], pts[3 * MAXP];
  size_t n;
  gi_ref_probe ref[MAXP];
} cornell;

static int setup(void **state) {
  const char *path = tu_scene_path("cornell-box/cornell-box.obj");
  if (!path) {
    *state = NULL;
    return 0;
  }
  cornell *c = calloc(1, sizeof *c);
  gi_error_info err = {0};
  gi_scene_options so = {.up = GI_UP_Y};
  if (!c || gi_scene_load(path, &so, &c->s, &err) != GI_OK) return -1;
  c->at[0] = 278, c->at[1] = 273, c->at[2] = 279.6;
  double lo[3], hi[3], cand[3 * 27];
  gi_scene_bounds(c->s, lo, hi);
  static const double f[3] = {0.2, 0.5, 0.8};
  for (int i = 0; i < 27; i++) {
    int ix[3] = {i % 3, (i / 3) % 3, i / 9};
    for (int k = 0; k < 3; k++) cand[3 * i + k] = lo[k] + f[ix[k]] * (hi[k] - lo[k]);
  }
  /* Drop points inside the blocks (no direct light at all), as gi-accuracy does. */
  gi_ref_probe d[27];
  gi_reference_opts od = {.samples = 64, .max_depth = -1, .seed = 7};
  if (gi_reference_irradiance(c->s, cand, 27, &od, d, NULL, &err) != GI_OK) return -1;
  double best = 0;
  for (int i = 0; i < 27; i++) best = fmax(best, d[i].direct[1]);
  for (int i = 0; i < 27; i++)
    if (d[i].direct[1] > 0.02 * best) memcpy(&c->pts[3 * c->n++], &cand[3 * i], sizeof(double[3]));
  gi_reference_opts o = {.samples = 65536, .seed = 1};
  double ms = 0;
  if (gi_reference_irradiance(c->s, c->pts, c->n, &o, c->ref, &ms, &err) != GI_OK) return -1;
  acc_metrics m;
  acc_compare_refs(c->ref, c->ref, c->n, ACC_INDIRECT, &m);
  printf("cornell: %zu probes, reference %.0f ms, its relative standard error on indirect %.2f%%\n", c->n, ms,
         100 * m.ref_rel_se);
  *state = c;
  return 0;
}

static int teardown(void **state) {
  cornell *c = *state;
  if (c) gi_scene_release(c->s);
  free(c);
  return 0;
}

static void bake_metrics(const cornell *c, const gi_quality *q, const char *what, acc_metrics m[3]) {
  gi_cascade *cas = NULL;
  gi_bake_report rep;
  gi_error_info err = {0};
  gi_probe pr[MAXP];
  double t0 = 0;
  gi_result rc = gi_cascade_bake(c->s, c->at, q, &cas, &rep, &err);
  if (rc) fprintf(stderr, "%s: %s\n", what, err.msg);
  assert_int_equal(rc, GI_OK);
  assert_int_equal(gi_cascade_gather(cas, c->pts, c->n, pr, &t0, &err), GI_OK);
  for (int p = 0; p < 3; p++) acc_compare_probes(pr, c->ref, c->n, (acc_part)p, &m[p]);
  printf("%-8s MRE total %.2f%%  direct %.2f%%  indirect %.2f%%  indirect bias %.3f [%.3f, %.3f]\n", what,
         100 * m[0].mre, 100 * m[1].mre, 100 * m[2].mre, m[2].ratio_mean, m[2].ratio_min, m[2].ratio_max);
  gi_cascade_free(cas);
}

static void test_cone_error_falls(void **state) {
  cornell *c = *state;
  if (!c) skip();
  gi_quality dq = {0};
  gi_cascade *tmp = NULL;
  gi_bake_report rep;
  gi_error_info err = {0};
  assert_int_equal(gi_cascade_bake(c->s, c->at, &dq, &tmp, &rep, &err), GI_OK);
  double s0 = rep.quality.voxel0;
  gi_cascade_free(tmp);
  gi_quality low = {.res = 16, .voxel0 = s0 * 2, .cones = 6, .bounces = 1};
  /* High: finer voxels over the same extent, 32 cones, bounces from the
   * same albedo rule as the default (3 and the geometric tail of the rest),
   * and light sampled as the service's "high" preset does (64 rays per
   * voxel, 1024 per probe). Finer voxels alone (res 48, 16 cones) leave the
   * indirect error at the probes where indirect light dominates where it
   * was (8.9% -> 8.9% MRE; two probes worse), so their total was not below
   * the default's once the default's direct light stopped being noisy
   * (light tree): that setting compared noise, not quality. */
  gi_quality high = {.res = 48, .voxel0 = s0 * 32 / 48, .cones = 32, .light_samples = 64, .probe_samples = 1024};
  acc_metrics ml[3], md[3], mh[3];
  bake_metrics(c, &low, "low", ml);
  bake_metrics(c, &dq, "default", md);
  bake_metrics(c, &high, "high", mh);
  assert_true(ml[ACC_INDIRECT].mre > md[ACC_INDIRECT].mre);
  assert_true(md[ACC_INDIRECT].mre > mh[ACC_INDIRECT].mre);
  assert_true(ml[ACC_TOTAL].rel_mse > md[ACC_TOTAL].rel_mse && md[ACC_TOTAL].rel_mse > mh[ACC_TOTAL].rel_mse);
  /* Default-quality bounds (4 bounces from the albedo rule, plus the
   * geometric tail of the orders after them). Measured: indirect MRE
   * 6.46%, total 1.38% (the ambition is 10% on indirect); high quality
   * 3.23% indirect, 0.82% total. */
  assert_true(md[ACC_INDIRECT].mre < 0.12);
  assert_true(md[ACC_TOTAL].mre < 0.03);
  assert_true(mh[ACC_INDIRECT].mre < 0.10);
  /* The direct part is Monte Carlo at the probe in both: 256 probe samples
   * against the reference's 65536. Measured 0.72% (light tree, emitter
   * points stratified; 1.86% picking by power alone). */
  assert_true(md[ACC_DIRECT].mre < 0.03);
}

static void test_path_error_falls(void **state) {
  cornell *c = *state;
  if (!c) skip();
  double prev = INFINITY;
  for (int s = 16; s <= 4096; s *= 16) {
    gi_ref_probe pr[MAXP];
    gi_reference_opts o = {.samples = s, .seed = 2};
    gi_error_info err = {0};
    assert_int_equal(gi_reference_irradiance(c->s, c->pts, c->n, &o, pr, NULL, &err), GI_OK);
    acc_metrics m;
    acc_compare_refs(pr, c->ref, c->n, ACC_TOTAL, &m);
    printf("path %4d samples: MRE total %.2f%%\n", s, 100 * m.mre);
    /* 16x the samples: a quarter of the noise, less the reference's own. */
    assert_true(m.mre < 0.5 * prev);
    prev = m.mre;
  }
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_cone_error_falls),
      cmocka_unit_test(test_path_error_falls),
  };
  return cmocka_run_group_tests(tests, setup, teardown);
}
