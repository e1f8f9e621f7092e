/* export.c: the encode stage, probes to EXR and cascades to VDB.
 *
 * This file only arranges data; the files themselves are written by the
 * dependency glue (io/exr_io.c, io/vdb_shim.cpp), which writes to a
 * temporary name and renames into place. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "base/internal.h"
#include "cascade/cascade_internal.h"
#include "gi/gi_exr.h"
#include "gi/gi_vdb.h"
#include "gi_git_rev.h" /* GI_GIT_REV: generated at build time (cmake/git_rev.cmake) */

static const char *const sh_names[9] = {"L00", "L1-1", "L10", "L11", "L2-2", "L2-1", "L20", "L21", "L22"};
static const char rgb[3] = {'R', 'G', 'B'};

/* Writes the effect plan as "name=ran|skipped(why); ..." into buf. */
static void effects_text(const gi_bake_report *rep, char *buf, size_t size) {
  size_t off = 0;
  buf[0] = 0;
  for (int i = 0; i < GI_FX_COUNT && off < size; i++) {
    int w = snprintf(buf + off, size - off, "%s%s=%s (%s)", i ? "; " : "", gi_effect_name(i),
                     rep->effects[i].ran ? "ran" : "skipped", rep->effects[i].why);
    if (w < 0) break;
    off += (size_t)w;
  }
}

static void quality_text(const gi_quality *q, char *buf, size_t size) {
  snprintf(buf, size, "levels=%d res=%d voxel0=%.9g cones=%d aperture_deg=%g step=%g bounces=%d bounce_tail=%d "
                      "light_samples=%d probe_samples=%d seed=%llu",
           q->levels, q->res, q->voxel0, q->cones, q->aperture_deg, q->step, q->bounces, q->bounce_tail,
           q->light_samples, q->probe_samples, (unsigned long long)q->seed);
}

/* The header every EXR of a bake carries, plus the caller's extras. */
#define GI_MAX_EXR_ATTRS 24
typedef struct {
  char vp[128], qual[256], fx[1200], ver[64];
  gi_exr_attr attrs[GI_MAX_EXR_ATTRS];
  size_t n;
} exr_header;

/* Every file says the library that wrote it: gi-bake's files said
 * "gi-server", as if the server had made them. */
static void version_text(char *out, size_t size) { snprintf(out, size, "libgi %s (%s)", GI_VERSION, GI_GIT_REV); }

/* The attributes the writers set themselves (header_fill's six, then the
 * kind's own), and how many of the caller's extras fit beside them. */
static const char *const own_attrs[] = {"gi.scene", "gi.viewpoint", "gi.quality", "gi.effects",
                                        "gi.version", "gi.kind", "gi.sh", "gi.panorama"};
enum { MAX_EXTRA = GI_MAX_EXR_ATTRS - 2 - 6 };

/* The caller's extras: header_fill dereferenced a NULL array, dropped those
 * past MAX_EXTRA quietly, and let one named gi.scene replace the scene's. */
static gi_result check_extra(const gi_exr_extra *extra, size_t num_extra, const char *who, gi_error_info *err) {
  if (num_extra && !extra) return gi__fail(err, GI_ERR_INVALID_ARG, "%s: extra is NULL but num_extra is %zu", who,
                                           num_extra);
  if (num_extra > MAX_EXTRA)
    return gi__fail(err, GI_ERR_LIMIT, "%s: %zu extra attributes, at most %d fit", who, num_extra, MAX_EXTRA);
  for (size_t i = 0; i < num_extra; i++) {
    /* Named by the caller's index here: the writer's own list put it at 6. */
    if (!extra[i].name || !extra[i].name[0] || !extra[i].value)
      return gi__fail(err, GI_ERR_INVALID_ARG, "%s: extra attribute %zu has an empty name or no value", who, i);
    for (size_t k = 0; k < sizeof own_attrs / sizeof own_attrs[0]; k++)
      if (!strcmp(extra[i].name, own_attrs[k]))
        return gi__fail(err, GI_ERR_INVALID_ARG, "%s: extra attribute %zu ('%s') is one the writer sets", who, i,
                        extra[i].name);
  }
  return GI_OK;
}

static void header_fill(exr_header *h, const gi_scene *scene, const double at[3], const gi_bake_report *rep,
                        const char *kind, const gi_exr_extra *extra, size_t num_extra) {
  snprintf(h->vp, sizeof h->vp, "%.17g,%.17g,%.17g", at[0], at[1], at[2]);
  quality_text(&rep->quality, h->qual, sizeof h->qual);
  effects_text(rep, h->fx, sizeof h->fx);
  version_text(h->ver, sizeof h->ver);
  gi_exr_attr base[] = {
      {"gi.scene", scene ? gi_scene_name(scene) : ""},
      {"gi.viewpoint", h->vp},
      {"gi.quality", h->qual},
      {"gi.effects", h->fx},
      {"gi.version", h->ver},
      {"gi.kind", kind},
  };
  h->n = 0;
  for (size_t i = 0; i < sizeof base / sizeof base[0]; i++) h->attrs[h->n++] = base[i];
  /* Two places stay free for the kind's own attributes (gi.sh, gi.panorama). */
  for (size_t i = 0; i < num_extra && h->n < GI_MAX_EXR_ATTRS - 2; i++)
    h->attrs[h->n++] = (gi_exr_attr){extra[i].name, extra[i].value};
}

gi_result gi_probes_write_exr(const char *path, const gi_probe *probes, size_t n, const gi_scene *scene,
                              const double at[3], const gi_bake_report *rep, int use_half,
                              gi_error_info *err) {
  return gi_probes_write_exr_ex(path, probes, n, scene, at, rep, use_half, NULL, 0, err);
}

gi_result gi_panorama_write_exr(const char *path, int w, int h, const float *direct, const float *indirect,
                                const gi_scene *scene, const double at[3], const gi_bake_report *rep,
                                int use_half, const gi_exr_extra *extra, size_t num_extra, gi_error_info *err) {
  if (!path || !direct || !indirect || !rep || !at)
    return gi__fail(err, GI_ERR_INVALID_ARG, "panorama EXR: %s is NULL",
                    !path ? "path" : !direct ? "direct" : !indirect ? "indirect" : !rep ? "rep" : "at");
  if (w < 1 || h < 1) return gi__fail(err, GI_ERR_INVALID_ARG, "panorama EXR: size %dx%d is empty", w, h);
  gi_result rc = check_extra(extra, num_extra, "panorama EXR", err);
  if (rc != GI_OK) return rc;
  size_t px = (size_t)w * (size_t)h;
  float *planes = gi__malloc(9 * px * sizeof(float));
  if (!planes) return gi__fail(err, GI_ERR_NOMEM, "panorama EXR: out of memory");
  static const char *const names[9] = {"R", "G", "B", "direct.R", "direct.G", "direct.B",
                                       "indirect.R", "indirect.G", "indirect.B"};
  gi_exr_channel ch[9];
  for (int k = 0; k < 3; k++)
    for (size_t i = 0; i < px; i++) {
      planes[(size_t)k * px + i] = direct[3 * i + k] + indirect[3 * i + k];
      planes[(size_t)(3 + k) * px + i] = direct[3 * i + k];
      planes[(size_t)(6 + k) * px + i] = indirect[3 * i + k];
    }
  for (int c = 0; c < 9; c++) ch[c] = (gi_exr_channel){names[c], planes + (size_t)c * px};
  exr_header hd;
  header_fill(&hd, scene, at, rep, "panorama", extra, num_extra);
  const char *up = scene && gi_scene_up(scene) == GI_UP_Z ? "z" : "y";
  char map[200];
  snprintf(map, sizeof map, "lat-long incident radiance; row 0 looks up (+%s), theta = pi (y+0.5)/h, "
                            "phi = 2 pi (x+0.5)/w", up);
  if (hd.n < GI_MAX_EXR_ATTRS) hd.attrs[hd.n++] = (gi_exr_attr){"gi.panorama", map};
  gi_exr_image img = {.width = w, .height = h, .use_half = use_half, .compression = GI_EXR_ZIP,
                      .num_channels = 9, .channels = ch, .num_attrs = hd.n, .attrs = hd.attrs};
  rc = gi_exr_write(path, &img, err);
  gi__free(planes);
  return rc;
}

gi_result gi_probes_write_exr_ex(const char *path, const gi_probe *probes, size_t n, const gi_scene *scene,
                                 const double at[3], const gi_bake_report *rep, int use_half,
                                 const gi_exr_extra *extra, size_t num_extra, gi_error_info *err) {
  if (!path || !probes || !rep || !at)
    return gi__fail(err, GI_ERR_INVALID_ARG, "probe EXR: %s is NULL",
                    !path ? "path" : !probes ? "probes" : !rep ? "rep" : "at");
  if (n == 0) return gi__fail(err, GI_ERR_INVALID_ARG, "probe EXR: n is 0, no probes to write");
  gi_result erc = check_extra(extra, num_extra, "probe EXR", err);
  if (erc != GI_OK) return erc;
  if (n > (1u << 24)) return gi__fail(err, GI_ERR_LIMIT, "probe EXR: %zu probes exceed 2^24", n);
  enum { MAXCH = 3 + 3 + 3 + 3 + 1 + 27 };
  char names[MAXCH][32];
  float *planes = gi__calloc((size_t)MAXCH * n, sizeof(float));
  if (!planes) return gi__fail(err, GI_ERR_NOMEM, "probe EXR: out of memory");
  gi_exr_channel ch[MAXCH];
  int nc = 0;
  int ao = rep->effects[GI_FX_AO].ran;
#define ADD(fmt, ...) (snprintf(names[nc], sizeof names[nc], fmt, __VA_ARGS__), ch[nc].name = names[nc], \
                       ch[nc].data = planes + (size_t)nc * n, nc++)
  for (int k = 0; k < 3; k++) {
    int base = nc;
    ADD("%c", rgb[k]);
    ADD("irradiance.%c", rgb[k]);
    ADD("direct.%c", rgb[k]);
    ADD("indirect.%c", rgb[k]);
    for (size_t i = 0; i < n; i++) {
      planes[(size_t)(base + 0) * n + i] = probes[i].irradiance[k];
      planes[(size_t)(base + 1) * n + i] = probes[i].irradiance[k];
      planes[(size_t)(base + 2) * n + i] = probes[i].direct[k];
      planes[(size_t)(base + 3) * n + i] = probes[i].indirect[k];
    }
  }
  if (ao) {
    int base = nc;
    ADD("%s", "ao.Y");
    for (size_t i = 0; i < n; i++) planes[(size_t)base * n + i] = probes[i].ao;
  }
  for (int c = 0; c < 9; c++)
    for (int k = 0; k < 3; k++) {
      int base = nc;
      ADD("sh.%s.%c", sh_names[c], rgb[k]);
      for (size_t i = 0; i < n; i++) planes[(size_t)base * n + i] = probes[i].sh[c][k];
    }
#undef ADD
  exr_header hd;
  header_fill(&hd, scene, at, rep, "probe", extra, num_extra);
  hd.attrs[hd.n++] = (gi_exr_attr){"gi.sh", "SH L2 irradiance, real basis L00 L1-1 L10 L11 L2-2 L2-1 L20 L21 L22 "
                                            "over world x,y,z; E(n) = sum sh_i Y_i(n)"};
  gi_exr_image img = {.width = (int)n, .height = 1, .use_half = use_half, .compression = GI_EXR_ZIP,
                      .num_channels = (size_t)nc, .channels = ch, .num_attrs = hd.n, .attrs = hd.attrs};
  gi_result rc = gi_exr_write(path, &img, err);
  gi__free(planes);
  return rc;
}

/* Dense copies of one level in window order (x fastest), from toroidal storage. */
typedef struct {
  float *density, *cd, *albedo, *normal, *faces[6];
} level_dense;

static void free_dense(level_dense *ld) {
  gi__free(ld->density); gi__free(ld->cd); gi__free(ld->albedo); gi__free(ld->normal);
  for (int f = 0; f < 6; f++) gi__free(ld->faces[f]);
}

static gi_result fill_dense(const struct gi_cascade *c, int d, int faces, level_dense *ld) {
  const gi_level *L = &c->lv[d];
  int R = c->R;
  size_t vox = (size_t)R * R * R;
  memset(ld, 0, sizeof *ld);
  ld->density = gi__calloc(vox, sizeof(float));
  ld->cd = gi__calloc(vox * 3, sizeof(float));
  ld->albedo = gi__calloc(vox * 3, sizeof(float));
  ld->normal = gi__calloc(vox * 3, sizeof(float));
  if (!ld->density || !ld->cd || !ld->albedo || !ld->normal) return GI_ERR_NOMEM;
  if (faces)
    for (int f = 0; f < 6; f++)
      if (!(ld->faces[f] = gi__calloc(vox * 3, sizeof(float)))) return GI_ERR_NOMEM;
  for (int k = 0; k < R; k++)
    for (int j = 0; j < R; j++)
      for (int i = 0; i < R; i++) {
        uint32_t slot = gi__slot(L->cell0[0] + i, L->cell0[1] + j, L->cell0[2] + k, R);
        size_t o = (size_t)i + (size_t)R * ((size_t)j + (size_t)R * k);
        const gi_vgeo *g = gi__geo(L, slot);
        gi_vrad_f rv, *r = &rv;
        gi__vrad_unpack(c, &L->rad[slot], r);
        float dens = (r->alpha[0] + r->alpha[1] + r->alpha[2]) / 3.f;
        ld->density[o] = dens;
        if (g->area > 0) {
          /* Shown colour: the brightest face's outgoing radiance plus emission. */
          const float(*side)[3] = gi__side(L, slot);
          int fb = 0;
          for (int f = 1; f < GI_VOX_FACES; f++)
            if (gi__lum(side[f]) > gi__lum(side[fb])) fb = f;
          const float *E = side[fb];
          for (int a = 0; a < 3; a++) {
            ld->cd[3 * o + a] = g->albedo[a] / GI_PI_F * E[a] + g->emission[a];
            ld->albedo[3 * o + a] = g->albedo[a];
            ld->normal[3 * o + a] = g->normal[a];
          }
        }
        if (faces)
          for (int f = 0; f < 6; f++)
            for (int a = 0; a < 3; a++) ld->faces[f][3 * o + a] = r->p[f][a];
      }
  return GI_OK;
}

size_t gi_cascade_vdb_bytes_estimate(const gi_cascade *c, int faces) {
  if (!c) return 0;
  size_t vox = (size_t)c->R * c->R * c->R;
  return (size_t)c->n * vox * (size_t)(10 + (faces ? 18 : 0)) * sizeof(float);
}

gi_result gi_cascade_write_vdb(const gi_cascade *c, const char *path, int faces, gi_error_info *err) {
  if (!c || !path) return gi__fail(err, GI_ERR_INVALID_ARG, "VDB: %s is NULL", !c ? "cascade" : "path");
  if (gi__cascade_whole(c, "VDB", err) != GI_OK) return GI_ERR_INVALID_ARG;
  static const char *const face_names[6] = {"px", "nx", "py", "ny", "pz", "nz"};
  int n = c->n;
  int per = 4 + (faces ? 6 : 0);
  size_t ng = (size_t)n * per + 2;
  gi_vdb_grid *grids = gi__calloc(ng, sizeof *grids);
  level_dense *ld = gi__calloc((size_t)n, sizeof *ld);
  char(*names)[48] = gi__calloc(ng, sizeof *names);
  gi_vdb_meta(*meta)[6] = gi__calloc((size_t)n, sizeof *meta);
  char(*vp)[160] = gi__calloc((size_t)n, sizeof *vp);
  gi_result rc = GI_OK;
  if (!grids || !ld || !names || !meta || !vp) {
    rc = gi__fail(err, GI_ERR_NOMEM, "VDB '%s': out of memory", path);
    goto done;
  }
  size_t g = 0;
  char viewpoint[160];
  snprintf(viewpoint, sizeof viewpoint, "%.17g,%.17g,%.17g", c->at_world[0], c->at_world[1], c->at_world[2]);
  for (int d = 0; d < n; d++) {
    if (fill_dense(c, d, faces, &ld[d]) != GI_OK) {
      rc = gi__fail(err, GI_ERR_NOMEM, "VDB '%s': out of memory for level %d", path, d);
      goto done;
    }
    const gi_level *L = &c->lv[d];
    snprintf(vp[d], sizeof vp[d], "%s", viewpoint);
    meta[d][0] = (gi_vdb_meta){"gi.level", NULL, d};
    meta[d][1] = (gi_vdb_meta){"gi.resolution", NULL, c->R};
    meta[d][2] = (gi_vdb_meta){"gi.viewpoint", vp[d], 0};
    meta[d][3] = (gi_vdb_meta){"gi.scene", gi_scene_name(c->scene), 0};
    meta[d][4] = (gi_vdb_meta){"gi.voxel_size", NULL, L->s};
    gi_vdb_grid base = {.dims = {c->R, c->R, c->R}, .voxel_size = L->s, .num_meta = 5, .meta = meta[d]};
    for (int a = 0; a < 3; a++) base.origin[a] = (double)L->cell0[a] * L->s + c->scene->origin[a];
    const struct { const char *suffix; gi_vdb_kind kind; const float *data; int fog; } list[4] = {
        {"density", GI_VDB_FLOAT, ld[d].density, 1},
        {"Cd", GI_VDB_VEC3, ld[d].cd, 0},
        {"albedo", GI_VDB_VEC3, ld[d].albedo, 0},
        {"normal", GI_VDB_VEC3, ld[d].normal, 0},
    };
    for (int i = 0; i < 4; i++) {
      grids[g] = base;
      snprintf(names[g], sizeof names[g], "L%d_%s", d, list[i].suffix);
      grids[g].name = names[g];
      grids[g].kind = list[i].kind;
      grids[g].data = list[i].data;
      grids[g].fog_volume = list[i].fog;
      g++;
    }
    for (int f = 0; faces && f < 6; f++) {
      grids[g] = base;
      snprintf(names[g], sizeof names[g], "L%d_face_%s", d, face_names[f]);
      grids[g].name = names[g];
      grids[g].kind = GI_VDB_VEC3;
      grids[g].data = ld[d].faces[f];
      g++;
    }
    if (d == 0) {
      /* The finest level again under the names viewers show first. */
      grids[g] = grids[g - per];
      grids[g].name = "density";
      g++;
      grids[g] = grids[g - per];
      grids[g].name = "Cd";
      g++;
    }
  }
  char ver[64];
  version_text(ver, sizeof ver);
  gi_vdb_meta fm[] = {{"gi.scene", gi_scene_name(c->scene), 0}, {"gi.viewpoint", viewpoint, 0},
                      {"gi.levels", NULL, n}, {"gi.version", ver, 0}};
  rc = gi_vdb_write(path, grids, g, fm, sizeof fm / sizeof fm[0], err);
done:
  if (ld)
    for (int d = 0; d < n; d++) free_dense(&ld[d]);
  gi__free(ld); gi__free(grids); gi__free(names); gi__free(meta); gi__free(vp);
  return rc;
}
