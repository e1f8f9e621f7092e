/* gi_proto.h: the HTTP contract in C (openapi.yaml says the same in YAML).
 *
 * Parses and validates requests (query parameters and JSON bodies) into
 * plain structs, and encodes and decodes the JSON answers that both sides
 * read: errors and job status. Shared by gi-server and gi-client. No
 * sockets, no globals: every function is a pure function of its arguments
 * and thread-safe. Strings returned as char* are malloc'ed and owned by the
 * caller (free()); everything else is caller-allocated. */
#ifndef GI_PROTO_H
#define GI_PROTO_H

#include <stddef.h>
#include "gi/gi_bake.h"

#ifdef __cplusplus
extern "C" {
#endif

/* An error answer: HTTP status, snake_case name, and a message that names
 * the parameter or field and what was expected. */
typedef struct gi_proto_error {
  int status;
  char name[32];
  char message[384];
} gi_proto_error;

/* Fills e (status, its name, printf message) and returns status. */
int gi_proto_fail(gi_proto_error *e, int status, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));
/* The error name of an HTTP status ("bad_request" for 400...); never NULL. */
const char *gi_proto_status_name(int status);
/* {"code":status,"name":...,"message":...} */
char *gi_proto_error_json(const gi_proto_error *e);
/* Reads an error body back; returns 0, or -1 when it is not one. */
int gi_proto_error_parse(const char *json, size_t len, gi_proto_error *out);

/* Coordinates (viewpoints, probe points) beyond this are out of range
 * whatever the scene: products of such values stay finite. (The server
 * also refuses points more than 1e9 units from its scene, as the core does.) */
#define GI_PROTO_MAX_COORD 1e30
/* A panorama's width and height: the core's gi_cascade_panorama limits
 * (2..16384 x 1..8192), checked here so a refusal costs no bake. */
#define GI_PROTO_MAX_PANORAMA_WIDTH 16384
#define GI_PROTO_MAX_PANORAMA_HEIGHT 8192

/* Request limits (from the server's config). */
typedef struct gi_proto_limits {
  int max_levels;                  /* cascade levels per request */
  int max_res;                     /* voxels per side per request */
  long long max_panorama_pixels;   /* width * height */
  size_t max_probes_inline;        /* POST probes answered directly */
  size_t max_probes_job;           /* POST probes accepted at all */
  size_t max_body_bytes;
} gi_proto_limits;
void gi_proto_limits_default(gi_proto_limits *l);

typedef enum gi_proto_kind { GI_PROTO_PROBE = 0, GI_PROTO_PANORAMA = 1, GI_PROTO_LIGHTMAP = 2 } gi_proto_kind;

/* Hex digits of a cell URL's quality hash (q=). */
#define GI_PROTO_QHASH_LEN 16

/* One query parameter, already URL-decoded (the server's HTTP library does it). */
typedef struct gi_proto_kv {
  const char *key;
  const char *value;
} gi_proto_kv;

/* What to bake and what to answer. quality holds only what the request
 * set (zero = the core's default), so it resolves like gi-bake's knobs. */
typedef struct gi_proto_bake {
  int has_at;
  double at[3];
  gi_proto_kind kind;
  gi_quality quality;
  int half;          /* EXR pixels as HALF */
  int faces;         /* VDB: per-face radiance grids too */
  int width, height; /* panorama size */
  int has_region;    /* kind=lightmap: region given (else level 0's box around at) */
  double region[6];  /* min x,y,z then max x,y,z, world */
  double texel;      /* lightmap texel, world units; 0 = level 0's voxel */
  int atlas;         /* lightmap atlas side; 0 = GI_PROTO_DEFAULT_LIGHTMAP_ATLAS */
  int redirect;      /* viewpoint URLs: 1 (default) answers 307 to the cell's URL, 0 serves it */
  int cell;          /* a cell URL: at is the cell's centre (set by the server) */
  char q[GI_PROTO_QHASH_LEN + 1]; /* cell URLs: the quality hash */
} gi_proto_bake;

/* Lightmap atlas sides the server accepts (one atlas per answer). */
#define GI_PROTO_MIN_LIGHTMAP_ATLAS 16
#define GI_PROTO_MAX_LIGHTMAP_ATLAS 4096
#define GI_PROTO_DEFAULT_LIGHTMAP_ATLAS 1024

/* GET /v1/scenes/{id}/lighting. Returns 0 or the error status (400). */
int gi_proto_parse_lighting(const gi_proto_kv *kv, size_t n, const gi_proto_limits *lim,
                            gi_proto_bake *out, gi_proto_error *err);
/* GET /v1/scenes/{id}/lightmap-uv.glb: the lightmap's geometry for the
 * same parameters as kind=lightmap (sets kind to GI_PROTO_LIGHTMAP). */
int gi_proto_parse_lightmap_uv(const gi_proto_kv *kv, size_t n, const gi_proto_limits *lim, gi_proto_bake *out,
                               gi_proto_error *err);
/* GET /v1/scenes/{id}/cascades.vdb. */
int gi_proto_parse_cascades(const gi_proto_kv *kv, size_t n, const gi_proto_limits *lim,
                            gi_proto_bake *out, gi_proto_error *err);
/* GET /v1/scenes/{id}/cells/{i},{j},{k}/lighting: as lighting without 'at'
 * and 'redirect', with 'q' required; sets out->cell. */
int gi_proto_parse_cell_lighting(const gi_proto_kv *kv, size_t n, const gi_proto_limits *lim,
                                 gi_proto_bake *out, gi_proto_error *err);
/* GET /v1/scenes/{id}/cells/{i},{j},{k}/cascades.vdb. */
int gi_proto_parse_cell_cascades(const gi_proto_kv *kv, size_t n, const gi_proto_limits *lim,
                                 gi_proto_bake *out, gi_proto_error *err);
/* GET /v1/scenes/{id}: optional quality knobs, for the grid it publishes. */
int gi_proto_parse_scene(const gi_proto_kv *kv, size_t n, const gi_proto_limits *lim,
                         gi_proto_bake *out, gi_proto_error *err);
/* POST /v1/scenes/{id}/sessions: quality knobs and an optional start
 * 'at' (has_at), from the query (kv) or a JSON body {"at":[x,y,z],
 * "quality":...} as POST probes takes them; both at once is a 400. */
int gi_proto_parse_session(const gi_proto_kv *kv, size_t n, const char *body, size_t len,
                           const gi_proto_limits *lim, gi_proto_bake *out, gi_proto_error *err);
/* GET /v1/sessions/{sid}/lighting: 'at' (required), kind probe|panorama,
 * half, width, height; quality knobs are the session's (400 here). */
int gi_proto_parse_session_lighting(const gi_proto_kv *kv, size_t n, const gi_proto_limits *lim,
                                    gi_proto_bake *out, gi_proto_error *err);
/* A cell path segment "i,j,k" (plain integers, no leading zeros): 0, -1
 * when it is not one, or -2 when it is but an index has more than 18
 * digits (too far to address; out is then incomplete). */
int gi_proto_parse_cell(const char *s, long long out[3]);
/* A request that takes no parameters: any parameter is a 400. */
int gi_proto_parse_none(const gi_proto_kv *kv, size_t n, gi_proto_error *err);

/* POST /v1/scenes/{id}/probes. points holds 3 * num_points world
 * coordinates (owned: gi_proto_probes_free). */
typedef struct gi_proto_probes {
  gi_proto_bake bake;
  double *points;
  size_t num_points;
} gi_proto_probes;
int gi_proto_parse_probes(const char *body, size_t len, const gi_proto_limits *lim,
                          gi_proto_probes *out, gi_proto_error *err);
void gi_proto_probes_free(gi_proto_probes *p);

/* Job status, as GET /v1/jobs/{id} answers it. */
/* CANCELLED: by DELETE /v1/jobs/{id} or a server shutdown. */
typedef enum gi_proto_job_state {
  GI_JOB_QUEUED = 0, GI_JOB_RUNNING, GI_JOB_DONE, GI_JOB_FAILED, GI_JOB_CANCELLED, GI_JOB_STATE_COUNT
} gi_proto_job_state;
typedef struct gi_proto_job {
  char id[40];
  gi_proto_job_state state;
  size_t probes, probes_done;
  int tiles, tiles_done;
  double elapsed_s;
  gi_proto_error error;  /* when failed */
} gi_proto_job;
const char *gi_proto_job_state_name(gi_proto_job_state s);
char *gi_proto_job_json(const gi_proto_job *j);
int gi_proto_job_parse(const char *json, size_t len, gi_proto_job *out);

/* A session, as POST /v1/scenes/{id}/sessions (201) and GET
 * /v1/sessions/{sid} answer it; links are derived from the id. */
typedef struct gi_proto_session {
  char id[40];
  char scene[64];
  double ttl_s;          /* idle time after which the server ends it */
  double at[3];          /* where its cascade stands now */
  unsigned long long moves;
  unsigned long long bytes; /* what it holds of the server's memory budget */
} gi_proto_session;
char *gi_proto_session_json(const gi_proto_session *s);
int gi_proto_session_parse(const char *json, size_t len, gi_proto_session *out);

/* Header values. Server-Timing: "voxelize;dur=1.2, inject;dur=...". */
void gi_proto_server_timing(const gi_timings *t, double total_ms, char *buf, size_t size);
/* The same led by "layout;dur=...": a lightmap's charts, packing and texels sorted into tiles. */
void gi_proto_server_timing_layout(double layout_ms, const gi_timings *t, double total_ms, char *buf, size_t size);
/* X-GI-Effects: "sun=ran, local_lights=skipped, ...". */
void gi_proto_effects_header(const gi_effect fx[GI_FX_COUNT], char *buf, size_t size);

/* Parses "x,y,z" (plain decimals, nothing after) into three doubles; 0 on
 * success, -1 when malformed, -2 when a value is beyond GI_PROTO_MAX_COORD. */
int gi_proto_parse_vec3(const char *s, double out[3]);

#ifdef __cplusplus
}
#endif
#endif
