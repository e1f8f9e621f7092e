/* gi_lightmap.h: bake a scene's diffuse lighting into texture atlases.
 *
 * Two steps. gi_lightmap_layout gives every triangle of a region lightmap
 * UVs, the scene's own when it has them (a glTF's TEXCOORD_1, a second UV
 * channel), else new ones: triangles are grouped into charts (edge-connected, near coplanar:
 * a building's wall is one chart), each chart is projected onto its plane
 * at a texel density given in world units, and the charts are packed
 * (shelves, a gutter around each) into one or more atlases as wide as
 * gi_lightmap_opts.atlas and as tall as their shelves need (rounded up to
 * a multiple of 4: gi_lightmap_get_atlas gives each one's size). The
 * layout depends only on the scene and the options: the same inputs give
 * the same charts, bit for bit. gi_lightmap_bake then fills every texel
 * with the irradiance at its surface point and normal, gathered from a
 * cascade exactly as the probes gather (direct light by shadow rays,
 * indirect light by the cascade's cones), averaged over the texel's
 * footprint. The region is baked tile by tile, one cascade per tile, so
 * the bake's cascade memory stays bounded by one cascade whatever the
 * region's size; a texel belongs to the tile holding its surface point (a
 * chart may span many). The atlases themselves are held whole, 80 bytes per
 * atlas texel (its radiance, irradiance, direct and indirect light, surface
 * point and normal, valid, chart): they grow with the region's surface
 * over texel^2 (a 4096^2 atlas is 1.25 GiB; the procedural city's whole
 * surface at texel 0.25 reached 2.4 GB in its first 150 s). Bake large regions in
 * parts (gi-bake --region, the server's region).
 *
 * Texels whose surface point lies inside other geometry (a floor under a
 * box) are marked invalid and filled from their neighbours in the same
 * chart; the gutter around each chart is filled the same way (dilation),
 * so bilinear filtering never reads black at a chart's edge.
 *
 * Ownership: the caller owns a gi_lightmap until gi_lightmap_free. The
 * lightmap retains its scene until it is freed. Pointers in a
 * gi_lightmap_atlas or gi_lightmap_chart live as long as the lightmap and
 * change only during gi_lightmap_bake.
 * Thread-safety: gi_lightmap_layout reads the scene only (any number may
 * run at once); gi_lightmap_bake writes its lightmap, so one bake per
 * lightmap at a time, and no reader may run during it. Once baked, every
 * reader (atlas, chart, triangle accessors, the writers) may run at once.
 *
 * Units: texel in world units; irradiance in the scene's radiometric unit
 * (W m^-2 for physical inputs); radiance = albedo x irradiance / pi. */
#ifndef GI_LIGHTMAP_H
#define GI_LIGHTMAP_H

#include <stddef.h>
#include <stdint.h>
#include "gi_cancel.h"
#include "gi_cascade.h"
#include "gi_error.h"
#include "gi_quality.h"
#include "gi_scene.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Limits of the options below. */
#define GI_LIGHTMAP_MIN_ATLAS 16
#define GI_LIGHTMAP_MAX_ATLAS 16384
#define GI_LIGHTMAP_MAX_SUPERSAMPLE 8
#define GI_LIGHTMAP_MAX_GUTTER 16
#define GI_LIGHTMAP_MAX_ATLASES 9999

/* Zero means default for every field. */
typedef struct gi_lightmap_opts {
  double texel;        /* texel side, world units; default 0.25 */
  int atlas;           /* atlas side in texels, 16..16384; default 2048 */
  int gutter;          /* texels of padding on every side of a chart, 1..16; default 2 */
  int supersample;     /* sample points per texel side, 1..8; default 2 */
  int have_region;     /* 1: only triangles whose centre lies in [region_lo, region_hi] */
  double region_lo[3], region_hi[3]; /* world box; default: the whole scene */
  double tile;         /* tile side, world units; default 0.8 x the coarsest cascade level, smaller
                          until every tile's cascade holds its texels; a tile given whose cascade
                          cannot hold them is refused, one larger than the region is one tile) */
  int scene_uv;        /* 0: bake into the scene's own lightmap UVs when it has them
                          (gi_scene_has_lightmap_uv: one atlas of `atlas` texels, one chart,
                          texel unused: the layout takes the mean world side of a texel of
                          those UVs, the EXR's gi.texel); -1: always make charts */
  size_t max_bytes;    /* 0: no bound; else a layout whose atlases would take more than this many
                          bytes to bake and write (gi_lightmap_peak_bytes) is refused with
                          GI_ERR_LIMIT and the figures, before any atlas is allocated */
} gi_lightmap_opts;

/* The bytes a lightmap's atlases take at their peak, texels of all
 * atlases and `largest` of the largest one: 80 per texel held, plus the
 * more of the bake's sorting and filling (24 per texel, or 20 plus 20 per
 * texel of the atlas being filled) and the EXR writer's planar copy of the
 * atlas being written (52 per texel). One tile's cascade and the scene
 * come on top. */
uint64_t gi_lightmap_peak_bytes(uint64_t texels, uint64_t largest);

typedef struct gi_lightmap gi_lightmap;

/* What a layout and a bake did. */
typedef struct gi_lightmap_report {
  size_t triangles, charts, atlases;
  uint64_t texels;           /* texels inside chart rectangles (gutters included) */
  uint64_t texels_valid;     /* texels whose own surface was gathered */
  uint64_t texels_filled;    /* texels filled from neighbours (invalid or gutter) */
  int tiles;                 /* cascades baked */
  double layout_ms, bake_ms, cascade_ms, gather_ms, fill_ms;
  /* The bake by stage, as a cascade bake reports it: voxelize, inject,
   * filter and bounce summed over the tiles' cascades, gather the texels'
   * gathers and the fill from neighbours; encode 0 (the caller writes). */
  gi_timings ms;
  /* The bake's own share of the layout: the texels sorted into tiles
   * (again for each smaller default tile tried).
   * With layout_ms it is the layout stage. */
  double sort_ms;
  /* The tiles' effect plans: effects[i].ran when any tile ran effect i,
   * its why that of the first tile that ran it (else of the first tile),
   * effect_tiles[i] how many tiles ran it. */
  gi_effect effects[GI_FX_COUNT];
  int effect_tiles[GI_FX_COUNT];
} gi_lightmap_report;

/* Charts and packing for the triangles of opts' region. Fails with
 * GI_ERR_INVALID_ARG naming the option when an option is out of range,
 * the region is empty or holds no triangle, or one chart is larger than
 * the atlas (then the message gives the chart's size in texels); with
 * GI_ERR_LIMIT when the atlases would take more than opts' max_bytes. */
gi_result gi_lightmap_layout(const gi_scene *scene, const gi_lightmap_opts *opts, gi_lightmap **out,
                             gi_error_info *err);
/* Bakes every texel with quality q (may be NULL: defaults; `threads` and
 * `seed` are honoured), checking cancel (may be NULL) between texels.
 * report (may be NULL) receives counts and timings. A bad quality, one
 * cutting the region into too many tiles, or a tile whose cascade would
 * leave some of its texels outside every level (GI_ERR_INVALID_ARG: their
 * indirect light would be 0) leaves the lightmap as it was;
 * a bake that fails after it started (cancelled included) leaves every
 * atlas zero, as before any bake, never part of one. */
gi_result gi_lightmap_bake(gi_lightmap *lm, const gi_quality *q, const gi_cancel *cancel,
                           gi_lightmap_report *report, gi_error_info *err);
void gi_lightmap_free(gi_lightmap *lm); /* accepts NULL */

/* One atlas. Arrays are row-major with row 0 at v = 0 (the top of the
 * image, as glTF's TEXCOORD and EXR's first scanline). RGB arrays hold 3
 * floats per texel. All zero before gi_lightmap_bake. */
typedef struct gi_lightmap_atlas {
  int width, height;
  const float *radiance;     /* albedo x irradiance / pi: what an emission shader shows */
  const float *irradiance, *direct, *indirect;
  const float *valid;        /* 1: gathered at the texel's own surface; 0: filled or empty */
  const int32_t *chart;      /* the chart owning each texel, -1 for none */
  const float *point;        /* 3 per texel: mean surface point, local to gi_lightmap_origin */
  const float *normal;       /* 3 per texel: the side that was gathered (unit; 0 when not valid) */
} gi_lightmap_atlas;

size_t gi_lightmap_num_atlases(const gi_lightmap *lm);
/* 0 and *out filled, or -1 when i is out of range. */
int gi_lightmap_get_atlas(const gi_lightmap *lm, size_t i, gi_lightmap_atlas *out);
/* World position of local (0,0,0) for the atlases' points. */
void gi_lightmap_origin(const gi_lightmap *lm, double origin[3]);

/* One chart's rectangle in its atlas, gutter included, in texels. */
typedef struct gi_lightmap_chart {
  int atlas, x, y, w, h;
  float normal[3];           /* the plane it was projected on */
  size_t first, count;       /* its triangles: gi_lightmap_triangle(first .. first+count-1) */
} gi_lightmap_chart;
size_t gi_lightmap_num_charts(const gi_lightmap *lm);
int gi_lightmap_get_chart(const gi_lightmap *lm, size_t i, gi_lightmap_chart *out);

/* The lightmap's triangles, chart by chart. tri: the scene triangle's
 * index; uv: the three corners' atlas coordinates in [0,1] (u right, v
 * down); xyz: the corners, local to gi_lightmap_origin. -1 when out of range. */
size_t gi_lightmap_num_triangles(const gi_lightmap *lm);
int gi_lightmap_triangle(const gi_lightmap *lm, size_t i, uint32_t *tri, float uv[6], float xyz[9],
                         int *chart);

/* Writes the atlases as multilayer EXR: R,G,B (radiance), irradiance.R/G/B,
 * direct.R/G/B, indirect.R/G/B, valid.Y. One atlas goes to path itself;
 * several go to path with ".NNNN" before its extension (out.0001.exr ...).
 * Each file is written under a temporary name and renamed; when one fails
 * the ones already written are removed. half: 1 stores HALF pixels. */
gi_result gi_lightmap_write_exr(const gi_lightmap *lm, const char *path, int half, gi_error_info *err);
/* The file name atlas i gets for path (as above) into buf; -1 when it does not fit. */
int gi_lightmap_atlas_path(const gi_lightmap *lm, const char *path, size_t i, char *buf, size_t cap);
/* Writes the lightmap's triangles as binary glTF 2.0 (path ends in .glb)
 * through assimp's exporter: one node, mesh and material per atlas, named
 * "lightmap.NNNN" after the atlas's number, under a root node translated
 * to the scene origin (positions are local to it), TEXCOORD_1 = the lightmap UVs and TEXCOORD_0 = the
 * same (the core keeps no texture UVs). Y up, as glTF defines it: a Z-up
 * scene's positions, normals and origin are turned (x, y, z) -> (x, z, -y).
 * Temporary name, then rename. */
gi_result gi_lightmap_write_gltf(const gi_lightmap *lm, const char *path, gi_error_info *err);

#ifdef __cplusplus
}
#endif
#endif
