/* pack.c: charts into atlases.
 *
 * Design: shelf packing, tallest charts first (ties: wider, then lower
 * chart number, so the result is deterministic). Each chart's rectangle
 * carries `gutter` texels on every side, so two charts are at least twice
 * the gutter apart and the gutter can be dilated without reaching another
 * chart. A chart that does not fit on the current atlas opens the next
 * one; a chart larger than an atlas is an error that names its size. The
 * atlases are atlas texels wide and as tall as their shelves (rounded up
 * to a multiple of 4), so a small region does not cost a full atlas. */
#include <stdlib.h>
#include <string.h>
#include "base/internal.h"
#include "lightmap/lightmap_internal.h"

/* Texels around a triangle in which a texel still takes its nearest point
 * (bake.c): the bins must list the triangle there too. */
#define GI_LM_BIN_MARGIN 1.5f
/* Atlas heights are rounded up to this many texels (block-compressed formats). */
#define GI_LM_HEIGHT_ALIGN 4

typedef struct {
  int w, h;
  uint32_t id;
} pack_key;

static int cmp_key(const void *pa, const void *pb) {
  const pack_key *a = pa, *b = pb;
  if (a->h != b->h) return a->h > b->h ? -1 : 1;
  if (a->w != b->w) return a->w > b->w ? -1 : 1;
  return a->id < b->id ? -1 : a->id > b->id;
}

/* Shelf placement; fills each chart's atlas, x, y, w, h and the atlas count. */
static gi_result place(struct gi_lightmap *lm, pack_key *keys, int *heights, gi_error_info *err) {
  int N = lm->opts.atlas, atlas = 0, x = 0, y = 0, shelf = 0;
  for (size_t i = 0; i < lm->num_charts; i++) {
    pack_key *k = &keys[i];
    if (x + k->w > N) x = 0, y += shelf, shelf = 0;
    if (y + k->h > N) {
      heights[atlas] = y;
      if (++atlas >= GI_LIGHTMAP_MAX_ATLASES)
        return gi__fail(err, GI_ERR_INVALID_ARG,
                        "lightmap: more than %d atlases of %d texels would be needed: raise atlas or texel",
                        GI_LIGHTMAP_MAX_ATLASES, N);
      x = y = shelf = 0;
    }
    gi_lightmap_chart *c = &lm->charts[k->id].pub;
    c->atlas = atlas, c->x = x, c->y = y, c->w = k->w, c->h = k->h;
    x += k->w;
    if (k->h > shelf) shelf = k->h;
  }
  heights[atlas] = y + shelf;
  lm->num_atlases = (size_t)atlas + 1;
  return GI_OK;
}

/* Chart c's grid of bins: each lists the triangles whose texel box, grown
 * by the margin, touches it. */
static gi_result bin_chart(struct gi_lightmap *lm, gi_lm_chart *c, gi_error_info *err) {
  int bx = (c->pub.w + GI_LM_BIN - 1) / GI_LM_BIN, by = (c->pub.h + GI_LM_BIN - 1) / GI_LM_BIN;
  size_t nb = (size_t)bx * by;
  c->bins_x = bx, c->bins_y = by;
  c->bin_start = gi__calloc(nb + 1, sizeof *c->bin_start);
  if (!c->bin_start) return gi__fail(err, GI_ERR_NOMEM, "lightmap: out of memory for chart bins");
  for (int pass = 0; pass < 2; pass++) {
    uint32_t *fill = NULL;
    if (pass == 1) {
      for (size_t i = 0; i < nb; i++) c->bin_start[i + 1] += c->bin_start[i];
      c->bin_tri = gi__malloc((c->bin_start[nb] ? c->bin_start[nb] : 1) * sizeof *c->bin_tri);
      fill = gi__calloc(nb, sizeof *fill);
      if (!c->bin_tri || !fill) {
        gi__free(fill);
        return gi__fail(err, GI_ERR_NOMEM, "lightmap: out of memory for chart bins");
      }
    }
    for (size_t t = c->pub.first; t < c->pub.first + c->pub.count; t++) {
      const float *uv = lm->uv + 6 * t;
      float lo[2] = {INFINITY, INFINITY}, hi[2] = {-INFINITY, -INFINITY};
      for (int j = 0; j < 3; j++)
        for (int a = 0; a < 2; a++) lo[a] = fminf(lo[a], uv[2 * j + a]), hi[a] = fmaxf(hi[a], uv[2 * j + a]);
      int x0 = (int)floorf((lo[0] - GI_LM_BIN_MARGIN - (float)c->pub.x) / GI_LM_BIN);
      int x1 = (int)floorf((hi[0] + GI_LM_BIN_MARGIN - (float)c->pub.x) / GI_LM_BIN);
      int y0 = (int)floorf((lo[1] - GI_LM_BIN_MARGIN - (float)c->pub.y) / GI_LM_BIN);
      int y1 = (int)floorf((hi[1] + GI_LM_BIN_MARGIN - (float)c->pub.y) / GI_LM_BIN);
      for (int y = y0 < 0 ? 0 : y0; y <= y1 && y < by; y++)
        for (int x = x0 < 0 ? 0 : x0; x <= x1 && x < bx; x++) {
          size_t b = (size_t)y * bx + x;
          if (pass == 0) c->bin_start[b + 1]++;
          else c->bin_tri[c->bin_start[b] + fill[b]++] = (uint32_t)t;
        }
    }
    gi__free(fill);
  }
  return GI_OK;
}

static gi_result alloc_atlas(gi_lm_atlas *a, int w, int h, gi_error_info *err) {
  size_t n = (size_t)w * h;
  a->w = w, a->h = h;
  float **rgb[] = {&a->radiance, &a->irradiance, &a->direct, &a->indirect, &a->point, &a->normal};
  for (size_t i = 0; i < sizeof rgb / sizeof rgb[0]; i++)
    if (!(*rgb[i] = gi__calloc(3 * n, sizeof(float)))) goto oom;
  if (!(a->valid = gi__calloc(n, sizeof(float))) || !(a->chart = gi__malloc(n * sizeof *a->chart))) goto oom;
  for (size_t i = 0; i < n; i++) a->chart[i] = -1;
  return GI_OK;
oom:
  return gi__fail(err, GI_ERR_NOMEM, "lightmap: out of memory for a %d x %d atlas", w, h);
}

uint64_t gi_lightmap_peak_bytes(uint64_t texels, uint64_t largest) {
  uint64_t sort = 24 * texels, fill = 20 * texels + 20 * largest, write = 52 * largest;
  uint64_t work = sort > fill ? sort : fill;
  return 80 * texels + (work > write ? work : write);
}

/* The caller's bound, checked before the atlases are allocated (a 36 GB
 * layout on a 24 GiB machine ran 100 s into swap before). */
static gi_result check_bytes(const struct gi_lightmap *lm, const int *heights, size_t n, gi_error_info *err) {
  uint64_t texels = 0, largest = 0, N = (uint64_t)lm->opts.atlas;
  for (size_t a = 0; a < n; a++) {
    uint64_t t = N * (uint64_t)heights[a];
    texels += t;
    largest = t > largest ? t : largest;
  }
  uint64_t need = gi_lightmap_peak_bytes(texels, largest), max = lm->opts.max_bytes;
  if (!max || need <= max) return GI_OK;
  return gi__fail(err, GI_ERR_LIMIT, "lightmap: %zu atlas%s of %llu texels (%llu in all) need about %.1f GiB "
                  "(%llu bytes) to bake and write, more than the %.1f GiB (%llu bytes) allowed", n,
                  n == 1 ? "" : "es", (unsigned long long)N, (unsigned long long)texels, need / 1073741824.0,
                  (unsigned long long)need, max / 1073741824.0, (unsigned long long)max);
}

/* Chart-local uv to atlas texel units (texel j's centre at j + 0.5), and
 * the owner map over each chart's rectangle. */
static void to_atlas(struct gi_lightmap *lm) {
  int g = lm->opts.gutter;
  for (size_t ci = 0; ci < lm->num_charts; ci++) {
    gi_lightmap_chart *c = &lm->charts[ci].pub;
    for (size_t t = c->first; t < c->first + c->count; t++)
      for (int j = 0; j < 3; j++) {
        lm->uv[6 * t + 2 * j] += (float)(c->x + g) + 0.5f;
        lm->uv[6 * t + 2 * j + 1] += (float)(c->y + g) + 0.5f;
      }
    gi_lm_atlas *a = &lm->atlases[c->atlas];
    for (int y = c->y; y < c->y + c->h; y++)
      for (int x = c->x; x < c->x + c->w; x++) a->chart[(size_t)y * a->w + x] = (int32_t)ci;
  }
}

/* The scene's own UVs: one chart already in atlas texel units, one atlas. */
static gi_result pack_scene_uv(struct gi_lightmap *lm, gi_error_info *err) {
  int N = lm->opts.atlas;
  gi_lightmap_chart *c = &lm->charts[0].pub;
  c->atlas = 0, c->x = c->y = 0, c->w = c->h = N;
  lm->num_atlases = 1;
  gi_result rc = check_bytes(lm, &N, 1, err);
  if (rc != GI_OK) return rc;
  if (!(lm->atlases = gi__calloc(1, sizeof *lm->atlases)))
    return gi__fail(err, GI_ERR_NOMEM, "lightmap: out of memory for an atlas");
  rc = alloc_atlas(&lm->atlases[0], N, N, err);
  if (rc != GI_OK) return rc;
  for (size_t i = 0; i < (size_t)N * N; i++) lm->atlases[0].chart[i] = 0;
  return bin_chart(lm, &lm->charts[0], err);
}

gi_result gi__lm_pack(struct gi_lightmap *lm, gi_error_info *err) {
  if (lm->scene_uv) return pack_scene_uv(lm, err);
  int g = lm->opts.gutter, N = lm->opts.atlas;
  pack_key *keys = gi__malloc(lm->num_charts * sizeof *keys);
  int *heights = gi__calloc(GI_LIGHTMAP_MAX_ATLASES, sizeof *heights);
  gi_result rc = GI_OK;
  if (!keys || !heights) {
    rc = gi__fail(err, GI_ERR_NOMEM, "lightmap: out of memory packing %zu charts", lm->num_charts);
    goto done;
  }
  for (size_t i = 0; i < lm->num_charts; i++) {
    const gi_lm_chart *c = &lm->charts[i];
    keys[i] = (pack_key){c->cw + 2 * g, c->ch + 2 * g, (uint32_t)i};
    if (keys[i].w > N || keys[i].h > N) {
      double w[3];
      for (int k = 0; k < 3; k++) w[k] = lm->scene->origin[k] + c->centre[k];
      rc = gi__fail(err, GI_ERR_INVALID_ARG,
                    "lightmap: chart %zu (%d x %d texels with its gutter, centred at %.6g,%.6g,%.6g) does not fit in "
                    "an atlas of %d texels: raise atlas or texel",
                    i, keys[i].w, keys[i].h, w[0], w[1], w[2], N);
      goto done;
    }
  }
  qsort(keys, lm->num_charts, sizeof *keys, cmp_key);
  if ((rc = place(lm, keys, heights, err)) != GI_OK) goto done;
  for (size_t a = 0; a < lm->num_atlases; a++) {
    heights[a] = (heights[a] + GI_LM_HEIGHT_ALIGN - 1) / GI_LM_HEIGHT_ALIGN * GI_LM_HEIGHT_ALIGN;
    if (heights[a] > N) heights[a] = N;
  }
  if ((rc = check_bytes(lm, heights, lm->num_atlases, err)) != GI_OK) goto done;
  if (!(lm->atlases = gi__calloc(lm->num_atlases, sizeof *lm->atlases))) {
    rc = gi__fail(err, GI_ERR_NOMEM, "lightmap: out of memory for %zu atlases", lm->num_atlases);
    goto done;
  }
  for (size_t a = 0; a < lm->num_atlases && rc == GI_OK; a++) rc = alloc_atlas(&lm->atlases[a], N, heights[a], err);
  if (rc != GI_OK) goto done;
  to_atlas(lm);
  for (size_t i = 0; i < lm->num_charts && rc == GI_OK; i++) rc = bin_chart(lm, &lm->charts[i], err);
done:
  gi__free(keys);
  gi__free(heights);
  return rc;
}
