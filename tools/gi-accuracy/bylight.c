/* bylight.c: the cone tracer's error split by the light it comes from.
 *
 * Issue 16 asks where a city's indirect light goes wrong. With one kind of
 * light at a time (sun, point and spot lights, sky, emissive surfaces),
 * the reference sees only that kind (gi_reference_opts.lights) and the
 * bake has only that effect on, at the same probes and viewpoint as the
 * scene's sweep: each kind's indirect error and bias (cone / reference),
 * and its share of the reference's indirect light. A kind the default bake
 * does not run (no such light in the scene) is left out. The references
 * are cached like the scene's own, keyed by the kind too. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "acc.h"
#include "gi/gi.h"

static const struct {
  int fx;
  const char *name;
} KINDS[ACC_LIGHT_KINDS] = {
    {GI_FX_SUN, "sun"}, {GI_FX_LOCAL, "point/spot"}, {GI_FX_SKY, "sky"}, {GI_FX_EMISSIVE, "emissive"}};

static double lum(const float c[3]) { return 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]; }

/* The default bake with only effect fx among the lights on, gathered at the probes. */
static int kind_bake(const char *name, const acc_scene_set *ss, int fx, int threads, gi_probe *pr, double *ms) {
  gi_quality q = {.threads = threads};
  for (int k = 0; k < ACC_LIGHT_KINDS; k++)
    if (KINDS[k].fx != fx) q.effects[KINDS[k].fx] = GI_FX_OFF;
  gi_cascade *c = NULL;
  gi_bake_report rep;
  gi_error_info err = {0};
  double gms = 0;
  if (gi_cascade_bake(ss->s, ss->at, &q, &c, &rep, &err) != GI_OK ||
      gi_cascade_gather(c, ss->pts, ss->n, pr, &gms, &err) != GI_OK) {
    fprintf(stderr, "gi-accuracy: %s: bake with only effect %d: %s\n", name, fx, err.msg);
    gi_cascade_free(c);
    return 0;
  }
  *ms = acc_bake_ms(&rep) + gms;
  gi_cascade_free(c);
  return 1;
}

int acc_run_by_light(const char *name, const acc_scene_set *ss, const gi_ref_probe *full, int threads,
                     const char *out_dir, int ref_version, acc_light_row *out, size_t *nout) {
  /* Which kinds the default bake runs: its effect plan, without baking. */
  gi_quality q = {.threads = threads};
  gi_effect plan[GI_FX_COUNT];
  gi_error_info err = {0};
  if (gi_effect_plan(ss->s, ss->at, &q, plan, NULL, &err) != GI_OK) {
    fprintf(stderr, "gi-accuracy: %s: effect plan: %s\n", name, err.msg);
    return 0;
  }
  gi_ref_probe *ref = calloc(ss->n, sizeof *ref);
  gi_probe *pr = calloc(ss->n, sizeof *pr);
  int ok = ref && pr;
  double full_ind = 0;
  for (size_t i = 0; i < ss->n; i++) full_ind += lum(full[i].indirect);
  for (int k = 0; ok && k < ACC_LIGHT_KINDS; k++) {
    int fx = KINDS[k].fx;
    if (!plan[fx].ran) continue;
    acc_light_row *r = &out[(*nout)++];
    memset(r, 0, sizeof *r);
    snprintf(r->scene, sizeof r->scene, "%s", name);
    snprintf(r->kind, sizeof r->kind, "%s", KINDS[k].name);
    ok = acc_ref_cached(name, ss, 1 << fx, threads, out_dir, ref_version, ref, &r->ref_ms) &&
         kind_bake(name, ss, fx, threads, pr, &r->cone_ms);
    if (!ok) break;
    double ind = 0, se2 = 0;
    for (size_t i = 0; i < ss->n; i++) {
      ind += lum(ref[i].indirect);
      se2 += lum(ref[i].std_err_indirect) * lum(ref[i].std_err_indirect);
    }
    r->share = full_ind > 0 ? ind / full_ind : 0;
    r->ref_indirect_sum = ind;
    r->ref_indirect_se = sqrt(se2);
    acc_compare_probes(pr, ref, ss->n, ACC_INDIRECT, &r->indirect);
    acc_compare_probes(pr, ref, ss->n, ACC_DIRECT, &r->direct);
    fprintf(stderr, "  light %-10s share %5.1f%%  indirect MRE %.4f ratio %.3f [%.3f, %.3f]  direct MRE %.4f\n",
            r->kind, 100 * r->share, r->indirect.mre, r->indirect.ratio_mean, r->indirect.ratio_min,
            r->indirect.ratio_max, r->direct.mre);
  }
  free(ref);
  free(pr);
  return ok;
}

void acc_write_by_light_md(FILE *f, const acc_light_row *r, size_t n) {
  fprintf(f, "## Indirect light by the light it comes from\n\n");
  if (!n) {
    fprintf(f, "(Not measured in this run: --no-by-light.)\n\n");
    return;
  }
  fprintf(f, "One kind of light at a time, at each scene's probes and viewpoint: the reference sees only that kind "
             "(`gi_reference_opts.lights`) and the default bake has only that effect on. *Share*: that kind's part "
             "of the reference's indirect light (the shares add up to 100%% up to the references' noise); "
             "*ratio*: cone / reference indirect per probe, mean [min, max].\n\n");
  fprintf(f, "| scene | light | share of indirect | MRE indirect | indirect ratio | MRE direct | cone ms |\n"
             "|---|---|---|---|---|---|---|\n");
  for (size_t i = 0; i < n; i++)
    fprintf(f, "| %s | %s | %.1f%% | %.2f%% | %.3f [%.3f, %.3f] | %.2f%% | %.0f |\n", r[i].scene, r[i].kind,
            100 * r[i].share, 100 * r[i].indirect.mre, r[i].indirect.ratio_mean, r[i].indirect.ratio_min,
            r[i].indirect.ratio_max, 100 * r[i].direct.mre, r[i].cone_ms);
  fprintf(f, "\n");
}
