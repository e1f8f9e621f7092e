/* test_toolargs.c: the tools' shared command-line helpers (tools/common).
 *
 * The one number rule: an integer is -?[0-9]+, a number is a plain finite
 * decimal, a list is exactly n numbers separated by commas; no '+', blanks,
 * hex, inf/nan, trailing bytes, or values out of range. Accepted inputs must
 * give the exact value; rejected ones the right status, an untouched output,
 * and a message that names the option and quotes the input. */
#include "test_util.h"
#include <getopt.h>
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "toolargs.h"

static ta_ctx quiet_ctx(void) {
  ta_ctx c = TA_CTX("gi-test");
  c.quiet = 1;
  return c;
}

static void test_int_accepts(void **state) {
  long long v = 0;
  assert_int_equal(ta_parse_ll("0", -10, 10, &v), TA_OK);
  assert_true(v == 0);
  assert_int_equal(ta_parse_ll("-0", -10, 10, &v), TA_OK);
  assert_true(v == 0);
  assert_int_equal(ta_parse_ll("42", 0, 100, &v), TA_OK);
  assert_true(v == 42);
  assert_int_equal(ta_parse_ll("-17", -20, 0, &v), TA_OK);
  assert_true(v == -17);
  assert_int_equal(ta_parse_ll("007", 0, 10, &v), TA_SYNTAX); /* no leading zeros, as the HTTP contract */
  assert_int_equal(ta_parse_ll("0", 0, 10, &v), TA_OK);
  assert_int_equal(v, 0);
  assert_int_equal(ta_parse_ll("-0", -1, 10, &v), TA_OK);
  assert_true(v == 0);
  assert_int_equal(ta_parse_ll("12", 1, 12, &v), TA_OK); /* bounds are inclusive */
  assert_true(v == 12);
  assert_int_equal(ta_parse_ll("9223372036854775807", LLONG_MIN, LLONG_MAX, &v), TA_OK);
  assert_true(v == LLONG_MAX);
  assert_int_equal(ta_parse_ll("-9223372036854775808", LLONG_MIN, LLONG_MAX, &v), TA_OK);
  assert_true(v == LLONG_MIN);
  assert_int_equal(ta_parse_ll("9007199254740992", 1, 9007199254740992LL, &v), TA_OK);
  assert_true(v == 9007199254740992LL);
}

static void test_int_rejects(void **state) {
  static const struct {
    const char *s;
    ta_status st;
  } bad[] = {
      {"", TA_EMPTY},       {"+5", TA_SYNTAX},    {" 5", TA_SYNTAX},    {"5 ", TA_SYNTAX},
      {"5x", TA_SYNTAX},    {"0x10", TA_SYNTAX},  {"1.0", TA_SYNTAX},   {"1e3", TA_SYNTAX},
      {"-", TA_SYNTAX},     {"--5", TA_SYNTAX},   {"-+5", TA_SYNTAX},   {"nan", TA_SYNTAX},
      {"5\n", TA_SYNTAX},   {"13", TA_RANGE},     {"0", TA_RANGE},      {"-1", TA_RANGE},
      {"99999999999999999999", TA_RANGE},         {"9223372036854775808", TA_RANGE},
      {"-9223372036854775809", TA_RANGE},
  };
  for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
    long long v = 1234;
    long long lo = 1, hi = 12;
    if (strlen(bad[i].s) > 15) lo = LLONG_MIN, hi = LLONG_MAX; /* the overflow cases */
    ta_status st = ta_parse_ll(bad[i].s, lo, hi, &v);
    if (st != bad[i].st) fprintf(stderr, "'%s': got status %d, want %d\n", bad[i].s, st, bad[i].st);
    assert_int_equal(st, bad[i].st);
    assert_true(v == 1234); /* untouched */
  }
}

static void test_u64(void **state) {
  uint64_t v = 0;
  assert_int_equal(ta_parse_u64("0", &v), TA_OK);
  assert_true(v == 0);
  assert_int_equal(ta_parse_u64("18446744073709551615", &v), TA_OK);
  assert_true(v == UINT64_MAX);
  v = 99;
  assert_int_equal(ta_parse_u64("18446744073709551616", &v), TA_RANGE);
  assert_int_equal(ta_parse_u64("-1", &v), TA_SYNTAX); /* strtoull would give UINT64_MAX */
  assert_int_equal(ta_parse_u64("+1", &v), TA_SYNTAX);
  assert_int_equal(ta_parse_u64(" 1", &v), TA_SYNTAX);
  assert_int_equal(ta_parse_u64("0x10", &v), TA_SYNTAX);
  assert_int_equal(ta_parse_u64("01", &v), TA_SYNTAX);
  assert_int_equal(ta_parse_u64("", &v), TA_EMPTY);
  assert_true(v == 99);
}

static void test_double_accepts(void **state) {
  static const struct {
    const char *s;
    double v;
  } ok[] = {{"1.5", 1.5},   {"-2e1", -20.0}, {".5", 0.5},     {"1.", 1.0},          {"1e+3", 1000.0},
            {"1E-2", 0.01}, {"0", 0.0},      {"-0.25", -0.25}, {"278", 278.0},      {"1e308", 1e308},
            {"007.5", 7.5}, {"3e2", 300.0},  {"-.5", -0.5},   {"20000", 20000.0}};
  for (size_t i = 0; i < sizeof ok / sizeof ok[0]; i++) {
    double v = -1234;
    assert_int_equal(ta_parse_double(ok[i].s, &v), TA_OK);
    assert_true(v == ok[i].v);
  }
  double z = 1;
  assert_int_equal(ta_parse_double("-0", &z), TA_OK);
  assert_true(z == 0 && signbit(z));
}

static void test_double_rejects(void **state) {
  static const struct {
    const char *s;
    ta_status st;
  } bad[] = {
      {"", TA_EMPTY},        {"+5", TA_SYNTAX},   {"nan", TA_SYNTAX},  {"NaN", TA_SYNTAX},
      {"inf", TA_SYNTAX},    {"-inf", TA_SYNTAX}, {"infinity", TA_SYNTAX}, {"0x10", TA_SYNTAX},
      {"0x1p3", TA_SYNTAX},  {"1e", TA_SYNTAX},   {"e5", TA_SYNTAX},   {".", TA_SYNTAX},
      {"-", TA_SYNTAX},      {" 1", TA_SYNTAX},   {"1 ", TA_SYNTAX},   {"1,2", TA_SYNTAX},
      {"5s", TA_SYNTAX},     {"1.2.3", TA_SYNTAX}, {"1e5.0", TA_SYNTAX}, {"--1", TA_SYNTAX},
      {"1e999", TA_RANGE},   {"-1e999", TA_RANGE},
  };
  for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
    double v = -1234;
    ta_status st = ta_parse_double(bad[i].s, &v);
    if (st != bad[i].st) fprintf(stderr, "'%s': got status %d, want %d\n", bad[i].s, st, bad[i].st);
    assert_int_equal(st, bad[i].st);
    assert_true(v == -1234);
  }
}

/* Underflow is a number within 1e-308 of 0, not out of range. */
static void test_double_underflow(void **state) {
  double v = -1;
  assert_int_equal(ta_parse_double("1e-400", &v), TA_OK);
  assert_true(v == 0.0);
  assert_int_equal(ta_parse_double("-2.5e-320", &v), TA_OK);
  assert_true(v < 0 && v > -1e-319);
  double t[3];
  assert_int_equal(ta_parse_doubles("1e-320,2,3", t, 3), TA_OK);
  assert_true(t[0] > 0 && t[0] < 1e-319 && t[1] == 2.0 && t[2] == 3.0);
}

static void test_lists(void **state) {
  double v[3] = {0, 0, 0};
  assert_int_equal(ta_parse_doubles("1,-2.5,3e2", v, 3), TA_OK);
  assert_true(v[0] == 1.0 && v[1] == -2.5 && v[2] == 300.0);
  assert_int_equal(ta_parse_doubles("278,273,279.6", v, 3), TA_OK);
  assert_true(v[0] == 278.0 && v[1] == 273.0 && v[2] == 279.6);
  double one;
  assert_int_equal(ta_parse_doubles("0.5", &one, 1), TA_OK);
  assert_true(one == 0.5);
  double nine[9];
  assert_int_equal(ta_parse_doubles("0,1,2,3,4,5,60,256,128", nine, 9), TA_OK);
  assert_true(nine[6] == 60.0 && nine[7] == 256.0 && nine[8] == 128.0);

  static const char *const bad[] = {"",        "1,2",       "1,2,3,",   "1,,3",      ",1,2",     "1,2,3 ",
                                    "1, 2,3",  "+1,2,3",    "0x10,2,3", "nan,0,0",   "1,2,inf",  "1,2,3,4",
                                    "1;2;3",   "1e999,0,0", "a,b,c",    "1,2,3\n"};
  for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
    double w[3] = {7, 7, 7};
    ta_status st = ta_parse_doubles(bad[i], w, 3);
    if (st == TA_OK) fprintf(stderr, "'%s' was accepted\n", bad[i]);
    assert_int_not_equal(st, TA_OK);
    assert_true(w[0] == 7 && w[1] == 7 && w[2] == 7); /* untouched, even in part */
  }
  assert_int_equal(ta_parse_doubles("1e999,0,0", v, 3), TA_RANGE);
  assert_int_equal(ta_parse_doubles("", v, 3), TA_EMPTY);
}

/* Each rejection: exit code 2, a message that names the option and quotes the input. */
static void expect_msg(const ta_ctx *c, int rc, const char *want) {
  if (rc != TA_EXIT_USAGE || strcmp(c->msg, want)) fprintf(stderr, "rc %d, msg '%s', want '%s'\n", rc, c->msg, want);
  assert_int_equal(rc, TA_EXIT_USAGE);
  assert_string_equal(c->msg, want);
}

static void test_option_messages(void **state) {
  ta_ctx c = quiet_ctx();
  int i = 0;
  long long l = 0;
  double d = 0, t[3];
  uint64_t u = 0;

  assert_int_equal(ta_int(&c, "--levels", NULL, "7", 1, 12, &i), 0);
  assert_int_equal(i, 7);
  expect_msg(&c, ta_int(&c, "--levels", NULL, "+5", 1, 12, &i), "--levels: expected an integer in 1..12, got '+5'");
  expect_msg(&c, ta_int(&c, "--levels", NULL, "5x", 1, 12, &i), "--levels: expected an integer in 1..12, got '5x'");
  expect_msg(&c, ta_int(&c, "--levels", NULL, "", 1, 12, &i), "--levels: expected an integer in 1..12, got ''");
  expect_msg(&c, ta_int(&c, "--levels", NULL, "0x10", 1, 12, &i),
             "--levels: expected an integer in 1..12, got '0x10'");
  expect_msg(&c, ta_int(&c, "--levels", NULL, "13", 1, 12, &i), "--levels: expected an integer in 1..12, got '13'");
  expect_msg(&c, ta_int(&c, "--threads", NULL, "99999999999999999999", 0, 256, &i),
             "--threads: expected an integer in 0..256, got '99999999999999999999'");
  /* ta_int's range is an int's: 2^31 is refused, not truncated. */
  expect_msg(&c, ta_int(&c, "--n", NULL, "2147483648", INT_MIN, INT_MAX, &i),
             "--n: expected an integer in -2147483648..2147483647, got '2147483648'");
  assert_int_equal(i, 7);
  expect_msg(&c, ta_int(&c, "--res", "a multiple of 4 in 8..256", "+16", 8, 256, &i),
             "--res: expected a multiple of 4 in 8..256, got '+16'");
  expect_msg(&c, ta_ll(&c, "--set: seed", "an integer >= 1", "0", 1, 9007199254740992LL, &l),
             "--set: seed: expected an integer >= 1, got '0'");

  assert_int_equal(ta_u64(&c, "--city-seed", NULL, "18446744073709551615", &u), 0);
  assert_true(u == UINT64_MAX);
  expect_msg(&c, ta_u64(&c, "--city-seed", NULL, "-3", &u), "--city-seed: expected an unsigned 64-bit integer, got '-3'");

  assert_int_equal(ta_double(&c, "--voxel", NULL, "0.25", 0, HUGE_VAL, &d), 0);
  assert_true(d == 0.25);
  expect_msg(&c, ta_double(&c, "--voxel", NULL, "1e999", 0, HUGE_VAL, &d),
             "--voxel: expected a finite number > 0, got '1e999'");
  expect_msg(&c, ta_double(&c, "--voxel", NULL, "nan", 0, HUGE_VAL, &d),
             "--voxel: expected a finite number > 0, got 'nan'");
  expect_msg(&c, ta_double(&c, "--voxel", NULL, "0", 0, HUGE_VAL, &d),
             "--voxel: expected a finite number > 0, got '0'");
  expect_msg(&c, ta_double(&c, "--voxel", NULL, "+1", 0, HUGE_VAL, &d),
             "--voxel: expected a finite number > 0, got '+1'");
  /* Without a description, a bounded range is named: 0 is finite but not in it. */
  expect_msg(&c, ta_double(&c, "--seconds", NULL, "0", 0, 3600, &d),
             "--seconds: expected a number in (0, 3600], got '0'");
  expect_msg(&c, ta_double(&c, "--x", NULL, "x", -HUGE_VAL, HUGE_VAL, &d), "--x: expected a finite number, got 'x'");
  expect_msg(&c, ta_double(&c, "--x", NULL, "2", -HUGE_VAL, 1, &d), "--x: expected a finite number <= 1, got '2'");
  assert_true(d == 0.25);
  /* (above, at_most]: the upper bound is included, the lower one is not. */
  assert_int_equal(ta_double(&c, "--city-extent", "metres in (0, 20000]", "20000", 0, 20000, &d), 0);
  assert_true(d == 20000.0);
  expect_msg(&c, ta_double(&c, "--city-extent", "metres in (0, 20000]", "20000.5", 0, 20000, &d),
             "--city-extent: expected metres in (0, 20000], got '20000.5'");
  expect_msg(&c, ta_double(&c, "--timeout", "seconds in (0, 1e6]", "5s", 0, 1e6, &d),
             "--timeout: expected seconds in (0, 1e6], got '5s'");

  assert_int_equal(ta_triple(&c, "--at", "10,1.7,-4", t), 0);
  assert_true(t[0] == 10.0 && t[1] == 1.7 && t[2] == -4.0);
  expect_msg(&c, ta_triple(&c, "--at", "1,2", t), "--at: expected three finite numbers X,Y,Z, got '1,2'");
  expect_msg(&c, ta_triple(&c, "--at", "1,2,3,", t), "--at: expected three finite numbers X,Y,Z, got '1,2,3,'");
  expect_msg(&c, ta_triple(&c, "--at", "1e999,0,0", t), "--at: expected three finite numbers X,Y,Z, got '1e999,0,0'");
  expect_msg(&c, ta_doubles(&c, "--sun", NULL, "1,2", 6, t),
             "--sun: expected 6 finite numbers separated by commas, got '1,2'");
  assert_true(t[0] == 10.0);
}

/* The printed form: "PROG: OPT: ..." then "Try 'PROG --help'." */
static void test_printed(void **state) {
  FILE *f = tmpfile();
  assert_non_null(f);
  ta_ctx c = TA_CTX("gi-test");
  c.err = f;
  int i;
  assert_int_equal(ta_int(&c, "--levels", NULL, "+5", 1, 12, &i), TA_EXIT_USAGE);
  assert_int_equal(ta_error(&c, TA_EXIT_RUN, "--probes", "cannot read '%s'", "p.txt"), TA_EXIT_RUN);
  assert_int_equal(ta_fail(&c, NULL, "missing SCENE"), TA_EXIT_USAGE);
  char buf[1024] = {0};
  rewind(f);
  size_t n = fread(buf, 1, sizeof buf - 1, f);
  fclose(f);
  buf[n] = '\0';
  assert_string_equal(buf, "gi-test: --levels: expected an integer in 1..12, got '+5'\n"
                           "Try 'gi-test --help'.\n"
                           "gi-test: --probes: cannot read 'p.txt'\n"
                           "gi-test: missing SCENE\n"
                           "Try 'gi-test --help'.\n");
}

/* getopt_long's ':' and '?' are named: the long option, the letter, the word. */
static void test_getopt(void **state) {
  static const struct option lo[] = {{"at", required_argument, NULL, 256},
                                     {"output", required_argument, NULL, 'o'},
                                     {"json", no_argument, NULL, 257},
                                     {NULL, 0, NULL, 0}};
  static const struct {
    const char *arg;
    const char *want;
  } cases[] = {{"--at", "option '--at' needs a value"},      {"-o", "option '-o' needs a value"},
               {"--output", "option '-o' needs a value"},    {"-x", "unknown option '-x'"},
               {"--bogus", "unknown option '--bogus'"},     {"--json=1", "unknown option '--json=1'"}};
  opterr = 0;
  for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
    char prog[] = "gi-test", arg[32];
    snprintf(arg, sizeof arg, "%s", cases[i].arg);
    char *argv[] = {prog, arg, NULL};
    optind = 0; /* glibc: start over */
    int r = getopt_long(2, argv, ":o:", lo, NULL);
    assert_true(r == ':' || r == '?');
    ta_ctx c = quiet_ctx();
    assert_int_equal(ta_getopt_fail(&c, r, argv, lo), TA_EXIT_USAGE);
    if (strcmp(c.msg, cases[i].want)) fprintf(stderr, "'%s': '%s'\n", cases[i].arg, c.msg);
    assert_string_equal(c.msg, cases[i].want);
  }
}

static void test_files(void **state) {
  ta_ctx c = quiet_ctx();
  const char *empty = "", *missing = "/no-such-dir-gi/x.exr";
  expect_msg(&c, ta_check_output(&c, "--exr", &empty), "--exr: expected a file name, got ''");
  assert_int_equal(ta_check_output(&c, "--exr", &missing), TA_EXIT_RUN);
  assert_non_null(strstr(c.msg, "--exr: cannot write into '/no-such-dir-gi' for '/no-such-dir-gi/x.exr'"));
  char path[1200];
  snprintf(path, sizeof path, "%s/out.exr", tu_tmpdir());
  const char *out = path, *dir = tu_tmpdir();
  assert_int_equal(ta_check_output(&c, "--exr", &out), 0);
  assert_string_equal(out, path);
  assert_int_equal(ta_check_output(&c, "--exr", &dir), TA_EXIT_USAGE);
  assert_non_null(strstr(c.msg, "is a folder"));
  assert_int_equal(ta_outputs_finish(&c, 1), 0);

  static const char good[] = "# points\n1 2 3\n-4.5 5 6e1  # note\n";
  const char *p = tu_write_file("pts.txt", good, sizeof good - 1);
  double *pts = NULL;
  size_t n = 0;
  assert_int_equal(ta_read_points(&c, "--probes", p, 16, &pts, &n), 0);
  assert_int_equal(n, 2);
  assert_true(pts[0] == 1 && pts[1] == 2 && pts[2] == 3 && pts[3] == -4.5 && pts[4] == 5 && pts[5] == 60);
  free(pts);
  static const char bad[] = "1 2 3\n4 5 x\n";
  p = tu_write_file("bad.txt", bad, sizeof bad - 1);
  pts = NULL;
  assert_int_equal(ta_read_points(&c, "--probes", p, 16, &pts, &n), TA_EXIT_USAGE);
  assert_non_null(strstr(c.msg, "--probes: "));
  assert_non_null(strstr(c.msg, "bad.txt:2"));
  free(pts);
  assert_int_equal(ta_read_points(&c, "--points", "/no-such-dir-gi/p.txt", 16, &pts, &n), TA_EXIT_RUN);
  assert_non_null(strstr(c.msg, "--points: "));
  /* A binary file's bytes are not echoed to the terminal; a long line is cut. */
  static const char bin[] = "\xff\x1b[2J1 2 3 x\n";
  p = tu_write_file("bin.txt", bin, sizeof bin - 1);
  pts = NULL;
  assert_int_equal(ta_read_points(&c, "--probes", p, 16, &pts, &n), TA_EXIT_USAGE);
  assert_non_null(strstr(c.msg, "got '??[2J1 2 3 x'"));
  free(pts);
  char longl[300];
  memset(longl, 'y', sizeof longl);
  memcpy(longl, "1 2 x", 5);
  longl[sizeof longl - 1] = '\n';
  p = tu_write_file("long.txt", longl, sizeof longl);
  pts = NULL;
  assert_int_equal(ta_read_points(&c, "--probes", p, 16, &pts, &n), TA_EXIT_USAGE);
  assert_non_null(strstr(c.msg, "got '1 2 xyyy"));
  assert_non_null(strstr(c.msg, "...'"));
  assert_true(strlen(c.msg) < 200);
  free(pts);
}

/* Spreadsheet files: a first line naming the columns is skipped (points:
 * three names, paths: four), CRLF too; a header later, a header of the
 * wrong width, and "nan" columns (bad numbers, not names) are errors. */
static void test_headers(void **state) {
  (void)state;
  ta_ctx c = quiet_ctx();
  double *pts = NULL;
  size_t n = 0;
  static const char ph[] = "# exported\r\nx, y, z\r\n1,2,3\r\n4 5 6\r\n";
  assert_int_equal(ta_read_points(&c, "--probes", tu_write_file("ph.csv", ph, sizeof ph - 1), 16, &pts, &n), 0);
  assert_int_equal(n, 2);
  assert_true(pts[0] == 1 && pts[5] == 6);
  free(pts);
  /* A comma with blanks around it, as numpy and Python print a list (it
   * was refused: "expected three finite numbers"), under a header quoted
   * as a CSV writer quotes every field (an error at line 1 before). */
  static const char pq[] = "\"x\",\"y\", \"z\"\n1, 0.5, 2\n3 ,4 , 5\n6\t,\t7,8\n";
  assert_int_equal(ta_read_points(&c, "--probes", tu_write_file("pq.csv", pq, sizeof pq - 1), 16, &pts, &n), 0);
  assert_int_equal(n, 3);
  const double want[9] = {1, 0.5, 2, 3, 4, 5, 6, 7, 8};
  for (int i = 0; i < 9; i++) assert_true(pts[i] == want[i]);
  free(pts);
  /* Two commas, a quoted header later, one cut short or of two names: errors. */
  const char *bad_pts[7] = {"1 2 3\nx y z\n", "x,y\n1,2,3\n", "nan nan nan\n1 2 3\n", "1,,2,3\n",
                            "1 2 3\n\"x\",\"y\",\"z\"\n", "\"x\",\"y\",\"z\n1 2 3\n", "\"x\",\"y\"\n1 2 3\n"};
  const char *bad_at[7] = {"bph0.csv:2", "bph1.csv:1", "bph2.csv:1", "bph3.csv:1", "bph4.csv:2", "bph5.csv:1",
                           "bph6.csv:1"};
  for (int i = 0; i < 7; i++) {
    char name[32];
    snprintf(name, sizeof name, "bph%d.csv", i);
    pts = NULL;
    assert_int_equal(ta_read_points(&c, "--probes", tu_write_file(name, bad_pts[i], strlen(bad_pts[i])), 16, &pts, &n),
                     TA_EXIT_USAGE);
    assert_non_null(strstr(c.msg, bad_at[i]));
    free(pts);
  }
  ta_step *st = NULL;
  static const char path[] = "t_s,x,y,z\r\n0,1,2,3\r\n# pause\r\n\r\n0.5, 4 ,5,6\r\n";
  assert_int_equal(ta_read_path(&c, "--path", tu_write_file("p.csv", path, sizeof path - 1), &st, &n), 0);
  assert_int_equal(n, 2);
  assert_true(st[0].t == 0 && st[0].at[2] == 3 && st[1].t == 0.5 && st[1].at[0] == 4);
  free(st);
  /* Excel's "CSV UTF-8" starts with a byte-order mark, before the header. */
  static const char bom_path[] = "\xEF\xBB\xBFt,x,y,z\n0,1,2,3\n";
  assert_int_equal(ta_read_path(&c, "--path", tu_write_file("bom.csv", bom_path, sizeof bom_path - 1), &st, &n), 0);
  assert_true(n == 1 && st[0].at[0] == 1);
  free(st);
  /* Plain decimals only: strtod alone read "0x10" as 16. */
  static const char hex_pts[] = "0x10 1 1\n";
  assert_int_equal(ta_read_points(&c, "--probes", tu_write_file("hex.txt", hex_pts, sizeof hex_pts - 1), 16, &pts, &n),
                   TA_EXIT_USAGE);
  assert_non_null(strstr(c.msg, "hex.txt:1"));
  static const char forms[] = "1. .5 -2e3\n+1 1E+2 0.25e-1\n";
  assert_int_equal(ta_read_points(&c, "--probes", tu_write_file("forms.txt", forms, sizeof forms - 1), 16, &pts, &n), 0);
  assert_true(n == 2 && pts[0] == 1 && pts[1] == 0.5 && pts[2] == -2000 && pts[3] == 1 && pts[4] == 100 &&
              pts[5] == 0.025);
  free(pts);
  static const char bom_pts[] = "\xEF\xBB\xBF" "1 2 3\n";
  assert_int_equal(ta_read_points(&c, "--probes", tu_write_file("bom.txt", bom_pts, sizeof bom_pts - 1), 16, &pts, &n), 0);
  assert_true(n == 1 && pts[0] == 1 && pts[2] == 3);
  free(pts);
  /* A blank inside a field: "2 1" read as 21 (blanks were stripped everywhere). */
  const char *bad_paths[5] = {"0,1,2,3\nt,x,y,z\n", "t,x,y\n0,1,2,3\n", "nan,nan,nan,nan\n", "1,0,0,0\n0,0,0,0\n",
                              "0,0,2,2\n0.1,2 1,0,2\n"};
  const char *why[5] = {"bp0.csv:2: expected t,x,y,z", "bp1.csv:1: expected t,x,y,z", "bp2.csv:1: expected t,x,y,z",
                        "bp3.csv:2: t = 0 goes back in time", "bp4.csv:2: expected t,x,y,z"};
  for (int i = 0; i < 5; i++) {
    char name[32];
    snprintf(name, sizeof name, "bp%d.csv", i);
    st = NULL;
    assert_int_equal(ta_read_path(&c, "--path", tu_write_file(name, bad_paths[i], strlen(bad_paths[i])), &st, &n),
                     TA_EXIT_USAGE);
    assert_non_null(strstr(c.msg, why[i]));
    free(st);
  }
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_int_accepts),    cmocka_unit_test(test_int_rejects), cmocka_unit_test(test_u64),
      cmocka_unit_test(test_double_accepts), cmocka_unit_test(test_double_rejects),
      cmocka_unit_test(test_double_underflow), cmocka_unit_test(test_lists),
      cmocka_unit_test(test_option_messages), cmocka_unit_test(test_printed),   cmocka_unit_test(test_getopt),
      cmocka_unit_test(test_files),          cmocka_unit_test(test_headers),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
