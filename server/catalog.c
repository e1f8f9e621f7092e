/* catalog.c: the configured scenes, loaded once at start.
 *
 * Loading is the slow part of a cold start (seconds for a large city), so
 * it happens before the port opens: a server that answers is a server
 * whose scenes are in memory. Scenes are immutable and reference-counted;
 * every request reads them without locks. */
#define _POSIX_C_SOURCE 200809L
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include "server.h"

/* A scene file without `up` that looks z-up (gi_scene_looks_z_up): read
 * with y, its sun lights it from the side. A note, not an error. */
static void note_up_axis(const gs_config *cfg, const gs_scene_conf *sc, const gi_scene *scene) {
  if (sc->is_city || sc->up || !gi_scene_looks_z_up(scene)) return;
  double lo[3], hi[3];
  gi_scene_bounds(scene, lo, hi);
  fprintf(stderr, "gi-server: note: %s:%d: [scene %s] is flat along z (%g x %g x %g) and has no 'up': read with y "
          "up; if z is up, as in OpenStreetMap and GIS exports, add 'up = z'\n", cfg->path, sc->line, sc->id,
          hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]);
}

int gs_catalog_load(const gs_config *cfg, gs_catalog *cat, char *err, size_t errsize) {
  memset(cat, 0, sizeof *cat);
  cat->scenes = calloc(cfg->num_scenes ? cfg->num_scenes : 1, sizeof *cat->scenes);
  if (!cat->scenes) {
    snprintf(err, errsize, "catalog: out of memory");
    return -1;
  }
  for (size_t i = 0; i < cfg->num_scenes; i++) {
    const gs_scene_conf *sc = &cfg->scenes[i];
    gs_scene *s = &cat->scenes[cat->num];
    gi_error_info e = {0};
    gi_scene_options opt = {.up = sc->up ? sc->up : GI_UP_Y, .threads = cfg->bake_threads, .default_lights = 1};
    double t0 = gs_now_ms();
    gi_result rc;
    if (sc->is_city) {
      gi_city_params p = {.seed = sc->seed, .extent = sc->extent, .detail = sc->detail};
      rc = gi_city_build(&p, &opt, &s->scene, &e);
      if (rc == GI_OK) gi_city_default_viewpoint(&p, s->default_at);
    } else {
      if (sc->optional && access(sc->source, R_OK) != 0) {
        fprintf(stderr, "gi-server: scene '%s': %s is absent; skipped (optional = yes)\n", sc->id, sc->source);
        continue;
      }
      rc = gi_scene_load(sc->source, &opt, &s->scene, &e);
      if (rc == GI_OK) {
        double lo[3], hi[3];
        gi_scene_bulk_bounds(s->scene, lo, hi); /* not between a model and a stray triangle far off */
        for (int a = 0; a < 3; a++) s->default_at[a] = 0.5 * (lo[a] + hi[a]);
      }
    }
    if (rc != GI_OK) {
      /* The line that names the file, not the section's (a helper's find). */
      snprintf(err, errsize, "%s:%d: [scene %s] source: %s", cfg->path, sc->source_line ? sc->source_line : sc->line,
               sc->id, e.msg);
      gs_catalog_free(cat);
      return -1;
    }
    /* Read after the load: the version names what was loaded (a file
     * replaced meanwhile gives a version the next start will change). */
    if (gs_scene_version(sc, &s->version, err, errsize) != 0) {
      gi_scene_release(s->scene);
      gs_catalog_free(cat);
      return -1;
    }
    snprintf(s->id, sizeof s->id, "%s", sc->id);
    s->load_ms = gs_now_ms() - t0;
    if (gi_effect_plan(s->scene, s->default_at, NULL, s->effects, &s->quality, &e) != GI_OK) {
      snprintf(err, errsize, "[scene %s]: %s", sc->id, e.msg);
      gi_scene_release(s->scene);
      gs_catalog_free(cat);
      return -1;
    }
    gi_scene_stats st;
    gi_scene_get_stats(s->scene, &st);
    fprintf(stderr, "gi-server: scene '%s': %llu triangles, %u lights, loaded in %.0f ms\n", s->id,
            (unsigned long long)st.triangles, st.lights, s->load_ms);
    note_up_axis(cfg, sc, s->scene);
    cat->num++;
  }
  return 0;
}

const gs_scene *gs_catalog_find(const gs_catalog *cat, const char *id) {
  for (size_t i = 0; i < cat->num; i++)
    if (!strcmp(cat->scenes[i].id, id)) return &cat->scenes[i];
  return NULL;
}

void gs_catalog_free(gs_catalog *cat) {
  for (size_t i = 0; i < cat->num; i++) gi_scene_release(cat->scenes[i].scene);
  free(cat->scenes);
  cat->scenes = NULL;
  cat->num = 0;
}
