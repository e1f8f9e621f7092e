/* acc.h: gi-accuracy's shared types (the sweep's rows and the report). */
#ifndef GI_ACC_H
#define GI_ACC_H

#include <stddef.h>
#include "metrics.h"

/* One measured configuration: a cone-traced bake (kind "cone") or a
 * path-traced answer (kind "path") at the same probes. */
typedef struct acc_row {
  char scene[32];
  char kind[8];        /* "cone" or "path" */
  char knob[16];       /* "default", "res", "levels", "voxel0", "cones", "aperture", "step", "bounces", "samples" */
  double value;        /* the knob's value */
  int is_default;
  double ms;           /* bake + gather (cone) or path tracing (path), wall clock */
  double bake_ms, gather_ms;
  acc_metrics m[3];    /* ACC_TOTAL, ACC_DIRECT, ACC_INDIRECT */
  int on_front;        /* on the scene's Pareto front of (ms, total mre) */
  int specular_ran;
} acc_row;

typedef struct acc_scene_info {
  char name[32];
  size_t probes;
  int ref_samples;
  double ref_ms;       /* time the reference took (0 when read from the cache) */
  double ref_rel_se[3];
  char at[96];
} acc_scene_info;

/* report.c: writes out_dir/accuracy.csv, accuracy.gp (+ accuracy.png via
 * gnuplot when present) and the markdown report md_path, with the
 * hand-written notes file (may be NULL) after the method. Returns 0 on success. */
int acc_write_reports(const acc_row *rows, size_t n, const acc_scene_info *sc, size_t nsc, const char *out_dir,
                      const char *md_path, const char *png_path, const char *machine, const char *cmdline,
                      const char *notes);

#endif
