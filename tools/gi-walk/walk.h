/* walk.h: gi-walk, the moving-viewpoint benchmark (issue 12 items 3 and 4).
 *
 *   gi-walk bench   street walk and drive through the city: each step moves
 *                   one cascade (gi_cascade_move) and gathers the probe at
 *                   the eye; a subsample of steps is also baked cold, for
 *                   speed-up, drift and popping against the goals.
 *   gi-walk tables  the paper's tables for one scene: voxel counts per level,
 *                   memory against a dense grid and an OpenVDB grid, stage
 *                   times per level, cold bake against a move.
 * One file per concern: path.c (street paths, footprint check, CSV),
 * stats.c (percentiles), probe.c (the probe's figures), bench.c, report.c
 * (the bench's printout and JSON), tables.c, vdbmem.c, main.c (arguments). */
#ifndef GI_WALK_H
#define GI_WALK_H

#include <errno.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>
#include "gi/gi.h"
#include "gi/gi_move.h"

/* --- path.c ---------------------------------------------------------------- */

typedef struct walk_path {
  const char *name;   /* "walk" or "drive", or a --path file's base name (owned: name_buf) */
  char name_buf[64];
  double speed;       /* m/s */
  double eye;         /* eye height above the street, m */
  double rate;        /* samples per second */
  size_t n;
  double *t;          /* n times, s */
  double (*at)[3];    /* n world points (city: y up) */
  gi_quality resolved; /* set by bench_path: the quality the cascade was baked with */
  /* Set by bench_path: the crossing step whose update jumped most at a fixed
   * point (0: none) and the jump of cold bakes across that same shift (the
   * bakes at the steps either side, both gathered at its point; < 0 when
   * not measured): equal jumps are the cascade's structure, a larger moved
   * one is the move's drift. */
  size_t worst_shift;
  double worst_shift_cold;
  double setup_ms; /* set by bench_path: gi_cascade_move_prepare after the first bake */
  /* Per point: 1 inside a solid (GI_INSIDE_SHARE), owned; NULL: none is. A
   * probe there holds only leaked light, so drift and popping leave it out. */
  unsigned char *inside;
  size_t num_inside;
} walk_path;

static inline int walk_point_inside(const walk_path *p, size_t i) { return p->inside && p->inside[i]; }

/* A path along the city's street centre lines from the central
 * intersection, turning at intersections (seeded), kept inside the city. */
int walk_path_make(const gi_city_params *cp, const char *name, double speed, double eye, double rate,
                   double seconds, uint64_t seed, walk_path *out);
/* Checks every point lies on a street band, outside building footprints (a
 * ray down from above the roofs meets the street first) and that the eye's
 * segment to the next point is clear. Prints the first violation; 0 = ok. */
int walk_path_check(const gi_scene *s, const gi_city_params *cp, const walk_path *p);
int walk_path_write_csv(const walk_path *p, const char *file);
/* A path from a file's steps (ta_read_path), named after the file's base
 * name (characters other than letters, digits, '.', '_' and '-' become
 * '_'); its speed is its length over its duration, its rate its steps
 * over it, its eye height unknown (NAN). 0, or -1 when out of memory. */
struct ta_step;
int walk_path_from_steps(const char *file, const struct ta_step *st, size_t n, walk_path *out);
void walk_path_free(walk_path *p);
/* A scene file read without --up that looks z-up (gi_scene_looks_z_up): a
 * note on stderr naming the fix (the paths' points are then read wrongly). */
void walk_note_up(const char *file, gi_up_axis up, const gi_scene *s);

/* --- stats.c --------------------------------------------------------------- */

double stat_mean(const double *v, size_t n);
/* Nearest-rank percentile q in [0,100] (copies and sorts). */
double stat_pct(const double *v, size_t n, double q);
double stat_max(const double *v, size_t n);
double now_ms(void);     /* monotonic wall clock */
double cpu_ms(void);     /* process CPU time, all threads */

/* --- probe.c --------------------------------------------------------------- */

/* The figures compared: SH L00 and the irradiance of the 6 axis directions
 * (+x, -x, +y, -y, +z, -z), each the mean of its RGB channels. */
#define PROBE_FIGS 7
typedef struct probe_figs {
  double v[PROBE_FIGS];
} probe_figs;

int probe_at(const gi_cascade *c, const double at[3], probe_figs *out, double *gather_ms);
/* The largest relative difference of a against reference b over the
 * figures (each relative to the larger of |b| and 1e-3 of b's largest). */
double probe_rel(const probe_figs *a, const probe_figs *b);

/* --- bench.c / report.c ---------------------------------------------------- */

typedef struct bench_opts {
  gi_city_params city;
  gi_quality q;
  double seconds, rate;
  int samples;          /* cold bake pairs per path */
  const char *out_dir;
  const char *jsonl;    /* appended to; NULL: none */
  const char *path_file; /* --path: replay this file instead of the city's walk and drive */
  const char *scene_file; /* with --path: this scene instead of the city */
  gi_up_axis up;         /* the scene file's, 0: y */
} bench_opts;

/* One step of a path. */
typedef struct step_rec {
  int crossed;          /* the level-0 anchor changed: the move scrolled */
  int closed;           /* the move closed the refresh cycle */
  double move_ms, move_cpu_ms, gather_ms;
  probe_figs moved;     /* at this step's point, after the move */
  probe_figs pre;       /* at this step's point, before the move (the previous step's cascade) */
  int cold;             /* 1: a cold bake was made here */
  double cold_ms, cold_cpu_ms;
  probe_figs cold_probe;
  probe_figs cold_next; /* the cold bake gathered at the next step's point */
  uint64_t redone[3];   /* voxels voxelized, injected, re-gathered by the move */
} step_rec;

int bench_path(const bench_opts *o, const gi_scene *s, walk_path *p, step_rec *steps);
/* Prints the figures against the goals, appends the JSON line, writes the
 * per-step CSV (for the chart). */
void report_path(const bench_opts *o, const walk_path *p, const step_rec *steps, FILE *json);

/* --- tables.c / vdbmem.c --------------------------------------------------- */

typedef struct tables_opts {
  const char *label;
  const char *scene_file;  /* NULL: the city */
  gi_city_params city;
  gi_quality q;            /* zero: the defaults */
  gi_up_axis up;
  double at[3];
  int have_at;
  int moves;               /* one-cell moves timed after the bake */
  size_t vdb_max_voxels;   /* above this, the OpenVDB grid covers the finer levels only */
} tables_opts;

int tables_run(const tables_opts *o, FILE *md);

typedef struct vdb_figure {
  size_t bytes;            /* OpenVDB memUsage() of the grids */
  uint64_t active;         /* active voxels at the finest size */
  int levels_covered;      /* levels 0..levels_covered-1 resampled */
} vdb_figure;
/* Resamples the cascade's own occupied voxels to the finest voxel size (a
 * coarse voxel's surface plane, through its centroid along its normal) into
 * OpenVDB Vec3f grids: 6 face radiances and the opacity per axis. */
int vdb_figure_measure(const gi_cascade *c, size_t max_voxels, vdb_figure *out);

/* A file gi-walk could not open or finish: which one and why, on stderr. */
static inline void walk_file_error(const char *file) {
  fprintf(stderr, "gi-walk: cannot write '%s': %s\n", file, strerror(errno));
}

#endif
