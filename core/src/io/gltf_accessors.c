/* io/gltf_accessors.c: a glTF accessor's numbers, read without assimp (see
 * the header for why). */
#define _DEFAULT_SOURCE
#include "io/gltf_accessors.h"
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "base/internal.h"
#include "io/texture_image.h" /* gi__read_file */

enum { GLTF_BYTE = 5120, GLTF_SHORT = 5122, GLTF_FLOAT = 5126 };

/* A buffer's bytes: owned (a decoded data: URI or a file read) or
 * borrowed (the .glb chunk). */
typedef struct {
  unsigned char *owned;
  const unsigned char *p;
  size_t len;
} bytes;

static int b64_value(unsigned char c) {
  if (c >= 'A' && c <= 'Z') return c - 'A';
  if (c >= 'a' && c <= 'z') return c - 'a' + 26;
  if (c >= '0' && c <= '9') return c - '0' + 52;
  if (c == '+' || c == '-') return 62;
  if (c == '/' || c == '_') return 63;
  return -1;
}

/* Base64 text (padding optional) into a new buffer; -1 on a bad character. */
static int b64_decode(const char *s, bytes *out) {
  size_t n = strlen(s);
  out->owned = gi__malloc(n / 4 * 3 + 3);
  if (!out->owned) return -2;
  size_t k = 0;
  uint32_t acc = 0;
  int bits = 0;
  for (size_t i = 0; i < n && s[i] != '='; i++) {
    int v = b64_value((unsigned char)s[i]);
    if (v < 0) return -1;
    acc = acc << 6 | (uint32_t)v;
    bits += 6;
    if (bits >= 8) bits -= 8, out->owned[k++] = (unsigned char)(acc >> bits);
  }
  out->p = out->owned, out->len = k;
  return 0;
}

/* A relative URI beside the glTF (percent escapes decoded), read whole:
 * 0, -1 when it cannot be read, -2 out of memory. */
static int read_beside(const char *gltf, const char *uri, bytes *out) {
  char rel[4096], full[8192];
  size_t k = 0;
  for (size_t i = 0; uri[i] && k + 1 < sizeof rel; i++) {
    unsigned hex;
    if (uri[i] == '%' && sscanf(uri + i + 1, "%2x", &hex) == 1) rel[k++] = (char)hex, i += 2;
    else rel[k++] = uri[i];
  }
  rel[k] = 0;
  const char *slash = strrchr(gltf, '/');
  int dl = slash ? (int)(slash - gltf + 1) : 0;
  if (snprintf(full, sizeof full, "%.*s%s", dl, gltf, rel) >= (int)sizeof full) return -1;
  void *data = NULL;
  gi_error_info e = {0};
  gi_result r = gi__read_file(full, SIZE_MAX, &data, &out->len, &e);
  if (r != GI_OK) return r == GI_ERR_NOMEM ? -2 : -1;
  out->owned = data, out->p = out->owned;
  return 0;
}

/* A buffer as read (or not yet: state 0; 1 read, -1 unreadable). */
struct gi__gltf_buf {
  bytes b;
  int state;
};

void gi__gltf_bin_fini(gi__gltf_bin *bin) {
  for (size_t i = 0; i < bin->ncache; i++) gi__free(bin->cache[i].b.owned);
  gi__free(bin->cache);
  bin->cache = NULL, bin->ncache = 0;
}

/* Buffer b's bytes into *out, borrowed from bin's cache (read the first
 * time): 0, -1 when it cannot be read, -2 out of memory. */
static int buffer_bytes(json_t *root, gi__gltf_bin *bin, json_int_t b, bytes *out) {
  json_t *bufs = json_object_get(root, "buffers"), *buf = json_array_get(bufs, b < 0 ? SIZE_MAX : (size_t)b);
  if (!json_is_object(buf)) return -1;
  if (!bin->cache) {
    if (!(bin->cache = gi__calloc(json_array_size(bufs), sizeof *bin->cache))) return -2;
    bin->ncache = json_array_size(bufs);
  }
  struct gi__gltf_buf *c = &bin->cache[b];
  if (c->state == 0) {
    const char *uri = json_string_value(json_object_get(buf, "uri"));
    int r = -1;
    if (!uri) {
      if (b == 0 && bin->glb_bin) c->b.p = bin->glb_bin, c->b.len = bin->glb_bin_len, r = 0;
    } else if (!strncmp(uri, "data:", 5)) {
      const char *comma = strstr(uri, ";base64,");
      r = comma ? b64_decode(comma + 8, &c->b) : -1;
    } else {
      r = read_beside(bin->path, uri, &c->b);
    }
    if (r == -2) return -2; /* not remembered: out of memory may pass */
    c->state = r == 0 ? 1 : -1;
  }
  if (c->state < 0) return -1;
  *out = (bytes){.p = c->b.p, .len = c->b.len};
  return 0;
}

static double component(const unsigned char *p, int type) {
  if (type == GLTF_FLOAT) {
    float f;
    memcpy(&f, p, 4);
    return f;
  }
  if (type == GLTF_SHORT) {
    int16_t v = (int16_t)(p[0] | p[1] << 8);
    return fmax(v / 32767.0, -1.0);
  }
  return fmax((int8_t)p[0] / 127.0, -1.0);
}

static uint32_t le32(const unsigned char *p) {
  return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static json_int_t int_member(json_t *o, const char *key, json_int_t dflt) {
  json_t *v = json_object_get(o, key);
  return json_is_integer(v) ? json_integer_value(v) : v ? -1 : dflt;
}

gi_result gi__gltf_accessor_read(json_t *root, gi__gltf_bin *bin, json_int_t index, int ncomp, int normalized_ok,
                                 size_t max_count, const char *what, double **out, size_t *count, gi_error_info *err) {
  *out = NULL, *count = 0;
  const char *path = bin->path;
  json_t *acc = json_array_get(json_object_get(root, "accessors"), index < 0 ? SIZE_MAX : (size_t)index);
  if (!json_is_object(acc))
    return gi__fail(err, GI_ERR_FORMAT, "scene file '%s': %s: accessor %lld does not exist", path, what,
                    (long long)index);
  const char *type = json_string_value(json_object_get(acc, "type"));
  json_int_t ct = int_member(acc, "componentType", -1), n = int_member(acc, "count", -1);
  json_int_t view = int_member(acc, "bufferView", -1), aoff = int_member(acc, "byteOffset", 0);
  int normalized = json_is_true(json_object_get(acc, "normalized"));
  char want[8];
  snprintf(want, sizeof want, "VEC%d", ncomp);
  int ok_type = ct == GLTF_FLOAT || (normalized_ok && normalized && (ct == GLTF_BYTE || ct == GLTF_SHORT));
  if (!type || strcmp(type, want) || !ok_type || n < 0 || aoff < 0 || json_object_get(acc, "sparse"))
    return gi__fail(err, GI_ERR_FORMAT,
                    "scene file '%s': %s: accessor %lld: expected a %s of floats%s with a count, not sparse", path,
                    what, (long long)index, want, normalized_ok ? " (or normalized bytes or shorts)" : "");
  if ((uint64_t)n > max_count)
    return gi__fail(err, GI_ERR_LIMIT, "scene file '%s': %s: accessor %lld has %lld elements; the limit is %zu", path,
                    what, (long long)index, (long long)n, max_count);
  json_t *bv = json_array_get(json_object_get(root, "bufferViews"), view < 0 ? SIZE_MAX : (size_t)view);
  json_int_t boff = int_member(bv, "byteOffset", 0), blen = int_member(bv, "byteLength", -1);
  json_int_t stride = int_member(bv, "byteStride", 0), buf = int_member(bv, "buffer", -1);
  size_t csize = ct == GLTF_FLOAT ? 4 : ct == GLTF_SHORT ? 2 : 1, esize = csize * (size_t)ncomp;
  /* The spec's stride is at most 252; a larger one (or an offset past the
   * view) could wrap the end computed below. */
  if (!json_is_object(bv) || boff < 0 || blen < 0 || stride < 0 || stride > 252 || buf < 0 ||
      (stride && (size_t)stride < esize) || aoff > blen)
    return gi__fail(err, GI_ERR_FORMAT, "scene file '%s': %s: accessor %lld: its bufferView %lld is missing or bad",
                    path, what, (long long)index, (long long)view);
  size_t step = stride ? (size_t)stride : esize;
  /* The last element's end within the view, the view within its buffer. */
  uint64_t need = n ? (uint64_t)aoff + (uint64_t)(n - 1) * step + esize : 0;
  bytes b = {0};
  int got = buffer_bytes(root, bin, buf, &b);
  gi_result rc = GI_OK;
  if (got == -2) {
    rc = gi__fail(err, GI_ERR_NOMEM, "scene file '%s': out of memory reading %s", path, what);
  } else if (got < 0) {
    rc = gi__fail(err, GI_ERR_FORMAT, "scene file '%s': %s: buffer %lld cannot be read", path, what, (long long)buf);
  } else if (need > (uint64_t)blen || (uint64_t)boff + (uint64_t)blen > b.len) {
    rc = gi__fail(err, GI_ERR_FORMAT, "scene file '%s': %s: accessor %lld reaches past its buffer's end", path, what,
                  (long long)index);
  } else if (n && !(*out = gi__malloc((size_t)n * (size_t)ncomp * sizeof **out))) {
    rc = gi__fail(err, GI_ERR_NOMEM, "scene file '%s': out of memory reading %s", path, what);
  } else {
    const unsigned char *p = b.p + boff + aoff;
    for (json_int_t i = 0; i < n; i++)
      for (int c = 0; c < ncomp; c++) (*out)[i * ncomp + c] = component(p + (size_t)i * step + (size_t)c * csize, (int)ct);
    *count = (size_t)n;
  }
  return rc;
}

int gi__gltf_indices_past(json_t *root, gi__gltf_bin *bin, json_int_t index, uint64_t vertices, size_t *at,
                          uint64_t *value, gi_error_info *err) {
  *at = SIZE_MAX, *value = 0;
  json_t *acc = json_array_get(json_object_get(root, "accessors"), index < 0 ? SIZE_MAX : (size_t)index);
  json_int_t ct = int_member(acc, "componentType", -1), n = int_member(acc, "count", -1);
  json_int_t view = int_member(acc, "bufferView", -1), aoff = int_member(acc, "byteOffset", 0);
  const char *type = json_string_value(json_object_get(acc, "type"));
  size_t size = ct == 5121 ? 1 : ct == 5123 ? 2 : ct == 5125 ? 4 : 0;
  json_t *bv = json_array_get(json_object_get(root, "bufferViews"), view < 0 ? SIZE_MAX : (size_t)view);
  json_int_t boff = int_member(bv, "byteOffset", 0), blen = int_member(bv, "byteLength", -1);
  json_int_t stride = int_member(bv, "byteStride", 0), buf = int_member(bv, "buffer", -1);
  if (!size || !type || strcmp(type, "SCALAR") || n < 0 || aoff < 0 || json_object_get(acc, "sparse") ||
      !json_is_object(bv) || boff < 0 || blen < 0 || stride < 0 || stride > 252 || buf < 0 || aoff > blen)
    return 0;
  size_t step = stride ? (size_t)stride : size;
  uint64_t need = n ? (uint64_t)aoff + (uint64_t)(n - 1) * step + size : 0;
  bytes b = {0};
  int got = buffer_bytes(root, bin, buf, &b);
  if (got == -2) {
    gi__fail(err, GI_ERR_NOMEM, "scene file '%s': out of memory reading buffer %lld", bin->path, (long long)buf);
    return -1;
  }
  if (got < 0 || need > (uint64_t)blen || (uint64_t)boff + (uint64_t)blen > b.len) return 0;
  const unsigned char *p = b.p + boff + aoff;
  for (json_int_t i = 0; i < n; i++, p += step) {
    uint64_t v = size == 1 ? p[0] : size == 2 ? (uint64_t)(p[0] | p[1] << 8) : (uint64_t)le32(p);
    if (v >= vertices) {
      *at = (size_t)i, *value = v;
      break;
    }
  }
  return 1;
}
