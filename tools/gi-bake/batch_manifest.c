/* batch_manifest.c: a grid bake's name (hash), progress, outputs and
 * manifest.
 *
 * The hash covers everything that decides the output bytes: the layout,
 * resolved quality, effect plan, the scene as loaded (gi_scene_digest),
 * the version and CPU path, and every point's position and state. Two shards agree on it exactly
 * when they are shares of the same bake. Timings and memory go only into
 * the manifest, never into the EXR or VDB. */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>
#include "batch_run.h"
#include "gi_git_rev.h" /* GI_GIT_REV: generated at build time (cmake/git_rev.cmake) */

#define SH_TEXT "SH L2 irradiance, real basis L00 L1-1 L10 L11 L2-2 L2-1 L20 L21 L22 over world x,y,z; E(n) = sum sh_i Y_i(n)"
#define BAR_WIDTH 30

int batch_is_dir(const char *path) {
  struct stat sb;
  return stat(path, &sb) == 0 && S_ISDIR(sb.st_mode);
}

static void quality_text(const gi_quality *q, char *buf, size_t size) {
  snprintf(buf, size, "levels=%d res=%d voxel0=%.17g cones=%d aperture_deg=%.9g step=%.9g bounces=%d bounce_tail=%d "
                      "light_samples=%d probe_samples=%d ao=%d specular=%d seed=%llu",
           q->levels, q->res, q->voxel0, q->cones, q->aperture_deg, q->step, q->bounces, q->bounce_tail,
           q->light_samples, q->probe_samples, q->ao, q->specular, (unsigned long long)q->seed);
}

static void effects_text(const gi_effect fx[GI_FX_COUNT], char *buf, size_t size) {
  size_t off = 0;
  buf[0] = 0;
  for (int i = 0; i < GI_FX_COUNT && off < size; i++) {
    int w = snprintf(buf + off, size - off, "%s%s=%s (%s)", i ? "; " : "", gi_effect_name(i),
                     fx[i].ran ? "ran" : "skipped", fx[i].why);
    if (w < 0) break;
    off += (size_t)w;
  }
}

/* The scene's name (the EXR's gi.scene) and its content as loaded
 * (gi_scene_digest): geometry, materials, textures, lights. The scene
 * file's bytes were hashed instead, and missed what the loader read
 * beside it: a glTF's .bin or a texture swapped kept the hash, and
 * --resume and merge took tiles baked from the old one. */
static uint64_t hash_scene(const gi_scene *s, uint64_t h) {
  char buf[160];
  snprintf(buf, sizeof buf, "%s|%016llx", gi_scene_name(s), (unsigned long long)gi_scene_digest(s));
  return batch_fnv(buf, strlen(buf) + 1, h);
}

int batch_identify(batch_state *st) {
  double centre[3];
  for (int a = 0; a < 3; a++) centre[a] = st->L.origin[a] + 0.5 * (st->L.counts[a] - 1) * st->L.spacing;
  gi_error_info err = {0};
  gi_quality planned;
  gi_result r = gi_effect_plan(st->scene, centre, &st->q, st->plan, &planned, &err);
  if (r != GI_OK) {
    fprintf(stderr, "gi-bake: effect plan: %s\n", err.msg[0] ? err.msg : gi_strerror(r));
    return EXIT_RUN;
  }
  /* Record what the bake runs, not gi_quality_resolve's placeholders: the
   * plan's bounce count (automatic bounces resolve to 2) and the cones'
   * matched aperture (resolve leaves 0), as a single bake reports them. */
  st->resolved.bounces = planned.bounces;
  st->resolved.bounce_tail = planned.bounce_tail;
  if (st->shared_bounces && st->plan[GI_FX_BOUNCE].ran)
    snprintf(st->plan[GI_FX_BOUNCE].why, sizeof st->plan[GI_FX_BOUNCE].why,
             "%d bounces%s in every tile: the most any tile's plan chose (one count: no step between tiles)",
             planned.bounces, planned.bounce_tail ? " and the geometric tail" : "");
  if (!(st->resolved.aperture_deg > 0))
    st->resolved.aperture_deg = (float)(2.0 * acos(1.0 - 1.0 / st->resolved.cones) * 180.0 / 3.14159265358979);
  quality_text(&st->resolved, st->quality, sizeof st->quality);
  effects_text(st->plan, st->effects, sizeof st->effects);
  layout_text(&st->L, st->grid_text, sizeof st->grid_text);
  /* The march's CPU path too: the two round a few products differently
   * (FMA), so shards of both never merge into one bake's bytes. */
  snprintf(st->version, sizeof st->version, "gi-bake %s (%s), cpu path %s", GI_VERSION, GI_GIT_REV, gi_cpu_path());
  const cli_batch *b = &st->o->batch;
  if (b->have_shard) snprintf(st->shard, sizeof st->shard, "%d/%d", b->shard_i, b->shard_n);
  const char *texts[] = {st->quality, st->effects, st->grid_text, st->version, st->o->q.ao ? "ao" : "no-ao"};
  uint64_t h = BATCH_FNV_BASIS;
  for (size_t i = 0; i < sizeof texts / sizeof texts[0]; i++) h = batch_fnv(texts[i], strlen(texts[i]) + 1, h);
  h = hash_scene(st->scene, h);
  h = batch_fnv(st->grid.pos, st->grid.n * 3 * sizeof(double), h);
  h = batch_fnv(st->grid.state, st->grid.n, h);
  snprintf(st->hash, sizeof st->hash, "%016llx", (unsigned long long)h);
  return 0;
}

void batch_progress(batch_state *st, size_t t, const char *source) {
  double el = (batch_now_ms() - st->loop_start_ms) / 1e3;
  size_t done = st->tiles_baked + st->tiles_resumed + st->tiles_empty;
  double rate = el > 0 ? st->probes_baked / el : 0;
  double eta = rate > 0 ? (double)(st->probes_owned - st->probes_done) / rate : -1;
  if (!st->tty) {
    fprintf(stderr, "gi-bake: progress tile=%zu done=%zu/%zu probes=%zu/%zu probes_per_s=%.1f eta_s=%.1f source=%s\n",
            t, done, st->tiles_owned, st->probes_done, st->probes_owned, rate, eta, source);
    return;
  }
  int fill = st->tiles_owned ? (int)(BAR_WIDTH * done / st->tiles_owned) : BAR_WIDTH;
  char bar[BAR_WIDTH + 1];
  for (int i = 0; i < BAR_WIDTH; i++) bar[i] = i < fill ? '#' : '.';
  bar[BAR_WIDTH] = 0;
  if (eta >= 0)
    fprintf(stderr, "\r[%s] %zu/%zu tiles  %.0f probes/s  ETA %d:%02d  ", bar, done, st->tiles_owned, rate,
            (int)(eta / 60), (int)eta % 60);
  else
    fprintf(stderr, "\r[%s] %zu/%zu tiles  ", bar, done, st->tiles_owned);
}

void batch_progress_end(batch_state *st) {
  if (st->tty) fputc('\n', stderr);
}

int batch_write(batch_state *st) {
  const cli_opts *o = st->o;
  if (!o->exr && !o->vdb) return 0;
  const char *values[HDR_COUNT] = {BATCH_KIND, gi_scene_name(st->scene), st->version, st->quality, st->effects,
                                   st->grid_text, st->hash, SH_TEXT, st->shard[0] ? st->shard : NULL};
  gi_exr_attr attrs[HDR_COUNT];
  size_t na = batch_attrs(values, attrs);
  gi_probe_volume v = {.spacing = st->L.spacing, .up_axis = st->L.up_axis, .street_level = st->L.above > 0,
                       .n = st->grid.n, .pos = st->grid.pos, .valid = st->valid, .probes = st->probes,
                       .ao = st->o->q.ao};
  memcpy(v.counts, st->L.counts, sizeof v.counts);
  memcpy(v.origin, st->L.origin, sizeof v.origin);
  return batch_write_outputs(o->exr, o->vdb, &v, attrs, na, st->hash) ? EXIT_RUN : 0;
}

static json_t *ints3(const int v[3]) {
  return json_pack("[iii]", v[0], v[1], v[2]);
}

static json_t *manifest_grid(const batch_state *st) {
  const batch_layout *L = &st->L;
  return json_pack("{s:[fff],s:f,s:o,s:s,s:f,s:I,s:I,s:I,s:I,s:o}", "origin", L->origin[0], L->origin[1],
                   L->origin[2], "spacing", L->spacing, "counts", ints3(L->counts), "up", L->up_axis == 2 ? "z" : "y",
                   "above_ground", L->above, "points", (json_int_t)st->grid.n, "valid",
                   (json_int_t)st->grid.num_valid, "dropped_inside", (json_int_t)st->grid.num_inside, "no_ground",
                   (json_int_t)st->grid.num_no_ground, "region",
                   st->o->batch.have_region ? json_pack("[ffffff]", st->o->batch.region[0], st->o->batch.region[1],
                                                        st->o->batch.region[2], st->o->batch.region[3],
                                                        st->o->batch.region[4], st->o->batch.region[5])
                                            : json_null());
}

static const char *const SOURCE_NAMES[] = {"none", "baked", "resumed", "empty"};

static size_t tile_probes(const batch_state *st, size_t t) { return st->tile_start[t + 1] - st->tile_start[t]; }

/* One record per tile in the outputs: where its answers came from, the run
 * that baked them (a resumed tile's is an earlier run's) and what its bake
 * did (kept in its checkpoint). */
static json_t *tile_record(const batch_state *st, size_t t) {
  const batch_tile_stats *ts = &st->tile_stats[t];
  json_t *fx = json_array();
  for (int e = 0; e < GI_FX_COUNT; e++)
    if (ts->fx_ran >> e & 1u) json_array_append_new(fx, json_string(gi_effect_name(e)));
  return json_pack("{s:I,s:I,s:s,s:s,s:I,s:o,s:f,s:f,s:f}", "tile", (json_int_t)t, "probes",
                   (json_int_t)tile_probes(st, t), "source", SOURCE_NAMES[st->tile_source[t]], "run", ts->run,
                   "outside_level0", (json_int_t)ts->outside_level0, "effects_ran", fx, "cascade_mb",
                   ts->cascade_bytes / 1048576.0, "bake_ms", ts->bake_ms, "gather_ms", ts->gather_ms);
}

/* Tiles and probes per run, in the order the runs first appear. */
static json_t *tile_runs(const batch_state *st, json_t *records) {
  json_t *runs = json_array(), *by = json_object();
  size_t i;
  json_t *r;
  json_array_foreach(records, i, r) {
    const char *id = json_string_value(json_object_get(r, "run"));
    json_t *e = json_object_get(by, id);
    if (!e) {
      e = json_pack("{s:s,s:b,s:I,s:I}", "run", id, "this_run", !strcmp(id, st->run), "tiles", (json_int_t)0,
                    "probes", (json_int_t)0);
      json_object_set_new(by, id, e);
      json_array_append(runs, e);
    }
    json_object_set_new(e, "tiles", json_integer(json_integer_value(json_object_get(e, "tiles")) + 1));
    json_object_set_new(e, "probes", json_integer(json_integer_value(json_object_get(e, "probes")) +
                                                  json_integer_value(json_object_get(r, "probes"))));
  }
  json_decref(by);
  return runs;
}

/* baked, resumed and empty are this run's counts (as its progress lines);
 * the probe totals, probes_outside_level0, runs and records describe
 * every tile in the outputs, whichever run baked it. */
static json_t *manifest_tiles(const batch_state *st) {
  const cli_batch *b = &st->o->batch;
  json_t *shard = b->have_shard ? json_pack("{s:i,s:i}", "index", b->shard_i, "count", b->shard_n) : json_null();
  json_t *records = json_array();
  size_t outside = 0, resumed = 0, done = 0;
  for (size_t t = 0; t < st->L.tiles; t++) {
    if (!st->tile_source[t]) continue;
    json_array_append_new(records, tile_record(st, t));
    outside += st->tile_stats[t].outside_level0;
    done += tile_probes(st, t);
    if (st->tile_source[t] == TILE_RESUMED) resumed += tile_probes(st, t);
  }
  json_t *j = json_pack("{s:o,s:o,s:I,s:o,s:I,s:I,s:I,s:I,s:I,s:I}", "size", ints3(st->L.tile), "grid",
                        ints3(st->L.ntiles), "count", (json_int_t)st->L.tiles, "shard", shard, "owned",
                        (json_int_t)st->tiles_owned, "baked", (json_int_t)st->tiles_baked, "resumed",
                        (json_int_t)st->tiles_resumed, "empty", (json_int_t)st->tiles_empty, "probes_owned",
                        (json_int_t)st->probes_owned, "probes_outside_level0", (json_int_t)outside);
  json_object_set_new(j, "probes_done", json_integer((json_int_t)done));
  json_object_set_new(j, "probes_baked", json_integer((json_int_t)st->probes_baked));
  json_object_set_new(j, "probes_resumed", json_integer((json_int_t)resumed));
  json_object_set_new(j, "runs", tile_runs(st, records));
  json_object_set_new(j, "records", records);
  return j;
}

/* tiles_ran: the tiles in the outputs whose cascade ran the effect. */
static json_t *manifest_effects(const batch_state *st) {
  json_t *fx = json_object();
  for (int i = 0; i < GI_FX_COUNT; i++) {
    json_int_t ran = 0;
    for (size_t t = 0; t < st->L.tiles; t++) ran += st->tile_source[t] && (st->tile_stats[t].fx_ran >> i & 1u);
    json_object_set_new(fx, gi_effect_name(i),
                        json_pack("{s:b,s:s,s:I}", "ran", st->plan[i].ran, "why", st->plan[i].why, "tiles_ran", ran));
  }
  return fx;
}

static json_t *manifest_json(const batch_state *st) {
  const gi_quality *q = &st->resolved;
  struct rusage ru;
  getrusage(RUSAGE_SELF, &ru);
  double secs = st->bake_ms + st->gather_ms > 0 ? (st->bake_ms + st->gather_ms) / 1e3 : 0;
  json_t *m = json_pack("{s:s,s:s,s:s,s:s,s:{s:s,s:s}}", "kind", "gi-bake probe grid", "bake_hash", st->hash,
                        "run", st->run, "version", st->version, "scene", "name", gi_scene_name(st->scene), "path",
                        st->o->scene);
  json_object_set_new(m, "grid", manifest_grid(st));
  json_object_set_new(m, "tiles", manifest_tiles(st));
  json_object_set_new(m, "quality", json_pack("{s:i,s:i,s:f,s:i,s:i,s:i,s:i,s:b,s:s}", "levels", q->levels, "res",
                                              q->res, "voxel0", q->voxel0, "cones", q->cones, "bounces", q->bounces,
                                              "light_samples", q->light_samples, "probe_samples", q->probe_samples,
                                              "ao", q->ao, "text", st->quality));
  json_object_set_new(m, "effects", manifest_effects(st));
  json_object_set_new(m, "outputs", json_pack("{s:s?,s:s?,s:s?,s:s?}", "exr", st->o->exr, "vdb", st->o->vdb,
                                              "manifest", st->o->batch.manifest, "resume", st->o->batch.resume));
  json_object_set_new(m, "timings_ms", json_pack("{s:f,s:f,s:f,s:f,s:f,s:f}", "load", st->load_ms, "plan",
                                                 st->plan_ms, "bake", st->bake_ms, "gather", st->gather_ms, "write",
                                                 st->write_ms, "total", st->total_ms));
  json_object_set_new(m, "probes_per_s", json_real(secs > 0 ? st->probes_baked / secs : 0));
  json_object_set_new(m, "threads", json_integer(q->threads));
  json_object_set_new(m, "peak_rss_mb", json_real(ru.ru_maxrss / 1024.0));
  json_object_set_new(m, "peak_cascade_mb", json_real(st->peak_cascade_bytes / 1048576.0));
  return m;
}

/* Dumps m to path through a temporary name. */
static int dump_atomic(json_t *m, const char *path) {
  char tmp[4200];
  snprintf(tmp, sizeof tmp, "%s.tmp.%ld", path, (long)getpid());
  errno = 0;
  /* The reason too: "cannot write 'c3.json'" hid that it was a folder. */
  const char *failed = json_dump_file(m, tmp, JSON_INDENT(2) | JSON_REAL_PRECISION(17)) != 0 ? tmp
                       : rename(tmp, path) != 0                                            ? path
                                                                                           : NULL;
  if (failed) {
    int e = errno;
    remove(tmp);
    fprintf(stderr, "gi-bake: --manifest: cannot write '%s': %s\n", failed, e ? strerror(e) : "write failed");
    return EXIT_RUN;
  }
  return 0;
}

int batch_manifest(batch_state *st) {
  json_t *m = manifest_json(st);
  if (!m) {
    fprintf(stderr, "gi-bake: manifest: internal error building JSON\n");
    return EXIT_RUN;
  }
  int rc = st->o->batch.manifest ? dump_atomic(m, st->o->batch.manifest) : 0;
  if (!rc && st->o->json) {
    json_dumpf(m, stdout, JSON_INDENT(2) | JSON_REAL_PRECISION(17));
    fputc('\n', stdout);
  } else if (!rc) {
    printf("gi-bake: grid %d x %d x %d (%zu probes, %zu inside buildings, %zu without ground), %zu tiles "
           "(%zu baked, %zu resumed, %zu empty here), bake %s, %.0f ms\n",
           st->L.counts[0], st->L.counts[1], st->L.counts[2], st->grid.num_valid, st->grid.num_inside,
           st->grid.num_no_ground, st->L.tiles, st->tiles_baked, st->tiles_resumed, st->tiles_empty, st->hash,
           st->total_ms);
  }
  json_decref(m);
  return rc;
}
