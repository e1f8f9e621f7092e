/* batch.h: gi-bake's batch probe grids (--grid) and `gi-bake merge`.
 *
 * A grid bake is cut into tiles of whole probes; each tile is one cascade
 * bake around the middle of its probes, sized so the finest level spans
 * twice the tile, then one gather. Tiles run one after another, so memory
 * holds one cascade plus the grid's answers. Tile t belongs to shard
 * t mod N. Everything that goes into the EXR and VDB bytes is a function
 * of the scene, the grid and the quality only; timings go to the manifest. */
#ifndef GI_BAKE_BATCH_H
#define GI_BAKE_BATCH_H

#include <stdint.h>
#include "gi/gi.h"
#include "toolargs.h"

struct cli_opts;

/* The batch options, after strict parsing. */
typedef struct cli_batch {
  double grid;              /* spacing; 0 = no grid bake */
  int have_region;
  double region[6];         /* minx,miny,minz,maxx,maxy,maxz */
  double above;             /* --above-ground; 0 = full lattice */
  int have_above;
  int have_shard, shard_i, shard_n;
  const char *resume;       /* checkpoint folder */
  const char *manifest;     /* JSON manifest path */
  long long max_tiles;      /* refuse a grid of more tiles (0: BATCH_MAX_TILES) */
} cli_batch;

/* Tiles a grid may have unless --max-tiles says more: planning costs about
 * 1.3 ms a tile (automatic bounces), baking 0.1 to 1 s; a 1.38M-tile grid
 * planned silently for 43 s and then showed an ETA of 9.5 days. */
#define BATCH_MAX_TILES 100000

/* Option codes of the batch options (above args.c's own). */
enum { OPT_GRID = 400, OPT_REGION, OPT_ABOVE_GROUND, OPT_SHARD, OPT_RESUME, OPT_MANIFEST, OPT_MAX_TILES };

/* args.c hands these options to batch_option(). */
#define BATCH_LONG_OPTS                                        \
  {"grid", required_argument, NULL, OPT_GRID},                 \
  {"region", required_argument, NULL, OPT_REGION},             \
  {"above-ground", required_argument, NULL, OPT_ABOVE_GROUND}, \
  {"shard", required_argument, NULL, OPT_SHARD},               \
  {"resume", required_argument, NULL, OPT_RESUME},             \
  {"manifest", required_argument, NULL, OPT_MANIFEST},          \
  {"max-tiles", required_argument, NULL, OPT_MAX_TILES}

#define BATCH_HELP                                                                    \
  "Batch probe grids (see also: gi-bake merge --help)\n"                              \
  "  --grid S              bake a regular grid of probes S world units apart\n"       \
  "                        instead of one viewpoint; --exr gets one pixel per\n"      \
  "                        grid point (plus P.X,P.Y,P.Z, valid.Y), --vdb the probe\n" \
  "                        volume (sh_L00..sh_L22, irradiance, P); not with\n"       \
  "                        --half, --vdb-faces, --at, --probes or --render\n"         \
  "  --region X0,Y0,Z0,X1,Y1,Z1  the grid's box (default: the scene's bounds)\n"      \
  "  --above-ground H      one probe per column, H above the ground found by a\n"     \
  "                        downward ray; probes inside buildings are dropped\n"       \
  "  --shard I/N           bake only tiles t with t mod N = I (0 <= I < N)\n"         \
  "  --resume DIR          keep each finished tile in DIR; a rerun skips them\n"      \
  "                        (DIR must not be an output's name)\n"                      \
  "  --manifest OUT.json   grid, counts, quality, effect plan, timings, bake hash,\n" \
  "                        and each tile's record (which run baked it)\n"            \
  "  --max-tiles N         refuse a grid of more than N tiles before any work\n"     \
  "                        (default 100000)\n"                                       \
  "\n"

/* One batch option; c is OPT_GRID .. OPT_MAX_TILES. Returns 0 or an exit code. */
int batch_option(ta_ctx *ta, cli_batch *b, int c, const char *arg);
/* Combinations, once all options are read. */
int batch_check(ta_ctx *ta, struct cli_opts *o);
/* The grid bake, after the scene is loaded. Returns an exit code. */
int batch_run(const struct cli_opts *o, const gi_scene *scene, double load_ms);
/* gi-bake merge ARGS (argv[0] = "merge"). Returns an exit code. */
int batch_merge_main(int argc, char **argv);

#endif
