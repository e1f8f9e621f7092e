/* camera.c: the pinhole camera of camera views: validation, the Mitsuba
 * sensor reader and the ray through a pixel. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "answer/answer.h"
#include "base/internal.h"
#include "gi/gi_render.h"
#include "plan.h"

gi_result gi_camera_validate(const gi_camera *cam, gi_error_info *err) {
  if (!cam) return gi__fail(err, GI_ERR_INVALID_ARG, "camera: cam is NULL");
  for (int k = 0; k < 3; k++)
    if (!isfinite(cam->eye[k]) || !isfinite(cam->target[k]) || !isfinite(cam->up[k]))
      return gi__fail(err, GI_ERR_NONFINITE, "camera: eye, target and up must be finite");
  double d[3], l = 0, u = 0, du = 0;
  for (int k = 0; k < 3; k++) d[k] = cam->target[k] - cam->eye[k], l += d[k] * d[k], u += cam->up[k] * cam->up[k];
  for (int k = 0; k < 3; k++) du += d[k] * cam->up[k];
  if (!(l > 0)) return gi__fail(err, GI_ERR_INVALID_ARG, "camera: eye and target are the same point");
  if (!(u > 0) || fabs(du) >= 0.9999 * sqrt(l * u))
    return gi__fail(err, GI_ERR_INVALID_ARG, "camera: up must not be zero or along the view direction");
  if (!(cam->fov_deg > 0 && cam->fov_deg < 180))
    return gi__fail(err, GI_ERR_INVALID_ARG, "camera: fov must be in (0, 180) degrees, got %g", cam->fov_deg);
  if (cam->width < 1 || cam->height < 1 || cam->width > 8192 || cam->height > 8192)
    return gi__fail(err, GI_ERR_INVALID_ARG, "camera: width and height must be 1..8192, got %d x %d", cam->width,
                    cam->height);
  return GI_OK;
}

gi_result gi__cam_setup(const gi_scene *s, const gi_camera *cam, gi__cam *k, gi_error_info *err) {
  gi_result rc = gi_camera_validate(cam, err);
  if (rc != GI_OK) return rc;
  double f[3], r[3], u[3], lf = 0, lr = 0;
  for (int a = 0; a < 3; a++) f[a] = cam->target[a] - cam->eye[a], lf += f[a] * f[a];
  lf = sqrt(lf);
  for (int a = 0; a < 3; a++) f[a] /= lf;
  /* right = forward x up: with Mitsuba's lookat the red wall of the Cornell box is on the left. */
  r[0] = f[1] * cam->up[2] - f[2] * cam->up[1];
  r[1] = f[2] * cam->up[0] - f[0] * cam->up[2];
  r[2] = f[0] * cam->up[1] - f[1] * cam->up[0];
  for (int a = 0; a < 3; a++) lr += r[a] * r[a];
  lr = sqrt(lr);
  for (int a = 0; a < 3; a++) r[a] /= lr;
  u[0] = r[1] * f[2] - r[2] * f[1];
  u[1] = r[2] * f[0] - r[0] * f[2];
  u[2] = r[0] * f[1] - r[1] * f[0];
  double t = tan(0.5 * cam->fov_deg * 3.14159265358979323846 / 180.0);
  double small = cam->width < cam->height ? cam->width : cam->height;
  k->w = cam->width, k->h = cam->height;
  k->tanx = (float)(t * cam->width / small);
  k->tany = (float)(t * cam->height / small);
  for (int a = 0; a < 3; a++) {
    k->eye[a] = (float)(cam->eye[a] - s->origin[a]);
    k->fwd[a] = (float)f[a], k->right[a] = (float)r[a], k->upv[a] = (float)u[a];
  }
  /* In double, as the bake's rule: rounded to float, 1e9 + 32 passed. */
  for (int a = 0; a < 3; a++)
    if (!isfinite(k->eye[a]) || fabs(cam->eye[a] - s->origin[a]) > GI_MAX_VIEW_DISTANCE)
      return gi__fail(err, GI_ERR_INVALID_ARG,
                      "camera: eye is more than " GI_MAX_VIEW_DISTANCE_TEXT
                      " units from the scene's origin on axis %c (%g)", "xyz"[a], fabs(cam->eye[a] - s->origin[a]));
  return GI_OK;
}

void gi__cam_ray(const gi__cam *k, float px, float py, float dir[3]) {
  float sx = (2 * px / (float)k->w - 1) * k->tanx, sy = (1 - 2 * py / (float)k->h) * k->tany;
  for (int a = 0; a < 3; a++) dir[a] = k->fwd[a] + sx * k->right[a] + sy * k->upv[a];
  float l = gi__len(dir);
  for (int a = 0; a < 3; a++) dir[a] /= l;
}
