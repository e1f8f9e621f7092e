/* replay.c: runs every file of the given corpus folders (or files) through
 * a fuzz target's LLVMFuzzerTestOneInput, built with the normal compiler,
 * so the corpus is a regression test in every ctest run (zstd's
 * "regression driver"). Prints one line per input; exits 1 when no input
 * was found (a missing corpus must not pass silently). */
#include <dirent.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static int run_file(const char *path) {
  FILE *f = fopen(path, "rb");
  if (!f) { perror(path); return -1; }
  uint8_t *buf = NULL;
  size_t n = 0, cap = 0;
  for (;;) {
    if (n == cap) {
      cap = cap ? 2 * cap : 65536;
      uint8_t *nb = realloc(buf, cap);
      if (!nb) { free(buf); fclose(f); return -1; }
      buf = nb;
    }
    size_t k = fread(buf + n, 1, cap - n, f);
    if (k == 0) break;
    n += k;
  }
  fclose(f);
  LLVMFuzzerTestOneInput(buf, n);
  free(buf);
  printf("replayed %s (%zu bytes)\n", path, n);
  return 1;
}

int main(int argc, char **argv) {
  int count = 0, bad = 0;
  for (int i = 1; i < argc; i++) {
    struct stat st;
    if (stat(argv[i], &st) != 0) { perror(argv[i]); bad++; continue; }
    if (!S_ISDIR(st.st_mode)) { int r = run_file(argv[i]); r > 0 ? count++ : bad++; continue; }
    struct dirent **names;
    int m = scandir(argv[i], &names, NULL, alphasort); /* sorted: the same order every run */
    for (int j = 0; j < m; j++) {
      if (names[j]->d_name[0] != '.') {
        char p[4096];
        snprintf(p, sizeof p, "%s/%s", argv[i], names[j]->d_name);
        int r = run_file(p);
        r > 0 ? count++ : bad++;
      }
      free(names[j]);
    }
    free(names);
  }
  printf("%d input(s) replayed, %d unreadable\n", count, bad);
  return count > 0 && bad == 0 ? 0 : 1;
}
