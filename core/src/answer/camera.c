/* camera.c: the pinhole camera of camera views: validation, the Mitsuba
 * sensor reader and the ray through a pixel. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "answer/answer.h"
#include "base/internal.h"
#include "gi/gi_render.h"

gi_result gi_camera_validate(const gi_camera *cam, gi_error_info *err) {
  if (!cam) return gi__fail(err, GI_ERR_INVALID_ARG, "camera: missing");
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
  if (!gi__finite3(k->eye) || fabsf(k->eye[0]) > 1e9f || fabsf(k->eye[1]) > 1e9f || fabsf(k->eye[2]) > 1e9f)
    return gi__fail(err, GI_ERR_INVALID_ARG, "camera: eye is more than 1e9 units from the scene");
  return GI_OK;
}

void gi__cam_ray(const gi__cam *k, float px, float py, float dir[3]) {
  float sx = (2 * px / (float)k->w - 1) * k->tanx, sy = (1 - 2 * py / (float)k->h) * k->tany;
  for (int a = 0; a < 3; a++) dir[a] = k->fwd[a] + sx * k->right[a] + sy * k->upv[a];
  float l = gi__len(dir);
  for (int a = 0; a < 3; a++) dir[a] /= l;
}

/* ---- Mitsuba sensor ------------------------------------------------- */

/* Value of attribute `name` inside [b, e): name, optional blanks, '=', quote. */
static int xml_attr(const char *b, const char *e, const char *name, char *out, size_t n) {
  size_t ln = strlen(name);
  for (const char *p = b; p + ln < e; p++) {
    if (strncmp(p, name, ln) || (p > b && !strchr(" \t\r\n", p[-1]))) continue;
    const char *q = p + ln;
    while (q < e && strchr(" \t\r\n", *q)) q++;
    if (q >= e || *q != '=') continue;
    q++;
    while (q < e && strchr(" \t\r\n", *q)) q++;
    if (q >= e || (*q != '"' && *q != '\'')) continue;
    char quote = *q++;
    const char *end = memchr(q, quote, (size_t)(e - q));
    if (!end || (size_t)(end - q) >= n) return 0;
    memcpy(out, q, (size_t)(end - q));
    out[end - q] = '\0';
    return 1;
  }
  return 0;
}

static int parse3(const char *s, double v[3]) {
  char *end;
  for (int k = 0; k < 3; k++) {
    while (*s == ' ' || *s == ',' || *s == '\t') s++;
    v[k] = strtod(s, &end);
    if (end == s || !isfinite(v[k])) return 0;
    s = end;
  }
  while (*s == ' ' || *s == '\t') s++;
  return *s == '\0';
}

gi_result gi_camera_from_mitsuba(const char *path, gi_camera *cam, gi_error_info *err) {
  FILE *f = fopen(path, "rb");
  if (!f) return gi__fail(err, GI_ERR_IO, "camera: cannot open %s", path);
  char *buf = gi__malloc(1 << 20);
  size_t n = buf ? fread(buf, 1, (1 << 20) - 1, f) : 0;
  fclose(f);
  if (!buf) return gi__fail(err, GI_ERR_NOMEM, "camera: out of memory");
  buf[n] = '\0';
  gi_result rc = GI_OK;
  char v[256];
  const char *b = strstr(buf, "<sensor"), *e = b ? strstr(b, "</sensor>") : NULL;
  if (!b || !e) {
    rc = gi__fail(err, GI_ERR_FORMAT, "camera: %s has no <sensor> ... </sensor>", path);
    goto done;
  }
  if (!xml_attr(b, e, "type", v, sizeof v) || strcmp(v, "perspective")) {
    rc = gi__fail(err, GI_ERR_FORMAT, "camera: %s: the sensor is not 'perspective'", path);
    goto done;
  }
  const char *fov = strstr(b, "name=\"fov\"");
  char *end;
  if (!fov || fov > e || !xml_attr(fov, e, "value", v, sizeof v) || (cam->fov_deg = strtod(v, &end), *end)) {
    rc = gi__fail(err, GI_ERR_FORMAT, "camera: %s: sensor field 'fov' missing or not a number", path);
    goto done;
  }
  const char *la = strstr(b, "<lookat");
  const char *lae = la ? strstr(la, "/>") : NULL;
  if (!la || !lae || lae > e) {
    rc = gi__fail(err, GI_ERR_FORMAT, "camera: %s: sensor has no <lookat .../>", path);
    goto done;
  }
  static const char *const names[3] = {"origin", "target", "up"};
  double *dst[3] = {cam->eye, cam->target, cam->up};
  for (int i = 0; i < 3; i++)
    if (!xml_attr(la, lae, names[i], v, sizeof v) || !parse3(v, dst[i])) {
      rc = gi__fail(err, GI_ERR_FORMAT, "camera: %s: lookat field '%s' missing or not three numbers", path, names[i]);
      goto done;
    }
done:
  gi__free(buf);
  return rc;
}
