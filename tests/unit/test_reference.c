/* test_reference.c: the path tracer against closed-form answers.
 *
 * The reference is what every accuracy figure is measured against, so it
 * is checked itself, each time within a bound taken from the standard
 * error it reports (so a wrong error estimate fails too):
 *   white furnace, albedo a, emission Le: E / pi = Le (1 + a + ... + a^k)
 *     with k reflections, Le / (1 - a) unbounded (Russian roulette);
 *   sun of irradiance E at 60 degrees over a plane of albedo a:
 *     E(up) = E cos 60 exactly (direct), E(down) = a E cos 60 (the plane);
 *   sky of radiance L over the same open plane: E(up) = pi L, E(down) = a pi L;
 *   every light kind at once (sun, sky, point, spot, an emissive quad): the
 *   direct irradiance at a few points against the lights' own formulas and
 *   Lambert's polygon formula for the quad, within 3 standard errors of the
 *   spread over 32 seeds. The reference samples lights with its own code,
 *   so this pins its light models to the physics, not to the bake's sampler.
 * The standard error is itself checked against the spread over 8 seeds.
 * The reference's own camera, PCG32 stream and frame are checked against
 * the view's camera, the published generator and orthonormality. */
#include "test_util.h"
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "answer/answer.h"
#include "gi/gi.h"
#include "reference/ref_internal.h"

static const double PI = 3.14159265358979;

static gi_scene *make_furnace(double a, double Le) {
  gi_mesh_builder *b = gi_mesh_builder_new();
  gi_material m = {.albedo = {a, a, a}, .emission = {Le, Le, Le}, .roughness = 1};
  uint32_t mat = gi_mesh_builder_add_material(b, &m);
  double P[8][3];
  for (int i = 0; i < 8; i++) P[i][0] = i & 1, P[i][1] = (i & 2) ? 1 : 0, P[i][2] = (i & 4) ? 1 : 0;
  /* Wound so normals point into the cube (emitters are one-sided). */
  static const int q[6][4] = {{0, 2, 6, 4}, {1, 5, 7, 3}, {0, 4, 5, 1}, {2, 3, 7, 6}, {0, 1, 3, 2}, {4, 6, 7, 5}};
  for (int f = 0; f < 6; f++) gi_mesh_builder_add_quad(b, P[q[f][0]], P[q[f][1]], P[q[f][2]], P[q[f][3]], mat);
  gi_scene *s = NULL;
  gi_error_info err = {0};
  gi_scene_options opt = {.up = GI_UP_Y};
  assert_int_equal(gi_scene_build(b, "furnace", &opt, &s, &err), GI_OK);
  gi_mesh_builder_free(b);
  return s;
}

static gi_scene *make_plane(const gi_light *l, double a) {
  gi_mesh_builder *b = gi_mesh_builder_new();
  gi_material m = {.albedo = {a, a, a}, .roughness = 1};
  uint32_t mat = gi_mesh_builder_add_material(b, &m);
  double A[3] = {-1000, 0, -1000}, B[3] = {-1000, 0, 1000}, C[3] = {1000, 0, 1000}, D[3] = {1000, 0, -1000};
  gi_mesh_builder_add_quad(b, A, B, C, D, mat);
  gi_scene_options opt = {.up = GI_UP_Y, .lights = l, .num_lights = 1};
  gi_scene *s = NULL;
  gi_error_info err = {0};
  assert_int_equal(gi_scene_build(b, "plane", &opt, &s, &err), GI_OK);
  gi_mesh_builder_free(b);
  return s;
}

static gi_ref_probe ref_at(const gi_scene *s, const double p[3], int samples, int depth, uint64_t seed) {
  gi_reference_opts o = {.samples = samples, .max_depth = depth, .seed = seed};
  gi_ref_probe r;
  gi_error_info err = {0};
  gi_result rc = gi_reference_irradiance(s, p, 1, &o, &r, NULL, &err);
  if (rc) fprintf(stderr, "reference: %s\n", err.msg);
  assert_int_equal(rc, GI_OK);
  for (int k = 0; k < 3; k++) assert_true(isfinite(r.irradiance[k]) && isfinite(r.std_err[k]));
  return r;
}

/* |got - want| within 4 standard errors (plus float rounding). */
static void near_se(const char *what, double got, double want, double se) {
  printf("%-34s %.5f  exact %.5f  diff %+.2f se (se %.5f, %.3f%%)\n", what, got, want, (got - want) / se, se,
         100 * se / want);
  assert_true(fabs(got - want) <= 4 * se + 1e-5 * fabs(want));
}

static void test_furnace(void **state) {
  const double p[3] = {0.43, 0.55, 0.47};
  const double albedos[] = {0.5, 0.8};
  for (int ai = 0; ai < 2; ai++) {
    double a = albedos[ai];
    gi_scene *s = make_furnace(a, 1.0);
    for (int k = 1; k <= 4; k++) {
      gi_ref_probe r = ref_at(s, p, 8192, k, 1);
      double want = 0, pw = 1;
      for (int i = 0; i <= k; i++, pw *= a) want += pw;
      char what[64];
      snprintf(what, sizeof what, "furnace a=%.1f k=%d  E/pi", a, k);
      near_se(what, r.irradiance[1] / PI, want, r.std_err[1] / PI);
      near_se("  direct/pi", r.direct[1] / PI, 1.0, r.std_err_direct[1] / PI);
      /* The noise must be small enough for the bound to mean something. */
      assert_true(r.std_err[1] / PI < 0.01 * want);
    }
    gi_ref_probe r = ref_at(s, p, 8192, 0, 1);
    near_se("  unbounded (Russian roulette)", r.irradiance[1] / PI, 1.0 / (1 - a), r.std_err[1] / PI);
    /* Direct-only mode: no indirect at all. */
    r = ref_at(s, p, 256, -1, 1);
    assert_true(r.indirect[0] == 0 && r.indirect[1] == 0);
    gi_scene_release(s);
  }
}

static void test_standard_error_is_honest(void **state) {
  /* The spread of 8 seeds' means must match the reported standard error. */
  gi_scene *s = make_furnace(0.8, 1.0);
  const double p[3] = {0.3, 0.6, 0.5};
  double sum = 0, sum2 = 0, se = 0;
  const int n = 8;
  for (int seed = 1; seed <= n; seed++) {
    gi_ref_probe r = ref_at(s, p, 1024, 0, (uint64_t)seed);
    sum += r.irradiance[0];
    sum2 += r.irradiance[0] * r.irradiance[0];
    se += r.std_err[0] / n;
  }
  double mean = sum / n, sd = sqrt(fmax(0, (sum2 - n * mean * mean) / (n - 1)));
  printf("8 seeds: spread %.5f, mean reported standard error %.5f, ratio %.2f\n", sd, se, sd / se);
  /* With 8 seeds the sample sd is within a factor 2 of sigma with >99% probability. */
  assert_true(sd / se > 0.45 && sd / se < 2.0);
  /* Threads do not change the answer. */
  gi_reference_opts o1 = {.samples = 512, .threads = 1}, o2 = {.samples = 512, .threads = 2};
  gi_ref_probe a, b;
  gi_error_info err = {0};
  assert_int_equal(gi_reference_irradiance(s, p, 1, &o1, &a, NULL, &err), GI_OK);
  assert_int_equal(gi_reference_irradiance(s, p, 1, &o2, &b, NULL, &err), GI_OK);
  assert_memory_equal(&a, &b, sizeof a);
  gi_scene_release(s);
}

/* E(down) from the SH over 8 seeds: the SH has no standard error of its
 * own, so the bound is 4 standard deviations of the 8 seeds' mean. */
static void sh_down_check(const char *what, const gi_scene *s, int samples, double want) {
  const double p[3] = {0, 1, 0};
  float down[3] = {0, -1, 0}, E[3];
  double sum = 0, sum2 = 0;
  const int n = 8;
  for (int seed = 1; seed <= n; seed++) {
    gi_ref_probe r = ref_at(s, p, samples, 0, (uint64_t)seed);
    gi_sh_eval_irradiance((const float(*)[3])r.sh, down, E);
    sum += E[2];
    sum2 += (double)E[2] * E[2];
  }
  double mean = sum / n, sd = sqrt(fmax(0, (sum2 - n * mean * mean) / (n - 1)));
  near_se(what, mean, want, sd / sqrt(n));
  assert_true(sd / sqrt(n) < 0.03 * want); /* tight enough to mean something */
}

/* Irradiance at n from SH L2 of a single direction w carrying irradiance V
 * (the cosine lobe's L2 truncation rings: a delta light is not exact in L2). */
static double sh_delta_at(const float w[3], double V, const float n[3]) {
  static const double A[9] = {3.14159265, 2.0943951, 2.0943951, 2.0943951, 0.78539816,
                              0.78539816, 0.78539816, 0.78539816, 0.78539816};
  double e = 0;
  for (int i = 0; i < 9; i++) {
    float unit[9][3] = {{0}}, yw[3], yn[3];
    unit[i][0] = 1;
    gi_sh_eval_irradiance((const float(*)[3])unit, w, yw);
    gi_sh_eval_irradiance((const float(*)[3])unit, n, yn);
    e += A[i] * V * yw[0] * yn[0];
  }
  return e;
}

static void test_sun_on_plane(void **state) {
  /* Sun travelling down at 60 degrees from the vertical. */
  const double c60 = 0.5, s60 = sqrt(3.0) / 2;
  gi_light sun = {.type = GI_LIGHT_SUN, .color = {2, 3, 4}, .direction = {(float)s60, (float)-c60, 0}};
  const double a = 0.5;
  gi_scene *s = make_plane(&sun, a);
  const double p[3] = {0, 1, 0};
  gi_ref_probe r = ref_at(s, p, 1024, 0, 1);
  printf("sun: E(up) %.6f %.6f %.6f (exact 1 1.5 2), se %.2g\n", r.irradiance[0], r.irradiance[1],
         r.irradiance[2], r.std_err[0]);
  for (int k = 0; k < 3; k++) assert_true(fabs(r.irradiance[k] - sun.color[k] * c60) < 1e-4);
  assert_true(r.indirect[0] == 0); /* the plane is below: nothing reaches an up-facing surface */
  /* Facing down: the lit plane fills the lower hemisphere (a half-space is
   * exact in SH L1; a 2000 m plane seen from 1 m misses < 1e-6 of it), plus
   * the sun's own L2 ringing. */
  float down[3] = {0, -1, 0}, ws[3] = {(float)-s60, (float)c60, 0};
  sh_down_check("sun: E(down) from SH, 8 seeds", s, 4096, a * sun.color[2] * c60 + sh_delta_at(ws, sun.color[2], down));
  gi_scene_release(s);
}

static void test_sky_on_plane(void **state) {
  gi_light sky = {.type = GI_LIGHT_SKY, .color = {1, 1, 1}};
  const double a = 0.5;
  gi_scene *s = make_plane(&sky, a);
  const double p[3] = {0, 1, 0};
  gi_ref_probe r = ref_at(s, p, 16384, 0, 1);
  near_se("sky: E(up)", r.irradiance[0], PI, r.std_err[0]);
  /* The sky's upper half gives a down-facing surface nothing; the plane a pi L. */
  sh_down_check("sky: E(down) from SH, 8 seeds", s, 4096, a * PI);
  gi_scene_release(s);
}

/* ---- every light kind at once, against closed forms ----------------- */

/* The emissive quad: y = QUAD_Y, |x|, |z| <= QUAD_HALF, facing down. */
#define QUAD_Y 3.0
#define QUAD_HALF 1.0

static void unit3(double v[3]) {
  double l = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
  for (int k = 0; k < 3; k++) v[k] /= l;
}

/* 1 when the ray p + t w, 0 < t < tmax, crosses the quad (the only geometry). */
static int quad_blocks(const double p[3], const double w[3], double tmax) {
  if (!(fabs(w[1]) > 0)) return 0;
  double t = (QUAD_Y - p[1]) / w[1];
  if (!(t > 0 && t < tmax)) return 0;
  return fabs(p[0] + t * w[0]) <= QUAD_HALF && fabs(p[2] + t * w[2]) <= QUAD_HALF;
}

/* Projected solid angle of a polygon seen from p by a surface of normal n,
 * the polygon wholly above that surface (Lambert): (1/2) |sum_i theta_i
 * n . g_i|, theta_i the angle between the directions to corners i and i+1
 * and g_i the unit normal of the plane through them and p. The irradiance
 * from a uniform emitter of radiance Le is Le times this. */
static double polygon_psa(const double p[3], const double V[][3], int nv, const double n[3]) {
  double sum = 0;
  for (int i = 0; i < nv; i++) {
    double a[3], b[3], g[3];
    for (int k = 0; k < 3; k++) a[k] = V[i][k] - p[k], b[k] = V[(i + 1) % nv][k] - p[k];
    unit3(a), unit3(b);
    g[0] = a[1] * b[2] - a[2] * b[1], g[1] = a[2] * b[0] - a[0] * b[2], g[2] = a[0] * b[1] - a[1] * b[0];
    unit3(g);
    double c = fmax(-1.0, fmin(1.0, a[0] * b[0] + a[1] * b[1] + a[2] * b[2]));
    sum += acos(c) * (g[0] * n[0] + g[1] * n[1] + g[2] * n[2]);
  }
  return 0.5 * fabs(sum);
}

/* Irradiance from a delta light on an up-facing surface at p, 0 when hidden
 * by the quad. Sun: colour times the cosine; point: I cos / r^2; spot: the
 * same times the smoothstep from the outer cone (0) to the inner (1). */
static double delta_irradiance(const gi_light *l, const double p[3]) {
  double w[3], r = INFINITY, f = 1;
  if (l->type == GI_LIGHT_SUN) {
    for (int k = 0; k < 3; k++) w[k] = -l->direction[k];
    unit3(w);
  } else {
    for (int k = 0; k < 3; k++) w[k] = l->position[k] - p[k];
    r = sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]);
    unit3(w);
    if (l->type == GI_LIGHT_SPOT) {
      double d[3] = {l->direction[0], l->direction[1], l->direction[2]};
      unit3(d);
      double c = -(w[0] * d[0] + w[1] * d[1] + w[2] * d[2]);
      double t = fmax(0.0, fmin(1.0, (c - l->cos_outer) / (l->cos_inner - l->cos_outer)));
      f = t * t * (3 - 2 * t);
    }
  }
  if (!(w[1] > 0) || quad_blocks(p, w, r)) return 0;
  return f * l->color[1] * w[1] / (isinf(r) ? 1.0 : r * r);
}

/* Every kind of light at once: a sun, a sky of radiance ALL_LSKY, a point
 * light, a spot light and a black emissive quad of radiance ALL_LE facing
 * down over the origin (no indirect light at all). */
#define ALL_LSKY 0.5
#define ALL_LE 2.0
static gi_scene *make_all_lights(gi_light lights[4], double Q[4][3]) {
  const double cos25 = cos(25 * PI / 180), cos40 = cos(40 * PI / 180);
  gi_light l[4] = {
      {.type = GI_LIGHT_SUN, .color = {1.5, 1.5, 1.5}, .direction = {1.5f, -2.f, 0.5f}},
      {.type = GI_LIGHT_SKY, .color = {(float)ALL_LSKY, (float)ALL_LSKY, (float)ALL_LSKY}},
      {.type = GI_LIGHT_POINT, .color = {6, 6, 6}, .position = {3, 2, 0}},
      {.type = GI_LIGHT_SPOT, .color = {30, 30, 30}, .position = {-3, 4, 0}, .direction = {0, -1, 0},
       .cos_inner = (float)cos25, .cos_outer = (float)cos40},
  };
  memcpy(lights, l, sizeof l);
  gi_mesh_builder *b = gi_mesh_builder_new();
  gi_material m = {.emission = {ALL_LE, ALL_LE, ALL_LE}, .roughness = 1};
  uint32_t mat = gi_mesh_builder_add_material(b, &m);
  /* Wound to face down (-y), toward the points. */
  double q[4][3] = {{-QUAD_HALF, QUAD_Y, -QUAD_HALF}, {QUAD_HALF, QUAD_Y, -QUAD_HALF},
                    {QUAD_HALF, QUAD_Y, QUAD_HALF}, {-QUAD_HALF, QUAD_Y, QUAD_HALF}};
  memcpy(Q, q, sizeof q);
  gi_mesh_builder_add_quad(b, Q[0], Q[1], Q[2], Q[3], mat);
  gi_scene_options opt = {.up = GI_UP_Y, .lights = lights, .num_lights = 4};
  gi_scene *s = NULL;
  gi_error_info err = {0};
  assert_int_equal(gi_scene_build(b, "all lights", &opt, &s, &err), GI_OK);
  gi_mesh_builder_free(b);
  return s;
}

/* The exact direct irradiance at p (facing up) from the kinds in mask
 * (gi_reference_opts.lights) of make_all_lights's scene. */
static double all_lights_exact(const gi_light lights[4], double Q[4][3], const double p[3], int mask) {
  const double up[3] = {0, 1, 0};
  /* Sky and quad: the quad covers part of the upper hemisphere. */
  double psa = polygon_psa(p, Q, 4, up), want = 0;
  if (mask >> GI_FX_SKY & 1) want += ALL_LSKY * (PI - psa);
  if (mask >> GI_FX_EMISSIVE & 1) want += ALL_LE * psa;
  for (int l = 0; l < 4; l++) {
    int fx = lights[l].type == GI_LIGHT_SUN ? GI_FX_SUN : GI_FX_LOCAL;
    if (lights[l].type != GI_LIGHT_SKY && (mask >> fx & 1)) want += delta_irradiance(&lights[l], p);
  }
  return want;
}

static void test_all_lights_closed_form(void **state) {
  gi_light lights[4];
  double Q[4][3];
  gi_scene *s = make_all_lights(lights, Q);
  /* Under the quad (spot in its falloff), under the spot (inside its inner
   * cone), by the point light (outside the spot), and close under the quad
   * (the sun hidden by it, the sky mostly too). */
  static const double P[4][3] = {{0, 0, 0}, {-3, 0, 0.5}, {2.5, 0.5, -1}, {0.5, 1.5, 0.3}};
  const double up[3] = {0, 1, 0};
  const int seeds = 32;
  for (int i = 0; i < 4; i++) {
    double psa = polygon_psa(P[i], Q, 4, up), want = all_lights_exact(lights, Q, P[i], GI_REF_LIGHTS_ALL);
    double deltas = want - all_lights_exact(lights, Q, P[i], 1 << GI_FX_SKY | 1 << GI_FX_EMISSIVE);
    double sum = 0, sum2 = 0, se_rep = 0;
    for (int seed = 1; seed <= seeds; seed++) {
      gi_ref_probe r = ref_at(s, P[i], 1024, -1, (uint64_t)seed);
      assert_true(r.indirect[1] == 0);
      sum += r.direct[1], sum2 += (double)r.direct[1] * r.direct[1], se_rep += r.std_err_direct[1] / seeds;
    }
    double mean = sum / seeds, sd = sqrt(fmax(0, (sum2 - seeds * mean * mean) / (seeds - 1))), se = sd / sqrt(seeds);
    printf("all lights, point %d: E %.5f exact %.5f (quad psa %.4f, sun+point+spot %.4f) diff %+.2f se "
           "(se %.5f, %.2f%%; one seed's reported se %.5f, spread %.5f)\n",
           i, mean, want, psa, deltas, (mean - want) / se, se, 100 * se / want, se_rep, sd);
    assert_true(fabs(mean - want) <= 3 * se + 1e-5 * want);
    assert_true(se < 0.005 * want);                   /* tight enough to mean something */
    assert_true(se_rep > 0.5 * sd && se_rep < 2 * sd); /* and the reported error is honest */
  }
  gi_scene_release(s);
}

/* gi_reference_opts.lights: with one kind of light (or two) the direct
 * irradiance is that kind's exact share of make_all_lights's. */
static void test_light_mask_closed_form(void **state) {
  gi_light lights[4];
  double Q[4][3];
  gi_scene *s = make_all_lights(lights, Q);
  static const double P[2][3] = {{0, 0, 0}, {2.5, 0.5, -1}};
  static const int masks[5] = {1 << GI_FX_SUN, 1 << GI_FX_LOCAL, 1 << GI_FX_SKY, 1 << GI_FX_EMISSIVE,
                               1 << GI_FX_LOCAL | 1 << GI_FX_SKY};
  for (int i = 0; i < 2; i++)
    for (int m = 0; m < 5; m++) {
      gi_reference_opts o = {.samples = 8192, .max_depth = -1, .seed = 5, .lights = masks[m]};
      gi_ref_probe r;
      gi_error_info err = {0};
      assert_int_equal(gi_reference_irradiance(s, P[i], 1, &o, &r, NULL, &err), GI_OK);
      double want = all_lights_exact(lights, Q, P[i], masks[m]), se = r.std_err_direct[1];
      printf("lights %#x at point %d: E %.5f exact %.5f (se %.5f)\n", masks[m], i, r.direct[1], want, se);
      assert_true(r.indirect[1] == 0);
      /* A delta light's share has no noise: exact up to float rounding. */
      assert_true(fabs(r.direct[1] - want) <= 4 * se + 1e-5 * want + 1e-7);
    }
  gi_scene_release(s);
}

/* With a grey floor the light comes back as indirect light: one reference
 * per kind of light sums to the reference with all of them (within the
 * standard errors), so the mask neither loses nor double-counts a path
 * (emitters hit by diffuse rays, the sky escaped to, light tracing from
 * the point and spot lights). */
static void test_light_mask_partition(void **state) {
  gi_light lights[4];
  double Q[4][3];
  gi_scene *base = make_all_lights(lights, Q);
  gi_scene_release(base);
  gi_mesh_builder *b = gi_mesh_builder_new();
  gi_material em = {.albedo = {0.3f, 0.3f, 0.3f}, .emission = {ALL_LE, ALL_LE, ALL_LE}, .roughness = 1};
  gi_material fl = {.albedo = {0.6f, 0.6f, 0.6f}, .roughness = 1};
  uint32_t me = gi_mesh_builder_add_material(b, &em), mf = gi_mesh_builder_add_material(b, &fl);
  gi_mesh_builder_add_quad(b, Q[0], Q[1], Q[2], Q[3], me);
  double A[3] = {-40, -0.5, -40}, B[3] = {-40, -0.5, 40}, C[3] = {40, -0.5, 40}, D[3] = {40, -0.5, -40};
  gi_mesh_builder_add_quad(b, A, B, C, D, mf);
  double w0[3] = {-1.5, -0.5, -2}, w1[3] = {-1.2, 2.5, 2}; /* a wall: light bounces between it and the floor */
  gi_mesh_builder_add_box(b, w0, w1, mf);
  gi_scene_options opt = {.up = GI_UP_Y, .lights = lights, .num_lights = 4};
  gi_scene *s = NULL;
  gi_error_info err = {0};
  assert_int_equal(gi_scene_build(b, "all lights, floor", &opt, &s, &err), GI_OK);
  gi_mesh_builder_free(b);
  const double p[3] = {0.4, 0.6, 0.3};
  static const int kinds[4] = {GI_FX_SUN, GI_FX_LOCAL, GI_FX_SKY, GI_FX_EMISSIVE};
  gi_reference_opts o = {.samples = 32768, .seed = 9};
  gi_ref_probe all, one;
  assert_int_equal(gi_reference_irradiance(s, p, 1, &o, &all, NULL, &err), GI_OK);
  double sum[2] = {0, 0}, var[2] = {0, 0};
  for (int k = 0; k < 4; k++) {
    o.lights = 1 << kinds[k];
    assert_int_equal(gi_reference_irradiance(s, p, 1, &o, &one, NULL, &err), GI_OK);
    assert_true(one.indirect[1] > 0); /* every kind reaches the probe by a bounce */
    sum[0] += one.direct[1], var[0] += (double)one.std_err_direct[1] * one.std_err_direct[1];
    sum[1] += one.indirect[1], var[1] += (double)one.std_err_indirect[1] * one.std_err_indirect[1];
    printf("kind %d alone: direct %.4f indirect %.4f\n", kinds[k], one.direct[1], one.indirect[1]);
  }
  printf("all: direct %.4f indirect %.4f (se %.4f); the kinds summed: %.4f %.4f (se %.4f)\n", all.direct[1], all.indirect[1], all.std_err_indirect[1], sum[0], sum[1], sqrt(var[1]));
  double se_d = sqrt(var[0] + (double)all.std_err_direct[1] * all.std_err_direct[1]);
  double se_i = sqrt(var[1] + (double)all.std_err_indirect[1] * all.std_err_indirect[1]);
  assert_true(fabs(sum[0] - all.direct[1]) <= 4 * se_d + 1e-5 * all.direct[1]);
  assert_true(fabs(sum[1] - all.indirect[1]) <= 4 * se_i);
  assert_true(se_i < 0.03 * all.indirect[1]); /* tight enough to mean something */
  gi_scene_release(s);
}

/* ---- emitter picking: by distance (light tree) and by power ----------- */

/* A field of down-facing emissive squares over the point (0, 0, 0), none
 * hiding another from it: EMIT_GRID^2 squares whose directions from the
 * origin lie on a grid of slopes (x / y, z / y) EMIT_SLOPE apart, each at
 * its own height (0.6 m to 15 m) and angular size, so distance and power
 * disagree: the biggest squares are the farthest. The emitters reflect
 * (albedo EMIT_ALBEDO) and, with a floor, light comes back up to the
 * point as indirect light. */
#define EMIT_GRID 6
#define EMIT_SLOPE 0.6
#define EMIT_ALBEDO 0.5
#define FLOOR_Y -1.0
static gi_scene *make_emitter_field(int with_floor, double Q[][4][3], int *nq) {
  static const double heights[4] = {0.6, 2.0, 6.0, 15.0};
  static const double half_slope[3] = {0.05, 0.12, 0.25}; /* < EMIT_SLOPE / 2: no two overlap */
  gi_mesh_builder *b = gi_mesh_builder_new();
  gi_material m = {.albedo = {EMIT_ALBEDO, EMIT_ALBEDO, EMIT_ALBEDO}, .emission = {2, 2, 2}, .roughness = 1};
  gi_material f = {.albedo = {0.6, 0.6, 0.6}, .roughness = 1};
  uint32_t me = gi_mesh_builder_add_material(b, &m), mf = gi_mesh_builder_add_material(b, &f);
  *nq = 0;
  for (int i = 0; i < EMIT_GRID * EMIT_GRID; i++) {
    double sa = EMIT_SLOPE * (i % EMIT_GRID - 0.5 * (EMIT_GRID - 1)), sb = EMIT_SLOPE * (i / EMIT_GRID - 0.5 * (EMIT_GRID - 1));
    double h = heights[i % 4], r = half_slope[i % 3] * h;
    double (*q)[3] = Q[(*nq)++];
    /* Wound to face down (-y), toward the point, as the all-lights quad. */
    double c[4][2] = {{-r, -r}, {r, -r}, {r, r}, {-r, r}};
    for (int v = 0; v < 4; v++) q[v][0] = sa * h + c[v][0], q[v][1] = h, q[v][2] = sb * h + c[v][1];
    gi_mesh_builder_add_quad(b, q[0], q[1], q[2], q[3], me);
  }
  if (with_floor) {
    double A[3] = {-200, FLOOR_Y, -200}, B[3] = {-200, FLOOR_Y, 200}, C[3] = {200, FLOOR_Y, 200},
           D[3] = {200, FLOOR_Y, -200};
    gi_mesh_builder_add_quad(b, A, B, C, D, mf);
  }
  gi_scene_options opt = {.up = GI_UP_Y};
  gi_scene *s = NULL;
  gi_error_info err = {0};
  assert_int_equal(gi_scene_build(b, "emitter field", &opt, &s, &err), GI_OK);
  gi_mesh_builder_free(b);
  return s;
}

/* Pick probabilities from the tree and from the power table sum to 1, the
 * pick returns the same probability that gi__ref_emitter_pick_prob (what MIS
 * uses) gives, and the frequencies of many picks match them (each within
 * 4.5 sigma of its binomial count; a chi-square over all of them). */
static void test_pick_probabilities(void **state) {
  double Q[EMIT_GRID * EMIT_GRID][4][3];
  int nq;
  gi_scene *s = make_emitter_field(1, Q, &nq);
  const int draws = 1000000;
  /* Under the field, on the floor, and among the squares (world). */
  static const double W[3][3] = {{0, 0, 0}, {3.5, FLOOR_Y, -2}, {1, 7, 0.5}};
  float X[3][3];
  for (int i = 0; i < 9; i++) X[i / 3][i % 3] = (float)(W[i / 3][i % 3] - s->origin[i % 3]);
  for (int mode = GI_REF_PICK_TREE; mode <= GI_REF_PICK_POWER; mode++) {
    ref_lights L;
    gi_error_info err = {0};
    assert_int_equal(gi__ref_lights_init(&L, s, mode, 0, &err), GI_OK);
    assert_int_equal(L.num_emitters, 2 * nq);
    double *count = calloc(L.num_emitters, sizeof *count);
    for (int xi = 0; xi < 3; xi++) {
      double sum = 0, chi2 = 0, worst = 0;
      for (uint32_t q = 0; q < L.num_emitters; q++) sum += gi__ref_emitter_pick_prob(&L, X[xi], q);
      assert_true(fabs(sum - 1) < 1e-5);
      memset(count, 0, L.num_emitters * sizeof *count);
      ref_rng r;
      gi__ref_rng_seed(&r, 21 + xi);
      for (int d = 0; d < draws; d++) {
        double prob;
        uint32_t q = gi__ref_emitter_pick(&L, X[xi], ref_u01d(&r), &prob);
        assert_true(q < L.num_emitters);
        double want = gi__ref_emitter_pick_prob(&L, X[xi], q);
        assert_true(fabs(prob - want) <= 1e-6 * want);
        count[q]++;
      }
      int cells = 0;
      for (uint32_t q = 0; q < L.num_emitters; q++) {
        double p = gi__ref_emitter_pick_prob(&L, X[xi], q), mu = draws * p, sd = sqrt(mu * (1 - p));
        if (p == 0) assert_true(count[q] == 0);
        if (mu < 5) continue;
        worst = fmax(worst, fabs(count[q] - mu) / sd);
        chi2 += (count[q] - mu) * (count[q] - mu) / mu, cells++;
      }
      /* chi-square with cells - 1 degrees of freedom: mean k, sd sqrt(2k). */
      double k = cells - 1, z = (chi2 - k) / sqrt(2 * k);
      printf("%s pick at (%g, %g, %g): probabilities sum to 1%+.1e; %d draws: worst cell %.2f sigma, chi2 %.1f "
             "on %.0f dof (z %+.2f)\n",
             mode == GI_REF_PICK_TREE ? "tree " : "power", W[xi][0], W[xi][1], W[xi][2], sum - 1, draws, worst,
             chi2, k, z);
      assert_true(worst < 4.5);
      assert_true(z < 5);
    }
    free(count);
    gi__ref_lights_free(&L);
  }
  gi_scene_release(s);
}

static gi_ref_probe ref_pick(const gi_scene *s, const double p[3], int samples, int depth, int pick) {
  gi_reference_opts o = {.samples = samples, .max_depth = depth, .seed = 3, .emitter_pick = pick};
  gi_ref_probe r;
  gi_error_info err = {0};
  assert_int_equal(gi_reference_irradiance(s, p, 1, &o, &r, NULL, &err), GI_OK);
  return r;
}

/* Direct irradiance at the origin from the field of emitters (nothing
 * else: black sky, no floor) is the sum of Lambert's polygon formula over
 * the squares; both pickers must find it within 4 standard errors, their
 * MIS weights with the path direction included. The tree, which picks by
 * distance, must also be the less noisy here, where the biggest squares
 * are the farthest. */
static void test_pickers_closed_form(void **state) {
  double Q[EMIT_GRID * EMIT_GRID][4][3];
  int nq;
  gi_scene *s = make_emitter_field(0, Q, &nq);
  const double p[3] = {0, 0, 0}, up[3] = {0, 1, 0};
  double want = 0;
  for (int i = 0; i < nq; i++) want += 2.0 * polygon_psa(p, (const double(*)[3])Q[i], 4, up);
  double se[2];
  for (int mode = GI_REF_PICK_TREE; mode <= GI_REF_PICK_POWER; mode++) {
    gi_ref_probe r = ref_pick(s, p, 16384, -1, mode);
    near_se(mode == GI_REF_PICK_TREE ? "emitter field, tree pick: E(up)" : "emitter field, power pick: E(up)",
            r.direct[1], want, r.std_err_direct[1]);
    assert_true(r.std_err_direct[1] < 0.02 * want); /* tight enough to mean something */
    se[mode] = r.std_err_direct[1];
  }
  printf("emitter field: standard error tree / power %.3f\n", se[0] / se[1]);
  assert_true(se[GI_REF_PICK_TREE] < 0.7 * se[GI_REF_PICK_POWER]);
  gi_scene_release(s);
}

/* With a floor the emitters' light comes back up: indirect light, whose
 * paths pick emitters at every vertex (floor and squares) and meet them
 * with MIS weights from those vertices' pick probabilities. Tree and power
 * picks are both unbiased, so they agree within 4 combined standard errors. */
static void test_pickers_agree_with_indirect(void **state) {
  double Q[EMIT_GRID * EMIT_GRID][4][3];
  int nq;
  gi_scene *s = make_emitter_field(1, Q, &nq);
  static const double P[2][3] = {{0, 0, 0}, {2.5, -0.5, 1.5}};
  for (int i = 0; i < 2; i++) {
    gi_ref_probe t = ref_pick(s, P[i], 65536, 0, GI_REF_PICK_TREE), w = ref_pick(s, P[i], 65536, 0, GI_REF_PICK_POWER);
    const float *vt[3] = {t.direct, t.indirect, t.irradiance}, *vw[3] = {w.direct, w.indirect, w.irradiance};
    const float *st[3] = {t.std_err_direct, t.std_err_indirect, t.std_err};
    const float *sw[3] = {w.std_err_direct, w.std_err_indirect, w.std_err};
    static const char *part[3] = {"direct", "indirect", "total"};
    for (int q = 0; q < 3; q++) {
      double se = sqrt((double)st[q][1] * st[q][1] + (double)sw[q][1] * sw[q][1]);
      printf("emitter field + floor, point %d, %-8s tree %.5f (se %.2f%%) power %.5f (se %.2f%%): diff %+.2f se\n", i,
             part[q], vt[q][1], 100 * st[q][1] / vt[q][1], vw[q][1], 100 * sw[q][1] / vw[q][1],
             (vt[q][1] - vw[q][1]) / se);
      assert_true(vt[q][1] > 0 && se < 0.04 * vt[q][1]); /* tight enough to mean something */
      assert_true(fabs(vt[q][1] - vw[q][1]) <= 4 * se);
    }
  }
  gi_scene_release(s);
}

/* Direct irradiance at a point on a 400 m floor, 1 m under a 0.6 m square
 * emitter facing it, as a path vertex there gathers it: gi__ref_direct's MIS-
 * weighted emitter sample plus the cosine sample's MIS-weighted hit (as
 * diffuse_vertex adds it), against Lambert's formula. The floor makes the
 * scene large, so the shadow ray starts 8 mm off the surface: aimed along
 * the sample's direction from there instead of at the sampled point, it
 * would pass the emitter's plane and be blocked by it (E then came out
 * at 9% of the truth here). */
static void test_surface_direct_near_emitter(void **state) {
  const double H = 1.0, R = 0.3, Le = 2.0;
  gi_mesh_builder *b = gi_mesh_builder_new();
  gi_material m = {.emission = {Le, Le, Le}, .roughness = 1}, f = {.albedo = {0.5, 0.5, 0.5}, .roughness = 1};
  uint32_t me = gi_mesh_builder_add_material(b, &m), mf = gi_mesh_builder_add_material(b, &f);
  double Q[4][3] = {{-R, H, -R}, {R, H, -R}, {R, H, R}, {-R, H, R}}; /* faces down */
  gi_mesh_builder_add_quad(b, Q[0], Q[1], Q[2], Q[3], me);
  double A[3] = {-200, 0, -200}, B[3] = {-200, 0, 200}, C[3] = {200, 0, 200}, D[3] = {200, 0, -200};
  gi_mesh_builder_add_quad(b, A, B, C, D, mf);
  gi_scene_options opt = {.up = GI_UP_Y};
  gi_scene *s = NULL;
  gi_error_info err = {0};
  assert_int_equal(gi_scene_build(b, "square over a floor", &opt, &s, &err), GI_OK);
  gi_mesh_builder_free(b);
  const double pw[3] = {0.2, 0, 0.1}, up[3] = {0, 1, 0};
  const double want = Le * polygon_psa(pw, (const double(*)[3])Q, 4, up);
  const float n[3] = {0, 1, 0};
  float x[3];
  for (int k = 0; k < 3; k++) x[k] = (float)(pw[k] - s->origin[k]);
  const int N = 200000;
  for (int mode = GI_REF_PICK_TREE; mode <= GI_REF_PICK_POWER; mode++) {
    ref_lights L;
    assert_int_equal(gi__ref_lights_init(&L, s, mode, 0, &err), GI_OK);
    assert_true(L.eps > 0.005f); /* the lift this test is about */
    ref_rng r;
    gi__ref_rng_seed(&r, 5);
    double sum = 0, sum2 = 0;
    for (int i = 0; i < N; i++) {
      float E[3] = {0, 0, 0}, w[3], o[3], t, ng[3];
      uint32_t tri;
      gi__ref_direct(&L, x, n, &r, E, NULL);
      gi__ref_cosine(n, &r, w);
      for (int k = 0; k < 3; k++) o[k] = x[k] + L.eps * n[k];
      if (gi__intersect1(s, o, w, 0, INFINITY, &t, &tri, ng) && s->materials[s->tri_material[tri]].emission[1] > 0) {
        float cos_e = -gi__dot(ng, w), pb = w[1] / (float)PI, y[3];
        for (int k = 0; k < 3; k++) y[k] = o[k] + t * w[k] - x[k];
        if (cos_e > 0) E[1] += (float)(PI * Le) * pb / (pb + gi__ref_emitter_pdf(&L, x, tri, gi__len(y), cos_e));
      }
      sum += E[1], sum2 += (double)E[1] * E[1];
    }
    double mean = sum / N, se = sqrt(fmax(0, sum2 / N - mean * mean) / N);
    near_se(mode == GI_REF_PICK_TREE ? "surface under a square, tree pick" : "surface under a square, power pick",
            mean, want, se);
    assert_true(se < 0.01 * want);
    gi__ref_lights_free(&L);
  }
  gi_scene_release(s);
}

/* ---- light tracing from point lights ------------------------------------ */

/* A street lamp's geometry in small: a point light LAMP_DROP under a white
 * ceiling (LAMP_H high, 2 LAMP_HALF wide), optionally a grey floor. */
#define LAMP_H 4.0
#define LAMP_DROP 0.1
#define LAMP_HALF 50.0
#define LAMP_I 100.0
#define CEIL_ALBEDO 0.8
static gi_scene *make_lamp_room(int with_floor) {
  gi_light l = {.type = GI_LIGHT_POINT, .color = {LAMP_I, LAMP_I, LAMP_I}, .position = {0, LAMP_H - LAMP_DROP, 0}};
  gi_mesh_builder *b = gi_mesh_builder_new();
  gi_material c = {.albedo = {CEIL_ALBEDO, CEIL_ALBEDO, CEIL_ALBEDO}, .roughness = 1};
  gi_material f = {.albedo = {0.4, 0.4, 0.4}, .roughness = 1};
  uint32_t mc = gi_mesh_builder_add_material(b, &c), mf = gi_mesh_builder_add_material(b, &f);
  double A[3] = {-LAMP_HALF, LAMP_H, -LAMP_HALF}, B[3] = {LAMP_HALF, LAMP_H, -LAMP_HALF},
         C[3] = {LAMP_HALF, LAMP_H, LAMP_HALF}, D[3] = {-LAMP_HALF, LAMP_H, LAMP_HALF};
  gi_mesh_builder_add_quad(b, A, B, C, D, mc);
  if (with_floor) {
    for (int k = 0; k < 4; k++) (k == 0 ? A : k == 1 ? B : k == 2 ? C : D)[1] = 0;
    gi_mesh_builder_add_quad(b, A, B, C, D, mf);
  }
  gi_scene_options opt = {.up = GI_UP_Y, .lights = &l, .num_lights = 1};
  gi_scene *s = NULL;
  gi_error_info err = {0};
  assert_int_equal(gi_scene_build(b, "lamp room", &opt, &s, &err), GI_OK);
  gi_mesh_builder_free(b);
  return s;
}

/* Up-facing irradiance at p from the ceiling's one reflection of the lamp:
 * the integral over the ceiling of (a / pi) E_c(q) cos_p cos_q / |p - q|^2,
 * E_c = I h / |q - l|^3, in polar coordinates about the point above the
 * lamp with geometric steps in r (the spike under the lamp is 1/h^2). */
static double lamp_one_bounce(const double p[3]) {
  const int nt = 720, nr = 6000;
  const double h = LAMP_DROP, H = LAMP_H - p[1], r0 = 1e-5;
  double sum = 0;
  for (int i = 0; i < nt; i++) {
    double th = 2 * PI * (i + 0.5) / nt, ct = cos(th), st = sin(th);
    double rmax = LAMP_HALF / fmax(fabs(ct), fabs(st)), q = pow(rmax / r0, 1.0 / nr);
    /* [0, r0] by one midpoint, then nodes r0 q^j (trapezoid in ln r). */
    double acc = 0;
    for (int j = 0; j <= nr; j++) {
      double r = r0 * pow(q, j), dx = r * ct - p[0], dz = r * st - p[2], d2 = dx * dx + H * H + dz * dz;
      double f = h * r / pow(h * h + r * r, 1.5) * H * H / (d2 * d2) * r; /* times r: d(ln r) */
      acc += (j == 0 || j == nr ? 0.5 : 1) * f;
    }
    sum += acc * log(q) * (2 * PI / nt);
  }
  return CEIL_ALBEDO / PI * LAMP_I * sum;
}

/* One reflection (max_depth 1) off a ceiling with a point light 10 cm
 * under it, the city's lamp head in small: the probe's path rarely meets
 * the bright spot over the lamp; light tracing from the lamp does. The
 * indirect irradiance matches the integral within 4 standard errors, and
 * with light tracing its error is far below the estimator's without it. */
static void test_light_tracing_closed_form(void **state) {
  gi_scene *s = make_lamp_room(0);
  static const double P[2][3] = {{1.5, 0, 0.7}, {6, 2, -3}};
  for (int i = 0; i < 2; i++) {
    double want = lamp_one_bounce(P[i]);
    gi_reference_opts o = {.samples = 16384, .max_depth = 1, .seed = 9};
    gi_ref_probe r, q;
    gi_error_info err = {0};
    assert_int_equal(gi_reference_irradiance(s, P[i], 1, &o, &r, NULL, &err), GI_OK);
    o.no_light_tracing = 1;
    assert_int_equal(gi_reference_irradiance(s, P[i], 1, &o, &q, NULL, &err), GI_OK);
    near_se(i ? "lamp under a ceiling, far: indirect" : "lamp under a ceiling: indirect", r.indirect[1], want,
            r.std_err_indirect[1]);
    printf("  without light tracing %.5f (se %.2f%%); with it se %.2f%%\n", q.indirect[1],
           100 * q.std_err_indirect[1] / want, 100 * r.std_err_indirect[1] / want);
    assert_true(r.std_err_indirect[1] < 0.01 * want);
    assert_true(r.std_err_indirect[1] < 0.3 * q.std_err_indirect[1]);
  }
  gi_scene_release(s);
}

/* Up-facing irradiance at p (under the ceiling, above the floor) from
 * light reflected by the floor and then the ceiling. The floor's
 * irradiance I h' / (r^2 + h'^2)^(3/2) (h' the lamp's height) reflected to
 * the ceiling gives a radially symmetric E_c(rho), tabulated; the ceiling
 * then reflects it to p. Midpoint rules over discs of radius LAMP_HALF
 * (the squares' corners add well under 0.1%). */
#define FLOOR_ALBEDO 0.4
static double lamp_two_bounce(const double p[3]) {
  enum { NRHO = 201, NR = 500, NTH = 180, NS = 600, NPH = 360 };
  const double hl = LAMP_H - LAMP_DROP, R = LAMP_HALF, H = LAMP_H - p[1], dr = R / NR;
  static double ec[NRHO];
  for (int j = 0; j < NRHO; j++) {
    double rho = R * j / (NRHO - 1), sum = 0;
    for (int i = 0; i < NR; i++) {
      double r = (i + 0.5) * dr, ef = LAMP_I * hl / pow(r * r + hl * hl, 1.5), ring = 0;
      for (int k = 0; k < NTH; k++) { /* 0..pi, doubled: symmetric about the line to rho */
        double th = PI * (k + 0.5) / NTH, D2 = rho * rho + r * r - 2 * rho * r * cos(th) + LAMP_H * LAMP_H;
        ring += LAMP_H * LAMP_H / (D2 * D2);
      }
      sum += FLOOR_ALBEDO / PI * ef * ring * (2 * PI / NTH) * r * dr;
    }
    ec[j] = sum;
  }
  double sum = 0, ds = (R + 15) / NS;
  for (int i = 0; i < NS; i++) {
    double sd = (i + 0.5) * ds, ring = 0;
    for (int k = 0; k < NPH; k++) {
      double ph = 2 * PI * (k + 0.5) / NPH, qx = p[0] + sd * cos(ph), qz = p[2] + sd * sin(ph);
      double rho = sqrt(qx * qx + qz * qz), x = rho / R * (NRHO - 1);
      if (x >= NRHO - 1) continue; /* beyond the ceiling */
      int j = (int)x;
      double e = ec[j] + (x - j) * (ec[j + 1] - ec[j]), d2 = sd * sd + H * H;
      ring += CEIL_ALBEDO / PI * e * H * H / (d2 * d2);
    }
    sum += ring * (2 * PI / NPH) * sd * ds;
  }
  return sum;
}

/* With a floor, light goes lamp - floor - ceiling - probe and further:
 * light tracing toward every path vertex, weighted against its cosine
 * sample. With and without light tracing the reference must agree (the
 * estimator without it is unbiased, only noisy): the indirect light within
 * 4 combined standard errors, the direct light (the lamp alone, exact)
 * to float rounding. */
static void test_light_tracing_agrees(void **state) {
  gi_scene *s = make_lamp_room(1);
  const double p[3] = {2.0, 1.5, -1.0};
  gi_reference_opts o = {.samples = 1 << 17, .seed = 4};
  gi_ref_probe r, q;
  gi_error_info err = {0};
  assert_int_equal(gi_reference_irradiance(s, p, 1, &o, &r, NULL, &err), GI_OK);
  o.no_light_tracing = 1;
  assert_int_equal(gi_reference_irradiance(s, p, 1, &o, &q, NULL, &err), GI_OK);
  double se = sqrt((double)r.std_err_indirect[1] * r.std_err_indirect[1] +
                   (double)q.std_err_indirect[1] * q.std_err_indirect[1]);
  printf("lamp room, indirect with light tracing %.5f (se %.2f%%), without %.5f (se %.2f%%): diff %+.2f se; "
         "direct %.6f and %.6f\n",
         r.indirect[1], 100 * r.std_err_indirect[1] / r.indirect[1], q.indirect[1],
         100 * q.std_err_indirect[1] / q.indirect[1], (r.indirect[1] - q.indirect[1]) / se, r.direct[1], q.direct[1]);
  assert_true(fabs(r.direct[1] - q.direct[1]) <= 1e-5 * r.direct[1]);
  assert_true(se < 0.06 * r.indirect[1]); /* tight enough to mean something */
  assert_true(fabs(r.indirect[1] - q.indirect[1]) <= 4 * se);
  assert_true(r.std_err_indirect[1] < 0.2 * q.std_err_indirect[1]);
  /* Two reflections at most (lamp - ceiling - probe, lamp - floor -
   * ceiling - probe), 12 m from the lamp where the second is two thirds
   * of the light: it strains the light tracing toward the ceiling point
   * the probe's path meets, against that point's cosine sample, and the
   * floor point's lamp term weighted against it. */
  const double pf[3] = {12, 1.5, -1};
  gi_reference_opts o2 = {.samples = 1 << 15, .seed = 5, .max_depth = 2};
  assert_int_equal(gi_reference_irradiance(s, pf, 1, &o2, &r, NULL, &err), GI_OK);
  double e1 = lamp_one_bounce(pf), e2 = lamp_two_bounce(pf);
  printf("lamp room, two reflections: one %.5f + two %.5f (quadrature)\n", e1, e2);
  near_se("lamp room, two reflections: indirect", r.indirect[1], e1 + e2, r.std_err_indirect[1]);
  assert_true(r.std_err_indirect[1] < 0.01 * (e1 + e2));
  gi_scene_release(s);
}

/* The reference's own camera keeps gi_camera's public semantics (fov
 * across the smaller side, right = forward x up, rows from the top) and so
 * agrees with the cone-traced view's camera ray for ray. */
static void test_camera(void **state) {
  gi_scene *s = make_furnace(0.5, 1.0);
  gi_camera cams[3] = {
      {.eye = {0.5, 0.5, 3}, .target = {0.5, 0.5, 0}, .up = {0, 1, 0}, .fov_deg = 60, .width = 40, .height = 30},
      {.eye = {-2, 1, 0.3}, .target = {0.4, 0.2, 0.7}, .up = {0.3, 1, -0.2}, .fov_deg = 35, .width = 17, .height = 64},
      {.eye = {1, 4, 1}, .target = {0.9, 0, 1.1}, .up = {0, 0, 1}, .fov_deg = 120, .width = 8, .height = 8},
  };
  gi_error_info err = {0};
  for (int c = 0; c < 3; c++) {
    ref_cam k;
    gi__cam g;
    assert_int_equal(gi__ref_cam_init(&k, s, &cams[c], &err), GI_OK);
    assert_int_equal(gi__cam_setup(s, &cams[c], &g, &err), GI_OK);
    double maxd = 0;
    for (int y = 0; y <= 4; y++)
      for (int x = 0; x <= 4; x++) {
        float px = cams[c].width * x / 4.0f, py = cams[c].height * y / 4.0f, a[3], b[3];
        gi__ref_cam_dir(&k, px, py, a);
        gi__cam_ray(&g, px, py, b);
        for (int i = 0; i < 3; i++) maxd = fmax(maxd, fabs(a[i] - b[i]));
      }
    /* The middle of the smaller side's edge is fov / 2 from the view axis. */
    float mid[3], edge[3];
    int w = cams[c].width, h = cams[c].height;
    gi__ref_cam_dir(&k, 0.5f * w, 0.5f * h, mid);
    if (w <= h) gi__ref_cam_dir(&k, 0, 0.5f * h, edge);
    else gi__ref_cam_dir(&k, 0.5f * w, 0, edge);
    double ang = acos(mid[0] * edge[0] + mid[1] * edge[1] + mid[2] * edge[2]) * 180 / PI;
    printf("camera %d: largest difference from the view's camera %.2g, half fov %.4f deg (want %.4f)\n", c, maxd, ang,
           cams[c].fov_deg / 2);
    assert_true(maxd < 1e-5);
    assert_true(fabs(ang - cams[c].fov_deg / 2) < 1e-3);
  }
  /* Bad cameras fail with the public validation's message. */
  gi_camera bad = cams[0];
  bad.fov_deg = 180;
  ref_cam k;
  assert_int_equal(gi__ref_cam_init(&k, s, &bad, &err), GI_ERR_INVALID_ARG);
  assert_non_null(strstr(err.msg, "fov"));
  gi_scene_release(s);
}

/* The reference's own sampling primitives: PCG32 is the published
 * generator (pcg32-demo's first outputs for seed 42, stream 54), and the
 * frame is orthonormal and right-handed about any normal, axes included. */
static void test_rng_and_frame(void **state) {
  static const uint32_t want[6] = {0xa15c02b7u, 0x7b47f409u, 0xba1d3330u, 0x83d2f293u, 0xbfa4784bu, 0xcbed606eu};
  ref_rng r = {0, (54u << 1) | 1u};
  (void)ref_rng_u32(&r);
  r.state += 42u;
  (void)ref_rng_u32(&r);
  for (int i = 0; i < 6; i++) assert_int_equal(ref_rng_u32(&r), want[i]);
  gi__ref_rng_seed(&r, 7);
  double worst = 0;
  for (int i = 0; i < 1000; i++) {
    float n[3], t[3], b[3], c[3];
    if (i < 6) n[0] = n[1] = n[2] = 0, n[i % 3] = i < 3 ? 1.f : -1.f;
    else gi__ref_sphere(&r, n);
    gi__ref_frame(n, t, b);
    c[0] = t[1] * b[2] - t[2] * b[1], c[1] = t[2] * b[0] - t[0] * b[2], c[2] = t[0] * b[1] - t[1] * b[0];
    const float *v[3] = {t, b, n};
    for (int p = 0; p < 3; p++)
      for (int q = 0; q < 3; q++) {
        double d = v[p][0] * v[q][0] + v[p][1] * v[q][1] + v[p][2] * v[q][2];
        worst = fmax(worst, fabs(d - (p == q)));
      }
    for (int k = 0; k < 3; k++) worst = fmax(worst, fabs(c[k] - n[k])); /* t x b = n */
  }
  printf("frame: largest deviation from orthonormal and right-handed over 1000 normals %.2g\n", worst);
  assert_true(worst < 1e-6);
}

static void test_bad_input(void **state) {
  gi_scene *s = make_furnace(0.5, 1.0);
  double p[3] = {0.5, NAN, 0.5};
  gi_ref_probe r;
  gi_error_info err = {0};
  assert_int_equal(gi_reference_irradiance(s, p, 1, NULL, &r, NULL, &err), GI_ERR_NONFINITE);
  p[1] = 0.5;
  gi_reference_opts o = {.samples = -3};
  assert_int_equal(gi_reference_irradiance(s, p, 1, &o, &r, NULL, &err), GI_ERR_INVALID_ARG);
  assert_non_null(strstr(err.msg, "samples"));
  o.samples = 16, o.max_depth = -2;
  assert_int_equal(gi_reference_irradiance(s, p, 1, &o, &r, NULL, &err), GI_ERR_INVALID_ARG);
  assert_non_null(strstr(err.msg, "max_depth"));
  o.max_depth = 0, o.emitter_pick = 2;
  assert_int_equal(gi_reference_irradiance(s, p, 1, &o, &r, NULL, &err), GI_ERR_INVALID_ARG);
  assert_non_null(strstr(err.msg, "emitter_pick"));
  o.emitter_pick = 0, o.no_light_tracing = 7;
  assert_int_equal(gi_reference_irradiance(s, p, 1, &o, &r, NULL, &err), GI_ERR_INVALID_ARG);
  assert_non_null(strstr(err.msg, "no_light_tracing"));
  o.no_light_tracing = 0, o.lights = 1 << GI_FX_BOUNCE;
  assert_int_equal(gi_reference_irradiance(s, p, 1, &o, &r, NULL, &err), GI_ERR_INVALID_ARG);
  assert_non_null(strstr(err.msg, "lights"));
  gi_scene_release(s);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_furnace),
      cmocka_unit_test(test_standard_error_is_honest),
      cmocka_unit_test(test_sun_on_plane),
      cmocka_unit_test(test_sky_on_plane),
      cmocka_unit_test(test_all_lights_closed_form),
      cmocka_unit_test(test_light_mask_closed_form),
      cmocka_unit_test(test_light_mask_partition),
      cmocka_unit_test(test_surface_direct_near_emitter),
      cmocka_unit_test(test_pick_probabilities),
      cmocka_unit_test(test_pickers_closed_form),
      cmocka_unit_test(test_pickers_agree_with_indirect),
      cmocka_unit_test(test_light_tracing_closed_form),
      cmocka_unit_test(test_light_tracing_agrees),
      cmocka_unit_test(test_camera),
      cmocka_unit_test(test_rng_and_frame),
      cmocka_unit_test(test_bad_input),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
