/* output.c: the lightmap atlases as multilayer EXR (through io/exr_io.c).
 *
 * Each atlas is one file, written under a temporary name and renamed by
 * gi_exr_write. Several atlases are numbered (out.0001.exr ...); when one
 * of them fails, those already written are removed, so a failed run leaves
 * either every atlas or none. Planar channels are split out of the
 * interleaved RGB arrays one channel at a time. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "base/internal.h"
#include "gi/gi_exr.h"
#include "lightmap/lightmap_internal.h"

#define LM_CHANNELS 13

int gi_lightmap_atlas_path(const gi_lightmap *lm, const char *path, size_t i, char *buf, size_t cap) {
  if (!lm || !path || !buf || i >= lm->num_atlases) return -1;
  if (lm->num_atlases == 1) {
    /* Compared as size_t: (int)cap was negative for a cap past INT_MAX. */
    int n = snprintf(buf, cap, "%s", path);
    return n >= 0 && (size_t)n < cap ? 0 : -1;
  }
  const char *dot = strrchr(path, '.'), *slash = strrchr(path, '/');
  size_t stem = dot && (!slash || dot > slash) ? (size_t)(dot - path) : strlen(path);
  int n = snprintf(buf, cap, "%.*s.%04zu%s", (int)stem, path, i + 1, path + stem);
  return n >= 0 && (size_t)n < cap ? 0 : -1;
}

/* Planar copies of the atlas's channels, in file order. */
static float *planar(const gi_lm_atlas *a, gi_exr_channel ch[LM_CHANNELS]) {
  static const char *names[LM_CHANNELS] = {"R", "G", "B", "irradiance.R", "irradiance.G", "irradiance.B",
                                            "direct.R", "direct.G", "direct.B", "indirect.R", "indirect.G",
                                            "indirect.B", "valid.Y"};
  size_t n = (size_t)a->w * a->h;
  float *buf = gi__malloc(LM_CHANNELS * n * sizeof *buf);
  if (!buf) return NULL;
  const float *src[4] = {a->radiance, a->irradiance, a->direct, a->indirect};
  for (int c = 0; c < LM_CHANNELS; c++) {
    float *d = buf + (size_t)c * n;
    if (c < 12)
      for (size_t i = 0; i < n; i++) d[i] = src[c / 3][3 * i + c % 3];
    else
      memcpy(d, a->valid, n * sizeof *d);
    ch[c].name = names[c];
    ch[c].data = d;
  }
  return buf;
}

static gi_result write_one(const gi_lightmap *lm, size_t i, const char *file, int half, gi_error_info *err) {
  const gi_lm_atlas *a = &lm->atlases[i];
  gi_exr_channel ch[LM_CHANNELS];
  float *buf = planar(a, ch);
  if (!buf) return gi__fail(err, GI_ERR_NOMEM, "lightmap: out of memory writing '%s'", file);
  char texel[32], idx[32], count[32];
  snprintf(texel, sizeof texel, "%.9g", lm->opts.texel);
  snprintf(idx, sizeof idx, "%zu", i + 1);
  snprintf(count, sizeof count, "%zu", lm->num_atlases);
  gi_exr_attr attrs[] = {{"gi.kind", "lightmap"}, {"gi.scene", lm->scene->name}, {"gi.texel", texel},
                         {"gi.atlas", idx}, {"gi.atlases", count}};
  gi_exr_image img = {.width = a->w, .height = a->h, .use_half = half, .compression = GI_EXR_ZIP,
                      .num_channels = LM_CHANNELS, .channels = ch, .num_attrs = sizeof attrs / sizeof attrs[0],
                      .attrs = attrs};
  gi_result rc = gi_exr_write(file, &img, err);
  gi__free(buf);
  return rc;
}

gi_result gi_lightmap_write_exr(const gi_lightmap *lm, const char *path, int half, gi_error_info *err) {
  if (!lm || !path || !*path)
    return gi__fail(err, GI_ERR_INVALID_ARG, "lightmap: %s",
                    !lm ? "lm is NULL" : !path ? "path is NULL" : "path is empty");
  char file[4096];
  gi_result rc = GI_OK;
  size_t i = 0;
  for (; i < lm->num_atlases; i++) {
    if (gi_lightmap_atlas_path(lm, path, i, file, sizeof file)) {
      rc = gi__fail(err, GI_ERR_INVALID_ARG, "lightmap: path '%s' is too long", path);
      break;
    }
    if ((rc = write_one(lm, i, file, half, err)) != GI_OK) break;
  }
  if (rc != GI_OK)
    while (i-- > 0)
      if (!gi_lightmap_atlas_path(lm, path, i, file, sizeof file)) remove(file);
  return rc;
}
