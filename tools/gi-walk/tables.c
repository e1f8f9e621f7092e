/* tables.c: the paper's tables for one scene (docs/experiments.md).
 *
 * A cold bake at the scene's viewpoint gives the voxel counts per level and
 * the stage times; the memory of the cascade is set against a dense grid of
 * the finest voxel size over the coarsest level's extent (computed, the
 * cascade's bytes per voxel) and against an OpenVDB grid of the same
 * radiance and opacity (vdbmem.c, measured). Then the cascade is moved by
 * one anchor cell (2 finest voxels) along +x `moves` times: the per-move
 * update against the cold bake (the paper's Table 7 "dynamic update").
 * The report has stage times for the whole bake only; the per-level times
 * are apportioned by each level's share of the stage's voxel counts. */
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include "walk.h"

#define MIB (1024.0 * 1024.0)

static int load_scene(const tables_opts *o, gi_scene **s) {
  gi_error_info err = {0};
  gi_result r;
  if (o->scene_file) {
    gi_scene_options opt = {.up = o->up, .default_lights = 1};
    r = gi_scene_load(o->scene_file, &opt, s, &err);
    if (r == GI_OK) walk_note_up(o->scene_file, o->up, *s);
  } else {
    r = gi_city_build(&o->city, NULL, s, &err);
  }
  if (r != GI_OK) fprintf(stderr, "gi-walk: %s: %s\n", o->label, err.msg);
  return r == GI_OK ? 0 : -1;
}

static double share(uint64_t part, uint64_t whole) { return whole ? (double)part / (double)whole : 0; }

static void voxel_table(const gi_cascade *c, const gi_bake_report *r, FILE *md) {
  uint64_t vox = (uint64_t)r->quality.res * r->quality.res * r->quality.res, sv = 0, si = 0, sb = 0;
  for (int d = 0; d < r->levels; d++) sv += r->level_voxelized[d], si += r->level_injected[d], sb += r->level_rebounced[d];
  fprintf(md, "| level | voxel m | extent m | occupied | occupied share | voxelized | injected | bounce gathers |"
              " voxelize ms | inject ms | bounce ms |\n|---|---|---|---|---|---|---|---|---|---|---|\n");
  for (int d = 0; d < r->levels; d++)
    fprintf(md, "| %d | %.3f | %.1f | %llu | %.1f%% | %llu | %llu | %llu | %.1f | %.1f | %.1f |\n", d,
            r->voxel_size[d], r->voxel_size[d] * r->quality.res, (unsigned long long)r->occupied[d],
            100 * share(r->occupied[d], vox), (unsigned long long)r->level_voxelized[d],
            (unsigned long long)r->level_injected[d], (unsigned long long)r->level_rebounced[d],
            r->ms.voxelize * share(r->level_voxelized[d], sv), r->ms.inject * share(r->level_injected[d], si),
            r->ms.bounce * share(r->level_rebounced[d], sb));
  fprintf(md, "\nStage totals: voxelize %.1f ms, inject %.1f ms, bounce %.1f ms, filter %.1f ms (%d bounces).\n\n",
          r->ms.voxelize, r->ms.inject, r->ms.bounce, r->ms.filter, r->bounces_run);
  (void)c;
}

static void memory_table(const gi_cascade *c, const gi_bake_report *r, size_t vdb_max, FILE *md) {
  int n = r->levels, R = r->quality.res;
  double per_voxel = (double)r->cascade_bytes / ((double)n * R * R * R);
  /* A dense grid keeps a voxel's whole record everywhere: the cascade's
   * bytes a voxel as if every voxel held geometry (its admission bound). */
  double full = (double)gi_cascade_bytes_estimate(&r->quality) / ((double)n * R * R * R);
  double side = (double)R * (double)(1u << (n - 1)), dense = full * side * side * side;
  vdb_figure v = {0};
  int ok = vdb_figure_measure(c, vdb_max, &v) == 0;
  fprintf(md, "| store | bytes | MiB | store / cascade |\n|---|---|---|---|\n");
  fprintf(md, "| cascade (cascade_bytes, %d x %d^3 voxels, %.0f B a voxel on average) | %zu | %.1f | 1x |\n", n, R,
          per_voxel, r->cascade_bytes, r->cascade_bytes / MIB);
  fprintf(md, "| dense grid, %.3f m voxels over %.0f m (%.0f^3 of %.0f B, computed) | %.4g | %.0f | %.0fx |\n",
          r->voxel_size[0], side * r->voxel_size[0], side, full, dense, dense / MIB, dense / (double)r->cascade_bytes);
  if (ok)
    fprintf(md, "| OpenVDB, %.3f m voxels, 7 Vec3f grids, %llu active (memUsage) | %zu | %.1f | %.1fx |\n",
            r->voxel_size[0], (unsigned long long)v.active, v.bytes, v.bytes / MIB,
            (double)v.bytes / (double)r->cascade_bytes);
  else
    fprintf(md, "| OpenVDB | could not be built (see the log) | | |\n");
  if (ok && v.levels_covered < n)
    fprintf(md, "\nThe OpenVDB grid covers levels 0..%d only (%.0f m): the finest-size grid over the whole "
                "extent exceeds %zu voxels.\n", v.levels_covered - 1, R * r->voxel_size[v.levels_covered - 1], vdb_max);
  fprintf(md, "\n");
}

typedef struct move_sums {
  int n, closed;
  double ms, cpu, max_ms, open_ms, closed_ms;
  gi_timings st;
  uint64_t vox, inj, reb;
} move_sums;

static int time_moves(gi_cascade *c, const double at0[3], double step, int moves, move_sums *m) {
  memset(m, 0, sizeof *m);
  for (int i = 1; i <= moves; i++) {
    double at[3] = {at0[0] + i * step, at0[1], at0[2]};
    gi_bake_report r;
    gi_move_info info;
    gi_error_info err = {0};
    double w0 = now_ms(), c0 = cpu_ms();
    if (gi_cascade_move(c, at, &r, &info, &err) != GI_OK) return fprintf(stderr, "gi-walk: move: %s\n", err.msg), -1;
    double ms = now_ms() - w0;
    m->n++, m->ms += ms, m->cpu += cpu_ms() - c0, m->max_ms = fmax(m->max_ms, ms);
    if (info.cycle_closed) m->closed++, m->closed_ms += ms;
    else m->open_ms += ms;
    m->st.voxelize += r.ms.voxelize, m->st.inject += r.ms.inject, m->st.bounce += r.ms.bounce, m->st.filter += r.ms.filter;
    for (int d = 0; d < r.levels; d++) m->vox += r.level_voxelized[d], m->inj += r.level_injected[d], m->reb += r.level_rebounced[d];
  }
  return 0;
}

static void move_table(const gi_bake_report *r, double bake_ms, double bake_cpu, const move_sums *m, FILE *md) {
  uint64_t sv = 0, si = 0, sb = 0;
  for (int d = 0; d < r->levels; d++) sv += r->level_voxelized[d], si += r->level_injected[d], sb += r->level_rebounced[d];
  double k = m->n ? 1.0 / m->n : 0;
  fprintf(md, "| | wall ms | CPU ms | voxelize ms | inject ms | bounce ms | filter ms | voxels voxelized |"
              " injected | bounce gathers |\n|---|---|---|---|---|---|---|---|---|---|\n");
  fprintf(md, "| cold bake | %.1f | %.1f | %.1f | %.1f | %.1f | %.1f | %llu | %llu | %llu |\n", bake_ms, bake_cpu,
          r->ms.voxelize, r->ms.inject, r->ms.bounce, r->ms.filter, (unsigned long long)sv, (unsigned long long)si,
          (unsigned long long)sb);
  fprintf(md, "| dynamic update (mean of %d one-cell moves) | %.1f | %.1f | %.1f | %.1f | %.1f | %.1f | %.0f | %.0f | %.0f |\n",
          m->n, m->ms * k, m->cpu * k, m->st.voxelize * k, m->st.inject * k, m->st.bounce * k, m->st.filter * k,
          m->vox * k, m->inj * k, m->reb * k);
  fprintf(md, "\nCold bake / mean move: %.1fx wall, %.1fx CPU. Moves that closed the refresh cycle: %d (%.1f ms "
              "each); the others %.1f ms on average; the slowest move %.1f ms.\n\n",
          bake_ms / (m->ms * k), bake_cpu / (m->cpu * k), m->closed, m->closed ? m->closed_ms / m->closed : 0,
          m->n > m->closed ? m->open_ms / (m->n - m->closed) : 0, m->max_ms);
}

int tables_run(const tables_opts *o, FILE *md) {
  gi_scene *s = NULL;
  if (load_scene(o, &s) != 0) return -1;
  double at[3];
  if (o->have_at) memcpy(at, o->at, sizeof at);
  else gi_city_default_viewpoint(&o->city, at);
  gi_cascade *c = NULL;
  gi_error_info err = {0};
  gi_quality q = o->q;
  double w0 = now_ms(), c0 = cpu_ms();
  gi_result rc = gi_cascade_bake(s, at, &q, &c, NULL, &err);
  double bake_ms = now_ms() - w0, bake_cpu = cpu_ms() - c0;
  gi_scene_stats st;
  gi_scene_get_stats(s, &st);
  gi_scene_release(s);
  if (rc != GI_OK) return fprintf(stderr, "gi-walk: %s: bake: %s\n", o->label, err.msg), -1;
  gi_bake_report r = *gi_cascade_report(c);
  fprintf(md, "### %s\n\n%llu triangles; viewpoint %.2f %.2f %.2f; quality: %d levels of %d^3, finest "
              "voxel %.3f m, coarsest level %.0f m.\n\n",
          o->label, (unsigned long long)st.triangles, at[0], at[1], at[2], r.levels, r.quality.res, r.voxel_size[0],
          r.voxel_size[r.levels - 1] * r.quality.res);
  voxel_table(c, &r, md);
  memory_table(c, &r, o->vdb_max_voxels, md);
  move_sums m;
  int ok = time_moves(c, at, 2.0 * r.voxel_size[0], o->moves, &m) == 0;
  if (ok) move_table(&r, bake_ms, bake_cpu, &m, md);
  gi_cascade_free(c);
  fflush(md);
  return ok ? 0 : -1;
}
