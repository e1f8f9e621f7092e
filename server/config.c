/* config.c: the server's INI file (inih glue), validated at start.
 *
 * Every key is checked as it is read: its type, its range, and that it
 * belongs to its section. The first problem stops the load with a message
 * "FILE:LINE: [section] key: expected ..., got '...'" so a bad deployment
 * fails at start, never on the first request. Scene paths are resolved
 * against the config file's folder so the same file works from any cwd. */
#define _POSIX_C_SOURCE 200809L
#include <arpa/inet.h>
#include <errno.h>
#include <ini.h>
#include <limits.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>
#include <unistd.h>
#include "server.h"

void gs_config_defaults(gs_config *c) {
  memset(c, 0, sizeof *c);
  snprintf(c->bind, sizeof c->bind, "127.0.0.1");
  c->port = 8080;
  c->connection_threads = 4;
  c->workers = 2;
  c->queue = 32;
  c->bake_threads = 0;
  c->deadline_s = 120;
  c->max_connections_per_ip = 128;
  c->request_timeout_s = 30;
  c->shutdown_grace_s = 10;
  c->job_deadline_s = 3600;
  gi_proto_limits_default(&c->lim);
  c->max_tiles_inline = 4;
  c->cache_bytes = (size_t)1024 << 20;
  c->max_sessions = 8;
  c->session_ttl_s = 300;
  c->max_jobs = 1;
  c->max_jobs_queued = 16;
  c->max_jobs_retained = 64;
}

typedef struct {
  gs_config *c;
  char dir[1024];
  char err[1400];
  int line;            /* current line, counted by our reader */
  gs_scene_conf *cur;  /* the [scene ID] being read */
  char token_file[1024];
  int token_line;      /* where token_file was set */
  struct seen_key {    /* every key set so far, to refuse a second value */
    char sec[80], key[64];
    int line;
  } *seen;
  size_t num_seen;
} load_ctx;

static int fail(load_ctx *x, const char *section, const char *key, const char *fmt, ...)
    __attribute__((format(printf, 4, 5)));
static int fail(load_ctx *x, const char *section, const char *key, const char *fmt, ...) {
  if (x->err[0]) return 0;
  char msg[400];
  va_list ap;
  va_start(ap, fmt);
  vsnprintf(msg, sizeof msg, fmt, ap);
  va_end(ap);
  snprintf(x->err, sizeof x->err, "%s:%d: [%s] %s: %s", x->c->path, x->line, section, key, msg);
  return 0;
}

static int get_int(load_ctx *x, const char *sec, const char *key, const char *v, long long lo, long long hi,
                   long long *out) {
  char *end;
  errno = 0;
  long long n = strtoll(v, &end, 10);
  if (end == v || *end || errno == ERANGE || n < lo || n > hi)
    return fail(x, sec, key, "expected an integer in %lld..%lld, got '%s'", lo, hi, v);
  *out = n;
  return 1;
}

static int get_num(load_ctx *x, const char *sec, const char *key, const char *v, double lo, double hi,
                   double *out) {
  char *end;
  errno = 0;
  double d = strtod(v, &end);
  /* ERANGE with |d| < 1 is underflow: a number within 1e-308 of 0, kept. */
  if (end == v || *end || (errno == ERANGE && fabs(d) >= 1.0) || !isfinite(d) || d < lo || d > hi)
    return fail(x, sec, key, "expected a number in %g..%g, got '%s'", lo, hi, v);
  *out = d;
  return 1;
}

static int get_bool(load_ctx *x, const char *sec, const char *key, const char *v, int *out) {
  if (!strcasecmp(v, "yes") || !strcasecmp(v, "true") || !strcmp(v, "1")) *out = 1;
  else if (!strcasecmp(v, "no") || !strcasecmp(v, "false") || !strcmp(v, "0")) *out = 0;
  else return fail(x, sec, key, "expected yes or no, got '%s'", v);
  return 1;
}

static int resolve_path(load_ctx *x, const char *sec, const char *key, const char *v, char *out, size_t size) {
  int n = v[0] == '/' || !x->dir[0] ? snprintf(out, size, "%s", v) : snprintf(out, size, "%s/%s", x->dir, v);
  if (n < 0 || (size_t)n >= size) return fail(x, sec, key, "path longer than %zu bytes", size - 1);
  return 1;
}

static int server_key(load_ctx *x, const char *k, const char *v) {
  gs_config *c = x->c;
  long long n = 0;
  double d = 0;
  const char *S = "server";
  if (!strcmp(k, "bind")) {
    struct in_addr a; /* checked here, so --check-config sees it and the line is named */
    if (!*v || strlen(v) >= sizeof c->bind || inet_pton(AF_INET, v, &a) != 1)
      return fail(x, S, k, "expected an IPv4 address, got '%s'", v);
    snprintf(c->bind, sizeof c->bind, "%s", v);
  } else if (!strcmp(k, "port")) {
    if (!get_int(x, S, k, v, 0, 65535, &n)) return 0;
    c->port = (int)n;
  } else if (!strcmp(k, "connection_threads")) {
    if (!get_int(x, S, k, v, 1, 256, &n)) return 0;
    c->connection_threads = (int)n;
  } else if (!strcmp(k, "workers")) {
    if (!get_int(x, S, k, v, 1, 256, &n)) return 0;
    c->workers = (int)n;
  } else if (!strcmp(k, "queue")) {
    if (!get_int(x, S, k, v, 0, 100000, &n)) return 0;
    c->queue = (int)n;
  } else if (!strcmp(k, "bake_threads")) {
    if (!get_int(x, S, k, v, 0, 256, &n)) return 0;
    c->bake_threads = (int)n;
  } else if (!strcmp(k, "deadline_s")) {
    if (!get_num(x, S, k, v, 0.1, 86400, &d)) return 0;
    c->deadline_s = d;
  } else if (!strcmp(k, "max_connections_per_ip")) {
    if (!get_int(x, S, k, v, 1, 1000, &n)) return 0;
    c->max_connections_per_ip = (int)n;
  } else if (!strcmp(k, "request_timeout_s")) {
    if (!get_num(x, S, k, v, 0.5, 3600, &d)) return 0;
    c->request_timeout_s = d;
  } else if (!strcmp(k, "shutdown_grace_s")) {
    if (!get_num(x, S, k, v, 0.1, 3600, &d)) return 0;
    c->shutdown_grace_s = d;
  } else if (!strcmp(k, "token_file")) {
    x->token_line = x->line;
    if (*v) return resolve_path(x, S, k, v, x->token_file, sizeof x->token_file);
  } else if (!strcmp(k, "tmp_dir")) {
    if (*v) return resolve_path(x, S, k, v, c->tmp_dir, sizeof c->tmp_dir);
  } else {
    return fail(x, S, k, "unknown key (expected bind, port, connection_threads, workers, queue, bake_threads, "
                         "deadline_s, max_connections_per_ip, request_timeout_s, shutdown_grace_s, token_file, "
                         "tmp_dir)");
  }
  return 1;
}

static int limits_key(load_ctx *x, const char *k, const char *v) {
  gs_config *c = x->c;
  long long n = 0;
  double d = 0;
  const char *S = "limits";
  if (!strcmp(k, "max_body_bytes")) {
    if (!get_int(x, S, k, v, 64, 1ll << 32, &n)) return 0;
    c->lim.max_body_bytes = (size_t)n;
  } else if (!strcmp(k, "max_probes_inline")) {
    if (!get_int(x, S, k, v, 1, 1 << 24, &n)) return 0;
    c->lim.max_probes_inline = (size_t)n;
  } else if (!strcmp(k, "max_probes_job")) {
    if (!get_int(x, S, k, v, 1, 1 << 24, &n)) return 0;
    c->lim.max_probes_job = (size_t)n;
  } else if (!strcmp(k, "max_levels")) {
    if (!get_int(x, S, k, v, 1, GI_MAX_LEVELS, &n)) return 0;
    c->lim.max_levels = (int)n;
  } else if (!strcmp(k, "max_res")) {
    if (!get_int(x, S, k, v, 8, 256, &n)) return 0;
    c->lim.max_res = (int)n;
  } else if (!strcmp(k, "max_panorama_pixels")) {
    if (!get_int(x, S, k, v, 2, 1ll << 26, &n)) return 0;
    c->lim.max_panorama_pixels = n;
  } else if (!strcmp(k, "max_tiles_inline")) {
    if (!get_int(x, S, k, v, 1, 1024, &n)) return 0;
    c->max_tiles_inline = (int)n;
  } else if (!strcmp(k, "cache_mb")) {
    if (!get_int(x, S, k, v, 0, 1 << 20, &n)) return 0;
    c->cache_bytes = (size_t)n << 20;
  } else if (!strcmp(k, "max_jobs")) {
    if (!get_int(x, S, k, v, 1, 64, &n)) return 0;
    c->max_jobs = (int)n;
  } else if (!strcmp(k, "max_jobs_queued")) {
    if (!get_int(x, S, k, v, 0, 100000, &n)) return 0;
    c->max_jobs_queued = (int)n;
  } else if (!strcmp(k, "max_jobs_retained")) {
    if (!get_int(x, S, k, v, 1, 100000, &n)) return 0;
    c->max_jobs_retained = (int)n;
  } else if (!strcmp(k, "job_deadline_s")) {
    if (!get_num(x, S, k, v, 0.1, 604800, &d)) return 0;
    c->job_deadline_s = d;
  } else if (!strcmp(k, "max_sessions")) {
    if (!get_int(x, S, k, v, 1, 100000, &n)) return 0;
    c->max_sessions = (int)n;
  } else if (!strcmp(k, "session_ttl_s")) {
    if (!get_num(x, S, k, v, 0.1, 604800, &d)) return 0;
    c->session_ttl_s = d;
  } else {
    return fail(x, S, k, "unknown key (expected max_body_bytes, max_probes_inline, max_probes_job, max_levels, "
                         "max_res, max_panorama_pixels, max_tiles_inline, cache_mb, max_jobs, max_jobs_queued, "
                         "max_jobs_retained, job_deadline_s, max_sessions, session_ttl_s)");
  }
  return 1;
}

static int scene_key(load_ctx *x, const char *sec, const char *k, const char *v) {
  gs_scene_conf *s = x->cur;
  long long n = 0;
  double d = 0;
  if (!strcmp(k, "source")) {
    if (!*v) return fail(x, sec, k, "expected 'city' or a scene file path");
    s->source_line = x->line;
    if (!strcmp(v, "city")) {
      s->is_city = 1;
      snprintf(s->source, sizeof s->source, "city");
    } else {
      s->is_city = 0;
      return resolve_path(x, sec, k, v, s->source, sizeof s->source);
    }
  } else if (!strcmp(k, "up")) {
    if (!strcmp(v, "y")) s->up = GI_UP_Y;
    else if (!strcmp(v, "z")) s->up = GI_UP_Z;
    else return fail(x, sec, k, "expected y or z, got '%s'", v);
  } else if (!strcmp(k, "optional")) {
    return get_bool(x, sec, k, v, &s->optional);
  } else if (!strcmp(k, "extent")) {
    if (!get_num(x, sec, k, v, 100, 20000, &d)) return 0;
    s->extent = d;
  } else if (!strcmp(k, "seed")) {
    /* The full unsigned 64-bit range, as gi-bake --city-seed takes it. */
    char *end;
    errno = 0;
    unsigned long long u = strtoull(v, &end, 10);
    if (end == v || *end || errno == ERANGE || v[strspn(v, " \t")] == '-')
      return fail(x, sec, k, "expected an integer in 0..%llu, got '%s'", (unsigned long long)UINT64_MAX, v);
    s->seed = (uint64_t)u;
  } else if (!strcmp(k, "detail")) {
    if (!get_int(x, sec, k, v, 1, 8, &n)) return 0;
    s->detail = (int)n;
  } else {
    return fail(x, sec, k, "unknown key (expected source, up, optional, extent, seed, detail)");
  }
  return 1;
}

static int valid_id(const char *id) {
  size_t n = strlen(id);
  if (n == 0 || n > 63) return 0;
  for (const char *p = id; *p; p++)
    if (!((*p >= 'a' && *p <= 'z') || (*p >= 'A' && *p <= 'Z') || (*p >= '0' && *p <= '9') || *p == '-' ||
          *p == '_'))
      return 0;
  return 1;
}

/* The line where [section] key was set, else 0. */
static int line_of(const load_ctx *x, const char *section, const char *key) {
  for (size_t i = 0; i < x->num_seen; i++)
    if (!strcmp(x->seen[i].sec, section) && !strcmp(x->seen[i].key, key)) return x->seen[i].line;
  return 0;
}

/* A key given twice in a section (or in a repeated [server] or [limits]) is
 * refused: the last value silently won. inih also hands an indented line
 * to the key above it as a second value, so "workers = 2" then "  8" on the
 * next line would have set 8. Called once the value was accepted. */
static int once(load_ctx *x, const char *section, const char *name) {
  int first = line_of(x, section, name);
  if (first)
    return fail(x, section, name, "given twice (first on line %d; an indented line continues the key above it)",
                first);
  struct seen_key *ns = realloc(x->seen, (x->num_seen + 1) * sizeof *ns);
  if (!ns) return fail(x, section, name, "out of memory");
  x->seen = ns;
  struct seen_key *k = &ns[x->num_seen++];
  snprintf(k->sec, sizeof k->sec, "%s", section);
  snprintf(k->key, sizeof k->key, "%s", name);
  k->line = x->line;
  return 1;
}

static int on_entry(void *user, const char *section, const char *name, const char *value) {
  load_ctx *x = user;
  if (x->err[0]) return 0;
  if (!strcmp(section, "server")) return server_key(x, name, value) && once(x, section, name);
  if (!strcmp(section, "limits")) return limits_key(x, name, value) && once(x, section, name);
  if (!strncmp(section, "scene ", 6)) {
    /* scene_header made it, with its whole id: inih cuts a section's name
     * at 49 bytes, so a long id would read as another scene's. */
    if (!x->cur) return fail(x, section, name, "no [scene ID] header seen (a byte-order mark?)");
    char sec[80];
    snprintf(sec, sizeof sec, "scene %s", x->cur->id);
    return scene_key(x, sec, name, value) && once(x, sec, name);
  }
  return fail(x, section, name, "unknown section (expected [server], [limits] or [scene ID])");
}

/* A "[scene ID]" header line, seen by read_line before inih: the scene is
 * made here, so an id is never cut short, a section without keys is still
 * a scene (and needs its source), and a second header for an id, even
 * right after the first, is refused. Other headers are left to inih. */
static int scene_header(load_ctx *x, const char *name, size_t len) {
  if (len < 6 || strncmp(name, "scene ", 6)) return 1;
  char id[80];
  snprintf(id, sizeof id, "%.*s", (int)(len - 6 < sizeof id ? len - 6 : sizeof id - 1), name + 6);
  const char *why = NULL;
  int first = 0;
  gs_config *c = x->c;
  if (len - 6 >= sizeof id || !valid_id(id)) why = "must be 1..63 of [A-Za-z0-9_-]";
  for (size_t i = 0; !why && i < c->num_scenes; i++)
    if (!strcmp(c->scenes[i].id, id)) why = "is defined twice", first = c->scenes[i].line;
  if (why) {
    snprintf(x->err, sizeof x->err, "%s:%d: [scene %s]: scene%s '%s' %s", c->path, x->line, id,
             first ? "" : " id", id, why);
    if (first) snprintf(x->err + strlen(x->err), sizeof x->err - strlen(x->err), " (first on line %d)", first);
    return 0;
  }
  gs_scene_conf *ns = realloc(c->scenes, (c->num_scenes + 1) * sizeof *ns);
  if (!ns) {
    snprintf(x->err, sizeof x->err, "%s:%d: [scene %s]: out of memory", c->path, x->line, id);
    return 0;
  }
  c->scenes = ns;
  x->cur = &c->scenes[c->num_scenes++];
  memset(x->cur, 0, sizeof *x->cur);
  snprintf(x->cur->id, sizeof x->cur->id, "%s", id);
  x->cur->line = x->line; /* up stays 0 until given: y, but a flat scene gets a note (catalog.c) */
  return 1;
}

/* inih's reader callback: counts lines so messages can name them, and
 * stops at what inih would misread: a line longer than its buffer (inih
 * parsed the rest as a line of its own, under the wrong number), a NUL byte
 * (the rest of the line ignored) and a read error (a folder read as an
 * empty file, reported as "no [scene ID] sections"). */
static char *read_line(char *str, int num, void *stream) {
  FILE *f = ((void **)stream)[0];
  load_ctx *x = ((void **)stream)[1];
  int n = 0, c = 0;
  while (n < num - 1 && (c = getc(f)) != EOF && c != '\0') {
    str[n++] = (char)c;
    if (c == '\n') break;
  }
  if (c == EOF && ferror(f)) {
    snprintf(x->err, sizeof x->err, "%s: cannot read config: %s", x->c->path, strerror(errno));
    return NULL;
  }
  if (n == 0 && c == EOF) return NULL;
  x->line++;
  if (c == '\0') {
    snprintf(x->err, sizeof x->err, "%s:%d: a NUL byte (not a text file?)", x->c->path, x->line);
    return NULL;
  }
  if (n == num - 1 && str[n - 1] != '\n' && (c = getc(f)) != '\n' && c != EOF) {
    snprintf(x->err, sizeof x->err, "%s:%d: line longer than %d characters", x->c->path, x->line, num - 1);
    return NULL;
  }
  str[n] = '\0';
  const char *p = str;
  if (x->line == 1 && !strncmp(p, "\xEF\xBB\xBF", 3)) p += 3; /* a UTF-8 byte-order mark, as inih skips it */
  while (*p == ' ' || *p == '\t') p++;
  const char *end = *p == '[' ? strchr(p, ']') : NULL;
  if (end && !scene_header(x, p + 1, (size_t)(end - p - 1))) return NULL;
  return str;
}

const char *gs_token_bad(const char *tok) {
  size_t n = strlen(tok);
  if (n < 16 || n > 255) return "must hold one token of 16..255 characters";
  /* A line break or a space inside could never arrive in an Authorization
   * header as written: every request would be a 401. */
  for (const char *p = tok; *p; p++)
    if (*p <= ' ' || *p == 0x7f) return "must hold one token of visible ASCII characters (no spaces, one line)";
  return NULL;
}

static int read_token(load_ctx *x, const char *path) {
  FILE *f = fopen(path, "r");
  if (!f) {
    snprintf(x->err, sizeof x->err, "%s:%d: [server] token_file: cannot open '%s': %s", x->c->path, x->token_line,
             path, strerror(errno));
    return -1;
  }
  char buf[sizeof x->c->token + 1];
  size_t n = fread(buf, 1, sizeof buf - 1, f);
  fclose(f);
  buf[n] = 0;
  while (n && (buf[n - 1] == '\n' || buf[n - 1] == '\r' || buf[n - 1] == ' ')) buf[--n] = 0;
  const char *why = n >= sizeof x->c->token || strlen(buf) != n ? "must hold one token of 16..255 characters"
                                                                : gs_token_bad(buf);
  if (why) {
    snprintf(x->err, sizeof x->err, "%s:%d: [server] token_file: '%s' %s", x->c->path, x->token_line, path, why);
    return -1;
  }
  snprintf(x->c->token, sizeof x->c->token, "%s", buf);
  return 0;
}

/* After the parse (rc: inih's): its errors, then what no one key shows. */
static int check_loaded(load_ctx *x, int rc, char *err, size_t errsize) {
  const gs_config *c = x->c;
  const char *path = c->path;
  if (x->err[0]) {
    snprintf(err, errsize, "%s", x->err);
    return -1;
  }
  if (rc != 0) {
    snprintf(err, errsize, "%s:%d: syntax error (expected [section] or key = value)", path, rc);
    return -1;
  }
  if (x->token_file[0] && read_token(x, x->token_file)) {
    snprintf(err, errsize, "%s", x->err);
    return -1;
  }
  for (size_t i = 0; i < c->num_scenes; i++) {
    gs_scene_conf *s = &c->scenes[i];
    if (!s->source[0]) {
      snprintf(err, errsize, "%s:%d: [scene %s]: 'source' is required ('city' or a file path)", path, s->line,
               s->id);
      return -1;
    }
    if (!s->is_city && (s->extent || s->seed || s->detail)) {
      snprintf(err, errsize, "%s:%d: [scene %s]: extent, seed and detail apply to source = city only", path,
               s->line, s->id);
      return -1;
    }
    if (s->is_city && s->up == GI_UP_Z) {
      /* The core builds the city Y-up whatever it is told: up = z was
       * accepted and ignored (gi-bake refuses city --up z). */
      char sec[80];
      snprintf(sec, sizeof sec, "scene %s", s->id);
      snprintf(err, errsize, "%s:%d: [scene %s] up: the procedural city is always Y-up; up = z applies to scene files",
               path, line_of(x, sec, "up"), s->id);
      return -1;
    }
  }
  struct stat st; /* main.c checks TMPDIR's folder too; this one has a line */
  if (c->tmp_dir[0] && (stat(c->tmp_dir, &st) != 0 || !S_ISDIR(st.st_mode) || access(c->tmp_dir, W_OK) != 0)) {
    snprintf(err, errsize, "%s:%d: [server] tmp_dir: '%s' is not a writable folder", path,
             line_of(x, "server", "tmp_dir"), c->tmp_dir);
    return -1;
  }
  if (c->lim.max_probes_inline > c->lim.max_probes_job) {
    /* Named where the later of the two was set (the defaults have no line). */
    int li = line_of(x, "limits", "max_probes_inline"), lj = line_of(x, "limits", "max_probes_job");
    const char *key = li > lj ? "max_probes_inline" : "max_probes_job";
    snprintf(err, errsize, "%s:%d: [limits] %s: max_probes_inline (%zu) exceeds max_probes_job (%zu)", path,
             li > lj ? li : lj, key, c->lim.max_probes_inline, c->lim.max_probes_job);
    return -1;
  }
  return 0;
}

int gs_config_load(const char *path, gs_config *c, char *err, size_t errsize) {
  load_ctx x;
  memset(&x, 0, sizeof x);
  x.c = c;
  snprintf(c->path, sizeof c->path, "%s", path);
  const char *slash = strrchr(path, '/');
  if (slash) snprintf(x.dir, sizeof x.dir, "%.*s", (int)(slash - path), path);
  FILE *f = fopen(path, "r");
  if (!f) {
    snprintf(err, errsize, "%s: cannot open config: %s", path, strerror(errno));
    return -1;
  }
  void *stream[2] = {f, &x};
  int rc = ini_parse_stream(read_line, stream, on_entry, &x);
  fclose(f);
  rc = check_loaded(&x, rc, err, errsize);
  free(x.seen);
  return rc;
}

void gs_config_free(gs_config *c) {
  free(c->scenes);
  c->scenes = NULL;
  c->num_scenes = 0;
}
