/* light.h: lighting the cascade: injection (light/inject.c) and bounces
 * (light/bounce.c). Each writes the cascade it is given; one call at a time
 * per cascade. */
#ifndef GI_LIGHT_H
#define GI_LIGHT_H

#include "cascade/cascade_internal.h"
#include "scene/lights.h"

/* inject.c: direct light into every occupied voxel (both sides). */
gi_result gi__inject(struct gi_cascade *c, const gi_quality *q, gi_error_info *err);
/* Direct light into the listed voxels of every level (slots[d][0..count[d]),
 * a move's new voxels), in one parallel loop; the caller reshades
 * (gi__shade_all). */
gi_result gi__inject_levels(struct gi_cascade *c, const gi_quality *q, const uint32_t *const slots[],
                            const uint32_t count[], gi_error_info *err);
/* Recomputes each occupied voxel's face radiance from its side irradiance. */
void gi__shade_voxels(struct gi_cascade *c, int d, uint32_t begin, uint32_t end);
/* gi__shade_voxels over every occupied voxel of every level. */
void gi__shade_all(struct gi_cascade *c);
/* As gi__shade_all, from the irradiance from[d][q] of level d's occupied
 * voxel q instead of its side light (a bounce's increment, which the next
 * bounce gathers alone); side is left as it is. */
void gi__shade_all_from(struct gi_cascade *c, gi_faces3 *const from[]);
/* near_field.c: a point or spot light near a voxel's own surfaces, lit
 * piece by piece. The scratch belongs to one worker; gi__near_reset before
 * each voxel (it caches the voxel's triangles), gi__near_free at the end. */
typedef struct gi_near_scratch {
  uint32_t *tris;
  size_t count, cap;
  int have;            /* tris holds the current voxel's triangles */
  /* gi__spread_light: the voxel's pieces (clipped once per voxel) and the
   * groups' areas. */
  struct gi_piece *pieces;
  size_t npieces, pieces_cap;
  int have_pieces;
  float wsum[GI_VOX_GROUPS], total;
  float wside[GI_VOX_GROUPS][2]; /* per group side, the area of the pieces seen from it */
} gi_near_scratch;
/* A voxel holding more triangles than this keeps the centroid's value: the
 * pieces cost a clip and a shadow ray each, per near light, and a coarse
 * voxel of a dense scanned mesh can hold hundreds of thousands (the
 * procedural city's largest near voxel holds 80). */
#define GI_NEAR_MAX_TRIS 4096
void gi__near_reset(gi_near_scratch *ns);
void gi__near_free(gi_near_scratch *ns);
/* Adds to Es[2 h + s] the irradiance on side s (0: the side orient[h]
 * faces) of every group h of voxel g, global cell `cell` of size sz, from
 * local light sample l taken at g's centroid: the flux the group's pieces
 * receive over their area. Each piece is clipped and traced once whatever
 * the groups it shows in. Adds the shadow rays traced to *rays. Returns
 * the groups it lit as a bit mask (bit h); a group without a piece, or
 * every group of a voxel with too many triangles to light one by one,
 * is left to the caller's centroid value; -1 when out of memory.
 * Thread-safe with one scratch per thread. */
int gi__near_field(const gi_scene *s, const gi_vgeo *g, double sz, const int64_t cell[3], const gi_lsample *l,
                   gi_near_scratch *ns, float Es[GI_VOX_FACES][3], uint64_t *rays);
/* Light on a coarse voxel (level >= GI_SPREAD_FROM) from points spread
 * over its surface by area, each with its own shadow ray, instead of rays
 * from its groups' centroids. ls[0..m) are the samples of one light: the
 * sun (m = 1) takes GI_SUN_POINTS points, the sky's m samples one point
 * each. A coarse voxel half in a building's shadow is then half lit, as
 * the filter of its children says, not all or nothing: the two disagreed
 * by the whole sun wherever a shadow's edge crossed a voxel, and a grid
 * shift that turned one into the other moved a street probe's dim side
 * 11% (the drive's worst shift, sun alone). Adds to Es as
 * gi__near_field; returns the groups it lit (0: none, or too many
 * triangles: the caller's centroid rays decide), -1 when out of memory.
 * Draws from rng. Thread-safe with one scratch per thread. */
#define GI_SPREAD_FROM 1
#define GI_SUN_POINTS 8
/* The most points a spread (gi__spread_light, gi__spread_emitters) takes:
 * the most light samples per voxel a quality may ask for (plan.c). */
#define GI_SPREAD_MAX_POINTS 512
int gi__spread_light(const gi_scene *s, const gi_vgeo *g, double sz, const int64_t cell[3], const gi_lsample *ls,
                     int m, uint64_t *rng, gi_near_scratch *ns, float Es[GI_VOX_FACES][3], uint64_t *rays);
/* Injection spreads the emitters over voxels of this level and coarser.
 * From level 1, test_move's drive drift (moved against cold bakes, E(-y)
 * over a dark road at its last steps) read 6.9% where it reads 3.8% from
 * level 2 and without spreading; why is not found yet. The grid shifts
 * that jumped most were on levels 3-5. */
#define GI_EMIT_SPREAD_FROM 2
/* Injection spreads the emitters over a coarse voxel only with an emitter
 * this many voxels from its centroid: farther, the light changes little
 * across the voxel (its centroid's and its mean differ by about
 * (size / distance)^2) and the centroid's samples are cheaper (the
 * Cornell box's injection 36 -> 55 ms on one thread when every coarse
 * voxel spread). */
#define GI_EMIT_SPREAD_REACH 8.0f
/* The emitters' light on a coarse voxel (level >= GI_EMIT_SPREAD_FROM) from
 * m points spread over its surface by area, each with one light sample
 * (m stratified light-tree picks from the voxel's centroid, one per
 * point) and one cosine-weighted ray per side, weighed by the balance
 * heuristic, instead of m samples and m rays per side taken at its
 * groups' centroids. Across a street of lit
 * windows the centroid's irradiance is not the surface's mean, and the
 * filter of the voxel's children takes the mean: a grid shift that
 * turned one into the other moved a probe on the 900 m city's drive by
 * 2.3% (1.8% at 64 samples per voxel: not the noise). Adds to Es as
 * gi__spread_light; returns the groups it lit (0: no emitters, no
 * pieces or too many triangles: the caller samples at the centroids),
 * -1 when out of memory. Draws from rng. Thread-safe with one scratch
 * per thread. */
int gi__spread_emitters(const gi_scene *s, const gi_vgeo *g, double sz, const int64_t cell[3], int m, uint64_t *rng,
                        gi_near_scratch *ns, float Es[GI_VOX_FACES][3], uint64_t *rays);
/* bounce.c: voxel-to-voxel bounces: gathers indirect irradiance at every occupied voxel.
 * tail (with bounces >= 2): then adds the orders after the last bounce as
 * a geometric series whose ratio is measured from the last two bounces. */
/* The cones of a voxel's first bounce that met opacity: bit side *
 * num_cones + cone (sides 2 g + s of its groups; cones past the mask
 * always run). */
#define GI_HIT_BITS (64 * 3)
typedef struct gi_hits {
  uint64_t w[GI_HIT_BITS / 64];
} gi_hits;
/* between.c: which voxels a bounce fills from gathered neighbours on
 * their plane or edge instead of gathering. Per occupied voxel of a level (its
 * index in occ): nb[0] < 0 when it gathers, else the occupied indices of
 * the four neighbours whose mean it takes (a pair given twice). */
typedef struct gi_between {
  int32_t nb[4];
} gi_between;
/* 1 when level L's own voxel in `slot` is filled from the four
 * neighbours in slots nb[] (a pair given twice), which are always
 * gathered. own[s] >= 0 marks the level's own voxels (its occ list), the
 * only neighbours it takes. */
int gi__between_slots(const gi_level *L, int R, const int32_t *own, uint32_t slot, uint32_t nb[4]);
/* Level d's plan into *plan (num_occ + 1 entries, reallocated; the caller
 * frees it with gi__free); GI_ERR_NOMEM when out of memory (*plan may
 * then have grown or stayed). Depends only on the level's voxels; runs
 * on the bake's threads (c->report.quality.threads). */
gi_result gi__between_plan(const struct gi_cascade *c, int d, gi_between **plan);
/* The irradiance on the sides of g's surfaces in voxel h from h's per-face
 * irradiance E (the faces across each surface's major axis show its two
 * sides), in the order of g's groups (g: the voxel planned between h and
 * others; h may hold more surfaces); 0 when they cannot be read so. */
int gi__between_sides(const gi_vgeo *g, const gi_vgeo *h, const float E[GI_VOX_FACES][3],
                      float Es[2 * GI_VOX_GROUPS][3]);
/* The mean of four neighbours' irradiance on `sides` sides into out when
 * they agree (between.c says how closely); 0 when they do not, and the
 * voxel between them must be gathered. */
int gi__between_mean(int sides, const float v[4][2 * GI_VOX_GROUPS][3], float out[2 * GI_VOX_GROUPS][3]);
/* Voxel g's irradiance per face into E from its four neighbours h[k]
 * (per-face irradiance from[k]) when their sides agree (gi__between_sides,
 * gi__between_mean, faced back by gi__face_light); 0 (E untouched) when
 * they do not, and g must be gathered. */
int gi__between_take(const gi_vgeo *g, const gi_vgeo *const h[4], const float (*const from[4])[3],
                     float E[GI_VOX_FACES][3]);
/* Level d's planned voxels (plan: its plan; E: the bounce's gathers of
 * its other voxels) whose neighbours agree take their mean, on `threads`
 * workers; lists the others' occupied indices in redo (num_occ room), in
 * order, and returns how many. */
uint32_t gi__between_fill(const struct gi_cascade *c, int d, const gi_between *plan, gi_faces3 *E, uint32_t *redo,
                          int threads);
/* The gathers of level d's voxels slots[0..n) from the current texture
 * with the diffuse or the wide set: E[i] per face (the side it shows), and
 * when H is not NULL H[i] per face: the cosine-weighted share of that
 * side's cones that met a surface (the tail's energy ratio, bounce.c),
 * each voxel's the same as gathered alone (the cones are marched in
 * batches across voxels); returns the texture samples taken and adds the
 * cones marched to *cones. plan (NULL: none) is the slots' own plan
 * entries: a voxel it fills from its neighbours is skipped, E[i] left as
 * it is. A level with a shift array (a moving cascade) takes each voxel's
 * apex shift from it, finding and keeping it at the voxel's first gather.
 * Thread-safe for disjoint E and slots. */
uint64_t gi__gather_voxels(const struct gi_cascade *c, int d, const uint32_t *slots, size_t n, int wide,
                           const gi_between *plan, gi_faces3 *E, gi_hfaces *H, uint64_t *cones);
/* 1 when bounce `it` (from 0) of level d's voxels gathers with the wide
 * set: the bake and the move's re-bake must agree bounce by bounce. */
int gi__bounce_wide(const struct gi_cascade *c, int it, int d);
gi_result gi__bounce(struct gi_cascade *c, const gi_quality *q, int bounces, int tail, gi_error_info *err);
/* The most bytes of tapes (trace.h: gi_tap) one bake's bounces keep to
 * replay a cone set's later bounces: GI_TAPE_MAX_BYTES unless
 * gi__set_tape_budget changed it (0: none, every bounce marches).
 * Process-wide, for tests and measurements; thread-safe, read at each
 * bake's start. A default bake keeps 14-57 MB (the Cornell box, the
 * city, Munich). */
#define GI_TAPE_MAX_BYTES ((size_t)256 << 20)
void gi__set_tape_budget(size_t bytes);
/* The end of bounce `it`'s gathers (plan[d]: every level's plan; E: the
 * bounce's gathers of every other voxel): gi__between_fill, then the
 * voxels it turned down gathered with their level's set for the bounce
 * (gi__bounce_wide). Adds the samples and cones marched; GI_ERR_NOMEM, or
 * GI_ERR_CANCELLED when the cascade's token fired. Shared by gi__bounce
 * and the move's re-bake. */
gi_result gi__bounce_between(struct gi_cascade *c, gi_between *const plan[], gi_faces3 *const E[], int it,
                             int threads, uint64_t *samples, uint64_t *cones, gi_error_info *err);
/* The largest ratio the bounces' geometric tail takes (gi__bounce_end): a
 * furnace of albedo 0.99 would otherwise multiply its last increment by
 * 99. The effect plan's estimate of the tail takes the same cap. */
#define GI_TAIL_RATIO_MAX 0.95
/* The end of one bounce from its gathers E (per level, per occupied voxel:
 * the bounce's increment, gi__bounce_between done): the tail's sums S
 * rolled, side light summed, the texture reshaded from the increment, or
 * from the whole side light when `last` (the caller refilters). H: the
 * last bounce's hit shares (gi__gather_voxels; GI_HIT_UNKNOWN where a
 * voxel was not gathered), or NULL: the tail's ratio is then the
 * increments' alone.
 * Shared by gi__bounce and the move's re-bake. Runs on the bake's
 * threads (c->report.quality.threads); its sums do not depend on them. */
void gi__bounce_end(struct gi_cascade *c, gi_faces3 *const E[], gi_hfaces *const H[], double S[2][3], int add_tail,
                    int last);

#endif
