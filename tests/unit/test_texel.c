/* test_texel.c: the half-float texels and the two builds of the march.
 *
 * Conversions are checked exhaustively against their definition (every
 * half round-trips; every float goes to its nearest half), packing keeps
 * radiance to half precision over the scale's whole range, a bake gives
 * the same light on the baseline and the x86-64-v3 march, and the
 * x86-64-v3 march's eight-lane batches give every cone what the baseline's
 * one-cone march gives. */
#include "test_util.h"
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "base/half.h"
#include "cascade/cascade_internal.h"
#include "gi/gi_city.h"
#include "gi/gi_cpu.h"
#include "gi/gi_probe.h"
#include "light/light.h"
#include "trace/trace.h"

/* Half's relative spacing at the top of a binade: 2^-10; half of it is the
 * worst rounding error. */
#define HALF_REL_ROUNDING (1.0f / 2048.0f)

static void test_every_half_round_trips(void **state) {
  int checked = 0;
  for (uint32_t h = 0; h < 65536; h++) {
    float f = gi__h2f((uint16_t)h);
    uint32_t e = (h >> 10) & 0x1f;
    if (e == 0x1f && (h & 0x3ff)) {
      assert_true(isnan(f));
      continue;
    }
    assert_int_equal(gi__f2h(f), h);
    checked++;
  }
  /* The definition of a few: 1, -2, the largest, the smallest subnormal. */
  assert_true(gi__h2f(0x3c00) == 1.0f && gi__h2f(0xc000) == -2.0f);
  assert_true(gi__h2f(0x7bff) == 65504.0f && gi__h2f(0x0001) == ldexpf(1.0f, -24));
  assert_true(isinf(gi__h2f(0x7c00)));
  printf("  %d halves round-trip\n", checked);
}

/* Every float in [2^-26, 65504] (a million spread over the range) goes to
 * the nearer of the two halves around it, ties to the even one. */
static void test_floats_round_to_nearest(void **state) {
  uint64_t seed = 7;
  int n = 0;
  for (int i = 0; i < 1000000; i++) {
    float f = ldexpf(1.0f + gi__u01(&seed), -26 + (int)(gi__u01(&seed) * 42.0f));
    if (f > 65504.0f) continue;
    uint16_t h = gi__f2h(f);
    float got = gi__h2f(h), below = h ? gi__h2f((uint16_t)(h - 1)) : -INFINITY, above = h < 0x7bff ? gi__h2f((uint16_t)(h + 1)) : INFINITY;
    float err = fabsf(got - f);
    assert_true(err <= fabsf(below - f));
    assert_true(err <= fabsf(above - f));
    if (err == fabsf(below - f) || err == fabsf(above - f)) assert_int_equal(h & 1, 0);
    assert_int_equal(gi__f2h(-f), h | 0x8000);
    n++;
  }
  assert_int_equal(gi__f2h(1e6f), 0x7c00); /* beyond the range: infinity, never a wrap */
  printf("  %d floats rounded to their nearest half\n", n);
}

/* Packing at a scale chosen for the brightest value keeps every radiance
 * lane within half's rounding, down to 2e-7 of the brightest. */
static void test_pack_keeps_precision(void **state) {
  struct gi_cascade c;
  memset(&c, 0, sizeof c);
  const float brightest = 3.7e6f;
  gi__vrad_rescale(&c, brightest);
  assert_true(c.rad_scale > 0 && isfinite(c.rad_scale));
  float worst = 0;
  for (int e = 0; e < 7 * 4; e++) {
    float v = brightest * powf(10.0f, -(float)e / 4.0f);
    gi_vrad_f in, out;
    memset(&in, 0, sizeof in);
    for (int f = 0; f < 6; f++)
      for (int k = 0; k < 3; k++) in.p[f][k] = v * (1.0f - 0.1f * (float)k);
    in.alpha[0] = 0.999f, in.tau[0] = 6.9f, in.alpha[1] = 0.25f, in.tau[1] = 0.2877f;
    gi_vrad r;
    gi__vrad_pack(&c, &in, &r);
    gi__vrad_unpack(&c, &r, &out);
    for (int f = 0; f < 6; f++)
      for (int k = 0; k < 3; k++) worst = fmaxf(worst, fabsf(out.p[f][k] - in.p[f][k]) / in.p[f][k]);
    for (int a = 0; a < 3; a++) {
      assert_true(fabsf(out.alpha[a] - in.alpha[a]) <= HALF_REL_ROUNDING * in.alpha[a]);
      assert_true(fabsf(out.tau[a] - in.tau[a]) <= HALF_REL_ROUNDING * in.tau[a]);
    }
  }
  printf("  radiance 3.7e6 .. 3.7e-1 packed: worst relative error %.2e (bound %.2e)\n", worst, HALF_REL_ROUNDING);
  assert_true(worst <= HALF_REL_ROUNDING);
}

/* The default city's cascade around its default viewpoint, 4 levels of
 * 16^3 (bounces: 0 = the plan's, -1 = none). It keeps the scene. */
static gi_cascade *city_cascade(int bounces) {
  gi_city_params p = {0};
  gi_scene *s = NULL;
  gi_error_info err = {0};
  assert_int_equal(gi_city_build(&p, NULL, &s, &err), GI_OK);
  double at[3];
  gi_city_default_viewpoint(&p, at);
  gi_quality q = {0};
  q.levels = 4;
  q.res = 16;
  q.bounces = bounces;
  gi_cascade *c = NULL;
  gi_bake_report rep;
  assert_int_equal(gi_cascade_bake(s, at, &q, &c, &rep, &err), GI_OK);
  if (bounces) assert_int_equal(rep.bounces_run, bounces < 0 ? 0 : bounces);
  gi_scene_release(s);
  return c;
}

static double bake_city_irradiance(int v3, uint64_t *samples) {
  gi__cpu_force(v3);
  gi_cascade *c = city_cascade(0);
  gi_error_info err = {0};
  gi_probe pr;
  assert_int_equal(gi_cascade_gather(c, c->at_world, 1, &pr, NULL, &err), GI_OK);
  *samples = gi_cascade_report(c)->cone_samples;
  gi_cascade_free(c);
  return pr.indirect[0] + pr.indirect[1] + pr.indirect[2];
}

/* The CPUID reading of x86-64-v3 (cpu.c) against GCC's own test of the
 * level, where the compiler has one (GCC 12 does; clang 14 does not). */
static void test_cpu_level_matches_compiler(void **state) {
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
  __builtin_cpu_init();
  int gcc = __builtin_cpu_supports("x86-64-v3") ? 1 : 0;
  printf("  x86-64-v3: CPUID says %d, GCC says %d\n", gi_cpu_has_v3(), gcc);
  assert_int_equal(gi_cpu_has_v3(), gcc);
#else
  printf("SKIP: this compiler cannot name x86-64-v3 for __builtin_cpu_supports\n");
  skip();
#endif
}

/* Both builds of the march: same samples, same light (FMA rounds a few
 * products differently, nothing more). */
static void test_both_march_builds_agree(void **state) {
  if (!gi_cpu_has_v3()) {
    printf("SKIP: this CPU has no x86-64-v3; only the baseline march can run\n");
    skip();
  }
  uint64_t n_base, n_v3;
  double e_base = bake_city_irradiance(0, &n_base);
  double e_v3 = bake_city_irradiance(1, &n_v3);
  gi__cpu_force(1);
  double rel = fabs(e_v3 - e_base) / e_base;
  printf("  city probe indirect: baseline %.6f, x86-64-v3 %.6f (rel. difference %.2e); samples %llu and %llu\n", e_base,
         e_v3, rel, (unsigned long long)n_base, (unsigned long long)n_v3);
  assert_true(rel < 1e-4);
  /* A sample lands on the other side of a level border at most rarely. */
  assert_true(llabs((long long)n_base - (long long)n_v3) <= (long long)(n_base / 10000));
}

/* Cones from surfaces (the bounce's start: occupied voxels of every level,
 * both sides) and from free points (probes), on one baked city. */
static int city_jobs(const gi_cascade *c, gi_cone_job *jobs, int cap) {
  int nj = 0, nc = c->num_cones;
  for (int d = 0; d < c->n; d++) {
    const gi_level *L = &c->lv[d];
    /* Every 37th occupied voxel: a spread of places and orientations. */
    for (uint32_t i = 0; i < L->num_occ && nj + 2 * nc <= cap; i += 37) {
      const gi_vgeo *g = gi__geo(L, L->occ[i]);
      for (int sd = 0; sd < 2; sd++) {
        float n[3];
        for (int k = 0; k < 3; k++) n[k] = (sd ? -1.f : 1.f) * g->normal[k];
        gi_gather_start st;
        gi__gather_start(c, g->centroid, n, GI_GATHER_SURFACE, d, &st);
        gi__hemisphere_jobs(c, 0, &st, n, jobs + nj);
        nj += nc;
      }
    }
  }
  /* Free points on a line through the viewpoint, hemispheres facing up and sideways. */
  for (int i = 0; i < 40 && nj + nc <= cap; i++) {
    float p[3] = {c->at[0] + 0.7f * (float)(i - 20), c->at[1] + 0.3f * (float)i, c->at[2] - 0.2f * (float)i};
    float n[3] = {i % 3 == 0 ? 1.f : 0.f, i % 3 == 1 ? 1.f : 0.f, i % 3 == 2 ? 1.f : 0.f};
    gi_gather_start st;
    if (!gi__gather_start(c, p, n, GI_GATHER_FREE, -1, &st)) continue;
    gi__hemisphere_jobs(c, 0, &st, n, jobs + nj);
    nj += nc;
  }
  return nj;
}

/* The eight-lane march (lane refill, idle lanes, batches longer than one
 * call's 128 jobs, an odd count) against the baseline march, cone by cone,
 * on the same cascade. */
static void test_lanes_match_scalar_march(void **state) {
  if (!gi_cpu_has_v3()) {
    printf("SKIP: this CPU has no x86-64-v3; only the baseline march can run\n");
    skip();
  }
  gi__cpu_force(1);
  gi_cascade *c = city_cascade(0);
  enum { CAP = 6000 };
  gi_cone_job *jobs = malloc(CAP * sizeof *jobs);
  gi_cone_out *base = malloc(CAP * sizeof *base), *lanes = malloc(CAP * sizeof *lanes);
  assert_non_null(jobs);
  assert_non_null(base);
  assert_non_null(lanes);
  int nj = city_jobs(c, jobs, CAP) - 3; /* not a multiple of 8 */
  assert_true(nj > 1000);
  float step = c->report.quality.step, ao = c->report.quality.ao_lambda;
  gi__cpu_force(0);
  gi__cone_march_jobs(c, jobs, nj, c->cone_tan, step, ao, base);
  gi__cpu_force(1);
  gi__cone_march_jobs(c, jobs, nj, c->cone_tan, step, ao, lanes);
  /* A cone whose sample lands a rounding error from a level's border may
   * read the other level there and then march another path: such cones
   * are counted, every other cone must agree to float rounding. */
  double worst = 0, worst_a = 0, lit = 0;
  int diff_samples = 0;
  for (int i = 0; i < nj; i++) {
    for (int k = 0; k < 3; k++) lit += base[i].L[k] > 0;
    if (lanes[i].samples != base[i].samples) {
      printf("  cone %d: %u samples against %u, radiance %.5g against %.5g\n", i, lanes[i].samples,
             base[i].samples, lanes[i].L[0], base[i].L[0]);
      diff_samples++;
      continue;
    }
    for (int k = 0; k < 3; k++)
      worst = fmax(worst, fabs(lanes[i].L[k] - base[i].L[k]) / fmax(fabs(base[i].L[k]), 1e-3));
    worst_a = fmax(worst_a, fabs(lanes[i].alpha - base[i].alpha));
    worst_a = fmax(worst_a, fabs(lanes[i].occlusion - base[i].occlusion));
  }
  printf("  %d cones, %.0f lit channels: largest relative radiance difference %.2e, opacity/occlusion %.2e; "
         "%d cones with another sample count\n", nj, lit, worst, worst_a, diff_samples);
  assert_true(lit > nj); /* the cones see light: the comparison means something */
  assert_true(worst < 1e-4);
  assert_true(worst_a < 1e-5);
  assert_true(diff_samples <= nj / 1000 + 1);
  free(jobs);
  free(base);
  free(lanes);
  gi_cascade_free(c);
}

/* A march's taps (trace.h) give each cone's light again, bit for bit:
 * every cone of the city's set, recorded and replayed by both builds of
 * the march, in batches as the bounces record them, each packed as a
 * voxel's tape is (gi_tape_unit). A cone with no tap took no light. */
static void test_taps_replay_cones(void **state) {
  gi_cascade *c = city_cascade(0);
  enum { CAP = 6000 };
  gi_cone_job *jobs = malloc(CAP * sizeof *jobs);
  gi_cone_out *out = malloc(CAP * sizeof *out);
  gi_tape_plan *pl = malloc(sizeof *pl);
  int16_t id[GI_MARCH_BATCH_JOBS];
  uint16_t job[GI_MARCH_BATCH_JOBS];
  float(*L)[3] = calloc(GI_MARCH_BATCH_JOBS, sizeof *L);
  assert_non_null(jobs);
  assert_non_null(out);
  assert_non_null(pl);
  assert_non_null(L);
  for (int j = 0; j < GI_MARCH_BATCH_JOBS; j++) id[j] = (int16_t)(GI_MARCH_BATCH_JOBS - 1 - j);
  int nj = city_jobs(c, jobs, CAP) - 3;
  float step = c->report.quality.step, ao = c->report.quality.ao_lambda;
  for (int v3 = 0; v3 < 2; v3++) {
    if (v3 && !gi_cpu_has_v3()) {
      printf("SKIP (x86-64-v3 part): this CPU has no x86-64-v3; the baseline's taps were checked\n");
      continue;
    }
    gi__cpu_force(v3);
    int lit = 0, differ = 0, blends = 0, alts = 0;
    size_t taps = 0, units = 0;
    for (int b = 0; b < nj; b += GI_MARCH_BATCH_JOBS) {
      int nb = nj - b < GI_MARCH_BATCH_JOBS ? nj - b : GI_MARCH_BATCH_JOBS;
      gi_tap_rec rec = {.max = (size_t)1 << 24};
      gi__cone_march_jobs_rec(c, jobs + b, nb, c->cone_tan, step, ao, out + b, &rec);
      assert_false(rec.full);
      for (size_t i = 0; i < rec.n; i++) blends += (rec.t[i].flags & GI_TAP_BLEND) != 0;
      gi__tape_plan(rec.t, rec.n, nb, pl);
      size_t nu = pl->start[nb];
      gi_tape_unit *tape = malloc((nu + 1) * sizeof *tape);
      assert_non_null(tape);
      gi__tape_pack(rec.t, rec.n, nb, pl, id, out + b, tape);
      size_t cones = gi__replay_tape(c, tape, nu, L, job);
      size_t run = 0;
      for (int j = 0; j < nb; j++) {
        float z[3] = {0, 0, 0};
        const float *want = out[b + j].L, *got = z; /* no tap: no light */
        alts += pl->k1[j] >= 0;
        if (pl->taps[j]) {
          assert_true(run < cones);
          assert_int_equal(job[run], id[j]); /* the cones in job order, each with its id */
          got = L[run++];
        }
        lit += pl->taps[j] > 0 && want[0] + want[1] + want[2] > 0;
        if (memcmp(got, want, sizeof z) != 0 && differ++ < 5)
          printf("  cone %d: replay %.9g %.9g %.9g, march %.9g %.9g %.9g\n", b + j, got[0], got[1], got[2], want[0],
                 want[1], want[2]);
      }
      assert_int_equal(run, cones);
      taps += rec.n, units += nu;
      free(tape);
      gi__free(rec.t);
    }
    printf("  %s: %d cones, %zu taps (%d blending two levels, %d cones with a second k) in %zu units; replays "
           "differing from the march: %d\n",
           v3 ? "x86-64-v3" : "baseline", nj, taps, blends, alts, units, differ);
    assert_true(lit > nj / 4);
    assert_true(blends > 0);
    /* Half a gi_tap's 40 bytes per tap, plus a head per lit cone. */
    assert_true(units > taps && units < 2 * taps);
    assert_int_equal(differ, 0);
  }
  gi__cpu_force(1);
  free(L);
  free(pl);
  free(jobs);
  free(out);
  gi_cascade_free(c);
}

/* Texels whose bits differ between two bakes of one scene. */
static size_t texels_differing(const gi_cascade *a, const gi_cascade *b) {
  size_t vox = (size_t)a->R * a->R * a->R, differ = 0;
  for (int d = 0; d < a->n; d++)
    for (size_t i = 0; i < vox; i++) differ += memcmp(&a->lv[d].rad[i], &b->lv[d].rad[i], sizeof(gi_vrad)) != 0;
  return differ;
}

/* The bounces replay their first bounce's taps (light/bounce.c): the same
 * texture, bit for bit, as marching every bounce, with every tape kept
 * and with a budget that holds only some of them. 4 bounces: both cone
 * sets record and replay. */
static void test_bounce_replays_match_marches(void **state) {
  gi__cpu_force(gi_cpu_has_v3());
  gi__set_tape_budget(0);
  gi_cascade *march = city_cascade(4);
  gi__set_tape_budget((size_t)1 << 20);
  gi_cascade *part = city_cascade(4);
  gi__set_tape_budget(GI_TAPE_MAX_BYTES);
  gi_cascade *all = city_cascade(4);
  const gi_bake_report *rm = gi_cascade_report(march), *rp = gi_cascade_report(part), *ra = gi_cascade_report(all);
  printf("  samples marched: every bounce %llu, 1 MB of tapes %llu (%llu taps), all tapes %llu (%llu taps)\n",
         (unsigned long long)rm->cone_samples, (unsigned long long)rp->cone_samples,
         (unsigned long long)rp->taps_replayed, (unsigned long long)ra->cone_samples,
         (unsigned long long)ra->taps_replayed);
  assert_true(rm->taps_replayed == 0);
  assert_true(ra->taps_replayed > 0 && ra->cone_samples < rm->cone_samples * 3 / 4);
  assert_true(rp->taps_replayed > 0 && rp->taps_replayed < ra->taps_replayed);
  assert_true(rp->cone_samples > ra->cone_samples && rp->cone_samples < rm->cone_samples);
  size_t da = texels_differing(march, all), dp = texels_differing(march, part);
  printf("  texels differing from marching every bounce: all tapes %zu, 1 MB of tapes %zu (of %zu)\n", da, dp,
         (size_t)march->R * march->R * march->R * (size_t)march->n);
  assert_int_equal(da, 0);
  assert_int_equal(dp, 0);
  gi_cascade_free(march);
  gi_cascade_free(part);
  gi_cascade_free(all);
}

/* The bounce skips, after its first pass, the cones that met no opacity
 * (light/bounce.c): exact only while the texture's opacity lanes and busy
 * masks stay as injection left them. A bake with no bounce and one with
 * three hold the same opacity, bit for bit, on every level. */
static void test_bounces_keep_opacity(void **state) {
  gi_cascade *a = city_cascade(-1), *b = city_cascade(3);
  size_t vox = (size_t)a->R * a->R * a->R, differ = 0, opaque = 0;
  for (int d = 0; d < a->n; d++)
    for (size_t i = 0; i < vox; i++) {
      differ += memcmp(a->lv[d].rad[i].h + GI_VRAD_ALPHA, b->lv[d].rad[i].h + GI_VRAD_ALPHA, 6 * sizeof(uint16_t)) != 0;
      differ += a->lv[d].busy[i] != b->lv[d].busy[i];
      opaque += a->lv[d].busy[i] != 0;
    }
  printf("  %zu busy blocks; opacity lanes or busy masks differing after 3 bounces: %zu\n", opaque, differ);
  assert_true(opaque > 100);
  assert_int_equal(differ, 0);
  gi_cascade_free(a);
  gi_cascade_free(b);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_every_half_round_trips),
      cmocka_unit_test(test_floats_round_to_nearest),
      cmocka_unit_test(test_pack_keeps_precision),
      cmocka_unit_test(test_cpu_level_matches_compiler),
      cmocka_unit_test(test_both_march_builds_agree),
      cmocka_unit_test(test_lanes_match_scalar_march),
      cmocka_unit_test(test_bounces_keep_opacity),
      cmocka_unit_test(test_taps_replay_cones),
      cmocka_unit_test(test_bounce_replays_match_marches),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
