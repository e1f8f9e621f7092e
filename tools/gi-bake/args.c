/* args.c: gi-bake's command line, parsed strictly.
 *
 * Design: every number goes through one of three helpers (list of finite
 * doubles, bounded integer, unsigned 64-bit) that check the whole string
 * was consumed, the value is finite and within range, and otherwise print
 * "gi-bake: --opt: expected ..., got '...'" and make the run exit 2. Values
 * are range-checked here, before any scene is loaded, so a typo never costs
 * a slow load; the core checks them again (it trusts no caller). Defaults
 * stay zero in gi_quality so the core resolves them in one place. */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <stdarg.h>
#include <float.h>
#include <getopt.h>
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include "cli.h"

#define MAX_POINTS ((size_t)1 << 24) /* the probe EXR holds at most 2^24 pixels */

enum {
  OPT_AT = 256, OPT_UP, OPT_LEVELS, OPT_RES, OPT_VOXEL, OPT_CONES, OPT_BOUNCES, OPT_SAMPLES,
  OPT_PROBE_SAMPLES, OPT_THREADS, OPT_EXR, OPT_HALF, OPT_VDB, OPT_VDB_FACES, OPT_JSON, OPT_PROBES,
  OPT_SUN, OPT_SKY, OPT_POINT, OPT_SPOT, OPT_NO_DEFAULT_LIGHTS, OPT_AO, OPT_CITY_EXTENT, OPT_CITY_SEED,
  OPT_CITY_DETAIL, OPT_EFFECT, OPT_RENDER, OPT_PNG, OPT_RENDER_SAMPLES
};

static const struct option long_opts[] = {
    {"at", required_argument, NULL, OPT_AT},
    {"up", required_argument, NULL, OPT_UP},
    {"levels", required_argument, NULL, OPT_LEVELS},
    {"res", required_argument, NULL, OPT_RES},
    {"voxel", required_argument, NULL, OPT_VOXEL},
    {"cones", required_argument, NULL, OPT_CONES},
    {"bounces", required_argument, NULL, OPT_BOUNCES},
    {"samples", required_argument, NULL, OPT_SAMPLES},
    {"probe-samples", required_argument, NULL, OPT_PROBE_SAMPLES},
    {"threads", required_argument, NULL, OPT_THREADS},
    {"exr", required_argument, NULL, OPT_EXR},
    {"half", no_argument, NULL, OPT_HALF},
    {"vdb", required_argument, NULL, OPT_VDB},
    {"vdb-faces", no_argument, NULL, OPT_VDB_FACES},
    {"json", no_argument, NULL, OPT_JSON},
    {"probes", required_argument, NULL, OPT_PROBES},
    {"sun", required_argument, NULL, OPT_SUN},
    {"sky", required_argument, NULL, OPT_SKY},
    {"point", required_argument, NULL, OPT_POINT},
    {"spot", required_argument, NULL, OPT_SPOT},
    {"no-default-lights", no_argument, NULL, OPT_NO_DEFAULT_LIGHTS},
    {"ao", no_argument, NULL, OPT_AO},
    {"effect", required_argument, NULL, OPT_EFFECT},
    {"render", required_argument, NULL, OPT_RENDER},
    {"png", required_argument, NULL, OPT_PNG},
    {"render-samples", required_argument, NULL, OPT_RENDER_SAMPLES},
    {"city-extent", required_argument, NULL, OPT_CITY_EXTENT},
    {"city-seed", required_argument, NULL, OPT_CITY_SEED},
    {"city-detail", required_argument, NULL, OPT_CITY_DETAIL},
    {"help", no_argument, NULL, 'h'},
    {"version", no_argument, NULL, 'V'},
    {NULL, 0, NULL, 0}};

static const char help_text[] =
    "Usage: gi-bake SCENE [options]\n"
    "Bakes global illumination around a viewpoint with cascaded voxel cone tracing\n"
    "and prints what it did. SCENE is a scene file (OBJ, PLY, glTF, 3DS, FBX) or the\n"
    "word 'city' for the embedded procedural city (use ./city for a file named city).\n"
    "\n"
    "Viewpoint and scene\n"
    "  --at X,Y,Z            viewpoint, world units (default: city street corner, or\n"
    "                        the centre of a file scene's bounds)\n"
    "  --up y|z              file scene's up axis (default y; OSM cities use z)\n"
    "  --probes FILE         extra gather points, one 'x y z' per line, '#' comments;\n"
    "                        the probe EXR gets one pixel per point, viewpoint first\n"
    "\n"
    "Quality (defaults resolved by the core)\n"
    "  --levels N            cascade levels, 1..12 (default 6)\n"
    "  --res R               voxels per side per level, multiple of 4 in 8..256 (32)\n"
    "  --voxel S0            finest voxel size, world units (default: coarsest level\n"
    "                        spans the scene)\n"
    "  --cones N             diffuse cones per hemisphere: 4, 6, 8, 16, 32 (16)\n"
    "  --bounces N           voxel-to-voxel bounces, 0..8, 0 = none (default: from\n"
    "                        the albedo in range, 1..3; the effect plan says why)\n"
    "  --samples N           shadow rays per voxel for sky/area lights, 1..512 (16)\n"
    "  --probe-samples N     shadow rays per probe for sky/area lights, 1..8192 (256)\n"
    "  --ao                  also compute ambient occlusion at the probes (off)\n"
    "  --effect NAME=on|off|auto  override the effect plan for one effect; NAME is\n"
    "                        sun, local_lights, sky, emissive, bounce, specular or ao\n"
    "                        (repeatable; default auto: decided from the scene)\n"
    "  --threads N           worker threads, 0 = all cores (0)\n"
    "\n"
    "Lights (added to the scene's own; repeatable, at most 64)\n"
    "  --sun DX,DY,DZ,R,G,B  directional light: direction the light travels (need not\n"
    "                        be unit length), irradiance on a facing surface (W/m^2)\n"
    "  --sky R,G,B           uniform sky radiance (W/m^2/sr)\n"
    "  --point X,Y,Z,R,G,B   point light: position (world units), intensity (W/sr)\n"
    "  --spot X,Y,Z,DX,DY,DZ,INNER,OUTER,R,G,B\n"
    "                        spot light: position, direction it shines, full cone\n"
    "                        angles in degrees (full intensity inside INNER, none\n"
    "                        outside OUTER, 0 < INNER <= OUTER < 180), intensity (W/sr)\n"
    "  --no-default-lights   do not add a sun and sky to a scene with no lights and\n"
    "                        no emitters (added by default)\n"
    "\n"
    "Procedural city (SCENE = city only)\n"
    "  --city-extent M       side of the square city, metres, up to 20000 (600)\n"
    "  --city-seed N         layout seed, unsigned 64-bit, 0 = default (1)\n"
    "  --city-detail N       facade subdivision, 1..8 (2)\n"
    "\n"
    "Outputs (files are written to a temporary name, then renamed)\n"
    "  --exr OUT.exr         probe EXR: R,G,B, irradiance/direct/indirect.R,G,B, ao.Y,\n"
    "                        sh.L00.R .. sh.L22.B (one pixel per probe)\n"
    "  --half                store the EXR as half floats (default float)\n"
    "  --vdb OUT.vdb         cascade snapshot: L<d>_density, L<d>_Cd, L<d>_albedo,\n"
    "                        L<d>_normal per level, plain density/Cd for level 0\n"
    "  --vdb-faces           add the six per-face radiance grids L<d>_face_px..\n"
    "  --json                print one JSON object instead of the summary\n"
    "\n"
    "Pictures (the view from the cascade beside the same view path-traced)\n"
    "  --render CAMERA       a Mitsuba XML file's perspective sensor (lookat, fov;\n"
    "                        256 x 256), or X,Y,Z,TX,TY,TZ,FOV,W,H: eye, target,\n"
    "                        fov in degrees across the smaller side, pixels\n"
    "                        (up = the scene's up axis)\n"
    "  --png OUT.png         cone-traced | path-traced | error side by side (needs\n"
    "                        --render); with --render, --exr gets the images\n"
    "                        (R,G,B cone-traced, path.R/G/B, error.Y) instead of probes\n"
    "  --render-samples N    paths per pixel of the path-traced view, 1..65536 (64)\n"
    "  -h, --help            this text;  -V, --version  the version\n"
    "\n"
    "Exit status: 0 success, 1 the scene, bake or an output failed, 2 bad arguments.\n"
    "\n"
    "Examples\n"
    "  gi-bake city --exr out/city-probe.exr --vdb out/city-cascades.vdb\n"
    "  gi-bake cornell-box.obj --at 278,273,279.6 --bounces 3 --json\n";

static int usage_fail(const char *opt, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static int usage_fail(const char *opt, const char *fmt, ...) {
  va_list ap;
  va_start(ap, fmt);
  fprintf(stderr, "gi-bake: %s%s", opt ? opt : "", opt ? ": " : "");
  vfprintf(stderr, fmt, ap);
  fputs("\nTry 'gi-bake --help'.\n", stderr);
  va_end(ap);
  return EXIT_USAGE;
}

/* Splits s on commas into exactly n finite doubles. Returns 0 on success. */
static int parse_doubles(const char *s, double *out, int n) {
  const char *p = s;
  for (int i = 0; i < n; i++) {
    char *end;
    errno = 0;
    double v = strtod(p, &end);
    if (end == p || errno == ERANGE || !isfinite(v)) return -1;
    /* strtod skips leading blanks; refuse trailing ones and empty fields. */
    if (*end != (i + 1 < n ? ',' : '\0')) return -1;
    out[i] = v;
    p = end + 1;
  }
  return 0;
}

static int parse_long(const char *s, long lo, long hi, long *out) {
  char *end;
  errno = 0;
  long v = strtol(s, &end, 10);
  if (end == s || *end || errno == ERANGE || v < lo || v > hi) return -1;
  *out = v;
  return 0;
}

static int parse_u64(const char *s, uint64_t *out) {
  /* strtoull silently negates "-1"; only plain digits are unsigned. */
  const char *p = s;
  while (*p == ' ' || *p == '\t') p++;
  if (*p < '0' || *p > '9') return -1;
  char *end;
  errno = 0;
  unsigned long long v = strtoull(p, &end, 10);
  if (*end || errno == ERANGE) return -1;
  *out = (uint64_t)v;
  return 0;
}

/* A light colour: three finite non-negative values that survive the cast to float. */
static int colour_ok(const double c[3]) {
  for (int k = 0; k < 3; k++)
    if (!(c[k] >= 0) || c[k] > FLT_MAX) return 0;
  return 1;
}

static int add_light(cli_opts *o, const char *opt, const char *arg) {
  if (o->num_lights >= CLI_MAX_LIGHTS)
    return usage_fail(opt, "at most %d lights can be given on the command line", CLI_MAX_LIGHTS);
  gi_light l;
  memset(&l, 0, sizeof l);
  double v[11];
  if (!strcmp(opt, "--spot")) {
    if (parse_doubles(arg, v, 11))
      return usage_fail(opt, "expected eleven finite numbers X,Y,Z,DX,DY,DZ,INNER,OUTER,R,G,B, got '%s'", arg);
    double len = sqrt(v[3] * v[3] + v[4] * v[4] + v[5] * v[5]);
    if (!(len > 1e-12) || !isfinite(len))
      return usage_fail(opt, "direction DX,DY,DZ must be a non-zero finite vector, got '%s'", arg);
    if (!(v[6] > 0 && v[6] <= v[7] && v[7] < 180))
      return usage_fail(opt, "cone angles must satisfy 0 < INNER <= OUTER < 180 degrees, got '%s'", arg);
    if (!colour_ok(v + 8)) return usage_fail(opt, "intensity R,G,B must be finite and >= 0, got '%s'", arg);
    l.type = GI_LIGHT_SPOT;
    for (int k = 0; k < 3; k++) {
      l.position[k] = v[k];
      l.direction[k] = (float)(v[3 + k] / len);
      l.color[k] = (float)v[8 + k];
    }
    const double deg = 3.14159265358979323846 / 180.0;
    l.cos_inner = (float)cos(0.5 * v[6] * deg);
    l.cos_outer = (float)cos(0.5 * v[7] * deg);
  } else if (!strcmp(opt, "--sun")) {
    if (parse_doubles(arg, v, 6))
      return usage_fail(opt, "expected six finite numbers DX,DY,DZ,R,G,B, got '%s'", arg);
    double len = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    if (!(len > 1e-12) || !isfinite(len))
      return usage_fail(opt, "direction DX,DY,DZ must be a non-zero finite vector, got '%s'", arg);
    if (!colour_ok(v + 3)) return usage_fail(opt, "irradiance R,G,B must be finite and >= 0, got '%s'", arg);
    l.type = GI_LIGHT_SUN;
    for (int k = 0; k < 3; k++) {
      l.direction[k] = (float)(v[k] / len);
      l.color[k] = (float)v[3 + k];
    }
  } else if (!strcmp(opt, "--sky")) {
    if (parse_doubles(arg, v, 3) || !colour_ok(v))
      return usage_fail(opt, "expected three finite numbers R,G,B >= 0, got '%s'", arg);
    l.type = GI_LIGHT_SKY;
    for (int k = 0; k < 3; k++) l.color[k] = (float)v[k];
  } else {
    if (parse_doubles(arg, v, 6))
      return usage_fail(opt, "expected six finite numbers X,Y,Z,R,G,B, got '%s'", arg);
    if (!colour_ok(v + 3)) return usage_fail(opt, "intensity R,G,B must be finite and >= 0, got '%s'", arg);
    l.type = GI_LIGHT_POINT;
    for (int k = 0; k < 3; k++) {
      l.position[k] = v[k];
      l.color[k] = (float)v[3 + k];
    }
  }
  o->lights[o->num_lights++] = l;
  return 0;
}

/* Reads --probes FILE (gi_points.h). Returns 0, EXIT_RUN (cannot read) or
 * EXIT_USAGE (a bad line, named by file and number). The viewpoint takes
 * one of the EXR's pixels. */
static int read_probes(cli_opts *o, const char *path) {
  gi_error_info e = {0};
  gi_result rc = gi_points_read(path, MAX_POINTS - 1, &o->probes, &o->num_probes, &e);
  if (rc == GI_OK) return 0;
  fprintf(stderr, "gi-bake: --probes: %s\n", e.msg);
  return rc == GI_ERR_FORMAT || rc == GI_ERR_LIMIT ? EXIT_USAGE : EXIT_RUN;
}

/* An output's folder must exist and be writable: fail before a slow bake. */
static int check_output(const char *opt, const char *path) {
  if (!*path) return usage_fail(opt, "expected a file name, got ''");
  char *dir = strdup(path);
  if (!dir) return EXIT_RUN;
  char *slash = strrchr(dir, '/');
  const char *d = ".";
  if (slash) {
    if (slash == dir) slash[1] = '\0';
    else *slash = '\0';
    d = dir;
  }
  int rc = 0;
  if (access(d, W_OK | X_OK) != 0) {
    fprintf(stderr, "gi-bake: %s: cannot write into '%s' for '%s': %s\n", opt, d, path, strerror(errno));
    rc = EXIT_RUN;
  }
  free(dir);
  return rc;
}

#define INT_OPT(name, lo, hi, dst, what)                                      \
  do {                                                                        \
    long v_;                                                                  \
    if (parse_long(optarg, lo, hi, &v_))                                      \
      return usage_fail(name, "expected " what ", got '%s'", optarg);         \
    dst = (int)v_;                                                            \
  } while (0)

int cli_parse(int argc, char **argv, cli_opts *o) {
  memset(o, 0, sizeof *o);
  opterr = 0; /* our messages, with our program name */
  int c, rc;
  long v;
  double d[3];
  while ((c = getopt_long(argc, argv, ":hV", long_opts, NULL)) != -1) {
    switch (c) {
    case 'h':
      fputs(help_text, stdout);
      return -1;
    case 'V':
      printf("gi-bake %s\n", cli_version());
      return -1;
    case OPT_AT:
      if (parse_doubles(optarg, d, 3))
        return usage_fail("--at", "expected three finite numbers X,Y,Z, got '%s'", optarg);
      memcpy(o->at, d, sizeof d);
      o->have_at = 1;
      break;
    case OPT_UP:
      if (!strcmp(optarg, "y") || !strcmp(optarg, "Y")) o->up = GI_UP_Y;
      else if (!strcmp(optarg, "z") || !strcmp(optarg, "Z")) o->up = GI_UP_Z;
      else return usage_fail("--up", "expected y or z, got '%s'", optarg);
      break;
    case OPT_LEVELS:
      INT_OPT("--levels", 1, GI_MAX_LEVELS, o->q.levels, "an integer in 1..12");
      break;
    case OPT_RES:
      if (parse_long(optarg, 8, 256, &v) || v % 4)
        return usage_fail("--res", "expected a multiple of 4 in 8..256, got '%s'", optarg);
      o->q.res = (int)v;
      break;
    case OPT_VOXEL:
      if (parse_doubles(optarg, d, 1) || !(d[0] > 0))
        return usage_fail("--voxel", "expected a finite number > 0, got '%s'", optarg);
      o->q.voxel0 = d[0];
      break;
    case OPT_CONES:
      if (parse_long(optarg, 4, 32, &v) || (v != 4 && v != 6 && v != 8 && v != 16 && v != 32))
        return usage_fail("--cones", "expected 4, 6, 8, 16 or 32, got '%s'", optarg);
      o->q.cones = (int)v;
      break;
    case OPT_BOUNCES:
      INT_OPT("--bounces", 0, 8, o->q.bounces, "an integer in 0..8");
      if (o->q.bounces == 0) o->q.bounces = -1; /* the core reads 0 as "default" */
      break;
    case OPT_SAMPLES:
      INT_OPT("--samples", 1, 512, o->q.light_samples, "an integer in 1..512");
      break;
    case OPT_PROBE_SAMPLES:
      INT_OPT("--probe-samples", 1, 8192, o->q.probe_samples, "an integer in 1..8192");
      break;
    case OPT_THREADS:
      INT_OPT("--threads", 0, 256, o->q.threads, "an integer in 0..256 (0 = all cores)");
      break;
    case OPT_EXR: o->exr = optarg; break;
    case OPT_HALF: o->half = 1; break;
    case OPT_VDB: o->vdb = optarg; break;
    case OPT_VDB_FACES: o->vdb_faces = 1; break;
    case OPT_JSON: o->json = 1; break;
    case OPT_PROBES: o->probes_file = optarg; break;
    case OPT_SUN:
      if ((rc = add_light(o, "--sun", optarg))) return rc;
      break;
    case OPT_SKY:
      if ((rc = add_light(o, "--sky", optarg))) return rc;
      break;
    case OPT_POINT:
      if ((rc = add_light(o, "--point", optarg))) return rc;
      break;
    case OPT_SPOT:
      if ((rc = add_light(o, "--spot", optarg))) return rc;
      break;
    case OPT_NO_DEFAULT_LIGHTS: o->no_default_lights = 1; break;
    case OPT_AO: o->q.ao = 1; break;
    case OPT_RENDER: {
      double c[9];
      const char *dot = strrchr(optarg, '.');
      if (dot && !strcmp(dot, ".xml")) {
        gi_error_info e = {0};
        if (gi_camera_from_mitsuba(optarg, &o->cam, &e) != GI_OK) return usage_fail("--render", "%s", e.msg);
        o->cam.width = o->cam.height = 256;
      } else if (!parse_doubles(optarg, c, 9)) {
        memcpy(o->cam.eye, c, sizeof(double[3]));
        memcpy(o->cam.target, c + 3, sizeof(double[3]));
        o->cam.fov_deg = c[6];
        if (c[7] != floor(c[7]) || c[8] != floor(c[8]) || !(c[7] >= 1 && c[7] <= 4096 && c[8] >= 1 && c[8] <= 4096))
          return usage_fail("--render", "W and H must be whole numbers of pixels in 1..4096, got '%s'", optarg);
        o->cam.width = (int)c[7], o->cam.height = (int)c[8];
        o->cam_up_from_scene = 1;
      } else {
        return usage_fail("--render", "expected a Mitsuba .xml file or X,Y,Z,TX,TY,TZ,FOV,W,H, got '%s'", optarg);
      }
      o->render = 1;
      break;
    }
    case OPT_PNG: o->png = optarg; break;
    case OPT_RENDER_SAMPLES:
      INT_OPT("--render-samples", 1, 65536, o->render_spp, "an integer in 1..65536");
      break;
    case OPT_EFFECT: {
      const char *eq = strchr(optarg, '=');
      char name[32];
      size_t len = eq ? (size_t)(eq - optarg) : 0;
      if (!eq || len == 0 || len >= sizeof name)
        return usage_fail("--effect", "expected NAME=on|off|auto, got '%s'", optarg);
      memcpy(name, optarg, len);
      name[len] = '\0';
      int id = gi_effect_from_name(name);
      if (id < 0)
        return usage_fail("--effect", "unknown effect '%s' (sun, local_lights, sky, emissive, bounce, specular, ao)",
                          name);
      if (!strcmp(eq + 1, "on")) o->q.effects[id] = GI_FX_ON;
      else if (!strcmp(eq + 1, "off")) o->q.effects[id] = GI_FX_OFF;
      else if (!strcmp(eq + 1, "auto")) o->q.effects[id] = GI_FX_AUTO;
      else return usage_fail("--effect", "expected on, off or auto after '%s=', got '%s'", name, eq + 1);
      break;
    }
    case OPT_CITY_EXTENT:
      if (parse_doubles(optarg, d, 1) || !(d[0] > 0) || d[0] > 20000)
        return usage_fail("--city-extent", "expected metres in (0, 20000], got '%s'", optarg);
      o->city.extent = d[0];
      o->city_opts_given = 1;
      break;
    case OPT_CITY_SEED:
      if (parse_u64(optarg, &o->city.seed))
        return usage_fail("--city-seed", "expected an unsigned 64-bit integer, got '%s'", optarg);
      o->city_opts_given = 1;
      break;
    case OPT_CITY_DETAIL:
      INT_OPT("--city-detail", 1, 8, o->city.detail, "an integer in 1..8");
      o->city_opts_given = 1;
      break;
    case ':': {
      const char *name = argv[optind - 1];
      for (const struct option *lo = long_opts; lo->name; lo++)
        if (lo->val == optopt) name = lo->name;
      return usage_fail(NULL, "option '--%s' needs a value", name);
    }
    default:
      return usage_fail(NULL, "unknown option '%s'", argv[optind - 1]);
    }
  }
  if (optind >= argc) return usage_fail(NULL, "missing SCENE (a scene file or 'city')");
  if (optind + 1 < argc) return usage_fail(NULL, "one SCENE expected, got '%s' and '%s'", argv[optind], argv[optind + 1]);
  o->scene = argv[optind];
  o->is_city = !strcmp(o->scene, "city");
  if (o->is_city && o->up == GI_UP_Z)
    return usage_fail("--up", "the procedural city is always Y-up");
  if (!o->is_city && o->city_opts_given)
    return usage_fail(NULL, "--city-extent, --city-seed and --city-detail apply only to the scene 'city'");
  if (o->half && !o->exr) return usage_fail("--half", "needs --exr");
  if (o->png && !o->render) return usage_fail("--png", "needs --render");
  if (o->render && !o->png && !o->exr) return usage_fail("--render", "needs --png or --exr for the pictures");
  if (o->render) {
    gi_camera cam = o->cam;
    gi_error_info e = {0};
    /* The up axis is known only after loading, where it is checked again:
     * here take whichever of y and z lies farther from the view. */
    if (o->cam_up_from_scene) {
      double d[3];
      for (int a = 0; a < 3; a++) d[a] = cam.target[a] - cam.eye[a];
      cam.up[fabs(d[1]) <= fabs(d[2]) ? 1 : 2] = 1;
    }
    if (gi_camera_validate(&cam, &e) != GI_OK) return usage_fail("--render", "%s", e.msg);
  }
  if (o->png && (rc = check_output("--png", o->png))) return rc;
  if (o->vdb_faces && !o->vdb) return usage_fail("--vdb-faces", "needs --vdb");
  if (o->exr && (rc = check_output("--exr", o->exr))) return rc;
  if (o->vdb && (rc = check_output("--vdb", o->vdb))) return rc;
  if (o->probes_file && (rc = read_probes(o, o->probes_file))) return rc;
  return 0;
}

void cli_opts_fini(cli_opts *o) {
  free(o->probes);
  o->probes = NULL;
}

const char *cli_version(void) {
#ifndef GI_VERSION
#define GI_VERSION "0.0.0"
#endif
#ifndef GI_GIT_REV
#define GI_GIT_REV "unknown"
#endif
  return GI_VERSION " (" GI_GIT_REV ")";
}
