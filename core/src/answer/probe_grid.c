/* probe_grid.c: where a batch bake's probes go (gi_batch.h).
 *
 * A full lattice is pure arithmetic. Street-level mode shoots rays through
 * the scene's Embree BVH. Per column one downward ray, repeated past each
 * hit, lists the surfaces that are level enough to stand on, each facing
 * up (a floor: ground, roof, deck top) or down (an underside), reading the
 * winding as the cities' meshes give it (roofs and ground face up). The
 * ground is the first floor from the top that is not
 *  - a roof: a floor with another floor below it and no underside between
 *    (a building without a bottom) or an underside right on one (a closed
 *    box standing on the ground), nor
 *  - a cover: the top of a solid with open air and a floor below it that
 *    is narrower than COVER_MAX_WIDTH across (a canopy, a bridge deck).
 * So the top of a closed ground slab is ground (the lowest surface was its
 * bottom face), and so is a street over a tunnel (the layer above the
 * tunnel is no narrow solid), while the probes of a building's columns go
 * onto the ground inside it, to be dropped, and those under a canopy onto
 * the street. A column with no floor at all takes its lowest surface.
 *
 * A probe is inside a building when it is covered (the ray straight up
 * hits something) and enclosed: each of eight horizontal rays meets a
 * wall. Under a ceiling (a cover's underside, facing down) a wall is one
 * met from behind (inside a closed solid) or within ENCLOSE_REACH: a
 * facade across the square or at the end of the street, met from the
 * front, leaves an arcade, a canopy or a bridge open. Under a roof seen
 * from inside (its back) any wall at any distance encloses: OSM blocks'
 * courtyard walls may face into the block. A street is open to the sky;
 * a room is closed whichever way its walls are wound. */
#include <float.h>
#include <math.h>
#include <string.h>
#include "base/internal.h"
#include "gi/gi_batch.h"
#include "scene/scene_internal.h"

/* At most this many surfaces are stepped through on the way down a column. */
#define MAX_COLUMN_HITS 256
/* Horizontal directions of the enclosure test. */
#define ENCLOSE_DIRS 8
/* A wall a horizontal ray meets from the front encloses the probe when it
 * is nearer than this (world units, metres in the cities): a room's or a
 * building's wall, not a facade across a square. */
#define ENCLOSE_REACH 30.0f
/* A solid with open air below that is narrower than this across (world
 * units) in some horizontal direction is a cover over the ground (a canopy,
 * a bridge deck); a wider one is ground (a street over a tunnel). */
#define COVER_MAX_WIDTH 60.0f
/* The step, in ray offsets, of a cover test repeated beside its column. */
#define COVER_NUDGE 100
/* A surface is level (a floor or an underside) when its normal is within
 * about 84 degrees of the up axis; steeper ones are walls. */
#define LEVEL_COS 0.1
/* Facing flags of a column's hit. */
#define FACES_UP 1
#define FACES_DOWN 2
/* Ray offsets, as a fraction of the scene's largest extent. */
#define REL_EPS 1e-6

typedef struct {
  float h;              /* local up coordinate */
  int faces;            /* FACES_UP | FACES_DOWN of the level surfaces there; 0: a wall */
} col_hit;

typedef struct {
  const struct gi_scene *s;
  int u, h0, h1;        /* up axis and the two horizontal ones (0..2) */
  float eps;            /* ray offset, local units */
  float top, floor_;    /* local up coordinates: where columns start and stop */
  uint32_t *tris;       /* scratch of facings_at */
  size_t ntris, cap;
  col_hit hits[MAX_COLUMN_HITS];
} ray_ctx;

/* The facings of the level surfaces crossing the column at (a, b) within
 * 2 eps of height h: the one a ray met and any coplanar one it hid (a
 * box's bottom face on the ground: the step past a hit skips the other). */
static int facings_at(ray_ctx *c, float a, float b, float h) {
  float lo[3], hi[3];
  lo[c->h0] = a - c->eps, hi[c->h0] = a + c->eps;
  lo[c->h1] = b - c->eps, hi[c->h1] = b + c->eps;
  lo[c->u] = h - 2 * c->eps, hi[c->u] = h + 2 * c->eps;
  c->ntris = 0;
  if (gi__query_box(c->s, lo, hi, &c->tris, &c->ntris, &c->cap) != GI_OK) return 0;
  int faces = 0;
  for (size_t q = 0; q < c->ntris; q++) {
    const uint32_t *ti = c->s->indices + 3 * (size_t)c->tris[q];
    double v[3][3];
    for (int k = 0; k < 3; k++)
      for (int a3 = 0; a3 < 3; a3++) v[k][a3] = c->s->vertices[3 * (size_t)ti[k] + a3];
    double e1[3], e2[3];
    for (int a3 = 0; a3 < 3; a3++) e1[a3] = v[1][a3] - v[0][a3], e2[a3] = v[2][a3] - v[0][a3];
    double n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
    double len = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    if (!(fabs(n[c->u]) > LEVEL_COS * len)) continue;
    /* Barycentric weights of the column in the horizontal plane. */
    double w[3], area = 0;
    for (int k = 0; k < 3; k++) {
      const double *p = v[(k + 1) % 3], *r = v[(k + 2) % 3];
      w[k] = (p[c->h0] - a) * (r[c->h1] - b) - (p[c->h1] - b) * (r[c->h0] - a);
      area += w[k];
    }
    if (area == 0 || w[0] / area < -1e-6 || w[1] / area < -1e-6 || w[2] / area < -1e-6) continue;
    double at = (w[0] * v[0][c->u] + w[1] * v[1][c->u] + w[2] * v[2][c->u]) / area;
    if (fabs(at - h) <= 2 * c->eps) faces |= n[c->u] > 0 ? FACES_UP : FACES_DOWN;
  }
  return faces;
}

/* Whether the solid between heights top and bottom at local (a, b) is
 * narrower than COVER_MAX_WIDTH between its sides in some direction. */
static int narrow_at(const ray_ctx *c, float a, float b, float top, float bottom) {
  float p[3], t0, t1;
  p[c->h0] = a, p[c->h1] = b, p[c->u] = 0.5f * (top + bottom);
  for (int k = 0; k < ENCLOSE_DIRS / 2; k++) {
    double ang = 2.0 * GI_PI * k / ENCLOSE_DIRS;
    float d[3] = {0, 0, 0}, e[3] = {0, 0, 0};
    d[c->h0] = (float)cos(ang), d[c->h1] = (float)sin(ang);
    e[c->h0] = -d[c->h0], e[c->h1] = -d[c->h1];
    if (gi__intersect1(c->s, p, d, c->eps, COVER_MAX_WIDTH, &t0, NULL, NULL) &&
        gi__intersect1(c->s, p, e, c->eps, COVER_MAX_WIDTH, &t1, NULL, NULL) && t0 + t1 <= COVER_MAX_WIDTH)
      return 1;
  }
  return 0;
}

/* A cover (see the file comment). A column in the plane of the solid's
 * side (a grid line along a canopy's edge) has its rays graze that side:
 * then a step inside decides. */
static int is_cover(const ray_ctx *c, float a, float b, float top, float bottom) {
  if (narrow_at(c, a, b, top, bottom)) return 1;
  float d = COVER_NUDGE * c->eps;
  return narrow_at(c, a + d, b, top, bottom) || narrow_at(c, a - d, b, top, bottom) ||
         narrow_at(c, a, b + d, top, bottom) || narrow_at(c, a, b - d, top, bottom);
}

/* The ground of the column at local (a, b) (see the file comment); 0 when
 * the column meets nothing. */
static int column_ground(ray_ctx *c, float a, float b, float *ground) {
  float org[3], dir[3] = {0, 0, 0}, ng[3];
  org[c->h0] = a, org[c->h1] = b, org[c->u] = c->top;
  dir[c->u] = -1;
  float tfar = c->top - c->floor_, tnear = 0, t;
  col_hit *hit = c->hits;
  int n = 0;
  while (n < MAX_COLUMN_HITS) {
    if (!gi__intersect1(c->s, org, dir, tnear, tfar, &t, NULL, ng)) break;
    float h = c->top - t;
    int faces = facings_at(c, a, b, h);
    if (fabsf(ng[c->u]) > LEVEL_COS) faces |= ng[c->u] > 0 ? FACES_UP : FACES_DOWN;
    hit[n++] = (col_hit){h, faces};
    tnear = t + c->eps;
    if (tnear > tfar) break;
  }
  if (!n) return 0;
  int i = 0;
  while (i < n && !(hit[i].faces & FACES_UP)) i++;
  if (i == n) { /* nothing faces up (a mesh wound the other way): the lowest surface */
    *ground = hit[n - 1].h;
    return 1;
  }
  for (;;) {
    int j = i + 1;
    while (j < n && !hit[j].faces) j++;
    if (j == n) break;
    /* A floor next: hit[i] is a roof (or a sheet) over it. */
    if (hit[j].faces & FACES_UP) { i = j; continue; }
    /* hit[i]'s underside at hit[j]: a cover when it is narrow and has a floor below. */
    int k = j + 1;
    while (k < n && !(hit[k].faces & FACES_UP)) k++;
    if (k == n || !is_cover(c, a, b, hit[i].h, hit[j].h)) break;
    i = k;
  }
  *ground = hit[i].h;
  return 1;
}

/* A column on the scene's outer edge (a grid over the bounds puts its last
 * row there) runs along the ground's boundary edge, which Embree's edge
 * rule counts on one side only: the max edge's columns all missed. Such a
 * column looks for ground just inside the bounds. 0 when it is not on an
 * edge or finds nothing there either. */
static int edge_ground(ray_ctx *c, const float local[3], float *ground) {
  const int ax[2] = {c->h0, c->h1};
  float q[2] = {local[c->h0], local[c->h1]};
  int moved = 0;
  for (int i = 0; i < 2; i++) {
    float lo = c->s->lo[ax[i]], hi = c->s->hi[ax[i]];
    if (fabsf(q[i] - hi) <= c->eps) q[i] = hi - c->eps, moved = 1;
    else if (fabsf(q[i] - lo) <= c->eps) q[i] = lo + c->eps, moved = 1;
  }
  return moved && column_ground(c, q[0], q[1], ground);
}

/* Covered and enclosed: see the file comment. */
static int inside_building(const ray_ctx *c, const float p[3]) {
  float dir[3] = {0, 0, 0}, t, ng[3];
  dir[c->u] = 1;
  if (!gi__intersect1(c->s, p, dir, c->eps, INFINITY, &t, NULL, ng)) return 0;
  int ceiling = ng[c->u] < 0;
  for (int k = 0; k < ENCLOSE_DIRS; k++) {
    double ang = 2.0 * GI_PI * k / ENCLOSE_DIRS;
    float d[3] = {0, 0, 0};
    d[c->h0] = (float)cos(ang), d[c->h1] = (float)sin(ang);
    if (!gi__intersect1(c->s, p, d, c->eps, INFINITY, &t, NULL, ng)) return 0;
    /* Under a ceiling, a front face far off is a facade across the street, not a wall of ours. */
    if (ceiling && t > ENCLOSE_REACH && gi__dot(ng, d) <= 0) return 0;
  }
  return 1;
}

/* Region checks; the region (or the scene's bounds) into lo, hi. */
static gi_result region_of(const gi_scene *scene, const gi_grid_spec *spec, double lo[3], double hi[3],
                           gi_error_info *err) {
  double slo[3], shi[3];
  gi_scene_bounds(scene, slo, shi);
  if (!spec->have_region) {
    memcpy(lo, slo, sizeof slo), memcpy(hi, shi, sizeof shi);
    return GI_OK;
  }
  for (int a = 0; a < 3; a++) {
    lo[a] = spec->lo[a], hi[a] = spec->hi[a];
    if (!isfinite(lo[a]) || !isfinite(hi[a]) || lo[a] > hi[a])
      return gi__fail(err, GI_ERR_INVALID_ARG, "region: min must not exceed max on axis %c (%g > %g)", "xyz"[a],
                      lo[a], hi[a]);
  }
  /* Beside the scene, not above or below it: probes over the roofs (an
   * aerial box wholly above the bounds) are a fair request; it was refused
   * while one reaching 1 cm into the bounds baked the same probes. */
  int up = gi_scene_up(scene) == GI_UP_Z ? 2 : 1;
  for (int a = 0; a < 3; a++)
    if (a != up && (hi[a] < slo[a] || lo[a] > shi[a]))
      return gi__fail(err, GI_ERR_INVALID_ARG,
                      "region (%g,%g,%g)..(%g,%g,%g) lies beside the scene bounds (%g,%g,%g)..(%g,%g,%g)", lo[0],
                      lo[1], lo[2], hi[0], hi[1], hi[2], slo[0], slo[1], slo[2], shi[0], shi[1], shi[2]);
  return GI_OK;
}

/* Counts, origin and n, nothing allocated. */
static gi_result count_points(const gi_grid_spec *spec, int u, const double lo[3], const double hi[3],
                              gi_probe_grid *g, gi_error_info *err) {
  double total = 1;
  for (int a = 0; a < 3; a++) {
    /* A point on the region's far face counts, whatever the rounding of
     * its ends: 1e6 away, 0.9 of 0.02 steps read 44.99999999 (45 points
     * where the same region at the origin has 46). */
    double tol = 1e-9 + 8 * DBL_EPSILON * (fabs(lo[a]) + fabs(hi[a])) / spec->spacing;
    double c = (spec->above_ground > 0 && a == u) ? 1 : floor((hi[a] - lo[a]) / spec->spacing + tol) + 1;
    total *= c;
    if (total > (double)GI_GRID_MAX_POINTS)
      return gi__fail(err, GI_ERR_LIMIT, "grid spacing %g gives more than %zu probes over the region", spec->spacing,
                      GI_GRID_MAX_POINTS);
    g->counts[a] = (int)c;
    g->origin[a] = lo[a];
  }
  g->n = (size_t)total;
  return GI_OK;
}

/* Counts and allocation; the lattice positions (street level: up = floor). */
static gi_result lay_out(const gi_grid_spec *spec, int u, const double lo[3], const double hi[3], gi_probe_grid *g,
                         gi_error_info *err) {
  gi_result rc = count_points(spec, u, lo, hi, g, err);
  if (rc != GI_OK) return rc;
  g->pos = gi__malloc(g->n * 3 * sizeof(double));
  g->state = gi__malloc(g->n);
  if (!g->pos || !g->state) return gi__fail(err, GI_ERR_NOMEM, "probe grid: out of memory for %zu probes", g->n);
  size_t i = 0;
  for (int z = 0; z < g->counts[2]; z++)
    for (int y = 0; y < g->counts[1]; y++)
      for (int x = 0; x < g->counts[0]; x++, i++) {
        int idx[3] = {x, y, z};
        for (int a = 0; a < 3; a++) g->pos[3 * i + a] = g->origin[a] + idx[a] * spec->spacing;
        g->state[i] = GI_GRID_VALID;
      }
  g->num_valid = g->n;
  return GI_OK;
}

/* Street level: each column's probe on its ground, or dropped. */
static void place_above_ground(const gi_scene *scene, const gi_grid_spec *spec, const double hi[3], gi_probe_grid *g) {
  const struct gi_scene *s = scene;
  ray_ctx c = {.s = s, .u = g->up_axis, .h0 = 0, .h1 = g->up_axis == 1 ? 2 : 1};
  double ext = 0;
  for (int a = 0; a < 3; a++) ext = fmax(ext, (double)s->hi[a] - s->lo[a]);
  c.eps = (float)(REL_EPS * ext + 1e-7);
  /* Start just above the scene (or the region's top, when lower). */
  double top_world = fmin(hi[c.u], s->origin[c.u] + s->hi[c.u] + 10 * c.eps);
  c.top = (float)(top_world - s->origin[c.u]) + c.eps;
  c.floor_ = (float)(g->origin[c.u] - s->origin[c.u]) - 10 * c.eps; /* a ground exactly at the floor counts */
  g->num_valid = 0;
  for (size_t i = 0; i < g->n; i++) {
    double *p = g->pos + 3 * i;
    float local[3];
    for (int a = 0; a < 3; a++) local[a] = (float)(p[a] - s->origin[a]);
    float ground;
    if (!column_ground(&c, local[c.h0], local[c.h1], &ground) && !edge_ground(&c, local, &ground)) {
      g->state[i] = GI_GRID_NO_GROUND;
      g->num_no_ground++;
      continue;
    }
    local[c.u] = ground + (float)spec->above_ground;
    p[c.u] = s->origin[c.u] + local[c.u];
    if (inside_building(&c, local)) {
      g->state[i] = GI_GRID_INSIDE;
      g->num_inside++;
    } else {
      g->num_valid++;
    }
  }
  gi__free(c.tris);
}

/* The checks both entry points make; the region into lo, hi and the layout's fields into out. */
static gi_result grid_start(const gi_scene *scene, const gi_grid_spec *spec, gi_probe_grid *out, double lo[3],
                            double hi[3], gi_error_info *err) {
  if (!out) return gi__fail(err, GI_ERR_INVALID_ARG, "probe grid: out is NULL");
  memset(out, 0, sizeof *out);
  if (!scene || !spec)
    return gi__fail(err, GI_ERR_INVALID_ARG, "probe grid: %s is NULL", !scene ? "scene" : "spec");
  if (!(spec->spacing > 0) || !isfinite(spec->spacing))
    return gi__fail(err, GI_ERR_INVALID_ARG, "grid spacing must be finite and > 0, got %g", spec->spacing);
  if (!(spec->above_ground >= 0) || !isfinite(spec->above_ground))
    return gi__fail(err, GI_ERR_INVALID_ARG, "height above ground must be finite and >= 0, got %g",
                    spec->above_ground);
  gi_result rc = region_of(scene, spec, lo, hi, err);
  if (rc != GI_OK) return rc;
  out->spacing = spec->spacing;
  out->above_ground = spec->above_ground;
  out->up_axis = gi_scene_up(scene) == GI_UP_Z ? 2 : 1;
  return GI_OK;
}

gi_result gi_probe_grid_size(const gi_scene *scene, const gi_grid_spec *spec, gi_probe_grid *out,
                             gi_error_info *err) {
  double lo[3], hi[3];
  gi_result rc = grid_start(scene, spec, out, lo, hi, err);
  if (rc == GI_OK) rc = count_points(spec, out->up_axis, lo, hi, out, err);
  if (rc != GI_OK) gi_probe_grid_free(out);
  else out->num_valid = out->n; /* before street level drops any */
  return rc;
}

gi_result gi_probe_grid_build(const gi_scene *scene, const gi_grid_spec *spec, gi_probe_grid *out,
                              gi_error_info *err) {
  double lo[3], hi[3];
  gi_result rc = grid_start(scene, spec, out, lo, hi, err);
  if (rc != GI_OK) return rc;
  if ((rc = lay_out(spec, out->up_axis, lo, hi, out, err)) != GI_OK) {
    gi_probe_grid_free(out);
    return rc;
  }
  if (spec->above_ground > 0) place_above_ground(scene, spec, hi, out);
  /* The files store points as float: a region or a height past its range
   * (1e39) gave valid probes at Inf, which every gather and writer refuses. */
  for (size_t i = 0; i < 3 * out->n; i++)
    if (!(fabs(out->pos[i]) <= FLT_MAX)) {
      double at = out->pos[i];
      gi_probe_grid_free(out);
      return gi__fail(err, GI_ERR_INVALID_ARG, "grid point %zu lies at %g on axis %c, beyond float range: "
                      "the region or above_ground is too large", i / 3, at, "xyz"[i % 3]);
    }
  return GI_OK;
}

void gi_probe_grid_free(gi_probe_grid *g) {
  if (!g) return;
  gi__free(g->pos);
  gi__free(g->state);
  /* Zeroed whole: a build that fails after laying out leaves no counts
   * (n, counts) beside NULL arrays. */
  memset(g, 0, sizeof *g);
}
