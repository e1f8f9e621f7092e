/* io/assimp_nodes.h: assimp's node graph walked into world space.
 *
 * assimp's aiProcess_PreTransformVertices moved every mesh to world space
 * but kept its triangles' winding under a node that mirrors (a negative
 * determinant, Blender's scale -1): the mirrored object came out inside
 * out, its one-sided emitters lit away from where they face and its
 * inside read as outside. The importer walks the graph itself: each
 * node's world transform composed in double from assimp's float matrices,
 * and whether it mirrors. It also meets every instance of a mesh that
 * several nodes use, as the pre-transform did.
 *
 * Not thread-safe for one aiScene (assimp's scenes are not); no state. */
#ifndef GI_ASSIMP_NODES_H
#define GI_ASSIMP_NODES_H

#include "gi/gi_error.h"

struct aiScene;
struct aiNode;

/* A world transform: rows of a 3x4 matrix (x' = m[0][0..2] . x + m[0][3]). */
typedef struct gi__xform {
  double m[3][4];
} gi__xform;

/* Called once per node, parents first, with its world transform; mirrored
 * is 1 when the transform's determinant is negative (reverse the winding).
 * A result other than GI_OK stops the walk and is returned. */
typedef gi_result (*gi__node_visit)(void *ctx, const struct aiNode *node, const gi__xform *world, int mirrored);

/* Walks as's node graph from its root without recursion (a file may nest
 * nodes as deep as it likes). GI_ERR_NOMEM when its stack cannot grow. */
gi_result gi__assimp_walk(const struct aiScene *as, gi__node_visit visit, void *ctx, gi_error_info *err);

/* x applied to the point (px, py, pz). */
static inline void gi__xform_point(const gi__xform *x, double px, double py, double pz, double out[3]) {
  for (int r = 0; r < 3; r++) out[r] = x->m[r][0] * px + x->m[r][1] * py + x->m[r][2] * pz + x->m[r][3];
}

/* x's linear part applied to the direction (dx, dy, dz). */
static inline void gi__xform_dir(const gi__xform *x, double dx, double dy, double dz, double out[3]) {
  for (int r = 0; r < 3; r++) out[r] = x->m[r][0] * dx + x->m[r][1] * dy + x->m[r][2] * dz;
}

#endif
