/* gi_scene.h: an immutable, reference-counted scene.
 *
 * A scene is triangles, materials and lights plus one Embree BVH. It is built
 * once (from a file through assimp, or from a gi_mesh_builder) and is
 * read-only afterwards: every function taking a const gi_scene* is
 * thread-safe, so one scene serves all requests at once.
 *
 * Ownership: gi_scene_load and gi_scene_build give the caller one
 * reference; gi_scene_retain adds one, gi_scene_release drops one and the
 * last frees the scene (a baked cascade holds its own). Pointers and
 * strings returned by the accessors (gi_scene_light, gi_scene_material,
 * gi_scene_name) live as long as the scene. A gi_mesh_builder belongs to
 * one thread at a time; gi_scene_build copies what it needs from it.
 *
 * NULL: the accessors below take a NULL scene as an empty one (zeros,
 * NULL, GI_UP_Y; gi_scene_get_stats fills zeros and ignores a NULL out);
 * gi_mesh_builder_add_vertex on NULL returns UINT32_MAX. The calls that
 * return a gi_result refuse NULL with GI_ERR_INVALID_ARG.
 *
 * Precision: positions are stored as float relative to a double-precision
 * scene origin (the centre of the input's bounds), so a scene 10^7 units
 * from the world origin keeps sub-millimetre float resolution. OBJ and PLY
 * files are read in double, so this holds for them too (glTF and the other
 * assimp formats are parsed in float). Public functions take world
 * coordinates as double. */
#ifndef GI_SCENE_H
#define GI_SCENE_H

#include <stddef.h>
#include <stdint.h>
#include "gi_error.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct gi_scene gi_scene;
typedef struct gi_mesh_builder gi_mesh_builder;

/* Which world axis points up: 1 = Y (OBJ, glTF default), 2 = Z (OSM cities). */
typedef enum gi_up_axis { GI_UP_Y = 1, GI_UP_Z = 2 } gi_up_axis;

/* A surface's material. Units: albedo is reflectance in [0,1] (larger input
 * is clamped and counted); emission is radiance (W m^-2 sr^-1, or the
 * scene's own radiometric unit); roughness in [0,1] (1 = fully diffuse);
 * specular is the scalar normal-incidence reflectance of the glossy lobe
 * (used when roughness < 0.5). A scene scales a material whose brightest
 * albedo channel plus that lobe exceed 1, and its triangles' own albedos,
 * so that it reflects at most what it receives. */
typedef struct gi_material {
  float albedo[3];
  float emission[3];
  float roughness;
  float specular;
  char name[64];
  /* Emission leaves both sides of the surface (glTF's doubleSided, a
   * lamp panel modelled as one plane); 0, the default: only its front,
   * the side its winding's normal points to. Reflection is two-sided
   * either way. Last, so positional initialisers stay valid. */
  int two_sided;
  /* The glossy lobe's reflectance per channel (a gold metal's base colour);
   * all 0, the default: `specular` in every channel. When set, the scene
   * takes `specular` as its brightest channel (build time). Last, as
   * two_sided. */
  float specular_rgb[3];
} gi_material;

typedef enum gi_light_type {
  GI_LIGHT_SUN = 0,  /* direction + irradiance on a surface facing it */
  GI_LIGHT_POINT = 1,/* position + intensity (power per steradian) */
  GI_LIGHT_SPOT = 2, /* point light restricted to a cone */
  GI_LIGHT_SKY = 3   /* uniform radiance from every unoccluded direction */
} gi_light_type;

/* The largest light colour component and material emission a scene
 * takes; more is refused with GI_ERR_LIMIT (naming the light or the
 * material). The answers multiply light by 1/r^2 at a voxel's scale and
 * sum it over samples and bands in float: a sky of 1e38 overflowed a
 * probe's SH and a point light of 1e32 a millimetre off a surface did
 * too. 1e20 leaves 1e18 of headroom, and lies far above any physical
 * source (the sun's disc: about 2e7 W m^-2 sr^-1). */
#define GI_MAX_LIGHT_VALUE 1e20f

/* A light. color: sun = irradiance E (on a surface facing the sun), point and
 * spot = intensity I, sky = radiance L. direction: the way the light
 * travels (sun, spot), unit length. position: world coordinates. */
typedef struct gi_light {
  gi_light_type type;
  float color[3];
  double position[3];
  float direction[3];
  float cos_inner, cos_outer; /* spot cone, cosines of the half-angles */
} gi_light;

/* How to load or build a scene. Zero means default for every field. */
typedef struct gi_scene_options {
  gi_up_axis up;        /* default GI_UP_Y */
  int threads;          /* Embree build threads; 0 = all cores */
  double scale;         /* multiply input positions by this, > 0; 0 = 1 */
  const gi_light *lights; /* extra lights (command line, config); copied */
  size_t num_lights;
  int default_lights;   /* 1: add a sun and a sky when the scene has neither lights nor emitters */
} gi_scene_options;

/* What the loader kept and what it dropped, for reports and tests. */
typedef struct gi_scene_stats {
  uint64_t input_triangles;
  uint64_t triangles;          /* kept */
  uint64_t dropped_nonfinite;  /* NaN/Inf positions, or past float's range (3.4e38) */
  uint64_t dropped_degenerate; /* zero area (incl. repeated vertices) */
  uint64_t dropped_see_through; /* of materials passing >= half the light straight through (glass,
                                   alpha-blended): left out, they pass it all */
  uint64_t clamped_albedo;     /* materials whose albedo was out of [0, 1], or whose brightest
                                  albedo channel plus glossy reflectance exceeded 1 (both scaled
                                  to sum to 1), or with a negative or non-finite value (set to 0
                                  or its default); and vertex colours with a NaN or infinite
                                  channel (the vertex keeps its material's albedo) */
  uint32_t materials;
  uint32_t lights;
  uint32_t emissive_triangles;
  int default_lights_added;    /* 1 when a default sun + sky were added */
  uint64_t textures_unreadable; /* diffuse textures missing or undecodable (factor used alone) */
  uint32_t lights_skipped;     /* a file's lights of kinds not modelled (area, ambient, undefined):
                                  not in `lights`; an area light is better an emissive surface */
  uint64_t uv2_missing;        /* kept vertices without finite lightmap UVs in a scene where others
                                  have them: the set is then not used (gi_scene_has_lightmap_uv is 0)
                                  and a lightmap makes charts of its own */
  uint64_t far_triangles;      /* kept, but stray: at most 1% of the triangles, more than 100 times
                                  the rest's extent away (a leftover at 0,0,0 beside a model in
                                  map coordinates); the origin and the default voxel size follow
                                  the rest (gi_scene_bulk_bounds) */
} gi_scene_stats;

/* Loads a scene file through assimp (OBJ+MTL, PLY, glTF 2.0, 3DS, FBX...).
 * On failure *out is NULL and err says which file and what is wrong.
 * The caller owns *out (release with gi_scene_release). */
gi_result gi_scene_load(const char *path, const gi_scene_options *opt,
                        gi_scene **out, gi_error_info *err);

/* Reference counting; release accepts NULL. Thread-safe. */
gi_scene *gi_scene_retain(gi_scene *s);
void gi_scene_release(gi_scene *s);

void gi_scene_get_stats(const gi_scene *s, gi_scene_stats *out);
/* World-space bounds of the kept triangles (min, max). Empty scene: origin both. */
void gi_scene_bounds(const gi_scene *s, double lo[3], double hi[3]);
/* The world box of the scene less its stray far triangles (see
 * gi_scene_stats.far_triangles); the same as gi_scene_bounds without them. */
void gi_scene_bulk_bounds(const gi_scene *s, double lo[3], double hi[3]);
/* 1 when the bounds are flat along the file's z (its extent above 0 and
 * under a quarter of both others) while the scene was read with y up: most likely a z-up
 * export (OpenStreetMap, GIS) whose sun and sky would light it from the
 * side. For tools to note; the scene is valid either way. */
int gi_scene_looks_z_up(const gi_scene *s);
/* The scene origin (world, double): the centre of the input's bounds, from
 * which gi_cascade_anchor snaps viewpoints. NULL scene: zeros. */
void gi_scene_origin(const gi_scene *s, double out[3]);
gi_up_axis gi_scene_up(const gi_scene *s);
const char *gi_scene_name(const gi_scene *s);
size_t gi_scene_num_lights(const gi_scene *s);
/* The distance from world point p to the nearest surface along the 26
 * directions of the axes and the face and cube diagonals, or max when none
 * is nearer (0 for a non-finite p or max <= 0): the room a probe has (a
 * point in a wall's plane has none). Thread-safe. */
double gi_scene_clearance(const gi_scene *s, const double p[3], double max);
/* The share, in [0, 1], of the same 26 directions from world point p whose
 * first surface shows p its back (winding normal facing away): about 1
 * inside a closed solid wound outward (a building's volume), where the
 * truth is darkness and a gather reads only light that leaks in; 0 for a
 * non-finite p or a scene without surfaces. Thread-safe. A share above
 * GI_INSIDE_SHARE is what the tools call inside a solid. */
double gi_scene_backface_share(const gi_scene *s, const double p[3]);
#define GI_INSIDE_SHARE 0.5
/* The share, in [0, 1], of the same 26 directions from world point p that
 * meet no surface at all: 0 in a closed room or a solid of any winding
 * (OpenStreetMap's buildings promise none), 1 for a non-finite p or a
 * scene without surfaces. Thread-safe. */
double gi_scene_escape_share(const gi_scene *s, const double p[3]);
const gi_light *gi_scene_light(const gi_scene *s, size_t i);
size_t gi_scene_num_materials(const gi_scene *s);
const gi_material *gi_scene_material(const gi_scene *s, size_t i);
/* A 64-bit hash of everything the scene holds that an answer reads: its
 * vertices, triangles and their materials, its triangles' own albedos
 * (textures, vertex colours), lightmap UVs, materials, lights, up axis and
 * origin, as built. So an edit of any file the loader read (a glTF's .bin,
 * a texture, an .mtl) changes it, and one that loads the same scene (a
 * comment) does not. The same for every load of the same files with the
 * same options by the same build on x86-64; not the name. Reads every
 * array once: about 20 ms per million triangles. NULL: a constant.
 * Thread-safe. */
uint64_t gi_scene_digest(const gi_scene *s);

/* Builder for scenes made in code (procedural city, tests). Not thread-safe;
 * one builder per thread. Positions are world coordinates in double. */
gi_mesh_builder *gi_mesh_builder_new(void);
void gi_mesh_builder_free(gi_mesh_builder *b); /* accepts NULL */
/* Returns the new material's index; copies m. */
uint32_t gi_mesh_builder_add_material(gi_mesh_builder *b, const gi_material *m);
/* Adds a vertex and returns its index. */
uint32_t gi_mesh_builder_add_vertex(gi_mesh_builder *b, double x, double y, double z);
void gi_mesh_builder_add_triangle(gi_mesh_builder *b, uint32_t a, uint32_t c, uint32_t d, uint32_t material);
/* The lightmap UVs of an added vertex (u right, v down, as glTF's
 * TEXCOORD_1; 1 = the atlas's far edge). The scene keeps them only when
 * every vertex its triangles use has finite ones; gi_lightmap_layout then
 * bakes into them instead of making charts. */
void gi_mesh_builder_set_lightmap_uv(gi_mesh_builder *b, uint32_t vertex, double u, double v);
/* The colour of an added vertex, linear RGB (a scan's or glTF's COLOR_0):
 * a triangle's albedo is its material's times the mean of its three
 * corners' colours, clamped to [0, 1]. A vertex never given one is white;
 * one given a NaN or infinite channel is white too (its material's albedo)
 * and counted in gi_scene_stats.clamped_albedo. */
void gi_mesh_builder_set_vertex_color(gi_mesh_builder *b, uint32_t vertex, double r, double g, double bl);
/* How many triangles the builder holds (the next one's index). */
size_t gi_mesh_builder_num_triangles(const gi_mesh_builder *b);
/* The albedo of an added triangle in place of its material's (a texture
 * averaged over the triangle's own part of it), linear RGB; vertex colours
 * still multiply it, and the result is clamped to [0, 1]. A non-finite
 * component keeps the material's. */
void gi_mesh_builder_set_triangle_albedo(gi_mesh_builder *b, size_t tri, double r, double g, double bl);
/* 1 when the scene kept lightmap UVs (a file's second UV set, or the builder's). */
int gi_scene_has_lightmap_uv(const gi_scene *s);
/* Convenience: a quad a,b,c,d (counter-clockwise seen from the front) as two triangles. */
void gi_mesh_builder_add_quad(gi_mesh_builder *b, const double a[3], const double bb[3],
                              const double c[3], const double d[3], uint32_t material);
/* Convenience: an axis-aligned box with outward-facing sides. */
void gi_mesh_builder_add_box(gi_mesh_builder *b, const double lo[3], const double hi[3], uint32_t material);
/* Builds the scene (drops bad triangles, builds the BVH). The builder stays
 * valid and unchanged. name is copied (may be NULL). GI_ERR_INVALID_ARG
 * names the first builder call given a bad argument (a NULL material, a
 * vertex or triangle index past those added). */
gi_result gi_scene_build(const gi_mesh_builder *b, const char *name, const gi_scene_options *opt,
                         gi_scene **out, gi_error_info *err);

#ifdef __cplusplus
}
#endif
#endif
