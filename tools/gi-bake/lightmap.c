/* lightmap.c: gi-bake's --lightmap mode, a lightmap atlas instead of probes.
 *
 * Design: args.c hands the lightmap options here (lightmap_option) and
 * asks for their checks (lightmap_check) before any scene is loaded; main.c
 * runs lightmap_run after loading the scene instead of the viewpoint bake.
 * The run lays out the charts (a chart too large for the atlas or a region
 * outside the scene is a usage error naming the option, exit 2, as is a
 * --tile cutting too many tiles or too large for its cascade), bakes
 * every tile, then writes the glTF and the EXR atlases; when the second
 * write fails the first file is removed, so a failed run leaves nothing. */
#define _POSIX_C_SOURCE 200809L
#include <dirent.h>
#include <jansson.h>
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <string.h>
#include <stdlib.h>
#include <strings.h>
#include <unistd.h>
#include "cli.h"

static ta_ctx ta = TA_CTX("gi-bake");

int lightmap_option(cli_opts *o, int c, const char *arg) {
  cli_lightmap *l = &o->lm;
  switch (c) {
  case LM_OPT_OUT: l->out = arg; return 0;
  case LM_OPT_UV_OUT: l->uv_out = arg; return 0;
  case LM_OPT_TEXEL:
    return ta_double(&ta, "--texel", "a texel size in world units > 0", arg, 0, HUGE_VAL, &l->opts.texel);
  case LM_OPT_ATLAS:
    return ta_int(&ta, "--atlas", NULL, arg, GI_LIGHTMAP_MIN_ATLAS, GI_LIGHTMAP_MAX_ATLAS, &l->opts.atlas);
  case LM_OPT_TILE:
    return ta_double(&ta, "--tile", "a tile side in world units > 0", arg, 0, HUGE_VAL, &l->opts.tile);
  case LM_OPT_OWN_CHARTS: l->opts.scene_uv = -1; return 0;
  default: return 0;
  }
}

static int ends_with_ci(const char *s, const char *suffix) {
  size_t n = strlen(s), m = strlen(suffix);
  return n >= m && !strcasecmp(s + n - m, suffix);
}

/* The lightmap's file names: OUT.exr itself for one atlas, else OUT.0001.exr
 * .. OUT.9999.exr (gi_lightmap_atlas_path), split as stem and extension of
 * the base name. */
typedef struct lm_names {
  char dir[4096], stem[1024], ext[64];
} lm_names;

static int split_names(const char *out, lm_names *n) {
  const char *slash = strrchr(out, '/'), *base = slash ? slash + 1 : out, *dot = strrchr(base, '.');
  size_t dl = !slash ? 1 : slash == out ? 1 : (size_t)(slash - out), sl = dot ? (size_t)(dot - base) : strlen(base);
  if (dl >= sizeof n->dir || sl >= sizeof n->stem || (dot && strlen(dot) >= sizeof n->ext)) return -1;
  snprintf(n->dir, sizeof n->dir, "%.*s", (int)dl, !slash ? "." : slash == out ? "/" : out);
  snprintf(n->stem, sizeof n->stem, "%.*s", (int)sl, base);
  snprintf(n->ext, sizeof n->ext, "%s", dot ? dot : "");
  return 0;
}

/* 0: not the lightmap's; 1: its bare name; 2 + k: its numbered atlas k. */
static int atlas_number(const lm_names *n, const char *name, size_t len) {
  size_t sl = strlen(n->stem), el = strlen(n->ext);
  if (len < sl + el || strncmp(name, n->stem, sl) || strncmp(name + len - el, n->ext, el)) return 0;
  if (len == sl + el) return 1;
  if (len != sl + 5 + el || name[sl] != '.') return 0;
  int k = 0;
  for (size_t i = sl + 1; i < sl + 5; i++) {
    if (name[i] < '0' || name[i] > '9') return 0;
    k = 10 * k + name[i] - '0';
  }
  return k > 0 ? 2 + k : 0;
}

static int owns_atlas(const char *name, size_t len, const void *arg) { return atlas_number(arg, name, len) != 0; }

/* Whether the file is a lightmap atlas gi-bake wrote: an EXR whose header
 * holds gi.kind = "lightmap" (only those are removed as stale). Found in
 * the header's bytes, not by gi_exr_read, which decodes every pixel of an
 * atlas (up to gigabytes) that is about to be deleted. */
static int is_lightmap_exr(const char *path) {
  static const char key[] = "gi.kind\0string\0\10\0\0\0lightmap";
  unsigned char buf[1 << 16];
  FILE *f = fopen(path, "rb");
  size_t got = f ? fread(buf, 1, sizeof buf, f) : 0;
  if (f) fclose(f);
  if (got < 4 || memcmp(buf, "\x76\x2f\x31\x01", 4)) return 0;
  for (size_t i = 4; i + sizeof key - 1 <= got; i++)
    if (!memcmp(buf + i, key, sizeof key - 1)) return 1;
  return 0;
}

int lightmap_check(cli_opts *o) {
  cli_lightmap *l = &o->lm; /* its paths become the ones to write (ta_check_output) */
  int rc;
  if (!l->out) {
    if (l->uv_out) return ta_fail(&ta, "--uv-out", "needs --lightmap");
    if (l->opts.scene_uv) return ta_fail(&ta, "--own-charts", "needs --lightmap");
    if (l->opts.texel) return ta_fail(&ta, "--texel", "needs --lightmap");
    if (l->opts.atlas) return ta_fail(&ta, "--atlas", "needs --lightmap");
    if (l->opts.tile) return ta_fail(&ta, "--tile", "needs --lightmap");
    return 0;
  }
  /* --region is shared with --grid (parsed into o->batch); a lightmap's box
   * must have volume. */
  if (o->batch.have_region)
    for (int k = 0; k < 3; k++)
      if (!(o->batch.region[k] < o->batch.region[3 + k]))
        return ta_fail(&ta, "--region", "min must be below max on every axis for --lightmap");
  if (o->batch.grid > 0) return ta_fail(&ta, "--lightmap", "cannot be combined with --grid");
  /* A lightmap covers a region, not a viewpoint, and has outputs of its own. */
  if (o->have_at) return ta_fail(&ta, "--at", "does not apply to --lightmap (use --region)");
  if (o->exr || o->vdb || o->render || o->probes_file)
    return ta_fail(&ta, "--lightmap", "cannot be combined with --exr, --vdb, --render or --probes");
  if (!ends_with_ci(l->out, ".exr")) return ta_fail(&ta, "--lightmap", "expected an .exr file name, got '%s'", l->out);
  if (l->uv_out && !ends_with_ci(l->uv_out, ".glb"))
    return ta_fail(&ta, "--uv-out", "expected a binary glTF .glb file name, got '%s'", l->uv_out);
  if ((rc = ta_check_output(&ta, "--lightmap", &l->out))) return rc;
  /* Several atlases go to OUT.0001.exr, ...: names beside a file, not a device's. */
  if (ta_output_is_special(l->out))
    return ta_fail(&ta, "--lightmap", "expected a file name (a lightmap may be several files), got a device or pipe");
  lm_names names; /* the numbered atlases' temporaries a killed run left */
  if (!split_names(l->out, &names)) ta_remove_stale(&ta, names.dir, owns_atlas, &names);
  if (l->uv_out && (rc = ta_check_output(&ta, "--uv-out", &l->uv_out))) return rc;
  return 0;
}

/* After a run wrote its atlases: the lightmap files of an earlier run under
 * the same name that this run did not write (its numbered atlases past this
 * run's count, the bare name beside numbered ones, or numbered ones beside
 * the bare name), removed and said on stderr, so OUT's files are this
 * run's alone. A file that is not a gi-bake lightmap EXR is left alone. */
static void remove_stale_atlases(const char *out, size_t written) {
  lm_names n;
  DIR *d = split_names(out, &n) ? NULL : opendir(n.dir);
  if (!d) return;
  struct dirent *e;
  while ((e = readdir(d))) {
    int k = atlas_number(&n, e->d_name, strlen(e->d_name));
    int mine = written == 1 ? k == 1 : k >= 3 && (size_t)(k - 2) <= written;
    char path[4200];
    if (!k || mine || snprintf(path, sizeof path, "%s/%s", n.dir, e->d_name) >= (int)sizeof path) continue;
    if (!is_lightmap_exr(path) || unlink(path) != 0) continue;
    fprintf(stderr, "gi-bake: removed '%s', an atlas of an earlier lightmap under this name (this one has %zu)\n", path,
            written);
  }
  closedir(d);
}

static const int held_sigs[3] = {SIGINT, SIGTERM, SIGHUP};
static struct sigaction held_old[3];
static volatile sig_atomic_t held_sig;

static void hold_signal(int sig) { held_sig = sig; }

/* on: later SIGINT/TERM/HUP are only noted; off: the former handlers back,
 * and a noted signal raised again for them. One ignored stays ignored. */
static void hold_signals(int on) {
  for (int i = 0; i < 3; i++) {
    if (on) {
      struct sigaction sa;
      memset(&sa, 0, sizeof sa);
      sa.sa_handler = hold_signal;
      sigemptyset(&sa.sa_mask);
      sigaction(held_sigs[i], NULL, &held_old[i]);
      if (held_old[i].sa_handler != SIG_IGN) sigaction(held_sigs[i], &sa, NULL);
    } else {
      sigaction(held_sigs[i], &held_old[i], NULL);
    }
  }
  if (!on && held_sig) raise(held_sig);
}

/* What a lightmap may take: the machine's memory (as --city-extent is
 * bounded) less what the process holds now (the scene) and one tile's
 * cascade, with the server's allowance for a bake's transients. 0 when
 * the machine does not say (no bound). */
typedef struct lm_memory {
  double machine, held, cascade;
} lm_memory;

static size_t lightmap_budget(const cli_opts *o, const gi_scene *scene, lm_memory *m) {
  long pages = sysconf(_SC_PHYS_PAGES), page = sysconf(_SC_PAGESIZE);
  memset(m, 0, sizeof *m);
  if (pages <= 0 || page <= 0) return 0;
  m->machine = (double)pages * (double)page;
  long size = 0, resident = 0;
  FILE *f = fopen("/proc/self/statm", "r");
  if (f && fscanf(f, "%ld %ld", &size, &resident) == 2 && resident > 0) m->held = (double)resident * (double)page;
  if (f) fclose(f);
  gi_quality rq;
  if (gi_quality_resolve(scene, &o->q, &rq, NULL) == GI_OK) {
    size_t cas = gi_cascade_bytes_estimate(&rq);
    m->cascade = (double)cas + (double)cas / 6;
  }
  double left = m->machine - m->held - m->cascade;
  return left >= 1 ? (size_t)left : 1;
}

/* A layout the options make impossible is a usage error naming the option. */
static int layout_failed(const gi_error_info *err, gi_result r, int scene_uv, const lm_memory *m) {
  if (r == GI_ERR_LIMIT) /* past the memory bound: the option that sets the texel count */
    return ta_fail(&ta, scene_uv ? "--atlas" : "--texel", "%s: this machine's %.1f GiB of memory less %.2f GiB "
                   "held now (the scene) and %.2f GiB for one tile's cascade; %s", err->msg, m->machine / 1073741824.0,
                   m->held / 1073741824.0, m->cascade / 1073741824.0,
                   scene_uv ? "lower --atlas (the scene's own UVs fill one atlas), or use --own-charts"
                            : "raise --texel or bake a smaller --region in parts");
  if (r != GI_ERR_INVALID_ARG) {
    fprintf(stderr, "gi-bake: --lightmap: %s\n", err->msg[0] ? err->msg : gi_strerror(r));
    return EXIT_RUN;
  }
  const char *opt = strstr(err->msg, "region") ? "--region" : strstr(err->msg, "atlas") ? "--atlas" : "--texel";
  return ta_fail(&ta, opt, "%s", err->msg);
}

/* The run's stages, named as a probe bake's timings_ms: load, the layout
 * (with the texels sorted into tiles, as the server's layout stage), the
 * tiles' cascade stages summed, gather (the texels and the fill), and
 * encode (writing the glTF and the atlases). */
typedef struct lm_times {
  double load, encode, total;
} lm_times;

static json_t *timings_json(const gi_lightmap_report *r, const lm_times *t) {
  return json_pack("{s:f,s:f,s:f,s:f,s:f,s:f,s:f,s:f,s:f,s:f}", "load", t->load, "layout", r->layout_ms + r->sort_ms,
                   "plan", r->ms.plan, "voxelize", r->ms.voxelize, "inject", r->ms.inject, "filter", r->ms.filter,
                   "bounce", r->ms.bounce, "gather", r->ms.gather, "encode", t->encode, "total", t->total);
}

/* The tiles' effect plans, as gi-bake's own report gives one bake's (its
 * JSON adds how many tiles ran each). */
static json_t *effects_json(const gi_lightmap_report *r) {
  json_t *fx = json_object();
  for (int i = 0; i < GI_FX_COUNT; i++)
    json_object_set_new(fx, gi_effect_name((gi_effect_id)i),
                        json_pack("{s:b,s:i,s:s}", "ran", r->effects[i].ran, "tiles", r->effect_tiles[i], "why",
                                  r->effects[i].why));
  return fx;
}

static void print_report(const cli_opts *o, const gi_lightmap *lm, const gi_lightmap_report *r, const lm_times *t) {
  size_t na = gi_lightmap_num_atlases(lm);
  if (!o->json) {
    printf("lightmap: %zu triangles in %zu charts, %zu atlas%s, %llu texels (%llu gathered, %llu filled), %d tile%s\n",
           r->triangles, r->charts, na, na == 1 ? "" : "es", (unsigned long long)r->texels,
           (unsigned long long)r->texels_valid, (unsigned long long)r->texels_filled, r->tiles, r->tiles == 1 ? "" : "s");
    printf("time: layout %.1f ms, cascades %.1f ms, gather %.1f ms, fill %.1f ms, total %.1f ms\n", r->layout_ms,
           r->cascade_ms, r->gather_ms, r->fill_ms, t->total);
    printf("stages (ms): load %.2f, layout %.2f, plan %.2f, voxelize %.2f, inject %.2f, filter %.2f, bounce %.2f, "
           "gather %.2f, encode %.2f, total %.2f\n", t->load, r->layout_ms + r->sort_ms, r->ms.plan, r->ms.voxelize,
           r->ms.inject, r->ms.filter, r->ms.bounce, r->ms.gather, t->encode, t->total);
    printf("effects (of %d tile%s)\n", r->tiles, r->tiles == 1 ? "" : "s");
    for (int i = 0; i < GI_FX_COUNT; i++)
      printf("           %-13s %-8s %d tile%s: %s\n", gi_effect_name((gi_effect_id)i),
             r->effects[i].ran ? "ran" : "skipped", r->effect_tiles[i], r->effect_tiles[i] == 1 ? "" : "s",
             r->effects[i].why);
    return;
  }
  json_t *j = json_pack("{s:I,s:I,s:I,s:I,s:I,s:I,s:i,s:f,s:f,s:f,s:f,s:f,s:o,s:s,s:s?}", "triangles",
                        (json_int_t)r->triangles, "charts", (json_int_t)r->charts, "atlases", (json_int_t)na, "texels",
                        (json_int_t)r->texels, "texels_gathered", (json_int_t)r->texels_valid, "texels_filled",
                        (json_int_t)r->texels_filled, "tiles", r->tiles, "layout_ms", r->layout_ms, "cascade_ms",
                        r->cascade_ms, "gather_ms", r->gather_ms, "fill_ms", r->fill_ms, "total_ms", t->total,
                        "timings_ms", timings_json(r, t), "exr", o->lm.out, "glb", o->lm.uv_out);
  json_object_set_new(j, "effects", effects_json(r));
  json_t *root = json_pack("{s:o}", "lightmap", j);
  char *s = json_dumps(root, JSON_INDENT(2));
  if (s) puts(s);
  free(s);
  json_decref(root);
}

int lightmap_run(const cli_opts *o, const gi_scene *scene, double t_start_ms, double load_ms, double (*now_ms)(void)) {
  gi_error_info err;
  memset(&err, 0, sizeof err);
  gi_lightmap *lm = NULL;
  gi_lightmap_opts opts = o->lm.opts;
  if (o->batch.have_region) {
    memcpy(opts.region_lo, o->batch.region, sizeof(double[3]));
    memcpy(opts.region_hi, o->batch.region + 3, sizeof(double[3]));
    opts.have_region = 1;
  }
  gi_scene_stats st;
  gi_scene_get_stats(scene, &st);
  if (st.uv2_missing && opts.scene_uv == 0)
    fprintf(stderr, "gi-bake: note: the scene's lightmap UVs (its second UV set) are not used: %llu vertices have none "
            "or non-finite ones; charts are made instead\n", (unsigned long long)st.uv2_missing);
  lm_memory mem;
  opts.max_bytes = lightmap_budget(o, scene, &mem);
  gi_result r = gi_lightmap_layout(scene, &opts, &lm, &err);
  if (r != GI_OK) return layout_failed(&err, r, opts.scene_uv == 0 && gi_scene_has_lightmap_uv(scene), &mem);
  gi_lightmap_report rep;
  lm_times t = {.load = load_ms};
  int rc = 0;
  gi_quality rq;
  if ((r = gi_lightmap_bake(lm, &o->q, NULL, &rep, &err)) != GI_OK && r == GI_ERR_LIMIT && o->lm.opts.tile > 0) {
    /* Too many tiles for --tile: the option's fault, like an atlas too
     * small (exit 2 naming it), not a failed bake (it was exit 1). */
    rc = ta_fail(&ta, "--tile", "%s", err.msg);
  } else if (r == GI_ERR_INVALID_ARG && o->lm.opts.tile > 0 && gi_quality_resolve(scene, &o->q, &rq, NULL) == GI_OK) {
    /* With a valid quality the bake refuses only a tile whose cascade
     * cannot hold its texels: --tile's fault too (it was exit 1), and the
     * coarsest level's side is the limit to compare it with. */
    rc = ta_fail(&ta, "--tile", "%s (the coarsest cascade level spans %g world units)", err.msg,
                 rq.res * rq.voxel0 * (double)(1u << (rq.levels - 1)));
  } else if (r != GI_OK) {
    fprintf(stderr, "gi-bake: lightmap bake: %s\n", err.msg[0] ? err.msg : gi_strerror(r));
    rc = EXIT_RUN;
  } else {
    /* SIGINT, SIGTERM and SIGHUP wait until every file is in place: each
     * atlas is renamed into place as it is written, so a signal between two
     * left the glTF and the first atlases under their final names, and the
     * next atlas's temporary file (not one the signal handler knows).
     * Worker threads exist already, so a signal mask would not do. */
    hold_signals(1);
    double te = now_ms();
    if (o->lm.uv_out && (r = gi_lightmap_write_gltf(lm, o->lm.uv_out, &err)) != GI_OK) {
      fprintf(stderr, "gi-bake: --uv-out: %s\n", err.msg);
      rc = EXIT_RUN;
    } else if ((r = gi_lightmap_write_exr(lm, o->lm.out, o->half, &err)) != GI_OK) {
      fprintf(stderr, "gi-bake: --lightmap: %s\n", err.msg);
      if (o->lm.uv_out) remove(o->lm.uv_out);
      rc = EXIT_RUN;
    }
    t.encode = now_ms() - te;
    hold_signals(0); /* a signal held meanwhile ends the run now */
  }
  if (!rc) {
    remove_stale_atlases(o->lm.out, gi_lightmap_num_atlases(lm));
    for (size_t i = 0; i < gi_lightmap_num_atlases(lm); i++) {
      char file[4096];
      gi_lightmap_atlas a;
      gi_lightmap_get_atlas(lm, i, &a);
      if (!gi_lightmap_atlas_path(lm, o->lm.out, i, file, sizeof file))
        fprintf(stderr, "gi-bake: wrote %s (%d x %d)\n", file, a.width, a.height);
    }
    if (o->lm.uv_out) fprintf(stderr, "gi-bake: wrote %s\n", o->lm.uv_out);
    t.total = now_ms() - t_start_ms;
    print_report(o, lm, &rep, &t);
  }
  gi_lightmap_free(lm);
  return rc;
}
