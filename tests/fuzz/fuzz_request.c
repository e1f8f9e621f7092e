/* fuzz_request.c: the HTTP request parser (proto/) on arbitrary bytes.
 *
 * The first byte picks what the rest is: 0 a lighting query, 1 a cascades
 * query (both "k=v&k=v", as libmicrohttpd hands them over, already
 * decoded), 2 a probe-list JSON body, 3 an error or job JSON as the client
 * decodes it. Every call must return 0 or a 4xx/5xx with a named error, and
 * whatever it accepts must be within the contract: finite viewpoint and
 * points, knobs in range. Anything else aborts, which the fuzzer reports. */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include "gi_proto.h"

static void check_error(int st, const gi_proto_error *e) {
  if (st == 0) return;
  if (st < 400 || st > 599 || e->status != st || !e->name[0] || !e->message[0]) abort();
}

static void check_bake(const gi_proto_bake *b, const gi_proto_limits *l) {
  const gi_quality *q = &b->quality;
  if (b->has_at && !(isfinite(b->at[0]) && isfinite(b->at[1]) && isfinite(b->at[2]))) abort();
  if (q->levels < 0 || q->levels > l->max_levels || q->res < 0 || q->res > l->max_res || q->res % 4) abort();
  if (!isfinite(q->voxel0) || q->voxel0 < 0 || !isfinite(q->step) || !isfinite(q->aperture_deg)) abort();
  if (q->bounces < -1 || q->bounces > 8) abort();
  for (int i = 0; i < GI_FX_COUNT; i++)
    if (q->effects[i] < -1 || q->effects[i] > 1) abort();
  if (b->kind == GI_PROTO_PANORAMA && (long long)b->width * b->height > l->max_panorama_pixels) abort();
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  if (size < 1) return 0;
  int mode = data[0] & 3;
  char *s = malloc(size);
  if (!s) return 0;
  memcpy(s, data + 1, size - 1);
  s[size - 1] = 0;
  gi_proto_limits lim;
  gi_proto_limits_default(&lim);
  gi_proto_error e;
  memset(&e, 0, sizeof e);
  if (mode <= 1) {
    gi_proto_kv kv[64];
    size_t n = 0;
    for (char *save = NULL, *tok = strtok_r(s, "&", &save); tok && n < 64; tok = strtok_r(NULL, "&", &save)) {
      char *eq = strchr(tok, '=');
      if (eq) *eq = 0;
      kv[n].key = tok;
      kv[n].value = eq ? eq + 1 : "";
      n++;
    }
    gi_proto_bake b;
    int st = mode == 0 ? gi_proto_parse_lighting(kv, n, &lim, &b, &e) : gi_proto_parse_cascades(kv, n, &lim, &b, &e);
    check_error(st, &e);
    if (st == 0) {
      if (!b.has_at) abort(); /* 'at' is required */
      check_bake(&b, &lim);
    }
    /* The same query on a cell URL (issue 14): 'q' required, no 'at'. */
    st = mode == 0 ? gi_proto_parse_cell_lighting(kv, n, &lim, &b, &e) : gi_proto_parse_cell_cascades(kv, n, &lim, &b, &e);
    check_error(st, &e);
    if (st == 0) {
      if (b.has_at || !b.cell || strlen(b.q) != GI_PROTO_QHASH_LEN) abort();
      check_bake(&b, &lim);
    }
    long long cell[3];
    if (n && gi_proto_parse_cell(kv[0].key, cell) == 0 && strlen(kv[0].key) > 3 * 19 + 2) abort();
  } else if (mode == 2) {
    gi_proto_probes p;
    int st = gi_proto_parse_probes(s, size - 1, &lim, &p, &e);
    check_error(st, &e);
    if (st == 0) {
      if (p.num_points == 0 || p.num_points > lim.max_probes_job) abort();
      for (size_t i = 0; i < 3 * p.num_points; i++)
        if (!isfinite(p.points[i])) abort();
      check_bake(&p.bake, &lim);
      gi_proto_probes_free(&p);
    } else if (p.points) {
      abort(); /* a refused body owns nothing */
    }
  } else {
    gi_proto_error pe;
    gi_proto_job j;
    gi_proto_error_parse(s, size - 1, &pe);
    if (gi_proto_job_parse(s, size - 1, &j) == 0 && (unsigned)j.state > GI_JOB_FAILED) abort();
  }
  free(s);
  return 0;
}
