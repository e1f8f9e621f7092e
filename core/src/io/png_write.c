/* io/png_write.c: linear RGB floats to an 8-bit sRGB PNG (libpng).
 *
 * The only PNG writer in the core, for rendered views. libpng reports
 * errors by longjmp; the jump lands here and becomes a gi_result. The file
 * is written to a temporary name and renamed into place. */
#include <png.h>
#include <setjmp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include "gi/gi_render.h"
#include "base/internal.h"

static unsigned char to_srgb8(float v) {
  if (!(v > 0)) return 0;
  if (v >= 1) return 255;
  float s = v <= 0.0031308f ? 12.92f * v : 1.055f * powf(v, 1 / 2.4f) - 0.055f;
  return (unsigned char)(s * 255.f + 0.5f);
}

gi_result gi_image_write_png(const char *path, const float *rgb, int width, int height, float exposure,
                             gi_error_info *err) {
  if (!path || !rgb || width < 1 || height < 1 || !isfinite(exposure))
    return gi__fail(err, GI_ERR_INVALID_ARG, "png: bad arguments for %s", path ? path : "(null)");
  char tmp[4096];
  snprintf(tmp, sizeof tmp, "%s.tmp.%d", path, (int)getpid());
  unsigned char *row = gi__malloc((size_t)width * 3);
  if (!row) return gi__fail(err, GI_ERR_NOMEM, "png: out of memory for a row of %d pixels of %s", width, path);
  FILE *f = fopen(tmp, "wb");
  if (!f) {
    gi__free(row);
    return gi__fail(err, GI_ERR_IO, "png: cannot write %s", tmp);
  }
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, NULL, NULL, NULL);
  png_infop info = png ? png_create_info_struct(png) : NULL;
  if (!png || !info || setjmp(png_jmpbuf(png))) {
    png_destroy_write_struct(&png, &info);
    fclose(f);
    gi__free(row);
    remove(tmp);
    return gi__fail(err, GI_ERR_IO, "png: libpng failed writing %s", path);
  }
  png_init_io(png, f);
  png_set_IHDR(png, info, (png_uint_32)width, (png_uint_32)height, 8, PNG_COLOR_TYPE_RGB, PNG_INTERLACE_NONE,
               PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  png_set_sRGB(png, info, PNG_sRGB_INTENT_PERCEPTUAL);
  png_write_info(png, info);
  for (int y = 0; y < height; y++) {
    for (int x = 0; x < 3 * width; x++) row[x] = to_srgb8(exposure * rgb[(size_t)y * width * 3 + x]);
    png_write_row(png, row);
  }
  png_write_end(png, NULL);
  png_destroy_write_struct(&png, &info);
  gi__free(row);
  if (fclose(f) != 0 || rename(tmp, path) != 0) {
    remove(tmp);
    return gi__fail(err, GI_ERR_IO, "png: cannot finish %s", path);
  }
  return GI_OK;
}
