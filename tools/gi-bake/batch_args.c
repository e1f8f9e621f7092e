/* batch_args.c: the --grid options, parsed as strictly as the rest.
 *
 * Checks that need only the command line happen here (spacing, region
 * order, shard range, which outputs a shard needs); the region against the
 * scene's bounds is checked after loading, still as a usage error. */
#define _POSIX_C_SOURCE 200809L
#include <math.h>
#include <stdio.h>
#include <string.h>
#include <sys/stat.h>
#include "cli.h"

/* --shard I/N: 0 <= I < N, N >= 1. */
static int parse_shard(ta_ctx *ta, cli_batch *b, const char *arg) {
  static const char what[] = "I/N with whole numbers 0 <= I < N";
  const char *slash = strchr(arg, '/');
  char head[32];
  size_t len = slash ? (size_t)(slash - arg) : 0;
  long long i, n;
  if (!slash || len == 0 || len >= sizeof head) return ta_fail(ta, "--shard", "expected %s, got '%s'", what, arg);
  memcpy(head, arg, len);
  head[len] = '\0';
  if (ta_parse_ll(head, 0, 1 << 20, &i) != TA_OK || ta_parse_ll(slash + 1, 1, 1 << 20, &n) != TA_OK)
    return ta_fail(ta, "--shard", "expected %s, got '%s'", what, arg);
  if (i >= n) return ta_fail(ta, "--shard", "index %lld out of range for %lld shards (0..%lld), got '%s'", i, n, n - 1, arg);
  b->have_shard = 1, b->shard_i = (int)i, b->shard_n = (int)n;
  return 0;
}

int batch_option(ta_ctx *ta, cli_batch *b, int c, const char *arg) {
  int rc;
  switch (c) {
  case OPT_GRID: return ta_double(ta, "--grid", "a spacing: a finite number > 0", arg, 0, HUGE_VAL, &b->grid);
  case OPT_REGION:
    if ((rc = ta_doubles(ta, "--region", "six finite numbers minx,miny,minz,maxx,maxy,maxz", arg, 6, b->region)))
      return rc;
    for (int a = 0; a < 3; a++)
      if (b->region[a] > b->region[3 + a])
        return ta_fail(ta, "--region", "min %c exceeds max %c, got '%s'", "xyz"[a], "xyz"[a], arg);
    b->have_region = 1;
    return 0;
  case OPT_ABOVE_GROUND:
    b->have_above = 1;
    return ta_double(ta, "--above-ground", "a height: a finite number > 0", arg, 0, HUGE_VAL, &b->above);
  case OPT_SHARD: return parse_shard(ta, b, arg);
  case OPT_RESUME:
    if (!arg[0]) return ta_fail(ta, "--resume", "expected a folder, got ''");
    b->resume = arg;
    return 0;
  case OPT_MAX_TILES: return ta_ll(ta, "--max-tiles", "a tile count >= 1", arg, 1, 1LL << 40, &b->max_tiles);
  default: b->manifest = arg; return 0;
  }
}

int batch_check(ta_ctx *ta, cli_opts *o) {
  cli_batch *b = &o->batch; /* --manifest becomes the path to write (ta_check_output) */
  int rc;
  if (b->grid <= 0) {
    if (b->have_region && !o->lm.out) return ta_fail(ta, "--region", "needs --grid or --lightmap");
    if (b->have_above) return ta_fail(ta, "--above-ground", "needs --grid");
    if (b->have_shard) return ta_fail(ta, "--shard", "needs --grid");
    if (b->resume) return ta_fail(ta, "--resume", "needs --grid");
    if (b->manifest) return ta_fail(ta, "--manifest", "needs --grid");
    if (b->max_tiles) return ta_fail(ta, "--max-tiles", "needs --grid");
    return 0;
  }
  if (o->render) return ta_fail(ta, "--grid", "cannot be combined with --render");
  if (o->probes_file) return ta_fail(ta, "--grid", "cannot be combined with --probes");
  if (o->have_at) return ta_fail(ta, "--grid", "cannot be combined with --at (each tile picks its own viewpoint)");
  if (o->half) return ta_fail(ta, "--half", "is not available with --grid (shards must merge losslessly)");
  if (o->vdb_faces) return ta_fail(ta, "--vdb-faces", "is not available with --grid (the VDB is the probe volume)");
  if (b->have_shard && !o->exr) return ta_fail(ta, "--shard", "needs --exr (the merge reads the shards' EXRs)");
  if (!o->exr && !o->vdb && !b->manifest && !o->json && !b->resume)
    return ta_fail(ta, "--grid", "needs an output: --exr, --vdb, --manifest, --resume or --json");
  if (b->manifest && (rc = ta_check_output(ta, "--manifest", &b->manifest))) return rc;
  /* The folder is made and filled before the outputs are written: named as
   * an output (--manifest c3.json --resume c3.json), the whole bake ran and
   * then failed; a file of that name failed after the grid's planning. */
  if (b->resume) {
    struct stat st;
    if ((rc = ta_check_not_output(ta, "--resume", b->resume))) return rc;
    if (stat(b->resume, &st) == 0 && !S_ISDIR(st.st_mode))
      return ta_fail(ta, "--resume", "'%s' exists and is not a folder; expected a folder for the tiles", b->resume);
  }
  return 0;
}
