/* lightmap.c: GET .../lighting?kind=lightmap (the EXR atlas) and
 * GET .../lightmap-uv.glb (its geometry), for one region.
 *
 * The region is the request's, else the smallest of the cascade's level
 * boxes around `at` that holds a triangle (by its centre): level 0's, the
 * part of the scene the viewpoint's cascade sees best, when it holds one.
 * From the middle of a room (the Cornell box) level 0's box held no
 * triangle and the answer was a 400 blaming a region the client never
 * gave. The texel is the request's, else level 0's voxel, doubled while
 * the region needs more than one atlas (up to the coarsest level's voxel).
 * Both answers lay out the same charts from the same parameters (the
 * layout is deterministic), so the glTF a client fetches matches the atlas
 * it fetched. An answer is one atlas: a region that needs more is a 413
 * that says how many. The bake runs tile by tile with
 * cascades of its own, outside the cascade cache (like a job's), admitted
 * by the same memory budget: one tile's cascade plus the atlas. */
#define _POSIX_C_SOURCE 200809L
#include <math.h>
#include <stdio.h>
#include <string.h>
#include "server.h"

/* Bytes per texel while a lightmap is baked and encoded: six RGB float
 * arrays, valid and chart (80), the texels' tiles while the bake sorts
 * them (12) and the EXR's 13 planar channels (52). */
#define GS_LIGHTMAP_TEXEL_BYTES 144

static void fail(gs_answer *a, int status, const char *msg) {
  gi_proto_error pe;
  gi_proto_fail(&pe, status, "%s", msg);
  gs_answer_error(a, &pe);
}

/* The core's options from the request: level d's box around `at` unless
 * it gave a region, texel (0: level 0's voxel) times 2^doubled. */
static void lightmap_opts(const gi_proto_bake *b, const gi_quality *q, int d, int doubled, gi_lightmap_opts *o) {
  memset(o, 0, sizeof *o);
  double side = ldexp(q->res * q->voxel0, d);
  o->texel = ldexp(b->texel > 0 ? b->texel : q->voxel0, doubled);
  o->atlas = b->atlas ? b->atlas : GI_PROTO_DEFAULT_LIGHTMAP_ATLAS;
  o->have_region = 1;
  for (int k = 0; k < 3; k++) {
    o->region_lo[k] = b->has_region ? b->region[k] : b->at[k] - 0.5 * side;
    o->region_hi[k] = b->has_region ? b->region[3 + k] : b->at[k] + 0.5 * side;
  }
}

/* The core's refusals of a region without a triangle, or beside the scene
 * (lightmap/uv.c); they share GI_ERR_INVALID_ARG with others, so their
 * words tell them. */
static int no_triangle(gi_result rc, const gi_error_info *e) {
  return rc == GI_ERR_INVALID_ARG && (strstr(e->msg, "no triangle") || strstr(e->msg, "outside the scene"));
}

/* Lays out the request's lightmap with the defaults above into *lm (and
 * the options used into o). A default region that holds no triangle even
 * at the coarsest level is an error that says so, with the box. */
static gi_result layout(const gs_scene *s, const gi_proto_bake *b, const gi_quality *q, gi_lightmap_opts *o,
                        gi_lightmap **lm, gi_error_info *e) {
  gi_result rc = GI_ERR_INVALID_ARG;
  int d = 0;
  for (; d < q->levels; d++) {
    lightmap_opts(b, q, d, 0, o);
    rc = gi_lightmap_layout(s->scene, o, lm, e);
    if (b->has_region || !no_triangle(rc, e)) break;
  }
  if (rc != GI_OK && !b->has_region && no_triangle(rc, e)) {
    snprintf(e->msg, sizeof e->msg, "lightmap: no triangle of the scene has its centre in the default region, the "
             "cascade's boxes around 'at' up to its coarsest (level %d: %g,%g,%g to %g,%g,%g); give "
             "region=x0,y0,z0,x1,y1,z1", q->levels - 1, o->region_lo[0], o->region_lo[1], o->region_lo[2],
             o->region_hi[0], o->region_hi[1], o->region_hi[2]);
    return rc;
  }
  /* The default texel coarsens until one atlas holds the region. */
  for (int k = 1; rc == GI_OK && b->texel <= 0 && gi_lightmap_num_atlases(*lm) > 1 && k < q->levels; k++) {
    gi_lightmap *next = NULL;
    gi_lightmap_opts o2;
    lightmap_opts(b, q, d, k, &o2);
    if (gi_lightmap_layout(s->scene, &o2, &next, e) != GI_OK) break; /* keep the finer one: its 413 */
    gi_lightmap_free(*lm);
    *lm = next;
    *o = o2;
  }
  return rc;
}

/* Writes the answer's file into the work folder and takes it as the body. */
static gi_result encode(gs_service *svc, const gi_lightmap *lm, gs_endpoint ep, int half, gs_answer *a,
                        gi_error_info *e) {
  char path[1200];
  gs_tmp_path(svc, ep == GS_EP_LIGHTMAP_UV ? ".glb" : ".exr", path, sizeof path);
  gi_result rc = ep == GS_EP_LIGHTMAP_UV ? gi_lightmap_write_gltf(lm, path, e) : gi_lightmap_write_exr(lm, path, half, e);
  if (rc != GI_OK) return rc;
  return gs_answer_take_file(svc, a, path, ep == GS_EP_LIGHTMAP_UV ? "model/gltf-binary" : "image/x-exr", e);
}

void gs_serve_lightmap(gs_service *svc, const gs_scene *s, gs_endpoint ep, const gi_proto_bake *b, double t_start_ms,
                       const gi_cancel *cancel, gs_answer *a) {
  double t0 = gs_now_ms();
  gi_error_info e = {0};
  gi_quality req = b->quality, q;
  req.threads = svc->cfg->bake_threads;
  gi_result rc = gi_quality_resolve(s->scene, &req, &q, &e);
  gi_lightmap_opts o;
  gi_lightmap *lm = NULL;
  if (rc == GI_OK) rc = layout(s, b, &q, &o, &lm, &e);
  double layout_ms = gs_now_ms() - t0;
  if (rc != GI_OK) return gs_answer_core_error(a, rc, &e);
  size_t na = gi_lightmap_num_atlases(lm);
  if (na > 1) {
    char msg[256];
    snprintf(msg, sizeof msg,
             "the region needs %zu lightmap atlases of %d texels at texel %g; one answer holds one: raise 'texel' "
             "or 'atlas', or shrink 'region'",
             na, o.atlas, o.texel);
    gi_lightmap_free(lm);
    return fail(a, 413, msg);
  }
  gi_lightmap_report rep;
  gi_timings ms = {0};
  gi_lightmap_atlas at;
  gi_lightmap_get_atlas(lm, 0, &at);
  size_t need = ep == GS_EP_LIGHTMAP_UV ? 0 : gs_bake_bytes(&q) + (size_t)at.width * at.height * GS_LIGHTMAP_TEXEL_BYTES;
  if (need && (rc = gs_cache_reserve(svc->cache, need, "this lightmap's bake", &e)) != GI_OK) {
    gi_lightmap_free(lm);
    return gs_answer_core_error(a, rc, &e);
  }
  if (ep != GS_EP_LIGHTMAP_UV) {
    /* Stops once nobody waits (deadline, hang-up): counted as a cancelled bake. */
    gs_metrics_bake_begin(svc->metrics);
    rc = gi_lightmap_bake(lm, &req, cancel, &rep, &e);
    gs_metrics_bake_end(svc->metrics, rc == GI_ERR_CANCELLED);
  }
  /* Server-Timing's stages as for a probe: the tiles' cascade stages summed, gather the texels;
   * layout leads them, with the bake's sorting of texels into tiles. */
  if (rc == GI_OK && ep != GS_EP_LIGHTMAP_UV) {
    ms = rep.ms;
    layout_ms += rep.sort_ms;
  }
  double t1 = gs_now_ms();
  if (rc == GI_OK) rc = encode(svc, lm, ep, b->half, a, &e);
  ms.encode = gs_now_ms() - t1;
  gi_lightmap_free(lm);
  if (need) gs_cache_unreserve(svc->cache, need);
  if (rc != GI_OK) return gs_answer_core_error(a, rc, &e);
  /* The atlas: what its tiles ran (each tile plans from its centre and
   * texels). The glTF bakes nothing: the plan at the region's centre. */
  gi_effect fx[GI_FX_COUNT];
  double centre[3];
  for (int k = 0; k < 3; k++) centre[k] = 0.5 * (o.region_lo[k] + o.region_hi[k]);
  if (ep != GS_EP_LIGHTMAP_UV) gi_proto_effects_header(rep.effects, a->effects, sizeof a->effects);
  else if (gi_effect_plan(s->scene, centre, &req, fx, NULL, &e) == GI_OK)
    gi_proto_effects_header(fx, a->effects, sizeof a->effects);
  gi_proto_server_timing_layout(layout_ms, &ms, gs_now_ms() - t_start_ms, a->server_timing, sizeof a->server_timing);
  a->cache = "miss";
  snprintf(a->disposition, sizeof a->disposition, "attachment; filename=\"%s-lightmap%s\"", s->id,
           ep == GS_EP_LIGHTMAP_UV ? "-uv.glb" : ".exr");
}
