/* request.c: requests in, validated structs out.
 *
 * Strict on purpose: an unknown or repeated parameter, an integer knob not
 * written as plain digits (64.0, 6.4e1 and 032 are refused), a number that is
 * not a finite decimal, a value out of range ("out of range" when it is finite
 * but too large), or an empty or repeated effect is a 400 that names it,
 * before any work is queued. Quality knobs map onto gi_quality with zero meaning
 * "the core's default", so the core resolves defaults in one place and
 * checks them again (it trusts no caller). A preset (quality=low|default|
 * high) sets several knobs; explicit knobs override it whatever the order. */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <float.h>
#include <jansson.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "gi_proto.h"

void gi_proto_limits_default(gi_proto_limits *l) {
  l->max_levels = 8;
  l->max_res = 64;
  l->max_panorama_pixels = 1 << 20;
  l->max_probes_inline = 1024;
  l->max_probes_job = 1000000;
  l->max_body_bytes = 1 << 20;
}

/* Whether s is a plain decimal number: strtod alone would also take "nan",
 * "inf" and hex. */
static int plain_decimal(const char *s, size_t n) {
  if (n == 0) return 0;
  for (size_t i = 0; i < n; i++)
    if (!strchr("0123456789+-.eE", s[i])) return 0;
  return 1;
}

/* One number of s up to `stop` (',' or NUL): 0, or -1 malformed, -2 out of range. */
static int parse_real(const char *s, char stop, double abs_max, double *out, const char **end_out) {
  size_t n = strcspn(s, stop ? "," : "");
  if (!plain_decimal(s, n)) return -1;
  char *end;
  errno = 0;
  double v = strtod(s, &end);
  if (end != s + n) return -1;
  /* ERANGE with |v| < 1 is underflow: a number within 1e-308 of 0, which it is
   * (0 or subnormal). ERANGE otherwise is overflow: out of range. */
  if ((errno == ERANGE && fabs(v) >= 1.0) || !isfinite(v) || fabs(v) > abs_max) return -2;
  *out = v;
  *end_out = end;
  return 0;
}

int gi_proto_parse_vec3(const char *s, double out[3]) {
  const char *p = s;
  for (int i = 0; i < 3; i++) {
    const char *end;
    int rc = parse_real(p, ',', GI_PROTO_MAX_COORD, &out[i], &end);
    if (rc) return rc;
    if (i < 2) {
      if (*end != ',') return -1;
      p = end + 1;
    } else if (*end) {
      return -1;
    }
  }
  return 0;
}

/* A plain decimal number: all of s. 0, -1 malformed, -2 out of range. */
static int parse_num(const char *s, double *out) {
  const char *end;
  int rc = parse_real(s, 0, DBL_MAX, out, &end);
  return rc ? rc : (*end ? -1 : 0);
}

/* An integer: an optional '-' and decimal digits, no leading zeros (so
 * "032", "64.0", "6.4e1" and "1e0" are refused: the contract says integer).
 * 0, -1 malformed, -3 leading zero; beyond long long it saturates, which
 * every range check then refuses as out of range. */
static int parse_int(const char *s, long long *out) {
  const char *d = s + (*s == '-');
  if (!*d) return -1;
  for (const char *q = d; *q; q++)
    if (*q < '0' || *q > '9') return -1;
  if (d[0] == '0' && d[1]) return -3;
  errno = 0;
  long long v = strtoll(s, NULL, 10);
  *out = v; /* ERANGE: LLONG_MIN or LLONG_MAX, out of every range */
  return 0;
}

/* The parameters a request kind accepts. */
enum {
  P_AT = 1 << 0, P_KIND = 1 << 1, P_QUALITY = 1 << 2, P_HALF = 1 << 3, P_PANO = 1 << 4, P_FACES = 1 << 5,
  P_LM = 1 << 6,       /* kind=lightmap: region, texel, atlas */
  P_REDIRECT = 1 << 7, /* viewpoint URLs: 307 to the cell's URL, or serve it */
  P_CELLQ = 1 << 8,    /* cell URLs: the quality hash */
  P_AT_OPT = 1 << 9    /* 'at' allowed but not required (a session's start) */
};

typedef struct {
  const char *key;
  int group;
} param_def;

static const param_def params[] = {
    {"at", P_AT},           {"kind", P_KIND},      {"quality", P_QUALITY}, {"levels", P_QUALITY},
    {"res", P_QUALITY},     {"voxel", P_QUALITY},  {"cones", P_QUALITY},   {"aperture", P_QUALITY},
    {"step", P_QUALITY},    {"bounces", P_QUALITY}, {"samples", P_QUALITY}, {"probe_samples", P_QUALITY},
    {"ao", P_QUALITY},      {"seed", P_QUALITY},   {"effects", P_QUALITY},   {"half", P_HALF},       {"width", P_PANO},
    {"height", P_PANO},     {"faces", P_FACES},        {"region", P_LM},       {"texel", P_LM},
    {"atlas", P_LM},        {"redirect", P_REDIRECT}, {"q", P_CELLQ},
};

/* Applies a preset. low: a quick preview (one bounce); high: more cones
 * and samples, a shorter step, at the same memory (R stays 32 so a
 * request's cost stays bounded), and the bounces the plan's albedo rule
 * gives, with its tail: a fixed count drops the tail, and 3 read a bright
 * room (albedo 0.95) at a fifth of the default's indirect light. */
static int set_preset(gi_quality *q, const char *v, gi_proto_error *err, const char *where) {
  if (!strcmp(v, "default")) return 0;
  if (!strcmp(v, "low")) {
    q->levels = 5, q->res = 16, q->cones = 6, q->bounces = 1, q->light_samples = 8, q->probe_samples = 64;
    return 0;
  }
  if (!strcmp(v, "high")) {
    q->cones = 32, q->light_samples = 64, q->probe_samples = 1024, q->step = 0.35f;
    return 0;
  }
  return gi_proto_fail(err, 400, "%s: expected low, default or high, got '%s'", where, v);
}

/* Whether key is a knob the contract says is an integer. */
static int is_int_knob(const char *key) {
  static const char *const ints[] = {"levels", "res", "cones", "bounces", "samples", "probe_samples", "seed",
                                     "ao", "width", "height"};
  for (size_t i = 0; i < sizeof ints / sizeof ints[0]; i++)
    if (!strcmp(key, ints[i])) return 1;
  return 0;
}

/* Sets one real-valued quality knob; `where` names it in errors. */
static int set_real_knob(gi_quality *q, const char *key, double v, gi_proto_error *err, const char *where) {
  if (!strcmp(key, "voxel")) {
    if (!(v > 0) || v > 1e7)
      return gi_proto_fail(err, 400, "%s: expected a voxel size in (0, 1e7], got %g (out of range)", where, v);
    q->voxel0 = v;
  } else if (!strcmp(key, "aperture")) {
    if (!(v >= 1 && v <= 120))
      return gi_proto_fail(err, 400, "%s: expected degrees in 1..120, got %g (out of range)", where, v);
    q->aperture_deg = (float)v;
  } else if (!strcmp(key, "step")) {
    if (!(v >= 0.05 && v <= 4)) return gi_proto_fail(err, 400, "%s: expected 0.05..4, got %g (out of range)", where, v);
    q->step = (float)v;
  } else {
    return gi_proto_fail(err, 400, "%s: unknown quality knob", where);
  }
  return 0;
}

/* Sets one integer quality knob; `text` is the value as the client wrote it. */
static int set_int_knob(gi_quality *q, const char *key, long long i, const char *text, const gi_proto_limits *lim,
                        gi_proto_error *err, const char *where) {
  if (!strcmp(key, "levels")) {
    if (i < 1 || i > lim->max_levels)
      return gi_proto_fail(err, 400, "%s: expected 1..%d (server limit), got %.40s (out of range)", where,
                           lim->max_levels, text);
    q->levels = (int)i;
  } else if (!strcmp(key, "res")) {
    if (i < 8 || i > lim->max_res || i % 4)
      return gi_proto_fail(err, 400, "%s: expected a multiple of 4 in 8..%d (server limit), got %.40s%s", where,
                           lim->max_res, text, i < 8 || i > lim->max_res ? " (out of range)" : "");
    q->res = (int)i;
  } else if (!strcmp(key, "cones")) {
    if (i != 4 && i != 6 && i != 8 && i != 16 && i != 32)
      return gi_proto_fail(err, 400, "%s: expected 4, 6, 8, 16 or 32, got %.40s", where, text);
    q->cones = (int)i;
  } else if (!strcmp(key, "bounces")) {
    if (i < 0 || i > 8) return gi_proto_fail(err, 400, "%s: expected 0..8, got %.40s (out of range)", where, text);
    q->bounces = i == 0 ? -1 : (int)i; /* the core's 0 means "default" */
  } else if (!strcmp(key, "samples")) {
    if (i < 1 || i > 512) return gi_proto_fail(err, 400, "%s: expected 1..512, got %.40s (out of range)", where, text);
    q->light_samples = (int)i;
  } else if (!strcmp(key, "probe_samples")) {
    if (i < 1 || i > 8192)
      return gi_proto_fail(err, 400, "%s: expected 1..8192, got %.40s (out of range)", where, text);
    q->probe_samples = (int)i;
  } else if (!strcmp(key, "seed")) {
    if (i < 1 || i > (1ll << 53))
      return gi_proto_fail(err, 400, "%s: expected 1..2^53, got %.40s (out of range)", where, text);
    q->seed = (uint64_t)i;
  } else if (!strcmp(key, "ao")) {
    if (i != 0 && i != 1) return gi_proto_fail(err, 400, "%s: expected 0 or 1, got %.40s", where, text);
    q->ao = (int)i;
  } else {
    return gi_proto_fail(err, 400, "%s: unknown quality knob", where);
  }
  return 0;
}

/* "sky:off,specular:on": per-effect overrides of the effect plan. Every
 * entry is NAME:MODE; an empty entry or an effect named twice is refused
 * (which of two contradicting modes would win is not the client's guess). */
static int set_effects(gi_quality *q, const char *v, gi_proto_error *err, const char *where) {
  enum { MAX_ENTRY = 64 };
  int seen[GI_FX_COUNT] = {0};
  for (const char *p = v;; p++) {
    size_t n = strcspn(p, ",");
    if (n == 0)
      return gi_proto_fail(err, 400, "%s: empty entry (expected NAME:on|off|auto[,...]), got '%.64s'", where, v);
    char tok[MAX_ENTRY];
    if (n >= sizeof tok) return gi_proto_fail(err, 400, "%s: entry too long in '%.64s'", where, v);
    memcpy(tok, p, n);
    tok[n] = 0;
    char *colon = strchr(tok, ':');
    if (!colon) return gi_proto_fail(err, 400, "%s: expected NAME:on|off|auto[,...], got '%.64s'", where, tok);
    *colon = 0;
    int id = gi_effect_from_name(tok);
    if (id < 0)
      return gi_proto_fail(err, 400, "%s: unknown effect '%.32s' (sun, local_lights, sky, emissive, bounce, specular, ao)",
                           where, tok);
    if (seen[id]++) return gi_proto_fail(err, 400, "%s: effect '%s' given twice", where, tok);
    const char *m = colon + 1;
    if (!strcmp(m, "on")) q->effects[id] = GI_FX_ON;
    else if (!strcmp(m, "off")) q->effects[id] = GI_FX_OFF;
    else if (!strcmp(m, "auto")) q->effects[id] = GI_FX_AUTO;
    else return gi_proto_fail(err, 400, "%s: expected on, off or auto after '%s:', got '%.32s'", where, tok, m);
    p += n;
    if (!*p) return 0;
  }
}

static int parse_flag(const char *v, int *out, gi_proto_error *err, const char *key) {
  if (!strcmp(v, "1") || !strcmp(v, "true")) *out = 1;
  else if (!strcmp(v, "0") || !strcmp(v, "false")) *out = 0;
  else return gi_proto_fail(err, 400, "parameter '%s': expected 0 or 1, got '%s'", key, v);
  return 0;
}

/* A numeric parameter: integers must be written as integers. */
static int set_query_number(gi_proto_bake *out, const char *k, const char *v, const gi_proto_limits *lim,
                            gi_proto_error *err, const char *where) {
  if (!is_int_knob(k)) {
    double x;
    int rc = parse_num(v, &x);
    if (rc == -2) return gi_proto_fail(err, 400, "%s: '%.64s' is out of range", where, v);
    if (rc) return gi_proto_fail(err, 400, "%s: expected a finite number, got '%.64s'", where, v);
    return set_real_knob(&out->quality, k, x, err, where);
  }
  long long i;
  int rc = parse_int(v, &i);
  if (rc == -3) return gi_proto_fail(err, 400, "%s: expected an integer without leading zeros, got '%.64s'", where, v);
  if (rc) return gi_proto_fail(err, 400, "%s: expected an integer (decimal digits), got '%.64s'", where, v);
  if (strcmp(k, "width") && strcmp(k, "height")) return set_int_knob(&out->quality, k, i, v, lim, err, where);
  int w = !strcmp(k, "width"), max = w ? GI_PROTO_MAX_PANORAMA_WIDTH : GI_PROTO_MAX_PANORAMA_HEIGHT;
  /* A lat-long image needs two columns: the range said 1.. and width=1 was refused after all. */
  int min = w ? 2 : 1;
  if (i < min || i > max)
    return gi_proto_fail(err, 400, "%s: expected an integer in %d..%d, got '%.40s' (out of range)", where, min, max,
                         v);
  *(!strcmp(k, "width") ? &out->width : &out->height) = (int)i;
  return 0;
}

/* region=x0,y0,z0,x1,y1,z1, texel=S, atlas=N (kind=lightmap). */
static int set_lightmap_param(gi_proto_bake *out, const char *k, const char *v, gi_proto_error *err) {
  if (!strcmp(k, "atlas")) {
    long long i;
    if (parse_int(v, &i) || i < GI_PROTO_MIN_LIGHTMAP_ATLAS || i > GI_PROTO_MAX_LIGHTMAP_ATLAS)
      return gi_proto_fail(err, 400, "parameter 'atlas': expected an integer in %d..%d, got '%.64s'",
                           GI_PROTO_MIN_LIGHTMAP_ATLAS, GI_PROTO_MAX_LIGHTMAP_ATLAS, v);
    out->atlas = (int)i;
    return 0;
  }
  if (!strcmp(k, "texel")) {
    if (parse_num(v, &out->texel) || !(out->texel > 0))
      return gi_proto_fail(err, 400, "parameter 'texel': expected a finite size > 0, got '%.64s'", v);
    return 0;
  }
  char buf[260];
  snprintf(buf, sizeof buf, "%s", v);
  char *p = buf;
  for (int i = 0; i < 6; i++) {
    char *comma = strchr(p, ',');
    if ((comma != NULL) != (i < 5)) goto bad;
    if (comma) *comma = 0;
    if (parse_num(p, &out->region[i]) || fabs(out->region[i]) > GI_PROTO_MAX_COORD) goto bad;
    p = comma ? comma + 1 : p;
  }
  for (int k3 = 0; k3 < 3; k3++)
    if (!(out->region[k3] < out->region[3 + k3]))
      return gi_proto_fail(err, 400, "parameter 'region': min must be below max on every axis, got '%.64s'", v);
  out->has_region = 1;
  return 0;
bad:
  return gi_proto_fail(err, 400, "parameter 'region': expected six finite numbers x0,y0,z0,x1,y1,z1, got '%.64s'", v);
}

static int parse_query(const gi_proto_kv *kv, size_t n, int allowed, const gi_proto_limits *lim,
                       gi_proto_bake *out, gi_proto_error *err) {
  memset(out, 0, sizeof *out);
  out->width = 256;
  out->height = 128;
  out->redirect = 1;
  /* Reject unknown and repeated keys first, then apply the preset, then the knobs. */
  for (size_t i = 0; i < n; i++) {
    const char *k = kv[i].key ? kv[i].key : "";
    size_t j;
    for (j = 0; j < sizeof params / sizeof params[0]; j++)
      if (!strcmp(params[j].key, k)) break;
    if (j == sizeof params / sizeof params[0] || !(params[j].group & allowed))
      return gi_proto_fail(err, 400, "unknown parameter '%.64s'", k);
    for (size_t m = 0; m < i; m++)
      if (kv[m].key && !strcmp(kv[m].key, k)) return gi_proto_fail(err, 400, "parameter '%s' given twice", k);
    if (!kv[i].value || !*kv[i].value) return gi_proto_fail(err, 400, "parameter '%s' has no value", k);
    if (strlen(kv[i].value) > 256) return gi_proto_fail(err, 400, "parameter '%s' is too long", k);
  }
  for (size_t i = 0; i < n; i++)
    if (!strcmp(kv[i].key, "quality") && set_preset(&out->quality, kv[i].value, err, "parameter 'quality'"))
      return err->status;
  for (size_t i = 0; i < n; i++) {
    const char *k = kv[i].key, *v = kv[i].value;
    char where[64];
    snprintf(where, sizeof where, "parameter '%s'", k);
    if (!strcmp(k, "quality")) continue;
    if (!strcmp(k, "at")) {
      int rc = gi_proto_parse_vec3(v, out->at);
      if (rc == -2)
        return gi_proto_fail(err, 400, "parameter 'at': out of range: expected |x|, |y|, |z| <= %g, got '%.64s'",
                             GI_PROTO_MAX_COORD, v);
      if (rc) return gi_proto_fail(err, 400, "parameter 'at': expected three finite numbers x,y,z, got '%.64s'", v);
      out->has_at = 1;
    } else if (!strcmp(k, "kind")) {
      if (!strcmp(v, "probe")) out->kind = GI_PROTO_PROBE;
      else if (!strcmp(v, "panorama")) out->kind = GI_PROTO_PANORAMA;
      else if (!strcmp(v, "lightmap")) out->kind = GI_PROTO_LIGHTMAP;
      else return gi_proto_fail(err, 400, "parameter 'kind': expected probe, panorama or lightmap, got '%.64s'", v);
    } else if (!strcmp(k, "half") || !strcmp(k, "faces") || !strcmp(k, "redirect")) {
      int *flag = !strcmp(k, "half") ? &out->half : !strcmp(k, "faces") ? &out->faces : &out->redirect;
      if (parse_flag(v, flag, err, k)) return err->status;
    } else if (!strcmp(k, "q")) {
      size_t len = strlen(v);
      if (len != GI_PROTO_QHASH_LEN || strspn(v, "0123456789abcdef") != len)
        return gi_proto_fail(err, 400, "parameter 'q': expected %d lowercase hex digits, got '%.64s'",
                             GI_PROTO_QHASH_LEN, v);
      memcpy(out->q, v, len + 1);
    } else if (!strcmp(k, "effects")) {
      if (set_effects(&out->quality, v, err, where)) return err->status;
    } else if (!strcmp(k, "region") || !strcmp(k, "texel") || !strcmp(k, "atlas")) {
      if (set_lightmap_param(out, k, v, err)) return err->status;
    } else if (!strcmp(k, "ao")) {
      int f = 0;
      if (parse_flag(v, &f, err, k)) return err->status;
      out->quality.ao = f;
    } else if (set_query_number(out, k, v, lim, err, where)) {
      return err->status;
    }
  }
  if ((allowed & P_AT) && !(allowed & P_AT_OPT) && !out->has_at)
    return gi_proto_fail(err, 400, "parameter 'at' is required (x,y,z)");
  if ((allowed & P_CELLQ) && !out->q[0])
    return gi_proto_fail(err, 400, "parameter 'q' is required (the quality hash the redirect or the scene's grid gives)");
  return 0;
}

/* What a lighting request's kind allows, after its parameters parsed. */
static int check_lighting(const gi_proto_kv *kv, size_t n, const gi_proto_limits *lim, gi_proto_bake *out,
                          gi_proto_error *err) {
  if (out->kind != GI_PROTO_LIGHTMAP)
    for (size_t i = 0; i < n; i++)
      if (!strcmp(kv[i].key, "region") || !strcmp(kv[i].key, "texel") || !strcmp(kv[i].key, "atlas"))
        return gi_proto_fail(err, 400, "parameter '%s' applies to kind=lightmap only", kv[i].key);
  if (out->kind == GI_PROTO_PANORAMA) {
    if (out->width < 2) return gi_proto_fail(err, 400, "parameter 'width': a panorama needs at least 2 columns");
    if ((long long)out->width * out->height > lim->max_panorama_pixels)
      return gi_proto_fail(err, 400, "parameters 'width' x 'height': %d x %d exceeds the server limit of %lld pixels",
                           out->width, out->height, lim->max_panorama_pixels);
  } else {
    for (size_t i = 0; i < n; i++)
      if (!strcmp(kv[i].key, "width") || !strcmp(kv[i].key, "height"))
        return gi_proto_fail(err, 400, "parameter '%s' applies to kind=panorama only", kv[i].key);
  }
  return 0;
}

int gi_proto_parse_lighting(const gi_proto_kv *kv, size_t n, const gi_proto_limits *lim, gi_proto_bake *out,
                            gi_proto_error *err) {
  if (parse_query(kv, n, P_AT | P_REDIRECT | P_KIND | P_QUALITY | P_HALF | P_PANO | P_LM, lim, out, err))
    return err->status;
  return check_lighting(kv, n, lim, out, err);
}

/* Lightmaps are not cell-addressed yet (canonical.c says how they will be):
 * a cell URL takes probe and panorama. */
int gi_proto_parse_cell_lighting(const gi_proto_kv *kv, size_t n, const gi_proto_limits *lim, gi_proto_bake *out,
                                 gi_proto_error *err) {
  if (parse_query(kv, n, P_CELLQ | P_KIND | P_QUALITY | P_HALF | P_PANO, lim, out, err)) return err->status;
  out->cell = 1;
  if (out->kind == GI_PROTO_LIGHTMAP)
    return gi_proto_fail(err, 501, "kind=lightmap has no cell URL yet; ask /v1/scenes/{id}/lighting?at=...&kind=lightmap");
  return check_lighting(kv, n, lim, out, err);
}

int gi_proto_parse_lightmap_uv(const gi_proto_kv *kv, size_t n, const gi_proto_limits *lim, gi_proto_bake *out,
                               gi_proto_error *err) {
  if (parse_query(kv, n, P_AT | P_QUALITY | P_LM, lim, out, err)) return err->status;
  out->kind = GI_PROTO_LIGHTMAP;
  return 0;
}

int gi_proto_parse_cascades(const gi_proto_kv *kv, size_t n, const gi_proto_limits *lim, gi_proto_bake *out,
                            gi_proto_error *err) {
  return parse_query(kv, n, P_AT | P_QUALITY | P_FACES | P_REDIRECT, lim, out, err);
}

int gi_proto_parse_cell_cascades(const gi_proto_kv *kv, size_t n, const gi_proto_limits *lim, gi_proto_bake *out,
                                 gi_proto_error *err) {
  if (parse_query(kv, n, P_QUALITY | P_FACES | P_CELLQ, lim, out, err)) return err->status;
  out->cell = 1;
  return 0;
}

int gi_proto_parse_scene(const gi_proto_kv *kv, size_t n, const gi_proto_limits *lim, gi_proto_bake *out,
                         gi_proto_error *err) {
  return parse_query(kv, n, P_QUALITY, lim, out, err);
}

/* POST /v1/scenes/{id}/sessions: quality knobs and an optional start 'at',
 * in the query or as a JSON body (probes' 'at' and 'quality'), not both. */
static int session_body(const char *body, size_t len, const gi_proto_limits *lim, gi_proto_bake *out,
                        gi_proto_error *err);

int gi_proto_parse_session(const gi_proto_kv *kv, size_t n, const char *body, size_t len,
                           const gi_proto_limits *lim, gi_proto_bake *out, gi_proto_error *err) {
  /* Name what was given twice: the message blamed the quality when only 'at' was. */
  if (len && n) {
    const char *k = kv[0].key ? kv[0].key : "";
    return gi_proto_fail(err, 400, "the session's start 'at' and quality come in the JSON body or in the query, not "
                         "both: the query has '%s' and there is a body", k);
  }
  if (len) return session_body(body, len, lim, out, err);
  return parse_query(kv, n, P_AT | P_AT_OPT | P_QUALITY, lim, out, err);
}

int gi_proto_parse_session_lighting(const gi_proto_kv *kv, size_t n, const gi_proto_limits *lim,
                                    gi_proto_bake *out, gi_proto_error *err) {
  for (size_t i = 0; i < n; i++) {
    const char *k = kv[i].key ? kv[i].key : "";
    for (size_t j = 0; j < sizeof params / sizeof params[0]; j++)
      if (params[j].group == P_QUALITY && !strcmp(params[j].key, k))
        return gi_proto_fail(err, 400, "parameter '%s': a session's quality is set when it is created", k);
  }
  if (parse_query(kv, n, P_AT | P_KIND | P_HALF | P_PANO, lim, out, err)) return err->status;
  if (out->kind == GI_PROTO_LIGHTMAP)
    return gi_proto_fail(err, 400, "parameter 'kind': a session answers probe or panorama, got 'lightmap'");
  return check_lighting(kv, n, lim, out, err);
}

int gi_proto_parse_cell(const char *s, long long out[3]) {
  const char *p = s;
  int far = 0;
  for (int i = 0; i < 3; i++) {
    const char *d = p + (*p == '-');
    size_t nd = strspn(d, "0123456789");
    /* Plain integers: no sign but '-', no leading zeros. */
    if (nd == 0 || (d[0] == '0' && nd > 1) || (*p == '-' && d[0] == '0')) return -1;
    /* Past 18 digits an index may not fit int64; no scene reaches that far anyway. */
    if (nd > 18) far = 1;
    else out[i] = strtoll(p, NULL, 10);
    p = d + nd;
    if (i < 2 && *p++ != ',') return -1;
  }
  return *p ? -1 : far ? -2 : 0;
}

int gi_proto_parse_none(const gi_proto_kv *kv, size_t n, gi_proto_error *err) {
  if (n) return gi_proto_fail(err, 400, "unknown parameter '%.64s'", kv[0].key ? kv[0].key : "");
  return 0;
}

/* A JSON array of three finite numbers: 0, -1 malformed, -2 out of range. */
static int json_vec3(const json_t *a, double out[3]) {
  if (!json_is_array(a) || json_array_size(a) != 3) return -1;
  for (size_t k = 0; k < 3; k++) {
    const json_t *x = json_array_get(a, k);
    if (!json_is_number(x)) return -1;
    out[k] = json_number_value(x);
    if (!isfinite(out[k])) return -1;
    if (fabs(out[k]) > GI_PROTO_MAX_COORD) return -2;
  }
  return 0;
}

/* The body's fields are these and no others. */
static int probes_check_fields(json_t *root, gi_proto_error *err) {
  const char *key;
  json_t *v;
  json_object_foreach(root, key, v) {
    if (strcmp(key, "points") && strcmp(key, "at") && strcmp(key, "quality") && strcmp(key, "half") &&
        strcmp(key, "ao"))
      return gi_proto_fail(err, 400, "body: unknown field '%.64s' (expected points, at, quality, half, ao)", key);
  }
  return 0;
}

/* 'points': a non-empty array of [x,y,z] within the job limit, into out. */
static int probes_points(json_t *root, const gi_proto_limits *lim, gi_proto_probes *out, gi_proto_error *err) {
  json_t *pts = json_object_get(root, "points");
  if (!json_is_array(pts) || json_array_size(pts) == 0)
    return gi_proto_fail(err, 400, "body: 'points' must be a non-empty array of [x,y,z]");
  size_t n = json_array_size(pts);
  if (n > lim->max_probes_job)
    return gi_proto_fail(err, 413, "body: %zu points exceed the server limit of %zu", n, lim->max_probes_job);
  out->points = malloc(3 * n * sizeof(double));
  if (!out->points) return gi_proto_fail(err, 500, "body: out of memory for %zu points", n);
  for (size_t i = 0; i < n; i++) {
    int rc = json_vec3(json_array_get(pts, i), &out->points[3 * i]);
    if (rc == -2)
      return gi_proto_fail(err, 400, "body: points[%zu]: out of range: expected |x|, |y|, |z| <= %g", i,
                           GI_PROTO_MAX_COORD);
    if (rc) return gi_proto_fail(err, 400, "body: points[%zu]: expected an array of 3 finite numbers", i);
  }
  out->num_points = n;
  return 0;
}

/* 'at', 'half' and 'ao'. */
static int probes_flags(json_t *root, gi_proto_bake *b, gi_proto_error *err) {
  json_t *v;
  if ((v = json_object_get(root, "at"))) {
    int rc = json_vec3(v, b->at);
    if (rc == -2) return gi_proto_fail(err, 400, "body: 'at': out of range: expected |x|, |y|, |z| <= %g", GI_PROTO_MAX_COORD);
    if (rc) return gi_proto_fail(err, 400, "body: 'at': expected an array of 3 finite numbers");
    b->has_at = 1;
  }
  for (int f = 0; f < 2; f++) {
    const char *name = f ? "ao" : "half";
    if (!(v = json_object_get(root, name))) continue;
    if (!json_is_boolean(v)) return gi_proto_fail(err, 400, "body: '%s': expected true or false", name);
    if (f) b->quality.ao = json_is_true(v);
    else b->half = json_is_true(v);
  }
  return 0;
}

/* The keys of a body's 'quality' object besides 'preset'. */
static int is_body_knob(const char *key) {
  static const char *const knobs[] = {"levels", "res",   "voxel",         "cones", "aperture", "step",
                                      "bounces", "samples", "probe_samples", "seed",  "ao",       "effects"};
  for (size_t i = 0; i < sizeof knobs / sizeof knobs[0]; i++)
    if (!strcmp(key, knobs[i])) return 1;
  return 0;
}

/* One knob of a 'quality' object (not the preset). */
static int probes_knob(gi_proto_bake *b, const char *key, json_t *x, const gi_proto_limits *lim,
                       gi_proto_error *err) {
  char where[96];
  snprintf(where, sizeof where, "body: quality.%.64s", key);
  /* Named before its value is typed: "quality.quality: expected a number"
   * sent a client looking for a number where the key itself was wrong. */
  if (!is_body_knob(key))
    return gi_proto_fail(err, 400,
                         "%s: unknown quality knob (expected preset, levels, res, voxel, cones, aperture, step, "
                         "bounces, samples, probe_samples, seed, ao, effects)", where);
  if (!strcmp(key, "effects")) {
    if (!json_is_string(x)) return gi_proto_fail(err, 400, "%s: expected a string NAME:on|off|auto[,...]", where);
    return set_effects(&b->quality, json_string_value(x), err, where) ? err->status : 0;
  }
  if (!strcmp(key, "ao") && json_is_boolean(x)) {
    b->quality.ao = json_is_true(x);
    return 0;
  }
  if (is_int_knob(key)) {
    /* JSON keeps 64 and 64.0 apart: the contract says integer. */
    if (!json_is_integer(x)) return gi_proto_fail(err, 400, "%s: expected an integer", where);
    char text[32];
    snprintf(text, sizeof text, "%lld", (long long)json_integer_value(x));
    return set_int_knob(&b->quality, key, json_integer_value(x), text, lim, err, where) ? err->status : 0;
  }
  if (!json_is_number(x)) return gi_proto_fail(err, 400, "%s: expected a number", where);
  return set_real_knob(&b->quality, key, json_number_value(x), err, where) ? err->status : 0;
}

/* 'quality': a preset name, or an object of knobs with an optional preset
 * applied first. */
static int probes_quality(json_t *root, gi_proto_bake *b, const gi_proto_limits *lim, gi_proto_error *err) {
  json_t *v = json_object_get(root, "quality");
  if (!v) return 0;
  if (json_is_string(v))
    return set_preset(&b->quality, json_string_value(v), err, "body: 'quality'") ? err->status : 0;
  if (!json_is_object(v))
    return gi_proto_fail(err, 400, "body: 'quality': expected low|default|high or an object of knobs");
  json_t *preset = json_object_get(v, "preset");
  if (preset && !json_is_string(preset)) return gi_proto_fail(err, 400, "body: quality.preset: expected a string");
  if (preset && set_preset(&b->quality, json_string_value(preset), err, "body: quality.preset")) return err->status;
  const char *key;
  json_t *x;
  json_object_foreach(v, key, x) {
    if (strcmp(key, "preset") && probes_knob(b, key, x, lim, err)) return err->status;
  }
  return 0;
}

int gi_proto_parse_probes(const char *body, size_t len, const gi_proto_limits *lim, gi_proto_probes *out,
                          gi_proto_error *err) {
  memset(out, 0, sizeof *out);
  if (len > lim->max_body_bytes)
    return gi_proto_fail(err, 413, "body: %zu bytes exceed the server limit of %zu", len, lim->max_body_bytes);
  json_error_t je;
  json_t *root = json_loadb(body ? body : "", len, JSON_REJECT_DUPLICATES, &je);
  if (!root) return gi_proto_fail(err, 400, "body: line %d column %d: %s", je.line, je.column, je.text);
  int rc;
  out->bake.kind = GI_PROTO_PROBE;
  if (!json_is_object(root)) rc = gi_proto_fail(err, 400, "body: expected a JSON object with 'points'");
  else if (!(rc = probes_check_fields(root, err)) && !(rc = probes_points(root, lim, out, err)) &&
           !(rc = probes_flags(root, &out->bake, err)))
    rc = probes_quality(root, &out->bake, lim, err);
  json_decref(root);
  if (rc) gi_proto_probes_free(out);
  return rc;
}

static int session_body(const char *body, size_t len, const gi_proto_limits *lim, gi_proto_bake *out,
                        gi_proto_error *err) {
  memset(out, 0, sizeof *out);
  if (len > lim->max_body_bytes)
    return gi_proto_fail(err, 413, "body: %zu bytes exceed the server limit of %zu", len, lim->max_body_bytes);
  json_error_t je;
  json_t *root = json_loadb(body, len, JSON_REJECT_DUPLICATES, &je);
  if (!root) return gi_proto_fail(err, 400, "body: line %d column %d: %s", je.line, je.column, je.text);
  int rc = 0;
  const char *key;
  json_t *v;
  if (!json_is_object(root)) rc = gi_proto_fail(err, 400, "body: expected a JSON object with 'at' and 'quality'");
  else json_object_foreach(root, key, v) {
    if (!rc && strcmp(key, "at") && strcmp(key, "quality") && strcmp(key, "ao"))
      rc = gi_proto_fail(err, 400, "body: unknown field '%.64s' (expected at, quality, ao)", key);
  }
  if (!rc && !(rc = probes_flags(root, out, err))) rc = probes_quality(root, out, lim, err);
  json_decref(root);
  return rc;
}

void gi_proto_probes_free(gi_proto_probes *p) {
  if (!p) return;
  free(p->points);
  p->points = NULL;
  p->num_points = 0;
}
