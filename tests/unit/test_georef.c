/* test_georef.c: georeferenced files load exactly (issue 16, item 4).
 *
 * City files come in projected coordinates (UTM: easting ~7e5, northing
 * ~5e6). The shared Cornell box and Munich are shifted there and to 1e7,
 * written as OBJ (%.17g), binary PLY with double properties and glTF with
 * node translations (the mesh stays local, as float32), loaded and
 * baked at the shifted viewpoint; probes must match the unshifted bake to
 * 1e-3 relative. Before the double-precision readers (io/import_exact.c)
 * assimp parsed positions into float. Malformed files must say where. */
#include "test_util.h"
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "gi/gi.h"
#include "io/import_exact.h"

/* Issue 16: probes within 1e-3 relative of the unshifted bake. */
#define GEOREF_TOLERANCE 1e-3
/* Not round numbers, so world and local coordinates round differently. */
static const double utm_shift[3] = {691000.37, 5334000.81, 0.0};
static const double far_shift[3] = {1e7 + 0.3217, -1e7 + 0.77, 1e7 + 0.129};

/* The whole file, NUL-terminated (caller frees). */
static char *slurp(const char *path, size_t *len) {
  FILE *f = fopen(path, "rb");
  assert_non_null(f);
  fseek(f, 0, SEEK_END);
  long n = ftell(f);
  fseek(f, 0, SEEK_SET);
  char *buf = malloc((size_t)n + 1);
  assert_non_null(buf);
  assert_int_equal(fread(buf, 1, (size_t)n, f), (size_t)n);
  buf[n] = 0;
  fclose(f);
  if (len) *len = (size_t)n;
  return buf;
}

/* Copies the OBJ at src into the temporary folder as name with every vertex
 * moved by s (printed with %.17g: the double round-trips), and its MTL
 * (mtl_name, next to src) beside it. Returns the new path. */
static const char *write_shifted_obj(const char *src, const char *mtl_name, const char *name, const double s[3]) {
  char *text = slurp(src, NULL);
  size_t cap = 2 * strlen(text) + 4096, n = 0;
  char *out = malloc(cap);
  assert_non_null(out);
  for (char *line = strtok(text, "\n"); line; line = strtok(NULL, "\n")) {
    if (n + 256 + strlen(line) > cap) assert_non_null(out = realloc(out, cap *= 2));
    double p[3];
    if (line[0] == 'v' && line[1] == ' ' && sscanf(line + 2, "%lf %lf %lf", &p[0], &p[1], &p[2]) == 3)
      n += (size_t)sprintf(out + n, "v %.17g %.17g %.17g\n", p[0] + s[0], p[1] + s[1], p[2] + s[2]);
    else
      n += (size_t)sprintf(out + n, "%s\n", line);
  }
  const char *path = tu_write_file(name, out, n);
  free(out);
  free(text);
  if (mtl_name) {
    char mp[4096];
    snprintf(mp, sizeof mp, "%.*s%s", (int)(strrchr(src, '/') + 1 - src), src, mtl_name);
    size_t ml;
    char *mtl = slurp(mp, &ml);
    tu_write_file(mtl_name, mtl, ml);
    free(mtl);
  }
  return path;
}

static void put_bytes(unsigned char **p, const void *v, int n, int big) {
  for (int i = 0; i < n; i++) (*p)[i] = ((const unsigned char *)v)[big ? n - 1 - i : i];
  *p += n;
}

/* The OBJ's geometry moved by s as a binary PLY with double x, y, z; checks
 * that our reader gives back exactly the doubles written. */
static const char *write_shifted_ply(const char *src, const char *name, const double s[3], int big) {
  gi__exact_mesh m;
  gi_error_info err = {0};
  assert_int_equal(gi__exact_read_obj(src, &m, &err), GI_OK);
  char head[512];
  int hl = snprintf(head, sizeof head,
                    "ply\nformat binary_%s_endian 1.0\ncomment shifted by test_georef\nelement vertex %zu\n"
                    "property double x\nproperty double y\nproperty double z\nelement face %zu\n"
                    "property list uchar int vertex_indices\nend_header\n",
                    big ? "big" : "little", m.nv, m.nt);
  size_t len = (size_t)hl + m.nv * 24 + m.nt * 13;
  unsigned char *buf = malloc(len), *p = buf + hl;
  assert_non_null(buf);
  memcpy(buf, head, (size_t)hl);
  for (size_t i = 0; i < 3 * m.nv; i++) {
    double x = m.v[i] + s[i % 3];
    put_bytes(&p, &x, 8, big);
  }
  for (size_t t = 0; t < m.nt; t++) {
    unsigned char three = 3;
    put_bytes(&p, &three, 1, big);
    for (int k = 0; k < 3; k++) {
      int32_t idx = (int32_t)m.tri[3 * t + k];
      put_bytes(&p, &idx, 4, big);
    }
  }
  assert_int_equal((size_t)(p - buf), len);
  const char *path = tu_write_file(name, buf, len);
  free(buf);
  /* Read back: bit-exact positions, the same triangles. */
  gi__exact_mesh r;
  gi_result rc = gi__exact_read_ply(path, &r, &err);
  if (rc) fprintf(stderr, "%s\n", err.msg);
  assert_int_equal(rc, GI_OK);
  assert_int_equal(r.nv, m.nv);
  assert_int_equal(r.nt, m.nt);
  for (size_t i = 0; i < 3 * m.nv; i++) assert_true(r.v[i] == m.v[i] + s[i % 3]);
  assert_memory_equal(r.tri, m.tri, 3 * m.nt * sizeof *m.tri);
  gi__exact_free(&r);
  gi__exact_free(&m);
  return path;
}

/* Cornell's geometry as glTF: the mesh in a child node translated by
 * child_t (its vertices written less child_t, as float32, the glTF type),
 * under a root node that moves everything by s (as 'translation', or as a
 * 'matrix' when as_matrix), and a KHR point light under the ceiling beside
 * the mesh. glb: one binary file; else .gltf with an external .bin, so the
 * importer must still find files beside the one it rewrote. */
static const double child_t[3] = {1.5, -2.25, 0.125};

static const char *write_shifted_gltf(const char *src, const char *name, const double s[3], int glb, int as_matrix) {
  gi__exact_mesh m;
  gi_error_info err = {0};
  assert_int_equal(gi__exact_read_obj(src, &m, &err), GI_OK);
  size_t pos_bytes = 12 * m.nv, idx_bytes = 12 * m.nt, bin_len = pos_bytes + idx_bytes;
  unsigned char *bin = malloc(bin_len);
  assert_non_null(bin);
  float lo[3] = {1e30f, 1e30f, 1e30f}, hi[3] = {-1e30f, -1e30f, -1e30f};
  for (size_t i = 0; i < 3 * m.nv; i++) {
    float f = (float)(m.v[i] - child_t[i % 3]);
    memcpy(bin + 4 * i, &f, 4);
    lo[i % 3] = fminf(lo[i % 3], f), hi[i % 3] = fmaxf(hi[i % 3], f);
  }
  memcpy(bin + pos_bytes, m.tri, idx_bytes);
  char root_tf[512], bin_name[256], buf_uri[300] = "";
  if (as_matrix)
    snprintf(root_tf, sizeof root_tf, "\"matrix\":[1,0,0,0,0,1,0,0,0,0,1,0,%.17g,%.17g,%.17g,1]", s[0], s[1], s[2]);
  else
    snprintf(root_tf, sizeof root_tf, "\"translation\":[%.17g,%.17g,%.17g]", s[0], s[1], s[2]);
  snprintf(bin_name, sizeof bin_name, "%s.bin", name);
  if (!glb) snprintf(buf_uri, sizeof buf_uri, ",\"uri\":\"%s\"", bin_name);
  char *json = malloc(8192);
  assert_non_null(json);
  int jl = snprintf(json, 8192,
      "{\"asset\":{\"version\":\"2.0\"},\"extensionsUsed\":[\"KHR_lights_punctual\"],"
      "\"extensions\":{\"KHR_lights_punctual\":{\"lights\":[{\"type\":\"point\",\"color\":[1,1,1],"
      "\"intensity\":200000}]}},\"scene\":0,\"scenes\":[{\"nodes\":[0]}],"
      "\"nodes\":[{\"name\":\"site\",%s,\"children\":[1,2]},"
      "{\"name\":\"box\",\"mesh\":0,\"translation\":[%.17g,%.17g,%.17g]},"
      "{\"name\":\"lamp\",\"translation\":[278,500,279.6],\"extensions\":{\"KHR_lights_punctual\":{\"light\":0}}}],"
      "\"meshes\":[{\"primitives\":[{\"attributes\":{\"POSITION\":0},\"indices\":1}]}],"
      "\"buffers\":[{\"byteLength\":%zu%s}],"
      "\"bufferViews\":[{\"buffer\":0,\"byteOffset\":0,\"byteLength\":%zu},"
      "{\"buffer\":0,\"byteOffset\":%zu,\"byteLength\":%zu}],"
      "\"accessors\":[{\"bufferView\":0,\"componentType\":5126,\"count\":%zu,\"type\":\"VEC3\","
      "\"min\":[%.9g,%.9g,%.9g],\"max\":[%.9g,%.9g,%.9g]},"
      "{\"bufferView\":1,\"componentType\":5125,\"count\":%zu,\"type\":\"SCALAR\"}]}",
      root_tf, child_t[0], child_t[1], child_t[2], bin_len, buf_uri, pos_bytes, pos_bytes, idx_bytes, m.nv,
      lo[0], lo[1], lo[2], hi[0], hi[1], hi[2], 3 * m.nt);
  assert_true(jl > 0 && jl < 8192);
  const char *path;
  if (!glb) {
    tu_write_file(bin_name, bin, bin_len);
    path = tu_write_file(name, json, (size_t)jl);
  } else {
    size_t jpad = ((size_t)jl + 3) & ~(size_t)3, bpad = (bin_len + 3) & ~(size_t)3;
    size_t total = 12 + 8 + jpad + 8 + bpad;
    unsigned char *g = calloc(1, total);
    assert_non_null(g);
    uint32_t hdr[5] = {0x46546C67u, 2, (uint32_t)total, (uint32_t)jpad, 0x4E4F534Au};
    memcpy(g, hdr, 20);
    memcpy(g + 20, json, (size_t)jl);
    memset(g + 20 + jl, ' ', jpad - (size_t)jl);
    uint32_t bh[2] = {(uint32_t)bpad, 0x004E4942u};
    memcpy(g + 20 + jpad, bh, 8);
    memcpy(g + 28 + jpad, bin, bin_len);
    path = tu_write_file(name, g, total);
    free(g);
  }
  free(json);
  free(bin);
  gi__exact_free(&m);
  return path;
}

typedef struct {
  gi_up_axis up;
  int default_lights;
  const gi_light *light; /* one extra light in unshifted world coordinates, or NULL */
  double at[3];
  double pts[3][3];
  gi_quality q;
} bake_setup;

/* Loads path, bakes at the setup's viewpoint moved by s, gathers its points moved by s. */
static void load_bake(const char *path, const bake_setup *bs, const double s[3], gi_probe out[3]) {
  gi_light l;
  if (bs->light) {
    l = *bs->light;
    for (int k = 0; k < 3; k++) l.position[k] += s[k];
  }
  gi_scene_options so = {.up = bs->up, .default_lights = bs->default_lights, .lights = bs->light ? &l : NULL,
                         .num_lights = bs->light ? 1 : 0};
  gi_scene *sc = NULL;
  gi_error_info err = {0};
  gi_result rc = gi_scene_load(path, &so, &sc, &err);
  if (rc) fprintf(stderr, "%s\n", err.msg);
  assert_int_equal(rc, GI_OK);
  double at[3], pts[9];
  for (int k = 0; k < 3; k++) at[k] = bs->at[k] + s[k];
  for (int i = 0; i < 9; i++) pts[i] = bs->pts[i / 3][i % 3] + s[i % 3];
  gi_cascade *c = NULL;
  rc = gi_cascade_bake(sc, at, &bs->q, &c, NULL, &err);
  if (rc) fprintf(stderr, "%s\n", err.msg);
  assert_int_equal(rc, GI_OK);
  assert_int_equal(gi_cascade_gather(c, pts, 3, out, NULL, &err), GI_OK);
  gi_cascade_free(c);
  gi_scene_release(sc);
}

/* Largest difference over irradiance (relative) and SH (relative to the DC term). */
static double probe_diff(const gi_probe *ref, const gi_probe *p, int n) {
  double worst = 0;
  for (int i = 0; i < n; i++)
    for (int k = 0; k < 3; k++) {
      double a = ref[i].irradiance[k], b = p[i].irradiance[k];
      assert_true(isfinite(b));
      worst = fmax(worst, fabs(a - b) / fmax(fabs(a), 1e-6));
      for (int j = 0; j < 9; j++)
        worst = fmax(worst, fabs(ref[i].sh[j][k] - p[i].sh[j][k]) / fmax(fabs(ref[i].sh[0][k]), 1e-6));
    }
  return worst;
}

/* Bakes the unshifted file and each shifted one; every shift must match. */
static void check_shifts(const char *what, const char *paths[3], const bake_setup *bs) {
  static const double zero[3] = {0, 0, 0};
  const double *shift[3] = {zero, utm_shift, far_shift};
  gi_probe ref[3], pr[3];
  load_bake(paths[0], bs, zero, ref);
  assert_true(ref[0].irradiance[0] > 0);
  for (int i = 1; i < 3; i++) {
    load_bake(paths[i], bs, shift[i], pr);
    double d = probe_diff(ref, pr, 3);
    printf("georef: %s shifted by (%.2f, %.2f, %.2f): largest relative probe difference %.3g\n", what, shift[i][0],
           shift[i][1], shift[i][2], d);
    assert_true(d <= GEOREF_TOLERANCE);
  }
}

static const gi_quality small_q = {.levels = 3, .res = 32, .bounces = 2, .light_samples = 4, .probe_samples = 16,
                                   .threads = 2};

static void test_cornell_obj(void **state) {
  TU_SKIP_IF_NO_SCENE(src, "cornell-box/cornell-box.obj");
  const char *paths[3] = {write_shifted_obj(src, "cornell-box.mtl", "cbox0.obj", (double[3]){0, 0, 0}),
                          write_shifted_obj(src, "cornell-box.mtl", "cbox-utm.obj", utm_shift),
                          write_shifted_obj(src, "cornell-box.mtl", "cbox-far.obj", far_shift)};
  bake_setup bs = {.up = GI_UP_Y, .at = {278, 273, 279.6},
                   .pts = {{516, 273, 279.6}, {40, 273, 279.6}, {278, 273, 279.6}}, .q = small_q};
  check_shifts("cornell OBJ", paths, &bs);
}

static void test_cornell_ply(void **state) {
  TU_SKIP_IF_NO_SCENE(src, "cornell-box/cornell-box.obj");
  /* PLY has no materials: a point light under the ceiling stands in for the emitter. */
  const char *paths[3] = {write_shifted_ply(src, "cbox0.ply", (double[3]){0, 0, 0}, 0),
                          write_shifted_ply(src, "cbox-utm.ply", utm_shift, 0),
                          write_shifted_ply(src, "cbox-far.ply", far_shift, 1)};
  gi_light pl = {.type = GI_LIGHT_POINT, .color = {2e5, 2e5, 2e5}, .position = {278, 500, 279.6}};
  bake_setup bs = {.up = GI_UP_Y, .light = &pl, .at = {278, 273, 279.6},
                   .pts = {{516, 273, 279.6}, {40, 273, 279.6}, {278, 273, 279.6}}, .q = small_q};
  check_shifts("cornell binary PLY (double)", paths, &bs);
}

/* glTF: node translations (as TRS and as a matrix) composed in double; the
 * file's own point light moves with them. */
static void test_cornell_gltf(void **state) {
  TU_SKIP_IF_NO_SCENE(src, "cornell-box/cornell-box.obj");
  const char *paths[3] = {write_shifted_gltf(src, "cbox0.glb", (double[3]){0, 0, 0}, 1, 0),
                          write_shifted_gltf(src, "cbox-utm.glb", utm_shift, 1, 0),
                          write_shifted_gltf(src, "cbox-far.gltf", far_shift, 0, 1)};
  bake_setup bs = {.up = GI_UP_Y, .at = {278, 273, 279.6},
                   .pts = {{516, 273, 279.6}, {40, 273, 279.6}, {278, 273, 279.6}}, .q = small_q};
  check_shifts("cornell glTF (node translation)", paths, &bs);
}

static void test_munich_obj(void **state) {
  TU_SKIP_IF_NO_SCENE(src, "munich/munich.obj");
  const char *paths[3] = {write_shifted_obj(src, "munich.mtl", "munich0.obj", (double[3]){0, 0, 0}),
                          write_shifted_obj(src, "munich.mtl", "munich-utm.obj", utm_shift),
                          write_shifted_obj(src, "munich.mtl", "munich-far.obj", far_shift)};
  /* gi-accuracy's Munich viewpoint: an open square, 2 m above the street;
   * probes 12..24 m away from it. */
  bake_setup bs = {.up = GI_UP_Z, .default_lights = 1, .at = {-67.85, -85.78, 2},
                   .pts = {{-55.85, -73.78, 2}, {-79.85, -97.78, 2}, {-43.85, -61.78, 2}},
                   .q = {.levels = 4, .res = 16, .bounces = 1, .threads = 2}};
  check_shifts("munich OBJ", paths, &bs);
}

/* Loading must fail with GI_ERR_FORMAT and a message naming the file and saying `what`. */
static void expect_bad(const char *name, const char *text, const char *what) {
  const char *path = tu_write_file(name, text, strlen(text));
  gi_scene *s = (gi_scene *)1;
  gi_error_info err = {0};
  gi_result r = gi_scene_load(path, NULL, &s, &err);
  printf("  %s -> %s: %s\n", name, gi_err_name(r), err.msg);
  assert_int_equal(r, GI_ERR_FORMAT);
  assert_null(s);
  assert_non_null(strstr(err.msg, path));
  if (!strstr(err.msg, what)) fail_msg("message for %s does not say '%s': %s", name, what, err.msg);
}

static void test_malformed(void **state) {
  expect_bad("nan-word.obj", "v 0 0 0\nv 1 0 abc\nv 0 1 0\nf 1 2 3\n", "line 2: vertex coordinate 3 is not a number");
  expect_bad("short-v.obj", "# two numbers\nv 0 0\n", "line 2: a vertex needs x y z, found 2 numbers");
  expect_bad("bad-f.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 x\n", "line 4: face corner 3: expected a vertex index");
  expect_bad("zero-f.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n", "line 4: face corner 1: vertex 0: index out of range");
  expect_bad("neg-f.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -1 -2 -4\n", "vertex -4: index out of range");
  /* A texture coordinate index past the vt lines, or not a number: refused
   * as a vertex index is (the corner's UVs were dropped without a word). */
  expect_bad("vt-oor.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/5/9 3/1\n",
             "line 5: face corner 2: texture coordinate index '5' is not one of the 1 texture coordinates");
  expect_bad("vt-word.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/1 3/q\n",
             "line 5: face corner 3: texture coordinate index 'q'");
  /* A normal index past the vn lines, or not a number: refused the same
   * way, though normals are not read (such a file was taken as it was). */
  expect_bad("vn-oor.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3//2\n",
             "line 5: face corner 3: normal index '2' is not one of the 1 normals (vn)");
  expect_bad("vn-word.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1/x 2/1 3/1\n",
             "line 5: face corner 1: normal index 'x' is not one of the 0 normals");
  {
    const char *ok = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\nf 1//1 2/1/-1 3/1/1\nf 1 2/1 3\n";
    const char *path = tu_write_file("vn-ok.obj", ok, strlen(ok));
    gi_scene *s = NULL;
    gi_error_info err = {0};
    assert_int_equal(gi_scene_load(path, NULL, &s, &err), GI_OK);
    gi_scene_release(s);
  }
  expect_bad("usemtl.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl  \nf 1 2 3\n", "line 4: usemtl needs a material name");
  const char *head = "ply\nformat ascii 1.0\nelement vertex 3\nproperty double x\nproperty double y\n"
                     "property double z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n";
  char ply[1024];
  snprintf(ply, sizeof ply, "%s0 0 0\n1 zz 0\n0 1 0\n3 0 1 2\n", head);
  expect_bad("word.ply", ply, "line 11 (vertex 1): property 'y': expected a number");
  snprintf(ply, sizeof ply, "%s0 0 0\n1 0 0\n0 1 0\n2 0 1\n", head);
  expect_bad("two.ply", ply, "a face needs 3..255 vertex indices, found 2");
  snprintf(ply, sizeof ply, "%s0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n", head);
  expect_bad("oor.ply", ply, "(face 0): vertex index 3 out of range; expected 0..2");
  expect_bad("noz.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
             "end_header\n0 0\n1 0\n0 1\n", "PLY vertex element needs scalar properties x, y and z");
  expect_bad("fmt.ply", "ply\nformat binary_middle_endian 1.0\nelement vertex 0\nend_header\n",
             "line 2: unknown PLY format 'binary_middle_endian'");
}

int main(void) {
  const struct CMUnitTest tests[] = {cmocka_unit_test(test_malformed), cmocka_unit_test(test_cornell_obj),
                                     cmocka_unit_test(test_cornell_ply), cmocka_unit_test(test_cornell_gltf),
                                     cmocka_unit_test(test_munich_obj)};
  return cmocka_run_group_tests(tests, NULL, NULL);
}
