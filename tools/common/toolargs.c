/* toolargs.c: the tools' shared command-line helpers (see toolargs.h for
 * the one number rule). The grammar is checked by hand first; strtoll,
 * strtoull and strtod then only convert a string already known to be plain
 * decimal, so their leniencies (blanks, '+', hex, "inf", "nan", locale
 * prefixes) never reach a tool. */
#define _POSIX_C_SOURCE 200809L
#include "toolargs.h"
#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>
#include "gi/gi_cpu.h"
#include "gi/gi_points.h"
#include "gi_git_rev.h" /* GI_GIT_REV: generated at build time (cmake/git_rev.cmake) */

static int is_digit(char ch) { return ch >= '0' && ch <= '9'; }

/* Length of the leading run of digits of s. */
static size_t digits(const char *s) {
  size_t n = 0;
  while (is_digit(s[n])) n++;
  return n;
}

ta_status ta_parse_ll(const char *s, long long lo, long long hi, long long *out) {
  if (!*s) return TA_EMPTY;
  const char *p = s + (*s == '-');
  size_t n = digits(p);
  /* No leading zeros, as the HTTP contract: "07" is refused, "0" is not. */
  if (n == 0 || p[n] || (n > 1 && p[0] == '0')) return TA_SYNTAX;
  errno = 0;
  long long v = strtoll(s, NULL, 10);
  if (errno == ERANGE || v < lo || v > hi) return TA_RANGE;
  *out = v;
  return TA_OK;
}

ta_status ta_parse_u64(const char *s, uint64_t *out) {
  if (!*s) return TA_EMPTY;
  size_t n = digits(s);
  /* no '-': strtoull would negate "-1" silently; no leading zeros, as in ta_parse_ll */
  if (n == 0 || s[n] || (n > 1 && s[0] == '0')) return TA_SYNTAX;
  errno = 0;
  unsigned long long v = strtoull(s, NULL, 10);
  if (errno == ERANGE) return TA_RANGE;
  *out = (uint64_t)v;
  return TA_OK;
}

/* Length of the plain decimal number at the start of s, 0 if there is none. */
static size_t number_len(const char *s) {
  size_t i = *s == '-';
  size_t whole = digits(s + i), frac = 0;
  i += whole;
  if (s[i] == '.') {
    frac = digits(s + i + 1);
    i += 1 + frac;
  }
  if (whole == 0 && frac == 0) return 0;
  if (s[i] == 'e' || s[i] == 'E') {
    size_t j = i + 1;
    if (s[j] == '+' || s[j] == '-') j++;
    size_t e = digits(s + j);
    if (e == 0) return 0;
    i = j + e;
  }
  return i;
}

/* One number at the start of s, followed by the byte `end` ('\0' or ','). */
static ta_status number_at(const char *s, char end, double *out) {
  size_t n = number_len(s);
  if (n == 0 || s[n] != end) return s[0] == '\0' || s[0] == ',' ? TA_EMPTY : TA_SYNTAX;
  errno = 0;
  double v = strtod(s, NULL);
  /* ERANGE with |v| < 1 is underflow: a number within 1e-308 of 0, kept. */
  if ((errno == ERANGE && fabs(v) >= 1.0) || !isfinite(v)) return TA_RANGE;
  *out = v;
  return TA_OK;
}

ta_status ta_parse_double(const char *s, double *out) {
  return number_at(s, '\0', out);
}

ta_status ta_parse_doubles(const char *s, double *out, int n) {
  double tmp[64];
  if (n < 1 || n > 64) return TA_RANGE;
  const char *p = s;
  for (int i = 0; i < n; i++) {
    ta_status st = number_at(p, i + 1 < n ? ',' : '\0', &tmp[i]);
    if (st != TA_OK) return st == TA_EMPTY && *s ? TA_SYNTAX : st;
    if (i + 1 < n) p += number_len(p) + 1; /* past the number and its comma */
  }
  memcpy(out, tmp, (size_t)n * sizeof *out);
  return TA_OK;
}

/* ---- messages ---------------------------------------------------------- */

static void vemit(ta_ctx *c, int try_line, const char *opt, const char *fmt, va_list ap) {
  size_t k = 0;
  if (opt) k = (size_t)snprintf(c->msg, sizeof c->msg, "%s: ", opt);
  if (k < sizeof c->msg) vsnprintf(c->msg + k, sizeof c->msg - k, fmt, ap);
  if (c->quiet) return;
  FILE *f = c->err ? c->err : stderr;
  fprintf(f, "%s: %s\n", c->prog, c->msg);
  if (try_line) fprintf(f, "Try '%s --help'.\n", c->prog);
}

int ta_fail(ta_ctx *c, const char *opt, const char *fmt, ...) {
  va_list ap;
  va_start(ap, fmt);
  vemit(c, 1, opt, fmt, ap);
  va_end(ap);
  return TA_EXIT_USAGE;
}

int ta_error(ta_ctx *c, int rc, const char *opt, const char *fmt, ...) {
  va_list ap;
  va_start(ap, fmt);
  vemit(c, 0, opt, fmt, ap);
  va_end(ap);
  return rc;
}

/* ---- option-level parsers ---------------------------------------------- */

int ta_ll(ta_ctx *c, const char *opt, const char *what, const char *s, long long lo, long long hi, long long *out) {
  if (ta_parse_ll(s, lo, hi, out) == TA_OK) return 0;
  if (what) return ta_fail(c, opt, "expected %s, got '%s'", what, s);
  return ta_fail(c, opt, "expected an integer in %lld..%lld, got '%s'", lo, hi, s);
}

int ta_int(ta_ctx *c, const char *opt, const char *what, const char *s, int lo, int hi, int *out) {
  long long v = 0;
  int rc = ta_ll(c, opt, what, s, lo, hi, &v);
  if (!rc) *out = (int)v;
  return rc;
}

int ta_u64(ta_ctx *c, const char *opt, const char *what, const char *s, uint64_t *out) {
  if (ta_parse_u64(s, out) == TA_OK) return 0;
  return ta_fail(c, opt, "expected %s, got '%s'", what ? what : "an unsigned 64-bit integer", s);
}

int ta_double(ta_ctx *c, const char *opt, const char *what, const char *s, double above, double at_most,
              double *out) {
  double v;
  if (ta_parse_double(s, &v) == TA_OK && v > above && v <= at_most) {
    *out = v;
    return 0;
  }
  if (what) return ta_fail(c, opt, "expected %s, got '%s'", what, s);
  /* Without a description the bounds say what was expected. */
  if (isinf(above) && isinf(at_most)) return ta_fail(c, opt, "expected a finite number, got '%s'", s);
  if (isinf(at_most)) return ta_fail(c, opt, "expected a finite number > %g, got '%s'", above, s);
  if (isinf(above)) return ta_fail(c, opt, "expected a finite number <= %g, got '%s'", at_most, s);
  return ta_fail(c, opt, "expected a number in (%g, %g], got '%s'", above, at_most, s);
}

int ta_doubles(ta_ctx *c, const char *opt, const char *what, const char *s, int n, double *out) {
  if (ta_parse_doubles(s, out, n) == TA_OK) return 0;
  if (what) return ta_fail(c, opt, "expected %s, got '%s'", what, s);
  return ta_fail(c, opt, "expected %d finite numbers separated by commas, got '%s'", n, s);
}

int ta_triple(ta_ctx *c, const char *opt, const char *s, double out[3]) {
  return ta_doubles(c, opt, "three finite numbers X,Y,Z", s, 3, out);
}

/* ---- getopt, outputs, points, version ---------------------------------- */

int ta_getopt_fail(ta_ctx *c, int ret, char **argv, const struct option *long_opts) {
  if (ret == ':') {
    /* Short options are named by their letter, long ones (val >= 256) by name. */
    if (optopt > 0 && optopt < 256) return ta_fail(c, NULL, "option '-%c' needs a value", optopt);
    for (const struct option *lo = long_opts; lo && lo->name; lo++)
      if (lo->val == optopt) return ta_fail(c, NULL, "option '--%s' needs a value", lo->name);
    return ta_fail(c, NULL, "option '%s' needs a value", argv[optind - 1]);
  }
  if (optopt > 0 && optopt < 256) return ta_fail(c, NULL, "unknown option '-%c'", optopt);
  return ta_fail(c, NULL, "unknown option '%s'", argv[optind - 1]);
}

int ta_once(ta_ctx *c, const struct option *long_opts, int val, const int *repeatable, unsigned char *seen) {
  for (const int *r = repeatable; r && *r; r++)
    if (*r == val) return 0;
  for (int i = 0; long_opts[i].name; i++) {
    if (long_opts[i].val != val || long_opts[i].has_arg == no_argument) continue;
    if (seen[i]) {
      char opt[64];
      snprintf(opt, sizeof opt, "--%s", long_opts[i].name);
      return ta_fail(c, opt, "given twice (it takes one value)");
    }
    seen[i] = 1;
    return 0;
  }
  return 0;
}

int ta_mkdirs(ta_ctx *c, const char *opt, const char *path) {
  char *b = strdup(path);
  if (!b) return ta_error(c, TA_EXIT_RUN, opt, "out of memory");
  int rc = 0;
  for (char *s = b + 1; *s && !rc; s++)
    if (*s == '/') {
      *s = 0;
      if (mkdir(b, 0777) && errno != EEXIST)
        rc = ta_error(c, TA_EXIT_RUN, opt, "cannot create '%s': %s", b, strerror(errno));
      *s = '/';
    }
  if (!rc && mkdir(b, 0777) && errno != EEXIST)
    rc = ta_error(c, TA_EXIT_RUN, opt, "cannot create '%s': %s", b, strerror(errno));
  /* EEXIST is also a plain file of that name: the run would fail at its
   * first write into it, perhaps hours later. */
  struct stat st;
  if (!rc && (stat(b, &st) != 0 || !S_ISDIR(st.st_mode)))
    rc = ta_error(c, TA_EXIT_RUN, opt, "'%s' exists and is not a folder", b);
  else if (!rc && access(b, W_OK | X_OK) != 0)
    rc = ta_error(c, TA_EXIT_RUN, opt, "cannot write into '%s': %s", b, strerror(errno));
  free(b);
  return rc;
}

/* A path line's fields: "t,x,y,z" with blanks around, '#' starts a comment. */
static int path_blank(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\n'; }

static int path_line(char *line, double v[4]) {
  char *hash = strchr(line, '#');
  if (hash) *hash = 0;
  /* Blanks around the commas only: "0.1,2 1,0,2" read x as 21. A field
   * with a blank inside is refused (after the strip, so the caller's
   * header test still sees the text). */
  int inside = 0;
  char prev = 0; /* the last non-blank */
  for (const char *p = line; *p; p++) {
    if (path_blank(*p)) continue;
    if (prev && prev != ',' && *p != ',' && path_blank(p[-1])) inside = 1;
    prev = *p;
  }
  char *p = line, *q = line;
  for (; *p; p++)
    if (!path_blank(*p)) *q++ = *p;
  *q = 0;
  if (!*line) return 1; /* blank or comment only */
  return !inside && ta_parse_doubles(line, v, 4) == TA_OK ? 0 : -1;
}

/* A column header ("t,x,y,z", "time_s,x,y,z"): four comma-separated names,
 * each starting with a letter, as spreadsheets and pandas write them.
 * Allowed on the first line only; line holds path_line's blank-free text. */
static int path_header(const char *line) {
  int fields = 0;
  for (const char *f = line; f; f = strchr(f, ',') ? strchr(f, ',') + 1 : NULL) {
    if (!((*f >= 'a' && *f <= 'z') || (*f >= 'A' && *f <= 'Z'))) return 0;
    char *end;
    strtod(f, &end);
    if (end == f + strcspn(f, ",")) return 0; /* "nan", "inf": bad numbers, not names; the line stays an error */
    fields++;
  }
  return fields == 4;
}

int ta_read_path(ta_ctx *ta, const char *opt, const char *path, ta_step **out, size_t *n) {
  FILE *f = fopen(path, "r");
  if (!f) return ta_error(ta, TA_EXIT_RUN, opt, "cannot open '%s': %s", path, strerror(errno));
  ta_step *s = NULL;
  size_t cap = 0, k = 0;
  char line[TA_PATH_LINE_MAX + 2];
  int rc = 0, seen = 0; /* seen: a line that is not blank or a comment, so no header may follow */
  for (long no = 1; !rc && fgets(line, sizeof line, f); no++) {
    if (!strchr(line, '\n') && !feof(f)) {
      rc = ta_error(ta, TA_EXIT_USAGE, opt, "%s:%ld: line longer than %d bytes", path, no, TA_PATH_LINE_MAX);
      break;
    }
    /* A UTF-8 byte-order mark (Excel's "CSV UTF-8") starts some files. */
    if (no == 1 && !strncmp(line, "\xEF\xBB\xBF", 3)) memmove(line, line + 3, strlen(line + 3) + 1);
    char copy[sizeof line];
    snprintf(copy, sizeof copy, "%s", line);
    copy[strcspn(copy, "\r\n")] = 0;
    double v[4] = {0, 0, 0, 0};
    int st = path_line(line, v);
    if (st > 0) continue;
    if (st < 0 && !k && !seen && path_header(line)) {
      seen = 1;
      continue;
    }
    seen = 1;
    if (st < 0) rc = ta_error(ta, TA_EXIT_USAGE, opt, "%s:%ld: expected t,x,y,z (four finite numbers), got '%.80s'",
                              path, no, copy);
    else if (k && v[0] < s[k - 1].t)
      rc = ta_error(ta, TA_EXIT_USAGE, opt, "%s:%ld: t = %g goes back in time (the line before has %g)", path, no,
                    v[0], s[k - 1].t);
    if (rc) break;
    if (k == cap) {
      cap = cap ? 2 * cap : 64;
      ta_step *ns = realloc(s, cap * sizeof *ns);
      if (!ns) {
        rc = ta_error(ta, TA_EXIT_RUN, opt, "out of memory");
        break;
      }
      s = ns;
    }
    s[k++] = (ta_step){v[0], {v[1], v[2], v[3]}};
  }
  if (!rc && ferror(f)) rc = ta_error(ta, TA_EXIT_RUN, opt, "cannot read '%s'", path);
  fclose(f);
  if (!rc && !k) rc = ta_error(ta, TA_EXIT_USAGE, opt, "%s: no steps (one 't,x,y,z' per line expected)", path);
  if (rc) {
    free(s);
    return rc;
  }
  *out = s;
  *n = k;
  return 0;
}

int ta_read_points(ta_ctx *c, const char *opt, const char *path, size_t max, double **pts, size_t *n) {
  gi_error_info e = {0};
  gi_result rc = gi_points_read(path, max, pts, n, &e);
  if (rc != GI_OK)
    return ta_error(c, rc == GI_ERR_FORMAT || rc == GI_ERR_LIMIT ? TA_EXIT_USAGE : TA_EXIT_RUN, opt, "%s", e.msg);
  /* A file of comments only (the wrong file, a commented-out list) is a
   * mistake every tool must say: gi-bake baked the viewpoint alone and
   * gi-accuracy measured its default points instead, both with success. */
  if (*n == 0) return ta_fail(c, opt, "'%s' holds no points (expected one 'x y z' per line)", path);
  return 0;
}

const char *ta_version(void) {
#ifndef GI_VERSION
#define GI_VERSION "0.0.0"
#endif
  return GI_VERSION " (" GI_GIT_REV ")";
}

int ta_check_cpu_path(ta_ctx *c) {
  char why[256];
  if (!gi_cpu_path_check(why, sizeof why)) return 0;
  return ta_error(c, TA_EXIT_USAGE, NULL, "%s", why);
}

uint64_t ta_fnv(uint64_t h, const void *p, size_t n) {
  const unsigned char *b = p;
  for (size_t i = 0; i < n; i++) h = (h ^ b[i]) * 1099511628211ull;
  return h;
}

uint64_t ta_fnv_file(uint64_t h, const char *path) {
  FILE *f = fopen(path, "rb");
  char buf[1 << 16];
  size_t k;
  while (f && (k = fread(buf, 1, sizeof buf, f)) > 0) h = ta_fnv(h, buf, k);
  if (f) fclose(f);
  return h;
}
