/* points_io.c: the probe-point text file (see gi_points.h). */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "gi/gi_points.h"
#include "base/internal.h"

/* Length of the plain decimal number at p ([+-]d[.d][e[+-]d], digits on
 * at least one side of the point), 0 when there is none: strtod alone also
 * takes hex ("0x10" read as 16), "infinity" and locale forms. */
static size_t decimal_len(const char *p) {
  size_t i = (*p == '+' || *p == '-'), d = 0;
  while (p[i] >= '0' && p[i] <= '9') i++, d++;
  if (p[i] == '.')
    for (i++; p[i] >= '0' && p[i] <= '9'; i++) d++;
  if (!d) return 0;
  if (p[i] == 'e' || p[i] == 'E') {
    size_t j = i + 1 + (p[i + 1] == '+' || p[i + 1] == '-'), e = j;
    while (p[j] >= '0' && p[j] <= '9') j++;
    if (j > e) i = j;
  }
  return i;
}

/* Three finite numbers separated by blanks, one comma, or both ("1 2 3",
 * "1,2,3", and "1, 0.5, 2" as numpy and Python print a list). */
static int parse_line(const char *p, double v[3]) {
  const char *q = p;
  for (int i = 0; i < 3; i++) {
    char *end;
    errno = 0;
    size_t len = decimal_len(q);
    if (!len) return -1;
    v[i] = strtod(q, &end);
    if ((size_t)(end - q) != len) return -1;
    /* ERANGE with |v| < 1 is underflow: a number within 1e-308 of 0, kept. */
    if (end == q || (errno == ERANGE && fabs(v[i]) >= 1.0) || !isfinite(v[i])) return -1;
    if (i < 2) {
      if (*end != ' ' && *end != '\t' && *end != ',') return -1;
      while (*end == ' ' || *end == '\t') end++;
      if (*end == ',') end++;
      while (*end == ' ' || *end == '\t') end++;
    }
    q = end;
  }
  return *q ? -1 : 0;
}

/* A column header ("x,y,z", "X Y Z", "px, py, pz", and quoted as a CSV
 * writer quotes every field: "\"x\",\"y\",\"z\""): three names, each
 * starting with a letter, separated as the numbers are. Spreadsheets and
 * pandas write one; it is taken on the first line only. */
static int header_line(const char *p) {
  int fields = 0;
  while (*p) {
    int quoted = *p == '"';
    p += quoted;
    if (!((*p >= 'a' && *p <= 'z') || (*p >= 'A' && *p <= 'Z'))) return 0;
    const char *f = p;
    char *end;
    strtod(f, &end);
    if (quoted)
      while (*p && *p != '"') p++;
    else
      while (*p && *p != ' ' && *p != '\t' && *p != ',') p++;
    if (end == p) return 0; /* "nan", "inf": bad numbers, not names; the line stays an error */
    if (quoted && *p++ != '"') return 0; /* no closing quote */
    if (*p && *p != ' ' && *p != '\t' && *p != ',') return 0;
    fields++;
    while (*p == ' ' || *p == '\t') p++;
    if (*p == ',') p++;
    while (*p == ' ' || *p == '\t') p++;
  }
  return fields == 3;
}

/* The start of a bad line for an error message: a binary file's bytes
 * (control characters, bytes past ASCII) become '?', so the message
 * cannot drive a terminal; a long line is cut with "...". */
static void printable(const char *p, char *out, size_t cap) {
  size_t i = 0;
  for (; p[i] && i + 4 < cap; i++) out[i] = (unsigned char)p[i] < 0x20 || (unsigned char)p[i] > 0x7e ? '?' : p[i];
  if (p[i]) memcpy(out + i, "...", 3), i += 3;
  out[i] = 0;
}

gi_result gi_points_read(const char *path, size_t max, double **pts, size_t *n, gi_error_info *err) {
  if (!pts || !n) return gi__fail(err, GI_ERR_INVALID_ARG, "gi_points_read: %s is NULL", pts ? "n" : "pts");
  *pts = NULL;
  *n = 0;
  if (!path) return gi__fail(err, GI_ERR_INVALID_ARG, "gi_points_read: path is NULL");
  FILE *f = fopen(path, "r");
  if (!f) return gi__fail(err, GI_ERR_IO, "cannot open '%s': %s", path, strerror(errno));
  char *line = NULL;
  size_t cap = 0, alloc = 0, lineno = 0;
  int seen = 0; /* a line with content: no header after it */
  double *out = NULL;
  gi_result rc = GI_OK;
  ssize_t got;
  while ((got = getline(&line, &cap, f)) >= 0) {
    lineno++;
    /* The line is read as a C string: a NUL byte in it hid the rest (the
     * second point of "1 2 3\0 4 5 6" was dropped without a word). */
    if (memchr(line, '\0', (size_t)got)) {
      rc = gi__fail(err, GI_ERR_FORMAT, "%s:%zu: a NUL byte in the line (a binary file?); expected 'x y z'", path,
                    lineno);
      break;
    }
    char *hash = strchr(line, '#');
    if (hash) *hash = '\0';
    char *p = line;
    /* A UTF-8 byte-order mark (Notepad's and Excel's "CSV UTF-8") starts some files. */
    if (lineno == 1 && !strncmp(p, "\xEF\xBB\xBF", 3)) p += 3;
    while (*p == ' ' || *p == '\t' || *p == '\r' || *p == '\n') p++;
    if (!*p) continue;
    size_t len = strlen(p);
    while (len && (p[len - 1] == ' ' || p[len - 1] == '\t' || p[len - 1] == '\r' || p[len - 1] == '\n'))
      p[--len] = '\0';
    double v[3];
    if (!seen++ && header_line(p)) continue;
    if (parse_line(p, v)) {
      char shown[64];
      printable(p, shown, sizeof shown);
      rc = gi__fail(err, GI_ERR_FORMAT, "%s:%zu: expected three finite numbers 'x y z', got '%s'", path, lineno,
                    shown);
      break;
    }
    if (*n >= max) {
      rc = gi__fail(err, GI_ERR_LIMIT, "%s:%zu: more than %zu points", path, lineno, max);
      break;
    }
    if (*n == alloc) {
      size_t na = alloc ? alloc * 2 : 64;
      double *np = gi__realloc(out, na * 3 * sizeof *np);
      if (!np) {
        rc = gi__fail(err, GI_ERR_NOMEM, "%s: out of memory", path);
        break;
      }
      out = np;
      alloc = na;
    }
    memcpy(&out[3 * (*n)++], v, sizeof v);
  }
  if (rc == GI_OK && ferror(f)) rc = gi__fail(err, GI_ERR_IO, "cannot read '%s': %s", path, strerror(errno));
  free(line); /* getline's buffer is libc's, not ours */
  fclose(f);
  if (rc != GI_OK) {
    gi__free(out);
    *n = 0;
    return rc;
  }
  gi__alloc_release(out); /* the caller frees it with free() */
  *pts = out;
  return GI_OK;
}
