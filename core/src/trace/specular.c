/* specular.c: the specular cone along a view's mirror direction. */
#include <string.h>
#include "base/internal.h"
#include "scene/lights.h"
#include "trace/trace.h"

/* A mirror's cone: half a degree, the finest a voxel texture can resolve. */
#define GI_SPECULAR_MIN_HALF 0.0087f
/* Beyond 80 degrees a cone is no longer a lobe: the widest half-angle. */
#define GI_SPECULAR_MAX_HALF 1.396f
/* tan(GI_SPECULAR_MIN_HALF): a mirror's cone. */
#define GI_SPECULAR_MIN_TAN 0.00870022f

float gi__specular_tan(float roughness) {
  float r = fminf(fmaxf(roughness, 0.f), 1.f);
  float a = r * r;
  float half;
  if (a < (float)GI_MIRROR_ALPHA) {
    half = GI_SPECULAR_MIN_HALF;
  } else {
    double ns = 2.0 / ((double)a * a) - 2.0;
    half = ns > 0 ? (float)acos(pow(0.5, 1.0 / ns)) : 0.5f * GI_PI_F;
    half = fmaxf(half, GI_SPECULAR_MIN_HALF);
  }
  return tanf(fminf(half, GI_SPECULAR_MAX_HALF));
}

void gi__specular_trace(const struct gi_cascade *c, const float p[3], const float n[3], const float v[3],
                        float roughness, uint64_t seed, gi_cone_out *out) {
  gi__specular_trace_tan(c, p, n, v, gi__specular_tan(roughness), seed, out);
}

/* Rays for the emitters a lobe reflects (one for a mirror's cone). */
#define GI_SPEC_EMIT_RAYS 16

/* The emitters seen within the cone (axis r, half-angle tangent tan_half)
 * from p on the side of n: their mean radiance over the cone's solid
 * angle, as the cone averages the voxels' light over its footprint. The
 * texture holds no emission (emitters reach the voxels as light samples),
 * so without this a glossy floor under a lamp showed 0.02 of its 4.7
 * (a helper's probe against the path tracer). Stratified in the cone's
 * solid angle, rotated by seed. */
static void specular_emitters(const struct gi_cascade *c, const float p[3], const float n[3], const float r[3],
                              float tan_half, uint64_t seed, float L[3]) {
  const gi_scene *s = c->scene;
  float cmax = 1.f / sqrtf(1 + tan_half * tan_half), t[3], b[3];
  int m = tan_half <= GI_SPECULAR_MIN_TAN ? 1 : GI_SPEC_EMIT_RAYS;
  gi__basis(r, t, b);
  float o[GI_SPEC_EMIT_RAYS][3], w[GI_SPEC_EMIT_RAYS][3], tn[GI_SPEC_EMIT_RAYS], th[GI_SPEC_EMIT_RAYS];
  uint32_t tri[GI_SPEC_EMIT_RAYS];
  uint8_t hit[GI_SPEC_EMIT_RAYS], vis[GI_SPEC_EMIT_RAYS];
  uint64_t rng = gi__mix64(seed ^ 0x5bec7ull);
  float lift = 1e-3f * (float)c->s0, phi0 = 2 * GI_PI_F * gi__u01(&rng);
  for (int i = 0; i < m; i++) {
    float ct = m == 1 ? 1.f : 1 - ((float)i + gi__u01(&rng)) / (float)m * (1 - cmax);
    float st = sqrtf(fmaxf(0.f, 1 - ct * ct)), phi = phi0 + (float)i * 2.39996323f;
    for (int k = 0; k < 3; k++) {
      w[i][k] = ct * r[k] + st * (cosf(phi) * t[k] + sinf(phi) * b[k]);
      o[i][k] = p[k] + lift * n[k];
    }
    /* A ray into the surface finds nothing: a NaN start disables it. */
    tn[i] = gi__dot(w[i], n) > 0 ? 0.f : NAN;
  }
  gi__emitter_find_n(s, m, (const float(*)[3])o, (const float(*)[3])w, tn, th, tri, hit);
  float tf[GI_SPEC_EMIT_RAYS], zero[GI_SPEC_EMIT_RAYS];
  for (int i = 0; i < m; i++) {
    float ce;
    if (hit[i]) hit[i] = gi__emitter_hit(s, tri[i], w[i], &ce);
    /* Stop short of the emitter's own plane; a missed ray tests nothing. */
    tf[i] = hit[i] ? th[i] * (1.f - GI_EMIT_SHADOW_SHORT) : -1.f;
    zero[i] = 0;
  }
  gi__occluded(s, m, &o[0][0], &w[0][0], zero, tf, vis);
  for (int i = 0; i < m; i++) {
    if (!hit[i] || !vis[i]) continue;
    const float *Le = s->materials[s->tri_material[tri[i]]].emission;
    for (int k = 0; k < 3; k++) L[k] += Le[k] / (float)m;
  }
}

void gi__specular_trace_tan(const struct gi_cascade *c, const float p[3], const float n[3], const float v[3],
                            float tan_half, uint64_t seed, gi_cone_out *out) {
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
   * it (diffuse cones leave the sky to the shadow rays, a mirror cannot).
   * Wherever answers see the sky, not only where the voxels took it: a
   * glossy ground outside a closed hut the viewpoint sat in reflected no
   * sky (0.299 where the path tracer reads 0.437). */
  if (!c->scene) return; /* a texture built by hand (test_cone): no lights to reflect */
  if (gi__answer_sky(c->scene, &c->report) && out->alpha < GI_OPAQUE_ALPHA) {
    float sky[3];
    gi__sky_radiance(c->scene, sky);
    for (int k = 0; k < 3; k++) out->L[k] += (1 - out->alpha) * sky[k];
  }
  if (c->scene->num_emitters && c->report.quality.effects[GI_FX_EMISSIVE] != GI_FX_OFF)
    specular_emitters(c, p, n, r, tan_half, seed, out->L);
}
