/* views.c: camera views at equal error, the paper's final rendering step.
 *
 * A probe answer is a handful of points, where the path tracer is cheap;
 * a camera view is a pixel per point, where one bake serves every pixel.
 * Per view: a path-traced reference image (two independent halves at
 * ref_spp / 2 paths per pixel each, cached under the output folder), the
 * cone tracer's bake + render at default quality, and the path tracer at
 * 1, 4, 16, ... paths per pixel, all against the reference. The error is
 * the mean relative error of pixel luminance, floored at 5% of the
 * reference's mean (as gi-bake --render does); pixels where every
 * reference path escaped to the sky are left out (both renderers show the
 * sky radiance there exactly). The reference's own error is estimated
 * from its halves: MRE(A, B) / 2 for the mean of two independent halves.
 * A lat-long panorama at a point (the workloads, workload.c) goes through
 * the same steps: gi_cascade_panorama's direct + indirect against
 * gi_reference_panorama, cached as pano-NAME-HASH.bin. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "acc.h"
#include "toolargs.h"
#include "gi/gi.h"

static float lum(const float *c) { return 0.2126f * c[0] + 0.7152f * c[1] + 0.0722f * c[2]; }

double acc_image_mre(const float *a, const float *ref, const uint8_t *mask, size_t np, double floor_l) {
  double sum = 0;
  size_t k = 0;
  for (size_t i = 0; i < np; i++) {
    if (!mask[i]) continue;
    double r = lum(&ref[3 * i]);
    sum += fabs(lum(&a[3 * i]) - r) / fmax(r, floor_l);
    k++;
  }
  return k ? sum / (double)k : 0;
}

double acc_image_ssim(const float *a, const float *ref, const uint8_t *mask, int w, int h, double exposure) {
  const double C1 = 1e-4, C2 = 9e-4;
  double sum = 0;
  size_t k = 0;
  for (int y0 = 0; y0 + 8 <= h; y0 += 4)
    for (int x0 = 0; x0 + 8 <= w; x0 += 4) {
      double sa = 0, sr = 0, saa = 0, srr = 0, sar = 0;
      int in = 1;
      for (int y = y0; y < y0 + 8 && in; y++)
        for (int x = x0; x < x0 + 8; x++) {
          size_t i = (size_t)y * w + x;
          if (!mask[i]) {
            in = 0;
            break;
          }
          double va = pow(fmin(fmax(exposure * lum(&a[3 * i]), 0), 1), 1 / 2.2);
          double vr = pow(fmin(fmax(exposure * lum(&ref[3 * i]), 0), 1), 1 / 2.2);
          sa += va, sr += vr, saa += va * va, srr += vr * vr, sar += va * vr;
        }
      if (!in) continue;
      double ma = sa / 64, mr = sr / 64, va = saa / 64 - ma * ma, vr = srr / 64 - mr * mr, cv = sar / 64 - ma * mr;
      sum += (2 * ma * mr + C1) * (2 * cv + C2) / ((ma * ma + mr * mr + C1) * (va + vr + C2));
      k++;
    }
  return k ? sum / (double)k : 1;
}

/* What an image shows: a pinhole camera's view, or (cam NULL) the
 * lat-long panorama of the light arriving at the point at. */
typedef struct img_src {
  const gi_camera *cam;
  double at[3];
  int w, h;
} img_src;

/* The path tracer's image of src at spp paths per pixel. */
static int path_image(const gi_scene *s, const img_src *src, int spp, uint64_t seed, int threads, float *img,
                      double *ms, gi_error_info *err) {
  if (src->cam) return gi_reference_render(s, src->cam, spp, seed, threads, img, ms, err) == GI_OK;
  gi_render_opts o = {.spp = spp, .seed = seed, .threads = threads};
  return gi_reference_panorama(s, src->at, src->w, src->h, &o, img, ms, err) == GI_OK;
}

/* The cone tracer's image of src from a baked cascade; tmp holds np * 3
 * floats (the panorama's indirect half). */
static int cone_image(const gi_cascade *c, const img_src *src, int threads, float *img, float *tmp, double *ms,
                      unsigned long long *spec, gi_error_info *err) {
  *spec = 0;
  if (!src->cam) {
    if (gi_cascade_panorama(c, src->at, src->w, src->h, img, tmp, ms, err) != GI_OK) return 0;
    for (size_t i = 0; i < (size_t)src->w * src->h * 3; i++) img[i] += tmp[i];
    return 1;
  }
  gi_render_opts ro = {.threads = threads};
  gi_render_stats st;
  if (gi_cascade_render_ex(c, src->cam, &ro, img, &st, err) != GI_OK) return 0;
  *ms = st.ms, *spec = st.specular_cones;
  return 1;
}

/* The two reference halves, from the cache or rendered (and cached). A
 * camera's cache key is unchanged from before panoramas existed. */
static int reference_halves(const char *name, const gi_scene *s, const img_src *src, int spp, int threads,
                            const char *out_dir, int ref_version, float *A, float *B, double *ms) {
  size_t nf = (size_t)src->w * src->h * 3;
  uint64_t h = acc_cache_key(name);
  if (src->cam) h = ta_fnv(h, src->cam, sizeof *src->cam);
  else h = ta_fnv(ta_fnv(ta_fnv(h, "pano", 4), src->at, sizeof src->at), &src->w, 2 * sizeof src->w);
  h = ta_fnv(h, &spp, sizeof spp);
  h = ta_fnv(h, &ref_version, sizeof ref_version);
  const char *kind = src->cam ? "view" : "pano";
  char path[1024];
  snprintf(path, sizeof path, "%s/%s-%s-%016llx.bin", out_dir, kind, name, (unsigned long long)h);
  *ms = 0;
  if (acc_cache_read(path, A, nf * sizeof *A, B, nf * sizeof *B)) {
    int ok = 1;
    for (size_t i = 0; ok && i < nf; i++) ok = isfinite(A[i]) && isfinite(B[i]);
    if (ok) {
      fprintf(stderr, "gi-accuracy: %s %s: reference from cache %s\n", name, kind, path);
      return 1;
    }
    fprintf(stderr, "gi-accuracy: %s %s: cache %s unreadable, recomputing\n", name, kind, path);
  }
  fprintf(stderr, "gi-accuracy: %s %s: reference, %d x %d pixels x %d paths...\n", name, kind, src->w, src->h, spp);
  gi_error_info err = {0};
  double ta = 0, tb = 0;
  if (!path_image(s, src, spp / 2, 11, threads, A, &ta, &err) || !path_image(s, src, spp / 2, 12, threads, B, &tb, &err)) {
    fprintf(stderr, "gi-accuracy: %s %s: reference: %s\n", name, kind, err.msg);
    return 0;
  }
  *ms = ta + tb;
  acc_cache_write(path, A, nf * sizeof *A, B, nf * sizeof *B);
  return 1;
}

/* cone | reference | error (0 black .. 50% and above white), one exposure. */
static int write_picture(const char *png, const float *cone, const float *ref, const uint8_t *mask, int w, int h,
                         double floor_l, double mean) {
  size_t np = (size_t)w * h;
  float *side = malloc(np * 9 * sizeof(float));
  if (!side) return 0;
  float exposure = mean > 0 ? (float)(0.18 / mean) : 1.f;
  for (int y = 0; y < h; y++)
    for (int x = 0; x < w; x++) {
      size_t i = (size_t)y * w + x, row = (size_t)y * 3 * w;
      double r = lum(&ref[3 * i]);
      float e = mask[i] ? (float)fmin(fabs(lum(&cone[3 * i]) - r) / fmax(r, floor_l) / 0.5, 1.0) : 0.f;
      float heat[3] = {fminf(1.f, 3 * e), fminf(1.f, fmaxf(0.f, 3 * e - 1)), fminf(1.f, fmaxf(0.f, 3 * e - 2))};
      for (int k = 0; k < 3; k++) {
        side[3 * (row + x) + k] = cone[3 * i + k];
        side[3 * (row + w + x) + k] = ref[3 * i + k];
        side[3 * (row + 2 * w + x) + k] = heat[k] / exposure;
      }
    }
  gi_error_info err = {0};
  int ok = gi_image_write_png(png, side, 3 * w, h, exposure, &err) == GI_OK;
  if (!ok) fprintf(stderr, "gi-accuracy: %s: %s\n", png, err.msg);
  free(side);
  return ok;
}

/* The images of one comparison, and what the error is counted over. */
typedef struct img_work {
  size_t np;
  float *ref, *img, *tmp;
  uint8_t *mask;
  double floor_l, mean, exposure;
} img_work;

/* The reference as the mean of its halves; the mask drops the pixels that
 * both halves show as pure sky. Sets the pixel count and its own error. */
static void reference_mask(const gi_scene *s, const float *A, const float *B, img_work *wk, acc_view *v) {
  float sky[3] = {0, 0, 0};
  for (size_t i = 0; i < gi_scene_num_lights(s); i++) {
    const gi_light *l = gi_scene_light(s, i);
    if (l->type == GI_LIGHT_SKY)
      for (int k = 0; k < 3; k++) sky[k] += l->color[k];
  }
  double mean = 0;
  size_t kept = 0;
  for (size_t i = 0; i < wk->np; i++) {
    for (int k = 0; k < 3; k++) wk->ref[3 * i + k] = 0.5f * (A[3 * i + k] + B[3 * i + k]);
    wk->mask[i] = !(A[3 * i] == sky[0] && A[3 * i + 1] == sky[1] && A[3 * i + 2] == sky[2] && B[3 * i] == sky[0] &&
                    B[3 * i + 1] == sky[1] && B[3 * i + 2] == sky[2]);
    if (wk->mask[i]) mean += lum(&wk->ref[3 * i]), kept++;
  }
  wk->mean = kept ? mean / (double)kept : 0;
  wk->floor_l = fmax(0.05 * wk->mean, 1e-30);
  wk->exposure = wk->mean > 0 ? 0.18 / wk->mean : 1;
  v->pixels = kept;
  v->ref_mre = 0.5 * acc_image_mre(A, B, wk->mask, wk->np, wk->floor_l);
}

/* The cone tracer: bake + image at default quality, fastest of repeat. */
static int run_cone_image(const char *name, const gi_scene *s, const double at[3], const img_src *src, int threads,
                          int repeat, img_work *wk, acc_view *v) {
  gi_quality q = {.threads = threads};
  gi_error_info err = {0};
  v->cone_ms = INFINITY;
  for (int r = 0; r < repeat; r++) {
    gi_cascade *c = NULL;
    gi_bake_report rep;
    double ms = 0;
    unsigned long long spec = 0;
    if (gi_cascade_bake(s, at, &q, &c, &rep, &err) != GI_OK || !cone_image(c, src, threads, wk->img, wk->tmp, &ms, &spec, &err)) {
      fprintf(stderr, "gi-accuracy: %s view: %s\n", name, err.msg);
      gi_cascade_free(c);
      return 0;
    }
    double b = acc_bake_ms(&rep);
    if (b + ms < v->cone_ms) v->cone_ms = b + ms, v->cone_bake_ms = b, v->cone_render_ms = ms;
    v->specular_cones = spec;
    gi_cascade_free(c);
  }
  v->cone_mre = acc_image_mre(wk->img, wk->ref, wk->mask, wk->np, wk->floor_l);
  v->cone_ssim = acc_image_ssim(wk->img, wk->ref, wk->mask, src->w, src->h, wk->exposure);
  fprintf(stderr, "  view cone: bake %.1f + render %.1f ms, MRE %.4f, SSIM %.4f (reference's own MRE %.4f)\n",
          v->cone_bake_ms, v->cone_render_ms, v->cone_mre, v->cone_ssim, v->ref_mre);
  return 1;
}

/* The path tracer at 1, 4, 16, ... paths per pixel, up to a quarter of the reference. */
static int run_path_images(const char *name, const gi_scene *s, const img_src *src, int threads, int repeat,
                           img_work *wk, acc_view *v) {
  gi_error_info err = {0};
  for (int spp = 1; spp <= v->ref_spp / 4 && v->num_path < ACC_VIEW_MAX_PATH; spp *= 4) {
    double best = INFINITY;
    for (int r = 0; r < repeat; r++) {
      double t = 0;
      if (!path_image(s, src, spp, 3, threads, wk->img, &t, &err)) {
        fprintf(stderr, "gi-accuracy: %s view: path %d: %s\n", name, spp, err.msg);
        return 0;
      }
      best = fmin(best, t);
    }
    int k = v->num_path++;
    v->path_spp[k] = spp, v->path_ms[k] = best, v->path_mre[k] = acc_image_mre(wk->img, wk->ref, wk->mask, wk->np, wk->floor_l);
    v->path_ssim[k] = acc_image_ssim(wk->img, wk->ref, wk->mask, src->w, src->h, wk->exposure);
    fprintf(stderr, "  view path %5d spp: %9.1f ms, MRE %.4f, SSIM %.4f\n", spp, best, v->path_mre[k], v->path_ssim[k]);
  }
  /* Time at the cone tracer's error: log-log interpolation between samples. */
  int how;
  v->path_ms_at_cone = acc_ms_at_error(v->path_ms, v->path_mre, v->num_path, v->cone_mre, &how);
  if (how < 0) v->path_ms_at_cone = -1;
  return 1;
}

static int run_image(const char *name, const gi_scene *s, const double at[3], const img_src *src, int ref_spp,
                     int threads, int repeat, const char *out_dir, const char *png, int ref_version, acc_view *v) {
  memset(v, 0, sizeof *v);
  snprintf(v->scene, sizeof v->scene, "%s", name);
  v->w = src->w, v->h = src->h, v->ref_spp = ref_spp;
  img_work wk = {.np = (size_t)src->w * src->h};
  float *A = malloc(wk.np * 3 * sizeof(float)), *B = malloc(wk.np * 3 * sizeof(float));
  wk.ref = malloc(wk.np * 3 * sizeof(float)), wk.img = malloc(wk.np * 3 * sizeof(float));
  wk.tmp = malloc(wk.np * 3 * sizeof(float)), wk.mask = malloc(wk.np);
  int ok = A && B && wk.ref && wk.img && wk.tmp && wk.mask &&
           reference_halves(name, s, src, ref_spp, threads, out_dir, ref_version, A, B, &v->ref_ms);
  if (ok) reference_mask(s, A, B, &wk, v);
  ok = ok && run_cone_image(name, s, at, src, threads, repeat, &wk, v);
  if (ok && png) ok = write_picture(png, wk.img, wk.ref, wk.mask, src->w, src->h, wk.floor_l, wk.mean);
  ok = ok && run_path_images(name, s, src, threads, repeat, &wk, v);
  free(A);
  free(B);
  free(wk.ref);
  free(wk.img);
  free(wk.tmp);
  free(wk.mask);
  return ok;
}

int acc_run_view(const char *name, const gi_scene *s, const double at[3], const gi_camera *cam, int ref_spp,
                 int threads, int repeat, const char *out_dir, const char *png, int ref_version, acc_view *v) {
  img_src src = {.cam = cam, .w = cam->width, .h = cam->height};
  return run_image(name, s, at, &src, ref_spp, threads, repeat, out_dir, png, ref_version, v);
}

double acc_view_image_error(const char *name, const gi_scene *s, const gi_camera *cam, int ref_spp, const char *out_dir,
                            int ref_version, const float *img) {
  img_src src = {.cam = cam, .w = cam->width, .h = cam->height};
  acc_view v;
  img_work wk = {.np = (size_t)src.w * src.h};
  float *A = malloc(wk.np * 3 * sizeof(float)), *B = malloc(wk.np * 3 * sizeof(float));
  wk.ref = malloc(wk.np * 3 * sizeof(float)), wk.mask = malloc(wk.np);
  double e = -1;
  if (A && B && wk.ref && wk.mask && reference_halves(name, s, &src, ref_spp, 0, out_dir, ref_version, A, B, &v.ref_ms)) {
    reference_mask(s, A, B, &wk, &v);
    e = acc_image_mre(img, wk.ref, wk.mask, wk.np, wk.floor_l);
  }
  free(A);
  free(B);
  free(wk.ref);
  free(wk.mask);
  return e;
}

int acc_run_pano(const char *name, const gi_scene *s, const double at[3], int w, int h, int ref_spp, int threads,
                 int repeat, const char *out_dir, const char *png, int ref_version, acc_view *v) {
  img_src src = {.cam = NULL, .at = {at[0], at[1], at[2]}, .w = w, .h = h};
  return run_image(name, s, at, &src, ref_spp, threads, repeat, out_dir, png, ref_version, v);
}

void acc_write_views_md(FILE *f, const acc_view *v, size_t n) {
  if (!n) return;
  fprintf(f, "## Camera views at equal error\n\n"
             "The paper's final rendering step: one bake serves every pixel of a view. Per view, the cone "
             "tracer's bake + render at default quality, and the path tracer at increasing paths per pixel, both "
             "against a path-traced reference image. Error: mean relative error of pixel luminance (floor 5%% of "
             "the reference's mean), over the pixels that are not pure sky; SSIM on display luminance (exposure "
             "to mid grey, gamma 2.2, 8 x 8 windows wholly off the sky; 1 = identical). Pictures: cone-traced | reference | "
             "error (black 0, white 50%% and above).\n\n");
  for (size_t i = 0; i < n; i++) {
    const acc_view *x = &v[i];
    fprintf(f, "### %s, %d x %d\n\n", x->scene, x->w, x->h);
    fprintf(f, "Reference: %d paths per pixel (two halves of %d)", x->ref_spp, x->ref_spp / 2);
    if (x->ref_ms > 0) fprintf(f, ", %.1f s", x->ref_ms / 1000);
    else fprintf(f, " (from the cache)");
    fprintf(f, "; its own error, from its halves: %.2f%% over %zu pixels.\n\n", 100 * x->ref_mre, x->pixels);
    fprintf(f, "| method | paths/pixel | ms | MRE | SSIM |\n|---|---|---|---|---|\n");
    fprintf(f, "| cone (bake %.0f + render %.0f ms, %llu specular cones) | - | %.1f | %.2f%% | %.4f |\n",
            x->cone_bake_ms, x->cone_render_ms, (unsigned long long)x->specular_cones, x->cone_ms,
            100 * x->cone_mre, x->cone_ssim);
    for (int k = 0; k < x->num_path; k++)
      fprintf(f, "| path | %d | %.1f | %.2f%% | %.4f |\n", x->path_spp[k], x->path_ms[k], 100 * x->path_mre[k],
              x->path_ssim[k]);
    if (x->path_ms_at_cone > 0) {
      double pt = x->path_ms_at_cone, r = x->cone_render_ms;
      fprintf(f, "\nThe path tracer reaches the cone tracer's error (%.2f%%) in about %.0f ms (interpolated): the "
                 "cone tracer, bake included, is **%.2fx %s** on this view; counting the render alone (a bake "
                 "reused by later frames from nearby viewpoints), %.2fx %s.\n\n",
              100 * x->cone_mre, pt, x->cone_ms < pt ? pt / x->cone_ms : x->cone_ms / pt,
              x->cone_ms < pt ? "faster" : "slower", r < pt ? pt / r : r / pt, r < pt ? "faster" : "slower");
    }
    else
      fprintf(f, "\nThe path tracer does not reach the cone tracer's error (%.2f%%) within %d paths per pixel "
                 "(%.0f ms): the cone tracer is at least %.1fx faster on this view.\n\n",
              100 * x->cone_mre, x->num_path ? x->path_spp[x->num_path - 1] : 0,
              x->num_path ? x->path_ms[x->num_path - 1] : 0,
              x->num_path ? x->path_ms[x->num_path - 1] / x->cone_ms : 0);
    if (x->png[0]) fprintf(f, "![%s: cone-traced, reference, error](%s)\n\n", x->scene, x->png);
  }
}
