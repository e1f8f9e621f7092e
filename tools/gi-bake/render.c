/* render.c: gi-bake --render, the cascade's view beside the truth.
 *
 * Renders the camera view from the baked cascade (gi_cascade_render) and
 * path-traced (gi_reference_render), and puts them side by side with an
 * error image: |cone - path| / path on luminance, 0 black to 50% and
 * above white (false colour through red and yellow). Both views share one
 * exposure, chosen so the path-traced view's mean luminance lands at 0.18
 * (mid grey), so the pictures compare at a glance. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "cli.h"

static float lum(const float *c) { return 0.2126f * c[0] + 0.7152f * c[1] + 0.0722f * c[2]; }

void cli_render_up(gi_camera *cam, int z_up) {
  double d[3], l = 0;
  for (int a = 0; a < 3; a++) d[a] = cam->target[a] - cam->eye[a], l += d[a] * d[a];
  memset(cam->up, 0, sizeof cam->up);
  /* Within 2.6 degrees of straight up or down the up axis leaves no
   * picture; north goes to the top instead, as on a map. */
  if (fabs(d[z_up ? 2 : 1]) >= 0.999 * sqrt(l)) cam->up[z_up ? 1 : 2] = z_up ? 1 : -1;
  else cam->up[z_up ? 2 : 1] = 1;
}

int cli_render(const cli_opts *o, const gi_scene *scene, const gi_cascade *cas, cli_render_stats *st) {
  gi_camera cam = o->cam;
  if (o->cam_up_from_scene) cli_render_up(&cam, gi_scene_up(scene) == GI_UP_Z);
  gi_error_info err = {0};
  if (gi_camera_validate(&cam, &err) != GI_OK) {
    fprintf(stderr, "gi-bake: --render: %s\n", err.msg);
    return EXIT_USAGE;
  }
  int w = cam.width, h = cam.height, spp = o->render_spp ? o->render_spp : 64;
  size_t np = (size_t)w * h;
  float *cone = malloc(np * 3 * sizeof(float)), *path = malloc(np * 3 * sizeof(float));
  float *side = malloc(np * 9 * sizeof(float)), *errimg = malloc(np * sizeof(float));
  int rc = EXIT_RUN;
  if (!cone || !path || !side || !errimg) {
    fprintf(stderr, "gi-bake: --render: out of memory for %d x %d pixels\n", w, h);
    goto done;
  }
  memset(st, 0, sizeof *st);
  st->width = w, st->height = h, st->spp = spp;
  gi_render_opts ro = {.threads = o->q.threads, .indirect_stride = o->render_stride};
  if (gi_cascade_render_ex(cas, &cam, &ro, cone, &st->view, &err) != GI_OK ||
      gi_reference_render(scene, &cam, spp, 1, o->q.threads, path, &st->path_ms, &err) != GI_OK) {
    fprintf(stderr, "gi-bake: --render: %s\n", err.msg);
    goto done;
  }
  st->cone_ms = st->view.ms;
  /* The cone view shows light leaked into a solid the camera stands in;
   * the path-traced one is black there (as the probes' note says). */
  double eye[3] = {cam.eye[0], cam.eye[1], cam.eye[2]}, share = gi_scene_backface_share(scene, eye);
  if (share > GI_INSIDE_SHARE)
    fprintf(stderr, "gi-bake: note: the camera (%g, %g, %g) looks inside a solid (%.0f%% of 26 rays from it meet a "
            "surface's back first): the cone-traced view shows only light that leaks in\n", eye[0], eye[1], eye[2],
            100 * share);
  if (st->view.pixels_outside)
    fprintf(stderr, "gi-bake: note: %llu of %zu pixels see surfaces outside the cascade around the viewpoint: their "
            "indirect light is 0 and only their direct light is drawn; bake with more --levels, or nearer what the "
            "camera sees\n", (unsigned long long)st->view.pixels_outside, np);
  double mean = 0, cone_mean = 0;
  for (size_t i = 0; i < np; i++) mean += lum(&path[3 * i]) / (double)np, cone_mean += lum(&cone[3 * i]) / (double)np;
  /* Errors relative to each pixel, floored at 5% of the mean: a dark pixel
   * is not divided by nothing. A black reference (an eye inside a closed,
   * unlit solid) floors at the cone view's mean instead, which read
   * 4e29% when the floor was 1e-30; both black is no error. */
  float floor_l = (float)(0.05 * (mean > 0 ? mean : cone_mean)), exposure = mean > 0 ? (float)(0.18 / mean) : 1.f;
  double sum = 0;
  for (size_t i = 0; i < np; i++) {
    float lc = lum(&cone[3 * i]), lp = lum(&path[3 * i]);
    errimg[i] = floor_l > 0 ? fabsf(lc - lp) / fmaxf(lp, floor_l) : 0.f;
    sum += errimg[i];
  }
  st->mre = sum / (double)np;
  /* Side by side: cone | path | error (already scaled, so undo the exposure). */
  for (int y = 0; y < h; y++)
    for (int x = 0; x < w; x++) {
      size_t i = (size_t)y * w + x, row = (size_t)y * 3 * w;
      float e = fminf(errimg[i] / 0.5f, 1.f);
      float heat[3] = {fminf(1.f, 3 * e) / exposure, fminf(1.f, fmaxf(0.f, 3 * e - 1)) / exposure,
                       fminf(1.f, fmaxf(0.f, 3 * e - 2)) / exposure};
      for (int k = 0; k < 3; k++) {
        side[3 * (row + x) + k] = cone[3 * i + k];
        side[3 * (row + w + x) + k] = path[3 * i + k];
        side[3 * (row + 2 * w + x) + k] = heat[k];
      }
    }
  if (o->png && gi_image_write_png(o->png, side, 3 * w, h, exposure, &err) != GI_OK) {
    fprintf(stderr, "gi-bake: --png: %s\n", err.msg);
    goto done;
  }
  if (o->exr) {
    float *planes = malloc(np * 7 * sizeof(float));
    if (!planes) goto done;
    static const char *const names[7] = {"R", "G", "B", "path.R", "path.G", "path.B", "error.Y"};
    gi_exr_channel ch[7];
    for (int c = 0; c < 7; c++) {
      for (size_t i = 0; i < np; i++)
        planes[c * np + i] = c < 3 ? cone[3 * i + c] : c < 6 ? path[3 * i + c - 3] : errimg[i];
      ch[c].name = names[c], ch[c].data = &planes[c * np];
    }
    char spp_s[32];
    snprintf(spp_s, sizeof spp_s, "%d", spp);
    gi_exr_attr at[3] = {{"gi.kind", "render"}, {"gi.scene", gi_scene_name(scene)}, {"gi.path_spp", spp_s}};
    gi_exr_image img = {.width = w, .height = h, .use_half = o->half, .num_channels = 7, .channels = ch,
                        .num_attrs = 3, .attrs = at};
    gi_result r = gi_exr_write(o->exr, &img, &err);
    free(planes);
    if (r != GI_OK) {
      fprintf(stderr, "gi-bake: --exr: %s\n", err.msg);
      goto done;
    }
  }
  rc = 0;
done:
  free(cone);
  free(path);
  free(side);
  free(errimg);
  return rc;
}
