/* cascade_internal.h: the cascaded voxel texture's layout, shared by the
 * stages that fill it (voxelize.c, inject.c, trace.c, bake.c).
 *
 * Level d has R^3 voxels of size s_d = s0 * 2^d. Voxel positions are global
 * integer cells of that level, counted from the scene's local origin; a
 * level's window is cells [cell0, cell0 + R) per axis, with cell0 even so
 * that levels nest on coarse cell borders. Storage is toroidal: cell c lives
 * at slot (c mod R), so re-centring a level later moves no memory.
 *
 * Radiance model (DESIGN section 3). Surfaces are two-sided: each voxel has
 * one orientation n (area-weighted, sign-canonical) and a reflected
 * radiance for its +n side and its -n side. Per axis the voxel stores the
 * projected surface area as an opacity alpha and as an optical depth
 * tau = -ln(1 - alpha); tau interpolates linearly without thinning walls,
 * which alpha would. Per face it stores premultiplied radiance: the
 * radiance leaving through that face times the face's covered fraction.
 * The texture holds reflected light only; emitters reach everything as
 * area lights sampled with shadow rays, so nothing counts them twice. */
#ifndef GI_CASCADE_INTERNAL_H
#define GI_CASCADE_INTERNAL_H

#include <math.h>
#include <stdint.h>
#include "gi/gi_bake.h"
#include "scene_internal.h"

/* Face order: +X, -X, +Y, -Y, +Z, -Z (face f: axis f/2, sign + when f even). */
enum { GI_FACE_PX, GI_FACE_NX, GI_FACE_PY, GI_FACE_NY, GI_FACE_PZ, GI_FACE_NZ };

/* Geometry buffer of one voxel (sums while voxelizing, then normalised). */
typedef struct gi_vgeo {
  float area;          /* surface area inside the voxel */
  float albedo[3];     /* area-weighted mean */
  float emission[3];   /* area-weighted mean emitted radiance */
  float normal[3];     /* unit, sign-canonical (two-sided surfaces) */
  float centroid[3];   /* area-weighted centroid, local coordinates */
  float proj[3];       /* projected area per axis, |A_axis| summed */
  float gloss;         /* area-weighted specular reflectance of glossy materials */
} gi_vgeo;

/* Light buffer of one voxel: what cones sample. */
typedef struct gi_vrad {
  float p[6][3];       /* premultiplied radiance leaving through each face */
  float tau[3];        /* optical depth across the voxel along each axis */
  float alpha[3];      /* opacity along each axis, 1 - exp(-tau) */
} gi_vrad;

typedef struct gi_level {
  double s;            /* voxel size */
  int64_t cell0[3];    /* first cell of the window */
  int slot0[3];        /* its toroidal slot per axis, cell0 mod R (saves a 64-bit division per sample) */
  float lo[3], hi[3];  /* window box, local coordinates */
  int has_inner;       /* 1 when level d-1 nests inside (cells filtered from it) */
  int64_t inner0[3], inner1[3]; /* this level's cells covered by level d-1: [inner0, inner1) */
  gi_vgeo *geo;        /* R^3, toroidal */
  gi_vrad *rad;        /* R^3, toroidal */
  float (*side)[2][3]; /* R^3: direct+indirect irradiance on the +n and -n sides */
  float (*direct)[2][3]; /* R^3: the direct part of side */
  uint8_t *busy;       /* per slot: 1 when the 2x2x2 block starting there has any opacity */
  uint32_t *occ;       /* slots of occupied voxels outside the inner region */
  uint32_t num_occ;
  uint64_t num_geo;    /* voxels holding geometry (incl. the inner region) */
} gi_level;

struct gi_cascade {
  gi_scene *scene;     /* retained */
  int n, R;
  double s0;
  double at_world[3];
  float at[3];         /* viewpoint, local */
  gi_level lv[GI_MAX_LEVELS];
  gi_bake_report report;
  /* Diffuse cone set around +Z, shared by bounce and gather. */
  int num_cones;
  float cone_dir[64][3];
  float cone_weight[64]; /* integral of cos over the cone's region; sums to pi */
  float cone_tan;        /* tan(aperture / 2) */
};

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

/* cascade.c */
gi_result gi__cascade_alloc(struct gi_cascade *c, gi_error_info *err);
void gi__cascade_place(struct gi_cascade *c);
/* Filters the region of level d covered by level d-1 from level d-1's light
 * (compositing along each axis) and geometry. */
void gi__cascade_filter(struct gi_cascade *c, int threads);
/* Rebuilds every level's busy mask from its opacity (after filtering). */
void gi__cascade_mark_busy(struct gi_cascade *c);
/* 1 when the local point lies in level d's window shrunk by `border` voxels. */
int gi__level_contains(const gi_level *L, const float p[3], float border);
/* 1 when cell (i,j,k) of level L is covered by the finer level. */
int gi__is_inner(const gi_level *L, int64_t i, int64_t j, int64_t k);

/* voxelize.c */
gi_result gi__voxelize(struct gi_cascade *c, int threads, gi_error_info *err);

/* inject.c: direct light into every occupied voxel (both sides). */
gi_result gi__inject(struct gi_cascade *c, const gi_quality *q, gi_error_info *err);
/* Recomputes each occupied voxel's face radiance from its side irradiance. */
void gi__shade_voxels(struct gi_cascade *c, int d, uint32_t begin, uint32_t end);
/* One light sample seen from a point: direction w (unit, local), distance
 * to the light (INFINITY for sun and sky) and V, such that a surface with
 * unit normal m receives irradiance V * max(0, m.w) from it when visible.
 * Solid-angle and pdf weights are folded into V. */
typedef struct gi_lsample {
  float w[3];
  float dist;
  float V[3];
  float mpl;           /* emitters: sample count times solid-angle pdf, for MIS; else 0 */
  uint8_t fx;          /* gi_effect_id of the light kind */
} gi_lsample;
/* Solid-angle pdf (times the light-sample count m) of reaching emissive
 * triangle tri along a ray of length t meeting it at cosine cos_e. */
float gi__emitter_mpl(const gi_scene *s, uint32_t tri, float t, float cos_e, int m);
/* MIS companion of emitter light sampling: traces o + t w (t > tnear); when
 * it meets an emitter's front, out = Le / (mpl + pb) with mpl the light
 * strategy's pdf for that point (m_light samples) and pb the caller's own
 * pdf times its sample count. Returns 0 (out untouched) otherwise. */
int gi__emitter_ray(const gi_scene *s, const float o[3], const float w[3], float tnear, int m_light,
                    float pb, float out[3]);
/* Which light kinds to sample, and how many rays for sky and emitters. */
typedef struct gi_light_plan {
  int sun, local, sky, emissive;
  int sky_samples, emit_samples;
} gi_light_plan;
/* The light kinds the effect plan of report r enabled, with `samples` rays
 * for sky and emitters. */
gi_light_plan gi__light_plan(const gi_bake_report *r, int samples);
/* Per-thread buffers for one batch of light samples and their shadow rays. */
typedef struct gi_ray_scratch {
  int cap;
  gi_lsample *ls;
  float *org, *dir, *tn, *tf;  /* 3, 3, 1, 1 floats per ray */
  uint8_t *vis;
} gi_ray_scratch;
/* Allocates cap of each; 0 on success, -1 (everything freed) when out of memory. */
int gi__scratch_alloc(gi_ray_scratch *sc, int cap);
void gi__scratch_free(gi_ray_scratch *sc);
/* Fills out (capacity max) with samples for point p; returns the count. */
int gi__light_samples(const gi_scene *s, const gi_light_plan *lp, const float p[3], uint64_t *rng,
                      gi_lsample *out, int max);
/* bake.c: the request's override for one effect, GI_FX_ON, GI_FX_OFF or
 * GI_FX_AUTO (the legacy `specular` and `ao` fields count when effects[id]
 * is auto). Shared by the bake's plan and the camera view's. */
int gi__fx_forced(const gi_quality *q, gi_effect_id id);
/* The sum of the scene's sky radiances: what a ray that escapes sees. */
void gi__sky_radiance(const gi_scene *s, float out[3]);
/* Voxel-to-voxel bounces: gathers indirect irradiance at every occupied voxel.
 * tail (with bounces >= 2): then adds the orders after the last bounce as
 * a geometric series whose ratio is measured from the last two bounces. */
gi_result gi__bounce(struct gi_cascade *c, const gi_quality *q, int bounces, int tail, gi_error_info *err);

/* trace.c */
void gi__cone_set(int count, float aperture_deg, float dirs[][3], float weights[], float *tan_half);
typedef struct gi_cone_out {
  float L[3];          /* radiance arriving along the cone */
  float alpha;         /* accumulated opacity */
  float occlusion;     /* AO-weighted occlusion */
  uint32_t samples;
} gi_cone_out;
void gi__cone_trace(const struct gi_cascade *c, const float p[3], const float w[3], float tan_half,
                    float t0, float step, float ao_lambda, gi_cone_out *out);
/* The same from a point h0 above a surface of unit normal n (w.n > 0):
 * levels coarse enough for their footprint to reach back to the surface
 * are not sampled there (keeps light from leaking through walls thinner
 * than a voxel; see trace.c), and where the window forces one, it is read
 * across the normal only. */
#define GI_SURFACE_LOD_K 3.0f
void gi__cone_trace_surface(const struct gi_cascade *c, const float p[3], const float w[3], float tan_half,
                            float t0, float step, float ao_lambda, float h0, const float n[3], gi_cone_out *out);
/* Half-angle tangent of the specular cone for a roughness in [0,1]: the
 * half-width at half maximum of the Phong lobe equivalent to Beckmann
 * alpha = roughness^2 (exponent 2 / alpha^2 - 2), at least 0.5 degree. */
float gi__specular_tan(float roughness);
/* Radiance arriving along the mirror direction of view v (unit, pointing
 * from the eye to p) about unit normal n, through one cone. */
void gi__specular_trace(const struct gi_cascade *c, const float p[3], const float n[3], const float v[3],
                        float roughness, gi_cone_out *out);
/* The same with the cone's half-angle tangent given (aperture sweeps in tests). */
void gi__specular_trace_tan(const struct gi_cascade *c, const float p[3], const float n[3], const float v[3],
                            float tan_half, gi_cone_out *out);
/* Samples the texture at local p for direction w (the faces facing -w),
 * trilinearly on level d: premultiplied radiance and optical depth per unit length. */
int gi__sample_level(const struct gi_cascade *c, int d, const float p[3], const float w[3],
                     float prem[3], float *wsum_alpha, float *sigma);
/* Orthonormal basis with n as the third axis. */
void gi__basis(const float n[3], float t[3], float b[3]);
/* Finest level whose window (minus one voxel) contains p; -1 when none. */
int gi__finest_level_at(const struct gi_cascade *c, const float p[3]);

/* render.c: a camera set up in the scene's local frame, shared by the
 * cone-traced and the path-traced views. */
struct gi_camera;
typedef struct gi__cam {
  float eye[3], fwd[3], right[3], upv[3];
  float tanx, tany;    /* half-extent of the image plane at distance 1 */
  int w, h;
} gi__cam;
gi_result gi__cam_setup(const gi_scene *s, const struct gi_camera *cam, gi__cam *k, gi_error_info *err);
/* Unit direction through image position (px, py), in pixels from the top-left. */
void gi__cam_ray(const gi__cam *k, float px, float py, float dir[3]);

/* sh.c */
void gi__sh_basis(const float w[3], float y[9]);
void gi__sh_add(float sh[9][3], const float w[3], const float L[3], float weight);
void gi__sh_radiance_to_irradiance(float sh[9][3]);

/* inject.c: deterministic hash-based random numbers. */
static inline uint64_t gi__mix64(uint64_t x) {
  x ^= x >> 30; x *= 0xbf58476d1ce4e5b9ULL;
  x ^= x >> 27; x *= 0x94d049bb133111ebULL;
  x ^= x >> 31;
  return x;
}
static inline float gi__u01(uint64_t *state) {
  *state += 0x9e3779b97f4a7c15ULL;
  return (float)(gi__mix64(*state) >> 40) * (1.0f / 16777216.0f);
}

static inline float gi__dot(const float a[3], const float b[3]) { return a[0]*b[0] + a[1]*b[1] + a[2]*b[2]; }
static inline void gi__cross(const float a[3], const float b[3], float o[3]) {
  o[0] = a[1]*b[2] - a[2]*b[1]; o[1] = a[2]*b[0] - a[0]*b[2]; o[2] = a[0]*b[1] - a[1]*b[0];
}
static inline float gi__len(const float a[3]) { return sqrtf(gi__dot(a, a)); }
static inline float gi__lum(const float c[3]) { return 0.2126f*c[0] + 0.7152f*c[1] + 0.0722f*c[2]; }

#endif
