/* trace.c: the cone-tracing filter over the cascaded texture.
 *
 * A cone at distance t has diameter D = 2 t tan(aperture/2). The level to
 * sample follows directly from D (lod = log2(D / s0)) and from the sample's
 * position (the finest level whose window, less a one-voxel border for the
 * trilinear footprint, contains it): no tree is walked. Between two levels
 * the sample blends linearly in D within the octave, so a cone's result
 * changes smoothly as the viewpoint or the cascade moves (not where the
 * surface rule below picks the level: there it reads one level).
 *
 * A sample reads the three faces that face back toward the apex, weighted
 * by the squared components of the direction. Opacity comes from optical
 * depth: sigma = sum |w_a| tau_a / s, so a slab that is opaque along its
 * normal stays opaque at any angle, and a segment of length dt has opacity
 * 1 - exp(-sigma dt) (the step-length correction). Compositing is front to
 * back: c += (1 - a) a_s c_s, a += (1 - a) a_s, until a >= GI_OPAQUE_ALPHA
 * or the cone leaves the coarsest level; a cone stopped by opacity is
 * renormalised by a. Where a cone starts and which levels it may enter
 * near a surface is the gather's rule (trace/gather.c).
 * */
#include "base/internal.h"
#include "trace/trace.h"

int gi__finest_level_at(const struct gi_cascade *c, const float p[3]) {
  for (int d = 0; d < c->n; d++)
    if (gi__level_contains(&c->lv[d], p, 1.0f)) return d;
  return -1;
}

float gi__voxel_at(const struct gi_cascade *c, const float p[3]) {
  int d = gi__finest_level_at(c, p);
  return (float)(d >= 0 ? c->lv[d].s : c->s0);
}

/* The two builds of march_kernel.c. */
#define GI_MARCH_ARGS                                                                                         \
  const struct gi_cascade *c, const float o[3], const float w[3], float tan_half, float t0, float step,      \
      float ao_lambda, float h0, const float *n, gi_cone_out *out
void gi__cone_march_base(GI_MARCH_ARGS);
int gi__sample_level_base(const struct gi_cascade *c, int d, const float p[3], const float w[3], float prem[3],
                          float *wsum_alpha, float *sigma);
void gi__cone_march_rec_base(GI_MARCH_ARGS, gi_tap_rec *rec, uint16_t job);
size_t gi__replay_tape_base(const struct gi_cascade *c, const gi_tape_unit *u, size_t units, float L[][3],
                            uint16_t *job);
#ifdef GI_HAVE_V3_BUILD
void gi__cone_march_v3(GI_MARCH_ARGS);
size_t gi__replay_tape_lanes(const struct gi_cascade *c, const gi_tape_unit *u, size_t units, float L[][3],
                             uint16_t *job);
void gi__cone_march_jobs_v3(const struct gi_cascade *c, const gi_cone_job *jobs, int count, float tan_half,
                            float step, float ao_lambda, gi_cone_out *out, gi_tap_rec *rec);
int gi__sample_level_v3(const struct gi_cascade *c, int d, const float p[3], const float w[3], float prem[3],
                        float *wsum_alpha, float *sigma);
#endif

void gi__cone_march(const struct gi_cascade *c, const float o[3], const float w[3], float tan_half, float t0,
                    float step, float ao_lambda, float h0, const float *n, gi_cone_out *out) {
#ifdef GI_HAVE_V3_BUILD
  if (gi__cpu_v3()) {
    gi__cone_march_v3(c, o, w, tan_half, t0, step, ao_lambda, h0, n, out);
    return;
  }
#endif
  gi__cone_march_base(c, o, w, tan_half, t0, step, ao_lambda, h0, n, out);
}

int gi__sample_level(const struct gi_cascade *c, int d, const float p[3], const float w[3], float prem[3],
                     float *wsum_alpha, float *sigma) {
#ifdef GI_HAVE_V3_BUILD
  if (gi__cpu_v3()) return gi__sample_level_v3(c, d, p, w, prem, wsum_alpha, sigma);
#endif
  return gi__sample_level_base(c, d, p, w, prem, wsum_alpha, sigma);
}

#ifdef GI_HAVE_V3_BUILD
/* Batches march in eight lanes (and their taps replay so): x86-64-v3, and
 * the lanes address texels by 32-bit byte offsets, R^3 x 48 bytes. */
static int lanes_path(const struct gi_cascade *c) { return gi__cpu_v3() && c->R <= GI_MARCH_LANES_MAX_RES; }
#endif

void gi__cone_march_jobs_rec(const struct gi_cascade *c, const gi_cone_job *jobs, int count, float tan_half,
                             float step, float ao_lambda, gi_cone_out *out, gi_tap_rec *rec) {
#ifdef GI_HAVE_V3_BUILD
  if (lanes_path(c)) {
    gi__cone_march_jobs_v3(c, jobs, count, tan_half, step, ao_lambda, out, rec);
    return;
  }
#endif
  for (int i = 0; i < count; i++) {
    const gi_cone_job *j = &jobs[i];
    gi__cone_march_rec_base(c, j->o, j->w, tan_half, j->t0, step, ao_lambda, j->h0, j->h0 >= 0 ? j->n : NULL,
                            &out[i], rec, (uint16_t)i);
  }
}

void gi__cone_march_jobs(const struct gi_cascade *c, const gi_cone_job *jobs, int count, float tan_half,
                         float step, float ao_lambda, gi_cone_out *out) {
  gi__cone_march_jobs_rec(c, jobs, count, tan_half, step, ao_lambda, out, NULL);
}

size_t gi__replay_tape(const struct gi_cascade *c, const gi_tape_unit *u, size_t units, float L[][3],
                       uint16_t *job) {
#ifdef GI_HAVE_V3_BUILD
  /* The path gi__cone_march_jobs_rec took: its arithmetic is the replay's. */
  if (lanes_path(c)) return gi__replay_tape_lanes(c, u, units, L, job);
#endif
  return gi__replay_tape_base(c, u, units, L, job);
}
