/* batch_merge.c: gi-bake merge, shards of a grid bake into one result.
 *
 * Each shard's EXR holds the whole grid with only its own tiles valid, and
 * a header naming the bake (gi.bake_hash), the layout (gi.grid) and the
 * share (gi.shard = I/N). The merge reads the shards one at a time, takes
 * every point from the shard owning its tile (tile mod N), and writes the
 * EXR and VDB with the same writers and header as an unsharded bake, so the
 * bytes are the same. Float channels round-trip exactly. Every input is
 * checked (same bake, each share once, none missing) before anything is
 * written. */
#define _POSIX_C_SOURCE 200809L
#include <getopt.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "batch.h"
#include "batch_internal.h"

static const char merge_help[] =
    "Usage: gi-bake merge [--exr OUT.exr] [--vdb OUT.vdb] SHARD.exr...\n"
    "Joins the probe EXRs of a grid bake's shards (gi-bake --grid ... --shard I/N\n"
    "--exr SHARD.exr) into the probe EXR and/or probe volume VDB the unsharded\n"
    "bake writes, byte for byte. Every shard 0..N-1 of one bake must be given once.\n"
    "\n"
    "  --exr OUT.exr   the merged probe EXR\n"
    "  --vdb OUT.vdb   the merged probe volume (sh_L00..sh_L22, irradiance, P)\n"
    "  -h, --help      this text\n"
    "\n"
    "Exit status: 0 success, 1 a shard is missing, unreadable or from another bake, 2 bad arguments.\n";

typedef struct {
  const char *exr, *vdb;
  char **inputs;
  int num_inputs;
} merge_opts;

/* What the first shard said, which every other must repeat. */
typedef struct {
  char *values[HDR_COUNT];
  const char *first;
  char **inputs;
  batch_layout L;
  int shards, ao;
  int *seen;               /* per shard index: the input number + 1 */
  gi_probe *probes;
  double *pos;
  uint8_t *valid;
} merge_state;

static ta_ctx ta = TA_CTX("gi-bake merge");

static int parse_merge(int argc, char **argv, merge_opts *m) {
  static const struct option opts[] = {{"exr", required_argument, NULL, 'e'},
                                       {"vdb", required_argument, NULL, 'v'},
                                       {"help", no_argument, NULL, 'h'},
                                       {NULL, 0, NULL, 0}};
  int c, rc;
  memset(m, 0, sizeof *m);
  optind = 1;
  opterr = 0;
  while ((c = getopt_long(argc, argv, ":h", opts, NULL)) != -1) {
    if (c == 'h') {
      fputs(merge_help, stdout);
      return -1;
    }
    /* A second --exr (meant as --vdb?) silently replaced the first. */
    const char **out = c == 'e' ? &m->exr : c == 'v' ? &m->vdb : NULL;
    if (!out) return ta_getopt_fail(&ta, c, argv, opts);
    if (*out) return ta_fail(&ta, c == 'e' ? "--exr" : "--vdb", "given twice ('%s' and '%s')", *out, optarg);
    *out = optarg;
  }
  if (!m->exr && !m->vdb) return ta_fail(&ta, NULL, "needs --exr OUT.exr and/or --vdb OUT.vdb");
  if (optind >= argc) return ta_fail(&ta, NULL, "no shard EXRs given");
  if (m->exr && (rc = ta_check_output(&ta, "--exr", &m->exr))) return rc;
  if (m->vdb && (rc = ta_check_output(&ta, "--vdb", &m->vdb))) return rc;
  m->inputs = argv + optind;
  m->num_inputs = argc - optind;
  /* An output on a shard would replace that shard with the merged file (no
   * gi.shard), so the same merge could never run again. */
  for (int k = 0; k < m->num_inputs; k++)
    if ((rc = ta_check_outputs_spare(&ta, "shard input", m->inputs[k]))) return rc;
  return 0;
}

static int bad(const char *file, const char *why) {
  fprintf(stderr, "gi-bake merge: %s: %s\n", file, why);
  return TA_EXIT_RUN;
}

/* The first shard: the bake's header, layout and room for the result. */
static int first_shard(merge_state *s, const char *file, const gi_exr_file *f, const char *vals[HDR_COUNT]) {
  s->first = file;
  for (int i = 0; i < HDR_COUNT; i++)
    if (vals[i] && !(s->values[i] = strdup(vals[i]))) return bad(file, "out of memory");
  if (layout_parse(vals[HDR_GRID], &s->L) != 0) return bad(file, "gi.grid does not describe a probe grid");
  s->ao = gi_exr_file_channel(f, "ao.Y") != NULL;
  s->seen = calloc((size_t)s->shards, sizeof *s->seen);
  s->probes = calloc(s->L.n, sizeof *s->probes);
  s->pos = calloc(s->L.n * 3, sizeof *s->pos);
  s->valid = calloc(s->L.n, 1);
  if (!s->seen || !s->probes || !s->pos || !s->valid) return bad(file, "out of memory");
  return 0;
}

/* Header checks: a shard of the same bake, not seen before. */
static int check_header(merge_state *s, const char *file, const gi_exr_file *f, int index) {
  const char *vals[HDR_COUNT];
  for (int i = 0; i < HDR_COUNT; i++) vals[i] = gi_exr_file_attr(f, batch_attr_names[i]);
  if (!vals[HDR_KIND] || strcmp(vals[HDR_KIND], BATCH_KIND))
    return bad(file, "not a probe-grid EXR from gi-bake --grid (gi.kind)");
  for (int i = 0; i < HDR_COUNT; i++)
    if (!vals[i]) {
      char why[128];
      snprintf(why, sizeof why, "header attribute %s missing (not a shard of a grid bake?)", batch_attr_names[i]);
      return bad(file, why);
    }
  int si, sn, used = 0;
  if (sscanf(vals[HDR_SHARD], "%d/%d%n", &si, &sn, &used) != 2 || vals[HDR_SHARD][used] || sn < 1 || si < 0 ||
      si >= sn)
    return bad(file, "gi.shard is not I/N");
  if (index == 0) {
    s->shards = sn;
    int rc = first_shard(s, file, f, vals);
    if (rc) return rc;
  }
  char why[512];
  if (strcmp(vals[HDR_HASH], s->values[HDR_HASH])) {
    /* Shards of one scene and grid baked by two builds or CPU paths: the
     * version says which (the hashes alone look like another scene). */
    char by[320] = "";
    if (strcmp(vals[HDR_VERSION], s->values[HDR_VERSION]))
      snprintf(by, sizeof by, ": it was baked by '%.100s', %.80s by '%.100s'", vals[HDR_VERSION], s->first,
               s->values[HDR_VERSION]);
    snprintf(why, sizeof why, "belongs to a different bake (gi.bake_hash %s; %s has %s)%s", vals[HDR_HASH], s->first,
             s->values[HDR_HASH], by);
    return bad(file, why);
  }
  for (int i = 0; i < HDR_SHARD; i++)
    if (strcmp(vals[i], s->values[i])) {
      snprintf(why, sizeof why, "%s differs from %s's although the bake hash is the same", batch_attr_names[i],
               s->first);
      return bad(file, why);
    }
  if (sn != s->shards) {
    snprintf(why, sizeof why, "is shard %d of %d, but %s is one of %d", si, sn, s->first, s->shards);
    return bad(file, why);
  }
  /* Every shard, not only the first: its points are read as the grid's. */
  if (gi_exr_file_width(f) != s->L.counts[0] || gi_exr_file_height(f) != s->L.counts[1] * s->L.counts[2]) {
    snprintf(why, sizeof why, "image is %d x %d, but its gi.grid needs %d x %d", gi_exr_file_width(f),
             gi_exr_file_height(f), s->L.counts[0], s->L.counts[1] * s->L.counts[2]);
    return bad(file, why);
  }
  if (s->seen[si]) {
    snprintf(why, sizeof why, "shard %d/%d given twice (also '%s')", si, sn, s->inputs[s->seen[si] - 1]);
    return bad(file, why);
  }
  s->seen[si] = index + 1;
  return 0;
}

/* Channel `name` of f; the first one missing is kept in *missing. */
static const float *channel(const gi_exr_file *f, const char *name, char missing[32]) {
  const float *c = gi_exr_file_channel(f, name);
  if (!c && !missing[0]) snprintf(missing, 32, "%s", name);
  return c;
}

/* Copies the points of the tiles this shard owns. */
static int take_points(merge_state *s, const char *file, const gi_exr_file *f, int shard) {
  static const char *const sh_names[9] = {"L00", "L1-1", "L10", "L11", "L2-2", "L2-1", "L20", "L21", "L22"};
  const float *irr[3], *dir[3], *ind[3], *sh[9][3], *P[3], *val, *ao = NULL;
  char name[32], missing[32] = "";
  val = channel(f, "valid.Y", missing);
  for (int k = 0; k < 3; k++) {
    char c = "RGB"[k];
    snprintf(name, sizeof name, "irradiance.%c", c), irr[k] = channel(f, name, missing);
    snprintf(name, sizeof name, "direct.%c", c), dir[k] = channel(f, name, missing);
    snprintf(name, sizeof name, "indirect.%c", c), ind[k] = channel(f, name, missing);
    snprintf(name, sizeof name, "P.%c", "XYZ"[k]), P[k] = channel(f, name, missing);
    for (int i = 0; i < 9; i++)
      snprintf(name, sizeof name, "sh.%s.%c", sh_names[i], c), sh[i][k] = channel(f, name, missing);
  }
  if (s->ao) ao = channel(f, "ao.Y", missing);
  if (missing[0]) {
    char why[160];
    snprintf(why, sizeof why, "probe-grid channel %s is missing%s", missing,
             s->ao && !ao ? " (the first shard has ao.Y)" : "");
    return bad(file, why);
  }
  for (size_t i = 0; i < s->L.n; i++) {
    if ((int)(layout_tile_of(&s->L, i) % (size_t)s->shards) != shard) continue;
    gi_probe *p = &s->probes[i];
    for (int k = 0; k < 3; k++) {
      p->irradiance[k] = irr[k][i], p->direct[k] = dir[k][i], p->indirect[k] = ind[k][i];
      s->pos[3 * i + k] = P[k][i];
      for (int c = 0; c < 9; c++) p->sh[c][k] = sh[c][k][i];
    }
    p->ao = ao ? ao[i] : 0;
    s->valid[i] = val[i] != 0;
  }
  return 0;
}

static int read_shards(merge_state *s, const merge_opts *m) {
  for (int k = 0; k < m->num_inputs; k++) {
    gi_exr_file *f = NULL;
    gi_error_info err = {0};
    gi_result r = gi_exr_read(m->inputs[k], &f, &err);
    if (r != GI_OK) return bad(m->inputs[k], err.msg[0] ? err.msg : gi_strerror(r));
    int rc = check_header(s, m->inputs[k], f, k);
    if (!rc) {
      int si = 0;
      sscanf(gi_exr_file_attr(f, "gi.shard"), "%d", &si);
      rc = take_points(s, m->inputs[k], f, si);
    }
    gi_exr_file_free(f);
    if (rc) return rc;
  }
  for (int i = 0; i < s->shards; i++)
    if (!s->seen[i]) {
      fprintf(stderr, "gi-bake merge: shard %d/%d missing (bake %s); nothing written\n", i, s->shards,
              s->values[HDR_HASH]);
      return TA_EXIT_RUN;
    }
  return 0;
}

int batch_merge_main(int argc, char **argv) {
  merge_opts m;
  int rc = parse_merge(argc, argv, &m);
  if (rc) return rc < 0 ? 0 : rc;
  merge_state s;
  memset(&s, 0, sizeof s);
  s.inputs = m.inputs;
  rc = read_shards(&s, &m);
  if (!rc) {
    const char *vals[HDR_COUNT];
    for (int i = 0; i < HDR_COUNT; i++) vals[i] = s.values[i];
    vals[HDR_SHARD] = NULL; /* the merged file is the whole bake */
    gi_exr_attr attrs[HDR_COUNT];
    size_t na = batch_attrs(vals, attrs);
    gi_probe_volume v = {.spacing = s.L.spacing, .up_axis = s.L.up_axis, .street_level = s.L.above > 0, .n = s.L.n,
                         .pos = s.pos, .valid = s.valid, .probes = s.probes, .ao = s.ao};
    memcpy(v.counts, s.L.counts, sizeof v.counts);
    memcpy(v.origin, s.L.origin, sizeof v.origin);
    rc = batch_write_outputs(m.exr, m.vdb, &v, attrs, na, s.values[HDR_HASH]);
    if (!rc) fprintf(stderr, "gi-bake merge: %d shards of bake %s merged\n", s.shards, s.values[HDR_HASH]);
  }
  for (int i = 0; i < HDR_COUNT; i++) free(s.values[i]);
  free(s.seen); free(s.probes); free(s.pos); free(s.valid);
  return rc;
}
