/* io/import_assimp.c: gi_scene_load, scene files through assimp's C API.
 *
 * Design: before assimp sees a file we check that it opens, is a regular
 * non-empty file and, for PLY, that the element counts in its header fit in
 * the bytes that follow (a header claiming 10^9 faces would otherwise make
 * assimp reserve gigabytes), and for FBX that its object connections do
 * not loop (io/fbx_check.c: assimp recursed until the stack ran out).
 * assimp then triangulates and joins vertices (not in a scene with lightmap
 * UVs: import_file), and we walk its node graph
 * (io/assimp_nodes.h: world transforms in double, mirrored nodes' winding
 * reversed) to copy every instance of its triangle meshes into a
 * gi_mesh_builder and to place its lights; points and lines are skipped.
 * OBJ and PLY geometry comes instead from our own double-precision readers
 * (io/import_exact.c), run before assimp: assimp parses positions into
 * float, which moves a georeferenced vertex (UTM, ~5e6) by up to 0.5 m
 * before the scene can subtract its origin. glTF node matrices are composed
 * in double (io/gltf_recentre.c) and the file assimp reads is recentred on
 * its first mesh; the offset is added back here, in double. A glTF's lights
 * are read there too, one per node that holds one, and kept from assimp,
 * whose name matching made thousands of lights load in seconds.
 * Non-finite positions are passed through so that gi_scene_build drops and
 * counts those triangles; an index outside its mesh is a malformed file.
 * Materials map OBJ (Kd, Ke, Ks, Ns: an unnormalised Blinn-Phong lobe) and
 * glTF (baseColor, emissive, metallic/roughness) onto gi_material; a
 * diffuse or base-colour texture multiplies the colour factor by its
 * average linear colour. A triangle
 * with texture coordinates takes instead the average of its own part of
 * the texture (read on a grid of at most 128 x 128 cells,
 * gi_mesh_builder_set_triangle_albedo): a city's facades often share one
 * atlas, and its average made every building the same colour. Vertex
 * colours multiply either (gi_mesh_builder_set_vertex_color: assimp's first
 * colour set, or the exact readers' for OBJ and PLY).
 * Textures are decoded once per load (cached by path), embedded ones from
 * the aiScene, and one that cannot be read costs a warning on stderr and a
 * count in the stats, never the load. assimp keeps its last error in a
 * global string, so the import and the read of that string run under one
 * mutex; loading is rare, serving is not, so this costs nothing that
 * matters. assimp logs only when a logger is attached, and we attach none,
 * so nothing goes to stdout. */
#define _POSIX_C_SOURCE 200809L /* fileno, fstat under -std=c11 */
#include <errno.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <assimp/cfileio.h>
#include <assimp/cimport.h>
#include <assimp/commonMetaData.h>
#include <assimp/material.h>
#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include "base/internal.h"
#include "io/assimp_nodes.h"
#include "io/fbx_check.h"
#include "io/gltf_recentre.h"
#include "io/import_exact.h"
#include "io/texture_image.h"
#include "scene/scene_internal.h"

static pthread_mutex_t assimp_lock = PTHREAD_MUTEX_INITIALIZER;

static int ends_with_ci(const char *s, const char *suffix) {
  size_t n = strlen(s), m = strlen(suffix);
  if (m > n) return 0;
  for (size_t i = 0; i < m; i++) {
    char a = s[n - m + i], b = suffix[i];
    if (a >= 'A' && a <= 'Z') a = (char)(a - 'A' + 'a');
    if (a != b) return 0;
  }
  return 1;
}

/* A glTF file, text or binary. */
static int is_gltf(const char *path) { return ends_with_ci(path, ".gltf") || ends_with_ci(path, ".glb"); }

/* Size in bytes of a PLY scalar type name; 0 when unknown. */
static int ply_type_size(const char *t) {
  static const struct { const char *name; int size; } types[] = {
      {"char", 1}, {"uchar", 1}, {"int8", 1}, {"uint8", 1}, {"short", 2}, {"ushort", 2},
      {"int16", 2}, {"uint16", 2}, {"int", 4}, {"uint", 4}, {"int32", 4}, {"uint32", 4},
      {"float", 4}, {"float32", 4}, {"double", 8}, {"float64", 8}};
  for (size_t i = 0; i < sizeof types / sizeof types[0]; i++)
    if (strcmp(t, types[i].name) == 0) return types[i].size;
  return 0;
}

/* A PLY element as its header declares it, for walking a binary body. */
#define PLY_MAX_ELEMS 16
#define PLY_MAX_PROPS 32
typedef struct {
  char name[64];
  long long count;
  int nprops;
  struct { int size, list_count_size, is_index_list; } prop[PLY_MAX_PROPS];
} ply_elem;

/* Buffered little reader over the body: refills 64 KiB at a time. */
typedef struct {
  FILE *f;
  unsigned char buf[65536];
  size_t pos, len;
} ply_reader;

static int ply_read(ply_reader *r, void *out, size_t n) {
  unsigned char *o = out;
  while (n) {
    if (r->pos == r->len) {
      r->len = fread(r->buf, 1, sizeof r->buf, r->f);
      r->pos = 0;
      if (!r->len) return -1;
    }
    size_t k = r->len - r->pos < n ? r->len - r->pos : n;
    memcpy(o, r->buf + r->pos, k);
    r->pos += k, o += k, n -= k;
  }
  return 0;
}

/* An unsigned integer of `size` bytes in the file's byte order; -1 past the end. */
static long long ply_read_uint(ply_reader *r, int size, int big) {
  unsigned char b[8];
  if (ply_read(r, b, (size_t)size)) return -1;
  unsigned long long v = 0;
  for (int i = 0; i < size; i++) v |= (unsigned long long)b[big ? size - 1 - i : i] << (8 * i);
  return (long long)v;
}

/* Walks a binary body: every record present, every face a polygon of 3..255
 * vertices whose indices exist. assimp 5.2 trusts these and aborts on a
 * short face list (an assertion in its triangulation, found by fuzz_scene). */
static gi_result check_ply_body(const char *path, FILE *f, int big, const ply_elem *el, int nel,
                                gi_error_info *err) {
  static _Thread_local ply_reader r;
  r.f = f, r.pos = r.len = 0;
  long long vertices = 0;
  for (int e = 0; e < nel; e++)
    if (!strcmp(el[e].name, "vertex")) vertices = el[e].count;
  for (int e = 0; e < nel; e++) {
    const ply_elem *E = &el[e];
    int is_face = !strcmp(E->name, "face");
    for (long long i = 0; i < E->count; i++)
      for (int p = 0; p < E->nprops; p++) {
        int lc = E->prop[p].list_count_size, sz = E->prop[p].size;
        long long n = 1;
        if (lc) {
          n = ply_read_uint(&r, lc, big);
          if (n < 0) goto truncated;
          if (is_face && E->prop[p].is_index_list && (n < 3 || n > 255))
            return gi__fail(err, GI_ERR_FORMAT, "scene file '%s': PLY face %lld has %lld vertex indices; a face needs 3..255",
                            path, i, n);
        }
        for (long long k = 0; k < n; k++) {
          if (is_face && E->prop[p].is_index_list) {
            long long v = ply_read_uint(&r, sz, big);
            if (v < 0) goto truncated;
            /* Signed index types: a negative index reads as a huge unsigned one. */
            if (v >= vertices)
              return gi__fail(err, GI_ERR_FORMAT, "scene file '%s': PLY face %lld uses vertex %lld of %lld", path, i,
                              v, vertices);
          } else {
            unsigned char skip[8];
            if (ply_read(&r, skip, (size_t)sz)) goto truncated;
          }
        }
      }
    continue;
  truncated:
    return gi__fail(err, GI_ERR_FORMAT, "scene file '%s': PLY data ends inside element '%s'; the file is truncated",
                    path, E->name);
  }
  return GI_OK;
}

/* Checks a PLY header's element counts against the data that follows: each
 * element needs at least a few bytes, so a count the file cannot hold is a
 * truncated or hostile file; a binary body is then walked record by record.
 * Anything we do not understand is left to assimp. */
static gi_result check_ply_header(const char *path, FILE *f, long long file_size, gi_error_info *err) {
  char line[512];
  int binary = -1, big = 0;
  long long header_end = 0;
  long long need = 0;           /* minimum bytes for all elements */
  long long count = 0, per = 0; /* current element */
  char elem[64] = "";
  ply_elem el[PLY_MAX_ELEMS];
  int nel = 0, walkable = 1;
  if (!fgets(line, sizeof line, f) || strncmp(line, "ply", 3) != 0) return GI_OK;
  while (fgets(line, sizeof line, f)) {
    char a[64] = "", b[64] = "", c[64] = "", d[64] = "", e5[64] = "";
    int n = sscanf(line, "%63s %63s %63s %63s %63s", a, b, c, d, e5);
    if (n >= 2 && strcmp(a, "format") == 0) {
      binary = strcmp(b, "ascii") != 0;
      big = strcmp(b, "binary_big_endian") == 0;
    } else if (n >= 3 && strcmp(a, "element") == 0) {
      need += count * per;
      char *end;
      errno = 0;
      count = strtoll(c, &end, 10);
      if (*end || errno || count < 0)
        return gi__fail(err, GI_ERR_FORMAT, "scene file '%s': PLY element '%s' has a bad count '%s'", path, b, c);
      snprintf(elem, sizeof elem, "%s", b);
      per = 0;
      if (strcmp(b, "face") == 0 && count > ((long long)1 << 31))
        return gi__fail(err, GI_ERR_LIMIT, "scene file '%s': %lld faces; the limit is 2^31", path, count);
      if (nel < PLY_MAX_ELEMS) {
        snprintf(el[nel].name, sizeof el[nel].name, "%s", b);
        el[nel].count = count;
        el[nel].nprops = 0;
        nel++;
      } else {
        walkable = 0;
      }
    } else if (n >= 3 && strcmp(a, "property") == 0) {
      /* An unknown type would make assimp guess (and, in 5.2, leak: found by
       * fuzz_scene); say what is wrong instead. */
      int list = strcmp(b, "list") == 0;
      const char *bad = !ply_type_size(list ? c : b) ? (list ? c : b) : (list && !ply_type_size(d) ? d : NULL);
      if (bad)
        return gi__fail(err, GI_ERR_FORMAT, "scene file '%s': PLY element '%s' has a property of unknown type '%s'",
                        path, elem, bad);
      /* ASCII: a digit and a separator; binary: the scalar, or a list's count. */
      int size = ply_type_size(list ? c : b);
      per += binary == 1 ? (size ? size : 1) : 2;
      if (nel == 0 || el[nel - 1].nprops == PLY_MAX_PROPS) {
        walkable = 0;
      } else {
        ply_elem *E = &el[nel - 1];
        E->prop[E->nprops].list_count_size = list ? ply_type_size(c) : 0;
        E->prop[E->nprops].size = list ? ply_type_size(d) : size;
        E->prop[E->nprops].is_index_list = list && (!strcmp(e5, "vertex_indices") || !strcmp(e5, "vertex_index"));
        E->nprops++;
      }
    } else if (n >= 1 && strcmp(a, "end_header") == 0) {
      header_end = ftell(f);
      need += count * per;
      long long have = file_size - header_end;
      if (need > have)
        return gi__fail(err, GI_ERR_FORMAT,
                        "scene file '%s': PLY header declares elements needing at least %lld bytes "
                        "(last element '%s': %lld) but only %lld bytes follow the header; the file is truncated",
                        path, need, elem, count, have);
      return binary == 1 && walkable ? check_ply_body(path, f, big, el, nel, err) : GI_OK;
    }
    /* Counts this large overflow the estimate; only a corrupt header has them. */
    if (count > ((long long)1 << 40) || need > ((long long)1 << 60))
      return gi__fail(err, GI_ERR_FORMAT, "scene file '%s': PLY header declares an impossible element count", path);
  }
  return gi__fail(err, GI_ERR_FORMAT, "scene file '%s': PLY header has no end_header", path);
}

static float lum(const float c[3]) { return 0.2126f * c[0] + 0.7152f * c[1] + 0.0722f * c[2]; }

static int get_color(const struct aiMaterial *m, const char *key, unsigned type, unsigned idx, float out[3]) {
  struct aiColor4D c;
  if (aiGetMaterialColor(m, key, type, idx, &c) != aiReturn_SUCCESS) return 0;
  out[0] = c.r; out[1] = c.g; out[2] = c.b;
  return 1;
}

static int get_float(const struct aiMaterial *m, const char *key, unsigned type, unsigned idx, float *out) {
  ai_real v;
  unsigned int n = 1;
  if (aiGetMaterialFloatArray(m, key, type, idx, &v, &n) != aiReturn_SUCCESS || n < 1) return 0;
  *out = (float)v;
  return 1;
}

/* --- diffuse textures ------------------------------------------------ */

/* One texture's average and grid, computed once per load: key is "*N"
 * for an embedded texture, else the resolved file path. */
typedef struct tex_entry {
  char *key;
  int ok;
  float rgb[3];
  gi__tex_grid grid; /* the texture on a coarse grid, for its triangles' own parts */
} tex_entry;

/* Per material of ours: the texture its triangles sample (index in
 * tc->tex; -1: none readable), the colour factor that multiplies it, and
 * the UV set it reads. */
typedef struct mat_tex {
  long tex;
  float factor[3];
  unsigned uv;
  const double *uv_tf; /* glTF: KHR_texture_transform (gi__gltf_shift.uv_tf), or NULL */
  gi__tex_wrap wrap[2]; /* u, v outside [0, 1] (glTF's sampler wrapS, wrapT); repeat unless said */
} mat_tex;

/* assimp's mapping mode for one axis (glTF's sampler, an MTL's -clamp) as ours. */
static gi__tex_wrap tex_wrap(enum aiTextureMapMode m) {
  return m == aiTextureMapMode_Clamp ? GI__TEX_CLAMP : m == aiTextureMapMode_Mirror ? GI__TEX_MIRROR : GI__TEX_REPEAT;
}

/* An OBJ material's name, whether its MTL block has a Kd line, and
 * whether Blender wrote its MTL file; seq orders repeats (see sort_mtl). */
typedef struct mtl_entry {
  char *name;
  int has_kd;
  int by_blender;
  size_t seq;
} mtl_entry;

typedef struct tex_ctx {
  const struct aiScene *as;
  const char *path;   /* the scene file */
  tex_entry *tex;
  size_t ntex, captex;
  uint64_t unreadable;
  uint64_t see_through; /* triangles of see-through materials, left out (add_materials) */
  int warned_dae_emission; /* the Blender Collada emission warning was given */
  int mtl_scanned;    /* OBJ: the MTL files were read into mtl[] */
  const char *mtllib; /* OBJ: its mtllib statements (gi__exact_mesh), or NULL */
  mtl_entry *mtl;     /* sorted by name, one per name, once scanned */
  size_t nmtl, capmtl;
  mat_tex *mt;        /* per material of ours (add_materials) */
  const gi__gltf_shift *gs; /* glTF: the file's transforms, or NULL */
} tex_ctx;

static void tex_ctx_fini(tex_ctx *tc) {
  for (size_t i = 0; i < tc->ntex; i++) gi__free(tc->tex[i].key), gi__tex_grid_free(&tc->tex[i].grid);
  gi__free(tc->mt);
  for (size_t i = 0; i < tc->nmtl; i++) gi__free(tc->mtl[i].name);
  gi__free(tc->tex);
  gi__free(tc->mtl);
}

/* A file name from the scene, resolved against the scene file's folder;
 * backslashes become slashes. malloc'ed; NULL when out of memory. */
static char *resolve_path(const char *scene_path, const char *name, size_t len) {
  const char *slash = strrchr(scene_path, '/');
  size_t dl = (name[0] == '/' || name[0] == '\\' || !slash) ? 0 : (size_t)(slash - scene_path) + 1;
  char *r = gi__malloc(dl + len + 1);
  if (!r) return NULL;
  memcpy(r, scene_path, dl);
  for (size_t i = 0; i < len; i++) r[dl + i] = name[i] == '\\' ? '/' : name[i];
  r[dl + len] = 0;
  return r;
}

static const char *base_name(const char *p) {
  const char *a = strrchr(p, '/'), *b = strrchr(p, '\\');
  if (b && (!a || b > a)) a = b;
  return a ? a + 1 : p;
}

/* The embedded texture a material's path names ("*N", or a file name that
 * matches an embedded texture's, as aiScene::GetEmbeddedTexture does), or -1. */
static long embedded_index(const struct aiScene *as, const char *p) {
  if (p[0] == '*') {
    char *end;
    errno = 0;
    long i = strtol(p + 1, &end, 10);
    return (!*end && !errno && i >= 0 && (unsigned long)i < as->mNumTextures) ? i : -1;
  }
  const char *bn = base_name(p);
  for (unsigned i = 0; i < as->mNumTextures; i++)
    if (as->mTextures[i] && strcmp(base_name(as->mTextures[i]->mFilename.data), bn) == 0) return (long)i;
  return -1;
}

/* Average of one texture, decoded the first time it is asked for. Returns
 * the cache entry, or NULL when out of memory. A texture that cannot be
 * read is counted and reported once (naming the first material using it
 * and what it is for: kind). */
static const tex_entry *texture_average(tex_ctx *tc, const char *mat_name, const char *kind, const char *tpath) {
  const struct aiScene *as = tc->as;
  long ei = embedded_index(as, tpath);
  char *key = NULL;
  if (ei >= 0) {
    key = gi__malloc(24);
    if (key) snprintf(key, 24, "*%ld", ei);
  } else {
    key = resolve_path(tc->path, tpath, strlen(tpath));
  }
  if (!key) return NULL;
  for (size_t i = 0; i < tc->ntex; i++)
    if (strcmp(tc->tex[i].key, key) == 0) {
      gi__free(key);
      return &tc->tex[i];
    }
  if (tc->ntex == tc->captex) {
    size_t cap = tc->captex ? 2 * tc->captex : 8;
    tex_entry *t = gi__realloc(tc->tex, cap * sizeof *t);
    if (!t) { gi__free(key); return NULL; }
    tc->tex = t;
    tc->captex = cap;
  }
  tex_entry *e = &tc->tex[tc->ntex++];
  memset(e, 0, sizeof *e);
  e->key = key;
  gi_error_info te = {0};
  gi_result r;
  char what[96];
  if (ei >= 0) {
    const struct aiTexture *t = as->mTextures[ei];
    snprintf(what, sizeof what, "embedded texture *%ld", ei);
    if (t->mHeight == 0)
      r = gi__image_average_grid(t->pcData, t->mWidth, what, e->rgb, &e->grid, &te);
    else
      r = gi__texels_average_grid(t->pcData, t->mWidth, t->mHeight, what, e->rgb, &e->grid, &te);
  } else {
    void *data = NULL;
    size_t size = 0;
    r = gi__read_file(key, GI__TEXTURE_FILE_MAX, &data, &size, &te);
    const char *bn = base_name(tpath);
    if (r == GI_ERR_NOT_FOUND && bn != tpath) {
      /* Exporters often write the author's absolute path: try the file
       * name alone next to the scene. */
      char *near = resolve_path(tc->path, bn, strlen(bn));
      gi_error_info te2 = {0};
      gi_result r2 = near ? gi__read_file(near, GI__TEXTURE_FILE_MAX, &data, &size, &te2) : GI_ERR_NOMEM;
      if (r2 == GI_OK || r2 == GI_ERR_NOMEM) r = r2;
      gi__free(near);
    }
    if (r == GI_OK) r = gi__image_average_grid(data, size, key, e->rgb, &e->grid, &te);
    gi__free(data);
  }
  /* Out of memory fails the load; only a texture that cannot be read falls back to the colour. */
  if (r == GI_ERR_NOMEM) return NULL;
  e->ok = r == GI_OK && gi__finite3(e->rgb);
  if (!e->ok) {
    tc->unreadable++;
    fprintf(stderr, "gi: warning: scene file '%s': material '%s': %s texture '%s' is unreadable, using the "
            "material's colour alone: %s\n", tc->path, mat_name, kind, tpath, te.msg[0] ? te.msg : "non-finite average");
  }
  return e;
}

/* Leading blanks skipped, trailing blanks and line ends cut; returns the start. */
static char *trim(char *l) {
  while (*l == ' ' || *l == '\t') l++;
  size_t n = strlen(l);
  while (n && (l[n - 1] == '\n' || l[n - 1] == '\r' || l[n - 1] == ' ' || l[n - 1] == '\t')) l[--n] = 0;
  return l;
}

/* Records which materials of one MTL file have a Kd line; one that cannot
 * be read is a warning (assimp goes on without it, every material it holds
 * grey). 0: out of memory. */
static int scan_mtl(tex_ctx *tc, const char *mtl_path) {
  FILE *f = fopen(mtl_path, "rb");
  if (!f) {
    fprintf(stderr, "gi: warning: scene file '%s': material library '%s' cannot be read (%s): its materials "
            "load as assimp's grey default (albedo 0.6)\n", tc->path, mtl_path, strerror(errno));
    return 1;
  }
  char line[1024];
  long cur = -1;
  int ok = 1, first = 1, blender = 0;
  while (ok && fgets(line, sizeof line, f)) {
    char *l = trim(line);
    /* Its first line: "# Blender MTL File" (3.4's), "# Blender 3.6.0 MTL File". */
    if (first && l[0]) blender = !strncmp(l, "# Blender", 9) && strstr(l, "MTL File") != NULL, first = 0;
    if (strncmp(l, "newmtl", 6) == 0 && (l[6] == ' ' || l[6] == '\t')) {
      char *name = trim(l + 6);
      if (tc->nmtl == tc->capmtl) {
        size_t cap = tc->capmtl ? 2 * tc->capmtl : 16;
        mtl_entry *m = gi__realloc(tc->mtl, cap * sizeof *m);
        if (!m) { ok = 0; break; }
        tc->mtl = m;
        tc->capmtl = cap;
      }
      char *copy = gi__strdup(name);
      if (!copy) { ok = 0; break; }
      tc->mtl[tc->nmtl] = (mtl_entry){copy, 0, blender, tc->nmtl};
      cur = (long)tc->nmtl++;
    } else if (cur >= 0 && (l[0] == 'K' || l[0] == 'k') && l[1] == 'd' && (l[2] == ' ' || l[2] == '\t')) {
      tc->mtl[cur].has_kd = 1;
    }
  }
  fclose(f);
  return ok;
}

static int mtl_cmp(const void *a, const void *b) {
  const mtl_entry *x = a, *y = b;
  int c = strcmp(x->name, y->name);
  return c ? c : (x->seq > y->seq) - (x->seq < y->seq);
}

/* Sorts mtl[] by name and merges each name's repeats into its first, as
 * assimp merges a repeated newmtl (its Kd lines count; the first file
 * says who wrote it): one lookup is then a binary search, where a scan per
 * material made an OBJ of 30,000 materials load in 16 s. */
static void sort_mtl(tex_ctx *tc) {
  if (tc->nmtl) qsort(tc->mtl, tc->nmtl, sizeof *tc->mtl, mtl_cmp);
  size_t k = 0;
  for (size_t i = 0; i < tc->nmtl; i++) {
    if (k && !strcmp(tc->mtl[k - 1].name, tc->mtl[i].name)) {
      tc->mtl[k - 1].has_kd |= tc->mtl[i].has_kd;
      gi__free(tc->mtl[i].name);
    } else {
      tc->mtl[k++] = tc->mtl[i];
    }
  }
  tc->nmtl = k;
}

/* OBJ only: reads the MTL files the OBJ names (its mtllib statements, as
 * our reader kept them), once per load. 0: out of memory. */
static int scan_obj_mtllibs(tex_ctx *tc) {
  if (tc->mtl_scanned) return 1;
  tc->mtl_scanned = 1;
  int ok = 1;
  for (const char *l = tc->mtllib; ok && l && *l;) {
    const char *end = strchr(l, '\n');
    size_t n = end ? (size_t)(end - l) : strlen(l);
    if (n < 6) { /* not a statement: "mtllib" and its file */
      l = end ? end + 1 : l + n;
      continue;
    }
    char *stmt = gi__malloc(n + 1);
    if (!stmt) return 0;
    memcpy(stmt, l, n), stmt[n] = 0;
    char *name = trim(stmt + 6); /* past "mtllib": one file a line (import_exact.c split the statement) */
    char *mp = resolve_path(tc->path, name, strlen(name));
    ok = mp && scan_mtl(tc, mp);
    gi__free(mp);
    gi__free(stmt);
    l = end ? end + 1 : l + n;
  }
  sort_mtl(tc);
  return ok;
}

/* The MTL entry whose name starts with name's first n characters (n =
 * strlen(name) for an exact match), or NULL. */
static const mtl_entry *find_mtl(const tex_ctx *tc, const char *name, size_t n, int exact) {
  size_t lo = 0, hi = tc->nmtl;
  while (lo < hi) {
    size_t mid = lo + (hi - lo) / 2;
    if (strncmp(tc->mtl[mid].name, name, n) < 0) lo = mid + 1;
    else hi = mid;
  }
  if (lo == tc->nmtl || strncmp(tc->mtl[lo].name, name, n)) return NULL;
  if (!exact) return &tc->mtl[lo];
  /* Among the names starting so, the one that ends there sorts first. */
  return tc->mtl[lo].name[n] == 0 ? &tc->mtl[lo] : NULL;
}

/* OBJ only: warns when material `name` (ours, maybe cut to gi_material's
 * name length) is used but defined in none of the file's MTL files: assimp
 * makes it grey (0.6), as a typo in usemtl or newmtl would. 0: out of memory. */
static int check_obj_material(tex_ctx *tc, const char *name) {
  if (!ends_with_ci(tc->path, ".obj") || !strcmp(name, AI_DEFAULT_MATERIAL_NAME)) return 1;
  if (!scan_obj_mtllibs(tc)) return 0;
  size_t n = strlen(name), cut = sizeof(((gi_material *)0)->name) - 1; /* n == cut: ours may be cut short */
  if (find_mtl(tc, name, n, n != cut)) return 1;
  fprintf(stderr, "gi: warning: scene file '%s': material '%s' is used but defined in none of its material "
          "libraries: grey (albedo 0.6)\n", tc->path, name);
  return 1;
}

/* The factor that goes with a diffuse texture. assimp reports Kd 0.6 for an
 * OBJ material without a Kd line, and map_Kd alone means "the texture as is",
 * so for OBJ the MTL is consulted: no Kd line gives a factor of 1. Blender
 * writes its base colour's unused default (Kd 0.8) beside the texture that
 * replaces it, and reads map_Kd back as the colour: its MTLs' textures
 * stand alone too (they read 20% dark against the same glTF). Otherwise Kd
 * multiplies the texture, as the MTL format says. 0: out of memory. */
static int texture_factor(tex_ctx *tc, const char *mat_name, float c[3]) {
  if (!ends_with_ci(tc->path, ".obj")) return 1;
  if (!scan_obj_mtllibs(tc)) return 0;
  const mtl_entry *e = find_mtl(tc, mat_name, strlen(mat_name), 1);
  if (e && (e->by_blender || (!e->has_kd && c[0] == 0.6f && c[1] == 0.6f && c[2] == 0.6f))) c[0] = c[1] = c[2] = 1.f;
  return 1;
}

/* Whether an OBJ material's MTL file was written by Blender. */
static int obj_by_blender(tex_ctx *tc, const char *mat_name) {
  if (!ends_with_ci(tc->path, ".obj") || !scan_obj_mtllibs(tc)) return 0; /* out of memory: the general rule */
  const mtl_entry *e = find_mtl(tc, mat_name, strlen(mat_name), 1);
  return e && e->by_blender;
}

/* An emissive texture (glTF's emissiveTexture, an MTL's map_Ke) multiplies
 * the emission by its average: emitters are per material here, so a facade
 * whose texture lights only its windows emits that share over its whole
 * surface, where ignoring the texture made all of it glow. A texture that
 * cannot be read leaves the factor alone (counted and warned, as a diffuse
 * one). Fails only when out of memory. */
static gi_result emissive_texture(const struct aiMaterial *am, tex_ctx *tc, gi_material *m, gi_error_info *err) {
  struct aiString epath;
  if (aiGetMaterialTexture(am, aiTextureType_EMISSIVE, 0, &epath, NULL, NULL, NULL, NULL, NULL, NULL) !=
          aiReturn_SUCCESS ||
      epath.length == 0)
    return GI_OK;
  const tex_entry *t = texture_average(tc, m->name, "emissive", epath.data);
  if (!t)
    return gi__fail(err, GI_ERR_NOMEM, "scene file '%s': material '%s': out of memory for its emissive texture",
                    tc->path, m->name);
  if (t->ok)
    for (int i = 0; i < 3; i++) m->emission[i] *= t->rgb[i];
  return GI_OK;
}

/* Blender's own export (its FBX and Collada exporters name themselves in
 * the file's generator): its lamps' units are known (convert_light). */
static int written_by_blender(const struct aiScene *as) {
  const struct aiMetadata *md = as->mMetaData;
  for (unsigned i = 0; md && i < md->mNumProperties; i++) {
    if (strcmp(md->mKeys[i].data, AI_METADATA_SOURCE_GENERATOR) || md->mValues[i].mType != AI_AISTRING) continue;
    const struct aiString *g = md->mValues[i].mData;
    return !strncmp(g->data, "Blender", 7);
  }
  return 0;
}

/* A Collada <lambert> or <constant> material has no specular term; assimp
 * 5.2 still reports its default Ks 0.4 at shininess 10 for it, which read
 * as an 18% glossy lobe on every diffuse surface Blender writes. (An OBJ's
 * shading model cannot tell: assimp maps illum 3 and up to Gouraud too.) */
static int collada_diffuse_only(const struct aiMaterial *am, const char *path) {
  int model = 0;
  if (!ends_with_ci(path, ".dae") || aiGetMaterialIntegerArray(am, AI_MATKEY_SHADING_MODEL, &model, NULL) != aiReturn_SUCCESS)
    return 0;
  return model == aiShadingMode_Gouraud || model == aiShadingMode_NoShading || model == aiShadingMode_Flat;
}

/* m's glossy lobe (roughness, specular) from am, its albedo already set.
 * Returns what the diffuse albedo keeps: a glossy metal's base colour is
 * its lobe's, not also its diffuse part (glTF's model: diffuse = base x
 * (1 - metallic)); a metal floor of base 0.5 reflected 0.5 twice, an
 * all-metal room 6.6x a diffuse one's light. A rough one (no lobe: every
 * stage drops it, GI_GLOSSY_ROUGHNESS) keeps its base colour as diffuse. */
static float material_lobe(const struct aiMaterial *am, tex_ctx *tc, unsigned index, gi_material *m) {
  float rough = 1.f, metal = 0.f, ns = 0.f, ks[3] = {0, 0, 0};
  int has_rough = get_float(am, AI_MATKEY_ROUGHNESS_FACTOR, &rough);
  int has_metal = get_float(am, AI_MATKEY_METALLIC_FACTOR, &metal);
  int has_ks = !collada_diffuse_only(am, tc->path) && get_color(am, AI_MATKEY_COLOR_SPECULAR, ks) &&
               (ks[0] > 0 || ks[1] > 0 || ks[2] > 0);
  /* assimp 5.2 makes every FBX material's roughness up from its shininess
   * (1 - sqrt(Ns) / 10, Blender's rule), and the metallic/roughness rule
   * below then took its Ks as the lobe's whole reflectance: a Blender
   * dielectric of roughness 0.2 became a 46% mirror (its glTF: 4%). An FBX
   * Blender wrote is that rule's material: its roughness, its metallic as
   * the reflection factor, Ks (its base colour) ignored. Other FBX files
   * are Phong materials: the Blinn-Phong rule. */
  if (ends_with_ci(tc->path, ".fbx")) {
    if (written_by_blender(tc->as)) {
      has_ks = 0;
      has_metal = get_float(am, AI_MATKEY_REFLECTIVITY, &metal);
      if (!(metal >= 0.f && metal <= 1.f)) metal = 0.f;
    } else {
      has_rough = 0;
    }
  }
  if (has_rough) {
    m->roughness = rough;
    /* Metallic/roughness: normal-incidence reflectance between 4 % (dielectric) and the base colour (metal). */
    float mt = has_metal ? metal : 0.f;
    if (!(mt >= 0.f)) mt = 0.f;
    if (mt > 1.f) mt = 1.f;
    /* A glTF dielectric's 4%, or what its KHR_materials_specular / _ior say (gltf_recentre.c). */
    float f0 = tc->gs && index < tc->gs->num_f0 && !isnan(tc->gs->f0[index]) ? tc->gs->f0[index] : 0.04f;
    m->specular = has_ks ? lum(ks) : f0 * (1.f - mt) + mt * lum(m->albedo);
    /* A metal's lobe is its base colour per channel (a gold floor reflected
     * grey: blue 2.9x Cycles); scene.c makes `specular` its brightest. */
    if (!has_ks && mt > 0.f)
      for (int k = 0; k < 3; k++) m->specular_rgb[k] = f0 * (1.f - mt) + mt * m->albedo[k];
    if (!has_ks && rough < GI_GLOSSY_ROUGHNESS) return 1.f - mt;
  } else if (has_ks && obj_by_blender(tc, m->name)) {
    /* Blender's MTL is its Principled material's: Ns = 1000 (1 - roughness)^2
     * and Ks its specular level, whose reflectance is 0.08 x that (its
     * default 0.5: 4%), as its OBJ importer reads them back. The Blinn-Phong
     * rule made its roughness 0.8 a glossy 0.22 (its glTF: 0.8). */
    get_float(am, AI_MATKEY_SHININESS, &ns);
    ns = ns >= 0.f && ns <= 1000.f ? ns : ns > 1000.f ? 1000.f : 0.f;
    m->roughness = 1.f - sqrtf(ns / 1000.f);
    m->specular = 0.08f * lum(ks);
  } else if (has_ks) {
    /* Phong exponent to roughness, the usual Beckmann correspondence. */
    get_float(am, AI_MATKEY_SHININESS, &ns);
    if (!(ns >= 0.f)) ns = 0.f;
    m->roughness = sqrtf(2.f / (ns + 2.f));
    /* Ks is the peak of an unnormalised Blinn-Phong lobe (MTL's illum 2,
     * Collada's <blinn>): Ks (N.H)^Ns reflects about Ks 8 / (Ns + 8) of what
     * arrives. Taken as the lobe's whole reflectance, Blender's default
     * material (Kd 0.8, Ks 0.5, Ns 250) was a 50% mirror over 80% diffuse. */
    m->specular = lum(ks) * 8.f / (ns + 8.f);
  } else {
    m->roughness = 1.f;
    m->specular = 0.f;
  }
  return 1.f;
}

/* Maps one assimp material onto ours. The albedo is the colour factor
 * times the average of the diffuse (or base-colour) texture when there is
 * one; a texture that cannot be read leaves the factor alone. Fails only
 * when out of memory. */
static gi_result convert_material(const struct aiMaterial *am, tex_ctx *tc, unsigned index, gi_material *m,
                                  mat_tex *mt, gi_error_info *err) {
  memset(m, 0, sizeof *m);
  *mt = (mat_tex){.tex = -1}; /* add_meshes reads its uv set for every material */
  struct aiString name;
  if (aiGetMaterialString(am, AI_MATKEY_NAME, &name) == aiReturn_SUCCESS)
    snprintf(m->name, sizeof m->name, "%.*s", (int)(name.length < sizeof m->name ? name.length : sizeof m->name - 1),
             name.data);
  if (!check_obj_material(tc, m->name)) return gi__fail(err, GI_ERR_NOMEM, "scene file '%s': out of memory", tc->path);
  float c[3];
  /* glTF's base colour is the truer albedo when both are present. */
  int has_factor = get_color(am, AI_MATKEY_BASE_COLOR, c) || get_color(am, AI_MATKEY_COLOR_DIFFUSE, c);
  struct aiString tpath;
  unsigned uv = 0;
  enum aiTextureMapMode mode[2] = {aiTextureMapMode_Wrap, aiTextureMapMode_Wrap};
  int has_tex = aiGetMaterialTexture(am, aiTextureType_BASE_COLOR, 0, &tpath, NULL, &uv, NULL, NULL, mode, NULL) ==
                    aiReturn_SUCCESS ||
                aiGetMaterialTexture(am, aiTextureType_DIFFUSE, 0, &tpath, NULL, &uv, NULL, NULL, mode, NULL) ==
                    aiReturn_SUCCESS;
  if (has_tex && tpath.length == 0) has_tex = 0;
  if (has_tex) {
    /* An FBX texture connected to the diffuse colour takes its place (the
     * colour is what shows without it): Blender writes its default 0.8
     * there, and the texture read 20% dark against the same glTF. */
    if (!has_factor || ends_with_ci(tc->path, ".fbx")) c[0] = c[1] = c[2] = 1.f;
    const tex_entry *t = NULL;
    if ((has_factor && !texture_factor(tc, m->name, c)) || !(t = texture_average(tc, m->name, "diffuse", tpath.data)))
      return gi__fail(err, GI_ERR_NOMEM, "scene file '%s': material '%s': out of memory for its texture", tc->path,
                      m->name);
    if (t->ok) {
      *mt = (mat_tex){.tex = (long)(t - tc->tex), .factor = {c[0], c[1], c[2]}, .uv = uv,
                      .wrap = {tex_wrap(mode[0]), tex_wrap(mode[1])}};
      for (int i = 0; i < 3; i++) c[i] *= t->rgb[i];
    }
    has_factor = 1;
  }
  if (has_factor)
    memcpy(m->albedo, c, sizeof c);
  else
    m->albedo[0] = m->albedo[1] = m->albedo[2] = 0.8f;
  if (get_color(am, AI_MATKEY_COLOR_EMISSIVE, c)) {
    float k = 1.f;
    if (get_float(am, AI_MATKEY_EMISSIVE_INTENSITY, &k) && !(k >= 0.f)) k = 0.f;
    for (int i = 0; i < 3; i++) m->emission[i] = c[i] * k;
    if ((c[0] > 0 || c[1] > 0 || c[2] > 0) && !tc->warned_dae_emission && ends_with_ci(tc->path, ".dae") &&
        written_by_blender(tc->as)) {
      /* The file holds the colour alone (a strength of 20 reads as 1). */
      fprintf(stderr, "gi: warning: scene file '%s': material '%s': Blender's Collada export writes an emitter's "
              "colour without its strength, so emitters may light less than in Blender (its glTF and FBX exports "
              "keep it)\n", tc->path, m->name);
      tc->warned_dae_emission = 1;
    }
    gi_result rc = emissive_texture(am, tc, m, err);
    if (rc != GI_OK) return rc;
  }
  /* glTF's doubleSided (assimp's two-sided flag; Blender writes it unless
   * backface culling is on) lights a surface's back as its front: a lamp
   * panel modelled as one plane emits both ways, as the renderers that
   * read the file show it. */
  int two = 0;
  if (aiGetMaterialIntegerArray(am, AI_MATKEY_TWOSIDED, &two, NULL) == aiReturn_SUCCESS) m->two_sided = two != 0;
  float keep = material_lobe(am, tc, index, m);
  for (int k = 0; k < 3; k++) m->albedo[k] *= keep, mt->factor[k] *= keep;
  return GI_OK;
}

/* A Collada spot's cone: <falloff_angle> is the full cone (assimp's inner
 * angle); assimp invents an outer angle from <falloff_exponent>
 * (acos(0.1^(1/e)) wider: a 60 degree Blender spot lit 150 degrees), from
 * which e comes back. Blender writes its spot blend as e: full light within
 * (1 - blend) of the cone, as its glTF and FBX exports say. Other tools'
 * exponents shape a cos^e falloff we do not model: a hard edge at the cone. */
static void collada_spot(const struct aiLight *al, int blender, float *inner, float *outer) {
  double cone = al->mAngleInnerCone, spread = al->mAngleOuterCone - cone, blend = 0;
  /* assimp takes e = 0 as 1: that spread is Blender's blend 0 (its default
   * is 0.15; a blend of 1 reads as 0, a hard edge). */
  if (blender && spread > 0 && spread < 0.5 * GI_PI && fabs(spread - acos(0.1)) > 1e-5)
    blend = log(0.1) / log(cos(spread));
  *outer = (float)cone;
  *inner = (float)(cone * (1.0 - (blend < 1 ? blend : 1)));
}

static gi_result convert_light(const char *path, const struct aiLight *al, const gi__xform *w, const double shift[3],
                               double scale, int blender, gi_light *l, gi_error_info *err) {
  memset(l, 0, sizeof *l);
  switch (al->mType) {
    case aiLightSource_DIRECTIONAL: l->type = GI_LIGHT_SUN; break;
    case aiLightSource_POINT: l->type = GI_LIGHT_POINT; break;
    case aiLightSource_SPOT: l->type = GI_LIGHT_SPOT; break;
    default: return GI_ERR_NOT_FOUND; /* ambient, area: not supported, skipped */
  }
  l->color[0] = al->mColorDiffuse.r;
  l->color[1] = al->mColorDiffuse.g;
  l->color[2] = al->mColorDiffuse.b;
  /* Blender's FBX and Collada exporters write a lamp's power in watts (a
   * 500 W lamp reads 500), the power Cycles spreads over the sphere; its
   * glTF exporter writes the same lamp as 500 / 4 pi x 683 cd. Read as
   * W/sr, a Blender FBX lamp lit 4 pi times brighter than the same lamp
   * from its glTF. Other tools' intensities have no physical unit: as
   * they are. A sun's strength is irradiance (W/m^2) in all three. */
  if (l->type != GI_LIGHT_SUN && blender && !is_gltf(path))
    for (int k = 0; k < 3; k++) l->color[k] *= (float)(1.0 / (4.0 * GI_PI));
  /* A light is placed by the node of its name (assimp's rule), or where it
   * says when none has it. */
  const gi__xform id = {{{1, 0, 0, 0}, {0, 1, 0, 0}, {0, 0, 1, 0}}};
  if (!w) w = &id;
  double p[3], dir[3];
  gi__xform_point(w, al->mPosition.x, al->mPosition.y, al->mPosition.z, p);
  gi__xform_dir(w, al->mDirection.x, al->mDirection.y, al->mDirection.z, dir);
  for (int k = 0; k < 3; k++) {
    l->position[k] = (p[k] + shift[k]) * scale;
    l->direction[k] = (float)dir[k];
  }
  /* assimp's cone angles are full angles; ours are cosines of half-angles.
   * Its glTF reader (5.2) passes KHR_lights_punctual's angles through,
   * and those are half-angles already: halved again, a glTF spot lit half
   * its cone (0 at 0.4 rad off-axis under a 0.5 rad outer angle). */
  float half = is_gltf(path) ? 1.f : 0.5f, inner = al->mAngleInnerCone, outer = al->mAngleOuterCone;
  if (l->type == GI_LIGHT_SPOT && ends_with_ci(path, ".dae")) collada_spot(al, blender, &inner, &outer);
  l->cos_inner = cosf(half * inner);
  l->cos_outer = cosf(half * outer);
  int bad = !gi__finite3(l->color) || !isfinite(l->position[0]) || !isfinite(l->position[1]) ||
            !isfinite(l->position[2]) ||
            (l->type != GI_LIGHT_POINT && (!gi__finite3(l->direction) || !isfinite(l->cos_inner) ||
                                           (l->type == GI_LIGHT_SPOT && !isfinite(l->cos_outer))));
  if (bad)
    return gi__fail(err, GI_ERR_NONFINITE, "scene file '%s': light '%.*s' has a non-finite value", path,
                    (int)al->mName.length, al->mName.data);
  return GI_OK;
}

/* Our own checks first: assimp's messages for these cases are vague. */
static gi_result check_file(const char *path, gi_error_info *err) {
  FILE *f = gi__fopen_read(path);
  if (!f) {
    int e = errno;
    return gi__fail(err, e == ENOENT ? GI_ERR_NOT_FOUND : GI_ERR_IO, "scene file '%s': cannot open: %s", path,
                    strerror(e));
  }
  struct stat st;
  gi_result rc = GI_OK;
  if (fstat(fileno(f), &st) != 0 || !S_ISREG(st.st_mode))
    rc = gi__fail(err, GI_ERR_IO, "scene file '%s' is not a regular file", path);
  else if (st.st_size == 0)
    rc = gi__fail(err, GI_ERR_FORMAT, "scene file '%s' is empty", path);
  else if (ends_with_ci(path, ".ply"))
    rc = check_ply_header(path, f, (long long)st.st_size, err);
  fclose(f);
  return rc;
}

/* Whether a mesh of the scene has a second UV set (the lightmap's). */
static int has_second_uv(const struct aiScene *as) {
  for (unsigned i = 0; i < as->mNumMeshes; i++)
    if (as->mMeshes[i] && as->mMeshes[i]->mTextureCoords[1]) return 1;
  return 0;
}

/* assimp's import under its lock (its error string is global). Vertices
 * are joined afterwards, and only in a scene without lightmap UVs: assimp
 * 5.2's JoinIdenticalVertices compares position, normal and the first UV
 * set only, so a seam of the second set (two vertices that differ only in
 * TEXCOORD_1) was welded, one island stretched onto its neighbour's edge.
 * Unjoined, an unindexed format (FBX, Collada) costs up to three vertices
 * per triangle; glTF arrives indexed anyway. */
static gi_result import_file(const char *path, gi__gltf_shift *gs, const struct aiScene **out,
                             gi_error_info *err) {
  const unsigned flags = aiProcess_Triangulate | aiProcess_ValidateDataStructure |
                         aiProcess_SortByPType; /* not PreTransformVertices: io/assimp_nodes.h */
  struct aiFileIO io;
  gi__gltf_open_io(&io, gs);
  pthread_mutex_lock(&assimp_lock);
  *out = gs->data ? aiImportFileEx(path, flags, &io) : aiImportFile(path, flags);
  /* NULL when the step fails: the scene is released, reported below. */
  if (*out && !gs->io_oom && !gs->io_err[0] && !has_second_uv(*out))
    *out = aiApplyPostProcessing(*out, aiProcess_JoinIdenticalVertices);
  gi_result rc = GI_OK;
  if (gs->io_oom) {
    /* Even when assimp went on without the file it could not open (an
     * OBJ's material library): that scene would be quietly wrong. */
    if (*out) aiReleaseImport(*out);
    *out = NULL;
    rc = gi__fail(err, GI_ERR_NOMEM, "scene file '%s': out of memory opening its files for assimp", path);
  } else if (gs->io_err[0]) {
    /* assimp would go on without that material library: every material grey. */
    if (*out) aiReleaseImport(*out);
    *out = NULL;
    rc = gi__fail(err, GI_ERR_FORMAT, "scene file '%s': %s", path, gs->io_err);
  } else if (!*out) {
    const char *msg = aiGetErrorString();
    msg = msg && msg[0] ? msg : "unknown error";
    /* assimp's wording for the commonest failures says what it did, not
     * what is wrong with the file: say that first, keep its text after. */
    const char *why = "";
    if (strstr(msg, "No suitable reader"))
      why = "not a readable file of its type (cut short, corrupt, or another format); ";
    else if (strstr(msg, "mNumMeshes is 0") || strstr(msg, "has no faces"))
      why = "no usable triangles (binary junk, or faces whose indices are out of range); ";
    rc = gi__fail(err, GI_ERR_FORMAT, "scene file '%s': %sassimp cannot read it: %s", path, why, msg);
  }
  pthread_mutex_unlock(&assimp_lock);
  return rc;
}

/* Metres per unit of an FBX file. Its UnitScaleFactor is centimetres per
 * unit (Maya, 3ds Max and Blender's exporter write centimetres), and
 * assimp 5.2 converts only under aiProcess_GlobalScale, which would scale
 * every format's positions in float; here the factor joins the scale the
 * positions get in double, as Collada's <unit> and glTF's metres arrive.
 * A file without the factor is taken as centimetres, FBX's default. */
static gi_result fbx_metres(const struct aiScene *as, const char *path, double *metres, gi_error_info *err) {
  *metres = 0.01;
  const struct aiMetadata *md = as->mMetaData;
  for (unsigned i = 0; md && i < md->mNumProperties; i++) {
    if (strcmp(md->mKeys[i].data, "UnitScaleFactor")) continue;
    const struct aiMetadataEntry *e = &md->mValues[i];
    double f = e->mType == AI_DOUBLE ? *(const double *)e->mData : NAN;
    if (e->mType == AI_FLOAT) {
      /* assimp keeps the file's double as a float: its shortest decimal
       * (2.54, not 2.5399999618) keeps an inch file's metres exact. */
      char txt[32];
      snprintf(txt, sizeof txt, "%.7g", *(const float *)e->mData);
      f = strtod(txt, NULL);
    }
    if (!(f > 0) || !isfinite(f))
      return gi__fail(err, GI_ERR_FORMAT, "scene file '%s': FBX UnitScaleFactor is %g; expected a finite number > 0",
                      path, f);
    *metres = f * 0.01;
  }
  return GI_OK;
}

/* Counts in 64 bits, so a huge file fails before we allocate. */
typedef struct {
  const struct aiScene *as;
  uint64_t ntri, nvert;
} count_walk;

static gi_result count_node(void *ctx, const struct aiNode *nd, const gi__xform *w, int mirrored) {
  (void)w, (void)mirrored;
  count_walk *cw = ctx;
  for (unsigned i = 0; i < nd->mNumMeshes; i++) {
    if (nd->mMeshes[i] >= cw->as->mNumMeshes) continue;
    const struct aiMesh *m = cw->as->mMeshes[nd->mMeshes[i]];
    if (!(m->mPrimitiveTypes & aiPrimitiveType_TRIANGLE)) continue;
    cw->ntri += m->mNumFaces;
    cw->nvert += m->mNumVertices;
  }
  return GI_OK;
}

static gi_result check_totals(uint64_t ntri, uint64_t nvert, const char *path, gi_error_info *err) {
  if (ntri > ((uint64_t)1 << 31))
    return gi__fail(err, GI_ERR_LIMIT, "scene file '%s': %llu triangles; the limit is 2^31", path,
                    (unsigned long long)ntri);
  if (nvert >= UINT32_MAX)
    return gi__fail(err, GI_ERR_LIMIT, "scene file '%s': %llu vertices; the limit is 2^32-1", path,
                    (unsigned long long)nvert);
  if (ntri == 0) return gi__fail(err, GI_ERR_EMPTY, "scene file '%s' contains no triangles", path);
  return GI_OK;
}

/* Counts every instance (a mesh a thousand nodes use is a thousand). */
static gi_result check_counts(const struct aiScene *as, const char *path, gi_error_info *err) {
  count_walk cw = {.as = as};
  gi_result rc = gi__assimp_walk(as, count_node, &cw, err);
  return rc != GI_OK ? rc : check_totals(cw.ntri, cw.nvert, path, err);
}

/* PLY and STL carry no materials; assimp makes one up, white (diffuse and
 * specular 1), and a scan baked as a perfect white reflector, every bounce
 * at the tail's cap. Such a file gets the grey default every format gets
 * without a colour (0.8), or, when its vertices or faces carry colours (a
 * coloured scan), albedo 1: the colours are the albedo. */
static int no_materials(const char *path) { return ends_with_ci(path, ".ply") || ends_with_ci(path, ".stl"); }

/* matmap[i] = 1 where a triangle mesh uses assimp material i, else 0, in
 * one pass over the meshes (a scan per material was quadratic: 30,000
 * materials took 0.35 s); add_materials overwrites entry i at material i. */
static void mark_used(const struct aiScene *as, uint32_t *matmap) {
  memset(matmap, 0, (as->mNumMaterials + 1) * sizeof *matmap);
  for (unsigned j = 0; j < as->mNumMeshes; j++)
    if ((as->mMeshes[j]->mPrimitiveTypes & aiPrimitiveType_TRIANGLE) && as->mMeshes[j]->mMaterialIndex < as->mNumMaterials)
      matmap[as->mMeshes[j]->mMaterialIndex] = 1;
}

/* matmap's mark for a see-through material, whose triangles are left out. */
#define MAT_SEE_THROUGH (UINT32_MAX - 1)
/* A material passing at least this share of light straight through is
 * left out of the scene: the voxels and shadow rays model opaque surfaces
 * only, and a window pane taken as opaque left the room behind it dark.
 * Left out, it passes all the light and reflects none (a pane's 4-8%). */
#define SEE_THROUGH_SHARE 0.5f

/* The share of light material am passes straight through: glTF's
 * KHR_materials_transmission, or one minus its opacity where the format
 * blends by it (glTF only under alphaMode BLEND; MASK with the factor under
 * the cutoff passes all; an OBJ's d or Tr, an FBX's opacity). Textured
 * alpha is not read. */
static float see_through_share(const struct aiMaterial *am, const char *path) {
  float t = 0.f, op = 1.f;
  if (get_float(am, AI_MATKEY_TRANSMISSION_FACTOR, &t) && !(t >= 0.f && t <= 1.f)) t = 0.f;
  int has_op = get_float(am, AI_MATKEY_OPACITY, &op) && op >= 0.f && op <= 1.f;
  if (has_op && is_gltf(path)) {
    struct aiString mode;
    float cutoff = 0.5f;
    if (aiGetMaterialString(am, "$mat.gltf.alphaMode", 0, 0, &mode) != aiReturn_SUCCESS) mode.data[0] = 0;
    get_float(am, "$mat.gltf.alphaCutoff", 0, 0, &cutoff);
    if (!strcmp(mode.data, "MASK")) op = op < cutoff ? 0.f : 1.f;
    else if (strcmp(mode.data, "BLEND") != 0) op = 1.f; /* OPAQUE: alpha is ignored */
  }
  if (has_op && 1.f - op > t) t = 1.f - op;
  return t;
}

/* The file's materials into b; matmap[i] is material i's index in b.
 * assimp adds a material of its own (OBJ: "DefaultMaterial", glTF: an
 * unnamed one); it is kept only when a mesh uses it, so the material list
 * matches the file's. colored: the vertices carry colours (no_materials). */
static gi_result add_materials(const struct aiScene *as, tex_ctx *tc, gi_mesh_builder *b, uint32_t *matmap,
                               int colored, gi_error_info *err) {
  uint32_t nmat = 0;
  if (!(tc->mt = gi__malloc((as->mNumMaterials + 1) * sizeof *tc->mt)))
    return gi__fail(err, GI_ERR_NOMEM, "scene file '%s': out of memory", tc->path);
  tc->mt[0] = (mat_tex){.tex = -1}; /* the default material's, when no material is kept */
  /* Every used material see-through is more likely a file that says
   * opacity the other way round (an MTL's Tr 1 for opaque): kept then. */
  mark_used(as, matmap);
  int opaque_used = 0;
  for (unsigned i = 0; i < as->mNumMaterials && !opaque_used; i++)
    opaque_used = matmap[i] && see_through_share(as->mMaterials[i], tc->path) < SEE_THROUGH_SHARE;
  for (unsigned i = 0; i < as->mNumMaterials; i++) {
    int used = matmap[i] != 0;
    if (opaque_used && see_through_share(as->mMaterials[i], tc->path) >= SEE_THROUGH_SHARE) {
      matmap[i] = MAT_SEE_THROUGH;
      continue;
    }
    gi_material m;
    mat_tex mt;
    gi_result rc = convert_material(as->mMaterials[i], tc, i, &m, &mt, err);
    if (rc != GI_OK) return rc;
    /* An OBJ's faces before any usemtl (a file with no MTL at all: a scan)
     * take assimp's DefaultMaterial, Kd 0.6: colourless, they take the
     * default every colourless surface gets, as the same mesh as a PLY
     * does (the OBJ read 40% darker, its vertex colours times 0.6). */
    int assimps = strcmp(m.name, AI_DEFAULT_MATERIAL_NAME) == 0 || m.name[0] == 0;
    int colourless = no_materials(tc->path) || (ends_with_ci(tc->path, ".obj") && assimps);
    if (colourless) {
      float a = colored ? 1.f : 0.8f;
      m = (gi_material){.albedo = {a, a, a}, .roughness = 1.f, .name = "default"};
      mt = (mat_tex){.tex = -1};
    }
    if (mt.tex >= 0 && tc->gs && i < tc->gs->num_uv_tf) {
      mt.uv_tf = tc->gs->uv_tf[i];
      if (mt.uv_tf[5] >= 0) mt.uv = (unsigned)mt.uv_tf[5]; /* the transform's own texCoord */
    }
    matmap[i] = UINT32_MAX;
    if (!used && (assimps || (no_materials(tc->path) && !strcmp(m.name, "default")))) continue;
    tc->mt[nmat] = mt;
    matmap[i] = nmat++;
    gi_mesh_builder_add_material(b, &m);
  }
  if (nmat == 0) {
    gi_material m = {.albedo = {0.8f, 0.8f, 0.8f}, .roughness = 1.f, .name = "default"};
    gi_mesh_builder_add_material(b, &m);
  }
  return GI_OK;
}

/* A vertex colour channel as linear: glTF's COLOR_0 is linear by its spec
 * (linear set); other formats' colours are taken as sRGB-encoded, as their
 * textures are. */
static double vertex_linear(int linear, float c) {
  return linear || !(c > 0 && c <= 1) ? c : gi__srgb_to_linear(c);
}

/* The texture of our material mat over the triangle b holds as tri, from
 * its corners' uv: the triangle's own albedo (a facade's part of a city's
 * atlas, not the whole atlas's average). Nothing when mat has no texture
 * or it has no grid. */
static void texture_triangle(const tex_ctx *tc, uint32_t mat, const float uv[3][2], gi_mesh_builder *b, size_t tri) {
  const mat_tex *mt = &tc->mt[mat];
  if (mt->tex < 0 || tc->tex[mt->tex].grid.w == 0) return;
  float c[3], tuv[3][2];
  if (mt->uv_tf) {
    /* glTF's transform, in glTF's coordinates (v down; assimp gave 1 - v):
     * translation * rotation * scale, the rotation's columns (cos, sin) and
     * (-sin, cos) as KHR_texture_transform's reference shader has them. */
    const double *t = mt->uv_tf;
    double cr = cos(t[2]), sr = sin(t[2]);
    for (int k = 0; k < 3; k++) {
      double u = t[3] * uv[k][0], v = t[4] * (1.0 - uv[k][1]);
      tuv[k][0] = (float)(t[0] + cr * u - sr * v);
      tuv[k][1] = (float)(1.0 - (t[1] + sr * u + cr * v));
    }
    uv = (const float(*)[2])tuv;
  }
  gi__tex_grid_triangle_wrap(&tc->tex[mt->tex].grid, uv, mt->wrap[0], mt->wrap[1], c);
  gi_mesh_builder_set_triangle_albedo(b, tri, mt->factor[0] * c[0], mt->factor[1] * c[1], mt->factor[2] * c[2]);
}

/* add_meshes' walk. */
typedef struct {
  const struct aiScene *as;
  const uint32_t *matmap;
  const double *shift;
  tex_ctx *tc;
  gi_mesh_builder *b;
  const char *path;
  gi_error_info *err;
} mesh_walk;

/* One instance of mesh m under a node's world transform w (winding
 * reversed where w mirrors). */
static gi_result add_instance(mesh_walk *mw, const struct aiMesh *m, const gi__xform *w, int mirrored) {
  const struct aiScene *as = mw->as;
  tex_ctx *tc = mw->tc;
  gi_mesh_builder *b = mw->b;
  uint32_t mat = m->mMaterialIndex < as->mNumMaterials ? mw->matmap[m->mMaterialIndex] : 0;
  if (mat == UINT32_MAX) mat = 0;
  if (mat == MAT_SEE_THROUGH) {
    for (unsigned t = 0; t < m->mNumFaces; t++) tc->see_through += m->mFaces[t].mNumIndices == 3;
    return GI_OK;
  }
  unsigned uvset = tc->mt[mat].uv;
  int linear = is_gltf(mw->path);
  const struct aiVector3D *tuv = uvset < AI_MAX_NUMBER_OF_TEXTURECOORDS ? m->mTextureCoords[uvset] : NULL;
  uint32_t base = 0;
  for (unsigned v = 0; v < m->mNumVertices; v++) {
    double p[3];
    gi__xform_point(w, m->mVertices[v].x, m->mVertices[v].y, m->mVertices[v].z, p);
    uint32_t id = gi_mesh_builder_add_vertex(b, p[0] + mw->shift[0], p[1] + mw->shift[1], p[2] + mw->shift[2]);
    if (v == 0) base = id;
    if (m->mColors[0])
      gi_mesh_builder_set_vertex_color(b, id, vertex_linear(linear, m->mColors[0][v].r),
                                       vertex_linear(linear, m->mColors[0][v].g),
                                       vertex_linear(linear, m->mColors[0][v].b));
    /* The second UV set is the lightmap's (glTF TEXCOORD_1); assimp's V runs up. */
    if (m->mTextureCoords[1])
      gi_mesh_builder_set_lightmap_uv(b, id, m->mTextureCoords[1][v].x, 1.0 - m->mTextureCoords[1][v].y);
  }
  const int order[2][3] = {{0, 1, 2}, {0, 2, 1}};
  const int *o = order[mirrored != 0];
  for (unsigned t = 0; t < m->mNumFaces; t++) {
    const struct aiFace *fc = &m->mFaces[t];
    if (fc->mNumIndices != 3) continue; /* a point or line left in a mixed mesh */
    for (int k = 0; k < 3; k++)
      if (fc->mIndices[k] >= m->mNumVertices)
        return gi__fail(mw->err, GI_ERR_FORMAT, "scene file '%s': mesh '%.*s' face %u uses vertex %u of %u",
                        mw->path, (int)m->mName.length, m->mName.data, t, fc->mIndices[k], m->mNumVertices);
    size_t tri = gi_mesh_builder_num_triangles(b);
    gi_mesh_builder_add_triangle(b, base + fc->mIndices[o[0]], base + fc->mIndices[o[1]], base + fc->mIndices[o[2]],
                                 mat);
    if (tuv) {
      float uv[3][2];
      for (int k = 0; k < 3; k++) uv[k][0] = tuv[fc->mIndices[o[k]]].x, uv[k][1] = tuv[fc->mIndices[o[k]]].y;
      texture_triangle(tc, mat, (const float(*)[2])uv, b, tri);
    }
  }
  return GI_OK;
}

static gi_result add_node_meshes(void *ctx, const struct aiNode *nd, const gi__xform *w, int mirrored) {
  mesh_walk *mw = ctx;
  for (unsigned i = 0; i < nd->mNumMeshes; i++) {
    if (nd->mMeshes[i] >= mw->as->mNumMeshes) continue; /* assimp's validation refuses these */
    const struct aiMesh *m = mw->as->mMeshes[nd->mMeshes[i]];
    if (!(m->mPrimitiveTypes & aiPrimitiveType_TRIANGLE)) continue;
    gi_result rc = add_instance(mw, m, w, mirrored);
    if (rc != GI_OK) return rc;
  }
  return GI_OK;
}

/* Every node's triangle meshes, in world space (io/assimp_nodes.h):
 * vertices (unscaled: gi_scene_build applies opt->scale), their colours,
 * and faces into b, each textured triangle with its own part of its
 * texture; a mesh several nodes use, once per node. */
static gi_result add_meshes(const struct aiScene *as, const uint32_t *matmap, const double shift[3], tex_ctx *tc,
                            gi_mesh_builder *b, const char *path, gi_error_info *err) {
  mesh_walk mw = {.as = as, .matmap = matmap, .shift = shift, .tc = tc, .b = b, .path = path, .err = err};
  return gi__assimp_walk(as, add_node_meshes, &mw, err);
}

/* Our material index for assimp material i; 0 when assimp's was dropped,
 * MAT_SEE_THROUGH when its triangles are left out. */
static uint32_t our_material(const struct aiScene *as, const uint32_t *matmap, unsigned i) {
  return i < as->mNumMaterials && matmap[i] != UINT32_MAX ? matmap[i] : 0;
}

/* An assimp material's name and index, sorted by name then index. */
typedef struct {
  char *name;
  unsigned i;
} named_mat;

static int named_cmp(const void *a, const void *b) {
  const named_mat *x = a, *y = b;
  int c = strcmp(x->name, y->name);
  return c ? c : (x->i > y->i) - (x->i < y->i);
}

/* map[k]: our material for usemtl name k, the last assimp material of that
 * name (fallback when none), found by a binary search over the names
 * sorted once: a scan of every material per name made an OBJ of 30,000
 * materials load in 16 s. -1: out of memory. */
static int name_index_map(const struct aiScene *as, const uint32_t *matmap, const gi__exact_mesh *m,
                          uint32_t fallback, uint32_t *map) {
  named_mat *nm = gi__malloc((as->mNumMaterials + 1) * sizeof *nm);
  if (!nm) return -1;
  size_t n = 0;
  int rc = 0;
  for (unsigned i = 0; i < as->mNumMaterials && rc == 0; i++) {
    struct aiString s;
    if (aiGetMaterialString(as->mMaterials[i], AI_MATKEY_NAME, &s) != aiReturn_SUCCESS) continue;
    if (!(nm[n].name = gi__strdup(s.data))) rc = -1;
    else nm[n++].i = i;
  }
  if (rc == 0 && n) qsort(nm, n, sizeof *nm, named_cmp);
  for (size_t k = 0; rc == 0 && k < m->nnames; k++) {
    size_t lo = 0, hi = n; /* past the last entry named names[k] */
    while (lo < hi) {
      size_t mid = lo + (hi - lo) / 2;
      if (strcmp(nm[mid].name, m->names[k]) <= 0) lo = mid + 1;
      else hi = mid;
    }
    map[k] = lo > 0 && !strcmp(nm[lo - 1].name, m->names[k]) ? our_material(as, matmap, nm[lo - 1].i) : fallback;
  }
  for (size_t j = 0; j < n; j++) gi__free(nm[j].name);
  gi__free(nm);
  return rc;
}

/* OBJ and PLY positions in double (io/import_exact.c): assimp's float would
 * round a georeferenced file's coordinates before the scene subtracts its
 * origin. Materials stay assimp's, matched to usemtl by name; a face before
 * any usemtl (and every PLY face) takes the material of assimp's first mesh. */
static gi_result add_exact_meshes(const struct aiScene *as, const uint32_t *matmap, const gi__exact_mesh *mp,
                                  tex_ctx *tc, gi_mesh_builder *b, const char *path, gi_error_info *err) {
  const gi__exact_mesh m = *mp;
  uint32_t fallback = 0;
  for (unsigned i = 0; i < as->mNumMaterials; i++) {
    struct aiString n;
    if (aiGetMaterialString(as->mMaterials[i], AI_MATKEY_NAME, &n) == aiReturn_SUCCESS &&
        strcmp(n.data, AI_DEFAULT_MATERIAL_NAME) == 0)
      fallback = our_material(as, matmap, i);
  }
  if (!ends_with_ci(path, ".obj") && as->mNumMeshes)
    fallback = our_material(as, matmap, as->mMeshes[0]->mMaterialIndex);
  uint32_t *map = gi__malloc((m.nnames + 1) * sizeof *map);
  if (!map || name_index_map(as, matmap, &m, fallback, map) < 0) {
    gi__free(map);
    return gi__fail(err, GI_ERR_NOMEM, "scene file '%s': out of memory", path);
  }
  uint32_t base = 0;
  for (size_t v = 0; v < m.nv; v++) {
    uint32_t id = gi_mesh_builder_add_vertex(b, m.v[3 * v], m.v[3 * v + 1], m.v[3 * v + 2]);
    if (v == 0) base = id;
    if (m.col) gi_mesh_builder_set_vertex_color(b, id, m.col[3 * v], m.col[3 * v + 1], m.col[3 * v + 2]);
  }
  for (size_t t = 0; t < m.nt; t++) {
    uint32_t mat = m.mat[t] == GI__EXACT_NO_MATERIAL ? fallback : map[m.mat[t]];
    if (mat == MAT_SEE_THROUGH) {
      tc->see_through++;
      continue;
    }
    size_t tri = gi_mesh_builder_num_triangles(b);
    gi_mesh_builder_add_triangle(b, base + m.tri[3 * t], base + m.tri[3 * t + 1], base + m.tri[3 * t + 2], mat);
    /* A PLY face's colour is its triangles' albedo (NAN: the material's). */
    if (t < m.ntc) gi_mesh_builder_set_triangle_albedo(b, tri, m.tcol[3 * t], m.tcol[3 * t + 1], m.tcol[3 * t + 2]);
    const uint32_t *tx = m.tuv ? &m.tuv[3 * t] : NULL;
    if (tx && tx[0] != GI__EXACT_NO_UV && tx[1] != GI__EXACT_NO_UV && tx[2] != GI__EXACT_NO_UV) {
      float uv[3][2];
      for (int k = 0; k < 3; k++) uv[k][0] = m.uv[2 * tx[k]], uv[k][1] = m.uv[2 * tx[k] + 1];
      texture_triangle(tc, mat, (const float(*)[2])uv, b, tri);
    }
  }
  gi__free(map);
  return GI_OK;
}

/* The world transform of each assimp light's node, found by name. */
typedef struct {
  const struct aiScene *as;
  unsigned *by_name;  /* light indices sorted by name */
  gi__xform *world;   /* per light */
  unsigned char *placed;
} light_walk;

static void light_walk_free(light_walk *lw) {
  gi__free(lw->by_name);
  gi__free(lw->world);
  gi__free(lw->placed);
}

static int name_cmp(const struct aiString *a, const struct aiString *b) {
  unsigned n = a->length < b->length ? a->length : b->length;
  int c = memcmp(a->data, b->data, n);
  return c ? c : (a->length > b->length) - (a->length < b->length);
}

/* qsort takes no context: the scene whose lights light_name_cmp sorts, per
 * thread (scenes load on several threads at once). */
static _Thread_local const struct aiScene *sort_lights;

static int light_name_cmp(const void *x, const void *y) {
  const struct aiLight *const *L = (const struct aiLight *const *)sort_lights->mLights;
  return name_cmp(&L[*(const unsigned *)x]->mName, &L[*(const unsigned *)y]->mName);
}

/* The first node of a light's name places it. */
static gi_result place_light(void *ctx, const struct aiNode *nd, const gi__xform *w, int mirrored) {
  (void)mirrored;
  light_walk *lw = ctx;
  unsigned lo = 0, hi = lw->as->mNumLights;
  while (lo < hi) {
    unsigned mid = lo + (hi - lo) / 2;
    if (name_cmp(&lw->as->mLights[lw->by_name[mid]]->mName, &nd->mName) < 0) lo = mid + 1;
    else hi = mid;
  }
  for (; lo < lw->as->mNumLights && !name_cmp(&lw->as->mLights[lw->by_name[lo]]->mName, &nd->mName); lo++) {
    unsigned i = lw->by_name[lo];
    if (!lw->placed[i]) lw->world[i] = *w, lw->placed[i] = 1;
  }
  return GI_OK;
}

/* The file's lights (assimp's, placed by their nodes, and a glTF's own,
 * gltf_recentre.c), then the caller's, into a new array *lights (caller
 * frees) that o then points at. */
static gi_result collect_lights(const struct aiScene *as, const gi__gltf_shift *gs, const char *path, double scale,
                                gi_scene_options *o, gi_light **lights, uint32_t *skipped, gi_error_info *err) {
  if (o->num_lights && !o->lights)
    return gi__fail(err, GI_ERR_INVALID_ARG, "options: num_lights is %zu but lights is NULL", o->num_lights);
  size_t nl = 0;
  gi_light *l = *lights = gi__calloc(as->mNumLights + gs->num_lights + o->num_lights + 1, sizeof *l);
  if (!l) return gi__fail(err, GI_ERR_NOMEM, "scene file '%s': out of memory", path);
  int blender = written_by_blender(as);
  light_walk lw = {.as = as};
  if (as->mNumLights) {
    lw.by_name = gi__malloc(as->mNumLights * sizeof *lw.by_name);
    lw.world = gi__malloc(as->mNumLights * sizeof *lw.world);
    lw.placed = gi__calloc(as->mNumLights, 1);
    if (!lw.by_name || !lw.world || !lw.placed) {
      light_walk_free(&lw);
      return gi__fail(err, GI_ERR_NOMEM, "scene file '%s': out of memory", path);
    }
    for (unsigned i = 0; i < as->mNumLights; i++) lw.by_name[i] = i;
    sort_lights = as;
    qsort(lw.by_name, as->mNumLights, sizeof *lw.by_name, light_name_cmp);
    sort_lights = NULL;
    gi_result rc = gi__assimp_walk(as, place_light, &lw, err);
    if (rc != GI_OK) {
      light_walk_free(&lw);
      return rc;
    }
  }
  for (unsigned i = 0; i < as->mNumLights; i++) {
    gi_result r = convert_light(path, as->mLights[i], lw.placed[i] ? &lw.world[i] : NULL, gs->t, scale, blender,
                                &l[nl], err);
    if (r == GI_OK) nl++;
    else if (r == GI_ERR_NOT_FOUND) ++*skipped;
    else {
      light_walk_free(&lw);
      return r;
    }
  }
  light_walk_free(&lw);
  for (size_t i = 0; i < gs->num_lights; i++) {
    l[nl] = gs->lights[i];
    for (int k = 0; k < 3; k++) l[nl].position[k] *= scale;
    nl++;
  }
  for (size_t i = 0; i < o->num_lights; i++) l[nl++] = o->lights[i];
  o->lights = l;
  o->num_lights = nl;
  return GI_OK;
}

/* Builds the scene, named after the file's base name without its
 * extension; a file whose every triangle was dropped is an error. */
static gi_result build(const gi_mesh_builder *b, const char *path, const gi_scene_options *o, const tex_ctx *tc,
                       gi_scene **out, gi_error_info *err) {
  char name[128];
  const char *slash = strrchr(path, '/');
  snprintf(name, sizeof name, "%s", slash ? slash + 1 : path);
  char *dot = strrchr(name, '.');
  if (dot && dot != name) *dot = 0;
  gi_error_info e2 = {0};
  gi_result rc = gi_scene_build(b, name, o, out, &e2);
  if (rc != GI_OK) return gi__fail(err, rc, "scene file '%s': %s", path, e2.msg);
  (*out)->stats.textures_unreadable = tc->unreadable;
  (*out)->stats.dropped_see_through = tc->see_through;
  (*out)->stats.input_triangles += tc->see_through;
  gi_scene_stats ss;
  gi_scene_get_stats(*out, &ss);
  if (ss.triangles > 0) return GI_OK;
  gi_scene_release(*out);
  *out = NULL;
  return gi__fail(err, GI_ERR_EMPTY,
                  "scene file '%s': all %llu triangles were dropped (%llu with non-finite positions, %llu degenerate)",
                  path, (unsigned long long)ss.input_triangles, (unsigned long long)ss.dropped_nonfinite,
                  (unsigned long long)ss.dropped_degenerate);
}

/* A Collada file's <up_axis> (in its first 64 KiB): 'Z' or 'X', else 0
 * (Y_UP, none, or unreadable). */
static char collada_up(const char *path) {
  FILE *f = fopen(path, "rb");
  if (!f) return 0;
  static const size_t cap = 65536;
  char *buf = gi__malloc(cap + 1);
  size_t n = buf ? fread(buf, 1, cap, f) : 0;
  fclose(f);
  char up = 0;
  if (buf) {
    buf[n] = 0;
    const char *t = strstr(buf, "<up_axis>");
    if (t) {
      t += strlen("<up_axis>");
      while (*t == ' ' || *t == '\t' || *t == '\r' || *t == '\n') t++;
      if (!strncmp(t, "Z_UP", 4)) up = 'Z';
      else if (!strncmp(t, "X_UP", 4)) up = 'X';
    }
  }
  gi__free(buf);
  return up;
}

/* assimp turns every Collada file Y-up (a Z_UP file's y is its z, its z
 * the file's -y): --up z then laid a Blender room on its side, and points
 * given in the file's own coordinates missed it. Refused with z up; a note
 * names the frame otherwise. */
static gi_result check_collada_up(const char *path, gi_up_axis up, gi_error_info *err) {
  char ax = ends_with_ci(path, ".dae") ? collada_up(path) : 0;
  if (!ax) return GI_OK;
  if (up == GI_UP_Z)
    return gi__fail(err, GI_ERR_INVALID_ARG,
                    "scene file '%s' declares <up_axis>%c_UP</up_axis>, and assimp reads every Collada file turned "
                    "Y-up: load it with up y (gi-bake's default), not z", path, ax);
  fprintf(stderr, "gi: note: scene file '%s' declares <up_axis>%c_UP</up_axis> and is read turned Y-up: points and "
          "bounds are in that frame (%s)\n", path, ax,
          ax == 'Z' ? "its y is the file's z, its z the file's -y" : "its y is the file's x");
  return GI_OK;
}

gi_result gi_scene_load(const char *path, const gi_scene_options *opt, gi_scene **out, gi_error_info *err) {
  gi_scene_options o = {0};
  if (!out) return gi__fail(err, GI_ERR_INVALID_ARG, "gi_scene_load: out is NULL");
  *out = NULL;
  if (!path || !path[0]) return gi__fail(err, GI_ERR_INVALID_ARG, "gi_scene_load: no file name given");
  if (opt) o = *opt;
  double scale = o.scale == 0 ? 1.0 : o.scale;
  if (!isfinite(scale)) return gi__fail(err, GI_ERR_NONFINITE, "scene file '%s': scale is not finite", path);
  gi_result rc = check_file(path, err);
  if (rc == GI_OK && ends_with_ci(path, ".fbx")) rc = gi__fbx_check(path, err);
  if (rc == GI_OK) rc = check_collada_up(path, o.up, err);
  if (rc != GI_OK) return rc;

  const struct aiScene *as = NULL;
  gi_mesh_builder *b = NULL;
  gi_light *lights = NULL;
  uint32_t skipped = 0;
  uint32_t *matmap = NULL;
  tex_ctx tc = {.path = path};
  /* Our strict reader first: its errors name the line, assimp's do not. */
  gi__exact_mesh em = {0};
  gi__gltf_shift gs = {.path = path};
  int exact = ends_with_ci(path, ".obj") || ends_with_ci(path, ".ply");
  if (exact && (rc = ends_with_ci(path, ".obj") ? gi__exact_read_obj(path, &em, err)
                                                : gi__exact_read_ply(path, &em, err)) != GI_OK)
    goto done;
  if (is_gltf(path) && (rc = gi__gltf_recentre(path, ends_with_ci(path, ".glb"), &gs, err)) != GI_OK) goto done;
  /* assimp reads an OBJ's materials (a PLY has none) from a stub of it,
   * served in its place as a rewritten glTF is: our reader has its geometry
   * already, and assimp's second parse doubled the load (2M triangles:
   * 2.2 -> 0.54 s, 1.08 -> 0.39 GB). */
  if (exact && em.nv == 0) {
    rc = gi__fail(err, GI_ERR_FORMAT, "scene file '%s': no usable triangles (binary junk, or no vertex in it)", path);
    goto done;
  }
  if (exact && (rc = check_totals(em.nt, em.nv, path, err)) != GI_OK) goto done;
  if (exact && !(gs.data = (unsigned char *)(ends_with_ci(path, ".obj") ? gi__exact_obj_stub(&em, &gs.len)
                                                                        : gi__exact_ply_stub(&gs.len)))) {
    rc = gi__fail(err, GI_ERR_NOMEM, "scene file '%s': out of memory", path);
    goto done;
  }
  if ((rc = import_file(path, &gs, &as, err)) != GI_OK || (!exact && (rc = check_counts(as, path, err)) != GI_OK))
    goto done;
  if (ends_with_ci(path, ".fbx")) {
    double metres;
    if ((rc = fbx_metres(as, path, &metres, err)) != GI_OK) goto done;
    scale *= metres;
    o.scale = scale;
  }
  tc.as = as;
  tc.mtllib = em.mtllib;
  tc.gs = is_gltf(path) ? &gs : NULL;
  b = gi_mesh_builder_new();
  matmap = gi__malloc((as->mNumMaterials + 1) * sizeof *matmap);
  if (!b || !matmap) {
    rc = gi__fail(err, GI_ERR_NOMEM, "scene file '%s': out of memory", path);
    goto done;
  }
  int colored = em.col != NULL || em.tcol != NULL;
  for (unsigned i = 0; i < as->mNumMeshes && !colored; i++) colored = as->mMeshes[i]->mColors[0] != NULL;
  if ((rc = add_materials(as, &tc, b, matmap, colored, err)) == GI_OK &&
      (rc = exact ? add_exact_meshes(as, matmap, &em, &tc, b, path, err)
                  : add_meshes(as, matmap, gs.t, &tc, b, path, err)) == GI_OK &&
      (rc = collect_lights(as, &gs, path, scale, &o, &lights, &skipped, err)) == GI_OK &&
      (rc = build(b, path, &o, &tc, out, err)) == GI_OK)
    (*out)->stats.lights_skipped = skipped;

done:
  if (as) aiReleaseImport(as);
  gi__exact_free(&em);
  gi__gltf_shift_free(&gs);
  gi__free(lights);
  gi__free(matmap);
  tex_ctx_fini(&tc);
  gi_mesh_builder_free(b);
  return rc;
}
