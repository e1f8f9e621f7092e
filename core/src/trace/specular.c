/* specular.c: the specular cone along a view's mirror direction. */
#include <string.h>
#include "base/internal.h"
#include "scene/lights.h"
#include "trace/trace.h"

/* A mirror's cone: half a degree, the finest a voxel texture can resolve. */
#define GI_SPECULAR_MIN_HALF 0.0087f
/* Beyond 80 degrees a cone is no longer a lobe: the widest half-angle. */
#define GI_SPECULAR_MAX_HALF 1.396f
/* Below this Beckmann alpha the surface is a mirror. */
#define GI_SPECULAR_MIRROR_ALPHA 1e-4f

float gi__specular_tan(float roughness) {
  float r = fminf(fmaxf(roughness, 0.f), 1.f);
  float a = r * r;
  float half;
  if (a < GI_SPECULAR_MIRROR_ALPHA) {
    half = GI_SPECULAR_MIN_HALF;
  } else {
    double ns = 2.0 / ((double)a * a) - 2.0;
    half = ns > 0 ? (float)acos(pow(0.5, 1.0 / ns)) : 0.5f * GI_PI_F;
    half = fmaxf(half, GI_SPECULAR_MIN_HALF);
  }
  return tanf(fminf(half, GI_SPECULAR_MAX_HALF));
}

void gi__specular_trace(const struct gi_cascade *c, const float p[3], const float n[3], const float v[3],
                        float roughness, gi_cone_out *out) {
  gi__specular_trace_tan(c, p, n, v, gi__specular_tan(roughness), out);
}

void gi__specular_trace_tan(const struct gi_cascade *c, const float p[3], const float n[3], const float v[3],
                            float tan_half, gi_cone_out *out) {
  float d = gi__dot(v, n);
  float r[3];
  for (int k = 0; k < 3; k++) r[k] = v[k] - 2 * d * n[k];
  float len = gi__len(r);
  for (int k = 0; k < 3; k++) r[k] /= len;
  /* The gather's surface rule, as the diffuse cones. */
  gi_gather_start g;
  gi__gather_start(c, p, n, GI_GATHER_SURFACE, -1, &g);
  gi__gather_cone(c, &g, r, tan_half, out);
  /* What the cone did not meet is sky: nothing else lights a reflection of
   * it (diffuse cones leave the sky to the shadow rays, a mirror cannot). */
  if (c->report.effects[GI_FX_SKY].ran && out->alpha < GI_OPAQUE_ALPHA) {
    float sky[3];
    gi__sky_radiance(c->scene, sky);
    for (int k = 0; k < 3; k++) out->L[k] += (1 - out->alpha) * sky[k];
  }
}
