/* ref_sampling.c: the reference's random streams, frames, direction
 * samplers and SH projection, written apart from base/internal.h and
 * answer/sh.c so the two implementations share no sampling code. */
#include "reference/ref_internal.h"

uint64_t gi__ref_hash(uint64_t h, uint64_t v) {
  uint64_t x = h ^ (v * 0xc2b2ae3d27d4eb4fULL);
  x ^= x >> 33;
  x *= 0xff51afd7ed558ccdULL;
  x ^= x >> 33;
  x *= 0xc4ceb9fe1a85ec53ULL;
  x ^= x >> 33;
  return x;
}

void gi__ref_rng_seed(ref_rng *r, uint64_t key) {
  /* PCG's own seeding: step once, add the initial state, step again. */
  r->state = 0;
  r->inc = (gi__ref_hash(key, 0x73747265616dULL) << 1) | 1u;
  (void)ref_rng_u32(r);
  r->state += gi__ref_hash(key, 0x7374617465ULL);
  (void)ref_rng_u32(r);
}

void gi__ref_frame(const float n[3], float t[3], float b[3]) {
  /* The axis least aligned with n is at least 54.7 degrees away from it:
   * the projection never degenerates. */
  float ax = fabsf(n[0]), ay = fabsf(n[1]), az = fabsf(n[2]);
  int i = ax <= ay && ax <= az ? 0 : ay <= az ? 1 : 2;
  float e[3] = {0, 0, 0};
  e[i] = 1;
  float d = n[i], l = 0;
  for (int k = 0; k < 3; k++) t[k] = e[k] - d * n[k], l += t[k] * t[k];
  l = 1.0f / sqrtf(l);
  for (int k = 0; k < 3; k++) t[k] *= l;
  gi__cross(n, t, b);
}

void gi__ref_cosine(const float n[3], ref_rng *r, float w[3]) {
  /* Malley: a uniform point on the unit disc lifted to the hemisphere. */
  float t[3], b[3];
  gi__ref_frame(n, t, b);
  float rad = sqrtf(ref_u01(r)), phi = 2 * (float)GI_PI * ref_u01(r);
  float x = rad * cosf(phi), y = rad * sinf(phi), z = sqrtf(fmaxf(0.f, 1 - rad * rad));
  for (int k = 0; k < 3; k++) w[k] = x * t[k] + y * b[k] + z * n[k];
}

void gi__ref_sphere(ref_rng *r, float w[3]) {
  /* Archimedes: z uniform in [-1, 1], azimuth uniform. */
  float z = 2 * ref_u01(r) - 1, phi = 2 * (float)GI_PI * ref_u01(r);
  float s = sqrtf(fmaxf(0.f, 1 - z * z));
  w[0] = s * cosf(phi), w[1] = s * sinf(phi), w[2] = z;
}

/* Real SH normalisation constants, from their definitions. */
#define SH_C0 0.28209479177387814  /* 1 / (2 sqrt(pi)) */
#define SH_C1 0.48860251190291992  /* sqrt(3 / (4 pi)) */
#define SH_C2 1.09254843059207907  /* sqrt(15 / (4 pi)) */
#define SH_C3 0.31539156525252001  /* sqrt(5 / (16 pi)) */
#define SH_C4 0.54627421529603953  /* sqrt(15 / (16 pi)) */

void gi__ref_sh_add(float sh[9][3], const float w[3], const float L[3], float weight) {
  double x = w[0], y = w[1], z = w[2];
  const double Y[9] = {SH_C0,           SH_C1 * y,     SH_C1 * z,     SH_C1 * x,           SH_C2 * x * y,
                       SH_C2 * y * z,   SH_C3 * (3 * z * z - 1),      SH_C2 * x * z, SH_C4 * (x * x - y * y)};
  for (int i = 0; i < 9; i++)
    for (int k = 0; k < 3; k++) sh[i][k] += (float)(weight * Y[i] * L[k]);
}

void gi__ref_sh_to_irradiance(float sh[9][3]) {
  /* Clamped cosine's zonal coefficients: pi, 2 pi / 3, pi / 4 by band. */
  for (int i = 0; i < 9; i++) {
    double A = i == 0 ? GI_PI : i < 4 ? 2 * GI_PI / 3 : GI_PI / 4;
    for (int k = 0; k < 3; k++) sh[i][k] = (float)(sh[i][k] * A);
  }
}
