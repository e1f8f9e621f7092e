/* io/import_exact.c: strict double-precision OBJ and PLY geometry readers
 * (see import_exact.h for why). Errors name the file, the line (OBJ, ASCII
 * PLY) or element record (binary PLY), and what was expected. */
#define _POSIX_C_SOURCE 200809L /* getline */
#include "io/import_exact.h"
#include "io/texture_image.h"
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "base/internal.h"

/* Largest PLY file read into memory; larger city tiles should be split. */
#define EXACT_PLY_FILE_MAX ((size_t)4 << 30)
#define PLY_MAX_ELEMENTS 16
#define PLY_MAX_PROPERTIES 32
#define PLY_MAX_POLYGON 255
/* An OBJ face's corners: Blender writes an n-gon cap (a disc, a
 * cylinder's end) as one face, and 255 refused a 360-corner disc. The
 * triangulator's corner indices are 16-bit; its work is bounded below. */
#define OBJ_MAX_POLYGON 4096
/* Point-in-triangle tests one polygon's ear cutting may make before it
 * fans what is left (as for a polygon no ear can be cut from): ~0.3 s. A
 * 255-corner polygon needs at most ~5.5e6, so only a hostile one of
 * thousands of corners ever stops early. */
#define EAR_TEST_BUDGET (1LL << 27)

void gi__exact_free(gi__exact_mesh *m) {
  if (!m) return;
  for (size_t i = 0; i < m->nnames; i++) gi__free(m->names[i]);
  gi__free(m->names);
  gi__free(m->v);
  gi__free(m->tri);
  gi__free(m->mat);
  gi__free(m->col);
  gi__free(m->tcol);
  gi__free(m->uv);
  gi__free(m->tuv);
  gi__free(m->mtllib);
  gi__free(m->name_slots);
  memset(m, 0, sizeof *m);
}

/* Grows *p to hold at least n items of size sz (doubling). 0: out of memory. */
static int grow(void **p, size_t *cap, size_t n, size_t sz) {
  if (n <= *cap) return 1;
  size_t c = *cap ? *cap : 64;
  while (c < n) c *= 2;
  void *q = gi__realloc(*p, c * sz);
  if (!q) return 0;
  *p = q;
  *cap = c;
  return 1;
}

static int push_vertex(gi__exact_mesh *m, const double p[3]) {
  if (m->nv >= UINT32_MAX - 1 || !grow((void **)&m->v, &m->cap_v, 3 * (m->nv + 1), sizeof *m->v)) return 0;
  memcpy(m->v + 3 * m->nv++, p, 3 * sizeof *p);
  return 1;
}

/* Room in m->col for every vertex pushed, the new part white. 0: out of memory. */
static int color_room(gi__exact_mesh *m) {
  size_t old = m->col ? m->cap_c : 0;
  if (!grow((void **)&m->col, &m->cap_c, 3 * m->nv, sizeof *m->col)) return 0;
  for (size_t i = old; i < m->cap_c; i++) m->col[i] = 1.f;
  return 1;
}

/* A colour channel as the file holds it (sRGB-encoded, [0, 1] nominal) as linear. */
static float color_linear(double x) {
  x = x < 0 ? 0 : x;
  return (float)(x <= 1 ? gi__srgb_to_linear(x) : x);
}

/* The colour of the last vertex pushed (sRGB-encoded, [0, 1] nominal), stored
 * linear; the first colour makes every earlier vertex white. 0: out of memory. */
static int set_color(gi__exact_mesh *m, const double c[3]) {
  if (!color_room(m)) return 0;
  for (int k = 0; k < 3; k++) m->col[3 * (m->nv - 1) + k] = color_linear(c[k]);
  return 1;
}

/* A face's colour (as set_color's) for its triangles, from..m->nt; earlier
 * triangles without one get NAN (their material's). 0: out of memory. */
static int set_face_color(gi__exact_mesh *m, size_t from, const double c[3]) {
  if (!grow((void **)&m->tcol, &m->cap_tc, 3 * m->nt, sizeof *m->tcol)) return 0;
  for (size_t t = m->ntc; t < m->nt; t++)
    for (int k = 0; k < 3; k++) m->tcol[3 * t + k] = t < from ? NAN : color_linear(c[k]);
  m->ntc = m->nt;
  return 1;
}

/* White for the last vertex pushed once colours exist. */
static int keep_white(gi__exact_mesh *m) { return !m->col || color_room(m); }

/* A triangle; tex (NULL: none) its corners' vt indices. 0: out of memory. */
static int push_tri_uv(gi__exact_mesh *m, uint32_t a, uint32_t b, uint32_t c, uint32_t mat, const uint32_t *tex) {
  if (!grow((void **)&m->tri, &m->cap_t, 3 * (m->nt + 1), sizeof *m->tri) ||
      !grow((void **)&m->mat, &m->cap_m, m->nt + 1, sizeof *m->mat))
    return 0;
  if (tex || m->tuv) {
    size_t old = m->tuv ? m->cap_tuv : 0;
    if (!grow((void **)&m->tuv, &m->cap_tuv, 3 * (m->nt + 1), sizeof *m->tuv)) return 0;
    for (size_t i = old; i < m->cap_tuv; i++) m->tuv[i] = GI__EXACT_NO_UV;
    for (int k = 0; k < 3 && tex; k++) m->tuv[3 * m->nt + k] = tex[k];
  }
  m->tri[3 * m->nt] = a, m->tri[3 * m->nt + 1] = b, m->tri[3 * m->nt + 2] = c;
  m->mat[m->nt++] = mat;
  return 1;
}

static int push_tri(gi__exact_mesh *m, uint32_t a, uint32_t b, uint32_t c, uint32_t mat) {
  return push_tri_uv(m, a, b, c, mat, NULL);
}

/* --- polygons ------------------------------------------------------------ */

/* Corner k of polygon poly in the plane that drops axis `drop` (the
 * largest of its Newell normal's), as 2D doubles. */
static void corner2(const gi__exact_mesh *m, const uint32_t *poly, int k, int drop, double out[2]) {
  const double *v = &m->v[3 * (size_t)poly[k]];
  out[0] = v[drop == 0 ? 1 : 0], out[1] = v[drop == 2 ? 1 : 2];
}

static double cross2(const double a[2], const double b[2], const double c[2]) {
  return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
}

/* Whether p lies inside or on triangle abc of orientation sg (+1 or -1). */
static int in_tri2(const double a[2], const double b[2], const double c[2], const double p[2], double sg) {
  return sg * cross2(a, b, p) >= 0 && sg * cross2(b, c, p) >= 0 && sg * cross2(c, a, p) >= 0;
}

/* The triangles of polygon poly[0..n) (n <= OBJ_MAX_POLYGON) as corner
 * triples into out (3 (n - 2) of them), in the polygon's winding. A convex
 * polygon is fanned from its first corner (what this reader always did);
 * a concave one (an L-shaped roof, a courtyard's footprint) is cut ear by
 * ear in the plane of its Newell normal, as assimp's triangulation does:
 * a fan there laid triangles over the notch. A polygon no ear can be cut
 * from (self-intersecting) fans what is left. Returns the triangles, -1
 * out of memory (a polygon over PLY_MAX_POLYGON corners works on the heap). */
static int polygon_triangles(const gi__exact_mesh *m, const uint32_t *poly, int n, uint16_t out[][3]) {
  uint16_t idx_small[PLY_MAX_POLYGON], *idx = idx_small;
  double p_small[PLY_MAX_POLYGON][2], (*p)[2] = p_small;
  void *heap = NULL;
  if (n > PLY_MAX_POLYGON) {
    if (!(heap = gi__malloc((size_t)n * (sizeof *p + sizeof *idx)))) return -1;
    p = heap, idx = (uint16_t *)(p + n);
  }
  int left = n, nt = 0;
  for (int k = 0; k < n; k++) idx[k] = (uint16_t)k;
  int placed = 1; /* a PLY may list its faces before its vertices: then fan */
  for (int k = 0; k < n; k++) placed &= poly[k] < m->nv;
  if (placed && n > 3) {
    double nrm[3] = {0, 0, 0};
    for (int k = 0; k < n; k++) {
      const double *a = &m->v[3 * (size_t)poly[k]], *b = &m->v[3 * (size_t)poly[(k + 1) % n]];
      nrm[0] += (a[1] - b[1]) * (a[2] + b[2]);
      nrm[1] += (a[2] - b[2]) * (a[0] + b[0]);
      nrm[2] += (a[0] - b[0]) * (a[1] + b[1]);
    }
    int drop = fabs(nrm[0]) >= fabs(nrm[1]) && fabs(nrm[0]) >= fabs(nrm[2]) ? 0 : fabs(nrm[1]) >= fabs(nrm[2]) ? 1 : 2;
    /* The projection keeps the winding when the dropped component is positive. */
    double sg = nrm[drop] >= 0 ? 1 : -1;
    if (drop == 1) sg = -sg; /* (z, x) order for y: corner2 gives (x, z) */
    int convex = 1;
    long long budget = EAR_TEST_BUDGET;
    for (int k = 0; k < n; k++) corner2(m, poly, k, drop, p[k]);
    for (int k = 0; k < n && convex; k++) convex = sg * cross2(p[k], p[(k + 1) % n], p[(k + 2) % n]) >= 0;
    for (int guard = 0; !convex && left > 3 && guard < n && budget > 0; guard++) {
      int cut = -1;
      for (int i = 0; i < left && cut < 0 && budget > 0; i++) {
        int a = idx[(i + left - 1) % left], b = idx[i], c = idx[(i + 1) % left];
        if (!(sg * cross2(p[a], p[b], p[c]) > 0)) continue; /* reflex or flat: not an ear */
        int clear = 1;
        for (int j = 0; j < left && clear; j++) {
          int q = idx[j];
          if (q != a && q != b && q != c) clear = !in_tri2(p[a], p[b], p[c], p[q], sg);
        }
        budget -= left;
        if (clear) cut = i;
      }
      if (cut < 0) break;
      out[nt][0] = idx[(cut + left - 1) % left], out[nt][1] = idx[cut], out[nt][2] = idx[(cut + 1) % left];
      nt++;
      memmove(&idx[cut], &idx[cut + 1], (size_t)(left - cut - 1) * sizeof *idx);
      left--;
    }
  }
  /* The fan of what is left: the whole polygon when convex (or unplaced). */
  for (int t = 1; t + 1 < left; t++) out[nt][0] = idx[0], out[nt][1] = idx[t], out[nt][2] = idx[t + 1], nt++;
  gi__free(heap);
  return nt;
}

static size_t name_hash(const char *s) {
  uint64_t h = 14695981039346656037ull; /* FNV-1a */
  for (; *s; s++) h = (h ^ (unsigned char)*s) * 1099511628211ull;
  return (size_t)h;
}

/* The slot of name in m->name_slots: its entry, or the empty one to fill. */
static size_t name_slot(const gi__exact_mesh *m, const char *name) {
  size_t mask = m->cap_slots - 1, i = name_hash(name) & mask;
  while (m->name_slots[i] && strcmp(m->names[m->name_slots[i] - 1], name)) i = (i + 1) & mask;
  return i;
}

/* Index of name in m->names, added when new; GI__EXACT_NO_MATERIAL when
 * out of memory. A hash table finds it: a scan of the names per usemtl
 * was a quarter of an OBJ of 30,000 materials' load. */
static uint32_t intern_name(gi__exact_mesh *m, const char *name) {
  if (m->cap_slots) {
    size_t i = name_slot(m, name);
    if (m->name_slots[i]) return m->name_slots[i] - 1;
  }
  if (2 * (m->nnames + 1) > m->cap_slots) { /* at most half full */
    size_t cap = m->cap_slots ? 2 * m->cap_slots : 64;
    uint32_t *slots = gi__calloc(cap, sizeof *slots), *old = m->name_slots;
    if (!slots) return GI__EXACT_NO_MATERIAL;
    m->name_slots = slots, m->cap_slots = cap;
    for (size_t k = 0; k < m->nnames; k++) m->name_slots[name_slot(m, m->names[k])] = (uint32_t)k + 1;
    gi__free(old);
  }
  if (!grow((void **)&m->names, &m->cap_names, m->nnames + 1, sizeof *m->names)) return GI__EXACT_NO_MATERIAL;
  char *c = gi__strdup(name);
  if (!c) return GI__EXACT_NO_MATERIAL;
  m->names[m->nnames] = c;
  m->name_slots[name_slot(m, c)] = (uint32_t)m->nnames + 1;
  return (uint32_t)m->nnames++;
}

/* --- OBJ --------------------------------------------------------------- */

static int is_blank(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\n' || c == '\f' || c == '\v'; }
static char *skip_blank(char *s) { while (*s && is_blank(*s)) s++; return s; }
/* Length of the token at s, at most 40 characters, for messages. */
static int token_len(const char *s) {
  int n = 0;
  while (n < 40 && s[n] && !is_blank(s[n])) n++;
  return n;
}

/* "v x y z [w | r g b]": three numbers, and only numbers after them. */
static gi_result obj_vertex(const char *path, size_t line, char *s, gi__exact_mesh *m, gi_error_info *err) {
  double p[6];
  int n = 0;
  for (;; n++) {
    s = skip_blank(s);
    if (!*s) break;
    char *e;
    double x = strtod(s, &e);
    if (e == s || (*e && !is_blank(*e)))
      return gi__fail(err, GI_ERR_FORMAT, "scene file '%s' line %zu: vertex coordinate %d is not a number: '%.*s'",
                      path, line, n + 1, token_len(s), s);
    if (n < 6) p[n] = x;
    s = e;
  }
  if (n < 3)
    return gi__fail(err, GI_ERR_FORMAT, "scene file '%s' line %zu: a vertex needs x y z, found %d number%s", path, line,
                    n, n == 1 ? "" : "s");
  if (!push_vertex(m, p) || !(n == 6 ? set_color(m, p + 3) : keep_white(m)))
    return gi__fail(err, GI_ERR_NOMEM, "scene file '%s': out of memory or too many vertices", path);
  return GI_OK;
}

/* The vt index after a corner's vertex index (at e: "/t", "/t/n") into
 * *k, GI__EXACT_NO_UV when it has none; -1 when it is not an index or out
 * of range (that corner's UVs were dropped without a word, the vertex's
 * own index being refused). */
static int obj_tex_index(const char *e, const gi__exact_mesh *m, uint32_t *k) {
  *k = GI__EXACT_NO_UV;
  if (*e != '/' || e[1] == '/' || !e[1] || is_blank(e[1])) return 0;
  char *end;
  errno = 0;
  long long i = strtoll(e + 1, &end, 10);
  long long t = i > 0 ? i - 1 : (long long)m->nuv + i;
  if (end == e + 1 || errno || (*end && *end != '/' && !is_blank(*end)) || i == 0 || t < 0 ||
      t >= (long long)m->nuv)
    return -1;
  *k = (uint32_t)t;
  return 0;
}

/* 0 when the corner at e ("/t", "/t/n", "//n" or nothing) names no
 * normal or one of the m->nvn defined so far; -1 otherwise (a file with a
 * bad normal index is a bad file, though normals are not read). */
static int obj_normal_index(const char *e, const gi__exact_mesh *m) {
  if (*e != '/') return 0;
  const char *n = strchr(e + 1, '/');
  if (!n || (n - e) > (long)strcspn(e, " \t\r\n\f\v")) return 0;
  char *end;
  errno = 0;
  long long i = strtoll(n + 1, &end, 10);
  long long k = i > 0 ? i - 1 : (long long)m->nvn + i;
  if (end == n + 1 || errno || (*end && !is_blank(*end)) || i == 0 || k < 0 || k >= (long long)m->nvn) return -1;
  return 0;
}

/* "vt u [v [w]]": the first two; a missing v is 0. */
static gi_result obj_texcoord(const char *path, size_t line, char *s, gi__exact_mesh *m, gi_error_info *err) {
  double t[2] = {0, 0};
  for (int n = 0;; n++) {
    s = skip_blank(s);
    if (!*s) {
      if (n == 0) return gi__fail(err, GI_ERR_FORMAT, "scene file '%s' line %zu: vt needs a coordinate", path, line);
      break;
    }
    char *e;
    double x = strtod(s, &e);
    if (e == s || (*e && !is_blank(*e)) || !isfinite(x))
      return gi__fail(err, GI_ERR_FORMAT, "scene file '%s' line %zu: texture coordinate %d is not a finite number: "
                      "'%.*s'", path, line, n + 1, token_len(s), s);
    if (n < 2) t[n] = x;
    s = e;
  }
  if (!grow((void **)&m->uv, &m->cap_uv, 2 * (m->nuv + 1), sizeof *m->uv))
    return gi__fail(err, GI_ERR_NOMEM, "scene file '%s': out of memory", path);
  m->uv[2 * m->nuv] = (float)t[0], m->uv[2 * m->nuv + 1] = (float)t[1];
  m->nuv++;
  return GI_OK;
}

/* The vertex indices of an "f", "l" or "p" statement (what: "face",
 * "line" or "point") into poly, *count of them, at least min: each v,
 * v/t, v//n or v/t/n; negative counts back from the last vertex. */
static gi_result obj_indices(const char *path, size_t line, char *s, const char *what, int min, const gi__exact_mesh *m,
                             uint32_t poly[OBJ_MAX_POLYGON], uint32_t *tex, int *count, gi_error_info *err) {
  int n = 0;
  for (;;) {
    s = skip_blank(s);
    if (!*s) break;
    char *e;
    errno = 0;
    long long i = strtoll(s, &e, 10);
    if (e == s || errno || (*e && *e != '/' && !is_blank(*e)))
      return gi__fail(err, GI_ERR_FORMAT, "scene file '%s' line %zu: %s corner %d: expected a vertex index, found '%.*s'",
                      path, line, what, n + 1, token_len(s), s);
    long long k = i > 0 ? i - 1 : (long long)m->nv + i;
    if (i == 0 || k < 0 || k >= (long long)m->nv)
      return gi__fail(err, GI_ERR_FORMAT,
                      "scene file '%s' line %zu: %s corner %d: vertex %lld: index out of range "
                      "(%zu vertices defined so far)", path,
                      line, what, n + 1, i, m->nv);
    if (n == OBJ_MAX_POLYGON)
      return gi__fail(err, GI_ERR_FORMAT, "scene file '%s' line %zu: a %s has more than %d corners", path, line, what,
                      OBJ_MAX_POLYGON);
    uint32_t t = GI__EXACT_NO_UV;
    if (tex && obj_tex_index(e, m, &t) < 0)
      return gi__fail(err, GI_ERR_FORMAT,
                      "scene file '%s' line %zu: %s corner %d: texture coordinate index '%.*s' is not one of the "
                      "%zu texture coordinates (vt) defined so far", path, line, what, n + 1,
                      (int)strcspn(e + 1, "/ \t\r\n\f\v"), e + 1, m->nuv);
    if (obj_normal_index(e, m) < 0) {
      const char *ni = strchr(e + 1, '/') + 1;
      return gi__fail(err, GI_ERR_FORMAT,
                      "scene file '%s' line %zu: %s corner %d: normal index '%.*s' is not one of the %zu normals "
                      "(vn) defined so far", path, line, what, n + 1, (int)strcspn(ni, " \t\r\n\f\v"), ni, m->nvn);
    }
    if (tex) tex[n] = t;
    poly[n++] = (uint32_t)k;
    while (*e && !is_blank(*e)) e++;
    s = e;
  }
  if (n < min)
    return gi__fail(err, GI_ERR_FORMAT, "scene file '%s' line %zu: a %s needs at least %d corner%s, found %d", path,
                    line, what, min, min == 1 ? "" : "s", n);
  *count = n;
  return GI_OK;
}

/* One OBJ polygon's corners and triangles, off the stack (~56 KiB). */
typedef struct {
  uint32_t poly[OBJ_MAX_POLYGON], tex[OBJ_MAX_POLYGON];
  uint16_t tris[OBJ_MAX_POLYGON][3];
} obj_work;

/* "f a b c ...": triangulated by polygon_triangles. */
static gi_result obj_face(const char *path, size_t line, char *s, uint32_t mat, gi__exact_mesh *m, obj_work *w,
                          gi_error_info *err) {
  int n = 0;
  gi_result rc = obj_indices(path, line, s, "face", 3, m, w->poly, w->tex, &n, err);
  if (rc != GI_OK) return rc;
  int has_uv = 0;
  for (int k = 0; k < n; k++) has_uv |= w->tex[k] != GI__EXACT_NO_UV;
  int nt = polygon_triangles(m, w->poly, n, w->tris);
  if (nt < 0) return gi__fail(err, GI_ERR_NOMEM, "scene file '%s': out of memory", path);
  for (int t = 0; t < nt; t++) {
    const uint16_t *c = w->tris[t];
    uint32_t t3[3] = {w->tex[c[0]], w->tex[c[1]], w->tex[c[2]]};
    if (!push_tri_uv(m, w->poly[c[0]], w->poly[c[1]], w->poly[c[2]], mat, has_uv ? t3 : NULL))
      return gi__fail(err, GI_ERR_NOMEM, "scene file '%s': out of memory", path);
  }
  return GI_OK;
}

/* Whether line s starts with keyword kw followed by a blank; *rest after it. */
static int keyword(char *s, const char *kw, char **rest) {
  size_t n = strlen(kw);
  if (strncmp(s, kw, n) != 0 || (s[n] && !is_blank(s[n]))) return 0;
  *rest = s + n;
  return 1;
}

/* A backslash ending a line (before its \r\n or \n) joins the next line to
 * it, the backslash and the line end dropped: the OBJ spec's continuation,
 * read as assimp (which reads this file's materials) reads it. Reads one
 * statement into *buf (getline's buffer); *no counts physical lines, *first
 * gets the statement's first. Returns its length, -1 at the end or on a
 * read error, -2 out of memory. */
static ssize_t obj_statement(FILE *f, char **buf, size_t *cap, char **more, size_t *more_cap, size_t *no,
                             size_t *first) {
  ssize_t n = getline(buf, cap, f);
  if (n < 0) return -1;
  *first = ++*no;
  for (;;) {
    ssize_t e = n;
    while (e > 0 && ((*buf)[e - 1] == '\n' || (*buf)[e - 1] == '\r')) e--;
    if (e == 0 || (*buf)[e - 1] != '\\') return n;
    (*buf)[e - 1] = 0;
    n = e - 1;
    ssize_t k = getline(more, more_cap, f);
    if (k < 0) return n;
    ++*no;
    if ((size_t)(n + k + 1) > *cap) {
      char *g = realloc(*buf, (size_t)(n + k + 1)); /* getline's buffer: libc's allocator */
      if (!g) return -2;
      *buf = g, *cap = (size_t)(n + k + 1);
    }
    memcpy(*buf + n, *more, (size_t)k + 1);
    n += k;
  }
}

/* Appends "mtllib " and name[0..n) and a '\n' to m->mtllib. 0: out of memory. */
static int keep_mtllib_line(gi__exact_mesh *m, const char *name, size_t n) {
  char *g = gi__realloc(m->mtllib, m->mtllib_len + n + 9);
  if (!g) return 0;
  m->mtllib_len += (size_t)sprintf(g + m->mtllib_len, "mtllib %.*s\n", (int)n, name);
  m->mtllib = g;
  return 1;
}

/* Whether the file `name` (n chars, relative to the OBJ at path's folder,
 * backslashes as slashes, as the importer resolves it) can be opened; -1
 * out of memory. */
static int lib_exists(const char *path, const char *name, size_t n) {
  const char *slash = strrchr(path, '/');
  size_t dl = name[0] == '/' || name[0] == '\\' || !slash ? 0 : (size_t)(slash - path) + 1;
  char *full = gi__malloc(dl + n + 1);
  if (!full) return -1;
  memcpy(full, path, dl);
  for (size_t i = 0; i < n; i++) full[dl + i] = name[i] == '\\' ? '/' : name[i];
  full[dl + n] = 0;
  FILE *f = fopen(full, "rb");
  gi__free(full);
  if (f) fclose(f);
  return f != NULL;
}

/* An mtllib statement (rest: after the keyword) as one "mtllib NAME" line
 * per library into m->mtllib, for assimp's stub and the MTL scan. The OBJ
 * spec's form names several files ("mtllib a.mtl b.mtl"), which assimp
 * 5.2 read as one file "a.mtl b.mtl" (every material grey); Blender writes
 * a name with a space as it is. So the rest names one file when a file of
 * that name exists or none of its words does, else each word is a file.
 * 0: out of memory. */
static int keep_mtllib(gi__exact_mesh *m, const char *path, char *rest) {
  rest = skip_blank(rest);
  size_t n = strlen(rest);
  while (n && is_blank(rest[n - 1])) n--;
  if (!n) return 1;
  int several = 0, found = 0, whole = 0;
  for (size_t i = 0; i < n; i++) several |= is_blank(rest[i]);
  for (size_t i = 0; several && i < n && !found;) {
    size_t w = 0;
    while (i + w < n && !is_blank(rest[i + w])) w++;
    if ((found = lib_exists(path, rest + i, w)) < 0) return 0;
    for (i += w; i < n && is_blank(rest[i]); i++) {}
  }
  if (found && (whole = lib_exists(path, rest, n)) < 0) return 0;
  if (!found || whole) return keep_mtllib_line(m, rest, n);
  for (size_t i = 0; i < n;) {
    size_t w = 0;
    while (i + w < n && !is_blank(rest[i + w])) w++;
    if (!keep_mtllib_line(m, rest + i, w)) return 0;
    for (i += w; i < n && is_blank(rest[i]); i++) {}
  }
  return 1;
}

char *gi__exact_obj_stub(const gi__exact_mesh *m, size_t *len) {
  static const char tri[] = "f 1 2 3\n";
  int unnamed = 0;
  for (size_t t = 0; t < m->nt && !unnamed; t++) unnamed = m->mat[t] == GI__EXACT_NO_MATERIAL;
  size_t cap = m->mtllib_len + 64 + (unnamed ? sizeof tri : 0);
  for (size_t k = 0; k < m->nnames; k++) cap += strlen(m->names[k]) + 8 + sizeof tri;
  char *s = gi__malloc(cap);
  if (!s) return NULL;
  size_t n = 0;
  if (m->mtllib) memcpy(s, m->mtllib, m->mtllib_len), n = m->mtllib_len;
  n += (size_t)snprintf(s + n, cap - n, "v 0 0 0\nv 1 0 0\nv 0 1 0\n%s", unnamed ? tri : "");
  for (size_t k = 0; k < m->nnames; k++) n += (size_t)snprintf(s + n, cap - n, "usemtl %s\n%s", m->names[k], tri);
  *len = n;
  return s;
}

char *gi__exact_ply_stub(size_t *len) {
  static const char ply[] = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                            "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
                            "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
  char *s = gi__malloc(sizeof ply);
  if (s) memcpy(s, ply, sizeof ply), *len = sizeof ply - 1;
  return s;
}

/* The colour statements assimp reads three numbers from (K then a, d, s or
 * e, any case for the K; Tf), and how many leading chars are the keyword. */
static int mtl_colour_keyword(const char *s, size_t n) {
  if (n < 2 || (n > 2 && s[2] != ' ' && s[2] != '\t')) return 0;
  if ((s[0] == 'K' || s[0] == 'k') && (s[1] == 'a' || s[1] == 'd' || s[1] == 's' || s[1] == 'e')) return 2;
  return s[0] == 'T' && s[1] == 'f' ? 2 : 0;
}

char *gi__exact_mtl_normalise(const char *mtl_path, const char *text, size_t len, size_t *out_len, char *msg,
                              size_t msg_len) {
  /* A one-number line grows to at most three times its length. */
  size_t cap = 3 * len + 1, n = 0, line = 0;
  char *out = gi__malloc(cap), *buf = NULL;
  if (msg_len) msg[0] = 0; /* out of memory, unless a bad line says otherwise */
  if (!out) return NULL;
  for (size_t at = 0; at < len; line++) {
    const char *l = text + at, *nl = memchr(l, '\n', len - at);
    size_t ll = nl ? (size_t)(nl - l) : len - at;
    at += ll + (nl != NULL);
    size_t b = 0, e = ll;
    while (b < e && (l[b] == ' ' || l[b] == '\t')) b++;
    while (e > b && is_blank(l[e - 1])) e--;
    int kw = mtl_colour_keyword(l + b, e - b);
    if (!kw) { /* as it was */
      memcpy(out + n, l, ll), n += ll;
      if (nl) out[n++] = '\n';
      continue;
    }
    /* The numbers after the keyword, parsed on a NUL-terminated copy. */
    gi__free(buf);
    if (!(buf = gi__malloc(e - b + 1))) {
      gi__free(out);
      return NULL;
    }
    memcpy(buf, l + b, e - b), buf[e - b] = 0;
    char *p = buf + kw, *first = NULL, *end;
    int count = 0, numeric = 1;
    for (p = skip_blank(p); *p; p = skip_blank(end)) {
      strtod(p, &end);
      if (end == p || (*end && !is_blank(*end))) { numeric = 0; break; }
      if (!count++) first = p;
    }
    if (numeric && (count == 0 || count == 2)) {
      snprintf(msg, msg_len, "material library '%s' line %zu: '%.2s' needs 1 or 3 numbers (r, or r g b), found %d",
               mtl_path, line + 1, buf, count);
      gi__free(buf);
      gi__free(out);
      return NULL;
    }
    if (numeric && count == 1) {
      /* The MTL format: "if only r is specified, g and b are equal to r". */
      size_t fl = strcspn(first, " \t");
      n += (size_t)sprintf(out + n, "%.2s %.*s %.*s %.*s", buf, (int)fl, first, (int)fl, first, (int)fl, first);
    } else {
      memcpy(out + n, l + b, e - b), n += e - b;
    }
    if (nl) out[n++] = '\n';
  }
  gi__free(buf);
  out[n] = 0;
  *out_len = n;
  return out;
}

gi_result gi__exact_read_obj(const char *path, gi__exact_mesh *m, gi_error_info *err) {
  memset(m, 0, sizeof *m);
  FILE *f = fopen(path, "rb");
  if (!f) return gi__fail(err, GI_ERR_IO, "scene file '%s': cannot open: %s", path, strerror(errno));
  obj_work *w = gi__malloc(sizeof *w);
  if (!w) {
    fclose(f);
    return gi__fail(err, GI_ERR_NOMEM, "scene file '%s': out of memory", path);
  }
  char *buf = NULL, *more = NULL, *rest;
  size_t cap = 0, more_cap = 0, no = 0, line = 0;
  uint32_t mat = GI__EXACT_NO_MATERIAL;
  gi_result rc = GI_OK;
  ssize_t got;
  while (rc == GI_OK && (got = obj_statement(f, &buf, &cap, &more, &more_cap, &no, &line)) != -1) {
    if (got == -2) {
      rc = gi__fail(err, GI_ERR_NOMEM, "scene file '%s': out of memory at line %zu", path, line);
      break;
    }
    char *s = skip_blank(buf);
    if (keyword(s, "v", &rest)) {
      rc = obj_vertex(path, line, rest, m, err);
    } else if (keyword(s, "vt", &rest)) {
      rc = obj_texcoord(path, line, rest, m, err);
    } else if (keyword(s, "vn", &rest)) {
      m->nvn++;
    } else if (keyword(s, "f", &rest)) {
      rc = obj_face(path, line, rest, mat, m, w, err);
    } else if (keyword(s, "usemtl", &rest)) {
      /* Like assimp: the rest of the line, trimmed, is the name. */
      rest = skip_blank(rest);
      size_t n = strlen(rest);
      while (n && is_blank(rest[n - 1])) rest[--n] = 0;
      if (!n) rc = gi__fail(err, GI_ERR_FORMAT, "scene file '%s' line %zu: usemtl needs a material name", path, line);
      else if ((mat = intern_name(m, rest)) == GI__EXACT_NO_MATERIAL)
        rc = gi__fail(err, GI_ERR_NOMEM, "scene file '%s': out of memory", path);
    } else if (keyword(s, "l", &rest) || keyword(s, "p", &rest)) {
      /* Not geometry we use, but checked: a bad index is a bad file. */
      int n = 0, l = s[0] == 'l';
      rc = obj_indices(path, line, rest, l ? "line" : "point", l ? 2 : 1, m, w->poly, NULL, &n, err);
    } else if (keyword(s, "mtllib", &rest)) {
      rc = keep_mtllib(m, path, rest) ? GI_OK : gi__fail(err, GI_ERR_NOMEM, "scene file '%s': out of memory", path);
    }
    /* vn, o, g, s, lod, comments: not geometry we use. assimp reads a stub
     * of this file (gi__exact_obj_stub), never these lines: it took any
     * line starting with f, l or p for a face, line or point, and leaked or
     * looped on some (fuzz_scene). */
  }
  if (rc == GI_OK && ferror(f)) rc = gi__fail(err, GI_ERR_IO, "scene file '%s': read error after line %zu", path, no);
  free(buf); /* getline's buffers come from libc malloc */
  free(more);
  gi__free(w);
  fclose(f);
  if (rc != GI_OK) gi__exact_free(m);
  return rc;
}

/* --- PLY --------------------------------------------------------------- */

typedef enum { T_NONE, T_I8, T_U8, T_I16, T_U16, T_I32, T_U32, T_F32, T_F64 } ply_type;

static ply_type type_of(const char *t) {
  static const struct { const char *name; ply_type t; } tab[] = {
      {"char", T_I8},   {"int8", T_I8},     {"uchar", T_U8},  {"uint8", T_U8},     {"short", T_I16},
      {"int16", T_I16}, {"ushort", T_U16},  {"uint16", T_U16}, {"int", T_I32},     {"int32", T_I32},
      {"uint", T_U32},  {"uint32", T_U32},  {"float", T_F32}, {"float32", T_F32}, {"double", T_F64},
      {"float64", T_F64}};
  for (size_t i = 0; i < sizeof tab / sizeof tab[0]; i++)
    if (strcmp(t, tab[i].name) == 0) return tab[i].t;
  return T_NONE;
}

static const int type_size[] = {0, 1, 1, 2, 2, 4, 4, 4, 8};

typedef struct {
  char name[64];
  ply_type type, count_type; /* count_type != T_NONE: a list */
} ply_prop;

typedef struct {
  char name[64];
  long long count;
  int nprops;
  ply_prop prop[PLY_MAX_PROPERTIES];
} ply_element;

/* The body as a stream of numbers. */
typedef struct {
  const char *path;
  const unsigned char *p, *end;
  int ascii, big;
  size_t line; /* ascii only */
} ply_body;

/* Next value of type t as a double. 0 ok, -1 end of data, -2 not a number. */
static int body_value(ply_body *b, ply_type t, double *out) {
  if (b->ascii) {
    while (b->p < b->end && is_blank((char)*b->p)) b->line += *b->p++ == '\n';
    if (b->p >= b->end) return -1;
    char *e;
    *out = strtod((const char *)b->p, &e); /* the buffer is NUL-terminated */
    if ((const unsigned char *)e == b->p || (*e && !is_blank(*e))) return -2;
    b->p = (const unsigned char *)e;
    return 0;
  }
  int n = type_size[t];
  if (b->end - b->p < n) return -1;
  unsigned char v[8];
  for (int i = 0; i < n; i++) v[i] = b->p[b->big ? n - 1 - i : i];
  b->p += n;
  union { uint8_t u8; int8_t i8; uint16_t u16; int16_t i16; uint32_t u32; int32_t i32; float f; double d; } u;
  memcpy(&u, v, (size_t)n); /* v is now little-endian, as this machine */
  switch (t) {
    case T_I8: *out = u.i8; break;
    case T_U8: *out = u.u8; break;
    case T_I16: *out = u.i16; break;
    case T_U16: *out = u.u16; break;
    case T_I32: *out = u.i32; break;
    case T_U32: *out = u.u32; break;
    case T_F32: *out = u.f; break;
    default: *out = u.d; break;
  }
  return 0;
}

/* Where a record sits, for error messages. */
static void body_where(const ply_body *b, const ply_element *e, long long i, char *w, size_t n) {
  if (b->ascii) snprintf(w, n, "line %zu (%s %lld)", b->line, e->name, i);
  else snprintf(w, n, "%s %lld", e->name, i);
}

/* Parses the header; *body_start is the offset after end_header's line. */
static gi_result ply_header(const char *path, char *text, size_t size, ply_element *el, int *nel, int *ascii, int *big,
                            size_t *body_start, gi_error_info *err) {
  char *p = text, *end = text + size;
  int format = 0;
  *nel = 0;
  for (size_t line = 1; p < end; line++) {
    char *nl = memchr(p, '\n', (size_t)(end - p));
    if (!nl) break;
    *nl = 0;
    /* Tokens are split by spaces and tabs alone: another control character
     * (a vertical tab, a NUL) is whitespace to sscanf but not to assimp,
     * whose PLY reader then never finds the header's end and spins (a
     * 319-byte file, found by fuzz_scene). */
    size_t len = (size_t)(nl - p) - (nl > p && nl[-1] == '\r');
    if (line == 1 && (len != 3 || memcmp(p, "ply", 3)))
      return gi__fail(err, GI_ERR_FORMAT, "scene file '%s' line 1: expected the PLY magic number 'ply'", path);
    for (const char *q = p; q < nl; q++)
      if ((unsigned char)*q < 0x20 && *q != '\t' && !(*q == '\r' && q + 1 == nl))
        return gi__fail(err, GI_ERR_FORMAT, "scene file '%s' line %zu: control character 0x%02x in the PLY header",
                        path, line, (unsigned)(unsigned char)*q);
    char a[64] = "", b[64] = "", c[64] = "", d[64] = "", e[64] = "", f[64] = "";
    int n = sscanf(p, "%63s %63s %63s %63s %63s %63s", a, b, c, d, e, f);
    p = nl + 1;
    if (line == 1) {
      /* checked above */
    } else if (!strcmp(a, "format") && n >= 2) {
      format = 1;
      *ascii = !strcmp(b, "ascii");
      *big = !strcmp(b, "binary_big_endian");
      if (!*ascii && !*big && strcmp(b, "binary_little_endian"))
        return gi__fail(err, GI_ERR_FORMAT, "scene file '%s' line %zu: unknown PLY format '%s'", path, line, b);
    } else if (!strcmp(a, "element") && n >= 3) {
      if (*nel == PLY_MAX_ELEMENTS)
        return gi__fail(err, GI_ERR_FORMAT, "scene file '%s' line %zu: more than %d PLY elements", path, line,
                        PLY_MAX_ELEMENTS);
      ply_element *E = &el[(*nel)++];
      memset(E, 0, sizeof *E);
      snprintf(E->name, sizeof E->name, "%s", b);
      char *x;
      errno = 0;
      E->count = strtoll(c, &x, 10);
      if (*x || errno || E->count < 0)
        return gi__fail(err, GI_ERR_FORMAT, "scene file '%s' line %zu: element '%s' has a bad count '%s'", path, line, b,
                        c);
    } else if (!strcmp(a, "property") && n >= 3) {
      if (!*nel || el[*nel - 1].nprops == PLY_MAX_PROPERTIES)
        return gi__fail(err, GI_ERR_FORMAT, "scene file '%s' line %zu: property outside an element or too many", path,
                        line);
      ply_element *E = &el[*nel - 1];
      ply_prop *P = &E->prop[E->nprops++];
      int list = !strcmp(b, "list");
      P->count_type = list ? type_of(c) : T_NONE;
      P->type = type_of(list ? d : b);
      snprintf(P->name, sizeof P->name, "%s", list ? e : c);
      /* Exactly those words: assimp misread "property uchar int name" (a
       * leak in its reader, found by fuzz_scene) where we read a uchar. */
      if (P->type == T_NONE || n != (list ? 5 : 3) || (list && P->count_type == T_NONE))
        return gi__fail(err, GI_ERR_FORMAT, "scene file '%s' line %zu: expected 'property TYPE NAME' or 'property list "
                        "TYPE TYPE NAME' with a PLY scalar type", path, line);
    } else if (!strcmp(a, "end_header") && n == 1) {
      if (!format) return gi__fail(err, GI_ERR_FORMAT, "scene file '%s': PLY header has no format line", path);
      *body_start = (size_t)(p - text);
      return GI_OK;
    } else if (!strcmp(a, "end_header")) {
      return gi__fail(err, GI_ERR_FORMAT, "scene file '%s' line %zu: end_header must stand alone on its line, found "
                      "'%s' after it", path, line, b);
    } else if (n > 0 && strcmp(a, "comment") && strcmp(a, "obj_info")) {
      /* What assimp would skip or misread: the header says what it is, or the file is not PLY. */
      return gi__fail(err, GI_ERR_FORMAT, "scene file '%s' line %zu: expected a PLY header line (format, comment, "
                      "obj_info, element, property or end_header alone), found '%s'", path, line, a);
    }
  }
  return gi__fail(err, GI_ERR_FORMAT, "scene file '%s': PLY header has no end_header", path);
}

/* A PLY colour value as a fraction: integers over their type's largest
 * value (uchar 255), floats as they are. */
static double color_unit(ply_type t, double x) {
  switch (t) {
    case T_U8: return x / 255.0;
    case T_I8: return x / 127.0;
    case T_U16: return x / 65535.0;
    case T_I16: return x / 32767.0;
    case T_U32: return x / 4294967295.0;
    case T_I32: return x / 2147483647.0;
    default: return x;
  }
}

/* Index of the scalar property called name, or -1. */
static int find_prop(const ply_element *e, const char *name, int list) {
  for (int i = 0; i < e->nprops; i++)
    if (!strcmp(e->prop[i].name, name) && (e->prop[i].count_type != T_NONE) == list) return i;
  return -1;
}

/* The scalar colour properties of element e into ic (red, green, blue),
 * under the names writers use: red green blue (MeshLab, CloudCompare),
 * diffuse_red ... (the Stanford scanners'), r g b. 1 when all three are there. */
static int find_color(const ply_element *e, int ic[3]) {
  static const char *const names[3][3] = {
      {"red", "green", "blue"}, {"diffuse_red", "diffuse_green", "diffuse_blue"}, {"r", "g", "b"}};
  for (int n = 0; n < 3; n++) {
    for (int k = 0; k < 3; k++) ic[k] = find_prop(e, names[n][k], 0);
    if (ic[0] >= 0 && ic[1] >= 0 && ic[2] >= 0) return 1;
  }
  ic[0] = ic[1] = ic[2] = -1;
  return 0;
}

/* One element's records: vertices keep x, y, z and their colour; faces
 * keep their index list and their colour (MeshLab writes it after the
 * list), which becomes their triangles' albedo. */
static gi_result ply_element_body(ply_body *b, const ply_element *E, long long nverts, gi__exact_mesh *m,
                                  gi_error_info *err) {
  int is_v = !strcmp(E->name, "vertex"), is_f = !strcmp(E->name, "face");
  int ix = is_v ? find_prop(E, "x", 0) : -1, iy = is_v ? find_prop(E, "y", 0) : -1, iz = is_v ? find_prop(E, "z", 0) : -1;
  int il = is_f ? find_prop(E, "vertex_indices", 1) : -1;
  int ic[3] = {-1, -1, -1};
  int colored = (is_v || is_f) && find_color(E, ic);
  if (is_f && il < 0) il = find_prop(E, "vertex_index", 1);
  char w[128];
  if (is_v && (ix < 0 || iy < 0 || iz < 0))
    return gi__fail(err, GI_ERR_FORMAT, "scene file '%s': PLY vertex element needs scalar properties x, y and z", b->path);
  if (is_f && il < 0)
    return gi__fail(err, GI_ERR_FORMAT, "scene file '%s': PLY face element needs a list property vertex_indices", b->path);
  for (long long i = 0; i < E->count; i++) {
    double pos[3] = {0, 0, 0}, col[3] = {1, 1, 1};
    size_t first_tri = m->nt;
    for (int p = 0; p < E->nprops; p++) {
      const ply_prop *P = &E->prop[p];
      double n = 1, x;
      int r = 0;
      if (P->count_type != T_NONE) {
        r = body_value(b, P->count_type, &n);
        if (!r && !(n >= 0 && n == floor(n) && n <= (p == il ? PLY_MAX_POLYGON : 1e6))) {
          body_where(b, E, i, w, sizeof w);
          return gi__fail(err, GI_ERR_FORMAT, "scene file '%s' %s: list '%s' has length %g; expected %s", b->path, w,
                          P->name, n, p == il ? "3..255 vertex indices" : "a whole number");
        }
        if (!r && p == il && n < 3) {
          body_where(b, E, i, w, sizeof w);
          return gi__fail(err, GI_ERR_FORMAT, "scene file '%s' %s: a face needs 3..255 vertex indices, found %g",
                          b->path, w, n);
        }
      }
      uint32_t poly[PLY_MAX_POLYGON];
      for (int k = 0; !r && k < (int)n; k++) {
        if ((r = body_value(b, P->type, &x))) break;
        if (p == ix || p == iy || p == iz) pos[p == ix ? 0 : p == iy ? 1 : 2] = x;
        if (colored && (p == ic[0] || p == ic[1] || p == ic[2])) col[p == ic[0] ? 0 : p == ic[1] ? 1 : 2] = color_unit(P->type, x);
        if (p == il) {
          if (!(x >= 0 && x < (double)nverts && x == floor(x))) {
            body_where(b, E, i, w, sizeof w);
            return gi__fail(err, GI_ERR_FORMAT, "scene file '%s' %s: vertex index %g out of range; expected 0..%lld",
                            b->path, w, x,
                            nverts - 1);
          }
          poly[k] = (uint32_t)x;
        }
      }
      if (r) {
        body_where(b, E, i, w, sizeof w);
        return gi__fail(err, GI_ERR_FORMAT, "scene file '%s' %s: property '%s': %s", b->path, w, P->name,
                        r == -1 ? "the data ends here; the file is truncated" : "expected a number");
      }
      if (p == il) {
        uint16_t tris[PLY_MAX_POLYGON][3];
        int nt = polygon_triangles(m, poly, (int)n, tris);
        if (nt < 0) return gi__fail(err, GI_ERR_NOMEM, "scene file '%s': out of memory", b->path);
        for (int t = 0; t < nt; t++)
          if (!push_tri(m, poly[tris[t][0]], poly[tris[t][1]], poly[tris[t][2]], GI__EXACT_NO_MATERIAL))
            return gi__fail(err, GI_ERR_NOMEM, "scene file '%s': out of memory", b->path);
      }
    }
    if (is_v && (!push_vertex(m, pos) || (colored && !set_color(m, col))))
      return gi__fail(err, GI_ERR_NOMEM, "scene file '%s': out of memory or too many vertices", b->path);
    if (is_f && colored && !set_face_color(m, first_tri, col))
      return gi__fail(err, GI_ERR_NOMEM, "scene file '%s': out of memory", b->path);
  }
  return GI_OK;
}

/* The whole file, NUL-terminated, so ASCII numbers can be read with strtod. */
static gi_result slurp(const char *path, char **out, size_t *size, gi_error_info *err) {
  FILE *f = fopen(path, "rb");
  if (!f) return gi__fail(err, GI_ERR_IO, "scene file '%s': cannot open: %s", path, strerror(errno));
  gi_result rc = GI_OK;
  long n = fseek(f, 0, SEEK_END) == 0 ? ftell(f) : -1;
  char *buf = NULL;
  if (n < 0 || (size_t)n > EXACT_PLY_FILE_MAX) {
    rc = gi__fail(err, n < 0 ? GI_ERR_IO : GI_ERR_LIMIT, "scene file '%s': cannot size it, or larger than %zu bytes",
                  path, EXACT_PLY_FILE_MAX);
  } else if (!(buf = gi__malloc((size_t)n + 1))) {
    rc = gi__fail(err, GI_ERR_NOMEM, "scene file '%s': out of memory", path);
  } else if (fseek(f, 0, SEEK_SET) != 0 || fread(buf, 1, (size_t)n, f) != (size_t)n) {
    rc = gi__fail(err, GI_ERR_IO, "scene file '%s': read error", path);
  }
  fclose(f);
  if (rc != GI_OK) { gi__free(buf); return rc; }
  buf[n] = 0;
  *out = buf;
  *size = (size_t)n;
  return GI_OK;
}

gi_result gi__exact_read_ply(const char *path, gi__exact_mesh *m, gi_error_info *err) {
  memset(m, 0, sizeof *m);
  char *text = NULL;
  size_t size = 0, start = 0;
  gi_result rc = slurp(path, &text, &size, err);
  if (rc != GI_OK) return rc;
  static _Thread_local ply_element el[PLY_MAX_ELEMENTS]; /* ~40 KiB: off the stack */
  int nel = 0, ascii = 0, big = 0;
  /* The header is parsed on a copy: it writes NULs over line ends. */
  char *head = gi__malloc(size + 1);
  if (!head) rc = gi__fail(err, GI_ERR_NOMEM, "scene file '%s': out of memory", path);
  else memcpy(head, text, size + 1);
  if (rc == GI_OK) rc = ply_header(path, head, size, el, &nel, &ascii, &big, &start, err);
  gi__free(head);
  long long nverts = 0;
  for (int e = 0; e < nel; e++)
    if (!strcmp(el[e].name, "vertex")) nverts = el[e].count;
  ply_body b = {.path = path, .p = (const unsigned char *)text + start, .end = (const unsigned char *)text + size,
                .ascii = ascii, .big = big, .line = 1};
  /* ASCII line numbers count from the file's first line. */
  for (size_t i = 0; ascii && i < start; i++) b.line += text[i] == '\n';
  for (int e = 0; rc == GI_OK && e < nel; e++) rc = ply_element_body(&b, &el[e], nverts, m, err);
  /* Triangle strips (a Stanford range scan's 'tristrips', -1 between
   * strips) are not read: a file of strips alone said only that it held
   * no triangles. */
  for (int e = 0; rc == GI_OK && m->nt == 0 && e < nel; e++)
    if (!strcmp(el[e].name, "tristrips") && el[e].count > 0)
      rc = gi__fail(err, GI_ERR_FORMAT, "scene file '%s': its surface is a PLY 'tristrips' element (%lld record%s), "
                    "which is not read; only 'face' elements (vertex_indices lists) are", path, el[e].count,
                    el[e].count == 1 ? "" : "s");
  gi__free(text);
  if (rc != GI_OK) gi__exact_free(m);
  return rc;
}
