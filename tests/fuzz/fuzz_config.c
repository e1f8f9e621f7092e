/* fuzz_config.c: gi-server's config loader (server/config.c, inih) on
 * arbitrary bytes, written to a private temporary file as the server reads
 * it. Loading must succeed with every value in its documented range, or
 * fail with a message that names the file; never crash, hang or leak. */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include "server.h"

static char dir[64];

/* Each input's file is unlinked after it; the folder goes at exit. */
static void remove_dir(void) { rmdir(dir); }

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  if (!dir[0]) {
    snprintf(dir, sizeof dir, "/tmp/gi-fuzz-config-XXXXXX");
    if (!mkdtemp(dir)) abort();
    atexit(remove_dir);
  }
  char path[128];
  snprintf(path, sizeof path, "%s/gi-server.ini", dir);
  FILE *f = fopen(path, "wb");
  if (!f) abort();
  if (size && fwrite(data, 1, size, f) != size) abort();
  fclose(f);
  static gs_config c;
  char err[1400] = "";
  gs_config_defaults(&c);
  int rc = gs_config_load(path, &c, err, sizeof err);
  if (rc == 0) {
    if (c.port < 0 || c.port > 65535 || c.workers < 1 || c.connection_threads < 1 || c.queue < 0 ||
        !(c.deadline_s >= 0.1) || c.lim.max_res < 8 || c.lim.max_levels < 1 || c.lim.max_levels > GI_MAX_LEVELS ||
        c.lim.max_probes_inline > c.lim.max_probes_job)
      abort();
    for (size_t i = 0; i < c.num_scenes; i++)
      if (!c.scenes[i].id[0] || !c.scenes[i].source[0]) abort();
  } else if (!strstr(err, path)) {
    abort(); /* every message names the file */
  }
  gs_config_free(&c);
  unlink(path);
  return 0;
}
