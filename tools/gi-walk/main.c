/* main.c: gi-walk's command line (see walk.h for what it measures).
 *
 *   gi-walk bench [--extent M] [--levels N] [--res R] [--seconds S] [--rate HZ]
 *                 [--samples N] [--out DIR] [--json FILE] [--paths-only]
 *                 [--path FILE.csv [--scene FILE [--up y|z]]]
 *   gi-walk tables --label TEXT (--extent M | --scene FILE [--up y|z]) [--at X,Y,Z]
 *                  [--levels N] [--res R] [--moves N] [--vdb-max N] --md FILE
 * Exit 0 when the work ran (figures never fail it), 1 when it could not (a
 * path leaving the streets is such a failure), 2 for usage errors. */
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include "gi/gi_cpu.h"
#include "toolargs.h"
#include "walk.h"

#define WALK_SPEED 1.4
#define WALK_EYE 1.7
#define DRIVE_SPEED 14.0
#define DRIVE_EYE 1.2
#define PATH_SEED 12
#define DEFAULT_SAMPLES 12
#define DEFAULT_MOVES 8
#define DEFAULT_VDB_MAX 60000000ull

static const char USAGE[] =
    "usage: gi-walk bench [--extent M] [--levels N] [--res R] [--seconds S] [--rate HZ]\n"
    "                     [--samples N] [--out DIR] [--json FILE] [--paths-only]\n"
    "                     [--path FILE.csv [--scene FILE [--up y|z]]]\n"
    "       gi-walk tables --label TEXT (--extent M | --scene FILE [--up y|z]) [--at X,Y,Z]\n"
    "                      [--levels N] [--res R] [--moves N] [--vdb-max N] --md FILE\n"
    "bench: a street walk (1.4 m/s, eye 1.7 m) and a drive (14 m/s, eye 1.2 m) through the\n"
    "  city; writes DIR/walk-walk.csv and DIR/walk-drive.csv (t,x,y,z), moves one cascade\n"
    "  along each and compares with cold bakes at N sampled grid shifts (pairs).\n"
    "  --path FILE.csv: that path instead (t,x,y,z per line, as gi-client walk reads), through\n"
    "  the city or --scene FILE; the figures are named after the file.\n"
    "tables: the paper's tables for one scene, appended to FILE as markdown.\n"
    "-h, --help: this text; -V, --version: the version and the march's CPU path.\n";

/* The bench's scene: the city, or --scene FILE with --up. */
static gi_scene *bench_scene(const bench_opts *o) {
  gi_scene *s = NULL;
  gi_error_info err = {0};
  gi_scene_options so = {.up = o->up, .default_lights = 1}; /* 0: y */
  gi_result r = o->scene_file ? gi_scene_load(o->scene_file, &so, &s, &err) : gi_city_build(&o->city, NULL, &s, &err);
  if (r != GI_OK) fprintf(stderr, "gi-walk: %s: %s\n", o->scene_file ? "scene" : "city", err.msg);
  walk_note_up(o->scene_file, o->up, s);
  return s;
}

/* Direct-light paths per point for the darkness test below. */
#define DARK_SAMPLES 64

/* p->inside: points whose probes hold only leaked light. Inside a solid
 * wound outward most directions meet a back face; OpenStreetMap's
 * buildings promise no winding, so also a point that no direction leaves
 * (a closed volume) and that no light reaches directly (the reference's
 * direct light, sun, sky, lamps and emitters, is 0): Munich along y = 0 at
 * 2 m read 0.1 of leaked light in rooms the reference has at 0.0001, and
 * the moved and cold cascades' leaks differed by up to 34%. A closed room
 * with a lamp in it stays in. Returns -1 when out of memory. */
static int mark_inside(const gi_scene *s, walk_path *p) {
  double *pts = malloc(p->n * 3 * sizeof *pts);
  size_t *idx = malloc(p->n * sizeof *idx), m = 0;
  int rc = pts && idx ? 0 : -1;
  for (size_t i = 0; !rc && i < p->n; i++) {
    p->inside[i] = gi_scene_backface_share(s, p->at[i]) > GI_INSIDE_SHARE;
    if (!p->inside[i] && gi_scene_escape_share(s, p->at[i]) == 0)
      memcpy(&pts[3 * m], p->at[i], sizeof(double[3])), idx[m++] = i;
  }
  gi_ref_probe *ref = !rc && m ? malloc(m * sizeof *ref) : NULL;
  gi_reference_opts ro = {.samples = DARK_SAMPLES, .max_depth = -1};
  gi_error_info err = {0};
  if (m && (!ref || gi_reference_irradiance(s, pts, m, &ro, ref, NULL, &err) != GI_OK)) rc = -1;
  for (size_t k = 0; !rc && k < m; k++) {
    double sum = 0;
    for (int j = 0; j < 9; j++) sum += fabs(ref[k].sh[j][0]) + fabs(ref[k].sh[j][1]) + fabs(ref[k].sh[j][2]);
    p->inside[idx[k]] = sum == 0;
  }
  p->num_inside = 0;
  for (size_t i = 0; i < p->n; i++) p->num_inside += p->inside[i];
  free(ref), free(idx), free(pts);
  return rc;
}

/* --path FILE: the bench along that path (read as gi-client walk reads it). */
static int run_path_file(const bench_opts *o, ta_ctx *ta) {
  ta_step *st = NULL;
  size_t n = 0;
  int rc = ta_read_path(ta, "--path", o->path_file, &st, &n);
  if (rc) return rc;
  walk_path p = {0};
  if (walk_path_from_steps(o->path_file, st, n, &p) != 0) {
    free(st);
    return fprintf(stderr, "gi-walk: out of memory\n"), 1;
  }
  free(st);
  gi_scene *s = bench_scene(o);
  /* A path through buildings is a valid path, but a probe inside a solid
   * holds only leaked light: the figures leave those points out. */
  p.inside = s ? calloc(p.n, 1) : NULL;
  if (p.inside && mark_inside(s, &p) != 0) {
    walk_path_free(&p);
    gi_scene_release(s);
    return fprintf(stderr, "gi-walk: out of memory\n"), 1;
  }
  if (p.num_inside)
    fprintf(stderr, "gi-walk: note: %zu of %zu points of %s lie inside solids (most directions meet a surface's "
            "back, or none leaves and no light reaches them): their probes hold only light that leaks in; drift "
            "and popping leave them out\n", p.num_inside, p.n, o->path_file);
  step_rec *steps = s && p.inside ? calloc(p.n, sizeof *steps) : NULL;
  rc = !steps || bench_path(o, s, &p, steps);
  if (!rc) {
    FILE *json = o->jsonl ? fopen(o->jsonl, "a") : NULL;
    if (o->jsonl && !json) walk_file_error(o->jsonl);
    report_path(o, &p, steps, json);
    if (json) fclose(json);
  }
  free(steps);
  walk_path_free(&p);
  gi_scene_release(s);
  return rc ? 1 : 0;
}

static int run_bench(const bench_opts *o, int paths_only) {
  gi_scene *s = bench_scene(o);
  if (!s) return 1;
  struct { const char *name; double speed, eye; } kinds[2] = {{"walk", WALK_SPEED, WALK_EYE}, {"drive", DRIVE_SPEED, DRIVE_EYE}};
  walk_path p[2] = {{0}};
  int rc = 0;
  for (int k = 0; k < 2 && !rc; k++) {
    char file[1024];
    snprintf(file, sizeof file, "%s/walk-%s.csv", o->out_dir, kinds[k].name);
    rc = walk_path_make(&o->city, kinds[k].name, kinds[k].speed, kinds[k].eye, o->rate, o->seconds, PATH_SEED, &p[k]) ||
         walk_path_check(s, &o->city, &p[k]) || walk_path_write_csv(&p[k], file);
    if (!rc) printf("gi-walk: %s: %zu points on the streets (checked against building footprints) -> %s\n",
                    kinds[k].name, p[k].n, file);
  }
  FILE *json = (!rc && o->jsonl && !paths_only) ? fopen(o->jsonl, "a") : NULL;
  if (!rc && o->jsonl && !paths_only && !json) walk_file_error(o->jsonl);
  for (int k = 0; k < 2 && !rc && !paths_only; k++) {
    step_rec *st = calloc(p[k].n, sizeof *st);
    rc = !st || bench_path(o, s, &p[k], st);
    if (!rc) report_path(o, &p[k], st, json);
    free(st);
  }
  if (json) fclose(json);
  for (int k = 0; k < 2; k++) walk_path_free(&p[k]);
  gi_scene_release(s);
  return rc ? 1 : 0;
}

enum { O_EXTENT = 1, O_LEVELS, O_RES, O_SECONDS, O_RATE, O_SAMPLES, O_OUT, O_JSON, O_PATHS, O_LABEL, O_SCENE,
       O_UP, O_AT, O_MOVES, O_VDBMAX, O_MD, O_PATH };

static const struct option LONG_OPTS[] = {
    {"extent", required_argument, NULL, O_EXTENT}, {"levels", required_argument, NULL, O_LEVELS},
    {"res", required_argument, NULL, O_RES},       {"seconds", required_argument, NULL, O_SECONDS},
    {"rate", required_argument, NULL, O_RATE},     {"samples", required_argument, NULL, O_SAMPLES},
    {"out", required_argument, NULL, O_OUT},       {"json", required_argument, NULL, O_JSON},
    {"paths-only", no_argument, NULL, O_PATHS},    {"label", required_argument, NULL, O_LABEL},
    {"scene", required_argument, NULL, O_SCENE},   {"up", required_argument, NULL, O_UP},
    {"at", required_argument, NULL, O_AT},         {"moves", required_argument, NULL, O_MOVES},
    {"vdb-max", required_argument, NULL, O_VDBMAX}, {"md", required_argument, NULL, O_MD},
    {"path", required_argument, NULL, O_PATH},
    {NULL, 0, NULL, 0}};

typedef struct all_opts {
  bench_opts b;
  tables_opts t;
  const char *md;
  int paths_only, have_extent, up_given;
} all_opts;

static int parse_one(ta_ctx *ctx, int ch, const char *v, all_opts *a) {
  uint64_t u = 0;
  int r = 0;
  switch (ch) {
    case O_EXTENT: r = ta_double(ctx, "--extent", NULL, v, 0, 20000, &a->b.city.extent); a->have_extent = 1; break;
    case O_LEVELS: return ta_int(ctx, "--levels", NULL, v, 1, GI_MAX_LEVELS, &a->b.q.levels);
    case O_RES: {
      /* As gi-bake: 18 passed here and failed after the first outputs were written. */
      static const char what[] = "a multiple of 4 in 8..256";
      if (!(r = ta_int(ctx, "--res", what, v, 8, 256, &a->b.q.res)) && a->b.q.res % 4)
        r = ta_fail(ctx, "--res", "expected %s, got '%s'", what, v);
      return r;
    }
    case O_SECONDS: return ta_double(ctx, "--seconds", NULL, v, 0, 3600, &a->b.seconds);
    case O_RATE: return ta_double(ctx, "--rate", NULL, v, 0, 1000, &a->b.rate);
    case O_SAMPLES: return ta_int(ctx, "--samples", NULL, v, 0, 10000, &a->b.samples);
    case O_OUT: a->b.out_dir = v; break;
    case O_JSON: a->b.jsonl = v; break;
    case O_PATHS: a->paths_only = 1; break;
    case O_LABEL: a->t.label = v; break;
    case O_SCENE: a->t.scene_file = v; break;
    case O_UP:
      if (strcmp(v, "y") && strcmp(v, "z")) return ta_fail(ctx, "--up", "expected y or z, got '%s'", v);
      a->t.up = v[0] == 'z' ? GI_UP_Z : GI_UP_Y;
      a->up_given = 1;
      break;
    case O_AT: r = ta_triple(ctx, "--at", v, a->t.at); a->t.have_at = 1; break;
    case O_MOVES: return ta_int(ctx, "--moves", NULL, v, 0, 100000, &a->t.moves);
    case O_VDBMAX: r = ta_u64(ctx, "--vdb-max", NULL, v, &u); a->t.vdb_max_voxels = (size_t)u; break;
    case O_MD: a->md = v; break;
    case O_PATH: a->b.path_file = v; break;
    default: return TA_EXIT_USAGE;
  }
  return r;
}

static int run_tables(all_opts *a, ta_ctx *ctx) {
  if (!a->t.label || !a->md) return ta_fail(ctx, NULL, "tables needs --label and --md");
  if (!a->t.scene_file == !a->have_extent) return ta_fail(ctx, NULL, "tables needs --extent (the city) or --scene FILE");
  a->t.city = a->b.city;
  a->t.q = a->b.q;
  FILE *md = fopen(a->md, "a");
  if (!md) return walk_file_error(a->md), 1;
  int rc = tables_run(&a->t, md);
  fclose(md);
  return rc ? 1 : 0;
}

int main(int argc, char **argv) {
  ta_ctx ctx = TA_CTX("gi-walk");
  ta_memory_policy();
  int crc = ta_check_cpu_path(&ctx);
  if (crc) return crc;
  setvbuf(stdout, NULL, _IOLBF, 0); /* figures show up as they come, also through tee */
  /* --help or -h anywhere (gi-walk bench --help too) prints the usage. */
  for (int i = 1; i < argc; i++)
    if (!strcmp(argv[i], "--help") || !strcmp(argv[i], "-h")) return fputs(USAGE, stdout), 0;
  /* As gi-bake, gi-client and gi-server. */
  for (int i = 1; i < argc; i++)
    if (!strcmp(argv[i], "--version") || !strcmp(argv[i], "-V"))
      return printf("gi-walk %s\ncpu path: %s\n", ta_version(), gi_cpu_path()), 0;
  if (argc < 2 || (strcmp(argv[1], "bench") && strcmp(argv[1], "tables"))) return fputs(USAGE, stderr), 2;
  all_opts a = {.b = {.seconds = 60, .rate = 10, .samples = DEFAULT_SAMPLES, .out_dir = "out"},
                .t = {.moves = DEFAULT_MOVES, .vdb_max_voxels = DEFAULT_VDB_MAX}};
  int ch;
  optind = 2;
  unsigned char given[sizeof LONG_OPTS / sizeof LONG_OPTS[0]] = {0};
  while ((ch = getopt_long(argc, argv, ":", LONG_OPTS, NULL)) != -1) {
    if (ch == ':' || ch == '?') return ta_getopt_fail(&ctx, ch, argv, LONG_OPTS);
    /* Each value once: a second --out silently replaced the first. */
    int r = ta_once(&ctx, LONG_OPTS, ch, NULL, given);
    if (!r) r = parse_one(&ctx, ch, optarg, &a);
    if (r) return r;
  }
  if (optind < argc) return ta_fail(&ctx, NULL, "unexpected argument '%s'", argv[optind]);
  /* The city is y up: --up z without a file was taken and ignored. */
  if (a.up_given && !a.t.scene_file) return ta_fail(&ctx, "--up", "applies to a --scene file (the city is y up)");
  if (!strcmp(argv[1], "tables")) return run_tables(&a, &ctx);
  if (ta_mkdirs(&ctx, "--out", a.b.out_dir)) return 1;
  a.b.q.threads = 0;
  if (a.t.scene_file && !a.b.path_file)
    return ta_fail(&ctx, "--scene",
                   "bench takes a scene file with --path FILE only (its walk and drive follow the city's streets)");
  if (a.b.path_file) {
    if (a.paths_only) return ta_fail(&ctx, "--paths-only", "writes the city's generated paths; not with --path");
    a.b.scene_file = a.t.scene_file, a.b.up = a.t.up;
    return run_path_file(&a.b, &ctx);
  }
  return run_bench(&a.b, a.paths_only);
}
