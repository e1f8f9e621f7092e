/* gi-accuracy: what each quality knob costs in milliseconds and buys in error.
 *
 * For each scene (Cornell box, Munich, procedural city): a fixed,
 * deterministic set of probe points; a path-traced reference at a high
 * sample count (cached under the output folder, keyed by scene, points,
 * samples and reference version, so reruns are cheap); then one bake and
 * gather per knob value, changing one knob at a time around the default,
 * and the path tracer itself at 1..4096 samples, all timed and compared
 * with the reference; then each scene's camera view (views.c) and its
 * workloads at equal error (workload.c: probe counts, a panorama, the
 * view, Munich's aerial view and Blender Cycles on it). Writes a CSV, a
 * gnuplot plot and a markdown report (report.c), and workloads.csv/.jsonl.
 * Figures are measured on the machine it runs on; nothing is estimated
 * (a probe workload's path-tracer time is scaled from its error subset
 * only when timing the full count would take too long, and says so). Exit status: 0 done, 1 a scene or bake failed, 2 bad arguments. */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>
#include "acc.h"
#include "gi/gi.h"
#include "toolargs.h"

/* The library's reference version keys the cache: a changed path tracer
 * never reuses old files. (Tool-side history: 2 = glossy lobe, sky seen.) */
#define REF_VERSION GI_REFERENCE_VERSION
#define CITY5K_EXTENT 5000.0 /* metres: the "city5k" scene */

static int g_repeat = 2; /* runs per configuration; the fastest counts */

typedef struct opts {
  const char *scenes_dir, *out_dir, *md, *png, *notes;
  char scenes[ACC_MAX_SCENES][16];
  int num_scenes;
  int ref_samples, pt_max, threads;
  int quick;
  int view_spp;        /* reference paths per pixel of the camera views; 0 = no views */
  int workloads;       /* 1: the workloads at equal error (--no-workloads: 0) */
  int cycles;          /* 1: Blender Cycles on the aerial view when blender is on PATH (--no-cycles: 0) */
  int by_light;        /* 1: the error split by light kind (--no-by-light: 0) */
  const char *knobs;   /* --knobs: the knobs to sweep; NULL = all */
  int scenes_given;    /* --scenes named the scenes: a missing one is an error, not a SKIP */
  acc_file_opts file;  /* --scene FILE and its options */
  char out_buf[1024];  /* the default --out of a --scene run */
} opts;

static void usage(FILE *f) {
  fprintf(f,
          "usage: gi-accuracy [--scenes LIST] [--scenes-dir DIR] [--out DIR] [--md FILE] [--png FILE]\n"
          "                   [--notes FILE] [--ref-samples N] [--pt-max N] [--threads N] [--repeat N]\n"
          "                   [--view-samples N] [--no-views] [--no-workloads] [--no-cycles] [--no-by-light]\n"
          "                   [--quick]\n"
          "                   [--knobs LIST]\n"
          "       gi-accuracy --scene FILE [--up y|z] [--at X,Y,Z] [--probes FILE | --above-ground H [--spacing M]]\n"
          "                   [--view CAMERA] [the options above but --scenes]\n"
          "  --scenes LIST      comma-separated: cornell, munich, city, city5k (default all four;\n"
          "                     city5k, the generator over 5 km, runs the default and high only)\n"
          "  --scene FILE       any scene file instead (OBJ, glTF, PLY, ...); default --out\n"
          "                     out/accuracy-NAME (NAME: the file's base name)\n"
          "  --up y|z           the file's up axis (default y)\n"
          "  --at X,Y,Z         the cone tracer's viewpoint (default: the placed probe nearest the\n"
          "                     middle of the bounds or of the grid; the --probes points' mean)\n"
          "  --probes FILE      the probe points, one 'x y z' per line, '#' comments (as gi-bake --probes);\n"
          "                     default: a 3x3x3 lattice at 20/50/80%% of the bounds, points that see\n"
          "                     direct light (the Cornell box's rule)\n"
          "  --above-ground H   instead a 7x7 street-level grid H above the ground around --at, none\n"
          "                     inside buildings (Munich's and the city's rule)\n"
          "  --spacing M        that grid's spacing (default: a quarter of the scene's width across\n"
          "                     with --at, most of it without; Munich's is 12)\n"
          "  --view CAMERA      also compare a camera view: a Mitsuba .xml sensor or\n"
          "                     X,Y,Z,TX,TY,TZ,FOV,W,H (as gi-bake --render)\n"
          "  --scenes-dir DIR   the shared scenes (default %s); a scene\n"
          "                     --scenes names must be there (else exit 1 before any work),\n"
          "                     the default list skips a missing one\n"
          "  --out DIR          CSV, plot script and reference cache (default out/accuracy)\n"
          "  --md FILE          the markdown report (default OUT/accuracy.md)\n"
          "  --png FILE         the plot (default OUT/accuracy.png; needs gnuplot)\n"
          "  --notes FILE       hand-written markdown to put after the method in the report\n"
          "  --ref-samples N    reference paths per probe (default 65536)\n"
          "  --pt-max N         largest path-tracer sample count in the sweep, a power of 4 (default 4096);\n"
          "                     the probe workloads go on past it, up to a quarter of --ref-samples,\n"
          "                     until the path tracer reaches the cone tracer's error\n"
          "  --threads N        threads for bakes and path tracing (default: all cores)\n"
          "  --repeat N         runs per configuration, the fastest counts (default 2)\n"
          "  --view-samples N   reference paths per pixel of each scene's camera view, panorama and\n"
          "                     Munich's aerial view (default 1024; the path tracer is swept up to a\n"
          "                     quarter of it)\n"
          "  --no-views         skip the camera views\n"
          "  --no-workloads     skip the workloads at equal error (20/1000/10000 probes, panorama,\n"
          "                     camera view, Munich's aerial view; out/workloads.csv, .jsonl)\n"
          "  --no-cycles        do not run Blender Cycles on Munich's aerial view (run when on PATH)\n"
          "  --no-by-light      skip the error split by light kind (a reference and a bake per kind:\n"
          "                     sun, point/spot, sky, emissive, each alone) and the hand-built\n"
          "                     cascade's small source within a level and across levels\n"
          "  --quick            fewer knob values, views at 64 paths per pixel, workloads' error on 20\n"
          "                     probes and Cycles at 16 samples only (a smoke run)\n"
          "  --knobs LIST       sweep only these: res, levels, voxel0, cones, aperture, step, bounces,\n"
          "                     light_samples (sky and emitter samples per voxel),\n"
          "                     high (comma-separated; the default bake always runs)\n"
          "  -h, --help         this text;  -V, --version  the version and the march's CPU path\n",
          GI_SCENES_DIR);
}

static ta_ctx ta = TA_CTX("gi-accuracy");

static int takes_value(const char *a) {
  static const char *const v[] = {"--scenes", "--scenes-dir", "--out", "--md", "--png", "--notes",
                                   "--ref-samples", "--pt-max", "--threads", "--repeat", "--view-samples", "--knobs"};
  for (size_t i = 0; i < sizeof v / sizeof v[0]; i++)
    if (!strcmp(a, v[i])) return 1;
  return 0;
}

/* An option given twice: the second value silently won ('--md a.md --md
 * b.md' wrote b.md only). Each takes one value. */
static int repeated(const char *a, const char **seen, int *n) {
  static const char *const file_opts[] = {"--scene", "--up", "--at", "--probes", "--above-ground", "--view",
                                          "--spacing"};
  int value = takes_value(a);
  for (size_t k = 0; k < sizeof file_opts / sizeof file_opts[0]; k++) value |= !strcmp(a, file_opts[k]);
  if (!value) return 0;
  for (int k = 0; k < *n; k++)
    if (!strcmp(seen[k], a)) return ta_fail(&ta, a, "given twice (it takes one value)");
  seen[(*n)++] = a; /* at most one entry per option: fewer than 32 */
  return 0;
}

/* --knobs LIST: names from the sweep, comma-separated. */
static int check_knobs(const char *list) {
  static const char *const known[] = {"res", "levels", "voxel0", "cones", "aperture", "step", "bounces", "light_samples",
                                      "high"};
  char buf[128];
  if (!*list || strlen(list) >= sizeof buf) return ta_fail(&ta, "--knobs", "expected a list of knobs, got '%s'", list);
  snprintf(buf, sizeof buf, "%s", list);
  for (char *t = buf, *e; t; t = e ? e + 1 : NULL) {
    if ((e = strchr(t, ','))) *e = 0;
    size_t k = 0;
    while (k < sizeof known / sizeof known[0] && strcmp(t, known[k])) k++;
    if (k == sizeof known / sizeof known[0])
      return ta_fail(&ta, "--knobs",
                     "unknown knob '%s' (res, levels, voxel0, cones, aperture, step, bounces, light_samples, high)", t);
  }
  return 0;
}

/* The shipped scenes. A run names each at most once, so every per-scene
 * table (results below) holds them all: a fifth scene must grow
 * ACC_MAX_SCENES with it (four scenes once wrote past tables of three). */
static const char *const KNOWN_SCENES[] = {"cornell", "munich", "city", "city5k"};
_Static_assert(sizeof KNOWN_SCENES / sizeof KNOWN_SCENES[0] == ACC_MAX_SCENES, "per-scene tables hold every scene");

static int known_scene(const char *t) {
  for (size_t i = 0; i < ACC_MAX_SCENES; i++)
    if (!strcmp(t, KNOWN_SCENES[i])) return 1;
  return 0;
}

/* --scenes LIST: the shipped scenes, each once. */
static int parse_list(const char *list, opts *o) {
  char buf[64];
  snprintf(buf, sizeof buf, "%s", list);
  for (char *t = strtok(buf, ","); t; t = strtok(NULL, ",")) {
    if (!known_scene(t)) {
      fprintf(stderr, "gi-accuracy: --scenes: unknown scene '%s' (cornell, munich, city, city5k)\n", t);
      return 2;
    }
    for (int i = 0; i < o->num_scenes; i++)
      if (!strcmp(o->scenes[i], t)) {
        fprintf(stderr, "gi-accuracy: --scenes: '%s' named twice\n", t);
        return 2;
      }
    snprintf(o->scenes[o->num_scenes++], sizeof o->scenes[0], "%s", t);
  }
  if (!o->num_scenes) {
    fprintf(stderr, "gi-accuracy: --scenes is empty\n");
    return 2;
  }
  return 0;
}

static int parse_args(int argc, char **argv, opts *o) {
  memset(o, 0, sizeof *o);
  o->scenes_dir = GI_SCENES_DIR;
  o->out_dir = "out/accuracy";
  o->ref_samples = 65536;
  o->pt_max = 4096;
  o->view_spp = -1;
  o->workloads = o->cycles = o->by_light = 1;
  int no_views = 0;
  const char *list = "cornell,munich,city,city5k";
  int out_given = 0, nseen = 0;
  const char *seen[32];
  for (int i = 1; i < argc; i++) {
    const char *a = argv[i];
    if (repeated(a, seen, &nseen)) return 2;
    int has = i + 1 < argc, took = acc_file_option(&ta, &o->file, argc, argv, &i);
    if (took == 2) return 2;
    if (took) continue;
    if (!strcmp(a, "--help") || !strcmp(a, "-h")) {
      usage(stdout);
      return -1;
    } else if (!strcmp(a, "--version") || !strcmp(a, "-V")) {
      printf("gi-accuracy %s\ncpu path: %s\n", ta_version(), gi_cpu_path());
      return -1;
    } else if (!strcmp(a, "--quick")) {
      o->quick = 1;
    } else if (!strcmp(a, "--no-views")) {
      no_views = 1;
    } else if (!strcmp(a, "--no-workloads")) {
      o->workloads = 0;
    } else if (!strcmp(a, "--no-cycles")) {
      o->cycles = 0;
    } else if (!strcmp(a, "--no-by-light")) {
      o->by_light = 0;
    } else if (!has && takes_value(a)) {
      return ta_fail(&ta, NULL, "option '%s' needs a value", a);
    } else if (!strcmp(a, "--scenes")) list = argv[++i], o->scenes_given = 1;
    else if (!strcmp(a, "--scenes-dir")) o->scenes_dir = argv[++i];
    else if (!strcmp(a, "--out")) o->out_dir = argv[++i], out_given = 1;
    else if (!strcmp(a, "--md")) o->md = argv[++i];
    else if (!strcmp(a, "--png")) o->png = argv[++i];
    else if (!strcmp(a, "--notes")) o->notes = argv[++i];
    else if (!strcmp(a, "--knobs")) {
      if (check_knobs(o->knobs = argv[++i])) return 2;
    }
    else if (!strcmp(a, "--ref-samples")) {
      if (ta_int(&ta, "--ref-samples", NULL, argv[++i], 64, 1 << 22, &o->ref_samples)) return 2;
    } else if (!strcmp(a, "--pt-max")) {
      if (ta_int(&ta, "--pt-max", "a power of 4 in 1..1048576", argv[++i], 1, 1 << 20, &o->pt_max)) return 2;
      int p4 = 1;
      while (p4 < o->pt_max) p4 *= 4;
      if (p4 != o->pt_max) return ta_fail(&ta, "--pt-max", "expected a power of 4 in 1..1048576, got '%s'", argv[i]);
    } else if (!strcmp(a, "--repeat")) {
      if (ta_int(&ta, "--repeat", NULL, argv[++i], 1, 20, &g_repeat)) return 2;
    } else if (!strcmp(a, "--view-samples")) {
      if (ta_int(&ta, "--view-samples", NULL, argv[++i], 8, 1 << 20, &o->view_spp)) return 2;
    } else if (!strcmp(a, "--threads")) {
      if (ta_int(&ta, "--threads", NULL, argv[++i], 0, 256, &o->threads)) return 2;
    } else {
      return ta_fail(&ta, NULL, "unknown argument '%s'", a);
    }
  }
  int rc = acc_file_check(&ta, &o->file);
  if (rc) return rc;
  if (no_views && o->file.have_view) return ta_fail(&ta, "--view", "cannot be combined with --no-views");
  if (no_views) o->view_spp = 0;
  else if (o->view_spp < 0) o->view_spp = o->quick ? 64 : 1024;
  if (o->file.path) {
    if (o->scenes_given) return ta_fail(&ta, "--scene", "cannot be combined with --scenes");
    if (!out_given) {
      snprintf(o->out_buf, sizeof o->out_buf, "out/accuracy-%s", o->file.name);
      o->out_dir = o->out_buf;
    }
    o->num_scenes = 1;
    return 0;
  }
  return parse_list(list, o);
}


/* ---- scenes and probe points ---------------------------------------- */

typedef acc_scene_set scene_set;

/* Candidate points on a grid; keeps those that see direct light above 2%
 * of the best candidate (drops points inside buildings and inside the
 * Cornell box's blocks, where the truth is darkness), at most `keep`.
 * By luminance: a scene lit in red alone kept nothing by its green
 * channel and gi-accuracy exited 1 without a word (the shared scenes keep
 * the same points either way). 0 after saying why when none is kept. */
static double lum709(const float c[3]) { return 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]; }
int acc_keep_lit(scene_set *ss, const double *cand, size_t nc, size_t keep, int threads) {
  gi_ref_probe *r = calloc(nc, sizeof *r);
  gi_reference_opts o = {.samples = 64, .max_depth = -1, .seed = 7, .threads = threads};
  gi_error_info err = {0};
  if (!r || gi_reference_irradiance(ss->s, cand, nc, &o, r, NULL, &err) != GI_OK) {
    fprintf(stderr, "gi-accuracy: probe selection: %s\n", err.msg);
    free(r);
    return 0;
  }
  double best = 0;
  for (size_t i = 0; i < nc; i++) best = fmax(best, lum709(r[i].direct));
  ss->pts = malloc(3 * keep * sizeof(double));
  ss->n = 0;
  size_t lit = 0;
  for (size_t i = 0; i < nc && ss->n < keep && ss->pts; i++) {
    if (!(lum709(r[i].direct) > 0.02 * best)) continue;
    lit++;
    if (ss->clearance > 0 && gi_scene_clearance(ss->s, &cand[3 * i], ss->clearance) < ss->clearance) continue;
    memcpy(&ss->pts[3 * ss->n++], &cand[3 * i], 3 * sizeof(double));
  }
  free(r);
  if (!ss->pts) fprintf(stderr, "gi-accuracy: probe selection: out of memory for %zu points\n", keep);
  else if (!(best > 0))
    fprintf(stderr, "gi-accuracy: probe selection: none of the %zu candidate points sees direct light (the scene's "
            "lights and emitters reach none of them); give the points with --probes FILE\n", nc);
  else if (!ss->n)
    fprintf(stderr, "gi-accuracy: probe selection: the %zu of %zu candidate points that see direct light all lie "
            "within %g of a surface; give the points with --probes FILE\n", lit, nc, ss->clearance);
  return ss->n > 0;
}

/* The shared scene file behind a scene name, or 0 for the generated ones. */
static int shared_file(const opts *o, const char *name, char *path, size_t size) {
  if (!strcmp(name, "cornell")) return snprintf(path, size, "%s/cornell-box/cornell-box.obj", o->scenes_dir), 1;
  if (!strcmp(name, "munich")) return snprintf(path, size, "%s/munich/munich.obj", o->scenes_dir), 1;
  return 0;
}

/* Scenes named by --scenes must be there, checked before hours of work on
 * the others: a missing one was skipped with exit 0 (all of them: "no
 * scene was available", exit 0). The default list still skips. */
static int check_shared(const opts *o) {
  char path[1024];
  for (int i = 0; o->scenes_given && i < o->num_scenes; i++)
    if (shared_file(o, o->scenes[i], path, sizeof path) && access(path, R_OK) != 0)
      return ta_error(&ta, TA_EXIT_RUN, "--scenes", "%s: cannot read '%s': %s (the shared scenes are --scenes-dir %s)",
                      o->scenes[i], path, strerror(errno), o->scenes_dir);
  return 0;
}

static int setup_scene(const opts *o, const char *name, scene_set *ss) {
  memset(ss, 0, sizeof *ss);
  /* Every scene takes the same paths: since the reference traces light
   * from the city's lamps too (GI_REFERENCE_VERSION 6), its street probes'
   * indirect standard error is 1.1% at 65536 paths (9.6% before, when the
   * city took 16x the paths and still read 2.9%). */
  ss->ref_samples = o->ref_samples;
  gi_error_info err = {0};
  gi_scene_options so = {.up = GI_UP_Y, .threads = o->threads, .default_lights = 1};
  char path[1024];
  if (!strcmp(name, "cornell")) {
    shared_file(o, name, path, sizeof path);
    if (access(path, R_OK)) return fprintf(stderr, "gi-accuracy: SKIP cornell: %s not found\n", path), -1;
    if (gi_scene_load(path, &so, &ss->s, &err)) return fprintf(stderr, "gi-accuracy: %s\n", err.msg), 0;
    ss->at[0] = 278, ss->at[1] = 273, ss->at[2] = 279.6;
    /* 3x3x3 points inside the box, 20/50/80% of its bounds. */
    double lo[3], hi[3], cand[3 * 27];
    gi_scene_bounds(ss->s, lo, hi);
    static const double f[3] = {0.2, 0.5, 0.8};
    for (int i = 0; i < 27; i++) {
      int ix[3] = {i % 3, (i / 3) % 3, i / 9};
      for (int k = 0; k < 3; k++) cand[3 * i + k] = lo[k] + f[ix[k]] * (hi[k] - lo[k]);
    }
    return acc_keep_lit(ss, cand, 27, 27, o->threads);
  }
  double cand[3 * 49];
  if (!strcmp(name, "munich")) {
    shared_file(o, name, path, sizeof path);
    if (access(path, R_OK)) return fprintf(stderr, "gi-accuracy: SKIP munich: %s not found\n", path), -1;
    so.up = GI_UP_Z;
    if (gi_scene_load(path, &so, &ss->s, &err)) return fprintf(stderr, "gi-accuracy: %s\n", err.msg), 0;
    ss->at[0] = -67.85, ss->at[1] = -85.78, ss->at[2] = 2;
    /* A 7x7 grid, 12 m apart, 2 m above the ground, around the README's open square. */
    for (int i = 0; i < 49; i++) {
      cand[3 * i] = ss->at[0] + 12.0 * (i % 7 - 3);
      cand[3 * i + 1] = ss->at[1] + 12.0 * (i / 7 - 3);
      cand[3 * i + 2] = 2;
    }
  } else {
    /* city5k: the same generator over 5 km (item 6 of the city issue: a
     * street probe there as accurate as in the 600 m city). */
    gi_city_params cp = {.extent = strcmp(name, "city5k") ? 0 : CITY5K_EXTENT};
    if (gi_city_build(&cp, &so, &ss->s, &err)) return fprintf(stderr, "gi-accuracy: %s: %s\n", name, err.msg), 0;
    gi_city_default_viewpoint(&cp, ss->at);
    int up = gi_scene_up(ss->s) == GI_UP_Z ? 2 : 1, h0 = up == 2 ? 0 : 2;
    for (int i = 0; i < 49; i++) {
      memcpy(&cand[3 * i], ss->at, sizeof ss->at);
      cand[3 * i + 0] += 6.0 * (i % 7 - 3);
      cand[3 * i + h0] += 6.0 * (i / 7 - 3);
    }
  }
  /* Street probes stand in the open: a grid point that lands in a wall's
   * plane (one of Munich's did, 5 mm off a facade) measures the wall, not
   * the street. A quarter of the probes' height of room keeps them clear. */
  ss->clearance = 0.25 * (strcmp(name, "munich") ? 1.7 : 2.0);
  return acc_keep_lit(ss, cand, 49, 24, o->threads);
}

/* ---- reference cache ------------------------------------------------- */

static int load_or_make_ref(const opts *o, const char *name, const scene_set *ss, gi_ref_probe *ref, double *ms) {
  return acc_ref_cached(name, ss, 0, o->threads, o->out_dir, REF_VERSION, ref, ms);
}

/* ---- the sweep -------------------------------------------------------- */

typedef struct rows {
  acc_row *v;
  size_t n, cap;
} rows;

static acc_row *push(rows *r) {
  if (r->n == r->cap) {
    size_t c = r->cap ? 2 * r->cap : 64;
    acc_row *v = realloc(r->v, c * sizeof *v);
    if (!v) return NULL;
    r->v = v, r->cap = c;
  }
  memset(&r->v[r->n], 0, sizeof r->v[0]);
  return &r->v[r->n++];
}

static int run_cone(const char *name, const scene_set *ss, const gi_ref_probe *ref, const gi_quality *q,
                    const char *knob, double value, int is_default, rows *out) {
  gi_cascade *c = NULL;
  gi_bake_report rep;
  gi_error_info err = {0};
  gi_probe *pr = calloc(ss->n, sizeof *pr);
  if (!pr) return 0;
  double gms = 0, best = INFINITY, bake = 0;
  /* Deterministic bakes: repeats change only the time; keep the fastest
   * (the machine is shared, the slow runs are other people's work). */
  for (int rep_i = 0; rep_i < g_repeat; rep_i++) {
    gi_cascade_free(c);
    c = NULL;
    if (gi_cascade_bake(ss->s, ss->at, q, &c, &rep, &err) != GI_OK ||
        gi_cascade_gather(c, ss->pts, ss->n, pr, &gms, &err) != GI_OK) {
      fprintf(stderr, "gi-accuracy: %s %s=%g: %s\n", name, knob, value, err.msg);
      gi_cascade_free(c);
      free(pr);
      return 0;
    }
    double b = acc_bake_ms(&rep);
    if (b + gms < best) best = b + gms, bake = b;
  }
  /* A probe outside the cascade reads no indirect light: its error is the
   * cascade's reach, not its accuracy. Said once, for the default. */
  size_t out_n = 0;
  for (size_t i = 0; is_default && i < ss->n; i++) out_n += !gi_cascade_covers(c, ss->pts + 3 * i);
  if (out_n)
    fprintf(stderr, "gi-accuracy: %s: note: %zu of %zu probes lie outside the default cascade around (%g, %g, %g): "
            "their indirect light reads 0 (give --at nearer them)\n", name, out_n, ss->n, ss->at[0], ss->at[1],
            ss->at[2]);
  acc_row *r = push(out);
  if (!r) return 0;
  snprintf(r->scene, sizeof r->scene, "%s", name);
  snprintf(r->kind, sizeof r->kind, "cone");
  snprintf(r->knob, sizeof r->knob, "%s", knob);
  r->value = value;
  r->is_default = is_default;
  r->bake_ms = bake;
  r->ms = best;
  r->gather_ms = best - bake;
  r->specular_ran = rep.effects[GI_FX_SPECULAR].ran;
  for (int p = 0; p < 3; p++) acc_compare_probes(pr, ref, ss->n, (acc_part)p, &r->m[p]);
  fprintf(stderr, "  cone %-8s %8g  %9.1f ms  mre total %.4f direct %.4f indirect %.4f\n", knob, value, r->ms,
          r->m[0].mre, r->m[1].mre, r->m[2].mre);
  gi_cascade_free(c);
  free(pr);
  return 1;
}

static int run_path(const char *name, const scene_set *ss, const gi_ref_probe *ref, int samples, int threads,
                    rows *out) {
  gi_ref_probe *pr = calloc(ss->n, sizeof *pr);
  gi_reference_opts ro = {.samples = samples, .seed = 2, .threads = threads}; /* seed 2: independent of the reference */
  gi_error_info err = {0};
  double ms = INFINITY;
  for (int i = 0; i < g_repeat; i++) {
    double t = 0;
    if (!pr || gi_reference_irradiance(ss->s, ss->pts, ss->n, &ro, pr, &t, &err) != GI_OK) {
      fprintf(stderr, "gi-accuracy: %s path %d: %s\n", name, samples, err.msg);
      free(pr);
      return 0;
    }
    ms = fmin(ms, t);
  }
  acc_row *r = push(out);
  if (!r) return 0;
  snprintf(r->scene, sizeof r->scene, "%s", name);
  snprintf(r->kind, sizeof r->kind, "path");
  snprintf(r->knob, sizeof r->knob, "samples");
  r->value = samples;
  r->ms = ms;
  for (int p = 0; p < 3; p++) acc_compare_refs(pr, ref, ss->n, (acc_part)p, &r->m[p]);
  fprintf(stderr, "  path samples  %8d  %9.1f ms  mre total %.4f direct %.4f indirect %.4f\n", samples, r->ms,
          r->m[0].mre, r->m[1].mre, r->m[2].mre);
  free(pr);
  return 1;
}

/* Whether --knobs (default: every knob) names this one. */
static int sweeps(const opts *o, const char *knob) {
  if (!o->knobs) return 1;
  size_t n = strlen(knob);
  for (const char *p = o->knobs; (p = strstr(p, knob)); p += n)
    if ((p == o->knobs || p[-1] == ',') && (p[n] == ',' || !p[n])) return 1;
  return 0;
}

/* The 5 km city is there for one question, whether its street probes are
 * as accurate as the 600 m city's at the same quality: it runs the default
 * and "high" only (a bake there takes 4-25 s). */
static int scale_only(const opts *o, const char *name) { return !o->file.path && !strcmp(name, "city5k"); }

/* Whether this scene sweeps this knob: --knobs, and on the 5 km city only "high". */
static int sweeps_here(const opts *o, const char *name, const char *knob) {
  return (!scale_only(o, name) || !strcmp(knob, "high")) && sweeps(o, knob);
}

static int sweep_scene(const opts *o, const char *name, const scene_set *ss, const gi_ref_probe *ref, rows *out) {
  gi_quality q0 = {.threads = o->threads};
  /* Resolve the default voxel size once, so `levels` can move alone. */
  gi_cascade *c = NULL;
  gi_bake_report rep;
  gi_error_info err = {0};
  if (gi_cascade_bake(ss->s, ss->at, &q0, &c, &rep, &err) != GI_OK) {
    fprintf(stderr, "gi-accuracy: %s: %s\n", name, err.msg);
    return 0;
  }
  double s0 = rep.quality.voxel0;
  /* The default's level count too: a scene wider than its reach gets more
   * than 6 (gi_quality_resolve), and a knob given s0 alone would get 6. */
  int n0 = rep.quality.levels;
  float ap16 = rep.quality.aperture_deg;
  gi_cascade_free(c);
  int ok = run_cone(name, ss, ref, &q0, "default", 0, 1, out);
  static const int res_full[] = {16, 24, 48, 64}, res_quick[] = {16, 48};
  const int lev[] = {n0 - 2, n0 - 1, n0 < GI_MAX_LEVELS ? n0 + 1 : n0 - 3};
  static const int cones[] = {4, 6, 32}, bnc[] = {-1, 1, 2, 3};
  static const double vx[] = {0.5, 2.0};
  static const float steps[] = {0.25f, 1.0f}, aps[] = {0.6f, 1.5f};
  const int *res = o->quick ? res_quick : res_full;
  int nres = o->quick ? 2 : 4;
  for (int i = 0; ok && sweeps_here(o, name, "res") && i < nres; i++) {
    gi_quality q = q0;
    q.res = res[i];
    q.levels = n0;
    q.voxel0 = s0 * 32.0 / res[i]; /* same extent, finer voxels */
    ok = run_cone(name, ss, ref, &q, "res", res[i], 0, out);
  }
  for (int i = 0; ok && sweeps_here(o, name, "levels") && i < 3; i++) {
    gi_quality q = q0;
    q.levels = lev[i];
    q.voxel0 = s0;
    ok = run_cone(name, ss, ref, &q, "levels", lev[i], 0, out);
  }
  for (int i = 0; ok && sweeps_here(o, name, "voxel0") && i < 2; i++) {
    gi_quality q = q0;
    q.levels = n0;
    q.voxel0 = s0 * vx[i];
    ok = run_cone(name, ss, ref, &q, "voxel0", q.voxel0, 0, out);
  }
  for (int i = 0; ok && sweeps_here(o, name, "cones") && i < 3; i++) {
    gi_quality q = q0;
    q.cones = cones[i];
    ok = run_cone(name, ss, ref, &q, "cones", cones[i], 0, out);
  }
  for (int i = 0; ok && sweeps_here(o, name, "aperture") && i < 2; i++) {
    gi_quality q = q0;
    q.aperture_deg = ap16 * aps[i];
    ok = run_cone(name, ss, ref, &q, "aperture", q.aperture_deg, 0, out);
  }
  for (int i = 0; ok && sweeps_here(o, name, "step") && i < 2; i++) {
    gi_quality q = q0;
    q.step = steps[i];
    ok = run_cone(name, ss, ref, &q, "step", steps[i], 0, out);
  }
  for (int i = 0; ok && sweeps_here(o, name, "bounces") && i < 4; i++) {
    gi_quality q = q0;
    q.bounces = bnc[i];
    ok = run_cone(name, ss, ref, &q, "bounces", bnc[i] < 0 ? 0 : bnc[i], 0, out);
  }
  /* Light samples per voxel (sky, emitters): the inject's cost; the probes keep their own. */
  static const int lsamp[] = {4, 8, 32};
  for (int i = 0; ok && sweeps_here(o, name, "light_samples") && i < 3; i++) {
    gi_quality q = q0;
    q.light_samples = lsamp[i];
    ok = run_cone(name, ss, ref, &q, "light_samples", lsamp[i], 0, out);
  }
  if (ok && !o->quick && sweeps_here(o, name, "high")) {
    /* A "high" setting: every knob that helped, together. */
    gi_quality q = q0;
    q.levels = n0, q.res = 64, q.voxel0 = s0 * 0.5, q.cones = 32, q.step = 0.25f; /* bounces: the albedo rule and its tail */
    ok = run_cone(name, ss, ref, &q, "high", 1, 0, out);
  }
  for (int s = 1; ok && s <= o->pt_max; s *= 4) ok = run_path(name, ss, ref, s, o->threads, out);
  return ok;
}

/* ---- camera views ------------------------------------------------------ */

/* Each scene's view: the Cornell box through its Mitsuba camera; Munich
 * and the city from the viewpoint at eye height, down a street. */
static int view_camera(const opts *o, const char *name, const scene_set *ss, gi_camera *cam) {
  gi_error_info err = {0};
  memset(cam, 0, sizeof *cam);
  if (o->file.path) return acc_file_camera(&o->file, ss->s, cam);
  if (!strcmp(name, "cornell")) {
    char path[1024];
    snprintf(path, sizeof path, "%s/cornell-box/cbox-mitsuba.xml", o->scenes_dir);
    if (gi_camera_from_mitsuba(path, cam, &err) != GI_OK) {
      fprintf(stderr, "gi-accuracy: SKIP cornell view: %s\n", err.msg);
      return 0;
    }
    gi_camera_fit(cam, 192);
    return 1;
  }
  int up = gi_scene_up(ss->s) == GI_UP_Z ? 2 : 1, along = up == 2 ? 1 : 0;
  memcpy(cam->eye, ss->at, sizeof cam->eye);
  cam->eye[up] = ss->at[up] - (strcmp(name, "munich") ? 0 : 0.3); /* Munich's viewpoint is 2 m up: eye at 1.7 */
  memcpy(cam->target, cam->eye, sizeof cam->target);
  cam->target[along] += 40;
  cam->up[up] = 1;
  cam->fov_deg = 70, cam->width = 320, cam->height = 180;
  return 1;
}

static const char *dir_of(const char *path, char *buf, size_t n) {
  snprintf(buf, n, "%s", path);
  char *sl = strrchr(buf, '/');
  if (sl) *sl = 0;
  else snprintf(buf, n, ".");
  return buf;
}

static void machine_name(char *out, size_t n) {
  snprintf(out, n, "unknown CPU");
  FILE *f = fopen("/proc/cpuinfo", "r");
  char line[256];
  while (f && fgets(line, sizeof line, f))
    if (!strncmp(line, "model name", 10)) {
      char *c = strchr(line, ':');
      if (c) {
        c += 2;
        c[strcspn(c, "\n")] = 0;
        snprintf(out, n, "%s, %ld cores", c, sysconf(_SC_NPROCESSORS_ONLN));
      }
      break;
    }
  if (f) fclose(f);
}

/* Everything one run gathers for the report. */
typedef struct results {
  rows out;
  acc_scene_info info[ACC_MAX_SCENES];
  acc_view views[ACC_MAX_SCENES];
  size_t ninfo, nviews;
  acc_workload *wl;
  size_t nwl;
  acc_light_row by_light[ACC_MAX_SCENES * ACC_LIGHT_KINDS];
  size_t n_by_light;
  acc_handover handover;
  char cycles_note[160]; /* why Blender Cycles did not run; "" when it did or was not wanted */
} results;

/* The workloads of one scene; Munich also gets the aerial view (and Cycles). */
static int scene_workloads(const opts *o, const char *name, const scene_set *ss, const acc_view *view,
                           const char *md_dir, results *R) {
  char obj[1024];
  int munich = !o->file.path && !strcmp(name, "munich");
  snprintf(obj, sizeof obj, "%s/munich/munich.obj", o->scenes_dir);
  acc_wl_opts wo = {.quick = o->quick, .threads = o->threads, .repeat = g_repeat,
                    .pt_max = o->pt_max, .view_spp = o->view_spp > 0 ? o->view_spp : (o->quick ? 64 : 1024),
                    .ref_version = REF_VERSION, .out_dir = o->out_dir, .md_dir = md_dir,
                    .munich_obj = munich ? obj : NULL};
  if (munich && o->cycles) {
    wo.cycles = acc_have_blender();
    if (!wo.cycles) {
      snprintf(R->cycles_note, sizeof R->cycles_note, "`blender` is not on PATH on the machine that made this report");
      fprintf(stderr, "gi-accuracy: SKIP Blender Cycles column: blender is not on PATH\n");
    }
  } else if (munich) {
    snprintf(R->cycles_note, sizeof R->cycles_note, "run with --no-cycles");
    fprintf(stderr, "gi-accuracy: SKIP Blender Cycles column: --no-cycles\n");
  }
  return acc_run_workloads(&wo, name, ss, view, munich, &R->wl, &R->nwl);
}

/* Whether the reference reads any light at the probes; says why not. With
 * none, every relative error is 0/0: --probes points inside a closed box
 * gave NaN figures, "nan%" in the report and exit 0. */
static int ref_has_light(const char *name, const gi_ref_probe *ref, size_t n) {
  for (size_t i = 0; i < n; i++)
    if (lum709(ref[i].irradiance) > 0) return 1;
  fprintf(stderr, "gi-accuracy: %s: the reference reads no light at any of the %zu probes (the scene's lights and "
          "emitters reach none of them): relative errors are undefined; give points the light reaches\n", name, n);
  return 0;
}

/* One scene: probes, reference, sweep, view, workloads. 0 done, 1 failed, -1 skipped. */
static int run_scene(const opts *o, const char *name, const char *md_dir, results *R) {
  scene_set ss;
  acc_scene_info *si = &R->info[R->ninfo];
  char placement[sizeof si->placement] = "";
  int st = o->file.path ? acc_file_setup(&o->file, o->ref_samples, o->threads, &ss, placement, sizeof placement)
                        : setup_scene(o, name, &ss);
  if (st < 0) return -1; /* skipped loudly */
  gi_ref_probe *ref = st ? calloc(ss.n, sizeof *ref) : NULL;
  int rc = 0;
  memset(si, 0, sizeof *si);
  if (!st || !ref || !load_or_make_ref(o, name, &ss, ref, &si->ref_ms) || !ref_has_light(name, ref, ss.n) ||
      !sweep_scene(o, name, &ss, ref, &R->out)) {
    rc = 1;
  } else {
    snprintf(si->name, sizeof si->name, "%s", name);
    si->probes = ss.n;
    si->ref_samples = ss.ref_samples;
    snprintf(si->placement, sizeof si->placement, "%s", placement);
    snprintf(si->at, sizeof si->at, "%.6g, %.6g, %.6g", ss.at[0], ss.at[1], ss.at[2]);
    acc_metrics m;
    for (int p = 0; p < 3; p++) {
      acc_compare_refs(ref, ref, ss.n, (acc_part)p, &m);
      si->ref_rel_se[p] = m.ref_rel_se;
    }
    R->ninfo++;
    if (o->by_light && !scale_only(o, name) &&
        !acc_run_by_light(name, &ss, ref, o->threads, o->out_dir, REF_VERSION, R->by_light, &R->n_by_light))
      rc = 1;
    gi_camera cam;
    const acc_view *view = NULL;
    if (o->view_spp > 0 && !scale_only(o, name) && view_camera(o, name, &ss, &cam)) {
      char png_path[1100];
      acc_view *v = &R->views[R->nviews];
      snprintf(png_path, sizeof png_path, "%s/view-%s.png", md_dir, name);
      if (!acc_run_view(name, ss.s, ss.at, &cam, o->view_spp, o->threads, g_repeat, o->out_dir, png_path, REF_VERSION, v)) {
        rc = 1;
      } else {
        snprintf(v->png, sizeof v->png, "view-%s.png", name);
        view = v;
        R->nviews++;
      }
    }
    if (!rc && o->workloads && !scale_only(o, name) && !scene_workloads(o, name, &ss, view, md_dir, R)) rc = 1;
  }
  free(ref);
  free(ss.pts);
  gi_scene_release(ss.s);
  return rc;
}

/* Pareto front per scene over (ms, total mean relative error). */
static void mark_fronts(rows *out) {
  for (size_t i = 0; i < out->n;) {
    size_t j = i;
    while (j < out->n && !strcmp(out->v[j].scene, out->v[i].scene)) j++;
    double ms[j - i], e[j - i];
    int front[j - i];
    for (size_t k = i; k < j; k++) ms[k - i] = out->v[k].ms, e[k - i] = out->v[k].m[ACC_TOTAL].mre;
    acc_pareto(ms, e, j - i, front);
    for (size_t k = i; k < j; k++) out->v[k].on_front = front[k - i];
    i = j;
  }
}

/* --notes must be a readable file: it is read only when the report is
 * written, after the whole sweep, and was then left out with exit 0. */
static int check_notes(const char *path) {
  struct stat st;
  FILE *f = fopen(path, "r");
  if (!f) return ta_error(&ta, TA_EXIT_RUN, "--notes", "cannot read '%s': %s", path, strerror(errno));
  int plain = fstat(fileno(f), &st) == 0 && S_ISREG(st.st_mode);
  fclose(f);
  return plain ? 0 : ta_error(&ta, TA_EXIT_RUN, "--notes", "'%s' is not a file", path);
}

int main(int argc, char **argv) {
  opts o;
  ta_memory_policy();
  int rc = ta_check_cpu_path(&ta);
  if (rc) return rc;
  rc = parse_args(argc, argv, &o);
  if (rc) return rc < 0 ? 0 : rc;
  if ((rc = check_shared(&o))) return rc;
  if (ta_mkdirs(&ta, "--out", o.out_dir)) return 1;
  /* What the run writes and reads at its very end is checked now, not
   * after a sweep of hours (--out's folder exists by now: --md may be in it). */
  if ((o.md && (rc = ta_check_output(&ta, "--md", &o.md))) || (o.png && (rc = ta_check_output(&ta, "--png", &o.png))) ||
      (o.notes && (rc = check_notes(o.notes))))
    return rc;
  char md[1024], png[1024], machine[256], cmd[1024] = "", md_dir[1024];
  snprintf(md, sizeof md, "%s", o.md ? o.md : "");
  if (!o.md) snprintf(md, sizeof md, "%s/accuracy.md", o.out_dir);
  if (o.png) snprintf(png, sizeof png, "%s", o.png);
  else snprintf(png, sizeof png, "%s/accuracy.png", o.out_dir);
  machine_name(machine, sizeof machine);
  for (int i = 0; i < argc; i++) {
    size_t l = strlen(cmd);
    snprintf(cmd + l, sizeof cmd - l, "%s%s", i ? " " : "", argv[i]);
  }
  dir_of(md, md_dir, sizeof md_dir);
  results *R = calloc(1, sizeof *R);
  if (!R) return fprintf(stderr, "gi-accuracy: out of memory\n"), 1;
  rc = 0;
  for (int i = 0; i < o.num_scenes && !rc; i++) {
    int r = run_scene(&o, o.file.path ? o.file.name : o.scenes[i], md_dir, R);
    if (r > 0) rc = 1;
  }
  /* The level hand-over on a hand-built cascade, with the light split (both explain the cities' errors). */
  if (!rc && R->out.n && o.by_light && !acc_run_handover(o.threads, &R->handover)) rc = 1;
  if (!rc && R->out.n) {
    mark_fronts(&R->out);
    acc_wl_report wl = {.w = R->wl, .n = R->nwl, .ran = o.workloads, .cycles_note = R->cycles_note,
                        .by_light = R->by_light, .n_by_light = R->n_by_light,
                        .handover = R->handover.ran ? &R->handover : NULL};
    if (acc_write_reports(R->out.v, R->out.n, R->info, R->ninfo, R->views, R->nviews, &wl, o.out_dir, md, png, machine,
                          cmd, o.notes))
      rc = 1;
  } else if (!rc) {
    fprintf(stderr, "gi-accuracy: SKIP: no scene was available\n");
  }
  free(R->out.v);
  free(R->wl);
  free(R);
  free(o.file.pts);
  int frc = ta_outputs_finish(&ta, rc == 0); /* a device or FIFO named by --md or --png gets its bytes */
  return rc ? rc : frc;
}
