/* plan.c: quality resolution and the effect plan.
 *
 * gi_quality_resolve turns a request's quality into explicit knobs
 * (defaults, validation). The effect plan then decides which effects the
 * scene and request call for around a placed cascade, and says why, so a
 * bake pays only for what the scene holds. */
#include <float.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "base/internal.h"
#include "cascade/cascade_internal.h"
#include "light/light.h"
#include "plan.h"
#include "scene/lights.h"
#include "trace/trace.h"

/* The automatic bounce count's cap. Four, not three: the Cornell box
 * (mean albedo 0.76) left three orders and more to the geometric tail,
 * which over-added (indirect ratio 1.07 against 0.95 without it); a
 * fourth bounce took its indirect error from 8.8% to 6.9% and Munich's
 * from 9.6% to 9.5%, for about 10% more bake time (make accuracy). */
#define MAX_AUTO_BOUNCES 4
/* The automatic count stops when the first order left out, a^(B+2),
 * weighs less than this share of the direct light. */
#define ORDER_LEFT 0.02
/* At the cap, the fourth bounce gives way to the geometric tail when the
 * orders after the third, a^5 / (1 - a) of the direct light, are at most
 * this share. Measured against the fourth bounce (default quality, the
 * probe's indirect light at 200 points around the viewpoint): Munich
 * (a 0.57, 13.7%) -1.6% mean, 10.5% at most, for 14% less bounce time;
 * Florence (a 0.57, 14.5%) -0.9% / 7.8%; the Stanford bunny (a 0.60,
 * 19.4%) +0.1% / 0.6%. Against the path-traced reference the default
 * indirect error did not move (Munich 7.94 -> 7.95%, Florence 10.74 ->
 * 10.65%, bunny 103.2 -> 103.3%); high quality's rose 0.13 points on
 * Munich and Florence. The Cornell box (a 0.76, 80%) keeps four: at
 * three its tail over-added (above). */
#define TAIL_SHARE 0.20

static const char *const fx_names[GI_FX_COUNT] = {"sun", "local_lights", "sky", "emissive",
                                                  "bounce", "specular", "ao"};

const char *gi_effect_name(gi_effect_id id) {
  return (unsigned)id < GI_FX_COUNT ? fx_names[id] : "unknown";
}

int gi_effect_from_name(const char *name) {
  for (int i = 0; name && i < GI_FX_COUNT; i++)
    if (!strcmp(name, fx_names[i])) return i;
  return -1;
}

static void set_fx(gi_bake_report *r, gi_effect_id id, int ran, const char *fmt, ...)
    __attribute__((format(printf, 4, 5)));
static void set_fx(gi_bake_report *r, gi_effect_id id, int ran, const char *fmt, ...) {
  va_list ap;
  va_start(ap, fmt);
  r->effects[id].ran = ran;
  vsnprintf(r->effects[id].why, sizeof r->effects[id].why, fmt, ap);
  va_end(ap);
}

/* The default cascade's shape. DEFAULT_LEVELS levels; the coarsest spans
 * SPAN_MARGIN times the scene's reach: a centred viewpoint then keeps every
 * wall a few voxels inside the window, clear of the one-voxel border cones
 * need for filtering. */
enum { DEFAULT_LEVELS = 6 };
#define SPAN_MARGIN 1.25
/* The reach of a wide, flat scene (a city): at most REACH_HEIGHTS times its
 * height (but at least 1/REACH_WIDTH_DIV of its width). Light from farther
 * away barely reaches a street, and a cascade over all of a 5 km city would
 * voxelize every triangle of it for each viewpoint. */
#define REACH_HEIGHTS 16.0
#define REACH_WIDTH_DIV 8.0
/* A scene wider than its reach is a plain of neighbourhoods, and a
 * viewpoint in one needs the finest voxel a compact piece of it would get:
 * one LOCAL_HEIGHTS heights across (the 600 m city, compact, is 5 heights
 * across). Its coarsest level keeps the reach, so levels are added at the
 * fine end, each halving s0, until s0 is no coarser than the piece's. */
#define LOCAL_HEIGHTS 4.0
/* Below this share of its extent a scene's height is rounding: flat. */
#define FLAT_SHARE 1e-6

/* Default s0 (and, when auto_levels, the level count) for q->res. A scene
 * the default levels cover whole keeps DEFAULT_LEVELS and an s0 that grows
 * with its size. A wider one keeps that reach with more levels, up to
 * GI_MAX_LEVELS: beyond that s0 grows with the reach again, so memory
 * (levels x R^3 voxels) and bake time stay bounded. A flat scene (no
 * height) has no neighbourhood scale: it keeps the extent rule. */
static void default_voxel(const gi_scene *s, gi_quality *q, int auto_levels) {
  double lo[3], hi[3], ext = 0;
  gi_scene_bulk_bounds(s, lo, hi); /* stray far triangles (a leftover at 0,0,0) set no scale */
  for (int a = 0; a < 3; a++) ext = fmax(ext, hi[a] - lo[a]);
  int up = gi_scene_up(s) == GI_UP_Z ? 2 : 1;
  double height = hi[up] - lo[up];
  /* A height under FLAT_SHARE of the extent is float rounding (Blender's
   * 20 m plane, turned, is 8.7e-7 m high), not a neighbourhood: flat. It
   * added levels to the cap and a finest voxel of 4.8e-5 m. */
  if (height < FLAT_SHARE * ext) height = 0;
  /* Flat: the whole extent (ext / 8 made a 10 m floor's coarsest level
   * 1.6 m across, and its lightmap 676 tiles or none). */
  double reach = height > 0 ? fmin(ext, fmax(REACH_HEIGHTS * height, ext / REACH_WIDTH_DIV)) : ext;
  if (!(reach > 0)) reach = 1.0;
  if (auto_levels && height > 0 && ext > reach) {
    double piece = LOCAL_HEIGHTS * height;
    while (q->levels < GI_MAX_LEVELS && reach > piece * (double)(1ull << (q->levels - DEFAULT_LEVELS))) q->levels++;
  }
  q->voxel0 = SPAN_MARGIN * reach / ((double)q->res * (double)(1ull << (q->levels - 1)));
}

gi_result gi_quality_resolve(const gi_scene *s, const gi_quality *in, gi_quality *q,
                             gi_error_info *err) {
  if (!s || !q) return gi__fail(err, GI_ERR_INVALID_ARG, "quality: %s is NULL", !s ? "scene" : "out");
  gi_quality z = {0};
  *q = in ? *in : z;
  int auto_levels = q->levels == 0 && q->voxel0 == 0;
  if (q->levels == 0) q->levels = DEFAULT_LEVELS;
  if (q->res == 0) q->res = 32;
  if (q->cones == 0) q->cones = 16;
  if (q->step == 0) q->step = 1.0f;
  /* With an explicit count of 2 or more, a caller may ask for the tail
   * too (a tiled bake giving every tile the plan of its brightest); with
   * an automatic count the plan sets it. */
  q->bounce_tail = q->bounces >= 2 && q->bounce_tail ? 1 : 0;
  if (q->bounces < 0 && q->effects[GI_FX_BOUNCE] == GI_FX_ON)
    return gi__fail(err, GI_ERR_INVALID_ARG, "quality: bounces is none (-1) while effects[bounce] is forced on: "
                    "ask for one or the other");
  if (q->bounces == 0) q->bounces = 2; /* auto: the effect plan replaces it */
  else if (q->bounces < 0) q->bounces = 0;
  for (int i = 0; i < GI_FX_COUNT; i++)
    if (q->effects[i] < -1 || q->effects[i] > 1)
      return gi__fail(err, GI_ERR_INVALID_ARG, "quality: effects[%s] must be -1 (off), 0 (auto) or 1 (on), got %d",
                      fx_names[i], q->effects[i]);
  if (q->specular < -1 || q->specular > 1)
    return gi__fail(err, GI_ERR_INVALID_ARG, "quality: specular must be -1, 0 or 1, got %d", q->specular);
  /* Any other value read as "on": ao = -1, off in specular's convention, ran AO. */
  if (q->ao != 0 && q->ao != 1)
    return gi__fail(err, GI_ERR_INVALID_ARG, "quality: ao must be 0 or 1, got %d", q->ao);
  if (q->light_samples == 0) q->light_samples = 16;
  if (q->probe_samples == 0) q->probe_samples = 256;
  if (q->seed == 0) q->seed = 1;
  if (q->levels < 1 || q->levels > GI_MAX_LEVELS)
    return gi__fail(err, GI_ERR_INVALID_ARG, "quality: levels must be 1..%d, got %d", GI_MAX_LEVELS, q->levels);
  if (q->res < 8 || q->res > GI_MAX_RES || q->res % 4)
    return gi__fail(err, GI_ERR_INVALID_ARG, "quality: res must be a multiple of 4 in 8..%d, got %d", GI_MAX_RES,
                    q->res);
  if (q->cones != 4 && q->cones != 6 && q->cones != 8 && q->cones != 16 && q->cones != 32)
    return gi__fail(err, GI_ERR_INVALID_ARG, "quality: cones must be 4, 6, 8, 16 or 32, got %d", q->cones);
  if (!isfinite(q->voxel0) || q->voxel0 < 0)
    return gi__fail(err, GI_ERR_INVALID_ARG, "quality: voxel size must be a positive finite number");
  /* Larger, the cascade's extent leaves float range (1e38 failed in a triangle query). */
  if (q->voxel0 > GI_MAX_VOXEL)
    return gi__fail(err, GI_ERR_INVALID_ARG, "quality: voxel size must be at most %g units, got %g", GI_MAX_VOXEL,
                    q->voxel0);
  if (!isfinite(q->aperture_deg) || q->aperture_deg < 0 || q->aperture_deg >= 180)
    return gi__fail(err, GI_ERR_INVALID_ARG, "quality: aperture must be in (0, 180) degrees");
  if (!isfinite(q->step) || q->step < 0.05f || q->step > 4)
    return gi__fail(err, GI_ERR_INVALID_ARG, "quality: step must be in 0.05..4, got %g", q->step);
  if (q->bounces > 8)
    return gi__fail(err, GI_ERR_INVALID_ARG, "quality: bounces must be at most 8, got %d", q->bounces);
  if (q->light_samples < 1 || q->light_samples > 512 || q->probe_samples < 1 || q->probe_samples > 8192)
    return gi__fail(err, GI_ERR_INVALID_ARG, "quality: light samples must be 1..512 and probe samples 1..8192");
  if (q->voxel0 == 0) {
    default_voxel(s, q, auto_levels);
    /* The default follows the scene's size; out of the range a caller may
     * give, the bake went wrong quietly (a box 1e10 across: half its
     * indirect light; 1e12: a NaN probe; 1e-10: every level empty). */
    if (q->voxel0 > GI_MAX_VOXEL)
      return gi__fail(err, GI_ERR_INVALID_ARG, "quality: the scene is too large for a default voxel size (%g units, "
                      "over %g); give one, or rescale the scene", q->voxel0, GI_MAX_VOXEL);
    if (q->voxel0 < GI_MIN_VOXEL)
      return gi__fail(err, GI_ERR_INVALID_ARG, "quality: the scene is too small for a default voxel size (%g units, "
                      "under %g, where the voxelizer's float areas underflow); rescale the scene", q->voxel0,
                      GI_MIN_VOXEL);
  }
  if (!isfinite(q->ao_lambda) || q->ao_lambda < 0)
    return gi__fail(err, GI_ERR_INVALID_ARG, "quality: ao_lambda must be finite and >= 0");
  /* A given voxel is judged against the viewpoint's distance (the anchor);
   * at the origin 1e-40 passed, and 1 / 4 s0 overflowed float into Inf. */
  if (q->ao_lambda == 0) q->ao_lambda = (float)fmin(1.0 / (4.0 * q->voxel0), FLT_MAX);
  return GI_OK;
}

int gi__fx_forced(const gi_quality *q, gi_effect_id id) {
  int f = q->effects[id];
  if (f == GI_FX_AUTO && id == GI_FX_SPECULAR) f = q->specular;
  if (f == GI_FX_AUTO && id == GI_FX_AO && q->ao) f = GI_FX_ON;
  return f;
}

/* Sky visibility: 32 stratified upward rays from the centre of the
 * viewpoint's anchor cell (the 2 s0 cell that places level 0, see
 * gi_cascade_anchor) and from the points half the finest level's side away
 * from it along each axis (its faces' centres, give or take s0). One
 * escaping ray is enough; a closed room (or the Cornell box's ceiling side)
 * stops them all. The origins come from the snapped placement, not the raw
 * viewpoint, so viewpoints with equal anchors get the same plan. The cell
 * centre sits on an odd multiple of s0, off the even grid lines where
 * axis-aligned walls of round coordinates tend to lie. Where the caller
 * names the points its answers are gathered at (a lightmap tile's
 * texels; probes, with no normal: from the point itself), HINT_PER rays
 * from half a voxel off each side of each of them too: a tile's centre
 * inside a box on a sky-lit floor saw no sky, and every texel around it
 * lost the sky's bounce light. */
#define MAX_HINTS 32
#define HINT_PER 8

/* The anchor cell's centre, which the plan's rays leave from: level 0
 * starts R/2 cells below the anchor cell's first cell (cascade.c). */
static void anchor_centre(const struct gi_cascade *c, float centre[3]) {
  const gi_level *L0 = &c->lv[0];
  for (int a = 0; a < 3; a++) centre[a] = (float)(((double)L0->cell0[a] + c->R / 2 + 1) * L0->s);
}

/* The plan's seven points: the anchor cell's centre (o = 0), and half
 * level 0's box off it along x, y and z, + then - (o = 1..6). The sky
 * test looks up from all of them, the wide-level rule judges from them
 * when the centre is inside a solid. */
#define PLAN_POINTS 7
static void plan_point(const struct gi_cascade *c, int o, float p[3]) {
  float half = (float)(0.5 * c->R * c->lv[0].s);
  anchor_centre(c, p);
  if (o) p[(o - 1) / 2] += (o & 1) ? half : -half;
}

/* Direction i of n on a Fibonacci sphere: even directions, no random numbers. */
static void sphere_dir(int i, int n, float w[3]) {
  float z = 1 - (2 * (float)i + 1) / (float)n, r = sqrtf(fmaxf(0.f, 1 - z * z)), phi = (float)i * 2.39996323f;
  w[0] = r * cosf(phi), w[1] = r * sinf(phi), w[2] = z;
}

/* The upward rays' frame, and the arrays sky_rays fills. */
typedef struct {
  float up[3], t[3], b[3];
  float *org, *dir, *tn, *tf;
  int n;
} sky_batch;

/* per stratified upward rays from p (cos theta in per strata), seeded. */
static void upward_rays(sky_batch *sb, const float p[3], int per, uint64_t seed) {
  uint64_t rng = gi__mix64(seed);
  for (int j = 0; j < per; j++, sb->n++) {
    float ct = ((float)j + gi__u01(&rng)) / (float)per, st = sqrtf(fmaxf(0.f, 1 - ct * ct));
    float phi = 2 * GI_PI_F * gi__u01(&rng);
    for (int k = 0; k < 3; k++) {
      sb->org[3 * sb->n + k] = p[k];
      sb->dir[3 * sb->n + k] = st * cosf(phi) * sb->t[k] + st * sinf(phi) * sb->b[k] + ct * sb->up[k];
    }
    sb->tn[sb->n] = 0;
    sb->tf[sb->n] = INFINITY;
  }
}

/* The sky on what the viewpoint sees: SEEN_DIRS rays from the anchor
 * cell's centre over the sphere find the surfaces round it, and SEEN_UP
 * upward rays from half a finest voxel off each (on the viewpoint's side)
 * look for the sky. A room lit through a 3 m skylight in its 10 m
 * ceiling: the floor under the opening sees the sky, which 224 rays from
 * round the viewpoint missed (1 in 224 at a neighbouring viewpoint), and
 * the room lost the sky's bounce light (0.56x the path tracer's indirect
 * light). A closed room's surfaces see only its ceiling. Adds what it
 * traced to *tested; returns the rays that escaped. */
#define SEEN_DIRS 128
#define SEEN_UP 8
static int sky_beyond(const struct gi_cascade *c, sky_batch *sb, const float centre[3], int *tested) {
  const gi_scene *s = c->scene;
  float off = 0.5f * (float)c->lv[0].s;
  sb->n = 0;
  for (int i = 0; i < SEEN_DIRS; i++) {
    float w[3], t, ng[3], p[3];
    uint32_t tri;
    sphere_dir(i, SEEN_DIRS, w);
    if (!gi__intersect1(s, centre, w, 0, INFINITY, &t, &tri, ng)) continue; /* escapes: the sky test's own rays judge that */
    float side = gi__dot(ng, w) > 0 ? -1.f : 1.f; /* toward the viewpoint */
    for (int k = 0; k < 3; k++) p[k] = centre[k] + t * w[k] + side * off * ng[k];
    upward_rays(sb, p, SEEN_UP, 0x5c3ull + (uint64_t)i);
  }
  uint8_t vis[SEEN_DIRS * SEEN_UP];
  gi__occluded(s, sb->n, sb->org, sb->dir, sb->tn, sb->tf, vis);
  int seen = 0;
  for (int i = 0; i < sb->n; i++) seen += vis[i];
  *tested += sb->n;
  return seen;
}

static int sky_rays(const struct gi_cascade *c, int *tested) {
  const gi_scene *s = c->scene;
  enum { ORG = PLAN_POINTS, PER = 32, NEAR = ORG * PER + 2 * MAX_HINTS * HINT_PER, BEYOND = SEEN_DIRS * SEEN_UP };
  enum { MAXR = NEAR > BEYOND ? NEAR : BEYOND }; /* sky_beyond reuses the arrays */
  float org[3 * MAXR], dir[3 * MAXR], tn[MAXR], tf[MAXR];
  uint8_t vis[MAXR];
  sky_batch sb = {.up = {0, s->up == GI_UP_Z ? 0.f : 1.f, s->up == GI_UP_Z ? 1.f : 0.f},
                  .org = org, .dir = dir, .tn = tn, .tf = tf};
  gi__basis(sb.up, sb.t, sb.b);
  const gi_level *L0 = &c->lv[0];
  float centre[3];
  anchor_centre(c, centre);
  for (int o = 0; o < ORG; o++) {
    float p[3];
    plan_point(c, o, p);
    upward_rays(&sb, p, PER, 0x5c1ull + (uint64_t)o);
  }
  int nh = c->num_answer_pts < MAX_HINTS ? c->num_answer_pts : MAX_HINTS;
  for (int h = 0; h < 2 * nh; h++) {
    /* Evenly over the caller's points, each side in turn. */
    const float *P = c->answer_pts + 6 * ((size_t)(h / 2) * (size_t)c->num_answer_pts / (size_t)nh);
    if ((h & 1) && P[3] == 0 && P[4] == 0 && P[5] == 0) continue; /* a point in space: one side */
    float off = (h & 1 ? -0.5f : 0.5f) * (float)L0->s, p[3];
    for (int k = 0; k < 3; k++) p[k] = P[k] + off * P[3 + k];
    upward_rays(&sb, p, HINT_PER, 0x5c2ull + (uint64_t)h);
  }
  int n = sb.n;
  gi__occluded(s, n, org, dir, tn, tf, vis);
  int seen = 0;
  for (int i = 0; i < n; i++) seen += vis[i];
  *tested = n;
  if (!seen) seen = sky_beyond(c, &sb, centre, tested);
  return seen;
}

/* The coarse levels the viewpoint barely sees gather with the bounces'
 * wide set from the first bounce (light/bounce.c), not from the third:
 * WIDE_DIRS rays over the sphere from the anchor cell's centre (as
 * sky_beyond's) find the first surface each way, and the levels from L
 * up take the wide set when the surfaces the rays meet there are at most
 * WIDE_SEEN of all the rays. Their light reaches the viewpoint through
 * that share of its view, read at their own coarse resolution or
 * coarser. Only where the view is open (WIDE_OPEN of the rays escape):
 * in a closed room the light its far walls gather comes back bounce
 * after bounce (a lamp room of albedo 0.8 whose far walls fill 20% of the
 * view from its coarsest level: walls' indirect 1.021x -> 1.031x the exact
 * energy with that level on the wide set), in the open it leaves. A room
 * whose walls fill the view from its coarsest level (the Cornell box: 42%)
 * keeps the full set either way. Measured with levels 2-5 on the wide set
 * (make accuracy's references, 2026-12-07): Munich's default indirect
 * error 6.94 -> 6.94%, its camera view 3.26 -> 3.26%, its aerial view
 * 8.44 -> 8.49%; the city's 10.45 -> 10.41%, its view 11.97 -> 11.96%;
 * Florence's 37.3 -> 38.3%; the Cornell box's 6.41 -> 8.90%. Level 0
 * always keeps the full set. Returns L (c->n: none).
 *
 * A centre inside a solid (WIDE_INSIDE of its rays' surfaces show their
 * backs: in a building, under the ground) sees the solid's inside, not
 * the view: issue 11's Munich viewpoint (0, 0, 2) lies in a building, and
 * none of its rays escaped. Then the sky test's six points half level
 * 0's box off it (sky_rays) judge, those outside solids, their rays
 * pooled: the region the answers come from, round the solid. A point
 * outside solids finds no back: the other scenes' centres and every
 * point above ground. When the solid holds all seven (a room wider than
 * level 0 wound outward, as gi_mesh_builder_add_box winds a box: one
 * solid to the rays), the level count as before. Munich's viewpoint now
 * takes levels 2-5: its bake 1.1-1.2x faster, and at street probes round
 * it (gi-accuracy --at 0,0,2 --above-ground 2, spacing 6, 12 and 20: 10,
 * 19 and 21 probes, references at 65,536 paths) the default indirect
 * error 10.40 -> 10.41%, 11.06 -> 11.05%, 13.11 -> 12.50%. */
#define WIDE_DIRS 256
#define WIDE_SEEN 0.2
#define WIDE_OPEN 0.1
#define WIDE_INSIDE 0.1
static int wide_level(const struct gi_cascade *c) {
  int per[GI_MAX_LEVELS] = {0}, open = 0, cast = 0;
  for (int o = 0; o < PLAN_POINTS; o++) {
    float q[3];
    plan_point(c, o, q);
    int pq[GI_MAX_LEVELS] = {0}, escaped = 0, back = 0;
    for (int i = 0; i < WIDE_DIRS; i++) {
      float w[3], t, p[3], ng[3];
      sphere_dir(i, WIDE_DIRS, w);
      if (!gi__intersect1(c->scene, q, w, 0, INFINITY, &t, NULL, ng)) {
        escaped++;
        continue;
      }
      back += gi__dot(ng, w) > 0;
      for (int k = 0; k < 3; k++) p[k] = q[k] + t * w[k];
      int d = gi__finest_level_at(c, p);
      if (d >= 0) pq[d]++;
    }
    if (back > WIDE_INSIDE * (WIDE_DIRS - escaped)) continue; /* inside a solid */
    open += escaped, cast += WIDE_DIRS;
    for (int d = 0; d < c->n; d++) per[d] += pq[d];
    if (o == 0) break; /* the centre sees the view: it judges alone */
  }
  if (!cast || open < WIDE_OPEN * cast) return c->n;
  int L = c->n, far = 0;
  while (L > 1 && far + per[L - 1] <= WIDE_SEEN * cast) far += per[--L];
  return L;
}

/* What the geometric tail after B bounces brings, as a share of the direct
 * light, at mean albedo a: a^(B+2) / (1 - a), the ratio capped as the bake
 * caps it (a material reflects at most 1, scene.c, so a may reach 1). */
static double tail_share(double a, int B) {
  double r = fmin(a, GI_TAIL_RATIO_MAX);
  return pow(a, B + 2) / (1 - r);
}

/* The area of triangle P (local coordinates) inside the box [lo, hi]:
 * the triangle clipped by the box's six planes (in double: a city's
 * ground triangle is kilometres across, a level's box metres). */
#define CLIP_MAXV 9
static double area_in_box(const float *P[3], const float lo[3], const float hi[3]) {
  double a[CLIP_MAXV][3], b[CLIP_MAXV][3];
  int n = 3, inside = 1;
  for (int v = 0; v < 3; v++)
    for (int k = 0; k < 3; k++) {
      a[v][k] = P[v][k];
      inside &= P[v][k] >= lo[k] && P[v][k] <= hi[k];
    }
  /* Most triangles of a level lie wholly inside its box: no clipping. */
  for (int pl = 0; pl < 6 && n > 0 && !inside; pl++) {
    int ax = pl >> 1;
    double sg = pl & 1 ? -1 : 1, lim = pl & 1 ? hi[ax] : lo[ax];
    int m = 0;
    for (int i = 0; i < n; i++) {
      const double *p = a[i], *q = a[(i + 1) % n];
      double dp = sg * (p[ax] - lim), dq = sg * (q[ax] - lim);
      if (dp >= 0) memcpy(b[m++], p, sizeof b[0]);
      if ((dp >= 0) != (dq >= 0) && m < CLIP_MAXV) {
        double t = dp / (dp - dq);
        for (int k = 0; k < 3; k++) b[m][k] = p[k] + t * (q[k] - p[k]);
        m++;
      }
    }
    n = m;
    memcpy(a, b, (size_t)n * sizeof a[0]);
  }
  double c[3] = {0, 0, 0};
  for (int i = 1; i + 1 < n; i++) {
    double e1[3], e2[3];
    for (int k = 0; k < 3; k++) e1[k] = a[i][k] - a[0][k], e2[k] = a[i + 1][k] - a[0][k];
    c[0] += e1[1] * e2[2] - e1[2] * e2[1];
    c[1] += e1[2] * e2[0] - e1[0] * e2[2];
    c[2] += e1[0] * e2[1] - e1[1] * e2[0];
  }
  return 0.5 * sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]);
}

/* The reflectance (brightest channel of the albedo, plus a glossy lobe's
 * specular) that sets the bounce count: each level's area-weighted mean
 * over the surfaces inside its box, and the brightest of those means.
 * Every level has as many voxels and the answers read all of them, so a
 * bright room round the viewpoint calls for its bounces whatever lies
 * around it: one mean over the coarsest box let a 60 m grey ground
 * outside a white room (0.33 against the room's 0.65) cut the room's
 * bounces to 2 and its indirect light to half the path tracer's, and a
 * black ground (0.05) to 1 bounce, though a black ground takes no more
 * light from the room than the open sky would. A level holding less
 * surface than a strip one voxel wide across it (a corner of a wall)
 * does not count, unless no level holds more. level_sums: level d's
 * clipped area and albedo-weighted area into c->survey.lvl[d]. */
/* 1 when level d's sums are of its current box. */
static int sums_current(const struct gi_cascade *c, int d) {
  const gi_level *L = &c->lv[d];
  return c->survey.lvl[d].valid && !memcmp(c->survey.lvl[d].lo, L->lo, sizeof L->lo) &&
         !memcmp(c->survey.lvl[d].hi, L->hi, sizeof L->hi);
}

static gi_result level_sums(struct gi_cascade *c, int d) {
  const gi_scene *s = c->scene;
  const gi_level *L = &c->lv[d];
  if (sums_current(c, d)) return GI_OK;
  size_t n = 0, cap = 0;
  uint32_t *tris = NULL;
  gi_result rc = gi__query_box(s, L->lo, L->hi, &tris, &n, &cap);
  if (rc != GI_OK) {
    gi__free(tris);
    return rc;
  }
  double area = 0, a_sum = 0;
  uint32_t glossy = 0;
  for (size_t i = 0; i < n; i++) {
    const uint32_t *ix = &s->indices[3 * tris[i]];
    const float *P[3] = {&s->vertices[3 * ix[0]], &s->vertices[3 * ix[1]], &s->vertices[3 * ix[2]]};
    const float *alb = gi__tri_albedo(s, tris[i]);
    double ar = area_in_box(P, L->lo, L->hi);
    /* A glossy lobe reflects `specular` more (the texture holds it as diffuse light, inject.c). */
    float gl = gi__gloss(&s->materials[s->tri_material[tris[i]]]);
    area += ar, a_sum += ar * (fmaxf(alb[0], fmaxf(alb[1], alb[2])) + gl);
    glossy += gl > 0;
  }
  gi__free(tris);
  c->survey.lvl[d].valid = 1;
  memcpy(c->survey.lvl[d].lo, L->lo, sizeof L->lo);
  memcpy(c->survey.lvl[d].hi, L->hi, sizeof L->hi);
  c->survey.lvl[d].area = area, c->survey.lvl[d].a_sum = a_sum, c->survey.lvl[d].glossy = glossy;
  return GI_OK;
}

/* level_sums of the levels whose box changed, in one parallel loop,
 * coarsest first: the coarsest holds the most triangles (the city's: all
 * 142k), so it starts at once. Each level's sums are its own (its
 * triangles in its query's order): side by side they give the same bits.
 * One after another they were 11-12.5 ms of the city's plan on 2 threads
 * (8.3-8.8 ms now). A move's re-plan mostly re-surveys the finest level
 * alone, which then runs on the caller without waking a helper. */
typedef struct {
  struct gi_cascade *c;
  int stale[GI_MAX_LEVELS]; /* the levels to survey, coarsest first */
  gi_result rc[GI_MAX_LEVELS];
} sums_ctx;

static void sums_range(void *p, size_t b, size_t e, int worker) {
  (void)worker;
  sums_ctx *x = p;
  for (size_t i = b; i < e; i++) x->rc[x->stale[i]] = level_sums(x->c, x->stale[i]);
}

/* The brightest level's mean (above); *surfaces 0 when no level holds any.
 * Each level's sums depend on its box alone and are kept while it stays
 * (a move that scrolls only the finest level queries that level again),
 * so a moved cascade plans as a cold bake at its anchor does. */
static gi_result level_albedo(struct gi_cascade *c, int threads, double *abar, int *surfaces) {
  double best = 0, any = 0;
  *surfaces = 0;
  sums_ctx x = {.c = c};
  size_t n = 0;
  for (int d = c->n - 1; d >= 0; d--) {
    x.rc[d] = GI_OK;
    if (!sums_current(c, d)) x.stale[n++] = d;
  }
  gi__parallel_for(n, 1, threads, sums_range, &x);
  for (int d = 0; d < c->n; d++) {
    gi_result rc = x.rc[d];
    if (rc != GI_OK) return rc;
    double area = c->survey.lvl[d].area;
    if (!(area > 0)) continue;
    *surfaces = 1;
    double mean = c->survey.lvl[d].a_sum / area;
    any = fmax(any, mean);
    if (area >= (double)c->R * c->lv[d].s * c->lv[d].s) best = fmax(best, mean);
  }
  *abar = best > 0 ? best : any;
  return GI_OK;
}

/* The emissive triangles within reach of the cascade: no farther from its
 * box than half its side, or than twice their own size (the diagonal of
 * their bounds). Emitters light the cascade from outside it too: a small
 * one farther away than half a cascade lights it at under a ninth of the
 * irradiance it would give at the border, and one twice its own size
 * away at about a twelfth of what it gives up close. The size term keeps
 * a large panel near a small cascade (a hall's glowing ceiling 5 m above
 * a 3 m cascade: the voxels took none of its light, and the floor's
 * bounce light was lost). The coarsest level already spans the whole
 * scene by default. */
static uint32_t emitters_in_reach(const struct gi_cascade *c) {
  const gi_scene *s = c->scene;
  const gi_level *L = &c->lv[c->n - 1];
  uint32_t n = 0;
  for (uint32_t e = 0; e < s->num_emitters; e++) {
    const uint32_t *ix = &s->indices[3 * s->emitter_tri[e]];
    double gap = 0, diag2 = 0;
    for (int a = 0; a < 3; a++) {
      double lo = s->vertices[3 * ix[0] + a], hi = lo;
      for (int v = 1; v < 3; v++) lo = fmin(lo, s->vertices[3 * ix[v] + a]), hi = fmax(hi, s->vertices[3 * ix[v] + a]);
      gap = fmax(gap, fmax((double)L->lo[a] - hi, lo - (double)L->hi[a]));
      diag2 += (hi - lo) * (hi - lo);
    }
    /* Per axis, as the box grown by half its side on every face was. */
    double reach = fmax(0.5 * ((double)L->hi[0] - L->lo[0]), 2 * sqrt(diag2));
    n += gap <= reach;
  }
  return n;
}

/* What lies in range of the cascade: emissive triangles in reach of it
 * (emitters_in_reach, *emit_in), glossy triangles inside it and their
 * reflectance (level_albedo, *abar; *surfaces 0 when the cascade holds
 * none). Gloss: inside only. */
static gi_result survey_range(struct gi_cascade *c, int threads, uint32_t *emit_in, uint32_t *glossy, double *abar,
                              int *surfaces, gi_error_info *err) {
  const gi_level *top = &c->lv[c->n - 1];
  gi_result rc = level_albedo(c, threads, abar, surfaces);
  if (rc != GI_OK) return gi__fail(err, rc, "plan: triangle query in a level failed (%s)", gi_strerror(rc));
  *glossy = c->survey.lvl[c->n - 1].glossy; /* the coarsest box: everything in the cascade */
  if (!(c->survey.valid && !memcmp(c->survey.lo, top->lo, sizeof top->lo) &&
        !memcmp(c->survey.hi, top->hi, sizeof top->hi))) {
    c->survey.emit_in = emitters_in_reach(c);
    c->survey.valid = 1;
    memcpy(c->survey.lo, top->lo, sizeof top->lo);
    memcpy(c->survey.hi, top->hi, sizeof top->hi);
  }
  *emit_in = c->survey.emit_in;
  return GI_OK;
}

/* The local lights' reason: how many, and whether voxels and answers take
 * them one by one or through the light cut (scene/local_tree.c). */
static void local_why(const gi_scene *s, const gi_quality *q, gi_bake_report *r, int local) {
  int vc = gi__local_cut_size(q->light_samples), pc = gi__local_cut_size(q->probe_samples);
  int voxel_cut = gi__local_cut_on(s, vc), probe_cut = gi__local_cut_on(s, pc);
  if (!voxel_cut && !probe_cut) {
    set_fx(r, GI_FX_LOCAL, 1, "%d point/spot light%s", local, local > 1 ? "s" : "");
  } else if (!probe_cut) {
    set_fx(r, GI_FX_LOCAL, 1, "%d point/spot lights: voxels take them through a light cut of %d rays, probes one by "
           "one", local, vc);
  } else {
    set_fx(r, GI_FX_LOCAL, 1, "%d point/spot lights through a light cut: %d rays per voxel, %d per probe", local, vc,
           pc);
  }
}

/* Ambient occlusion runs when asked for (--ao, or forced on), unless an override turns it off. */
static void plan_ao(const gi_quality *q, gi_bake_report *r) {
  int fao = gi__fx_forced(q, GI_FX_AO);
  if (fao == GI_FX_ON) set_fx(r, GI_FX_AO, 1, "requested, lambda %.3g per unit", q->ao_lambda);
  else if (fao == GI_FX_OFF) set_fx(r, GI_FX_AO, 0, "turned off by the request");
  else set_fx(r, GI_FX_AO, 0, "not requested");
}

/* The bounce entry of the plan (after the light kinds'): sets q->bounces
 * when auto_bounces; returns 1 when the plan reached the cap and adds the
 * tail (before the entry's own ran is known: the caller combines them). */
static int plan_bounces(gi_quality *q, int auto_bounces, double abar, int surfaces, gi_bake_report *r) {
  /* From the albedo: the k-th reflection adds about a^k of the
   * direct light (a = the brightest level's area-weighted albedo, level_albedo,
   * in the cascade). With B voxel bounces the gather holds k = B + 1, so
   * the first one missing weighs a^(B+2). Stop when that is under 2% of
   * the direct light: the probe's own Monte Carlo noise on direct light is
   * about that (measured 1.2% Cornell, 1.6% Munich at 256 probe samples).
   * At most MAX_AUTO_BOUNCES: each bounce is a cone gather at every voxel.
   * When the cap stops short of that (a bright closed room: the Cornell
   * box's mean albedo gives a^6 = 19%), the orders left out are not
   * dropped: the bounce stage extrapolates them as a geometric series from
   * the last two bounces (see gi__bounce), which costs no gather; and when
   * that series is small enough, it replaces the last bounce too
   * (TAIL_SHARE). */
  int fb = gi__fx_forced(q, GI_FX_BOUNCE);
  int tail = !auto_bounces && q->bounce_tail;
  if (auto_bounces) {
    int B = 1;
    while (B < MAX_AUTO_BOUNCES && pow(abar, B + 2) >= ORDER_LEFT) B++;
    /* At the cap, what is left out is worth a tail even under 2%: a^6
     * just under it still leaves a^6 / (1 - a) of the direct light (3% at
     * a = 0.5, which a furnace of that albedo would then miss). */
    tail = B == MAX_AUTO_BOUNCES;
    if (tail && tail_share(abar, B - 1) <= TAIL_SHARE) B--;
    q->bounces = B;
  }
  /* The voxels hold light only from the kinds that ran for them: with
   * none, every bounce gathers zeros (a room with no lights, every light
   * turned off by the request). */
  int lit = r->effects[GI_FX_SUN].ran || r->effects[GI_FX_LOCAL].ran || r->effects[GI_FX_SKY].ran ||
            r->effects[GI_FX_EMISSIVE].ran;
  if (fb == GI_FX_OFF) q->bounces = 0, set_fx(r, GI_FX_BOUNCE, 0, "turned off by the request");
  else if (q->bounces == 0) set_fx(r, GI_FX_BOUNCE, 0, "bounces set to none by the request");
  else if (!surfaces && fb != GI_FX_ON)
    q->bounces = 0, set_fx(r, GI_FX_BOUNCE, 0, "no surface inside the cascade: a bounce would add nothing");
  else if (abar <= 0 && fb != GI_FX_ON)
    q->bounces = 0, set_fx(r, GI_FX_BOUNCE, 0, "every albedo in range is 0: a bounce would add nothing");
  else if (!lit && fb != GI_FX_ON)
    q->bounces = 0, set_fx(r, GI_FX_BOUNCE, 0, "no light reaches the voxels (sun, local lights, sky and emitters "
                                               "all skipped): a bounce would add nothing");
  else if (auto_bounces && tail)
    set_fx(r, GI_FX_BOUNCE, 1, "%d bounces and the geometric tail of the rest: mean albedo %.2f in range, the "
                               "tail brings %.1f%% of direct (at most %d, %d when it brings <= %.0f%%)", q->bounces, abar,
           100 * tail_share(abar, q->bounces), MAX_AUTO_BOUNCES, MAX_AUTO_BOUNCES - 1, 100 * TAIL_SHARE);
  else if (auto_bounces)
    set_fx(r, GI_FX_BOUNCE, 1, "%d bounce%s: mean albedo %.2f in range, next bounce would add %.1f%% of direct "
                               "(stop under 2%%, at most %d)", q->bounces, q->bounces > 1 ? "s" : "", abar,
           100 * pow(abar, q->bounces + 2), MAX_AUTO_BOUNCES);
  else if (tail)
    set_fx(r, GI_FX_BOUNCE, 1, "%d bounces and the geometric tail of the rest as requested, mean albedo %.2f in range",
           q->bounces, abar);
  else set_fx(r, GI_FX_BOUNCE, 1, "%d bounce%s as requested, mean albedo %.2f in range", q->bounces,
              q->bounces > 1 ? "s" : "", abar);

  return tail;
}

/* The effect plan: what this scene and request call for, with reasons.
 * Runs after placement (it looks at what lies inside the cascade). May set
 * q->bounces when the request left it to the plan (auto_bounces). *tail is
 * 1 when the plan reached the cap while the orders left out still weigh
 * 2% or more (and may then take one bounce off it): the bounce stage then
 * adds their geometric tail (light/bounce.c). */
gi_result gi__plan_effects(struct gi_cascade *c, gi_quality *q, int auto_bounces, gi_bake_report *r,
                           int *tail_out, gi_error_info *err) {
  const gi_scene *s = c->scene;
  int sun = 0, local = 0, sky = 0;
  for (uint32_t i = 0; i < s->num_lights; i++) {
    const gi_light *l = &s->lights[i];
    int lit = l->color[0] > 0 || l->color[1] > 0 || l->color[2] > 0;
    if (!lit) continue;
    if (l->type == GI_LIGHT_SUN) sun++;
    else if (l->type == GI_LIGHT_SKY) sky++;
    else local++;
  }
  if (gi__fx_forced(q, GI_FX_SUN) == GI_FX_OFF) set_fx(r, GI_FX_SUN, 0, "turned off by the request");
  else if (sun) set_fx(r, GI_FX_SUN, 1, "%d directional light%s", sun, sun > 1 ? "s" : "");
  else set_fx(r, GI_FX_SUN, 0, "no directional light in the scene");
  if (gi__fx_forced(q, GI_FX_LOCAL) == GI_FX_OFF) set_fx(r, GI_FX_LOCAL, 0, "turned off by the request");
  else if (local) local_why(s, q, r, local);
  else set_fx(r, GI_FX_LOCAL, 0, "no point or spot light in the scene");

  int fs = gi__fx_forced(q, GI_FX_SKY);
  if (fs == GI_FX_OFF) set_fx(r, GI_FX_SKY, 0, "turned off by the request");
  else if (!sky) set_fx(r, GI_FX_SKY, 0, "no sky light in the scene");
  else if (fs == GI_FX_ON) set_fx(r, GI_FX_SKY, 1, "forced on by the request, %d samples per voxel", q->light_samples);
  else {
    int tested = 0, seen = sky_rays(c, &tested);
    if (seen) set_fx(r, GI_FX_SKY, 1, "sky seen by %d of %d test rays, %d samples per voxel", seen, tested,
                     q->light_samples);
    else set_fx(r, GI_FX_SKY, 0, "sky light present, but none of %d upward test rays (round the viewpoint, off "
                                 "what it sees) escapes: no voxel takes it (probes, views, texels still sample it)",
                 tested);
  }

  uint32_t emit_in = 0, glossy = 0;
  double abar = 0;
  int surfaces = 0;
  gi_result rc = survey_range(c, q->threads, &emit_in, &glossy, &abar, &surfaces, err);
  if (rc != GI_OK) return rc;
  int fe = gi__fx_forced(q, GI_FX_EMISSIVE);
  if (fe == GI_FX_OFF) set_fx(r, GI_FX_EMISSIVE, 0, "turned off by the request");
  else if (!s->num_emitters) set_fx(r, GI_FX_EMISSIVE, 0, "no emissive surfaces");
  else if (emit_in || fe == GI_FX_ON)
    set_fx(r, GI_FX_EMISSIVE, 1, "%u emissive triangles (%u within reach of the cascade%s), %d samples per voxel",
           s->num_emitters, emit_in, emit_in ? "" : ", forced on", q->light_samples);
  else set_fx(r, GI_FX_EMISSIVE, 0, "%u emissive triangles, none in reach (half a cascade, twice their size): "
                                    "no voxel takes "
                                    "their light (probes, views and texels still sample it)", s->num_emitters);

  int tail = plan_bounces(q, auto_bounces, abar, surfaces, r);
  c->wide_level = c->n;
  if (r->effects[GI_FX_BOUNCE].ran && c->num_wide_cones < c->num_cones) c->wide_level = wide_level(c);
  r->wide_from_level = c->wide_level;

  /* The specular cone needs a view direction; probes have none. Camera
   * views re-decide this entry (gi_cascade_view_plan) from the same count. */
  r->glossy_triangles = glossy;
  int fsp = gi__fx_forced(q, GI_FX_SPECULAR);
  if (fsp == GI_FX_OFF) set_fx(r, GI_FX_SPECULAR, 0, "turned off by the request");
  else if (fsp == GI_FX_ON)
    set_fx(r, GI_FX_SPECULAR, 0, "forced on: camera views trace it at every pixel; probe output has no view direction");
  else if (glossy)
    set_fx(r, GI_FX_SPECULAR, 0, "%u glossy triangle%s in range: camera views trace it; probe output has no view "
                                 "direction", glossy, glossy > 1 ? "s" : "");
  else set_fx(r, GI_FX_SPECULAR, 0, "no glossy material within the cascade");
  plan_ao(q, r);
  *tail_out = tail && r->effects[GI_FX_BOUNCE].ran;
  q->bounce_tail = *tail_out;
  return GI_OK;
}

gi_result gi__cascade_placed(const gi_scene *s, const double at[3], const gi_quality *q, const char *who,
                             struct gi_cascade **out, gi_error_info *err) {
  *out = NULL;
  struct gi_cascade *c = gi__calloc(1, sizeof *c);
  if (!c) return gi__fail(err, GI_ERR_NOMEM, "%s: out of memory", who);
  c->scene = (gi_scene *)s;
  c->wide_level = GI_MAX_LEVELS;
  c->n = q->levels;
  c->R = q->res;
  c->s0 = q->voxel0;
  gi_result rc = isfinite(at[0]) && isfinite(at[1]) && isfinite(at[2])
                     ? gi__viewpoint_range(s, at, c->s0, who, err)
                     : gi__fail(err, GI_ERR_NONFINITE, "%s: viewpoint (%g, %g, %g) is not finite", who, at[0], at[1],
                                at[2]);
  if (rc != GI_OK) {
    gi__free(c);
    return rc;
  }
  /* The bake's float rounding: the placement depends on the anchor alone. */
  for (int a = 0; a < 3; a++) c->at[a] = (float)(at[a] - s->origin[a]);
  gi__cascade_place(c);
  *out = c;
  return GI_OK;
}

gi_result gi_effect_plan(const gi_scene *s, const double at[3], const gi_quality *qin, gi_effect out[GI_FX_COUNT],
                         gi_quality *resolved, gi_error_info *err) {
  return gi__effect_plan_for(s, at, qin, NULL, 0, out, resolved, err);
}

gi_result gi__effect_plan_for(const gi_scene *s, const double at[3], const gi_quality *qin, const float *pts, int npts,
                              gi_effect out[GI_FX_COUNT], gi_quality *resolved, gi_error_info *err) {
  if (!s || !at || !out)
    return gi__fail(err, GI_ERR_INVALID_ARG, "plan: %s is NULL", !s ? "scene" : !at ? "viewpoint" : "out");
  gi_quality q;
  gi_result rc = gi_quality_resolve(s, qin, &q, err);
  if (rc != GI_OK) return rc;
  /* The plan looks at what lies inside the placed cascade. */
  struct gi_cascade *c;
  if ((rc = gi__cascade_placed(s, at, &q, "plan", &c, err)) != GI_OK) return rc;
  int tail;
  c->answer_pts = pts, c->num_answer_pts = pts ? npts : 0;
  rc = gi__plan_effects(c, &q, !qin || qin->bounces == 0, &c->report, &tail, err);
  if (rc != GI_OK) {
    gi__free(c);
    return rc;
  }
  memcpy(out, c->report.effects, sizeof c->report.effects);
  if (resolved) *resolved = q;
  gi__free(c);
  return GI_OK;
}

gi_result gi__viewpoint_range(const gi_scene *s, const double at[3], double s0, const char *who, gi_error_info *err) {
  for (int a = 0; a < 3; a++) {
    float al = (float)(at[a] - s->origin[a]);
    if (!isfinite(al) || fabs(at[a] - s->origin[a]) > GI_MAX_VIEW_DISTANCE)
      return gi__fail(err, GI_ERR_INVALID_ARG,
                      "%s: viewpoint is more than " GI_MAX_VIEW_DISTANCE_TEXT
                      " units from the scene's origin on axis %c (%g)", who, "xyz"[a], fabs(at[a] - s->origin[a]));
    if (!gi__cells_ok(al, s0))
      return gi__fail(err, GI_ERR_INVALID_ARG,
                      "%s: the voxel size %g is too small for a viewpoint %g units from the scene's origin "
                      "(more than 2^52 voxels)", who, s0, fabs((double)al));
  }
  return GI_OK;
}
