/* test_lightmap.c: lightmap charts, packing, texels against the reference,
 * seams, and the EXR and glTF outputs read back.
 *
 * Layout tests use scenes built in code (a room with a box in it); the
 * accuracy test uses the shared Cornell box and skips loudly without it. */
#include "test_util.h"
#include <assimp/cimport.h>
#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "base/alloc_test.h"
#include "gi/gi.h"

/* A 4 x 3 x 5 room (walls facing in) with a 1 m box standing on its floor,
 * or without the box and with the floor in two halves that share no
 * vertex (two charts meeting at x = 2: a seam in the middle of a plane). */
static gi_scene *room_scene_ex(int split_floor) {
  gi_mesh_builder *b = gi_mesh_builder_new();
  gi_material m = {.albedo = {0.7f, 0.7f, 0.7f}, .roughness = 1};
  uint32_t mat = gi_mesh_builder_add_material(b, &m);
  double c[8][3];
  for (int i = 0; i < 8; i++) c[i][0] = i & 1 ? 4 : 0, c[i][1] = i & 2 ? 3 : 0, c[i][2] = i & 4 ? 5 : 0;
  /* Inward-facing sides: counter-clockwise seen from inside. */
  if (split_floor) {
    double m0[3] = {2, 0, 0}, m1[3] = {2, 0, 5};
    gi_mesh_builder_add_quad(b, c[0], c[4], m1, m0, mat);
    gi_mesh_builder_add_quad(b, m0, m1, c[5], c[1], mat);
  } else {
    gi_mesh_builder_add_quad(b, c[0], c[4], c[5], c[1], mat); /* floor y=0, normal +y */
  }
  gi_mesh_builder_add_quad(b, c[2], c[3], c[7], c[6], mat); /* ceiling, normal -y */
  gi_mesh_builder_add_quad(b, c[0], c[2], c[6], c[4], mat); /* x=0, normal +x */
  gi_mesh_builder_add_quad(b, c[1], c[5], c[7], c[3], mat); /* x=4, normal -x */
  gi_mesh_builder_add_quad(b, c[0], c[1], c[3], c[2], mat); /* z=0, normal +z */
  gi_mesh_builder_add_quad(b, c[4], c[6], c[7], c[5], mat); /* z=5, normal -z */
  double lo[3] = {1.5, 0, 2}, hi[3] = {2.5, 1, 3};
  if (!split_floor) gi_mesh_builder_add_box(b, lo, hi, mat);
  gi_light sun = {.type = GI_LIGHT_POINT, .color = {20, 20, 20}, .position = {2, 2.5, 2.5}};
  gi_scene_options so = {.up = GI_UP_Y, .lights = &sun, .num_lights = 1};
  gi_scene *s = NULL;
  gi_error_info err = {0};
  assert_int_equal(gi_scene_build(b, "room", &so, &s, &err), GI_OK);
  gi_mesh_builder_free(b);
  return s;
}

static gi_scene *room_scene(void) { return room_scene_ex(0); }

static int rects_overlap(const gi_lightmap_chart *a, const gi_lightmap_chart *b) {
  return a->atlas == b->atlas && a->x < b->x + b->w && b->x < a->x + a->w && a->y < b->y + b->h &&
         b->y < a->y + a->h;
}

static void check_layout(const gi_lightmap *lm, int atlas, int gutter) {
  size_t nc = gi_lightmap_num_charts(lm);
  for (size_t i = 0; i < nc; i++) {
    gi_lightmap_chart a, b;
    assert_int_equal(gi_lightmap_get_chart(lm, i, &a), 0);
    gi_lightmap_atlas at;
    assert_int_equal(gi_lightmap_get_atlas(lm, (size_t)a.atlas, &at), 0);
    assert_true(a.x >= 0 && a.y >= 0 && a.x + a.w <= at.width && a.y + a.h <= at.height && at.width == atlas);
    for (size_t j = i + 1; j < nc; j++) {
      assert_int_equal(gi_lightmap_get_chart(lm, j, &b), 0);
      assert_false(rects_overlap(&a, &b));
    }
    /* Every corner lies in the chart's rectangle with the gutter kept clear
     * (texel centres of the content's edge texels, hence the half texel). */
    for (size_t t = a.first; t < a.first + a.count; t++) {
      float uv[6];
      int ch;
      assert_int_equal(gi_lightmap_triangle(lm, t, NULL, uv, NULL, &ch), 0);
      assert_int_equal(ch, (int)i);
      for (int j = 0; j < 3; j++) {
        float x = uv[2 * j] * (float)at.width, y = uv[2 * j + 1] * (float)at.height;
        assert_true(x >= (float)(a.x + gutter) + 0.5f - 1e-3f && x <= (float)(a.x + a.w - gutter) - 0.5f + 1e-3f);
        assert_true(y >= (float)(a.y + gutter) + 0.5f - 1e-3f && y <= (float)(a.y + a.h - gutter) - 0.5f + 1e-3f);
      }
    }
  }
}

static void test_charts_and_packing(void **state) {
  (void)state;
  gi_scene *s = room_scene();
  gi_lightmap_opts o = {.texel = 0.25, .atlas = 64, .gutter = 2};
  gi_lightmap *lm = NULL, *again = NULL;
  gi_error_info err = {0};
  assert_int_equal(gi_lightmap_layout(s, &o, &lm, &err), GI_OK);
  /* Six room sides plus five visible box sides and its bottom: one chart each. */
  assert_int_equal(gi_lightmap_num_charts(lm), 12);
  assert_int_equal(gi_lightmap_num_triangles(lm), 24);
  check_layout(lm, 64, 2);
  /* The 4 x 5 floor at 0.25: 17 x 21 texel centres plus the gutters. */
  int found = 0;
  for (size_t i = 0; i < gi_lightmap_num_charts(lm); i++) {
    gi_lightmap_chart c;
    gi_lightmap_get_chart(lm, i, &c);
    if (c.normal[1] > 0.99f && c.count == 2 && (c.w == 21 + 4 || c.w == 17 + 4)) found = c.w + c.h == 17 + 21 + 8;
  }
  assert_true(found);
  /* 64 texels hold the room in more than one atlas. */
  printf("room at 0.25: %zu charts in %zu atlases of 64\n", gi_lightmap_num_charts(lm), gi_lightmap_num_atlases(lm));
  assert_true(gi_lightmap_num_atlases(lm) > 1);
  /* Deterministic: the same options give the same UVs, bit for bit. */
  assert_int_equal(gi_lightmap_layout(s, &o, &again, &err), GI_OK);
  assert_int_equal(gi_lightmap_num_triangles(again), gi_lightmap_num_triangles(lm));
  for (size_t t = 0; t < gi_lightmap_num_triangles(lm); t++) {
    float a[6], b[6];
    uint32_t ta, tb;
    gi_lightmap_triangle(lm, t, &ta, a, NULL, NULL);
    gi_lightmap_triangle(again, t, &tb, b, NULL, NULL);
    assert_int_equal(ta, tb);
    assert_memory_equal(a, b, sizeof a);
  }
  gi_lightmap_free(again);
  gi_lightmap_free(lm);
  /* A big atlas holds everything in one. */
  o.atlas = 256;
  assert_int_equal(gi_lightmap_layout(s, &o, &lm, &err), GI_OK);
  assert_int_equal(gi_lightmap_num_atlases(lm), 1);
  check_layout(lm, 256, 2);
  gi_lightmap_free(lm);
  gi_scene_release(s);
}

/* opts.max_bytes: a layout needing more is refused before its atlases are
 * allocated (GI_ERR_LIMIT, the bytes said), one needing exactly that is not. */
static void test_max_bytes(void **state) {
  (void)state;
  gi_scene *s = room_scene();
  gi_lightmap_opts o = {.texel = 0.25, .atlas = 64};
  gi_lightmap *lm = NULL;
  gi_error_info err = {0};
  assert_int_equal(gi_lightmap_layout(s, &o, &lm, &err), GI_OK);
  uint64_t texels = 0, largest = 0;
  for (size_t i = 0; i < gi_lightmap_num_atlases(lm); i++) {
    gi_lightmap_atlas a;
    gi_lightmap_get_atlas(lm, i, &a);
    uint64_t t = (uint64_t)a.width * (uint64_t)a.height;
    texels += t;
    largest = t > largest ? t : largest;
  }
  gi_lightmap_free(lm);
  /* 80 held, plus the most of sorting (24), filling (20 + 20 of one atlas) and writing (52 of one). */
  uint64_t work = 24 * texels > 20 * texels + 20 * largest ? 24 * texels : 20 * texels + 20 * largest;
  uint64_t need = 80 * texels + (work > 52 * largest ? work : 52 * largest);
  assert_true(texels > largest); /* several atlases */
  assert_true(gi_lightmap_peak_bytes(texels, largest) == need);
  assert_true(gi_lightmap_peak_bytes(100, 100) == 80 * 100 + 52 * 100); /* one atlas: the write's copy */
  o.max_bytes = need;
  assert_int_equal(gi_lightmap_layout(s, &o, &lm, &err), GI_OK);
  gi_lightmap_free(lm);
  lm = (gi_lightmap *)1;
  o.max_bytes = need - 1;
  assert_int_equal(gi_lightmap_layout(s, &o, &lm, &err), GI_ERR_LIMIT);
  assert_null(lm);
  printf("past max_bytes: %s\n", err.msg);
  char want[64];
  snprintf(want, sizeof want, "(%llu bytes) to bake and write", (unsigned long long)need);
  assert_non_null(strstr(err.msg, want));
  gi_scene_release(s);
}

static void test_bad_options(void **state) {
  (void)state;
  gi_scene *s = room_scene();
  gi_lightmap *lm = (gi_lightmap *)1;
  gi_error_info err = {0};
  gi_lightmap_opts o = {.texel = 0.25, .atlas = 16};
  assert_int_equal(gi_lightmap_layout(s, &o, &lm, &err), GI_ERR_INVALID_ARG);
  assert_null(lm);
  printf("atlas too small: %s\n", err.msg);
  assert_non_null(strstr(err.msg, "does not fit in an atlas of 16 texels"));
  o = (gi_lightmap_opts){.texel = -1};
  assert_int_equal(gi_lightmap_layout(s, &o, &lm, &err), GI_ERR_INVALID_ARG);
  assert_non_null(strstr(err.msg, "texel"));
  o = (gi_lightmap_opts){.texel = NAN};
  assert_int_equal(gi_lightmap_layout(s, &o, &lm, &err), GI_ERR_INVALID_ARG);
  o = (gi_lightmap_opts){.atlas = 20000};
  assert_int_equal(gi_lightmap_layout(s, &o, &lm, &err), GI_ERR_INVALID_ARG);
  assert_non_null(strstr(err.msg, "atlas"));
  o = (gi_lightmap_opts){.have_region = 1, .region_lo = {10, 10, 10}, .region_hi = {11, 11, 11}};
  assert_int_equal(gi_lightmap_layout(s, &o, &lm, &err), GI_ERR_INVALID_ARG);
  printf("region outside: %s\n", err.msg);
  assert_non_null(strstr(err.msg, "outside the scene"));
  o = (gi_lightmap_opts){.have_region = 1, .region_lo = {1, 1, 1}, .region_hi = {0, 2, 2}};
  assert_int_equal(gi_lightmap_layout(s, &o, &lm, &err), GI_ERR_INVALID_ARG);
  assert_non_null(strstr(err.msg, "min < max"));
  /* Tiles of 1 mm over the 5 m room: 4096^3 cascade bakes, refused before any. */
  o = (gi_lightmap_opts){.texel = 0.5, .atlas = 64, .tile = 1e-3};
  assert_int_equal(gi_lightmap_layout(s, &o, &lm, &err), GI_OK);
  gi_lightmap_report rep = {0};
  assert_int_equal(gi_lightmap_bake(lm, NULL, NULL, &rep, &err), GI_ERR_LIMIT);
  printf("tiles too small: %s\n", err.msg);
  assert_non_null(strstr(err.msg, "raise tile"));
  assert_int_equal(rep.tiles, 0);
  gi_lightmap_free(lm);
  gi_scene_release(s);
}

/* Relative error of the luminance of a against b. */
static double rel_err(const float a[3], const float b[3]) {
  double la = 0.2126 * a[0] + 0.7152 * a[1] + 0.0722 * a[2], lb = 0.2126 * b[0] + 0.7152 * b[1] + 0.0722 * b[2];
  return fabs(la - lb) / lb;
}

#define CB_MAXP 256
/* Reference points: lightmap texels that face up (floor and box tops),
 * gathered from their own surface, a border set (a texel next to one that
 * is not) and an interior set, spread evenly over the atlas. */
typedef struct {
  double pts[3 * CB_MAXP];
  size_t idx[CB_MAXP];
  int border[CB_MAXP];
  size_t n;
} cb_points;

static int is_border(const gi_lightmap_atlas *a, int x, int y) {
  size_t i = (size_t)y * a->width + x;
  for (int dy = -1; dy <= 1; dy++)
    for (int dx = -1; dx <= 1; dx++) {
      int u = x + dx, v = y + dy;
      if (u < 0 || v < 0 || u >= a->width || v >= a->height) return 1;
      size_t j = (size_t)v * a->width + u;
      if (a->chart[j] != a->chart[i] || a->valid[j] == 0) return 1;
    }
  return 0;
}

static void pick_points(const gi_lightmap *lm, const gi_lightmap_atlas *a, double top, cb_points *p, int per_kind) {
  double o[3];
  gi_lightmap_origin(lm, o);
  size_t cand[2][4096], nc[2] = {0, 0};
  for (int y = 0; y < a->height; y++)
    for (int x = 0; x < a->width; x++) {
      size_t i = (size_t)y * a->width + x;
      /* Not the light's back, which faces the outside above the ceiling. */
      if (a->valid[i] == 0 || a->normal[3 * i + 1] < 0.99f || o[1] + a->point[3 * i + 1] > top) continue;
      int b = is_border(a, x, y);
      if (nc[b] < 4096) cand[b][nc[b]++] = i;
    }
  p->n = 0;
  for (int b = 0; b < 2; b++)
    for (int k = 0; k < per_kind && nc[b]; k++) {
      size_t i = cand[b][(size_t)k * nc[b] / per_kind];
      p->idx[p->n] = i;
      p->border[p->n] = b;
      /* A hair above the surface: the reference answers at points in space. */
      for (int j = 0; j < 3; j++) p->pts[3 * p->n + j] = o[j] + a->point[3 * i + j] + (j == 1 ? 0.5 : 0.0);
      p->n++;
    }
}

static void test_cornell_against_reference(void **state) {
  (void)state;
  TU_SKIP_IF_NO_SCENE(path, "cornell-box/cornell-box.obj");
  gi_scene *sc = NULL;
  gi_error_info err = {0};
  gi_scene_options so = {.up = GI_UP_Y};
  assert_int_equal(gi_scene_load(path, &so, &sc, &err), GI_OK);
  gi_lightmap_opts o = {.texel = 20, .atlas = 256, .supersample = 2};
  gi_lightmap *lm = NULL;
  assert_int_equal(gi_lightmap_layout(sc, &o, &lm, &err), GI_OK);
  gi_quality q = {.res = 16, .probe_samples = 64};
  gi_lightmap_report rep;
  gi_result rc = gi_lightmap_bake(lm, &q, NULL, &rep, &err);
  if (rc) printf("%s\n", err.msg);
  assert_int_equal(rc, GI_OK);
  printf("cornell lightmap at 20 mm: %zu charts, %zu atlases, %llu texels (%llu gathered, %llu filled), %d tile(s);"
         " layout %.1f ms, cascade %.1f ms, gather %.1f ms, fill %.1f ms\n",
         rep.charts, rep.atlases, (unsigned long long)rep.texels, (unsigned long long)rep.texels_valid,
         (unsigned long long)rep.texels_filled, rep.tiles, rep.layout_ms, rep.cascade_ms, rep.gather_ms, rep.fill_ms);
  assert_int_equal(gi_lightmap_num_atlases(lm), 1);
  gi_lightmap_atlas a;
  gi_lightmap_get_atlas(lm, 0, &a);
  double lo[3], hi[3], at[3];
  gi_scene_bounds(sc, lo, hi);
  static cb_points p;
  pick_points(lm, &a, hi[1] - 50, &p, 48);
  assert_true(p.n > 60);
  /* The probes at the same points, from a cascade of the same quality at the tile's centre. */
  for (int k = 0; k < 3; k++) at[k] = 0.5 * (lo[k] + hi[k]);
  gi_cascade *c = NULL;
  assert_int_equal(gi_cascade_bake(sc, at, &q, &c, NULL, &err), GI_OK);
  static gi_probe pr[CB_MAXP];
  static gi_ref_probe ref[CB_MAXP];
  assert_int_equal(gi_cascade_gather(c, p.pts, p.n, pr, NULL, &err), GI_OK);
  gi_reference_opts ro = {.samples = 4096, .seed = 3};
  double ref_ms = 0;
  assert_int_equal(gi_reference_irradiance(sc, p.pts, p.n, &ro, ref, &ref_ms, &err), GI_OK);
  /* Per kind (0 interior, 1 border): lightmap and probe errors, signed lightmap error. */
  double e_lm[2] = {0, 0}, e_pr[2] = {0, 0}, bias[2] = {0, 0}, se = 0;
  size_t nk[2] = {0, 0};
  for (size_t i = 0; i < p.n; i++) {
    const float *E = a.irradiance + 3 * p.idx[i];
    int b = p.border[i];
    e_lm[b] += rel_err(E, ref[i].irradiance);
    e_pr[b] += rel_err(pr[i].irradiance, ref[i].irradiance);
    bias[b] += (E[1] - ref[i].irradiance[1]) / ref[i].irradiance[1];
    se += (double)ref[i].std_err[1] / ref[i].irradiance[1];
    nk[b]++;
    if (getenv("LM_DEBUG"))
      printf("%d %7.1f %7.1f %7.1f  lm %.4f probe %.4f ref %.4f  direct lm %.4f ref %.4f\n", b, p.pts[3 * i],
             p.pts[3 * i + 1], p.pts[3 * i + 2], E[1], pr[i].irradiance[1], ref[i].irradiance[1],
             a.direct[3 * p.idx[i] + 1], ref[i].direct[1]);
  }
  double lm_all = (e_lm[0] + e_lm[1]) / (double)p.n, pr_all = (e_pr[0] + e_pr[1]) / (double)p.n;
  for (int b = 0; b < 2; b++) e_lm[b] /= (double)nk[b], e_pr[b] /= (double)nk[b], bias[b] /= (double)nk[b];
  se /= (double)p.n;
  printf("cornell, %zu up-facing texels (%zu interior, %zu border), reference %d paths (%.0f ms, rel. std. error "
         "%.2f%%):\n  MRE lightmap %.2f%%, probes at the same points %.2f%% (ratio %.2f)\n"
         "  interior: lightmap %.2f%%, probes %.2f%%; border: lightmap %.2f%% (signed %+.2f%%), probes %.2f%% "
         "(interior signed %+.2f%%)\n",
         p.n, nk[0], nk[1], ro.samples, ref_ms, 100 * se, 100 * lm_all, 100 * pr_all, lm_all / pr_all,
         100 * e_lm[0], 100 * e_pr[0], 100 * e_lm[1], 100 * bias[1], 100 * e_pr[1], 100 * bias[0]);
  assert_true(lm_all <= 1.2 * pr_all);
  /* Every chart border of the Cornell box is a corner, where the cascade
   * itself is least accurate (its voxels straddle two walls; the probes at
   * the same points show it): there the lightmap is held to the probes'
   * error. Seams inside a plane are test_no_dark_seams. */
  assert_true(e_lm[1] <= 1.2 * e_pr[1]);
  gi_cascade_free(c);
  gi_lightmap_free(lm);
  gi_scene_release(sc);
}

/* The room baked small and fast: the outputs only need real values. */
static gi_lightmap *baked_room(gi_scene *s, int atlas) {
  gi_lightmap_opts o = {.texel = 0.25, .atlas = atlas};
  gi_lightmap *lm = NULL;
  gi_error_info err = {0};
  assert_int_equal(gi_lightmap_layout(s, &o, &lm, &err), GI_OK);
  gi_quality q = {.levels = 3, .res = 16, .probe_samples = 16, .cones = 6};
  gi_lightmap_report rep;
  assert_int_equal(gi_lightmap_bake(lm, &q, NULL, &rep, &err), GI_OK);
  assert_true(rep.texels_valid > 0 && rep.texels_filled > 0);
  assert_int_equal(rep.texels, rep.texels_valid + rep.texels_filled);
  return lm;
}

static void test_exr_read_back(void **state) {
  (void)state;
  gi_scene *s = room_scene();
  gi_lightmap *lm = baked_room(s, 64);
  size_t na = gi_lightmap_num_atlases(lm);
  assert_true(na > 1);
  char path[512], file[512];
  snprintf(path, sizeof path, "%s/room-lm.exr", tu_tmpdir());
  gi_error_info err = {0};
  assert_int_equal(gi_lightmap_write_exr(lm, path, 0, &err), GI_OK);
  /* Several atlases: numbered files, none under the bare name. */
  FILE *f = fopen(path, "rb");
  assert_null(f);
  static const char *rgb[] = {"R", "G", "B"};
  for (size_t i = 0; i < na; i++) {
    assert_int_equal(gi_lightmap_atlas_path(lm, path, i, file, sizeof file), 0);
    char want[512];
    snprintf(want, sizeof want, "%s/room-lm.%04zu.exr", tu_tmpdir(), i + 1);
    assert_string_equal(file, want);
    gi_exr_file *x = NULL;
    assert_int_equal(gi_exr_read(file, &x, &err), GI_OK);
    gi_lightmap_atlas a;
    gi_lightmap_get_atlas(lm, i, &a);
    assert_int_equal(gi_exr_file_width(x), a.width);
    assert_int_equal(gi_exr_file_height(x), a.height);
    assert_int_equal(gi_exr_file_num_channels(x), 13);
    assert_string_equal(gi_exr_file_attr(x, "gi.kind"), "lightmap");
    const float *src[4] = {a.radiance, a.irradiance, a.direct, a.indirect};
    const char *layer[4] = {"", "irradiance.", "direct.", "indirect."};
    size_t n = (size_t)a.width * a.height, lit = 0;
    for (int l = 0; l < 4; l++)
      for (int k = 0; k < 3; k++) {
        char name[32];
        snprintf(name, sizeof name, "%s%s", layer[l], rgb[k]);
        const float *ch = gi_exr_file_channel(x, name);
        assert_non_null(ch);
        for (size_t t = 0; t < n; t++) assert_true(ch[t] == src[l][3 * t + k]);
      }
    const float *valid = gi_exr_file_channel(x, "valid.Y"), *R = gi_exr_file_channel(x, "R");
    const float *irr = gi_exr_file_channel(x, "irradiance.R");
    for (size_t t = 0; t < n; t++) {
      assert_true(valid[t] == a.valid[t]);
      /* Radiance is albedo (0.7) x irradiance / pi on every gathered texel. */
      if (valid[t] > 0) assert_float_equal(R[t], 0.7f * irr[t] / 3.14159265f, 1e-5f + 1e-4f * R[t]);
      lit += valid[t] > 0 && irr[t] > 0;
    }
    assert_true(lit > 0);
    gi_exr_file_free(x);
  }
  gi_lightmap_free(lm);
  gi_scene_release(s);
}

static void test_gltf_read_back(void **state) {
  (void)state;
  gi_scene *s = room_scene();
  gi_lightmap *lm = baked_room(s, 256);
  char path[512];
  snprintf(path, sizeof path, "%s/room-uv.glb", tu_tmpdir());
  gi_error_info err = {0};
  assert_int_equal(gi_lightmap_write_gltf(lm, path, &err), GI_OK);
  const struct aiScene *as = aiImportFile(path, 0);
  assert_non_null(as);
  assert_int_equal(as->mNumMeshes, 1);
  const struct aiMesh *m = as->mMeshes[0];
  size_t nt = gi_lightmap_num_triangles(lm);
  assert_int_equal(m->mNumFaces, nt);
  assert_non_null(m->mTextureCoords[0]);
  assert_non_null(m->mTextureCoords[1]);
  /* assimp reads glTF's V (down) as 1 - v; the root node carries the origin. */
  double o[3];
  gi_lightmap_origin(lm, o);
  const struct aiNode *node = as->mRootNode;
  assert_float_equal(node->mTransformation.a4, o[0], 1e-6);
  assert_float_equal(node->mTransformation.b4, o[1], 1e-6);
  assert_int_equal(node->mNumChildren, 1);
  assert_string_equal(node->mChildren[0]->mName.data, "lightmap.0001");
  for (size_t t = 0; t < nt; t++) {
    float uv[6], xyz[9];
    gi_lightmap_triangle(lm, t, NULL, uv, xyz, NULL);
    const struct aiFace *fc = &m->mFaces[t];
    assert_int_equal(fc->mNumIndices, 3);
    for (int j = 0; j < 3; j++) {
      unsigned v = fc->mIndices[j];
      assert_float_equal(m->mTextureCoords[1][v].x, uv[2 * j], 1e-6);
      assert_float_equal(1 - m->mTextureCoords[1][v].y, uv[2 * j + 1], 1e-6);
      assert_float_equal(m->mVertices[v].x, xyz[3 * j], 1e-5);
    }
  }
  aiReleaseImport(as);
  /* Loaded back as a scene, its second UV set is the lightmap's: the layout
   * keeps it (one chart, the same UVs) instead of making charts. */
  gi_scene *back = NULL;
  gi_scene_options so = {.up = GI_UP_Y};
  assert_int_equal(gi_scene_load(path, &so, &back, &err), GI_OK);
  assert_true(gi_scene_has_lightmap_uv(back));
  assert_false(gi_scene_has_lightmap_uv(s));
  gi_lightmap_opts lo = {.atlas = 256};
  gi_lightmap *own = NULL;
  assert_int_equal(gi_lightmap_layout(back, &lo, &own, &err), GI_OK);
  assert_int_equal(gi_lightmap_num_charts(own), 1);
  assert_int_equal(gi_lightmap_num_triangles(own), nt);
  for (size_t t = 0; t < nt; t++) {
    float a[6], b[6];
    gi_lightmap_triangle(lm, t, NULL, a, NULL, NULL);
    gi_lightmap_triangle(own, t, NULL, b, NULL, NULL);
    for (int j = 0; j < 6; j++) assert_float_equal(a[j], b[j], 1e-6);
  }
  gi_quality q = {.levels = 3, .res = 16, .probe_samples = 16, .cones = 6};
  gi_lightmap_report rep;
  assert_int_equal(gi_lightmap_bake(own, &q, NULL, &rep, &err), GI_OK);
  printf("scene's own UVs: %llu texels gathered of %llu\n", (unsigned long long)rep.texels_valid,
         (unsigned long long)rep.texels);
  assert_true(rep.texels_valid > 100);
  lo.scene_uv = -1;
  gi_lightmap_free(own);
  assert_int_equal(gi_lightmap_layout(back, &lo, &own, &err), GI_OK);
  assert_true(gi_lightmap_num_charts(own) > 1);
  gi_lightmap_free(own);
  gi_scene_release(back);
  assert_int_equal(gi_lightmap_write_gltf(lm, "/tmp/x.gltf", &err), GI_ERR_INVALID_ARG);
  assert_non_null(strstr(err.msg, ".glb"));
  gi_lightmap_free(lm);
  gi_scene_release(s);
}

/* glTF is Y up. A Z-up scene (a block 4 x 3 x 6 m tall, far from the
 * origin, as a city's) is written turned (x, y, z) -> (x, z, -y): its roof
 * faces +Y, its top at glTF y = 6, and the root translation turned with
 * it. The file was written Z up: Munich lay on its side in Blender. */
static void test_gltf_z_up(void **state) {
  (void)state;
  gi_mesh_builder *b = gi_mesh_builder_new();
  gi_material mat = {.albedo = {0.5f, 0.5f, 0.5f}, .roughness = 1};
  uint32_t m0 = gi_mesh_builder_add_material(b, &mat);
  const double lo[3] = {1000, 2000, 0}, hi[3] = {1004, 2003, 6};
  gi_mesh_builder_add_box(b, lo, hi, m0);
  gi_scene_options so = {.up = GI_UP_Z};
  gi_scene *s = NULL;
  gi_error_info err = {0};
  assert_int_equal(gi_scene_build(b, "block", &so, &s, &err), GI_OK);
  gi_mesh_builder_free(b);
  gi_lightmap_opts o = {.texel = 0.5, .atlas = 128};
  gi_lightmap *lm = NULL;
  assert_int_equal(gi_lightmap_layout(s, &o, &lm, &err), GI_OK);
  char path[512];
  snprintf(path, sizeof path, "%s/block-uv.glb", tu_tmpdir());
  assert_int_equal(gi_lightmap_write_gltf(lm, path, &err), GI_OK);
  const struct aiScene *as = aiImportFile(path, 0);
  assert_non_null(as);
  assert_int_equal(as->mNumMeshes, 1);
  double org[3];
  gi_lightmap_origin(lm, org);
  const struct aiMatrix4x4 *root = &as->mRootNode->mTransformation;
  assert_float_equal(root->a4, org[0], 1e-3);
  assert_float_equal(root->b4, org[2], 1e-3);
  assert_float_equal(root->c4, -org[1], 1e-3);
  const struct aiMesh *m = as->mMeshes[0];
  size_t nt = gi_lightmap_num_triangles(lm), roof = 0;
  assert_int_equal(m->mNumFaces, nt);
  assert_non_null(m->mNormals);
  for (size_t t = 0; t < nt; t++) {
    float xyz[9];
    gi_lightmap_triangle(lm, t, NULL, NULL, xyz, NULL);
    const struct aiFace *fc = &m->mFaces[t];
    int top = 1;
    for (int j = 0; j < 3; j++) {
      unsigned v = fc->mIndices[j];
      assert_float_equal(m->mVertices[v].x, xyz[3 * j], 1e-5);
      assert_float_equal(m->mVertices[v].y, xyz[3 * j + 2], 1e-5);
      assert_float_equal(m->mVertices[v].z, -xyz[3 * j + 1], 1e-5);
      top &= fabs(m->mVertices[v].y + root->b4 - 6) < 1e-3;
    }
    if (!top) continue;
    /* The roof: up in glTF is +Y, and its corners lie over the block's
     * footprint turned, x 1000..1004, z -2003..-2000. */
    roof++;
    const struct aiVector3D *n = &m->mNormals[fc->mIndices[0]];
    assert_float_equal(n->x, 0, 1e-6);
    assert_float_equal(n->y, 1, 1e-6);
    assert_float_equal(n->z, 0, 1e-6);
    for (int j = 0; j < 3; j++) {
      const struct aiVector3D *p = &m->mVertices[fc->mIndices[j]];
      assert_true(p->x + root->a4 > 1000 - 1e-3 && p->x + root->a4 < 1004 + 1e-3);
      assert_true(p->z + root->c4 > -2003 - 1e-3 && p->z + root->c4 < -2000 + 1e-3);
    }
  }
  assert_int_equal(roof, 2);
  aiReleaseImport(as);
  gi_lightmap_free(lm);
  gi_scene_release(s);
}

/* A 10 m plate of two triangles with lightmap UVs (u, v) = k (x, z) / 10 +
 * off, but u = NaN at vertex nan_at (-1: none). */
static gi_scene *plate_with_uv(double k, double off, int nan_at) {
  gi_mesh_builder *b = gi_mesh_builder_new();
  gi_material m = {.albedo = {0.5f, 0.5f, 0.5f}, .roughness = 1};
  uint32_t mat = gi_mesh_builder_add_material(b, &m), v[4];
  static const double xz[4][2] = {{0, 0}, {10, 0}, {10, 10}, {0, 10}};
  for (int i = 0; i < 4; i++) {
    v[i] = gi_mesh_builder_add_vertex(b, xz[i][0], 0, xz[i][1]);
    gi_mesh_builder_set_lightmap_uv(b, v[i], i == nan_at ? NAN : k * xz[i][0] / 10 + off, k * xz[i][1] / 10 + off);
  }
  gi_mesh_builder_add_triangle(b, v[0], v[2], v[1], mat);
  gi_mesh_builder_add_triangle(b, v[0], v[3], v[2], mat);
  gi_scene_options so = {.up = GI_UP_Y, .threads = 1};
  gi_scene *s = NULL;
  gi_error_info err = {0};
  assert_int_equal(gi_scene_build(b, "plate", &so, &s, &err), GI_OK);
  gi_mesh_builder_free(b);
  return s;
}

/* A UV set that misses a vertex (a mesh without TEXCOORD_1, a NaN) is not
 * used, and the scene counts the vertices that made it so. */
static void test_scene_uv_incomplete(void **state) {
  (void)state;
  gi_scene *s = plate_with_uv(1, 0, 2);
  gi_scene_stats st;
  gi_scene_get_stats(s, &st);
  assert_false(gi_scene_has_lightmap_uv(s));
  assert_int_equal(st.uv2_missing, 1);
  gi_scene_release(s);
}

/* A scene's own UVs are a layout only inside [0, 1] and with area: moved by
 * a whole tile they baked nothing, all at one point they gathered one
 * texel for the whole atlas, both with success. Each fails now, naming
 * the way out; --own-charts (scene_uv = -1) still bakes. */
static void test_scene_uv_checked(void **state) {
  (void)state;
  static const struct {
    double k, off;
    gi_result want;
    const char *says;
  } cases[] = {{1, 0, GI_OK, NULL},
               {0.98, 0.01, GI_OK, NULL},
               {1, 3, GI_ERR_FORMAT, "put 2 of 2 triangles outside [0, 1]"},
               {10, 0, GI_ERR_FORMAT, "outside [0, 1]"},
               {0, 0.5, GI_ERR_FORMAT, "100.0% of the surface no area"},
               {1e-9, 0.5, GI_ERR_FORMAT, "no area"}};
  for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
    gi_scene *s = plate_with_uv(cases[i].k, cases[i].off, -1);
    assert_true(gi_scene_has_lightmap_uv(s));
    gi_lightmap_opts o = {.atlas = 64};
    gi_lightmap *lm = NULL;
    gi_error_info err = {0};
    assert_int_equal(gi_lightmap_layout(s, &o, &lm, &err), cases[i].want);
    if (cases[i].says) {
      printf("uv x %g + %g: %s\n", cases[i].k, cases[i].off, err.msg);
      assert_non_null(strstr(err.msg, cases[i].says));
      assert_non_null(strstr(err.msg, "scene_uv = -1"));
      o.scene_uv = -1;
      assert_int_equal(gi_lightmap_layout(s, &o, &lm, &err), GI_OK);
    } else {
      assert_int_equal(gi_lightmap_num_charts(lm), 1);
    }
    gi_lightmap_free(lm);
    gi_scene_release(s);
  }
}

/* Plates 10 m wide 5 m apart (two, or `count`), each a 2 x 2 grid of
 * quads (edges shared inside, texel centres on the diagonals), with
 * lightmap UVs on half the atlas each: the first at u in [0, 0.5], the
 * others shifted by `shift`. */
static gi_scene *plates_with_uv_n(double shift, int count) {
  gi_mesh_builder *b = gi_mesh_builder_new();
  gi_material m = {.albedo = {0.5f, 0.5f, 0.5f}, .roughness = 1};
  uint32_t mat = gi_mesh_builder_add_material(b, &m);
  for (int p = 0; p < count; p++) {
    uint32_t v[3][3];
    for (int i = 0; i < 3; i++)
      for (int j = 0; j < 3; j++) {
        v[i][j] = gi_mesh_builder_add_vertex(b, 5.0 * i, 5.0 * p, 5.0 * j);
        gi_mesh_builder_set_lightmap_uv(b, v[i][j], 0.25 * i + (p ? shift : 0), 0.5 * j);
      }
    for (int i = 0; i < 2; i++)
      for (int j = 0; j < 2; j++) {
        gi_mesh_builder_add_triangle(b, v[i][j], v[i + 1][j + 1], v[i + 1][j], mat);
        gi_mesh_builder_add_triangle(b, v[i][j], v[i][j + 1], v[i + 1][j + 1], mat);
      }
  }
  gi_scene_options so = {.up = GI_UP_Y, .threads = 1};
  gi_scene *s = NULL;
  gi_error_info err = {0};
  assert_int_equal(gi_scene_build(b, "plates", &so, &s, &err), GI_OK);
  gi_mesh_builder_free(b);
  return s;
}

static gi_scene *plates_with_uv(double shift) { return plates_with_uv_n(shift, 2); }

/* Two surfaces on one texel cannot both keep their light: the bake finds
 * one triangle per texel and the other showed its light, silently. Islands
 * side by side (edges shared, texel centres on them) pass; stacked or
 * overlapping islands fail naming a shared texel and the way out. */
static void test_scene_uv_overlap(void **state) {
  (void)state;
  static const struct {
    double shift;
    gi_result want;
    const char *says;
  } cases[] = {{0.5, GI_OK, NULL},
               {0.25, GI_ERR_FORMAT, "overlap: 33.3% of the texels they cover belong to two triangles"},
               {0, GI_ERR_FORMAT, "overlap: 100.0%"}};
  for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
    gi_scene *s = plates_with_uv(cases[i].shift);
    gi_lightmap_opts o = {.atlas = 64};
    gi_lightmap *lm = NULL;
    gi_error_info err = {0};
    assert_int_equal(gi_lightmap_layout(s, &o, &lm, &err), cases[i].want);
    if (cases[i].says) {
      printf("plates shifted %g: %s\n", cases[i].shift, err.msg);
      assert_non_null(strstr(err.msg, cases[i].says));
      assert_non_null(strstr(err.msg, "scene_uv = -1"));
      o.scene_uv = -1;
      assert_int_equal(gi_lightmap_layout(s, &o, &lm, &err), GI_OK);
      assert_true(gi_lightmap_num_charts(lm) >= 2);
    } else {
      assert_int_equal(gi_lightmap_num_charts(lm), 1);
    }
    gi_lightmap_free(lm);
    gi_scene_release(s);
  }
  /* Four plates on one spot: every texel they cover is shared, 100% (each
   * extra claim counted read 300%). */
  gi_scene *s = plates_with_uv_n(0, 4);
  gi_lightmap_opts o = {.atlas = 64};
  gi_lightmap *lm = NULL;
  gi_error_info err = {0};
  assert_int_equal(gi_lightmap_layout(s, &o, &lm, &err), GI_ERR_FORMAT);
  printf("four plates stacked: %s\n", err.msg);
  assert_non_null(strstr(err.msg, "overlap: 100.0% of the texels"));
  gi_scene_release(s);
}

/* The bake does not depend on threads or on how the region is tiled per
 * texel seed; a second bake of the same lightmap gives the same atlas. */
static void test_bake_deterministic_and_tiled(void **state) {
  (void)state;
  gi_scene *s = room_scene();
  gi_lightmap_opts o = {.texel = 0.25, .atlas = 256};
  gi_lightmap *lm = NULL;
  gi_error_info err = {0};
  assert_int_equal(gi_lightmap_layout(s, &o, &lm, &err), GI_OK);
  gi_quality q = {.levels = 3, .res = 16, .probe_samples = 16, .cones = 6, .threads = 1};
  gi_lightmap_report r1, r2;
  assert_int_equal(gi_lightmap_bake(lm, &q, NULL, &r1, &err), GI_OK);
  gi_lightmap_atlas a;
  gi_lightmap_get_atlas(lm, 0, &a);
  size_t n = 3 * (size_t)a.width * a.height;
  float *first = malloc(n * sizeof *first);
  memcpy(first, a.radiance, n * sizeof *first);
  q.threads = 2;
  assert_int_equal(gi_lightmap_bake(lm, &q, NULL, &r2, &err), GI_OK);
  assert_memory_equal(first, a.radiance, n * sizeof *first);
  assert_int_equal(r1.texels_valid, r2.texels_valid);
  assert_int_equal(r1.tiles, 1);
  /* 2 m tiles: the 4 x 3 x 5 room in several cascades, every gathered texel
   * finite, and lit but for the box's bottom (pressed onto the floor). */
  gi_lightmap_free(lm);
  o.tile = 2;
  assert_int_equal(gi_lightmap_layout(s, &o, &lm, &err), GI_OK);
  assert_int_equal(gi_lightmap_bake(lm, &q, NULL, &r2, &err), GI_OK);
  printf("room: %d tiles, %llu texels gathered (one tile: %llu)\n", r2.tiles, (unsigned long long)r2.texels_valid,
         (unsigned long long)r1.texels_valid);
  assert_true(r2.tiles > 1);
  assert_int_equal(r1.texels_valid, r2.texels_valid);
  gi_lightmap_get_atlas(lm, 0, &a);
  size_t lit = 0, dark_not_bottom = 0;
  for (size_t i = 0; i < (size_t)a.width * a.height; i++) {
    if (a.valid[i] == 0) continue;
    assert_true(isfinite(a.irradiance[3 * i]) && a.irradiance[3 * i] >= 0);
    lit += a.irradiance[3 * i] > 0;
    dark_not_bottom += a.irradiance[3 * i] == 0 && a.normal[3 * i + 1] > -0.99f;
  }
  assert_int_equal(dark_not_bottom, 0);
  assert_true(lit > 0.9 * r2.texels_valid);
  free(first);
  gi_lightmap_free(lm);
  gi_scene_release(s);
}

/* A 200 m street (twenty quads of 10 x 20 m) and, at its far
 * end (x = 90), a 10 m wall facing back along it in the sun: the street in
 * front of the wall takes the wall's bounce. */
static gi_scene *long_street(void) {
  gi_mesh_builder *b = gi_mesh_builder_new();
  gi_material m = {.albedo = {0.6f, 0.6f, 0.6f}, .roughness = 1};
  uint32_t mat = gi_mesh_builder_add_material(b, &m);
  for (int i = 0; i < 20; i++) {
    double x0 = -100 + 10 * i, x1 = x0 + 10;
    double q[4][3] = {{x0, 0, -10}, {x0, 0, 10}, {x1, 0, 10}, {x1, 0, -10}};
    gi_mesh_builder_add_quad(b, q[0], q[1], q[2], q[3], mat);
  }
  double w[4][3] = {{90, 0, -10}, {90, 0, 10}, {90, 10, 10}, {90, 10, -10}};
  gi_mesh_builder_add_quad(b, w[0], w[1], w[2], w[3], mat);
  gi_light sun = {.type = GI_LIGHT_SUN, .color = {3, 3, 3}, .direction = {0.70710678f, -0.70710678f, 0}};
  gi_scene_options so = {.up = GI_UP_Y, .lights = &sun, .num_lights = 1};
  gi_scene *s = NULL;
  gi_error_info err = {0};
  assert_int_equal(gi_scene_build(b, "street", &so, &s, &err), GI_OK);
  gi_mesh_builder_free(b);
  return s;
}

/* Mean indirect light (green) of the street's texels 1-6 m in front of the wall. */
static double street_indirect(gi_scene *s, const gi_lightmap_opts *o, int *tiles) {
  gi_lightmap *lm = NULL;
  gi_error_info err = {0};
  assert_int_equal(gi_lightmap_layout(s, o, &lm, &err), GI_OK);
  gi_quality q = {.levels = 4, .res = 16, .probe_samples = 16, .cones = 6};
  gi_lightmap_report rep;
  assert_int_equal(gi_lightmap_bake(lm, &q, NULL, &rep, &err), GI_OK);
  *tiles = rep.tiles;
  double org[3], sum = 0;
  size_t n = 0;
  gi_lightmap_origin(lm, org);
  for (size_t k = 0; k < gi_lightmap_num_atlases(lm); k++) {
    gi_lightmap_atlas a;
    gi_lightmap_get_atlas(lm, k, &a);
    for (size_t i = 0; i < (size_t)a.width * a.height; i++) {
      double x = org[0] + a.point[3 * i], z = org[2] + a.point[3 * i + 2];
      if (a.valid[i] == 0 || a.normal[3 * i + 1] < 0.99f || x < 84 || x > 89 || fabs(z) > 8) continue;
      sum += a.indirect[3 * i + 1];
      n++;
    }
  }
  assert_true(n > 100);
  gi_lightmap_free(lm);
  return sum / (double)n;
}

/* Texels belong to the tile holding them, not to their chart's: the whole
 * street is one chart centred at x = 0, yet with 20 m tiles the texels in
 * front of the far wall read their bounce as a bake of that corner alone
 * does. (By the chart's centre they were all gathered from the middle
 * tile's cascade, 85 m away in its coarse levels.) */
static void test_big_chart_tiles(void **state) {
  (void)state;
  gi_scene *s = long_street();
  gi_lightmap_opts all = {.texel = 0.5, .atlas = 512, .tile = 20};
  gi_lightmap_opts corner = all;
  corner.have_region = 1;
  double lo[3] = {78, -1, -11}, hi[3] = {101, 11, 11};
  memcpy(corner.region_lo, lo, sizeof lo), memcpy(corner.region_hi, hi, sizeof hi);
  int ta, tc;
  double ea = street_indirect(s, &all, &ta), ec = street_indirect(s, &corner, &tc);
  printf("street: indirect light in front of the far wall: whole street (%d tiles) %.4f, the corner alone (%d "
         "tiles) %.4f\n", ta, ea, tc, ec);
  assert_true(ec > 0.05);
  assert_true(fabs(ea - ec) <= 0.1 * ec);
  gi_scene_release(s);
}

/* A floor of two charts meeting at x = 2 under the light: the texels on
 * both sides of the seam are as close to the reference, and no darker
 * against it, than the texels 0.3 m beside them inside their charts. */
static void test_no_dark_seams(void **state) {
  (void)state;
  gi_scene *s = room_scene_ex(1);
  gi_lightmap_opts o = {.texel = 0.1, .atlas = 256};
  gi_lightmap *lm = NULL;
  gi_error_info err = {0};
  assert_int_equal(gi_lightmap_layout(s, &o, &lm, &err), GI_OK);
  gi_quality q = {.levels = 3, .res = 16, .probe_samples = 16, .cones = 6};
  assert_int_equal(gi_lightmap_bake(lm, &q, NULL, NULL, &err), GI_OK);
  gi_lightmap_atlas a;
  gi_lightmap_get_atlas(lm, 0, &a);
  double o3[3];
  gi_lightmap_origin(lm, o3);
  /* Floor texels (normal up) within half a texel of the seam, each paired
   * with the floor texel nearest to 0.3 m beside it (alternating sides),
   * which sees the same light pattern from inside its chart. */
  enum { PER = 40 };
  static double pts[3 * 2 * PER];
  size_t idx[2 * PER], n[2] = {0, 0}, cand[2048], nc = 0, floor_t[8192], nf = 0;
  for (size_t i = 0; i < (size_t)a.width * a.height; i++) {
    if (a.valid[i] == 0 || a.normal[3 * i + 1] < 0.99f || o3[1] + a.point[3 * i + 1] > 0.5) continue;
    if (nf < 8192) floor_t[nf++] = i;
    if (fabs(o3[0] + a.point[3 * i] - 2) < 0.06 && nc < 2048) cand[nc++] = i;
  }
  assert_true(nc >= PER);
  for (int j = 0; j < PER; j++) {
    size_t i = cand[(size_t)j * nc / PER], best = 0;
    double want[2] = {o3[0] + a.point[3 * i] + (j % 2 ? 0.3 : -0.3), o3[2] + a.point[3 * i + 2]}, bd = INFINITY;
    for (size_t f = 0; f < nf; f++) {
      double dx = o3[0] + a.point[3 * floor_t[f]] - want[0], dz = o3[2] + a.point[3 * floor_t[f] + 2] - want[1];
      if (dx * dx + dz * dz < bd) bd = dx * dx + dz * dz, best = floor_t[f];
    }
    idx[j] = best, idx[PER + j] = i;
  }
  n[0] = n[1] = PER;
  for (size_t m = 0; m < 2 * PER; m++)
    for (int c = 0; c < 3; c++) pts[3 * m + c] = o3[c] + a.point[3 * idx[m] + c] + (c == 1 ? 1e-3 : 0);
  printf("seam: %zu texels along it, %zu beside them inside the charts\n", n[1], n[0]);
  static gi_ref_probe ref[2 * PER];
  gi_reference_opts ro = {.samples = 2048, .seed = 5};
  assert_int_equal(gi_reference_irradiance(s, pts, n[0] + n[1], &ro, ref, NULL, &err), GI_OK);
  double e[2] = {0, 0}, bias[2] = {0, 0}, se = 0;
  for (size_t m = 0; m < n[0] + n[1]; m++) {
    int k = m >= n[0];
    const float *E = a.irradiance + 3 * idx[m];
    e[k] += rel_err(E, ref[m].irradiance);
    bias[k] += (E[1] - ref[m].irradiance[1]) / ref[m].irradiance[1];
    se += (double)ref[m].std_err[1] / ref[m].irradiance[1];
    if (getenv("LM_DEBUG"))
      printf("%d %.3f %.3f  lm %.4f (direct %.4f) ref %.4f (direct %.4f)\n", k, pts[3 * m], pts[3 * m + 2], E[1],
             a.direct[3 * idx[m] + 1], ref[m].irradiance[1], ref[m].direct[1]);
  }
  for (int k = 0; k < 2; k++) e[k] /= (double)n[k], bias[k] /= (double)n[k];
  se /= (double)(n[0] + n[1]);
  printf("seam texels: MRE %.2f%% (signed %+.2f%%); beside them: %.2f%% (signed %+.2f%%); reference rel. std. error "
         "%.2f%%\n",
         100 * e[1], 100 * bias[1], 100 * e[0], 100 * bias[0], 100 * se);
  assert_true(e[1] <= 1.2 * e[0] + 2 * se);
  assert_true(bias[1] >= bias[0] - 2 * se - 0.02);
  gi_lightmap_free(lm);
  gi_scene_release(s);
}

/* Valid texels of every atlas of lm, and how many read no indirect light. */
static void count_unlit(const gi_lightmap *lm, size_t *valid, size_t *unlit) {
  *valid = *unlit = 0;
  for (size_t k = 0; k < gi_lightmap_num_atlases(lm); k++) {
    gi_lightmap_atlas a;
    assert_int_equal(gi_lightmap_get_atlas(lm, k, &a), 0);
    for (size_t i = 0; i < (size_t)a.width * a.height; i++) {
      if (!(a.valid[i] > 0)) continue;
      (*valid)++;
      *unlit += a.indirect[3 * i] + a.indirect[3 * i + 1] + a.indirect[3 * i + 2] == 0;
    }
  }
}

/* Every texel of a closed lit room takes bounce light, whatever the
 * cascade's size, but where the box stands on the floor (its underside, 25
 * texels at every res): at res 8 the default tile (0.8 of the coarsest
 * level) reached past the level's border and most texels read none (84%
 * of the Cornell box's). The default now shrinks until each tile's
 * cascade holds its texels; a tile the caller chose too large is refused,
 * naming it, and leaves the previous bake as it was. */
static void test_small_res_tiles(void **state) {
  (void)state;
  gi_scene *s = room_scene();
  gi_lightmap_opts o = {.texel = 0.25, .atlas = 256};
  gi_lightmap *lm = NULL;
  gi_error_info err = {0};
  assert_int_equal(gi_lightmap_layout(s, &o, &lm, &err), GI_OK);
  gi_quality def = {.probe_samples = 16, .cones = 6, .threads = 2};
  gi_lightmap_report rep;
  assert_int_equal(gi_lightmap_bake(lm, &def, NULL, &rep, &err), GI_OK);
  size_t valid_def, unlit_def, valid, unlit;
  count_unlit(lm, &valid_def, &unlit_def);
  gi_quality q = {.levels = 2, .res = 8, .probe_samples = 16, .cones = 6, .threads = 2};
  gi_result rc = gi_lightmap_bake(lm, &q, NULL, &rep, &err);
  if (rc) printf("%s\n", err.msg);
  assert_int_equal(rc, GI_OK);
  count_unlit(lm, &valid, &unlit);
  printf("room: %zu valid texels; without indirect light %zu at the default quality, %zu at res 8 and 2 levels "
         "(%d tiles)\n", valid, unlit_def, unlit, rep.tiles);
  assert_true(valid == valid_def && valid > 1000);
  assert_true(unlit_def < valid / 50);
  assert_true(unlit <= unlit_def);
  assert_true(rep.tiles > 1);
  gi_lightmap_free(lm);

  o.tile = 4;
  assert_int_equal(gi_lightmap_layout(s, &o, &lm, &err), GI_OK);
  gi_quality big = q;
  big.levels = 4, big.res = 16;
  assert_int_equal(gi_lightmap_bake(lm, &big, NULL, &rep, &err), GI_OK);
  count_unlit(lm, &valid, &unlit);
  assert_true(valid == valid_def && unlit <= unlit_def);
  assert_int_equal(gi_lightmap_bake(lm, &q, NULL, &rep, &err), GI_ERR_INVALID_ARG);
  printf("tile 4 at 2 levels of 8: %s\n", err.msg);
  assert_non_null(strstr(err.msg, "lie outside its cascade"));
  size_t valid2, unlit2;
  count_unlit(lm, &valid2, &unlit2);
  assert_true(valid2 == valid && unlit2 == unlit);
  gi_lightmap_free(lm);
  gi_scene_release(s);
}

/* A ground strip 300 m long whose centre lies in a 10 m region, beside a
 * sunlit wall along all of it: the strip's texels far out of the region
 * fell in the region's edge tile, outside every level of its cascade (the
 * bake said so, or before that read indirect 0). Tiles now reach them:
 * every texel takes the wall's light, 100 m out as at the middle. */
static void test_region_reaching_texels(void **state) {
  (void)state;
  gi_mesh_builder *b = gi_mesh_builder_new();
  gi_material m = {.albedo = {0.6f, 0.6f, 0.6f}, .roughness = 1};
  uint32_t mat = gi_mesh_builder_add_material(b, &m);
  uint32_t v0 = gi_mesh_builder_add_vertex(b, -150, 0, -1), v1 = gi_mesh_builder_add_vertex(b, 0, 0, 2),
           v2 = gi_mesh_builder_add_vertex(b, 150, 0, -1);
  gi_mesh_builder_add_triangle(b, v0, v1, v2, mat); /* up: centre (0, 0, 0) */
  double w[4][3] = {{-150, 0, 3}, {-150, 4, 3}, {150, 4, 3}, {150, 0, 3}}; /* facing -z */
  gi_mesh_builder_add_quad(b, w[0], w[1], w[2], w[3], mat);
  gi_light sun = {.type = GI_LIGHT_SUN, .color = {3, 3, 3}, .direction = {0, -0.70710678f, 0.70710678f}};
  gi_scene *s = tu_build(b, "strip", &sun, 1);
  gi_lightmap_opts o = {.texel = 0.5, .atlas = 1024, .have_region = 1, .region_lo = {-5, -1, -5},
                        .region_hi = {5, 5, 5}};
  gi_lightmap *lm = NULL;
  gi_error_info err = {0};
  assert_int_equal(gi_lightmap_layout(s, &o, &lm, &err), GI_OK);
  gi_quality q = {.probe_samples = 16, .cones = 6, .threads = 2};
  gi_lightmap_report rep;
  gi_result rc = gi_lightmap_bake(lm, &q, NULL, &rep, &err);
  if (rc) printf("%s\n", err.msg);
  assert_int_equal(rc, GI_OK);
  double org[3];
  gi_scene_origin(s, org);
  size_t valid = 0, unlit = 0, far = 0;
  double near_sum = 0, far_sum = 0;
  size_t near_n = 0;
  for (size_t k = 0; k < gi_lightmap_num_atlases(lm); k++) {
    gi_lightmap_atlas a;
    assert_int_equal(gi_lightmap_get_atlas(lm, k, &a), 0);
    for (size_t i = 0; i < (size_t)a.width * a.height; i++) {
      if (!(a.valid[i] > 0) || a.normal[3 * i + 1] < 0.99f) continue; /* the strip's texels */
      double x = org[0] + a.point[3 * i], z = org[2] + a.point[3 * i + 2];
      valid++;
      unlit += a.indirect[3 * i + 1] == 0;
      if (z < -0.5 || z > 0) continue; /* one band across the strip, 3-3.5 m from the wall */
      if (fabs(x) > 100 && fabs(x) < 120) far_sum += a.indirect[3 * i + 1], far++;
      if (fabs(x) < 20) near_sum += a.indirect[3 * i + 1], near_n++;
    }
  }
  printf("strip: %d tiles, %zu texels, %zu without indirect light; indirect 100-120 m out %.4f (%zu), within 20 m "
         "%.4f (%zu)\n", rep.tiles, valid, unlit, far_sum / (double)far, far, near_sum / (double)near_n, near_n);
  assert_true(rep.tiles > 1 && far > 20 && near_n > 20);
  assert_true(unlit <= valid / 100);
  assert_true(fabs(far_sum / far - near_sum / near_n) <= 0.15 * (near_sum / near_n));
  gi_lightmap_free(lm);
  gi_scene_release(s);
}

/* Mean indirect light (red) of the valid texels whose normal is horizontal
 * (a box's sides), and the report, of a lightmap of s with quality q. */
static double side_indirect(gi_scene *s, const gi_quality *q, gi_lightmap_report *rep) {
  gi_lightmap_opts o = {.texel = 0.25, .atlas = 256};
  gi_lightmap *lm = NULL;
  gi_error_info err = {0};
  assert_int_equal(gi_lightmap_layout(s, &o, &lm, &err), GI_OK);
  assert_int_equal(gi_lightmap_bake(lm, q, NULL, rep, &err), GI_OK);
  double sum = 0;
  size_t n = 0;
  gi_lightmap_atlas a;
  gi_lightmap_get_atlas(lm, 0, &a);
  for (size_t i = 0; i < (size_t)a.width * a.height; i++)
    if (a.valid[i] != 0 && fabsf(a.normal[3 * i + 1]) < 0.01f) sum += a.indirect[3 * i], n++;
  assert_true(n > 16);
  gi_lightmap_free(lm);
  return sum / (double)n;
}

/* A tile's cascade centred inside a solid box on a sky-lit floor: the
 * plan tested the sky only around the tile's centre, saw none, and every
 * texel lost the sky's bounce (the box's sides read 0). The plan now tests
 * from the tile's texels too: the sides read as with the sky forced on. */
static void test_tile_centre_inside_solid(void **state) {
  (void)state;
  gi_scene *s = tu_box_on_sky_floor();
  /* Level 0 (0.64 across) lies inside the box: every origin of the old test did. */
  gi_quality q = {.levels = 6, .res = 16, .voxel0 = 0.04, .probe_samples = 16, .cones = 6};
  gi_lightmap_report rep;
  double autos = side_indirect(s, &q, &rep);
  assert_int_equal(rep.tiles, 1);
  printf("box on a sky-lit floor, tile centred inside it: sky %s (%s), sides' indirect %.4f\n",
         rep.effects[GI_FX_SKY].ran ? "ran" : "skipped", rep.effects[GI_FX_SKY].why, autos);
  assert_true(rep.effects[GI_FX_SKY].ran);
  assert_int_equal(rep.effect_tiles[GI_FX_SKY], 1);
  q.effects[GI_FX_SKY] = GI_FX_ON;
  double forced = side_indirect(s, &q, &rep);
  printf("  forced on: %.4f\n", forced);
  assert_true(autos > 0.2);
  assert_true(fabs(autos - forced) <= 1e-6 * forced);
  gi_scene_release(s);
}

/* Tiles share one bounce count: a white room (0.7, a lamp inside) on a
 * 40 m black ground, baked in 2 m tiles. Each tile's own plan follows the
 * brightest level round it: a tile out on the ground plans fewer bounces
 * than the room's (checked below), and the light stepped where they met.
 * Every tile now runs the most any tile planned, with the tail. */
static void test_tiles_share_bounces(void **state) {
  (void)state;
  gi_mesh_builder *b = gi_mesh_builder_new();
  gi_material wall = {.albedo = {0.7f, 0.7f, 0.7f}, .roughness = 1}, black = {.roughness = 1};
  uint32_t mw = gi_mesh_builder_add_material(b, &wall), mg = gi_mesh_builder_add_material(b, &black);
  double lo[3] = {0, 0, 0}, hi[3] = {4, 3, 5};
  gi_mesh_builder_add_box(b, lo, hi, mw);
  double g[4][3] = {{-18, -0.01, -18}, {-18, -0.01, 22}, {22, -0.01, 22}, {22, -0.01, -18}};
  gi_mesh_builder_add_quad(b, g[0], g[1], g[2], g[3], mg);
  gi_light lamp = {.type = GI_LIGHT_POINT, .color = {20, 20, 20}, .position = {2, 2.5, 2.5}};
  gi_scene_options so = {.up = GI_UP_Y, .lights = &lamp, .num_lights = 1};
  gi_scene *s = NULL;
  gi_error_info err = {0};
  assert_int_equal(gi_scene_build(b, "room on black", &so, &s, &err), GI_OK);
  gi_mesh_builder_free(b);
  gi_quality q = {.levels = 4, .res = 16, .cones = 6, .probe_samples = 16, .light_samples = 4};
  gi_lightmap_opts o = {.texel = 0.5, .atlas = 512, .tile = 2};
  gi_lightmap *lm = NULL;
  gi_lightmap_report rep;
  assert_int_equal(gi_lightmap_layout(s, &o, &lm, &err), GI_OK);
  assert_int_equal(gi_lightmap_bake(lm, &q, NULL, &rep, &err), GI_OK);
  printf("room on a black ground, %d tiles: bounce %s in %d (%s)\n", (int)rep.tiles,
         rep.effects[GI_FX_BOUNCE].ran ? "ran" : "skipped", (int)rep.effect_tiles[GI_FX_BOUNCE], rep.effects[GI_FX_BOUNCE].why);
  assert_true(rep.tiles > 4);
  gi_effect fx[GI_FX_COUNT];
  gi_quality room, ground;
  const double in_room[3] = {2, 1.5, 2.5}, out_there[3] = {-15, 0.5, -15};
  assert_int_equal(gi_effect_plan(s, in_room, &q, fx, &room, &err), GI_OK);
  assert_int_equal(gi_effect_plan(s, out_there, &q, fx, &ground, &err), GI_OK);
  printf("  plans: in the room %d bounces, tail %d; out on the ground %d, tail %d\n", room.bounces, room.bounce_tail,
         ground.bounces, ground.bounce_tail);
  assert_true(room.bounces > ground.bounces || room.bounce_tail > ground.bounce_tail);
  char want[64];
  snprintf(want, sizeof want, "%d bounces%s in every tile", room.bounces, room.bounce_tail ? " and the geometric tail" : "");
  assert_non_null(strstr(rep.effects[GI_FX_BOUNCE].why, want));
  assert_int_equal(rep.effect_tiles[GI_FX_BOUNCE], rep.tiles);
  gi_lightmap_free(lm);
  gi_scene_release(s);
}

/* A flat floor alone (no height): the default cascade spanned an eighth of
 * it, the default tiles were 4 cm, and --texel 1 failed ("texels ... lie
 * outside its cascade") while 0.25 took 676 tiles. Now one tile holds it,
 * and an open floor under a sky of 1 reads irradiance pi. */
static void test_flat_floor_one_tile(void **state) {
  (void)state;
  gi_mesh_builder *b = gi_mesh_builder_new();
  gi_material m = {.albedo = {0.5f, 0.5f, 0.5f}, .roughness = 1};
  uint32_t mat = gi_mesh_builder_add_material(b, &m);
  double f[4][3] = {{-5, 0, -5}, {-5, 0, 5}, {5, 0, 5}, {5, 0, -5}};
  gi_mesh_builder_add_quad(b, f[0], f[1], f[2], f[3], mat);
  gi_light sky = {.type = GI_LIGHT_SKY, .color = {1, 1, 1}};
  gi_scene_options so = {.up = GI_UP_Y, .lights = &sky, .num_lights = 1};
  gi_scene *s = NULL;
  gi_error_info err = {0};
  assert_int_equal(gi_scene_build(b, "floor", &so, &s, &err), GI_OK);
  gi_mesh_builder_free(b);
  for (int i = 0; i < 2; i++) {
    gi_lightmap_opts o = {.texel = i ? 1.0 : 0.25, .atlas = 256};
    gi_lightmap *lm = NULL;
    assert_int_equal(gi_lightmap_layout(s, &o, &lm, &err), GI_OK);
    /* 256 sky samples per texel (the default): the worst texel within 0.2% of pi; 64 gave 1.9%. */
    gi_quality q = {.probe_samples = 256, .cones = 6};
    gi_lightmap_report rep;
    gi_result rc = gi_lightmap_bake(lm, &q, NULL, &rep, &err);
    if (rc) fprintf(stderr, "%s\n", err.msg);
    assert_int_equal(rc, GI_OK);
    gi_lightmap_atlas a;
    gi_lightmap_get_atlas(lm, 0, &a);
    double worst = 0;
    for (size_t k = 0; k < (size_t)a.width * a.height; k++)
      if (a.valid[k] != 0) worst = fmax(worst, fabs(a.irradiance[3 * k] - 3.14159265) / 3.14159265);
    printf("flat floor, texel %.2f: %d tile(s), irradiance within %.4f of pi\n", o.texel, rep.tiles, worst);
    assert_int_equal(rep.tiles, 1);
    assert_true(worst < 0.01);
    gi_lightmap_free(lm);
  }
  gi_scene_release(s);
}

/* A closed 4 x 2.5 x 4 room cut in two by a 2 cm wall from floor to
 * ceiling at x = x0, a point light of intensity 10 in the half past it. */
static gi_scene *walled_rooms(double x0) {
  gi_mesh_builder *b = gi_mesh_builder_new();
  gi_material m = {.albedo = {0.5f, 0.5f, 0.5f}, .roughness = 1};
  uint32_t mat = gi_mesh_builder_add_material(b, &m);
  double c[8][3];
  for (int i = 0; i < 8; i++) c[i][0] = i & 1 ? 2 : -2, c[i][1] = i & 2 ? 2.5 : 0, c[i][2] = i & 4 ? 2 : -2;
  gi_mesh_builder_add_quad(b, c[0], c[4], c[5], c[1], mat); /* floor, normal +y */
  gi_mesh_builder_add_quad(b, c[2], c[3], c[7], c[6], mat);
  gi_mesh_builder_add_quad(b, c[0], c[2], c[6], c[4], mat);
  gi_mesh_builder_add_quad(b, c[1], c[5], c[7], c[3], mat);
  gi_mesh_builder_add_quad(b, c[0], c[1], c[3], c[2], mat);
  gi_mesh_builder_add_quad(b, c[4], c[6], c[7], c[5], mat);
  double lo[3] = {x0, 0, -2}, hi[3] = {x0 + 0.02, 2.5, 2};
  gi_mesh_builder_add_box(b, lo, hi, mat);
  gi_light pl = {.type = GI_LIGHT_POINT, .color = {10, 10, 10}, .position = {1, 1.5, -0.5}};
  gi_scene_options so = {.up = GI_UP_Y, .lights = &pl, .num_lights = 1};
  gi_scene *s = NULL;
  gi_error_info err = {0};
  assert_int_equal(gi_scene_build(b, "walled", &so, &s, &err), GI_OK);
  gi_mesh_builder_free(b);
  return s;
}

/* A wall thinner than half a texel standing on the floor: every floor
 * texel reads one side of it, 0 direct light in the dark room, the point
 * light's I cos / d^2 at its point on the lit side. Four wall positions a
 * quarter texel apart put it between two footprint columns of one texel
 * at least once; such a texel averaged both sides (half the analytic
 * value, 0.49 off it). */
static void test_thin_wall_one_side(void **state) {
  (void)state;
  size_t dark_near = 0, lit_near = 0;
  double worst = 0;
  for (int w = 0; w < 4; w++) {
    double x0 = -0.13 + 0.0625 * w;
    gi_scene *s = walled_rooms(x0);
    gi_lightmap_opts o = {.texel = 0.25, .atlas = 256};
    gi_lightmap *lm = NULL;
    gi_error_info err = {0};
    assert_int_equal(gi_lightmap_layout(s, &o, &lm, &err), GI_OK);
    gi_quality q = {.levels = 3, .res = 16, .probe_samples = 16, .cones = 6};
    assert_int_equal(gi_lightmap_bake(lm, &q, NULL, NULL, &err), GI_OK);
    double org[3];
    gi_lightmap_origin(lm, org);
    for (size_t at = 0; at < gi_lightmap_num_atlases(lm); at++) {
      gi_lightmap_atlas a;
      gi_lightmap_get_atlas(lm, at, &a);
      for (size_t i = 0; i < (size_t)a.width * a.height; i++) {
        double p[3] = {org[0] + a.point[3 * i], org[1] + a.point[3 * i + 1], org[2] + a.point[3 * i + 2]};
        if (a.valid[i] == 0 || a.normal[3 * i + 1] < 0.99f || fabs(p[1]) > 1e-3) continue;
        double d[3] = {1 - p[0], 1.5 - p[1], -0.5 - p[2]}, d2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
        double E = 10 * d[1] / sqrt(d2) / d2, got = a.direct[3 * i];
        /* Dark texels read exactly 0; lit ones the analytic value. */
        double e = got == 0 ? 0 : fabs(got - E) / E;
        if (getenv("LM_DEBUG") && (e > 0.05 || fabs(p[0] - x0) < 0.25))
          printf("wall %.4f texel at %.4f, %.4f: direct %.4f, analytic %.4f\n", x0, p[0], p[2], got, E);
        if (p[0] < x0 && got != 0) e = 1; /* light in the dark room */
        worst = fmax(worst, e);
        if (fabs(p[0] - x0) < 0.2) dark_near += got == 0 && p[0] < x0, lit_near += got != 0 && p[0] > x0;
      }
    }
    gi_lightmap_free(lm);
    gi_scene_release(s);
  }
  printf("thin wall: %zu dark and %zu lit floor texels within 0.2 m of it; worst lit texel %.4f off I cos/d^2\n",
         dark_near, lit_near, worst);
  assert_true(dark_near > 0 && lit_near > 0);
  assert_true(worst < 0.05);
}

/* The Cornell box's x = 0 wall at 2 cm texels against 1-pixel path-traced
 * views of the texels' points (4096 paths each): its top row, under the
 * ceiling, as close to the reference as its texels away from the edges.
 * The row's gathers started within a voxel of the ceiling and read its
 * voxels going down: 0.70 of the reference on average (0.49-0.92) where
 * the texels away from the edges read 1.03; 0.94 since. */
static void test_wall_ceiling_edge(void **state) {
  (void)state;
  TU_SKIP_IF_NO_SCENE(path, "cornell-box/cornell-box.obj");
  gi_scene *sc = NULL;
  gi_error_info err = {0};
  gi_scene_options so = {.up = GI_UP_Y};
  assert_int_equal(gi_scene_load(path, &so, &sc, &err), GI_OK);
  gi_lightmap_opts o = {.texel = 20, .atlas = 512};
  gi_lightmap *lm = NULL;
  assert_int_equal(gi_lightmap_layout(sc, &o, &lm, &err), GI_OK);
  gi_quality q = {.probe_samples = 64};
  assert_int_equal(gi_lightmap_bake(lm, &q, NULL, NULL, &err), GI_OK);
  gi_lightmap_atlas a;
  gi_lightmap_get_atlas(lm, 0, &a);
  double org[3], lo[3], hi[3];
  gi_lightmap_origin(lm, org);
  gi_scene_bounds(sc, lo, hi);
  /* Both kinds 100..450 from the back and front edges; kind 0 100..450 from
   * the floor, kind 1 the top row (its points half a texel under the ceiling). */
  enum { PER = 10 };
  size_t cand[2][512], nc[2] = {0, 0};
  for (size_t i = 0; i < (size_t)a.width * a.height; i++) {
    double x = org[0] + a.point[3 * i], y = org[1] + a.point[3 * i + 1], z = org[2] + a.point[3 * i + 2];
    if (a.valid[i] == 0 || a.normal[3 * i] < 0.99f || x > lo[0] + 1) continue;
    int k = z < 100 || z > 450 ? -1 : y > hi[1] - 10 ? 1 : y > 100 && y < 450 ? 0 : -1;
    if (k >= 0 && nc[k] < 512) cand[k][nc[k]++] = i;
  }
  assert_true(nc[0] >= PER && nc[1] >= PER);
  double ratio[2] = {0, 0};
  for (int k = 0; k < 2; k++) {
    for (int j = 0; j < PER; j++) {
      size_t i = cand[k][(size_t)j * nc[k] / PER];
      gi_camera cam = {.up = {0, 1, 0}, .fov_deg = 1, .width = 1, .height = 1};
      for (int c = 0; c < 3; c++) {
        cam.target[c] = org[c] + a.point[3 * i + c];
        cam.eye[c] = cam.target[c] + 10 * a.normal[3 * i + c];
      }
      gi_render_opts ro = {.spp = 4096, .seed = 7 + (uint64_t)j};
      float rgb[3];
      assert_int_equal(gi_reference_render_ex(sc, &cam, &ro, rgb, NULL, &err), GI_OK);
      double r = rel_err(a.radiance + 3 * i, rgb), lum = 0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2];
      double got = 0.2126 * a.radiance[3 * i] + 0.7152 * a.radiance[3 * i + 1] + 0.0722 * a.radiance[3 * i + 2];
      if (getenv("LM_DEBUG"))
        printf("%d (%.1f, %.1f, %.1f): lightmap %.5f reference %.5f (rel. err. %.3f)\n", k, cam.target[0],
               cam.target[1], cam.target[2], got, lum, r);
      ratio[k] += got / lum / PER;
    }
  }
  printf("x = 0 wall, lightmap over path tracer: %.3f away from the edges, %.3f under the ceiling\n", ratio[0],
         ratio[1]);
  assert_true(fabs(ratio[1] - ratio[0]) < 0.1);
  gi_lightmap_free(lm);
  gi_scene_release(sc);
}

/* A scene's own UVs set the texel: the EXR's gi.texel is the mean world
 * side of their texels (a 10 x 10 plate over 32 x 32 texels of a 64 atlas:
 * 0.3125), whatever texel was asked (it said the unused default, 0.25). */
static void test_scene_uv_texel(void **state) {
  (void)state;
  gi_scene *s = plate_with_uv(0.5, 0.25, -1);
  assert_true(gi_scene_has_lightmap_uv(s));
  static const double asked[2] = {0, 2};
  for (int i = 0; i < 2; i++) {
    gi_lightmap_opts o = {.texel = asked[i], .atlas = 64};
    gi_lightmap *lm = NULL;
    gi_error_info err = {0};
    assert_int_equal(gi_lightmap_layout(s, &o, &lm, &err), GI_OK);
    char path[512];
    snprintf(path, sizeof path, "%s/plate-lm-%d.exr", tu_tmpdir(), i);
    assert_int_equal(gi_lightmap_write_exr(lm, path, 0, &err), GI_OK);
    gi_exr_file *x = NULL;
    assert_int_equal(gi_exr_read(path, &x, &err), GI_OK);
    const char *t = gi_exr_file_attr(x, "gi.texel");
    assert_non_null(t);
    printf("scene's own UVs, texel %g asked: gi.texel %s\n", asked[i], t);
    assert_float_equal(strtod(t, NULL), 0.3125, 1e-6);
    gi_exr_file_free(x);
    remove(path);
    gi_lightmap_free(lm);
  }
  gi_scene_release(s);
}

/* Whether every gathered array of every atlas is zero (unbaked). */
static int atlases_zero(const gi_lightmap *lm) {
  for (size_t k = 0; k < gi_lightmap_num_atlases(lm); k++) {
    gi_lightmap_atlas a;
    assert_int_equal(gi_lightmap_get_atlas(lm, k, &a), 0);
    size_t n = (size_t)a.width * a.height;
    for (size_t i = 0; i < n; i++) {
      if (a.valid[i] != 0) return 0;
      for (int c = 0; c < 3; c++)
        if (a.radiance[3 * i + c] != 0 || a.irradiance[3 * i + c] != 0 || a.direct[3 * i + c] != 0 ||
            a.indirect[3 * i + c] != 0 || a.point[3 * i + c] != 0 || a.normal[3 * i + c] != 0)
          return 0;
    }
  }
  return 1;
}

/* A bake that fails part way (here: out of memory in a later tile, after
 * earlier tiles wrote their texels) leaves every atlas zero, whether the
 * lightmap was fresh or held a previous bake; only the texels the tiles
 * wrote are cleared (a fresh 4096^2 atlas is never written whole), so
 * each failure point is checked. A clean bake after them matches the
 * first bit for bit. */
static void test_failed_bake_leaves_zero(void **state) {
  (void)state;
  gi_scene *s = room_scene();
  gi_lightmap_opts o = {.texel = 0.25, .atlas = 256, .tile = 2};
  gi_lightmap *lm = NULL;
  gi_error_info err = {0};
  assert_int_equal(gi_lightmap_layout(s, &o, &lm, &err), GI_OK);
  gi_quality q = {.levels = 3, .res = 16, .probe_samples = 16, .cones = 6, .threads = 1};
  gi_lightmap_report rep;
  long a0 = gi__alloc_attempts();
  assert_int_equal(gi_lightmap_bake(lm, &q, NULL, &rep, &err), GI_OK);
  long calls = gi__alloc_attempts() - a0;
  assert_true(rep.tiles > 1 && rep.texels_valid > 0);
  gi_lightmap_atlas a;
  gi_lightmap_get_atlas(lm, 0, &a);
  size_t n = 3 * (size_t)a.width * a.height;
  float *first = malloc(n * sizeof *first);
  assert_non_null(first);
  memcpy(first, a.radiance, n * sizeof *first);
  int failed = 0;
  for (int fresh = 0; fresh < 2; fresh++)
    for (int f = 1; f <= 9; f += 2) {
      if (fresh) {
        gi_lightmap_free(lm);
        assert_int_equal(gi_lightmap_layout(s, &o, &lm, &err), GI_OK);
      } else {
        assert_int_equal(gi_lightmap_bake(lm, &q, NULL, &rep, &err), GI_OK);
        assert_false(atlases_zero(lm));
      }
      gi__alloc_fail_after(calls * f / 10);
      gi_result rc = gi_lightmap_bake(lm, &q, NULL, &rep, &err);
      int reached = !gi__alloc_fail_armed();
      gi__alloc_fail_after(-1);
      assert_true(reached ? rc == GI_ERR_NOMEM : rc == GI_OK);
      if (rc != GI_OK) {
        failed++;
        assert_true(atlases_zero(lm));
      }
    }
  printf("room: %d of 10 bakes failed part way (of %ld allocations), each left its atlases zero\n", failed, calls);
  assert_true(failed >= 8);
  assert_int_equal(gi_lightmap_bake(lm, &q, NULL, &rep, &err), GI_OK);
  gi_lightmap_get_atlas(lm, 0, &a);
  assert_memory_equal(first, a.radiance, n * sizeof *first);
  free(first);
  gi_lightmap_free(lm);
  gi_scene_release(s);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_charts_and_packing),
      cmocka_unit_test(test_bad_options),
      cmocka_unit_test(test_max_bytes),
      cmocka_unit_test(test_cornell_against_reference),
      cmocka_unit_test(test_exr_read_back),
      cmocka_unit_test(test_gltf_read_back),
      cmocka_unit_test(test_gltf_z_up),
      cmocka_unit_test(test_scene_uv_checked),
      cmocka_unit_test(test_scene_uv_overlap),
      cmocka_unit_test(test_scene_uv_incomplete),
      cmocka_unit_test(test_bake_deterministic_and_tiled),
      cmocka_unit_test(test_big_chart_tiles),
      cmocka_unit_test(test_small_res_tiles),
      cmocka_unit_test(test_region_reaching_texels),
      cmocka_unit_test(test_no_dark_seams),
      cmocka_unit_test(test_tile_centre_inside_solid),
      cmocka_unit_test(test_flat_floor_one_tile),
      cmocka_unit_test(test_tiles_share_bounces),
      cmocka_unit_test(test_thin_wall_one_side),
      cmocka_unit_test(test_wall_ceiling_edge),
      cmocka_unit_test(test_scene_uv_texel),
      cmocka_unit_test(test_failed_bake_leaves_zero),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
