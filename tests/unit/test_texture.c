/* test_texture.c: texture averages (PNG, JPEG, raw texels) and textured
 * materials in scene import (OBJ map_Kd, glTF baseColorTexture). */
#include "test_util.h"
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <jpeglib.h>
#include <png.h>
#include "gi/gi_scene.h"
#include "io/texture_image.h"
#include "scene/scene_internal.h"

/* The exact sRGB transfer function, in double. */
static double lin(double v8) {
  double c = v8 / 255.0;
  return c <= 0.04045 ? c / 12.92 : pow((c + 0.055) / 1.055, 2.4);
}

/* --- image writers ----------------------------------------------------- */

/* A PNG in memory (simplified API); *size bytes, malloc'ed. */
static void *png_mem(const void *pixels, uint32_t w, uint32_t h, uint32_t format, const void *colormap,
                     uint32_t ncolors, size_t *size) {
  png_image im;
  memset(&im, 0, sizeof im);
  im.version = PNG_IMAGE_VERSION;
  im.width = w;
  im.height = h;
  im.format = format;
  im.colormap_entries = ncolors;
  png_alloc_size_t n = 0;
  assert_true(png_image_write_to_memory(&im, NULL, &n, 0, pixels, 0, colormap));
  void *buf = malloc(n);
  assert_non_null(buf);
  assert_true(png_image_write_to_memory(&im, buf, &n, 0, pixels, 0, colormap));
  *size = n;
  return buf;
}

/* A PNG file in the test folder, through png_image_write_to_file. */
static const char *png_file(const char *name, const void *rgba, uint32_t w, uint32_t h) {
  char path[4096];
  snprintf(path, sizeof path, "%s/%s", tu_tmpdir(), name);
  png_image im;
  memset(&im, 0, sizeof im);
  im.version = PNG_IMAGE_VERSION;
  im.width = w;
  im.height = h;
  im.format = PNG_FORMAT_RGBA;
  assert_true(png_image_write_to_file(&im, path, 0, rgba, 0, NULL));
  return name;
}

/* An 8-bit RGB PNG through the low-level API, interlaced (Adam7) or not. */
static void *png_mem_rgb(const unsigned char *rgb, uint32_t w, uint32_t h, int interlace, size_t *size) {
  char path[4096];
  snprintf(path, sizeof path, "%s/lowlevel.png", tu_tmpdir());
  FILE *f = fopen(path, "wb");
  assert_non_null(f);
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, NULL, NULL, NULL);
  png_infop info = png_create_info_struct(png);
  assert_non_null(info);
  if (setjmp(png_jmpbuf(png))) fail_msg("libpng write failed");
  png_init_io(png, f);
  png_set_IHDR(png, info, w, h, 8, PNG_COLOR_TYPE_RGB, interlace ? PNG_INTERLACE_ADAM7 : PNG_INTERLACE_NONE,
               PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  png_bytep *rows = malloc(h * sizeof *rows);
  for (uint32_t y = 0; y < h; y++) rows[y] = (png_bytep)rgb + (size_t)y * w * 3;
  png_set_rows(png, info, rows);
  png_write_png(png, info, PNG_TRANSFORM_IDENTITY, NULL);
  png_destroy_write_struct(&png, &info);
  fclose(f);
  free(rows);
  f = fopen(path, "rb");
  fseek(f, 0, SEEK_END);
  long n = ftell(f);
  rewind(f);
  void *buf = malloc((size_t)n);
  assert_int_equal(fread(buf, 1, (size_t)n, f), (size_t)n);
  fclose(f);
  *size = (size_t)n;
  return buf;
}

/* A JPEG in memory, quality 100, 4:4:4; components 3 (RGB) or 1 (grey). */
static void *jpeg_mem(const unsigned char *pixels, uint32_t w, uint32_t h, int components, size_t *size) {
  struct jpeg_compress_struct ci;
  struct jpeg_error_mgr je;
  ci.err = jpeg_std_error(&je);
  jpeg_create_compress(&ci);
  unsigned char *buf = NULL;
  unsigned long n = 0;
  jpeg_mem_dest(&ci, &buf, &n);
  ci.image_width = w;
  ci.image_height = h;
  ci.input_components = components;
  ci.in_color_space = components == 3 ? JCS_RGB : JCS_GRAYSCALE;
  jpeg_set_defaults(&ci);
  jpeg_set_quality(&ci, 100, TRUE);
  for (int c = 0; c < ci.num_components; c++) ci.comp_info[c].h_samp_factor = ci.comp_info[c].v_samp_factor = 1;
  jpeg_start_compress(&ci, TRUE);
  while (ci.next_scanline < h) {
    JSAMPROW row = (JSAMPROW)pixels + (size_t)ci.next_scanline * w * components;
    jpeg_write_scanlines(&ci, &row, 1);
  }
  jpeg_finish_compress(&ci);
  jpeg_destroy_compress(&ci);
  *size = n;
  void *copy = malloc(n); /* so callers free() it like the others */
  memcpy(copy, buf, n);
  free(buf);
  return copy;
}

/* The 4x4 test image: top half pure red, bottom half sRGB grey 128; alpha
 * varies and must not matter. */
static void half_red_half_grey(unsigned char rgba[64]) {
  for (int i = 0; i < 16; i++) {
    unsigned char *p = rgba + 4 * i;
    if (i < 8) { p[0] = 255; p[1] = 0; p[2] = 0; }
    else { p[0] = p[1] = p[2] = 128; }
    p[3] = (unsigned char)(i * 16);
  }
}
#define GREY128 0.2158605 /* sRGB 128 in linear */
#define HALF_RED_R ((1.0 + GREY128) / 2)
#define HALF_RED_GB (GREY128 / 2)

/* --- gi__image_average ------------------------------------------------ */

static void test_png_average(void **state) {
  assert_float_equal(lin(128), GREY128, 1e-7);
  unsigned char rgba[64];
  half_red_half_grey(rgba);
  size_t n;
  void *png = png_mem(rgba, 4, 4, PNG_FORMAT_RGBA, NULL, 0, &n);
  float rgb[3];
  gi_error_info err = {0};
  assert_int_equal(gi__image_average(png, n, "mem.png", rgb, &err), GI_OK);
  assert_float_equal(rgb[0], HALF_RED_R, 1e-6);
  assert_float_equal(rgb[1], HALF_RED_GB, 1e-6);
  assert_float_equal(rgb[2], HALF_RED_GB, 1e-6);
  free(png);

  /* Grey, and a two-colour palette. */
  unsigned char grey[6] = {128, 128, 128, 0, 255, 64};
  png = png_mem(grey, 3, 2, PNG_FORMAT_GRAY, NULL, 0, &n);
  assert_int_equal(gi__image_average(png, n, "grey.png", rgb, &err), GI_OK);
  double g = (3 * lin(128) + lin(0) + lin(255) + lin(64)) / 6;
  for (int c = 0; c < 3; c++) assert_float_equal(rgb[c], g, 1e-6);
  free(png);
  unsigned char cmap[6] = {255, 0, 0, 0, 0, 128}, idx[4] = {0, 1, 1, 1};
  png = png_mem(idx, 2, 2, PNG_FORMAT_RGB_COLORMAP, cmap, 2, &n);
  assert_int_equal(gi__image_average(png, n, "palette.png", rgb, &err), GI_OK);
  assert_float_equal(rgb[0], 0.25, 1e-6);
  assert_float_equal(rgb[1], 0.0, 1e-6);
  assert_float_equal(rgb[2], 0.75 * lin(128), 1e-6);
  free(png);

  /* 16-bit linear (libpng writes gAMA 1.0): values are taken as they are. */
  uint16_t lin16[6] = {65535, 0, 0, 0, 0, 32768};
  png = png_mem(lin16, 2, 1, PNG_FORMAT_LINEAR_RGB, NULL, 0, &n);
  assert_int_equal(gi__image_average(png, n, "linear16.png", rgb, &err), GI_OK);
  assert_float_equal(rgb[0], 0.5, 1e-6);
  assert_float_equal(rgb[1], 0.0, 1e-6);
  assert_float_equal(rgb[2], 32768.0 / 65535 / 2, 1e-6);
  free(png);
}

/* Adam7 is read pass by pass without de-interlacing: same mean as plain. */
static void test_png_interlaced(void **state) {
  enum { W = 13, H = 7 };
  unsigned char rgb8[W * H * 3];
  double want[3] = {0, 0, 0};
  for (int i = 0; i < W * H * 3; i++) {
    rgb8[i] = (unsigned char)((i * 37 + 11) % 256);
    want[i % 3] += lin(rgb8[i]) / (W * H);
  }
  for (int il = 0; il < 2; il++) {
    size_t n;
    void *png = png_mem_rgb(rgb8, W, H, il, &n);
    float rgb[3];
    gi_error_info err = {0};
    assert_int_equal(gi__image_average(png, n, "il.png", rgb, &err), GI_OK);
    for (int c = 0; c < 3; c++) assert_float_equal(rgb[c], want[c], 1e-6);
    free(png);
  }
  /* A 1x1 interlaced image has six empty passes. */
  size_t n;
  void *png = png_mem_rgb(rgb8, 1, 1, 1, &n);
  float rgb[3];
  gi_error_info err = {0};
  assert_int_equal(gi__image_average(png, n, "one.png", rgb, &err), GI_OK);
  for (int c = 0; c < 3; c++) assert_float_equal(rgb[c], lin(rgb8[c]), 1e-6);
  free(png);
}

static void test_jpeg_average(void **state) {
  enum { W = 16, H = 16 };
  static unsigned char px[W * H * 3];
  const unsigned char col[3] = {200, 100, 50};
  for (int i = 0; i < W * H; i++) memcpy(px + 3 * i, col, 3);
  size_t n;
  void *jpg = jpeg_mem(px, W, H, 3, &n);
  float rgb[3];
  gi_error_info err = {0};
  assert_int_equal(gi__image_average(jpg, n, "uniform.jpg", rgb, &err), GI_OK);
  /* A uniform colour survives quality 100 to within one level. */
  for (int c = 0; c < 3; c++) {
    assert_true(rgb[c] >= lin(col[c] - 1) - 1e-6);
    assert_true(rgb[c] <= lin(col[c] + 1) + 1e-6);
  }
  free(jpg);
  memset(px, 77, W * H);
  jpg = jpeg_mem(px, W, H, 1, &n);
  assert_int_equal(gi__image_average(jpg, n, "grey.jpg", rgb, &err), GI_OK);
  for (int c = 0; c < 3; c++) assert_float_equal(rgb[c], lin(77), 1e-6); /* grey is exact */
  free(jpg);
}

static void test_texels_average(void **state) {
  const unsigned char bgra[8] = {0, 0, 255, 0, 128, 128, 128, 255};
  float rgb[3];
  gi_error_info err = {0};
  assert_int_equal(gi__texels_average(bgra, 2, 1, "raw", rgb, &err), GI_OK);
  assert_float_equal(rgb[0], HALF_RED_R, 1e-6);
  assert_float_equal(rgb[1], HALF_RED_GB, 1e-6);
  assert_float_equal(rgb[2], HALF_RED_GB, 1e-6);
  assert_int_equal(gi__texels_average(bgra, 16385, 1, "raw", rgb, &err), GI_ERR_LIMIT);
  assert_int_equal(gi__texels_average(bgra, 0, 1, "raw", rgb, &err), GI_ERR_FORMAT);
}

/* Junk, every truncation and a flipped byte: a clean error each time. */
static void test_corrupt_images(void **state) {
  float rgb[3];
  gi_error_info err = {0};
  const char junk[] = "this is not an image at all";
  assert_int_equal(gi__image_average(junk, sizeof junk, "junk", rgb, &err), GI_ERR_FORMAT);
  assert_non_null(strstr(err.msg, "junk"));
  assert_int_equal(gi__image_average(junk, 0, "empty", rgb, &err), GI_ERR_FORMAT);
  const unsigned char png_head[] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n', 1, 2, 3, 4, 5, 6, 7};
  assert_int_equal(gi__image_average(png_head, sizeof png_head, "head.png", rgb, &err), GI_ERR_FORMAT);
  const unsigned char jpg_head[] = {0xff, 0xd8, 0xff, 0xe0, 0, 16, 'J', 'F', 'I', 'F', 0, 1, 2, 3};
  assert_int_equal(gi__image_average(jpg_head, sizeof jpg_head, "head.jpg", rgb, &err), GI_ERR_FORMAT);

  unsigned char rgba[64];
  half_red_half_grey(rgba);
  size_t pn, jn;
  unsigned char *png = png_mem(rgba, 4, 4, PNG_FORMAT_RGBA, NULL, 0, &pn);
  static unsigned char px[16 * 16 * 3];
  for (size_t i = 0; i < sizeof px; i++) px[i] = (unsigned char)(i * 7);
  unsigned char *jpg = jpeg_mem(px, 16, 16, 3, &jn);
  /* Each prefix in its own buffer, so reading past it is caught by ASan. */
  for (size_t len = 0; len < pn; len++) {
    unsigned char *cut = malloc(len + 1);
    memcpy(cut, png, len);
    gi_error_info e = {0};
    assert_int_equal(gi__image_average(cut, len, "cut.png", rgb, &e), GI_ERR_FORMAT);
    free(cut);
  }
  for (size_t len = 0; len < jn; len++) {
    unsigned char *cut = malloc(len + 1);
    memcpy(cut, jpg, len);
    gi_error_info e = {0};
    if (gi__image_average(cut, len, "cut.jpg", rgb, &e) != GI_ERR_FORMAT) fail_msg("JPEG cut at %zu accepted", len);
    free(cut);
  }
  /* A flipped bit in the PNG's data: the CRC catches it. */
  png[pn - 20] ^= 0x10;
  assert_int_equal(gi__image_average(png, pn, "flip.png", rgb, &err), GI_ERR_FORMAT);
  assert_non_null(strstr(err.msg, "flip.png"));
  /* Garbage after a JPEG's header: no crash, whatever the verdict. */
  for (size_t i = 200; i < jn; i += 3) jpg[i] = (unsigned char)(i * 13);
  gi__image_average(jpg, jn, "garbled.jpg", rgb, &err);
  free(png);
  free(jpg);
}

static void test_size_limits(void **state) {
  float rgb[3];
  gi_error_info err = {0};
  unsigned char *row = calloc(16385 * 3, 1);
  size_t n;
  void *png = png_mem(row, 16385, 1, PNG_FORMAT_RGB, NULL, 0, &n);
  assert_int_equal(gi__image_average(png, n, "wide.png", rgb, &err), GI_ERR_LIMIT);
  free(png);
  void *jpg = jpeg_mem(row, 16385, 1, 3, &n);
  assert_int_equal(gi__image_average(jpg, n, "wide.jpg", rgb, &err), GI_ERR_LIMIT);
  free(jpg);
  png = png_mem(row, 16384, 1, PNG_FORMAT_RGB, NULL, 0, &n); /* at the limit: fine */
  assert_int_equal(gi__image_average(png, n, "edge.png", rgb, &err), GI_OK);
  free(png);
  free(row);
}

static void test_read_file(void **state) {
  void *data;
  size_t size;
  gi_error_info err = {0};
  const char *p = tu_write_file("bytes.bin", "abcdef", 6);
  assert_int_equal(gi__read_file(p, 100, &data, &size, &err), GI_OK);
  assert_int_equal(size, 6);
  assert_memory_equal(data, "abcdef", 6);
  free(data);
  assert_int_equal(gi__read_file(p, 5, &data, &size, &err), GI_ERR_LIMIT);
  assert_null(data);
  assert_int_equal(gi__read_file("/nonexistent/x.png", 100, &data, &size, &err), GI_ERR_NOT_FOUND);
  assert_int_equal(gi__read_file(tu_tmpdir(), 100, &data, &size, &err), GI_ERR_IO);
}

/* --- scene import ----------------------------------------------------- */

static const char tri_obj_head[] = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\n";

static gi_scene *load_ok(const char *path) {
  gi_scene *s = NULL;
  gi_error_info err = {0};
  gi_result r = gi_scene_load(path, NULL, &s, &err);
  if (r != GI_OK) fail_msg("load %s: %s", path, err.msg);
  return s;
}

static const gi_material *find_mat(const gi_scene *s, const char *name) {
  for (size_t i = 0; i < gi_scene_num_materials(s); i++)
    if (strcmp(gi_scene_material(s, i)->name, name) == 0) return gi_scene_material(s, i);
  fail_msg("no material '%s'", name);
  return NULL;
}

static void assert_albedo(const gi_material *m, double r, double g, double b) {
  assert_float_equal(m->albedo[0], r, 1e-4);
  assert_float_equal(m->albedo[1], g, 1e-4);
  assert_float_equal(m->albedo[2], b, 1e-4);
}

static void test_obj_map_kd(void **state) {
  unsigned char rgba[64];
  half_red_half_grey(rgba);
  png_file("tex.png", rgba, 4, 4);
  /* The same texture under a sub-folder, named with a backslash. */
  char sub[4096];
  snprintf(sub, sizeof sub, "%s/sub", tu_tmpdir());
  mkdir(sub, 0755);
  png_file("sub/tex2.png", rgba, 4, 4);
  static unsigned char px[8 * 8 * 3];
  for (int i = 0; i < 64; i++) px[3 * i] = 200, px[3 * i + 1] = 100, px[3 * i + 2] = 50;
  size_t jn;
  void *jpg = jpeg_mem(px, 8, 8, 3, &jn);
  tu_write_file("tex.jpg", jpg, jn);
  free(jpg);
  const char mtl[] =
      "newmtl half\nKd 0.5 0.5 0.5\nmap_Kd tex.png\n"
      "newmtl maponly\nmap_Kd tex.png\n"
      "newmtl sixty\nKd 0.6 0.6 0.6\nmap_Kd sub\\tex2.png\n"
      "newmtl jpeg\nKd 1 0.5 0.25\nmap_Kd tex.jpg\n"
      "newmtl plain\nKd 0.3 0.2 0.1\n"
      "newmtl abs\nKd 1 1 1\nmap_Kd C:\\art\\tex.png\n";
  tu_write_file("tex.mtl", mtl, strlen(mtl));
  char obj[1024];
  snprintf(obj, sizeof obj,
           "mtllib tex.mtl\n%s"
           "usemtl half\nf 1/1 2/2 3/3\nusemtl maponly\nf 1/1 2/2 3/3\nusemtl sixty\nf 1/1 2/2 3/3\n"
           "usemtl jpeg\nf 1/1 2/2 3/3\nusemtl plain\nf 1/1 2/2 3/3\nusemtl abs\nf 1/1 2/2 3/3\n",
           tri_obj_head);
  gi_scene *s = load_ok(tu_write_file("tex.obj", obj, strlen(obj)));
  assert_albedo(find_mat(s, "half"), 0.5 * HALF_RED_R, 0.5 * HALF_RED_GB, 0.5 * HALF_RED_GB);
  /* assimp reports Kd 0.6 when the MTL has none; map_Kd alone means factor 1. */
  assert_albedo(find_mat(s, "maponly"), HALF_RED_R, HALF_RED_GB, HALF_RED_GB);
  /* An explicit Kd 0.6 is kept. */
  assert_albedo(find_mat(s, "sixty"), 0.6 * HALF_RED_R, 0.6 * HALF_RED_GB, 0.6 * HALF_RED_GB);
  const gi_material *j = find_mat(s, "jpeg");
  assert_true(fabs(j->albedo[0] - lin(200)) <= lin(201) - lin(200));
  assert_true(fabs(j->albedo[1] - 0.5 * lin(100)) <= 0.5 * (lin(101) - lin(100)));
  assert_true(fabs(j->albedo[2] - 0.25 * lin(50)) <= 0.25 * (lin(51) - lin(50)));
  assert_albedo(find_mat(s, "plain"), 0.3, 0.2, 0.1);
  /* An exporter's absolute path: found by its file name next to the scene. */
  assert_albedo(find_mat(s, "abs"), HALF_RED_R, HALF_RED_GB, HALF_RED_GB);
  gi_scene_stats st;
  gi_scene_get_stats(s, &st);
  assert_int_equal(st.textures_unreadable, 0);
  gi_scene_release(s);
}

/* An MTL Blender wrote is its Principled material: map_Kd replaces the
 * Kd 0.8 Blender writes beside it (its importer reads it so; the texture
 * read 20% dark against the same glTF), Ns = 1000 (1 - roughness)^2 and Ks
 * its specular level (reflectance 0.08 Ks). The same MTL from another
 * tool keeps the format's rules: Kd times the texture, Blinn-Phong. */
static void test_blender_mtl(void **state) {
  (void)state;
  unsigned char rgba[64];
  half_red_half_grey(rgba);
  png_file("btex.png", rgba, 4, 4);
  const char body[] = "newmtl tex\nNs 250.000000\nKa 1.000000 1.000000 1.000000\nKd 0.800000 0.800000 0.800000\n"
                      "Ks 0.500000 0.500000 0.500000\nNi 1.450000\nd 1.000000\nillum 2\nmap_Kd btex.png\n"
                      "newmtl shiny\nNs 640.000000\nKd 0.6 0.5 0.4\nKs 0.5 0.5 0.5\nillum 2\n";
  for (int blender = 0; blender < 2; blender++) {
    char mtl[1024], obj[512], name[32];
    snprintf(mtl, sizeof mtl, "%s%s", blender ? "# Blender MTL File: 'None'\n# Material Count: 2\n\n" : "", body);
    snprintf(name, sizeof name, "b%d.mtl", blender);
    tu_write_file(name, mtl, strlen(mtl));
    snprintf(obj, sizeof obj, "mtllib b%d.mtl\n%susemtl tex\nf 1/1 2/2 3/3\nusemtl shiny\nf 1/1 2/2 3/3\n", blender,
             tri_obj_head);
    snprintf(name, sizeof name, "b%d.obj", blender);
    gi_scene *s = load_ok(tu_write_file(name, obj, strlen(obj)));
    const gi_material *t = find_mat(s, "tex"), *sh = find_mat(s, "shiny");
    printf("  %s: tex albedo %.4f roughness %.4f specular %.4f; shiny roughness %.4f specular %.4f\n",
           blender ? "Blender's MTL" : "another MTL", t->albedo[0], t->roughness, t->specular, sh->roughness,
           sh->specular);
    double k = blender ? 1.0 : 0.8;
    assert_albedo(t, k * HALF_RED_R, k * HALF_RED_GB, k * HALF_RED_GB);
    if (blender) {
      assert_float_equal(t->roughness, 1 - sqrt(0.25), 1e-5);
      assert_float_equal(sh->roughness, 1 - sqrt(0.64), 1e-5);
      assert_float_equal(t->specular, 0.04, 1e-6);
      assert_float_equal(sh->specular, 0.04, 1e-6);
    } else {
      assert_float_equal(t->roughness, sqrt(2.0 / 252.0), 1e-5);
      assert_float_equal(sh->roughness, sqrt(2.0 / 642.0), 1e-5);
      assert_float_equal(t->specular, 0.5 * 8.0 / 258.0, 1e-6);
      assert_float_equal(sh->specular, 0.5 * 8.0 / 648.0, 1e-6);
    }
    gi_scene_release(s);
  }
}

/* An FBX texture connected to the diffuse colour takes the colour's place
 * (Blender writes its unused default 0.8 there: the texture read 20% dark
 * against the same glTF). */
static void test_fbx_texture_replaces_colour(void **state) {
  (void)state;
  unsigned char rgba[64];
  half_red_half_grey(rgba);
  png_file("ftex.png", rgba, 4, 4);
  const char fbx[] =
      "; FBX 7.4.0 project file\nFBXHeaderExtension:  {\n\tFBXHeaderVersion: 1003\n\tFBXVersion: 7400\n}\n"
      "Objects:  {\n\tGeometry: 100, \"Geometry::q\", \"Mesh\" {\n\t\tVertices: *9 {\n\t\t\ta: 0,0,0,100,0,0,0,100,0\n"
      "\t\t}\n\t\tPolygonVertexIndex: *3 {\n\t\t\ta: 0,1,-3\n\t\t}\n"
      "\t\tLayerElementMaterial: 0 {\n\t\t\tVersion: 101\n\t\t\tName: \"\"\n\t\t\tMappingInformationType: \"AllSame\"\n"
      "\t\t\tReferenceInformationType: \"IndexToDirect\"\n\t\t\tMaterials: *1 {\n\t\t\t\ta: 0\n\t\t\t}\n\t\t}\n"
      "\t\tLayer: 0 {\n\t\t\tVersion: 100\n\t\t\tLayerElement:  {\n\t\t\t\tType: \"LayerElementMaterial\"\n"
      "\t\t\t\tTypedIndex: 0\n\t\t\t}\n\t\t}\n\t}\n"
      "\tModel: 200, \"Model::q\", \"Mesh\" {\n\t}\n"
      "\tMaterial: 300, \"Material::tex\", \"\" {\n\t\tShadingModel: \"lambert\"\n\t\tProperties70:  {\n"
      "\t\t\tP: \"DiffuseColor\", \"Color\", \"\", \"A\",0.8,0.8,0.8\n\t\t}\n\t}\n"
      "\tTexture: 400, \"Texture::ftex\", \"\" {\n\t\tType: \"TextureVideoClip\"\n\t\tFileName: \"ftex.png\"\n"
      "\t\tRelativeFilename: \"ftex.png\"\n\t}\n}\n"
      "Connections:  {\n\tC: \"OO\",100,200\n\tC: \"OO\",200,0\n\tC: \"OO\",300,200\n"
      "\tC: \"OP\",400,300,\"DiffuseColor\"\n}\n";
  gi_scene *s = load_ok(tu_write_file("ftex.fbx", fbx, strlen(fbx)));
  const gi_material *m = find_mat(s, "tex");
  printf("  FBX texture on a diffuse colour of 0.8: albedo %.4f %.4f %.4f\n", m->albedo[0], m->albedo[1],
         m->albedo[2]);
  assert_albedo(m, HALF_RED_R, HALF_RED_GB, HALF_RED_GB);
  gi_scene_stats st;
  gi_scene_get_stats(s, &st);
  assert_int_equal(st.textures_unreadable, 0);
  gi_scene_release(s);
}

static void test_obj_bad_textures(void **state) {
  const char corrupt[] = "\x89PNG\r\n\x1a\n\0\0\0\rIHDR garbage garbage";
  tu_write_file("corrupt.png", corrupt, sizeof corrupt - 1);
  const char mtl[] =
      "newmtl missing\nKd 0.5 0.25 0.125\nmap_Kd does_not_exist.png\n"
      "newmtl missing2\nKd 0.1 0.2 0.3\nmap_Kd does_not_exist.png\n"
      "newmtl corrupt\nKd 0.7 0.7 0.7\nmap_Kd corrupt.png\n";
  tu_write_file("bad.mtl", mtl, strlen(mtl));
  char obj[1024];
  snprintf(obj, sizeof obj,
           "mtllib bad.mtl\n%susemtl missing\nf 1/1 2/2 3/3\nusemtl missing2\nf 1/1 2/2 3/3\n"
           "usemtl corrupt\nf 1/1 2/2 3/3\n",
           tri_obj_head);
  gi_scene *s = load_ok(tu_write_file("bad.obj", obj, strlen(obj)));
  assert_albedo(find_mat(s, "missing"), 0.5, 0.25, 0.125);
  assert_albedo(find_mat(s, "missing2"), 0.1, 0.2, 0.3);
  assert_albedo(find_mat(s, "corrupt"), 0.7, 0.7, 0.7);
  gi_scene_stats st;
  gi_scene_get_stats(s, &st);
  assert_int_equal(st.textures_unreadable, 2); /* distinct textures: one missing (used twice), one corrupt */
  gi_scene_release(s);

  /* Only a missing texture: exactly one. */
  const char mtl1[] = "newmtl m\nKd 0.5 0.5 0.5\nmap_Kd nowhere.png\n";
  tu_write_file("one.mtl", mtl1, strlen(mtl1));
  snprintf(obj, sizeof obj, "mtllib one.mtl\n%susemtl m\nf 1/1 2/2 3/3\n", tri_obj_head);
  s = load_ok(tu_write_file("one.obj", obj, strlen(obj)));
  assert_albedo(find_mat(s, "m"), 0.5, 0.5, 0.5);
  gi_scene_get_stats(s, &st);
  assert_int_equal(st.textures_unreadable, 1);
  gi_scene_release(s);
}

static const char b64[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";

static char *base64(const unsigned char *d, size_t n) {
  char *o = malloc(4 * ((n + 2) / 3) + 1), *p = o;
  for (size_t i = 0; i < n; i += 3) {
    uint32_t v = (uint32_t)d[i] << 16 | (i + 1 < n ? (uint32_t)d[i + 1] << 8 : 0) | (i + 2 < n ? d[i + 2] : 0);
    *p++ = b64[v >> 18 & 63];
    *p++ = b64[v >> 12 & 63];
    *p++ = i + 1 < n ? b64[v >> 6 & 63] : '=';
    *p++ = i + 2 < n ? b64[v & 63] : '=';
  }
  *p = 0;
  return o;
}

/* One triangle with UVs; image_uri is the glTF image's uri. */
static char *gltf_doc(const char *image_uri) {
  /* positions (36 bytes), uvs (24), indices (6 + 2 pad) */
  static const char geometry[] =
      "AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAAAAAAAAAAAAAAAIA/AAAAAAAAAAAAAIA/AAABAAIAAAA=";
  const char *fmt =
      "{\"asset\":{\"version\":\"2.0\"},\"scene\":0,\"scenes\":[{\"nodes\":[0]}],\"nodes\":[{\"mesh\":0}],"
      "\"meshes\":[{\"primitives\":[{\"attributes\":{\"POSITION\":0,\"TEXCOORD_0\":1},\"indices\":2,\"material\":0}]}],"
      "\"materials\":[{\"name\":\"textured\",\"pbrMetallicRoughness\":{\"baseColorFactor\":[0.5,0.25,1,1],"
      "\"baseColorTexture\":{\"index\":0},\"metallicFactor\":0,\"roughnessFactor\":1}}],"
      "\"textures\":[{\"source\":0}],\"images\":[{\"uri\":\"%s\"}],"
      "\"buffers\":[{\"byteLength\":68,\"uri\":\"data:application/octet-stream;base64,%s\"}],"
      "\"bufferViews\":[{\"buffer\":0,\"byteOffset\":0,\"byteLength\":36},"
      "{\"buffer\":0,\"byteOffset\":36,\"byteLength\":24},{\"buffer\":0,\"byteOffset\":60,\"byteLength\":6}],"
      "\"accessors\":[{\"bufferView\":0,\"componentType\":5126,\"count\":3,\"type\":\"VEC3\","
      "\"min\":[0,0,0],\"max\":[1,1,0]},{\"bufferView\":1,\"componentType\":5126,\"count\":3,\"type\":\"VEC2\"},"
      "{\"bufferView\":2,\"componentType\":5123,\"count\":3,\"type\":\"SCALAR\"}]}";
  size_t n = strlen(fmt) + strlen(image_uri) + sizeof geometry + 1;
  char *doc = malloc(n);
  snprintf(doc, n, fmt, image_uri, geometry);
  return doc;
}

static void test_gltf_base_color_texture(void **state) {
  unsigned char rgba[64];
  half_red_half_grey(rgba);
  size_t n;
  void *png = png_mem(rgba, 4, 4, PNG_FORMAT_RGBA, NULL, 0, &n);
  char *enc = base64(png, n);
  char *uri = malloc(strlen(enc) + 32);
  sprintf(uri, "data:image/png;base64,%s", enc);
  /* Embedded (data URI). */
  char *doc = gltf_doc(uri);
  gi_scene *s = load_ok(tu_write_file("embedded.gltf", doc, strlen(doc)));
  assert_albedo(find_mat(s, "textured"), 0.5 * HALF_RED_R, 0.25 * HALF_RED_GB, 1.0 * HALF_RED_GB);
  gi_scene_stats st;
  gi_scene_get_stats(s, &st);
  assert_int_equal(st.textures_unreadable, 0);
  gi_scene_release(s);
  free(doc);
  /* External file next to the .gltf. */
  tu_write_file("gltf_tex.png", png, n);
  doc = gltf_doc("gltf_tex.png");
  s = load_ok(tu_write_file("external.gltf", doc, strlen(doc)));
  assert_albedo(find_mat(s, "textured"), 0.5 * HALF_RED_R, 0.25 * HALF_RED_GB, 1.0 * HALF_RED_GB);
  gi_scene_release(s);
  free(doc);
  /* External and missing: the factor alone. */
  doc = gltf_doc("gltf_missing.png");
  s = load_ok(tu_write_file("missing.gltf", doc, strlen(doc)));
  assert_albedo(find_mat(s, "textured"), 0.5, 0.25, 1.0);
  gi_scene_get_stats(s, &st);
  assert_int_equal(st.textures_unreadable, 1);
  gi_scene_release(s);
  free(doc);
  free(uri);
  free(enc);
  free(png);
}

/* --- per-triangle textures ------------------------------------------- */

/* A triangle's mean over a 4 x 4 checker (red and blue cells) against a
 * dense reference (400 x 400 points over it, each reading its cell): one
 * point per four cells read Blender's checker floor all red from one
 * format and all blue from another, where each half holds both colours. */
static void test_texture_grid_checker(void **state) {
  (void)state;
  unsigned char rgba[64];
  for (int y = 0; y < 4; y++)
    for (int x = 0; x < 4; x++) {
      unsigned char *p = &rgba[4 * (4 * y + x)];
      int red = (x + y) % 2;
      p[0] = red ? 255 : 0, p[1] = 0, p[2] = red ? 0 : 255, p[3] = 255;
    }
  size_t n;
  void *png = png_mem(rgba, 4, 4, PNG_FORMAT_RGBA, NULL, 0, &n);
  float rgb[3];
  gi__tex_grid g = {0};
  gi_error_info err = {0};
  assert_int_equal(gi__image_average_grid(png, n, "checker.png", rgb, &g, &err), GI_OK);
  const float tris[3][3][2] = {{{0, 0}, {1, 0}, {0, 1}}, {{1, 0}, {1, 1}, {0, 1}}, {{0.1f, 0.05f}, {0.9f, 0.3f}, {0.3f, 0.95f}}};
  for (int t = 0; t < 3; t++) {
    float got[3];
    gi__tex_grid_triangle(&g, tris[t], got);
    double want = 0; /* the red share, densely */
    int count = 0;
    const int N = 400;
    for (int i = 0; i < N; i++)
      for (int j = 0; i + j < N; j++) {
        double a = (i + 1.0 / 3) / N, b = (j + 1.0 / 3) / N, c = 1 - a - b;
        double u = a * tris[t][0][0] + b * tris[t][1][0] + c * tris[t][2][0];
        double v = a * tris[t][0][1] + b * tris[t][1][1] + c * tris[t][2][1];
        int x = (int)(u * 4), y = (int)((1 - v) * 4);
        x = x > 3 ? 3 : x, y = y > 3 ? 3 : y;
        want += (x + y) % 2, count++;
      }
    want /= count;
    printf("  checker triangle %d: red %.3f blue %.3f (dense: red share %.3f)\n", t, got[0], got[2], want);
    assert_float_equal(got[0], want, 0.03);
    assert_float_equal(got[2], 1 - want, 0.03);
  }
  gi__tex_grid_free(&g);
  free(png);
}

/* The grid of the 4x4 half-red, half-grey image: its top two rows red,
 * the rest grey, linear; a triangle over each half reads that half; an
 * interlaced PNG keeps no grid (its passes are not rows). */
static void test_texture_grid(void **state) {
  (void)state;
  unsigned char rgba[64];
  half_red_half_grey(rgba);
  size_t n;
  void *png = png_mem(rgba, 4, 4, PNG_FORMAT_RGBA, NULL, 0, &n);
  float rgb[3];
  gi__tex_grid g = {0};
  gi_error_info err = {0};
  assert_int_equal(gi__image_average_grid(png, n, "grid.png", rgb, &g, &err), GI_OK);
  assert_int_equal(g.w, 4);
  assert_int_equal(g.h, 4);
  for (int y = 0; y < 4; y++)
    for (int x = 0; x < 4; x++) {
      const float *c = &g.rgb[3 * (4 * y + x)];
      assert_float_equal(c[0], y < 2 ? 1.0 : GREY128, 1e-6);
      assert_float_equal(c[1], y < 2 ? 0.0 : GREY128, 1e-6);
    }
  /* v runs up: v in [0.6, 1] is the image's top (red), [0, 0.4] its bottom. */
  const float top[3][2] = {{0, 0.6f}, {1, 0.6f}, {0, 1}}, bottom[3][2] = {{0, 0}, {1, 0}, {0, 0.4f}};
  /* Repeating: the same top half one tile over. */
  const float tiled[3][2] = {{3, 1.6f}, {4, 1.6f}, {3, 2}};
  float t[3], b[3], r[3];
  gi__tex_grid_triangle(&g, top, t);
  gi__tex_grid_triangle(&g, bottom, b);
  gi__tex_grid_triangle(&g, tiled, r);
  printf("top %g %g %g, bottom %g %g %g\n", t[0], t[1], t[2], b[0], b[1], b[2]);
  assert_float_equal(t[0], 1.0, 1e-6);
  assert_float_equal(t[1], 0.0, 1e-6);
  assert_float_equal(b[0], GREY128, 1e-6);
  assert_memory_equal(t, r, sizeof t);
  /* A malformed file's coordinates read some cell, never outside the grid. */
  const float bad[3][2] = {{NAN, 0.7f}, {INFINITY, 1e30f}, {-1e30f, -INFINITY}};
  gi__tex_grid_triangle(&g, bad, r);
  for (int k = 0; k < 3; k++) assert_true(r[k] >= 0 && r[k] <= 1);
  gi__tex_grid_free(&g);
  free(png);
  /* JPEG and raw texels fill their grids too. */
  static unsigned char px[8 * 8 * 3];
  for (int i = 0; i < 64; i++) px[3 * i] = 200, px[3 * i + 1] = 100, px[3 * i + 2] = 50;
  void *jpg = jpeg_mem(px, 8, 8, 3, &n);
  assert_int_equal(gi__image_average_grid(jpg, n, "grid.jpg", rgb, &g, &err), GI_OK);
  assert_int_equal(g.w * g.h, 64);
  for (int i = 0; i < 64; i++) assert_true(fabs(g.rgb[3 * i] - lin(200)) <= lin(201) - lin(200));
  gi__tex_grid_free(&g);
  free(jpg);
  const unsigned char bgra[8] = {0, 0, 255, 255, 255, 0, 0, 255}; /* red, then blue */
  assert_int_equal(gi__texels_average_grid(bgra, 2, 1, "raw", rgb, &g, &err), GI_OK);
  assert_true(g.w == 2 && g.h == 1 && g.rgb[0] == 1.f && g.rgb[2] == 0.f && g.rgb[3] == 0.f && g.rgb[5] == 1.f);
  gi__tex_grid_free(&g);
  /* Interlaced: the average, no grid. */
  unsigned char rgb8[48];
  for (int i = 0; i < 16; i++) memcpy(rgb8 + 3 * i, rgba + 4 * i, 3);
  png = png_mem_rgb(rgb8, 4, 4, 1, &n);
  assert_int_equal(gi__image_average_grid(png, n, "il.png", rgb, &g, &err), GI_OK);
  assert_int_equal(g.w, 0);
  assert_null(g.rgb);
  free(png);
}

/* An OBJ whose one textured material covers two triangles, one on each
 * half of the image: each takes its own half times the factor, where the
 * material (and a triangle without vt) keeps the whole image's average. */
static void test_obj_texture_per_triangle(void **state) {
  (void)state;
  unsigned char rgba[64];
  half_red_half_grey(rgba);
  png_file("halves.png", rgba, 4, 4);
  const char mtl[] = "newmtl halves\nKd 0.5 0.5 0.5\nmap_Kd halves.png\n";
  tu_write_file("halves.mtl", mtl, strlen(mtl));
  const char obj[] = "mtllib halves.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\n"
                     "vt 0 0.6\nvt 1 0.6\nvt 0 1\nvt 0 0\nvt 1 0\nvt 0 0.4\n"
                     "usemtl halves\nf 1/1 2/2 3/3\nf 1/4 2/5 3/6\nf 1 2 3\n";
  gi_scene *s = load_ok(tu_write_file("halves.obj", obj, strlen(obj)));
  gi_material tm;
  const float *top = gi__tri_material(s, 0, &tm)->albedo;
  printf("top triangle %g %g %g\n", top[0], top[1], top[2]);
  assert_float_equal(top[0], 0.5, 1e-6);
  assert_float_equal(top[1], 0.0, 1e-6);
  const float *bottom = gi__tri_material(s, 1, &tm)->albedo;
  assert_float_equal(bottom[0], 0.5 * GREY128, 1e-6);
  assert_float_equal(bottom[2], 0.5 * GREY128, 1e-6);
  const float *plain = gi__tri_material(s, 2, &tm)->albedo;
  assert_float_equal(plain[0], 0.5 * HALF_RED_R, 1e-4);
  assert_albedo(find_mat(s, "halves"), 0.5 * HALF_RED_R, 0.5 * HALF_RED_GB, 0.5 * HALF_RED_GB);
  gi_scene_release(s);
}

/* A glTF of one triangle with texture coordinates uv over the half-red
 * image, its base-colour texture carrying KHR_texture_transform `tf` (a
 * JSON object's members; NULL: no extension); returns the triangle's albedo. */
static void gltf_sampled(const char *name, const float uv[6], const char *tf, const char *sampler, float out[3]);

static void gltf_transformed(const char *name, const float uv[6], const char *tf, float out[3]) {
  gltf_sampled(name, uv, tf, NULL, out);
}

/* The same with the texture's sampler (a JSON object's members; NULL: none). */
static void gltf_sampled(const char *name, const float uv[6], const char *tf, const char *sampler, float out[3]) {
  unsigned char rgba[64];
  half_red_half_grey(rgba);
  size_t n;
  void *png = png_mem(rgba, 4, 4, PNG_FORMAT_RGBA, NULL, 0, &n);
  tu_write_file("tf_halves.png", png, n);
  free(png);
  unsigned char buf[68] = {0};
  const float pos[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  const uint16_t idx[3] = {0, 1, 2};
  memcpy(buf, pos, 36), memcpy(buf + 36, uv, 24), memcpy(buf + 60, idx, 6);
  char *geo = base64(buf, sizeof buf), *doc = gltf_doc("tf_halves.png");
  static const char old[] =
      "AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAAAAAAAAAAAAAAAIA/AAAAAAAAAAAAAIA/AAABAAIAAAA=";
  char *at = strstr(doc, old);
  assert_non_null(at);
  memcpy(at, geo, strlen(geo));
  static const char bct[] = "\"baseColorTexture\":{\"index\":0}";
  char *b = strstr(doc, bct), full[4096];
  assert_non_null(b);
  if (tf)
    snprintf(full, sizeof full,
             "%.*s\"baseColorTexture\":{\"index\":0,\"extensions\":{\"KHR_texture_transform\":{%s}}}%s",
             (int)(b - doc), doc, tf, b + strlen(bct));
  else
    snprintf(full, sizeof full, "%s", doc);
  static const char tex[] = "\"textures\":[{\"source\":0}]";
  char *t = strstr(full, tex), with[4096];
  assert_non_null(t);
  if (sampler) {
    snprintf(with, sizeof with, "%.*s\"samplers\":[{%s}],\"textures\":[{\"source\":0,\"sampler\":0}]%s",
             (int)(t - full), full, sampler, t + strlen(tex));
    memcpy(full, with, strlen(with) + 1);
  }
  gi_scene *s = load_ok(tu_write_file(name, full, strlen(full)));
  gi_material tm;
  memcpy(out, gi__tri_material(s, 0, &tm)->albedo, 3 * sizeof(float));
  printf("%s: %s -> %g %g %g\n", name, tf ? tf : "(none)", out[0], out[1], out[2]);
  gi_scene_release(s);
  free(doc);
  free(geo);
}

/* glTF's texture coordinates run down from the image's top: a triangle
 * over v in [0, 0.4] reads the red top half (assimp turns v up, the grid
 * turns it back). */
static void test_gltf_texture_per_triangle(void **state) {
  (void)state;
  const float uv[6] = {0, 0, 1, 0, 0, 0.4f};
  float a[3];
  gltf_transformed("halves.gltf", uv, NULL, a);
  assert_float_equal(a[0], 0.5, 1e-6); /* factor 0.5 x red */
  assert_float_equal(a[1], 0.0, 1e-6);
}

/* KHR_texture_transform moves a triangle's coordinates before it reads the
 * texture (an atlas packer's offset and scale; assimp 5.2 only records
 * it): the triangle over v in [0, 0.4] (red without a transform) reads grey
 * offset by 0.5 in v, or scaled 0.5 in u with the offset; a quarter turn
 * (the extension's reference shader: u' = u cos - v sin, v' = u sin + v cos)
 * takes a triangle at u in [0, 0.4], v in [0.6, 1] (grey as it is) to
 * v' = u, the red top; texCoord 1 names a set the file lacks: no texture. */
static void test_gltf_texture_transform(void **state) {
  (void)state;
  const float top[6] = {0, 0, 1, 0, 0, 0.4f}, side[6] = {0, 0.6f, 0.4f, 0.6f, 0, 1};
  float a[3];
  gltf_transformed("tf0.gltf", top, "", a);
  assert_float_equal(a[0], 0.5, 1e-6), assert_float_equal(a[1], 0.0, 1e-6);
  gltf_transformed("tf1.gltf", top, "\"offset\":[0,0.5]", a);
  assert_float_equal(a[0], 0.5 * GREY128, 1e-6), assert_float_equal(a[2], GREY128, 1e-6);
  gltf_transformed("tf2.gltf", top, "\"offset\":[0.25,0.5],\"scale\":[0.5,1]", a);
  assert_float_equal(a[0], 0.5 * GREY128, 1e-6);
  gltf_transformed("tf3.gltf", side, "", a);
  assert_float_equal(a[0], 0.5 * GREY128, 1e-6);
  gltf_transformed("tf4.gltf", side, "\"rotation\":1.5707963267948966", a);
  assert_float_equal(a[0], 0.5, 1e-5), assert_float_equal(a[1], 0.0, 1e-5);
  gltf_transformed("tf5.gltf", top, "\"texCoord\":1", a); /* the material's average */
  assert_float_equal(a[0], 0.5 * HALF_RED_R, 1e-4);
}

/* glTF's sampler wrap modes: coordinates past the image repeat
 * (REPEAT, the default), hold at its edge (CLAMP_TO_EDGE) or repeat
 * mirrored (MIRRORED_REPEAT). All read as repeating before: a triangle at
 * v in [1.1, 1.4] (glTF's v runs down: the red top, repeated) reads the
 * grey bottom row clamped and the grey [0.6, 0.9] mirrored; one at v in
 * [1.6, 1.9] reads grey repeated and clamped, red mirrored. */
static void test_gltf_sampler_wrap(void **state) {
  (void)state;
  const float near[6] = {0, 1.1f, 1, 1.1f, 0, 1.4f}, far[6] = {0, 1.6f, 1, 1.6f, 0, 1.9f};
  static const char *const wraps[3] = {"\"wrapS\":10497,\"wrapT\":10497", "\"wrapS\":33071,\"wrapT\":33071",
                                       "\"wrapS\":33648,\"wrapT\":33648"};
  const double red = 0.5, grey = 0.5 * GREY128; /* the factor's red channel, 0.5, times the texture's */
  const double want_near[3] = {red, grey, grey}, want_far[3] = {grey, grey, red};
  for (int i = 0; i < 3; i++) {
    float a[3], b[3];
    gltf_sampled("wrap_near.gltf", near, NULL, wraps[i], a);
    gltf_sampled("wrap_far.gltf", far, NULL, wraps[i], b);
    assert_float_equal(a[0], want_near[i], 1e-5);
    assert_float_equal(b[0], want_far[i], 1e-5);
  }
  /* Each axis its own: wrapT is v's (mirrored: red), wrapS u's. */
  float c[3];
  gltf_sampled("wrap_st.gltf", far, NULL, "\"wrapS\":33071,\"wrapT\":33648", c);
  assert_float_equal(c[0], red, 1e-5);
  gltf_sampled("wrap_ts.gltf", far, NULL, "\"wrapS\":33648,\"wrapT\":33071", c);
  assert_float_equal(c[0], grey, 1e-5);
}

/* An emissive texture multiplies the emission by its average (glTF's
 * emissiveTexture, an MTL's map_Ke): a facade lit at its windows emits
 * that share, not all over. */
static void test_emissive_texture(void **state) {
  (void)state;
  unsigned char rgba[64];
  half_red_half_grey(rgba);
  png_file("glow.png", rgba, 4, 4);
  const char mtl[] = "newmtl glow\nKd 0.5 0.5 0.5\nKe 2 2 2\nmap_Ke glow.png\nnewmtl flat\nKe 2 2 2\n";
  tu_write_file("glow.mtl", mtl, strlen(mtl));
  char obj[512];
  snprintf(obj, sizeof obj, "mtllib glow.mtl\n%susemtl glow\nf 1/1 2/2 3/3\nusemtl flat\nf 1/1 2/2 3/3\n", tri_obj_head);
  gi_scene *s = load_ok(tu_write_file("glow.obj", obj, strlen(obj)));
  const gi_material *g = find_mat(s, "glow"), *f = find_mat(s, "flat");
  printf("map_Ke: emission %g %g %g (want %g %g %g)\n", g->emission[0], g->emission[1], g->emission[2],
         2 * HALF_RED_R, 2 * HALF_RED_GB, 2 * HALF_RED_GB);
  assert_float_equal(g->emission[0], 2 * HALF_RED_R, 1e-4);
  assert_float_equal(g->emission[1], 2 * HALF_RED_GB, 1e-4);
  assert_float_equal(f->emission[0], 2.0, 1e-6);
  assert_albedo(g, 0.5, 0.5, 0.5); /* map_Ke is not a diffuse texture */
  gi_scene_release(s);
  /* glTF: emissiveFactor x emissiveTexture; the base colour stays the factor. */
  char *doc = gltf_doc("glow.png");
  static const char bct[] = "\"baseColorTexture\":{\"index\":0},";
  char *at = strstr(doc, bct);
  assert_non_null(at);
  memmove(at, at + strlen(bct), strlen(at + strlen(bct)) + 1);
  static const char name[] = "\"name\":\"textured\",";
  static const char emit[] = "\"emissiveFactor\":[1,0.5,1],\"emissiveTexture\":{\"index\":0},";
  char *doc2 = malloc(strlen(doc) + sizeof emit);
  at = strstr(doc, name);
  assert_non_null(at);
  size_t head = (size_t)(at - doc) + strlen(name);
  memcpy(doc2, doc, head);
  strcpy(doc2 + head, emit);
  strcat(doc2, doc + head);
  s = load_ok(tu_write_file("glow.gltf", doc2, strlen(doc2)));
  g = find_mat(s, "textured");
  assert_float_equal(g->emission[0], HALF_RED_R, 1e-4);
  assert_float_equal(g->emission[1], 0.5 * HALF_RED_GB, 1e-4);
  assert_albedo(g, 0.5, 0.25, 1.0);
  gi_scene_release(s);
  free(doc2);
  free(doc);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_png_average),
      cmocka_unit_test(test_png_interlaced),
      cmocka_unit_test(test_jpeg_average),
      cmocka_unit_test(test_texels_average),
      cmocka_unit_test(test_corrupt_images),
      cmocka_unit_test(test_size_limits),
      cmocka_unit_test(test_read_file),
      cmocka_unit_test(test_obj_map_kd),
      cmocka_unit_test(test_blender_mtl),
      cmocka_unit_test(test_fbx_texture_replaces_colour),
      cmocka_unit_test(test_obj_bad_textures),
      cmocka_unit_test(test_gltf_base_color_texture),
      cmocka_unit_test(test_texture_grid),
      cmocka_unit_test(test_texture_grid_checker),
      cmocka_unit_test(test_obj_texture_per_triangle),
      cmocka_unit_test(test_gltf_texture_per_triangle),
      cmocka_unit_test(test_gltf_texture_transform),
      cmocka_unit_test(test_gltf_sampler_wrap),
      cmocka_unit_test(test_emissive_texture),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
