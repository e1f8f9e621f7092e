/* acc.h: gi-accuracy's shared types (the sweep's rows and the report). */
#ifndef GI_ACC_H
#define GI_ACC_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include "gi/gi_camera.h"
#include "metrics.h"

/* A cold bake's time: its plan and its four stages (the gather apart). */
static inline double acc_bake_ms(const gi_bake_report *r) {
  return r->ms.plan + r->ms.voxelize + r->ms.inject + r->ms.filter + r->ms.bounce;
}

/* The shipped scenes one run can name (cornell, munich, city, city5k):
 * every per-scene table of a run holds this many. */
#define ACC_MAX_SCENES 4

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
  char placement[160]; /* how the probes were chosen (--scene runs); "" for the shipped scenes */
} acc_scene_info;

/* A scene with its viewpoint and probe points. */
struct gi_scene;
typedef struct acc_scene_set {
  struct gi_scene *s;
  double at[3];
  double *pts;
  size_t n;
  int ref_samples;     /* reference paths per probe for this scene */
  double clearance;    /* street level: candidates nearer a surface than this are dropped (0: none) */
} acc_scene_set;

/* main.c: keeps the candidates that see direct light above 2% of the best
 * (drops points inside solids, where the truth is darkness) and have
 * ss->clearance of room around them, at most keep, in their order. Returns 1 when at least one is kept. */
int acc_keep_lit(acc_scene_set *ss, const double *cand, size_t nc, size_t keep, int threads);

/* cache.c: the cache files' names (keys hashed with toolargs' ta_fnv),
 * and the cache files themselves: read exactly na (+ nb when b is not
 * NULL) bytes, 1 on success; write through a temporary name renamed into
 * place (a failure is printed, the run goes on without the cache). */
/* The start of every reference cache key: the scene's name, and for a
 * --scene FILE run what was loaded (acc_cache_scene_version), so an edited
 * file never reuses the references of its former self. */
uint64_t acc_cache_key(const char *name);
void acc_cache_scene_version(uint64_t v); /* 0 (the built-in scenes): keys as before */
int acc_cache_read(const char *path, void *a, size_t na, void *b, size_t nb);
void acc_cache_write(const char *path, const void *a, size_t na, const void *b, size_t nb);
/* The probe reference of scene `name` at ss's points (ss->ref_samples
 * paths, seed 1), seeing the light kinds `lights` (a gi_reference_opts
 * mask, 0 = all): from out_dir's cache, keyed by all of these and
 * ref_version, or traced and cached. *ms: the tracing time (0 from the
 * cache). Returns 1 on success (0 printed). */
int acc_ref_cached(const char *name, const acc_scene_set *ss, int lights, int threads, const char *out_dir,
                   int ref_version, gi_ref_probe *ref, double *ms);

/* One camera view at equal error (views.c). */
#define ACC_VIEW_MAX_PATH 8
typedef struct acc_view {
  char scene[32];
  int w, h, ref_spp;
  double ref_ms;              /* reference render time (0 when read from the cache) */
  double ref_mre;             /* the reference's own error, from its two halves */
  size_t pixels;              /* pixels compared (not pure sky) */
  double cone_ms, cone_bake_ms, cone_render_ms, cone_mre, cone_ssim;
  unsigned long long specular_cones;
  int num_path, path_spp[ACC_VIEW_MAX_PATH];
  double path_ms[ACC_VIEW_MAX_PATH], path_mre[ACC_VIEW_MAX_PATH], path_ssim[ACC_VIEW_MAX_PATH];
  double path_ms_at_cone;     /* path-tracer ms at the cone's error; -1 not reached */
  char png[256];              /* the picture, relative to the report */
} acc_view;

/* Renders the view cam of scene s: the reference (ref_spp paths per pixel,
 * cached in out_dir under ref_version), the cone tracer's bake at `at` +
 * render at default quality, the path tracer at 1, 4, .. ref_spp / 4;
 * writes the side-by-side picture to png (may be NULL). Returns 1 on success. */
struct gi_camera;
int acc_run_view(const char *name, const struct gi_scene *s, const double at[3], const struct gi_camera *cam,
                 int ref_spp, int threads, int repeat, const char *out_dir, const char *png, int ref_version,
                 acc_view *v);
/* The same comparison for the lat-long panorama (w x h) of the light
 * arriving at `at`: gi_cascade_panorama (direct + indirect) against
 * gi_reference_panorama, the reference cached as pano-NAME-HASH.bin. */
int acc_run_pano(const char *name, const struct gi_scene *s, const double at[3], int w, int h, int ref_spp,
                 int threads, int repeat, const char *out_dir, const char *png, int ref_version, acc_view *v);
/* The error of img (the camera's w x h x 3 floats) against the view's
 * reference as acc_run_view counts it (same pixels, same floor); the
 * reference from its cache (rendered when missing). -1 on failure. */
double acc_view_image_error(const char *name, const struct gi_scene *s, const struct gi_camera *cam, int ref_spp,
                            const char *out_dir, int ref_version, const float *img);
/* Mean relative error of a's luminance against ref's over the pixels in
 * mask, each divided by max(ref, floor_l). */
double acc_image_mre(const float *a, const float *ref, const unsigned char *mask, size_t np, double floor_l);
/* Mean SSIM of a against ref on display luminance (times exposure, clamped
 * to [0, 1], gamma 1/2.2), over 8 x 8 windows at a stride of 4 that lie
 * wholly in the mask; 1 = structurally identical, 1 when no window fits. */
double acc_image_ssim(const float *a, const float *ref, const unsigned char *mask, int w, int h, double exposure);
/* The views' section of the markdown report. */
void acc_write_views_md(FILE *f, const acc_view *v, size_t n);

/* ---- workload.c: the cone tracer against the path tracer at equal error,
 * per workload (issue 11, item 4). ---- */
#define ACC_WL_MAX_PATH 12
#define ACC_WL_MAX_CYCLES 4
typedef struct acc_workload {
  char scene[32];
  char what[48];        /* "1000 probes", "panorama 256x128", "camera view 320x180", ... */
  char unit[12];        /* one query of it: "probe", "panorama", "view" */
  double count;         /* queries the one bake serves */
  size_t err_points;    /* probes or pixels the error is measured over */
  int ref_samples;      /* the reference's paths per probe or pixel */
  double ref_err;       /* the reference's own error (MRE), from its halves or standard errors */
  double cone_mre, bake_ms, answer_ms; /* answer: the gather or render of all count queries */
  int num_path, path_spp[ACC_WL_MAX_PATH];
  double path_ms[ACC_WL_MAX_PATH], path_mre[ACC_WL_MAX_PATH]; /* the path tracer, for all count queries */
  double path_ms_eq;    /* path-tracer ms at cone_mre (acc_ms_at_error) */
  int path_how;         /* 0 interpolated, 1 first count already better (an upper bound), -1 not reached */
  int path_timed_full;  /* probes: the path tracer's times that path_ms_eq rests on were measured on all
                           count probes (else scaled from the error subset); images: always 1 */
  double goal;          /* speed-up asked for (path / cone), 0 none */
  int num_cycles;       /* Blender Cycles runs (the Munich aerial view) */
  int cycles_spp[ACC_WL_MAX_CYCLES];
  double cycles_ms[ACC_WL_MAX_CYCLES], cycles_mre[ACC_WL_MAX_CYCLES]; /* mre < 0: not measured */
  char png[64];         /* cone | reference | error picture, relative to the report; "" none */
} acc_workload;

/* path_ms_eq / (bake + answer): a lower bound when path_how is -1, an upper one when 1. */
double acc_workload_ratio(const acc_workload *w);

typedef struct acc_wl_opts {
  int quick, threads, repeat, pt_max, view_spp, ref_version;
  int cycles;              /* 1: also time Blender Cycles on the Munich aerial view when blender is on PATH */
  const char *out_dir;     /* reference cache */
  const char *md_dir;      /* pictures next to the markdown */
  const char *munich_obj;  /* the Munich OBJ (for Blender), NULL when not run */
} acc_wl_opts;

/* Issue 11's aerial view of Munich: 900 m south, 250 m up, looking north
 * 18 degrees down, fov 84, 256 x 256 (Z up). */
void acc_aerial_camera(gi_camera *cam);
/* Times Blender Cycles (CPU, 2 threads, no denoising) on that view at a
 * few sample counts and measures their error against our reference;
 * fills w's cycles_*. Returns 0 (printed) when Blender fails. */
int acc_cycles_aerial(const acc_wl_opts *o, const struct gi_scene *s, const gi_camera *cam, acc_workload *w);
/* One Blender Cycles render of the OBJ file obj (as it is: Z up, no axis
 * change; every material a diffuse BSDF of its Kd) with s's sun and sky,
 * through cam at spp samples, 2 threads; its script and files go to dir.
 * img receives the picture (top-down RGB, as ours), *ms the render call's
 * time. Returns 0 (printed) when Blender fails. */
int acc_cycles_image(const char *obj, const char *dir, const struct gi_scene *s, const gi_camera *cam, int spp,
                     float *img, double *ms);
/* 1 when `blender` is on PATH. */
int acc_have_blender(void);

/* The workloads of one scene: probe counts in level 0's box, the
 * panorama, the scene's camera view (view: from acc_run_view, may be NULL)
 * and, for Munich (aerial != 0), the aerial view. Appends to *out (grown
 * with realloc, *n entries). Returns 1 on success. */
int acc_run_workloads(const acc_wl_opts *o, const char *name, const acc_scene_set *ss, const acc_view *view,
                      int aerial, acc_workload **out, size_t *n);
/* The markdown section; cycles_note says why Blender did not run ("" when it did). */
void acc_write_workloads_md(FILE *f, const acc_workload *w, size_t n, const char *cycles_note);
/* out_dir/workloads.csv and workloads.jsonl. Returns 0 on success. */
int acc_write_workloads_files(const acc_workload *w, size_t n, const char *out_dir);

/* ---- bylight.c: the error split by the light it comes from (issue 16). ---- */
#define ACC_LIGHT_KINDS 4 /* sun, point/spot, sky, emissive */
typedef struct acc_light_row {
  char scene[32];
  char kind[16];               /* "sun", "point/spot", "sky", "emissive" */
  double share;                /* this kind's part of the full reference's indirect light */
  double ref_indirect_sum;     /* the kind's reference indirect luminance summed over the probes */
  double ref_indirect_se;      /* its standard error */
  double ref_ms, cone_ms;      /* reference time (0 from the cache), bake + gather */
  acc_metrics indirect, direct;
} acc_light_row;
/* For each light kind the scene's default bake runs: the reference with
 * only that kind (cached in out_dir) against the default bake with only
 * that effect on, at ss's probes; full is the scene's own reference.
 * Appends to out (room for ACC_LIGHT_KINDS more). Returns 1 on success. */
int acc_run_by_light(const char *name, const acc_scene_set *ss, const gi_ref_probe *full, int threads,
                     const char *out_dir, int ref_version, acc_light_row *out, size_t *nout);
/* The markdown section (n = 0: not measured). */
void acc_write_by_light_md(FILE *f, const acc_light_row *r, size_t n);

/* ---- handover.c: a small source on a hand-built cascade, within a level
 * and across levels (the cone march's level hand-over). ---- */
typedef struct acc_handover {
  int ran;
  double one_level;        /* thin rays, one level: beam light / the plate's flux */
  double tau_over_alpha;   /* what one level should read (the optical-depth model's excess) */
  double mean, min, max;   /* the probes' cones across levels, over heights x distances */
  double probe_tan;
} acc_handover;
/* Measures it (deterministic, a few seconds on 2 cores). Returns 1 on success. */
int acc_run_handover(int threads, acc_handover *h);
/* The markdown section (h NULL or not run: says so). */
void acc_write_handover_md(FILE *f, const acc_handover *h);

/* The workloads as the report takes them. */
typedef struct acc_wl_report {
  const acc_workload *w;
  size_t n;
  int ran;               /* 0: --no-workloads */
  const char *cycles_note;
  const acc_light_row *by_light; /* the by-light section's rows (n_by_light 0: not measured) */
  size_t n_by_light;
  const acc_handover *handover;  /* the hand-built cascade's figures (NULL: not measured) */
} acc_wl_report;
/* report.c: writes out_dir/accuracy.csv, accuracy.gp (+ accuracy.png via
 * gnuplot when present) and the markdown report md_path, with the
 * hand-written notes file (may be NULL) after the method, and the
 * workloads (wl, may be NULL) in their section and files. Returns 0 on success. */
int acc_write_reports(const acc_row *rows, size_t n, const acc_scene_info *sc, size_t nsc, const acc_view *views,
                      size_t nviews, const acc_wl_report *wl, const char *out_dir, const char *md_path,
                      const char *png_path, const char *machine, const char *cmdline, const char *notes);

/* scene_file.c: `gi-accuracy --scene FILE`, any scene file. */
#define ACC_FILE_MAX_PROBES 4096 /* --probes: more would make the reference take hours */
typedef struct acc_file_opts {
  const char *path;       /* --scene; NULL: the shipped scenes */
  char name[32];          /* the file's base name without extension, safe for CSV and gnuplot */
  int up;                 /* GI_UP_Y or GI_UP_Z (--up) */
  int up_given;           /* --up was on the command line */
  int have_at;
  double at[3];           /* --at: the cone tracer's viewpoint */
  const char *probes_file;/* --probes */
  double *pts;            /* its points, read while parsing */
  size_t npts;
  double above_ground;    /* --above-ground: street-level probes this far up; 0 = a lattice in the bounds */
  double spacing;         /* --spacing: the street grid's spacing; 0 = from the scene's width */
  int have_view, cam_up_from_scene;
  gi_camera cam;          /* --view */
} acc_file_opts;

struct ta_ctx;
/* Takes argv[*i] when it is one of the --scene options (advancing *i past
 * its value): 1 taken, 0 not one of them, 2 bad value (message printed). */
int acc_file_option(struct ta_ctx *ta, acc_file_opts *f, int argc, char **argv, int *i);
/* After every option: the combinations, the files, the name. Returns 0,
 * 2 (bad usage) or 1 (a file cannot be read), the message printed. */
int acc_file_check(struct ta_ctx *ta, acc_file_opts *f);
/* Loads the file and places the probes (or takes --probes); the reference
 * paths per probe are ref_samples. 1 on success, 0 on failure (printed). */
int acc_file_setup(const acc_file_opts *f, int ref_samples, int threads, acc_scene_set *ss, char *placement,
                   size_t placement_size);
/* The --view camera with the scene's up axis; 0 when there is none. */
int acc_file_camera(const acc_file_opts *f, const struct gi_scene *s, gi_camera *cam);

#endif
