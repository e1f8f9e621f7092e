/* io/gltf_recentre.c: glTF node transforms composed in double (see the
 * header for why). jansson parses and rewrites the JSON; the binary chunk
 * of a .glb is kept byte for byte. */
#define _DEFAULT_SOURCE /* realpath */
#include "io/gltf_recentre.h"
#include "io/gltf_accessors.h"
#include "io/import_exact.h" /* gi__exact_mtl_normalise */
#include "io/texture_image.h"  /* gi__read_file */
#include <assimp/cfileio.h>
#include <float.h>
#include <jansson.h>
#include <limits.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h> /* strcasecmp */
#include "base/internal.h"
#include "gi/gi_scene.h"

#define GLB_MAGIC 0x46546C67u      /* "glTF" */
#define GLB_CHUNK_JSON 0x4E4F534Au /* "JSON" */
#define GLB_CHUNK_BIN 0x004E4942u  /* "BIN\0" */
#define GLB_HEADER 12
#define GLB_CHUNK_HEADER 8
/* Digits that carry a double through text unchanged. */
#define JSON_PRECISION 17

static uint32_t le32(const unsigned char *p) {
  return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static void put_le32(unsigned char *p, uint32_t v) {
  for (int i = 0; i < 4; i++) p[i] = (unsigned char)(v >> (8 * i));
}

/* The whole file (caller frees). */
static unsigned char *read_all(const char *path, size_t *len, gi_error_info *err) {
  FILE *f = fopen(path, "rb");
  if (!f) {
    gi__fail(err, GI_ERR_IO, "scene file '%s': cannot open", path);
    return NULL;
  }
  unsigned char *buf = NULL;
  long n = -1;
  if (fseek(f, 0, SEEK_END) == 0 && (n = ftell(f)) >= 0 && fseek(f, 0, SEEK_SET) == 0) {
    buf = gi__malloc((size_t)n + 1);
    if (buf && fread(buf, 1, (size_t)n, f) != (size_t)n) {
      gi__free(buf);
      buf = NULL;
    }
  }
  fclose(f);
  if (!buf) gi__fail(err, n < 0 ? GI_ERR_IO : GI_ERR_NOMEM, "scene file '%s': cannot read it", path);
  *len = (size_t)(n < 0 ? 0 : n);
  return buf;
}

/* ---- matrices: column-major 4x4 in double, as glTF stores them ---------- */

static void mat_mul(const double a[16], const double b[16], double out[16]) {
  double r[16];
  for (int c = 0; c < 4; c++)
    for (int row = 0; row < 4; row++) {
      double s = 0;
      for (int k = 0; k < 4; k++) s += a[k * 4 + row] * b[c * 4 + k];
      r[c * 4 + row] = s;
    }
  memcpy(out, r, sizeof r);
}

/* Reads n finite numbers from a JSON array member; 0 when absent. */
static int numbers(json_t *node, const char *key, double *out, size_t n, const char *path, size_t idx,
                   gi_error_info *err) {
  json_t *a = json_object_get(node, key);
  if (!a) return 0;
  if (!json_is_array(a) || json_array_size(a) != n) {
    gi__fail(err, GI_ERR_FORMAT, "scene file '%s': glTF node %zu: '%s' must be an array of %zu numbers", path, idx,
             key, n);
    return -1;
  }
  for (size_t i = 0; i < n; i++) {
    json_t *v = json_array_get(a, i);
    out[i] = json_is_number(v) ? json_number_value(v) : NAN;
    if (!isfinite(out[i])) {
      gi__fail(err, GI_ERR_FORMAT, "scene file '%s': glTF node %zu: '%s'[%zu] is not a finite number", path, idx, key,
               i);
      return -1;
    }
  }
  return 1;
}

/* translation * rotation (a quaternion x, y, z, w) * scale. */
static void trs_matrix(const double t[3], const double q[4], const double s[3], double m[16]) {
  double x = q[0], y = q[1], z = q[2], w = q[3];
  double r[9] = {1 - 2 * (y * y + z * z), 2 * (x * y + z * w),     2 * (x * z - y * w),
                 2 * (x * y - z * w),     1 - 2 * (x * x + z * z), 2 * (y * z + x * w),
                 2 * (x * z + y * w),     2 * (y * z - x * w),     1 - 2 * (x * x + y * y)};
  for (int c = 0; c < 3; c++) {
    for (int row = 0; row < 3; row++) m[c * 4 + row] = r[c * 3 + row] * s[c];
    m[c * 4 + 3] = 0;
  }
  m[12] = t[0], m[13] = t[1], m[14] = t[2], m[15] = 1;
}

/* Node idx's own matrix: 'matrix', or translation * rotation * scale. */
static int local_matrix(json_t *node, const char *path, size_t idx, double m[16], gi_error_info *err) {
  int has = numbers(node, "matrix", m, 16, path, idx, err);
  if (has) return has < 0 ? -1 : 0;
  double t[3] = {0, 0, 0}, q[4] = {0, 0, 0, 1}, s[3] = {1, 1, 1};
  if (numbers(node, "translation", t, 3, path, idx, err) < 0 || numbers(node, "rotation", q, 4, path, idx, err) < 0 ||
      numbers(node, "scale", s, 3, path, idx, err) < 0)
    return -1;
  trs_matrix(t, q, s, m);
  return 0;
}

/* A node that draws something assimp must place: a mesh or a light. */
static int carries_content(json_t *node) {
  json_t *ext = json_object_get(node, "extensions");
  return json_object_get(node, "mesh") || (ext && json_object_get(ext, "KHR_lights_punctual"));
}

typedef struct walk {
  json_t *root;
  json_t *nodes;
  gi__gltf_bin *bin; /* the file's buffers (EXT_mesh_gpu_instancing) */
  size_t instances;        /* expanded so far */
  const char *path;
  unsigned char *seen;
  size_t *order; /* content nodes in depth-first order */
  double *world; /* 16 per node */
  size_t count;
  gi_error_info *err;
} walk;

/* Depth-first from node idx under parent matrix pm; an explicit stack would
 * only matter for graphs deeper than any exporter writes, and every node is
 * visited once, so a cyclic file cannot loop. */
static int visit(walk *w, size_t idx, const double pm[16], int depth) {
  if (idx >= json_array_size(w->nodes) || w->seen[idx] || depth > 1024) {
    gi__fail(w->err, GI_ERR_FORMAT, "scene file '%s': glTF node %zu is out of range, reached twice or nested too deep",
             w->path, idx);
    return -1;
  }
  w->seen[idx] = 1;
  json_t *node = json_array_get(w->nodes, idx);
  double lm[16];
  if (!json_is_object(node) || local_matrix(node, w->path, idx, lm, w->err) < 0) {
    if (!json_is_object(node)) gi__fail(w->err, GI_ERR_FORMAT, "scene file '%s': glTF node %zu is not an object",
                                        w->path, idx);
    return -1;
  }
  mat_mul(pm, lm, &w->world[16 * idx]);
  if (carries_content(node)) w->order[w->count++] = idx;
  json_t *ch = json_object_get(node, "children");
  for (size_t i = 0; ch && i < json_array_size(ch); i++) {
    json_t *c = json_array_get(ch, i);
    if (!json_is_integer(c) || json_integer_value(c) < 0) {
      gi__fail(w->err, GI_ERR_FORMAT, "scene file '%s': glTF node %zu: children[%zu] is not a node index", w->path,
               idx, i);
      return -1;
    }
    if (visit(w, (size_t)json_integer_value(c), &w->world[16 * idx], depth + 1) < 0) return -1;
  }
  return 0;
}

/* m less t as a JSON matrix. */
static json_t *matrix_json(const double world[16], const double t[3]) {
  double m[16];
  memcpy(m, world, sizeof m);
  for (int i = 0; i < 3; i++) m[12 + i] -= t[i];
  json_t *arr = json_array();
  for (int i = 0; arr && i < 16; i++)
    if (json_array_append_new(arr, json_real(m[i]))) {
      json_decref(arr);
      return NULL;
    }
  return arr;
}

/* ---- EXT_mesh_gpu_instancing: each instance a node of its own ----------- */

#define GPU_INSTANCING "EXT_mesh_gpu_instancing"
/* Instances a file may expand to, in all: each becomes a node and a copy
 * of its mesh (the triangle count is checked after, io/import_assimp.c). */
#define GLTF_MAX_INSTANCES ((size_t)1 << 20)

/* Node k's instances (its extension's TRANSLATION, ROTATION and SCALE, each
 * optional, of one count) as roots: new nodes holding its mesh at world x
 * instance, less t; the node itself keeps no mesh. 1 when it has the
 * extension, 0 when not, -1 on error (w->err set). */
static int expand_instances(walk *w, size_t k, const double t[3], json_t *roots) {
  json_t *node = json_array_get(w->nodes, w->order[k]), *ext = json_object_get(node, "extensions");
  json_t *inst = json_object_get(ext, GPU_INSTANCING), *mesh = json_object_get(node, "mesh");
  if (!inst || !mesh) return 0;
  json_t *attrs = json_object_get(inst, "attributes");
  static const char *const names[3] = {"TRANSLATION", "ROTATION", "SCALE"};
  double *v[3] = {NULL, NULL, NULL};
  size_t n = SIZE_MAX;
  int rc = 0;
  char what[96];
  snprintf(what, sizeof what, "glTF node %zu's " GPU_INSTANCING, w->order[k]);
  for (int a = 0; a < 3 && rc == 0; a++) {
    json_t *ai = json_object_get(attrs, names[a]);
    if (!ai) continue;
    size_t c = 0, room = GLTF_MAX_INSTANCES - w->instances;
    if (!json_is_integer(ai) || gi__gltf_accessor_read(w->root, w->bin, json_integer_value(ai), a == 1 ? 4 : 3, a == 1,
                                                      room, what, &v[a], &c, w->err) != GI_OK) {
      if (!json_is_integer(ai))
        gi__fail(w->err, GI_ERR_FORMAT, "scene file '%s': %s: %s is not an accessor index", w->path, what, names[a]);
      rc = -1;
    } else if (n != SIZE_MAX && c != n) {
      gi__fail(w->err, GI_ERR_FORMAT, "scene file '%s': %s: %s has %zu elements where the others have %zu", w->path,
               what, names[a], c, n);
      rc = -1;
    }
    n = c;
  }
  if (rc == 0 && n == SIZE_MAX) {
    gi__fail(w->err, GI_ERR_FORMAT, "scene file '%s': %s: no TRANSLATION, ROTATION or SCALE", w->path, what);
    rc = -1;
  }
  for (size_t i = 0; rc == 0 && i < n; i++) {
    double tr[3] = {0, 0, 0}, q[4] = {0, 0, 0, 1}, s[3] = {1, 1, 1}, lm[16], wm[16];
    if (v[0]) memcpy(tr, &v[0][3 * i], sizeof tr);
    if (v[1]) memcpy(q, &v[1][4 * i], sizeof q);
    if (v[2]) memcpy(s, &v[2][3 * i], sizeof s);
    int finite = 1;
    for (int c = 0; c < 4; c++) finite &= isfinite(q[c]) && (c == 3 || (isfinite(tr[c]) && isfinite(s[c])));
    if (!finite) {
      gi__fail(w->err, GI_ERR_NONFINITE, "scene file '%s': %s: instance %zu has a non-finite value", w->path, what, i);
      rc = -1;
      break;
    }
    trs_matrix(tr, q, s, lm);
    mat_mul(&w->world[16 * w->order[k]], lm, wm);
    /* jansson's _new calls take their argument's reference even when they fail. */
    json_t *nn = json_object(), *mj = matrix_json(wm, t);
    int bad = !nn || !mj;
    if (!bad) bad = json_object_set_new(nn, "matrix", mj), mj = NULL;
    if (!bad) bad = json_object_set(nn, "mesh", mesh);
    if (!bad) bad = json_array_append_new(w->nodes, nn), nn = NULL;
    if (!bad) bad = json_array_append_new(roots, json_integer((json_int_t)json_array_size(w->nodes) - 1));
    if (bad) {
      json_decref(nn);
      json_decref(mj);
      gi__fail(w->err, GI_ERR_NOMEM, "scene file '%s': out of memory expanding %s", w->path, what);
      rc = -1;
    }
  }
  for (int a = 0; a < 3; a++) gi__free(v[a]);
  if (rc < 0) return -1;
  w->instances += n;
  json_object_del(node, "mesh");
  json_object_del(ext, GPU_INSTANCING);
  return 1;
}

/* Replaces the default scene by its content nodes as roots, each with its
 * world matrix less t (an instanced mesh's node by one node per instance). */
static int flatten(json_t *scene, walk *w, double t[3]) {
  const double *first = &w->world[16 * w->order[0]];
  t[0] = first[12], t[1] = first[13], t[2] = first[14];
  json_t *roots = json_array();
  if (!roots) {
    gi__fail(w->err, GI_ERR_NOMEM, "scene file '%s': out of memory rewriting the glTF scene", w->path);
    return -1;
  }
  for (size_t k = 0; k < w->count; k++) {
    json_t *node = json_array_get(w->nodes, w->order[k]);
    int inst = expand_instances(w, k, t, roots);
    json_t *arr = inst == 0 ? matrix_json(&w->world[16 * w->order[k]], t) : NULL;
    if (inst < 0 || (inst == 0 && (!arr || json_object_set_new(node, "matrix", arr) ||
                                   json_array_append_new(roots, json_integer((json_int_t)w->order[k]))))) {
      if (inst == 0) gi__fail(w->err, GI_ERR_NOMEM, "scene file '%s': out of memory rewriting the glTF scene", w->path);
      json_decref(roots);
      return -1;
    }
    json_object_del(node, "translation");
    json_object_del(node, "rotation");
    json_object_del(node, "scale");
    json_object_del(node, "children");
  }
  return json_object_set_new(scene, "nodes", roots) ? -1 : 0;
}

/* ---- KHR_lights_punctual: read here, hidden from assimp ----------------- */

#define KHR_LIGHTS "KHR_lights_punctual"
/* KHR_lights_punctual's intensities are photometric: candela for point and
 * spot lights, lux for directional ones. Ours are radiometric (W/sr, W/m^2):
 * divided by the luminous efficacy the glTF exporters convert with (683
 * lm/W; Blender writes a 1000 W lamp as 54351 cd and a sun of 3 W/m^2 as
 * 2049 lux). Read as they were, Blender's lights baked 683x too bright. */
#define GLTF_LUMENS_PER_WATT 683.0

/* The light reference of a node, or NULL. */
static json_t *node_light(json_t *node) { return json_object_get(json_object_get(node, "extensions"), KHR_LIGHTS); }

/* Member key of object def (a light's definition, a material's texture
 * transform; `what` names it in the message, "light 3"): n finite numbers
 * into out (one number for n = 1, else an array), left as they are when
 * absent. 1 when read, 0 when absent, -1 with err set when it is not that. */
static int member_numbers(json_t *def, const char *key, double *out, size_t n, const char *path, const char *what,
                          gi_error_info *err) {
  json_t *a = json_object_get(def, key);
  if (!a) return 0;
  for (size_t i = 0; i < n; i++) {
    json_t *v = n == 1 ? a : json_array_get(a, i);
    double x = json_is_number(v) ? json_number_value(v) : NAN;
    if ((n > 1 && (!json_is_array(a) || json_array_size(a) != n)) || !isfinite(x)) {
      gi__fail(err, GI_ERR_FORMAT, "scene file '%s': glTF %s: '%s' must be %s%zu finite number%s", path, what, key,
               n > 1 ? "an array of " : "", n, n > 1 ? "s" : "");
      return -1;
    }
    out[i] = x;
  }
  return 1;
}

/* The light node idx refers to, placed by its world matrix m (column-major:
 * a light sits at the node's origin and shines down its -z), into *l;
 * *range its point or spot light's range (0: none given). */
static int read_light(json_t *defs, json_t *node, size_t idx, const double m[16], const char *path, gi_light *l,
                      double *range, gi_error_info *err) {
  json_t *ref = json_object_get(node_light(node), "light");
  json_int_t li = json_is_integer(ref) ? json_integer_value(ref) : -1;
  json_t *def = li >= 0 ? json_array_get(defs, (size_t)li) : NULL;
  if (!json_is_object(def)) {
    gi__fail(err, GI_ERR_FORMAT, "scene file '%s': glTF node %zu: its light is not one of the file's %zu lights",
             path, idx, json_array_size(defs));
    return -1;
  }
  const char *type = json_string_value(json_object_get(def, "type"));
  memset(l, 0, sizeof *l);
  if (type && !strcmp(type, "directional")) l->type = GI_LIGHT_SUN;
  else if (type && !strcmp(type, "point")) l->type = GI_LIGHT_POINT;
  else if (type && !strcmp(type, "spot")) l->type = GI_LIGHT_SPOT;
  else {
    gi__fail(err, GI_ERR_FORMAT, "scene file '%s': glTF light %lld: type must be directional, point or spot", path,
             (long long)li);
    return -1;
  }
  double c[3] = {1, 1, 1}, in = 1, cone[2] = {0, GI_PI / 4};
  json_t *spot = json_object_get(def, "spot");
  char what[32];
  snprintf(what, sizeof what, "light %lld", (long long)li);
  if (member_numbers(def, "color", c, 3, path, what, err) < 0 ||
      member_numbers(def, "intensity", &in, 1, path, what, err) < 0 ||
      member_numbers(spot, "innerConeAngle", &cone[0], 1, path, what, err) < 0 ||
      member_numbers(spot, "outerConeAngle", &cone[1], 1, path, what, err) < 0)
    return -1;
  if (l->type == GI_LIGHT_SPOT && !json_is_object(spot)) {
    gi__fail(err, GI_ERR_FORMAT, "scene file '%s': glTF light %lld: a spot light needs its 'spot' object", path,
             (long long)li);
    return -1;
  }
  /* The spec's ranges (assimp refused an inner cone wider than the outer),
   * but for equal angles: the spec asks inner < outer, and Blender writes
   * a spot with no blend (a hard edge, its FBX's too) as inner = outer. */
  if (l->type == GI_LIGHT_SPOT && !(cone[0] >= 0 && cone[0] <= cone[1] && cone[1] > 0 && cone[1] <= GI_PI / 2)) {
    gi__fail(err, GI_ERR_FORMAT, "scene file '%s': glTF light %lld: cone angles %g and %g; expected 0 <= "
             "innerConeAngle <= outerConeAngle <= pi/2, outerConeAngle > 0", path, (long long)li, cone[0], cone[1]);
    return -1;
  }
  for (int k = 0; k < 3; k++) {
    l->color[k] = (float)(c[k] * in / GLTF_LUMENS_PER_WATT);
    l->position[k] = m[12 + k];
    l->direction[k] = (float)-m[8 + k];
  }
  /* glTF's cone angles are half-angles, as ours are. */
  l->cos_inner = (float)cos(cone[0]);
  l->cos_outer = (float)cos(cone[1]);
  json_t *r = json_object_get(def, "range");
  *range = l->type != GI_LIGHT_SUN && json_is_number(r) && json_number_value(r) > 0 ? json_number_value(r) : 0;
  return 0;
}

/* The lights of the content nodes into out (world matrices in w), then
 * every trace of the extension taken out of root for assimp. */
static int take_lights(json_t *root, walk *w, gi__gltf_shift *out) {
  json_t *defs = json_object_get(json_object_get(json_object_get(root, "extensions"), KHR_LIGHTS), "lights");
  size_t n = 0;
  for (size_t k = 0; k < w->count; k++) n += node_light(json_array_get(w->nodes, w->order[k])) != NULL;
  if (n && !(out->lights = gi__calloc(n, sizeof *out->lights))) {
    gi__fail(w->err, GI_ERR_NOMEM, "scene file '%s': out of memory for %zu glTF lights", w->path, n);
    return -1;
  }
  size_t ranged = 0;
  double first_range = 0;
  for (size_t k = 0; k < w->count; k++) {
    json_t *node = json_array_get(w->nodes, w->order[k]);
    double range;
    if (!node_light(node)) continue;
    if (read_light(defs, node, w->order[k], &w->world[16 * w->order[k]], w->path, &out->lights[out->num_lights],
                   &range, w->err) < 0)
      return -1;
    if (range > 0 && !ranged++) first_range = range;
    out->num_lights++;
    json_object_del(json_object_get(node, "extensions"), KHR_LIGHTS);
  }
  /* gi_light has no cutoff: a light with a range lights past it, as the
   * spec's "infinite" range would. Said once per file, not per lamp. */
  if (ranged)
    fprintf(stderr, "gi: note: scene file '%s': %zu glTF point or spot light%s a range (the first %g), which is "
            "ignored: lights fall off as 1/d^2 without a cutoff\n", w->path, ranged, ranged == 1 ? " gives" : "s give",
            first_range);
  json_object_del(json_object_get(root, "extensions"), KHR_LIGHTS);
  const char *lists[2] = {"extensionsUsed", "extensionsRequired"};
  for (int i = 0; i < 2; i++) {
    json_t *a = json_object_get(root, lists[i]);
    for (size_t j = json_array_size(a); j-- > 0;) {
      const char *name = json_string_value(json_array_get(a, j));
      if (name && !strcmp(name, KHR_LIGHTS)) json_array_remove(a, j);
    }
  }
  return 0;
}

/* The default scene, or NULL when the file has none to place. */
static json_t *default_scene(json_t *root) {
  json_t *scenes = json_object_get(root, "scenes");
  json_t *si = json_object_get(root, "scene");
  size_t s = json_is_integer(si) && json_integer_value(si) >= 0 ? (size_t)json_integer_value(si) : 0;
  json_t *scene = json_array_get(scenes, s);
  return json_is_object(scene) && json_is_array(json_object_get(scene, "nodes")) ? scene : NULL;
}

/* Rewrites root's scene graph in place; 1 when it did, 0 when there was
 * nothing to place, -1 on error (err set). */
static int recentre_json(json_t *root, gi__gltf_bin *bin, gi__gltf_shift *out, gi_error_info *err) {
  json_t *scene = default_scene(root), *nodes = json_object_get(root, "nodes");
  if (!scene || !json_is_array(nodes) || json_array_size(nodes) == 0) return 0;
  size_t n = json_array_size(nodes);
  const char *path = bin->path;
  walk w = {.root = root, .nodes = nodes, .bin = bin, .path = path, .err = err};
  w.seen = gi__calloc(n, 1);
  w.order = gi__malloc(n * sizeof *w.order);
  w.world = gi__malloc(n * 16 * sizeof *w.world);
  int rc = -1;
  if (!w.seen || !w.order || !w.world) {
    gi__fail(err, GI_ERR_NOMEM, "scene file '%s': out of memory for %zu glTF nodes", path, n);
    goto done;
  }
  static const double identity[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
  json_t *rn = json_object_get(scene, "nodes");
  for (size_t i = 0; i < json_array_size(rn); i++) {
    json_t *v = json_array_get(rn, i);
    if (!json_is_integer(v) || json_integer_value(v) < 0) {
      gi__fail(err, GI_ERR_FORMAT, "scene file '%s': glTF scene nodes[%zu] is not a node index", path, i);
      goto done;
    }
    if (visit(&w, (size_t)json_integer_value(v), identity, 0) < 0) goto done;
  }
  rc = 0;
  if (w.count && take_lights(root, &w, out) < 0) rc = -1;
  else if (w.count) rc = flatten(scene, &w, out->t) < 0 ? -1 : 1;
done:
  gi__free(w.seen);
  gi__free(w.order);
  gi__free(w.world);
  return rc;
}

#define KHR_EMISSIVE_STRENGTH "KHR_materials_emissive_strength"

/* KHR_materials_emissive_strength multiplies a material's emissiveFactor
 * (held in [0, 1] by the core spec) by its emissiveStrength. assimp 5.2
 * ignores the extension, and Blender writes every emitter brighter than 1
 * that way: its Cornell box's lamp read 18.4x too dark. The strength is
 * folded into the factor here and the extension taken off the material.
 * Returns the materials changed, -1 with err set on a strength that is not
 * a finite number >= 0 or a factor that is not three numbers. */
static int fold_emissive_strength(json_t *root, const char *path, gi_error_info *err) {
  json_t *mats = json_object_get(root, "materials");
  int changed = 0;
  for (size_t i = 0; i < json_array_size(mats); i++) {
    json_t *m = json_array_get(mats, i), *ext = json_object_get(m, "extensions");
    json_t *es = json_object_get(ext, KHR_EMISSIVE_STRENGTH);
    if (!es) continue;
    json_t *sv = json_object_get(es, "emissiveStrength");
    double k = sv ? (json_is_number(sv) ? json_number_value(sv) : NAN) : 1.0; /* the spec's default */
    if (!(k >= 0) || !isfinite(k)) {
      gi__fail(err, GI_ERR_FORMAT, "scene file '%s': glTF material %zu: " KHR_EMISSIVE_STRENGTH
               " emissiveStrength must be a finite number >= 0", path, i);
      return -1;
    }
    char what[32];
    snprintf(what, sizeof what, "material %zu", i);
    double f[3];
    int has = member_numbers(m, "emissiveFactor", f, 3, path, what, err);
    if (has < 0) return -1;
    for (size_t c = 0; has && c < 3; c++) {
      if (!(fabs(f[c] * k) <= FLT_MAX)) {
        /* Past float: the scene's own limit (GI_MAX_LIGHT_VALUE) can no longer name it. */
        gi__fail(err, GI_ERR_LIMIT, "scene file '%s': glTF material %zu: emissiveFactor %g x emissiveStrength %g "
                 "overflows", path, i, f[c], k);
        return -1;
      }
      if (json_array_set_new(json_object_get(m, "emissiveFactor"), c, json_real(f[c] * k)) < 0) {
        gi__fail(err, GI_ERR_NOMEM, "scene file '%s': out of memory", path);
        return -1;
      }
    }
    json_object_del(ext, KHR_EMISSIVE_STRENGTH);
    changed++;
  }
  return changed;
}

#define KHR_SPECULAR "KHR_materials_specular"
#define KHR_IOR "KHR_materials_ior"

/* Each material's dielectric reflectance at normal incidence into
 * out->f0 where KHR_materials_specular or KHR_materials_ior gives it (NAN
 * where neither does: the core spec's 4%): min(((ior - 1) / (ior + 1))^2
 * specularColorFactor, 1) specularFactor, the colour by its luminance.
 * assimp 5.2 reads neither, and Blender writes the specular one for every
 * Principled Specular other than 0.5: Specular 0 (no reflection in
 * Cycles) read as a 4% lobe, 5.8x Cycles' floor under a lamp. 0, or -1
 * with err set on a value out of its range (naming the material). */
static int read_specular(json_t *root, const char *path, gi__gltf_shift *out, gi_error_info *err) {
  json_t *mats = json_object_get(root, "materials");
  size_t n = json_array_size(mats);
  for (size_t i = 0; i < n; i++) {
    json_t *ext = json_object_get(json_array_get(mats, i), "extensions");
    json_t *sp = json_object_get(ext, KHR_SPECULAR), *io = json_object_get(ext, KHR_IOR);
    if (!sp && !io) continue;
    char what[64];
    snprintf(what, sizeof what, "material %zu %s", i, sp ? KHR_SPECULAR : KHR_IOR);
    double ior = 1.5, f = 1, c[3] = {1, 1, 1};
    if (member_numbers(io, "ior", &ior, 1, path, what, err) < 0 || member_numbers(sp, "specularFactor", &f, 1, path,
                                                                                   what, err) < 0 ||
        member_numbers(sp, "specularColorFactor", c, 3, path, what, err) < 0)
      return -1;
    if (!(ior >= 1) || !(f >= 0 && f <= 1) || !(c[0] >= 0 && c[1] >= 0 && c[2] >= 0)) {
      gi__fail(err, GI_ERR_FORMAT, "scene file '%s': glTF %s: ior must be >= 1, specularFactor in [0, 1] and "
               "specularColorFactor >= 0", path, what);
      return -1;
    }
    if (!out->f0) {
      if (!(out->f0 = gi__malloc(n * sizeof *out->f0))) {
        gi__fail(err, GI_ERR_NOMEM, "scene file '%s': out of memory for material reflectances", path);
        return -1;
      }
      for (size_t k = 0; k < n; k++) out->f0[k] = NAN;
      out->num_f0 = n;
    }
    double r = (ior - 1) / (ior + 1), lum = 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2];
    out->f0[i] = (float)(fmin(r * r * lum, 1.0) * f);
  }
  return 0;
}

#define KHR_TEXTURE_TRANSFORM "KHR_texture_transform"

/* Each material's base-colour texture transform into out->uv_tf (see the
 * header); 0, or -1 with err set on a transform whose numbers are not
 * finite (or out of memory). */
static int read_uv_transforms(json_t *root, const char *path, gi__gltf_shift *out, gi_error_info *err) {
  json_t *mats = json_object_get(root, "materials");
  size_t n = json_array_size(mats);
  for (size_t i = 0; i < n; i++) {
    json_t *ti = json_object_get(json_object_get(json_array_get(mats, i), "pbrMetallicRoughness"), "baseColorTexture");
    json_t *tf = json_object_get(json_object_get(ti, "extensions"), KHR_TEXTURE_TRANSFORM);
    if (!json_is_object(tf)) continue;
    if (!out->uv_tf) {
      if (!(out->uv_tf = gi__malloc(n * sizeof *out->uv_tf))) {
        gi__fail(err, GI_ERR_NOMEM, "scene file '%s': out of memory for texture transforms", path);
        return -1;
      }
      for (size_t k = 0; k < n; k++)
        for (int j = 0; j < GI_GLTF_UV_TF; j++) out->uv_tf[k][j] = j == 3 || j == 4 ? 1 : j == 5 ? -1 : 0;
      out->num_uv_tf = n;
    }
    double *o = out->uv_tf[i];
    char what[64];
    snprintf(what, sizeof what, "material %zu: " KHR_TEXTURE_TRANSFORM, i);
    if (member_numbers(tf, "offset", &o[0], 2, path, what, err) < 0 ||
        member_numbers(tf, "rotation", &o[2], 1, path, what, err) < 0 ||
        member_numbers(tf, "scale", &o[3], 2, path, what, err) < 0)
      return -1;
    json_t *tc = json_object_get(tf, "texCoord");
    if (json_is_integer(tc) && json_integer_value(tc) >= 0 && json_integer_value(tc) < 8)
      o[5] = (double)json_integer_value(tc);
  }
  return 0;
}

/* An integer member, def when absent, -1 when not a non-negative integer. */
static json_int_t sparse_int(json_t *o, const char *key, json_int_t def) {
  json_t *v = json_object_get(o, key);
  if (!v) return def;
  return json_is_integer(v) && json_integer_value(v) >= 0 ? json_integer_value(v) : -1;
}

/* Bytes of one element of a glTF type ("VEC3") of componentType ct; 0 if unknown. */
static json_int_t element_bytes(const char *type, json_int_t ct) {
  static const struct { const char *name; int n; } types[] = {{"SCALAR", 1}, {"VEC2", 2}, {"VEC3", 3}, {"VEC4", 4},
                                                                {"MAT2", 4},   {"MAT3", 9}, {"MAT4", 16}};
  int size = ct == 5120 || ct == 5121 ? 1 : ct == 5122 || ct == 5123 ? 2 : ct == 5125 || ct == 5126 ? 4 : 0;
  for (size_t i = 0; type && i < sizeof types / sizeof types[0]; i++)
    if (!strcmp(type, types[i].name)) return size * types[i].n;
  return 0;
}

/* One part (indices or values) of accessor a's sparse storage: `count`
 * elements of `bytes` each must lie inside its bufferView. 0, or -1 with
 * err set. */
static int sparse_part(json_t *root, json_t *part, const char *name, json_int_t count, json_int_t bytes,
                       const char *path, size_t a, gi_error_info *err) {
  json_t *bv = json_array_get(json_object_get(root, "bufferViews"), (size_t)sparse_int(part, "bufferView", -1));
  json_int_t off = sparse_int(part, "byteOffset", 0), boff = sparse_int(bv, "byteOffset", 0);
  json_int_t blen = sparse_int(bv, "byteLength", -1);
  if (!json_is_object(part) || !json_is_object(bv) || off < 0 || boff < 0 || blen < 0 || bytes <= 0) {
    gi__fail(err, GI_ERR_FORMAT, "scene file '%s': glTF accessor %zu: sparse %s needs a bufferView that exists, "
             "non-negative byte offsets and a known component type", path, a, name);
    return -1;
  }
  /* count <= the accessor's count (checked) and bytes <= 64: no overflow for counts under 2^56. */
  if ((uint64_t)count > ((uint64_t)1 << 56) || (uint64_t)off + (uint64_t)count * (uint64_t)bytes > (uint64_t)blen) {
    gi__fail(err, GI_ERR_FORMAT, "scene file '%s': glTF accessor %zu: sparse %s need %lld bytes from byteOffset "
             "%lld, but bufferView %lld holds %lld", path, a, name, (long long)count * (long long)bytes,
             (long long)off, (long long)sparse_int(part, "bufferView", -1), (long long)blen);
    return -1;
  }
  return 0;
}

/* Sparse accessors checked before assimp reads them: assimp 5.2 copies
 * sparse.count elements from the indices and values bufferViews before it
 * checks they are there (a count of 1e9 over 4 stored: a heap overread,
 * found under ASan). 0, or -1 with err set. */
static int check_sparse(json_t *root, const char *path, gi_error_info *err) {
  json_t *accs = json_object_get(root, "accessors");
  for (size_t a = 0; a < json_array_size(accs); a++) {
    json_t *acc = json_array_get(accs, a), *sp = json_object_get(acc, "sparse");
    if (!sp) continue;
    json_int_t n = sparse_int(acc, "count", -1), sc = sparse_int(sp, "count", -1);
    if (!json_is_object(sp) || n < 0 || sc < 1 || sc > n) {
      gi__fail(err, GI_ERR_FORMAT, "scene file '%s': glTF accessor %zu: sparse count must be 1..%lld (the "
               "accessor's count)", path, a, (long long)n);
      return -1;
    }
    json_t *ix = json_object_get(sp, "indices");
    json_int_t ict = sparse_int(ix, "componentType", -1);
    json_int_t ib = ict == 5121 ? 1 : ict == 5123 ? 2 : ict == 5125 ? 4 : 0;
    json_int_t vb = element_bytes(json_string_value(json_object_get(acc, "type")), sparse_int(acc, "componentType", -1));
    if (sparse_part(root, ix, "indices", sc, ib, path, a, err) < 0 ||
        sparse_part(root, json_object_get(sp, "values"), "values", sc, vb, path, a, err) < 0)
      return -1;
  }
  return 0;
}

/* Points and lines (primitive modes 0-3) are no surface to bake, and
 * assimp 5.2 crashes on a line loop whose indices pass its vertex count (a
 * segfault; with one index, an assertion abort): they leave the file
 * before assimp reads it, as the import would skip them after. Returns
 * how many were taken out. */
static int drop_points_and_lines(json_t *root) {
  json_t *meshes = json_object_get(root, "meshes");
  int n = 0;
  for (size_t i = 0; i < json_array_size(meshes); i++) {
    json_t *prims = json_object_get(json_array_get(meshes, i), "primitives");
    for (size_t j = json_array_size(prims); j-- > 0;) {
      json_t *mode = json_object_get(json_array_get(prims, j), "mode");
      json_int_t m = json_is_integer(mode) ? json_integer_value(mode) : 4; /* the spec's default: triangles */
      if (m >= 0 && m <= 3 && json_array_remove(prims, j) == 0) n++;
    }
  }
  return n;
}

/* Every primitive's indices against its vertex count (POSITION's count):
 * assimp 5.2 drops a triangle with an index past them without a word (rc
 * 0, the triangle gone from input_triangles), where the OBJ and PLY
 * readers refuse such a file. A Draco primitive's indices are the
 * decoder's, and assimp checks those. 0, or -1 with err naming the mesh,
 * the primitive and the index. Each buffer is read once (bin's cache). */
static int check_indices(json_t *root, gi__gltf_bin *bin, const char *path, gi_error_info *err) {
  json_t *meshes = json_object_get(root, "meshes"), *accs = json_object_get(root, "accessors");
  for (size_t i = 0; i < json_array_size(meshes); i++) {
    json_t *mesh = json_array_get(meshes, i), *prims = json_object_get(mesh, "primitives");
    for (size_t j = 0; j < json_array_size(prims); j++) {
      json_t *prim = json_array_get(prims, j), *ix = json_object_get(prim, "indices");
      json_t *pos = json_object_get(json_object_get(prim, "attributes"), "POSITION");
      if (!json_is_integer(ix) || !json_is_integer(pos) ||
          json_object_get(json_object_get(prim, "extensions"), "KHR_draco_mesh_compression"))
        continue;
      json_t *pc = json_object_get(json_array_get(accs, (size_t)json_integer_value(pos)), "count");
      if (!json_is_integer(pc) || json_integer_value(pc) < 0) continue; /* assimp says what is wrong */
      uint64_t nv = (uint64_t)json_integer_value(pc), v;
      size_t at;
      int r = gi__gltf_indices_past(root, bin, json_integer_value(ix), nv, &at, &v, err);
      if (r < 0) return -1;
      if (r == 0 || at == SIZE_MAX) continue;
      const char *name = json_string_value(json_object_get(mesh, "name"));
      gi__fail(err, GI_ERR_FORMAT, "scene file '%s': glTF mesh %zu%s%s%s primitive %zu: index %llu (element %zu of "
               "accessor %lld) is out of range; expected 0..%llu (its POSITION accessor has %llu vertices)", path, i,
               name ? " '" : "", name ? name : "", name ? "'" : "", j, (unsigned long long)v, at,
               (long long)json_integer_value(ix), (unsigned long long)(nv ? nv - 1 : 0), (unsigned long long)nv);
      return -1;
    }
  }
  return 0;
}

/* assimp 5.2 reads a primitive's TEXCOORD_n (and COLOR_n, JOINTS_n,
 * WEIGHTS_n) in the order its attributes object lists them and refuses
 * the file unless they come 0, 1, ... ("must start with 0 and be
 * continuous"); a JSON object has no order, so a valid file listing
 * TEXCOORD_1 first was refused. Such a set is listed again in index
 * order. Returns how many primitives changed. */
#define ATTR_SET_MAX 64
static int order_attribute_sets(json_t *root) {
  static const char *const sets[] = {"TEXCOORD_", "COLOR_", "JOINTS_", "WEIGHTS_"};
  json_t *meshes = json_object_get(root, "meshes");
  int changed = 0;
  for (size_t i = 0; i < json_array_size(meshes); i++) {
    json_t *prims = json_object_get(json_array_get(meshes, i), "primitives");
    for (size_t j = 0; j < json_array_size(prims); j++) {
      json_t *attrs = json_object_get(json_array_get(prims, j), "attributes");
      if (!json_is_object(attrs)) continue;
      int moved = 0;
      for (size_t k = 0; k < sizeof sets / sizeof sets[0]; k++) {
        size_t pl = strlen(sets[k]);
        long last = -1, top = -1;
        int sorted = 1;
        const char *key;
        json_t *v;
        json_object_foreach(attrs, key, v) {
          char *end;
          if (strncmp(key, sets[k], pl) || !key[pl]) continue;
          long n = strtol(key + pl, &end, 10);
          if (*end || n < 0 || n >= ATTR_SET_MAX) continue; /* not an index: assimp says what it makes of it */
          if (n < last) sorted = 0;
          last = n, top = n > top ? n : top;
        }
        for (long n = 0; !sorted && n <= top; n++) {
          char name[32];
          snprintf(name, sizeof name, "%s%ld", sets[k], n);
          json_t *val = json_object_get(attrs, name);
          if (!val) continue;
          json_incref(val);
          json_object_del(attrs, name);
          json_object_set_new(attrs, name, val); /* now after the ones before it */
        }
        moved |= !sorted;
      }
      changed += moved;
    }
  }
  return changed;
}

/* The extensions a file may require: what this loader reads (lights,
 * emissive strength, the base colour's texture transform, transmission as
 * a see-through share, GPU instancing: here and in import_assimp.c) and
 * what assimp 5.2 decodes (Draco, through libdraco). Sorted. */
static const char *const supported_required[] = {
    "EXT_mesh_gpu_instancing", "KHR_draco_mesh_compression", "KHR_lights_punctual",
    "KHR_materials_emissive_strength", "KHR_materials_ior", "KHR_materials_specular", "KHR_materials_transmission",
    "KHR_texture_transform"};
#define NUM_SUPPORTED_REQUIRED (sizeof supported_required / sizeof supported_required[0])

/* extensionsRequired: the spec says a loader that lacks one must fail.
 * assimp 5.2 never checks, and a file of quantized positions
 * (KHR_mesh_quantization: SHORT read as float bits, bounds of 9e-41) or
 * of KTX2 or WebP textures alone loaded quietly wrong. 0, or -1 with err
 * naming every extension missing and those that are read. */
static int check_required(json_t *root, const char *path, gi_error_info *err) {
  json_t *req = json_object_get(root, "extensionsRequired");
  char missing[256] = "", known[256] = "";
  size_t nm = 0, len = 0;
  for (size_t i = 0; i < json_array_size(req); i++) {
    const char *name = json_string_value(json_array_get(req, i));
    if (!name) {
      gi__fail(err, GI_ERR_FORMAT, "scene file '%s': glTF extensionsRequired[%zu] is not a string", path, i);
      return -1;
    }
    size_t k = 0;
    while (k < NUM_SUPPORTED_REQUIRED && strcmp(name, supported_required[k])) k++;
    if (k < NUM_SUPPORTED_REQUIRED) continue;
    /* snprintf cuts a long list short; the first names are the message. */
    if (len < sizeof missing) len += (size_t)snprintf(missing + len, sizeof missing - len, "%s%s", nm ? ", " : "", name);
    nm++;
  }
  if (!nm) return 0;
  for (size_t k = 0, n = 0; k < NUM_SUPPORTED_REQUIRED; k++)
    n += (size_t)snprintf(known + n, sizeof known - n, "%s%s", k ? ", " : "", supported_required[k]);
  gi__fail(err, GI_ERR_FORMAT, "scene file '%s': the glTF requires extension%s %s, which %s not supported (the "
           "extensions read are %s)", path, nm == 1 ? "" : "s", missing, nm == 1 ? "is" : "are", known);
  return -1;
}

/* A texture whose image is only in an extension (KHR_texture_basisu's
 * KTX2, EXT_texture_webp's WebP) and that has no fallback 'source': assimp
 * 5.2 gives the material no texture at all, and its colour factor went
 * on alone without a word. The extension's image becomes the texture's
 * source, which the texture reader refuses as it does a missing PNG: a
 * warning naming it, counted as textures_unreadable. Returns how many
 * textures changed. */
static int expose_extension_images(json_t *root) {
  json_t *texs = json_object_get(root, "textures");
  int changed = 0;
  for (size_t i = 0; i < json_array_size(texs); i++) {
    json_t *t = json_array_get(texs, i), *ext = json_object_get(t, "extensions"), *v;
    const char *key;
    if (!json_is_object(t) || json_object_get(t, "source")) continue;
    json_object_foreach(ext, key, v) {
      json_t *src = json_object_get(v, "source");
      if (!json_is_integer(src) || json_integer_value(src) < 0) continue;
      if (json_object_set(t, "source", src) == 0) changed++;
      break;
    }
  }
  return changed;
}

/* The JSON text of a .gltf, or the JSON chunk of a .glb. */
static int split_glb(const unsigned char *buf, size_t len, size_t *json_off, size_t *json_len) {
  if (len < GLB_HEADER + GLB_CHUNK_HEADER || le32(buf) != GLB_MAGIC || le32(buf + 12 + 4) != GLB_CHUNK_JSON) return -1;
  size_t cl = le32(buf + 12);
  if (cl > len - GLB_HEADER - GLB_CHUNK_HEADER) return -1;
  *json_off = GLB_HEADER + GLB_CHUNK_HEADER;
  *json_len = cl;
  return 0;
}

/* A .glb's binary chunk, the one after the JSON chunk (at off), if any. */
static void glb_bin_chunk(const unsigned char *buf, size_t len, size_t off, gi__gltf_bin *bin) {
  if (off > len || len - off < GLB_CHUNK_HEADER || le32(buf + off + 4) != GLB_CHUNK_BIN) return;
  size_t cl = le32(buf + off);
  if (cl > len - off - GLB_CHUNK_HEADER) return;
  bin->glb_bin = buf + off + GLB_CHUNK_HEADER;
  bin->glb_bin_len = cl;
}

/* The new file: text alone, or a .glb with text as its JSON chunk and the
 * original chunks after it. */
static int assemble(gi__gltf_shift *out, const char *text, const unsigned char *buf, size_t len, int glb,
                    size_t json_off, size_t json_len) {
  size_t tl = strlen(text), padded = (tl + 3) & ~(size_t)3;
  size_t rest = glb ? len - json_off - json_len : 0;
  size_t total = glb ? GLB_HEADER + GLB_CHUNK_HEADER + padded + rest : tl;
  if (glb && total > UINT32_MAX) return -1;
  out->data = gi__malloc(total ? total : 1);
  if (!out->data) return -1;
  if (!glb) {
    memcpy(out->data, text, tl);
  } else {
    memcpy(out->data, buf, GLB_HEADER);
    put_le32(out->data + 8, (uint32_t)total);
    put_le32(out->data + 12, (uint32_t)padded);
    put_le32(out->data + 16, GLB_CHUNK_JSON);
    memcpy(out->data + 20, text, tl);
    memset(out->data + 20 + tl, ' ', padded - tl); /* the spec pads JSON with spaces */
    memcpy(out->data + 20 + padded, buf + json_off + json_len, rest);
  }
  out->len = total;
  return 0;
}

gi_result gi__gltf_recentre(const char *path, int glb, gi__gltf_shift *out, gi_error_info *err) {
  memset(out, 0, sizeof *out);
  out->path = path;
  size_t len = 0, json_off = 0, json_len = 0;
  unsigned char *buf = read_all(path, &len, err);
  if (!buf) return err ? err->code : GI_ERR_IO;
  gi_result rc = GI_OK;
  if (glb && split_glb(buf, len, &json_off, &json_len) < 0) {
    rc = gi__fail(err, GI_ERR_FORMAT, "scene file '%s': not a readable glTF binary (cut short, corrupt, or another format): "
                  "bad header or JSON chunk", path);
    goto done;
  }
  if (!glb) json_len = len;
  json_error_t je;
  json_t *root = json_loadb((const char *)buf + json_off, json_len, 0, &je);
  if (!root) {
    rc = gi__fail(err, GI_ERR_FORMAT, "scene file '%s': not a readable glTF (cut short, corrupt, or another format): "
                  "JSON line %d column %d: %s", path, je.line, je.column, je.text);
    goto done;
  }
  gi__gltf_bin bin = {.path = path};
  if (glb) glb_bin_chunk(buf, len, json_off + json_len, &bin);
  int folded = check_required(root, path, err) < 0 || check_sparse(root, path, err) < 0 ||
                       read_uv_transforms(root, path, out, err) < 0 || read_specular(root, path, out, err) < 0
                   ? -1
                   : fold_emissive_strength(root, path, err);
  if (folded >= 0) folded += drop_points_and_lines(root) + order_attribute_sets(root) + expose_extension_images(root);
  if (folded >= 0 && check_indices(root, &bin, path, err) < 0) folded = -1;
  int r = folded < 0 ? -1 : recentre_json(root, &bin, out, err);
  gi__gltf_bin_fini(&bin); /* before assimp reads the buffers again */
  if (r == 0 && folded > 0) r = 1; /* no scene graph to place, but the materials or primitives changed */
  char *text = r > 0 ? json_dumps(root, JSON_COMPACT | JSON_REAL_PRECISION(JSON_PRECISION)) : NULL;
  json_decref(root);
  if (r < 0) {
    rc = err ? err->code : GI_ERR_FORMAT;
  } else if (r > 0 && (!text || assemble(out, text, buf, len, glb, json_off, json_len) < 0)) {
    rc = gi__fail(err, GI_ERR_NOMEM, "scene file '%s': out of memory rewriting the glTF scene", path);
  }
  free(text);
done:
  gi__free(buf);
  if (rc != GI_OK) gi__gltf_shift_free(out);
  return rc;
}

void gi__gltf_shift_free(gi__gltf_shift *s) {
  gi__free(s->data);
  gi__free(s->lights);
  gi__free(s->uv_tf);
  gi__free(s->f0);
  s->data = NULL;
  s->lights = NULL;
  s->uv_tf = NULL;
  s->f0 = NULL;
  s->num_f0 = 0;
  s->len = s->num_lights = s->num_uv_tf = 0;
}

/* ---- the assimp file system: the rewritten file from memory ------------- */

typedef struct mem_file {
  const unsigned char *data; /* NULL: read f */
  size_t len, pos;
  FILE *f;
  char *owned; /* data when it is ours to free (a rewritten MTL file) */
} mem_file;

static size_t io_read(struct aiFile *af, char *buf, size_t size, size_t count) {
  mem_file *m = (mem_file *)af->UserData;
  if (!m->data) return fread(buf, size, count, m->f);
  if (size == 0) return 0;
  size_t n = (m->len - m->pos) / size;
  if (n > count) n = count;
  memcpy(buf, m->data + m->pos, n * size);
  m->pos += n * size;
  return n;
}

static size_t io_write(struct aiFile *af, const char *buf, size_t size, size_t count) {
  (void)af, (void)buf, (void)size, (void)count;
  return 0; /* imports never write */
}

static size_t io_tell(struct aiFile *af) {
  mem_file *m = (mem_file *)af->UserData;
  return m->data ? m->pos : (size_t)ftell(m->f);
}

static size_t io_size(struct aiFile *af) {
  mem_file *m = (mem_file *)af->UserData;
  if (m->data) return m->len;
  long here = ftell(m->f), end = -1;
  if (fseek(m->f, 0, SEEK_END) == 0) end = ftell(m->f);
  fseek(m->f, here, SEEK_SET);
  return end < 0 ? 0 : (size_t)end;
}

static enum aiReturn io_seek(struct aiFile *af, size_t off, enum aiOrigin origin) {
  mem_file *m = (mem_file *)af->UserData;
  if (!m->data) {
    int whence = origin == aiOrigin_SET ? SEEK_SET : origin == aiOrigin_CUR ? SEEK_CUR : SEEK_END;
    return fseek(m->f, (long)off, whence) == 0 ? aiReturn_SUCCESS : aiReturn_FAILURE;
  }
  size_t base = origin == aiOrigin_SET ? 0 : origin == aiOrigin_CUR ? m->pos : m->len;
  if (off > m->len - base) return aiReturn_FAILURE;
  m->pos = base + off;
  return aiReturn_SUCCESS;
}

static void io_flush(struct aiFile *af) { (void)af; }

/* Same file: the same string, or the same resolved path. */
static int same_path(const char *a, const char *b) {
  if (!strcmp(a, b)) return 1;
  char ra[PATH_MAX], rb[PATH_MAX];
  return realpath(a, ra) && realpath(b, rb) && !strcmp(ra, rb);
}

static struct aiFile *io_open(struct aiFileIO *io, const char *name, const char *mode) {
  gi__gltf_shift *s = (gi__gltf_shift *)io->UserData;
  if (mode && strchr(mode, 'w')) return NULL;
  struct aiFile *af = gi__calloc(1, sizeof *af);
  mem_file *m = gi__calloc(1, sizeof *m);
  if (!af || !m) {
    s->io_oom = 1;
    goto fail;
  }
  size_t nl = strlen(name);
  if (s->data && same_path(name, s->path)) {
    m->data = s->data;
    m->len = s->len;
  } else if (nl > 4 && !strcasecmp(name + nl - 4, ".mtl")) {
    /* An OBJ's material library, its colours as the MTL format means them. */
    void *text = NULL;
    size_t len = 0;
    gi_error_info e = {0};
    gi_result rc = gi__read_file(name, GI__TEXTURE_FILE_MAX, &text, &len, &e);
    if (rc != GI_OK) {
      s->io_oom |= rc == GI_ERR_NOMEM;
      goto fail; /* unreadable: assimp goes on without it, and scan_mtl warns */
    }
    char msg[sizeof s->io_err];
    m->owned = gi__exact_mtl_normalise(name, text, len, &m->len, msg, sizeof msg);
    gi__free(text);
    if (!m->owned) {
      if (!msg[0]) s->io_oom = 1;
      else if (!s->io_err[0]) memcpy(s->io_err, msg, sizeof msg); /* the first bad library */
      goto fail;
    }
    m->data = (const unsigned char *)m->owned;
  } else if (!(m->f = fopen(name, "rb"))) {
    goto fail;
  }
  af->ReadProc = io_read;
  af->WriteProc = io_write;
  af->TellProc = io_tell;
  af->FileSizeProc = io_size;
  af->SeekProc = io_seek;
  af->FlushProc = io_flush;
  af->UserData = (aiUserData)m;
  return af;
fail:
  gi__free(af);
  gi__free(m);
  return NULL;
}

static void io_close(struct aiFileIO *io, struct aiFile *af) {
  (void)io;
  if (!af) return;
  mem_file *m = (mem_file *)af->UserData;
  if (m && m->f) fclose(m->f);
  if (m) gi__free(m->owned);
  gi__free(m);
  gi__free(af);
}

void gi__gltf_open_io(struct aiFileIO *io, gi__gltf_shift *s) {
  io->OpenProc = io_open;
  io->CloseProc = io_close;
  io->UserData = (aiUserData)s;
}
