/* cache.c: gi-accuracy's reference cache, shared by the probe and view
 * references: files named by a hash of what produced them, written to a
 * temporary name and renamed into place, so an interrupted run leaves no
 * half file that a later run would trust. */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>
#include "acc.h"
#include "toolargs.h"

static uint64_t scene_version; /* see acc_cache_key */

void acc_cache_scene_version(uint64_t v) { scene_version = v; }

uint64_t acc_cache_key(const char *name) {
  uint64_t h = ta_fnv(1469598103934665603ull, name, strlen(name));
  return scene_version ? ta_fnv(h, &scene_version, sizeof scene_version) : h;
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

int acc_ref_cached(const char *name, const acc_scene_set *ss, int lights, int threads, const char *out_dir,
                   int ref_version, gi_ref_probe *ref, double *ms) {
  uint64_t h = acc_cache_key(name);
  h = ta_fnv(h, ss->pts, ss->n * 3 * sizeof(double));
  h = ta_fnv(h, &ss->ref_samples, sizeof ss->ref_samples);
  h = ta_fnv(h, &ref_version, sizeof ref_version);
  char path[1100], what[48] = "";
  if (lights) { /* every light: the key (and file) the cache had before light kinds */
    h = ta_fnv(h, &lights, sizeof lights);
    snprintf(what, sizeof what, "-lights%x", (unsigned)lights);
  }
  snprintf(path, sizeof path, "%s/ref-%s%s-%016llx.bin", out_dir, name, what, (unsigned long long)h);
  *ms = 0;
  if (acc_cache_read(path, ref, ss->n * sizeof *ref, NULL, 0)) {
    int ok = 1;
    for (size_t i = 0; ok && i < ss->n; i++)
      for (int k = 0; k < 3; k++) ok &= isfinite(ref[i].irradiance[k]) && isfinite(ref[i].std_err[k]);
    if (ok) {
      fprintf(stderr, "gi-accuracy: %s%s: reference from cache %s\n", name, what, path);
      return 1;
    }
    fprintf(stderr, "gi-accuracy: %s%s: cache %s unreadable, recomputing\n", name, what, path);
  }
  gi_reference_opts ro = {.samples = ss->ref_samples, .seed = 1, .threads = threads, .lights = lights};
  gi_error_info err = {0};
  fprintf(stderr, "gi-accuracy: %s%s: reference, %zu probes x %d paths...\n", name, what, ss->n, ss->ref_samples);
  if (gi_reference_irradiance(ss->s, ss->pts, ss->n, &ro, ref, ms, &err) != GI_OK) {
    fprintf(stderr, "gi-accuracy: %s%s: reference: %s\n", name, what, err.msg);
    return 0;
  }
  acc_cache_write(path, ref, ss->n * sizeof *ref, NULL, 0);
  return 1;
}
