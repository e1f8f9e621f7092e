/* test_vdb.c: VDB writes read back through the shim, vdb_print and
 * pyopenvdb, plus clean failures. Being C, it also proves gi_vdb.h is.
 *
 * The grids sit 1e6 units from the world origin with a 0.5 voxel, so the
 * transform must be kept in doubles: index (0,0,0)'s centre is expected at
 * exactly origin + 0.25 on each axis. gi_vdb_mem's memory figure is checked
 * against the leaf buffers it must hold at least. */
#define _POSIX_C_SOURCE 200809L
#include "test_util.h"
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <signal.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>
#include "gi/gi_vdb.h"

/* OpenVDB 10's readTopology is not exception-safe: a read that fails half way
 * through the tree leaks the nodes built so far (inside libopenvdb, not the
 * shim). The truncation sweep below hits that on purpose, so under
 * LeakSanitizer it runs with leak detection off. */
#if defined(__SANITIZE_ADDRESS__)
#include <sanitizer/lsan_interface.h>
#define LSAN_OFF() __lsan_disable()
#define LSAN_ON() __lsan_enable()
#else
#define LSAN_OFF() ((void)0)
#define LSAN_ON() ((void)0)
#endif

#define NX 5
#define NY 4
#define NZ 3
#define NV (NX * NY * NZ)
#define IDX(i, j, k) ((i) + NX * ((j) + NY * (k)))

static const double kOrigin[3] = {1e6 + 0.25, -3.5, 2.0};
static float density[NV], level0[NV], cd[3 * NV];
static long n_density, n_level0, n_cd; /* non-zero dense values per grid */

/* Deterministic blocks with zeros in them (those must stay inactive). */
static void fill(void) {
  n_density = n_level0 = n_cd = 0;
  for (int k = 0; k < NZ; k++)
    for (int j = 0; j < NY; j++)
      for (int i = 0; i < NX; i++) {
        int n = IDX(i, j, k);
        density[n] = (i + j + k) % 3 == 0 ? 0.f : 0.25f * (float)(i + 1) + 0.01f * (float)k;
        level0[n] = i == 2 ? 0.f : (float)(n + 1) / 7.f;
        int zero = (i * j) % 4 == 1;
        cd[3 * n + 0] = zero ? 0.f : 0.1f * (float)i;
        cd[3 * n + 1] = zero ? 0.f : 0.2f * (float)j;
        cd[3 * n + 2] = zero ? 0.f : 1.f + (float)k; /* never 0, so a non-zero vector */
        n_density += density[n] != 0.f;
        n_level0 += level0[n] != 0.f;
        n_cd += cd[3 * n] != 0.f || cd[3 * n + 1] != 0.f || cd[3 * n + 2] != 0.f;
      }
}

static const gi_vdb_meta kGridMeta[] = {
    {"gi.level", NULL, 0.0},
    {"gi.resolution", "5x4x3", 0},
};
static const gi_vdb_meta kFileMeta[] = {
    {"gi.scene", "city-block-7", 0},
    {"gi.viewpoint_x", NULL, 1234567.891},
    {"gi.voxel_size", NULL, 0.5},
};

static gi_vdb_grid grids[3];

static void make_grids(void) {
  fill();
  gi_vdb_grid base = {.dims = {NX, NY, NZ}, .voxel_size = 0.5,
                      .origin = {kOrigin[0], kOrigin[1], kOrigin[2]}, .num_meta = 2, .meta = kGridMeta};
  grids[0] = base;
  grids[0].name = "density";
  grids[0].kind = GI_VDB_FLOAT;
  grids[0].data = density;
  grids[0].fog_volume = 1;
  grids[1] = base;
  grids[1].name = "L0_density";
  grids[1].kind = GI_VDB_FLOAT;
  grids[1].data = level0;
  grids[1].fog_volume = 1;
  grids[2] = base;
  grids[2].name = "Cd";
  grids[2].kind = GI_VDB_VEC3;
  grids[2].data = cd;
}

static const char *tmp_path(const char *name) {
  static char bufs[4][512];
  static int next;
  char *p = bufs[next++ & 3];
  snprintf(p, 512, "%s/%s", tu_tmpdir(), name);
  return p;
}

static const char *write_good(const char *name) {
  const char *path = tmp_path(name);
  make_grids();
  gi_error_info err = {0};
  gi_result r = gi_vdb_write(path, grids, 3, kFileMeta, 3, &err);
  if (r != GI_OK) fail_msg("gi_vdb_write: %s", err.msg);
  return path;
}

static void test_info(void **s) {
  const char *path = write_good("info.vdb");
  gi_vdb_grid_info info[8];
  size_t n = 0;
  gi_error_info err = {0};
  assert_int_equal(gi_vdb_read_info(path, info, 8, &n, &err), GI_OK);
  assert_int_equal(n, 3);
  const char *names[3] = {"density", "L0_density", "Cd"};
  long counts[3] = {n_density, n_level0, n_cd};
  assert_true(n_density > 0 && n_density < NV); /* the test data really has zeros */
  assert_true(n_cd > 0 && n_cd < NV);
  for (int g = 0; g < 3; g++) {
    const gi_vdb_grid_info *in = NULL;
    for (size_t m = 0; m < n; m++)
      if (strcmp(info[m].name, names[g]) == 0) in = &info[m];
    if (!in) fail_msg("grid %s not listed", names[g]);
    assert_int_equal(in->kind, g == 2 ? GI_VDB_VEC3 : GI_VDB_FLOAT);
    assert_true(in->voxel_size == 0.5);
    for (int a = 0; a < 3; a++)
      if (in->index_to_world[a] != kOrigin[a] + 0.25)
        fail_msg("%s index_to_world[%d] = %.17g, want %.17g", names[g], a, in->index_to_world[a],
                 kOrigin[a] + 0.25);
    assert_int_equal(in->active_voxels, counts[g]);
    assert_int_equal(in->is_fog_volume, g != 2);
  }
  /* A short array gets the first entries only. */
  assert_int_equal(gi_vdb_read_info(path, info, 1, &n, &err), GI_OK);
  assert_int_equal(n, 1);
}

static void check_value(const char *path, const char *name, int i, int j, int k, const float *want, int comps) {
  float v[3] = {-1.f, -1.f, -1.f};
  gi_error_info err = {0};
  gi_result r = gi_vdb_read_value(path, name, i, j, k, v, &err);
  if (r != GI_OK) fail_msg("read_value %s: %s", name, err.msg);
  for (int c = 0; c < comps; c++)
    if (v[c] != want[c]) fail_msg("%s(%d,%d,%d)[%d] = %.9g, want %.9g", name, i, j, k, c, v[c], want[c]);
}

static void test_values(void **s) {
  const char *path = write_good("values.vdb");
  static const int probes[][3] = {{0, 0, 0}, {1, 0, 0}, {4, 3, 2}, {2, 1, 1}, {3, 2, 0}, {0, 3, 2}, {1, 1, 1}};
  for (size_t p = 0; p < sizeof probes / sizeof probes[0]; p++) {
    int i = probes[p][0], j = probes[p][1], k = probes[p][2], n = IDX(i, j, k);
    check_value(path, "density", i, j, k, &density[n], 1);
    check_value(path, "L0_density", i, j, k, &level0[n], 1);
    check_value(path, "Cd", i, j, k, &cd[3 * n], 3);
  }
  /* Outside the block is background. */
  const float zero[3] = {0, 0, 0};
  check_value(path, "density", -1, 0, 0, zero, 1);
  check_value(path, "Cd", NX, NY, NZ, zero, 3);
  /* Unknown grid name. */
  float v[3];
  gi_error_info err = {0};
  assert_int_equal(gi_vdb_read_value(path, "nope", 0, 0, 0, v, &err), GI_ERR_NOT_FOUND);
  assert_non_null(strstr(err.msg, "nope"));
}

static void expect_meta(const char *path, const char *grid, const char *key, const char *want) {
  char buf[128];
  gi_error_info err = {0};
  gi_result r = gi_vdb_read_meta(path, grid, key, buf, sizeof buf, &err);
  if (r != GI_OK) fail_msg("read_meta %s/%s: %s", grid ? grid : "(file)", key, err.msg);
  assert_string_equal(buf, want);
}

static void test_metadata(void **s) {
  const char *path = write_good("meta.vdb");
  expect_meta(path, NULL, "gi.scene", "city-block-7");
  expect_meta(path, NULL, "gi.viewpoint_x", "1234567.891");
  expect_meta(path, NULL, "gi.voxel_size", "0.5");
  for (int g = 0; g < 3; g++) {
    expect_meta(path, grids[g].name, "gi.level", "0");
    expect_meta(path, grids[g].name, "gi.resolution", "5x4x3");
  }
  expect_meta(path, "density", "class", "fog volume"); /* OpenVDB's own */
  char buf[4];
  gi_error_info err = {0};
  assert_int_equal(gi_vdb_read_meta(path, "density", "absent", buf, sizeof buf, &err), GI_ERR_NOT_FOUND);
  assert_int_equal(gi_vdb_read_meta(path, NULL, "gi.scene", buf, sizeof buf, &err), GI_ERR_LIMIT);
  assert_int_equal(gi_vdb_read_meta(path, "nope", "gi.level", buf, sizeof buf, &err), GI_ERR_NOT_FOUND);
}

static void test_vdb_print(void **s) {
  if (access("/usr/bin/vdb_print", X_OK) != 0) {
    fprintf(stderr, "SKIP: /usr/bin/vdb_print is missing (apt-get install libopenvdb-tools)\n");
    skip();
  }
  const char *path = write_good("print.vdb");
  char cmd[600];
  snprintf(cmd, sizeof cmd, "/usr/bin/vdb_print -l '%s' 2>&1", path);
  int st = 0;
  const char *out = tu_run(cmd, &st);
  if (st != 0) fail_msg("vdb_print exited %d:\n%s", st, out);
  for (int g = 0; g < 3; g++)
    if (!strstr(out, grids[g].name)) fail_msg("vdb_print lacks grid %s:\n%s", grids[g].name, out);
  if (!strstr(out, "city-block-7")) fail_msg("vdb_print lacks the file metadata:\n%s", out);
}

/* Debian's pyopenvdb only works with /usr/bin/python3 (not a pyenv one). */
static void test_pyopenvdb(void **s) {
  if (access("/usr/bin/python3", X_OK) != 0) {
    fprintf(stderr, "SKIP: /usr/bin/python3 is missing\n");
    skip();
  }
  const char *path = write_good("py.vdb");
  char script[2048];
  snprintf(script, sizeof script,
           "/usr/bin/python3 -c '\n"
           "import sys\n"
           "try:\n"
           "    import pyopenvdb as vdb\n"
           "except ImportError:\n"
           "    sys.exit(77)\n"
           "grids, meta = vdb.readAll(\"%s\")\n"
           "by = {g.name: g for g in grids}\n"
           "assert set(by) == {\"density\", \"L0_density\", \"Cd\"}, by.keys()\n"
           "w = by[\"density\"].transform.indexToWorld((0, 0, 0))\n"
           "assert tuple(w) == (%.17g, %.17g, %.17g), w\n"
           "w = by[\"Cd\"].transform.indexToWorld((4, 3, 2))\n"
           "assert tuple(w) == (%.17g, %.17g, %.17g), w\n"
           "assert by[\"density\"].gridClass == vdb.GridClass.FOG_VOLUME\n"
           "assert by[\"density\"].activeVoxelCount() == %ld\n"
           "assert by[\"Cd\"].getConstAccessor().getValue((1, 2, 1))[2] == 2.0\n"
           "assert meta[\"gi.scene\"] == \"city-block-7\", meta\n"
           "print(\"pyopenvdb ok\")\n"
           "' 2>&1",
           path, kOrigin[0] + 0.25, kOrigin[1] + 0.25, kOrigin[2] + 0.25, kOrigin[0] + 2.25, kOrigin[1] + 1.75,
           kOrigin[2] + 1.25, n_density);
  int st = 0;
  const char *out = tu_run(script, &st);
  if (st == 77) {
    fprintf(stderr, "SKIP: pyopenvdb is not importable by /usr/bin/python3 (apt-get install python3-openvdb)\n");
    skip();
  }
  if (st != 0 || !strstr(out, "pyopenvdb ok")) fail_msg("pyopenvdb check exited %d:\n%s", st, out);
}

static void test_write_errors(void **s) {
  make_grids();
  gi_error_info err = {0};
  assert_int_equal(gi_vdb_write("/nonexistent-dir/x.vdb", grids, 3, NULL, 0, &err), GI_ERR_IO);
  assert_non_null(strstr(err.msg, "/nonexistent-dir/x.vdb"));

  /* Bad input leaves an existing file alone and no temp file behind. */
  const char *path = write_good("keep.vdb");
  size_t n = 0;
  gi_vdb_grid_info info[4];
  density[IDX(1, 1, 1)] = NAN;
  assert_int_equal(gi_vdb_write(path, grids, 3, NULL, 0, &err), GI_ERR_NONFINITE);
  assert_non_null(strstr(err.msg, "density"));
  make_grids();
  grids[1].name = "density"; /* twice */
  assert_int_equal(gi_vdb_write(path, grids, 3, NULL, 0, &err), GI_ERR_INVALID_ARG);
  make_grids();
  gi_vdb_meta reserved = {"class", "level set", 0};
  grids[0].meta = &reserved;
  grids[0].num_meta = 1;
  assert_int_equal(gi_vdb_write(path, grids, 3, NULL, 0, &err), GI_ERR_INVALID_ARG);
  make_grids();
  grids[2].voxel_size = 0;
  assert_int_equal(gi_vdb_write(path, grids, 3, NULL, 0, &err), GI_ERR_INVALID_ARG);
  assert_int_equal(gi_vdb_write(path, grids, 0, NULL, 0, &err), GI_ERR_EMPTY);
  assert_int_equal(gi_vdb_read_info(path, info, 4, &n, &err), GI_OK);
  assert_int_equal(n, 3);
  char cmd[600];
  snprintf(cmd, sizeof cmd, "ls '%s' | grep -q '\\.tmp\\.'", tu_tmpdir());
  assert_int_not_equal(system(cmd), 0);
}

/* A disk that fills up during the write, made without root: RLIMIT_FSIZE
 * makes the kernel refuse bytes past the limit (EFBIG, with SIGXFSZ
 * ignored), as a full disk refuses them (ENOSPC). OpenVDB's io::File
 * ignored the failed writes: the call returned GI_OK and renamed the
 * truncated file into place. */
static void test_write_full_disk(void **s) {
  (void)s;
  const char *path = write_good("full.vdb");
  FILE *f = fopen(path, "rb");
  assert_non_null(f);
  static unsigned char before[1 << 16], after[1 << 16];
  size_t n = fread(before, 1, sizeof before, f);
  fclose(f);
  assert_true(n > 1500 && n < sizeof before);
  /* New values, so a file that got through would differ from the old one. */
  for (int i = 0; i < NV; i++) density[i] = density[i] != 0.f ? density[i] + 1.f : 0.f;
  struct rlimit old, lim;
  assert_int_equal(getrlimit(RLIMIT_FSIZE, &old), 0);
  lim = old;
  lim.rlim_cur = 1024; /* under the file's size */
  void (*prev)(int) = signal(SIGXFSZ, SIG_IGN);
  assert_int_equal(setrlimit(RLIMIT_FSIZE, &lim), 0);
  gi_error_info err = {0};
  gi_result r = gi_vdb_write(path, grids, 3, kFileMeta, 3, &err);
  setrlimit(RLIMIT_FSIZE, &old);
  signal(SIGXFSZ, prev);
  assert_int_equal(r, GI_ERR_IO);
  assert_non_null(strstr(err.msg, path));
  assert_non_null(strstr(err.msg, strerror(EFBIG)));
  /* The old file is untouched and no temp file is left. */
  f = fopen(path, "rb");
  assert_non_null(f);
  assert_int_equal(fread(after, 1, sizeof after, f), n);
  fclose(f);
  assert_memory_equal(before, after, n);
  char cmd[600];
  snprintf(cmd, sizeof cmd, "ls '%s' | grep -q 'full\\.vdb\\.tmp\\.'", tu_tmpdir());
  assert_int_not_equal(system(cmd), 0);
  /* The same through the sparse writer (probe volumes), onto a new path. */
  const char *fresh = tmp_path("full-sparse.vdb");
  int ijk[3 * 200];
  float vals[3 * 200];
  for (int i = 0; i < 200; i++) {
    ijk[3 * i] = i, ijk[3 * i + 1] = 2 * i, ijk[3 * i + 2] = 3 * i;
    vals[3 * i] = 1.f + (float)i, vals[3 * i + 1] = 2.f, vals[3 * i + 2] = 3.f;
  }
  gi_vdb_sparse sp = {.name = "sh", .kind = GI_VDB_VEC3, .count = 200, .ijk = ijk, .data = vals,
                      .voxel_size = 1.0};
  prev = signal(SIGXFSZ, SIG_IGN);
  assert_int_equal(setrlimit(RLIMIT_FSIZE, &lim), 0);
  r = gi_vdb_write_sparse(fresh, &sp, 1, NULL, 0, NULL, &err);
  setrlimit(RLIMIT_FSIZE, &old);
  signal(SIGXFSZ, prev);
  assert_int_equal(r, GI_ERR_IO);
  assert_non_null(strstr(err.msg, strerror(EFBIG)));
  assert_int_not_equal(access(fresh, F_OK), 0);
  snprintf(cmd, sizeof cmd, "ls '%s' | grep -q 'full-sparse\\.vdb\\.tmp\\.'", tu_tmpdir());
  assert_int_not_equal(system(cmd), 0);
}

static void expect_read_fails(const char *path, gi_result want) {
  gi_vdb_grid_info info[4];
  size_t n = 99;
  float v[3];
  char buf[64];
  gi_error_info err = {0};
  gi_result r = gi_vdb_read_info(path, info, 4, &n, &err);
  if (r == GI_OK) fail_msg("reading '%s' succeeded", path);
  if (want != GI_OK) assert_int_equal(r, want);
  assert_int_equal(n, 0);
  assert_non_null(strstr(err.msg, path));
  for (const char *c = err.msg; *c; c++) /* printable: it may end up in JSON */
    assert_true(*c >= 0x20 && *c <= 0x7e);
  assert_int_not_equal(gi_vdb_read_value(path, "density", 0, 0, 0, v, &err), GI_OK);
  assert_int_not_equal(gi_vdb_read_meta(path, NULL, "gi.scene", buf, sizeof buf, &err), GI_OK);
}

static void test_read_bad_files(void **s) {
  expect_read_fails(tmp_path("missing.vdb"), GI_ERR_NOT_FOUND);
  expect_read_fails(tu_write_file("empty.vdb", "", 0), GI_ERR_FORMAT);
  unsigned char junk[4096];
  srand(99);
  for (size_t i = 0; i < sizeof junk; i++) junk[i] = (unsigned char)(rand() >> 7);
  expect_read_fails(tu_write_file("junk.vdb", junk, sizeof junk), GI_ERR_FORMAT);

  const char *good = write_good("good.vdb");
  FILE *f = fopen(good, "rb");
  assert_non_null(f);
  static unsigned char bytes[1 << 20];
  size_t n = fread(bytes, 1, sizeof bytes, f);
  fclose(f);
  assert_true(n > 1000 && n < sizeof bytes);
  expect_read_fails(tu_write_file("trunc100.vdb", bytes, 100), GI_ERR_FORMAT);
  /* Cuts through the header, metadata, topology and voxel buffers: each
   * must fail fast (the shim reads through a stream that throws). */
  LSAN_OFF();
  for (size_t cut = 1; cut < n; cut += 97) expect_read_fails(tu_write_file("trunc.vdb", bytes, cut), GI_ERR_FORMAT);
  expect_read_fails(tu_write_file("trunc1.vdb", bytes, n - 1), GI_ERR_FORMAT);
  LSAN_ON();
}

/* gi_vdb_mem: OpenVDB's memUsage of grids built in memory. A Vec3f leaf
 * holds 8^3 values of 12 bytes, whatever few of them are active. */
#define LEAF_VALUE_BYTES (512 * 12)
static void test_mem_usage(void **s) {
  (void)s;
  gi_vdb_mem *m = (gi_vdb_mem *)1;
  gi_error_info err = {0};
  assert_int_equal(gi_vdb_mem_new(0, &m, &err), GI_ERR_INVALID_ARG);
  assert_null(m);
  assert_int_equal(gi_vdb_mem_new(2, &m, &err), GI_OK);
  float v[6] = {1, 2, 3, 4, 5, 6};
  for (int i = 0; i < 10; i++) assert_int_equal(gi_vdb_mem_set(m, i, 0, 0, v, &err), GI_OK);
  size_t one_leaf, again, two_leaves;
  uint64_t active;
  gi_vdb_mem_usage(m, &one_leaf, &active);
  assert_int_equal(active, 10);
  assert_true(one_leaf >= 2 * LEAF_VALUE_BYTES);
  /* Setting an active voxel again adds nothing. */
  assert_int_equal(gi_vdb_mem_set(m, 3, 0, 0, v, &err), GI_OK);
  gi_vdb_mem_usage(m, &again, &active);
  assert_int_equal(active, 10);
  assert_int_equal(again, one_leaf);
  /* A far voxel needs a new leaf (and nodes above it) in each grid. */
  assert_int_equal(gi_vdb_mem_set(m, 1000, -1000, 1000, v, &err), GI_OK);
  gi_vdb_mem_usage(m, &two_leaves, &active);
  assert_int_equal(active, 11);
  assert_true(two_leaves >= one_leaf + 2 * LEAF_VALUE_BYTES);
  gi_vdb_mem_free(m);
  gi_vdb_mem_free(NULL);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_info),        cmocka_unit_test(test_values),
      cmocka_unit_test(test_metadata),    cmocka_unit_test(test_vdb_print),
      cmocka_unit_test(test_pyopenvdb),   cmocka_unit_test(test_write_errors),
      cmocka_unit_test(test_read_bad_files), cmocka_unit_test(test_mem_usage),
      cmocka_unit_test(test_write_full_disk),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
