/* path.c: street paths through the procedural city, and their checks.
 *
 * The city's street centre lines lie on multiples of the block pitch
 * (gi_city.h), so a path is a polyline through intersections: start at the
 * central one heading +x, turn left or right at the first intersection, and
 * at each later one go straight, left or right (seeded; never back, never
 * past the outermost line that still has blocks on both sides). The eye keeps a lateral offset from the centre line (the
 * right lane) so it does not run along voxel borders: the origin is a cell
 * border of every level. Points are sampled at the path's rate along the
 * polyline at constant speed. */
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include "toolargs.h"
#include "walk.h"
#include "scene/scene_internal.h"

#define DEFAULT_EXTENT 600.0
#define DEFAULT_BLOCK 60.0
#define DEFAULT_STREET 14.0
#define LANE_SHARE 0.15      /* lateral offset, share of the street width (as the default viewpoint) */
#define GROUND_TOL 0.5       /* a downward ray must meet the street below this height, m */
#define ROOF_MARGIN 10.0     /* the downward ray starts this far above the highest roof, m */
#define MAX_TURNS 100000

typedef struct city_dims {
  double extent, block, street;
  int kmax;                  /* intersections at k * block, |k| <= kmax */
} city_dims;

static city_dims dims_of(const gi_city_params *cp) {
  city_dims d;
  d.extent = cp->extent > 0 ? cp->extent : DEFAULT_EXTENT;
  d.block = cp->block > 0 ? cp->block : DEFAULT_BLOCK;
  d.street = cp->street > 0 ? cp->street : DEFAULT_STREET;
  d.kmax = (int)floor((0.5 * d.extent - 0.5 * d.block) / d.block);
  return d;
}

static uint64_t next_rand(uint64_t *s) {
  uint64_t z = (*s += 0x9e3779b97f4a7c15ull);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
  return z ^ (z >> 31);
}

/* Headings: 0 +x, 1 +z, 2 -x, 3 -z. */
static const int HX[4] = {1, 0, -1, 0}, HZ[4] = {0, 1, 0, -1};

/* The next heading at intersection (ix, iz): straight, left or right, seeded,
 * among those that stay within kmax; `must_turn` leaves straight out. */
static int turn(int ix, int iz, int h, int kmax, int must_turn, uint64_t *rng) {
  int opts[3] = {h, (h + 1) % 4, (h + 3) % 4}, ok[3], n = 0;
  for (int i = must_turn; i < 3; i++) {
    int nx = ix + HX[opts[i]], nz = iz + HZ[opts[i]];
    if (abs(nx) <= kmax && abs(nz) <= kmax) ok[n++] = opts[i];
  }
  return n ? ok[next_rand(rng) % (uint64_t)n] : (h + 2) % 4;
}

/* The offset vertex at an intersection entered along a and left along b. */
static void corner(const city_dims *d, int ix, int iz, int a, int b, double out[2]) {
  double off = LANE_SHARE * d->street;
  /* Right of heading (hx, hz) seen from above (y up): (-hz, hx). */
  double rx = -HZ[a], rz = HX[a];
  if (a != b) rx += -HZ[b], rz += HX[b];
  out[0] = ix * d->block + off * rx;
  out[1] = iz * d->block + off * rz;
}

/* Builds the corner polyline until it is at least `length` long. */
static int polyline(const city_dims *d, double length, uint64_t seed, double (**pts)[2], size_t *np) {
  size_t cap = 64, n = 0;
  double(*v)[2] = malloc(cap * sizeof *v);
  if (!v) return -1;
  uint64_t rng = seed;
  int ix = 0, iz = 0, h = 0, prev = 0;
  double total = 0;
  for (int k = 0; k < MAX_TURNS; k++) {
    /* The first intersection reached is always a corner: a minute's walk
     * (84 m) reaches only one, and it should turn there. */
    int nh = k ? turn(ix, iz, h, d->kmax, k == 1, &rng) : 0;
    if (n == cap) {
      double(*w)[2] = realloc(v, 2 * cap * sizeof *v);
      if (!w) return free(v), -1;
      v = w, cap *= 2;
    }
    corner(d, ix, iz, k ? prev : nh, nh, v[n]);
    if (n) total += hypot(v[n][0] - v[n - 1][0], v[n][1] - v[n - 1][1]);
    n++;
    if (total >= length && n >= 2) break;
    prev = h = nh;
    ix += HX[h], iz += HZ[h];
  }
  *pts = v, *np = n;
  return total >= length ? 0 : -1;
}

int walk_path_make(const gi_city_params *cp, const char *name, double speed, double eye, double rate,
                   double seconds, uint64_t seed, walk_path *out) {
  memset(out, 0, sizeof *out);
  city_dims d = dims_of(cp);
  if (d.kmax < 1 || !(speed > 0) || !(rate > 0) || !(seconds > 0)) {
    fprintf(stderr, "gi-walk: no street path: city %.0f m with blocks of %.0f m, speed %g, rate %g, %g s\n",
            d.extent, d.block, speed, rate, seconds);
    return -1;
  }
  double(*v)[2];
  size_t nv, n = (size_t)llround(seconds * rate) + 1;
  if (polyline(&d, speed * seconds + 1.0, seed, &v, &nv) != 0) return -1;
  out->name = name, out->speed = speed, out->eye = eye, out->rate = rate, out->n = n;
  out->t = malloc(n * sizeof *out->t);
  out->at = malloc(n * sizeof *out->at);
  if (!out->t || !out->at) return free(v), walk_path_free(out), -1;
  size_t seg = 0;
  double seg_start = 0;
  for (size_t i = 0; i < n; i++) {
    double t = (double)i / rate, s = speed * t, len;
    while ((len = hypot(v[seg + 1][0] - v[seg][0], v[seg + 1][1] - v[seg][1])), seg_start + len < s && seg + 2 < nv)
      seg_start += len, seg++;
    double u = len > 0 ? (s - seg_start) / len : 0;
    out->t[i] = t;
    out->at[i][0] = v[seg][0] + u * (v[seg + 1][0] - v[seg][0]);
    out->at[i][1] = eye;
    out->at[i][2] = v[seg][1] + u * (v[seg + 1][1] - v[seg][1]);
  }
  free(v);
  return 0;
}

/* 1 when (x, z) lies within a street band (centre line +- half the width). */
static int on_street(const city_dims *d, double x, double z) {
  double ex = fabs(x - d->block * round(x / d->block)), ez = fabs(z - d->block * round(z / d->block));
  return fabs(x) <= 0.5 * d->extent && fabs(z) <= 0.5 * d->extent && (ex <= 0.5 * d->street || ez <= 0.5 * d->street);
}

/* Height of the first surface below (x, z), world; -INFINITY when none. */
static double ground_below(const gi_scene *s, double x, double z) {
  double o[3], lo[3], hi[3];
  gi_scene_origin(s, o);
  gi_scene_bounds(s, lo, hi);
  float org[3] = {(float)(x - o[0]), (float)(hi[1] + ROOF_MARGIN - o[1]), (float)(z - o[2])};
  float dir[3] = {0, -1, 0}, t, ng[3];
  uint32_t tri;
  if (!gi__intersect1(s, org, dir, 0.f, 1e9f, &t, &tri, ng)) return -INFINITY;
  return (double)org[1] - (double)t + o[1];
}

int walk_path_check(const gi_scene *s, const gi_city_params *cp, const walk_path *p) {
  city_dims d = dims_of(cp);
  double o[3];
  gi_scene_origin(s, o);
  for (size_t i = 0; i < p->n; i++) {
    const double *a = p->at[i];
    double g = ground_below(s, a[0], a[2]);
    const char *why = !on_street(&d, a[0], a[2]) ? "off the street bands"
                      : !(g < GROUND_TOL)        ? "inside a building footprint (a roof or wall above the street)"
                      : !(a[1] > g)              ? "below the ground" : NULL;
    if (!why && i + 1 < p->n) {
      const double *b = p->at[i + 1];
      float org[3] = {(float)(a[0] - o[0]), (float)(a[1] - o[1]), (float)(a[2] - o[2])};
      float dir[3] = {(float)(b[0] - a[0]), (float)(b[1] - a[1]), (float)(b[2] - a[2])}, tn = 0, tf = 1;
      uint8_t vis = 0;
      gi__occluded(s, 1, org, dir, &tn, &tf, &vis);
      if (!vis) why = "its segment to the next point passes through geometry";
    }
    if (why) {
      fprintf(stderr, "gi-walk: %s path point %zu (t %.2f s, %.3f %.3f %.3f) is %s (ground %.3f)\n", p->name, i,
              p->t[i], a[0], a[1], a[2], why, g);
      return -1;
    }
  }
  return 0;
}

int walk_path_write_csv(const walk_path *p, const char *file) {
  FILE *f = fopen(file, "w");
  if (!f) return walk_file_error(file), -1;
  for (size_t i = 0; i < p->n; i++)
    fprintf(f, "%.3f,%.4f,%.4f,%.4f\n", p->t[i], p->at[i][0], p->at[i][1], p->at[i][2]);
  if (fclose(f) != 0) return walk_file_error(file), -1;
  return 0;
}

void walk_path_free(walk_path *p) {
  free(p->inside);
  free(p->t);
  free(p->at);
  p->t = NULL, p->at = NULL, p->inside = NULL, p->n = p->num_inside = 0;
}

int walk_path_from_steps(const char *file, const ta_step *st, size_t n, walk_path *out) {
  memset(out, 0, sizeof *out);
  const char *base = strrchr(file, '/');
  base = base ? base + 1 : file;
  size_t k = 0;
  for (; base[k] && base[k] != '.' && k + 1 < sizeof out->name_buf; k++) {
    char c = base[k];
    int ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' || c == '-';
    out->name_buf[k] = ok ? c : '_';
  }
  if (!k) out->name_buf[k++] = '_';
  out->name_buf[k] = 0;
  out->name = out->name_buf;
  out->t = malloc(n * sizeof *out->t);
  out->at = malloc(n * sizeof *out->at);
  if (!out->t || !out->at) return walk_path_free(out), -1;
  double len = 0;
  for (size_t i = 0; i < n; i++) {
    out->t[i] = st[i].t;
    memcpy(out->at[i], st[i].at, sizeof out->at[i]);
    if (i) len += sqrt(pow(st[i].at[0] - st[i - 1].at[0], 2) + pow(st[i].at[1] - st[i - 1].at[1], 2) +
                       pow(st[i].at[2] - st[i - 1].at[2], 2));
  }
  out->n = n;
  double dur = n > 1 ? st[n - 1].t - st[0].t : 0;
  out->speed = dur > 0 ? len / dur : NAN;
  out->rate = dur > 0 ? (double)(n - 1) / dur : NAN;
  out->eye = NAN;
  return 0;
}

void walk_note_up(const char *file, gi_up_axis up, const gi_scene *s) {
  if (!file || up || !s || !gi_scene_looks_z_up(s)) return;
  fprintf(stderr, "gi-walk: note: %s is flat along z " TA_NOTE_Z_UP_FIX "\n", file);
}
