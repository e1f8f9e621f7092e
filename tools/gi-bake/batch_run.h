/* batch_run.h: one grid bake's state, shared by batch.c (the tile loop)
 * and batch_manifest.c (its name, progress, outputs and manifest). */
#ifndef GI_BAKE_BATCH_RUN_H
#define GI_BAKE_BATCH_RUN_H

#include "batch_internal.h"
#include "cli.h"

/* The finest level spans this many tiles, so a tile's probes sit well inside it. */
#define TILE_SPAN_RATIO 2.0

enum { TILE_BAKED = 1, TILE_RESUMED, TILE_EMPTY };

typedef struct batch_state {
  const cli_opts *o;
  const gi_scene *scene;
  gi_probe_grid grid;
  gi_quality q, resolved;
  batch_layout L;
  gi_probe *probes;          /* per point */
  uint8_t *valid;            /* per point: baked (or resumed) here */
  size_t *tile_start;        /* tiles + 1: order[tile_start[t] ..] are tile t's valid points */
  uint32_t *order;
  double *pts;               /* one tile's points, 3 each */
  gi_probe *tile_probes;
  /* The bake's name and the EXR header values. */
  char hash[17], quality[320], effects[1400], grid_text[400], version[80], shard[48];
  gi_effect plan[GI_FX_COUNT];
  int shared_bounces;        /* q's bounce count is the tiles' shared one (batch.c) */
  int tty;
  char run[32];              /* this run's name (batch_tile_stats.run) */
  /* Per tile (owned ones filled): what its bake did, and where its answers
   * came from (0 not this shard's, else a TILE_* source). */
  batch_tile_stats *tile_stats;
  uint8_t *tile_source;
  /* What happened (this run: baked; the outputs: done, resumed). */
  size_t tiles_owned, tiles_baked, tiles_resumed, tiles_empty;
  size_t probes_owned, probes_done, probes_baked;
  size_t peak_cascade_bytes;
  double load_ms, plan_ms, bake_ms, gather_ms, write_ms, total_ms, loop_start_ms;
} batch_state;

double batch_now_ms(void);
int batch_owns(const batch_state *st, size_t t);
int batch_is_dir(const char *path);
/* The effect plan, the header texts and the bake hash. Returns an exit code. */
int batch_identify(batch_state *st);
void batch_progress(batch_state *st, size_t t, const char *source);
void batch_progress_end(batch_state *st);
/* The EXR and VDB. Returns an exit code. */
int batch_write(batch_state *st);
/* The manifest file and/or the --json report, or a summary on stdout. */
int batch_manifest(batch_state *st);

#endif
