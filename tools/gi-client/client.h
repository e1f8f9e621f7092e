/* client.h: gi-client's pieces shared between its files (options, points). */
#ifndef GI_CLIENT_H
#define GI_CLIENT_H

#include <curl/curl.h>
#include <stddef.h>
#include "toolargs.h"

/* Exit codes: 0 success, 1 the request failed (network, HTTP, I/O), 2 usage. */
enum { EXIT_RUN = TA_EXIT_RUN, EXIT_USAGE = TA_EXIT_USAGE };

typedef enum gc_command {
  GC_HEALTH, GC_SCENES, GC_SCENE, GC_METRICS, GC_JOB, GC_LIGHTING, GC_CASCADES, GC_PROBES, GC_WALK
} gc_command;

/* One step of a walk's path: its time (seconds) and viewpoint. */
typedef ta_step gc_step;

#define GC_MAX_SETS 16

/* One --set KEY=VALUE, checked for type (integer, number, 0|1, effects) by args.c. */
typedef struct gc_set {
  const char *key;
  const char *value;
  int is_int;        /* 1: value is an integer (JSON integer in a probes body) */
  int is_text;       /* 1: value is a word list (JSON string in a probes body): effects */
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
  const char *path_file;     /* walk: --path */
  gc_step *steps;            /* walk: the path, owned */
  size_t num_steps;
  double rate;               /* walk: steps per second; 0 = at once; < 0 = the path's t column */
  int json;                  /* walk: the summary as one JSON object */
} gc_opts;

/* Parses argv into o. Returns 0 on success, -1 when --help/--version was
 * printed (exit 0), or EXIT_USAGE / EXIT_RUN after printing the reason. */
int gc_parse(int argc, char **argv, gc_opts *o);
void gc_opts_fini(gc_opts *o);
/* cell.c: the cell URL (server included, malloc'ed) of a lighting or
 * cascades request, from the grid GET /v1/scenes/ID publishes; NULL when
 * the server gives none (then ask the viewpoint URL: it redirects). */
char *gc_cell_url(const gc_opts *o);

/* main.c: one request for other commands' files (walk.c). An answer kept
 * in memory (GC_MEM_ALL) or, for a 2xx, dropped after counting (GC_MEM_DROP). */
enum { GC_MEM_ALL = 2, GC_MEM_DROP = 3 };
typedef struct gc_response {
  long status;
  char *body;                /* GC_MEM_ALL, or an error body: malloc'ed */
  size_t body_len;
  char move[160];            /* X-GI-Move, or empty */
} gc_response;
/* 0 on a 2xx answer, else EXIT_RUN after printing why (status in r). method: GET, POST or DELETE. */
int gc_request(const gc_opts *o, CURL *c, const char *method, const char *url, const char *body, size_t len,
               int mem_mode, gc_response *r);
void gc_response_free(gc_response *r);
/* Shortest "%.*g" that reads back as the same double. */
void gc_fmt_double(char *dst, size_t cap, double v);
/* POST /v1/scenes/ID/sessions with the walk's first point and quality (malloc'ed). */
char *gc_session_url(const gc_opts *o, CURL *c);
/* GET .../sessions/SID/lighting?at=..[&kind=..] for one step of a walk,
 * the values percent-encoded as every query (a '+' would read as a space).
 * The caller frees it; NULL when out of memory. */
char *gc_step_url(const gc_opts *o, CURL *c, const char *sid, const double at[3]);
/* walk.c: the walk command. */
int gc_walk(const gc_opts *o, CURL *c);

#endif
