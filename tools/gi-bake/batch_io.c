/* batch_io.c: the tile layout, the EXR header, atomic outputs and tile
 * checkpoints of a grid bake (batch_internal.h).
 *
 * A checkpoint is "GIBTILE1", the bake hash (16 hex digits), the tile
 * number and probe count, then (point index, gi_probe) per probe, then an
 * FNV-1a of all of it: a file from another bake or a damaged one is
 * refused, never half-used. It reaches its name by rename after fsync, so
 * a kill -9 leaves either the whole tile or nothing. */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include "batch_internal.h"

const char *const batch_attr_names[HDR_COUNT] = {"gi.kind", "gi.scene",     "gi.version", "gi.quality", "gi.effects",
                                                 "gi.grid", "gi.bake_hash", "gi.sh",      "gi.shard"};

uint64_t batch_fnv(const void *data, size_t len, uint64_t h) { return ta_fnv(h, data, len); }

void layout_tiles(batch_layout *L) {
  L->tiles = 1;
  L->n = 1;
  for (int a = 0; a < 3; a++) {
    L->ntiles[a] = (L->counts[a] + L->tile[a] - 1) / L->tile[a];
    L->tiles *= (size_t)L->ntiles[a];
    L->n *= (size_t)L->counts[a];
  }
}

size_t layout_tile_of(const batch_layout *L, size_t i) {
  size_t nx = (size_t)L->counts[0], ny = (size_t)L->counts[1];
  size_t x = i % nx, y = (i / nx) % ny, z = i / (nx * ny);
  size_t tx = x / (size_t)L->tile[0], ty = y / (size_t)L->tile[1], tz = z / (size_t)L->tile[2];
  return tx + (size_t)L->ntiles[0] * (ty + (size_t)L->ntiles[1] * tz);
}

void layout_text(const batch_layout *L, char *buf, size_t size) {
  snprintf(buf, size, "counts=%d,%d,%d origin=%.17g,%.17g,%.17g spacing=%.17g up=%c above_ground=%.17g tile=%d,%d,%d",
           L->counts[0], L->counts[1], L->counts[2], L->origin[0], L->origin[1], L->origin[2], L->spacing,
           L->up_axis == 2 ? 'z' : 'y', L->above, L->tile[0], L->tile[1], L->tile[2]);
}

int layout_parse(const char *text, batch_layout *L) {
  char up = 0;
  int used = 0;
  memset(L, 0, sizeof *L);
  if (!text || sscanf(text, "counts=%d,%d,%d origin=%lf,%lf,%lf spacing=%lf up=%c above_ground=%lf tile=%d,%d,%d%n",
                      &L->counts[0], &L->counts[1], &L->counts[2], &L->origin[0], &L->origin[1], &L->origin[2],
                      &L->spacing, &up, &L->above, &L->tile[0], &L->tile[1], &L->tile[2], &used) != 12 ||
      text[used] != '\0')
    return -1;
  L->up_axis = up == 'z' ? 2 : up == 'y' ? 1 : 0;
  double total = 1;
  for (int a = 0; a < 3; a++) {
    if (L->counts[a] < 1 || L->tile[a] < 1) return -1;
    total *= L->counts[a];
  }
  if (!L->up_axis || !(L->spacing > 0) || total > (double)GI_GRID_MAX_POINTS) return -1;
  layout_tiles(L);
  return 0;
}

size_t batch_attrs(const char *const values[HDR_COUNT], gi_exr_attr attrs[HDR_COUNT]) {
  size_t n = 0;
  for (int i = 0; i < HDR_COUNT; i++)
    if (values[i]) attrs[n++] = (gi_exr_attr){batch_attr_names[i], values[i]};
  return n;
}

/* "<path>.tmp.<pid>": where an output waits for its sibling. It is the
 * name ta_check_output removes on SIGINT/SIGTERM, so a killed run leaves
 * nothing; ".part.<pid>" files were left behind, tens of MB each for a
 * large grid. The core's writers take it as their own temporary name and
 * write it in place: "<path>.tmp.<pid>.tmp.<pid>", which a kill -9 left,
 * is no longer made (a later run removes either kind once its process is
 * gone: ta_remove_stale). */
static void part_name(const char *path, char *buf, size_t size) {
  snprintf(buf, size, "%s.tmp.%ld", path, (long)getpid());
}

int batch_write_outputs(const char *exr, const char *vdb, const gi_probe_volume *v, const gi_exr_attr *attrs,
                        size_t num_attrs, const char *hash) {
  char pe[4096], pv[4096];
  gi_error_info err = {0};
  gi_result r;
  if (exr) part_name(exr, pe, sizeof pe);
  if (vdb) part_name(vdb, pv, sizeof pv);
  if (exr && (r = gi_probe_volume_write_exr(pe, v, attrs, num_attrs, &err)) != GI_OK) {
    fprintf(stderr, "gi-bake: --exr: %s\n", err.msg[0] ? err.msg : gi_strerror(r));
    return 1;
  }
  if (vdb && (r = gi_probe_volume_write_vdb(pv, v, hash, &err)) != GI_OK) {
    fprintf(stderr, "gi-bake: --vdb: %s\n", err.msg[0] ? err.msg : gi_strerror(r));
    if (exr) remove(pe);
    return 1;
  }
  if (exr && rename(pe, exr) != 0) {
    fprintf(stderr, "gi-bake: --exr: cannot rename '%s' to '%s': %s\n", pe, exr, strerror(errno));
    remove(pe);
    if (vdb) remove(pv);
    return 1;
  }
  if (vdb && rename(pv, vdb) != 0) {
    fprintf(stderr, "gi-bake: --vdb: cannot rename '%s' to '%s': %s\n", pv, vdb, strerror(errno));
    remove(pv);
    if (exr) remove(exr); /* its sibling failed: no half of a result */
    return 1;
  }
  return 0;
}

/* 2: the tile's stats after the header (1 had none). */
#define CKPT_MAGIC "GIBTILE2"
#define CKPT_MAGIC_V1 "GIBTILE1"

static void ckpt_path(const char *dir, size_t tile, char *buf, size_t size) {
  snprintf(buf, size, "%s/tile-%07zu.bin", dir, tile);
}

int ckpt_save(const char *dir, size_t tile, const char *hash, const uint32_t *idx, size_t m, const gi_probe *probes,
              const batch_tile_stats *stats, char *msg, size_t msgsize) {
  char path[4096], tmp[4200];
  ckpt_path(dir, tile, path, sizeof path);
  snprintf(tmp, sizeof tmp, "%s.tmp.%ld", path, (long)getpid());
  /* A signal meanwhile removes it: one that came before the rename left it, whole. */
  ta_scratch_begin(tmp);
  FILE *f = fopen(tmp, "wb");
  if (!f) {
    ta_scratch_end();
    snprintf(msg, msgsize, "cannot create '%s': %s", tmp, strerror(errno));
    return -1;
  }
  uint32_t head[2] = {(uint32_t)tile, (uint32_t)m};
  uint64_t h = batch_fnv(CKPT_MAGIC, 8, BATCH_FNV_BASIS);
  h = batch_fnv(hash, 16, h);
  h = batch_fnv(head, sizeof head, h);
  h = batch_fnv(stats, sizeof *stats, h);
  int ok = fwrite(CKPT_MAGIC, 1, 8, f) == 8 && fwrite(hash, 1, 16, f) == 16 && fwrite(head, sizeof head, 1, f) == 1 &&
           fwrite(stats, sizeof *stats, 1, f) == 1;
  for (size_t j = 0; ok && j < m; j++) {
    const gi_probe *p = &probes[idx[j]];
    ok = fwrite(&idx[j], sizeof idx[j], 1, f) == 1 && fwrite(p, sizeof *p, 1, f) == 1;
    h = batch_fnv(&idx[j], sizeof idx[j], h);
    h = batch_fnv(p, sizeof *p, h);
  }
  ok = ok && fwrite(&h, sizeof h, 1, f) == 1 && fflush(f) == 0 && fsync(fileno(f)) == 0;
  if (fclose(f) != 0) ok = 0;
  if (!ok || rename(tmp, path) != 0) {
    snprintf(msg, msgsize, "cannot write '%s': %s", path, strerror(errno));
    remove(tmp);
    ta_scratch_end();
    return -1;
  }
  ta_scratch_end();
  return 0;
}

/* "tile-NNNNNNN.bin" (7 digits or more): a checkpoint's name, its temporaries' stem. */
static int owns_tile(const char *name, size_t len, const void *arg) {
  (void)arg;
  if (len < 16 || strncmp(name, "tile-", 5) || strncmp(name + len - 4, ".bin", 4)) return 0;
  for (size_t i = 5; i < len - 4; i++)
    if (name[i] < '0' || name[i] > '9') return 0;
  return 1;
}

size_t ckpt_remove_stale(ta_ctx *ta, const char *dir) { return ta_remove_stale(ta, dir, owns_tile, NULL); }

/* Reads the body after the header into probes[], checking the sum. */
static int ckpt_body(FILE *f, uint64_t h, size_t m, size_t n, gi_probe *probes) {
  for (size_t j = 0; j < m; j++) {
    uint32_t i;
    gi_probe p;
    if (fread(&i, sizeof i, 1, f) != 1 || fread(&p, sizeof p, 1, f) != 1 || i >= n) return -1;
    h = batch_fnv(&i, sizeof i, h);
    h = batch_fnv(&p, sizeof p, h);
    probes[i] = p;
  }
  uint64_t sum;
  return fread(&sum, sizeof sum, 1, f) == 1 && sum == h && fgetc(f) == EOF ? 0 : -1;
}

int ckpt_load(const char *dir, size_t tile, const char *hash, size_t n, gi_probe *probes, batch_tile_stats *stats,
              char *msg, size_t msgsize) {
  char path[4096];
  ckpt_path(dir, tile, path, sizeof path);
  FILE *f = fopen(path, "rb");
  if (!f) {
    if (errno == ENOENT) return 0;
    snprintf(msg, msgsize, "cannot read '%s': %s", path, strerror(errno));
    return -1;
  }
  char magic[8], fh[16];
  uint32_t head[2];
  int rc = -1;
  int got = fread(magic, 1, 8, f) == 8;
  if (got && !memcmp(magic, CKPT_MAGIC_V1, 8)) {
    snprintf(msg, msgsize, "'%s' is an older gi-bake's tile checkpoint (no tile record): resume into a new folder",
             path);
  } else if (!got || memcmp(magic, CKPT_MAGIC, 8) || fread(fh, 1, 16, f) != 16 ||
             fread(head, sizeof head, 1, f) != 1 || head[0] != tile) {
    snprintf(msg, msgsize, "'%s' is not a gi-bake tile checkpoint", path);
  } else if (memcmp(fh, hash, 16)) {
    snprintf(msg, msgsize, "'%s' belongs to a different bake (hash %.16s, this bake %.16s)", path, fh, hash);
  } else {
    uint64_t h = batch_fnv(CKPT_MAGIC, 8, BATCH_FNV_BASIS);
    h = batch_fnv(fh, 16, h);
    h = batch_fnv(head, sizeof head, h);
    int ok = fread(stats, sizeof *stats, 1, f) == 1;
    h = batch_fnv(stats, sizeof *stats, h);
    stats->run[sizeof stats->run - 1] = 0;
    rc = ok && ckpt_body(f, h, head[1], n, probes) == 0 ? 1 : -1;
    if (rc < 0) snprintf(msg, msgsize, "'%s' is damaged (short or checksum mismatch)", path);
  }
  fclose(f);
  return rc;
}
