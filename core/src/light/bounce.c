/* bounce.c: the voxel-to-voxel bounces.
 *
 * Each occupied voxel gathers indirect irradiance on each side with the
 * diffuse cone set (weights sum to pi, see trace/cones.c) by the gather's
 * surface rule (trace/gather.c: one voxel off the surface); all voxels
 * gather from the previous bounce's texture (Jacobi), then the texture is
 * reshaded and the nested regions refiltered. A closed furnace of albedo a
 * and emission Le therefore reaches Le (a + ... + a^(k+1)) reflected
 * radiance after k bounces. When the effect plan capped an automatic
 * bounce count short of what the albedo asks for, the last bounce also
 * adds the geometric tail of the orders left out (ratio measured from the
 * last two bounces); an explicit bounce count keeps the exact k-bounce sum
 * above. */
#include <stdlib.h>
#include <string.h>
#include "base/internal.h"
#include "light/light.h"
#include "trace/trace.h"

typedef struct {
  struct gi_cascade *c;
  int d;
  float (*E)[2][3]; /* per occupied voxel */
  atomic_ullong samples, cones;
} bounce_ctx;

uint64_t gi__gather_voxel(const struct gi_cascade *c, int d, uint32_t slot, float E[2][3], uint64_t *cones) {
  const gi_vgeo *g = &c->lv[d].geo[slot];
  uint64_t samples = 0;
  memset(E, 0, sizeof(float[2][3]));
  if (g->albedo[0] <= 0 && g->albedo[1] <= 0 && g->albedo[2] <= 0) return 0;
  /* Both sides' cones in one batch: the SIMD march keeps its lanes full
   * across the two hemispheres. */
  int nc = c->num_cones;
  gi_cone_job jobs[2 * GI_MAX_CONES];
  gi_cone_out co[2 * GI_MAX_CONES];
  gi_gather_start st;
  for (int sd = 0; sd < 2; sd++) {
    float n[3];
    float sg = sd ? -1.f : 1.f;
    for (int k = 0; k < 3; k++) n[k] = sg * g->normal[k];
    /* A voxel is a surface at its own level's resolution (level d is
     * given, so the start always exists). */
    gi__gather_start(c, g->centroid, n, GI_GATHER_SURFACE, d, &st);
    gi__hemisphere_jobs(c, &st, n, jobs + sd * nc);
  }
  gi__cone_march_jobs(c, jobs, 2 * nc, c->cone_tan, st.step, st.ao_lambda, co);
  for (int sd = 0; sd < 2; sd++)
    for (int ci = 0; ci < nc; ci++) {
      const gi_cone_out *o = &co[sd * nc + ci];
      float cw = c->cone_weight[ci];
      for (int k = 0; k < 3; k++) E[sd][k] += cw * o->L[k];
      samples += o->samples;
    }
  *cones += 2 * (uint64_t)nc;
  return samples;
}

static void bounce_range(void *p, size_t b, size_t e, int worker) {
  bounce_ctx *bc = p;
  const gi_level *L = &bc->c->lv[bc->d];
  uint64_t samples = 0, cones = 0;
  for (size_t q = b; q < e; q++) samples += gi__gather_voxel(bc->c, bc->d, L->occ[q], bc->E[q], &cones);
  atomic_fetch_add(&bc->samples, samples);
  atomic_fetch_add(&bc->cones, cones);
}

gi_result gi__bounce(struct gi_cascade *c, const gi_quality *q, int bounces, int tail, gi_error_info *err) {
  float(*E[GI_MAX_LEVELS])[2][3] = {0};
  gi_result rc = GI_OK;
  /* Area-weighted sums of the gathered irradiance per bounce (both sides,
   * every level's own voxels), for the tail's ratio. */
  double S[3][3] = {{0}};
  for (int d = 0; d < c->n; d++) {
    E[d] = gi__malloc(((size_t)c->lv[d].num_occ + 1) * sizeof *E[d]);
    if (!E[d]) {
      rc = gi__fail(err, GI_ERR_NOMEM, "bounce: out of memory");
      goto done;
    }
  }
  for (int it = 0; it < bounces; it++) {
    for (int d = 0; d < c->n; d++) {
      bounce_ctx bc = {.c = c, .d = d, .E = E[d]};
      atomic_init(&bc.samples, 0);
      atomic_init(&bc.cones, 0);
      int cancelled = gi__parallel_for_cancel(c->lv[d].num_occ, 16, q->threads, bounce_range, &bc, NULL, c->cancel);
      c->report.cone_samples += atomic_load(&bc.samples);
      c->report.cones_traced += atomic_load(&bc.cones);
      if (cancelled) {
        rc = gi__cancel_fail(c->cancel, err, "bounce");
        goto done;
      }
    }
    int last = it + 1 == bounces;
    /* The tail: bounce k gathers E_k = E_1 + ... (orders 2..k+1 of the
     * light leaving the voxels); its increment D_k = E_k - E_(k-1) shrinks
     * by the room's mean reflection r = D_k / D_(k-1) (area-weighted over
     * every voxel, per channel; the dominant eigenvalue of the transport
     * once the first bounces have spread the light). The orders left out
     * add D_k (r + r^2 + ...) = D_k r / (1 - r), each voxel scaled by its
     * own last increment. r is capped at 0.95 (a furnace of albedo 0.99
     * would otherwise multiply its last increment by 99). */
    double f[3] = {0, 0, 0};
    for (int k = 0; k < 3; k++) S[0][k] = S[1][k], S[1][k] = S[2][k], S[2][k] = 0;
    for (int d = 0; d < c->n; d++) {
      const gi_level *L = &c->lv[d];
      for (uint32_t i = 0; i < L->num_occ; i++) {
        double a = L->geo[L->occ[i]].area;
        for (int sd = 0; sd < 2; sd++)
          for (int k = 0; k < 3; k++) S[2][k] += a * E[d][i][sd][k];
      }
    }
    if (tail && last && it >= 1)
      for (int k = 0; k < 3; k++) {
        double dk = S[2][k] - S[1][k], dk1 = S[1][k] - S[0][k];
        double r = dk1 > 0 && dk > 0 ? dk / dk1 : 0;
        if (r > 0.95) r = 0.95;
        f[k] = r / (1 - r);
      }
    for (int d = 0; d < c->n; d++) {
      gi_level *L = &c->lv[d];
      for (uint32_t i = 0; i < L->num_occ; i++) {
        uint32_t slot = L->occ[i];
        for (int sd = 0; sd < 2; sd++)
          for (int k = 0; k < 3; k++) {
            float e = E[d][i][sd][k];
            /* side - direct is still the previous bounce's E. */
            float inc = e - (L->side[slot][sd][k] - L->direct[slot][sd][k]);
            float t = (float)f[k] * inc;
            L->side[slot][sd][k] = L->direct[slot][sd][k] + e + (t > 0 ? t : 0);
          }
      }
    }
    gi__shade_all(c);
    if (gi__cascade_filter(c, q->threads)) {
      rc = gi__cancel_fail(c->cancel, err, "bounce filter");
      goto done;
    }
    c->report.bounces_run = it + 1;
  }
done:
  for (int d = 0; d < c->n; d++) gi__free(E[d]);
  return rc;
}
