/* cache.c: gi-accuracy's reference cache, shared by the probe and view
 * references: files named by a hash of what produced them, written to a
 * temporary name and renamed into place, so an interrupted run leaves no
 * half file that a later run would trust. */
#include <errno.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>
#include "acc.h"

uint64_t acc_fnv(uint64_t h, const void *p, size_t n) {
  const unsigned char *b = p;
  for (size_t i = 0; i < n; i++) h = (h ^ b[i]) * 1099511628211ull;
  return h;
}

int acc_cache_read(const char *path, void *a, size_t na, void *b, size_t nb) {
  FILE *f = fopen(path, "rb");
  if (!f) return 0;
  int ok = fread(a, 1, na, f) == na && (!b || fread(b, 1, nb, f) == nb);
  fclose(f);
  return ok;
}

void acc_cache_write(const char *path, const void *a, size_t na, const void *b, size_t nb) {
  char tmp[1100];
  snprintf(tmp, sizeof tmp, "%s.tmp.%d", path, (int)getpid());
  FILE *f = fopen(tmp, "wb");
  if (!f || fwrite(a, 1, na, f) != na || (b && fwrite(b, 1, nb, f) != nb) || fclose(f) != 0 ||
      rename(tmp, path) != 0) {
    fprintf(stderr, "gi-accuracy: cannot write the reference cache %s: %s\n", path, strerror(errno));
    remove(tmp);
  }
}
