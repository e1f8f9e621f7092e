/* io/texture_image.h: average colour of a texture image (PNG, JPEG, raw BGRA8).
 *
 * Only core/src includes this. Everything here is thread-safe and keeps no
 * state between calls. */
#ifndef GI_TEXTURE_IMAGE_H
#define GI_TEXTURE_IMAGE_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include "gi/gi_error.h"

/* Largest image we decode: each side at most GI__IMAGE_MAX_SIDE pixels and at
 * most GI__IMAGE_MAX_PIXELS in all. Larger images fail with GI_ERR_LIMIT. */
#define GI__IMAGE_MAX_SIDE 16384u
#define GI__IMAGE_MAX_PIXELS ((uint64_t)256 << 20)
/* Largest texture file gi__read_file is asked to read (512 MiB). */
#define GI__TEXTURE_FILE_MAX ((size_t)512 << 20)

/* A texture box-filtered onto a grid of at most GI__TEX_GRID_SIDE cells a
 * side (fewer for a smaller image), linear RGB, 3 floats per cell, row 0
 * at the image's top. w == 0 (rgb NULL): none (an interlaced PNG, whose
 * passes are not rows of the image). Freed with gi__tex_grid_free. */
#define GI__TEX_GRID_SIDE 128
typedef struct gi__tex_grid {
  int w, h;
  float *rgb;
} gi__tex_grid;
void gi__tex_grid_free(gi__tex_grid *g); /* accepts NULL */
/* The mean of grid g over a triangle with texture coordinates uv (u
 * right, v up, as assimp and OBJ give them; repeating), from points spread
 * evenly over it, about 30 per cell it covers (4 for a triangle under
 * half a cell wide), at most GI__TEX_TRI_SPLIT^2. g must have cells (w > 0). */
#define GI__TEX_TRI_SPLIT 32
void gi__tex_grid_triangle(const gi__tex_grid *g, const float uv[3][2], float out[3]);
/* How a coordinate outside [0, 1] reads the texture (glTF's sampler wrapS
 * and wrapT, assimp's aiTextureMapMode): repeating, held at the edge, or
 * repeating mirrored every other tile. */
typedef enum { GI__TEX_REPEAT, GI__TEX_CLAMP, GI__TEX_MIRROR } gi__tex_wrap;
/* gi__tex_grid_triangle with u and v wrapped as wrap_u and wrap_v say. */
void gi__tex_grid_triangle_wrap(const gi__tex_grid *g, const float uv[3][2], gi__tex_wrap wrap_u,
                                gi__tex_wrap wrap_v, float out[3]);

/* Decodes a PNG or JPEG held in memory (the format is told by its magic
 * bytes) and stores in rgb the plain mean over all pixels of the LINEAR
 * colour: 8- and 16-bit values are taken as sRGB-encoded and converted with
 * the exact sRGB transfer function; alpha is ignored. `what` names the image
 * in messages (a path, or "embedded texture *0"). Corrupt or unsupported data
 * gives GI_ERR_FORMAT, an image over the size limits GI_ERR_LIMIT; neither
 * ever aborts the process. Memory use is one row, not the whole image. */
gi_result gi__image_average(const void *data, size_t size, const char *what, float rgb[3], gi_error_info *err);
/* The same, and the image's grid into *grid (when not NULL; emptied on an error). */
gi_result gi__image_average_grid(const void *data, size_t size, const char *what, float rgb[3], gi__tex_grid *grid,
                                 gi_error_info *err);

/* The same for width*height uncompressed texels of 4 bytes in B, G, R, A
 * order (assimp's aiTexel), sRGB-encoded. */
gi_result gi__texels_average(const void *bgra, uint32_t width, uint32_t height, const char *what, float rgb[3],
                             gi_error_info *err);
gi_result gi__texels_average_grid(const void *bgra, uint32_t width, uint32_t height, const char *what, float rgb[3],
                                  gi__tex_grid *grid, gi_error_info *err);

/* One 8-bit-style sRGB-encoded value in [0, 1] to linear (the exact
 * transfer function); also for vertex colours (import_exact.c). */
double gi__srgb_to_linear(double c);

/* fopen(path, "rb") that does not wait: a FIFO's open blocks until some
 * writer appears (gi-bake hung on one), so it is opened non-blocking and
 * left for the caller's S_ISREG check to refuse. NULL with errno set. */
FILE *gi__fopen_read(const char *path);

/* Reads a whole regular file into a malloc'ed buffer (*data, freed by the
 * caller; *size bytes). A missing file gives GI_ERR_NOT_FOUND, a file larger
 * than max_size GI_ERR_LIMIT, any other failure GI_ERR_IO. */
gi_result gi__read_file(const char *path, size_t max_size, void **data, size_t *size, gi_error_info *err);

#endif
