/* io/gltf_accessors.h: a glTF accessor's numbers, read without assimp.
 *
 * gltf_recentre.c rewrites a glTF before assimp reads it, and some of what
 * it rewrites lives in binary buffers: EXT_mesh_gpu_instancing's per
 * instance translations, rotations and scales, which assimp 5.2 ignores
 * (an instanced forest or street of lamps loaded as one tree, one lamp).
 * This reads an accessor's elements as doubles from a buffer that is a
 * data: URI (base64), a file beside the glTF, or a .glb's binary chunk.
 *
 * Ownership: the caller frees what gi__gltf_accessor_read returns. No
 * state; thread-safe. */
#ifndef GI_GLTF_ACCESSORS_H
#define GI_GLTF_ACCESSORS_H

#include <jansson.h>
#include <stddef.h>
#include "gi/gi_error.h"

/* Where a glTF's buffers are: the file (for relative URIs) and a .glb's
 * binary chunk (buffer 0 without a uri), or NULL. Borrowed. */
typedef struct gi__gltf_bin {
  const char *path;
  const unsigned char *glb_bin;
  size_t glb_bin_len;
} gi__gltf_bin;

/* Accessor `index` of root as count x ncomp doubles (*out, caller frees;
 * *count set). Components float, or normalized signed byte or short when
 * `normalized_ok`; `ncomp` must match its type (VEC3 3, VEC4 4). Sparse
 * accessors, other component types, a bufferView or buffer out of range,
 * or data past a buffer's end fail with GI_ERR_FORMAT naming `what` and
 * the accessor; a count over max_count with GI_ERR_LIMIT. */
gi_result gi__gltf_accessor_read(json_t *root, const gi__gltf_bin *bin, json_int_t index, int ncomp, int normalized_ok,
                                 size_t max_count, const char *what, double **out, size_t *count, gi_error_info *err);

#endif
