/* server_util.c: see server_util.h. */
#define _POSIX_C_SOURCE 200809L
#include "server_util.h"
#include "test_util.h"
#include <arpa/inet.h>
#include <curl/curl.h>
#include <errno.h>
#include <jansson.h>
#include <netinet/in.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/socket.h>
#include <sys/prctl.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>
#include "gi/gi.h"

void su_sleep_ms(int ms) {
  struct timespec ts = {ms / 1000, (long)(ms % 1000) * 1000000L};
  nanosleep(&ts, NULL);
}

double su_now_ms(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return ts.tv_sec * 1e3 + ts.tv_nsec * 1e-6;
}

int su_start(su_server *s, const char *name, const char *ini) {
  snprintf(s->dir, sizeof s->dir, "%s/%s", tu_tmpdir(), name);
  mkdir(s->dir, 0700);
  char cfg[600], portf[600], log[600], tok[600];
  snprintf(cfg, sizeof cfg, "%s/gi-server.ini", s->dir);
  snprintf(portf, sizeof portf, "%s/port", s->dir);
  snprintf(log, sizeof log, "%s/server.log", s->dir);
  snprintf(tok, sizeof tok, "%s/token.txt", s->dir);
  FILE *f = fopen(cfg, "w");
  if (!f) return -1;
  fputs(ini, f);
  fclose(f);
  f = fopen(tok, "w");
  fputs(SU_TOKEN "\n", f);
  fclose(f);
  unlink(portf);
  /* Else the child would write the parent's pending output a second time. */
  fflush(stdout);
  fflush(stderr);
  pid_t parent = getpid();
  s->pid = fork();
  if (s->pid == 0) {
    /* A failed assert skips the test's su_stop: the server then dies with
     * the test binary instead of outliving it (eight did, before this). */
    prctl(PR_SET_PDEATHSIG, SIGKILL);
    if (getppid() != parent) _exit(127);
    FILE *lf = freopen(log, "a", stderr);
    lf = lf ? freopen(log, "a", stdout) : lf; /* its banner too: the test's output stays the test's */
    (void)lf;
    execl(GI_BIN_DIR "/gi-server", "gi-server", "--config", cfg, "--port", "0", "--port-file", portf, (char *)NULL);
    _exit(127);
  }
  for (int i = 0; i < 600; i++) {
    f = fopen(portf, "r");
    if (f) {
      int ok = fscanf(f, "%d", &s->port) == 1;
      fclose(f);
      if (ok && s->port > 0) return 0;
    }
    int st;
    if (waitpid(s->pid, &st, WNOHANG) == s->pid) {
      fprintf(stderr, "gi-server exited at start (status %d); log: %s\n", st, log);
      s->pid = 0;
      return -1;
    }
    su_sleep_ms(100);
  }
  return -1;
}

/* The last lines of the server's log on stderr: a server killed by a
 * signal (an abort's message, say) is seen in the test's output, which is
 * what a CI run keeps. */
static void print_log_tail(const su_server *s, int status) {
  char path[600];
  snprintf(path, sizeof path, "%s/server.log", s->dir);
  FILE *f = fopen(path, "r");
  if (!f) return;
  static char buf[4096];
  fseek(f, 0, SEEK_END);
  long end = ftell(f), from = end > (long)sizeof buf - 1 ? end - (long)sizeof buf + 1 : 0;
  fseek(f, from, SEEK_SET);
  size_t n = fread(buf, 1, sizeof buf - 1, f);
  buf[n] = 0;
  fclose(f);
  fprintf(stderr, "gi-server ended with status %d; the end of %s:\n%s\n", status, path, buf);
}

int su_signal_wait(su_server *s, int sig, int wait_ms, double *ms) {
  if (s->pid <= 0) return -1;
  double t0 = su_now_ms();
  kill(s->pid, sig);
  while (su_now_ms() - t0 < wait_ms) {
    int st;
    if (waitpid(s->pid, &st, WNOHANG) == s->pid) {
      if (ms) *ms = su_now_ms() - t0;
      s->pid = 0;
      if (WIFSIGNALED(st) && WTERMSIG(st) != sig) print_log_tail(s, 128 + WTERMSIG(st));
      return WIFEXITED(st) ? WEXITSTATUS(st) : 128 + WTERMSIG(st);
    }
    su_sleep_ms(5);
  }
  if (ms) *ms = su_now_ms() - t0;
  kill(s->pid, SIGKILL);
  waitpid(s->pid, NULL, 0);
  s->pid = 0;
  return -2;
}

int su_stop(su_server *s) { return su_signal_wait(s, SIGTERM, 60000, NULL); }

static size_t on_body(char *p, size_t sz, size_t n, void *u) {
  su_resp *r = u;
  char *nb = realloc(r->body, r->len + sz * n + 1);
  if (!nb) return 0;
  r->body = nb;
  memcpy(r->body + r->len, p, sz * n);
  r->len += sz * n;
  r->body[r->len] = 0;
  return sz * n;
}

static size_t on_header(char *p, size_t sz, size_t n, void *u) {
  su_resp *r = u;
  size_t k = sz * n;
  /* A followed redirect: keep the final answer's headers only. */
  if (k >= 5 && !memcmp(p, "HTTP/", 5)) r->hlen = 0;
  if (r->hlen + k < sizeof r->headers) {
    memcpy(r->headers + r->hlen, p, k);
    r->hlen += k;
    r->headers[r->hlen] = 0;
  }
  return k;
}

int su_follow_redirects = 1;

CURL *su_make_req(const su_server *s, const char *method, const char *path, const char *body, const char *token,
                  su_resp *r, struct curl_slist **hdrs) {
  /* Sized to the path: a fixed buffer cut long test URLs short. libcurl copies it. */
  size_t n = strlen(path) + 32;
  char *url = malloc(n);
  assert_non_null(url);
  snprintf(url, n, "http://127.0.0.1:%d%s", s->port, path);
  CURL *c = curl_easy_init();
  curl_easy_setopt(c, CURLOPT_URL, url);
  free(url);
  curl_easy_setopt(c, CURLOPT_WRITEFUNCTION, on_body);
  curl_easy_setopt(c, CURLOPT_WRITEDATA, r);
  curl_easy_setopt(c, CURLOPT_HEADERFUNCTION, on_header);
  curl_easy_setopt(c, CURLOPT_HEADERDATA, r);
  curl_easy_setopt(c, CURLOPT_TIMEOUT, 120L);
  /* Viewpoint URLs answer 307 to their cell's URL (issue 14). */
  curl_easy_setopt(c, CURLOPT_FOLLOWLOCATION, (long)su_follow_redirects);
  *hdrs = NULL;
  if (token) {
    char h[256];
    snprintf(h, sizeof h, "Authorization: Bearer %s", token);
    *hdrs = curl_slist_append(*hdrs, h);
  }
  if (body) {
    *hdrs = curl_slist_append(*hdrs, "Content-Type: application/json");
    curl_easy_setopt(c, CURLOPT_POSTFIELDS, body);
    curl_easy_setopt(c, CURLOPT_POSTFIELDSIZE, (long)strlen(body));
  }
  if (method) curl_easy_setopt(c, CURLOPT_CUSTOMREQUEST, method);
  if (*hdrs) curl_easy_setopt(c, CURLOPT_HTTPHEADER, *hdrs);
  return c;
}

su_resp su_http(const su_server *s, const char *method, const char *path, const char *body, const char *token) {
  su_resp r = {0};
  struct curl_slist *h;
  CURL *c = su_make_req(s, method, path, body, token, &r, &h);
  CURLcode rc = curl_easy_perform(c);
  if (rc != CURLE_OK) fprintf(stderr, "curl %.200s: %s\n", path, curl_easy_strerror(rc));
  assert_int_equal(rc, CURLE_OK);
  curl_easy_getinfo(c, CURLINFO_RESPONSE_CODE, &r.status);
  curl_slist_free_all(h);
  curl_easy_cleanup(c);
  return r;
}

const char *su_header(const su_resp *r, const char *name) {
  static _Thread_local char val[1024]; /* test_sessions reads headers on two threads at once */
  size_t n = strlen(name);
  for (const char *p = r->headers; p && *p;) {
    if (!strncasecmp(p, name, n) && p[n] == ':') {
      const char *v = p + n + 1;
      while (*v == ' ') v++;
      size_t k = strcspn(v, "\r\n");
      snprintf(val, sizeof val, "%.*s", (int)k, v);
      return val;
    }
    p = strchr(p, '\n');
    if (p) p++;
  }
  return NULL;
}

void su_expect_error(const su_resp *r, long status, const char *name, const char *needle) {
  if (r->status != status) fprintf(stderr, "got %ld: %s\n", r->status, r->body ? r->body : "");
  assert_int_equal(r->status, status);
  assert_string_equal(su_header(r, "Content-Type"), "application/json");
  json_t *o = json_loadb(r->body, r->len, 0, NULL);
  assert_non_null(o);
  assert_int_equal(json_integer_value(json_object_get(o, "code")), status);
  assert_string_equal(json_string_value(json_object_get(o, "name")), name);
  const char *msg = json_string_value(json_object_get(o, "message"));
  assert_non_null(msg);
  if (needle && !strstr(msg, needle)) fprintf(stderr, "message '%s' lacks '%s'\n", msg, needle);
  if (needle) assert_non_null(strstr(msg, needle));
  json_decref(o);
}

double su_metric(const su_server *s, const char *name, const char *labels) {
  su_resp r = su_http(s, NULL, "/metrics", NULL, SU_TOKEN);
  assert_int_equal(r.status, 200);
  double sum = 0;
  size_t n = strlen(name);
  for (char *line = strtok(r.body, "\n"); line; line = strtok(NULL, "\n")) {
    if (line[0] == '#' || strncmp(line, name, n) || (line[n] != ' ' && line[n] != '{')) continue;
    if (labels && (line[n] != '{' || strncmp(line + n + 1, labels, strlen(labels)))) continue;
    sum += strtod(strrchr(line, ' ') + 1, NULL);
  }
  free(r.body);
  return sum;
}

const char *su_save_body(const su_server *s, const su_resp *r, const char *name) {
  static char path[700];
  snprintf(path, sizeof path, "%s/%s", s->dir, name);
  FILE *f = fopen(path, "wb");
  assert_non_null(f);
  assert_int_equal(fwrite(r->body, 1, r->len, f), r->len);
  fclose(f);
  return path;
}

struct gi_exr_file *su_read_exr(const su_server *s, const su_resp *r, const char *name) {
  const char *path = su_save_body(s, r, name);
  gi_exr_file *x = NULL;
  gi_error_info e = {0};
  gi_result rc = gi_exr_read(path, &x, &e);
  if (rc) fprintf(stderr, "EXR: %s\n", e.msg);
  assert_int_equal(rc, GI_OK);
  return x;
}

double su_rss_mb(const su_server *s) {
  char path[64], line[256];
  snprintf(path, sizeof path, "/proc/%d/status", (int)s->pid);
  FILE *f = fopen(path, "r");
  if (!f) return -1;
  double kb = -1;
  while (fgets(line, sizeof line, f))
    if (!strncmp(line, "VmRSS:", 6)) kb = strtod(line + 6, NULL);
  fclose(f);
  return kb < 0 ? -1 : kb / 1024.0;
}

int su_connect(const su_server *s, const char *src) {
  int fd = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (fd < 0) return -1;
  if (src) {
    struct sockaddr_in a = {.sin_family = AF_INET};
    inet_pton(AF_INET, src, &a.sin_addr);
    if (bind(fd, (struct sockaddr *)&a, sizeof a) != 0) {
      close(fd);
      return -1;
    }
  }
  struct sockaddr_in a = {.sin_family = AF_INET, .sin_port = htons((uint16_t)s->port)};
  inet_pton(AF_INET, "127.0.0.1", &a.sin_addr);
  if (connect(fd, (struct sockaddr *)&a, sizeof a) != 0) {
    close(fd);
    return -1;
  }
  return fd;
}

long su_read(int fd, char *buf, size_t size, int ms) {
  size_t n = 0;
  double end = su_now_ms() + ms;
  while (n + 1 < size) {
    int left = (int)(end - su_now_ms());
    if (left <= 0) break;
    struct pollfd p = {fd, POLLIN, 0};
    if (poll(&p, 1, left) <= 0) break;
    ssize_t k = recv(fd, buf + n, size - 1 - n, 0);
    if (k <= 0) break;
    n += (size_t)k;
  }
  buf[n] = 0;
  return (long)n;
}

const char *su_raw(const su_server *s, const char *req, int ms) {
  static char buf[8192];
  int fd = su_connect(s, NULL);
  assert_true(fd >= 0);
  assert_int_equal(send(fd, req, strlen(req), MSG_NOSIGNAL), (ssize_t)strlen(req));
  su_read(fd, buf, sizeof buf, ms);
  close(fd);
  return buf;
}
