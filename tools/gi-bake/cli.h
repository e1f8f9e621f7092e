/* cli.h: gi-bake's pieces shared between its files (options, report). */
#ifndef GI_BAKE_CLI_H
#define GI_BAKE_CLI_H

#include <stddef.h>
#include <stdint.h>
#include "gi/gi.h"
#include "toolargs.h"
#include "batch.h"

/* Exit codes: 0 success, 1 the work failed (scene, bake, I/O), 2 usage. */
enum { EXIT_RUN = TA_EXIT_RUN, EXIT_USAGE = TA_EXIT_USAGE };

#define CLI_MAX_LIGHTS 64

/* --lightmap and its options (lightmap.c). */
typedef struct cli_lightmap {
  const char *out, *uv_out;
  gi_lightmap_opts opts;    /* zero fields = core defaults */
} cli_lightmap;
/* getopt_long values of the lightmap options (after args.c's own). */
enum { LM_OPT_OUT = 512, LM_OPT_UV_OUT, LM_OPT_TEXEL, LM_OPT_ATLAS, LM_OPT_TILE, LM_OPT_OWN_CHARTS }; /* --region: batch.h's, shared */

/* Everything the command line asked for, after strict parsing. */
typedef struct cli_opts {
  const char *scene;        /* a path, or "city" */
  int is_city;
  int have_at;
  double at[3];
  int up;                   /* 0 = not given, else GI_UP_Y / GI_UP_Z */
  gi_quality q;             /* zero fields = core defaults */
  const char *exr, *vdb, *probes_file;
  int half, vdb_faces, json, no_default_lights;
  gi_light lights[CLI_MAX_LIGHTS];
  size_t num_lights;
  gi_city_params city;
  int city_opts_given;      /* a --city-* option was used */
  unsigned char effect_given[GI_FX_COUNT]; /* --effect NAME=... seen for that NAME */
  int render, cam_up_from_scene, render_spp, render_stride;
  gi_camera cam;            /* --render */
  const char *png;
  double *probes;           /* extra points from --probes, 3 per point */
  size_t num_probes;
  cli_batch batch;          /* --grid and its options (batch.h) */
  cli_lightmap lm;          /* --lightmap */
} cli_opts;

/* Parses argv into o. Returns 0 on success, -1 when --help/--version was
 * printed (exit 0), or EXIT_USAGE / EXIT_RUN after printing the reason. */
int cli_parse(int argc, char **argv, cli_opts *o);
void cli_opts_fini(cli_opts *o);

/* What --render measured. */
typedef struct cli_render_stats {
  double cone_ms, path_ms, mre;
  int width, height, spp;
  gi_render_stats view;     /* the cone-traced view: its plan and cone counts */
} cli_render_stats;

/* What a finished run measured, for both output forms. */
typedef struct cli_run {
  const cli_opts *o;
  const gi_scene *scene;
  const gi_bake_report *rep;
  const gi_probe *probes;   /* viewpoint first, then o->probes */
  size_t num_probes;
  const double *points;     /* 3 per probe */
  const uint8_t *covered;   /* per probe: 1 inside the cascade (gi_cascade_covers) */
  double load_ms, gather_ms, encode_ms, total_ms;
  int threads;              /* resolved worker count */
  const cli_render_stats *render; /* NULL without --render */
} cli_run;

/* Prints the run as one JSON object (json = 1) or a human summary to
 * stdout. Returns 0, or EXIT_RUN after an internal error (a non-finite
 * number, which must never reach the output). */
int cli_report(const cli_run *r, int json);

/* The compact --render camera's up: the scene's up axis (z_up: z, else
 * y), or for a view along it north (+y for z up, -z for y up) at the top. */
void cli_render_up(gi_camera *cam, int z_up);

/* render.c: the --render pictures (cone-traced, path-traced, error) to
 * o->png and/or o->exr; fills st with what it measured. Returns 0,
 * EXIT_USAGE (bad camera for this scene) or EXIT_RUN. */
int cli_render(const cli_opts *o, const gi_scene *scene, const gi_cascade *cas, cli_render_stats *st);

/* lightmap.c: one lightmap option (LM_OPT_*) into o->lm; the checks of
 * the lightmap options and their combinations (0 or an exit code); the
 * --lightmap run on a loaded scene (0, EXIT_USAGE or EXIT_RUN), which
 * took load_ms to load. */
int lightmap_option(cli_opts *o, int c, const char *arg);
int lightmap_check(cli_opts *o);
int lightmap_run(const cli_opts *o, const gi_scene *scene, double t_start_ms, double load_ms, double (*now_ms)(void));

#endif
