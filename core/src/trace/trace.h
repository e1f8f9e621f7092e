/* trace.h: cone tracing over the cascaded texture (trace/cones.c,
 * trace/march.c, trace/specular.c). Reads a finished cascade only:
 * thread-safe. */
#ifndef GI_TRACE_H
#define GI_TRACE_H

#include "cascade/cascade_internal.h"

void gi__cone_set(int count, float aperture_deg, float dirs[][3], float weights[], float *tan_half);
/* The probes' final gather: the bake's set, or from 32 bake cones (the
 * high setting) a denser, narrower set of 64. A cone reads voxels about as
 * wide as itself, whose trilinear footprint spans twice its width, so a
 * wide cone at street level also reads the roofs and walls beside its path
 * (the city's street-level indirect light: 0.49 of the reference's with
 * 16 cones, 0.61 with 32, 0.65 with 64, one bounce, sun only). It is not
 * the default because a finer quadrature also reads what the 16-cone set
 * averages away: the furnace's edge voxels, whose single normal leaves
 * their bounced light about 1.2% low (the furnace probe reads -1.7% at
 * order 4 with 64 cones, -0.7% with 16; bound 1.5%).
 * aperture_deg is the request's (0 = matched to the regions). */
int gi__probe_cone_count(int bake_count);
void gi__probe_cone_set(int bake_count, float aperture_deg, float dirs[][3], float weights[], float *tan_half);
/* The bounces' set for the orders from the third on (light/bounce.c):
 * 8 wider cones (fewer for a smaller bake set), weights summing to pi.
 * What those bounces gather is the last order's light alone, which is
 * small and smooth by then, so half the cones lose little (measured: see
 * bounce.c). aperture_deg as for the probes' set. */
int gi__wide_cone_count(int bake_count);
void gi__wide_cone_set(int bake_count, float aperture_deg, float dirs[][3], float weights[], float *tan_half);
typedef struct gi_cone_out {
  float L[3];          /* radiance arriving along the cone */
  float alpha;         /* accumulated opacity */
  float occlusion;     /* AO-weighted occlusion */
  uint32_t samples;
} gi_cone_out;
/* Marches one cone from apex o along unit w, first sample at distance t0,
 * steps of `step` voxels of the sampled level. h0 < 0: the apex is in free
 * space. h0 >= 0: the apex is h0 above a surface of unit normal n (w.n > 0);
 * levels coarse enough for their footprint to reach back to the surface
 * are not sampled there (keeps light from leaking through walls thinner
 * than a voxel; see march.c), and where the window forces one, it is read
 * across the normal only. Callers go through the gather's rule below. */
#define GI_SURFACE_LOD_K 2.0f
/* Longest step, in voxels of the sampled level, while the surface rule
 * holds a cone on a level finer than its width. Free-space samples step
 * by the quality's step (default 1: the trilinear tents of samples one
 * voxel apart sum to one, so a wall's opacity is counted whole). 1.0 here
 * let the thin-wall test's camera views leak 1.6%, 0.75 leaks 1.3%, 0.5
 * 0.9% at 1.5x the samples. */
#define GI_NEAR_SURFACE_STEP 0.75f
/* Most samples one cone takes: far beyond what crossing every level needs. */
#define GI_CONE_MAX_STEPS 4096
void gi__cone_march(const struct gi_cascade *c, const float o[3], const float w[3], float tan_half, float t0,
                    float step, float ao_lambda, float h0, const float *n, gi_cone_out *out);

/* ---- the gather (trace/gather.c): one rule for where cones start ----
 * GI_GATHER_SURFACE: p lies on a surface of unit normal n (the side to
 * gather). Cones start one voxel s off the surface (apex p + s n, first
 * sample s further) and use the surface level-entry rule (h0 = s). Voxel
 * bounces, camera-view hits and specular cones.
 * GI_GATHER_FREE: p is a point in space (a probe, a panorama's eye). Cones
 * start at p itself, first sample one voxel s out, with no entry limit; n,
 * when given, only orients the hemisphere.
 * s is the voxel size of `level`; level < 0 takes the finest level whose
 * window contains p (the best resolution there). */
typedef enum { GI_GATHER_FREE = 0, GI_GATHER_SURFACE = 1 } gi_gather_mode;
typedef struct gi_gather_start {
  float o[3];          /* apex */
  float n[3];          /* surface normal (GI_GATHER_SURFACE) */
  float t0, h0;        /* first sample distance; apex height (< 0: free space) */
  float step, ao_lambda;
} gi_gather_start;
/* Fills g for a gather at p; returns 0 when level < 0 and p lies outside
 * every level (g is then set up with the finest voxel size). */
int gi__gather_start(const struct gi_cascade *c, const float p[3], const float *n, gi_gather_mode mode, int level,
                     gi_gather_start *g);
/* The surfaces a cone's start o has beside it: along each axis in `axes`
 * (bit 2a: +a, 2a + 1: -a) the first surface within reach (hits nearer
 * than `on` skipped: the one o lies on), unless its normal lies within
 * acos(skip_cos) of skip_n (may be NULL: none skipped). Per surface m[k]
 * is its unit normal toward o and r[k] how far a start lifted off it
 * goes: to `reach` from it, at most half way to what lies behind o along
 * m[k] (a gap's far wall). Returns how many (at most 6). Bounce sides
 * (light/bounce.c) and probes (answer/gather.c) start their cones off
 * them. Thread-safe. */
int gi__surfaces_beside(const struct gi_cascade *c, const float o[3], float reach, float on, unsigned axes,
                        const float *skip_n, float skip_cos, float m[6][3], float r[6]);
/* The shift of a surface gather's apex o (level d, unit normal n) off the
 * other surfaces beside it: by gi__surfaces_beside along the axes across
 * n, within GI_BESIDE_REACH voxels of level d. A wall's side in the row of
 * voxels under a ceiling started its cones within a coarse voxel of the
 * ceiling, and a cone going down read, in the ceiling's voxel, the light
 * the sunlit roof above sends up: a sealed room under the sun leaked
 * 0.5-22% of a windowed room's light into its dark inside (none after); a
 * room lit through a window read 30.7% indirect error (21.8% after).
 * Voxel bounces (light/bounce.c) and lightmap texels (answer/surface.c)
 * shift their apexes by it. Thread-safe. */
#define GI_BESIDE_REACH 1.5f
void gi__away_from_beside(const struct gi_cascade *c, int d, const float n[3], const float o[3], float out[3]);
/* One cone of half-angle tangent tan_half along unit w from g. */
void gi__gather_cone(const struct gi_cascade *c, const gi_gather_start *g, const float w[3], float tan_half,
                     gi_cone_out *out);
/* One cone of a batch: its start as gi__gather_start sets it (apex o,
 * first sample distance t0, apex height h0, < 0 in free space, and the
 * surface's unit normal n when h0 >= 0) and its unit direction w. */
typedef struct gi_cone_job {
  float o[3], n[3], w[3];
  float t0, h0;
} gi_cone_job;
/* Marches count cones of half-angle tangent tan_half with one step rule
 * into out[i], each as gi__cone_march would (to float rounding): on the
 * x86-64-v3 path eight at a time in AVX2 lanes (march_simd.c), so the
 * more cones one call gets (a voxel's two sides, several gathers), the
 * fuller the lanes stay. */
#define GI_MARCH_LANES_MAX_RES 256
/* Cones one batched march takes at most (the bounces' and the gathers'
 * batches): enough to keep the lanes busy past a batch's drain, and more
 * than any one voxel's cones (GI_VOX_FACES x GI_MAX_CONES = 384). */
#define GI_MARCH_BATCH_JOBS 512
void gi__cone_march_jobs(const struct gi_cascade *c, const gi_cone_job *jobs, int count, float tan_half,
                         float step, float ao_lambda, gi_cone_out *out);
/* A tap: one step of a marched cone that added light. A cone's light is
 * a sum over its steps of weights times texel radiance, and every weight
 * (the step, the opacity, the trilinear corners) follows from the
 * voxels' opacity, which no bounce changes: only the radiance does. So the
 * bounces record a set's taps on its first bounce and replay them on the
 * later ones (light/bounce.c): a replay reads the lit steps' texels again
 * and skips the march, and repeats the march's own arithmetic in its
 * order, so it returns the march's light bit for bit. A tap reads level d
 * at p (and with GI_TAP_BLEND level d + 1 there too, blended by frac),
 * axis a through the face facing -w (GI_TAP_FACE_X << a: w_a > 0) with
 * weight k[a]; kk is the step's compositing weight, alpha the cone's
 * final opacity (0 until the cone ends). `job` is the cone's index in its
 * march, or in a tape its bit (side x set size + cone). */
enum {
  GI_TAP_FACE_X = 1,  /* faces: bit a set when w_a > 0 */
  GI_TAP_BUSY = 8,    /* level d's block held opacity (else it read zero) */
  GI_TAP_BUSY2 = 16,  /* the same for level d + 1 */
  GI_TAP_BLEND = 32,  /* the step blended level d + 1 in by frac */
  GI_TAP_KALT = 64    /* the step read the axes across the normal only: k is the cone's second */
};
typedef struct gi_tap {
  float p[3], kk; /* p, kk, d and flags as a tape unit holds them (gi__tape_pack copies them whole) */
  float k[3], frac, alpha;
  uint8_t d, flags;
  uint16_t job;
} gi_tap;
/* Where a recording march puts its taps, in the order it takes them (one
 * cone's in step order). The caller owns t (gi__free) and sets max, the
 * most taps t may grow to; full says a tap did not fit (past max, or out
 * of memory: oom): t then misses some and must not be replayed. */
typedef struct gi_tap_rec {
  gi_tap *t;
  size_t n, cap, max;
  int full, oom;
} gi_tap_rec;
/* gi__tap_grow enlarges r's room (trace/taps.c); 0 when it cannot (at
 * max, or out of memory), with r->full set. gi__tap_reserve makes room
 * for k more taps (0: they do not fit, r->full set); gi__tap_push
 * appends one (marches call it; 0 when it did not fit). */
int gi__tap_grow(gi_tap_rec *r);
static inline int gi__tap_reserve(gi_tap_rec *r, size_t k) {
  while (r->cap - r->n < k)
    if (!gi__tap_grow(r)) return 0;
  return 1;
}
static inline int gi__tap_push(gi_tap_rec *r, const gi_tap *tap) {
  if (!gi__tap_reserve(r, 1)) return 0;
  r->t[r->n++] = *tap;
  return 1;
}
/* gi__cone_march_jobs, also recording the taps of every cone into rec
 * (NULL: none; job = the cone's index in jobs, alpha left 0). */
void gi__cone_march_jobs_rec(const struct gi_cascade *c, const gi_cone_job *jobs, int count, float tan_half,
                             float step, float ao_lambda, gi_cone_out *out, gi_tap_rec *rec);
/* A kept tape: its cones' taps packed into 20-byte units, half of a
 * gi_tap's 40 bytes, since a bake keeps tens of MB of them and fresh
 * memory is what a bake's first touch pays for. Per cone: a head (its
 * job, its tap count n, with GI_TAPE_ALT set when a unit holding its
 * second axis weights k follows, its alpha and its k), then its taps (p,
 * kk, d, flags; GI_TAP_KALT: the second k), a blending tap followed by a
 * unit whose f[0] is its frac. The per-cone values were the same in every
 * one of the cone's taps, so the replay reads the same numbers as from
 * the gi_taps, and returns the same bits. */
#define GI_TAPE_ALT 0x8000u
typedef union gi_tape_unit {
  struct {
    uint16_t job, n;
    float alpha, k[3];
  } head;
  struct {
    float p[3], kk;
    uint8_t d, flags;
    uint16_t unused;
  } tap;
  float f[5];
} gi_tape_unit;
_Static_assert(sizeof(gi_tape_unit) == 20, "a tape unit is 20 bytes");
_Static_assert(offsetof(gi_tap, kk) == offsetof(gi_tape_unit, tap.kk) && offsetof(gi_tap, d) == 36 &&
                   offsetof(gi_tape_unit, tap.d) == 16 && offsetof(gi_tap, flags) == 37 &&
                   offsetof(gi_tape_unit, tap.flags) == 17,
               "a tap's p, kk, d and flags copy into a unit in two moves");
_Static_assert(GI_CONE_MAX_STEPS < GI_TAPE_ALT, "a cone's tap count fits beside GI_TAPE_ALT");
/* How a recording march's taps (rec order, job: the cone's index in the
 * march, < nj <= GI_MARCH_BATCH_JOBS) pack, every cone's units laid out
 * in job order: cone j's are [start[j], start[j + 1]) (none without a
 * tap), and it holds taps[j] taps; k0[j] and k1[j] are taps holding its
 * axis weights and its second ones (GI_TAP_KALT; -1: none). A cone's
 * taps of either kind hold the same k, the march's per-cone constants
 * (test_texel checks the replay's bits). gi__tape_pack writes them
 * into u (start[nj] units), cone j's head with job id[j] and alpha
 * co[j].alpha: cones [j0, j1) are one tape of units [start[j0],
 * start[j1]). */
typedef struct gi_tape_plan {
  uint32_t start[GI_MARCH_BATCH_JOBS + 1], taps[GI_MARCH_BATCH_JOBS];
  int32_t k0[GI_MARCH_BATCH_JOBS], k1[GI_MARCH_BATCH_JOBS];
} gi_tape_plan;
void gi__tape_plan(const gi_tap *t, size_t n, int nj, gi_tape_plan *pl);
void gi__tape_pack(const gi_tap *t, size_t n, int nj, const gi_tape_plan *pl, const int16_t *id,
                   const gi_cone_out *co, gi_tape_unit *u);
/* The light of the cones of a packed tape of `units` units, reading the
 * cascade's texture as it is now: the k-th cone's in L[k] (its job in
 * job[k]; job may be NULL), what gi__cone_march_jobs would return for
 * that cone, bit for bit, on the same path (cpu and R). Returns the
 * cones. Thread-safe. */
size_t gi__replay_tape(const struct gi_cascade *c, const gi_tape_unit *u, size_t units, float L[][3],
                       uint16_t *job);
/* The same for the jobs[0..nj) whose done[k] is 0 (nj <= GI_MARCH_BATCH_JOBS);
 * out[k] of the others is left as it is (trace/gather.c). */
void gi__cone_march_rest(const struct gi_cascade *c, const gi_cone_job *jobs, const uint8_t *done, int nj,
                         float tan_half, float step, float ao_lambda, gi_cone_out *out);
/* The cascade's diffuse cone set (wide: the bounces' wide set) on the
 * hemisphere around unit n, started from g, as jobs (num_cones, or
 * num_wide_cones, of them). */
void gi__hemisphere_jobs(const struct gi_cascade *c, int wide, const gi_gather_start *g, const float n[3],
                         gi_cone_job *jobs);
/* What a hemisphere gather returns. */
typedef struct gi_gather_out {
  float E[3];          /* irradiance: sum over cones of weight x L */
  float occlusion;     /* sum of weight x occlusion: pi when fully occluded */
  uint64_t samples;    /* texture samples taken */
} gi_gather_out;
/* One hemisphere gather: at p, around unit n, by the gather's rule for
 * `mode` at `level` (see gi_gather_mode). */
typedef struct gi_gather_req {
  float p[3], n[3];
  gi_gather_mode mode;
  int level;
} gi_gather_req;
static inline gi_gather_req gi__gather_req(const float p[3], const float n[3], gi_gather_mode mode, int level) {
  gi_gather_req r = {.p = {p[0], p[1], p[2]}, .n = {n[0], n[1], n[2]}, .mode = mode, .level = level};
  return r;
}
/* The cascade's diffuse cone set (num_cones) for each gather req[0..count)
 * into out[i], zeroed where level < 0 and p lies outside every level
 * (there is nothing to gather). Several gathers' cones march together,
 * which keeps the SIMD lanes fuller (one surface gather's 16 cones kept
 * them 61% busy in a camera view); each out[i] has the bits of a gather
 * alone. Thread-safe. */
void gi__gather_hemispheres(const struct gi_cascade *c, const gi_gather_req *req, size_t count, gi_gather_out *out);
/* Free-space gathers (mode GI_GATHER_FREE, level -1) with the probes' set
 * (c->num_probe_cones cones; see gi__probe_cone_set), as
 * gi__gather_hemispheres: dirs and cones receive every cone's direction
 * and result for SH projection, num_probe_cones per gather (zeroed for a
 * gather outside every level). h0[i] >= 0: p lies h0 above a surface
 * whose normal is n (the ground under a street-level probe), and the
 * cones keep the surface rule's level limit and its across-the-normal
 * reads near that surface, as a voxel's gather does: otherwise a probe
 * outside the finest windows reads coarse voxels whose footprint holds
 * the ground below it, an occluder the cone never meets that darkens it
 * (the city's street probes read 26% of a cone's light off the ground's
 * underside). h0[i] < 0: plain free space. adjust (may be NULL) is
 * called on each gather's jobs once they are set up and before they
 * march: gather i's n cones, to change their start (the probe's nearest
 * surface, answer/gather.c), or to answer cone k itself: it then sets
 * done[k] = 1 and fills out[k], and that cone does not march. done[]
 * arrives zeroed. */
typedef void (*gi_cone_adjust)(void *ctx, size_t gather, gi_cone_job *jobs, int n, uint8_t *done,
                               gi_cone_out *out);
void gi__gather_probe_hemispheres(const struct gi_cascade *c, const gi_gather_req *req, const float *h0, size_t count,
                                  gi_cone_adjust adjust, void *ctx, gi_gather_out *out, float (*dirs)[3],
                                  gi_cone_out *cones);

/* Half-angle tangent of the specular cone for a roughness in [0,1]: the
 * half-width at half maximum of the Phong lobe equivalent to Beckmann
 * alpha = roughness^2 (exponent 2 / alpha^2 - 2), at least 0.5 degree. */
float gi__specular_tan(float roughness);

/* Radiance arriving along the mirror direction of view v (unit, pointing
 * from the eye to p) about unit normal n, through one cone, plus the sky
 * where the cone escapes and the emitters within it (rays seeded by seed:
 * the caller's pixel, so a view is the same on any thread count). */
void gi__specular_trace(const struct gi_cascade *c, const float p[3], const float n[3], const float v[3],
                        float roughness, uint64_t seed, gi_cone_out *out);
/* The same with the cone's half-angle tangent given (aperture sweeps in tests). */
void gi__specular_trace_tan(const struct gi_cascade *c, const float p[3], const float n[3], const float v[3],
                            float tan_half, uint64_t seed, gi_cone_out *out);
/* Samples the texture at local p for direction w (the faces facing -w),
 * trilinearly on level d: premultiplied radiance and optical depth per unit length. */
int gi__sample_level(const struct gi_cascade *c, int d, const float p[3], const float w[3],
                     float prem[3], float *wsum_alpha, float *sigma);
/* Finest level whose window (minus one voxel) contains p; -1 when none. */
int gi__finest_level_at(const struct gi_cascade *c, const float p[3]);
/* The local voxel size at p: that level's voxel, else the finest (s0). */
float gi__voxel_at(const struct gi_cascade *c, const float p[3]);

#endif
