/* panorama.c: a lat-long view of the light arriving at one point.
 *
 * Each pixel is split as the probes are: what a primary ray sees of light
 * sources directly (the front of an emitter, or the sky when it escapes)
 * and what surfaces reflect toward the point, which one cone per pixel
 * gathers from the cascade (a row's cones march as one batch). The cone's aperture is the pixel's angular
 * size, so the image is as sharp as the texture allows and no sharper.
 * The sun is a delta light: no finite pixel shows it, and its light
 * reaches the image only through the surfaces it lights. The eye takes
 * the probes' nearest-surface rule (answer.h): 1 cm from a sunlit wall's
 * shaded side its panorama read 21% off the path tracer's, 10% with it. */
#include <stdlib.h>
#include <string.h>
#include "answer/answer.h"
#include "base/internal.h"
#include "plan.h"
#include "scene/lights.h"
#include "trace/trace.h"

/* A row's cones march together, in the lanes of gi__cone_march_jobs
 * (one cone at a time kept 7 of 8 lanes idle). */
#define PANO_BATCH 256

typedef struct {
  const struct gi_cascade *c;
  const float *at;
  int w, h;
  float sky[3];
  float *direct, *indirect;
  gi_near_surface near; /* the eye's nearest surface (answer.h) */
} pano_ctx;

static void pixel_dir(int up_z, int w, int h, int x, int y, float out[3]) {
  float th = GI_PI_F * ((float)y + 0.5f) / (float)h, ph = 2 * GI_PI_F * ((float)x + 0.5f) / (float)w;
  float st = sinf(th), ct = cosf(th);
  if (up_z) {
    out[0] = st * cosf(ph), out[1] = st * sinf(ph), out[2] = ct;
  } else {
    out[0] = st * cosf(ph), out[1] = ct, out[2] = st * sinf(ph);
  }
}

static void pano_rows(void *p, size_t b, size_t e, int worker) {
  pano_ctx *pc = p;
  const struct gi_cascade *c = pc->c;
  const gi_scene *s = c->scene;
  int up_z = s->up == GI_UP_Z;
  /* The eye is a point in space: the gather's free-space rule. */
  gi_gather_start g;
  int inside = gi__gather_start(c, pc->at, NULL, GI_GATHER_FREE, -1, &g);
  /* Half the pixel's angular height: neighbouring cones just touch. */
  float tan_half = tanf(0.5f * GI_PI_F / (float)pc->h);
  /* Primary rays skip hits closer than the shadow rule's offset, as a
   * probe's shadow rays from the same point do. */
  float eps = gi__shadow_offset(gi__voxel_at(c, pc->at));
  /* Every cone starts at the eye, but for the eye's nearest surface's
   * rule, which moves some starts and answers some cones itself. */
  gi_cone_job jobs[PANO_BATCH];
  gi_cone_out co[PANO_BATCH];
  uint8_t done[PANO_BATCH];
  for (size_t y = b; y < e; y++)
    for (int x0 = 0; x0 < pc->w; x0 += PANO_BATCH) {
      int m = pc->w - x0 < PANO_BATCH ? pc->w - x0 : PANO_BATCH;
      for (int j = 0; j < m; j++) {
        memcpy(jobs[j].o, g.o, sizeof g.o);
        memcpy(jobs[j].n, g.n, sizeof g.n);
        jobs[j].t0 = g.t0, jobs[j].h0 = g.h0;
        done[j] = 0;
        size_t i = 3 * ((size_t)y * (size_t)pc->w + (size_t)(x0 + j));
        float *w = jobs[j].w, th, ng[3];
        uint32_t tri;
        pixel_dir(up_z, pc->w, pc->h, x0 + j, (int)y, w);
        float *D = &pc->direct[i];
        D[0] = D[1] = D[2] = 0;
        if (gi__intersect1(s, pc->at, w, eps, INFINITY, &th, &tri, ng)) {
          /* Emitters face their winding normal (both ways when two-sided). */
          const float *Le = s->materials[s->tri_material[tri]].emission;
          if (gi__emitter_cos(s, tri, -gi__dot(ng, w)) > 0 && c->report.effects[GI_FX_EMISSIVE].ran)
            for (int k = 0; k < 3; k++) D[k] = Le[k];
        } else {
          for (int k = 0; k < 3; k++) D[k] = pc->sky[k];
        }
      }
      if (inside) {
        gi__near_surface_rule(c, &pc->near, jobs, m, done, co);
        gi__cone_march_rest(c, jobs, done, m, tan_half, g.step, g.ao_lambda, co);
      } else {
        memset(co, 0, (size_t)m * sizeof co[0]);
      }
      for (int j = 0; j < m; j++)
        memcpy(&pc->indirect[3 * ((size_t)y * (size_t)pc->w + (size_t)(x0 + j))], co[j].L, sizeof co[j].L);
    }
}

gi_result gi_cascade_panorama(const gi_cascade *c, const double at[3], int w, int h, float *direct,
                              float *indirect, double *ms, gi_error_info *err) {
  return gi_cascade_panorama_ex(c, at, w, h, NULL, direct, indirect, ms, err);
}

gi_result gi_cascade_panorama_ex(const gi_cascade *c, const double at[3], int w, int h, const gi_cancel *cancel,
                                 float *direct, float *indirect, double *ms, gi_error_info *err) {
  if (!c || !at || !direct || !indirect)
    return gi__fail(err, GI_ERR_INVALID_ARG, "panorama: %s is NULL",
                    !c ? "cascade" : !at ? "viewpoint" : !direct ? "direct" : "indirect");
  if (gi__cascade_whole(c, "panorama", err) != GI_OK) return GI_ERR_INVALID_ARG;
  if (w < 2 || h < 1 || w > 16384 || h > 8192)
    return gi__fail(err, GI_ERR_INVALID_ARG, "panorama: size %dx%d outside 2..16384 x 1..8192", w, h);
  float p[3];
  for (int a = 0; a < 3; a++) {
    if (!isfinite(at[a])) return gi__fail(err, GI_ERR_NONFINITE, "panorama: viewpoint is not finite");
    p[a] = (float)(at[a] - c->scene->origin[a]);
    if (!isfinite(p[a]) || fabs(at[a] - c->scene->origin[a]) > GI_MAX_VIEW_DISTANCE)
      return gi__fail(err, GI_ERR_INVALID_ARG,
                      "panorama: viewpoint is more than " GI_MAX_VIEW_DISTANCE_TEXT
                      " units from the scene's origin on axis %c (%g)", "xyz"[a], fabs(at[a] - c->scene->origin[a]));
  }
  double t0 = gi__now_ms();
  pano_ctx pc = {.c = c, .at = p, .w = w, .h = h, .direct = direct, .indirect = indirect,
                 .near = gi__near_surface(c, p)};
  if (gi__answer_sky(c->scene, &c->report)) gi__sky_radiance(c->scene, pc.sky);
  /* Checked between rows: a row of the largest panorama is a few ms of cones. */
  if (gi__parallel_for_cancel((size_t)h, 1, c->report.quality.threads, pano_rows, &pc, NULL, cancel))
    return gi__cancel_fail(cancel, err, "panorama");
  if (ms) *ms = gi__now_ms() - t0;
  return GI_OK;
}
