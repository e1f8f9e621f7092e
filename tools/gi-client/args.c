/* args.c: gi-client's command line, parsed strictly.
 *
 * Design: options may come before or after COMMAND (getopt permutes), but
 * each command accepts only the options that mean something for it: an
 * option that would be ignored is an error, not a surprise. Numbers are
 * checked for form here by the tools' shared rule (tools/common/toolargs.h:
 * plain decimals, whole string, finite, integer where the server wants
 * one); ranges that depend on the server's config (max_levels, max_res, ...)
 * are left to the server, which answers 400 naming the field.
 * Then the query goes through the contract's own parser (proto/request.c,
 * with the widest limits the core allows), so what the server would refuse
 * whatever its config (cones=5, res=30, width without a panorama) is refused
 * here with the server's wording. Every usage error prints
 * "gi-client: --opt: ..." and exits 2; files that cannot be read
 * (--token-file, --points) exit 1 like any other I/O error. */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <getopt.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "client.h"
#include "gi_proto.h"
#include "toolargs.h"

#define MAX_POINTS ((size_t)1 << 24) /* the server's job limit is far below this */
#define DEFAULT_SERVER "http://127.0.0.1:8080"

enum {
  OPT_SERVER = 256, OPT_TOKEN, OPT_TOKEN_FILE, OPT_TIMEOUT, OPT_AT, OPT_KIND, OPT_QUALITY, OPT_SET,
  OPT_FACES, OPT_HALF, OPT_AO, OPT_NO_WAIT, OPT_POINTS, OPT_PATH, OPT_RATE, OPT_JSON
};

/* Options that apply to some commands only, as bits of a per-command mask. */
enum {
  F_AT = 1 << 0, F_KIND = 1 << 1, F_QUALITY = 1 << 2, F_SET = 1 << 3, F_FACES = 1 << 4,
  F_HALF = 1 << 5, F_AO = 1 << 6, F_NO_WAIT = 1 << 7, F_POINTS = 1 << 8, F_PATH = 1 << 9, F_RATE = 1 << 10,
  F_JSON = 1 << 11
};

static const struct {
  int bit;
  const char *name;
} flag_names[] = {{F_AT, "--at"},       {F_KIND, "--kind"}, {F_QUALITY, "--quality"},
                  {F_SET, "--set"},     {F_FACES, "--faces"}, {F_HALF, "--half"},
                  {F_AO, "--ao"},       {F_NO_WAIT, "--no-wait"}, {F_POINTS, "--points"},
                  {F_PATH, "--path"},   {F_RATE, "--rate"}, {F_JSON, "--json"}};

static const struct {
  const char *name;
  gc_command cmd;
  int takes_id;     /* 1: scene id, 2: job id */
  int allowed;      /* F_* bits */
  int needs_out;    /* binary answer: -o is required */
  const char *set_keys; /* --set keys allowed, space-separated */
} commands[] = {
    {"health", GC_HEALTH, 0, 0, 0, ""},
    {"scenes", GC_SCENES, 0, 0, 0, ""},
    {"scene", GC_SCENE, 1, 0, 0, ""},
    {"metrics", GC_METRICS, 0, 0, 0, ""},
    {"job", GC_JOB, 2, 0, 0, ""},
    {"lighting", GC_LIGHTING, 1, F_AT | F_KIND | F_QUALITY | F_SET, 1,
     "levels res voxel cones aperture step bounces samples probe_samples seed ao half width height effects"},
    /* probe_samples and ao act at gather points only: a cascade does not change with them. */
    {"cascades", GC_CASCADES, 1, F_AT | F_FACES | F_QUALITY | F_SET, 1,
     "levels res voxel cones aperture step bounces samples seed effects"},
    {"probes", GC_PROBES, 1, F_AT | F_QUALITY | F_SET | F_HALF | F_AO | F_NO_WAIT | F_POINTS, 1,
     "levels res voxel cones aperture step bounces samples probe_samples seed effects"},
    {"walk", GC_WALK, 1, F_KIND | F_QUALITY | F_SET | F_PATH | F_RATE | F_JSON, 0,
     "levels res voxel cones aperture step bounces samples probe_samples seed effects"},
};

static const struct option long_opts[] = {
    {"server", required_argument, NULL, OPT_SERVER},
    {"token", required_argument, NULL, OPT_TOKEN},
    {"token-file", required_argument, NULL, OPT_TOKEN_FILE},
    {"timeout", required_argument, NULL, OPT_TIMEOUT},
    {"output", required_argument, NULL, 'o'},
    {"quiet", no_argument, NULL, 'q'},
    {"at", required_argument, NULL, OPT_AT},
    {"kind", required_argument, NULL, OPT_KIND},
    {"quality", required_argument, NULL, OPT_QUALITY},
    {"set", required_argument, NULL, OPT_SET},
    {"faces", no_argument, NULL, OPT_FACES},
    {"half", no_argument, NULL, OPT_HALF},
    {"ao", no_argument, NULL, OPT_AO},
    {"no-wait", no_argument, NULL, OPT_NO_WAIT},
    {"points", required_argument, NULL, OPT_POINTS},
    {"path", required_argument, NULL, OPT_PATH},
    {"rate", required_argument, NULL, OPT_RATE},
    {"json", no_argument, NULL, OPT_JSON},
    {"help", no_argument, NULL, 'h'},
    {"version", no_argument, NULL, 'V'},
    {NULL, 0, NULL, 0}};

static const char help_text[] =
    "Usage: gi-client [global options] COMMAND [ID] [command options]\n"
    "A thin command-line client for gi-server's HTTP API (see proto/openapi.yaml).\n"
    "\n"
    "Global options (may also follow COMMAND)\n"
    "  --server URL          server base URL, http:// or https:// (default\n"
    "                        " DEFAULT_SERVER ", or $GI_SERVER)\n"
    "  --token T             bearer token (default $GI_TOKEN); every endpoint but\n"
    "                        health needs it when the server has one configured\n"
    "  --token-file F        read the token from file F (surrounding blanks and the\n"
    "                        final newline are ignored); not with --token\n"
    "  --timeout SECONDS     limit for each HTTP request, > 0 (default: none; the\n"
    "                        server answers 504 after its own deadline)\n"
    "  -o, --output OUT      write the answer to OUT (via OUT.tmp.<pid>, renamed on\n"
    "                        success: a failed request leaves an existing OUT as it\n"
    "                        was); default stdout for text answers\n"
    "  -q, --quiet           no progress, no Server-Timing / X-GI-Cache lines\n"
    "  -h, --help            this text;  -V, --version  the version\n"
    "\n"
    "Commands that print a JSON or text body (to stdout, or to -o OUT)\n"
    "  health                GET /v1/health (needs no token)\n"
    "  scenes                GET /v1/scenes\n"
    "  scene ID              GET /v1/scenes/ID: bounds, lights, quality, effect plan\n"
    "  metrics               GET /metrics (Prometheus text)\n"
    "  job JOBID             GET /v1/jobs/JOBID: state and progress of a probe job\n"
    "\n"
    "Commands that download a file (-o OUT required; probes --no-wait excepted)\n"
    "  lighting ID --at X,Y,Z [--kind probe|panorama] [--quality Q] [--set K=V ...]\n"
    "                        GET /v1/scenes/ID/lighting -> EXR (kind default probe)\n"
    "  cascades ID --at X,Y,Z [--faces] [--quality Q] [--set K=V ...]\n"
    "                        GET /v1/scenes/ID/cascades.vdb -> VDB; --faces adds the\n"
    "                        six per-face radiance grids\n"
    "  probes ID --points FILE [--at X,Y,Z] [--quality Q] [--set K=V ...] [--half]\n"
    "            [--ao] [--no-wait]\n"
    "                        POST /v1/scenes/ID/probes -> EXR, one pixel per point.\n"
    "                        FILE: one 'x y z' per line, '#' comments, blank lines\n"
    "                        ok (the format of gi-bake --probes). A large set becomes\n"
    "                        a job: gi-client polls it (progress bar on a terminal,\n"
    "                        a line per 10% otherwise) and downloads the result;\n"
    "                        Ctrl-C while it polls cancels the job (DELETE) and\n"
    "                        exits 130. --no-wait prints the job on stdout instead\n"
    "                        (see 'job JOBID') and needs no -o, but a list the\n"
    "                        server answers at once is an EXR: without -o that is\n"
    "                        an error (exit 1)\n"
    "\n"
    "  --at X,Y,Z            viewpoint, three finite numbers in world units\n"
    "  --quality Q           preset: low, default or high\n"
    "  --set KEY=VALUE       one more quality parameter, repeatable, each key once,\n"
    "                        overriding the preset: levels, res (multiple of 4),\n"
    "                        cones (4,6,8,16,32), bounces (0 = none), samples,\n"
    "                        probe_samples, seed (integers); voxel (finest voxel,\n"
    "                        world units), aperture (degrees), step (fraction of\n"
    "                        the cone diameter) (numbers > 0); lighting also\n"
    "                        ao=0|1, half=0|1, width, height (panorama only,\n"
    "                        default 256x128); cascades takes no probe_samples.\n"
    "                        effects=NAME:on|off|auto[,...] overrides the effect\n"
    "                        plan, e.g. effects=sky:off,ao:on (NAME: sun,\n"
    "                        local_lights, sky, emissive, bounce, specular, ao;\n"
    "                        each once).\n"
    "                        Ranges come from the server's config: it answers\n"
    "                        400 naming the parameter\n"
    "  --half, --ao          probes: half-float EXR; ambient occlusion channel\n"
    "\n"
    "A walk through a server session (prints a summary on stdout)\n"
    "  walk ID --path FILE [--rate HZ] [--kind probe|panorama] [--quality Q]\n"
    "          [--set K=V ...] [--json]\n"
    "                        POST /v1/scenes/ID/sessions at the path's first point,\n"
    "                        GET /v1/sessions/SID/lighting at every point (the\n"
    "                        server moves the session's cascade), DELETE at the end\n"
    "                        (also on Ctrl-C). FILE: one 't,x,y,z' per line (t in\n"
    "                        seconds, not decreasing), '#' comments, an optional\n"
    "                        header line of four names (t,x,y,z). Steps are paced\n"
    "                        by t, or --rate HZ steps per second (0: as fast as the\n"
    "                        server answers). Prints steps, moves that crossed a\n"
    "                        cell, refresh cycles closed, errors and the latency's\n"
    "                        p50/p90/p99/max; --json: one JSON object\n"
    "\n"
    "The server's Server-Timing and X-GI-Cache headers are printed on stderr\n"
    "unless -q. An error answer prints 'gi-client: HTTP <status> <name>: <message>'.\n"
    "\n"
    "Exit status: 0 success, 1 the request failed (network error, HTTP status not\n"
    "2xx, failed job, unwritable output), 2 bad arguments, 130 a walk stopped by\n"
    "Ctrl-C (its summary printed, its session deleted) or a probe job's wait\n"
    "stopped by Ctrl-C (the job cancelled).\n"
    "\n"
    "Examples\n"
    "  gi-client health\n"
    "  gi-client lighting city --at 10,1.7,-4 --quality high -o probe.exr\n"
    "  gi-client lighting city --at 10,1.7,-4 --kind panorama --set width=512 \\\n"
    "            --set height=256 -o pano.exr\n"
    "  gi-client cascades city --at 10,1.7,-4 --set levels=4 -o city.vdb\n"
    "  GI_TOKEN=s3cret-token-0123456 gi-client probes city --points pts.txt -o probes.exr\n";

static ta_ctx ta = TA_CTX("gi-client");

/* "http://host[:port][/prefix]" or https; returns a copy without trailing '/'. */
static char *check_server(const char *s) {
  if (strncmp(s, "http://", 7) && strncmp(s, "https://", 8)) return NULL;
  const char *host = strstr(s, "://") + 3;
  if (!*host || *host == '/') return NULL;
  for (const char *p = s; *p; p++)
    if ((unsigned char)*p <= ' ' || *p == 0x7f || *p == '?' || *p == '#') return NULL;
  char *c = strdup(s);
  if (!c) return NULL;
  size_t n = strlen(c);
  while (n && c[n - 1] == '/') c[--n] = '\0';
  return c;
}

/* A bearer token is sent in a header: refuse blanks and control bytes, which
 * would split or corrupt it. */
static int token_ok(const char *t) {
  if (!*t) return 0;
  for (const unsigned char *p = (const unsigned char *)t; *p; p++)
    if (*p <= ' ' || *p == 0x7f) return 0;
  return 1;
}

static int read_token_file(gc_opts *o, const char *path) {
  FILE *f = fopen(path, "r");
  if (!f) return ta_error(&ta, EXIT_RUN, "--token-file", "cannot open '%s': %s", path, strerror(errno));
  char buf[4097];
  size_t n = fread(buf, 1, sizeof buf - 1, f);
  int err = ferror(f), more = !feof(f) && fgetc(f) != EOF;
  fclose(f);
  if (err) return ta_error(&ta, EXIT_RUN, "--token-file", "cannot read '%s'", path);
  if (more) return ta_fail(&ta, "--token-file", "'%s' is longer than %zu bytes", path, sizeof buf - 1);
  buf[n] = '\0';
  char *p = buf;
  while (*p == ' ' || *p == '\t' || *p == '\r' || *p == '\n') p++;
  while (n && (buf[n - 1] == ' ' || buf[n - 1] == '\t' || buf[n - 1] == '\r' || buf[n - 1] == '\n'))
    buf[--n] = '\0';
  if (!token_ok(p))
    return ta_fail(&ta, "--token-file", "'%s' must hold one token without blanks or control characters", path);
  o->token = strdup(p);
  return o->token ? 0 : EXIT_RUN;
}

/* Reads --points FILE (gi_points.h, as gi-bake --probes). Returns 0, EXIT_RUN
 * (cannot read) or EXIT_USAGE (a bad line, named by file and number). */
static int read_points(gc_opts *o, const char *path) {
  return ta_read_points(&ta, "--points", path, MAX_POINTS, &o->points, &o->num_points);
}

/* effects=NAME:MODE[,...] through the contract's own parser (the server's
 * wording and effect names); the value goes into a probes body as a JSON
 * string unescaped, which this keeps safe: names and modes are plain words. */
static int check_effects(const char *label, const char *val) {
  gi_proto_kv kv[] = {{"at", "0,0,0"}, {"effects", val}};
  gi_proto_limits lim;
  gi_proto_limits_default(&lim);
  gi_proto_bake b;
  gi_proto_error e;
  if (!gi_proto_parse_lighting(kv, 2, &lim, &b, &e)) return 0;
  /* The label names the key already. */
  const char *m = e.message, *tag = "parameter 'effects': ";
  if (!strncmp(m, tag, strlen(tag))) m += strlen(tag);
  return ta_fail(&ta, label, "%s", m);
}

/* Checks one --set KEY=VALUE for form; the command's key list is checked later. */
static int add_set(gc_opts *o, char *arg) {
  char *eq = strchr(arg, '=');
  if (!eq || eq == arg || !eq[1]) return ta_fail(&ta, "--set", "expected KEY=VALUE, got '%s'", arg);
  if (o->num_sets >= GC_MAX_SETS) return ta_fail(&ta, "--set", "at most %d are allowed", GC_MAX_SETS);
  *eq = '\0'; /* argv strings are writable; the key is used alone from now on */
  const char *key = arg, *val = eq + 1;
  for (int i = 0; i < o->num_sets; i++)
    if (!strcmp(o->sets[i].key, key)) return ta_fail(&ta, "--set", "'%s' given twice", key);
  char label[64]; /* "--set: KEY" */
  snprintf(label, sizeof label, "--set: %s", key);
  long long l;
  double d;
  int is_int = 1, is_text = 0, rc = 0;
  if (!strcmp(key, "effects")) {
    rc = check_effects(label, val);
    is_int = 0, is_text = 1;
  } else if (!strcmp(key, "ao") || !strcmp(key, "half")) {
    if (strcmp(val, "0") && strcmp(val, "1")) rc = ta_fail(&ta, label, "expected 0 or 1, got '%s'", val);
  } else if (!strcmp(key, "voxel") || !strcmp(key, "aperture") || !strcmp(key, "step")) {
    rc = ta_double(&ta, label, "a finite number > 0", val, 0, HUGE_VAL, &d);
    is_int = 0;
  } else if (!strcmp(key, "bounces")) {
    rc = ta_ll(&ta, label, "an integer >= 0", val, 0, 1000000, &l);
  } else if (!strcmp(key, "levels") || !strcmp(key, "res") || !strcmp(key, "cones") || !strcmp(key, "samples") ||
             !strcmp(key, "probe_samples") || !strcmp(key, "width") || !strcmp(key, "height") ||
             !strcmp(key, "seed")) {
    rc = ta_ll(&ta, label, "an integer >= 1", val, 1, 9007199254740992LL, &l);
  } else {
    rc = ta_fail(&ta, "--set", "unknown key '%s' (levels, res, voxel, cones, aperture, step, bounces, samples, "
                 "probe_samples, seed, ao, half, width, height, effects)", key);
  }
  if (rc) return rc;
  o->sets[o->num_sets++] = (gc_set){key, val, is_int, is_text};
  return 0;
}

/* Is word in the space-separated list? */
static int in_list(const char *list, const char *word) {
  size_t n = strlen(word);
  for (const char *p = list; (p = strstr(p, word)); p += n)
    if ((p == list || p[-1] == ' ') && (p[n] == ' ' || !p[n])) return 1;
  return 0;
}

/* Runs the query (or, for probes, the knobs) through the server's parser with
 * config-independent limits. Returns 0 or EXIT_USAGE. */
static int check_with_proto(const gc_opts *o) {
  gi_proto_kv kv[GC_MAX_SETS + 4];
  size_t n = 0;
  kv[n++] = (gi_proto_kv){"at", o->at_text ? o->at_text : "0,0,0"};
  if (o->kind) kv[n++] = (gi_proto_kv){"kind", o->kind};
  if (o->quality) kv[n++] = (gi_proto_kv){"quality", o->quality};
  if (o->faces) kv[n++] = (gi_proto_kv){"faces", "1"};
  for (int i = 0; i < o->num_sets; i++) kv[n++] = (gi_proto_kv){o->sets[i].key, o->sets[i].value};
  gi_proto_limits lim;
  gi_proto_limits_default(&lim);
  lim.max_levels = GI_MAX_LEVELS; /* the server's own limits may be lower: it says so */
  lim.max_res = 256;
  lim.max_panorama_pixels = 16384LL * 16384;
  gi_proto_bake b;
  gi_proto_error e;
  int rc = o->cmd == GC_CASCADES ? gi_proto_parse_cascades(kv, n, &lim, &b, &e)
                                 : gi_proto_parse_lighting(kv, n, &lim, &b, &e);
  if (!rc) return 0;
  /* Our limits are not the server's: do not call them that. */
  char *tag = strstr(e.message, " (server limit)");
  if (tag) memmove(tag, tag + 15, strlen(tag + 15) + 1);
  return ta_fail(&ta, o->num_sets ? "--set" : NULL, "%s", e.message);
}

/* A walk's quality knobs through the session parser (as check_with_proto). */
static int check_session_knobs(const gc_opts *o) {
  gi_proto_kv kv[GC_MAX_SETS + 1];
  size_t n = 0;
  if (o->quality) kv[n++] = (gi_proto_kv){"quality", o->quality};
  for (int i = 0; i < o->num_sets; i++) kv[n++] = (gi_proto_kv){o->sets[i].key, o->sets[i].value};
  gi_proto_limits lim;
  gi_proto_limits_default(&lim);
  lim.max_levels = GI_MAX_LEVELS;
  lim.max_res = 256;
  gi_proto_bake b;
  gi_proto_error e;
  if (!gi_proto_parse_session(kv, n, NULL, 0, &lim, &b, &e)) return 0;
  char *tag = strstr(e.message, " (server limit)");
  if (tag) memmove(tag, tag + 15, strlen(tag + 15) + 1);
  return ta_fail(&ta, o->num_sets ? "--set" : NULL, "%s", e.message);
}

/* What the options said before the command is known. */
typedef struct pending {
  const char *server, *token, *token_file;
  int given; /* F_* bits of the options used */
} pending;

/* The options of the download commands: --at .. --points. */
static int command_option(gc_opts *o, pending *p, int c, char *arg) {
  int rc = 0;
  switch (c) {
  case OPT_AT:
    if ((rc = ta_triple(&ta, "--at", arg, o->at))) return rc;
    o->have_at = 1;
    o->at_text = arg;
    p->given |= F_AT;
    return 0;
  case OPT_KIND:
    if (strcmp(arg, "probe") && strcmp(arg, "panorama"))
      return ta_fail(&ta, "--kind", "expected probe or panorama, got '%s'", arg);
    o->kind = arg;
    p->given |= F_KIND;
    return 0;
  case OPT_QUALITY:
    if (strcmp(arg, "low") && strcmp(arg, "default") && strcmp(arg, "high"))
      return ta_fail(&ta, "--quality", "expected low, default or high, got '%s'", arg);
    o->quality = arg;
    p->given |= F_QUALITY;
    return 0;
  case OPT_SET:
    if ((rc = add_set(o, arg))) return rc;
    p->given |= F_SET;
    return 0;
  case OPT_FACES: o->faces = 1; p->given |= F_FACES; return 0;
  case OPT_HALF: o->half = 1; p->given |= F_HALF; return 0;
  case OPT_AO: o->ao = 1; p->given |= F_AO; return 0;
  case OPT_NO_WAIT: o->no_wait = 1; p->given |= F_NO_WAIT; return 0;
  case OPT_PATH: o->path_file = arg; p->given |= F_PATH; return 0;
  case OPT_RATE:
    if ((rc = ta_double(&ta, "--rate", "steps per second >= 0", arg, -1e-300, 1e6, &o->rate))) return rc;
    p->given |= F_RATE;
    return 0;
  case OPT_JSON: o->json = 1; p->given |= F_JSON; return 0;
  default: o->points_file = arg; p->given |= F_POINTS; return 0;
  }
}

/* One option from getopt_long. Returns 0, -1 (--help/--version printed) or an exit code. */
static int apply_option(gc_opts *o, pending *p, int c, char *arg, char **argv) {
  double d;
  int rc;
  switch (c) {
  case 'h': fputs(help_text, stdout); return -1;
  case 'V': printf("gi-client %s\n", ta_version()); return -1;
  case OPT_SERVER: p->server = arg; return 0;
  case OPT_TOKEN:
    if (!token_ok(arg)) return ta_fail(&ta, "--token", "expected a token without blanks or control characters");
    p->token = arg;
    return 0;
  case OPT_TOKEN_FILE: p->token_file = arg; return 0;
  case OPT_TIMEOUT:
    if ((rc = ta_double(&ta, "--timeout", "seconds in (0, 1e6]", arg, 0, 1e6, &d))) return rc;
    o->timeout_ms = (long)ceil(d * 1000.0);
    return 0;
  case 'o': o->out = arg; return 0;
  case 'q': o->quiet = 1; return 0;
  case OPT_AT: case OPT_KIND: case OPT_QUALITY: case OPT_SET: case OPT_FACES: case OPT_HALF: case OPT_AO:
  case OPT_NO_WAIT: case OPT_POINTS: case OPT_PATH: case OPT_RATE: case OPT_JSON:
    return command_option(o, p, c, arg);
  default: return ta_getopt_fail(&ta, c, argv, long_opts);
  }
}

/* COMMAND and its ID, after the options; *ci = its row in commands[]. */
static int take_command(int argc, char **argv, gc_opts *o, int *ci) {
  if (optind >= argc)
    return ta_fail(&ta, NULL, "missing COMMAND (health, scenes, scene, metrics, job, lighting, cascades, probes, walk)");
  const char *cmd = argv[optind++];
  *ci = -1;
  for (size_t i = 0; i < sizeof commands / sizeof commands[0]; i++)
    if (!strcmp(commands[i].name, cmd)) *ci = (int)i;
  if (*ci < 0)
    return ta_fail(&ta, NULL,
                   "unknown command '%s' (health, scenes, scene, metrics, job, lighting, cascades, probes, walk)", cmd);
  o->cmd = commands[*ci].cmd;
  o->cmd_name = commands[*ci].name;
  if (commands[*ci].takes_id) {
    const char *what = commands[*ci].takes_id == 2 ? "JOBID" : "scene ID";
    if (optind >= argc) return ta_fail(&ta, cmd, "missing %s", what);
    o->id = argv[optind++];
    if (!*o->id) return ta_fail(&ta, cmd, "%s must not be empty", what);
  }
  if (optind < argc) return ta_fail(&ta, cmd, "unexpected argument '%s'", argv[optind]);
  return 0;
}

/* Every option given must mean something for the command; what it needs must be there. */
static int check_command_options(const gc_opts *o, int ci, int given) {
  const char *cmd = commands[ci].name;
  int rc;
  for (size_t i = 0; i < sizeof flag_names / sizeof flag_names[0]; i++)
    if ((given & flag_names[i].bit) && !(commands[ci].allowed & flag_names[i].bit))
      return ta_fail(&ta, flag_names[i].name, "does not apply to '%s'", cmd);
  for (int i = 0; i < o->num_sets; i++)
    if (!in_list(commands[ci].set_keys, o->sets[i].key))
      return ta_fail(&ta, "--set", "'%s' does not apply to '%s' (allowed: %s)", o->sets[i].key, cmd,
                     commands[ci].set_keys);
  if ((o->cmd == GC_LIGHTING || o->cmd == GC_CASCADES) && !o->have_at)
    return ta_fail(&ta, "--at", "'%s' needs a viewpoint --at X,Y,Z", cmd);
  if (o->cmd == GC_LIGHTING && (!o->kind || strcmp(o->kind, "panorama")))
    for (int i = 0; i < o->num_sets; i++)
      if (!strcmp(o->sets[i].key, "width") || !strcmp(o->sets[i].key, "height"))
        return ta_fail(&ta, "--set", "'%s' applies only to --kind panorama", o->sets[i].key);
  if (o->cmd == GC_PROBES && !o->points_file) return ta_fail(&ta, "--points", "'probes' needs --points FILE");
  if (o->cmd == GC_WALK && !o->path_file) return ta_fail(&ta, "--path", "'walk' needs --path FILE");
  if (o->cmd == GC_WALK && (rc = check_session_knobs(o))) return rc;
  if ((o->cmd == GC_LIGHTING || o->cmd == GC_CASCADES || o->cmd == GC_PROBES) && (rc = check_with_proto(o)))
    return rc;
  /* --no-wait prints the job: -o is needed only if the server answers the list at once (main.c). */
  if (commands[ci].needs_out && !o->out && !(o->cmd == GC_PROBES && o->no_wait))
    return ta_fail(&ta, "-o", "'%s' downloads a file: give -o OUT", cmd);
  return 0;
}

/* --server, else $GI_SERVER, else the default. */
static int resolve_server(gc_opts *o, const char *server) {
  if (server) {
    if (!(o->server = check_server(server)))
      return ta_fail(&ta, "--server", "expected an http:// or https:// URL, got '%s'", server);
    return 0;
  }
  const char *env = getenv("GI_SERVER");
  if (env && *env) {
    if (!(o->server = check_server(env)))
      return ta_fail(&ta, "GI_SERVER", "expected an http:// or https:// URL, got '%s'", env);
    return 0;
  }
  return (o->server = strdup(DEFAULT_SERVER)) ? 0 : EXIT_RUN;
}

/* --token-file, else --token, else $GI_TOKEN, else none. */
static int resolve_token(gc_opts *o, const pending *p) {
  if (p->token_file) return read_token_file(o, p->token_file);
  if (p->token) return (o->token = strdup(p->token)) ? 0 : EXIT_RUN;
  const char *env = getenv("GI_TOKEN");
  if (!env || !*env) return 0;
  if (!token_ok(env)) return ta_fail(&ta, "GI_TOKEN", "expected a token without blanks or control characters");
  return (o->token = strdup(env)) ? 0 : EXIT_RUN;
}

int gc_parse(int argc, char **argv, gc_opts *o) {
  memset(o, 0, sizeof *o);
  o->rate = -1; /* walk: the path's own times */
  opterr = 0; /* our messages, with our program name */
  pending p = {0};
  int c, rc, ci = -1;
  /* --set repeats (one key each); every other value is given at most once. */
  static const int repeatable[] = {OPT_SET, 0};
  unsigned char given[sizeof long_opts / sizeof long_opts[0]] = {0};
  while ((c = getopt_long(argc, argv, ":o:qhV", long_opts, NULL)) != -1)
    if ((rc = ta_once(&ta, long_opts, c, repeatable, given)) || (rc = apply_option(o, &p, c, optarg, argv)))
      return rc;
  if ((rc = take_command(argc, argv, o, &ci))) return rc;
  if ((rc = check_command_options(o, ci, p.given))) return rc;
  if (p.token && p.token_file) return ta_fail(&ta, "--token-file", "give --token or --token-file, not both");
  if ((rc = resolve_server(o, p.server))) return rc;
  if ((rc = resolve_token(o, &p))) return rc;
  if (o->out && (rc = ta_check_output(&ta, "-o", &o->out))) return rc;
  if (o->points_file && (rc = read_points(o, o->points_file))) return rc;
  if (o->path_file && (rc = ta_read_path(&ta, "--path", o->path_file, &o->steps, &o->num_steps))) return rc;
  return 0;
}

void gc_opts_fini(gc_opts *o) {
  free(o->server);
  free(o->token);
  free(o->points);
  free(o->steps);
  o->steps = NULL;
  o->server = o->token = NULL;
  o->points = NULL;
}
