/* test_cone.c: the cone-tracing filter on hand-built textures.
 *
 * Two levels (s0 = 1 m, R = 16) around the origin: level 0 spans
 * [-8, 8) m, level 1 [-16, 16) m. Walls are written straight into the
 * light buffers, with a different radiance per level, so the radiance a
 * cone returns says which level it sampled. */
#include "test_util.h"
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "cascade/cascade_internal.h"
#include "light/light.h"
#include "trace/trace.h"
#include "scene/lights.h"
#include "answer/answer.h"

static struct gi_cascade *make(int levels) {
  static struct gi_cascade c;
  gi__cascade_free_levels(&c);
  memset(&c, 0, sizeof c);
  c.n = levels;
  c.R = 16;
  c.s0 = 1.0;
  c.at[0] = c.at[1] = c.at[2] = 0.1f;
  assert_int_equal(gi__cascade_alloc(&c, NULL), GI_OK);
  gi__cascade_place(&c);
  return &c;
}

/* Fills the slab of global cells x = i at level d: opacity alpha along x,
 * radiance L leaving toward -x (lit side facing the origin), 0 toward +x. */
static void slab(struct gi_cascade *c, int d, int64_t i, float alpha, float L) {
  gi_level *lv = &c->lv[d];
  for (int64_t k = lv->cell0[2]; k < lv->cell0[2] + c->R; k++)
    for (int64_t j = lv->cell0[1]; j < lv->cell0[1] + c->R; j++) {
      gi_vrad_f v;
      memset(&v, 0, sizeof v);
      v.alpha[0] = alpha;
      v.tau[0] = -logf(1 - alpha);
      for (int ch = 0; ch < 3; ch++) v.p[GI_FACE_NX][ch] = alpha * L;
      gi__vrad_pack(c, &v, &lv->rad[gi__slot(i, j, k, c->R)]);
    }
}

static gi_cone_out trace(struct gi_cascade *c, float ox, float dirx, float tan_half, float step) {
  gi__cascade_mark_busy(c);
  float o[3] = {ox, 0.3f, 0.2f}, w[3] = {dirx, 0, 0};
  gi_cone_out out;
  gi__cone_march(c, o, w, tan_half, 0.5f, step, 0.f, -1.f, NULL, &out);
  return out;
}

static void test_level_selection(void **state) {
  struct gi_cascade *c = make(2);
  slab(c, 0, 4, 0.999f, 1.0f); /* x in [4,5) at level 0: radiance 1 */
  slab(c, 1, 2, 0.999f, 3.0f); /* x in [4,6) at level 1: radiance 3 */
  slab(c, 1, 6, 0.999f, 5.0f); /* x in [12,14) at level 1 only: radiance 5 */
  /* Narrow: D = s0 all the way, so level 0. */
  gi_cone_out n = trace(c, 0.5f, 1, 1e-4f, 0.5f);
  printf("narrow: L=%.4f a=%.4f\n", n.L[0], n.alpha);
  assert_true(n.alpha >= 0.99f);
  assert_true(fabsf(n.L[0] - 1.0f) < 0.01f);
  /* Wide: D >= 2 s0 at the wall, so level 1. */
  gi_cone_out wd = trace(c, 0.5f, 1, 0.5f, 0.5f);
  printf("wide: L=%.4f a=%.4f\n", wd.L[0], wd.alpha);
  assert_true(fabsf(wd.L[0] - 3.0f) < 0.05f);
  /* In between: lod about 0.5 at the wall blends the two levels. */
  gi_cone_out mid = trace(c, 0.5f, 1, 0.177f, 0.5f);
  printf("blend: L=%.4f a=%.4f\n", mid.L[0], mid.alpha);
  assert_true(mid.L[0] > 1.4f && mid.L[0] < 2.6f);
  /* Position: beyond level 0's window a narrow cone must use level 1. */
  gi_cone_out far = trace(c, 8.5f, 1, 1e-4f, 0.5f);
  printf("outside level 0: L=%.4f a=%.4f\n", far.L[0], far.alpha);
  assert_true(fabsf(far.L[0] - 5.0f) < 0.05f);
  /* From behind, the wall is opaque and dark. */
  gi_cone_out back = trace(c, 6.5f, -1, 1e-4f, 0.5f);
  printf("behind: L=%.4f a=%.4f\n", back.L[0], back.alpha);
  assert_true(back.alpha >= 0.99f && back.L[0] < 1e-3f);
  /* Nothing in the way: the cone leaves the coarsest level transparent. */
  gi_cone_out none = trace(c, 0.5f, -1, 1e-4f, 0.5f);
  assert_true(none.alpha == 0 && none.L[0] == 0);
}

static void test_compositing(void **state) {
  struct gi_cascade *c = make(1);
  slab(c, 0, 2, 0.5f, 4.0f);   /* half-transparent, radiance 4 */
  slab(c, 0, 5, 0.999f, 2.0f); /* opaque behind it, radiance 2 */
  /* Front to back: 0.5 * 4 + (1 - 0.5) * 2 = 3, for any step length. */
  const float steps[] = {0.2f, 0.5f, 1.0f};
  for (int i = 0; i < 3; i++) {
    gi_cone_out o = trace(c, 0.5f, 1, 1e-4f, steps[i]);
    printf("step %.1f: L=%.4f a=%.4f samples=%u\n", steps[i], o.L[0], o.alpha, o.samples);
    assert_true(fabsf(o.L[0] - 3.0f) < 0.09f);
    assert_true(o.alpha >= 0.99f);
  }
}

/* One voxel at cell (0, 4, 0) of opacity alpha along the axes in `axes`
 * (bit a), its -y face sending radiance L down, the other faces dark. */
static void lit_voxel(struct gi_cascade *c, float alpha, float L, int axes) {
  gi_vrad_f v;
  memset(&v, 0, sizeof v);
  for (int a = 0; a < 3; a++)
    if (axes >> a & 1) v.alpha[a] = alpha, v.tau[a] = -logf(1 - alpha);
  for (int ch = 0; ch < 3; ch++) v.p[GI_FACE_NY][ch] = alpha * L;
  gi__vrad_pack(c, &v, &c->lv[0].rad[gi__slot(0, 4, 0, c->R)]);
  gi__cascade_mark_busy(c);
}

/* The light a beam of thin rays along w, 5 m across (past the trilinear
 * footprint's 2 voxels), gathers from that voxel: radiance times area. */
static double beam_flux(struct gi_cascade *c, const float w[3], const float u[3]) {
  const double ctr[3] = {0.5, 4.5, 0.5}, cell = 0.05;
  const int half = 50;
  double flux = 0;
  for (int a = -half; a <= half; a++)
    for (int b = -half; b <= half; b++) {
      float o[3] = {(float)(ctr[0] - 3 * w[0] + a * cell * u[0]), (float)(ctr[1] - 3 * w[1] + a * cell * u[1]),
                    (float)(ctr[2] + b * cell)};
      gi_cone_out out;
      gi__cone_march(c, o, w, 1e-4f, 0.f, 1.f, 0.f, -1.f, NULL, &out);
      flux += out.L[0] * cell * cell;
    }
  return flux;
}

/* Beams at `step` degree intervals up to 60 degrees off -y, in the x-y
 * plane: each sums L alpha |w_y| s^2 times tau / alpha. */
static void check_beams(struct gi_cascade *c, const char *what, int step, float alpha, float L) {
  const float tau = -logf(1 - alpha);
  for (int deg = 0; deg <= 60; deg += step) {
    double th = deg * M_PI / 180;
    float w[3] = {(float)sin(th), (float)cos(th), 0}, u[3] = {(float)cos(th), (float)-sin(th), 0};
    double flux = beam_flux(c, w, u), face = L * alpha * w[1], ratio = flux / face;
    printf("%s, rays at %d degrees: %.5f against the lit face's %.5f: %.3f (tau / alpha %.3f)\n", what, deg, flux,
           face, ratio, tau / alpha);
    assert_true(ratio > 1.0 && ratio < tau / alpha + 0.015);
  }
}

/* One small source at one level: a voxel of opacity 0.1 along y whose -y
 * face sends radiance L down, crossed by a beam of thin rays from below at
 * 0, 30 and 60 degrees. Summed over the beam's cross-section the light is
 * the flux a plate covering a tenth of the voxel sends that way, L alpha
 * |w_y| s^2, times tau / alpha (1.054: the march integrates optical depth,
 * linear in tau where the plate's coverage is alpha) up to the second order
 * of the exponential: the trilinear footprint, the steps and the face
 * weights lose and invent no light. (Across levels the same source reads
 * 0.85-1.5x by where it sits in the coarser voxels: docs/accuracy.md.) */
static void test_small_source_flux(void **state) {
  struct gi_cascade *c = make(1);
  lit_voxel(c, 0.1f, 4.0f, 2); /* a plate: opacity along y only */
  check_beams(c, "small source", 30, 0.1f, 4.0f);
}

/* A small closed solid: a voxel of opacity 0.1 along every axis (a box
 * seen from any side covers a tenth of the voxel) whose -y face sends
 * radiance L down and whose other faces are dark, crossed by beams of thin
 * rays from below, 0 to 60 degrees off the axis. The light the beam sums
 * is what the lit face sends that way, L alpha |w_y| s^2 (times the
 * march's tau / alpha, as above): a sample's colour is the faces' light
 * weighted by their projected area |w_a| alpha_a, the same weights its
 * opacity sums (tau along w, sum |w_a| tau_a). Weighting the faces by w_a^2
 * instead (before this test) read the lit face 1.22x at 15 degrees: it
 * over-weighted the face most aligned with the ray against the opacity's
 * own weights. */
static void test_box_voxel_flux(void **state) {
  struct gi_cascade *c = make(1);
  lit_voxel(c, 0.1f, 4.0f, 7);
  check_beams(c, "box voxel", 15, 0.1f, 4.0f);
}

static void test_cone_sets(void **state) {
  const int counts[] = {4, 6, 8, 16, 32};
  for (int i = 0; i < 5; i++) {
    float dirs[64][3], w[64], th;
    gi__cone_set(counts[i], 0, dirs, w, &th);
    double sum = 0, mean_cos = 0;
    for (int k = 0; k < counts[i]; k++) {
      sum += w[k];
      assert_true(fabsf(gi__len(dirs[k]) - 1) < 1e-5f);
      assert_true(dirs[k][2] > 0);
      mean_cos += w[k] * dirs[k][2];
    }
    /* Weights integrate the cosine lobe: pi. Cone solid angle = 2 pi / N. */
    assert_true(fabs(sum - M_PI) < 1e-5);
    double half = atan(th);
    assert_true(fabs(2 * M_PI * (1 - cos(half)) - 2 * M_PI / counts[i]) < 1e-5);
    /* Cos-weighted mean of cos over the hemisphere is 2/3 (int cos^2 / int cos). */
    printf("%d cones: sum w = %.6f, aperture %.2f deg, mean cos %.4f (exact 0.6667)\n", counts[i], sum,
           2 * half * 180 / M_PI, mean_cos / sum);
    assert_true(fabs(mean_cos / sum - 2.0 / 3.0) < (counts[i] >= 16 ? 0.02 : 0.06));
  }
}

/* The later bounces' wide set: 8 cones (the bake's own count when that is
 * smaller), unit directions in the hemisphere, weights summing to pi, each
 * cone wider than the bake set's; a chosen aperture scales it alike. */
static void test_wide_cone_set(void **state) {
  const int counts[] = {4, 6, 8, 16, 32};
  for (int i = 0; i < 5; i++) {
    float dirs[64][3], w[64], th, bake_dirs[64][3], bake_w[64], bake_th;
    int n = gi__wide_cone_count(counts[i]);
    assert_int_equal(n, counts[i] < 8 ? counts[i] : 8);
    gi__wide_cone_set(counts[i], 0, dirs, w, &th);
    gi__cone_set(counts[i], 0, bake_dirs, bake_w, &bake_th);
    double sum = 0;
    for (int k = 0; k < n; k++) {
      sum += w[k];
      assert_true(w[k] > 0);
      assert_true(fabsf(gi__len(dirs[k]) - 1) < 1e-5f);
      assert_true(dirs[k][2] > 0);
    }
    printf("wide set of %d bake cones: %d cones, sum w = %.6f, aperture %.2f deg (bake %.2f)\n", counts[i], n, sum,
           2 * atan(th) * 180 / M_PI, 2 * atan(bake_th) * 180 / M_PI);
    assert_true(fabs(sum - M_PI) < 1e-5);
    assert_true(fabs(2 * M_PI * (1 - cos(atan(th))) - 2 * M_PI / n) < 1e-5);
    if (n < counts[i]) assert_true(th > bake_th);
    else assert_true(th == bake_th);
  }
  /* A 40-degree request on 16 bake cones widens the 8 by the same factor. */
  float dirs[64][3], w[64], th;
  gi__wide_cone_set(16, 40.f, dirs, w, &th);
  double want = 40.0 * acos(1.0 - 1.0 / 8) / acos(1.0 - 1.0 / 16);
  assert_true(fabs(2 * atan(th) * 180 / M_PI - want) < 1e-3);
}

static void test_sh_constant(void **state) {
  /* Constant radiance 1 over the sphere: irradiance pi for every normal. */
  float sh[9][3] = {{0}};
  const int n = 20000;
  float L[3] = {1, 1, 1};
  for (int i = 0; i < n; i++) {
    float z = 1 - 2 * (i + 0.5f) / n, r = sqrtf(1 - z * z), phi = 2.399963f * i;
    float w[3] = {r * cosf(phi), r * sinf(phi), z};
    gi__sh_add(sh, w, L, 4 * (float)M_PI / n);
  }
  gi__sh_radiance_to_irradiance(sh);
  float ns[3][3] = {{1, 0, 0}, {0, -1, 0}, {0.6f, 0, 0.8f}};
  for (int i = 0; i < 3; i++) {
    float e[3];
    gi_sh_eval_irradiance((const float(*)[3])sh, ns[i], e);
    assert_true(fabsf(e[0] - (float)M_PI) < 1e-3f);
  }
}

static void test_specular_cone(void **state) {
  struct gi_cascade *c = make(2);
  slab(c, 0, 4, 0.999f, 2.0f); /* a wall of radiance 2 at x in [4,5) facing -x */
  gi__cascade_mark_busy(c);
  /* A floor point looking at 45 degrees: the mirror ray goes +x and meets the wall. */
  float p[3] = {0.5f, -2.0f, 0.2f}, n[3] = {0, 1, 0};
  float v[3] = {0.70710678f, -0.70710678f, 0};
  gi_cone_out o;
  gi__specular_trace(c, p, n, v, 0.1f, 1, &o);
  printf("specular: L=%.4f a=%.4f\n", o.L[0], o.alpha);
  assert_true(fabsf(o.L[0] - 2.0f) < 0.02f && o.alpha >= 0.99f);
  /* Reflected away from the wall: nothing. */
  float v2[3] = {-0.70710678f, -0.70710678f, 0};
  gi__specular_trace(c, p, n, v2, 0.1f, 1, &o);
  assert_true(o.L[0] == 0);
  /* The cone widens with roughness (strictly once above the half-degree
   * floor) and stays a lobe. */
  float prev = 0;
  for (int i = 0; i <= 10; i++) {
    float t = gi__specular_tan(i / 10.0f);
    assert_true(i < 2 ? t >= prev : t > prev);
    assert_true(t <= tanf(1.3963f));
    prev = t;
  }
  printf("specular half-angles: r=0.1 %.2f deg, r=0.5 %.2f deg, r=1 %.2f deg\n",
         atanf(gi__specular_tan(0.1f)) * 57.2958f, atanf(gi__specular_tan(0.5f)) * 57.2958f,
         atanf(gi__specular_tan(1.0f)) * 57.2958f);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_level_selection),
      cmocka_unit_test(test_compositing),
      cmocka_unit_test(test_small_source_flux),
      cmocka_unit_test(test_box_voxel_flux),
      cmocka_unit_test(test_cone_sets),
      cmocka_unit_test(test_wide_cone_set),
      cmocka_unit_test(test_sh_constant),
      cmocka_unit_test(test_specular_cone),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
