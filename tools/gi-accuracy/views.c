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
 * from its halves: MRE(A, B) / 2 for the mean of two independent halves. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "acc.h"
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

/* The two reference halves, from the cache or rendered (and cached). */
static int reference_halves(const char *name, const gi_scene *s, const gi_camera *cam, int spp, int threads,
                            const char *out_dir, int ref_version, float *A, float *B, double *ms) {
  size_t nf = (size_t)cam->width * cam->height * 3;
  uint64_t h = acc_fnv(1469598103934665603ull, name, strlen(name));
  h = acc_fnv(h, cam, sizeof *cam);
  h = acc_fnv(h, &spp, sizeof spp);
  h = acc_fnv(h, &ref_version, sizeof ref_version);
  char path[1024];
  snprintf(path, sizeof path, "%s/view-%s-%016llx.bin", out_dir, name, (unsigned long long)h);
  *ms = 0;
  if (acc_cache_read(path, A, nf * sizeof *A, B, nf * sizeof *B)) {
    int ok = 1;
    for (size_t i = 0; ok && i < nf; i++) ok = isfinite(A[i]) && isfinite(B[i]);
    if (ok) {
      fprintf(stderr, "gi-accuracy: %s view: reference from cache %s\n", name, path);
      return 1;
    }
    fprintf(stderr, "gi-accuracy: %s view: cache %s unreadable, recomputing\n", name, path);
  }
  fprintf(stderr, "gi-accuracy: %s view: reference, %d x %d pixels x %d paths...\n", name, cam->width, cam->height,
          spp);
  gi_error_info err = {0};
  double ta = 0, tb = 0;
  if (gi_reference_render(s, cam, spp / 2, 11, threads, A, &ta, &err) != GI_OK ||
      gi_reference_render(s, cam, spp / 2, 12, threads, B, &tb, &err) != GI_OK) {
    fprintf(stderr, "gi-accuracy: %s view: reference: %s\n", name, err.msg);
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

int acc_run_view(const char *name, const gi_scene *s, const double at[3], const gi_camera *cam, int ref_spp,
                 int threads, int repeat, const char *out_dir, const char *png, int ref_version, acc_view *v) {
  memset(v, 0, sizeof *v);
  snprintf(v->scene, sizeof v->scene, "%s", name);
  v->w = cam->width, v->h = cam->height, v->ref_spp = ref_spp;
  size_t np = (size_t)cam->width * cam->height;
  float *A = malloc(np * 3 * sizeof(float)), *B = malloc(np * 3 * sizeof(float));
  float *ref = malloc(np * 3 * sizeof(float)), *img = malloc(np * 3 * sizeof(float));
  uint8_t *mask = malloc(np);
  int ok = 0;
  if (!A || !B || !ref || !img || !mask) goto done;
  if (!reference_halves(name, s, cam, ref_spp, threads, out_dir, ref_version, A, B, &v->ref_ms)) goto done;
  float sky[3] = {0, 0, 0};
  for (size_t i = 0; i < gi_scene_num_lights(s); i++) {
    const gi_light *l = gi_scene_light(s, i);
    if (l->type == GI_LIGHT_SKY)
      for (int k = 0; k < 3; k++) sky[k] += l->color[k];
  }
  double mean = 0;
  size_t kept = 0;
  for (size_t i = 0; i < np; i++) {
    for (int k = 0; k < 3; k++) ref[3 * i + k] = 0.5f * (A[3 * i + k] + B[3 * i + k]);
    mask[i] = !(A[3 * i] == sky[0] && A[3 * i + 1] == sky[1] && A[3 * i + 2] == sky[2] && B[3 * i] == sky[0] &&
                B[3 * i + 1] == sky[1] && B[3 * i + 2] == sky[2]);
    if (mask[i]) mean += lum(&ref[3 * i]), kept++;
  }
  mean = kept ? mean / (double)kept : 0;
  v->pixels = kept;
  double floor_l = fmax(0.05 * mean, 1e-30);
  v->ref_mre = 0.5 * acc_image_mre(A, B, mask, np, floor_l);

  /* The cone tracer: bake + render at default quality, fastest of repeat. */
  gi_quality q = {.threads = threads};
  gi_render_opts ro = {.threads = threads};
  gi_error_info err = {0};
  v->cone_ms = INFINITY;
  for (int r = 0; r < repeat; r++) {
    gi_cascade *c = NULL;
    gi_bake_report rep;
    gi_render_stats st;
    if (gi_cascade_bake(s, at, &q, &c, &rep, &err) != GI_OK ||
        gi_cascade_render_ex(c, cam, &ro, img, &st, &err) != GI_OK) {
      fprintf(stderr, "gi-accuracy: %s view: %s\n", name, err.msg);
      gi_cascade_free(c);
      goto done;
    }
    double b = rep.ms.voxelize + rep.ms.inject + rep.ms.filter + rep.ms.bounce;
    if (b + st.ms < v->cone_ms) v->cone_ms = b + st.ms, v->cone_bake_ms = b, v->cone_render_ms = st.ms;
    v->specular_cones = st.specular_cones;
    gi_cascade_free(c);
  }
  v->cone_mre = acc_image_mre(img, ref, mask, np, floor_l);
  double exposure = mean > 0 ? 0.18 / mean : 1;
  v->cone_ssim = acc_image_ssim(img, ref, mask, cam->width, cam->height, exposure);
  fprintf(stderr, "  view cone: bake %.1f + render %.1f ms, MRE %.4f, SSIM %.4f (reference's own MRE %.4f)\n",
          v->cone_bake_ms, v->cone_render_ms, v->cone_mre, v->cone_ssim, v->ref_mre);
  if (png && !write_picture(png, img, ref, mask, cam->width, cam->height, floor_l, mean)) goto done;

  /* The path tracer at 1, 4, 16, ... paths per pixel, up to a quarter of the reference. */
  for (int spp = 1; spp <= ref_spp / 4 && v->num_path < ACC_VIEW_MAX_PATH; spp *= 4) {
    double best = INFINITY;
    for (int r = 0; r < repeat; r++) {
      double t = 0;
      if (gi_reference_render(s, cam, spp, 3, threads, img, &t, &err) != GI_OK) {
        fprintf(stderr, "gi-accuracy: %s view: path %d: %s\n", name, spp, err.msg);
        goto done;
      }
      best = fmin(best, t);
    }
    int k = v->num_path++;
    v->path_spp[k] = spp, v->path_ms[k] = best, v->path_mre[k] = acc_image_mre(img, ref, mask, np, floor_l);
    v->path_ssim[k] = acc_image_ssim(img, ref, mask, cam->width, cam->height, exposure);
    fprintf(stderr, "  view path %5d spp: %9.1f ms, MRE %.4f, SSIM %.4f\n", spp, best, v->path_mre[k], v->path_ssim[k]);
  }
  /* Time at the cone tracer's error: log-log interpolation between samples. */
  v->path_ms_at_cone = -1;
  for (int k = 0; k < v->num_path; k++) {
    if (v->path_mre[k] > v->cone_mre) continue;
    if (k == 0) v->path_ms_at_cone = v->path_ms[0];
    else {
      double e0 = log(v->path_mre[k - 1]), e1 = log(v->path_mre[k]), f = (log(v->cone_mre) - e0) / (e1 - e0);
      v->path_ms_at_cone = exp(log(v->path_ms[k - 1]) + f * (log(v->path_ms[k]) - log(v->path_ms[k - 1])));
    }
    break;
  }
  ok = 1;
done:
  free(A);
  free(B);
  free(ref);
  free(img);
  free(mask);
  return ok;
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
