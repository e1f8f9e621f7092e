/* client.h: gi-client's pieces shared between its files (options, points). */
#ifndef GI_CLIENT_H
#define GI_CLIENT_H

#include <stddef.h>
#include "toolargs.h"

/* Exit codes: 0 success, 1 the request failed (network, HTTP, I/O), 2 usage. */
enum { EXIT_RUN = TA_EXIT_RUN, EXIT_USAGE = TA_EXIT_USAGE };

typedef enum gc_command {
  GC_HEALTH, GC_SCENES, GC_SCENE, GC_METRICS, GC_JOB, GC_LIGHTING, GC_CASCADES, GC_PROBES
} gc_command;

#define GC_MAX_SETS 16

/* One --set KEY=VALUE, checked for type (integer, number, 0|1) by args.c. */
typedef struct gc_set {
  const char *key;
  const char *value;
  int is_int;        /* 1: value is an integer (JSON integer in a probes body) */
} gc_set;

/* Everything the command line asked for, after strict parsing. */
typedef struct gc_opts {
  gc_command cmd;
  const char *cmd_name;
  const char *id;            /* scene id or job id; NULL for health/scenes/metrics */
  char *server;              /* base URL without trailing '/', owned */
  char *token;               /* bearer token or NULL, owned */
  long timeout_ms;           /* per HTTP request; 0 = none */
  const char *out;           /* -o, or NULL for stdout */
  int quiet;
  int have_at;
  double at[3];
  const char *at_text;       /* the --at argument as given (already checked) */
  const char *kind;          /* lighting: probe | panorama, NULL = server default */
  const char *quality;       /* low | default | high, NULL = server default */
  gc_set sets[GC_MAX_SETS];
  int num_sets;
  int faces, half, ao, no_wait;
  const char *points_file;
  double *points;            /* probes: 3 per point, owned */
  size_t num_points;
} gc_opts;

/* Parses argv into o. Returns 0 on success, -1 when --help/--version was
 * printed (exit 0), or EXIT_USAGE / EXIT_RUN after printing the reason. */
int gc_parse(int argc, char **argv, gc_opts *o);
void gc_opts_fini(gc_opts *o);
/* cell.c: the cell URL (server included, malloc'ed) of a lighting or
 * cascades request, from the grid GET /v1/scenes/ID publishes; NULL when
 * the server gives none (then ask the viewpoint URL: it redirects). */
char *gc_cell_url(const gc_opts *o);

#endif
