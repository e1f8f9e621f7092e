/* server.h: the pieces of gi-server and who owns what.
 *
 * main.c reads the config (config.c), loads the catalog (catalog.c) and
 * starts the HTTP front (http.c). The front parses and routes requests on
 * libmicrohttpd's threads and never bakes: heavy work goes to the bounded
 * worker pool (pool.c) and long probe lists to the job runner (jobs.c).
 * Workers get cascades from the cache (cache.c), which bakes each key once
 * even when many requests ask for it at the same time, and keeps the
 * answers that are the same bytes for everyone (gathered and encoded once). metrics.c counts it
 * all for /metrics.
 *
 * Threading: the catalog and the config are read-only after start and
 * shared by all threads. The cache, the pool, the job table and the
 * metrics are internally synchronised; every function below is thread-safe
 * unless its comment says otherwise. */
#ifndef GS_SERVER_H
#define GS_SERVER_H

#include <signal.h>
#include <stdatomic.h>
#include <stddef.h>
#include <stdint.h>
#include "gi/gi.h"
#include "gi_proto.h"

/* ---- config.c: the INI file, validated at start ------------------------ */

typedef struct gs_scene_conf {
  char id[64];
  char source[1024];    /* "city" or a file path, resolved against the config's folder */
  int is_city;
  double extent;        /* city only */
  uint64_t seed;        /* city only */
  int detail;           /* city only */
  gi_up_axis up;        /* 0 = not given: y */
  int optional;         /* a missing file is a warning, not an error */
  int line;             /* where the section starts, for messages */
  int source_line;      /* where its source is given (0: not given) */
} gs_scene_conf;

typedef struct gs_config {
  char path[1024];
  char bind[64];
  int port;
  int connection_threads, workers, queue, bake_threads;
  double deadline_s;
  int max_connections_per_ip; /* libmicrohttpd refuses more from one address */
  double request_timeout_s;   /* headers and body must arrive within this, whatever the pace */
  double shutdown_grace_s;    /* SIGTERM: exit within this */
  double job_deadline_s;      /* a job running longer fails (its token's deadline) */
  char token[256];      /* empty: no authentication */
  char tmp_dir[1024];
  gi_proto_limits lim;
  int max_tiles_inline; /* POST probes spanning more cascades become a job */
  size_t cache_bytes;
  int max_sessions;           /* open sessions at once; more is a 503 */
  double session_ttl_s;       /* a session idle this long is ended */
  int max_jobs, max_jobs_queued, max_jobs_retained;
  gs_scene_conf *scenes;
  size_t num_scenes;
} gs_config;

/* Fills the defaults (no scenes). */
void gs_config_defaults(gs_config *c);
/* Reads and validates path over the defaults. On error returns -1 with a
 * message naming the file, line and key in err. */
int gs_config_load(const char *path, gs_config *c, char *err, size_t errsize);
/* Why tok cannot be the bearer token (length, spaces, control bytes), or NULL. */
const char *gs_token_bad(const char *tok);
void gs_config_free(gs_config *c);

/* ---- catalog.c: scenes loaded once, shared read-only ------------------- */

typedef struct gs_scene {
  char id[64];
  gi_scene *scene;
  double default_at[3];
  gi_quality quality;              /* the default quality resolved at default_at, with the plan's bounces */
  gi_effect effects[GI_FX_COUNT];  /* the default plan at default_at, for GET /v1/scenes/{id} */
  double load_ms;
  uint64_t version;                /* hash of what the scene was built from (canonical.c) */
} gs_scene;

typedef struct gs_catalog {
  gs_scene *scenes;
  size_t num;
} gs_catalog;

int gs_catalog_load(const gs_config *cfg, gs_catalog *cat, char *err, size_t errsize);
const gs_scene *gs_catalog_find(const gs_catalog *cat, const char *id);
void gs_catalog_free(gs_catalog *cat);

/* ---- metrics.c ---------------------------------------------------------- */

typedef enum gs_endpoint {
  GS_EP_HEALTH, GS_EP_SCENES, GS_EP_SCENE, GS_EP_LIGHTING, GS_EP_CASCADES, GS_EP_PROBES,
  GS_EP_JOB, GS_EP_JOB_RESULT, GS_EP_METRICS, GS_EP_LIGHTMAP_UV, GS_EP_SESSIONS, GS_EP_SESSION,
  GS_EP_SESSION_LIGHTING, GS_EP_OTHER, GS_EP_COUNT
} gs_endpoint;

typedef struct gs_metrics gs_metrics;
gs_metrics *gs_metrics_new(void);
void gs_metrics_free(gs_metrics *m);
void gs_metrics_request(gs_metrics *m, gs_endpoint ep, int status, double seconds);
void gs_metrics_bake(gs_metrics *m, double seconds);
typedef enum { GS_CACHE_HIT, GS_CACHE_MISS, GS_CACHE_COALESCED } gs_cache_how;
void gs_metrics_cache(gs_metrics *m, gs_cache_how how);
/* Around every bake (cache.c): the in-flight gauge, and the cancelled counter. */
void gs_metrics_bake_begin(gs_metrics *m);
void gs_metrics_bake_end(gs_metrics *m, int cancelled);
void gs_metrics_eviction(gs_metrics *m);
void gs_metrics_rejected(gs_metrics *m);
void gs_metrics_timeout(gs_metrics *m);
/* A kept answer (cache.c): reused (hit), encoded now (miss), or waited
 * for another request's encode of it (coalesced); and one evicted. */
void gs_metrics_encode(gs_metrics *m, gs_cache_how how);
void gs_metrics_encode_eviction(gs_metrics *m);
/* Sessions (session.c): one move (its seconds, whether it closed the
 * refresh cycle), and how sessions end or are refused. */
void gs_metrics_move(gs_metrics *m, double seconds, int cycle_closed);
void gs_metrics_move_cancelled(gs_metrics *m); /* a session move stopped by its token */
typedef enum { GS_SESSION_CREATED, GS_SESSION_EXPIRED, GS_SESSION_DELETED, GS_SESSION_REJECTED,
               GS_SESSION_EVENT_COUNT } gs_session_event;
void gs_metrics_session(gs_metrics *m, gs_session_event ev);
/* Gauges read at scrape time. */
typedef struct gs_gauges {
  size_t cache_bytes, cache_entries, cache_budget, inflight_bytes, sending_bytes;
  size_t answer_bytes, answers;  /* kept answers: their part of cache_bytes, and how many */
  int queue_depth, queue_capacity, workers_busy;
  int jobs[GI_JOB_STATE_COUNT];  /* by gi_proto_job_state */
  double uptime_s;
  size_t scenes;
  int sessions_open;
  size_t session_bytes;
} gs_gauges;
/* Prometheus text format (malloc'ed). */
char *gs_metrics_render(gs_metrics *m, const gs_gauges *g);

/* ---- blob (serve.c): encoded bytes shared by the cache and answers ------ */

/* Reference-counted bytes: the cache holds one reference, each answer
 * streaming them another, so a kept answer is encoded once and a client
 * that never reads holds no copy and no file. */
struct gs_cache;
typedef struct gs_blob {
  atomic_int refs;
  /* Counts size in this budget's bytes being sent until freed, or NULL
   * (not counted, or counted as kept by the cache, under its lock). */
  struct gs_cache *sending;
  size_t size;
  unsigned char data[];
} gs_blob;
/* Reads path into a new blob (one reference, not counted in any budget)
 * and unlinks the file; NULL with err on failure. */
gs_blob *gs_blob_take_file(const char *path, gi_error_info *err);
void gs_blob_retain(gs_blob *b);
void gs_blob_release(gs_blob *b); /* accepts NULL */
/* libmicrohttpd's free callback: data is a blob's data. */
void gs_blob_release_data(void *data);

/* ---- cache.c: cascades keyed by scene, anchor and quality -------------- */

/* A bake's transient buffers beside its cascade, as a fraction 1/DIV of the
 * cascade: bounce's irradiance pairs (24 of the 169 bytes a voxel holds),
 * voxelize's bins and inject's scratch. Measured peak RSS growth of one
 * bake on the city (server/README.md): see the table there. */
#define GS_BAKE_TRANSIENT_DIV 6

typedef struct gs_cache gs_cache;
typedef struct gs_entry gs_entry;
gs_cache *gs_cache_new(size_t budget_bytes, gs_metrics *m);
void gs_cache_free(gs_cache *c);
/* A request's interest in a bake (cache.c). The request owns it; the
 * cache links it to the entry being baked until the bake ends or the
 * request leaves (gs_cache_leave). */
typedef struct gs_waiter {
  void (*hold)(void *arg); /* called under the cache lock: keep arg alive until wake */
  void (*wake)(void *arg); /* the bake it waited for ended: run the request again (no lock held) */
  void *arg;
  /* Set by the owner before first use: the request waits on its own
   * thread (a probe list's tiles) instead of being woken; it still counts
   * as interested, so gs_cache_leave stops a bake only it wants. hold and
   * wake are then unused. */
  int blocking;
  /* The cache's, under its lock. */
  gs_entry *entry;         /* the bake (or answer's encode) it is interested in, or NULL */
  struct gs_waiter *next;
  /* What a wake hands it, held for its rerun (gs_cache_get, gs_cache_answer
   * take them; gs_cache_leave drops them), so a bake or encode it waited
   * for is not evicted (cache_mb = 0 evicts at once) before it reruns. */
  gs_entry *got;           /* its cascade: the bake it waited for, or its own while it waits for its answer */
  gs_entry *got_answer;    /* the answer's encode it waited for */
  gs_cache_how how;        /* got's outcome (X-GI-Cache): kept across the wait for its answer */
  int left;                /* gs_cache_leave was called: it joins no bake */
  gi_result rc;            /* that bake's failure, for the request's next try */
  gi_error_info err;
} gs_waiter;
/* gs_cache_get's answer when w waits for another request's bake: the
 * caller returns and frees its worker; w->wake comes when the bake ends. */
#define GS_PENDING ((gi_result)-100)
/* A baked cascade for (scene, at, resolved quality): from the cache, from a
 * bake already running for the same key, or baked now on the calling
 * thread. With a waiter, a running bake gives GS_PENDING (see gs_waiter)
 * and the call's own bake counts w as interested; a blocking waiter, and
 * no waiter (NULL), block until the running bake ends (a blocking waiter
 * also until gs_cache_leave: GI_ERR_CANCELLED). A bake nobody is
 * interested in any more is cancelled and never cached. The entry stays
 * valid until gs_cache_release. *how: how the cascade was found; a rerun
 * woken by a bake is coalesced, and one woken by its answer's encode
 * keeps what its first run was (the baker's miss, a waiter's coalesced). */
/* req is the request's quality as gi_cascade_bake takes it (zero = auto);
 * resolved is gi_quality_resolve's answer for it (placement, key). */
gi_result gs_cache_get(gs_cache *c, const gs_scene *s, const double at[3], const gi_quality *req,
                       const gi_quality *resolved, gs_waiter *w, gs_entry **out, gs_cache_how *how,
                       gi_error_info *err);
/* The request behind w gave up (deadline, hang-up): it stops counting as
 * interested. Returns 1 when that cancelled the bake (nobody else waits). */
/* Before a request takes a worker: when a bake for its key is running,
 * or (shape not NULL) the cascade is cached and its answer of that shape
 * is being encoded (gs_cache_answer), w (not blocking) joins it as
 * gs_cache_get would and 1 is returned; the request then waits without a
 * worker or a queue slot and w->wake comes when the bake or encode ends
 * (its rerun is a coalesced hit, or that error). 0: nothing to join; run
 * the request as usual. */
int gs_cache_join_running(gs_cache *c, const gs_scene *s, const double at[3], const gi_quality *req,
                          const gi_quality *resolved, const char *shape, gs_waiter *w);
/* 1 when that cancelled a bake, 2 an answer's gather and encode. */
int gs_cache_leave(gs_cache *c, gs_waiter *w);
const gi_cascade *gs_entry_cascade(const gs_entry *e);
void gs_cache_release(gs_cache *c, gs_entry *e);
void gs_cache_stats(gs_cache *c, size_t *bytes, size_t *entries);
/* The bytes a bake of this resolved quality is admitted for: its cascade's
 * bound (gi_cascade_bytes_estimate) plus its transient buffers. */
size_t gs_bake_bytes(const gi_quality *resolved);
/* Admission for bakes outside the cache (jobs): reserves need bytes when
 * cached + in-flight + need fit the budget (evicting unheld entries first);
 * GI_ERR_NOMEM when they do not now, GI_ERR_LIMIT when they never can. */
gi_result gs_cache_reserve(gs_cache *c, size_t need, const char *what, gi_error_info *err);
void gs_cache_unreserve(gs_cache *c, size_t need);
/* Sessions' cascades: admitted as gs_cache_reserve (evicting unheld
 * entries first), then counted apart as held bytes until gs_cache_unhold. */
gi_result gs_cache_hold(gs_cache *c, size_t need, gi_error_info *err);
void gs_cache_unhold(gs_cache *c, size_t need);
/* In-flight bytes: the estimates of admitted bakes still running (gauge). */
size_t gs_cache_inflight(gs_cache *c);
/* An answer's encoded bytes (a blob no one else holds yet) admitted in the
 * budget as a bake is, evicting unheld entries first, and counted as being
 * sent until the blob's last reference goes (gs_blob_release).
 * GI_ERR_NOMEM (503) when they do not fit now, GI_ERR_LIMIT when never. */
gi_result gs_cache_admit_sending(gs_cache *c, gs_blob *b, gi_error_info *err);
/* Bytes of answers being sent (gauge), and their release (gs_blob_release). */
size_t gs_cache_sending(gs_cache *c);
void gs_cache_unsend(gs_cache *c, size_t bytes);
/* Kept answers: one that is the same bytes for every request naming it
 * (a cell's probe or panorama, a cascade's VDB) is gathered and encoded
 * once and kept, keyed by shape (a text naming everything else that
 * shapes the bytes) and the cascade entry e it comes from (its
 * generation: a cascade baked again is another), counted in the budget
 * and evicted in LRU order with the cascades, and with e.
 * GI_OK with *blob (a reference for the caller): kept, or encoded by the
 * request w waited for. GI_OK with *blob NULL and *job: the caller
 * encodes it now, stopping on gs_entry_cancel(job), then calls
 * gs_cache_answer_done. GS_PENDING: w (not blocking) waits for another
 * request's encode (see gs_waiter), and the caller's reference to e
 * passes to w (its rerun's gs_cache_get returns it); a blocking waiter, and no waiter,
 * block for it. Else that encode's error, or GI_ERR_CANCELLED when w left. */
gi_result gs_cache_answer(gs_cache *c, gs_entry *e, const char *shape, gs_waiter *w, gs_blob **blob,
                          gs_entry **job, gi_error_info *err);
/* A job's token: set when no request wants its answer any more (gs_cache_leave). */
const gi_cancel *gs_entry_cancel(const gs_entry *job);
/* The job's encode ended with rc and b (the caller keeps its reference):
 * b is kept (its bytes, if admitted as being sent, now count as the
 * cache's) unless rc failed or nobody wanted it any more; a failure is
 * never kept, and the requests waiting for it get it. Wakes them and
 * releases job. */
void gs_cache_answer_done(gs_cache *c, gs_entry *job, gs_waiter *w, gi_result rc, gs_blob *b,
                          const gi_error_info *err);
/* Kept answers' bytes (part of gs_cache_stats' bytes) and count. */
void gs_cache_answer_stats(gs_cache *c, size_t *bytes, size_t *answers);

/* ---- pool.c: the bounded worker pool ----------------------------------- */

typedef struct gs_pool gs_pool;
typedef void (*gs_task_fn)(void *arg);
gs_pool *gs_pool_new(int workers, int queue_capacity);
/* Queues fn(arg); returns -1 when the queue is full (the caller answers 503). */
int gs_pool_submit(gs_pool *p, gs_task_fn fn, void *arg);
/* A task that already waited its turn (a request woken by the bake it
 * waited for): taken before the queue's, and never refused for a full
 * queue. -1 when the pool stops or there is no memory for it. */
int gs_pool_submit_first(gs_pool *p, gs_task_fn fn, void *arg);
void gs_pool_stats(gs_pool *p, int *depth, int *capacity, int *busy);
/* Runs what is queued, then joins the workers. */
void gs_pool_free(gs_pool *p);

/* ---- the service: what workers and the front share -------------------- */

typedef struct gs_jobs gs_jobs;
typedef struct gs_sessions gs_sessions;

typedef struct gs_service {
  const gs_config *cfg;
  const gs_catalog *cat;
  gs_cache *cache;
  gs_pool *pool;
  gs_jobs *jobs;
  gs_sessions *sessions;
  gs_metrics *metrics;
  double start_ms;
  atomic_ulong tmp_counter;
  char work_dir[1100];  /* private scratch folder (0700) in tmp_dir, made by gs_jobs_new */
} gs_service;

/* A fresh scratch path in work_dir (else tmp_dir) ending in ext. */
void gs_tmp_path(gs_service *svc, const char *ext, char *buf, size_t size);
/* log.c: in written with every byte outside printable ASCII (and '\\') as
 * \xNN, cut to fit size, so a client's bytes cannot forge a log line. */
void gs_log_escape(const char *in, char *out, size_t size);
/* HTTP status for a core error (a cancelled bake: 504, its deadline passed). */
int gs_status_of(gi_result rc);
/* Milliseconds on the monotonic clock. */
double gs_now_ms(void);

/* ---- canonical.c: cell-addressed, cacheable URLs ---------------------- */

/* max-age of a cell URL's answer: it never changes (immutable). */
#define GS_CELL_MAX_AGE_S 31536000
/* max-age of a viewpoint URL's 307: a stale one leads to a stale q, which
 * redirects again, so a short life is safe. */
#define GS_REDIRECT_MAX_AGE_S 60

typedef struct gs_canon {
  gi_quality req;        /* as the core takes it (zero = auto, the server's threads) */
  gi_quality resolved;   /* gi_quality_resolve of req */
  char knobs[384];       /* the request's quality knobs in canonical form: "levels=3&res=16" */
  char q[GI_PROTO_QHASH_LEN + 1];
} gs_canon;
uint64_t gs_hash_bytes(uint64_t h, const void *data, size_t n);
/* The scene's version: a hash of its file's bytes (or the city's parameters). */
int gs_scene_version(const gs_scene_conf *sc, uint64_t *out, char *err, size_t errsize);
/* Resolves a request's quality and its canonical knobs and q hash. */
gi_result gs_canon_quality(const gs_service *svc, const gs_scene *s, const gi_quality *in, gs_canon *out,
                           gi_error_info *err);
/* The cell URL of a lighting (ep GS_EP_LIGHTING) or cascades answer. */
void gs_canon_url(const gs_scene *s, const gs_canon *c, const int64_t cell[3], gs_endpoint ep,
                  const gi_proto_bake *b, char *buf, size_t size);
/* The strong ETag (quoted) of a cell answer. */
void gs_canon_etag(const gs_canon *c, const int64_t cell[3], gs_endpoint ep, const gi_proto_bake *b, char *out,
                   size_t size);
/* OpenVDB writes a random UUID into every file: replaces it with one
 * derived from the other bytes, so equal cascades encode to equal bytes on
 * every replica. -1 (b unchanged) when b is not shaped as expected. */
int gs_vdb_stable_uuid(gs_blob *b);
/* Whether an If-None-Match value names etag (or is "*"). */
int gs_etag_matches(const char *if_none_match, const char *etag);
/* The grid a client snaps viewpoints to, and the URL templates, for GET /v1/scenes/{id}. */
#include <jansson.h>
json_t *gs_canon_grid_json(const gs_scene *s, const gs_canon *c);

/* ---- bake.c (server side): turning a request into a file --------------- */

/* An encoded answer: bytes in memory or an open file (unlinked), and its headers. */
typedef struct gs_answer {
  int status;
  gs_blob *blob;          /* encoded bytes (one reference), or NULL */
  int fd;                 /* a job's result file, else -1 */
  size_t size;
  char *json;             /* error or job JSON when neither blob nor fd (malloc'ed) */
  const char *content_type;
  char disposition[160];
  char server_timing[320];
  char effects[200];
  const char *cache;      /* "hit", "miss", "coalesced" or NULL */
  char location[768];
  const char *cache_control; /* a 307's; NULL: no-store (a cell answer's come from its request) */
  int retry_after_s;      /* Retry-After for a 503 or 504 (0: 1 s) */
  char move[128];         /* X-GI-Move: what a session's move did, or empty */
} gs_answer;

void gs_answer_error(gs_answer *a, const gi_proto_error *e);
/* A core error as the answer: its status (gs_status_of) and message
 * (gs_client_message). */
void gs_answer_core_error(gs_answer *a, gi_result rc, const gi_error_info *e);
/* The message a client sees for a core error: e's own, except for
 * GI_ERR_IO (an answer's file could not be written or read back: a full
 * disk), which names the server's private paths: that one is logged and
 * the client gets "could not write the answer: <OS reason>" in buf. */
const char *gs_client_message(gi_result rc, const gi_error_info *e, char *buf, size_t size);
/* The request's quality as the core takes it (zero = auto, the server's
 * thread count) into *req, and its resolution (gi_quality_resolve). */
gi_quality gs_resolve_request(gs_service *svc, const gs_scene *s, const gi_quality *in, gi_quality *req,
                              gi_error_info *e, gi_result *rc);
/* The probe or panorama answer (EXR) at b->at from cascade c, with its
 * headers; ms holds the stages already run (a bake's or a move's), cache
 * names the outcome (X-GI-Cache and the EXR's gi.cache). cancel may be NULL. */
gi_result gs_answer_lighting(gs_service *svc, const gs_scene *s, const gi_cascade *c, const gi_proto_bake *b,
                             const gi_cancel *cancel, const char *cache, gi_timings *ms, double t_start_ms,
                             gs_answer *a, gi_error_info *e);
void gs_answer_free(gs_answer *a);
/* Reads the encoded file at path into the answer (200, type), unlinking
 * it; its bytes are admitted in the budget while they are sent
 * (gs_cache_admit_sending: GI_ERR_NOMEM when they do not fit). */
gi_result gs_answer_take_file(gs_service *svc, gs_answer *a, const char *path, const char *type, gi_error_info *e);

/* gs_cache_join_running for the cached bake gs_serve_bake would make or
 * wait for (lighting other than lightmaps, cascades), or the encode of its
 * kept answer; 0 for any other request or when its quality does not
 * resolve (the worker reports it). */
int gs_serve_join_running(gs_service *svc, const gs_scene *s, gs_endpoint ep, const gi_proto_bake *b, gs_waiter *w);
/* Lighting (probe, panorama) or cascades for one viewpoint. */
/* w (may be NULL: block for a running bake) as in gs_cache_get: out->status
 * stays 0 when the request waits for another request's bake, or for its
 * encode of the same kept answer (gs_cache_answer). cancel (may be NULL)
 * fires when nobody waits for the answer: a gather not shared with other
 * requests, or a lightmap bake, stops on it (a shared one stops when all
 * its requests left). */
void gs_serve_bake(gs_service *svc, const gs_scene *s, gs_endpoint ep, const gi_proto_bake *b,
                   double t_start_ms, gs_waiter *w, const gi_cancel *cancel, gs_answer *out);
/* lightmap.c: kind=lightmap (the EXR atlas) or lightmap-uv.glb (ep) for
 * b's region, baked tile by tile outside the cascade cache; the bake stops
 * on cancel (may be NULL). */
void gs_serve_lightmap(gs_service *svc, const gs_scene *s, gs_endpoint ep, const gi_proto_bake *b,
                       double t_start_ms, const gi_cancel *cancel, gs_answer *out);
/* Probe points: inline when small, else a job (202). Frees p's points.
 * w (a blocking waiter, or NULL) and cancel (or NULL) are the request's:
 * once it is given up, its tiles' bakes nobody else wants stop (never
 * cached) and so do its gathers. */
void gs_serve_probes(gs_service *svc, const gs_scene *s, gi_proto_probes *p, double t_start_ms, gs_waiter *w,
                     const gi_cancel *cancel, gs_answer *out);
/* Tiles: probe points grouped by the cascade that answers them. */
typedef struct gs_tile {
  double at[3];
  size_t *idx;          /* indices into the point list */
  size_t n;
} gs_tile;
/* 0, -1 out of memory, -2 a point too far from the origin to index its tile. */
int gs_tiles_make(const gs_scene *s, const gi_quality *resolved, const double *pts, size_t n, gs_tile **out,
                  size_t *num_tiles);
void gs_tiles_free(gs_tile *t, size_t n);
/* The one tile around at holding all n points (a request's 'at': the client
 * chose one cascade for them), for gs_tiles_free; 0, or -1 out of memory. */
int gs_tile_around(const double at[3], size_t n, gs_tile **out, size_t *num_tiles);
/* Gathers the points of every tile into probes; progress callback per
 * tile, which returns nonzero to stop before the next tile (GI_ERR_LIMIT,
 * its message in err).
 * use_cache = 0 bakes privately (batch jobs must not evict interactive views).
 * w as in gs_serve_probes (cached bakes only); cancel stops private bakes and every
 * gather; both may be NULL. */
gi_result gs_gather_tiles(gs_service *svc, const gs_scene *s, const gi_quality *req, const gi_quality *resolved,
                          const double *pts, const gs_tile *tiles, size_t num_tiles, int use_cache,
                          gs_waiter *w, const gi_cancel *cancel, gi_probe *out,
                          gi_bake_report *rep, gi_timings *ms, gs_cache_how *how,
                          int (*progress)(void *ctx, size_t tile, size_t probes, gi_error_info *err), void *ctx,
                          gi_error_info *err);

/* ---- jobs.c: long probe lists, run off the worker pool ------------------ */

/* Also makes svc->work_dir (mkdtemp in tmp_dir, 0700) after removing the
 * folders of earlier servers that are no longer running. */
gs_jobs *gs_jobs_new(gs_service *svc);
void gs_jobs_free(gs_jobs *j);
/* Queues a job (takes ownership of p's points). Returns 0 and the id, or a
 * status (503 when the job queue is full). */
int gs_jobs_submit(gs_jobs *j, const gs_scene *s, gi_proto_probes *p, const gi_quality *req, const gi_quality *resolved,
                   char id[40], gi_proto_error *err);
/* Status JSON into a->json (200), or 404. */
void gs_jobs_status(gs_jobs *j, const char *id, gs_answer *a);
/* The result EXR (200), 409 when not done, 404 when unknown. */
void gs_jobs_result(gs_jobs *j, const char *id, gs_answer *a);
/* DELETE: a queued job is cancelled at once (200), a running one between
 * tiles (202); its status JSON either way. 409 when it has finished, 404
 * when unknown. */
void gs_jobs_cancel(gs_jobs *j, const char *id, gs_answer *a);
/* Shutdown: queued and running jobs are cancelled (running ones inside their tile). */
void gs_jobs_cancel_all(gs_jobs *j);
/* A forced exit: removes the private folder (results, scratch files) now. */
void gs_jobs_abandon(gs_jobs *j);
void gs_jobs_count(gs_jobs *j, int by_state[GI_JOB_STATE_COUNT]);

/* ---- session.c: a walking client's own cascade ------------------------- */

/* Session ids: 32 hex digits from the kernel's random source. */
#define GS_SESSION_ID_LEN 32
gs_sessions *gs_sessions_new(gs_service *svc);
/* Shutdown (after the workers stopped): frees every session's cascade. */
void gs_sessions_free(gs_sessions *t);
/* Ends sessions idle longer than session_ttl_s (the reaper calls it). */
void gs_sessions_sweep(gs_sessions *t);
void gs_sessions_stats(gs_sessions *t, int *open, size_t *bytes);
/* POST /v1/scenes/{id}/sessions (a worker): bakes the session's cascade
 * at b->at (else the scene's default viewpoint), 201 with its JSON and
 * the bake's Server-Timing. */
void gs_session_create(gs_service *svc, const gs_scene *s, const gi_proto_bake *b, const gi_cancel *cancel,
                       double t_start_ms, gs_answer *a);
/* GET /v1/sessions/{sid}/lighting (a worker): moves the session's
 * cascade to b->at and answers as the scene's lighting URL does. Requests
 * on one session run one at a time. */
void gs_session_lighting(gs_service *svc, const char *sid, const gi_proto_bake *b, double t_start_ms,
                         const gi_cancel *cancel, gs_answer *a);
/* The scene of an open session, or NULL (scenes live as long as the server). */
const gs_scene *gs_session_scene(gs_service *svc, const char *sid);
/* GET (200, its JSON) and DELETE (204) /v1/sessions/{sid}: cheap, on the front. */
void gs_session_info(gs_service *svc, const char *sid, gs_answer *a);
void gs_session_delete(gs_service *svc, const char *sid, gs_answer *a);

/* ---- shutdown.c: after the first SIGINT/SIGTERM --------------------------- */

/* Exit status when shutdown is forced: a second signal, or shutdown_grace_s passed. */
#define GS_EXIT_FORCED 3
/* Cancels the jobs and starts a watchdog that exits the process (status
 * GS_EXIT_FORCED) on a second signal in sigs or when the grace runs out. */
void gs_shutdown_begin(gs_service *svc, const sigset_t *sigs);

/* ---- http.c: the front -------------------------------------------------- */

typedef struct gs_http gs_http;
gs_http *gs_http_start(gs_service *svc, char *err, size_t errsize);
int gs_http_port(const gs_http *h);
/* Stops accepting, lets queued work finish, answers, and stops. */
void gs_http_stop(gs_http *h);

/* The name of a stop signal (SIGINT, SIGTERM or SIGHUP) for the log. */
static inline const char *gs_signal_name(int sig) {
  return sig == SIGINT ? "SIGINT" : sig == SIGHUP ? "SIGHUP" : "SIGTERM";
}

#endif
