/* main.c: gi-bake, one bake around one viewpoint from the command line.
 *
 * Design: a straight line through the core's public API, nothing more:
 * parse (args.c), load or build the scene, gi_cascade_bake, one
 * gi_cascade_gather for the viewpoint and every --probes point, write the
 * EXR and VDB, then report (report.c). Stages the core does not time
 * itself (load, gather, encode, total) are timed here with a monotonic
 * clock. Output files are written by the core through temporary names, so
 * a failed or killed run leaves no truncated file behind. Exit codes:
 * 0 success, 1 the work failed, 2 bad arguments. */
#define _POSIX_C_SOURCE 200809L
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>
#include "cli.h"

static double now_ms(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return (double)ts.tv_sec * 1e3 + (double)ts.tv_nsec * 1e-6;
}

/* The worker count the core will use for threads = 0 ("all cores"). */
static int resolved_threads(int threads) {
  if (threads > 0) return threads;
  long n = sysconf(_SC_NPROCESSORS_ONLN);
  return n < 1 ? 1 : n > 256 ? 256 : (int)n;
}

static int fail(const char *what, const gi_error_info *err, gi_result rc) {
  const char *msg = err->msg[0] ? err->msg : gi_strerror(rc);
  size_t n = strlen(what);
  /* The core's messages often start with the stage: "bake: bake: ..." read as a stutter. */
  if (!strncmp(msg, what, n) && msg[n] == ':') fprintf(stderr, "gi-bake: %s\n", msg);
  else fprintf(stderr, "gi-bake: %s: %s\n", what, msg);
  return EXIT_RUN;
}

/* Loads the scene file, or builds the city, with the command line's lights. */
static int load_scene(const cli_opts *o, gi_scene **scene) {
  gi_error_info err = {0};
  gi_scene_options so;
  memset(&so, 0, sizeof so);
  so.up = o->up ? (gi_up_axis)o->up : GI_UP_Y;
  so.threads = o->q.threads;
  so.lights = o->num_lights ? o->lights : NULL;
  so.num_lights = o->num_lights;
  so.default_lights = !o->no_default_lights;
  gi_result r = o->is_city ? gi_city_build(&o->city, &so, scene, &err) : gi_scene_load(o->scene, &so, scene, &err);
  return r == GI_OK ? 0 : fail(o->is_city ? "city" : "scene", &err, r);
}

/* A scene file read with the default y up that looks z-up
 * (gi_scene_looks_z_up): still a valid request, so only a note, with the fix. */
static void note_up_axis(const cli_opts *o, const gi_scene *scene) {
  if (o->is_city || o->up || !gi_scene_looks_z_up(scene)) return;
  double lo[3], hi[3];
  gi_scene_bounds(scene, lo, hi);
  fprintf(stderr, "gi-bake: note: the scene is flat along z (%g x %g x %g) " TA_NOTE_Z_UP_FIX "\n", hi[0] - lo[0],
          hi[1] - lo[1], hi[2] - lo[2]);
}

/* Without --at: the city's street corner, or the centre of the bounds (said
 * on stderr). With --at outside the bounds: a note, usually a wrong --up or unit. */
static void choose_viewpoint(cli_opts *o, const gi_scene *scene) {
  double lo[3], hi[3], blo[3], bhi[3];
  gi_scene_bounds(scene, lo, hi);
  gi_scene_bulk_bounds(scene, blo, bhi); /* not between a model and a stray triangle far off */
  if (!o->have_at) {
    if (o->is_city) {
      gi_city_default_viewpoint(&o->city, o->at);
    } else {
      for (int k = 0; k < 3; k++) o->at[k] = 0.5 * (blo[k] + bhi[k]);
      gi_scene_stats st;
      gi_scene_get_stats(scene, &st);
      fprintf(stderr, "gi-bake: no --at given; baking at the centre of the scene bounds%s (%.9g, %.9g, %.9g)\n",
              st.far_triangles ? " less its stray far triangles" : "", o->at[0], o->at[1], o->at[2]);
    }
    return;
  }
  int inside = 1;
  for (int k = 0; k < 3; k++) inside &= o->at[k] >= lo[k] && o->at[k] <= hi[k];
  /* Still a valid request, so only a note. */
  if (!inside)
    fprintf(stderr, "gi-bake: note: --at (%g, %g, %g) lies outside the scene bounds (%g, %g, %g) .. (%g, %g, %g)\n",
            o->at[0], o->at[1], o->at[2], lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]);
}

/* --probes beyond the default cascade (around one object, probes just
 * past its bounds) took no indirect light at all: the coarsest level
 * spans the scene, not the points. With --levels and --voxel both left
 * to the default, adds levels (finest voxel kept) until the cascade, as
 * the bake will place it, holds as many points as any level count up to
 * GI_MAX_LEVELS would; each level costs about what the coarsest one did.
 * A point no count holds adds nothing: levels added for it changed the
 * other probes' light (+10% at one) and still left it out. It keeps the
 * note after the bake. */
static void cover_probes(cli_opts *o, const gi_scene *scene) {
  if (!o->num_probes || o->q.levels || o->q.voxel0 > 0) return;
  gi_quality rq;
  gi_error_info e = {0};
  if (gi_quality_resolve(scene, &o->q, &rq, &e) != GI_OK) return; /* the bake reports it */
  int base = rq.levels, best = base;
  size_t held[GI_MAX_LEVELS + 1] = {0};
  for (int L = base; L <= GI_MAX_LEVELS; L++) {
    rq.levels = L;
    if (gi_cascade_would_cover(scene, o->at, &rq, o->probes, o->num_probes, NULL, &held[L], &e) != GI_OK)
      return; /* the bake reports it */
    if (held[L] > held[best]) best = L;
    if (held[L] == o->num_probes) break;
  }
  if (best == base) return;
  o->q.levels = best, o->q.voxel0 = rq.voxel0;
  fprintf(stderr, "gi-bake: note: %d levels instead of %d (the finest voxel kept at %g) so the cascade holds the "
          "--probes points (%zu of %zu)\n", best, base, rq.voxel0, held[best], o->num_probes);
}

/* A point whose surroundings show it surfaces' backs lies inside a solid:
 * its probe reads only light that leaks in, where the truth is darkness
 * (the issue's own Munich viewpoint, 0,0,2, is inside a building). Notes
 * it, and how many --probes points are, on stderr: still valid requests. */
static void note_inside(const cli_opts *o, const gi_scene *scene) {
  double share = gi_scene_backface_share(scene, o->at);
  /* A view's indirect light comes from the cascade centred there too: a
   * helper's outdoor view baked at the bounds' centre (inside a block) read
   * the ground by the block at 0.2-0.4x of Cycles, 1.0-1.2x from in front. */
  if (share > GI_INSIDE_SHARE)
    fprintf(stderr, "gi-bake: note: the viewpoint (%g, %g, %g) looks inside a solid (%.0f%% of 26 rays from it "
            "meet a surface's back first): its probe holds only light that leaks in%s\n",
            o->at[0], o->at[1], o->at[2], 100 * share,
            o->render ? ", and the --render view's indirect light comes from a cascade centred there: give --at "
                        "where the view looks" : "");
  size_t in = 0;
  for (size_t i = 0; i < o->num_probes; i++) in += gi_scene_backface_share(scene, o->probes + 3 * i) > GI_INSIDE_SHARE;
  if (in)
    fprintf(stderr, "gi-bake: note: %zu of %zu --probes points look inside a solid (their probes hold only light "
            "that leaks in)\n", in, o->num_probes);
}

/* Which points the cascade covers, and a note on stderr about the --probes
 * points it does not: their indirect light is 0, not measured. */
static void note_outside(const cli_opts *o, const gi_cascade *cas, const double *pts, size_t n, uint8_t *covered) {
  size_t out = 0;
  for (size_t i = 0; i < n; i++) out += !(covered[i] = (uint8_t)gi_cascade_covers(cas, pts + 3 * i));
  if (out)
    fprintf(stderr, "gi-bake: note: %zu of %zu points lie outside the cascade around (%g, %g, %g): their "
            "indirect light is 0 and only their direct light is answered (\"in_cascade\": false in --json); "
            "bake with --at nearer them, or with more --levels\n", out, n, o->at[0], o->at[1], o->at[2]);
}

/* The gather points, viewpoint first, then --probes; and room for their probes. */
/* A --render eye the renderer will refuse (more than 1e9 from the scene's
 * origin on an axis, as the core's camera rule), refused before the bake: it failed
 * with exit 1 after a whole bake, where every other bad camera exits 2 at
 * once. */
static int check_render_eye(const cli_opts *o, const gi_scene *scene) {
  if (!o->render) return 0;
  double org[3];
  gi_scene_origin(scene, org);
  for (int a = 0; a < 3; a++)
    if (!(fabs(o->cam.eye[a] - org[a]) <= 1e9)) {
      fprintf(stderr,
              "gi-bake: --render: the eye (%g, %g, %g) is more than 1e9 units from the scene's origin on axis %c\n",
              o->cam.eye[0], o->cam.eye[1], o->cam.eye[2], "xyz"[a]);
      return EXIT_USAGE;
    }
  return 0;
}

static int make_points(const cli_opts *o, double **pts, gi_probe **probes, size_t *n) {
  *n = 1 + o->num_probes;
  *pts = malloc(*n * 3 * sizeof **pts);
  *probes = calloc(*n, sizeof **probes);
  if (!*pts || !*probes) {
    fprintf(stderr, "gi-bake: out of memory for %zu probes\n", *n);
    return EXIT_RUN;
  }
  memcpy(*pts, o->at, sizeof o->at);
  if (o->num_probes) memcpy(*pts + 3, o->probes, o->num_probes * 3 * sizeof **pts);
  return 0;
}

/* --render pictures, then the probe EXR and the VDB. */
static int write_outputs(const cli_opts *o, const gi_scene *scene, const gi_cascade *cas, const gi_probe *probes,
                         size_t n, const gi_bake_report *rep, cli_render_stats *rs) {
  gi_error_info err = {0};
  gi_result r;
  int rc;
  if (o->render) {
    if ((rc = cli_render(o, scene, cas, rs)) != 0) return rc;
    fprintf(stderr, "gi-bake: render %d x %d: cone-traced %.1f ms (%llu specular cones), path-traced (%d "
                    "paths/pixel) %.1f ms, mean relative error %.1f%%%s%s\n", rs->width, rs->height, rs->cone_ms,
            (unsigned long long)rs->view.specular_cones, rs->spp, rs->path_ms, 100 * rs->mre, o->png ? ", wrote " : "",
            o->png ? o->png : "");
  }
  if (o->exr && !o->render &&
      (r = gi_probes_write_exr(o->exr, probes, n, scene, o->at, rep, o->half, &err)) != GI_OK)
    return fail("--exr", &err, r);
  if (o->vdb && (r = gi_cascade_write_vdb(cas, o->vdb, o->vdb_faces, &err)) != GI_OK) return fail("--vdb", &err, r);
  return 0;
}

/* cli_report, to stderr when an output is standard output (--exr
 * /dev/stdout | ...), so that stream holds the file alone. */
static int report(const cli_run *run, int json) {
  int saved = -1;
  if (ta_output_is_stdout() && fflush(stdout) == 0 && (saved = dup(STDOUT_FILENO)) >= 0)
    dup2(STDERR_FILENO, STDOUT_FILENO);
  int rc = cli_report(run, json);
  if (saved >= 0) fflush(stdout), dup2(saved, STDOUT_FILENO), close(saved);
  return rc;
}

int main(int argc, char **argv) {
  static ta_ctx fin = TA_CTX("gi-bake");
  ta_memory_policy();
  int crc = ta_check_cpu_path(&fin);
  if (crc) return crc;
  if (argc > 1 && !strcmp(argv[1], "merge")) {
    int mrc = batch_merge_main(argc - 1, argv + 1);
    int frc = ta_outputs_finish(&fin, mrc == 0);
    return mrc ? mrc : frc;
  }
  cli_opts o;
  int rc = cli_parse(argc, argv, &o);
  if (rc) {
    cli_opts_fini(&o);
    ta_outputs_finish(&fin, 0);
    return rc < 0 ? 0 : rc;
  }

  gi_scene *scene = NULL;
  gi_cascade *cas = NULL;
  gi_probe *probes = NULL;
  uint8_t *covered = NULL;
  double *pts = NULL;
  size_t n = 0;
  gi_error_info err = {0};
  gi_result r;

  double t_start = now_ms();
  if ((rc = load_scene(&o, &scene))) goto done;
  double load_ms = now_ms() - t_start;
  note_up_axis(&o, scene);
  if (o.batch.grid > 0) {
    rc = batch_run(&o, scene, load_ms);
    goto done;
  }
  if (o.lm.out) {
    rc = lightmap_run(&o, scene, t_start, load_ms, now_ms);
    goto done;
  }
  choose_viewpoint(&o, scene);
  note_inside(&o, scene);
  cover_probes(&o, scene);
  if ((rc = check_render_eye(&o, scene)) || (rc = make_points(&o, &pts, &probes, &n))) goto done;

  gi_bake_report rep;
  memset(&rep, 0, sizeof rep);
  /* The extra probes (after the viewpoint) count in the plan's sky test. */
  if ((r = gi_cascade_bake_for(scene, o.at, pts + 3, n - 1, &o.q, NULL, &cas, &rep, &err)) != GI_OK) {
    rc = fail("bake", &err, r);
    goto done;
  }
  double gather_ms = 0;
  if ((r = gi_cascade_gather(cas, pts, n, probes, &gather_ms, &err)) != GI_OK) {
    rc = fail("gather", &err, r);
    goto done;
  }

  if (!(covered = malloc(n))) {
    fprintf(stderr, "gi-bake: out of memory for %zu probes\n", n);
    rc = EXIT_RUN;
    goto done;
  }
  note_outside(&o, cas, pts, n, covered);

  double t_enc = now_ms();
  cli_render_stats rs;
  memset(&rs, 0, sizeof rs);
  if ((rc = write_outputs(&o, scene, cas, probes, n, &rep, &rs))) goto done;
  double encode_ms = now_ms() - t_enc;
  rep.ms.gather = gather_ms;
  rep.ms.encode = encode_ms;

  cli_run run = {
      .o = &o,
      .scene = scene,
      .rep = &rep,
      .probes = probes,
      .num_probes = n,
      .points = pts,
      .covered = covered,
      .load_ms = load_ms,
      .gather_ms = gather_ms,
      .encode_ms = encode_ms,
      .total_ms = now_ms() - t_start,
      .threads = resolved_threads(rep.quality.threads),
      .render = o.render ? &rs : NULL,
  };
  rc = report(&run, o.json);

done:
  free(covered);
  free(probes);
  free(pts);
  gi_cascade_free(cas);
  gi_scene_release(scene);
  cli_opts_fini(&o);
  /* Outputs named as a device or FIFO get their bytes now, after success. */
  int frc = ta_outputs_finish(&fin, rc == 0);
  return rc ? rc : frc;
}
