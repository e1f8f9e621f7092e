/* layout.c: gi_lightmap_layout (options, then charts and packing) and the
 * lightmap's accessors and teardown. */
#include <stdlib.h>
#include <string.h>
#include "base/internal.h"
#include "lightmap/lightmap_internal.h"

#define GI_LM_DEFAULT_TEXEL 0.25
#define GI_LM_DEFAULT_ATLAS 2048
#define GI_LM_DEFAULT_GUTTER 2
#define GI_LM_DEFAULT_SUPERSAMPLE 2

static void free_atlas(gi_lm_atlas *a) {
  float *f[] = {a->radiance, a->irradiance, a->direct, a->indirect, a->point, a->normal, a->valid};
  for (size_t i = 0; i < sizeof f / sizeof f[0]; i++) gi__free(f[i]);
  gi__free(a->chart);
}

void gi_lightmap_free(gi_lightmap *lm) {
  if (!lm) return;
  for (size_t i = 0; lm->charts && i < lm->num_charts; i++) {
    gi__free(lm->charts[i].bin_start);
    gi__free(lm->charts[i].bin_tri);
  }
  for (size_t i = 0; lm->atlases && i < lm->num_atlases; i++) free_atlas(&lm->atlases[i]);
  gi__free(lm->atlases);
  gi__free(lm->charts);
  gi__free(lm->tri);
  gi__free(lm->uv);
  gi_scene_release(lm->scene);
  gi__free(lm);
}

/* Defaults and ranges; the region turned local and checked against the scene. */
static gi_result resolve(const gi_scene *s, const gi_lightmap_opts *in, gi_lightmap_opts *o, float lo[3], float hi[3],
                         gi_error_info *err) {
  *o = in ? *in : (gi_lightmap_opts){0};
  if (o->texel == 0) o->texel = GI_LM_DEFAULT_TEXEL;
  if (o->atlas == 0) o->atlas = GI_LM_DEFAULT_ATLAS;
  if (o->gutter == 0) o->gutter = GI_LM_DEFAULT_GUTTER;
  if (o->supersample == 0) o->supersample = GI_LM_DEFAULT_SUPERSAMPLE;
  if (!(o->texel > 0) || !isfinite(o->texel))
    return gi__fail(err, GI_ERR_INVALID_ARG, "lightmap: texel must be a finite size > 0, got %g", o->texel);
  if (o->atlas < GI_LIGHTMAP_MIN_ATLAS || o->atlas > GI_LIGHTMAP_MAX_ATLAS)
    return gi__fail(err, GI_ERR_INVALID_ARG, "lightmap: atlas must be %d..%d texels, got %d", GI_LIGHTMAP_MIN_ATLAS,
                    GI_LIGHTMAP_MAX_ATLAS, o->atlas);
  if (o->gutter < 1 || o->gutter > GI_LIGHTMAP_MAX_GUTTER)
    return gi__fail(err, GI_ERR_INVALID_ARG, "lightmap: gutter must be 1..%d texels, got %d", GI_LIGHTMAP_MAX_GUTTER,
                    o->gutter);
  if (o->supersample < 1 || o->supersample > GI_LIGHTMAP_MAX_SUPERSAMPLE)
    return gi__fail(err, GI_ERR_INVALID_ARG, "lightmap: supersample must be 1..%d, got %d",
                    GI_LIGHTMAP_MAX_SUPERSAMPLE, o->supersample);
  if (o->scene_uv != 0 && o->scene_uv != -1)
    return gi__fail(err, GI_ERR_INVALID_ARG, "lightmap: scene_uv must be 0 or -1, got %d", o->scene_uv);
  if (o->tile < 0 || !isfinite(o->tile))
    return gi__fail(err, GI_ERR_INVALID_ARG, "lightmap: tile must be a finite size >= 0 (0 = default), got %g", o->tile);
  for (int k = 0; k < 3; k++) lo[k] = s->lo[k], hi[k] = s->hi[k];
  if (!o->have_region) return GI_OK;
  for (int k = 0; k < 3; k++)
    if (!isfinite(o->region_lo[k]) || !isfinite(o->region_hi[k]) || !(o->region_lo[k] < o->region_hi[k]))
      return gi__fail(err, GI_ERR_INVALID_ARG,
                      "lightmap: region must be finite with min < max on every axis (axis %d: %g .. %g)", k,
                      o->region_lo[k], o->region_hi[k]);
  double wlo[3], whi[3];
  gi_scene_bounds(s, wlo, whi);
  for (int k = 0; k < 3; k++) {
    if (o->region_hi[k] < wlo[k] || o->region_lo[k] > whi[k])
      return gi__fail(err, GI_ERR_INVALID_ARG,
                      "lightmap: region %g,%g,%g .. %g,%g,%g lies outside the scene bounds %g,%g,%g .. %g,%g,%g",
                      o->region_lo[0], o->region_lo[1], o->region_lo[2], o->region_hi[0], o->region_hi[1],
                      o->region_hi[2], wlo[0], wlo[1], wlo[2], whi[0], whi[1], whi[2]);
    lo[k] = (float)(fmax(o->region_lo[k], wlo[k]) - s->origin[k]);
    hi[k] = (float)(fmin(o->region_hi[k], whi[k]) - s->origin[k]);
  }
  return GI_OK;
}

gi_result gi_lightmap_layout(const gi_scene *scene, const gi_lightmap_opts *opts, gi_lightmap **out,
                             gi_error_info *err) {
  if (!out) return gi__fail(err, GI_ERR_INVALID_ARG, "lightmap: out is NULL");
  *out = NULL;
  if (!scene) return gi__fail(err, GI_ERR_INVALID_ARG, "lightmap: scene is NULL");
  double t0 = gi__now_ms();
  gi_lightmap *lm = gi__calloc(1, sizeof *lm);
  if (!lm) return gi__fail(err, GI_ERR_NOMEM, "lightmap: out of memory");
  lm->scene = gi_scene_retain((gi_scene *)scene);
  gi_result rc = resolve(scene, opts, &lm->opts, lm->lo, lm->hi, err);
  if (rc == GI_OK && scene->num_triangles == 0)
    rc = gi__fail(err, GI_ERR_INVALID_ARG, "lightmap: the scene has no triangles");
  lm->scene_uv = scene->uv2 && lm->opts.scene_uv == 0;
  if (rc == GI_OK) rc = gi__lm_charts(lm, err);
  if (rc == GI_OK) rc = gi__lm_pack(lm, err);
  if (rc != GI_OK) {
    gi_lightmap_free(lm);
    return rc;
  }
  lm->layout_ms = gi__now_ms() - t0;
  *out = lm;
  return GI_OK;
}

size_t gi_lightmap_num_atlases(const gi_lightmap *lm) { return lm ? lm->num_atlases : 0; }

int gi_lightmap_get_atlas(const gi_lightmap *lm, size_t i, gi_lightmap_atlas *out) {
  if (!lm || !out || i >= lm->num_atlases) return -1;
  const gi_lm_atlas *a = &lm->atlases[i];
  *out = (gi_lightmap_atlas){a->w, a->h, a->radiance, a->irradiance, a->direct, a->indirect, a->valid, a->chart,
                             a->point, a->normal};
  return 0;
}

void gi_lightmap_origin(const gi_lightmap *lm, double origin[3]) {
  for (int k = 0; k < 3; k++) origin[k] = lm ? lm->scene->origin[k] : 0;
}

size_t gi_lightmap_num_charts(const gi_lightmap *lm) { return lm ? lm->num_charts : 0; }

int gi_lightmap_get_chart(const gi_lightmap *lm, size_t i, gi_lightmap_chart *out) {
  if (!lm || !out || i >= lm->num_charts) return -1;
  *out = lm->charts[i].pub;
  return 0;
}

size_t gi_lightmap_num_triangles(const gi_lightmap *lm) { return lm ? lm->num_tris : 0; }

int gi_lightmap_triangle(const gi_lightmap *lm, size_t i, uint32_t *tri, float uv[6], float xyz[9], int *chart) {
  if (!lm || i >= lm->num_tris) return -1;
  const gi_scene *s = lm->scene;
  if (tri) *tri = lm->tri[i];
  /* Charts hold contiguous triangle ranges: binary search by first. */
  size_t lo = 0, hi = lm->num_charts;
  while (hi - lo > 1) {
    size_t mid = (lo + hi) / 2;
    if (lm->charts[mid].pub.first <= i) lo = mid;
    else hi = mid;
  }
  const gi_lm_atlas *a = &lm->atlases[lm->charts[lo].pub.atlas];
  if (chart) *chart = (int)lo;
  for (int j = 0; j < 3; j++) {
    if (uv) uv[2 * j] = lm->uv[6 * i + 2 * j] / (float)a->w, uv[2 * j + 1] = lm->uv[6 * i + 2 * j + 1] / (float)a->h;
    if (xyz) memcpy(xyz + 3 * j, s->vertices + 3 * (size_t)s->indices[3 * (size_t)lm->tri[i] + j], 3 * sizeof(float));
  }
  return 0;
}
