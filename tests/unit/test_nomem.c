/* test_nomem.c: every allocation failure of the core is an error.
 *
 * For each public call on a small lit scene (a closed box with an emissive
 * quad, a point light, a sun and a sky forced on), the n-th core
 * allocation is made to fail for n = 0, 1, 2, ... until a run completes
 * without reaching it. Every failing run must return GI_ERR_NOMEM with a
 * message (never GI_OK with dark light, never a crash), leave *out NULL
 * and free everything it allocated (gi__alloc_live() back to where it
 * was). Allocations inside Embree, TBB, OpenEXR, OpenVDB and assimp are
 * theirs and not counted. A last bake with the hook disarmed must give
 * bit-identical probes to one made before any failure.
 *
 * test_light_budget: a plane under three sky lights with a thousand point
 * lights below it, at default sample counts. The per-thread light-sample
 * buffers used to hold 1024 samples (inject), 2 * samples + lights + 8
 * (gather, render): the last sky lights' samples were dropped silently.
 * The top side's irradiance must be pi * (sum of sky radiances). */
#include "test_util.h"
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "base/alloc_test.h"
#include "cascade/cascade_internal.h"
#include "gi/gi.h"

#define THREADS 2
#define NPROBES 4
#define PANO_W 16
#define PANO_H 8
#define VIEW_W 16
#define VIEW_H 12

static const double AT[3] = {0.5, 0.5, 0.5};
static const double PROBES[3 * NPROBES] = {0.3, 0.3, 0.3, 0.7, 0.4, 0.5, 0.5, 0.8, 0.6, 0.2, 0.6, 0.7};

/* A closed unit box (albedo 0.6), an emissive quad under its ceiling
 * facing down, a point light inside, a sun and a sky outside. */
static gi_scene *lit_box(gi_error_info *err, gi_result *rc) {
  gi_mesh_builder *b = gi_mesh_builder_new();
  if (!b) { /* the public constructor's NULL is the caller's out-of-memory report */
    err->code = *rc = GI_ERR_NOMEM;
    snprintf(err->msg, sizeof err->msg, "gi_mesh_builder_new returned NULL");
    return NULL;
  }
  gi_material wall = {.albedo = {0.6f, 0.6f, 0.6f}}, lamp = {.albedo = {0.2f, 0.2f, 0.2f}, .emission = {4, 4, 4}};
  uint32_t mw = gi_mesh_builder_add_material(b, &wall), ml = gi_mesh_builder_add_material(b, &lamp);
  gi_mesh_builder_add_box(b, (double[3]){0, 0, 0}, (double[3]){1, 1, 1}, mw);
  /* A block on the floor, so the finest level holds geometry too. */
  gi_mesh_builder_add_box(b, (double[3]){0.4, 0, 0.4}, (double[3]){0.6, 0.3, 0.6}, mw);
  gi_mesh_builder_add_quad(b, (double[3]){0.4, 0.95, 0.4}, (double[3]){0.6, 0.95, 0.4}, (double[3]){0.6, 0.95, 0.6},
                           (double[3]){0.4, 0.95, 0.6}, ml);
  gi_light lights[3] = {
      {.type = GI_LIGHT_SUN, .color = {3, 3, 3}, .direction = {0.29f, -0.95f, 0.1f}},
      {.type = GI_LIGHT_SKY, .color = {0.5f, 0.6f, 0.8f}},
      {.type = GI_LIGHT_POINT, .color = {0.2f, 0.2f, 0.2f}, .position = {0.3, 0.6, 0.4}},
  };
  gi_scene_options o = {.threads = THREADS, .lights = lights, .num_lights = 3};
  gi_scene *s = NULL;
  *rc = gi_scene_build(b, "nomem-box", &o, &s, err);
  gi_mesh_builder_free(b);
  return s;
}

static gi_quality low_quality(void) {
  gi_quality q = {.levels = 2, .res = 16, .bounces = 2, .light_samples = 8, .probe_samples = 32,
                  .threads = THREADS, .cones = 6};
  q.effects[GI_FX_SKY] = GI_FX_ON; /* the box is closed: only a forced sky is sampled */
  return q;
}

/* One call under test: runs it, keeps its output in ctx, frees it in undo. */
typedef struct {
  gi_scene *scene;
  gi_cascade *c;          /* a baked cascade for the answers */
  gi_cascade *baked;      /* the bake call's output */
  gi_scene *built;        /* the scene-build and load calls' output */
  gi_exr_file *exr;       /* the EXR read's output */
  double *pts;            /* the points read's output (plain free()) */
  size_t npts;
  gi_probe probes[NPROBES];
  gi_ref_probe ref[NPROBES];
  float pano_d[3 * PANO_W * PANO_H], pano_i[3 * PANO_W * PANO_H];
  float rgb[3 * VIEW_W * VIEW_H], spec[3 * VIEW_W * VIEW_H];
  char path[512];
} call_ctx;

typedef gi_result (*call_fn)(call_ctx *x, gi_error_info *err);

static gi_result call_build(call_ctx *x, gi_error_info *err) {
  gi_result rc;
  x->built = lit_box(err, &rc);
  if (rc != GI_OK) assert_null(x->built);
  return rc;
}

static gi_result call_bake(call_ctx *x, gi_error_info *err) {
  gi_quality q = low_quality();
  gi_bake_report rep;
  static char sentinel;
  x->baked = (gi_cascade *)&sentinel; /* the call must overwrite it */
  gi_result rc = gi_cascade_bake(x->scene, AT, &q, &x->baked, &rep, err);
  if (rc != GI_OK) assert_null(x->baked);
  return rc;
}

static gi_result call_plan(call_ctx *x, gi_error_info *err) {
  gi_quality q = low_quality();
  gi_effect fx[GI_FX_COUNT];
  return gi_effect_plan(x->scene, AT, &q, fx, NULL, err);
}

static gi_result call_gather(call_ctx *x, gi_error_info *err) {
  return gi_cascade_gather(x->c, PROBES, NPROBES, x->probes, NULL, err);
}

static gi_result call_panorama(call_ctx *x, gi_error_info *err) {
  return gi_cascade_panorama(x->c, AT, PANO_W, PANO_H, x->pano_d, x->pano_i, NULL, err);
}

static gi_camera view_camera(void) {
  gi_camera cam = {.eye = {0.5, 0.5, 0.05}, .target = {0.5, 0.5, 0.9}, .up = {0, 1, 0}, .fov_deg = 70,
                   .width = VIEW_W, .height = VIEW_H};
  return cam;
}

static gi_result call_render(call_ctx *x, gi_error_info *err) {
  gi_camera cam = view_camera();
  gi_render_opts o = {.light_samples = 8, .threads = THREADS, .specular = x->spec};
  return gi_cascade_render_ex(x->c, &cam, &o, x->rgb, NULL, err);
}

static gi_result call_reference(call_ctx *x, gi_error_info *err) {
  gi_reference_opts o = {.samples = 128, .max_depth = 2, .threads = THREADS};
  return gi_reference_irradiance(x->scene, PROBES, NPROBES, &o, x->ref, NULL, err);
}

static gi_result call_reference_view(call_ctx *x, gi_error_info *err) {
  gi_camera cam = view_camera();
  gi_render_opts o = {.spp = 2, .threads = THREADS};
  return gi_reference_render_ex(x->scene, &cam, &o, x->rgb, NULL, err);
}

static gi_result call_vdb(call_ctx *x, gi_error_info *err) {
  snprintf(x->path, sizeof x->path, "%s/nomem.vdb", tu_tmpdir());
  return gi_cascade_write_vdb(x->c, x->path, 1, err);
}

static gi_result call_exr(call_ctx *x, gi_error_info *err) {
  snprintf(x->path, sizeof x->path, "%s/nomem.exr", tu_tmpdir());
  return gi_probes_write_exr(x->path, x->probes, NPROBES, x->scene, AT, gi_cascade_report(x->c), 1, err);
}

static gi_result call_exr_read(call_ctx *x, gi_error_info *err) {
  snprintf(x->path, sizeof x->path, "%s/nomem.exr", tu_tmpdir());
  static char sentinel;
  x->exr = (gi_exr_file *)&sentinel;
  gi_result rc = gi_exr_read(x->path, &x->exr, err);
  if (rc != GI_OK) assert_null(x->exr);
  return rc;
}

static gi_result call_points_read(call_ctx *x, gi_error_info *err) {
  static char text[4096];
  if (!text[0]) /* more than the reader's first 64-point block, so it grows once */
    for (int i = 0; i < 100; i++)
      snprintf(text + strlen(text), sizeof text - strlen(text), "%d 0.5 %d.25\n", i, i);
  const char *path = tu_write_file("nomem.pts", text, strlen(text));
  x->pts = (double *)text;
  gi_result rc = gi_points_read(path, 1000, &x->pts, &x->npts, err);
  if (rc != GI_OK) assert_null(x->pts);
  else assert_int_equal(x->npts, 100);
  return rc;
}

static gi_result call_png(call_ctx *x, gi_error_info *err) {
  snprintf(x->path, sizeof x->path, "%s/nomem-tex.png", tu_tmpdir());
  for (size_t i = 0; i < sizeof x->rgb / sizeof x->rgb[0]; i++) x->rgb[i] = (float)(i % 7) / 7.f;
  return gi_image_write_png(x->path, x->rgb, VIEW_W, VIEW_H, 1.f, err);
}

/* The OBJ's wall material is textured with the PNG call_png wrote. */
static gi_result call_scene_load(call_ctx *x, gi_error_info *err) {
  static const char mtl[] = "newmtl wall\nKd 0.6 0.6 0.6\nmap_Kd nomem-tex.png\n"
                            "newmtl lamp\nKd 0.2 0.2 0.2\nKe 4 4 4\n";
  static const char obj[] = "mtllib nomem.mtl\n"
                            "v 0 0 0\nv 1 0 0\nv 1 0 1\nv 0 0 1\nv 0 1 0\nv 1 1 0\nv 1 1 1\nv 0 1 1\n"
                            "usemtl wall\nf 1 2 3 4\nf 5 8 7 6\nf 1 5 6 2\n"
                            "usemtl lamp\nf 4 3 7 8\n";
  tu_write_file("nomem.mtl", mtl, sizeof mtl - 1);
  const char *path = tu_write_file("nomem.obj", obj, sizeof obj - 1);
  gi_light sun = {.type = GI_LIGHT_SUN, .color = {1, 1, 1}, .direction = {0, -1, 0}};
  gi_scene_options o = {.threads = THREADS, .lights = &sun, .num_lights = 1};
  gi_result rc = gi_scene_load(path, &o, &x->built, err);
  if (rc != GI_OK) assert_null(x->built);
  return rc;
}

static gi_result call_city(call_ctx *x, gi_error_info *err) {
  gi_city_params p = {.extent = 130, .detail = 1};
  gi_scene_options o = {.threads = THREADS};
  gi_result rc = gi_city_build(&p, &o, &x->built, err);
  if (rc != GI_OK) assert_null(x->built);
  return rc;
}

static void undo(call_ctx *x) {
  gi_exr_file_free(x->exr);
  x->exr = NULL;
  free(x->pts); /* the caller's, by the API's contract */
  x->pts = NULL;
  gi_cascade_free(x->baked);
  x->baked = NULL;
  gi_scene_release(x->built);
  x->built = NULL;
}

/* Fails allocation n = 0, 1, ... of fn until a run completes without
 * reaching the failure; returns how many core allocations a whole run made. */
static long walk(const char *name, call_fn fn, call_ctx *x) {
  char last[sizeof ((gi_error_info *)0)->msg] = "";
  for (long n = 0;; n++) {
    long live0 = gi__alloc_live();
    gi_error_info err = {0};
    gi__alloc_fail_after(n);
    gi_result rc = fn(x, &err);
    int hit = !gi__alloc_fail_armed();
    gi__alloc_fail_after(-1);
    if (!hit) {
      if (rc != GI_OK) fprintf(stderr, "%s: clean run failed: %s\n", name, err.msg);
      assert_int_equal(rc, GI_OK);
      undo(x);
      assert_int_equal(gi__alloc_live(), live0);
      printf("%-22s %4ld core allocations, each failure -> GI_ERR_NOMEM, no leak\n", name, n);
      return n;
    }
    if (rc != GI_ERR_NOMEM)
      fprintf(stderr, "%s: allocation %ld failed but the call returned %s (%s)\n", name, n, gi_err_name(rc), err.msg);
    assert_int_equal(rc, GI_ERR_NOMEM);
    assert_int_equal(err.code, GI_ERR_NOMEM);
    assert_true(err.msg[0] != '\0');
    if (strcmp(err.msg, last)) { /* each distinct stage message once */
      printf("  %s n=%ld: %s\n", name, n, err.msg);
      snprintf(last, sizeof last, "%s", err.msg);
    }
    long leaked = gi__alloc_live() - live0;
    if (leaked) fprintf(stderr, "%s: allocation %ld failed and %ld blocks leaked\n", name, n, leaked);
    assert_int_equal(leaked, 0);
  }
}

static gi_cascade *bake_ok(gi_scene *s) {
  gi_quality q = low_quality();
  gi_cascade *c = NULL;
  gi_error_info err = {0};
  gi_result rc = gi_cascade_bake(s, AT, &q, &c, NULL, &err);
  if (rc) fprintf(stderr, "bake: %s\n", err.msg);
  assert_int_equal(rc, GI_OK);
  return c;
}

static void test_nomem_every_call(void **state) {
  (void)state;
  static call_ctx x;
  gi_error_info err = {0};
  gi_result rc;
  x.scene = lit_box(&err, &rc);
  if (rc) fprintf(stderr, "build: %s\n", err.msg);
  assert_int_equal(rc, GI_OK);
  /* The answer before any failure, to compare with after. */
  x.c = bake_ok(x.scene);
  gi_probe before[NPROBES];
  assert_int_equal(gi_cascade_gather(x.c, PROBES, NPROBES, before, NULL, &err), GI_OK);
  const gi_bake_report *rep = gi_cascade_report(x.c);
  assert_true(rep->bounces_run == 2);
  for (int f = 0; f < GI_FX_COUNT; f++)
    if (f == GI_FX_SUN || f == GI_FX_LOCAL || f == GI_FX_SKY || f == GI_FX_EMISSIVE || f == GI_FX_BOUNCE)
      assert_true(rep->effects[f].ran);

  assert_true(walk("gi_scene_build", call_build, &x) > 0);
  assert_true(walk("gi_effect_plan", call_plan, &x) > 0);
  assert_true(walk("gi_cascade_bake", call_bake, &x) > 0);
  assert_true(walk("gi_cascade_gather", call_gather, &x) > 0);
  assert_true(walk("gi_cascade_panorama", call_panorama, &x) >= 0);
  assert_true(walk("gi_cascade_render_ex", call_render, &x) > 0);
  assert_true(walk("gi_reference_irradiance", call_reference, &x) > 0);
  assert_true(walk("gi_reference_render_ex", call_reference_view, &x) > 0);
  assert_true(walk("gi_cascade_write_vdb", call_vdb, &x) > 0);
  assert_true(walk("gi_probes_write_exr", call_exr, &x) > 0);
  assert_true(walk("gi_exr_read", call_exr_read, &x) > 0);
  assert_true(walk("gi_points_read", call_points_read, &x) > 0);
  assert_true(walk("gi_image_write_png", call_png, &x) > 0);
  assert_true(walk("gi_scene_load", call_scene_load, &x) > 0);
  assert_true(walk("gi_city_build", call_city, &x) > 0);

  /* Hook disarmed: a fresh bake answers exactly as before. */
  gi_cascade *c2 = bake_ok(x.scene);
  gi_probe after[NPROBES];
  assert_int_equal(gi_cascade_gather(c2, PROBES, NPROBES, after, NULL, &err), GI_OK);
  assert_memory_equal(before, after, sizeof before);
  assert_true(before[0].direct[0] > 0 && before[0].indirect[0] > 0);
  gi_cascade_free(c2);
  gi_cascade_free(x.c);
  gi_scene_release(x.scene);
}

/* ---- light-sample budgets ------------------------------------------ */

#define NUM_POINTS 1000
#define NUM_SKIES 3

static gi_scene *plane_under_skies(const float sky[NUM_SKIES][3]) {
  gi_mesh_builder *b = gi_mesh_builder_new();
  gi_material m = {.albedo = {0.5f, 0.5f, 0.5f}};
  uint32_t mi = gi_mesh_builder_add_material(b, &m);
  const double H = 50; /* far wider than the cascade: no edge in it */
  gi_mesh_builder_add_quad(b, (double[3]){-H, 0, -H}, (double[3]){-H, 0, H}, (double[3]){H, 0, H},
                           (double[3]){H, 0, -H}, mi);
  static gi_light lights[NUM_POINTS + NUM_SKIES];
  /* Point lights first and far below, so a short buffer would cut the skies, not them. */
  for (int i = 0; i < NUM_POINTS; i++)
    lights[i] = (gi_light){.type = GI_LIGHT_POINT, .color = {1e-3f, 1e-3f, 1e-3f},
                           .position = {(double)(i % 10), -1000.0, (double)(i / 10)}};
  for (int k = 0; k < NUM_SKIES; k++) {
    lights[NUM_POINTS + k] = (gi_light){.type = GI_LIGHT_SKY};
    memcpy(lights[NUM_POINTS + k].color, sky[k], sizeof(float[3]));
  }
  gi_scene_options o = {.lights = lights, .num_lights = NUM_POINTS + NUM_SKIES};
  gi_scene *s = NULL;
  gi_error_info err = {0};
  gi_result rc = gi_scene_build(b, "skies", &o, &s, &err);
  if (rc) fprintf(stderr, "build: %s\n", err.msg);
  assert_int_equal(rc, GI_OK);
  gi_mesh_builder_free(b);
  return s;
}

/* Sampling noise of the stratified sky estimate on an open plane, per
 * voxel (16 samples per sky): relative sd 2 / (sqrt(12) m^1.5) = 0.9%
 * per sky; the mean over hundreds of voxels is far tighter. Bounds: 0.5%
 * for the voxel mean, 3% for any single voxel, 1% for the probe (256
 * samples) and the pixels (64). A dropped sky light costs 33% or more. */
static void test_light_budget(void **state) {
  (void)state;
  const float sky[NUM_SKIES][3] = {{0.2f, 0.3f, 0.4f}, {0.5f, 0.5f, 0.5f}, {0.7f, 0.4f, 0.1f}};
  double want[3] = {0, 0, 0};
  for (int k = 0; k < NUM_SKIES; k++)
    for (int a = 0; a < 3; a++) want[a] += 3.14159265358979 * sky[k][a];
  gi_scene *s = plane_under_skies(sky);
  gi_quality q = {.levels = 2, .res = 16, .voxel0 = 0.25, .bounces = -1};
  double at[3] = {0.1, 0.6, 0.1};
  gi_cascade *c = NULL;
  gi_error_info err = {0};
  gi_bake_report rep;
  gi_result rc = gi_cascade_bake(s, at, &q, &c, &rep, &err);
  if (rc) fprintf(stderr, "bake: %s\n", err.msg);
  assert_int_equal(rc, GI_OK);
  assert_true(rep.effects[GI_FX_SKY].ran && rep.effects[GI_FX_LOCAL].ran);
  assert_int_equal(rep.quality.light_samples, 16);

  /* Injected: the top side of every occupied voxel. */
  double sum[3] = {0, 0, 0}, worst = 0;
  long nv = 0;
  for (int d = 0; d < c->n; d++) {
    const gi_level *L = &c->lv[d];
    for (uint32_t i = 0; i < L->num_occ; i++) {
      uint32_t slot = L->occ[i];
      int top = GI_FACE_PY; /* the surface shown from above */
      for (int a = 0; a < 3; a++) {
        double v = gi__direct(L, slot)[top][a];
        sum[a] += v;
        worst = fmax(worst, fabs(v / want[a] - 1));
      }
      nv++;
    }
  }
  assert_true(nv > 100);
  for (int a = 0; a < 3; a++) {
    double mean = sum[a] / (double)nv;
    printf("inject: %ld voxels, top-side irradiance %.5f, pi * sum of skies %.5f (rel %+.5f), worst voxel %.4f\n", nv,
           mean, want[a], mean / want[a] - 1, worst);
    assert_true(fabs(mean / want[a] - 1) < 0.005);
  }
  assert_true(worst < 0.03);

  /* Gathered: a probe above the plane, up-facing direct irradiance. */
  gi_probe pr;
  double pt[3] = {0.2, 0.5, 0.3};
  assert_int_equal(gi_cascade_gather(c, pt, 1, &pr, NULL, &err), GI_OK);
  for (int a = 0; a < 3; a++) {
    printf("gather: direct %.5f, want %.5f (rel %+.5f)\n", pr.direct[a], want[a], pr.direct[a] / want[a] - 1);
    assert_true(fabs(pr.direct[a] / want[a] - 1) < 0.01);
  }

  /* Rendered: looking straight down, no bounces: pixel = albedo / pi * E. */
  enum { W = 8, H = 8 };
  gi_camera cam = {.eye = {0.1, 2.0, 0.1}, .target = {0.1, 0.0, 0.1}, .up = {0, 0, 1}, .fov_deg = 20,
                   .width = W, .height = H};
  float rgb[3 * W * H];
  assert_int_equal(gi_cascade_render(c, &cam, 0, 0, rgb, NULL, &err), GI_OK);
  double px[3] = {0, 0, 0};
  for (int i = 0; i < W * H; i++)
    for (int a = 0; a < 3; a++) px[a] += rgb[3 * i + a] / (W * H);
  for (int a = 0; a < 3; a++) {
    double w = 0.5 / 3.14159265358979 * want[a];
    printf("render: pixel %.5f, want %.5f (rel %+.5f)\n", px[a], w, px[a] / w - 1);
    assert_true(fabs(px[a] / w - 1) < 0.01);
  }
  gi_cascade_free(c);
  gi_scene_release(s);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_nomem_every_call),
      cmocka_unit_test(test_light_budget),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
