/* cascade_internal.h: the cascaded voxel texture's layout, shared by the
 * stages that fill it (cascade/, light/) and read it (trace/, answer/).
 *
 * Level d has R^3 voxels of size s_d = s0 * 2^d. Voxel positions are global
 * integer cells of that level, counted from the scene's local origin; a
 * level's window is cells [cell0, cell0 + R) per axis, with cell0 even so
 * that levels nest on coarse cell borders. Storage is toroidal: cell c lives
 * at slot (c mod R), so re-centring a level later moves no memory.
 *
 * Radiance model (DESIGN section 3). Surfaces are two-sided. What a voxel
 * shows through its +a and -a faces is the surface seen along axis a: its
 * orientation is N_a = M e_a, M = sum of area n n^T over the voxel's
 * pieces (n and -n count alike). A floor meeting a wall shows the wall
 * through the x faces and the floor through the y faces, where one mean
 * normal would tilt both by 45 degrees; a coarse voxel holding a closed
 * building shows each facade on its own side instead of the mean of its
 * lit walls and dark interior. Axes whose orientations agree share a
 * group; each side of each group gathers its own light, and each face
 * reflects the irradiance of the side it shows. Per axis the voxel stores the
 * projected surface area as an opacity alpha and as an optical depth
 * tau = -ln(1 - alpha); tau interpolates linearly without thinning walls,
 * which alpha would. Per face it stores premultiplied radiance: the
 * radiance leaving through that face times the face's covered fraction.
 * The texture holds reflected light only; emitters reach everything as
 * area lights sampled with shadow rays, so nothing counts them twice. */
#ifndef GI_CASCADE_INTERNAL_H
#define GI_CASCADE_INTERNAL_H

#include "gi/gi_cancel.h"
#include <math.h>
#include <stdint.h>
#include "gi/gi_bake.h"
#include "base/half.h"
#include "base/internal.h"
#include "scene/scene_internal.h"

/* The largest gi_quality.res (voxels per side) a cascade takes. */
#define GI_MAX_RES 256

/* A voxel's opacity along an axis stays below 1 (its optical depth finite,
 * tau = -ln(1 - alpha) <= 6.9), so a voxel covered twice over still
 * interpolates; the filter keeps a coarse voxel's transmittance above
 * GI_MIN_TRANSMITTANCE (tau <= 9.2) for the same reason. */
#define GI_MAX_VOXEL_ALPHA 0.999
#define GI_MIN_TRANSMITTANCE 1e-4

/* Face order: +X, -X, +Y, -Y, +Z, -Z (face f: axis f/2, sign + when f even). */
enum { GI_FACE_PX, GI_FACE_NX, GI_FACE_PY, GI_FACE_NY, GI_FACE_PZ, GI_FACE_NZ };

/* Orientation groups per voxel (one per axis at most) and faces. */
#define GI_VOX_GROUPS 3
#define GI_VOX_FACES 6
/* Irradiance per face: what the surface shown through face f receives on
 * its side facing out of f (faces showing the same side hold the same value). */
typedef float gi_faces3[GI_VOX_FACES][3];
/* A bounce's hit shares per face (gi__bounce_end), in steps of
 * 1/GI_HIT_STEPS; GI_HIT_UNKNOWN: the voxel was not gathered. A byte each:
 * a moving cascade keeps them per voxel, inside a session's budget. */
typedef uint8_t gi_hfaces[GI_VOX_FACES];
#define GI_HIT_STEPS 254
#define GI_HIT_UNKNOWN 255

/* Geometry buffer of one voxel (sums while voxelizing, then normalised). */
typedef struct gi_vgeo {
  float area;          /* surface area inside the voxel */
  float albedo[3];     /* area-weighted mean */
  float emission[3];   /* area-weighted mean emitted radiance */
  float normal[3];     /* the largest group's orientation (inspection, export) */
  float centroid[3];   /* area-weighted centroid, local coordinates */
  float proj[3];       /* projected area per axis, |A_axis| summed */
  float gloss[3];      /* area-weighted specular reflectance of glossy materials, per channel */
  union {
    struct {           /* while voxelizing (gi__voxel_add_tri) */
      float tensor[6];   /* sum of area n n^T: xx, yy, zz, xy, xz, yz */
      float acen[3][3];  /* per axis, sum of |A_axis| x piece centroid */
      float apos[3];     /* per axis, sum of A_axis over the pieces with A_axis > 0 */
      float afront[3][2]; /* per axis, the front-most centroid of the pieces facing
                             mostly along it, A_axis > 0 and < 0 apart: s + the
                             coordinate from the cell's low corner (> 0, the
                             largest) or 2 s - it (< 0, the smallest); 0 when
                             none (see side_offsets) */
    } sum;
    struct {           /* after gi__voxel_finalize */
      float orient[GI_VOX_GROUPS][3]; /* unit, orient[g] . e_a >= 0 for its first axis */
      float gcen[GI_VOX_GROUPS][3];   /* centroid of the surfaces seen through the group's axes */
      /* Per side 2 g + s, where the pieces whose normal faces that side
       * lie: gcen[g] + soff[2 g + s] orient[g] (gi__side_centroid). A
       * thin closed solid inside one voxel (a slab, a wall) has its two
       * faces on opposite sides; light and cones start from each face,
       * not from the middle, which lies inside the solid. */
      float soff[2 * GI_VOX_GROUPS];
    } fin;
  } u;
  uint8_t groups;      /* 1..GI_VOX_GROUPS when occupied */
  /* Face f shows side face_side[f] = 2 g + s of group g (s = 0: the side
   * +orient[g] faces, 1: the -orient[g] side). */
  uint8_t face_side[GI_VOX_FACES];
  /* Bit f: face f shows the brighter of its group's two sides instead
   * (gi__face_light). Set on the minor axes of a group whose pieces all
   * face one way: a single sheet at an angle to the grid (a facade of a
   * closed building, a room's wall). Its face along a minor axis is read
   * by viewers on either side of the sheet alike, so the sign of that
   * axis cannot say which side they see; the sheet's back is the inside
   * of its solid, dark, and showing it there darkened oblique facades by
   * up to a quarter (a street canyon turned 20 degrees read 0.785 of the
   * reference, 0.968 unturned). */
  uint8_t brighter;
} gi_vgeo;

/* The side of group g (orientation o) that face f shows: the one whose
 * normal points out of f (either, on a face along which o has no
 * component). Shared by voxelize.c and filter.c. */
static inline uint8_t gi__face_side(const float o[3], int g, int f) {
  float sf = (f & 1) ? -1.f : 1.f;
  return (uint8_t)(2 * g + (sf * o[f / 2] >= 0 ? 0 : 1));
}

/* Where side sd (2 g + s) of a finalized voxel's group g starts its shadow rays and cones. */
static inline void gi__side_centroid(const gi_vgeo *g, int sd, float out[3]) {
  for (int k = 0; k < 3; k++) out[k] = g->u.fin.gcen[sd / 2][k] + g->u.fin.soff[sd] * g->u.fin.orient[sd / 2][k];
}

/* The side face f reflects, given each side's irradiance Es (2 g + s). */
static inline int gi__face_side_of(const gi_vgeo *g, const float Es[][3], int f) {
  int sd = g->face_side[f];
  if (g->brighter >> f & 1) {
    int o = sd ^ 1;
    if (Es[o][0] + Es[o][1] + Es[o][2] > Es[sd][0] + Es[sd][1] + Es[sd][2]) sd = o;
  }
  return sd;
}

/* The irradiance each face reflects, from each side's Es (2 g + s). */
static inline void gi__face_light(const gi_vgeo *g, const float Es[][3], float E[GI_VOX_FACES][3]) {
  for (int f = 0; f < GI_VOX_FACES; f++) {
    int sd = gi__face_side_of(g, Es, f);
    for (int k = 0; k < 3; k++) E[f][k] = Es[sd][k];
  }
}

/* Light buffer of one voxel: what cones sample. 48 bytes, 24 half floats
 * (IEEE binary16), the lanes a trilinear sample sums at once:
 *   lanes 3f+k (f < 6, k < 3): radiance of channel k leaving through face f
 *     (f = 2 axis for the +axis face, 2 axis + 1 for -axis), premultiplied
 *     by the face's opacity and divided by the cascade's rad_scale;
 *   lanes GI_VRAD_ALPHA + a: opacity along axis a, 1 - exp(-tau);
 *   lanes GI_VRAD_TAU + a: optical depth across the voxel along axis a.
 * Half of v0.1's 96-byte float record: two fit in three cache lines. The
 * march reads texels directly; every other stage goes through
 * gi__vrad_unpack / gi__vrad_pack (cascade/texel.c). */
#define GI_VRAD_ALPHA 18
#define GI_VRAD_TAU 21
#define GI_VRAD_LANES 24
typedef struct gi_vrad {
  uint16_t h[GI_VRAD_LANES];
} gi_vrad;

/* A texel in float, radiance in true units: the lanes in the same order. */
typedef struct gi_vrad_f {
  float p[6][3];
  float alpha[3];
  float tau[3];
} gi_vrad_f;

/* Per side 2 g + s of an occupied voxel: how far its gathers' apex moves
 * off the surfaces beside it (light/bounce.c, away_from_beside). It
 * depends on the voxel's geometry alone: a bake's first bounce finds it
 * for its later ones, and a moving cascade keeps it with each entry (a
 * move regathers a voxel many times, and recasting its rays took a sixth
 * of Munich's walk). */
typedef struct gi_shift6 {
  float v[GI_VOX_FACES][3]; /* in a level's shift array, v[0][0] NaN: not found yet */
} gi_shift6;

typedef struct gi_level {
  double s;            /* voxel size */
  int64_t cell0[3];    /* first cell of the window */
  int slot0[3];        /* its toroidal slot per axis, cell0 mod R (saves a 64-bit division per sample) */
  float lo[3], hi[3];  /* window box, local coordinates */
  int has_inner;       /* 1 when level d-1 nests inside (cells filtered from it) */
  int64_t inner0[3], inner1[3]; /* this level's cells covered by level d-1: [inner0, inner1) */
  gi_vrad *rad;        /* R^3, toroidal */
  /* Geometry and light of the voxels that hold a surface, in entries:
   * slot s's are entry vix[s] of geo, side and direct (gi__geo, gi__side,
   * gi__direct). Entry 0 is all zeros and never written, so an empty
   * slot reads as empty; vix[s] != 0 exactly when the voxel holds
   * geometry (area > 0). A few percent of a level's voxels hold a
   * surface: dense arrays cost 5x the memory, and first touches of their
   * pages took a quarter of a Cornell box bake. The arrays are the
   * level's own allocations (gi__level_reserve); the move's re-bake
   * keeps a side array of the same capacity and swaps it with this one. */
  uint32_t *vix;       /* R^3 */
  gi_vgeo *geo;        /* cap entries */
  gi_faces3 *side;     /* cap entries: direct+indirect irradiance per face (see gi_faces3) */
  gi_faces3 *direct;   /* cap entries: the direct part of side */
  gi_shift6 *shift;    /* cap entries once the cascade moves (move.c, shift_alloc), else NULL:
                          the gathers' apex shift (gi_shift6), kept across moves */
  uint32_t cap;        /* entries allocated (entry 0 included) */
  uint32_t used;       /* entries handed out so far, entry 0 included: [used, cap) are fresh */
  uint32_t *freed;     /* cap: entries given back (a move's cells that left), reused first */
  uint32_t num_freed;
  uint8_t *busy;       /* per slot: 1 when the 2x2x2 block starting there has any opacity */
  /* Per GI_EMPTY_BLOCK^3 block of the window's cells (window coordinates,
   * not slots: rebuilt with busy): 1 when a sample whose trilinear base
   * cell lies in the block may read opacity, so a cone may cross an empty
   * block in one step where busy would take one step per cell. */
  uint8_t *busy4;
  uint32_t *occ;       /* slots of occupied voxels outside the inner region */
  uint32_t num_occ;
  uint64_t num_geo;    /* voxels holding geometry (incl. the inner region) */
} gi_level;

/* Cells per side of a busy4 block (R is a multiple of 4). */
#define GI_EMPTY_BLOCK 4 /* march_simd.c divides by it with a shift */
static inline int gi__busy4_side(int R) { return (R + GI_EMPTY_BLOCK - 1) / GI_EMPTY_BLOCK; }

/* Room in the cascade for the largest diffuse cone set (trace/cones.c: 32). */
#define GI_MAX_CONES 64

struct gi_cascade {
  gi_scene *scene;     /* retained */
  int n, R;
  double s0;
  double at_world[3];
  float at[3];         /* viewpoint, local */
  gi_level lv[GI_MAX_LEVELS];
  /* The one block every level's arrays lie in (gi__cascade_alloc). The
   * move swaps rad and side with its re-bake's block, so those pointers
   * may point into either block: both are freed together, never an array
   * on its own. */
  void *block;
  size_t block_bytes;
  gi_bake_report report;
  /* Diffuse cone set around +Z, shared by bounce and gather. */
  int num_cones;
  float cone_dir[GI_MAX_CONES][3];
  float cone_weight[GI_MAX_CONES]; /* integral of cos over the cone's region; sums to pi */
  float cone_tan;        /* tan(aperture / 2) */
  /* The bounces' wider, smaller set for the later orders (gi__wide_cone_set). */
  int num_wide_cones;
  float wide_dir[GI_MAX_CONES][3];
  float wide_weight[GI_MAX_CONES];
  float wide_tan;
  /* Levels from this one up take the wide set from the first bounce on
   * (the effect plan's, plan.c; n: none). */
  int wide_level;
  /* The probes' denser final-gather set (gi__probe_cone_set). */
  int num_probe_cones;
  float probe_dir[GI_MAX_CONES][3];
  float probe_weight[GI_MAX_CONES];
  float probe_tan;
  const gi_cancel *cancel; /* the bake's token while it runs (may be NULL); NULL after */
  /* Radiance lanes of every texel hold value / rad_scale, set by
   * gi__vrad_rescale so the brightest texel stays far from half's largest
   * value (a 1e6-bright light stays finite) and dim light keeps half's 11
   * bits. 1 until the first shading. */
  float rad_scale;
  /* What the move (move/move.c) needs to re-plan and re-bounce exactly as
   * a bake at its anchor would: the quality before the effect plan, whether
   * the request left the bounce count automatic, and the moves so far
   * (the refresh schedule's clock). */
  gi_quality plan_q;
  int auto_bounces;
  int tail;            /* the plan's bounce tail (gi__bounce) */
  /* Per channel, the share of the voxels' indirect light (side - direct,
   * area-weighted, with the tail) that the last bounce's increment D_k
   * added, and the tail's gain on it (the tail added tail_gain x D_k; 0
   * without a tail): a move's fresh gather takes (1 + tail_gain) x D_k off
   * to read the bake's orders, and puts the tail back (move.c). 0 after
   * no bounce. */
  float last_share[3], tail_gain[3];
  uint64_t moves;
  /* GI_TORN_MOVING while a move runs, GI_TORN_LEFT after one that failed
   * or was cancelled part way: the cascade is partial (gi_move.h) and every
   * call refuses it (gi__cascade_whole) rather than answer with wrong light,
   * except a move after a failed one, which bakes it afresh (move.c). */
  int torn;
  /* The bake's request (req_default: it was NULL), which such a re-bake
   * repeats so the cascade equals a cold bake made as this one was. */
  gi_quality req_q;
  int req_default;
  /* The effect plan's survey of what lies in the coarsest level's range
   * (plan.c), kept while that level's box stays: a move that scrolls only
   * finer levels does not query every triangle in range again (millions
   * on a large city). */
  struct {
    int valid;
    float lo[3], hi[3];
    uint32_t emit_in;
    /* Per level: its box, the area and albedo-weighted area of the
     * surfaces clipped to it, and its glossy triangles (plan.c's level_sums). */
    struct {
      int valid;
      float lo[3], hi[3];
      double area, a_sum;
      uint32_t glossy;
    } lvl[GI_MAX_LEVELS];
  } survey;
  /* The move's re-bake in slices (move/move.c); NULL until the first move. */
  struct gi_move_state *move_state;
  /* Points the answers will be gathered at, besides the viewpoint, during
   * gi__cascade_bake_at only (the caller's array; NULL otherwise): 6 floats
   * each, a surface point and its normal (0 for a point in space), local.
   * The plan tests the sky from both sides of each too (plan.c). */
  const float *answer_pts;
  int num_answer_pts;
};

/* gi_cascade_bake_ex for answers gathered at pts (see answer_pts). */
gi_result gi__cascade_bake_at(const struct gi_scene *scene, const double at[3], const gi_quality *q,
                              const gi_cancel *cancel, const float *pts, int npts, gi_cascade **out,
                              gi_bake_report *report, gi_error_info *err);

static inline int64_t gi__floordiv(int64_t a, int64_t b) {
  int64_t q = a / b;
  return (a % b != 0 && ((a < 0) != (b < 0))) ? q - 1 : q;
}
static inline int gi__wrap(int64_t c, int R) {
  int64_t m = c % R;
  return (int)(m < 0 ? m + R : m);
}
/* Slot of global cell (i,j,k) in a level of R^3. */
static inline uint32_t gi__slot(int64_t i, int64_t j, int64_t k, int R) {
  return (uint32_t)gi__wrap(i, R) + (uint32_t)R * ((uint32_t)gi__wrap(j, R) + (uint32_t)R * (uint32_t)gi__wrap(k, R));
}

/* Global cell of a slot in level L's current window. */
static inline void gi__slot_cell(const gi_level *L, int R, uint32_t slot, int64_t cell[3]) {
  uint32_t w[3] = {slot % (uint32_t)R, (slot / (uint32_t)R) % (uint32_t)R, slot / ((uint32_t)R * (uint32_t)R)};
  for (int a = 0; a < 3; a++) cell[a] = L->cell0[a] + gi__wrap((int64_t)w[a] - gi__wrap(L->cell0[a], R), R);
}

/* A slot's geometry, light and direct light (entry 0, all zeros, when it holds none). */
static inline gi_vgeo *gi__geo(const gi_level *L, uint32_t slot) { return &L->geo[L->vix[slot]]; }
static inline float (*gi__side(const gi_level *L, uint32_t slot))[3] { return L->side[L->vix[slot]]; }
static inline float (*gi__direct(const gi_level *L, uint32_t slot))[3] { return L->direct[L->vix[slot]]; }

/* cascade.c: the entries. gi__level_reserve grows level d's arrays to hold
 * `entries` (entry 0 included; with `slack`, a quarter more for the next
 * moves), keeping what they hold; serial, and never while the move has
 * swapped its texture in (the move grows its own side array to match).
 * gi__level_take gives slot a zeroed entry (room reserved; the slot must
 * have none); gi__level_release gives it back (a slot without one is
 * fine). Neither is thread-safe. gi__level_claim is gi__level_take
 * without the zeroing: it returns the entry, which gi__level_clear (or
 * the caller) must fill before anything reads it; gi__level_clear of
 * distinct entries may run on several threads at once. */
gi_result gi__level_reserve(struct gi_cascade *c, int d, uint32_t entries, int slack, gi_error_info *err);
uint32_t gi__level_free_entries(const gi_level *L);
void gi__level_take(gi_level *L, uint32_t slot);
uint32_t gi__level_claim(gi_level *L, uint32_t slot);
void gi__level_clear(gi_level *L, uint32_t e);
void gi__level_release(gi_level *L, uint32_t slot);
/* Bytes of one entry across geo, side, direct and freed (a moving
 * cascade's shift is the move's: gi__move_state_bytes). */
#define GI_ENTRY_BYTES (sizeof(gi_vgeo) + 2 * sizeof(gi_faces3) + sizeof(uint32_t))
/* Bytes per slot of the dense arrays: rad, vix, occ, busy. */
#define GI_SLOT_BYTES (sizeof(gi_vrad) + 2 * sizeof(uint32_t) + sizeof(uint8_t))
/* The levels' entries' bytes (allocated capacity). */
size_t gi__entries_bytes(const struct gi_cascade *c);

/* cascade.c: allocates every level's dense arrays, zeroed, in one block (c->n, c->R set). */
gi_result gi__cascade_alloc(struct gi_cascade *c, gi_error_info *err);
/* Frees that block and clears the level pointers (a cascade never allocated is fine). */
void gi__cascade_free_levels(struct gi_cascade *c);
/* Frees a cascade that holds no move state (a bake's, or one whose move
 * state was freed): its levels, its scene reference and itself. */
void gi__cascade_discard(struct gi_cascade *c);
void gi__cascade_place(struct gi_cascade *c);
/* gi_cascade.torn */
enum { GI_TORN_MOVING = 1, GI_TORN_LEFT = 2 };
/* GI_OK, or GI_ERR_INVALID_ARG naming `what` when c is torn (a move failed
 * or was cancelled part way: gi_move.h says to move it again or free it). */
gi_result gi__cascade_whole(const struct gi_cascade *c, const char *what, gi_error_info *err);
/* filter.c: filters the region of level d covered by level d-1 from level d-1's light
 * (compositing along each axis) and geometry. */
/* Returns nonzero when c->cancel stopped it (the regions are then partial). */
int gi__cascade_filter(struct gi_cascade *c, int threads);
/* Filters only the nested cells of level d (>= 1) inside its global cells
 * [lo, hi): a move whose finer level changed there. Nonzero when cancelled. */
int gi__cascade_filter_box(struct gi_cascade *c, int threads, int d, const int64_t lo[3], const int64_t hi[3]);
/* Rebuilds every level's busy and busy4 masks from its opacity (after
 * filtering), on the bake's threads (c->report.quality.threads). */
void gi__cascade_mark_busy(struct gi_cascade *c);
/* report.occupied[d]: voxels holding geometry per level, the filtered region included. */
void gi__cascade_count_occupied(struct gi_cascade *c);
/* 1 when the local point lies in level d's window shrunk by `border` voxels. */
int gi__level_contains(const gi_level *L, const float p[3], float border);
/* 1 when cell (i,j,k) of level L is covered by the finer level. */
int gi__is_inner(const gi_level *L, int64_t i, int64_t j, int64_t k);

/* texel.c: converting texels; rad_scale must not change between a
 * texel's pack and its unpack (gi__vrad_rescale repacks nothing). */
void gi__vrad_unpack(const struct gi_cascade *c, const gi_vrad *r, gi_vrad_f *out);
void gi__vrad_pack(const struct gi_cascade *c, const gi_vrad_f *in, gi_vrad *r);
/* Chooses rad_scale for radiance up to `brightest`; every radiance lane
 * must be rewritten afterwards (shade and filter do). */
void gi__vrad_rescale(struct gi_cascade *c, float brightest);
static inline float gi__vrad_alpha(const gi_vrad *r, int a) { return gi__h2f(r->h[GI_VRAD_ALPHA + a]); }
static inline float gi__vrad_tau(const gi_vrad *r, int a) { return gi__h2f(r->h[GI_VRAD_TAU + a]); }

/* move/move.c: frees the move's re-bake state (NULL is fine); its bytes. */
void gi__move_state_free(struct gi_move_state *m);
size_t gi__move_state_bytes(const struct gi_cascade *c);

/* What a cascade's levels hold: every level's slots and the entries of
 * its occupied voxels (all a bake holds: it has no move state yet). */
static inline size_t gi__cascade_level_bytes(const struct gi_cascade *c) {
  size_t vox = (size_t)c->R * (size_t)c->R * (size_t)c->R;
  /* No block: the levels were freed (a move's re-bake that stopped). */
  return (c->block ? (size_t)c->n * vox * GI_SLOT_BYTES : 0) + gi__entries_bytes(c);
}
/* What a cascade holds now (gi_cascade_bytes): its levels and a move's
 * re-bake state. Inline so a move can report it without calling the bake's
 * file. */
static inline size_t gi__cascade_held_bytes(const struct gi_cascade *c) {
  return gi__cascade_level_bytes(c) + gi__move_state_bytes(c);
}

/* voxelize.c: fills the geometry of a freshly allocated (zeroed) cascade. */
gi_result gi__voxelize(struct gi_cascade *c, int threads, gi_error_info *err);
/* Gives every nested cell of level d (>= 1) holding geometry below it an
 * entry and takes the others' back (after level d-1 changed);
 * gi__nested_need: how many new entries that takes. */
gi_result gi__nested_entries(struct gi_cascade *c, int d, gi_error_info *err);
uint32_t gi__nested_need(const struct gi_cascade *c, int d);
/* One triangle's piece in global cell `cell` (of size s, corner at
 * cell * s), added to the sums g. */
void gi__voxel_add_tri(gi_vgeo *g, double s, const int64_t cell[3], const float tv[3][3], const gi_material *mat);
/* Adds to A the vector area and to C the area-weighted centroid sum of the
 * planar polygon v (n vertices), by a fan from v[0]. */
static inline void gi__fan_moments(const float v[][3], int n, float A[3], float C[3]) {
  for (int i = 1; i + 1 < n; i++) {
    float e1[3], e2[3], x[3];
    for (int k = 0; k < 3; k++) {
      e1[k] = v[i][k] - v[0][k];
      e2[k] = v[i + 1][k] - v[0][k];
    }
    gi__cross(e1, e2, x);
    float a = 0.5f * gi__len(x);
    for (int k = 0; k < 3; k++) {
      A[k] += 0.5f * x[k];
      C[k] += a * (v[0][k] + v[i][k] + v[i + 1][k]) / 3.f;
    }
  }
}
/* The piece of triangle tv that global cell `cell` (size s) owns, as
 * voxelizing counts it: returns its vertex count (0: none), the vertices
 * in poly relative to the cell's corner, and the corner (local coords). */
#define GI_CLIP_MAXV 12
int gi__voxel_clip_tri(double s, const int64_t cell[3], const float tv[3][3], float poly[GI_CLIP_MAXV][3],
                       float corner[3]);
/* Normalises the sums g of the voxel in slot (global cell `cell`) and
 * writes its texel's opacity; 1 when it holds geometry (0: g and the
 * texel cleared). */
int gi__voxel_finalize(gi_level *L, gi_vgeo *g, uint32_t slot, const int64_t cell[3]);

#endif
