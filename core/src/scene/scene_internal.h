/* scene_internal.h: the scene's layout, shared by the pipeline stages.
 *
 * Only core/src includes this. The struct is immutable after gi_scene_build
 * or gi_scene_load returns; all readers may run concurrently. */
#ifndef GI_SCENE_INTERNAL_H
#define GI_SCENE_INTERNAL_H

#include <math.h>
#include <stdatomic.h>
#include <string.h>
#include <embree3/rtcore.h>
#include "gi/gi_scene.h"

/* A node of the emitters' light tree: the box and power of the emitters
 * below it; internal nodes have children child and child + 1. */
typedef struct gi_light_node {
  float lo[3], hi[3];
  float power;             /* luminance x area, summed */
  float axis[3];           /* the emitters' normals lie within angle theta of axis */
  float cos_o, sin_o;      /* cos and sin of theta (cos -1: any direction) */
  uint32_t parent;         /* UINT32_MAX at the root */
  uint32_t child;          /* internal nodes: the left child */
  uint32_t slot;           /* leaves: the emitter slot; UINT32_MAX for internal nodes */
} gi_light_node;

/* A node of the point and spot lights' tree (local_tree.c): the box of
 * its lights' positions (local coordinates), their summed colour, the
 * box's centre and squared half-diagonal. Inner nodes have children child
 * and child + 1 and light UINT32_MAX; a leaf has its index in lights. */
typedef struct gi_local_node {
  float lo[3], hi[3], cen[3], h2;
  float power;
  uint32_t child, light;
} gi_local_node;

/* The two children of an internal node side by side, as the light tree's
 * walk reads them (light_tree.c): each field [2] is (left, right), so
 * both importances come from one pass of SSE arithmetic. Box centre and
 * squared half-diagonal are precomputed with the very operations the walk
 * used to repeat, so picks are unchanged. link: an internal child's own
 * pair index, or GI_LT_LEAF | slot for a leaf. */
/* An emitter's corners (local coordinates) and emitted radiance, copied
 * out of the scene's arrays: a light sample then reads one record instead
 * of an index line, three vertex lines and a material. */
typedef struct gi_emitter_geo {
  float v[3][3];
  float Le[3];
  int two_sided; /* its material's */
} gi_emitter_geo;

#define GI_LT_LEAF 0x80000000u
typedef struct gi_light_pair {
  float cen[3][2], h2[2], h[2], power[2], axis[3][2], cos_o[2], sin_o[2];
  uint32_t link[2];
} gi_light_pair;

struct gi_scene {
  atomic_int refcount;
  char name[128];
  gi_up_axis up;
  double origin[3];        /* world position of local (0,0,0) */
  double bulk_lo[3], bulk_hi[3]; /* world box of all but stray far triangles (gi_scene_bulk_bounds) */
  float lo[3], hi[3];      /* local bounds of kept triangles */

  uint32_t num_vertices;
  float *vertices;         /* 3 floats per vertex, local coordinates */
  float *uv2;              /* 2 per vertex: the input's lightmap UVs (u right, v down, [0,1]), or NULL */
  uint32_t num_triangles;
  uint32_t *indices;       /* 3 per triangle */
  uint32_t *tri_material;  /* material index per triangle */
  float *tri_albedo;       /* 3 per triangle with its own albedo (vertex colours, texture), else NULL */

  uint32_t num_materials;
  gi_material *materials;  /* albedo already clamped to [0,1] */

  uint32_t num_lights;
  gi_light *lights;        /* positions in world coordinates, as given */
  /* With GI_LOCAL_TREE_MIN point and spot lights or more, their tree
   * (root first; num_local_nodes 0 when every one is dark); else NULL. */
  gi_local_node *local_tree;
  uint32_t num_local_nodes;
  uint32_t num_local;      /* point and spot lights */
  uint32_t *other_lights;  /* with the tree: the indices of the other lights (sun, sky), in order */
  uint32_t num_other;

  /* Emissive triangles, for sampling them as area lights (light_tree.c). */
  uint32_t num_emitters;
  uint32_t *emitter_tri;   /* triangle index per emitter slot, ascending */
  uint32_t *emitter_leaf;  /* per slot: its leaf in ltree */
  gi_light_node *ltree;    /* 2 num_emitters - 1 nodes, root first */
  gi_light_pair *lpair;    /* num_emitters - 1 pairs: node n's children are pair (child - 1) / 2 */
  gi_emitter_geo *emitter_geo; /* per slot: the triangle's corners and emission, copied */
  uint32_t num_lnodes;
  float emitter_area_total;

  gi_scene_stats stats;

  RTCDevice device;
  RTCScene rtc;            /* committed; NULL for an empty scene */
  RTCScene rtc_emit;       /* the emissive triangles alone (primID = emitter slot); NULL without */
};

/* The cosine at emissive triangle tri of the light it sends back along a
 * ray that meets it, from cos_front = -(unit winding normal . ray
 * direction): cos_front for an emitter with a front only, its magnitude
 * for a two-sided one (gi_material.two_sided). It emits along the ray
 * when this is > 0. */
static inline float gi__emitter_cos(const struct gi_scene *s, uint32_t tri, float cos_front) {
  return s->materials[s->tri_material[tri]].two_sided ? fabsf(cos_front) : cos_front;
}

/* --- bvh_embree.c: everything that touches Embree -------------------- */

/* Builds device + BVH over s->vertices/indices (shared buffers). */
gi_result gi__bvh_build(struct gi_scene *s, int threads, gi_error_info *err);
void gi__bvh_free(struct gi_scene *s);

/* Visibility of n segments org + t*dir, t in [tnear, tfar], local coords.
 * dir need not be normalised (t is in units of dir). visible[i] = 1 when
 * nothing blocks segment i. Issues the rays as one stream (rtcOccluded1M).
 * Thread-safe. An empty scene reports everything visible. */
void gi__occluded(const struct gi_scene *s, int n, const float *org, const float *dir,
                  const float *tnear, const float *tfar, uint8_t *visible);

/* Closest hit along org + t*dir (dir unit), t in [tnear, tfar]. Returns 1
 * on a hit with its distance, triangle and geometric normal (unit, facing
 * against dir is NOT guaranteed: it is the triangle's winding normal). */
int gi__intersect1(const struct gi_scene *s, const float org[3], const float dir[3],
                   float tnear, float tfar, float *t, uint32_t *tri, float ng[3]);
/* A camera's first hit from eye along w (unit), as gi__intersect1 from 0,
 * except that a surface the eye lies on is seen only by rays going into
 * it from the eye's side (above a level surface, else its front): the
 * cone-traced and the path-traced views share it. Thread-safe. */
int gi__camera_hit(const struct gi_scene *s, const float eye[3], const float w[3], float *t, uint32_t *tri,
                   float ng[3]);
/* The nearest emissive triangle along org[i] + t dir[i], t from tnear[i]
 * on, ignoring everything else (rtc_emit), for n rays as one stream:
 * found[i] = 1 with its distance t[i] and triangle index tri[i], else 0
 * (none, a ray not finite, or no emitters). Whether something stands in
 * front is the caller's shadow ray. Thread-safe. */
void gi__emitter_find_n(const struct gi_scene *s, int n, const float (*org)[3], const float (*dir)[3],
                        const float *tnear, float *t, uint32_t *tri, uint8_t *found);

/* The surface point nearest p within `radius` (local coordinates): 1 with
 * it in q, its distance in *dist and (n not NULL) its triangle's unit
 * winding normal in n, 0 when no triangle comes that close (or the scene
 * is empty). A BVH point query whose radius shrinks to the nearest point
 * found so far. Thread-safe. */
int gi__closest_point(const struct gi_scene *s, const float p[3], float radius, float q[3], float *dist,
                      float n[3]);
/* Appends to *out the indices of all triangles whose bounding box overlaps the
 * local-space box [lo, hi] (a BVH query, never a scan of all triangles),
 * each once: in the BVH's order for a nearly cubic box, ascending for a
 * thin one (queried in parts, see bvh_embree.c). *out is realloc'ed;
 * *count and *cap are updated. Returns GI_ERR_NOMEM on allocation
 * failure. Thread-safe. */
gi_result gi__query_box(const struct gi_scene *s, const float lo[3], const float hi[3],
                        uint32_t **out, size_t *count, size_t *cap);
/* tris[0..*count) in ascending order, each triangle once (*count shrinks
 * by the repeats), so accumulating them does not depend on the order a
 * BVH visits. Thread-safe on distinct lists. */
void gi__order_tris(const struct gi_scene *s, uint32_t *tris, size_t *count);

/* A material rougher than this has no glossy lobe: its `specular` is not
 * used (every stage's rule: voxelizer, renderer, reference, plan). */
#define GI_GLOSSY_ROUGHNESS 0.5f

/* The reflectance of m's glossy lobe: specular when m is glossy, else 0. */
static inline float gi__gloss(const gi_material *m) {
  return m->roughness < GI_GLOSSY_ROUGHNESS && m->specular > 0 ? m->specular : 0.f;
}

/* m's glossy lobe per channel: gi__gloss in every channel, or tinted by
 * specular_rgb (whose brightest channel is `specular`, scene.c). */
static inline void gi__gloss_rgb(const gi_material *m, float out[3]) {
  float g = gi__gloss(m), mx = fmaxf(m->specular_rgb[0], fmaxf(m->specular_rgb[1], m->specular_rgb[2]));
  for (int k = 0; k < 3; k++) out[k] = mx > 0 ? g * m->specular_rgb[k] / mx : g;
}

/* Below this Beckmann alpha (roughness^2) a glossy lobe is a mirror. */
#define GI_MIRROR_ALPHA 1e-4
/* The Phong exponent ns of m's glossy lobe as every stage models it
 * (Beckmann alpha = roughness^2, ns = 2 / alpha^2 - 2): 0 without a lobe,
 * INFINITY for a mirror. */
static inline double gi__gloss_exponent(const gi_material *m) {
  if (!(gi__gloss(m) > 0)) return 0;
  double a = (double)m->roughness * m->roughness;
  return a < GI_MIRROR_ALPHA ? INFINITY : 2.0 / (a * a) - 2.0;
}
/* The lobe's density p(w) = (ns + 1) / (2 pi) cos^ns at cos_r, the cosine
 * between w and the mirror direction: 0 behind it, and for a mirror (a
 * light of no area shows in it as a point of no area). */
static inline float gi__phong_lobe(double ns, float cos_r) {
  if (!(cos_r > 0) || !(ns > 0) || isinf(ns)) return 0.f;
  return (float)((ns + 1) / (2 * 3.14159265358979323846) * pow((double)cos_r, ns));
}

/* Triangle tri's albedo: its own (vertex colours, its part of a texture:
 * gi_mesh_builder_set_vertex_color, _set_triangle_albedo), else its
 * material's. Every stage that reads a triangle's albedo goes through here
 * or gi__tri_material. */
static inline const float *gi__tri_albedo(const gi_scene *s, uint32_t tri) {
  return s->tri_albedo ? &s->tri_albedo[3 * (size_t)tri] : s->materials[s->tri_material[tri]].albedo;
}

/* Triangle tri's material with gi__tri_albedo's albedo: its own, or a copy
 * in *tmp (for the voxelizer, which takes a whole material). */
static inline const gi_material *gi__tri_material(const gi_scene *s, uint32_t tri, gi_material *tmp) {
  const gi_material *m = &s->materials[s->tri_material[tri]];
  if (!s->tri_albedo) return m;
  *tmp = *m;
  memcpy(tmp->albedo, gi__tri_albedo(s, tri), sizeof tmp->albedo);
  return tmp;
}

#endif
