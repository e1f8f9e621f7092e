/* batch.c: gi-bake --grid, a probe grid baked tile by tile (batch.h).
 *
 * Steps: lay the grid out (core: gi_probe_grid_build), resolve the quality
 * (the finest voxel defaults to the grid spacing), cut tiles so the finest
 * level spans twice a tile, name the bake by a hash of everything that
 * decides its bytes, then bake this shard's tiles one at a time (each
 * from its checkpoint when --resume has it), and write the outputs and
 * the manifest (batch_manifest.c). Memory: one cascade at a time, plus
 * the grid's positions and answers (about 270 bytes per point). */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>
#include "batch_run.h"

double batch_now_ms(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return (double)ts.tv_sec * 1e3 + (double)ts.tv_nsec * 1e-6;
}

/* Prints "gi-bake: planning ..." every TICK_S while a stage that cannot
 * report its own progress runs (the street-level grid: a few rays per
 * column, about 5 us each, 75 s for 2^24 columns). */
#define TICK_S 5
typedef struct ticker {
  pthread_t th;
  pthread_mutex_t mu;
  pthread_cond_t cv;
  int stop, started;
  const char *what;
  double t0;
} ticker;

static void *tick_main(void *arg) {
  ticker *tk = arg;
  pthread_mutex_lock(&tk->mu);
  while (!tk->stop) {
    struct timespec ts;
    clock_gettime(CLOCK_REALTIME, &ts);
    ts.tv_sec += TICK_S;
    if (pthread_cond_timedwait(&tk->cv, &tk->mu, &ts) != 0 && !tk->stop)
      fprintf(stderr, "gi-bake: planning stage=%s elapsed_s=%.0f\n", tk->what, (batch_now_ms() - tk->t0) / 1e3);
  }
  pthread_mutex_unlock(&tk->mu);
  return NULL;
}

static void tick_start(ticker *tk, const char *what) {
  memset(tk, 0, sizeof *tk);
  tk->what = what;
  tk->t0 = batch_now_ms();
  pthread_mutex_init(&tk->mu, NULL);
  pthread_cond_init(&tk->cv, NULL);
  tk->started = pthread_create(&tk->th, NULL, tick_main, tk) == 0;
}

static void tick_stop(ticker *tk) {
  if (tk->started) {
    pthread_mutex_lock(&tk->mu);
    tk->stop = 1;
    pthread_cond_signal(&tk->cv);
    pthread_mutex_unlock(&tk->mu);
    pthread_join(tk->th, NULL);
  }
  pthread_mutex_destroy(&tk->mu);
  pthread_cond_destroy(&tk->cv);
}

static void grid_spec(const cli_batch *b, gi_grid_spec *spec) {
  *spec = (gi_grid_spec){.spacing = b->grid, .have_region = b->have_region, .above_ground = b->above};
  for (int a = 0; a < 3; a++) spec->lo[a] = b->region[a], spec->hi[a] = b->region[3 + a];
}

/* The message for a grid the core refused. */
static int grid_error(const cli_batch *b, gi_result r, const gi_error_info *err) {
  const char *opt = r == GI_ERR_LIMIT ? "--grid" : r == GI_ERR_INVALID_ARG && b->have_region ? "--region" : "--grid";
  fprintf(stderr, "gi-bake: %s: %s\n", opt, err->msg[0] ? err->msg : gi_strerror(r));
  return r == GI_ERR_NOMEM ? EXIT_RUN : EXIT_USAGE;
}

/* The grid's counts only (no ray, no allocation), so the tiles can be
 * counted and a huge grid refused before any work. */
static int size_grid(const cli_opts *o, const gi_scene *scene, gi_probe_grid *g) {
  gi_grid_spec spec;
  grid_spec(&o->batch, &spec);
  gi_error_info err = {0};
  gi_result r = gi_probe_grid_size(scene, &spec, g, &err);
  return r == GI_OK ? 0 : grid_error(&o->batch, r, &err);
}

/* The grid; a region outside the scene or too many probes is a usage error. */
static int make_grid(const cli_opts *o, const gi_scene *scene, gi_probe_grid *g) {
  const cli_batch *b = &o->batch;
  gi_grid_spec spec;
  grid_spec(b, &spec);
  gi_error_info err = {0};
  ticker tk;
  tick_start(&tk, b->above > 0 ? "ground" : "grid");
  gi_result r = gi_probe_grid_build(scene, &spec, g, &err);
  tick_stop(&tk);
  if (r == GI_OK && g->num_valid == 0) {
    fprintf(stderr, "gi-bake: --grid: no probe left: %zu columns without ground, %zu inside buildings\n",
            g->num_no_ground, g->num_inside);
    return EXIT_RUN;
  }
  return r == GI_OK ? 0 : grid_error(b, r, &err);
}

/* More tiles than --max-tiles (default BATCH_MAX_TILES): a usage error,
 * said at once, before the grid is built or any tile planned. */
static int check_tiles(const batch_state *st) {
  const cli_batch *b = &st->o->batch;
  long long limit = b->max_tiles > 0 ? b->max_tiles : BATCH_MAX_TILES;
  const batch_layout *L = &st->L;
  if ((long long)L->tiles <= limit) return 0;
  fprintf(stderr, "gi-bake: --max-tiles: the grid needs %zu tiles (%d x %d x %d points in tiles of %d x %d x %d), "
                  "more than the limit %lld; raise --max-tiles to bake it, or use a coarser --grid, a larger "
                  "--voxel or --res, or a smaller --region\n",
          L->tiles, L->counts[0], L->counts[1], L->counts[2], L->tile[0], L->tile[1], L->tile[2], limit);
  return EXIT_USAGE;
}

/* Resolved quality (finest voxel = spacing unless --voxel) and the tiles. */
static int plan_tiles(batch_state *st) {
  gi_error_info err = {0};
  st->q = st->o->q;
  if (st->q.voxel0 <= 0) st->q.voxel0 = st->grid.spacing;
  gi_result r = gi_quality_resolve(st->scene, &st->q, &st->resolved, &err);
  if (r != GI_OK) {
    /* Name the option: without --voxel the finest voxel is --grid's spacing,
     * and "quality: voxel size must be at most 1e+07" named neither. */
    const char *opt = st->o->q.voxel0 > 0 ? "--voxel" : "--grid (the finest voxel is the spacing unless --voxel)";
    fprintf(stderr, "gi-bake: %s: %s\n", opt, err.msg[0] ? err.msg : gi_strerror(r));
    return EXIT_USAGE;
  }
  batch_layout *L = &st->L;
  memset(L, 0, sizeof *L);
  int side = (int)floor(st->resolved.res * st->resolved.voxel0 / (TILE_SPAN_RATIO * st->grid.spacing));
  for (int a = 0; a < 3; a++) {
    L->counts[a] = st->grid.counts[a];
    L->origin[a] = st->grid.origin[a];
    L->tile[a] = side < 1 ? 1 : side;
  }
  L->spacing = st->grid.spacing;
  L->up_axis = st->grid.up_axis;
  L->above = st->grid.above_ground;
  if (L->above > 0) L->tile[L->up_axis] = 1;
  layout_tiles(L);
  return 0;
}

/* Room for the answers, and this shard's tiles with their valid probes. */
static int alloc_state(batch_state *st) {
  size_t n = st->grid.n;
  st->probes = calloc(n, sizeof *st->probes);
  st->valid = calloc(n, 1);
  st->tile_start = calloc(st->L.tiles + 1, sizeof *st->tile_start);
  st->order = malloc((st->grid.num_valid ? st->grid.num_valid : 1) * sizeof *st->order);
  st->tile_stats = calloc(st->L.tiles, sizeof *st->tile_stats);
  st->tile_source = calloc(st->L.tiles, 1);
  if (!st->probes || !st->valid || !st->tile_start || !st->order || !st->tile_stats || !st->tile_source) {
    fprintf(stderr, "gi-bake: out of memory for %zu probes\n", n);
    return EXIT_RUN;
  }
  /* Counting sort of the valid points by tile: each tile's list stays in point order. */
  for (size_t i = 0; i < n; i++)
    if (st->grid.state[i] == GI_GRID_VALID) st->tile_start[layout_tile_of(&st->L, i) + 1]++;
  for (size_t t = 0; t < st->L.tiles; t++) st->tile_start[t + 1] += st->tile_start[t];
  size_t *fill = calloc(st->L.tiles, sizeof *fill);
  if (!fill) {
    fprintf(stderr, "gi-bake: out of memory for %zu tiles\n", st->L.tiles);
    return EXIT_RUN;
  }
  for (size_t i = 0; i < n; i++)
    if (st->grid.state[i] == GI_GRID_VALID) {
      size_t t = layout_tile_of(&st->L, i);
      st->order[st->tile_start[t] + fill[t]++] = (uint32_t)i;
    }
  free(fill);
  /* One tile's points and answers at a time (the plan's pass and the bakes). */
  size_t maxm = 1;
  for (size_t t = 0; t < st->L.tiles; t++)
    if (st->tile_start[t + 1] - st->tile_start[t] > maxm) maxm = st->tile_start[t + 1] - st->tile_start[t];
  st->pts = malloc(maxm * 3 * sizeof *st->pts);
  st->tile_probes = malloc(maxm * sizeof *st->tile_probes);
  if (!st->pts || !st->tile_probes) {
    fprintf(stderr, "gi-bake: out of memory for a tile of %zu probes\n", maxm);
    return EXIT_RUN;
  }
  return 0;
}

int batch_owns(const batch_state *st, size_t t) {
  const cli_batch *b = &st->o->batch;
  return !b->have_shard || (int)(t % (size_t)b->shard_n) == b->shard_i;
}

/* Tile t's probes into st->pts (returns how many, at order[]) and the
 * middle of their box, where its cascade is baked. */
static size_t tile_points(batch_state *st, size_t t, double at[3]) {
  const uint32_t *idx = st->order + st->tile_start[t];
  size_t m = st->tile_start[t + 1] - st->tile_start[t];
  double lo[3] = {HUGE_VAL, HUGE_VAL, HUGE_VAL}, hi[3] = {-HUGE_VAL, -HUGE_VAL, -HUGE_VAL};
  for (size_t j = 0; j < m; j++)
    for (int a = 0; a < 3; a++) {
      double v = st->grid.pos[3 * (size_t)idx[j] + a];
      lo[a] = fmin(lo[a], v), hi[a] = fmax(hi[a], v);
      st->pts[3 * j + a] = v;
    }
  for (int a = 0; a < 3; a++) at[a] = 0.5 * (lo[a] + hi[a]);
  return m;
}

/* One bounce count for every tile, as a lightmap's tiles share one: each
 * tile's cascade plans its own from the albedo round it, and neighbouring
 * tiles' probes stepped where a bright room's tiles met the street's.
 * Left to the plan, every tile (every shard's: the count must not depend
 * on the shard) is planned first and all bake the most any chose, with
 * the tail if any adds it. */
static int shared_bounces(batch_state *st) {
  if (st->q.bounces != 0) return 0;
  int most = 0, tail = 0;
  double t0 = batch_now_ms(), next = t0 + 1e3 * TICK_S;
  for (size_t t = 0; t < st->L.tiles; t++) {
    double now = batch_now_ms();
    if (now >= next) { /* about 1.3 ms a tile: 100000 tiles take minutes */
      double eta = t ? (now - t0) / 1e3 * (double)(st->L.tiles - t) / (double)t : -1;
      fprintf(stderr, "gi-bake: planning stage=bounces tile=%zu/%zu elapsed_s=%.0f eta_s=%.0f\n", t, st->L.tiles,
              (now - t0) / 1e3, eta);
      next = now + 1e3 * TICK_S;
    }
    if (st->tile_start[t] == st->tile_start[t + 1]) continue;
    double at[3];
    size_t m = tile_points(st, t, at);
    gi_effect fx[GI_FX_COUNT];
    gi_quality r;
    gi_error_info err = {0};
    if (gi_effect_plan_for(st->scene, at, st->pts, m, &st->q, fx, &r, &err) != GI_OK) {
      fprintf(stderr, "gi-bake: tile %zu: effect plan: %s\n", t, err.msg);
      return EXIT_RUN;
    }
    if (!fx[GI_FX_BOUNCE].ran) continue;
    most = r.bounces > most ? r.bounces : most;
    tail |= r.bounce_tail;
  }
  st->q.bounces = most > 0 ? most : -1;
  st->q.bounce_tail = tail;
  st->shared_bounces = 1;
  return 0;
}

/* Bakes tile t's probes around the middle of their box. */
static int bake_tile(batch_state *st, size_t t) {
  double at[3];
  size_t m = tile_points(st, t, at);
  gi_error_info err = {0};
  gi_bake_report rep;
  gi_cascade *cas = NULL;
  double t0 = batch_now_ms(), gms = 0;
  gi_result r = gi_cascade_bake_for(st->scene, at, st->pts, m, &st->q, NULL, &cas, &rep, &err);
  double t1 = batch_now_ms();
  if (r == GI_OK) r = gi_cascade_gather(cas, st->pts, m, st->tile_probes, &gms, &err);
  gi_cascade_free(cas);
  if (r != GI_OK) {
    fprintf(stderr, "gi-bake: tile %zu: %s\n", t, err.msg[0] ? err.msg : gi_strerror(r));
    return EXIT_RUN;
  }
  batch_tile_stats *ts = &st->tile_stats[t];
  ts->bake_ms = t1 - t0;
  ts->gather_ms = batch_now_ms() - t1;
  ts->cascade_bytes = rep.cascade_bytes;
  st->bake_ms += ts->bake_ms;
  st->gather_ms += ts->gather_ms;
  if (rep.cascade_bytes > st->peak_cascade_bytes) st->peak_cascade_bytes = rep.cascade_bytes;
  for (int e = 0; e < GI_FX_COUNT; e++) ts->fx_ran |= (uint32_t)(rep.effects[e].ran != 0) << e;
  double span = rep.voxel_size[0] * rep.quality.res;
  const uint32_t *idx = st->order + st->tile_start[t];
  for (size_t j = 0; j < m; j++) {
    int out = 0;
    for (int a = 0; a < 3; a++)
      out |= st->pts[3 * j + a] < rep.level_origin[0][a] || st->pts[3 * j + a] > rep.level_origin[0][a] + span;
    ts->outside_level0 += (uint32_t)out;
    st->probes[idx[j]] = st->tile_probes[j];
  }
  return 0;
}

/* One tile: from its checkpoint, or baked (and checkpointed). */
static int run_tile(batch_state *st, size_t t) {
  const char *dir = st->o->batch.resume;
  size_t m = st->tile_start[t + 1] - st->tile_start[t];
  char msg[4400];
  const char *source = "empty";
  batch_tile_stats *ts = &st->tile_stats[t];
  memset(ts, 0, sizeof *ts);
  if (dir) {
    int got = ckpt_load(dir, t, st->hash, st->grid.n, st->probes, ts, msg, sizeof msg);
    if (got < 0) {
      fprintf(stderr, "gi-bake: --resume: %s\n", msg);
      return EXIT_RUN;
    }
    if (got > 0) source = "resumed";
  }
  if (strcmp(source, "resumed")) memcpy(ts->run, st->run, sizeof ts->run);
  if (!strcmp(source, "empty") && m > 0) {
    int rc = bake_tile(st, t);
    if (rc) return rc;
    source = "baked";
  }
  if (dir && strcmp(source, "resumed") &&
      ckpt_save(dir, t, st->hash, st->order + st->tile_start[t], m, st->probes, ts, msg, sizeof msg)) {
    fprintf(stderr, "gi-bake: --resume: %s\n", msg);
    return EXIT_RUN;
  }
  for (size_t j = 0; j < m; j++) st->valid[st->order[st->tile_start[t] + j]] = 1;
  if (!strcmp(source, "resumed")) st->tiles_resumed++, st->tile_source[t] = TILE_RESUMED;
  else if (!strcmp(source, "baked")) st->tiles_baked++, st->probes_baked += m, st->tile_source[t] = TILE_BAKED;
  else st->tiles_empty++, st->tile_source[t] = TILE_EMPTY;
  st->probes_done += m;
  batch_progress(st, t, source);
  return 0;
}

static int run_tiles(batch_state *st) {
  for (size_t t = 0; t < st->L.tiles; t++) {
    size_t m = st->tile_start[t + 1] - st->tile_start[t];
    if (batch_owns(st, t)) {
      st->tiles_owned++;
      st->probes_owned += m;
    }
  }
  const char *dir = st->o->batch.resume;
  if (dir && mkdir(dir, 0777) != 0 && !batch_is_dir(dir)) {
    fprintf(stderr, "gi-bake: --resume: cannot create folder '%s': %s\n", dir, strerror(errno));
    return EXIT_RUN;
  }
  static ta_ctx ta = TA_CTX("gi-bake");
  if (dir) ckpt_remove_stale(&ta, dir);
  st->loop_start_ms = batch_now_ms();
  for (size_t t = 0; t < st->L.tiles; t++) {
    if (!batch_owns(st, t)) continue;
    int rc = run_tile(st, t);
    if (rc) return rc;
  }
  batch_progress_end(st);
  return 0;
}

static void free_state(batch_state *st) {
  gi_probe_grid_free(&st->grid);
  free(st->probes); free(st->valid); free(st->tile_start); free(st->order); free(st->pts); free(st->tile_probes);
  free(st->tile_stats); free(st->tile_source);
}

/* "YYYYMMDDTHHMMSSZ-PID": names the run in each tile it bakes. */
static void name_run(char *buf, size_t size) {
  time_t now = time(NULL);
  struct tm tm;
  char when[32] = "unknown";
  if (gmtime_r(&now, &tm)) strftime(when, sizeof when, "%Y%m%dT%H%M%SZ", &tm);
  memset(buf, 0, size);
  snprintf(buf, size, "%s-%ld", when, (long)getpid());
}

int batch_run(const cli_opts *o, const gi_scene *scene, double load_ms) {
  batch_state st;
  memset(&st, 0, sizeof st);
  st.o = o;
  st.scene = scene;
  st.load_ms = load_ms;
  st.tty = isatty(STDERR_FILENO);
  name_run(st.run, sizeof st.run);
  double t0 = batch_now_ms();
  int rc = size_grid(o, scene, &st.grid);
  if (!rc) rc = plan_tiles(&st);
  if (!rc) rc = check_tiles(&st);
  if (!rc) {
    gi_probe_grid_free(&st.grid);
    rc = make_grid(o, scene, &st.grid);
  }
  if (!rc) rc = alloc_state(&st);
  if (!rc) rc = shared_bounces(&st);
  if (!rc) rc = batch_identify(&st);
  st.plan_ms = batch_now_ms() - t0;
  if (!rc) rc = run_tiles(&st);
  double t1 = batch_now_ms();
  if (!rc) rc = batch_write(&st);
  st.write_ms = batch_now_ms() - t1;
  st.total_ms = batch_now_ms() - t0 + load_ms;
  if (!rc) rc = batch_manifest(&st);
  free_state(&st);
  return rc;
}
