/* trace.h: cone tracing over the cascaded texture (trace/cones.c,
 * trace/march.c, trace/specular.c). Reads a finished cascade only:
 * thread-safe. */
#ifndef GI_TRACE_H
#define GI_TRACE_H

#include "cascade/cascade_internal.h"

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
/* Finest level whose window (minus one voxel) contains p; -1 when none. */
int gi__finest_level_at(const struct gi_cascade *c, const float p[3]);

#endif
