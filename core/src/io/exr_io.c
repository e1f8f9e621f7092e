/* io/exr_io.c: layered scanline EXR files through the OpenEXR core C API.
 *
 * DESIGN. The writer validates everything first (sizes, channel names,
 * finite samples), so bad input never creates a file. It then writes one
 * scanline part to "<path>.tmp.<pid>" chunk by chunk with the library's
 * encode pipeline and renames the result into place; on any failure the
 * temporary file is removed and a file already at path is left untouched.
 * A path that already ends in ".tmp.<pid>" of this process is the
 * caller's own temporary name: it is written in place (no second name).
 * The core API keeps channels sorted by name, so pipeline channels are
 * matched to the caller's channels by name, never by position.
 *
 * Half conversion is done by the library (float input, HALF channel; it
 * rounds to nearest even). Finite values beyond the half range (+-65504)
 * would become infinities, which viewers and later maths treat as poison,
 * so they are clamped to +-65504 before conversion: a saturated pixel is
 * more useful to a user than a refused bake, but a warning on stderr says
 * how many values were clamped (a 4e6 probe read back as 65504, silently).
 * FLOAT output is stored as is.
 *
 * The reader decodes every channel of part 0 into float planes (half is
 * widened by the library) and keeps every string attribute. Tiled, deep
 * and subsampled files are refused with GI_ERR_FORMAT. OpenEXR's own
 * message reaches the caller through the context's error callback, which
 * keeps the first message per call in a stack-local buffer (current_msg). */
#define _POSIX_C_SOURCE 200809L
#include "gi/gi_exr.h"

#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include <openexr.h>

#include "base/internal.h"

#define HALF_MAX 65504.0f
/* Refuse headers that would need more than this many float samples (8 GiB);
 * a corrupt header must not make us allocate the world. */
#define MAX_READ_SAMPLES ((uint64_t)1 << 31)

/* The first OpenEXR message of one call; lives on the caller's stack. */
typedef struct exr_msg {
  char text[256];
} exr_msg;

/* The calling thread's exr_msg while one of our calls runs. The callback
 * cannot ask the context for its user data: OpenEXR 3.1 reports a failed
 * write of a file's header or offsets while it holds the context's lock,
 * which exr_get_user_data takes again, and the write never returned (a
 * server worker hung on a full disk). The library calls back on the
 * calling thread. */
static _Thread_local exr_msg *current_msg;

static void on_exr_error(exr_const_context_t ctxt, exr_result_t code, const char *msg) {
  (void)ctxt;
  exr_msg *m = current_msg;
  if (!m) return;
  /* Keep the first message: later ones are usually fallout of the first. */
  if (m->text[0]) return;
  snprintf(m->text, sizeof m->text, "%s", msg ? msg : exr_get_default_error_message(code));
  /* Messages can quote raw bytes of a damaged file; keep ours printable. */
  for (char *p = m->text; *p; p++)
    if ((unsigned char)*p < 0x20 || (unsigned char)*p > 0x7e) *p = '?';
}

/* The library's message when it gave one, else its text for the code. */
static const char *why(const exr_msg *m, exr_result_t rv) {
  return m->text[0] ? m->text : exr_get_default_error_message(rv);
}

static exr_compression_t to_exr_compression(gi_exr_compression c) {
  switch (c) {
    case GI_EXR_PIZ: return EXR_COMPRESSION_PIZ;
    case GI_EXR_NONE: return EXR_COMPRESSION_NONE;
    case GI_EXR_ZIP: break;
  }
  return EXR_COMPRESSION_ZIP;
}

/* ------------------------------------------------------------------ write */

static gi_result validate(const char *path, const gi_exr_image *img, gi_error_info *err) {
  if (!path || !path[0]) return gi__fail(err, GI_ERR_INVALID_ARG, "EXR write: empty path");
  if (!img) return gi__fail(err, GI_ERR_INVALID_ARG, "EXR file '%s': no image given", path);
  if (img->width <= 0 || img->height <= 0)
    return gi__fail(err, GI_ERR_INVALID_ARG, "EXR file '%s': size %dx%d, expected both > 0", path,
                    img->width, img->height);
  if (img->compression != GI_EXR_ZIP && img->compression != GI_EXR_PIZ &&
      img->compression != GI_EXR_NONE)
    return gi__fail(err, GI_ERR_INVALID_ARG, "EXR file '%s': unknown compression %d", path,
                    (int)img->compression);
  if (img->num_channels < 1 || !img->channels)
    return gi__fail(err, GI_ERR_EMPTY, "EXR file '%s': no channels", path);
  if (img->num_channels > INT16_MAX)
    return gi__fail(err, GI_ERR_LIMIT, "EXR file '%s': %zu channels, at most %d", path,
                    img->num_channels, INT16_MAX);
  if (img->num_attrs && !img->attrs)
    return gi__fail(err, GI_ERR_INVALID_ARG, "EXR file '%s': attrs is NULL", path);
  size_t npix = (size_t)img->width * (size_t)img->height;
  for (size_t c = 0; c < img->num_channels; c++) {
    const gi_exr_channel *ch = &img->channels[c];
    if (!ch->name || !ch->name[0])
      return gi__fail(err, GI_ERR_INVALID_ARG, "EXR file '%s': channel %zu has an empty name", path, c);
    if (strlen(ch->name) > 255)
      return gi__fail(err, GI_ERR_INVALID_ARG, "EXR file '%s': channel name '%.40s...' is longer than 255",
                      path, ch->name);
    for (size_t d = 0; d < c; d++)
      if (strcmp(img->channels[d].name, ch->name) == 0)
        return gi__fail(err, GI_ERR_INVALID_ARG, "EXR file '%s': channel '%s' given twice", path, ch->name);
    if (!ch->data)
      return gi__fail(err, GI_ERR_INVALID_ARG, "EXR file '%s': channel '%s' has no data", path, ch->name);
    for (size_t i = 0; i < npix; i++)
      if (!isfinite(ch->data[i]))
        return gi__fail(err, GI_ERR_NONFINITE, "EXR file '%s': channel '%s' pixel (%zu,%zu) is %s", path,
                        ch->name, i % (size_t)img->width, i / (size_t)img->width,
                        isnan(ch->data[i]) ? "NaN" : "infinite");
  }
  for (size_t a = 0; a < img->num_attrs; a++) {
    const gi_exr_attr *at = &img->attrs[a];
    if (!at->name || !at->name[0] || !at->value)
      return gi__fail(err, GI_ERR_INVALID_ARG, "EXR file '%s': attribute %zu has an empty name or no value",
                      path, a);
  }
  return GI_OK;
}

static const gi_exr_channel *find_channel(const gi_exr_image *img, const char *name) {
  for (size_t c = 0; c < img->num_channels; c++)
    if (strcmp(img->channels[c].name, name) == 0) return &img->channels[c];
  return NULL;
}

/* OpenEXR 3.1's ZIP encoder keeps the zlib bytes when they are exactly as
 * long as the raw chunk, and every reader then takes them for raw pixels:
 * small probe images came back as garbage (upstream issue 2306, fixed in
 * 3.4). This wraps the library's compressor with the fix: a chunk that
 * compression does not shrink is stored raw. */
typedef struct {
  exr_result_t (*compress)(exr_encode_pipeline_t *enc);
} zip_guard;

static exr_result_t compress_or_raw(exr_encode_pipeline_t *enc) {
  const zip_guard *g = enc->encoding_user_data;
  exr_result_t rv = g->compress(enc);
  if (rv == EXR_ERR_SUCCESS && enc->compressed_bytes >= enc->packed_bytes && enc->compressed_buffer &&
      enc->packed_buffer) {
    memcpy(enc->compressed_buffer, enc->packed_buffer, enc->packed_bytes);
    enc->compressed_bytes = enc->packed_bytes;
  }
  return rv;
}

/* Writes every chunk of the part. For HALF output the chunk's rows are first
 * copied into `scratch` with the clamp described at the top of the file. */
static exr_result_t write_chunks(exr_context_t ctx, int part, const gi_exr_image *img, float *scratch,
                                 int lines_per_chunk, const char **what, size_t *clamped) {
  exr_encode_pipeline_t enc = EXR_ENCODE_PIPELINE_INITIALIZER;
  exr_result_t rv = EXR_ERR_SUCCESS;
  int started = 0;
  zip_guard guard = {NULL};
  size_t w = (size_t)img->width;
  for (int y = 0; y < img->height && rv == EXR_ERR_SUCCESS; y += lines_per_chunk) {
    exr_chunk_info_t cinfo;
    *what = "preparing a chunk";
    rv = exr_write_scanline_chunk_info(ctx, part, y, &cinfo);
    if (rv != EXR_ERR_SUCCESS) break;
    rv = started ? exr_encoding_update(ctx, part, &cinfo, &enc)
                 : exr_encoding_initialize(ctx, part, &cinfo, &enc);
    if (rv != EXR_ERR_SUCCESS) break;
    started = 1;
    for (int c = 0; c < enc.channel_count; c++) {
      exr_coding_channel_info_t *ec = &enc.channels[c];
      const gi_exr_channel *src = find_channel(img, ec->channel_name);
      if (!src) { /* cannot happen: the header's channels are ours */
        rv = EXR_ERR_INVALID_ARGUMENT;
        *what = "matching channels";
        break;
      }
      const float *rows = src->data + (size_t)cinfo.start_y * w;
      if (img->use_half) {
        float *dst = scratch + (size_t)c * (size_t)lines_per_chunk * w;
        size_t n = (size_t)cinfo.height * w;
        for (size_t i = 0; i < n; i++) {
          dst[i] = fminf(fmaxf(rows[i], -HALF_MAX), HALF_MAX);
          *clamped += dst[i] != rows[i];
        }
        rows = dst;
      }
      ec->user_bytes_per_element = 4;
      ec->user_data_type = EXR_PIXEL_FLOAT;
      ec->user_pixel_stride = 4;
      ec->user_line_stride = (int32_t)(4 * w);
      ec->encode_from_ptr = (const uint8_t *)rows;
    }
    if (rv != EXR_ERR_SUCCESS) break;
    if (y == 0) {
      *what = "choosing encoders";
      rv = exr_encoding_choose_default_routines(ctx, part, &enc);
      if (rv != EXR_ERR_SUCCESS) break;
      if (enc.compress_fn) {
        guard.compress = enc.compress_fn;
        enc.encoding_user_data = &guard;
        enc.compress_fn = compress_or_raw;
      }
    }
    *what = "encoding a chunk";
    rv = exr_encoding_run(ctx, part, &enc);
  }
  if (started) exr_encoding_destroy(ctx, &enc);
  return rv;
}

static gi_result map_write_error(exr_result_t rv) {
  switch (rv) {
    case EXR_ERR_OUT_OF_MEMORY: return GI_ERR_NOMEM;
    case EXR_ERR_FILE_ACCESS:
    case EXR_ERR_WRITE_IO: return GI_ERR_IO;
    default: return GI_ERR_BACKEND;
  }
}

static gi_result write_file(const char *path, const gi_exr_image *img, gi_error_info *err) {
  gi_result r = validate(path, img, err);
  if (r != GI_OK) return r;

  char tmp[4096], own[32];
  if (snprintf(tmp, sizeof tmp, "%s.tmp.%ld", path, (long)getpid()) >= (int)sizeof tmp)
    return gi__fail(err, GI_ERR_INVALID_ARG, "EXR file '%.200s...': path too long", path);
  /* A path that is this process's temporary name already is its caller's
   * (who renames it): written in place, so a kill leaves one temporary name,
   * not "<out>.tmp.<pid>.tmp.<pid>" beside it. */
  snprintf(own, sizeof own, ".tmp.%ld", (long)getpid());
  size_t np = strlen(path), no = strlen(own);
  int in_place = np > no && !strcmp(path + np - no, own);
  if (in_place) snprintf(tmp, sizeof tmp, "%s", path);

  exr_msg msg = {{0}};
  current_msg = &msg; /* until the public call returns */
  exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
  init.error_handler_fn = on_exr_error;
  init.user_data = &msg;

  exr_context_t ctx = NULL;
  float *scratch = NULL;
  const char *what = "creating the file";
  int part = 0;
  exr_result_t rv = exr_start_write(&ctx, tmp, EXR_WRITE_FILE_DIRECTLY, &init);
  if (rv != EXR_ERR_SUCCESS) {
    ctx = NULL;
    goto fail;
  }
  what = "adding the part";
  rv = exr_add_part(ctx, NULL, EXR_STORAGE_SCANLINE, &part);
  if (rv != EXR_ERR_SUCCESS) goto fail;
  what = "setting the required attributes";
  rv = exr_initialize_required_attr_simple(ctx, part, img->width, img->height,
                                           to_exr_compression(img->compression));
  if (rv != EXR_ERR_SUCCESS) goto fail;
  exr_pixel_type_t ptype = img->use_half ? EXR_PIXEL_HALF : EXR_PIXEL_FLOAT;
  what = "adding a channel";
  for (size_t c = 0; c < img->num_channels; c++) {
    /* exr_add_channel keeps the list sorted by name, as the format requires. */
    rv = exr_add_channel(ctx, part, img->channels[c].name, ptype, EXR_PERCEPTUALLY_LOGARITHMIC, 1, 1);
    if (rv != EXR_ERR_SUCCESS) goto fail;
  }
  what = "setting a string attribute";
  for (size_t a = 0; a < img->num_attrs; a++) {
    rv = exr_attr_set_string(ctx, part, img->attrs[a].name, img->attrs[a].value);
    if (rv != EXR_ERR_SUCCESS) goto fail;
  }
  what = "writing the header";
  rv = exr_write_header(ctx);
  if (rv != EXR_ERR_SUCCESS) goto fail;

  int32_t lines = 1;
  what = "querying the chunk layout";
  rv = exr_get_scanlines_per_chunk(ctx, part, &lines);
  if (rv != EXR_ERR_SUCCESS) goto fail;
  if (lines < 1) lines = 1;
  if (img->use_half) {
    scratch = gi__malloc(img->num_channels * (size_t)lines * (size_t)img->width * sizeof *scratch);
    if (!scratch) {
      r = gi__fail(err, GI_ERR_NOMEM, "EXR file '%s': out of memory for a %d-line chunk", path, lines);
      goto fail_cleanup;
    }
  }
  size_t clamped = 0;
  rv = write_chunks(ctx, part, img, scratch, lines, &what, &clamped);
  if (rv != EXR_ERR_SUCCESS) goto fail;

  /* exr_finish writes the chunk offset table: its result matters. */
  what = "finishing the file";
  rv = exr_finish(&ctx);
  ctx = NULL;
  if (rv != EXR_ERR_SUCCESS) goto fail;
  gi__free(scratch);
  if (!in_place && rename(tmp, path) != 0) {
    int e = errno;
    unlink(tmp);
    return gi__fail(err, GI_ERR_IO, "EXR file '%s': cannot rename '%s' into place: %s", path, tmp, strerror(e));
  }
  if (clamped)
    fprintf(stderr, "gi: warning: EXR file '%s': %zu values beyond the half-float range were stored as +-65504; "
            "write it as float to keep them\n", path, clamped);
  return GI_OK;

fail:
  r = gi__fail(err, map_write_error(rv), "EXR file '%s': %s failed: %s", path, what, why(&msg, rv));
fail_cleanup:
  if (ctx) exr_finish(&ctx);
  gi__free(scratch);
  unlink(tmp);
  return r;
}

/* ------------------------------------------------------------------- read */

struct gi_exr_file {
  int width, height;
  gi_exr_compression compression;
  size_t num_channels;
  char **names;
  int *is_half;
  float **planes;
  size_t num_attrs;
  char **attr_names;
  char **attr_values;
};

void gi_exr_file_free(gi_exr_file *f) {
  if (!f) return;
  for (size_t c = 0; c < f->num_channels; c++) {
    if (f->names) gi__free(f->names[c]);
    if (f->planes) gi__free(f->planes[c]);
  }
  for (size_t a = 0; a < f->num_attrs; a++) {
    gi__free(f->attr_names[a]);
    gi__free(f->attr_values[a]);
  }
  gi__free(f->names);
  gi__free(f->is_half);
  gi__free(f->planes);
  gi__free(f->attr_names);
  gi__free(f->attr_values);
  gi__free(f);
}

static gi_result map_read_error(exr_result_t rv) {
  switch (rv) {
    case EXR_ERR_OUT_OF_MEMORY: return GI_ERR_NOMEM;
    case EXR_ERR_FILE_ACCESS: return GI_ERR_IO;
    /* A short read from a regular file means it is truncated. */
    default: return GI_ERR_FORMAT;
  }
}

static char *dup_n(const char *s, size_t n) {
  char *d = gi__malloc(n + 1);
  if (d) {
    memcpy(d, s, n);
    d[n] = '\0';
  }
  return d;
}

/* Copies every string attribute of the part. */
static gi_result read_attrs(exr_context_t ctx, gi_exr_file *f, const char *path, gi_error_info *err) {
  int32_t n = 0;
  if (exr_get_attribute_count(ctx, 0, &n) != EXR_ERR_SUCCESS || n <= 0) return GI_OK;
  f->attr_names = gi__calloc((size_t)n, sizeof *f->attr_names);
  f->attr_values = gi__calloc((size_t)n, sizeof *f->attr_values);
  if (!f->attr_names || !f->attr_values)
    return gi__fail(err, GI_ERR_NOMEM, "EXR file '%s': out of memory for attributes", path);
  for (int32_t i = 0; i < n; i++) {
    const exr_attribute_t *at = NULL;
    if (exr_get_attribute_by_index(ctx, 0, EXR_ATTR_LIST_FILE_ORDER, i, &at) != EXR_ERR_SUCCESS || !at)
      continue;
    if (at->type != EXR_ATTR_STRING || !at->string) continue;
    size_t k = f->num_attrs;
    f->attr_names[k] = dup_n(at->name, strlen(at->name));
    f->attr_values[k] = dup_n(at->string->str ? at->string->str : "",
                              at->string->str && at->string->length > 0 ? (size_t)at->string->length : 0);
    f->num_attrs++; /* counted before the check so gi__free() sees both slots */
    if (!f->attr_names[k] || !f->attr_values[k])
      return gi__fail(err, GI_ERR_NOMEM, "EXR file '%s': out of memory for attributes", path);
  }
  return GI_OK;
}

/* Decodes every chunk into the float planes of f. */
static exr_result_t read_chunks(exr_context_t ctx, gi_exr_file *f, const exr_attr_box2i_t *dw,
                                const char **what) {
  exr_decode_pipeline_t dec = EXR_DECODE_PIPELINE_INITIALIZER;
  exr_result_t rv = EXR_ERR_SUCCESS;
  int32_t lines = 1;
  int started = 0;
  *what = "querying the chunk layout";
  rv = exr_get_scanlines_per_chunk(ctx, 0, &lines);
  if (rv != EXR_ERR_SUCCESS) return rv;
  if (lines < 1) lines = 1;
  size_t w = (size_t)f->width;
  for (int64_t y = dw->min.y; y <= dw->max.y && rv == EXR_ERR_SUCCESS; y += lines) {
    exr_chunk_info_t cinfo;
    *what = "reading a chunk table entry";
    rv = exr_read_scanline_chunk_info(ctx, 0, (int)y, &cinfo);
    if (rv != EXR_ERR_SUCCESS) break;
    *what = "preparing a chunk";
    rv = started ? exr_decoding_update(ctx, 0, &cinfo, &dec) : exr_decoding_initialize(ctx, 0, &cinfo, &dec);
    if (rv != EXR_ERR_SUCCESS) break;
    /* Chunk rows must lie inside the data window, or we would write outside a plane. */
    if (cinfo.start_y < dw->min.y || cinfo.height < 0 ||
        (int64_t)cinfo.start_y + cinfo.height - 1 > (int64_t)dw->max.y) {
      rv = EXR_ERR_CORRUPT_CHUNK;
      *what = "checking a chunk's rows";
      break;
    }
    started = 1;
    for (int c = 0; c < dec.channel_count; c++) {
      exr_coding_channel_info_t *dc = &dec.channels[c];
      size_t row0 = (size_t)(cinfo.start_y - dw->min.y);
      /* Match by name: the pipeline's order is the library's business. */
      float *plane = (float *)gi_exr_file_channel(f, dc->channel_name);
      if (!plane) {
        rv = EXR_ERR_INCORRECT_CHUNK;
        *what = "matching channels";
        break;
      }
      dc->user_bytes_per_element = 4;
      dc->user_data_type = EXR_PIXEL_FLOAT;
      dc->user_pixel_stride = 4;
      dc->user_line_stride = (int32_t)(4 * w);
      dc->decode_to_ptr = (uint8_t *)(plane + row0 * w);
    }
    if (rv != EXR_ERR_SUCCESS) break;
    *what = "choosing decoders";
    rv = exr_decoding_choose_default_routines(ctx, 0, &dec);
    if (rv != EXR_ERR_SUCCESS) break;
    *what = "decoding a chunk";
    rv = exr_decoding_run(ctx, 0, &dec);
  }
  if (started) exr_decoding_destroy(ctx, &dec);
  return rv;
}

static gi_result read_file(const char *path, gi_exr_file **out, gi_error_info *err) {
  if (out) *out = NULL;
  if (!path || !path[0] || !out) return gi__fail(err, GI_ERR_INVALID_ARG, "EXR read: empty path or out");
  struct stat st;
  if (stat(path, &st) != 0) {
    int e = errno;
    return gi__fail(err, e == ENOENT ? GI_ERR_NOT_FOUND : GI_ERR_IO, "EXR file '%s': %s", path, strerror(e));
  }
  if (!S_ISREG(st.st_mode)) return gi__fail(err, GI_ERR_IO, "EXR file '%s': not a regular file", path);
  if (st.st_size == 0) return gi__fail(err, GI_ERR_FORMAT, "EXR file '%s': file is empty", path);

  exr_msg msg = {{0}};
  current_msg = &msg; /* until the public call returns */
  exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
  init.error_handler_fn = on_exr_error;
  init.user_data = &msg;
  /* A damaged file should fail, not be half-read by guessing chunk positions. */
  init.flags = EXR_CONTEXT_FLAG_DISABLE_CHUNK_RECONSTRUCTION;

  gi_result r = GI_OK;
  gi_exr_file *f = NULL;
  exr_context_t ctx = NULL;
  const char *what = "opening";
  exr_result_t rv = exr_start_read(&ctx, path, &init);
  if (rv != EXR_ERR_SUCCESS) {
    ctx = NULL;
    goto fail;
  }
  exr_storage_t storage;
  what = "reading the part type";
  rv = exr_get_storage(ctx, 0, &storage);
  if (rv != EXR_ERR_SUCCESS) goto fail;
  if (storage != EXR_STORAGE_SCANLINE) {
    r = gi__fail(err, GI_ERR_FORMAT, "EXR file '%s': only flat scanline images are supported (%s)", path,
                 storage == EXR_STORAGE_TILED ? "this one is tiled" : "this one is deep");
    goto cleanup;
  }
  exr_attr_box2i_t dw;
  const exr_attr_chlist_t *chl = NULL;
  exr_compression_t comp;
  what = "reading the header";
  if ((rv = exr_get_data_window(ctx, 0, &dw)) != EXR_ERR_SUCCESS ||
      (rv = exr_get_channels(ctx, 0, &chl)) != EXR_ERR_SUCCESS ||
      (rv = exr_get_compression(ctx, 0, &comp)) != EXR_ERR_SUCCESS)
    goto fail;
  int64_t w64 = (int64_t)dw.max.x - dw.min.x + 1, h64 = (int64_t)dw.max.y - dw.min.y + 1;
  if (w64 <= 0 || h64 <= 0 || !chl || chl->num_channels <= 0) {
    r = gi__fail(err, GI_ERR_FORMAT, "EXR file '%s': empty data window or no channels", path);
    goto cleanup;
  }
  if ((uint64_t)w64 * (uint64_t)h64 * (uint64_t)chl->num_channels > MAX_READ_SAMPLES) {
    r = gi__fail(err, GI_ERR_LIMIT, "EXR file '%s': %lldx%lld with %d channels is too large", path,
                 (long long)w64, (long long)h64, chl->num_channels);
    goto cleanup;
  }

  f = gi__calloc(1, sizeof *f);
  if (!f) goto nomem;
  f->width = (int)w64;
  f->height = (int)h64;
  /* ZIPS is ZIP one line per chunk. Other codecs (RLE, PXR24, B44, DWA)
   * decode fine but have no gi_exr_compression value: reported as ZIP. */
  f->compression = comp == EXR_COMPRESSION_PIZ ? GI_EXR_PIZ : comp == EXR_COMPRESSION_NONE ? GI_EXR_NONE : GI_EXR_ZIP;
  size_t nch = (size_t)chl->num_channels, npix = (size_t)w64 * (size_t)h64;
  f->names = gi__calloc(nch, sizeof *f->names);
  f->is_half = gi__calloc(nch, sizeof *f->is_half);
  f->planes = gi__calloc(nch, sizeof *f->planes);
  if (!f->names || !f->is_half || !f->planes) goto nomem;
  f->num_channels = nch;
  for (size_t c = 0; c < nch; c++) {
    const exr_attr_chlist_entry_t *e = &chl->entries[c];
    if (e->x_sampling != 1 || e->y_sampling != 1) {
      r = gi__fail(err, GI_ERR_FORMAT, "EXR file '%s': channel '%.*s' is subsampled (%d,%d); not supported",
                   path, (int)e->name.length, e->name.str, e->x_sampling, e->y_sampling);
      goto cleanup;
    }
    f->names[c] = dup_n(e->name.str, (size_t)e->name.length);
    /* Zeroed planes: a channel the decoder skips reads back as 0, not garbage. */
    f->planes[c] = gi__calloc(npix, sizeof(float));
    if (!f->names[c] || !f->planes[c]) goto nomem;
    f->is_half[c] = e->pixel_type == EXR_PIXEL_HALF;
  }
  if ((r = read_attrs(ctx, f, path, err)) != GI_OK) goto cleanup;
  rv = read_chunks(ctx, f, &dw, &what);
  if (rv != EXR_ERR_SUCCESS) goto fail;
  exr_finish(&ctx);
  *out = f;
  return GI_OK;

nomem:
  r = gi__fail(err, GI_ERR_NOMEM, "EXR file '%s': out of memory", path);
  goto cleanup;
fail:
  r = gi__fail(err, map_read_error(rv), "EXR file '%s': %s failed: %s", path, what, why(&msg, rv));
cleanup:
  if (ctx) exr_finish(&ctx);
  gi_exr_file_free(f);
  return r;
}

int gi_exr_file_width(const gi_exr_file *f) { return f ? f->width : 0; }
int gi_exr_file_height(const gi_exr_file *f) { return f ? f->height : 0; }
size_t gi_exr_file_num_channels(const gi_exr_file *f) { return f ? f->num_channels : 0; }

const char *gi_exr_file_channel_name(const gi_exr_file *f, size_t i) {
  return f && i < f->num_channels ? f->names[i] : NULL;
}

int gi_exr_file_channel_is_half(const gi_exr_file *f, size_t i) {
  return f && i < f->num_channels ? f->is_half[i] : 0;
}

const float *gi_exr_file_channel(const gi_exr_file *f, const char *name) {
  if (!f || !name) return NULL;
  for (size_t c = 0; c < f->num_channels; c++)
    if (strcmp(f->names[c], name) == 0) return f->planes[c];
  return NULL;
}

const char *gi_exr_file_attr(const gi_exr_file *f, const char *name) {
  if (!f || !name) return NULL;
  for (size_t a = 0; a < f->num_attrs; a++)
    if (strcmp(f->attr_names[a], name) == 0) return f->attr_values[a];
  return NULL;
}

gi_exr_compression gi_exr_file_compression(const gi_exr_file *f) { return f ? f->compression : GI_EXR_ZIP; }

/* The public calls: the callback's message buffer is the call's own. */
gi_result gi_exr_write(const char *path, const gi_exr_image *img, gi_error_info *err) {
  exr_msg *outer = current_msg;
  gi_result r = write_file(path, img, err);
  current_msg = outer;
  return r;
}

gi_result gi_exr_read(const char *path, gi_exr_file **out, gi_error_info *err) {
  exr_msg *outer = current_msg;
  gi_result r = read_file(path, out, err);
  current_msg = outer;
  return r;
}
