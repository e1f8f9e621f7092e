/* lightmap_internal.h: the lightmap's layout, shared by its stages
 * (uv.c charts, pack.c packing and the layout entry, bake.c texels,
 * output.c EXR, io/gltf_export.cpp glTF). Only core/src includes this. */
#ifndef GI_LIGHTMAP_INTERNAL_H
#define GI_LIGHTMAP_INTERNAL_H

#include "gi/gi_lightmap.h"
#include "scene/scene_internal.h"

/* Triangles whose normals lie within this angle of their chart's first
 * triangle join it (an OSM wall's quads are coplanar; a curved surface
 * breaks into facets of about this size). */
#define GI_LM_CHART_COS 0.97f
/* A chart's grid of triangle bins, in texels per bin side: a texel looks
 * only at the triangles of its bin, whatever the chart's size. */
#define GI_LM_BIN 8

typedef struct gi_lm_chart {
  gi_lightmap_chart pub;
  float o[3], t[3], b[3];     /* plane frame: u = (p-o).t / texel, v = (p-o).b / texel */
  float umin, vmin;           /* texel coordinates of the content's corner */
  int cw, ch;                 /* content size in texels (rect minus gutters) */
  float centre[3];            /* local centre of its bounds: which tile bakes it */
  int bins_x, bins_y;
  uint32_t *bin_start;        /* bins_x*bins_y+1 offsets into bin_tri */
  uint32_t *bin_tri;          /* triangle indices into the lightmap's list */
} gi_lm_chart;

typedef struct gi_lm_atlas {
  int w, h;
  float *radiance, *irradiance, *direct, *indirect; /* 3 per texel */
  float *valid;
  int32_t *chart;
  float *point, *normal;
} gi_lm_atlas;

struct gi_lightmap {
  gi_scene *scene;            /* retained */
  gi_lightmap_opts opts;      /* resolved */
  float lo[3], hi[3];         /* the region, local */
  int scene_uv;               /* 1: the scene's lightmap UVs, one chart covering one atlas */
  size_t num_tris;
  uint32_t *tri;              /* scene triangle per lightmap triangle, chart by chart */
  float *uv;                  /* 6 per triangle, atlas texel units (x right, y down) */
  size_t num_charts;
  gi_lm_chart *charts;
  size_t num_atlases;
  gi_lm_atlas *atlases;
  int written;                /* a bake wrote the atlases since they were last zero */
  double layout_ms;
};

/* uv.c: triangles of the region grouped into charts and projected. Fills
 * lm->tri (chart by chart), lm->charts (frame, content size, first/count)
 * and lm->uv in chart-local texel units (0..cw-1 spans the content). */
gi_result gi__lm_charts(struct gi_lightmap *lm, gi_error_info *err);
/* pack.c: places the charts (gutter included) into atlases, moves their
 * uv to atlas texel units, builds the bins and allocates the atlases. */
gi_result gi__lm_pack(struct gi_lightmap *lm, gi_error_info *err);

#endif
