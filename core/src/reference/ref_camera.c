/* ref_camera.c: the reference's pinhole camera, set up apart from the
 * cone-traced view's (answer/camera.c) from the public semantics of
 * gi_camera: fov across the smaller image side, right = forward x up (so
 * with Mitsuba's lookat the Cornell box's red wall is on the left), image
 * rows from the top. */
#include <string.h>
#include "reference/ref_internal.h"

gi_result gi__ref_cam_init(ref_cam *k, const gi_scene *s, const gi_camera *cam, gi_error_info *err) {
  gi_result rc = gi_camera_validate(cam, err);
  if (rc != GI_OK) return rc;
  /* Forward, then the up vector made orthogonal to it (Gram-Schmidt), then right. */
  double f[3], u[3], lf = 0, fu = 0, lu = 0;
  for (int a = 0; a < 3; a++) f[a] = cam->target[a] - cam->eye[a], lf += f[a] * f[a];
  lf = sqrt(lf);
  for (int a = 0; a < 3; a++) f[a] /= lf, fu += f[a] * cam->up[a];
  for (int a = 0; a < 3; a++) u[a] = cam->up[a] - fu * f[a], lu += u[a] * u[a];
  lu = sqrt(lu);
  for (int a = 0; a < 3; a++) u[a] /= lu;
  double r[3] = {f[1] * u[2] - f[2] * u[1], f[2] * u[0] - f[0] * u[2], f[0] * u[1] - f[1] * u[0]};
  for (int a = 0; a < 3; a++) {
    double e = cam->eye[a] - s->origin[a];
    if (!(fabs(e) <= REF_MAX_DIST))
      return gi__fail(err, GI_ERR_INVALID_ARG,
                      "camera: eye is more than %g units from the scene's origin on axis %c (%g)", REF_MAX_DIST,
                      "xyz"[a], fabs(e));
    k->eye[a] = (float)e;
    k->fwd[a] = (float)f[a], k->up[a] = (float)u[a], k->right[a] = (float)r[a];
  }
  int small = cam->width < cam->height ? cam->width : cam->height;
  k->half = (float)(tan(0.5 * cam->fov_deg * GI_PI / 180.0) / (0.5 * small));
  k->w = cam->width, k->h = cam->height, k->pano = 0, k->up_z = 0;
  return GI_OK;
}

/* The panorama's size limits, as gi_cascade_panorama's. */
#define PANO_MAX_W 16384
#define PANO_MAX_H 8192

gi_result gi__ref_pano_init(ref_cam *k, const gi_scene *s, const double at[3], int w, int h, gi_error_info *err) {
  if (!at) return gi__fail(err, GI_ERR_INVALID_ARG, "reference panorama: at is NULL");
  if (w < 2 || h < 1 || w > PANO_MAX_W || h > PANO_MAX_H)
    return gi__fail(err, GI_ERR_INVALID_ARG, "reference panorama: size %dx%d outside 2..16384 x 1..8192", w, h);
  memset(k, 0, sizeof *k);
  for (int a = 0; a < 3; a++) {
    double e = at[a] - s->origin[a];
    if (!(fabs(e) <= REF_MAX_DIST))
      return gi__fail(err, GI_ERR_NONFINITE,
                      "reference panorama: point is not finite or more than %g units from the scene's origin "
                      "on axis %c", REF_MAX_DIST, "xyz"[a]);
    k->eye[a] = (float)e;
  }
  k->w = w, k->h = h, k->pano = 1, k->up_z = s->up == GI_UP_Z;
  return GI_OK;
}

/* Polar angle from the up axis down the rows, azimuth across the columns:
 * gi_cascade_panorama's pixel directions at pixel centres. */
static void pano_dir(const ref_cam *k, float px, float py, float w[3]) {
  float th = (float)GI_PI * py / (float)k->h, ph = 2 * (float)GI_PI * px / (float)k->w;
  float st = sinf(th), ct = cosf(th);
  w[0] = st * cosf(ph);
  w[1] = k->up_z ? st * sinf(ph) : ct;
  w[2] = k->up_z ? ct : st * sinf(ph);
}

void gi__ref_cam_dir(const ref_cam *k, float px, float py, float w[3]) {
  if (k->pano) {
    pano_dir(k, px, py, w);
    return;
  }
  /* Image-plane offsets at distance 1 from the eye, from the image centre. */
  float sx = (px - 0.5f * (float)k->w) * k->half, sy = (0.5f * (float)k->h - py) * k->half;
  float l = 0;
  for (int a = 0; a < 3; a++) w[a] = k->fwd[a] + sx * k->right[a] + sy * k->up[a], l += w[a] * w[a];
  l = 1.0f / sqrtf(l);
  for (int a = 0; a < 3; a++) w[a] *= l;
}
