/* io/texture_image.c: the average linear colour of a PNG or JPEG texture.
 *
 * Design: the importer only needs one number per texture (the mean albedo),
 * so images are streamed row by row into a per-channel histogram of the
 * encoded values and never held whole; the histogram is then converted
 * through the exact sRGB transfer function, which makes the mean exact for
 * 8-bit data and cheap (256 or 65536 conversions, not one per pixel).
 * Adam7-interlaced PNGs are read pass by pass without de-interlacing: every
 * pixel lies in exactly one pass, and a mean does not care where. Both
 * libraries report errors through callbacks that longjmp back here, so a
 * corrupt or truncated file is a GI_ERR_FORMAT, never an exit() or a crash;
 * libpng warnings and libjpeg's harmless warnings are dropped, libjpeg's
 * "corrupt data" warnings (truncation, bad codes) are errors, and a PNG is
 * read to its IEND, so a truncated file of either kind is refused. Image size is
 * checked from the header before anything large is allocated, and libjpeg's
 * own memory (progressive files keep all coefficients) is capped. */
#include "io/texture_image.h"
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <setjmp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>
#include <jpeglib.h>
#include <jerror.h>
#include <png.h>
#include "base/internal.h"

/* libjpeg's working memory ceiling; a progressive image needs about
 * 2 bytes per pixel per component. */
#define JPEG_MEMORY_MAX (768L << 20)

/* Per-channel histograms of encoded values: hist[c * levels + v]; and,
 * when a grid is asked for, linear sums per grid cell. */
typedef struct accum {
  uint64_t *hist;
  unsigned levels; /* 256 or 65536 */
  uint64_t pixels;
  gi__tex_grid *grid; /* NULL: none asked for */
  double *gsum;       /* 3 per cell */
  uint32_t *gcnt;
  uint32_t *gcol;     /* per image column: its grid column */
  uint32_t grow;      /* the grid row of the rows now added */
  float *lut;         /* encoded value -> linear */
} accum;

static int accum_init(accum *a, unsigned levels) {
  a->levels = levels;
  a->pixels = 0;
  a->hist = gi__calloc((size_t)3 * levels, sizeof *a->hist);
  return a->hist != NULL;
}

static void accum_free(accum *a) {
  gi__free(a->hist);
  gi__free(a->gsum);
  gi__free(a->gcnt);
  gi__free(a->gcol);
  gi__free(a->lut);
  a->hist = NULL, a->gsum = NULL, a->gcnt = NULL, a->gcol = NULL, a->lut = NULL;
}

/* Sets up the grid of a w x h image (values linear already, or sRGB); 0
 * when out of memory. Without a grid asked for, nothing to do. */
static int accum_grid_init(accum *a, gi__tex_grid *grid, uint32_t w, uint32_t h, int linear) {
  a->grid = grid;
  if (!grid) return 1;
  grid->w = (int)(w < GI__TEX_GRID_SIDE ? w : GI__TEX_GRID_SIDE);
  grid->h = (int)(h < GI__TEX_GRID_SIDE ? h : GI__TEX_GRID_SIDE);
  size_t cells = (size_t)grid->w * (size_t)grid->h;
  a->gsum = gi__calloc(3 * cells, sizeof *a->gsum);
  a->gcnt = gi__calloc(cells, sizeof *a->gcnt);
  a->gcol = gi__malloc((size_t)w * sizeof *a->gcol);
  a->lut = gi__malloc(a->levels * sizeof *a->lut);
  grid->rgb = gi__malloc(3 * cells * sizeof *grid->rgb);
  if (!a->gsum || !a->gcnt || !a->gcol || !a->lut || !grid->rgb) return 0;
  for (uint32_t x = 0; x < w; x++) a->gcol[x] = (uint32_t)((uint64_t)x * (uint64_t)grid->w / w);
  double max = (double)(a->levels - 1);
  for (unsigned v = 0; v < a->levels; v++) a->lut[v] = (float)(linear ? v / max : gi__srgb_to_linear(v / max));
  return 1;
}

/* Row y of an h-row image will be added next. */
static void accum_grid_row(accum *a, uint32_t y, uint32_t h) {
  if (a->grid) a->grow = (uint32_t)((uint64_t)y * (uint64_t)a->grid->h / h);
}

/* One pixel (encoded values) at column x of the current row. */
static inline void accum_grid_px(accum *a, uint32_t x, unsigned r, unsigned g, unsigned b) {
  size_t cell = (size_t)a->grow * (size_t)a->grid->w + a->gcol[x];
  a->gsum[3 * cell] += a->lut[r], a->gsum[3 * cell + 1] += a->lut[g], a->gsum[3 * cell + 2] += a->lut[b];
  a->gcnt[cell]++;
}

static void accum_grid_finish(const accum *a) {
  if (!a->grid) return;
  size_t cells = (size_t)a->grid->w * (size_t)a->grid->h;
  for (size_t i = 0; i < cells; i++)
    for (int c = 0; c < 3; c++) a->grid->rgb[3 * i + c] = a->gcnt[i] ? (float)(a->gsum[3 * i + c] / a->gcnt[i]) : 0.f;
}

double gi__srgb_to_linear(double c) {
  return c <= 0.04045 ? c / 12.92 : pow((c + 0.055) / 1.055, 2.4);
}

/* linear: the values are linear already (a PNG with gAMA 1.0), not sRGB. */
static void accum_finish(const accum *a, int linear, float rgb[3]) {
  double max = (double)(a->levels - 1);
  for (int c = 0; c < 3; c++) {
    double sum = 0.0;
    const uint64_t *h = a->hist + (size_t)c * a->levels;
    for (unsigned v = 0; v < a->levels; v++)
      if (h[v]) sum += (double)h[v] * (linear ? v / max : gi__srgb_to_linear(v / max));
    rgb[c] = (float)(sum / (double)a->pixels);
  }
}

static gi_result check_size(uint64_t w, uint64_t h, const char *what, const char *kind, gi_error_info *err) {
  if (w == 0 || h == 0) return gi__fail(err, GI_ERR_FORMAT, "texture '%s': %s image has no pixels", what, kind);
  if (w > GI__IMAGE_MAX_SIDE || h > GI__IMAGE_MAX_SIDE || w * h > GI__IMAGE_MAX_PIXELS)
    return gi__fail(err, GI_ERR_LIMIT, "texture '%s': %s image is %llux%llu; the limit is %ux%u", what, kind,
                    (unsigned long long)w, (unsigned long long)h, GI__IMAGE_MAX_SIDE, GI__IMAGE_MAX_SIDE);
  return GI_OK;
}

/* --- PNG ------------------------------------------------------------- */

typedef struct png_ctx {
  const unsigned char *data;
  size_t size, pos;
  char msg[200];
} png_ctx;

static void png_on_error(png_structp png, png_const_charp msg) {
  png_ctx *c = png_get_error_ptr(png);
  snprintf(c->msg, sizeof c->msg, "%s", msg ? msg : "unknown error");
  png_longjmp(png, 1);
}

static void png_on_warning(png_structp png, png_const_charp msg) { (void)png, (void)msg; }

static void png_read_mem(png_structp png, png_bytep out, png_size_t len) {
  png_ctx *c = png_get_io_ptr(png);
  if (len > c->size - c->pos) png_error(png, "the data is truncated");
  memcpy(out, c->data + c->pos, len);
  c->pos += len;
}

static gi_result png_average(const void *data, size_t size, const char *what, float rgb[3], gi__tex_grid *grid,
                             gi_error_info *err) {
  png_ctx ctx = {.data = data, .size = size};
  png_structp png = png_create_read_struct(PNG_LIBPNG_VER_STRING, &ctx, png_on_error, png_on_warning);
  png_infop info = png ? png_create_info_struct(png) : NULL;
  /* Changed after setjmp, read after a longjmp: volatile. */
  unsigned char *volatile row = NULL;
  accum *volatile acc = NULL;
  accum a = {0};
  volatile gi_result rc = GI_OK;
  if (!info) {
    rc = gi__fail(err, GI_ERR_NOMEM, "texture '%s': out of memory", what);
    goto done;
  }
  if (setjmp(png_jmpbuf(png))) {
    rc = gi__fail(err, GI_ERR_FORMAT, "texture '%s': corrupt or unsupported PNG: %s", what, ctx.msg);
    goto done;
  }
  png_set_read_fn(png, &ctx, png_read_mem);
  png_set_user_limits(png, 0x7fffffff, 0x7fffffff); /* we apply our own limit, as GI_ERR_LIMIT */
  png_read_info(png, info);
  png_uint_32 w = png_get_image_width(png, info), h = png_get_image_height(png, info);
  rc = check_size(w, h, what, "PNG", err);
  if (rc != GI_OK) goto done;
  int interlaced = png_get_interlace_type(png, info) == PNG_INTERLACE_ADAM7;
  /* Textures are sRGB unless the file says its values are linear (gAMA 1.0,
   * as libpng itself writes 16-bit linear data); other gAMA values are
   * close enough to sRGB that the exact curve is the better guess. */
  png_fixed_point gamma = 0;
  int linear = !png_get_valid(png, info, PNG_INFO_sRGB) && png_get_gAMA_fixed(png, info, &gamma) &&
               gamma >= 99000 && gamma <= 101000;
  /* Everything to 8- or 16-bit RGB; no png_set_interlace_handling (see the top). */
  png_set_expand(png);
  png_set_strip_alpha(png);
  png_set_gray_to_rgb(png);
  png_read_update_info(png, info);
  int depth = png_get_bit_depth(png, info);
  if (png_get_channels(png, info) != 3 || (depth != 8 && depth != 16))
    png_error(png, "unexpected pixel layout after conversion");
  acc = &a;
  /* An interlaced image's passes are not rows of the image: no grid (its
   * triangles take the average). */
  if (!accum_init(&a, depth == 16 ? 65536u : 256u) || !accum_grid_init(&a, interlaced ? NULL : grid, w, h, linear)) {
    rc = gi__fail(err, GI_ERR_NOMEM, "texture '%s': out of memory", what);
    goto done;
  }
  row = gi__malloc(png_get_rowbytes(png, info));
  if (!row) {
    rc = gi__fail(err, GI_ERR_NOMEM, "texture '%s': out of memory", what);
    goto done;
  }
  for (int pass = 0; pass < (interlaced ? 7 : 1); pass++) {
    png_uint_32 rows = interlaced ? PNG_PASS_ROWS(h, pass) : h;
    png_uint_32 cols = interlaced ? PNG_PASS_COLS(w, pass) : w;
    if (rows == 0 || cols == 0) continue; /* libpng skips empty passes too */
    for (png_uint_32 y = 0; y < rows; y++) {
      png_read_row(png, row, NULL);
      const unsigned char *p = row;
      accum_grid_row(&a, y, rows);
      if (depth == 8) {
        for (png_uint_32 x = 0; x < cols; x++, p += 3) {
          a.hist[p[0]]++;
          a.hist[256 + p[1]]++;
          a.hist[512 + p[2]]++;
          if (a.grid) accum_grid_px(&a, x, p[0], p[1], p[2]);
        }
      } else {
        for (png_uint_32 x = 0; x < cols; x++, p += 6) {
          unsigned r = (p[0] << 8) | p[1], g = (p[2] << 8) | p[3], b = (p[4] << 8) | p[5];
          a.hist[r]++;
          a.hist[65536 + g]++;
          a.hist[131072 + b]++;
          if (a.grid) accum_grid_px(&a, x, r, g, b);
        }
      }
      a.pixels += cols;
    }
  }
  png_read_end(png, NULL); /* the rest of the file, so truncation and bad CRCs show */
  accum_finish(&a, linear, rgb);
  accum_grid_finish(&a);
done:
  png_destroy_read_struct(png ? &png : NULL, info ? &info : NULL, NULL);
  gi__free(row);
  if (acc) accum_free(acc);
  return rc;
}

/* --- JPEG ------------------------------------------------------------ */

typedef struct jpeg_fail_mgr {
  struct jpeg_error_mgr pub;
  jmp_buf jump;
  char msg[JMSG_LENGTH_MAX];
} jpeg_fail_mgr;

static void jpeg_on_error(j_common_ptr ci) {
  jpeg_fail_mgr *e = (jpeg_fail_mgr *)ci->err;
  e->pub.format_message(ci, e->msg);
  longjmp(e->jump, 1);
}

/* Warnings (level -1) that mean the pixels are wrong are errors; the rest
 * (trace messages, "extraneous bytes", unknown JFIF revision) are dropped. */
static void jpeg_on_message(j_common_ptr ci, int level) {
  if (level >= 0) return;
  switch (ci->err->msg_code) {
    case JWRN_JPEG_EOF:
    case JWRN_HIT_MARKER:
    case JWRN_HUFF_BAD_CODE:
    case JWRN_ARITH_BAD_CODE:
    case JWRN_MUST_RESYNC: jpeg_on_error(ci); break;
    default: break;
  }
}

static gi_result jpeg_average(const void *data, size_t size, const char *what, float rgb[3], gi__tex_grid *grid,
                              gi_error_info *err) {
  struct jpeg_decompress_struct ci;
  jpeg_fail_mgr je;
  unsigned char *volatile row = NULL;
  accum a = {0};
  volatile gi_result rc = GI_OK;
  if (!accum_init(&a, 256)) return gi__fail(err, GI_ERR_NOMEM, "texture '%s': out of memory", what);
  ci.err = jpeg_std_error(&je.pub);
  je.pub.error_exit = jpeg_on_error;
  je.pub.emit_message = jpeg_on_message;
  je.msg[0] = 0;
  if (setjmp(je.jump)) {
    rc = gi__fail(err, GI_ERR_FORMAT, "texture '%s': corrupt or unsupported JPEG: %s", what, je.msg);
    goto done;
  }
  jpeg_create_decompress(&ci);
  ci.mem->max_memory_to_use = JPEG_MEMORY_MAX;
  jpeg_mem_src(&ci, (const unsigned char *)data, (unsigned long)size);
  if (jpeg_read_header(&ci, TRUE) != JPEG_HEADER_OK) {
    rc = gi__fail(err, GI_ERR_FORMAT, "texture '%s': JPEG holds no image", what);
    goto done;
  }
  rc = check_size(ci.image_width, ci.image_height, what, "JPEG", err);
  if (rc != GI_OK) goto done;
  /* libjpeg converts grey and YCbCr to RGB but not CMYK: that we do below. */
  int cmyk = ci.jpeg_color_space == JCS_CMYK || ci.jpeg_color_space == JCS_YCCK;
  ci.out_color_space = cmyk ? JCS_CMYK : JCS_RGB;
  jpeg_start_decompress(&ci);
  int n = ci.output_components;
  if (n != (cmyk ? 4 : 3)) {
    rc = gi__fail(err, GI_ERR_FORMAT, "texture '%s': JPEG decodes to %d components", what, n);
    goto done;
  }
  row = gi__malloc((size_t)ci.output_width * (size_t)n);
  if (!row || !accum_grid_init(&a, grid, ci.output_width, ci.output_height, 0)) {
    rc = gi__fail(err, GI_ERR_NOMEM, "texture '%s': out of memory", what);
    goto done;
  }
  /* Photoshop (Adobe marker) stores CMYK inverted, everyone else plain. */
  int inverted = ci.saw_Adobe_marker;
  while (ci.output_scanline < ci.output_height) {
    JSAMPROW rows[1] = {row};
    accum_grid_row(&a, ci.output_scanline, ci.output_height);
    if (jpeg_read_scanlines(&ci, rows, 1) != 1) break;
    const unsigned char *p = row;
    for (JDIMENSION x = 0; x < ci.output_width; x++, p += n) {
      unsigned v[3] = {p[0], p[1], p[2]};
      if (cmyk) {
        unsigned k = inverted ? p[3] : 255u - p[3];
        for (int c = 0; c < 3; c++) v[c] = ((inverted ? p[c] : 255u - p[c]) * k + 127) / 255;
      }
      a.hist[v[0]]++;
      a.hist[256 + v[1]]++;
      a.hist[512 + v[2]]++;
      if (a.grid) accum_grid_px(&a, x, v[0], v[1], v[2]);
    }
    a.pixels += ci.output_width;
  }
  if (a.pixels != (uint64_t)ci.output_width * ci.output_height) {
    rc = gi__fail(err, GI_ERR_FORMAT, "texture '%s': JPEG data ends early", what);
    goto done;
  }
  jpeg_finish_decompress(&ci);
  accum_finish(&a, 0, rgb);
  accum_grid_finish(&a);
done:
  jpeg_destroy_decompress(&ci);
  gi__free(row);
  accum_free(&a);
  return rc;
}

/* --- entry points ---------------------------------------------------- */

void gi__tex_grid_free(gi__tex_grid *g) {
  if (!g) return;
  gi__free(g->rgb);
  memset(g, 0, sizeof *g);
}

gi_result gi__image_average_grid(const void *data, size_t size, const char *what, float rgb[3], gi__tex_grid *grid,
                                 gi_error_info *err) {
  static const unsigned char png_magic[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  static const unsigned char jpeg_magic[3] = {0xff, 0xd8, 0xff};
  static const unsigned char ktx2_magic[12] = {0xab, 'K', 'T', 'X', ' ', '2', '0', 0xbb, '\r', '\n', 0x1a, '\n'};
  if (!what) what = "(unnamed)";
  if (grid) memset(grid, 0, sizeof *grid);
  if (!data || !rgb) return gi__fail(err, GI_ERR_INVALID_ARG, "texture '%s': no data", what);
  gi_result rc;
  if (size >= 8 && memcmp(data, png_magic, 8) == 0) rc = png_average(data, size, what, rgb, grid, err);
  else if (size >= 3 && memcmp(data, jpeg_magic, 3) == 0) rc = jpeg_average(data, size, what, rgb, grid, err);
  else if (size >= 12 && !memcmp(data, ktx2_magic, 12))
    rc = gi__fail(err, GI_ERR_FORMAT, "texture '%s': a KTX2 (Basis Universal) image; only PNG and JPEG are read", what);
  else if (size >= 12 && !memcmp(data, "RIFF", 4) && !memcmp((const char *)data + 8, "WEBP", 4))
    rc = gi__fail(err, GI_ERR_FORMAT, "texture '%s': a WebP image; only PNG and JPEG are read", what);
  else rc = gi__fail(err, GI_ERR_FORMAT, "texture '%s': not a PNG or JPEG image (%zu bytes)", what, size);
  if (rc != GI_OK) gi__tex_grid_free(grid);
  return rc;
}

gi_result gi__image_average(const void *data, size_t size, const char *what, float rgb[3], gi_error_info *err) {
  return gi__image_average_grid(data, size, what, rgb, NULL, err);
}

gi_result gi__texels_average_grid(const void *bgra, uint32_t width, uint32_t height, const char *what, float rgb[3],
                                  gi__tex_grid *grid, gi_error_info *err) {
  if (!what) what = "(unnamed)";
  if (grid) memset(grid, 0, sizeof *grid);
  if (!bgra || !rgb) return gi__fail(err, GI_ERR_INVALID_ARG, "texture '%s': no data", what);
  gi_result rc = check_size(width, height, what, "raw", err);
  if (rc != GI_OK) return rc;
  accum a = {0};
  if (!accum_init(&a, 256) || !accum_grid_init(&a, grid, width, height, 0)) {
    accum_free(&a);
    gi__tex_grid_free(grid);
    return gi__fail(err, GI_ERR_NOMEM, "texture '%s': out of memory", what);
  }
  const unsigned char *p = bgra;
  for (uint32_t y = 0; y < height; y++) {
    accum_grid_row(&a, y, height);
    for (uint32_t x = 0; x < width; x++, p += 4) {
      a.hist[p[2]]++;
      a.hist[256 + p[1]]++;
      a.hist[512 + p[0]]++;
      if (a.grid) accum_grid_px(&a, x, p[2], p[1], p[0]);
    }
  }
  a.pixels = (size_t)width * height;
  accum_finish(&a, 0, rgb);
  accum_grid_finish(&a);
  accum_free(&a);
  return GI_OK;
}

gi_result gi__texels_average(const void *bgra, uint32_t width, uint32_t height, const char *what, float rgb[3],
                             gi_error_info *err) {
  return gi__texels_average_grid(bgra, width, height, what, rgb, NULL, err);
}

/* A texture coordinate in [0, 1] as wrap reads it: the fraction
 * (repeating), held to [0, 1] (clamped), or folded back every other tile
 * (mirrored: 1.2 reads 0.8, -0.2 reads 0.2). */
static double wrap_coord(double x, gi__tex_wrap wrap) {
  if (wrap == GI__TEX_CLAMP) return x < 0 ? 0 : x > 1 ? 1 : x;
  if (wrap == GI__TEX_MIRROR) {
    double t = x - 2 * floor(x / 2); /* [0, 2) */
    return t > 1 ? 2 - t : t;
  }
  return x - floor(x);
}

/* The grid cell under texture coordinate (u, v), v up, each wrapped as
 * its wrap says; a non-finite coordinate (a malformed file's) reads as 0. */
static const float *grid_at(const gi__tex_grid *g, double u, double v, gi__tex_wrap wu, gi__tex_wrap wv) {
  double fu = wrap_coord(u, wu), fv = wrap_coord(v, wv);
  if (!(fu >= 0 && fu <= 1)) fu = 0;
  if (!(fv >= 0 && fv <= 1)) fv = 0;
  int x = (int)(fu * g->w), y = (int)((1.0 - fv) * g->h);
  x = x < 0 ? 0 : x >= g->w ? g->w - 1 : x;
  y = y < 0 ? 0 : y >= g->h ? g->h - 1 : y;
  return &g->rgb[3 * ((size_t)y * (size_t)g->w + (size_t)x)];
}

void gi__tex_grid_triangle(const gi__tex_grid *g, const float uv[3][2], float out[3]) {
  gi__tex_grid_triangle_wrap(g, uv, GI__TEX_REPEAT, GI__TEX_REPEAT, out);
}

void gi__tex_grid_triangle_wrap(const gi__tex_grid *g, const float uv[3][2], gi__tex_wrap wrap_u,
                                gi__tex_wrap wrap_v, float out[3]) {
  /* Subdivided n times a side, the triangle's n^2 small triangles have
   * centroids that weigh it evenly; n grows with its extent in cells. */
  double ext = 0;
  for (int k = 0; k < 2; k++) {
    double lo = fmin(uv[0][k], fmin(uv[1][k], uv[2][k])), hi = fmax(uv[0][k], fmax(uv[1][k], uv[2][k]));
    ext = fmax(ext, (hi - lo) * (k ? g->h : g->w));
  }
  /* n = four times the extent in cells: about 30 points per cell, where
   * a regular lattice against a checker is within a few percent. One
   * point per four cells (n = ext / 2) read Blender's 4 x 4 checker floor
   * all red from its glTF and all blue from its Collada (each half holds
   * both). */
  int n = ext < 0.5 ? 2 : 4 * ext >= GI__TEX_TRI_SPLIT ? GI__TEX_TRI_SPLIT : (int)ceil(4 * ext);
  double sum[3] = {0, 0, 0};
  int count = 0;
  for (int i = 0; i < n; i++)
    for (int j = 0; i + j < n; j++)
      for (int up = 0; up < 2; up++) {
        if (up && i + j == n - 1) continue;
        double a = (i + (up ? 2.0 : 1.0) / 3.0) / n, b = (j + (up ? 2.0 : 1.0) / 3.0) / n, c = 1.0 - a - b;
        const float *t = grid_at(g, a * uv[0][0] + b * uv[1][0] + c * uv[2][0], a * uv[0][1] + b * uv[1][1] +
                                 c * uv[2][1], wrap_u, wrap_v);
        for (int k = 0; k < 3; k++) sum[k] += t[k];
        count++;
      }
  for (int k = 0; k < 3; k++) out[k] = (float)(sum[k] / count);
}

FILE *gi__fopen_read(const char *path) {
  int fd = open(path, O_RDONLY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) return NULL;
  FILE *f = fdopen(fd, "rb");
  if (!f) {
    int e = errno;
    close(fd);
    errno = e;
  }
  return f;
}

gi_result gi__read_file(const char *path, size_t max_size, void **data, size_t *size, gi_error_info *err) {
  *data = NULL;
  *size = 0;
  FILE *f = gi__fopen_read(path);
  if (!f) {
    int e = errno;
    return gi__fail(err, e == ENOENT || e == ENOTDIR ? GI_ERR_NOT_FOUND : GI_ERR_IO, "'%s': cannot open: %s", path,
                    strerror(e));
  }
  struct stat st;
  gi_result rc = GI_OK;
  unsigned char *buf = NULL;
  if (fstat(fileno(f), &st) != 0 || !S_ISREG(st.st_mode)) {
    rc = gi__fail(err, GI_ERR_IO, "'%s' is not a regular file", path);
    goto done;
  }
  if ((uint64_t)st.st_size > max_size) {
    rc = gi__fail(err, GI_ERR_LIMIT, "'%s' is %lld bytes; the limit is %zu", path, (long long)st.st_size, max_size);
    goto done;
  }
  size_t n = (size_t)st.st_size;
  buf = gi__malloc(n ? n : 1);
  if (!buf) {
    rc = gi__fail(err, GI_ERR_NOMEM, "'%s': out of memory for %zu bytes", path, n);
    goto done;
  }
  if (fread(buf, 1, n, f) != n) {
    rc = gi__fail(err, GI_ERR_IO, "'%s': read failed", path);
    goto done;
  }
  *data = buf;
  *size = n;
  buf = NULL;
done:
  gi__free(buf);
  fclose(f);
  return rc;
}
