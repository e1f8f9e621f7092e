#include "test_util.h"
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

const char *tu_scene_path(const char *rel) {
  static char buf[4096];
  snprintf(buf, sizeof buf, "%s/%s", GI_SCENES_DIR, rel);
  if (access(buf, R_OK) != 0) {
    fprintf(stderr, "SKIP: shared scene %s is absent (looked in %s)\n", rel, GI_SCENES_DIR);
    return NULL;
  }
  return buf;
}

const char *tu_tmpdir(void) {
  static char dir[256];
  if (!dir[0]) {
    snprintf(dir, sizeof dir, "/tmp/gi-test-XXXXXX");
    if (!mkdtemp(dir)) { perror("mkdtemp"); abort(); }
  }
  return dir;
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
