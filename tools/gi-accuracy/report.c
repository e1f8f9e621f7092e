/* report.c: gi-accuracy's outputs: CSV, gnuplot plot and markdown report.
 *
 * Every file goes to a temporary name and is renamed into place. The
 * markdown is generated entirely from the measured rows, so `make accuracy`
 * regenerates docs/accuracy.md without hand edits; the sentences that
 * answer "what does each knob buy" are computed from the rows next to the
 * default. The plot is drawn by gnuplot when it is installed (package
 * gnuplot-nox); without it the script is still written and the report says so. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>
#include "acc.h"


/* A relative error's table cell: "n/a" where the reference reads 0 at
 * every probe (metrics.c gives NaN), else a percentage / a number. */
static void pct_cell(double v, char *buf, size_t size) {
  if (isnan(v)) snprintf(buf, size, "n/a");
  else snprintf(buf, size, "%.2f%%", 100 * v);
}
static void num_cell(double v, char *buf, size_t size) {
  if (isnan(v)) snprintf(buf, size, "n/a");
  else snprintf(buf, size, "%.3g", v);
}

static FILE *open_tmp(const char *path, char *tmp, size_t n) {
  snprintf(tmp, n, "%s.tmp.%d", path, (int)getpid());
  FILE *f = fopen(tmp, "w");
  if (!f) fprintf(stderr, "gi-accuracy: cannot write %s\n", tmp);
  return f;
}

static int close_rename(FILE *f, const char *tmp, const char *path) {
  int bad = ferror(f);
  if (fclose(f) != 0 || bad || rename(tmp, path) != 0) {
    fprintf(stderr, "gi-accuracy: cannot write %s\n", path);
    remove(tmp);
    return 1;
  }
  return 0;
}

static const acc_row *find_default(const acc_row *r, size_t n, const char *scene) {
  for (size_t i = 0; i < n; i++)
    if (!strcmp(r[i].scene, scene) && r[i].is_default) return &r[i];
  return NULL;
}

/* Path-tracing time to reach error e (total MRE), by log-log interpolation
 * between the measured sample counts; -1 when the curve never reaches e,
 * 0 when even one sample is better. */
/* The largest path-tracer sample count in the rows (of scene; NULL: any):
 * the report said 4096 whatever --pt-max swept. */
static int path_max(const acc_row *r, size_t n, const char *scene) {
  double m = 0;
  for (size_t i = 0; i < n; i++)
    if (!strcmp(r[i].kind, "path") && (!scene || !strcmp(r[i].scene, scene))) m = fmax(m, r[i].value);
  return (int)m;
}

static double path_ms_at(const acc_row *r, size_t n, const char *scene, double e) {
  const acc_row *prev = NULL;
  for (size_t i = 0; i < n; i++) {
    if (strcmp(r[i].scene, scene) || strcmp(r[i].kind, "path")) continue;
    double ei = r[i].m[ACC_TOTAL].mre;
    if (ei <= e) {
      if (!prev) return 0;
      double ep = prev->m[ACC_TOTAL].mre;
      double t = (log(e) - log(ep)) / (log(ei) - log(ep));
      return exp(log(prev->ms) + t * (log(r[i].ms) - log(prev->ms)));
    }
    prev = &r[i];
  }
  return -1;
}

static int write_csv(const acc_row *r, size_t n, const char *path) {
  char tmp[1100];
  FILE *f = open_tmp(path, tmp, sizeof tmp);
  if (!f) return 1;
  fprintf(f, "scene,kind,knob,value,default,ms,bake_ms,gather_ms,relmse_total,mre_total,relmse_direct,mre_direct,"
             "relmse_indirect,mre_indirect,ratio_indirect_mean,ratio_indirect_min,ratio_indirect_max,"
             "ref_rel_se_total,pareto\n");
  for (size_t i = 0; i < n; i++) {
    const acc_row *x = &r[i];
    fprintf(f, "%s,%s,%s,%.6g,%d,%.3f,%.3f,%.3f,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.5f,%.5f,%.5f,%.6g,%d\n", x->scene,
            x->kind, x->knob, x->value, x->is_default, x->ms, x->bake_ms, x->gather_ms, x->m[0].rel_mse,
            x->m[0].mre, x->m[1].rel_mse, x->m[1].mre, x->m[2].rel_mse, x->m[2].mre, x->m[2].ratio_mean,
            x->m[2].ratio_min, x->m[2].ratio_max, x->m[0].ref_rel_se, x->on_front);
  }
  return close_rename(f, tmp, path);
}

/* One panel per scene: cone bakes, default, path tracer, Pareto front. */
static int write_plot(const acc_row *r, size_t n, const acc_scene_info *sc, size_t nsc, const char *csv,
                      const char *out_dir, const char *png, int *drawn) {
  char gp[1024], tmp[1100];
  snprintf(gp, sizeof gp, "%s/accuracy.gp", out_dir);
  FILE *f = open_tmp(gp, tmp, sizeof tmp);
  if (!f) return 1;
  fprintf(f, "# gi-accuracy plot: mean relative error of irradiance against milliseconds, log-log.\n"
             "if (strstrt(GPVAL_TERMINALS, 'pngcairo') > 0) { set terminal pngcairo size %d,520 font ',10' } "
             "else { set terminal png size %d,520 }\n"
             "set output '%s'\nset datafile separator ','\nset logscale xy\nset grid\n"
             "set xlabel 'milliseconds (bake + gather, or path tracing)'\n"
             "set ylabel 'mean relative error of irradiance'\nset key bottom left font ',8'\n"
             "set multiplot layout 1,%zu\n",
          (int)(520 * (nsc ? nsc : 1)), (int)(520 * (nsc ? nsc : 1)), png, nsc ? nsc : 1);
  for (size_t s = 0; s < nsc; s++) {
    const char *nm = sc[s].name;
    fprintf(f,
            "set title '%s (%zu probes)'\n"
            "plot '%s' u ((strcol(1) eq '%s' && strcol(2) eq 'cone') ? $6 : 1/0):10 w p pt 7 ps 0.8 lc rgb '#4477aa' t 'cone tracer (one knob moved)', \\\n"
            "     '' u ((strcol(1) eq '%s' && strcol(2) eq 'cone') ? $6 : 1/0):10:(strcol(3)) w labels offset 0,0.7 font ',6' notitle, \\\n"
            "     '' u ((strcol(1) eq '%s' && $5 == 1) ? $6 : 1/0):10 w p pt 6 ps 2.5 lw 2 lc rgb '#000000' t 'default quality', \\\n"
            "     '' u ((strcol(1) eq '%s' && strcol(2) eq 'path') ? $6 : 1/0):10 w lp pt 5 ps 0.8 lc rgb '#cc3311' t 'path tracer, 1..%d samples', \\\n"
            "     '' u ((strcol(1) eq '%s' && $19 == 1) ? $6 : 1/0):10 smooth unique w l lw 2 dt 2 lc rgb '#228833' t 'Pareto front'\n",
            nm, sc[s].probes, csv, nm, nm, nm, nm, path_max(r, n, nm), nm);
  }
  fprintf(f, "unset multiplot\n");
  if (close_rename(f, tmp, gp)) return 1;
  *drawn = 0;
  if (system("command -v gnuplot >/dev/null 2>&1") == 0) {
    char cmd[2200];
    snprintf(cmd, sizeof cmd, "gnuplot '%s'", gp);
    if (system(cmd) == 0) *drawn = 1;
    else *drawn = -1, fprintf(stderr, "gi-accuracy: gnuplot failed on %s\n", gp);
  } else {
    fprintf(stderr, "gi-accuracy: gnuplot not installed (package gnuplot-nox): %s not drawn\n", png);
  }
  return 0;
}

static const char *knob_what(const char *k) {
  if (!strcmp(k, "res")) return "voxels per side R (finer voxels over the same extent)";
  if (!strcmp(k, "levels")) return "cascade levels n (same finest voxel: reach doubles per level)";
  if (!strcmp(k, "voxel0")) return "finest voxel size s0 (the whole cascade scales with it)";
  if (!strcmp(k, "cones")) return "diffuse cones per hemisphere";
  if (!strcmp(k, "aperture")) return "diffuse cone aperture (degrees)";
  if (!strcmp(k, "step")) return "march step, fraction of the cone diameter";
  if (!strcmp(k, "bounces")) return "voxel-to-voxel bounces";
  if (!strcmp(k, "light_samples")) return "sky and emitter samples per voxel (the injection; probes keep their own)";
  if (!strcmp(k, "high")) return "all the helpful knobs together (R 64, s0/2, 32 cones, step 0.25, bounces from the albedo rule)";
  return k;
}

static const acc_row *find_knob(const acc_row *r, size_t n, const char *scene, const char *knob) {
  for (size_t i = 0; i < n; i++)
    if (!strcmp(r[i].scene, scene) && !strcmp(r[i].knob, knob)) return &r[i];
  return NULL;
}

/* The ambition, measured: Cornell-box indirect error at default
 * (10%) and high quality (5%), and speed against the path tracer at equal
 * error (30x), per scene. */
/* The reference's own noise per scene: a reference is trusted when its
 * mean relative standard error of indirect light is within this. */
#define REF_TRUSTED_SE 0.02
static void write_ref_noise(FILE *f, const acc_scene_info *sc, size_t nsc) {
  fprintf(f, "- The reference's own noise (mean relative standard error over the probes; ambition: indirect within "
             "%.0f%%):\n\n| scene | paths per probe | indirect | direct | total | trusted |\n|---|---|---|---|---|---|\n",
          100 * REF_TRUSTED_SE);
  for (size_t s = 0; s < nsc; s++)
    fprintf(f, "| %s | %d | %.2f%% | %.2f%% | %.2f%% | %s |\n", sc[s].name, sc[s].ref_samples,
            100 * sc[s].ref_rel_se[ACC_INDIRECT], 100 * sc[s].ref_rel_se[ACC_DIRECT],
            100 * sc[s].ref_rel_se[ACC_TOTAL], sc[s].ref_rel_se[ACC_INDIRECT] <= REF_TRUSTED_SE ? "yes" : "no");
  fprintf(f, "\n");
}

/* The city issue's item 6: a street probe in the 5 km city as accurate as
 * in the 600 m city at the same quality, within this many points of
 * indirect error. */
#define SCALE_POINTS 2.0
static void write_scale(FILE *f, const acc_row *r, size_t n) {
  const char *what[2] = {"default", "high"};
  for (int k = 0; k < 2; k++) {
    const acc_row *a = k ? find_knob(r, n, "city", "high") : find_default(r, n, "city");
    const acc_row *b = k ? find_knob(r, n, "city5k", "high") : find_default(r, n, "city5k");
    if (!a || !b) continue;
    double ea = 100 * a->m[ACC_INDIRECT].mre, eb = 100 * b->m[ACC_INDIRECT].mre;
    fprintf(f, "- Scale, %s quality: indirect mean relative error at street probes **%.2f%%** in the 5 km city "
               "(ratio %.3f), %.2f%% in the 600 m city (ratio %.3f): %+.2f points (ambition: within %.0f) -> %s.\n",
            what[k], eb, b->m[ACC_INDIRECT].ratio_mean, ea, a->m[ACC_INDIRECT].ratio_mean, eb - ea, SCALE_POINTS,
            eb - ea <= SCALE_POINTS ? "met" : "not met");
  }
}

static void write_standing(FILE *f, const acc_row *r, size_t n, const acc_scene_info *sc, size_t nsc) {
  fprintf(f, "## Standing against the ambition\n\n");
  const acc_row *d = find_default(r, n, "cornell"), *h = find_knob(r, n, "cornell", "high");
  if (d)
    fprintf(f, "- Cornell box, default quality, indirect irradiance: mean relative error **%.1f%%** (ambition: "
               "within 10%%) -> %s.\n", 100 * d->m[ACC_INDIRECT].mre, d->m[ACC_INDIRECT].mre <= 0.10 ? "met" : "not met");
  if (h)
    fprintf(f, "- Cornell box, high quality (%s), indirect: **%.1f%%** (ambition: within 5%%) -> %s.\n",
            "R 64, s0/2, 32 cones, step 0.25, bounces from the albedo rule", 100 * h->m[ACC_INDIRECT].mre,
            h->m[ACC_INDIRECT].mre <= 0.05 ? "met" : "not met");
  write_scale(f, r, n);
  write_ref_noise(f, sc, nsc);
  fprintf(f, "- Speed at equal error (ambition: the cone tracer at least 30x faster than the path tracer):\n\n"
             "| scene | default ms (bake + gather) | gather ms | default total MRE | path tracer ms at that error "
             "| speed-up, bake + gather | speed-up, gather alone |\n"
             "|---|---|---|---|---|---|---|\n");
  for (size_t s = 0; s < nsc; s++) {
    const acc_row *x = find_default(r, n, sc[s].name);
    if (!x) continue;
    double pt = path_ms_at(r, n, sc[s].name, x->m[ACC_TOTAL].mre);
    if (pt > 0)
      fprintf(f, "| %s | %.1f | %.2f | %.2f%% | %.2f | %.3gx | %.3gx |\n", sc[s].name, x->ms, x->gather_ms,
              100 * x->m[ACC_TOTAL].mre, pt, pt / x->ms, x->gather_ms > 0 ? pt / x->gather_ms : 0);
    else if (pt == 0)
      fprintf(f, "| %s | %.1f | %.2f | %.2f%% | 1 sample already better | - | - |\n", sc[s].name, x->ms,
              x->gather_ms, 100 * x->m[ACC_TOTAL].mre);
    else
      fprintf(f, "| %s | %.1f | %.2f | %.2f%% | not reached by %d samples | - | - |\n", sc[s].name, x->ms,
              x->gather_ms, 100 * x->m[ACC_TOTAL].mre, path_max(r, n, sc[s].name));
  }
  fprintf(f, "\n(A speed-up below 1 means the path tracer is faster at that error. Probe answers: the cone "
             "tracer's bake is paid once per viewpoint and amortised over every probe gathered from it, the path "
             "tracer pays per probe; with %s probes per scene here, a bake serving thousands of probes would "
             "compare differently. *Gather alone* is what a repeat request near a cached viewpoint costs the "
             "server. Camera views, where one bake serves every pixel, follow below.)\n\n", nsc ? "about 20" : "few");
}

static int write_md(const acc_row *r, size_t n, const acc_scene_info *sc, size_t nsc, const acc_view *views,
                    size_t nviews, const acc_wl_report *wl, const char *path, const char *png, int drawn,
                    const char *machine, const char *cmdline, const char *notes) {
  char tmp[1100];
  FILE *f = open_tmp(path, tmp, sizeof tmp);
  if (!f) return 1;
  char when[64];
  time_t t = time(NULL);
  strftime(when, sizeof when, "%Y-%m-%d %H:%M UTC", gmtime(&t));
  const char *slash = strrchr(png, '/');
  fprintf(f, "# What accuracy costs in time\n\n"
             "Generated by `gi-accuracy` (`make accuracy`) on %s, %s. Command: `%s`.\n"
             "Every figure below is measured in that one run; times are single runs (not medians) on a machine\n"
             "shared with other work, so treat differences under ~10%% as noise.\n\n",
          machine, when, cmdline);
  fprintf(f, "**Method.** Per scene, a fixed set of probe points (Cornell box: a 3x3x3 grid inside the box; "
             "Munich and the city: a grid around the viewpoint, 2 m up / at street level, keeping points that see "
             "direct light, i.e. not inside buildings). The reference is the core's path tracer "
             "(`gi_reference_irradiance`: next-event estimation, MIS for emitters, unbounded depth with Russian "
             "roulette, fixed seeds). The cone tracer bakes around the viewpoint and gathers at the points; its "
             "time is bake + gather. One knob moves at a time around the default (`gi_quality q = {0}`). The path "
             "tracer runs at 1..%d samples per probe with a different seed from the reference. Errors are on "
             "each probe's luminance (Rec. 709), averaged over probes: *MRE* = mean |x - ref| / ref, *relMSE* = mean (x - ref)^2 / ref^2 (ref "
             "floored at 1%% of its mean); *bias* = per-probe ratio of indirect irradiance to the reference "
             "(mean [min, max]). Direct and indirect are the same split as the probe EXR's channels.\n\n", path_max(r, n, NULL));
  FILE *nf = notes ? fopen(notes, "r") : NULL;
  if (notes && !nf) fprintf(stderr, "gi-accuracy: notes %s not readable: left out\n", notes);
  if (nf) {
    char buf[4096];
    size_t k;
    while ((k = fread(buf, 1, sizeof buf, nf)) > 0) fwrite(buf, 1, k, f);
    fclose(nf);
    fprintf(f, "\n");
  }
  write_standing(f, r, n, sc, nsc);
  /* drawn: 1 drawn, 0 gnuplot missing, -1 gnuplot failed (it said "not installed" then too). */
  if (drawn > 0 && slash) fprintf(f, "![error against time](%s)\n\n", slash + 1);
  else if (drawn > 0) fprintf(f, "![error against time](%s)\n\n", png);
  else if (drawn < 0) fprintf(f, "(The plot was not drawn: gnuplot failed on its script, accuracy.gp.)\n\n");
  else fprintf(f, "(The plot was not drawn: gnuplot is not installed.)\n\n");
  acc_write_views_md(f, views, nviews);
  if (wl) acc_write_by_light_md(f, wl->by_light, wl->n_by_light);
  if (wl) acc_write_handover_md(f, wl->handover);
  if (wl && wl->ran) acc_write_workloads_md(f, wl->w, wl->n, wl->cycles_note);
  else fprintf(f, "## At equal error, per workload\n\n(Not measured in this run: --no-workloads.)\n\n");

  for (size_t s = 0; s < nsc; s++) {
    const char *name = sc[s].name;
    const acc_row *d = find_default(r, n, name);
    fprintf(f, "## %s\n\n", name);
    fprintf(f, "Viewpoint (%s), %zu probes", sc[s].at, sc[s].probes);
    if (sc[s].placement[0]) fprintf(f, " (%s)", sc[s].placement);
    fprintf(f, ". Reference: %d paths per probe", sc[s].ref_samples);
    if (sc[s].ref_ms > 0) fprintf(f, ", %.1f s", sc[s].ref_ms / 1000);
    else fprintf(f, " (from the cache)");
    fprintf(f, "; its own mean relative standard error: total %.3f%%, direct %.3f%%, indirect %.3f%%.\n\n",
            100 * sc[s].ref_rel_se[ACC_TOTAL], 100 * sc[s].ref_rel_se[ACC_DIRECT], 100 * sc[s].ref_rel_se[ACC_INDIRECT]);
    fprintf(f, "| method | knob | value | ms | bake ms | gather ms | MRE total | MRE direct | MRE indirect | relMSE total "
               "| relMSE indirect | indirect bias | Pareto |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
    for (size_t i = 0; i < n; i++) {
      const acc_row *x = &r[i];
      if (strcmp(x->scene, name)) continue;
      char e[3][24], rm[2][24];
      for (int p = 0; p < 3; p++) pct_cell(x->m[p].mre, e[p], sizeof e[p]);
      for (int p = 0; p < 2; p++) num_cell(x->m[2 * p].rel_mse, rm[p], sizeof rm[p]);
      fprintf(f, "| %s | %s | %g | %.1f | %.1f | %.1f | %s | %s | %s | %s | %s | %.3f [%.3f, %.3f] | %s |\n",
              x->kind, x->is_default ? "**default**" : x->knob, x->value, x->ms, x->bake_ms, x->gather_ms, e[0], e[1],
              e[2], rm[0], rm[1], x->m[2].ratio_mean, x->m[2].ratio_min, x->m[2].ratio_max, x->on_front ? "yes" : "");
    }
    if (!d) continue;
    /* The knobs move the indirect light, unless the scene has none: then the total. */
    int by = isnan(d->m[2].mre) ? 0 : 2;
    char de_cell[24];
    pct_cell(d->m[2].mre, de_cell, sizeof de_cell);
    fprintf(f, "\n**What each knob buys here** (against the default: %.1f ms, indirect MRE %s, total %.2f%%):\n\n",
            d->ms, de_cell, 100 * d->m[0].mre);
    for (size_t i = 0; i < n; i++) {
      const acc_row *x = &r[i];
      if (strcmp(x->scene, name) || strcmp(x->kind, "cone") || x->is_default) continue;
      double dt = x->ms - d->ms, de = x->m[by].mre - d->m[by].mre;
      const char *verdict = de < -0.002 ? (dt > 0 ? "buys accuracy for time" : "better and cheaper")
                           : de > 0.002 ? (dt < 0 ? "saves time, costs accuracy" : "worse and slower")
                                        : (dt < 0 ? "saves time at no cost" : "costs time, buys nothing");
      fprintf(f, "- %s = %g: %+.1f ms (%+.0f%%), %s MRE %+.2f points -> %s.\n", knob_what(x->knob), x->value,
              dt, 100 * dt / d->ms, by ? "indirect" : "total", 100 * de, verdict);
    }
    double pt = path_ms_at(r, n, name, d->m[0].mre);
    fprintf(f, "\nThe default is %son the Pareto front. ", d->on_front ? "" : "**not** ");
    if (pt > 0)
      fprintf(f, "The path tracer reaches the default's total error (%.2f%%) in about %.1f ms "
                 "(interpolated between measured sample counts): the cone tracer is %.1fx %s.\n\n",
              100 * d->m[0].mre, pt, d->ms > pt ? d->ms / pt : pt / d->ms, d->ms > pt ? "slower" : "faster");
    else if (pt == 0)
      fprintf(f, "Even 1 path per probe beats the default's total error (%.2f%%).\n\n", 100 * d->m[0].mre);
    else
      fprintf(f, "The path tracer never reaches the default's total error (%.2f%%) within the measured samples.\n\n",
              100 * d->m[0].mre);
  }
  return close_rename(f, tmp, path);
}

int acc_write_reports(const acc_row *rows, size_t n, const acc_scene_info *sc, size_t nsc, const acc_view *views,
                      size_t nviews, const acc_wl_report *wl, const char *out_dir, const char *md_path,
                      const char *png_path, const char *machine, const char *cmdline, const char *notes) {
  char csv[1024];
  snprintf(csv, sizeof csv, "%s/accuracy.csv", out_dir);
  int drawn = 0;
  if (write_csv(rows, n, csv)) return 1;
  if (write_plot(rows, n, sc, nsc, csv, out_dir, png_path, &drawn)) return 1;
  if (wl && wl->ran && acc_write_workloads_files(wl->w, wl->n, out_dir)) return 1;
  if (write_md(rows, n, sc, nsc, views, nviews, wl, md_path, png_path, drawn, machine, cmdline, notes)) return 1;
  fprintf(stderr, "gi-accuracy: wrote %s, %s%s and %s\n", csv, drawn > 0 ? png_path : "", drawn > 0 ? "" : "(no plot)",
          md_path);
  return 0;
}
