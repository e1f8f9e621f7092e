/* io/assimp_nodes.c: assimp's node graph walked into world space (see the
 * header for why). */
#include "io/assimp_nodes.h"
#include <assimp/scene.h>
#include "base/internal.h"

typedef struct {
  const struct aiNode *node;
  gi__xform world;
} walk_item;

/* out = parent x local (assimp's row-major 4x4, last row 0 0 0 1). */
static void compose(const gi__xform *parent, const struct aiMatrix4x4 *l, gi__xform *out) {
  const double local[3][4] = {{l->a1, l->a2, l->a3, l->a4}, {l->b1, l->b2, l->b3, l->b4}, {l->c1, l->c2, l->c3, l->c4}};
  for (int r = 0; r < 3; r++) {
    for (int c = 0; c < 4; c++) {
      double v = c == 3 ? parent->m[r][3] : 0;
      for (int k = 0; k < 3; k++) v += parent->m[r][k] * local[k][c];
      out->m[r][c] = v;
    }
  }
}

static double det3(const gi__xform *x) {
  const double(*m)[4] = x->m;
  return m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
         m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
}

gi_result gi__assimp_walk(const struct aiScene *as, gi__node_visit visit, void *ctx, gi_error_info *err) {
  if (!as->mRootNode) return GI_OK;
  size_t cap = 64, n = 0;
  walk_item *stack = gi__malloc(cap * sizeof *stack);
  if (!stack) return gi__fail(err, GI_ERR_NOMEM, "scene: out of memory for the node graph");
  const gi__xform id = {{{1, 0, 0, 0}, {0, 1, 0, 0}, {0, 0, 1, 0}}};
  stack[n].node = as->mRootNode;
  compose(&id, &as->mRootNode->mTransformation, &stack[n].world);
  n++;
  gi_result rc = GI_OK;
  while (n > 0 && rc == GI_OK) {
    walk_item it = stack[--n];
    rc = visit(ctx, it.node, &it.world, det3(&it.world) < 0);
    const struct aiNode *nd = it.node;
    if (rc != GI_OK || nd->mNumChildren == 0) continue;
    if (n + nd->mNumChildren > cap) {
      size_t want = cap;
      while (want < n + nd->mNumChildren) want *= 2;
      walk_item *grown = gi__realloc(stack, want * sizeof *stack);
      if (!grown) {
        rc = gi__fail(err, GI_ERR_NOMEM, "scene: out of memory for the node graph");
        break;
      }
      stack = grown, cap = want;
    }
    /* Pushed last first: children are visited in the file's order. */
    for (unsigned i = nd->mNumChildren; i-- > 0;) {
      const struct aiNode *ch = nd->mChildren[i];
      if (!ch) continue;
      stack[n].node = ch;
      compose(&it.world, &ch->mTransformation, &stack[n].world);
      n++;
    }
  }
  gi__free(stack);
  return rc;
}
