/* workload.c: the cone tracer against the path tracer at equal error, per
 * workload (issue 11, item 4).
 *
 * A bake is paid once and then answers many queries; the path tracer pays
 * for every query. So whether the cone tracer wins depends on how many
 * queries one bake serves. Per scene: 20, 1,000 and 10,000 probes spread
 * over the finest level's box, a lat-long panorama at the viewpoint, the
 * scene's camera view (views.c) and, on Munich, the aerial view of issue
 * 11. Each gets the cone tracer's error and time (bake + gather/render),
 * the path tracer's time to reach the same error (log-log interpolation
 * over its sample sweep), their ratio and the crossover: how many queries
 * one bake must serve before it wins.
 *
 * Probe workloads time the full count for the cone tracer (one bake, a
 * gather of N points) but measure the error on a fixed subset (the first
 * WL_SUBSET points, in random order), where a strong reference is
 * affordable; the path tracer is swept on that subset and its time scaled
 * to N by its mean cost per probe (each probe's paths are independent). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "acc.h"
#include "toolargs.h"
#include "gi/gi.h"

/* Probe counts of the probe workloads, and the subset the error is measured on. */
static const size_t wl_counts[] = {20, 1000, 10000};
#define WL_NUM_COUNTS (sizeof wl_counts / sizeof wl_counts[0])
#define WL_SUBSET 64
#define WL_SUBSET_QUICK 20
/* Speed-ups asked for by issue 11: at 10,000 probes, and one camera view with its bake. */
#define WL_GOAL_PROBES 30.0
#define WL_GOAL_PROBES_AT 10000
#define WL_GOAL_VIEW 3.0
/* The panorama's size, and the aerial view of Munich (issue 11). */
#define WL_PANO_W 256
#define WL_PANO_H 128
#define WL_AERIAL_SIDE 256
#define WL_AERIAL_TILT_DEG 18.0
#define WL_AERIAL_FOV_DEG 84.0
/* The path tracer is timed on a probe workload's full count when that
 * takes at most this long (else its time on the subset, scaled). */
#define WL_FULL_BUDGET_MS 60000.0
#define WL_FULL_BUDGET_QUICK_MS 20000.0
/* Placement: at most this many rounds of candidates, each twice what is still missing. */
#define WL_PLACE_ROUNDS 8

double acc_workload_ratio(const acc_workload *w) {
  double cone = w->bake_ms + w->answer_ms;
  return cone > 0 ? w->path_ms_eq / cone : 0;
}

static void wl_print(const acc_workload *w);

static acc_workload *wl_push(acc_workload **v, size_t *n) {
  acc_workload *g = realloc(*v, (*n + 1) * sizeof **v);
  if (!g) return NULL;
  *v = g;
  memset(&g[*n], 0, sizeof **v);
  return &g[(*n)++];
}

/* ---- probe workloads ------------------------------------------------- */

/* splitmix64: the placement's own deterministic stream. */
static double wl_u01(uint64_t *s) {
  uint64_t z = (*s += 0x9e3779b97f4a7c15ull);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
  return (double)((z ^ (z >> 31)) >> 11) * (1.0 / 9007199254740992.0);
}

/* want points, uniform in the box [lo, hi], kept where they see direct
 * light (acc_keep_lit: not inside solids), in random order. */
static int place_in_box(const acc_scene_set *ss, const double lo[3], const double hi[3], size_t want, int threads,
                        double **pts, size_t *n) {
  *pts = malloc(3 * want * sizeof **pts);
  *n = 0;
  uint64_t seed = 0x776f726b6c6f6164ull; /* "workload" */
  for (int round = 0; *pts && *n < want && round < WL_PLACE_ROUNDS; round++) {
    size_t nc = 2 * (want - *n) + 64;
    double *cand = malloc(3 * nc * sizeof *cand);
    if (!cand) break;
    for (size_t i = 0; i < 3 * nc; i++) cand[i] = lo[i % 3] + wl_u01(&seed) * (hi[i % 3] - lo[i % 3]);
    acc_scene_set t = *ss;
    t.pts = NULL;
    if (acc_keep_lit(&t, cand, nc, want - *n, threads)) {
      memcpy(*pts + 3 * *n, t.pts, 3 * t.n * sizeof *t.pts);
      *n += t.n;
    }
    free(t.pts);
    free(cand);
  }
  return *pts && *n >= want;
}

/* The strong reference at the subset's points, cached like the sweep's. */
static int subset_reference(const acc_wl_opts *o, const char *name, const acc_scene_set *ss, const double *pts,
                            size_t m, gi_ref_probe *ref) {
  int ver = o->ref_version;
  uint64_t h = acc_cache_key(name);
  h = ta_fnv(h, pts, m * 3 * sizeof *pts);
  h = ta_fnv(h, &ss->ref_samples, sizeof ss->ref_samples);
  h = ta_fnv(h, &ver, sizeof ver);
  char path[1024];
  snprintf(path, sizeof path, "%s/wlref-%s-%016llx.bin", o->out_dir, name, (unsigned long long)h);
  if (acc_cache_read(path, ref, m * sizeof *ref, NULL, 0)) {
    int ok = 1;
    for (size_t i = 0; i < m; i++) ok &= isfinite(ref[i].irradiance[1]) && isfinite(ref[i].std_err[1]);
    if (ok) return fprintf(stderr, "gi-accuracy: %s workloads: reference from cache %s\n", name, path), 1;
  }
  gi_reference_opts ro = {.samples = ss->ref_samples, .seed = 1, .threads = o->threads};
  gi_error_info err = {0};
  fprintf(stderr, "gi-accuracy: %s workloads: reference, %zu probes x %d paths...\n", name, m, ss->ref_samples);
  if (gi_reference_irradiance(ss->s, pts, m, &ro, ref, NULL, &err) != GI_OK)
    return fprintf(stderr, "gi-accuracy: %s workloads: reference: %s\n", name, err.msg), 0;
  acc_cache_write(path, ref, m * sizeof *ref, NULL, 0);
  return 1;
}

/* What the probe workloads share: one bake, its gathers, the path sweep. */
typedef struct probe_run {
  double *pts;
  size_t npts, m;            /* points placed; the error subset */
  double bake_ms, gather_ms[WL_NUM_COUNTS];
  double cone_mre_m, cone_mre_20; /* over the subset, and over its first 20 */
  double ref_se;
  int num_path, spp[ACC_WL_MAX_PATH];
  double per_probe_ms[ACC_WL_MAX_PATH], mre_m[ACC_WL_MAX_PATH], mre_20[ACC_WL_MAX_PATH];
} probe_run;

/* Bakes at the viewpoint (fastest of repeat), places the points in level
 * 0's box and times the gather of each count; the cone's probes of the
 * subset go to pr. */
static int cone_probes(const acc_wl_opts *o, const char *name, const acc_scene_set *ss, probe_run *r, gi_probe *pr) {
  gi_quality q = {.threads = o->threads};
  gi_bake_report rep;
  gi_error_info err = {0};
  gi_cascade *c = NULL;
  r->bake_ms = INFINITY;
  for (int i = 0; i < o->repeat; i++) {
    gi_cascade_free(c);
    c = NULL;
    if (gi_cascade_bake(ss->s, ss->at, &q, &c, &rep, &err) != GI_OK)
      return fprintf(stderr, "gi-accuracy: %s workloads: %s\n", name, err.msg), 0;
    r->bake_ms = fmin(r->bake_ms, acc_bake_ms(&rep));
  }
  double lo[3], hi[3], side = rep.voxel_size[0] * rep.quality.res;
  for (int k = 0; k < 3; k++) lo[k] = rep.level_origin[0][k], hi[k] = lo[k] + side;
  size_t want = wl_counts[WL_NUM_COUNTS - 1];
  int ok = place_in_box(ss, lo, hi, want, o->threads, &r->pts, &r->npts);
  if (!ok) fprintf(stderr, "gi-accuracy: %s workloads: only %zu of %zu points in level 0's box see light\n", name,
                   r->npts, want);
  gi_probe *all = ok ? malloc(want * sizeof *all) : NULL;
  for (size_t j = 0; ok && all && j < WL_NUM_COUNTS; j++) {
    r->gather_ms[j] = INFINITY;
    for (int i = 0; ok && i < o->repeat; i++) {
      double ms = 0;
      ok = gi_cascade_gather(c, r->pts, wl_counts[j], all, &ms, &err) == GI_OK;
      r->gather_ms[j] = fmin(r->gather_ms[j], ms);
    }
    if (!ok) fprintf(stderr, "gi-accuracy: %s workloads: gather: %s\n", name, err.msg);
  }
  if (ok && all) memcpy(pr, all, r->m * sizeof *pr);
  ok = ok && all;
  free(all);
  gi_cascade_free(c);
  return ok;
}

/* Whether the sweep's last count is still worse than the cone tracer on
 * either error (the subset's or its first 20 points'). */
static int path_above_cone(const probe_run *r) {
  int k = r->num_path - 1;
  return k < 0 || r->mre_m[k] > r->cone_mre_m || r->mre_20[k] > r->cone_mre_20;
}

/* The path tracer on the subset at 1, 4, .. pt_max paths per probe, and
 * on past pt_max while it is still worse than the cone tracer, up to a
 * quarter of the reference's paths (beyond that the reference's own noise
 * is most of what it measures): without the count that reaches the cone's
 * error, the comparison would be a bound, not a figure. */
static int path_probes(const acc_wl_opts *o, const char *name, const acc_scene_set *ss, const gi_ref_probe *ref,
                       probe_run *r) {
  gi_ref_probe *got = malloc(r->m * sizeof *got);
  gi_error_info err = {0};
  int ok = got != NULL;
  for (int spp = 1; ok && r->num_path < ACC_WL_MAX_PATH &&
                    (spp <= o->pt_max || (spp <= ss->ref_samples / 4 && path_above_cone(r)));
       spp *= 4) {
    gi_reference_opts ro = {.samples = spp, .seed = 2, .threads = o->threads}; /* seed 2: not the reference's */
    double best = INFINITY;
    for (int i = 0; ok && i < o->repeat; i++) {
      double t = 0;
      ok = gi_reference_irradiance(ss->s, r->pts, r->m, &ro, got, &t, &err) == GI_OK;
      best = fmin(best, t);
    }
    if (!ok) break;
    acc_metrics mm, m20;
    acc_compare_refs(got, ref, r->m, ACC_TOTAL, &mm);
    acc_compare_refs(got, ref, wl_counts[0], ACC_TOTAL, &m20);
    int k = r->num_path++;
    r->spp[k] = spp, r->per_probe_ms[k] = best / (double)r->m, r->mre_m[k] = mm.mre, r->mre_20[k] = m20.mre;
    fprintf(stderr, "  workload path %5d paths/probe: %.3f ms per probe, MRE %.4f (first 20: %.4f)\n", spp,
            r->per_probe_ms[k], mm.mre, m20.mre);
  }
  if (!ok) fprintf(stderr, "gi-accuracy: %s workloads: path tracer: %s\n", name, err.msg);
  free(got);
  return ok;
}

/* Times the path tracer on all N points at the sweep's count k (fastest of
 * repeat) when that stays within the budget; the subset's scaled time
 * otherwise. Returns 1 when it timed the full count. */
static int time_full(const acc_wl_opts *o, const acc_scene_set *ss, const probe_run *r, size_t N, int k,
                     gi_ref_probe *buf, acc_workload *w) {
  double budget = o->quick ? WL_FULL_BUDGET_QUICK_MS : WL_FULL_BUDGET_MS;
  if (N == r->m || r->per_probe_ms[k] * (double)N * o->repeat > budget) return 0;
  gi_reference_opts ro = {.samples = r->spp[k], .seed = 2, .threads = o->threads};
  gi_error_info err = {0};
  double best = INFINITY;
  for (int i = 0; i < o->repeat; i++) {
    double t = 0;
    if (gi_reference_irradiance(ss->s, r->pts, N, &ro, buf, &t, &err) != GI_OK)
      return fprintf(stderr, "gi-accuracy: workloads: path tracer on %zu probes: %s\n", N, err.msg), 0;
    best = fmin(best, t);
  }
  w->path_ms[k] = best;
  return 1;
}

/* The three probe workloads from one probe_run; the path tracer's times
 * around the cone's error are re-measured on the full count. */
static int emit_probes(const acc_wl_opts *o, const acc_scene_set *ss, const probe_run *r, const char *name,
                       acc_workload **out, size_t *n) {
  gi_ref_probe *buf = malloc(r->npts * sizeof *buf);
  size_t done = 0;
  for (size_t j = 0; buf && j < WL_NUM_COUNTS; j++, done++) {
    acc_workload *w = wl_push(out, n);
    if (!w) break;
    size_t N = wl_counts[j], em = N < r->m ? N : r->m;
    snprintf(w->scene, sizeof w->scene, "%s", name);
    snprintf(w->what, sizeof w->what, "%zu probes", N);
    snprintf(w->unit, sizeof w->unit, "probe");
    w->count = (double)N, w->err_points = em, w->ref_samples = ss->ref_samples, w->ref_err = r->ref_se;
    w->cone_mre = em < r->m ? r->cone_mre_20 : r->cone_mre_m;
    w->bake_ms = r->bake_ms, w->answer_ms = r->gather_ms[j];
    w->num_path = r->num_path;
    for (int k = 0; k < r->num_path; k++) {
      w->path_spp[k] = r->spp[k];
      w->path_ms[k] = r->per_probe_ms[k] * (double)N;
      w->path_mre[k] = em < r->m ? r->mre_20[k] : r->mre_m[k];
    }
    w->path_ms_eq = acc_ms_at_error(w->path_ms, w->path_mre, w->num_path, w->cone_mre, &w->path_how);
    /* The counts the answer depends on: the bracketing pair, or the end reached. */
    int hi = 0;
    while (hi < w->num_path - 1 && !(w->path_mre[hi] <= w->cone_mre)) hi++;
    int full = w->num_path > 0;
    for (int k = hi > 0 && w->path_how == 0 ? hi - 1 : hi; full && k <= hi && k < w->num_path; k++)
      full = time_full(o, ss, r, N, k, buf, w);
    w->path_timed_full = full || N == r->m;
    w->path_ms_eq = acc_ms_at_error(w->path_ms, w->path_mre, w->num_path, w->cone_mre, &w->path_how);
    w->goal = N == WL_GOAL_PROBES_AT ? WL_GOAL_PROBES : 0;
    wl_print(w);
  }
  free(buf);
  int ok = done == WL_NUM_COUNTS;
  return ok;
}

static int probe_workloads(const acc_wl_opts *o, const char *name, const acc_scene_set *ss, acc_workload **out,
                           size_t *n) {
  probe_run r = {.m = o->quick ? WL_SUBSET_QUICK : WL_SUBSET};
  gi_probe *pr = malloc(r.m * sizeof *pr);
  gi_ref_probe *ref = malloc(r.m * sizeof *ref);
  int ok = pr && ref && cone_probes(o, name, ss, &r, pr) && subset_reference(o, name, ss, r.pts, r.m, ref);
  if (ok) {
    acc_metrics mm, m20, se;
    acc_compare_probes(pr, ref, r.m, ACC_TOTAL, &mm);
    acc_compare_probes(pr, ref, wl_counts[0], ACC_TOTAL, &m20);
    acc_compare_refs(ref, ref, r.m, ACC_TOTAL, &se);
    r.cone_mre_m = mm.mre, r.cone_mre_20 = m20.mre, r.ref_se = se.ref_rel_se;
    fprintf(stderr, "  workload cone: bake %.1f ms, gather %.1f / %.1f / %.1f ms, MRE %.4f (first 20: %.4f)\n",
            r.bake_ms, r.gather_ms[0], r.gather_ms[1], r.gather_ms[2], mm.mre, m20.mre);
    ok = path_probes(o, name, ss, ref, &r) && emit_probes(o, ss, &r, name, out, n);
  }
  free(r.pts);
  free(pr);
  free(ref);
  return ok;
}

/* ---- image workloads -------------------------------------------------- */

static int from_view(const acc_view *v, const char *what, const char *unit, double goal, const char *png,
                     acc_workload **out, size_t *n) {
  acc_workload *w = wl_push(out, n);
  if (!w) return 0;
  snprintf(w->png, sizeof w->png, "%s", png);
  snprintf(w->scene, sizeof w->scene, "%s", v->scene);
  snprintf(w->what, sizeof w->what, "%s %dx%d", what, v->w, v->h);
  snprintf(w->unit, sizeof w->unit, "%s", unit);
  w->count = 1, w->err_points = v->pixels, w->ref_samples = v->ref_spp, w->ref_err = v->ref_mre;
  w->cone_mre = v->cone_mre, w->bake_ms = v->cone_bake_ms, w->answer_ms = v->cone_render_ms;
  w->num_path = v->num_path < ACC_WL_MAX_PATH ? v->num_path : ACC_WL_MAX_PATH;
  for (int k = 0; k < w->num_path; k++)
    w->path_spp[k] = v->path_spp[k], w->path_ms[k] = v->path_ms[k], w->path_mre[k] = v->path_mre[k];
  w->path_ms_eq = acc_ms_at_error(w->path_ms, w->path_mre, w->num_path, w->cone_mre, &w->path_how);
  w->goal = goal;
  w->path_timed_full = 1;
  wl_print(w);
  return 1;
}

/* Issue 11's aerial view of Munich: 900 m south, 250 m up, looking north
 * 18 degrees down, fov 84, 256 x 256, Z up. */
void acc_aerial_camera(gi_camera *cam) {
  memset(cam, 0, sizeof *cam);
  double t = WL_AERIAL_TILT_DEG * M_PI / 180;
  cam->eye[0] = 0, cam->eye[1] = -900, cam->eye[2] = 250;
  cam->target[0] = 0, cam->target[1] = -900 + 100 * cos(t), cam->target[2] = 250 - 100 * sin(t);
  cam->up[2] = 1;
  cam->fov_deg = WL_AERIAL_FOV_DEG;
  cam->width = cam->height = WL_AERIAL_SIDE;
}

int acc_run_workloads(const acc_wl_opts *o, const char *name, const acc_scene_set *ss, const acc_view *view,
                      int aerial, acc_workload **out, size_t *n) {
  fprintf(stderr, "gi-accuracy: %s: workloads at equal error\n", name);
  if (!probe_workloads(o, name, ss, out, n)) return 0;
  char png[1200], rel[64];
  acc_view v;
  snprintf(rel, sizeof rel, "pano-%s.png", name);
  snprintf(png, sizeof png, "%s/%s", o->md_dir, rel);
  if (!acc_run_pano(name, ss->s, ss->at, WL_PANO_W, WL_PANO_H, o->view_spp, o->threads, o->repeat, o->out_dir, png,
                    o->ref_version, &v) ||
      !from_view(&v, "panorama", "panorama", 0, rel, out, n))
    return 0;
  if (view && !from_view(view, "camera view", "view", WL_GOAL_VIEW, "", out, n)) return 0;
  if (!aerial) return 1;
  gi_camera cam;
  acc_aerial_camera(&cam);
  /* Baked where issue 11 baked it (gi-bake --up z --at 0,0,2). */
  const double at[3] = {0, 0, 2};
  char vname[48];
  snprintf(vname, sizeof vname, "%s-aerial", name);
  snprintf(rel, sizeof rel, "aerial-%s.png", name);
  snprintf(png, sizeof png, "%s/%s", o->md_dir, rel);
  if (!acc_run_view(vname, ss->s, at, &cam, o->view_spp, o->threads, o->repeat, o->out_dir, png, o->ref_version,
                    &v) ||
      !from_view(&v, "aerial view", "view", WL_GOAL_VIEW, rel, out, n))
    return 0;
  snprintf((*out)[*n - 1].scene, sizeof (*out)[*n - 1].scene, "%s", name);
  if (o->cycles && o->munich_obj) acc_cycles_aerial(o, ss->s, &cam, &(*out)[*n - 1]);
  return 1;
}

/* ---- the report -------------------------------------------------------- */

/* The goal's verdict; a bound decides only when it clears the goal. */
static const char *goal_verdict(const acc_workload *w) {
  if (!(w->goal > 0)) return "";
  double r = acc_workload_ratio(w);
  if (w->path_how < 0) return r >= w->goal ? "met" : "undecided (path tracer never reached the error)";
  if (w->path_how > 0) return r < w->goal ? "missed" : "undecided (1 sample already better)";
  return r >= w->goal ? "met" : "missed";
}

/* Milliseconds with the digits that mean something. */
static void fmt_ms(char *b, size_t n, double ms) {
  snprintf(b, n, ms >= 100 ? "%.0f" : ms >= 1 ? "%.1f" : "%.3f", ms);
}

/* The path tracer's time at the cone's error, as text ("not reached ..." when it never got there). */
static void fmt_path(char *b, size_t n, const acc_workload *w) {
  char t[32];
  fmt_ms(t, sizeof t, w->path_ms_eq);
  if (w->path_how < 0)
    snprintf(b, n, "not reached (%d paths: %s ms, %.2f%%)", w->num_path ? w->path_spp[w->num_path - 1] : 0, t,
             w->num_path ? 100 * w->path_mre[w->num_path - 1] : 0);
  else snprintf(b, n, "%s%s ms", w->path_how > 0 ? "<= " : "", t);
  if (!w->path_timed_full) snprintf(b + strlen(b), n - strlen(b), " (scaled)");
}

/* The speed-up (path / cone) as "N.NNx faster|slower", with the bound the
 * path tracer's figure allows: a lower bound when it never reached the
 * error, an upper one when one sample already did better. */
static void fmt_ratio(char *b, size_t n, const acc_workload *w) {
  double r = acc_workload_ratio(w);
  int lower = w->path_how < 0, upper = w->path_how > 0, faster = r >= 1;
  const char *bound = faster ? (lower ? ">= " : upper ? "<= " : "") : (lower ? "<= " : upper ? ">= " : "");
  snprintf(b, n, "%s%.2fx %s", bound, faster ? r : 1 / r, faster ? "faster" : "slower");
}

/* The crossover, bounded the other way round from the path tracer's time. */
static void fmt_crossover(char *b, size_t n, const acc_workload *w) {
  double x = acc_crossover(w->bake_ms, w->answer_ms / w->count, w->path_ms_eq / w->count);
  if (isinf(x)) snprintf(b, n, w->path_how < 0 ? "undecided (path tracer not reached)" : "never");
  else snprintf(b, n, "%s%.0f %s%s", w->path_how < 0 ? "<= " : w->path_how > 0 ? ">= " : "", x, w->unit,
                x == 1 ? "" : "s");
}

static void md_row(FILE *f, const acc_workload *w) {
  char bake[32], ans[32], cone[32], path[96], ratio[48], cross[64];
  fmt_ms(bake, sizeof bake, w->bake_ms), fmt_ms(ans, sizeof ans, w->answer_ms);
  fmt_ms(cone, sizeof cone, w->bake_ms + w->answer_ms);
  fmt_path(path, sizeof path, w), fmt_ratio(ratio, sizeof ratio, w), fmt_crossover(cross, sizeof cross, w);
  fprintf(f, "| %s | %s | %zu | %.2f%% | %.2f%% | %s | %s | %s | %s | %s | %s | ", w->scene, w->what, w->err_points,
          100 * w->ref_err, 100 * w->cone_mre, bake, ans, cone, path, ratio, cross);
  if (w->goal > 0) fprintf(f, ">= %gx: **%s** |\n", w->goal, goal_verdict(w));
  else fprintf(f, " |\n");
}

/* One line per workload on stderr as it is measured. */
static void wl_print(const acc_workload *w) {
  char path[96], ratio[48], cross[64];
  fmt_path(path, sizeof path, w), fmt_ratio(ratio, sizeof ratio, w), fmt_crossover(cross, sizeof cross, w);
  fprintf(stderr, "  workload %s: cone MRE %.2f%% in %.1f + %.1f = %.1f ms; path tracer %s; cone %s; "
                  "crossover %s%s%s\n", w->what, 100 * w->cone_mre, w->bake_ms, w->answer_ms, w->bake_ms + w->answer_ms,
          path, ratio, cross, w->goal > 0 ? "; goal: " : "", w->goal > 0 ? goal_verdict(w) : "");
}

/* Cycles' time at the cone tracer's error, interpolated as the path tracer's is. */
static void md_cycles_equal(FILE *f, const acc_workload *w) {
  double mre[ACC_WL_MAX_CYCLES];
  for (int k = 0; k < w->num_cycles; k++) {
    if (w->cycles_mre[k] < 0) return fprintf(f, "\n"), (void)0; /* an error not measured: no interpolation */
    mre[k] = w->cycles_mre[k];
  }
  int how;
  double t = acc_ms_at_error(w->cycles_ms, mre, w->num_cycles, w->cone_mre, &how), cone = w->bake_ms + w->answer_ms;
  double r = t / cone;
  const char *bound = how < 0 ? "more than " : how > 0 ? "at most " : "about ";
  fprintf(f, "\nAt the cone tracer's error (%.2f%%) Cycles takes %s%.0f ms%s: the cone tracer, bake included, is "
             "%s%.2fx %s.\n\n",
          100 * w->cone_mre, bound, t, how > 0 ? " (its fewest samples are already better)" : "",
          how == 0 ? "" : (how < 0) == (r >= 1) ? "at least " : "at most ", r >= 1 ? r : 1 / r,
          r >= 1 ? "faster" : "slower");
}

static void md_cycles(FILE *f, const acc_workload *w, size_t n, const char *note) {
  if (note && note[0]) {
    fprintf(f, "**Blender Cycles: skipped** (%s).\n\n", note);
    return;
  }
  for (size_t i = 0; i < n; i++) {
    if (!w[i].num_cycles) continue;
    fprintf(f, "**Blender Cycles** on the %s of %s (CPU, %d threads, no denoising, box filter; the render call "
               "alone, Blender's start-up and the OBJ import left out), against the same reference:\n\n"
               "| samples | ms | MRE | against the cone tracer (%.0f ms, %.2f%%) |\n|---|---|---|---|\n",
            w[i].what, w[i].scene, 2, w[i].bake_ms + w[i].answer_ms, 100 * w[i].cone_mre);
    for (int k = 0; k < w[i].num_cycles; k++) {
      double r = w[i].cycles_ms[k] / (w[i].bake_ms + w[i].answer_ms);
      char e[32] = "not measured";
      if (w[i].cycles_mre[k] >= 0) snprintf(e, sizeof e, "%.2f%%", 100 * w[i].cycles_mre[k]);
      fprintf(f, "| %d | %.0f | %s | cone tracer %.2fx %s, %s error |\n", w[i].cycles_spp[k], w[i].cycles_ms[k], e,
              r >= 1 ? r : 1 / r, r >= 1 ? "faster" : "slower",
              w[i].cycles_mre[k] < 0 ? "unknown" : w[i].cycles_mre[k] <= w[i].cone_mre ? "Cycles at lower" : "Cycles at higher");
    }
    md_cycles_equal(f, &w[i]);
  }
}

/* The error subset the probe workloads used (the largest count's error points). */
static int subset_of(const acc_workload *w, size_t n) {
  size_t m = 0;
  for (size_t i = 0; i < n; i++)
    if (!strcmp(w[i].unit, "probe") && w[i].err_points > m) m = w[i].err_points;
  return (int)m;
}

void acc_write_workloads_md(FILE *f, const acc_workload *w, size_t n, const char *cycles_note) {
  fprintf(f, "## At equal error, per workload\n\n"
             "One bake answers many queries; the path tracer pays for each. Per workload: the cone tracer's error "
             "and time (one bake at the viewpoint at default quality + the gather or render of every query), and "
             "the path tracer's time to reach that same error, interpolated in log-log between its swept sample "
             "counts (*not reached*: even its largest count is worse, so its time there is only a lower bound; "
             "*<=*: one sample is already better). *Crossover*: how many queries one bake must serve before "
             "bake + answers cost less than path-tracing them, bake / (path-tracer cost per query at equal error - "
             "cone answer per query). Goals (issue 11): >= %gx faster at %d probes, >= %gx for one camera view "
             "including the bake.\n\n"
             "Probe workloads: %zu points uniform in the finest level's box around the viewpoint, kept where they "
             "see direct light (not inside solids), in random order; the 20 and 1,000 probes are the first of them. "
             "The cone tracer's gather is timed over the full count; the error is measured on the first %d points "
             "(all 20 of the smallest workload) against a reference at the scene's reference paths per probe "
             "(cached), where the path tracer is also swept (1, 4, .. --pt-max paths, and on by factors of 4 up to a "
             "quarter of the reference's paths while it is still worse than the cone tracer); its time at the sample counts around the cone's error "
             "is then measured again on the full count (*scaled*: that would have taken over %.0f s, %.0f s with --quick, so the "
             "subset's time is scaled to the count by its mean cost per probe). Panorama: %dx%d lat-long at the viewpoint "
             "(gi_cascade_panorama, direct + indirect) against gi_reference_panorama. Camera view: the view of the "
             "section above. Aerial view (Munich): issue 11's 256x256 view from (0, -900, 250) looking north 18 "
             "degrees down, fov 84, baked at (0, 0, 2). Image errors as in the camera views (pixels off the sky, "
             "floor 5%% of the mean). *Reference's own error*: for probes the mean relative standard error of the "
             "subset's reference, for images half the error between its two halves; the path tracer's measured error "
             "cannot fall far below it, so a weak reference makes the path tracer look slower.\n\n",
          WL_GOAL_PROBES, WL_GOAL_PROBES_AT, WL_GOAL_VIEW, wl_counts[WL_NUM_COUNTS - 1], subset_of(w, n),
          WL_FULL_BUDGET_MS / 1000, WL_FULL_BUDGET_QUICK_MS / 1000, WL_PANO_W, WL_PANO_H);
  fprintf(f, "| scene | workload | error over | reference's own error | cone MRE | bake ms | gather/render ms | cone ms "
             "| path tracer at that error | cone tracer | crossover | goal |\n"
             "|---|---|---|---|---|---|---|---|---|---|---|---|\n");
  for (size_t i = 0; i < n; i++) md_row(f, &w[i]);
  fprintf(f, "\n");
  for (size_t i = 0; i < n; i++)
    if (w[i].png[0]) fprintf(f, "![%s, %s: cone-traced, reference, error](%s)\n\n", w[i].scene, w[i].what, w[i].png);
  md_cycles(f, w, n, cycles_note);
}

static void jsonl_row(FILE *f, const acc_workload *w) {
  double x = acc_crossover(w->bake_ms, w->answer_ms / w->count, w->path_ms_eq / w->count);
  char xs[32] = "null"; /* JSON has no infinity */
  if (!isinf(x)) snprintf(xs, sizeof xs, "%.0f", x);
  fprintf(f, "{\"scene\":\"%s\",\"workload\":\"%s\",\"unit\":\"%s\",\"count\":%.0f,\"err_points\":%zu,"
             "\"ref_samples\":%d,\"ref_err\":%.6g,\"cone_mre\":%.6g,\"bake_ms\":%.3f,\"answer_ms\":%.3f,"
             "\"path_ms_eq\":%.3f,\"path_how\":%d,\"path_timed_full\":%d,\"ratio\":%.6g,\"crossover\":%s,\"goal\":%g,\"goal_verdict\":\"%s\","
             "\"path\":[",
          w->scene, w->what, w->unit, w->count, w->err_points, w->ref_samples, w->ref_err, w->cone_mre, w->bake_ms,
          w->answer_ms, w->path_ms_eq, w->path_how, w->path_timed_full, acc_workload_ratio(w), xs, w->goal, goal_verdict(w));
  for (int k = 0; k < w->num_path; k++)
    fprintf(f, "%s{\"spp\":%d,\"ms\":%.3f,\"mre\":%.6g}", k ? "," : "", w->path_spp[k], w->path_ms[k], w->path_mre[k]);
  fprintf(f, "],\"cycles\":[");
  for (int k = 0; k < w->num_cycles; k++)
    fprintf(f, "%s{\"spp\":%d,\"ms\":%.3f,\"mre\":%.6g}", k ? "," : "", w->cycles_spp[k], w->cycles_ms[k],
            w->cycles_mre[k]);
  fprintf(f, "]}\n");
}

static int close_checked(FILE *f, const char *path) {
  int bad = ferror(f);
  if (fclose(f) || bad) return fprintf(stderr, "gi-accuracy: cannot write %s\n", path), 1;
  return 0;
}

int acc_write_workloads_files(const acc_workload *w, size_t n, const char *out_dir) {
  char csv[1100], jl[1100];
  snprintf(csv, sizeof csv, "%s/workloads.csv", out_dir);
  snprintf(jl, sizeof jl, "%s/workloads.jsonl", out_dir);
  FILE *f = fopen(csv, "w"), *g = fopen(jl, "w");
  if (!f || !g) {
    if (f) fclose(f);
    if (g) fclose(g);
    return fprintf(stderr, "gi-accuracy: cannot write %s\n", f ? jl : csv), 1;
  }
  fprintf(f, "scene,workload,unit,count,err_points,ref_samples,ref_err,cone_mre,bake_ms,answer_ms,cone_ms,path_ms_eq,"
             "path_how,path_timed_full,ratio,crossover,goal,goal_verdict,cycles_spp,cycles_ms,cycles_mre\n");
  for (size_t i = 0; i < n; i++) {
    const acc_workload *x = &w[i];
    double c = acc_crossover(x->bake_ms, x->answer_ms / x->count, x->path_ms_eq / x->count);
    /* The Cycles run nearest issue 11's 16 samples. */
    int k16 = -1;
    for (int k = 0; k < x->num_cycles; k++)
      if (k16 < 0 || abs(x->cycles_spp[k] - 16) < abs(x->cycles_spp[k16] - 16)) k16 = k;
    fprintf(f, "%s,%s,%s,%.0f,%zu,%d,%.6g,%.6g,%.3f,%.3f,%.3f,%.3f,%d,%d,%.6g,%.0f,%g,%s,", x->scene, x->what, x->unit,
            x->count, x->err_points, x->ref_samples, x->ref_err, x->cone_mre, x->bake_ms, x->answer_ms,
            x->bake_ms + x->answer_ms, x->path_ms_eq, x->path_how, x->path_timed_full, acc_workload_ratio(x), isinf(c) ? -1.0 : c,
            x->goal, x->goal > 0 ? goal_verdict(x) : "");
    if (k16 >= 0) fprintf(f, "%d,%.3f,%.6g\n", x->cycles_spp[k16], x->cycles_ms[k16], x->cycles_mre[k16]);
    else fprintf(f, ",,\n");
    jsonl_row(g, x);
  }
  int rc = close_checked(f, csv);
  return close_checked(g, jl) | rc;
}
