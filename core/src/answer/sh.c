/* sh.c: real spherical harmonics up to L2 for irradiance probes.
 *
 * Radiance is projected as L_lm = sum_k L_k Y_lm(w_k) dOmega_k; the cosine
 * lobe's convolution turns it into irradiance coefficients by the factors
 * pi, 2 pi / 3 and pi / 4 for bands 0, 1, 2 (Ramamoorthi and Hanrahan 2001),
 * so E(n) = sum_lm E_lm Y_lm(n). */
#include "answer/answer.h"
#include "base/internal.h"

void gi__sh_basis(const float w[3], float y[9]) {
  float x = w[0], yy = w[1], z = w[2];
  y[0] = 0.282094792f;
  y[1] = 0.488602512f * yy;
  y[2] = 0.488602512f * z;
  y[3] = 0.488602512f * x;
  y[4] = 1.092548431f * x * yy;
  y[5] = 1.092548431f * yy * z;
  y[6] = 0.315391565f * (3.0f * z * z - 1.0f);
  y[7] = 1.092548431f * x * z;
  y[8] = 0.546274215f * (x * x - yy * yy);
}

void gi__sh_add(float sh[9][3], const float w[3], const float L[3], float weight) {
  float y[9];
  gi__sh_basis(w, y);
  for (int i = 0; i < 9; i++)
    for (int k = 0; k < 3; k++) sh[i][k] += weight * y[i] * L[k];
}

void gi__sh_radiance_to_irradiance(float sh[9][3]) {
  static const float A[9] = {3.14159265f, 2.09439510f, 2.09439510f, 2.09439510f, 0.78539816f,
                             0.78539816f, 0.78539816f, 0.78539816f, 0.78539816f};
  for (int i = 0; i < 9; i++)
    for (int k = 0; k < 3; k++) sh[i][k] *= A[i];
}

void gi_sh_eval_irradiance(const float sh[9][3], const float n[3], float out[3]) {
  float y[9];
  gi__sh_basis(n, y);
  for (int k = 0; k < 3; k++) {
    float v = 0;
    for (int i = 0; i < 9; i++) v += sh[i][k] * y[i];
    out[k] = v;
  }
}
