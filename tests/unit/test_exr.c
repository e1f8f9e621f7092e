/* test_exr.c: EXR write/read round trips, validation, atomic replace, and
 * clean failures on damaged files.
 *
 * The image is 7x3 with the channel names the bakes use. HALF round trips
 * are checked to half precision (values chosen so most are exact in half,
 * plus 0.1-style values that are not); FLOAT round trips must be exact.
 * exrheader, when installed, is the independent check that the files are
 * real EXR files a stock tool accepts. */
#define _POSIX_C_SOURCE 200809L
#include "test_util.h"
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>
#include "gi/gi_exr.h"

#define W 7
#define H 3
#define NCH 8

static const char *const kNames[NCH] = {"R", "G", "B", "A", "irradiance.R", "irradiance.G", "irradiance.B",
                                        "sh.L00.R"};
/* What the file holds, in the sorted order EXR keeps. */
static const char *const kSorted[NCH] = {"A", "B", "G", "R", "irradiance.B", "irradiance.G", "irradiance.R",
                                         "sh.L00.R"};

static float planes[NCH][W * H];

/* Channel c, pixel i: mostly multiples of 1/8 (exact in half), some
 * negative, every fifth an awkward decimal that half must round. */
static float sample(int c, int i) {
  float v = (float)(i + 1) * 0.125f + (float)c * 1.5f;
  if (i % 5 == 4) v = 0.1f * (float)(c + 1) + 1e-3f * (float)i;
  if (c == NCH - 1) v = -v; /* SH coefficients can be negative */
  return v;
}

static void fill(void) {
  for (int c = 0; c < NCH; c++)
    for (int i = 0; i < W * H; i++) planes[c][i] = sample(c, i);
}

static gi_exr_channel chans[NCH];
static const gi_exr_attr kAttrs[] = {
    {"gi.scene", "box-7x3"},
    {"gi.viewpoint", "1.5 -2 30.25"},
    {"gi.version", "0.1.0 (test)"},
};

static gi_exr_image image(int use_half, gi_exr_compression comp) {
  fill();
  for (int c = 0; c < NCH; c++) chans[c] = (gi_exr_channel){kNames[c], planes[c]};
  return (gi_exr_image){.width = W, .height = H, .use_half = use_half, .compression = comp,
                        .num_channels = NCH, .channels = chans, .num_attrs = 3, .attrs = kAttrs};
}

static const char *tmp_path(const char *name) {
  static char bufs[4][512];
  static int next;
  char *p = bufs[next++ & 3];
  snprintf(p, 512, "%s/%s", tu_tmpdir(), name);
  return p;
}

static unsigned char *slurp(const char *path, size_t *len) {
  FILE *f = fopen(path, "rb");
  assert_non_null(f);
  fseek(f, 0, SEEK_END);
  long n = ftell(f);
  fseek(f, 0, SEEK_SET);
  unsigned char *buf = malloc((size_t)n + 1);
  assert_non_null(buf);
  assert_int_equal(fread(buf, 1, (size_t)n, f), (size_t)n);
  fclose(f);
  *len = (size_t)n;
  return buf;
}

/* No "<name>.tmp.*" file may be left next to a failed write. */
static void assert_no_temp_left(void) {
  char cmd[600];
  snprintf(cmd, sizeof cmd, "ls '%s' | grep -q '\\.tmp\\.'", tu_tmpdir());
  assert_int_not_equal(system(cmd), 0);
}

/* path holds the n bytes `before` (freed here): a failed write left it as it was. */
static void assert_file_is(const char *path, unsigned char *before, size_t n) {
  size_t n1;
  unsigned char *after = slurp(path, &n1);
  assert_int_equal(n, n1);
  assert_memory_equal(before, after, n);
  free(before);
  free(after);
}

static void check_round_trip(int use_half, gi_exr_compression comp, const char *name) {
  const char *path = tmp_path(name);
  gi_exr_image img = image(use_half, comp);
  gi_error_info err = {0};
  assert_int_equal(gi_exr_write(path, &img, &err), GI_OK);

  gi_exr_file *f = NULL;
  gi_result r = gi_exr_read(path, &f, &err);
  if (r != GI_OK) fprintf(stderr, "%s\n", err.msg);
  assert_int_equal(r, GI_OK);
  assert_int_equal(gi_exr_file_width(f), W);
  assert_int_equal(gi_exr_file_height(f), H);
  assert_int_equal(gi_exr_file_compression(f), comp);
  assert_int_equal(gi_exr_file_num_channels(f), NCH);
  for (size_t c = 0; c < NCH; c++) {
    assert_string_equal(gi_exr_file_channel_name(f, c), kSorted[c]);
    assert_int_equal(gi_exr_file_channel_is_half(f, c), use_half);
  }
  for (int c = 0; c < NCH; c++) {
    const float *got = gi_exr_file_channel(f, kNames[c]);
    assert_non_null(got);
    for (int i = 0; i < W * H; i++) {
      float want = sample(c, i);
      if (!use_half) {
        assert_true(got[i] == want);
      } else {
        if (fabsf(got[i] - want) > 1e-3f * fabsf(want))
          fail_msg("%s %s[%d]: got %.8g want %.8g", name, kNames[c], i, got[i], want);
        if (i % 5 != 4) assert_true(got[i] == want); /* multiples of 1/8 are exact in half */
      }
    }
  }
  assert_string_equal(gi_exr_file_attr(f, "gi.scene"), "box-7x3");
  assert_string_equal(gi_exr_file_attr(f, "gi.viewpoint"), "1.5 -2 30.25");
  assert_string_equal(gi_exr_file_attr(f, "gi.version"), "0.1.0 (test)");
  assert_null(gi_exr_file_attr(f, "gi.absent"));
  assert_null(gi_exr_file_channel(f, "Z"));
  gi_exr_file_free(f);
}

static void test_round_trip_half_zip(void **s) { check_round_trip(1, GI_EXR_ZIP, "h_zip.exr"); }
static void test_round_trip_half_piz(void **s) { check_round_trip(1, GI_EXR_PIZ, "h_piz.exr"); }
static void test_round_trip_half_none(void **s) { check_round_trip(1, GI_EXR_NONE, "h_none.exr"); }
static void test_round_trip_float_zip(void **s) { check_round_trip(0, GI_EXR_ZIP, "f_zip.exr"); }
static void test_round_trip_float_piz(void **s) { check_round_trip(0, GI_EXR_PIZ, "f_piz.exr"); }
static void test_round_trip_float_none(void **s) { check_round_trip(0, GI_EXR_NONE, "f_none.exr"); }

/* Taller than one ZIP (16 lines) and one PIZ (32 lines) chunk, with a
 * partial last chunk, so chunk offsets and row addressing are exercised. */
static void test_many_chunks(void **s) {
  enum { TW = 5, TH = 45 };
  static float r[TW * TH], g[TW * TH];
  for (int i = 0; i < TW * TH; i++) {
    r[i] = (float)i;
    g[i] = (float)(TW * TH - i) * 0.5f;
  }
  gi_exr_channel ch[2] = {{"R", r}, {"G", g}};
  for (int comp = 0; comp < 3; comp++)
    for (int half = 0; half < 2; half++) {
      gi_exr_image img = {.width = TW, .height = TH, .use_half = half, .compression = comp,
                          .num_channels = 2, .channels = ch};
      const char *path = tmp_path("tall.exr");
      gi_error_info err = {0};
      assert_int_equal(gi_exr_write(path, &img, &err), GI_OK);
      gi_exr_file *f = NULL;
      assert_int_equal(gi_exr_read(path, &f, &err), GI_OK);
      const float *rr = gi_exr_file_channel(f, "R"), *gg = gi_exr_file_channel(f, "G");
      for (int i = 0; i < TW * TH; i++) { /* all exact in half too */
        assert_true(rr[i] == r[i]);
        assert_true(gg[i] == g[i]);
      }
      gi_exr_file_free(f);
    }
}

/* Values beyond the half range are clamped to +-65504 (see exr_io.c);
 * FLOAT files keep them. */
/* Small images with mixed values, as probe EXRs are: OpenEXR 3.1's ZIP
 * encoder used to store chunks whose zlib output was exactly as long as
 * the raw data, which readers took for raw pixels (a third of these
 * images came back as garbage before exr_io.c stored such chunks raw). */
static void test_small_zip_images_round_trip(void **s) {
  int images = 0;
  for (int trial = 0; trial < 1500; trial++) {
    int w = 1 + trial % 9, h = 1 + (trial / 9) % 3, nch = 1 + (trial / 27) % 40, half = trial & 1;
    size_t n = (size_t)w * h;
    float *d = malloc(sizeof(float) * n * nch);
    gi_exr_channel *ch = calloc(nch, sizeof *ch);
    char(*names)[16] = malloc(16 * (size_t)nch);
    uint64_t seed = (uint64_t)trial * 2654435761u + 1;
    for (size_t i = 0; i < n * (size_t)nch; i++) {
      seed = seed * 6364136223846793005ULL + 1442695040888963407ULL;
      uint32_t r = (uint32_t)(seed >> 33);
      int k = r % 4;
      d[i] = k == 0 ? (float)(r % 4096) / 1024.f : k == 1 ? 0.f : k == 2 ? (float)(r % 3) : -(float)(r % 1000) / 1000.f;
    }
    for (int c = 0; c < nch; c++) {
      snprintf(names[c], 16, "c%03d", c);
      ch[c].name = names[c];
      ch[c].data = d + (size_t)c * n;
    }
    gi_exr_image img = {.width = w, .height = h, .use_half = half, .compression = GI_EXR_ZIP,
                        .num_channels = (size_t)nch, .channels = ch};
    gi_error_info err = {0};
    const char *path = tu_write_file("small_zip.exr", "", 0);
    assert_int_equal(gi_exr_write(path, &img, &err), GI_OK);
    gi_exr_file *f = NULL;
    assert_int_equal(gi_exr_read(path, &f, &err), GI_OK);
    for (int c = 0; c < nch; c++) {
      const float *r = gi_exr_file_channel(f, names[c]);
      assert_non_null(r);
      for (size_t i = 0; i < n; i++) {
        float want = d[(size_t)c * n + i];
        assert_true(fabsf(r[i] - want) <= (half ? 1e-3f : 0.f) * fmaxf(1.f, fabsf(want)));
      }
    }
    gi_exr_file_free(f);
    free(d);
    free(ch);
    free(names);
    images++;
  }
  printf("  %d small ZIP images (1-9 x 1-3 pixels, 1-40 channels, half and float) read back exactly\n", images);
}

static void test_half_clamps(void **s) {
  float v[4] = {1e5f, -1e6f, 65504.f, 3e-8f};
  gi_exr_channel ch = {"Y", v};
  gi_exr_image img = {.width = 4, .height = 1, .use_half = 1, .compression = GI_EXR_ZIP,
                      .num_channels = 1, .channels = &ch};
  const char *path = tmp_path("clamp.exr");
  gi_error_info err = {0};
  assert_int_equal(gi_exr_write(path, &img, &err), GI_OK);
  gi_exr_file *f = NULL;
  assert_int_equal(gi_exr_read(path, &f, &err), GI_OK);
  const float *y = gi_exr_file_channel(f, "Y");
  assert_true(y[0] == 65504.f);
  assert_true(y[1] == -65504.f);
  assert_true(y[2] == 65504.f);
  assert_true(y[3] == ldexpf(1.f, -24)); /* rounds up to the smallest half subnormal */
  gi_exr_file_free(f);
  img.use_half = 0;
  assert_int_equal(gi_exr_write(path, &img, &err), GI_OK);
  assert_int_equal(gi_exr_read(path, &f, &err), GI_OK);
  assert_true(gi_exr_file_channel(f, "Y")[1] == -1e6f);
  gi_exr_file_free(f);
}

static void test_exrheader_accepts(void **s) {
  if (access("/usr/bin/exrheader", X_OK) != 0) {
    fprintf(stderr, "SKIP: /usr/bin/exrheader is missing (apt-get install openexr)\n");
    skip();
  }
  for (int comp = 0; comp < 3; comp++) {
    const char *path = tmp_path("hdr.exr");
    gi_exr_image img = image(comp != 1, comp);
    gi_error_info err = {0};
    assert_int_equal(gi_exr_write(path, &img, &err), GI_OK);
    char cmd[600];
    snprintf(cmd, sizeof cmd, "/usr/bin/exrheader '%s' 2>&1", path);
    int st = 0;
    const char *out = tu_run(cmd, &st);
    if (st != 0) fail_msg("exrheader exited %d:\n%s", st, out);
    for (int c = 0; c < NCH; c++) {
      char want[64];
      snprintf(want, sizeof want, "%s, %s", kNames[c], comp != 1 ? "16-bit floating-point" : "32-bit floating-point");
      if (!strstr(out, want)) fail_msg("exrheader output lacks '%s':\n%s", want, out);
    }
    if (!strstr(out, "box-7x3")) fail_msg("exrheader output lacks the gi.scene value:\n%s", out);
    const char *cname = comp == 0 ? "zip, multi-scanline blocks" : comp == 1 ? "piz" : "none";
    if (!strstr(out, cname)) fail_msg("exrheader output lacks compression '%s':\n%s", cname, out);
  }
}

static void test_nan_rejected_no_file(void **s) {
  gi_exr_image img = image(1, GI_EXR_ZIP);
  planes[5][2 * W + 3] = NAN; /* irradiance.G at (3,2) */
  const char *path = tmp_path("nan.exr");
  gi_error_info err = {0};
  assert_int_equal(gi_exr_write(path, &img, &err), GI_ERR_NONFINITE);
  assert_int_equal(err.code, GI_ERR_NONFINITE);
  assert_non_null(strstr(err.msg, "irradiance.G"));
  assert_non_null(strstr(err.msg, "(3,2)"));
  assert_non_null(strstr(err.msg, path));
  assert_int_equal(access(path, F_OK), -1);
  planes[5][2 * W + 3] = INFINITY;
  assert_int_equal(gi_exr_write(path, &img, &err), GI_ERR_NONFINITE);
  assert_int_equal(access(path, F_OK), -1);
  assert_no_temp_left();
}

static void test_bad_input_keeps_old_file(void **s) {
  const char *path = tmp_path("keep.exr");
  gi_exr_image img = image(1, GI_EXR_PIZ);
  gi_error_info err = {0};
  assert_int_equal(gi_exr_write(path, &img, &err), GI_OK);
  size_t n0;
  unsigned char *before = slurp(path, &n0);

  /* Rejected before any file is touched. */
  img = image(1, GI_EXR_PIZ);
  planes[0][0] = -NAN;
  assert_int_equal(gi_exr_write(path, &img, &err), GI_ERR_NONFINITE);
  /* Rejected by OpenEXR after the temp file exists: "channels" is a
   * required attribute of another type. */
  img = image(1, GI_EXR_PIZ);
  gi_exr_attr bad = {"channels", "oops"};
  img.attrs = &bad;
  img.num_attrs = 1;
  memset(&err, 0, sizeof err);
  gi_result r = gi_exr_write(path, &img, &err);
  assert_int_not_equal(r, GI_OK);
  assert_non_null(strstr(err.msg, path));

  assert_file_is(path, before, n0);
  assert_no_temp_left();
}

static void test_invalid_arguments(void **s) {
  gi_error_info err = {0};
  const char *path = tmp_path("inval.exr");
  gi_exr_image img = image(0, GI_EXR_ZIP);
  img.width = 0;
  assert_int_equal(gi_exr_write(path, &img, &err), GI_ERR_INVALID_ARG);
  img = image(0, GI_EXR_ZIP);
  img.num_channels = 0;
  assert_int_equal(gi_exr_write(path, &img, &err), GI_ERR_EMPTY);
  img = image(0, GI_EXR_ZIP);
  chans[2].name = "R"; /* duplicate */
  assert_int_equal(gi_exr_write(path, &img, &err), GI_ERR_INVALID_ARG);
  assert_non_null(strstr(err.msg, "'R' given twice"));
  img = image(0, GI_EXR_ZIP);
  chans[1].name = "";
  assert_int_equal(gi_exr_write(path, &img, &err), GI_ERR_INVALID_ARG);
  img = image(0, (gi_exr_compression)7);
  assert_int_equal(gi_exr_write(path, &img, &err), GI_ERR_INVALID_ARG);
  assert_int_equal(access(path, F_OK), -1);
}

static void test_unwritable_path(void **s) {
  gi_exr_image img = image(1, GI_EXR_ZIP);
  gi_error_info err = {0};
  assert_int_equal(gi_exr_write("/nonexistent-dir/x.exr", &img, &err), GI_ERR_IO);
  assert_int_equal(err.code, GI_ERR_IO);
  assert_non_null(strstr(err.msg, "/nonexistent-dir/x.exr"));
}

/* A write that fails part way (a full disk, here the file-size limit) is
 * an error naming the file, with no temporary left and the old file kept.
 * OpenEXR reports a failed chunk write through the error callback while
 * it holds the context's lock, and the callback asked the context for its
 * user data, which takes that lock: the write never returned (a server
 * worker hung on a full disk). Run in a child with an alarm so a hang
 * fails the test instead of the suite. */
static void test_write_fails_part_way(void **s) {
  const char *path = tmp_path("full.exr");
  gi_exr_image small = image(1, GI_EXR_ZIP);
  gi_error_info err = {0};
  assert_int_equal(gi_exr_write(path, &small, &err), GI_OK);
  size_t n0;
  unsigned char *before = slurp(path, &n0);
  pid_t pid = fork();
  assert_true(pid >= 0);
  if (pid == 0) {
    enum { BW = 512, BH = 512 };
    static float noise[BW * BH];
    uint32_t x = 12345;
    for (int i = 0; i < BW * BH; i++) x = x * 1664525u + 1013904223u, noise[i] = (float)(x >> 8) / 65536.f;
    gi_exr_channel ch = {"R", noise};
    gi_exr_image big = {.width = BW, .height = BH, .compression = GI_EXR_ZIP, .num_channels = 1, .channels = &ch};
    signal(SIGXFSZ, SIG_IGN);
    alarm(30);
    /* In the header (100, 300 bytes) and in the chunks (8 KiB, 64 KiB). */
    const rlim_t limits[] = {100, 300, 8 * 1024, 64 * 1024};
    for (int i = 0; i < 4; i++) {
      struct rlimit rl = {limits[i], RLIM_INFINITY};
      if (setrlimit(RLIMIT_FSIZE, &rl) != 0) _exit(3);
      gi_error_info e = {0};
      gi_result r = gi_exr_write(path, &big, &e);
      if (r != GI_ERR_IO || !strstr(e.msg, path)) _exit(10 + i);
    }
    _exit(0);
  }
  int status = 0;
  assert_int_equal(waitpid(pid, &status, 0), pid);
  if (WIFSIGNALED(status)) fail_msg("the failing write did not return (signal %d)", WTERMSIG(status));
  assert_true(WIFEXITED(status));
  assert_int_equal(WEXITSTATUS(status), 0);
  assert_file_is(path, before, n0);
  assert_no_temp_left();
}

/* Reads a file expected to be bad: must fail with a message naming it. */
static void expect_read_fails(const char *path, gi_result want) {
  gi_exr_file *f = (gi_exr_file *)(uintptr_t)1; /* must be reset to NULL */
  gi_error_info err = {0};
  gi_result r = gi_exr_read(path, &f, &err);
  if (r == GI_OK) fail_msg("reading '%s' succeeded", path);
  if (want != GI_OK) assert_int_equal(r, want);
  assert_null(f);
  assert_int_equal(err.code, r);
  assert_non_null(strstr(err.msg, path));
  for (const char *c = err.msg; *c; c++) /* printable: it may end up in JSON */
    assert_true(*c >= 0x20 && *c <= 0x7e);
}

static void test_read_bad_files(void **s) {
  expect_read_fails(tmp_path("missing.exr"), GI_ERR_NOT_FOUND);
  expect_read_fails(tu_write_file("empty.exr", "", 0), GI_ERR_FORMAT);

  unsigned char junk[4096];
  srand(1234);
  for (size_t i = 0; i < sizeof junk; i++) junk[i] = (unsigned char)(rand() >> 7);
  expect_read_fails(tu_write_file("junk.exr", junk, sizeof junk), GI_ERR_FORMAT);
  /* Junk behind a valid magic number and version gets past the first check. */
  memcpy(junk, "\x76\x2f\x31\x01\x02\x00\x00\x00", 8);
  expect_read_fails(tu_write_file("junk2.exr", junk, sizeof junk), GI_ERR_FORMAT);

  const char *good = tmp_path("good.exr");
  gi_exr_image img = image(1, GI_EXR_ZIP);
  gi_error_info err = {0};
  assert_int_equal(gi_exr_write(good, &img, &err), GI_OK);
  size_t n;
  unsigned char *bytes = slurp(good, &n);
  assert_true(n > 200);
  expect_read_fails(tu_write_file("trunc100.exr", bytes, 100), GI_ERR_FORMAT);
  /* Every cut through the header, offset table and chunk data fails cleanly. */
  for (size_t cut = 1; cut < n; cut += (cut < 64 ? 7 : 13)) {
    expect_read_fails(tu_write_file("trunc.exr", bytes, cut), GI_OK);
  }
  expect_read_fails(tu_write_file("trunc1.exr", bytes, n - 1), GI_OK);
  free(bytes);
  expect_read_fails(tu_tmpdir(), GI_ERR_IO); /* a directory */
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_round_trip_half_zip),
      cmocka_unit_test(test_round_trip_half_piz),
      cmocka_unit_test(test_round_trip_half_none),
      cmocka_unit_test(test_round_trip_float_zip),
      cmocka_unit_test(test_round_trip_float_piz),
      cmocka_unit_test(test_round_trip_float_none),
      cmocka_unit_test(test_small_zip_images_round_trip),
      cmocka_unit_test(test_many_chunks),
      cmocka_unit_test(test_half_clamps),
      cmocka_unit_test(test_exrheader_accepts),
      cmocka_unit_test(test_nan_rejected_no_file),
      cmocka_unit_test(test_bad_input_keeps_old_file),
      cmocka_unit_test(test_invalid_arguments),
      cmocka_unit_test(test_unwritable_path),
      cmocka_unit_test(test_write_fails_part_way),
      cmocka_unit_test(test_read_bad_files),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
