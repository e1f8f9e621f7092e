/* scene_file.c: `gi-accuracy --scene FILE`: the same sweep on any scene.
 *
 * Probes are placed as for the shipped scenes: by default a 3 x 3 x 3
 * lattice at 20/50/80% of the scene's bounds (the Cornell box's rule);
 * with --above-ground H a 7 x 7 street-level grid H above the ground found
 * by a downward ray, with points inside buildings dropped (Munich's and the
 * city's rule, through the core's gi_probe_grid_build). Either way only
 * points that see direct light are kept, since inside a solid the truth is
 * darkness and every relative error would be the floor's. --probes FILE
 * takes the points as they are (the same format as gi-bake --probes). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include "acc.h"
#include "gi/gi.h"
#include "gi/gi_batch.h"
#include "toolargs.h"

#define LATTICE_SIDE 3       /* the Cornell rule: 3 x 3 x 3 */
#define STREET_SIDE 7        /* the cities' rule: 7 x 7 columns */
#define STREET_KEEP 24       /* at most this many street probes, as for Munich and the city */
#define STREET_CLEARANCE 0.25 /* room a street probe needs around it, in heights above the ground */
#define STREET_AT_SHARE 0.25 /* with --at: the street grid spans this share of the scene's width */
#define STREET_ALL_SHARE 0.8 /* without --at: this share, centred on the bounds */
#define VIEW_XML_SIDE 192    /* a Mitsuba sensor's pixels along its film's longer side */

static int take_view(struct ta_ctx *ta, acc_file_opts *f, const char *arg) {
  double c[9];
  const char *dot = strrchr(arg, '.');
  memset(&f->cam, 0, sizeof f->cam);
  if (dot && !strcmp(dot, ".xml")) {
    gi_error_info e = {0};
    if (gi_camera_from_mitsuba(arg, &f->cam, &e) != GI_OK) return ta_fail(ta, "--view", "%s", e.msg);
    gi_camera_fit(&f->cam, VIEW_XML_SIDE);
  } else if (ta_parse_doubles(arg, c, 9) == TA_OK) {
    memcpy(f->cam.eye, c, sizeof(double[3]));
    memcpy(f->cam.target, c + 3, sizeof(double[3]));
    f->cam.fov_deg = c[6];
    if (c[7] != floor(c[7]) || c[8] != floor(c[8]) || !(c[7] >= 1 && c[7] <= 4096 && c[8] >= 1 && c[8] <= 4096))
      return ta_fail(ta, "--view", "W and H must be whole numbers of pixels in 1..4096, got '%s'", arg);
    f->cam.width = (int)c[7], f->cam.height = (int)c[8];
    f->cam_up_from_scene = 1;
  } else {
    return ta_fail(ta, "--view", "expected a Mitsuba .xml file or X,Y,Z,TX,TY,TZ,FOV,W,H, got '%s'", arg);
  }
  f->have_view = 1;
  return 0;
}

int acc_file_option(struct ta_ctx *ta, acc_file_opts *f, int argc, char **argv, int *i) {
  static const char *const opts[] = {"--scene", "--up", "--at", "--probes", "--above-ground", "--view", "--spacing"};
  const char *a = argv[*i];
  size_t k = 0;
  while (k < sizeof opts / sizeof opts[0] && strcmp(a, opts[k])) k++;
  if (k == sizeof opts / sizeof opts[0]) return 0;
  if (*i + 1 >= argc) return ta_fail(ta, NULL, "option '%s' needs a value", a), 2;
  const char *v = argv[++*i];
  switch (k) {
  case 0:
    if (!*v) return ta_fail(ta, "--scene", "expected a scene file, got ''");
    f->path = v;
    return 1;
  case 1:
    if (!strcmp(v, "y") || !strcmp(v, "Y")) f->up = GI_UP_Y;
    else if (!strcmp(v, "z") || !strcmp(v, "Z")) f->up = GI_UP_Z;
    else return ta_fail(ta, "--up", "expected y or z, got '%s'", v);
    return 1;
  case 2:
    if (ta_triple(ta, "--at", v, f->at)) return 2;
    f->have_at = 1;
    return 1;
  case 3: f->probes_file = v; return 1;
  case 4: return ta_double(ta, "--above-ground", "a finite number > 0", v, 0, HUGE_VAL, &f->above_ground) ? 2 : 1;
  case 5: return take_view(ta, f, v) ? 2 : 1;
  default: return ta_double(ta, "--spacing", "a finite number > 0", v, 0, HUGE_VAL, &f->spacing) ? 2 : 1;
  }
}

/* The file's base name without its extension; anything but [A-Za-z0-9._-]
 * becomes '_' so the name is safe in the CSV, in gnuplot and in paths. */
static void scene_name(const char *path, char *out, size_t n) {
  const char *b = strrchr(path, '/');
  b = b ? b + 1 : path;
  snprintf(out, n, "%s", b);
  char *dot = strrchr(out, '.');
  if (dot && dot != out) *dot = 0;
  for (char *c = out; *c; c++)
    if (!((*c >= 'a' && *c <= 'z') || (*c >= 'A' && *c <= 'Z') || (*c >= '0' && *c <= '9') || strchr("._-", *c)))
      *c = '_';
  if (!*out) snprintf(out, n, "scene");
}

int acc_file_check(struct ta_ctx *ta, acc_file_opts *f) {
  if (!f->path) {
    if (f->up || f->have_at || f->probes_file || f->above_ground > 0 || f->spacing > 0 || f->have_view)
      return ta_fail(ta, NULL, "--up, --at, --probes, --above-ground, --spacing and --view need --scene FILE");
    return 0;
  }
  f->up_given = f->up != 0;
  if (!f->up) f->up = GI_UP_Y;
  if (f->probes_file && f->above_ground > 0)
    return ta_fail(ta, "--above-ground", "places probes; it cannot be combined with --probes");
  if (f->spacing > 0 && !(f->above_ground > 0))
    return ta_fail(ta, "--spacing", "is the street grid's spacing: it needs --above-ground H");
  if (access(f->path, R_OK)) return ta_error(ta, TA_EXIT_RUN, "--scene", "cannot read '%s'", f->path);
  if (f->have_view) {
    gi_camera cam = f->cam;
    if (f->cam_up_from_scene) cam.up[f->up] = 1;
    gi_error_info e = {0};
    if (gi_camera_validate(&cam, &e) != GI_OK) return ta_fail(ta, "--view", "%s", e.msg);
  }
  scene_name(f->path, f->name, sizeof f->name);
  if (!f->probes_file) return 0;
  return ta_read_points(ta, "--probes", f->probes_file, ACC_FILE_MAX_PROBES, &f->pts, &f->npts);
}

/* Without --at the viewpoint is the kept probe nearest c: a point that
 * sees light, never one inside a solid (a bounds' centre or a grid's mean
 * may well be inside a building). */
static void at_nearest(acc_scene_set *ss, const double c[3]) {
  double best = INFINITY;
  for (size_t i = 0; i < ss->n; i++) {
    const double *p = &ss->pts[3 * i];
    double d = (p[0] - c[0]) * (p[0] - c[0]) + (p[1] - c[1]) * (p[1] - c[1]) + (p[2] - c[2]) * (p[2] - c[2]);
    if (d < best) best = d, memcpy(ss->at, p, sizeof ss->at);
  }
}

/* The Cornell rule over the scene's bounds. */
static int place_lattice(const acc_file_opts *f, int threads, acc_scene_set *ss, char *pl, size_t pn) {
  static const double frac[LATTICE_SIDE] = {0.2, 0.5, 0.8};
  enum { N = LATTICE_SIDE * LATTICE_SIDE * LATTICE_SIDE };
  double lo[3], hi[3], cand[3 * N];
  gi_scene_bounds(ss->s, lo, hi);
  for (int i = 0; i < N; i++) {
    int ix[3] = {i % LATTICE_SIDE, (i / LATTICE_SIDE) % LATTICE_SIDE, i / (LATTICE_SIDE * LATTICE_SIDE)};
    for (int k = 0; k < 3; k++) cand[3 * i + k] = lo[k] + frac[ix[k]] * (hi[k] - lo[k]);
  }
  snprintf(pl, pn, "a 3x3x3 lattice at 20/50/80%% of the scene's bounds, points that see direct light");
  if (!acc_keep_lit(ss, cand, N, N, threads)) return 0;
  if (!f->have_at) at_nearest(ss, cand + 3 * (N / 2)); /* the lattice's middle point: the bounds' centre */
  return 1;
}

/* The cities' rule: a 7 x 7 street-level grid around --at (a quarter of the
 * scene's width, or --spacing apart as Munich's 12 m) or over most of the
 * scene, above_ground up, no probe inside a building. */
static int place_street(const acc_file_opts *f, int threads, acc_scene_set *ss, char *pl, size_t pn) {
  double lo[3], hi[3];
  gi_scene_bounds(ss->s, lo, hi);
  int up = f->up, h0 = 0, h1 = up == GI_UP_Z ? 1 : 2; /* the horizontal axes */
  double width = fmax(hi[h0] - lo[h0], hi[h1] - lo[h1]);
  double side = f->spacing > 0 ? f->spacing * (STREET_SIDE - 1) : width * (f->have_at ? STREET_AT_SHARE : STREET_ALL_SHARE);
  gi_grid_spec spec = {.spacing = side / (STREET_SIDE - 1), .have_region = 1,
                       .above_ground = f->above_ground};
  for (int k = 0; k < 3; k++) {
    double c = f->have_at && k != up ? f->at[k] : 0.5 * (lo[k] + hi[k]);
    spec.lo[k] = k == up ? lo[k] : c - side / 2;
    spec.hi[k] = k == up ? hi[k] : c + side / 2;
  }
  gi_probe_grid g = {0};
  gi_error_info err = {0};
  if (gi_probe_grid_build(ss->s, &spec, &g, &err) != GI_OK)
    return fprintf(stderr, "gi-accuracy: --above-ground: %s\n", err.msg), 0;
  double *cand = malloc(3 * (g.n ? g.n : 1) * sizeof *cand), mean[3] = {0, 0, 0};
  size_t nc = 0;
  for (size_t i = 0; cand && i < g.n; i++) {
    if (g.state[i] != GI_GRID_VALID) continue;
    for (int k = 0; k < 3; k++) cand[3 * nc + k] = g.pos[3 * i + k], mean[k] += g.pos[3 * i + k] / g.num_valid;
    nc++;
  }
  snprintf(pl, pn, "a %dx%d street-level grid, %g apart, %g above the ground (gi_probe_grid_build), "
           "%zu inside buildings dropped, points that see direct light", g.counts[h0], g.counts[h1], spec.spacing,
           f->above_ground, g.num_inside);
  gi_probe_grid_free(&g);
  ss->clearance = STREET_CLEARANCE * f->above_ground; /* as for Munich and the city */
  int ok = cand && nc ? acc_keep_lit(ss, cand, nc, STREET_KEEP, threads) : 0;
  if (ok && !f->have_at) at_nearest(ss, mean);
  if (cand && !nc) fprintf(stderr, "gi-accuracy: --above-ground: no ground under the grid (wrong --up?)\n");
  free(cand);
  return ok;
}

/* Whether the bake could be placed at p: finite, within 1e9 of the scene's
 * origin on each axis (the core's limit for a viewpoint) and its cell
 * addressable (gi_cascade_anchor); else 0 after saying why, naming what.
 * Checked before the reference, which takes minutes before the bake
 * refused the point. */
static int placeable(const acc_scene_set *ss, const double p[3], const char *what) {
  double o[3];
  gi_scene_origin(ss->s, o);
  for (int a = 0; a < 3; a++)
    if (!(fabs(p[a] - o[a]) <= 1e9)) {
      fprintf(stderr, "gi-accuracy: %s (%g, %g, %g) is more than 1e9 units from the scene's origin on axis %c "
              "(origin %g, %g, %g)\n", what, p[0], p[1], p[2], "xyz"[a], o[0], o[1], o[2]);
      return 0;
    }
  gi_quality q = {0}, r;
  int64_t cell[3];
  gi_error_info err = {0};
  if (gi_quality_resolve(ss->s, &q, &r, &err) == GI_OK && gi_cascade_anchor(ss->s, p, &r, cell, &err) == GI_OK)
    return 1;
  fprintf(stderr, "gi-accuracy: %s (%g, %g, %g): %s\n", what, p[0], p[1], p[2], err.msg);
  return 0;
}

/* What was loaded, for the reference cache's keys: the scene as built
 * (gi_scene_digest: geometry, per-triangle albedo from textures and
 * vertex colours, materials, lights), so anything the loader read counts
 * (a glTF's .bin, an OBJ's .mtl and map_Kd images) and a comment does
 * not. The cache was keyed by the file's base name alone, then by its
 * bytes and material factors, and an edited .bin or texture read its
 * former references. */
static uint64_t scene_version(const struct gi_scene *s) {
  uint64_t d = gi_scene_digest(s);
  uint64_t h = ta_fnv(ta_fnv(1469598103934665603ull, "scene-digest", 12), &d, sizeof d);
  return h ? h : 1; /* 0 means a built-in scene */
}

int acc_file_setup(const acc_file_opts *f, int ref_samples, int threads, acc_scene_set *ss, char *placement,
                   size_t placement_size) {
  memset(ss, 0, sizeof *ss);
  ss->ref_samples = ref_samples;
  gi_scene_options so = {.up = (gi_up_axis)f->up, .threads = threads, .default_lights = 1};
  gi_error_info err = {0};
  if (gi_scene_load(f->path, &so, &ss->s, &err) != GI_OK)
    return fprintf(stderr, "gi-accuracy: --scene: %s\n", err.msg), 0;
  acc_cache_scene_version(scene_version(ss->s));
  if (!f->up_given && gi_scene_looks_z_up(ss->s))
    fprintf(stderr, "gi-accuracy: note: %s is flat along z " TA_NOTE_Z_UP_FIX "\n", f->path);
  if (f->have_at) memcpy(ss->at, f->at, sizeof ss->at);
  if (f->have_at && !placeable(ss, ss->at, "--at")) return 0;
  if (f->above_ground > 0) return place_street(f, threads, ss, placement, placement_size);
  if (!f->pts) return place_lattice(f, threads, ss, placement, placement_size);
  ss->pts = malloc(3 * f->npts * sizeof *ss->pts);
  if (!ss->pts) return fprintf(stderr, "gi-accuracy: out of memory\n"), 0;
  memcpy(ss->pts, f->pts, 3 * f->npts * sizeof *ss->pts);
  ss->n = f->npts;
  char what[1200];
  for (size_t i = 0; i < ss->n; i++) {
    snprintf(what, sizeof what, "--probes: %s: point %zu", f->probes_file, i + 1);
    if (!placeable(ss, &ss->pts[3 * i], what)) return 0;
  }
  /* Without --at, bake around the probes' middle. */
  if (!f->have_at)
    for (size_t i = 0; i < ss->n; i++)
      for (int k = 0; k < 3; k++) ss->at[k] += ss->pts[3 * i + k] / (double)ss->n;
  snprintf(placement, placement_size, "%zu points from %s, as given", ss->n, f->probes_file);
  return 1;
}

int acc_file_camera(const acc_file_opts *f, const struct gi_scene *s, gi_camera *cam) {
  if (!f->have_view) return 0;
  *cam = f->cam;
  if (f->cam_up_from_scene) cam->up[gi_scene_up(s) == GI_UP_Z ? 2 : 1] = 1;
  return 1;
}
