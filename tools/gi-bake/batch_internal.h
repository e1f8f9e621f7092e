/* batch_internal.h: what batch.c (the bake) and batch_merge.c share:
 * the tile layout, the EXR header, atomic output and tile checkpoints. */
#ifndef GI_BAKE_BATCH_INTERNAL_H
#define GI_BAKE_BATCH_INTERNAL_H

#include <stddef.h>
#include <stdint.h>
#include "gi/gi.h"
#include "toolargs.h" /* ta_fnv: the bake hash */

/* The grid and its tiles, as gi.grid in the EXR header records them. */
typedef struct batch_layout {
  int counts[3];
  double origin[3];
  double spacing;
  int up_axis;             /* 1 = y, 2 = z */
  double above;            /* street level height; 0 = full lattice */
  int tile[3];             /* probes per tile side, per axis */
  int ntiles[3];
  size_t tiles, n;
} batch_layout;

/* Fills ntiles, tiles and n from counts and tile. */
void layout_tiles(batch_layout *L);
/* The tile holding point i (x fastest). */
size_t layout_tile_of(const batch_layout *L, size_t i);
void layout_text(const batch_layout *L, char *buf, size_t size);
/* 0 when text is a gi.grid value that describes a sane layout. */
int layout_parse(const char *text, batch_layout *L);

/* The EXR header, always in this order; gi.shard only in a shard's file. */
enum { HDR_KIND, HDR_SCENE, HDR_VERSION, HDR_QUALITY, HDR_EFFECTS, HDR_GRID, HDR_HASH, HDR_SH, HDR_SHARD, HDR_COUNT };
extern const char *const batch_attr_names[HDR_COUNT];
#define BATCH_KIND "probe-grid"
/* attrs[] from values[] (values[HDR_SHARD] NULL: no gi.shard); returns the count. */
size_t batch_attrs(const char *const values[HDR_COUNT], gi_exr_attr attrs[HDR_COUNT]);

/* Writes the EXR and/or VDB (either path may be NULL) under temporary
 * names and renames both only when both are written, so a failure leaves
 * neither. Prints "gi-bake: OPT: why" and returns 0 or 1. */
int batch_write_outputs(const char *exr, const char *vdb, const gi_probe_volume *v, const gi_exr_attr *attrs,
                        size_t num_attrs, const char *hash);

/* What a tile's bake did, kept in its checkpoint so that the manifest of a
 * resumed bake still describes every tile in the outputs (it counted only
 * the last run's). 64 bytes, no padding: written as they are. */
typedef struct batch_tile_stats {
  char run[32];              /* the run that baked it: "YYYYMMDDTHHMMSSZ-PID" (UTC start, process id) */
  uint32_t outside_level0;   /* its probes outside the finest level */
  uint32_t fx_ran;           /* bit e: effect e ran in its cascade */
  uint64_t cascade_bytes;
  double bake_ms, gather_ms;
} batch_tile_stats;

/* Tile checkpoints in a --resume folder. ckpt_load: 1 loaded (into probes[]
 * by point index, and *stats), 0 absent, -1 unusable (why in msg). */
int ckpt_load(const char *dir, size_t tile, const char *hash, size_t n, gi_probe *probes, batch_tile_stats *stats,
              char *msg, size_t msgsize);
/* Writes tile's m probes (point indices idx) and its stats via a temporary
 * name and a rename, after fsync. 0 or -1 (why in msg). */
int ckpt_save(const char *dir, size_t tile, const char *hash, const uint32_t *idx, size_t m, const gi_probe *probes,
              const batch_tile_stats *stats, char *msg, size_t msgsize);

/* Removes the tile temporaries "tile-NNNNNNN.bin.tmp.<pid>" in dir that a
 * killed run (kill -9) left, when their process is gone; returns how many. */
size_t ckpt_remove_stale(ta_ctx *ta, const char *dir);

/* 64-bit FNV-1a, continued from h. */
uint64_t batch_fnv(const void *data, size_t len, uint64_t h);
#define BATCH_FNV_BASIS 14695981039346656037ull

#endif
