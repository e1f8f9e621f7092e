/* io/fbx_check.c: an FBX file's object connections, checked for loops
 * before assimp follows them (fbx_check.h says why).
 *
 * Binary FBX (the "Kaydara FBX Binary" header): node records, each with
 * its end offset, property count and length, name, properties and nested
 * records; the top-level "Connections" record holds one "C" record per
 * connection, whose properties are a type string and the child's and the
 * parent's ids (64-bit integers). ASCII FBX: lines `C: "OO",child,parent`.
 * Either way the connections become edges child -> parent, and a
 * topological sort (Kahn) finds whether any loop. */
#include "io/fbx_check.h"
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include "base/internal.h"
#include "io/texture_image.h" /* gi__read_file */

typedef struct {
  int64_t *e; /* child, parent pairs */
  size_t n, cap;
} edges;

static int add_edge(edges *g, int64_t child, int64_t parent) {
  if (g->n == g->cap) {
    size_t nc = g->cap ? 2 * g->cap : 256;
    int64_t *ne = gi__realloc(g->e, nc * 2 * sizeof *ne);
    if (!ne) return 0;
    g->e = ne, g->cap = nc;
  }
  g->e[2 * g->n] = child, g->e[2 * g->n + 1] = parent;
  g->n++;
  return 1;
}

/* ---- binary ----------------------------------------------------------------- */

/* What assimp compares to take a file for binary (18 bytes: whatever
 * follows, even "Binary! ", it tokenizes as binary). */
#define FBX_MAGIC "Kaydara FBX Binary"
#define FBX_HEADER 27 /* magic, NUL, 0x1a 0x00, version */

typedef struct {
  const unsigned char *d;
  size_t size;
  int wide; /* 7.5 and later: 64-bit offsets and counts */
} bin;

static uint64_t le(const unsigned char *p, int bytes) {
  uint64_t v = 0;
  for (int i = bytes - 1; i >= 0; i--) v = v << 8 | p[i];
  return v;
}

/* The record at *at: its end, property count, property bytes and name.
 * 0 when it does not fit in the file; *null set for the list's end. */
typedef struct {
  uint64_t end, nprops, proplen;
  const char *name;
  int namelen;
  size_t props; /* offset of the first property */
} record;

static int read_record(const bin *b, size_t at, record *r, int *null) {
  int w = b->wide ? 8 : 4;
  size_t head = 3 * (size_t)w + 1;
  if (at > b->size || b->size - at < head) return 0;
  r->end = le(b->d + at, w);
  r->nprops = le(b->d + at + w, w);
  r->proplen = le(b->d + at + 2 * w, w);
  r->namelen = b->d[at + 3 * w];
  *null = r->end == 0 && r->nprops == 0 && r->proplen == 0 && r->namelen == 0;
  if (*null) return 1;
  r->name = (const char *)b->d + at + head;
  r->props = at + head + (size_t)r->namelen;
  return r->end > at && r->end <= b->size && r->props <= r->end && r->proplen <= r->end - r->props;
}

/* A property's size in bytes at p (within [p, end)), or 0 when unknown, past
 * the end, or what assimp's tokenizer cannot take: a raw array whose byte
 * count is not its length times its element size (assimp checks that only
 * for f, i, d and l, and asserts, aborting, on a raw bool array), or an
 * array encoding other than raw (0) and deflate (1). */
static size_t prop_size(const unsigned char *p, const unsigned char *end) {
  if (p >= end) return 0;
  size_t left = (size_t)(end - p) - 1, n;
  switch (p[0]) {
    case 'C': n = 1; break;
    case 'Y': n = 2; break;
    case 'I': case 'F': n = 4; break;
    case 'L': case 'D': n = 8; break;
    case 'S': case 'R': n = left >= 4 ? 4 + (size_t)le(p + 1, 4) : SIZE_MAX; break;
    case 'f': case 'd': case 'l': case 'i': case 'b': {
      if (left < 12) return 0;
      uint64_t count = le(p + 1, 4), enc = le(p + 5, 4), bytes = le(p + 9, 4);
      uint64_t elem = p[0] == 'b' ? 1 : p[0] == 'f' || p[0] == 'i' ? 4 : 8;
      if (enc > 1 || (enc == 0 && (p[0] == 'b' || count * elem != bytes))) return 0;
      n = 12 + (size_t)bytes;
      break;
    }
    default: return 0;
  }
  return n <= left ? 1 + n : 0;
}

/* One "C" record: its string, then two 64-bit ids (child, parent). */
static void connection(const bin *b, const record *r, edges *g, int *oom) {
  const unsigned char *p = b->d + r->props, *end = p + r->proplen;
  int64_t id[2];
  int got = 0;
  for (uint64_t i = 0; i < r->nprops && got < 2; i++) {
    if (i > 0 && p[0] == 'L') id[got++] = (int64_t)le(p + 1, 8);
    p += prop_size(p, end); /* walk checked every size */
  }
  if (got == 2 && !add_edge(g, id[0], id[1])) *oom = 1;
}

/* Records nest this deep at most (a real file: 5 or 6). */
#define FBX_MAX_DEPTH 64

/* The record list at [at, limit), as assimp's tokenizer reads it: every
 * record inside its parent, its properties exactly filling their length,
 * a nested list followed by its zero sentinel; the top level ends at a
 * zero record or the file's end. The "C" records of the top-level
 * "Connections" become edges. 0 when anything does not fit. */
static int walk(const bin *b, size_t at, size_t limit, int depth, int conn, edges *g, int *oom) {
  size_t sentinel = 3 * (size_t)(b->wide ? 8 : 4) + 1;
  if (depth > FBX_MAX_DEPTH) return 0;
  while (at < limit && !*oom) {
    record r;
    int null;
    if (!read_record(b, at, &r, &null)) return 0;
    if (null) return depth == 0;
    if (r.end > limit) return 0;
    const unsigned char *p = b->d + r.props, *pe = p + r.proplen;
    for (uint64_t i = 0; i < r.nprops; i++) {
      size_t n = prop_size(p, pe);
      if (!n) return 0;
      p += n;
    }
    if (p != pe) return 0;
    if (conn && r.namelen == 1 && r.name[0] == 'C') connection(b, &r, g, oom);
    size_t nested = r.props + (size_t)r.proplen;
    if (nested < r.end) {
      if (r.end - nested < sentinel) return 0;
      size_t stop = (size_t)r.end - sentinel;
      for (size_t k = stop; k < r.end; k++)
        if (b->d[k]) return 0;
      int sub = depth == 0 && r.namelen == 11 && !memcmp(r.name, "Connections", 11);
      if (!walk(b, nested, stop, depth + 1, sub, g, oom)) return 0;
    }
    at = (size_t)r.end;
  }
  return at == limit || *oom;
}

/* ---- ASCII ------------------------------------------------------------------ */

/* A decimal id at *q, within the line (before eol): spaces, an optional
 * sign, digits. 0 when there is none or it overflows 64 bits. */
static int line_id(const char **q, const char *eol, int64_t *out) {
  const char *p = *q;
  while (p < eol && (*p == ' ' || *p == '\t')) p++;
  int neg = p < eol && *p == '-';
  if (p < eol && (*p == '-' || *p == '+')) p++;
  uint64_t v = 0;
  const char *digits = p;
  for (; p < eol && *p >= '0' && *p <= '9'; p++) {
    if (v > (UINT64_MAX - 9) / 10) return 0;
    v = 10 * v + (uint64_t)(*p - '0');
  }
  if (p == digits || v > (uint64_t)INT64_MAX) return 0;
  *out = neg ? -(int64_t)v : (int64_t)v;
  *q = p;
  return 1;
}

/* Lines `C: "TYPE",child,parent[,...]`, anywhere (only Connections has them). */
static void ascii_edges(const char *t, size_t size, edges *g, int *oom) {
  const char *end = t + size;
  for (const char *p = t; p < end && !*oom;) {
    const char *nl = memchr(p, '\n', (size_t)(end - p));
    const char *eol = nl ? nl : end;
    while (p < eol && (*p == ' ' || *p == '\t')) p++;
    if (eol - p > 3 && p[0] == 'C' && p[1] == ':') {
      const char *q = memchr(p, '"', (size_t)(eol - p));
      q = q ? memchr(q + 1, '"', (size_t)(eol - q - 1)) : NULL;
      int64_t id[2];
      int got = 0;
      while (q && got < 2) {
        q = memchr(q, ',', (size_t)(eol - q));
        if (!q) break;
        q++;
        if (!line_id(&q, eol, &id[got])) break;
        got++;
      }
      if (got == 2 && !add_edge(g, id[0], id[1])) *oom = 1;
    }
    p = nl ? nl + 1 : end;
  }
}

/* ---- loops ------------------------------------------------------------------ */

static int cmp_i64(const void *a, const void *b) {
  int64_t x = *(const int64_t *)a, y = *(const int64_t *)b;
  return x < y ? -1 : x > y;
}

static size_t index_of(const int64_t *ids, size_t n, int64_t id) {
  const int64_t *f = bsearch(&id, ids, n, sizeof *ids, cmp_i64);
  return (size_t)(f - ids);
}

/* Edges grouped by their `from` end (counting sort): first[v] .. first[v + 1]
 * index `to` for node v. */
static void group(const size_t *from, const size_t *to, size_t m, size_t n, size_t *first, size_t *fill, size_t *out) {
  memset(first, 0, (n + 1) * sizeof *first);
  memset(fill, 0, n * sizeof *fill);
  for (size_t k = 0; k < m; k++) first[from[k] + 1]++;
  for (size_t v = 0; v < n; v++) first[v + 1] += first[v];
  for (size_t k = 0; k < m; k++) out[first[from[k]] + fill[from[k]]++] = to[k];
}

/* 1 and an id on a loop in *where when g has one; 0 without; -1 out of memory. */
static int find_loop(const edges *g, int64_t *where) {
  if (g->n == 0) return 0;
  size_t n = 0, m = g->n, nn = 2 * m + 1;
  int64_t *ids = gi__malloc(nn * sizeof *ids);
  size_t *ci = gi__malloc((m + 1) * sizeof *ci), *pi = gi__malloc((m + 1) * sizeof *pi);
  size_t *up = gi__malloc((nn + 1) * sizeof *up), *upv = gi__malloc((m + 1) * sizeof *upv);
  size_t *down = gi__malloc((nn + 1) * sizeof *down), *downv = gi__malloc((m + 1) * sizeof *downv);
  size_t *indeg = gi__malloc(nn * sizeof *indeg), *queue = gi__malloc(nn * sizeof *queue);
  int rc = -1;
  if (!ids || !ci || !pi || !up || !upv || !down || !downv || !indeg || !queue) goto out;
  memcpy(ids, g->e, 2 * m * sizeof *ids);
  qsort(ids, 2 * m, sizeof *ids, cmp_i64);
  for (size_t i = 0; i < 2 * m; i++)
    if (i == 0 || ids[i] != ids[n - 1]) ids[n++] = ids[i];
  for (size_t k = 0; k < m; k++) ci[k] = index_of(ids, n, g->e[2 * k]), pi[k] = index_of(ids, n, g->e[2 * k + 1]);
  group(ci, pi, m, n, up, indeg, upv);     /* child -> its parents */
  group(pi, ci, m, n, down, indeg, downv); /* parent -> its children */
  /* Kahn from the leaves up: an object goes once all its children have. */
  size_t head = 0, tail = 0;
  for (size_t v = 0; v < n; v++)
    if (!(indeg[v] = down[v + 1] - down[v])) queue[tail++] = v;
  while (head < tail) {
    size_t v = queue[head++];
    for (size_t k = up[v]; k < up[v + 1]; k++)
      if (--indeg[upv[k]] == 0) queue[tail++] = upv[k];
  }
  rc = tail < n;
  if (rc) {
    /* Every object left has a child left: stepping from child to child n
     * times from any of them ends on a loop. */
    size_t v = 0;
    while (!indeg[v]) v++;
    for (size_t step = 0; step < n; step++)
      for (size_t k = down[v]; k < down[v + 1]; k++)
        if (indeg[downv[k]]) {
          v = downv[k];
          break;
        }
    *where = ids[v];
  }
out:
  gi__free(ids), gi__free(ci), gi__free(pi), gi__free(up), gi__free(upv);
  gi__free(down), gi__free(downv), gi__free(indeg), gi__free(queue);
  return rc;
}

gi_result gi__fbx_check(const char *path, gi_error_info *err) {
  void *data;
  size_t size;
  /* No size limit of ours: assimp reads the whole file next anyway. */
  gi_result rc = gi__read_file(path, SIZE_MAX, &data, &size, err);
  if (rc != GI_OK) return rc;
  const unsigned char *d = data;
  edges g = {0};
  int oom = 0;
  if (size >= FBX_HEADER && !memcmp(d, FBX_MAGIC, strlen(FBX_MAGIC))) {
    bin b = {d, size, le(d + 23, 4) >= 7500};
    if (!walk(&b, FBX_HEADER, size, 0, 0, &g, &oom))
      rc = gi__fail(err, GI_ERR_FORMAT, "scene file '%s': an FBX record runs past its parent or the file's end, or "
                    "holds a property assimp cannot read; the file is truncated or corrupt", path);
  } else {
    ascii_edges((const char *)d, size, &g, &oom);
  }
  int64_t where = 0;
  int loop = rc == GI_OK && !oom ? find_loop(&g, &where) : 0;
  if (oom || loop < 0) rc = gi__fail(err, GI_ERR_NOMEM, "scene file '%s': out of memory", path);
  else if (loop)
    rc = gi__fail(err, GI_ERR_FORMAT, "scene file '%s': its FBX connections form a loop (object %lld is its own "
                  "ancestor), which no valid file has", path, (long long)where);
  gi__free(g.e);
  gi__free(data);
  return rc;
}
