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
#include <stdint.h>
#include "gi/gi_error.h"

struct gi__gltf_buf;

/* Where a glTF's buffers are: the file (for relative URIs) and a .glb's
 * binary chunk (buffer 0 without a uri), or NULL. Borrowed. The buffers
 * read so far are kept (cache), so that one many accessors share is read
 * once; gi__gltf_bin_fini frees them. */
typedef struct gi__gltf_bin {
  const char *path;
  const unsigned char *glb_bin;
  size_t glb_bin_len;
  struct gi__gltf_buf *cache; /* per buffer index, or NULL */
  size_t ncache;
} gi__gltf_bin;
void gi__gltf_bin_fini(gi__gltf_bin *bin);

/* Accessor `index` of root as count x ncomp doubles (*out, caller frees;
 * *count set). Components float, or normalized signed byte or short when
 * `normalized_ok`; `ncomp` must match its type (VEC3 3, VEC4 4). Sparse
 * accessors, other component types, a bufferView or buffer out of range,
 * or data past a buffer's end fail with GI_ERR_FORMAT naming `what` and
 * the accessor; a count over max_count with GI_ERR_LIMIT. */
gi_result gi__gltf_accessor_read(json_t *root, gi__gltf_bin *bin, json_int_t index, int ncomp, int normalized_ok,
                                 size_t max_count, const char *what, double **out, size_t *count, gi_error_info *err);

/* Checks a primitive's indices, accessor `index` (a SCALAR of unsigned
 * bytes, shorts or ints), against its `vertices`: *at the element of the
 * first index past them and *value that index, or *at = SIZE_MAX when all
 * are in range. 1 when checked; 0 when the accessor is not one this can
 * read (no bufferView, sparse, another type, past its buffer: assimp's
 * own checks say what is wrong); -1 out of memory, err set. */
int gi__gltf_indices_past(json_t *root, gi__gltf_bin *bin, json_int_t index, uint64_t vertices, size_t *at,
                          uint64_t *value, gi_error_info *err);

#endif
