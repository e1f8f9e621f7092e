/* io/gltf_recentre.h: glTF node transforms composed in double.
 *
 * assimp composes glTF node matrices in float, so a node translated to a
 * georeferenced position (UTM northing ~5e6) moves its vertices by up to
 * 0.5 m before the scene can subtract its origin. Before assimp sees a
 * .gltf or .glb we compose every node's world matrix in double, pick an
 * offset T (the world position of the first node that carries a mesh),
 * and rewrite the default scene flat: each node with a mesh or a light
 * becomes a root whose matrix is its world matrix with T taken off. assimp
 * then works with small numbers, and the importer adds T back, in double,
 * to every vertex and light position. The rewritten file lives only in
 * memory: gi__gltf_open_io serves it to assimp under the original path, so
 * external buffers still resolve beside the file.
 *
 * Lights (KHR_lights_punctual) are read here too, one per node that holds
 * one, at its world position in double, and taken out of what assimp
 * sees: assimp 5.2 matches each light to its node by name, through the
 * whole node graph, in its validation and again when it moves lights to
 * world space, and 16,384 lamps took 3.6 s to load that way.
 *
 * Materials' KHR_materials_emissive_strength, which assimp 5.2 ignores,
 * is folded into their emissiveFactor in the same rewrite, and a node's
 * EXT_mesh_gpu_instancing (ignored too) becomes one root per instance,
 * its instance data read by io/gltf_accessors.c. A primitive's indexed
 * attributes (TEXCOORD_n, COLOR_n, ...) are listed in index order, which
 * assimp 5.2 requires and JSON does not promise. A file requiring an
 * extension we do not read (extensionsRequired) is refused, and a texture
 * whose image only an extension names (KTX2, WebP) gets it as its source,
 * for the texture reader to refuse with a warning.
 *
 * Ownership: gi__gltf_recentre fills a gi__gltf_shift the caller releases
 * with gi__gltf_shift_free. Not shared between threads. */
#ifndef GI_GLTF_RECENTRE_H
#define GI_GLTF_RECENTRE_H

#include <stddef.h>
#include "gi/gi_error.h"

struct aiFileIO;

struct gi_light;

#define GI_GLTF_UV_TF 6

typedef struct gi__gltf_shift {
  double t[3];         /* add to every position assimp returns */
  unsigned char *data; /* the rewritten file, or NULL: let assimp read the file as it is */
  size_t len;
  const char *path;    /* the file the data stands for (borrowed) */
  /* With data: the file's lights in world coordinates (t included,
   * unscaled; the rewritten file has none left), owned; else NULL. */
  struct gi_light *lights;
  size_t num_lights;
  /* Per glTF material (assimp keeps their order), its base-colour
   * texture's KHR_texture_transform: offset u, v, rotation, scale u, v,
   * texCoord (-1: the texture's own), or NULL when no material has one;
   * owned. assimp 5.2 does not apply it to the coordinates. */
  double (*uv_tf)[GI_GLTF_UV_TF];
  size_t num_uv_tf;
  /* Per glTF material, its dielectric reflectance from KHR_materials_specular
   * and KHR_materials_ior (NAN: neither given, the core spec's 4%), or NULL
   * when no material has them; owned. assimp 5.2 reads neither. */
  float *f0;
  size_t num_f0;
  int io_oom; /* gi__gltf_open_io's file system ran out of memory */
  char io_err[512]; /* an MTL file it refused (gi__exact_mtl_normalise), or "" */
} gi__gltf_shift;

/* For the .gltf (glb 0) or .glb (glb 1) at path: the shift and the rewritten file. A file
 * whose JSON cannot be parsed or whose nodes hold non-numbers fails with
 * GI_ERR_FORMAT naming the file and the place; a file without a scene
 * graph gets t = 0 and no data. */
gi_result gi__gltf_recentre(const char *path, int glb, gi__gltf_shift *out, gi_error_info *err);
void gi__gltf_shift_free(gi__gltf_shift *s);

/* An assimp file system that reads s->path from s->data and every other
 * file from disk, an OBJ's .mtl files through gi__exact_mtl_normalise; an
 * open that ran out of memory sets s->io_oom, an MTL file with a bad colour
 * s->io_err (assimp then says only that it could not open the file). io
 * must outlive the import; s must outlive io. */
void gi__gltf_open_io(struct aiFileIO *io, gi__gltf_shift *s);

#endif
