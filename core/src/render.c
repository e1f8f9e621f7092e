/* render.c: the final rendering step, a camera view shaded from the cascade.
 *
 * DESIGN. One primary ray per pixel (pixel centre) through Embree. At the
 * hit, surfaces are two-sided: the normal turns toward the camera. Direct
 * light comes from shadow rays with the bake's own light sampler and plan
 * (so a skipped effect stays skipped); indirect light from the bake's
 * diffuse cone set around the normal, started one voxel of the finest level
 * containing the point off the surface, exactly as the voxel bounces
 * gather; the specular pass (gi_cascade_view_plan decides whether it runs
 * and where) adds one specular cone along the mirror direction, weighted
 * by the material's specular reflectance. Pixels are independent: rows
 * run in parallel, each pixel seeded by its index.
 *
 * Also here: the camera (Mitsuba sensor reader, validation, ray setup,
 * shared with the path-traced view in reference.c). */
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "cascade_internal.h"
#include "gi/gi_render.h"
#include "internal.h"

#define PI_F 3.14159265358979f

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
  char *buf = malloc(1 << 20);
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
  free(buf);
  return rc;
}

/* ---- the cone-traced view ------------------------------------------- */

/* Where the specular pass traces its cone. */
enum { SPEC_NONE = 0, SPEC_GLOSSY = 1, SPEC_ALL = 2 };

static int spec_mode(const struct gi_cascade *c) {
  int f = gi__fx_forced(&c->report.quality, GI_FX_SPECULAR);
  if (f == GI_FX_OFF) return SPEC_NONE;
  if (f == GI_FX_ON) return SPEC_ALL;
  return c->report.glossy_triangles ? SPEC_GLOSSY : SPEC_NONE;
}

void gi_cascade_view_plan(const gi_cascade *c, gi_effect out[GI_FX_COUNT]) {
  if (!c || !out) return;
  memcpy(out, c->report.effects, sizeof c->report.effects);
  gi_effect *e = &out[GI_FX_SPECULAR];
  uint32_t g = c->report.glossy_triangles;
  switch (spec_mode(c)) {
    case SPEC_ALL:
      e->ran = 1;
      snprintf(e->why, sizeof e->why, "forced on: one specular cone at every pixel (%u glossy triangle%s in range)", g,
               g == 1 ? "" : "s");
      break;
    case SPEC_GLOSSY:
      e->ran = 1;
      snprintf(e->why, sizeof e->why, "%u glossy triangle%s in range: one specular cone at each of their pixels", g,
               g == 1 ? "" : "s");
      break;
    default:
      e->ran = 0;
      if (g) snprintf(e->why, sizeof e->why, "turned off by the request");
      else snprintf(e->why, sizeof e->why, "%s", c->report.effects[GI_FX_SPECULAR].why);
  }
}

typedef struct {
  const struct gi_cascade *c;
  const gi__cam *k;
  int samples;
  int spec;            /* SPEC_* */
  float *rgb;
  _Atomic uint64_t diffuse_cones, specular_cones;
  float *spec_img;     /* optional: specular * L_cone per pixel */
} render_ctx;

static void shade_pixel(render_ctx *rc, int px, int py, gi_ray_scratch *sc, uint64_t cones[2], float out[3],
                        float *spec) {
  gi_lsample *ls = sc->ls;
  float *org = sc->org, *dir = sc->dir, *tn = sc->tn, *tf = sc->tf;
  uint8_t *vis = sc->vis;
  int cap = sc->cap;
  const struct gi_cascade *c = rc->c;
  const gi_scene *s = c->scene;
  float w[3], t, ng[3];
  uint32_t tri;
  out[0] = out[1] = out[2] = 0;
  gi__cam_ray(rc->k, (float)px + 0.5f, (float)py + 0.5f, w);
  if (!gi__intersect1(s, rc->k->eye, w, 0, INFINITY, &t, &tri, ng)) {
    /* The camera sees the sky itself where the plan lights with it. */
    if (c->report.effects[GI_FX_SKY].ran) gi__sky_radiance(s, out);
    return;
  }
  const gi_material *m = &s->materials[s->tri_material[tri]];
  float cw = gi__dot(ng, w), n[3], x[3];
  for (int a = 0; a < 3; a++) n[a] = cw > 0 ? -ng[a] : ng[a], x[a] = rc->k->eye[a] + t * w[a];
  if (cw < 0) /* emitters are one-sided: their front faces the camera */
    for (int a = 0; a < 3; a++) out[a] += m->emission[a];
  float eps = (float)(1e-3 * c->s0), E[3] = {0, 0, 0};
  gi_light_plan lp = gi__light_plan(&c->report, rc->samples);
  uint64_t rng = gi__mix64(c->report.quality.seed ^ ((uint64_t)py << 32 | (uint32_t)px));
  int nl = gi__light_samples(s, &lp, x, &rng, ls, cap), k = 0;
  for (int i = 0; i < nl; i++) {
    float cn = gi__dot(n, ls[i].w);
    if (!(cn > 0)) continue;
    for (int a = 0; a < 3; a++) org[3 * k + a] = x[a] + eps * n[a], dir[3 * k + a] = ls[i].w[a];
    tn[k] = 0;
    tf[k] = isinf(ls[i].dist) ? INFINITY : ls[i].dist * 0.999f;
    ls[k] = ls[i];
    ls[k].dist = cn;
    k++;
  }
  gi__occluded(s, k, org, dir, tn, tf, vis);
  for (int i = 0; i < k; i++)
    if (vis[i])
      for (int a = 0; a < 3; a++) E[a] += ls[i].V[a] * ls[i].dist;
  int d = gi__finest_level_at(c, x);
  if (d >= 0 && c->report.bounces_run > 0) {
    float off = (float)c->lv[d].s, o[3], tt[3], bb[3];
    for (int a = 0; a < 3; a++) o[a] = x[a] + off * n[a];
    gi__basis(n, tt, bb);
    for (int ci = 0; ci < c->num_cones; ci++) {
      const float *cd = c->cone_dir[ci];
      float cwd[3];
      for (int a = 0; a < 3; a++) cwd[a] = cd[0] * tt[a] + cd[1] * bb[a] + cd[2] * n[a];
      gi_cone_out co;
      gi__cone_trace(c, o, cwd, c->cone_tan, off, c->report.quality.step, c->report.quality.ao_lambda, &co);
      for (int a = 0; a < 3; a++) E[a] += c->cone_weight[ci] * co.L[a];
    }
    cones[0] += (uint64_t)c->num_cones;
  }
  for (int a = 0; a < 3; a++) out[a] += m->albedo[a] * (1.f / PI_F) * E[a];
  int glossy = m->roughness < 0.5f && m->specular > 0;
  if (d >= 0 && (rc->spec == SPEC_ALL || (rc->spec == SPEC_GLOSSY && glossy))) {
    gi_cone_out co;
    gi__specular_trace(c, x, n, w, m->roughness, &co);
    cones[1]++;
    for (int a = 0; a < 3; a++) out[a] += m->specular * co.L[a];
    if (spec)
      for (int a = 0; a < 3; a++) spec[a] = m->specular * co.L[a];
  }
}

static void render_rows(void *p, size_t b, size_t e, int worker) {
  render_ctx *rc = p;
  const gi_scene *s = rc->c->scene;
  gi_ray_scratch sc = {0};
  uint64_t cones[2] = {0, 0};
  if (gi__scratch_alloc(&sc, 2 * rc->samples + (int)s->num_lights + 8) == 0)
    for (size_t y = b; y < e; y++)
      for (int x = 0; x < rc->k->w; x++)
        shade_pixel(rc, x, (int)y, &sc, cones, &rc->rgb[3 * ((size_t)y * rc->k->w + x)],
                    rc->spec_img ? &rc->spec_img[3 * ((size_t)y * rc->k->w + x)] : NULL);
  gi__scratch_free(&sc);
  atomic_fetch_add(&rc->diffuse_cones, cones[0]);
  atomic_fetch_add(&rc->specular_cones, cones[1]);
}

gi_result gi_cascade_render_ex(const gi_cascade *c, const gi_camera *cam, const gi_render_opts *opts, float *rgb,
                               gi_render_stats *st, gi_error_info *err) {
  if (!c || !rgb) return gi__fail(err, GI_ERR_INVALID_ARG, "render: missing cascade or image");
  gi_render_opts o = {0};
  if (opts) o = *opts;
  if (o.light_samples == 0) o.light_samples = 64;
  if (o.light_samples < 1 || o.light_samples > 4096)
    return gi__fail(err, GI_ERR_INVALID_ARG, "render: light_samples must be 1..4096, got %d", o.light_samples);
  gi__cam k;
  gi_result r = gi__cam_setup(c->scene, cam, &k, err);
  if (r != GI_OK) return r;
  double t0 = gi__now_ms();
  size_t np = (size_t)k.w * k.h * 3;
  memset(rgb, 0, np * sizeof(float));
  if (o.specular) memset(o.specular, 0, np * sizeof(float));
  render_ctx rc = {.c = c, .k = &k, .samples = o.light_samples, .spec = spec_mode(c), .rgb = rgb,
                   .spec_img = o.specular};
  gi__parallel_for((size_t)k.h, 1, o.threads, render_rows, &rc);
  if (st) {
    memset(st, 0, sizeof *st);
    st->ms = gi__now_ms() - t0;
    st->diffuse_cones = atomic_load(&rc.diffuse_cones);
    st->specular_cones = atomic_load(&rc.specular_cones);
    gi_cascade_view_plan(c, st->effects);
  }
  for (size_t i = 0; i < np; i++)
    if (!isfinite(rgb[i]) || (o.specular && !isfinite(o.specular[i])))
      return gi__fail(err, GI_ERR_NONFINITE, "render: pixel %zu is not finite", i / 3);
  return GI_OK;
}

gi_result gi_cascade_render(const gi_cascade *c, const gi_camera *cam, int light_samples, int threads, float *rgb,
                            double *ms, gi_error_info *err) {
  gi_render_opts o = {.light_samples = light_samples, .threads = threads};
  gi_render_stats st;
  gi_result r = gi_cascade_render_ex(c, cam, &o, rgb, &st, err);
  if (ms) *ms = r == GI_OK ? st.ms : 0;
  return r;
}
