/* gi_exr.h: write and read layered EXR images (OpenEXR core C API glue).
 *
 * The writer takes planar float channels and stores them as half or float,
 * ZIP or PIZ compressed, scanline, with string attributes in the header.
 * It writes to "<path>.tmp.<pid>" and renames into place, so a killed
 * process never leaves a truncated file under the final name. A path that
 * already ends in ".tmp.<pid>" of the calling process is taken as the
 * caller's own temporary name and written in place (the caller renames it;
 * the VDB writers do the same).
 * Both directions are thread-safe for distinct files. */
#ifndef GI_EXR_H
#define GI_EXR_H

#include <stddef.h>
#include "gi_error.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum gi_exr_compression { GI_EXR_ZIP = 0, GI_EXR_PIZ = 1, GI_EXR_NONE = 2 } gi_exr_compression;

typedef struct gi_exr_channel {
  const char *name;   /* e.g. "R", "irradiance.R", "sh.L00.R" */
  const float *data;  /* width*height values, row-major, borrowed */
} gi_exr_channel;

typedef struct gi_exr_attr {
  const char *name;   /* header attribute name, e.g. "gi.scene" */
  const char *value;  /* stored as an EXR string attribute */
} gi_exr_attr;

typedef struct gi_exr_image {
  int width, height;
  int use_half;                  /* 1: HALF pixels, 0: FLOAT */
  gi_exr_compression compression;
  size_t num_channels;
  const gi_exr_channel *channels;
  size_t num_attrs;
  const gi_exr_attr *attrs;
} gi_exr_image;

/* Writes img to path (temporary name, then rename). Non-finite samples are
 * rejected with GI_ERR_NONFINITE naming the channel. */
gi_result gi_exr_write(const char *path, const gi_exr_image *img, gi_error_info *err);

/* A file read back into memory, every channel converted to float. */
typedef struct gi_exr_file gi_exr_file;
gi_result gi_exr_read(const char *path, gi_exr_file **out, gi_error_info *err);
void gi_exr_file_free(gi_exr_file *f); /* accepts NULL */
int gi_exr_file_width(const gi_exr_file *f);
int gi_exr_file_height(const gi_exr_file *f);
size_t gi_exr_file_num_channels(const gi_exr_file *f);
const char *gi_exr_file_channel_name(const gi_exr_file *f, size_t i);
/* 1 when the channel is stored as HALF in the file. */
int gi_exr_file_channel_is_half(const gi_exr_file *f, size_t i);
/* Planar float data of the named channel, or NULL when absent. Owned by f. */
const float *gi_exr_file_channel(const gi_exr_file *f, const char *name);
/* A string attribute's value, or NULL when absent. Owned by f. */
const char *gi_exr_file_attr(const gi_exr_file *f, const char *name);
/* The file's compression as stored. */
gi_exr_compression gi_exr_file_compression(const gi_exr_file *f);

#ifdef __cplusplus
}
#endif
#endif
