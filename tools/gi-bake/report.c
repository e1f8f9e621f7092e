/* report.c: what gi-bake prints, as JSON (jansson) or as a human summary.
 *
 * Design: the JSON tree is always built first, even for the summary,
 * because building it is where every number is checked: a non-finite
 * value anywhere (a core bug) is an internal error and nothing is printed
 * to stdout, so a consumer never receives NaN or a half-written answer.
 * Doubles go out through json_real at jansson's full 17-digit precision. */
#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "cli.h"

typedef struct jctx {
  int bad;          /* a non-finite number was seen */
  char where[96];   /* the first one's field */
} jctx;

static json_t *num(jctx *j, double v, const char *where) {
  if (!isfinite(v)) {
    if (!j->bad) snprintf(j->where, sizeof j->where, "%s", where);
    j->bad = 1;
    return json_null();
  }
  return json_real(v);
}

static json_t *vec3d(jctx *j, const double v[3], const char *where) {
  json_t *a = json_array();
  for (int k = 0; k < 3; k++) json_array_append_new(a, num(j, v[k], where));
  return a;
}

static json_t *vec3f(jctx *j, const float v[3], const char *where) {
  json_t *a = json_array();
  for (int k = 0; k < 3; k++) json_array_append_new(a, num(j, (double)v[k], where));
  return a;
}

static json_t *count(uint64_t v) { return json_integer((json_int_t)v); }

/* n floats of field `where`, for finite numbers only (num's rule, without a JSON value). */
static void check_f(jctx *j, const float *v, int n, const char *where) {
  for (int i = 0; i < n && !j->bad; i++)
    if (!isfinite(v[i])) snprintf(j->where, sizeof j->where, "%s", where), j->bad = 1;
}

/* probe_json's numbers checked as it would, before any of the streamed array is printed. */
static void check_probe(jctx *j, const gi_probe *p, const double at[3]) {
  for (int k = 0; k < 3 && !j->bad; k++)
    if (!isfinite(at[k])) snprintf(j->where, sizeof j->where, "probe position"), j->bad = 1;
  check_f(j, &p->sh[0][0], 27, "probe sh");
  check_f(j, p->irradiance, 3, "probe irradiance");
  check_f(j, p->direct, 3, "probe direct");
  check_f(j, p->indirect, 3, "probe indirect");
  check_f(j, &p->ao, 1, "probe ao");
}

static json_t *probe_json(jctx *j, const gi_probe *p, const double at[3], int covered) {
  json_t *o = json_object(), *sh = json_array();
  json_object_set_new(o, "at", vec3d(j, at, "probe position"));
  json_object_set_new(o, "in_cascade", json_boolean(covered));
  for (int i = 0; i < 9; i++) json_array_append_new(sh, vec3f(j, p->sh[i], "probe sh"));
  json_object_set_new(o, "sh", sh);
  json_object_set_new(o, "irradiance", vec3f(j, p->irradiance, "probe irradiance"));
  json_object_set_new(o, "direct", vec3f(j, p->direct, "probe direct"));
  json_object_set_new(o, "indirect", vec3f(j, p->indirect, "probe indirect"));
  json_object_set_new(o, "ao", num(j, p->ao, "probe ao"));
  return o;
}

static json_t *quality_json(jctx *j, const gi_quality *q, int threads) {
  json_t *o = json_object();
  json_object_set_new(o, "levels", json_integer(q->levels));
  json_object_set_new(o, "res", json_integer(q->res));
  json_object_set_new(o, "voxel0", num(j, q->voxel0, "quality.voxel0"));
  json_object_set_new(o, "cones", json_integer(q->cones));
  /* 0 here means "derived from the cone count" (the core keeps it unresolved). */
  json_object_set_new(o, "aperture_deg", num(j, q->aperture_deg, "quality.aperture_deg"));
  json_object_set_new(o, "step", num(j, q->step, "quality.step"));
  json_object_set_new(o, "bounces", json_integer(q->bounces));
  json_object_set_new(o, "bounce_tail", json_boolean(q->bounce_tail));
  json_object_set_new(o, "light_samples", json_integer(q->light_samples));
  json_object_set_new(o, "probe_samples", json_integer(q->probe_samples));
  json_object_set_new(o, "ao_lambda", num(j, q->ao_lambda, "quality.ao_lambda"));
  json_object_set_new(o, "ao", json_boolean(q->ao));
  json_object_set_new(o, "specular", json_integer(q->specular));
  json_object_set_new(o, "threads", json_integer(threads));
  json_object_set_new(o, "seed", count(q->seed));
  return o;
}

/* The march's cost: cones traced, samples per cone, and per sample the
 * bounce's wall time on every thread less the replays' (so a loaded
 * machine reads slower); the replays' taps and their time per tap. */
static void add_march_figures(json_t *root, const gi_bake_report *rep) {
  json_object_set_new(root, "cones_traced", count(rep->cones_traced));
  json_object_set_new(root, "taps_replayed", count(rep->taps_replayed));
  json_object_set_new(root, "tape_bytes", count(rep->tape_bytes));
  json_object_set_new(root, "samples_per_cone",
                      json_real(rep->cones_traced ? (double)rep->cone_samples / (double)rep->cones_traced : 0.0));
  /* The replays' own time is not the march's: ns_per_tap. */
  double march_ms = rep->ms.bounce * rep->quality.threads - rep->replay_thread_ms;
  json_object_set_new(root, "ns_per_sample",
                      json_real(rep->cone_samples ? march_ms * 1e6 / (double)rep->cone_samples : 0.0));
  json_object_set_new(root, "ns_per_tap",
                      json_real(rep->taps_replayed ? rep->replay_thread_ms * 1e6 / (double)rep->taps_replayed : 0.0));
  json_object_set_new(root, "cpu_path", json_string(gi_cpu_path()));
}

/* The report's "scene" object: what the scene holds and what was dropped. */
static json_t *scene_json(const cli_run *r, jctx *j) {
  gi_scene_stats st;
  gi_scene_get_stats(r->scene, &st);
  double lo[3], hi[3];
  gi_scene_bounds(r->scene, lo, hi);
  json_t *sc = json_object(), *b = json_array();
  json_object_set_new(sc, "name", json_string(gi_scene_name(r->scene) ? gi_scene_name(r->scene) : ""));
  json_object_set_new(sc, "path", r->o->is_city ? json_null() : json_string(r->o->scene));
  json_object_set_new(sc, "up", json_string(gi_scene_up(r->scene) == GI_UP_Z ? "z" : "y"));
  json_object_set_new(sc, "triangles", count(st.triangles));
  json_object_set_new(sc, "input_triangles", count(st.input_triangles));
  json_object_set_new(sc, "dropped_nonfinite", count(st.dropped_nonfinite));
  json_object_set_new(sc, "dropped_degenerate", count(st.dropped_degenerate));
  json_object_set_new(sc, "dropped_see_through", count(st.dropped_see_through));
  json_object_set_new(sc, "clamped_albedo", count(st.clamped_albedo));
  json_object_set_new(sc, "textures_unreadable", count(st.textures_unreadable));
  json_object_set_new(sc, "materials", count(st.materials));
  json_object_set_new(sc, "lights", count(st.lights));
  json_object_set_new(sc, "lights_skipped", count(st.lights_skipped));
  json_object_set_new(sc, "far_triangles", count(st.far_triangles));
  json_object_set_new(sc, "uv2_missing", count(st.uv2_missing));
  json_object_set_new(sc, "emissive_triangles", count(st.emissive_triangles));
  json_object_set_new(sc, "default_lights_added", json_boolean(st.default_lights_added));
  json_array_append_new(b, vec3d(j, lo, "scene bounds"));
  json_array_append_new(b, vec3d(j, hi, "scene bounds"));
  json_object_set_new(sc, "bounds", b);
  return sc;
}

static json_t *build_json(const cli_run *r, jctx *j) {
  const gi_bake_report *rep = r->rep;
  json_t *root = json_object();
  json_object_set_new(root, "scene", scene_json(r, j));

  json_object_set_new(root, "viewpoint", vec3d(j, r->points, "viewpoint"));
  json_object_set_new(root, "quality", quality_json(j, &rep->quality, r->threads));
  json_object_set_new(root, "probe", probe_json(j, &r->probes[0], r->points, !r->covered || r->covered[0]));
  /* "probes" is streamed by print_json: a million of them as one jansson
   * tree took 7 GB. Here each is only checked for finite numbers. */
  for (size_t i = 1; i < r->num_probes && !j->bad; i++) check_probe(j, &r->probes[i], &r->points[3 * i]);

  json_t *t = json_object();
  json_object_set_new(t, "load", num(j, r->load_ms, "timings_ms.load"));
  json_object_set_new(t, "plan", num(j, rep->ms.plan, "timings_ms.plan"));
  json_object_set_new(t, "voxelize", num(j, rep->ms.voxelize, "timings_ms.voxelize"));
  json_object_set_new(t, "inject", num(j, rep->ms.inject, "timings_ms.inject"));
  json_object_set_new(t, "filter", num(j, rep->ms.filter, "timings_ms.filter"));
  json_object_set_new(t, "bounce", num(j, rep->ms.bounce, "timings_ms.bounce"));
  json_object_set_new(t, "gather", num(j, r->gather_ms, "timings_ms.gather"));
  json_object_set_new(t, "encode", num(j, r->encode_ms, "timings_ms.encode"));
  json_object_set_new(t, "total", num(j, r->total_ms, "timings_ms.total"));
  json_object_set_new(root, "timings_ms", t);
  json_object_set_new(root, "threads", json_integer(r->threads));

  /* With --render the view's plan is what ran: it decides the specular pass. */
  const gi_effect *effects = r->render ? r->render->view.effects : rep->effects;
  json_t *fx = json_object();
  for (int i = 0; i < GI_FX_COUNT; i++) {
    json_t *e = json_object();
    json_object_set_new(e, "ran", json_boolean(effects[i].ran));
    json_object_set_new(e, "why", json_string(effects[i].why));
    json_object_set_new(fx, gi_effect_name((gi_effect_id)i), e);
  }
  json_object_set_new(root, "effects", fx);

  json_object_set_new(root, "cascade_bytes", count(rep->cascade_bytes));
  if (r->render) {
    json_t *rj = json_object();
    json_object_set_new(rj, "width", json_integer(r->render->width));
    json_object_set_new(rj, "height", json_integer(r->render->height));
    json_object_set_new(rj, "path_samples", json_integer(r->render->spp));
    json_object_set_new(rj, "cone_ms", json_real(r->render->cone_ms));
    json_object_set_new(rj, "path_ms", json_real(r->render->path_ms));
    json_object_set_new(rj, "mean_relative_error", json_real(r->render->mre));
    json_object_set_new(rj, "indirect_stride", json_integer(r->render->view.indirect_stride));
    json_object_set_new(rj, "diffuse_cones", count(r->render->view.diffuse_cones));
    json_object_set_new(rj, "specular_cones", count(r->render->view.specular_cones));
    json_object_set_new(rj, "pixels_outside", count(r->render->view.pixels_outside));
    json_object_set_new(root, "render", rj);
  }
  json_t *lv = json_array();
  uint64_t total_occ = 0;
  for (int d = 0; d < rep->levels && d < GI_MAX_LEVELS; d++) {
    json_t *l = json_object();
    json_object_set_new(l, "level", json_integer(d));
    json_object_set_new(l, "voxel_size", num(j, rep->voxel_size[d], "levels.voxel_size"));
    json_object_set_new(l, "origin", vec3d(j, rep->level_origin[d], "levels.origin"));
    json_object_set_new(l, "occupied", count(rep->occupied[d]));
    json_array_append_new(lv, l);
    total_occ += rep->occupied[d];
  }
  json_object_set_new(root, "levels", lv);
  json_object_set_new(root, "voxels_occupied", count(total_occ));
  json_object_set_new(root, "triangles_visited", count(rep->triangles_visited));
  json_object_set_new(root, "shadow_rays", count(rep->shadow_rays));
  json_object_set_new(root, "cone_samples", count(rep->cone_samples));
  add_march_figures(root, rep);
  json_object_set_new(root, "bounces_run", json_integer(rep->bounces_run));
  json_object_set_new(root, "wide_from_level", json_integer(rep->wide_from_level));

  json_t *out = json_object();
  json_object_set_new(out, "exr", r->o->exr ? json_string(r->o->exr) : json_null());
  json_object_set_new(out, "vdb", r->o->vdb ? json_string(r->o->vdb) : json_null());
  /* Every file the run wrote: --render's picture too. */
  json_object_set_new(out, "png", r->o->png ? json_string(r->o->png) : json_null());
  json_object_set_new(root, "outputs", out);
  json_object_set_new(root, "version", json_string(ta_version()));
  return root;
}

static void print_human(const cli_run *r) {
  const gi_bake_report *rep = r->rep;
  gi_scene_stats st;
  gi_scene_get_stats(r->scene, &st);
  double lo[3], hi[3];
  gi_scene_bounds(r->scene, lo, hi);
  const char *name = gi_scene_name(r->scene);

  printf("gi-bake %s\n", ta_version());
  printf("scene      %s: %llu triangles kept of %llu (dropped %llu non-finite, %llu degenerate)\n",
         name && *name ? name : r->o->scene, (unsigned long long)st.triangles,
         (unsigned long long)st.input_triangles, (unsigned long long)st.dropped_nonfinite,
         (unsigned long long)st.dropped_degenerate);
  printf("           %u materials%s, %u lights%s, %u emissive triangles\n", st.materials,
         st.clamped_albedo ? " (some values out of range, not numbers or reflecting over 100%: corrected)" : "",
         st.lights,
         st.default_lights_added ? " (default sun + sky added)" : "", st.emissive_triangles);
  if (st.dropped_see_through)
    printf("           %llu triangle%s of see-through materials (glass, alpha-blended) left out: light passes "
           "them\n",
           (unsigned long long)st.dropped_see_through, st.dropped_see_through > 1 ? "s" : "");
  if (st.lights_skipped)
    printf("           %u light%s skipped: area and ambient lights are not modelled (make an area light an "
           "emissive surface)\n",
           st.lights_skipped, st.lights_skipped > 1 ? "s" : "");
  if (st.far_triangles) {
    double blo[3], bhi[3];
    gi_scene_bulk_bounds(r->scene, blo, bhi);
    printf("           %llu stray triangle%s far from the rest, which lies in (%g, %g, %g) .. (%g, %g, %g): the\n"
           "           default voxel size and viewpoint follow the rest\n",
           (unsigned long long)st.far_triangles, st.far_triangles > 1 ? "s" : "", blo[0], blo[1], blo[2], bhi[0],
           bhi[1], bhi[2]);
  }
  if (st.textures_unreadable)
    printf("           %llu texture%s unreadable: their materials keep the plain colour factor\n",
           (unsigned long long)st.textures_unreadable, st.textures_unreadable > 1 ? "s" : "");
  printf("           bounds (%g, %g, %g) .. (%g, %g, %g), %s up\n", lo[0], lo[1], lo[2], hi[0], hi[1], hi[2],
         gi_scene_up(r->scene) == GI_UP_Z ? "z" : "y");
  printf("viewpoint  (%.9g, %.9g, %.9g)\n", r->points[0], r->points[1], r->points[2]);

  uint64_t total_occ = 0;
  for (int d = 0; d < rep->levels; d++) total_occ += rep->occupied[d];
  printf("cascade    %d levels of %d^3 voxels, %.2f MiB, %llu voxels occupied\n", rep->levels,
         rep->quality.res, (double)rep->cascade_bytes / (1024.0 * 1024.0), (unsigned long long)total_occ);
  printf("           %-5s %12s %10s   %s\n", "level", "voxel size", "occupied", "origin (min corner)");
  for (int d = 0; d < rep->levels; d++)
    printf("           L%-4d %12.6g %10llu   (%g, %g, %g)\n", d, rep->voxel_size[d],
           (unsigned long long)rep->occupied[d], rep->level_origin[d][0], rep->level_origin[d][1],
           rep->level_origin[d][2]);

  printf("timings    ms on %d thread%s\n", r->threads, r->threads == 1 ? "" : "s");
  const char *names[9] = {"load", "plan", "voxelize", "inject", "filter", "bounce", "gather", "encode", "total"};
  double ms[9] = {r->load_ms, rep->ms.plan, rep->ms.voxelize, rep->ms.inject, rep->ms.filter,
                  rep->ms.bounce, r->gather_ms, r->encode_ms, r->total_ms};
  for (int i = 0; i < 9; i++) printf("           %-9s %10.2f\n", names[i], ms[i]);
  printf("work       %llu triangle/level pairs, %llu shadow rays, %llu cone samples, %d bounce%s run\n",
         (unsigned long long)rep->triangles_visited, (unsigned long long)rep->shadow_rays,
         (unsigned long long)rep->cone_samples, rep->bounces_run, rep->bounces_run == 1 ? "" : "s");
  if (rep->cones_traced && rep->cone_samples)
    printf("cones      %llu traced, %.1f samples per cone, %.1f ns per sample per thread (%s march)\n",
           (unsigned long long)rep->cones_traced, (double)rep->cone_samples / (double)rep->cones_traced,
           (rep->ms.bounce * rep->quality.threads - rep->replay_thread_ms) * 1e6 / (double)rep->cone_samples,
           gi_cpu_path());
  if (rep->taps_replayed)
    printf("replays    %llu lit steps read again from the first bounce's marches, %.1f ns each\n",
           (unsigned long long)rep->taps_replayed, rep->replay_thread_ms * 1e6 / (double)rep->taps_replayed);

  const gi_effect *effects = r->render ? r->render->view.effects : rep->effects;
  printf("effects%s\n", r->render ? "    (of the rendered view)" : "");
  for (int i = 0; i < GI_FX_COUNT; i++)
    printf("           %-13s %-8s %s\n", gi_effect_name((gi_effect_id)i),
           effects[i].ran ? "ran" : "skipped", effects[i].why);

  const gi_probe *p = &r->probes[0];
  printf("probe      irradiance on an up-facing surface (R, G, B)\n");
  printf("           total    %12.6g %12.6g %12.6g\n", p->irradiance[0], p->irradiance[1], p->irradiance[2]);
  printf("           direct   %12.6g %12.6g %12.6g\n", p->direct[0], p->direct[1], p->direct[2]);
  printf("           indirect %12.6g %12.6g %12.6g\n", p->indirect[0], p->indirect[1], p->indirect[2]);
  if (rep->effects[GI_FX_AO].ran) printf("           ao       %12.6g\n", p->ao);
  if (r->num_probes > 1)
    printf("probes     %zu extra points from %s (in the EXR and in --json)\n", r->num_probes - 1,
           r->o->probes_file);
  printf("outputs    exr: %s\n           vdb: %s\n", r->o->exr ? r->o->exr : "(none, use --exr)",
         r->o->vdb ? r->o->vdb : "(none, use --vdb)");
  if (r->o->png) printf("           png: %s\n", r->o->png);
}

/* The report, then its "probes" array one probe at a time (JSON object
 * members have no order; this one comes last). */
static int print_json(const cli_run *r, json_t *root) {
  const size_t flags = JSON_INDENT(2) | JSON_REAL_PRECISION(17);
  char *s = json_dumps(root, flags);
  char *close = s ? strrchr(s, '}') : NULL;
  if (!close) {
    free(s);
    fprintf(stderr, "gi-bake: internal error: cannot encode the JSON report\n");
    return EXIT_RUN;
  }
  while (close > s && (close[-1] == '\n' || close[-1] == ' ')) close--;
  fwrite(s, 1, (size_t)(close - s), stdout);
  free(s);
  fputs(",\n  \"probes\": [", stdout);
  jctx j = {0};
  for (size_t i = 1; i < r->num_probes; i++) {
    json_t *p = probe_json(&j, &r->probes[i], &r->points[3 * i], !r->covered || r->covered[i]);
    char *ps = p ? json_dumps(p, JSON_COMPACT | JSON_REAL_PRECISION(17)) : NULL;
    json_decref(p);
    if (!ps) {
      fprintf(stderr, "gi-bake: internal error: cannot encode probe %zu\n", i);
      return EXIT_RUN;
    }
    printf("%s\n    %s", i > 1 ? "," : "", ps);
    free(ps);
  }
  fputs(r->num_probes > 1 ? "\n  ]\n}\n" : "]\n}\n", stdout);
  return 0;
}

int cli_report(const cli_run *r, int json) {
  jctx j = {0};
  json_t *root = build_json(r, &j);
  int rc = 0;
  if (!root) {
    fprintf(stderr, "gi-bake: internal error: cannot build the JSON report (out of memory)\n");
    return EXIT_RUN;
  }
  if (j.bad) {
    fprintf(stderr, "gi-bake: internal error: non-finite value in %s; no result printed\n", j.where);
    rc = EXIT_RUN;
  } else if (json) {
    rc = print_json(r, root);
  } else {
    print_human(r);
  }
  json_decref(root);
  if (fflush(stdout) != 0 || ferror(stdout)) {
    fprintf(stderr, "gi-bake: cannot write to stdout\n");
    rc = EXIT_RUN;
  }
  return rc;
}
