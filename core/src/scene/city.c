/* city.c: the embedded default scene, a deterministic procedural city.
 *
 * Design: the whole layout is computed in integer millimetres (int64) and
 * every coordinate reaches the builder through one exact conversion
 * (mm / 1000.0), so no floating-point sum can be contracted or reordered
 * differently on another compiler or CPU: the same params give the same
 * triangles bit for bit everywhere. Randomness comes from splitmix64; each
 * block and each street line has its own stream seeded from (seed, cell), so
 * the result does not depend on loop order either. Street centre lines lie
 * on multiples of the block pitch, so the origin is always an intersection.
 * The ground is tiled into intersections, street segments and lots (one quad
 * each, clipped to the extent). Each lot is split into 1-4 x 1-4 buildings:
 * boxes whose facades are grids of storeys x window columns (column width
 * 6 m / detail) sharing vertices, some cells lit with an emissive material;
 * heights fall off from the centre, where a few towers rise. Street lamps
 * stand on the sidewalks every ~30 m; the ones nearest the centre also
 * become point lights. The palette is a fixed set of materials added once. */
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include "gi/gi_city.h"
#include "base/internal.h"

/* Limits that keep generation time and memory bounded for any input. */
#define CITY_MAX_EXTENT_M 20000.0
#define CITY_MAX_CELLS_PER_SIDE 2000
/* Point lights gi_city_build adds (the lamps nearest the centre): each one
 * costs a shadow ray per voxel at injection, and far ones barely matter. */
#define CITY_BUILD_POINT_LIGHTS 32

/* Dimensions in millimetres. */
enum {
  STOREY_MM = 3500,
  SETBACK_MM = 2000,     /* sidewalk between curb and buildings */
  MIN_LOT_MM = 6000,     /* smaller lots stay plazas */
  MIN_BUILDING_MM = 5000,
  COLUMN_MM = 6000,      /* window column width at detail 1 */
  LAMP_SPACING_MM = 30000,
  POLE_HALF_MM = 80,
  POLE_CURB_MM = 500,    /* pole centre behind the curb */
  POLE_TOP_MM = 6250,
  LAMP_HALF_MM = 250,
  LAMP_BOTTOM_MM = 6000,
  LIGHT_BELOW_MM = 100,  /* point light just under the lamp box, outside all geometry */
};

/* Palette indices (offsets from the first material this file adds). */
enum {
  M_ASPHALT, M_LOT, M_ROOF, M_BRICK, M_SAND, M_PLASTER, M_CONCRETE, M_GLASS,
  M_POLE, M_LAMP, M_WINDOW_WARM, M_WINDOW_BRIGHT, M_COUNT
};

typedef struct palette_entry {
  const char *name;
  float albedo[3], emission[3], roughness, specular;
} palette_entry;

static const palette_entry palette[M_COUNT] = {
    [M_ASPHALT] = {"city_asphalt", {0.10f, 0.10f, 0.10f}, {0, 0, 0}, 1.f, 0.f},
    [M_LOT] = {"city_sidewalk", {0.42f, 0.40f, 0.37f}, {0, 0, 0}, 1.f, 0.f},
    [M_ROOF] = {"city_roof", {0.30f, 0.29f, 0.28f}, {0, 0, 0}, 1.f, 0.f},
    [M_BRICK] = {"city_brick", {0.45f, 0.20f, 0.14f}, {0, 0, 0}, 1.f, 0.f},
    [M_SAND] = {"city_sandstone", {0.62f, 0.52f, 0.38f}, {0, 0, 0}, 1.f, 0.f},
    [M_PLASTER] = {"city_plaster", {0.80f, 0.80f, 0.78f}, {0, 0, 0}, 1.f, 0.f},
    [M_CONCRETE] = {"city_concrete", {0.42f, 0.42f, 0.42f}, {0, 0, 0}, 1.f, 0.f},
    /* The one glossy surface: dark glass curtain walls. */
    [M_GLASS] = {"city_glass", {0.10f, 0.12f, 0.14f}, {0, 0, 0}, 0.3f, 0.04f},
    [M_POLE] = {"city_pole", {0.25f, 0.25f, 0.26f}, {0, 0, 0}, 1.f, 0.f},
    [M_LAMP] = {"city_lamp", {0.80f, 0.80f, 0.80f}, {6.0f, 5.2f, 3.8f}, 1.f, 0.f},
    [M_WINDOW_WARM] = {"city_window_warm", {0.20f, 0.20f, 0.20f}, {3.0f, 2.2f, 1.3f}, 1.f, 0.f},
    [M_WINDOW_BRIGHT] = {"city_window_bright", {0.20f, 0.20f, 0.20f}, {6.0f, 5.0f, 3.4f}, 1.f, 0.f},
};

static const float LAMP_INTENSITY[3] = {120.f, 100.f, 72.f};
static const double SUN_DIR[3] = {0.35, -0.8, 0.45};
static const float SUN_IRRADIANCE[3] = {3.2f, 3.0f, 2.7f};
static const float SKY_RADIANCE[3] = {0.25f, 0.32f, 0.45f};

/* --- PRNG ------------------------------------------------------------------ */

typedef struct rng { uint64_t s; } rng;

static uint64_t splitmix64(uint64_t *s) {
  uint64_t z = (*s += 0x9E3779B97F4A7C15ull);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

/* An independent stream per (seed, kind, i, j): results never depend on the
 * order in which cells are visited. */
static rng rng_for(uint64_t seed, uint64_t kind, int64_t i, int64_t j) {
  uint64_t s = seed;
  uint64_t h = splitmix64(&s);
  h ^= kind * 0xD6E8FEB86659FD93ull;
  h ^= (uint64_t)i * 0xA0761D6478BD642Full;
  h ^= (uint64_t)j * 0xE7037ED1A0B428DBull;
  rng r = {h};
  splitmix64(&r.s); /* decorrelate neighbouring cells */
  return r;
}

/* Uniform in [0, n), n > 0 (the tiny modulo bias is irrelevant here). */
static uint32_t rnd(rng *r, uint32_t n) { return (uint32_t)(splitmix64(&r->s) % n); }

/* --- geometry helpers (integer millimetres in, metres out) ------------------ */

typedef struct city {
  gi_mesh_builder *b;
  uint32_t mat0;     /* builder index of palette[0] */
  int64_t half;      /* extent / 2 */
  int64_t pitch, street;
  int detail;
  uint64_t seed;
  int64_t towers_r2; /* squared radius (m^2) of the tower zone */
  int64_t r2;        /* squared half extent (m^2) */
  /* Lamp positions (light point) for the point lights, grown geometrically. */
  int64_t (*lamps)[3];
  size_t num_lamps, cap_lamps;
  int oom;
} city;

static double m_of(int64_t mm) { return (double)mm / 1000.0; }

static uint32_t vtx(city *c, int64_t x, int64_t y, int64_t z) {
  return gi_mesh_builder_add_vertex(c->b, m_of(x), m_of(y), m_of(z));
}

static uint32_t mat(const city *c, int m) { return c->mat0 + (uint32_t)m; }

/* A ground rectangle at y = 0 facing up, clipped to the city; skipped when empty. */
static void ground(city *c, int64_t x0, int64_t z0, int64_t x1, int64_t z1, int m) {
  if (x0 < -c->half) x0 = -c->half;
  if (z0 < -c->half) z0 = -c->half;
  if (x1 > c->half) x1 = c->half;
  if (z1 > c->half) z1 = c->half;
  if (x1 <= x0 || z1 <= z0) return;
  uint32_t a = vtx(c, x0, 0, z0), b = vtx(c, x0, 0, z1), d = vtx(c, x1, 0, z1), e = vtx(c, x1, 0, z0);
  gi_mesh_builder_add_triangle(c->b, a, b, d, mat(c, m));
  gi_mesh_builder_add_triangle(c->b, a, d, e, mat(c, m));
}

static void box(city *c, int64_t x0, int64_t y0, int64_t z0, int64_t x1, int64_t y1, int64_t z1, int m) {
  double lo[3] = {m_of(x0), m_of(y0), m_of(z0)}, hi[3] = {m_of(x1), m_of(y1), m_of(z1)};
  gi_mesh_builder_add_box(c->b, lo, hi, mat(c, m));
}

/* One facade: a grid of cols x storeys cells sharing vertices. (ox, oz) is the
 * bottom-left corner seen from outside and (ux, uz) the unit direction to the
 * right, so (u x up) is the outward normal and cells wind counter-clockwise. */
static void facade(city *c, rng *r, int64_t ox, int64_t oz, int ux, int uz, int64_t len, int storeys,
                   int wall) {
  int64_t cols = (len * c->detail + COLUMN_MM - 1) / COLUMN_MM;
  if (cols < 1) cols = 1;
  uint32_t first = 0;
  for (int row = 0; row <= storeys; row++)
    for (int64_t col = 0; col <= cols; col++) {
      int64_t t = len * col / cols;
      uint32_t v = vtx(c, ox + ux * t, (int64_t)row * STOREY_MM, oz + uz * t);
      if (row == 0 && col == 0) first = v;
    }
  uint32_t stride = (uint32_t)cols + 1;
  for (int row = 0; row < storeys; row++)
    for (int64_t col = 0; col < cols; col++) {
      /* About 7% of the windows are lit, two shades of warm light. */
      uint32_t roll = rnd(r, 1000);
      int m = roll < 45 ? M_WINDOW_WARM : roll < 70 ? M_WINDOW_BRIGHT : wall;
      uint32_t a = first + (uint32_t)row * stride + (uint32_t)col;
      uint32_t b = a + 1, d = a + stride + 1, e = a + stride;
      gi_mesh_builder_add_triangle(c->b, a, b, d, mat(c, m));
      gi_mesh_builder_add_triangle(c->b, a, d, e, mat(c, m));
    }
}

static void building(city *c, rng *r, int64_t x0, int64_t z0, int64_t x1, int64_t z1, int storeys, int wall) {
  int64_t h = (int64_t)storeys * STOREY_MM;
  facade(c, r, x1, z0, -1, 0, x1 - x0, storeys, wall); /* -z */
  facade(c, r, x0, z1, 1, 0, x1 - x0, storeys, wall);  /* +z */
  facade(c, r, x1, z1, 0, -1, z1 - z0, storeys, wall); /* +x */
  facade(c, r, x0, z0, 0, 1, z1 - z0, storeys, wall);  /* -x */
  uint32_t a = vtx(c, x0, h, z0), b = vtx(c, x0, h, z1), d = vtx(c, x1, h, z1), e = vtx(c, x1, h, z0);
  gi_mesh_builder_add_triangle(c->b, a, b, d, mat(c, M_ROOF));
  gi_mesh_builder_add_triangle(c->b, a, d, e, mat(c, M_ROOF));
}

/* Splits [lo, lo + len) into n parts separated by gap; part k is [*s, *e). */
static void part(int64_t lo, int64_t len, int64_t gap, int n, int k, int64_t *s, int64_t *e) {
  *s = lo + (len + gap) * k / n;
  *e = lo + (len + gap) * (k + 1) / n - gap;
}

static int parts(rng *r, int64_t len, int64_t gap) {
  int n = 1 + (int)rnd(r, 4);
  int64_t fit = (len + gap) / (MIN_BUILDING_MM + 1000 + gap);
  if (fit < 1) fit = 1;
  return n > fit ? (int)fit : n;
}

/* The buildings of the lot of cell (i, j), which is already clipped. */
static void lot(city *c, int64_t i, int64_t j, int64_t x0, int64_t z0, int64_t x1, int64_t z1) {
  x0 += SETBACK_MM; z0 += SETBACK_MM; x1 -= SETBACK_MM; z1 -= SETBACK_MM;
  if (x1 - x0 < MIN_LOT_MM || z1 - z0 < MIN_LOT_MM) return;
  rng r = rng_for(c->seed, 1, i, j);

  /* Height zone from the block centre's distance to the city centre (whole metres, integer). */
  int64_t cx = (x0 + x1) / 2000, cz = (z0 + z1) / 2000;
  int64_t d2 = cx * cx + cz * cz;
  int max_storeys = 6;                      /* outskirts: up to 21 m */
  if (d2 * 100 < c->r2 * 36) max_storeys = 11; /* within 0.6 R: 38.5 m */
  if (d2 * 100 < c->r2 * 9) max_storeys = 17;  /* within 0.3 R: 59.5 m */
  int tower_zone = d2 <= c->towers_r2;

  int64_t gap = 2000 + 1000 * (int64_t)rnd(&r, 3);
  int nx = parts(&r, x1 - x0, gap), nz = parts(&r, z1 - z0, gap);
  for (int kx = 0; kx < nx; kx++)
    for (int kz = 0; kz < nz; kz++) {
      int64_t bx0, bx1, bz0, bz1;
      part(x0, x1 - x0, gap, nx, kx, &bx0, &bx1);
      part(z0, z1 - z0, gap, nz, kz, &bz0, &bz1);
      /* Every draw happens whether or not it is used, so the stream stays in step. */
      uint32_t empty = rnd(&r, 100), tower = rnd(&r, 100), mroll = rnd(&r, 100);
      uint32_t hroll = rnd(&r, 1000);
      int64_t inset[4];
      for (int k = 0; k < 4; k++) inset[k] = 250 * (int64_t)rnd(&r, 7); /* 0 .. 1.5 m */
      if (empty < 6) continue; /* a small plaza */
      if (bx1 - bx0 - inset[0] - inset[1] >= MIN_BUILDING_MM) { bx0 += inset[0]; bx1 -= inset[1]; }
      if (bz1 - bz0 - inset[2] - inset[3] >= MIN_BUILDING_MM) { bz0 += inset[2]; bz1 -= inset[3]; }
      int storeys, wall;
      if (tower_zone && tower < 12) {
        storeys = 20 + (int)(hroll % 15); /* 70 .. 119 m */
        wall = mroll < 50 ? M_GLASS : mroll < 75 ? M_CONCRETE : M_PLASTER;
      } else {
        storeys = 2 + (int)(hroll % (uint32_t)(max_storeys - 1));
        wall = mroll < 30 ? M_BRICK : mroll < 50 ? M_SAND : mroll < 70 ? M_PLASTER : mroll < 90 ? M_CONCRETE
                                                                                                  : M_GLASS;
      }
      building(c, &r, bx0, bz0, bx1, bz1, storeys, wall);
    }
}

static void add_lamp_light(city *c, int64_t x, int64_t y, int64_t z) {
  if (c->num_lamps == c->cap_lamps) {
    size_t nc = c->cap_lamps ? 2 * c->cap_lamps : 256;
    void *q = gi__realloc(c->lamps, nc * sizeof *c->lamps);
    if (!q) { c->oom = 1; return; }
    c->lamps = q;
    c->cap_lamps = nc;
  }
  c->lamps[c->num_lamps][0] = x;
  c->lamps[c->num_lamps][1] = y;
  c->lamps[c->num_lamps][2] = z;
  c->num_lamps++;
}

/* Lamps along one street segment. along: the segment's coordinate range on
 * the running axis; across: the street's centre line; xrun: 1 when the
 * street runs along x. Poles stand on the sidewalk, alternating sides, and
 * the lamp head overhangs toward the street. */
static void lamps(city *c, int64_t lo, int64_t hi, int64_t across, int xrun, rng *r) {
  int64_t len = hi - lo;
  int64_t n = (len + LAMP_SPACING_MM / 2) / LAMP_SPACING_MM;
  int side0 = (int)rnd(r, 2);
  for (int64_t m = 0; m < n; m++) {
    int64_t s = ((m + side0) & 1) ? 1 : -1;
    int64_t a = lo + (2 * m + 1) * len / (2 * n);
    int64_t curb = across + s * (c->street / 2);
    int64_t pole = curb + s * POLE_CURB_MM;
    int64_t head = pole - s * (POLE_HALF_MM + LAMP_HALF_MM);
    int64_t lim = c->half - 300, hlim = c->half - LAMP_HALF_MM;
    if (a < -lim || a > lim || pole < -lim || pole > lim || head < -hlim || head > hlim) continue;
    /* Pole and head as (along, across) rectangles, mapped to (x, z). */
    int64_t pa0 = a - POLE_HALF_MM, pa1 = a + POLE_HALF_MM, pc0 = pole - POLE_HALF_MM, pc1 = pole + POLE_HALF_MM;
    int64_t ha0 = a - LAMP_HALF_MM, ha1 = a + LAMP_HALF_MM, hc0 = head - LAMP_HALF_MM, hc1 = head + LAMP_HALF_MM;
    if (xrun) {
      box(c, pa0, 0, pc0, pa1, POLE_TOP_MM, pc1, M_POLE);
      box(c, ha0, LAMP_BOTTOM_MM, hc0, ha1, POLE_TOP_MM, hc1, M_LAMP);
      add_lamp_light(c, a, LAMP_BOTTOM_MM - LIGHT_BELOW_MM, head);
    } else {
      box(c, pc0, 0, pa0, pc1, POLE_TOP_MM, pa1, M_POLE);
      box(c, hc0, LAMP_BOTTOM_MM, ha0, hc1, POLE_TOP_MM, ha1, M_LAMP);
      add_lamp_light(c, head, LAMP_BOTTOM_MM - LIGHT_BELOW_MM, a);
    }
  }
}

/* Nearest the centre first; ties broken by position, so the order is total
 * and qsort's instability cannot change the result. */
static int lamp_cmp(const void *pa, const void *pb) {
  const int64_t *a = pa, *b = pb;
  int64_t da = (a[0] / 1000) * (a[0] / 1000) + (a[2] / 1000) * (a[2] / 1000);
  int64_t db = (b[0] / 1000) * (b[0] / 1000) + (b[2] / 1000) * (b[2] / 1000);
  if (da != db) return da < db ? -1 : 1;
  if (a[0] != b[0]) return a[0] < b[0] ? -1 : 1;
  if (a[2] != b[2]) return a[2] < b[2] ? -1 : 1;
  return 0;
}

/* --- parameters ------------------------------------------------------------- */

typedef struct resolved {
  uint64_t seed;
  double extent, block, street;
  int detail;
} resolved;

static gi_result resolve(const gi_city_params *p, resolved *o, gi_error_info *err) {
  gi_city_params zero = {0};
  if (!p) p = &zero;
  o->seed = p->seed ? p->seed : 1;
  if (!isfinite(p->extent) || p->extent < 0)
    return gi__fail(err, GI_ERR_INVALID_ARG, "city: extent %g m must be finite and >= 0 (0 = 600 m)", p->extent);
  if (p->extent > CITY_MAX_EXTENT_M)
    return gi__fail(err, GI_ERR_INVALID_ARG, "city: extent %g m exceeds the limit of %g m", p->extent,
                    CITY_MAX_EXTENT_M);
  if (!isfinite(p->block) || p->block < 0)
    return gi__fail(err, GI_ERR_INVALID_ARG, "city: block %g m must be finite and >= 0 (0 = 60 m)", p->block);
  if (!isfinite(p->street) || p->street < 0)
    return gi__fail(err, GI_ERR_INVALID_ARG, "city: street %g m must be finite and >= 0 (0 = 14 m)", p->street);
  if (p->detail < 0 || p->detail > 8)
    return gi__fail(err, GI_ERR_INVALID_ARG, "city: detail %d is outside 1..8 (0 = 2)", p->detail);
  o->extent = p->extent == 0 ? 600.0 : p->extent;
  o->block = p->block == 0 ? 60.0 : p->block;
  o->street = p->street == 0 ? 14.0 : p->street;
  o->detail = p->detail == 0 ? 2 : p->detail;
  if (o->block <= o->street)
    return gi__fail(err, GI_ERR_INVALID_ARG, "city: block pitch %g m must exceed the street width %g m", o->block,
                    o->street);
  if (o->extent / o->block > CITY_MAX_CELLS_PER_SIDE)
    return gi__fail(err, GI_ERR_INVALID_ARG,
                    "city: block %g m is too small for extent %g m (at most %d blocks per side)", o->block,
                    o->extent, CITY_MAX_CELLS_PER_SIDE);
  return GI_OK;
}

/* Triangles per square metre at detail d, and the peak bytes per triangle
 * of generating, building and baking the scene at low quality: measured on
 * 1-2 km cities at details 1, 2, 4 and 8 (0.208, 0.353, 0.649 and 1.222
 * per m^2; 190-305 bytes each with ~30 MB fixed), rounded up. */
#define CITY_TRIS_PER_M2(d) (0.07 + 0.15 * (d))
#define CITY_BYTES_PER_TRI 240.0
#define CITY_FIXED_BYTES 64e6

/* The bytes the city would take against the machine's memory: a 20 km
 * city was killed by the kernel at 23.9 GB on a 24 GB machine, where an
 * error is due. */
static double estimate(const resolved *o, double *tris) {
  *tris = CITY_TRIS_PER_M2(o->detail) * o->extent * o->extent;
  return CITY_FIXED_BYTES + CITY_BYTES_PER_TRI * *tris;
}

double gi_city_bytes_estimate(const gi_city_params *p, double *triangles) {
  resolved o = {0};
  double tris = 0, need = resolve(p, &o, NULL) == GI_OK ? estimate(&o, &tris) : 0;
  if (triangles) *triangles = tris;
  return need;
}

static gi_result check_memory(const resolved *o, gi_error_info *err) {
  double tris, need = estimate(o, &tris);
  long pages = sysconf(_SC_PHYS_PAGES), page = sysconf(_SC_PAGESIZE);
  if (pages <= 0 || page <= 0) return GI_OK; /* unknown: nothing to compare with */
  double have = (double)pages * (double)page;
  if (need <= have) return GI_OK;
  return gi__fail(err, GI_ERR_NOMEM,
                  "city: extent %g m at detail %d makes about %.0f million triangles, about %.1f GiB to build, more "
                  "than this machine's %.1f GiB of memory: use a smaller extent or detail",
                  o->extent, o->detail, tris / 1e6, need / 1073741824.0, have / 1073741824.0);
}

/* --- public ------------------------------------------------------------------ */

gi_result gi_city_generate(const gi_city_params *p, gi_mesh_builder *b, gi_light *lights, size_t max_lights,
                           size_t *num_lights, gi_error_info *err) {
  resolved rp = {0};
  gi_result rc;
  if (num_lights) *num_lights = 0;
  if (!b) return gi__fail(err, GI_ERR_INVALID_ARG, "city: builder is NULL");
  if (max_lights && !lights) return gi__fail(err, GI_ERR_INVALID_ARG, "city: max_lights is %zu but lights is NULL",
                                             max_lights);
  if ((rc = resolve(p, &rp, err)) != GI_OK || (rc = check_memory(&rp, err)) != GI_OK) return rc;

  city c = {0};
  c.b = b;
  c.seed = rp.seed;
  c.detail = rp.detail;
  c.half = llround(rp.extent * 1000.0) / 2;
  c.pitch = llround(rp.block * 1000.0);
  c.street = llround(rp.street * 1000.0);
  if (c.street < 2) c.street = 2; /* keep street/2 > 0 so tiles never overlap */
  if (c.pitch <= c.street) c.pitch = c.street + 1;
  int64_t half_m = c.half / 1000 > 0 ? c.half / 1000 : 1;
  c.r2 = half_m * half_m;
  int64_t tr = half_m * 15 / 100 > 150 ? half_m * 15 / 100 : 150; /* towers near the centre */
  c.towers_r2 = tr * tr;

  for (int m = 0; m < M_COUNT; m++) {
    gi_material gm = {0};
    memcpy(gm.albedo, palette[m].albedo, sizeof gm.albedo);
    memcpy(gm.emission, palette[m].emission, sizeof gm.emission);
    gm.roughness = palette[m].roughness;
    gm.specular = palette[m].specular;
    strncpy(gm.name, palette[m].name, sizeof gm.name - 1);
    uint32_t id = gi_mesh_builder_add_material(b, &gm);
    if (m == 0) c.mat0 = id;
  }

  /* Cells k cover [k P, (k+1) P]; lines k are street centres at k P. */
  int64_t P = c.pitch, hw = c.street / 2;
  int64_t K = (c.half + P - 1) / P;
  for (int64_t i = -K; i <= K; i++)
    for (int64_t j = -K; j <= K; j++) {
      int64_t x = i * P, z = j * P;
      ground(&c, x - hw, z - hw, x + hw, z + hw, M_ASPHALT); /* intersection */
      if (i == K || j == K) {
        /* The last line only closes the grid: its segments along the other axis. */
        if (i < K) ground(&c, x + hw, z - hw, x + P - hw, z + hw, M_ASPHALT);
        if (j < K) ground(&c, x - hw, z + hw, x + hw, z + P - hw, M_ASPHALT);
        continue;
      }
      ground(&c, x + hw, z - hw, x + P - hw, z + hw, M_ASPHALT); /* along x on line j */
      ground(&c, x - hw, z + hw, x + hw, z + P - hw, M_ASPHALT); /* along z on line i */
      ground(&c, x + hw, z + hw, x + P - hw, z + P - hw, M_LOT);
      int64_t lx0 = x + hw, lz0 = z + hw, lx1 = x + P - hw, lz1 = z + P - hw;
      if (lx0 < -c.half) lx0 = -c.half;
      if (lz0 < -c.half) lz0 = -c.half;
      if (lx1 > c.half) lx1 = c.half;
      if (lz1 > c.half) lz1 = c.half;
      lot(&c, i, j, lx0, lz0, lx1, lz1);
    }
  /* Lamps on every street segment, each with its own stream. */
  for (int64_t i = -K; i < K; i++)
    for (int64_t j = -K; j <= K; j++) {
      rng rx = rng_for(c.seed, 2, i, j), rz = rng_for(c.seed, 3, j, i);
      lamps(&c, i * P + hw, (i + 1) * P - hw, j * P, 1, &rx); /* along x, on line z = j P */
      lamps(&c, i * P + hw, (i + 1) * P - hw, j * P, 0, &rz); /* along z, on line x = j P */
    }
  if (c.oom) {
    gi__free(c.lamps);
    return gi__fail(err, GI_ERR_NOMEM, "city: out of memory for %zu street lamps", c.num_lamps);
  }

  size_t nl = 0;
  if (nl < max_lights) {
    double len = sqrt(SUN_DIR[0] * SUN_DIR[0] + SUN_DIR[1] * SUN_DIR[1] + SUN_DIR[2] * SUN_DIR[2]);
    gi_light *l = &lights[nl++];
    memset(l, 0, sizeof *l);
    l->type = GI_LIGHT_SUN;
    memcpy(l->color, SUN_IRRADIANCE, sizeof l->color);
    for (int k = 0; k < 3; k++) l->direction[k] = (float)(SUN_DIR[k] / len);
  }
  if (nl < max_lights) {
    gi_light *l = &lights[nl++];
    memset(l, 0, sizeof *l);
    l->type = GI_LIGHT_SKY;
    memcpy(l->color, SKY_RADIANCE, sizeof l->color);
  }
  if (nl < max_lights && c.num_lamps) {
    qsort(c.lamps, c.num_lamps, sizeof *c.lamps, lamp_cmp);
    for (size_t k = 0; k < c.num_lamps && nl < max_lights; k++) {
      gi_light *l = &lights[nl++];
      memset(l, 0, sizeof *l);
      l->type = GI_LIGHT_POINT;
      memcpy(l->color, LAMP_INTENSITY, sizeof l->color);
      for (int a = 0; a < 3; a++) l->position[a] = m_of(c.lamps[k][a]);
    }
  }
  gi__free(c.lamps);
  if (num_lights) *num_lights = nl;
  return GI_OK;
}

gi_result gi_city_build(const gi_city_params *p, const gi_scene_options *opt, gi_scene **out,
                        gi_error_info *err) {
  gi_scene_options o = {0};
  gi_mesh_builder *b = NULL;
  gi_light *lights = NULL;
  gi_result rc;
  size_t n = 0;

  if (!out) return gi__fail(err, GI_ERR_INVALID_ARG, "gi_city_build: out is NULL");
  *out = NULL;
  if (opt) o = *opt;
  if (o.num_lights && !o.lights)
    return gi__fail(err, GI_ERR_INVALID_ARG, "options: num_lights is %zu but lights is NULL", o.num_lights);
  size_t cap = 2 + CITY_BUILD_POINT_LIGHTS;
  b = gi_mesh_builder_new();
  lights = gi__calloc(cap + o.num_lights, sizeof *lights);
  if (!b || !lights) { rc = gi__fail(err, GI_ERR_NOMEM, "city: out of memory"); goto done; }
  if ((rc = gi_city_generate(p, b, lights, cap, &n, err)) != GI_OK) goto done;
  /* The caller's lights come after the city's, so the sun and sky stay first. */
  if (o.num_lights) memcpy(lights + n, o.lights, o.num_lights * sizeof *lights);
  o.lights = lights;
  o.num_lights = n + o.num_lights;
  o.up = GI_UP_Y; /* the city is generated Y-up whatever the caller's files use */
  rc = gi_scene_build(b, "city", &o, out, err);
done:
  gi__free(lights);
  gi_mesh_builder_free(b);
  return rc;
}

void gi_city_default_viewpoint(const gi_city_params *p, double at[3]) {
  /* The central intersection (street lines pass through the origin), a little
   * off its exact centre so the eye does not sit on voxel borders. */
  double street = (p && isfinite(p->street) && p->street > 0) ? p->street : 14.0;
  double extent = (p && isfinite(p->extent) && p->extent > 0) ? p->extent : 600.0;
  double dx = 0.15 * street, dz = 0.1 * street;
  if (dx > 0.25 * extent) dx = 0.25 * extent; /* a town smaller than its street */
  if (dz > 0.2 * extent) dz = 0.2 * extent;
  at[0] = dx;
  at[1] = 1.7;
  at[2] = dz;
}
