/* probe_volume.c: a probe grid's answers as the probe EXR and an OpenVDB
 * probe volume (gi_batch.h).
 *
 * Both writers are pure functions of what they are given (no clock, no
 * pid, no random file id), because merging a sharded bake must give the
 * bytes of the unsharded one. The files are written through temporary
 * names by the glue (io/exr_io.c, io/vdb_shim.cpp). */
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <string.h>
#include "base/internal.h"
#include "gi/gi_batch.h"
#include "gi/gi_vdb.h"

static const char *const sh_names[9] = {"L00", "L1-1", "L10", "L11", "L2-2", "L2-1", "L20", "L21", "L22"};
static const char rgb[3] = {'R', 'G', 'B'};

/* R,G,B + irradiance/direct/indirect + ao + 27 SH + P + valid. */
enum { MAX_CHANNELS = 3 + 9 + 1 + 27 + 3 + 1 };

typedef struct {
  char names[MAX_CHANNELS][24];
  gi_exr_channel ch[MAX_CHANNELS];
  float *planes;
  size_t n;
  int nc;
} planes_t;

static float *add_plane(planes_t *p, const char *name) {
  snprintf(p->names[p->nc], sizeof p->names[p->nc], "%s", name);
  float *d = p->planes + (size_t)p->nc * p->n;
  p->ch[p->nc] = (gi_exr_channel){p->names[p->nc], d};
  p->nc++;
  return d;
}

/* Fills every plane; invalid points keep zeros except P and valid. */
static void fill_planes(planes_t *p, const gi_probe_volume *v) {
  char name[24];
  size_t n = v->n;
  for (int k = 0; k < 3; k++) {
    snprintf(name, sizeof name, "%c", rgb[k]);
    float *r = add_plane(p, name);
    snprintf(name, sizeof name, "irradiance.%c", rgb[k]);
    float *e = add_plane(p, name);
    snprintf(name, sizeof name, "direct.%c", rgb[k]);
    float *d = add_plane(p, name);
    snprintf(name, sizeof name, "indirect.%c", rgb[k]);
    float *ind = add_plane(p, name);
    for (size_t i = 0; i < n; i++)
      if (v->valid[i]) {
        r[i] = e[i] = v->probes[i].irradiance[k];
        d[i] = v->probes[i].direct[k];
        ind[i] = v->probes[i].indirect[k];
      }
  }
  if (v->ao) {
    float *ao = add_plane(p, "ao.Y");
    for (size_t i = 0; i < n; i++)
      if (v->valid[i]) ao[i] = v->probes[i].ao;
  }
  for (int c = 0; c < 9; c++)
    for (int k = 0; k < 3; k++) {
      snprintf(name, sizeof name, "sh.%s.%c", sh_names[c], rgb[k]);
      float *sh = add_plane(p, name);
      for (size_t i = 0; i < n; i++)
        if (v->valid[i]) sh[i] = v->probes[i].sh[c][k];
    }
  for (int a = 0; a < 3; a++) {
    snprintf(name, sizeof name, "P.%c", "XYZ"[a]);
    float *pp = add_plane(p, name);
    for (size_t i = 0; i < n; i++) pp[i] = (float)v->pos[3 * i + a];
  }
  float *val = add_plane(p, "valid.Y");
  for (size_t i = 0; i < n; i++) val[i] = v->valid[i] ? 1.f : 0.f;
}

static gi_result check_volume(const gi_probe_volume *v, gi_error_info *err) {
  if (!v || !v->pos || !v->valid || !v->probes)
    return gi__fail(err, GI_ERR_INVALID_ARG, "probe volume: %s is NULL",
                    !v ? "volume" : !v->pos ? "pos" : !v->valid ? "valid" : "probes");
  if (v->n == 0) return gi__fail(err, GI_ERR_INVALID_ARG, "probe volume: n is 0, no probes to write");
  /* Each count on its own: two negative ones multiply to a positive n. */
  if (v->counts[0] < 1 || v->counts[1] < 1 || v->counts[2] < 1 ||
      (size_t)v->counts[0] * v->counts[1] * v->counts[2] != v->n || v->n > GI_GRID_MAX_POINTS)
    return gi__fail(err, GI_ERR_INVALID_ARG, "probe volume: counts %d x %d x %d do not match %zu points",
                    v->counts[0], v->counts[1], v->counts[2], v->n);
  /* A street-level probe's height is read on this axis: 9 read pos and
   * wrote the voxel index out of bounds. */
  if (v->street_level && v->up_axis != 1 && v->up_axis != 2)
    return gi__fail(err, GI_ERR_INVALID_ARG, "probe volume: up_axis must be 1 (y) or 2 (z) for a street-level "
                    "volume, got %d", v->up_axis);
  if (!(v->spacing > 0) || !isfinite(v->spacing))
    return gi__fail(err, GI_ERR_INVALID_ARG, "probe volume: spacing must be finite and > 0");
  return GI_OK;
}

gi_result gi_probe_volume_write_exr(const char *path, const gi_probe_volume *v, const gi_exr_attr *attrs,
                                    size_t num_attrs, gi_error_info *err) {
  gi_result rc = check_volume(v, err);
  if (rc != GI_OK) return rc;
  planes_t p;
  memset(&p, 0, sizeof p);
  p.n = v->n;
  p.planes = gi__calloc((size_t)MAX_CHANNELS * v->n, sizeof(float));
  if (!p.planes) return gi__fail(err, GI_ERR_NOMEM, "probe EXR '%s': out of memory", path ? path : "");
  fill_planes(&p, v);
  gi_exr_image img = {.width = v->counts[0], .height = v->counts[1] * v->counts[2], .use_half = 0,
                      .compression = GI_EXR_ZIP, .num_channels = (size_t)p.nc, .channels = p.ch,
                      .num_attrs = num_attrs, .attrs = attrs};
  rc = gi_exr_write(path, &img, err);
  gi__free(p.planes);
  return rc;
}

/* 64-bit FNV-1a of s, from basis h. */
static uint64_t fnv1a(const char *s, uint64_t h) {
  for (; *s; s++) h = (h ^ (unsigned char)*s) * 1099511628211ull;
  return h;
}

/* A UUID-shaped file id derived from id, so equal bakes give equal files. */
static void uuid_from(const char *id, char out[37]) {
  uint64_t a = fnv1a(id, 14695981039346656037ull), b = fnv1a(id, a ^ 0x9e3779b97f4a7c15ull);
  snprintf(out, 37, "%08x-%04x-%04x-%04x-%012llx", (unsigned)(a >> 32), (unsigned)(a >> 16) & 0xffffu,
           (unsigned)a & 0xffffu, (unsigned)(b >> 48), (unsigned long long)(b & 0xffffffffffffull));
}

/* Voxel index of valid point i (x fastest), street-level probes at their
 * height; -1 when that height is no int voxel index (VDB's coordinates are
 * int32: 1e10 voxels up wrapped to 1.4e9). */
static int voxel_of(const gi_probe_volume *v, size_t i, int ijk[3]) {
  size_t nx = (size_t)v->counts[0], ny = (size_t)v->counts[1];
  ijk[0] = (int)(i % nx);
  ijk[1] = (int)((i / nx) % ny);
  ijk[2] = (int)(i / (nx * ny));
  if (v->street_level) {
    int u = v->up_axis;
    double h = (v->pos[3 * i + u] - v->origin[u]) / v->spacing;
    if (!(fabs(h) < INT_MAX)) return -1;
    ijk[u] = (int)lround(h);
  }
  return 0;
}

typedef struct {
  int *ijk;
  float *sh, *irr, *pos; /* 27, 3, 3 per voxel */
  size_t count;
} voxels_t;

static gi_result gather_voxels(const gi_probe_volume *v, voxels_t *vx, const char *path, gi_error_info *err) {
  size_t m = 0;
  for (size_t i = 0; i < v->n; i++) m += v->valid[i] != 0;
  vx->count = m;
  size_t cap = m ? m : 1;
  vx->ijk = gi__malloc(cap * 3 * sizeof(int));
  vx->sh = gi__malloc(cap * 27 * sizeof(float));
  vx->irr = gi__malloc(cap * 3 * sizeof(float));
  vx->pos = gi__malloc(cap * 3 * sizeof(float));
  if (!vx->ijk || !vx->sh || !vx->irr || !vx->pos)
    return gi__fail(err, GI_ERR_NOMEM, "probe VDB '%s': out of memory", path ? path : "");
  size_t o = 0;
  for (size_t i = 0; i < v->n; i++) {
    if (!v->valid[i]) continue;
    if (voxel_of(v, i, vx->ijk + 3 * o))
      return gi__fail(err, GI_ERR_INVALID_ARG, "probe VDB '%s': probe %zu's height %g is %g spacings from the "
                      "origin, past a VDB index", path ? path : "", i, (double)v->pos[3 * i + v->up_axis],
                      ((double)v->pos[3 * i + v->up_axis] - v->origin[v->up_axis]) / v->spacing);
    /* SH grid c holds coefficient c's RGB: stored grid by grid. */
    for (int c = 0; c < 9; c++)
      for (int k = 0; k < 3; k++) vx->sh[((size_t)c * m + o) * 3 + k] = v->probes[i].sh[c][k];
    for (int k = 0; k < 3; k++) {
      vx->irr[3 * o + k] = v->probes[i].irradiance[k];
      vx->pos[3 * o + k] = (float)v->pos[3 * i + k];
    }
    o++;
  }
  return GI_OK;
}

gi_result gi_probe_volume_write_vdb(const char *path, const gi_probe_volume *v, const char *id,
                                    gi_error_info *err) {
  gi_result rc = check_volume(v, err);
  if (rc != GI_OK) return rc;
  voxels_t vx;
  memset(&vx, 0, sizeof vx);
  if ((rc = gather_voxels(v, &vx, path, err)) != GI_OK) goto done;
  char names[9][16];
  gi_vdb_sparse grids[11];
  gi_vdb_sparse base = {.kind = GI_VDB_VEC3, .count = vx.count, .ijk = vx.ijk, .voxel_size = v->spacing};
  for (int a = 0; a < 3; a++) base.origin[a] = v->origin[a] - 0.5 * v->spacing;
  for (int c = 0; c < 9; c++) {
    snprintf(names[c], sizeof names[c], "sh_%s", sh_names[c]);
    grids[c] = base;
    grids[c].name = names[c];
    grids[c].data = vx.sh + (size_t)c * vx.count * 3;
  }
  grids[9] = base, grids[9].name = "irradiance", grids[9].data = vx.irr;
  grids[10] = base, grids[10].name = "P", grids[10].data = vx.pos;
  char counts[64], uuid[37];
  snprintf(counts, sizeof counts, "%d,%d,%d", v->counts[0], v->counts[1], v->counts[2]);
  gi_vdb_meta fm[] = {
      {"gi.kind", "probe-volume", 0},
      {"gi.bake_hash", id ? id : "", 0},
      {"gi.counts", counts, 0},
      {"gi.spacing", NULL, v->spacing},
      {"gi.sh", "SH L2 irradiance, real basis; grid sh_Lxx holds RGB of one coefficient; E(n) = sum sh_i Y_i(n)", 0},
  };
  if (id) uuid_from(id, uuid);
  rc = gi_vdb_write_sparse(path, grids, 11, fm, sizeof fm / sizeof fm[0], id ? uuid : NULL, err);
done:
  gi__free(vx.ijk); gi__free(vx.sh); gi__free(vx.irr); gi__free(vx.pos);
  return rc;
}
