/* mitsuba_sensor.c: the camera of a Mitsuba scene file, in the syntax of
 * Mitsuba 0.6 (toWorld, lookAt, fovAxis) and of Mitsuba 3 (to_world,
 * lookat, fov_axis).
 *
 * Only the first perspective sensor is read: its to_world transform (any
 * sequence of matrix, lookat, translate, rotate and scale, composed as
 * Mitsuba composes them), its field of view (fov and fov_axis, or
 * focal_length) and its film's size, with "$name" values taken from the
 * file's <default> elements. Published scenes write their cameras every one
 * of these ways (a lookat in Mitsuba's own Cornell box, a matrix in most
 * scenes exported from other tools), and a fov along x on a wide film is a
 * narrower view than the same number across the smaller side. The reader
 * is a small tag scanner rather than an XML library: it needs a dozen tag
 * kinds, and a malformed file elsewhere (a BSDF we never read) must not
 * stop the camera from being read. */
#include <ctype.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "base/internal.h"
#include "gi/gi_camera.h"
#include "io/texture_image.h"

#define MX_MAX_FILE (64u << 20) /* larger is not a scene description we can scan in memory */
#define MX_MAX_DEFAULTS 256
#define MX_VALUE 1024 /* longest attribute value read (a matrix is 16 numbers) */
#define MX_FILM_W 768 /* Mitsuba's film size when the file gives none */
#define MX_FILM_H 576

typedef struct {
  char name[64];
  char value[MX_VALUE];
} mx_default;

typedef struct {
  const char *buf, *path;
  mx_default *defs;
  int ndefs;
  gi_error_info *err;
} mx_file;

/* One tag: <name attrs>, <name attrs/> or </name>. */
typedef struct {
  char name[32];
  const char *attrs, *attrs_end, *at;
  int closing, empty;
} mx_tag;

static int line_of(const mx_file *f, const char *at) {
  int line = 1;
  for (const char *p = f->buf; p < at; p++) line += *p == '\n';
  return line;
}

/* Fails naming the file and the line of `at`. */
static gi_result mx_fail(const mx_file *f, const char *at, const char *fmt, const char *a, const char *b) {
  char what[512];
  snprintf(what, sizeof what, fmt, a ? a : "", b ? b : "");
  return gi__fail(f->err, GI_ERR_FORMAT, "camera: %s line %d: %s", f->path, line_of(f, at), what);
}

/* The next tag from *p (comments, processing instructions, doctype and
 * text skipped): 1, or 0 at the end. An unterminated tag ends the scan. */
static int next_tag(const char **p, mx_tag *t) {
  const char *s = *p;
  for (;;) {
    s = strchr(s, '<');
    if (!s) return 0;
    const char *close = NULL;
    if (!strncmp(s, "<!--", 4)) close = strstr(s + 4, "-->");
    else if (!strncmp(s, "<![CDATA[", 9)) close = strstr(s + 9, "]]>");
    else if (s[1] == '?') close = strstr(s + 2, "?>");
    else if (s[1] == '!') close = strchr(s, '>');
    else break;
    if (!close) return 0;
    s = close + 1;
  }
  t->at = s++;
  t->closing = *s == '/';
  if (t->closing) s++;
  size_t n = 0;
  while (*s && (isalnum((unsigned char)*s) || *s == '_' || *s == ':' || *s == '-')) {
    if (n + 1 < sizeof t->name) t->name[n++] = *s;
    s++;
  }
  t->name[n] = '\0';
  t->attrs = s;
  char quote = 0;
  for (; *s && (quote || *s != '>'); s++)
    if (quote ? *s == quote : (*s == '"' || *s == '\'')) quote = quote ? 0 : *s;
  if (!*s) return 0;
  t->attrs_end = s;
  t->empty = s > t->attrs && s[-1] == '/';
  *p = s + 1;
  return 1;
}

/* The raw value of attribute `name` of tag t: 1, or 0 when absent or too long. */
static int raw_attr(const mx_tag *t, const char *name, char *out, size_t n) {
  size_t ln = strlen(name);
  const char *e = t->attrs_end;
  for (const char *p = t->attrs; p + ln < e; p++) {
    if (strncmp(p, name, ln) || !isspace((unsigned char)p[-1])) continue;
    const char *q = p + ln;
    while (q < e && isspace((unsigned char)*q)) q++;
    if (q >= e || *q != '=') continue;
    for (q++; q < e && isspace((unsigned char)*q);) q++;
    if (q >= e || (*q != '"' && *q != '\'')) continue;
    const char *end = memchr(q + 1, *q, (size_t)(e - q - 1));
    if (!end || (size_t)(end - q - 1) >= n) return 0;
    memcpy(out, q + 1, (size_t)(end - q - 1));
    out[end - q - 1] = '\0';
    return 1;
  }
  return 0;
}

/* Attribute `name` with each $param replaced by its <default>: 1 when
 * present, 0 when absent, -1 (failed) for an unknown or overlong one. */
static int attr(const mx_file *f, const mx_tag *t, const char *name, char *out, size_t n) {
  char raw[MX_VALUE];
  if (!raw_attr(t, name, raw, sizeof raw)) return 0;
  size_t o = 0;
  for (const char *s = raw; *s;) {
    const char *val = NULL;
    char pname[64];
    size_t pn = 0;
    if (*s == '$') {
      while (pn + 1 < sizeof pname && (isalnum((unsigned char)s[1 + pn]) || s[1 + pn] == '_'))
        pname[pn] = s[1 + pn], pn++;
      pname[pn] = '\0';
      for (int i = 0; i < f->ndefs && pn; i++)
        if (!strcmp(f->defs[i].name, pname)) val = f->defs[i].value;
      if (!val) {
        mx_fail(f, t->at, "attribute '%s' uses $%s, which no <default> defines", name, pname);
        return -1;
      }
    }
    size_t len = val ? strlen(val) : 1;
    if (o + len >= n) {
      mx_fail(f, t->at, "attribute '%s' is too long%s", name, NULL);
      return -1;
    }
    memcpy(out + o, val ? val : s, len);
    o += len;
    s += val ? pn + 1 : 1;
  }
  out[o] = '\0';
  return 1;
}

/* Reads n numbers separated by blanks or commas, nothing after them. */
static int numbers(const char *s, double *v, int n) {
  char *end;
  for (int k = 0; k < n; k++) {
    while (*s == ',' || isspace((unsigned char)*s)) s++;
    v[k] = strtod(s, &end);
    if (end == s || !isfinite(v[k])) return 0;
    s = end;
  }
  while (*s == ',' || isspace((unsigned char)*s)) s++;
  return *s == '\0';
}

/* Numeric attribute `name` of n numbers: 1, 0 when absent, -1 (failed)
 * when it is not n finite numbers. */
static int num_attr(const mx_file *f, const mx_tag *t, const char *name, double *v, int n) {
  char s[MX_VALUE];
  int r = attr(f, t, name, s, sizeof s);
  if (r <= 0) return r;
  if (numbers(s, v, n)) return 1;
  char want[32];
  snprintf(want, sizeof want, n == 1 ? "a number" : "%d numbers", n);
  mx_fail(f, t->at, "attribute '%s' is not %s", name, want);
  return -1;
}

static int tag_is(const mx_tag *t, const char *a, const char *b) {
  return !strcmp(t->name, a) || (b && !strcmp(t->name, b));
}

/* Every <default name value/> of the file, for $name values. */
static gi_result read_defaults(mx_file *f) {
  const char *p = f->buf;
  mx_tag t;
  while (next_tag(&p, &t)) {
    if (t.closing || strcmp(t.name, "default")) continue;
    if (f->ndefs == MX_MAX_DEFAULTS) return mx_fail(f, t.at, "more than 256 <default> elements%s%s", NULL, NULL);
    mx_default *d = &f->defs[f->ndefs];
    if (!raw_attr(&t, "name", d->name, sizeof d->name) || !raw_attr(&t, "value", d->value, sizeof d->value))
      return mx_fail(f, t.at, "<default> needs a name and a value%s%s", NULL, NULL);
    /* The first definition stands, as in Mitsuba (later ones are ignored). */
    int dup = 0;
    for (int i = 0; i < f->ndefs; i++) dup |= !strcmp(f->defs[i].name, d->name);
    if (!dup) f->ndefs++;
  }
  return GI_OK;
}

/* ---- the to_world transform ------------------------------------------ */

typedef double mx_mat[4][4]; /* row-major: m[row][column], columns act on (x, y, z, 1) */

/* m = t * m: each element applies after the ones before it. */
static void mat_then(mx_mat m, const mx_mat t) {
  mx_mat r;
  for (int i = 0; i < 4; i++)
    for (int j = 0; j < 4; j++) r[i][j] = t[i][0] * m[0][j] + t[i][1] * m[1][j] + t[i][2] * m[2][j] + t[i][3] * m[3][j];
  memcpy(m, r, sizeof r);
}

static void mat_identity(mx_mat m) {
  memset(m, 0, sizeof(mx_mat));
  for (int i = 0; i < 4; i++) m[i][i] = 1;
}

static double norm3(double v[3]) {
  double l = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
  if (l > 0)
    for (int k = 0; k < 3; k++) v[k] /= l;
  return l;
}

/* Mitsuba's look_at: columns left = up x dir, up' = dir x left, dir, origin. */
static int lookat_matrix(const double o[3], const double tg[3], const double up[3], mx_mat m) {
  double dir[3] = {tg[0] - o[0], tg[1] - o[1], tg[2] - o[2]}, left[3], nu[3];
  if (!(norm3(dir) > 0)) return 0;
  gi__cross_d(up, dir, left);
  if (!(norm3(left) > 0)) return 0;
  gi__cross_d(dir, left, nu);
  mat_identity(m);
  for (int k = 0; k < 3; k++) m[k][0] = left[k], m[k][1] = nu[k], m[k][2] = dir[k], m[k][3] = o[k];
  return 1;
}

/* A vector from value="x y z" or from attributes x, y, z (each defaulting to d). */
static int xyz_attr(const mx_file *f, const mx_tag *t, double d, double v[3]) {
  int r = num_attr(f, t, "value", v, 3);
  if (r != 0) return r;
  static const char *const xyz[3] = {"x", "y", "z"};
  for (int k = 0; k < 3; k++) {
    v[k] = d;
    if (num_attr(f, t, xyz[k], &v[k], 1) < 0) return -1;
  }
  return 1;
}

/* Rotation by `deg` degrees about axis a (right-handed), Rodrigues. */
static int rotate_matrix(double a[3], double deg, mx_mat m) {
  if (!(norm3(a) > 0)) return 0;
  double th = deg * 3.14159265358979323846 / 180.0, c = cos(th), s = sin(th), k = 1 - c;
  mat_identity(m);
  m[0][0] = c + k * a[0] * a[0], m[0][1] = k * a[0] * a[1] - s * a[2], m[0][2] = k * a[0] * a[2] + s * a[1];
  m[1][0] = k * a[1] * a[0] + s * a[2], m[1][1] = c + k * a[1] * a[1], m[1][2] = k * a[1] * a[2] - s * a[0];
  m[2][0] = k * a[2] * a[0] - s * a[1], m[2][1] = k * a[2] * a[1] + s * a[0], m[2][2] = c + k * a[2] * a[2];
  return 1;
}

/* The lookat's own three vectors, kept so a plain lookat reads back as written. */
typedef struct {
  mx_mat m;
  int elements, lookat_only;
  double eye[3], target[3], up[3];
} mx_xform;

/* One element inside <transform name="to_world">, applied after the others. */
static gi_result xform_element(const mx_file *f, const mx_tag *t, mx_xform *x) {
  mx_mat e;
  double v[16], ang = 0;
  int r = 0;
  mat_identity(e);
  if (tag_is(t, "matrix", NULL)) {
    if ((r = num_attr(f, t, "value", v, 16)) == 0) return mx_fail(f, t->at, "<matrix> has no value%s%s", NULL, NULL);
    for (int i = 0; i < 16; i++) e[i / 4][i % 4] = v[i];
  } else if (tag_is(t, "lookat", "lookAt")) {
    static const char *const names[3] = {"origin", "target", "up"};
    double *dst[3] = {x->eye, x->target, x->up};
    for (int i = 0; i < 3 && r >= 0; i++)
      if ((r = num_attr(f, t, names[i], dst[i], 3)) == 0)
        return mx_fail(f, t->at, "<%s> has no '%s' (three numbers)", t->name, names[i]);
    if (r > 0 && !lookat_matrix(x->eye, x->target, x->up, e))
      return mx_fail(f, t->at, "<%s>: origin and target are the same point, or up is along the view%s", t->name, NULL);
    x->lookat_only = x->elements == 0;
  } else if (tag_is(t, "translate", NULL)) {
    if ((r = xyz_attr(f, t, 0, v)) > 0)
      for (int k = 0; k < 3; k++) e[k][3] = v[k];
  } else if (tag_is(t, "scale", NULL)) {
    char s[MX_VALUE];
    /* value="s" (uniform), value="x y z", or attributes x, y, z. */
    if ((r = attr(f, t, "value", s, sizeof s)) == 0) r = xyz_attr(f, t, 1, v);
    else if (r > 0 && numbers(s, v, 1)) v[1] = v[2] = v[0];
    else if (r > 0 && !numbers(s, v, 3))
      return mx_fail(f, t->at, "<scale> value '%.64s' is not one number or three%s", s, NULL);
    if (r > 0)
      for (int k = 0; k < 3; k++) e[k][k] = v[k];
  } else if (tag_is(t, "rotate", NULL)) {
    if ((r = xyz_attr(f, t, 0, v)) > 0 && (r = num_attr(f, t, "angle", &ang, 1)) == 0)
      return mx_fail(f, t->at, "<rotate> has no angle%s%s", NULL, NULL);
    if (r > 0 && !rotate_matrix(v, ang, e)) return mx_fail(f, t->at, "<rotate> has a zero axis%s%s", NULL, NULL);
  } else {
    return mx_fail(f, t->at, "<%s> inside the sensor's transform: expected matrix, lookat, translate, rotate or scale",
                   t->name, NULL);
  }
  if (r < 0) return GI_ERR_FORMAT;
  if (!tag_is(t, "lookat", "lookAt")) x->lookat_only = 0;
  mat_then(x->m, e);
  x->elements++;
  return GI_OK;
}

/* ---- the sensor ------------------------------------------------------- */

typedef struct {
  mx_xform x;
  char fov[MX_VALUE], axis[32], focal[64];
  const char *fov_at;
  int width, height;
} mx_sensor;

/* A <float|string|integer name=... value=...> of the sensor or its film. */
static gi_result property(const mx_file *f, const mx_tag *t, int in_film, mx_sensor *ms) {
  char name[64];
  if (!raw_attr(t, "name", name, sizeof name)) return GI_OK;
  char *dst = NULL;
  size_t n = 0;
  if (in_film && (!strcmp(name, "width") || !strcmp(name, "height"))) {
    double v;
    int r = num_attr(f, t, "value", &v, 1);
    if (r == 0 || (r > 0 && !(v >= 1 && v <= 65536 && v == floor(v))))
      return mx_fail(f, t->at, "film %s must be a whole number of pixels in 1..65536", name, NULL);
    if (r < 0) return GI_ERR_FORMAT;
    *(name[0] == 'w' ? &ms->width : &ms->height) = (int)v;
    return GI_OK;
  }
  if (in_film) return GI_OK;
  if (!strcmp(name, "fov")) dst = ms->fov, n = sizeof ms->fov, ms->fov_at = t->at;
  else if (!strcmp(name, "fov_axis") || !strcmp(name, "fovAxis")) dst = ms->axis, n = sizeof ms->axis;
  else if (!strcmp(name, "focal_length") || !strcmp(name, "focalLength")) dst = ms->focal, n = sizeof ms->focal;
  if (!dst) return GI_OK;
  int r = attr(f, t, "value", dst, n);
  if (r == 0) return mx_fail(f, t->at, "sensor field '%s' has no value%s", name, NULL);
  if (dst == ms->axis) /* Mitsuba compares it in lower case */
    for (char *c = dst; *c; c++) *c = (char)tolower((unsigned char)*c);
  return r < 0 ? GI_ERR_FORMAT : GI_OK;
}

/* Reads the first perspective sensor into ms. */
static gi_result read_sensor(const mx_file *f, mx_sensor *ms) {
  const char *p = f->buf;
  mx_tag t;
  int depth = 0, sensor = -1, xform = -1, film = -1;
  while (next_tag(&p, &t)) {
    if (t.closing) {
      depth--;
      if (sensor >= 0 && depth == sensor) return GI_OK;
      if (depth == xform) xform = -1;
      if (depth == film) film = -1;
      continue;
    }
    gi_result rc = GI_OK;
    if (sensor < 0 && tag_is(&t, "sensor", NULL)) {
      char type[64] = "";
      raw_attr(&t, "type", type, sizeof type);
      if (strcmp(type, "perspective"))
        return mx_fail(f, t.at, "the sensor is '%s'; only a 'perspective' sensor can be read (or give the camera as "
                       "X,Y,Z,TX,TY,TZ,FOV,W,H)", type, NULL);
      if (t.empty) return GI_OK;
      sensor = depth;
    } else if (sensor >= 0 && xform >= 0 && depth == xform + 1) {
      rc = xform_element(f, &t, &ms->x);
    } else if (sensor >= 0 && depth == sensor + 1 && tag_is(&t, "transform", NULL)) {
      char name[64] = "";
      raw_attr(&t, "name", name, sizeof name);
      if (!strcmp(name, "to_world") || !strcmp(name, "toWorld")) xform = depth;
    } else if (sensor >= 0 && depth == sensor + 1 && tag_is(&t, "film", NULL)) {
      film = depth;
    } else if (sensor >= 0 && (depth == sensor + 1 || (film >= 0 && depth == film + 1)) &&
               (tag_is(&t, "float", "string") || tag_is(&t, "integer", NULL))) {
      rc = property(f, &t, film >= 0 && depth == film + 1, ms);
    }
    if (rc != GI_OK) return rc;
    if (!t.empty) depth++;
  }
  if (sensor < 0) return gi__fail(f->err, GI_ERR_FORMAT, "camera: %s has no <sensor> element", f->path);
  return gi__fail(f->err, GI_ERR_FORMAT, "camera: %s: the <sensor> element is not closed", f->path);
}

/* The field of view in degrees across the film's smaller side (what
 * gi_camera holds), from fov and fov_axis (Mitsuba's default axis: x) or
 * a 35 mm focal length (along the diagonal, Mitsuba's default 50mm); 0
 * after a failure. A fov already along the smaller side is kept as written. */
static gi_result smaller_fov(const mx_file *f, const mx_sensor *ms, double *out) {
  double aspect = (double)ms->width / ms->height, fov, t;
  const char *axis = ms->axis[0] ? ms->axis : "x";
  if (ms->fov[0] && ms->focal[0]) return mx_fail(f, ms->fov_at, "the sensor gives both fov and focal_length%s%s", NULL, NULL);
  if (ms->fov[0]) {
    if (!numbers(ms->fov, &fov, 1) || !(fov > 0 && fov < 180))
      return mx_fail(f, ms->fov_at, "sensor field 'fov' must be a number of degrees in (0, 180), got '%.64s'", ms->fov, NULL);
  } else {
    char mm[64];
    snprintf(mm, sizeof mm, "%s", ms->focal[0] ? ms->focal : "50mm");
    size_t n = strlen(mm);
    if (n > 2 && !strcmp(mm + n - 2, "mm")) mm[n - 2] = '\0';
    double fl;
    if (!numbers(mm, &fl, 1) || !(fl > 0))
      return gi__fail(f->err, GI_ERR_FORMAT, "camera: %s: focal_length must be a length like '50mm', got '%s'", f->path,
                      ms->focal);
    fov = 2 * atan(sqrt(36.0 * 36.0 + 24.0 * 24.0) / (2 * fl)) * 180 / 3.14159265358979323846;
    axis = "diagonal";
  }
  t = tan(0.5 * fov * 3.14159265358979323846 / 180);
  if (!strcmp(axis, "smaller")) axis = aspect > 1 ? "y" : "x";
  else if (!strcmp(axis, "larger")) axis = aspect > 1 ? "x" : "y";
  *out = fov;
  if ((!strcmp(axis, "x") && aspect <= 1) || (!strcmp(axis, "y") && aspect >= 1)) return GI_OK;
  double tx;
  if (!strcmp(axis, "x")) tx = t;
  else if (!strcmp(axis, "y")) tx = t * aspect;
  else if (!strcmp(axis, "diagonal")) tx = t / sqrt(1 + 1 / (aspect * aspect));
  else
    return gi__fail(f->err, GI_ERR_FORMAT, "camera: %s: fov_axis must be x, y, smaller, larger or diagonal, got '%s'",
                    f->path, axis);
  *out = 2 * atan(aspect > 1 ? tx / aspect : tx) * 180 / 3.14159265358979323846;
  return GI_OK;
}

/* The camera from the composed transform: eye at its origin, looking
 * along its z axis with its y axis up (Mitsuba's camera space). Its x
 * axis is the image's left; a transform that mirrors it cannot be drawn
 * by gi_camera (right = forward x up), so it fails rather than flip the
 * picture. */
static gi_result camera_from(const mx_file *f, const mx_xform *x, gi_camera *cam) {
  if (x->lookat_only) {
    memcpy(cam->eye, x->eye, sizeof cam->eye), memcpy(cam->target, x->target, sizeof cam->target);
    memcpy(cam->up, x->up, sizeof cam->up);
    return GI_OK;
  }
  double left[3], up[3], fwd[3], c[3];
  for (int k = 0; k < 3; k++) left[k] = x->m[k][0], up[k] = x->m[k][1], fwd[k] = x->m[k][2];
  int ok = norm3(left) > 0 && norm3(up) > 0 && norm3(fwd) > 0 && isfinite(x->m[3][3]);
  for (int k = 0; k < 3; k++) ok &= isfinite(x->m[k][3]) && x->m[3][k] == 0;
  if (!ok || x->m[3][3] != 1)
    return gi__fail(f->err, GI_ERR_FORMAT, "camera: %s: the sensor's to_world transform is not an affine camera "
                    "placement (a zero axis or a projective row)", f->path);
  gi__cross_d(up, fwd, c);
  if (c[0] * left[0] + c[1] * left[1] + c[2] * left[2] < 0)
    return gi__fail(f->err, GI_ERR_FORMAT, "camera: %s: the sensor's to_world transform mirrors the image (a "
                    "negative scale); give the camera as X,Y,Z,TX,TY,TZ,FOV,W,H instead", f->path);
  for (int k = 0; k < 3; k++) cam->eye[k] = x->m[k][3], cam->target[k] = x->m[k][3] + fwd[k], cam->up[k] = up[k];
  return GI_OK;
}

gi_result gi_camera_from_mitsuba(const char *path, gi_camera *cam, gi_error_info *err) {
  if (!path || !cam)
    return gi__fail(err, GI_ERR_INVALID_ARG, "gi_camera_from_mitsuba: %s is NULL", path ? "cam" : "path");
  void *data = NULL;
  size_t size = 0;
  gi_error_info re = {0};
  gi_result rc = gi__read_file(path, MX_MAX_FILE, &data, &size, &re);
  if (rc != GI_OK) return gi__fail(err, rc, "camera: %s", re.msg);
  char *buf = gi__realloc(data, size + 1);
  mx_default *defs = gi__malloc(MX_MAX_DEFAULTS * sizeof *defs);
  mx_sensor *ms = gi__calloc(1, sizeof *ms);
  if (!buf || !defs || !ms) {
    gi__free(buf ? buf : data), gi__free(defs), gi__free(ms);
    return gi__fail(err, GI_ERR_NOMEM, "camera: out of memory reading %s", path);
  }
  buf[size] = '\0';
  /* A NUL inside the file ends the scan there: say so rather than read half. */
  mx_file f = {.buf = buf, .path = path, .defs = defs, .err = err};
  if (strlen(buf) != size) rc = gi__fail(err, GI_ERR_FORMAT, "camera: %s is not a text file (a NUL byte)", path);
  if (rc == GI_OK) rc = read_defaults(&f);
  mat_identity(ms->x.m);
  ms->width = MX_FILM_W, ms->height = MX_FILM_H;
  if (rc == GI_OK) rc = read_sensor(&f, ms);
  double fov = 0;
  if (rc == GI_OK) rc = smaller_fov(&f, ms, &fov);
  if (rc == GI_OK) rc = camera_from(&f, &ms->x, cam);
  if (rc == GI_OK) cam->fov_deg = fov, cam->width = ms->width, cam->height = ms->height;
  gi__free(buf), gi__free(defs), gi__free(ms);
  return rc;
}

void gi_camera_fit(gi_camera *cam, int longest) {
  if (!cam || longest < 1 || cam->width < 1 || cam->height < 1) return;
  int w = cam->width, h = cam->height;
  double s = (double)longest / (w > h ? w : h);
  cam->width = w >= h ? longest : (int)fmax(1, floor(w * s + 0.5));
  cam->height = h >= w ? longest : (int)fmax(1, floor(h * s + 0.5));
}
