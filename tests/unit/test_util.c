#define _XOPEN_SOURCE 700 /* nftw under -std=c11 */
#define _DEFAULT_SOURCE  /* on_exit */
#include "test_util.h"
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <ftw.h>
#include <sys/wait.h>
#include <unistd.h>
#include "gi/gi.h"

const char *tu_scene_path(const char *rel) {
  static char buf[4096];
  snprintf(buf, sizeof buf, "%s/%s", GI_SCENES_DIR, rel);
  if (access(buf, R_OK) != 0) {
    fprintf(stderr, "SKIP: shared scene %s is absent (looked in %s)\n", rel, GI_SCENES_DIR);
    return NULL;
  }
  return buf;
}

static char tmp_dir[256];
static pid_t tmp_owner;

static int remove_entry(const char *path, const struct stat *st, int flag, struct FTW *ftw) {
  (void)st, (void)flag, (void)ftw;
  if (remove(path) != 0) perror(path);
  return 0;
}

/* At the test binary's exit: every run left its folder behind (a thousand
 * of them in /tmp after a day's work). A failed run keeps it (cmocka's
 * main returns the failures: a server's log there shows what went wrong).
 * A forked child that returns through exit() must not remove its parent's
 * files. */
static void tmpdir_cleanup(int status, void *arg) {
  (void)arg;
  if (getpid() != tmp_owner) return;
  if (status != 0 || getenv("GI_KEEP_TEST_TMP")) {
    fprintf(stderr, "test files kept in %s (%s)\n", tmp_dir, status ? "the run failed" : "GI_KEEP_TEST_TMP");
    return;
  }
  nftw(tmp_dir, remove_entry, 16, FTW_DEPTH | FTW_PHYS);
}

const char *tu_tmpdir(void) {
  if (!tmp_dir[0]) {
    snprintf(tmp_dir, sizeof tmp_dir, "/tmp/gi-test-XXXXXX");
    if (!mkdtemp(tmp_dir)) { perror("mkdtemp"); abort(); }
    tmp_owner = getpid();
    on_exit(tmpdir_cleanup, NULL);
  }
  return tmp_dir;
}

const char *tu_write_file(const char *name, const void *data, size_t len) {
  static char bufs[8][4096];
  static int next;
  char *p = bufs[next++ & 7];
  snprintf(p, 4096, "%s/%s", tu_tmpdir(), name);
  FILE *f = fopen(p, "wb");
  if (!f) { perror(p); abort(); }
  if (len && fwrite(data, 1, len, f) != len) abort();
  fclose(f);
  return p;
}

const char *tu_run(const char *cmd, int *status) {
  static char out[65536];
  size_t n = 0;
  FILE *p = popen(cmd, "r");
  if (!p) {
    *status = -1;
    out[0] = 0;
    return out;
  }
  while (n + 1 < sizeof out) {
    size_t k = fread(out + n, 1, sizeof out - 1 - n, p);
    if (k == 0) break;
    n += k;
  }
  out[n] = '\0';
  int st = pclose(p);
  *status = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
  return out;
}

struct gi_scene *tu_build(struct gi_mesh_builder *b, const char *name, const struct gi_light *lights, size_t n) {
  return tu_build_up(b, name, GI_UP_Y, lights, n);
}

struct gi_scene *tu_build_up(struct gi_mesh_builder *b, const char *name, int up, const struct gi_light *lights,
                             size_t n) {
  gi_scene *sc = NULL;
  gi_error_info err = {0};
  gi_scene_options opt = {.up = up, .lights = lights, .num_lights = n};
  gi_result rc = gi_scene_build(b, name, &opt, &sc, &err);
  gi_mesh_builder_free(b);
  if (rc != GI_OK) fprintf(stderr, "%s build: %s\n", name, err.msg);
  assert_int_equal(rc, GI_OK);
  return sc;
}

struct gi_scene *tu_furnace_scene(double size, double a, double Le) { return tu_furnace_scene_mirror(size, a, 0, Le); }

struct gi_scene *tu_furnace_scene_mirror(double size, double a, double mirror, double Le) {
  gi_mesh_builder *b = gi_mesh_builder_new();
  gi_material m = {.albedo = {a, a, a}, .emission = {Le, Le, Le}, .roughness = mirror > 0 ? 0 : 1, .specular = mirror};
  uint32_t mat = gi_mesh_builder_add_material(b, &m);
  double s = size;
  /* Six walls wound so their normals point into the cube (emitters are one-sided). */
  double P[8][3];
  for (int i = 0; i < 8; i++) {
    P[i][0] = (i & 1) ? s : 0;
    P[i][1] = (i & 2) ? s : 0;
    P[i][2] = (i & 4) ? s : 0;
  }
  static const int q[6][4] = {{0, 2, 6, 4}, {1, 5, 7, 3}, {0, 4, 5, 1}, {2, 3, 7, 6}, {0, 1, 3, 2}, {4, 6, 7, 5}};
  for (int f = 0; f < 6; f++) gi_mesh_builder_add_quad(b, P[q[f][0]], P[q[f][1]], P[q[f][2]], P[q[f][3]], mat);
  return tu_build(b, "furnace", NULL, 0);
}

struct gi_scene *tu_sunlit_plane(double a, double E, double z_max) {
  gi_light sun = {.type = GI_LIGHT_SUN, .color = {(float)E, (float)E, (float)E},
                  .direction = {(float)(sqrt(3.0) / 2), -0.5f, 0}};
  gi_mesh_builder *b = gi_mesh_builder_new();
  gi_material m = {.albedo = {(float)a, (float)a, (float)a}, .roughness = 1};
  uint32_t mat = gi_mesh_builder_add_material(b, &m);
  double A[3] = {-100, 0, -100}, B[3] = {-100, 0, z_max}, C[3] = {100, 0, z_max}, D[3] = {100, 0, -100};
  gi_mesh_builder_add_quad(b, A, B, C, D, mat);
  return tu_build(b, "plane", &sun, 1);
}

struct gi_scene *tu_box_on_sky_floor(void) {
  gi_mesh_builder *b = gi_mesh_builder_new();
  gi_material m = {.albedo = {0.5f, 0.5f, 0.5f}, .roughness = 1};
  uint32_t mat = gi_mesh_builder_add_material(b, &m);
  double f[4][3] = {{-5, 0, -5}, {-5, 0, 5}, {5, 0, 5}, {5, 0, -5}}, lo[3] = {-0.5, 0, -0.5}, hi[3] = {0.5, 1, 0.5};
  gi_mesh_builder_add_quad(b, f[0], f[1], f[2], f[3], mat);
  gi_mesh_builder_add_box(b, lo, hi, mat);
  gi_light sky = {.type = GI_LIGHT_SKY, .color = {1, 1, 1}};
  return tu_build(b, "box-on-floor", &sky, 1);
}

struct gi_scene *tu_lit_room(float a) {
  gi_mesh_builder *b = gi_mesh_builder_new();
  gi_material m = {.albedo = {a, a, a}, .roughness = 1};
  uint32_t mat = gi_mesh_builder_add_material(b, &m);
  double lo[3] = {-2, 0, -2}, hi[3] = {2, 2.5, 2}, blo[3] = {-1.6, 0, -1.6}, bhi[3] = {-0.9, 0.7, -0.9};
  gi_mesh_builder_add_box(b, lo, hi, mat);
  gi_mesh_builder_add_box(b, blo, bhi, mat);
  gi_light pl = {.type = GI_LIGHT_POINT, .color = {20, 20, 20}, .position = {0.8, 2.0, 0.8}};
  return tu_build(b, "room", &pl, 1);
}
